"""A simulated robot behind the topics of a real one: the plant, its sensors and its camera.

:class:`SimRobot` runs a scenario's plant (:func:`pbvs_pin.sim.setup.build`: the Pinocchio or
MuJoCo plant, the target's motion, the obstacles) with the rendered camera, and speaks ROS 2 as
a robot's drivers do. Every control period ``T`` of simulated time it publishes ``/clock``,
``joint_states`` and ``odom`` (the encoders and odometry of
:class:`pbvs_pin.sim.sensing.Sensing`, with the scenario's quantisation and noise), ``scan`` at
the laser's rate, and ``camera/image_raw`` with ``camera/camera_info`` at the camera's rate: an
image drawn at its capture time ``t_c`` (its ``header.stamp``), published at
``t_c + camera.latency``. The detection is the node's. It applies the newest ``cmd_vel`` and
``arm_controller/commands`` to the plant for ``T``; a command older than ``command_timeout``
[s] (or none) is replaced by zero, so a controller that dies stops the robot.

Simulated time runs at ``rate_factor`` times the wall clock (or slower, when a step takes
longer); in lockstep, each step also waits for the controller's answer to its readings, so
that a slow machine slows the simulation instead of delaying the commands.
Not simulated here: the camera's faults (drops, occlusions, jitter) and TF.
"""

from __future__ import annotations

import json
import time as wallclock
from collections import deque
from pathlib import Path

import numpy as np
from geometry_msgs.msg import Twist
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, JointState, LaserScan
from std_msgs.msg import Float64MultiArray

from pbvs_pin.model import frames
from pbvs_pin.ros import messages
from pbvs_pin.ros.tf import TF_TYPE, tf_message
from pbvs_pin.sim.obstacles import clearance, footprint_points
from pbvs_pin.sim.scenario import Scenario
from pbvs_pin.sim.sensing import Sensing, planar_pose
from pbvs_pin.sim.setup import build

COMMAND_TIMEOUT = 0.1
"""Default age [s] of simulated time past which a command is replaced by zero."""

DISCOVERY_SETTLE = 0.5
"""Wall-clock time [s] given to the discovery of the other topics once a controller is seen."""

SUMMARY_RATE = 10.0
"""Rows per simulated second [Hz] of the true feature error in the summary."""


Received = tuple[float, np.ndarray] | None
"""A command and the simulated time [s] it arrived at; None before the first."""


def applied_command(
    t: float, base: Received, arm: Received, timeout: float, n_base: int, n: int
) -> np.ndarray:
    """The velocity references a robot applies at ``t`` [s], shape (n,).

    The newest platform and arm commands; each is replaced by zero when it is older than
    ``timeout`` [s], has not come, or is not finite (the robot's own command timeout).
    """
    v_ref = np.zeros(n)
    for received, part in ((base, slice(0, n_base)), (arm, slice(n_base, n))):
        if received is not None and t - received[0] <= timeout:
            if np.all(np.isfinite(received[1])):
                v_ref[part] = received[1]
    return v_ref


