"""Browser visualisation of PBVS runs (meshcat / three.js).

This subpackage is deliberately kept out of the control core: nothing in
``pbvs_pin`` outside ``pbvs_pin.viz`` may import it, and importing
``pbvs_pin.viz`` itself does not import :mod:`meshcat` (every meshcat import
happens lazily inside the functions that need it).

Modules
-------
* :mod:`~pbvs_pin.viz.server`: start and stop a served meshcat viewer.
* :mod:`~pbvs_pin.viz.recorder`: an offline viewer that records the scene in-process.
* :mod:`~pbvs_pin.viz.primitives`: meshcat paths, spheres, obstacles, trails, viewing camera.
* :mod:`~pbvs_pin.viz.frustum`: the camera: frustum, triad, image plane, feature points.
* :mod:`~pbvs_pin.viz.robot_scene`: a robot's visual geometries posed from Pinocchio.
* :mod:`~pbvs_pin.viz.animation`: pose tracks -> animation -> standalone HTML replay.
* :mod:`~pbvs_pin.viz.run_scene`: the scene of a closed-loop run.
* :mod:`~pbvs_pin.viz.live`, :mod:`~pbvs_pin.viz.html_replay`, :mod:`~pbvs_pin.viz.figures`:
  a run shown live, written as a replay, plotted.

Everything works on plain Pinocchio objects (``pin.Model``,
``pin.GeometryModel``, ``pin.SE3`` / 4x4 arrays) and on a
``meshcat.Visualizer``.  :mod:`meshcat` and :mod:`pinocchio.visualize` are
imported lazily inside the functions that need them, so importing these modules
never pulls meshcat in, and the control core must never import them.

Conventions
-----------
* Units are SI: metres, radians, seconds.  Image quantities are in pixels.
* Poses are 4x4 homogeneous transforms ``T`` (numpy, float) mapping child
  coordinates to parent coordinates; for objects at the top of the ``pbvs``
  tree the parent is the world (Pinocchio's universe frame).
* Meshcat paths are given *relative to the visualizer root* (``/meshcat``),
  e.g. ``"pbvs/robot/wrist_3_link_0"``.  Pose dictionaries map such paths to
  transforms.
* Meshcat is Z-up like Pinocchio.  The three.js scene of the browser viewer is
  Y-up; the viewer rotates its scene root by -pi/2 about X, so a world matrix
  read in the page (``object.matrixWorld``) equals
  ``MESHCAT_TO_THREEJS @ T_meshcat``.
* Cameras follow the optical-frame convention of :mod:`pbvs_pin.model.camera`:
  +z forward (optical axis), +x right, +y down.  The image helpers here take
  *pixels* ``(col, row)`` from the top-left corner, which back-project to the
  ray ``((col - cx) / f, (row - cy) / f, 1)``.  Image coordinates ``xi`` in
  the paper's eq. (2) sign convention (``xi = -(f / z) [x, y]``) convert with
  ``pbvs_pin.model.camera.CameraIntrinsics.to_pixel(xi)`` (``col = cx - u``,
  ``row = cy - v``).
* Colours are RGB triples in [0, 1] or 0xRRGGBB integers.

Typical use::

    from pbvs_pin.viz import open_visualizer, RobotScene, write_replay_html

    with open_visualizer() as vis:
        robot = RobotScene(vis, model, visual_model)
        add_target_spheres(vis, centers, diameter=0.05, color=(1, 0, 0))
        poses = robot.trajectory_poses(qs)            # {path: (T, 4, 4)}
        write_replay_html("run.html", vis, times, poses)

A file needs no server: :func:`offline_visualizer` records the scene in this
process and its ``static_html()`` is the page a server would return.  A
closed-loop run is drawn by :class:`RunScene` (robot, target, obstacles,
camera frustum, image plane, trails), shared by the live view
(:mod:`pbvs_pin.viz.live`) and the replay (:mod:`pbvs_pin.viz.html_replay`).
Starting a server that cannot start raises
:class:`~pbvs_pin.exceptions.ViewerUnavailable`.
"""

from . import animation, frustum, primitives, recorder, robot_scene, run_scene, server
from .animation import *  # noqa: F403
from .frustum import *  # noqa: F403
from .primitives import *  # noqa: F403
from .recorder import *  # noqa: F403
from .robot_scene import *  # noqa: F403
from .run_scene import *  # noqa: F403
from .server import *  # noqa: F403

__all__ = sorted(
    [
        *animation.__all__,
        *frustum.__all__,
        *primitives.__all__,
        *recorder.__all__,
        *robot_scene.__all__,
        *run_scene.__all__,
        *server.__all__,
    ]
)
