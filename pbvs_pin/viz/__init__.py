"""Browser visualisation of PBVS runs (meshcat / three.js).

This subpackage is deliberately kept out of the control core: nothing in
``pbvs_pin`` outside ``pbvs_pin.viz`` may import it, and importing
``pbvs_pin.viz`` itself does not import :mod:`meshcat` (every meshcat import
happens lazily inside the functions that need it).

Typical use::

    from pbvs_pin.viz import open_visualizer, RobotScene, write_replay_html

    with open_visualizer() as vis:
        robot = RobotScene(vis, model, visual_model)
        poses = robot.trajectory_poses(qs)          # {path: (T, 4, 4)}
        write_replay_html("run.html", vis, times, poses)

See :mod:`pbvs_pin.viz.scene` for the conventions (paths, frames, units).
"""

from . import scene
from .scene import *  # noqa: F403

__all__ = list(scene.__all__)