class SimRobot(Node):
    """The scenario's robot as a ROS 2 robot (module docstring).

    Args:
        scenario: The scenario; its camera is drawn (``camera.model = "rendered"`` is set).
        rate_factor: Simulated seconds per wall-clock second (at most).
        command_timeout: Age [s] past which a command counts as none.
        lockstep: When positive, each step also waits, up to this long [s] of wall-clock time,
            for a platform and an arm command received after its readings were published
            (simulated time then runs only as fast as the controller answers).
    """

    def __init__(
        self,
        scenario: Scenario,
        rate_factor: float = 1.0,
        command_timeout: float = COMMAND_TIMEOUT,
        lockstep: float = 0.0,
    ) -> None:
        super().__init__("pbvs_pin_sim")
        if scenario.camera.model != "rendered":
            scenario = scenario.with_values(**{"camera.model": "rendered"})
        self.scenario, self.rate_factor = scenario, rate_factor
        self.command_timeout, self.lockstep = command_timeout, lockstep
        self.setup = setup = build(scenario)
        self.sensing = Sensing(setup)
        self.robot, self.model = setup.robot, setup.model
        self.n_base, self.n_arm = self.model.n_base, self.model.n_arm
        self.period = 1.0 / scenario.controller.rate
        self.substeps = max(1, round(self.period / scenario.simulation.plant_dt))
        self.clock = self.create_publisher(Clock, "/clock", 10)
        self.joints = self.create_publisher(JointState, "joint_states", 10)
        self.odom = self.create_publisher(messages.Odometry, "odom", 10)
        self.scan = self.create_publisher(LaserScan, "scan", 10)
        self.image = self.create_publisher(Image, "camera/image_raw", 5)
        self.info = self.create_publisher(CameraInfo, "camera/camera_info", 5)
        self.create_subscription(Twist, "cmd_vel", self._on_cmd_vel, 10)
        self.create_subscription(Float64MultiArray, "arm_controller/commands", self._on_arm, 10)
        self.t = 0.0
        self.base_command: tuple[float, np.ndarray] | None = None  # (arrival, velocities)
        self.arm_command: tuple[float, np.ndarray] | None = None
        self.commands_received = 0
        self.fresh_commands = 0
        self.bag = None
        self.in_flight: deque[tuple[float, Image]] = deque()  # (delivery time, image)
        self.footprint = footprint_points(scenario.platform.length, scenario.platform.width)
        self.rows: dict[str, list] = {"t": [], "error": [], "v_ref": [], "clearance": [], "arm": []}

    def record(self, path: str) -> None:
        """Write every message sent and received (and the node's diagnostics) into a bag.

        Raises:
            OutputError: If ``path`` exists.
        """
        from diagnostic_msgs.msg import DiagnosticArray

        from pbvs_pin.ros.bag import BagRecorder

        self.bag = BagRecorder(path)
        self.create_subscription(DiagnosticArray, "diagnostics", self._on_other, 10)

    def send(self, publisher, message: object) -> None:
        """Publish, and record in the bag at the simulated time."""
        publisher.publish(message)
        if self.bag is not None:
            self.bag.write(publisher.topic_name, message, self.t)

    def _on_other(self, message: object) -> None:
        if self.bag is not None:
            self.bag.write("/diagnostics", message, self.t)

    def _on_cmd_vel(self, message: Twist) -> None:
        if self.bag is not None:
            self.bag.write("/cmd_vel", message, self.t)
        self.base_command = (self.t, messages.twist_velocity(message, self.n_base))
        self.commands_received += 1

    def _on_arm(self, message: Float64MultiArray) -> None:
        if self.bag is not None:
            self.bag.write("/arm_controller/commands", message, self.t)
        data = np.asarray(message.data, dtype=float)
        if data.shape == (self.n_arm,) and np.all(np.isfinite(data)):
            self.arm_command = (self.t, data)
        else:
            self.get_logger().error(
                f"arm_controller/commands: expected {self.n_arm} finite rates, got "
                f"{data.tolist()}; the arm stops", throttle_duration_sec=1.0,
            )  # fmt: skip
            self.arm_command = None

    def _answered(self) -> bool:
        """Both commands arrived at this step (after its readings were published)."""
        return all(c is not None and c[0] == self.t for c in (self.base_command, self.arm_command))

    def _wait(self, executor: SingleThreadedExecutor, deadline: float) -> None:
        """Take in commands until the wall-clock ``deadline`` and, in lockstep, the answer."""
        executor.spin_once(timeout_sec=0.0)
        while (remaining := deadline - wallclock.perf_counter()) > 0:
            executor.spin_once(timeout_sec=remaining)
        if self.lockstep > 0:
            give_up = wallclock.perf_counter() + self.lockstep
            while not self._answered() and (remaining := give_up - wallclock.perf_counter()) > 0:
                executor.spin_once(timeout_sec=remaining)

    def command(self) -> np.ndarray:
        """The velocity references applied now (:func:`applied_command`)."""
        return applied_command(
            self.t,
            self.base_command,
            self.arm_command,
            self.command_timeout,
            self.n_base,
            self.model.n,
        )

    def publish_sensors(self, step: int) -> None:
        """The encoders, odometry, the scan and image when due, then ``/clock``."""
        t, setup, sensing = self.t, self.setup, self.sensing
        sensing.read(t)
        q, v = sensing.q, sensing.v
        arm = self.model.arm_positions(q)
        self.send(
            self.joints, messages.joint_state(t, self.model.arm_joint_names, arm, v[self.n_base :])
        )
        planar = planar_pose(self.model, q)
        self.send(
            self.odom,
            messages.odometry(t, planar, v[: self.n_base], frames.ODOM, frames.DRIVE_FOOTPRINT),
        )
        scenario = self.scenario
        if setup.obstacles and step % max(1, round(1.0 / (scenario.laser.rate * self.period))) == 0:
            laser = setup.laser
            ranges = sensing.laser_ranges()  # as simulate() reads it: from the laser frame
            self.send(
                self.scan,
                messages.laser_scan(t, ranges, laser.field_of_view, laser.max_range, frames.LASER),
            )
        sensor = setup.sensor
        if sensor.capture_due(t):
            sensor.next_capture += sensor.period
            pose = self.robot.camera_pose(setup.plant.q)
            rgb = sensor.renderer.draw(t, pose, setup.target.centres(t))
            self.in_flight.append((t + scenario.camera.delivery_latency,
                                   messages.image(t, rgb, frames.CAMERA_OPTICAL)))  # fmt: skip
        while self.in_flight and self.in_flight[0][0] <= t + 1e-9:
            image = self.in_flight.popleft()[1]
            capture = messages.seconds(image.header.stamp)
            info = messages.camera_info(capture, self.model.camera, frames.CAMERA_OPTICAL)
            self.send(self.info, info)
            self.send(self.image, image)
        if self.bag is not None:  # TF into the bag only: ROS from pip cannot publish it
            tf = tf_message(t, self.robot, setup.plant.q, setup.target.midpoint(t))
            self.bag.write_serialised("/tf", TF_TYPE, tf, t)
        self.send(self.clock, Clock(clock=messages.stamp(t)))  # last: the readings of t are out

    def true_error(self) -> np.ndarray:
        """``xi - xi_d`` [px] of the true camera pose and target (eq. 2). Shape (r,)."""
        setup = self.setup
        pose = self.robot.camera_pose(setup.plant.q)
        points, _ = self.robot.camera.project_world(pose, setup.target.centres(self.t))
        return points.reshape(-1)[setup.features.rows] - setup.xi_d

    def true_clearance(self) -> float | None:
        """The platform's true clearance to the scenario's obstacles [m]; None without any."""
        pose = planar_pose(self.robot, self.setup.plant.q)
        distance = clearance(self.setup.obstacles, self.footprint, *pose)
        return round(distance, 5) if np.isfinite(distance) else None

    def wait_for_controller(self, timeout: float) -> bool:
        """Wait for a controller node, up to ``timeout`` [s] of wall-clock time.

        A controller is a node that reads ``joint_states`` and publishes ``cmd_vel``. Returns
        whether one came.
        """
        executor = SingleThreadedExecutor()
        executor.add_node(self)
        deadline = wallclock.perf_counter() + timeout
        try:
            while wallclock.perf_counter() < deadline:
                if self.count_publishers("cmd_vel") and self.joints.get_subscription_count():
                    executor.spin_once(timeout_sec=DISCOVERY_SETTLE)
                    return True
                executor.spin_once(timeout_sec=0.05)
        finally:
            executor.remove_node(self)
        return False

    def run(self, duration: float) -> dict:
        """Simulate ``duration`` [s]; return the summary (true feature error, commands)."""
        executor = SingleThreadedExecutor()
        executor.add_node(self)
        started = wallclock.perf_counter()
        log_every = max(1, round(1.0 / (SUMMARY_RATE * self.period)))
        steps = round(duration / self.period)
        fresh = 0  # steps whose platform command answered this step's readings
        try:
            for step in range(steps):
                self.t = step * self.period
                self.publish_sensors(step)
                self._wait(executor, started + (self.t + self.period) / self.rate_factor)
                v_ref = self.command()
                fresh += self.base_command is not None and self.base_command[0] == self.t
                if step % log_every == 0:
                    self.rows["t"].append(round(self.t, 6))
                    self.rows["error"].append(self.true_error().round(4).tolist())
                    self.rows["v_ref"].append(v_ref.round(6).tolist())
                    self.rows["clearance"].append(self.true_clearance())
                    arm = self.model.arm_positions(self.setup.plant.q)
                    self.rows["arm"].append(arm.round(6).tolist())
                for _ in range(self.substeps):
                    self.setup.plant.step(v_ref)
        finally:
            executor.remove_node(self)
            if self.bag is not None:
                self.bag.close()
        self.fresh_commands = fresh
        return self.summary(wallclock.perf_counter() - started)

    def summary(self, wall: float) -> dict:
        """What the run did, at :data:`SUMMARY_RATE`, and counts.

        The true feature error [px], the commands, the platform's clearance [m] (None without
        obstacles) and the arm's positions, with the posture target ``theta_d`` of eq. (19).
        """
        return {
            "scenario": self.scenario.name,
            "posture_target": np.asarray(self.setup.posture_target).round(6).tolist(),
            "arm_continuous": [bool(c) for c in self.model.arm_continuous],
            "simulated_s": round(self.t + self.period, 6),
            "wall_s": round(wall, 3),
            "commands_received": self.commands_received,
            "fresh_commands": self.fresh_commands,
            **self.rows,
        }


def write_summary(summary: dict, path: str | Path) -> None:
    """The summary as JSON."""
    Path(path).write_text(json.dumps(summary))
