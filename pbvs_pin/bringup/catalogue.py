"""The robots pbvs_pin ships: the paper's reference robot, arms on its platform, and TIAGo.

Each entry says how to build the robot and gives a *home* posture of its arm in which the
camera looks horizontally forward (optical z along the platform's x, image upright). The homes
are :func:`pbvs_pin.bringup.home.compute_home` with its default criteria, rounded to 1e-4 rad (or
m): camera 0.5-1.0 m above the floor, 0.3-0.7 m ahead, each joint at least 10% of its range from
its limits, largest manipulability, and the centre of mass 0.05 m inside the wheels' support
where the home found without it would tip the platform (UR5, Panda); ``tests/test_home.py``
checks them against the criteria.
The reference robot's home is all zeros, as in the paper's experiments, which is also what
compute_home gives for it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING
from xml.etree import ElementTree

import numpy as np

from pbvs_pin.exceptions import RobotNotFound, WrongType
from pbvs_pin.model.shipped import shipped_urdf

if TYPE_CHECKING:  # the names and recipes load without Pinocchio (the command line's --help)
    from pbvs_pin.model.camera import CameraIntrinsics
    from pbvs_pin.model.robot import MobileManipulator

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
        "pioneer3at", "ur5", "tool0", (0,) * 6, (-2.7799, -1.2665, -1.7208, -0.1543, 1.2091, 0.0)
    ),
    "pioneer_panda": Recipe(
        "pioneer3at",
        "panda",
        "panda_hand_tcp",
        (0,) * 6,
        (0.1137, -0.8764, 0.0898, -2.2966, 2.3178, 3.3755, 0.0946),
    ),
    "pioneer_z1": Recipe(
        "pioneer3at", "z1", "link06", OPTICAL_FROM_BODY, (0.0, 2.3915, -1.615, -0.7765, 0.0, 0.0)
    ),
    "pioneer_kinova": Recipe(
        "pioneer3at",
        "kinova",
        "j2s6s200_end_effector",
        (0,) * 6,
        (1.1073, 2.0258, 4.3866, -1.9119, 5.0325, -0.8456),
    ),
    "pioneer_xarm7": Recipe(
        "pioneer3at",
        "xarm7",
        "link_eef",
        (0,) * 6,
        (-0.0263, -0.933, 0.0332, 0.9223, 0.0231, 0.2842, 1.5753),
    ),
    "tiago": Recipe(
        "tiago",
        None,
        "arm_tool_link",
        OPTICAL_FROM_BODY,
        (0.3111, 1.3533, -0.9546, -1.2786, 0.2138, 0.1706, 0.9925, -1.6753),
        mount=(0,) * 6,
    ),
}
"""Shipped robots built by assembly, by name."""

REFERENCE_ROBOT = "pioneer_cyton"
"""The paper's robot: Pioneer 3-AT with a three-joint Cyton-like arm."""

ROBOT_NAMES = (REFERENCE_ROBOT, *RECIPES)
"""Every shipped robot name."""

OTHER_ROBOTS = tuple(name for name in ROBOT_NAMES if name != REFERENCE_ROBOT)
"""Robots the paper's experiments are repeated on by default: every other shipped robot."""


MIN_ARM_JOINTS = 3
"""Fewest moving joints before the first branch of an arm's tree (a camera needs 3 to aim)."""


def example_robot_data_arms() -> list[str]:
    """example-robot-data names that can be mounted on a platform as an arm.

    An arm has a fixed base (legged robots, humanoids and drones have a free-flyer root) and
    a single chain of at least :data:`MIN_ARM_JOINTS` moving joints from its root before its
    tree branches, holding at least half of its moving joints (:func:`chain_joints`; a
    gripper's fingers may branch off its end): hands (fingers branch at the palm), torsos
    carrying two arms, mobile robots (wheels branch at the base) and two-joint pendulums are
    not arms. A name example-robot-data maps to another robot's loader (``"ur3"`` loads the
    UR5: :func:`pbvs_pin.model.assembly.example_robot_data_alias`) is left out. Read from each
    URDF's joint tags; no model is built.
    """
    from example_robot_data.robots_loader import ROBOTS, getModelPath

    from pbvs_pin.model.assembly import example_robot_data_alias

    arms = []
    for name, loader in ROBOTS.items():
        if loader.free_flyer or not loader.urdf_filename or example_robot_data_alias(name):
            continue
        relative = Path(loader.path) / loader.urdf_subpath / loader.urdf_filename
        urdf = Path(getModelPath(str(relative))) / relative
        chain, total = chain_joints(urdf)
        if chain >= MIN_ARM_JOINTS and 2 * chain >= total:
            arms.append(name)
    return sorted(arms)


