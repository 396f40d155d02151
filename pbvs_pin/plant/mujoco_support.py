"""The floor support a robot stands on in the MuJoCo plant, for the home solver.

:func:`support_polygon` builds the robot's MuJoCo model
(:func:`pbvs_pin.plant.mujoco_spec.build_spec`, the plant's own), stands it at the origin and
returns the convex hull of its floor contacts in the platform's frame
(:func:`pbvs_pin.plant.mujoco_stability.contact_polygon`, the polygon the plant's tip-over warning
measures against). Only platform geometry meets the floor, so the polygon does not depend on the
arm's posture. :func:`pbvs_pin.bringup.home.compute_home` keeps the centre of mass inside it;
:func:`centre_of_mass_margins` measures it over a run's postures.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from pbvs_pin.exceptions import PbvsError
from pbvs_pin.model.base import DifferentialDrive
from pbvs_pin.plant.mujoco_spec import build_spec
from pbvs_pin.plant.mujoco_stability import contact_polygon, polygon_margin

if TYPE_CHECKING:
    from pbvs_pin.model.robot import MobileManipulator


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


def centre_of_mass_margins(
    robot: MobileManipulator, arm: npt.ArrayLike, support: npt.ArrayLike
) -> np.ndarray:
    """How far [m] the robot's centre of mass lies inside ``support`` at each arm posture.

    The static measure the plant's tip-over warning takes
    (:func:`pbvs_pin.plant.mujoco_stability.polygon_margin`), with Pinocchio's centre of mass of the
    whole robot (``pin.centerOfMass``), platform at the origin: a run's ``arm`` channel gives
    the margin over the run. It leaves out the platform's acceleration.

    Args:
        robot: The robot.
        arm: Arm postures [rad or m]. Shape (k, n_arm).
        support: The support's vertices [m] counter-clockwise in the platform frame
            (:func:`support_polygon`). Shape (m, 2).

    Returns:
        The margins [m] (negative: outside, the robot tips). Shape (k,).
    """
    base = robot.neutral()
    return np.array(
        [
            polygon_margin(
                support,
                pin.centerOfMass(robot.model, robot.data, robot.with_arm_positions(base, a)),
            )
            for a in np.asarray(arm, dtype=float).reshape(-1, robot.n_arm)
        ]
    )
