"""The robots pbvs_pin ships: the paper's reference robot, arms on its platform, and TIAGo.

Each entry says how to build the robot and gives a *home* posture of its arm in which the
camera looks horizontally forward (optical z along the platform's x, image upright). The homes
of the example-robot-data arms were solved once by inverse kinematics for a camera 0.45 m
ahead of the platform centre and 0.75 m above the floor (TIAGo: 0.6 m and 1.0 m), within the
joint limits. The reference robot's home is all zeros, as in the paper's experiments.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pbvs_pin.camera import CameraIntrinsics
from pbvs_pin.exceptions import RobotNotFound
from pbvs_pin.robot import MobileManipulator
from pbvs_pin.shipped import shipped_urdf

OPTICAL_FROM_BODY = (0.0, 0.0, 0.0, -np.pi / 2, 0.0, -np.pi / 2)
"""Pose of an optical frame (z forward) in a body frame whose x axis points forward."""

PIONEER_MOUNT = (0.10, 0.0, 0.27, 0.0, 0.0, 0.0)
"""Arm mount on the reference platform: front of the top plate [m, rad]."""


@dataclass(frozen=True)
class Recipe:
    """How to build one shipped robot.

    Attributes:
        base: Platform source for :meth:`MobileManipulator.assemble`.
        arm: Arm source, or None when the base carries its arm.
        camera_link: Link the camera is fixed to.
        camera_pose: Optical frame in ``camera_link`` (x, y, z, roll, pitch, yaw).
        home: Arm joint positions [rad or m] in which the camera looks forward.
        mount: Arm root pose in the platform's root link.
    """

    base: str
    arm: str | None
    camera_link: str
    camera_pose: tuple[float, ...]
    home: tuple[float, ...]
    mount: tuple[float, ...] = PIONEER_MOUNT


RECIPES = {
    "pioneer_ur5": Recipe(
        "pioneer3at", "ur5", "tool0", (0,) * 6, (-0.421, 0.125, -2.165, -1.101, -1.149, 0.0)
    ),
    "pioneer_panda": Recipe(
        "pioneer3at",
        "panda",
        "panda_hand_tcp",
        (0,) * 6,
        (-0.402, -1.298, 0.578, -2.949, 2.469, 2.825, 0.428),
    ),
    "pioneer_z1": Recipe(
        "pioneer3at", "z1", "link06", OPTICAL_FROM_BODY, (0.0, 1.591, -1.454, -0.137, 0.0, 0.0)
    ),
    "pioneer_kinova": Recipe(
        "pioneer3at",
        "kinova",
        "j2s6s200_end_effector",
        (0,) * 6,
        (0.903, 1.316, 1.448, 2.234, 1.489, -1.675),
    ),
    "pioneer_xarm7": Recipe(
        "pioneer3at",
        "xarm7",
        "link_eef",
        (0,) * 6,
        (0.442, -0.415, -0.303, 0.517, 0.256, -0.692, 1.249),
    ),
    "tiago": Recipe(
        "tiago",
        None,
        "arm_tool_link",
        OPTICAL_FROM_BODY,
        (0.0, 0.698, 1.091, -1.492, 1.528, -0.476, -0.608, -0.003),
        mount=(0,) * 6,
    ),
}
"""Shipped robots built by assembly, by name."""

REFERENCE_ROBOT = "pioneer_cyton"
"""The paper's robot: Pioneer 3-AT with a three-joint Cyton-like arm."""

ROBOT_NAMES = (REFERENCE_ROBOT, *RECIPES)
"""Every shipped robot name."""


def build_robot(name: str, camera: CameraIntrinsics | None = None) -> MobileManipulator:
    """Build a shipped robot, or load a URDF file that has a ``camera_optical_frame``.

    Args:
        name: A name from :data:`ROBOT_NAMES`, or a URDF path.
        camera: Intrinsics; the paper's camera by default.

    Raises:
        RobotNotFound: If ``name`` is neither.
    """
    if name == REFERENCE_ROBOT:
        return MobileManipulator.from_urdf(str(shipped_urdf(name)), camera=camera)
    if name in RECIPES:
        recipe = RECIPES[name]
        robot = MobileManipulator.assemble(
            recipe.base,
            recipe.arm,
            recipe.mount,
            recipe.camera_link,
            recipe.camera_pose,
            camera=camera,
        )
        robot.home_arm = np.array(recipe.home)
        return robot
    if Path(name).suffix.lower() == ".urdf" or Path(name).exists():
        return MobileManipulator.from_urdf(name, camera=camera)
    raise RobotNotFound(name, ROBOT_NAMES)


def load_robot(name: str, camera: CameraIntrinsics | None = None) -> MobileManipulator:
    """Load a shipped robot by name, or any URDF file holding the camera optical frame.

    Args:
        name: ``"pioneer_cyton"``, ``"pioneer_<arm>"`` for an example-robot-data arm on the
            reference platform (``"pioneer_ur5"``, ...), ``"tiago"``, or a URDF path.
        camera: Intrinsics; the paper's camera by default.

    Raises:
        RobotNotFound: If the name is unknown.
    """
    return build_robot(name, camera)