def chain_joints(urdf: Path) -> tuple[int, int]:
    """Moving joints on the unbranched chain from a URDF's root, and in the whole file.

    Fixed joints are followed through; the chain stops at the first link with two or more
    child subtrees holding a moving joint. ``(0, 0)`` for an unreadable file.
    """
    try:
        joints = ElementTree.parse(urdf).getroot().findall("joint")
    except (OSError, ElementTree.ParseError):
        return 0, 0
    children: dict[str, list[tuple[str, bool]]] = {}
    for joint in joints:
        parent, child = joint.find("parent"), joint.find("child")
        if parent is None or child is None:
            return 0, 0
        moving = joint.get("type") not in ("fixed", None)
        children.setdefault(parent.get("link", ""), []).append((child.get("link", ""), moving))
    parents = {child for kids in children.values() for child, _ in kids}
    roots = [link for link in children if link not in parents]
    total = sum(moving for kids in children.values() for _, moving in kids)
    count, link = 0, roots[0] if len(roots) == 1 else ""
    while True:
        moving_kids = [(c, m) for c, m in children.get(link, []) if _moves(children, c, m)]
        if len(moving_kids) != 1:
            return count, total
        link, moving = moving_kids[0]
        count += moving


def _moves(children: dict[str, list[tuple[str, bool]]], link: str, moving: bool) -> bool:
    """Whether the joint into ``link`` or any joint below it moves."""
    stack = [(link, moving)]
    while stack:
        link, moving = stack.pop()
        if moving:
            return True
        stack += children.get(link, [])
    return False


def build_robot(name: str, camera: CameraIntrinsics | None = None) -> MobileManipulator:
    """Build a shipped robot, or load a URDF file that has a ``camera_optical_frame``.

    A URDF file's home posture is computed (:func:`pbvs_pin.bringup.home.compute_home`).

    Args:
        name: A name from :data:`ROBOT_NAMES`, or a URDF path.
        camera: Intrinsics; the paper's camera by default.

    Raises:
        RobotNotFound: If ``name`` is neither.
    """
    is_file = Path(name).suffix.lower() == ".urdf" or Path(name).exists()
    if name not in ROBOT_NAMES and not is_file:  # refused before Pinocchio loads
        raise RobotNotFound(name, ROBOT_NAMES)
    from pbvs_pin.bringup.home import compute_home
    from pbvs_pin.model.robot import MobileManipulator

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
    else:
        source = str(shipped_urdf(name)) if name == REFERENCE_ROBOT else name
        robot = MobileManipulator.from_urdf(source, camera=camera)
    robot.support = floor_support(robot)
    if name != REFERENCE_ROBOT and name not in RECIPES:
        robot.home_arm = compute_home(robot, support=robot.support)
    return robot


def floor_support(robot: MobileManipulator) -> np.ndarray | None:
    """The support polygon ``robot`` stands on: the MuJoCo plant's floor contacts.

    Vertices [m] counter-clockwise in the platform frame, shape (m, 2)
    (:func:`pbvs_pin.plant.mujoco_support.support_polygon`); None when it has fewer than three
    (nothing to stand on with an inside) or the robot does not stand on wheels there.
    """
    from pbvs_pin.plant.mujoco_support import support_polygon

    support = support_polygon(robot)
    return support if support is not None and len(support) >= 3 else None


def load_robot(name: str, camera: CameraIntrinsics | None = None) -> MobileManipulator:
    """Load a shipped robot by name, or any URDF file holding the camera optical frame.

    Args:
        name: ``"pioneer_cyton"``, ``"pioneer_<arm>"`` for an example-robot-data arm on the
            reference platform (``"pioneer_ur5"``, ...), ``"tiago"``, or a URDF path.
        camera: Intrinsics; the paper's camera by default.

    Raises:
        RobotNotFound: If the name is unknown.
        WrongType: If ``name`` is not text or a path.
    """
    if not isinstance(name, str | os.PathLike) or str(name) == "":
        raise WrongType("name", "a robot name or a URDF path (str or pathlib.Path)", name)
    return build_robot(name, camera)
