"""A stand-in robot in the caller's process, for tests and benchmarks of the node.

:class:`StandInRobot` plays a robot's drivers in lockstep with the node: each :meth:`tick`
publishes ``joint_states`` and ``odom`` (a robot moving at constant velocities, so that the
controller's braking command, eq. (20), is not zero), optionally a camera image with two
discs where the target's spheres would be, then ``/clock``, and waits for the ``cmd_vel``
that answers. It records each command with the tick's time and the wall-clock time from the
readings' publication to the command's arrival (the latency through DDS and the node's step).
"""

from __future__ import annotations

import time

import cv2
import numpy as np
import rclpy
import rclpy.time
from geometry_msgs.msg import Twist
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Bool, Float64MultiArray

from pbvs_pin.model import frames
from pbvs_pin.perception.detection import SPHERE_HUES, sphere_rgba
from pbvs_pin.ros import messages
from pbvs_pin.sim.scenario import Scenario

RATE = 0.1
"""The stand-in's arm and platform velocities [rad/s, m/s]."""

DISC_DIAMETER = 20.0
"""Apparent diameter [px] of the discs drawn for the spheres."""


def target_image(scenario: Scenario) -> np.ndarray:
    """An RGB image with the two spheres' colours as discs at ``target.xi0``. Shape (H, W, 3)."""
    camera = scenario.camera.intrinsics()
    image = np.full((camera.height, camera.width, 3), 128, dtype=np.uint8)
    u, v1, v2 = scenario.target.xi0
    for v, hue in zip((v1, v2), SPHERE_HUES, strict=True):
        col, row = camera.to_pixel([u, v])
        colour = [round(255 * c) for c in sphere_rgba(hue)[:3]]
        cv2.circle(image, (round(col), round(row)), round(DISC_DIAMETER / 2), colour, -1)
    return image


class StandInRobot:
    """The drivers of a robot, in lockstep with the node (module docstring).

    Args:
        scenario: Gives the robot (its arm joints, home posture) and camera.
        start: The clock's first value [s].
        period: The clock's step [s].
    """

    def __init__(self, scenario: Scenario, start: float = 0.0, period: float = 0.01) -> None:
        robot = scenario.robot.build(scenario.camera.intrinsics())
        self.names, self.arm = tuple(robot.arm_joint_names), robot.home_arm
        self.camera, self.image = robot.camera, target_image(scenario)
        self.node = rclpy.create_node("stand_in_robot")
        publisher = self.node.create_publisher
        self.clock = publisher(Clock, "/clock", 10)
        self.joints = publisher(JointState, "joint_states", 10)
        self.odom = publisher(messages.Odometry, "odom", 10)
        self.estop = publisher(Bool, "estop", 10)
        self.images = publisher(Image, "camera/image_raw", 5)
        self.info = publisher(CameraInfo, "camera/camera_info", 5)
        self.commands: list[tuple[float, np.ndarray]] = []
        self.latencies: list[tuple[float, bool]] = []  # [s] wall clock, with an image or not
        self.node.create_subscription(Twist, "cmd_vel", self._on_cmd, 50)
        arm_topic = "arm_controller/commands"
        self.node.create_subscription(Float64MultiArray, arm_topic, lambda _: None, 50)
        self.t, self.period = start, period
        self._new, self._sent, self._with_image = False, 0.0, False

    def _on_cmd(self, message: Twist) -> None:
        self.commands.append((self.t, np.array([message.linear.x, message.angular.z])))
        if not self._new:
            self.latencies.append((time.perf_counter() - self._sent, self._with_image))
        self._new = True

    def spin(self, seconds: float) -> None:
        """Take in messages for ``seconds`` of wall-clock time."""
        end = time.perf_counter() + seconds
        while time.perf_counter() < end:
            rclpy.spin_once(self.node, timeout_sec=0.01)

    def tick(
        self, joints: bool = True, odom: bool = True, bad: bool = False, image: bool = False
    ) -> None:
        """One period: the readings (``bad``: a NaN joint rate), ``/clock``; wait for the answer.

        Waits up to 1 s of wall-clock time for a ``cmd_vel``.
        """
        self.t = round(self.t + self.period, 9)
        stamp = rclpy.time.Time(seconds=self.t).to_msg()
        t = messages.seconds(stamp)
        self._sent, self._with_image = time.perf_counter(), image
        if joints:
            rates = [float("nan") if bad else RATE] + [RATE] * (len(self.names) - 1)
            self.joints.publish(messages.joint_state(t, self.names, self.arm, rates))
        if odom:
            self.odom.publish(
                messages.odometry(t, [0.0, 0.0, 0.0], [RATE, RATE], frames.ODOM,
                                  frames.DRIVE_FOOTPRINT)
            )  # fmt: skip
        if image:
            self.info.publish(messages.camera_info(t, self.camera, frames.CAMERA_OPTICAL))
            self.images.publish(messages.image(t, self.image, frames.CAMERA_OPTICAL))
        self._new = False
        self.clock.publish(Clock(clock=stamp))
        end = time.perf_counter() + 1.0
        while not self._new and time.perf_counter() < end:
            rclpy.spin_once(self.node, timeout_sec=0.01)

    def since(self, t: float) -> list[np.ndarray]:
        """The platform commands ``[u, omega]`` received at ticks from ``t`` [s] on."""
        return [command for stamp, command in self.commands if stamp >= t - 1e-9]
