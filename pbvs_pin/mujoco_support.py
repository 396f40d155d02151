"""The floor support a robot stands on in the MuJoCo plant, for the home solver.

:func:`support_polygon` builds the robot's MuJoCo model (:func:`pbvs_pin.mujoco_plant.build_spec`,
the plant's own), stands it at the origin and returns the convex hull of its floor contacts
in the platform's frame (:func:`pbvs_pin.mujoco_stability.contact_polygon`, the polygon the
plant's tip-over warning measures against). Only platform geometry meets the floor, so the
polygon does not depend on the arm's posture. :func:`pbvs_pin.home.compute_home` keeps the
centre of mass inside it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

from pbvs_pin.base import DifferentialDrive
from pbvs_pin.exceptions import PbvsError
from pbvs_pin.mujoco_plant import build_spec
from pbvs_pin.mujoco_stability import contact_polygon

if TYPE_CHECKING:
    from pbvs_pin.robot import MobileManipulator


def support_polygon(robot: MobileManipulator) -> np.ndarray | None:
    """The support polygon of ``robot`` on the MuJoCo plant's floor, platform at the origin.

    Args:
        robot: The robot.

    Returns:
        Vertices [m] counter-clockwise in the platform frame (x forward, the drive footprint's
        origin), shape (m, 2); None for a robot that does not stand on wheels in the MuJoCo
        plant (a holonomic base, no URDF) or whose MuJoCo model cannot be built (the plant
        says why when it is asked to run it).
    """
    if robot.urdf_xml is None or not isinstance(robot.base, DifferentialDrive):
        return None
    try:
        model = build_spec(robot)[0].compile()
    except (PbvsError, ValueError):
        return None
    data = mujoco.MjData(model)
    data.qpos[:7] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]  # the free joint: upright, on the floor
    mujoco.mj_forward(model, data)
    return contact_polygon(data)
