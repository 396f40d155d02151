"""Standard ROS 2 messages to and from what :class:`pbvs_pin.Controller` takes and gives.

Conventions (REP-103, REP-105):

- ``nav_msgs/Odometry``: the pose of the platform's ``drive_footprint`` (the drive-axle
  midpoint on the floor, x forward) in the odometry's fixed frame ``odom``; its twist in the
  platform frame: ``linear.x`` [m/s] and ``angular.z`` [rad/s] (and ``linear.y`` for a
  holonomic base).
- ``sensor_msgs/JointState``: arm joints found by name, positions [rad or m], velocities
  [rad/s or m/s].
- ``sensor_msgs/LaserScan``: angles counter-clockwise from the laser's forward axis; the
  controller takes the nearest return ``(d, alpha)`` with ``alpha`` clockwise.
- ``sensor_msgs/Image``: ``rgb8`` or ``bgr8``; ``header.stamp`` is the capture time.
- ``sensor_msgs/CameraInfo``: checked against the controller's pinhole (``K``: fx = fy = f,
  principal point at the image centre).

Every reader raises the project's error naming the message and field on bad input.
"""

from __future__ import annotations

import math

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import CameraInfo, Image, JointState, LaserScan
from std_msgs.msg import Float64MultiArray

from pbvs_pin.exceptions import ControlInputError, NonFiniteValue, ShapeError
from pbvs_pin.model.camera import CameraIntrinsics
from pbvs_pin.model.robot import MobileManipulator

INTRINSICS_TOLERANCE = 0.5
"""Largest difference [px] between CameraInfo's ``K`` and the controller's intrinsics."""


def seconds(stamp: Time) -> float:
    """A ROS time as seconds [s]."""
    return stamp.sec + 1e-9 * stamp.nanosec


def stamp(t: float) -> Time:
    """Seconds [s] as a ROS time."""
    sec = math.floor(t)
    return Time(sec=sec, nanosec=min(round((t - sec) * 1e9), 999_999_999))


def _finite(name: str, values: np.ndarray) -> np.ndarray:
    if not np.all(np.isfinite(values)):
        raise NonFiniteValue(name)
    return values


