"""The ROS 2 node that runs :class:`pbvs_pin.Controller` on a robot.

Every control period (``controller.rate``; on the node's clock, which follows ``/clock``
with ``use_sim_time``) the node steps the public controller with what arrived since the
previous step, and publishes its velocity references. Topics (relative names, so a namespace
or a remap moves them):

- subscribed: ``joint_states`` (``sensor_msgs/JointState``: arm positions and rates, by
  name), ``odom`` (``nav_msgs/Odometry``: platform pose and velocity), ``scan``
  (``sensor_msgs/LaserScan``: the nearest obstacle ``(d, alpha)``), ``camera/image_raw``
  (``sensor_msgs/Image``: the detector finds the spheres; ``header.stamp`` is the capture
  time), ``camera/camera_info`` (``sensor_msgs/CameraInfo``: checked against the
  controller's intrinsics), ``estop`` (``std_msgs/Bool``: true stops until false);
- published: ``cmd_vel`` (``geometry_msgs/Twist``: platform velocity references),
  ``arm_controller/commands`` (``std_msgs/Float64MultiArray``: arm rates in the order of
  the ``arm_joints`` parameter), ``diagnostics`` (``diagnostic_msgs/DiagnosticArray``:
  feature error, seen, lost, frame age, saturation, or why the commands are zero).

With the ``wait_for_readings`` parameter (for a simulated robot in lockstep on ``/clock``),
a step whose ``joint_states`` and ``odom`` are not yet stamped with its time runs when they
come, instead of on the readings of the period before.

Safety: the published commands are exactly zero at the next control step (within one
period) when ``joint_states`` or ``odom`` is older than ``sensor_timeout`` [s] (or never
came), when the e-stop is set, after bad input (the project's error is logged; no callback
raises; the topic's next good message clears it), and when the node stops (SIGINT, SIGTERM):
it then publishes zero commands before it leaves.
"""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image, JointState, LaserScan
from std_msgs.msg import Bool, Float64MultiArray

from pbvs_pin.control.bounds import MAX_STEP_GAP
from pbvs_pin.controller import Controller
from pbvs_pin.exceptions import GainError, PbvsError
from pbvs_pin.interrupts import interrupted_in_compiled_code
from pbvs_pin.perception.camera_frame import CameraFrame
from pbvs_pin.perception.detection import detector_from
from pbvs_pin.ros import messages
from pbvs_pin.sim.scenario import Scenario

SENSOR_TIMEOUT = 0.05
"""Default ``sensor_timeout`` [s]: ``joint_states`` or ``odom`` older than this is stale."""

WAKE = 0.05
"""Longest wait [s] of wall-clock time inside ROS, so that SIGINT and SIGTERM are handled.

It does not pace the steps: the step's timer on ``/clock`` wakes the executor. (Experiment 2
across processes took the same 3.7-4.0 s for 6 simulated seconds with 0.005, 0.05 and 0.5 s.
An earlier slowness blamed on this wait was messages lost on the transport: ``fastdds.xml``.)"""

