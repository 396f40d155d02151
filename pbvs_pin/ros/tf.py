"""TF in the bags: the robot's links, its camera's optical frame and the target, in ``odom``.

``tf2_msgs`` is not on PyPI, so ROS installed by pip cannot publish ``/tf`` (its message
class is missing). A bag needs only the message's bytes: ``rosbags``' Kilted type store
defines ``tf2_msgs/msg/TFMessage`` and serialises it (CDR, as ROS would), and the bag carries
the definition, so that Foxglove and ``ros2 bag`` read ``/tf`` as the standard message.

Every link's pose is given in ``odom`` (the simulation's world frame, where the platform
starts), one transform per Pinocchio body frame: a flat tree, which TF viewers accept as it
is. Poses come from Pinocchio's forward kinematics of the configuration ``q``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin
from rosbags.typesys import Stores, get_typestore

from pbvs_pin.model import frames
from pbvs_pin.model.robot import MobileManipulator

TYPESTORE = get_typestore(Stores.ROS2_KILTED)
"""The message definitions the bags are written with (ROS 2 Kilted)."""

TF_TYPE = "tf2_msgs/msg/TFMessage"
"""The type of ``/tf``."""

TARGET_FRAME = "target"
"""The child frame of the target's midpoint (between the two spheres' centres)."""


def link_poses(robot: MobileManipulator, q: np.ndarray) -> list[tuple[str, pin.SE3]]:
    """Every link's pose (Pinocchio body frame) in ``odom``, the camera's optical frame last.

    Args:
        robot: The robot.
        q: Its configuration. Shape (nq,).
    """
    model, data = robot.model, robot.data
    pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
    poses = [
        (frame.name, data.oMf[index])
        for index, frame in enumerate(model.frames)
        if frame.type == pin.FrameType.BODY and frame.name != frames.CAMERA_OPTICAL
    ]
    return [*poses, (frames.CAMERA_OPTICAL, robot.camera_pose(q))]


def tf_message(t: float, robot: MobileManipulator, q: np.ndarray, target: np.ndarray) -> bytes:
    """``/tf`` at time ``t`` [s], serialised (CDR): the links and the target, in ``odom``.

    Every link as :func:`link_poses` gives it, then the target's midpoint
    (:data:`TARGET_FRAME`, no rotation).

    Args:
        t: The time [s].
        robot: The robot.
        q: Its configuration. Shape (nq,).
        target: The target's midpoint [m] in ``odom``. Shape (3,).
    """
    poses = [*link_poses(robot, q), (TARGET_FRAME, pin.SE3(np.eye(3), np.asarray(target, float)))]
    types: Any = TYPESTORE.types
    sec, nanosec = divmod(round(t * 1e9), 1_000_000_000)
    header = types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
        frame_id=frames.ODOM,
    )
    transforms = []
    for child, pose in poses:
        x, y, z, w = pin.Quaternion(pose.rotation).coeffs()  # Eigen's order: x, y, z, w
        transform = types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](*map(float, pose.translation)),
            rotation=types["geometry_msgs/msg/Quaternion"](float(x), float(y), float(z), float(w)),
        )
        transforms.append(
            types["geometry_msgs/msg/TransformStamped"](
                header=header, child_frame_id=child, transform=transform
            )
        )
    message = types[TF_TYPE](transforms=transforms)
    return bytes(TYPESTORE.serialize_cdr(message, TF_TYPE))