def arm_reading(message: JointState, names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Arm positions and velocities in the order of ``names`` (shape (n_arm,) each).

    Raises:
        ControlInputError: If a joint is missing or a velocity is not given.
        NonFiniteValue: If a value used is NaN or infinite.
    """
    index = {name: i for i, name in enumerate(message.name)}
    missing = [name for name in names if name not in index]
    if missing:
        raise ControlInputError(
            f"joint_states: no joint {missing} (has {list(message.name)}); expected every arm "
            f"joint {list(names)}"
        )
    rows = [index[name] for name in names]
    if len(message.position) != len(message.name) or len(message.velocity) != len(message.name):
        raise ControlInputError(
            f"joint_states: {len(message.name)} names, {len(message.position)} positions and "
            f"{len(message.velocity)} velocities; expected a position and a velocity per name"
        )
    positions = np.asarray(message.position, dtype=float)[rows]
    velocities = np.asarray(message.velocity, dtype=float)[rows]
    return _finite("joint_states.position", positions), _finite("joint_states.velocity", velocities)


def platform_reading(message: Odometry, n_base: int) -> tuple[np.ndarray, np.ndarray]:
    """The platform pose and velocity of an odometry message.

    Returns ``[x, y, yaw]`` [m, m, rad] and ``[u, omega]`` (``[vx, vy, omega]`` holonomic).

    Raises:
        NonFiniteValue: If a value used is NaN or infinite.
        ControlInputError: If the orientation is not a unit quaternion.
    """
    pose = message.pose.pose
    o = pose.orientation
    norm = math.sqrt(o.x**2 + o.y**2 + o.z**2 + o.w**2)
    if not abs(norm - 1.0) < 1e-3:
        raise ControlInputError(f"odom.pose.orientation: expected a unit quaternion, norm {norm}")
    yaw = math.atan2(2.0 * (o.w * o.z + o.x * o.y), 1.0 - 2.0 * (o.y**2 + o.z**2))
    planar = _finite("odom.pose", np.array([pose.position.x, pose.position.y, yaw]))
    twist = message.twist.twist
    if n_base == 2:
        velocity = [twist.linear.x, twist.angular.z]
    else:
        velocity = [twist.linear.x, twist.linear.y, twist.angular.z]
    return planar, _finite("odom.twist", np.array(velocity, dtype=float))


def configuration(robot: MobileManipulator, planar: np.ndarray, arm: np.ndarray) -> np.ndarray:
    """The Pinocchio configuration of a platform pose ``[x, y, yaw]`` and arm positions."""
    q = robot.neutral()
    q[:4] = planar[0], planar[1], math.cos(planar[2]), math.sin(planar[2])
    return robot.with_arm_positions(q, arm)


def nearest_return(message: LaserScan) -> tuple[float, float]:
    """``(d [m], alpha [rad])``: the shortest valid range and its angle, clockwise-positive.

    Ranges outside ``[range_min, range_max]`` or not finite are no return; with none,
    ``(inf, 0)``.
    """
    ranges = np.asarray(message.ranges, dtype=float)
    valid = np.isfinite(ranges) & (ranges >= message.range_min) & (ranges <= message.range_max)
    if not np.any(valid):
        return float("inf"), 0.0
    index = int(np.argmin(np.where(valid, ranges, np.inf)))
    return float(ranges[index]), -(message.angle_min + index * message.angle_increment)


def image_array(message: Image) -> np.ndarray:
    """An ``rgb8`` or ``bgr8`` image as RGB ``uint8``, shape (H, W, 3).

    Raises:
        ControlInputError: On another encoding, or a size that does not match the data.
    """
    if message.encoding not in ("rgb8", "bgr8"):
        raise ControlInputError(
            f"camera/image_raw.encoding: expected rgb8 or bgr8, got {message.encoding!r}"
        )
    height, width, step = message.height, message.width, message.step
    data = np.frombuffer(bytes(message.data), dtype=np.uint8)
    if step < 3 * width or data.size != step * height:
        raise ControlInputError(
            f"camera/image_raw: {data.size} bytes for {width} x {height} px with step {step}"
        )
    image = data.reshape(height, step)[:, : 3 * width].reshape(height, width, 3)
    return image[:, :, ::-1] if message.encoding == "bgr8" else image


def check_camera_info(message: CameraInfo, camera: CameraIntrinsics) -> None:
    """Check that CameraInfo describes the controller's camera.

    Raises:
        ShapeError: If the image size differs.
        ControlInputError: If ``K`` differs by more than :data:`INTRINSICS_TOLERANCE`.
    """
    if (message.height, message.width) != (camera.height, camera.width):
        raise ShapeError(
            "camera_info (height, width)", (camera.height, camera.width),
            (message.height, message.width),
        )  # fmt: skip
    k = np.asarray(message.k, dtype=float)
    expected = np.array([camera.focal_px, camera.focal_px, *camera.principal_point])
    got = k[[0, 4, 2, 5]]
    if not np.all(np.abs(got - expected) <= INTRINSICS_TOLERANCE):
        raise ControlInputError(
            f"camera_info.k: (fx, fy, cx, cy) = {got.tolist()} px; expected {expected.tolist()}"
            " px (camera.focal_px, the image centre)"
        )


def twist(v_base: np.ndarray) -> Twist:
    """``cmd_vel`` of platform velocities ``[u, omega]`` or ``[vx, vy, omega]``."""
    message = Twist()
    message.linear.x = float(v_base[0])
    if len(v_base) == 3:
        message.linear.y = float(v_base[1])
    message.angular.z = float(v_base[-1])
    return message


def twist_velocity(message: Twist, n_base: int) -> np.ndarray:
    """Platform velocities (shape (n_base,)) from a ``cmd_vel`` message."""
    if n_base == 2:
        return np.array([message.linear.x, message.angular.z])
    return np.array([message.linear.x, message.linear.y, message.angular.z])


def arm_command(v_arm: np.ndarray) -> Float64MultiArray:
    """Arm joint rates for a ros2_control ``JointGroupVelocityController``."""
    return Float64MultiArray(data=[float(x) for x in v_arm])


def diagnostics(t: float, name: str, values: dict[str, object], ok: bool) -> DiagnosticArray:
    """One ``diagnostic_msgs/DiagnosticArray`` status with ``values`` as key-value pairs."""
    status = DiagnosticStatus(
        level=DiagnosticStatus.OK if ok else DiagnosticStatus.WARN,
        name=name,
        message="servoing" if ok else str(values.get("stopped", "not servoing")),
        values=[KeyValue(key=key, value=str(value)) for key, value in values.items()],
    )
    message = DiagnosticArray(status=[status])
    message.header.stamp = stamp(t)
    return message


def joint_state(t: float, names: tuple[str, ...], positions, velocities) -> JointState:
    """A ``sensor_msgs/JointState`` stamped ``t`` [s]."""
    message = JointState(
        name=list(names),
        position=[float(x) for x in positions],
        velocity=[float(x) for x in velocities],
    )
    message.header.stamp = stamp(t)
    return message


def odometry(t: float, planar, v_base, frame: str, child: str) -> Odometry:
    """A ``nav_msgs/Odometry`` of ``[x, y, yaw]`` and platform velocities, stamped ``t``."""
    message = Odometry()
    message.header.stamp = stamp(t)
    message.header.frame_id, message.child_frame_id = frame, child
    pose = message.pose.pose
    pose.position.x, pose.position.y = float(planar[0]), float(planar[1])
    pose.orientation.z, pose.orientation.w = math.sin(planar[2] / 2), math.cos(planar[2] / 2)
    message.twist.twist = twist(v_base)
    return message


def laser_scan(t: float, ranges, field_of_view: float, max_range: float, frame: str) -> LaserScan:
    """A ``sensor_msgs/LaserScan`` of beams spread evenly over ``field_of_view`` [rad]."""
    beams = len(ranges)
    message = LaserScan(
        angle_min=-field_of_view / 2, angle_max=field_of_view / 2,
        angle_increment=field_of_view / max(beams - 1, 1), range_min=0.0,
        range_max=float(max_range), ranges=[float(r) for r in ranges],
    )  # fmt: skip
    message.header.stamp, message.header.frame_id = stamp(t), frame
    return message


def image(t: float, rgb: np.ndarray, frame: str) -> Image:
    """An ``rgb8`` ``sensor_msgs/Image`` of an RGB ``uint8`` array (H, W, 3), stamped ``t``."""
    height, width, _ = rgb.shape
    message = Image(height=height, width=width, encoding="rgb8", step=3 * width)
    message.data = np.ascontiguousarray(rgb, dtype=np.uint8).tobytes()
    message.header.stamp, message.header.frame_id = stamp(t), frame
    return message


def camera_info(t: float, camera: CameraIntrinsics, frame: str) -> CameraInfo:
    """The pinhole ``sensor_msgs/CameraInfo`` of ``camera`` (no distortion), stamped ``t``."""
    f = float(camera.focal_px)
    cx, cy = camera.principal_point
    message = CameraInfo(height=camera.height, width=camera.width, distortion_model="plumb_bob")
    message.k = [f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0]
    message.p = [f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    message.d = [0.0] * 5
    message.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    message.header.stamp, message.header.frame_id = stamp(t), frame
    return message