STAMP_TOLERANCE = 1e-6
"""Difference [s] below which a reading's stamp is the clock's time (seconds and
nanoseconds summed two ways differ in the last bits)."""

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""The signals that stop the node (zero commands first)."""

STOP_REPEATS = 3
"""Zero commands published when the node stops (one may be lost)."""


def arm_order(names: list[str], arm_joints: tuple[str, ...]) -> np.ndarray:
    """Indices into the controller's arm joints of the names of ``arm_joints`` parameter.

    Raises:
        GainError: If ``names`` is not an ordering of the arm's joints.
    """
    if sorted(names) != sorted(arm_joints):
        raise GainError(
            f"arm_joints: expected an ordering of the arm's joints {list(arm_joints)}, got "
            f"{names}", "arm_joints",
        )  # fmt: skip
    return np.array([arm_joints.index(name) for name in names], dtype=int)


def scenario_keys(node: Node) -> dict[str, object]:
    """The scenario keys given as ROS parameters at start, with their values.

    A scenario key is a dotted name, e.g. ``estimator.hold``.
    """
    names = node.list_parameters([], 0).names
    return {
        name: node.get_parameter(name).value
        for name in names
        if "." in name and not name.startswith("qos_overrides.")
    }


def frame_of(message: Image, detector, camera, diameter: float) -> CameraFrame:
    """The frame of an image: the detector's spheres, stamped with ``header.stamp``.

    Args:
        message: The image (``rgb8`` or ``bgr8``).
        detector: Finds the spheres (:func:`pbvs_pin.perception.detection.detector_from`).
        camera: The controller's intrinsics.
        diameter: The spheres' diameter [m].

    Raises:
        ControlInputError: If the image's encoding or size is not one the node reads.
    """
    capture = messages.seconds(message.header.stamp)
    points, diameters, visible = detector.detect(messages.image_array(message))
    if not visible:
        return CameraFrame.not_visible(capture)
    return CameraFrame.from_diameters(capture, points, diameters, camera, diameter)


def step_inputs(model, joints: tuple, odom: tuple, frames: list[CameraFrame], t: float) -> tuple:
    """What the controller steps on at ``t`` [s], from the newest readings.

    Args:
        model: The controller's robot model.
        joints: Arm positions and rates, shape (n_arm,) each (:func:`messages.arm_reading`).
        odom: Platform pose and velocity (:func:`messages.platform_reading`).
        frames: The frames not used yet, oldest first.
        t: The step's time [s].

    Returns:
        ``q`` (shape (nq,)), ``v`` (shape (n,)), the newest frame captured by ``t`` (None),
        and the frames captured after ``t``, kept for a later step.
    """
    arm, arm_rates = joints
    planar, base = odom
    q = messages.configuration(model, planar, arm)
    v = np.concatenate([base, arm_rates])
    ready = [f for f in frames if f.capture_time <= t]
    return q, v, ready[-1] if ready else None, [f for f in frames if f.capture_time > t]


class ControlNode(Node):
    """The controller as a ROS 2 node (module docstring).

    Parameters (ROS): ``arm_joints`` (string array, the order of the arm command; the arm's
    joints by default), ``sensor_timeout`` [s], ``wait_for_readings`` (bool), ``use_sim_time``,
    and any scenario key by its dotted name (``-p estimator.hold:=0.5``), applied to the
    scenario at start.

    Args:
        scenario: Gives the robot, the controller's settings and the detector
            (``camera.detector``).
        parameter_overrides: ROS parameters set at start (e.g. ``use_sim_time``).
        announce: Say on stderr when the controller's kernels are compiled.

    Raises:
        ScenarioError: If a scenario key given as a parameter is not one, or its value is bad.
    """

    def __init__(
        self,
        scenario: Scenario,
        parameter_overrides: list | None = None,
        announce: bool = False,
    ) -> None:
        super().__init__(
            "pbvs_pin_controller",
            parameter_overrides=parameter_overrides or [],
            automatically_declare_parameters_from_overrides=True,
        )
        keys = scenario_keys(self)
        scenario = scenario.with_values(**keys) if keys else scenario
        self.scenario = scenario
        self.controller = Controller.from_scenario(scenario, announce=announce)
        model = self.controller.model
        self.model, self.n_base = model, model.n_base
        self.arm_joints = tuple(model.arm_joint_names)
        names = self._parameter("arm_joints", list(self.arm_joints))
        self.order = arm_order(list(names), self.arm_joints)
        self.sensor_timeout = float(self._parameter("sensor_timeout", SENSOR_TIMEOUT))
        self.wait_for_readings = bool(self._parameter("wait_for_readings", False))
        self._stamps = {"joint_states": -np.inf, "odom": -np.inf}  # header stamps [s]
        self._due: float | None = None  # a step waiting for its readings
        self.detector = detector_from(scenario.camera.detector, model.camera)
        self.diameter = scenario.target.diameter
        self._joints: tuple[float, np.ndarray, np.ndarray] | None = None  # (arrival, pos, vel)
        self._odom: tuple[float, np.ndarray, np.ndarray] | None = None
        self._frames: list[CameraFrame] = []
        self._laser: tuple[float, float] | None = None
        self._camera_problem = "no camera_info yet"
        self._bad: dict[str, str] = {}
        self._estop = False
        self._t = -np.inf
        self.steps = 0
        self.cmd_vel = self.create_publisher(Twist, "cmd_vel", 10)
        self.arm_commands = self.create_publisher(Float64MultiArray, "arm_controller/commands", 10)
        self.diagnostics = self.create_publisher(DiagnosticArray, "diagnostics", 10)
        self.create_subscription(JointState, "joint_states", self._on_joints, 10)
        self.create_subscription(Odometry, "odom", self._on_odom, 10)
        self.create_subscription(LaserScan, "scan", self._on_scan, 10)
        self.create_subscription(Image, "camera/image_raw", self._on_image, 5)
        self.create_subscription(CameraInfo, "camera/camera_info", self._on_camera_info, 5)
        self.create_subscription(Bool, "estop", self._on_estop, 10)
        self.create_timer(self.controller.period, self.step)

    def _parameter(self, name: str, default: object) -> object:
        """A ROS parameter's value, declared with ``default`` unless given at start."""
        if self.has_parameter(name):
            return self.get_parameter(name).value
        return self.declare_parameter(name, default).value

    def now(self) -> float:
        """The node's time [s] (``/clock`` with ``use_sim_time``)."""
        return self.get_clock().now().nanoseconds * 1e-9

    @contextmanager
    def _guard(self, topic: str) -> Iterator[None]:
        """Log any error of a callback instead of raising it; mark the topic as bad."""
        try:
            yield
            self._bad.pop(topic, None)
        except PbvsError as err:
            self._bad[topic] = str(err)
            self.get_logger().error(f"{topic}: {err}", throttle_duration_sec=1.0)
        except Exception as err:  # a callback never raises: a stop, not a crash
            self._bad[topic] = f"{type(err).__name__}: {err}"
            self.get_logger().error(f"{topic}: {self._bad[topic]}", throttle_duration_sec=1.0)

    def _on_joints(self, message: JointState) -> None:
        with self._guard("joint_states"):
            self._joints = (self.now(), *messages.arm_reading(message, self.arm_joints))
            self._arrived("joint_states", message)

    def _on_odom(self, message: Odometry) -> None:
        with self._guard("odom"):
            self._odom = (self.now(), *messages.platform_reading(message, self.n_base))
            self._arrived("odom", message)

    def _arrived(self, topic: str, message: JointState | Odometry) -> None:
        """Note a reading's stamp; run the step that waits for it once both are there."""
        self._stamps[topic] = messages.seconds(message.header.stamp)
        if self._due is not None and min(self._stamps.values()) >= self._due - STAMP_TOLERANCE:
            self.step()

    def _waits(self, t: float) -> bool:
        """With ``wait_for_readings``: the step at ``t`` waits for readings stamped ``t``."""
        late = self.wait_for_readings and min(self._stamps.values()) < t - STAMP_TOLERANCE
        self._due = t if late else None
        return late

    def _on_scan(self, message: LaserScan) -> None:
        with self._guard("scan"):
            self._laser = messages.nearest_return(message)

    def _on_estop(self, message: Bool) -> None:
        self._estop = bool(message.data)

    def _on_camera_info(self, message: CameraInfo) -> None:
        with self._guard("camera/camera_info"):
            self._camera_problem = "camera_info does not match the controller's camera"
            messages.check_camera_info(message, self.model.camera)
            self._camera_problem = ""

    def _on_image(self, message: Image) -> None:
        """Detect the spheres; the frame is stamped with the image's capture time."""
        with self._guard("camera/image_raw"):
            if self._camera_problem:
                return
            self._frames.append(frame_of(message, self.detector, self.model.camera, self.diameter))

    def stop_reason(self, t: float) -> str:
        """Why the commands are zero at ``t`` [s]; empty when the controller runs."""
        if self._estop:
            return "e-stop"
        if self._bad:
            topic = next(iter(self._bad))
            return f"bad input on {topic}: {self._bad[topic]}"
        for topic, reading in (("joint_states", self._joints), ("odom", self._odom)):
            if reading is None:
                return f"no {topic} yet"
            if t - reading[0] > self.sensor_timeout:
                return f"{topic} stale ({t - reading[0]:.3f} s old)"
        return ""

    def step(self) -> None:
        """One control step: the controller's command, or zero (module docstring)."""
        t = self.now()
        try:
            if t == self._t:
                return  # the clock did not move
            jumped = np.isfinite(self._t) and t - self._t > MAX_STEP_GAP
            if t < self._t or jumped:  # a simulation restarted, or a pause: start afresh
                # (the controller refuses a step further than MAX_STEP_GAP after the last)
                self.get_logger().warning(f"the clock jumped from {self._t} s to {t} s")
                self.controller.reset()
                self._joints = self._odom = self._laser = None
                self._frames, self._t = [], -np.inf
                self._stamps = dict.fromkeys(self._stamps, -np.inf)
            reason = self.stop_reason(t)
            if reason:
                self.publish_zero(t, reason)
                return
            if self._waits(t):
                return
            command = self._controller_step(t)
        except Exception as err:  # a callback never raises: zero commands and the error logged
            self.get_logger().error(f"control step: {err}", throttle_duration_sec=1.0)
            self.publish_zero(t, f"control step: {err}")
            return
        self._t = t
        self.steps += 1
        self._publish(command.v_ref)
        output, _ = self.controller.diagnostics()
        error = command.error
        values = {
            "t": round(t, 6),
            "error_px": [round(float(e), 3) for e in error],
            "max_abs_error_px": round(float(np.max(np.abs(error))), 3) if command.seen else "nan",
            "seen": command.seen,
            "lost": command.lost,
            "frame_age_s": round(command.frame_age, 4),
            "saturated": bool(output.saturated),
            "rejected": command.rejected,
        }
        self.diagnostics.publish(messages.diagnostics(t, self.get_name(), values, True))

    def _controller_step(self, t: float):
        """Step the controller with the newest readings, frame and scan."""
        q, v, frame, self._frames = step_inputs(
            self.model, self._joints[1:], self._odom[1:], self._frames, t
        )
        laser, self._laser = self._laser, None
        return self.controller.step(t, q, v, frame, laser)

    def _publish(self, v_ref: np.ndarray) -> None:
        self.cmd_vel.publish(messages.twist(v_ref[: self.n_base]))
        self.arm_commands.publish(messages.arm_command(v_ref[self.n_base :][self.order]))

    def publish_zero(self, t: float, reason: str) -> None:
        """Zero commands, and the reason on the diagnostics topic."""
        self._publish(np.zeros(self.model.n))
        values = {"t": round(t, 6), "stopped": reason}
        self.diagnostics.publish(messages.diagnostics(t, self.get_name(), values, False))


def spin(node: ControlNode) -> None:
    """Run the node until SIGINT or SIGTERM, then publish zero commands and leave."""
    # both raise KeyboardInterrupt (SIGINT too: a shell's background job starts ignoring it)
    previous = [signal.signal(sig, signal.default_int_handler) for sig in STOP_SIGNALS]
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        while rclpy.ok():  # wakes at least every WAKE s, so that Python handles a signal
            executor.spin_once(timeout_sec=WAKE)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except SystemError as err:  # Ctrl-C inside a compiled kernel
        if not interrupted_in_compiled_code(err):
            raise
    finally:
        for sig, handler in zip(STOP_SIGNALS, previous, strict=True):
            signal.signal(sig, handler)
        executor.remove_node(node)
        for _ in range(STOP_REPEATS):
            node.publish_zero(node.now(), "node stopped")
