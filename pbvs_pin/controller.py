"""The controller a robot runs, and the one :func:`pbvs_pin.simulate` validates.

:class:`Controller` is the paper's control chain of Fig. 3, stepped by a loop of your own (a
real robot's driver, or a simulator other than :func:`pbvs_pin.simulate`, which steps this
same class). At every control step it takes what a robot has:

- the time ``t`` [s] on the controller's clock, increasing from step to step, at the rate it
  expects (``controller.rate``, 100 Hz by default; another interval is used as measured);
- the encoders and odometry as a Pinocchio configuration ``q`` (the platform's pose is the
  drive-axle midpoint on the floor, ``drive_footprint``, in the odometry's fixed frame) and
  the actuated velocities ``v = [u [m/s], omega [rad/s], arm joint rates]``;
- a camera frame when one arrived (:class:`~pbvs_pin.perception.camera_frame.CameraFrame`: its
  capture time, and the target's image points and depths, or "not visible"); None when none
  arrived;
- a laser reading ``(d [m], alpha [rad])`` of the nearest obstacle when a scan arrived.

and returns the velocity references for the robot's own velocity loops (:class:`ServoCommand`).
Inside, in the order of the paper's Fig. 3:

1. the encoder history places each frame at the configuration of its capture instant
   (:mod:`pbvs_pin.control.encoders`);
2. the frame updates the target's world position and the alpha-beta velocity filter
   (eq. 30), and is brought up to now along eq. (3) (prediction, hold and smoothing,
   :mod:`pbvs_pin.control.tracking`);
3. features ``xi`` and ``J``, ``J_o`` of eq. (3), secondary objectives ``Lambda`` (eq. 16),
   the upright row and the loop-gain net (:mod:`pbvs_pin.control.upright`) feed the kinematic
   controller of eq. (34), whose command ``u`` goes through the dynamic compensation of
   eq. (20), in one compiled call (:mod:`pbvs_pin.control.step`), for either law and whether
   or not anything is seen; a user's own objectives are evaluated in Python before that call
   and enter it as one input.

Bad input at run time: a wrong type or shape, a non-finite encoder value, a value beyond the
physical bounds of :mod:`pbvs_pin.control.bounds` in ``t``, ``q``, ``v`` or
``target_velocity``, time going backwards or a frame captured more than
:data:`~pbvs_pin.control.bounds.CLOCK_JITTER` after ``t`` raise the project's error naming the
argument, and leave the controller as it was. Each input is converted once, at this door, to
the float64 arrays the compiled step was compiled for (lists, integers, float32, read-only
and non-contiguous arrays alike). A frame older than the newest one, older than the encoder
history, or with non-finite or non-positive depths is not used (``ServoCommand.rejected`` says
why; a frame whose values are not usable counts as one that does not show the target); a
frame or a laser reading beyond the bounds, and a frame that fails the innovation gate of
:mod:`pbvs_pin.control.gating`, are dropped and counted (:attr:`Controller.counts`); a jump of
the odometry (a platform pose that the velocity limits cannot reach in one step) drops the
measurement, which was placed with the old odometry. ``v_ref`` is always finite and within
the velocity limits.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from pbvs_pin.compile_cache import announce_compiles
from pbvs_pin.control import bounds, layout
from pbvs_pin.control.encoders import TIME_TOLERANCE, EncoderHistory
from pbvs_pin.control.gating import FaultCounts, InnovationGate
from pbvs_pin.control.kinematic import ControlOutput
from pbvs_pin.control.odometry import OdometryJumps
from pbvs_pin.control.secondary import SecondaryObjective, user_objectives
from pbvs_pin.control.settings import (
    ControllerSettings,
    compensator,
    kinematic_law,
    loop_gain_margin,
    posture_target,
    secondary_objectives,
)
from pbvs_pin.control.step import FusedControlStep, split_objectives
from pbvs_pin.control.tracking import TargetTracker
from pbvs_pin.exceptions import ControlInputError, NonFiniteValue, ShapeError
from pbvs_pin.model.camera import MIN_DEPTH
from pbvs_pin.model.robot import UNIT_TOLERANCE, MobileManipulator
from pbvs_pin.perception.camera_frame import CameraFrame
from pbvs_pin.perception.estimation import velocity_filter
from pbvs_pin.perception.features import (
    FeatureSet,
    ImageMeasurement,
    TwoSphereFeatures,
    checked_feature_set,
)
from pbvs_pin.validation import as_array, as_instance, as_number, as_numbers

FLOAT64 = np.dtype(np.float64)
"""The dtype of the arrays the quick input checks accept as they are."""
LATENCY_RESOLUTION = 1e-6
"""The frames' latency is rounded to this [s] before it sets the loop-gain margin."""


@dataclass(slots=True)
class ServoCommand:
    """What one control step gives.

    Attributes:
        v_ref: Velocity references for the robot's velocity loops: platform ``[u [m/s], omega
            [rad/s]]`` then arm joint rates [rad/s or m/s], finite and within the velocity
            limits. Shape (n,). The compensation of a zero command (braking) when there is
            nothing to servo on.
        u: Kinematic command of eq. (34), same units. Shape (n,).
        error: Feature error ``xi - xi_d`` [px] of what was servoed on. Shape (r,); NaN when
            nothing was.
        target_velocity: The target velocity ``phat_dot`` used [m/s]. Shape (3,).
        seen: The step servoed on a measurement of the target or its prediction.
        lost: The newest frame did not show the target (or was not usable).
        predicting: What was servoed on is a prediction (``estimator.predict`` or the hold).
        frame_age: ``t`` minus the capture time of the newest measurement [s]; inf before
            the first.
        latency: The newest frame's age when it arrived [s]; NaN before the first.
        rejected: Why the frame or the laser reading given to this step was not used (not
            after the newest, out of the encoder history, beyond the bounds, failed the gate);
            empty when they were (or none was given).
        odometry_jumped: The platform pose jumped; the measurement was dropped.
        v2: ``V2 = |v - u|^2 / 2`` of eq. (22).
    """

    v_ref: np.ndarray
    u: np.ndarray
    error: np.ndarray
    target_velocity: np.ndarray
    seen: bool
    lost: bool
    predicting: bool
    frame_age: float
    latency: float
    rejected: str
    odometry_jumped: bool
    v2: float


class Controller:
    """The passivity-based visual servo controller, stepped by your own loop.

    Build it with typed settings (:class:`~pbvs_pin.control.settings.ControllerSettings`,
    whose sections are a scenario's, with the same defaults) or from a scenario::

        controller = Controller(robot, ControllerSettings(estimator=EstimatorSection(
            predict=True, hold=0.5)))
        controller = Controller.from_scenario(load_scenario("experiment1"), robot)

    It compiles its kernels (or loads them from Numba's cache) when it is built, saying so on
    stderr when a kernel really compiles (``announce``), so that its first step is as fast as
    the next.

    Args:
        robot: The controller's model of the robot; the camera intrinsics are the settings'.
        settings: The settings; the defaults when None.
        announce: Print a line on stderr before compiling the kernels.
        objectives: The user's own secondary objectives (any ``SecondaryObjective``, also of
            a built-in kind), added to the settings' in ``Lambda`` (eq. 16): each is called
            once a step, never while the controller is built; :meth:`reset` keeps them as
            they are (their own state is theirs to reset).
        features: Your own :class:`~pbvs_pin.perception.features.FeatureSet` (which
            coordinates of the frames' ``features.n_points`` points form ``xi``); None: the
            paper's ``[u1, v1, v2]`` of two spheres, with the settings' ``target.xi_d``.
        xi_d: The desired features of ``features`` [px], shape (r,); required with it.

    Raises:
        WrongType: If ``robot``, ``settings``, ``objectives`` or ``features`` is not one.
        GainError: If ``features`` has no valid rows or comes without ``xi_d``.
        ShapeError: If ``xi_d`` has not one entry per feature.

    Attributes:
        model: The controller's model of the robot (with the settings' intrinsics).
        settings: The settings.
        features: The feature set: the paper's two spheres unless you gave your own.
        xi_d: Desired features [px]. Shape (r,).
        posture_target: ``theta_d`` of eq. (19) [rad or m]. Shape (n_arm,).
        law: The kinematic controller's gains (eq. 34, or the IBVS baseline), which the
            compiled step packs.
        fused: The compiled step (:class:`~pbvs_pin.control.step.FusedControlStep`): the one
            path every step takes, seen or not, and the only copy of the step's state.
        compensator: The dynamic compensation's settings (eq. 20: rows, ``K_D``, ``tau``), which
            the compiled step packs; its ``step`` is the tests' reference, not run here.
        objectives: The secondary objectives: the settings' built-in ones, then the user's.
            The compiled step packs the built-in ones' gains and keeps their state (the
            obstacle impedance); their own ``contribution`` is the tests' reference, not run
            here. The others (the support objective, the user's) are called each step.
        user_objectives: The user's own objectives, as given.
        tracker: The newest measurement, prediction, hold and velocity filter.
        history: The encoder readings of the last ``settings.history`` seconds.
        counts: Frames and laser readings dropped or changed since the controller was built
            or reset (:class:`~pbvs_pin.control.gating.FaultCounts`).
    """

    def __init__(
        self,
        robot: MobileManipulator,
        settings: ControllerSettings | None = None,
        announce: bool = True,
        objectives: Sequence[SecondaryObjective] = (),
        features: FeatureSet | None = None,
        xi_d: npt.ArrayLike | None = None,
    ) -> None:
        robot = as_instance("robot", robot, MobileManipulator)
        given = user_objectives(objectives)
        self.user_objectives: tuple[SecondaryObjective, ...] = ()
        settings = ControllerSettings() if settings is None else settings
        settings = as_instance("settings", settings, ControllerSettings)
        camera = settings.camera.intrinsics()
        if robot.camera != camera:
            robot = copy.copy(robot)
            robot.camera = camera
        self.model, self.settings = robot, settings
        if features is None:
            self.features: FeatureSet = TwoSphereFeatures(settings.target.diameter)
            self.xi_d = np.asarray(settings.target.xi_d, dtype=float)
        else:
            self.features, self.xi_d = checked_feature_set(features, xi_d)
        self.posture_target = posture_target(settings, robot)
        self.period = settings.control_period
        self.history = EncoderHistory(robot.model, settings.history, self.period)
        self._exact = settings.estimator.kind == "exact"
        self._margin_slot = layout.slot(layout.Settings, "loop_gain_margin")
        self._nq = robot.model.nq
        self.reset()
        with announce_compiles(announce):
            self._warm_up()  # without the user's objectives: they see only real steps
        if given:
            self.user_objectives = given
            self.reset()

    @classmethod
    def from_scenario(
        cls,
        scenario: object,
        robot: MobileManipulator | None = None,
        announce: bool = True,
        objectives: Sequence[SecondaryObjective] = (),
        features: FeatureSet | None = None,
        xi_d: npt.ArrayLike | None = None,
    ) -> Controller:
        """The controller a simulation of ``scenario`` runs.

        Args:
            scenario: A :class:`~pbvs_pin.sim.scenario.Scenario`: gives the settings
                (:meth:`ControllerSettings.from_scenario`) and, unless ``robot`` is given, the
                robot, with the kinematic error of ``[model_error]``.
            robot: The controller's model of the robot, replacing the scenario's.
            announce: Print a line on stderr before compiling the kernels.
            objectives: The user's own secondary objectives (as for the constructor).
            features: Your own feature set (as for the constructor).
            xi_d: Its desired features [px] (as for the constructor).

        Raises:
            ScenarioError: If a value does not fit the robot.
        """
        if robot is None:
            robot = scenario.robot.build(scenario.camera.intrinsics())
            robot = robot.with_model_error(scenario.model_error.kinematic_scale)
        settings = ControllerSettings.from_scenario(scenario)
        return cls(robot, settings, announce, objectives, features, xi_d)

    def reset(self) -> None:
        """Forget every frame, reading and command: the state of a controller just built."""
        settings, model = self.settings, self.model
        self.latency = settings.camera.delivery_latency
        """The frames' age on arrival [s] that sets the loop-gain margin; the settings'
        camera latency until a frame arrives."""
        self.law = kinematic_law(settings, model, self.latency, self.features.size)
        self.compensator = compensator(settings, model)
        built_in = secondary_objectives(settings, model, self.posture_target)
        self.objectives = [*built_in, *self.user_objectives]
        compiled, in_python = split_objectives(built_in, self.user_objectives)
        spec = settings.estimator
        self.counts = FaultCounts()
        gate = InnovationGate(
            settings.camera.noise_px, model.camera.focal_px, settings.target.diameter,
            self.features.n_points, self.counts,
        )  # fmt: skip
        estimator = velocity_filter(spec.alpha, spec.beta, spec.process_noise)
        self.tracker = TargetTracker(
            model, estimator, spec.predict, spec.hold, spec.smoothing, gate
        )
        self.history.clear()
        self.fused = FusedControlStep(
            model, self.features, self.xi_d, self.law, self.compensator, compiled, in_python
        )
        self.laser = np.array([np.inf, 0.0])
        self._t = -np.inf
        limits = self.law.velocity_limits
        self._v_bound = tuple((bounds.VELOCITY_BOUND * np.asarray(limits)).tolist())
        self._odometry = OdometryJumps(model.model, (2 * limits[0], 2 * limits[model.n_base - 1]))
        self._newest_capture = -np.inf
        self._latency_seen = float("nan")

    def step(
        self,
        t: float,
        q: npt.ArrayLike,
        v: npt.ArrayLike,
        frame: CameraFrame | None = None,
        laser: tuple[float, float] | None = None,
        target_velocity: npt.ArrayLike | None = None,
    ) -> ServoCommand:
        """One control step.

        Args:
            t: Time [s] on the controller's clock; larger than the previous step's.
            q: Measured configuration (odometry and encoders). Shape (nq,).
            v: Measured actuated velocity ``[u, omega, arm rates]``. Shape (n,).
            frame: The camera frame that arrived since the previous step (the newest, if
                several did); None when none did. A frame whose target is not visible is
                ``CameraFrame.not_visible(capture_time)``.
            laser: Shortest laser range ``d`` [m] (``inf``: nothing in range) and its angle
                ``alpha`` [rad] (clockwise from the platform's forward axis) when a scan
                arrived; None keeps the previous reading.
            target_velocity: The target's velocity in the world [m/s], shape (3,), when you
                know it (required with ``estimator.kind = "exact"``); the filter's otherwise.

        Returns:
            The velocity references and what the step saw.

        Raises:
            WrongType: If an argument is not numbers (text, a bool, an object, a ragged list).
            ShapeError: If an array has the wrong shape.
            NonFiniteValue: If ``t``, ``q``, ``v``, ``laser`` or ``target_velocity`` is NaN
                or infinite (a range of ``inf`` is allowed).
            GainError: If a ``(cos, sin)`` pair of ``q`` is not unit.
            ControlInputError: If ``t`` is not after the previous step's or more than
                :data:`~pbvs_pin.control.bounds.MAX_STEP_GAP` after it; if an entry of ``q``,
                ``v`` or ``target_velocity`` is beyond its bound
                (:mod:`pbvs_pin.control.bounds`); if the frame is not a CameraFrame or was
                captured more than :data:`~pbvs_pin.control.bounds.CLOCK_JITTER` after ``t``;
                with ``estimator.kind = "exact"`` and no ``target_velocity``.
        """
        t, q, v, laser, given = self._checked(t, q, v, laser, target_velocity)
        capture, shown = self._frame_arrays(frame, t)
        dt = self.period if self._t == -np.inf else t - self._t
        if abs(dt - self.period) <= TIME_TOLERANCE:
            dt = self.period
        self._t = t
        jumped = self._odometry.jumped(q, dt)
        if jumped:
            self.history.clear()
            self.tracker.forget()
        self.history.record(t, q)
        rejected = ""
        if frame is not None:
            if frame.capture_time > t:  # within the clock's jitter: taken as captured now
                self.counts.clock_jitter += 1
            rejected = self._take(capture, shown, t, self._velocity(given))
        if laser is not None:
            fault = bounds.laser_fault(laser[0], laser[1])
            if fault:
                self.counts.laser_dropped += 1
                rejected = f"{rejected}; {fault}" if rejected else fault
            else:
                self.laser = laser
        velocity = self._velocity(given)
        u, v_ref, v2, error, seen = self._command(t, q, v, velocity, dt)
        tracker = self.tracker
        return ServoCommand(
            v_ref=v_ref.copy(), u=u.copy(), error=error, target_velocity=velocity,
            seen=seen, lost=tracker.lost, predicting=tracker.predicting,
            frame_age=t - tracker.capture_time, latency=self._latency_seen, rejected=rejected,
            odometry_jumped=jumped, v2=float(v2),
        )  # fmt: skip

    def diagnostics(self) -> tuple[ControlOutput, tuple[np.ndarray, np.ndarray] | None]:
        """The last step's kinematic output and ``(J, J_o)`` [px per unit] (None unseen)."""
        return self.fused.output()

    def _checked(self, t, q, v, laser, target_velocity) -> tuple:
        """The inputs as float arrays, checked (see :meth:`step`'s Raises)."""
        if type(t) is not float:
            t = as_number("t", t)  # text, bools and objects refused, naming t
        if not math.isfinite(t):
            raise NonFiniteValue("t")
        if not t > self._t:
            raise ControlInputError(f"t = {t:g} s is not after the previous step's ({self._t:g} s)")
        bounds.check_time_gap(t, self._t)
        model = self.model
        if not self._usable_as_given(q, v):  # the full checks name the argument at fault
            q, v = model.check_configuration(q), model.check_velocity(v)
            # one conversion: the C-ordered, writable float64 the kernels were compiled for
            q, v = np.require(q, FLOAT64, "CW"), np.require(v, FLOAT64, "CW")
        bounds.check_configuration_bounds(q)
        bounds.check_velocity_bounds(v, self._v_bound)
        if laser is not None:
            laser = as_numbers("laser", laser).copy()  # WrongType for text
            if laser.shape != (2,):
                raise ShapeError("laser", (2,), laser.shape)
            if math.isnan(laser[0]) or not math.isfinite(laser[1]):
                raise NonFiniteValue("laser")
        if target_velocity is not None:
            target_velocity = as_array("target_velocity", target_velocity, (3,)).copy()
            bounds.check_target_speed(target_velocity)
        elif self._exact:
            raise ControlInputError(
                'estimator.kind = "exact" needs target_velocity at every step; give it, or '
                'use kind = "alpha_beta"'
            )
        return t, q, v, laser, target_velocity

    def _usable_as_given(self, q: object, v: object) -> bool:
        """Whether ``q`` and ``v`` pass the quick checks of the 1 kHz path.

        They pass as C-ordered, writable float64 vectors of the right sizes, finite, with the
        configuration's angles unit.
        """
        return (
            _plain(q, self._nq)
            and _plain(v, self.model.n)
            and math.isfinite(sum(q.tolist()) + sum(v.tolist()))  # NaN or inf anywhere
            and pin.isNormalized(self.model.model, q, UNIT_TOLERANCE)
        )

    def _velocity(self, given: np.ndarray | None) -> np.ndarray:
        """``phat_dot``: the given velocity, or the filter's estimate."""
        return given if given is not None else self.tracker.estimator.velocity

    def _frame_arrays(
        self, frame: CameraFrame | None, t: float
    ) -> tuple[float, tuple[np.ndarray, np.ndarray] | None]:
        """A frame's capture time, and its points and depths (None: not visible).

        The points and depths are float arrays of the right shapes. A capture up to
        :data:`~pbvs_pin.control.bounds.CLOCK_JITTER` after ``t`` is taken as ``t``.
        The arrays are copies, C-ordered and writable (the kernels' own type).

        Raises:
            ControlInputError: If ``frame`` is not a CameraFrame or None, or was captured
                more than ``CLOCK_JITTER`` after ``t`` or at no finite time.
            ShapeError: If its points or depths have the wrong shape.
        """
        if frame is None:
            return -np.inf, None
        if not isinstance(frame, CameraFrame):
            raise ControlInputError(f"frame: expected a CameraFrame or None, got {frame!r}")
        capture = frame.capture_time
        if not -np.inf < capture <= t + bounds.CLOCK_JITTER:
            raise ControlInputError(
                f"frame captured at {capture!r} s, more than {bounds.CLOCK_JITTER:g} s after "
                f"now ({t:g} s); expected the capture time on the controller's clock"
            )
        if not frame.visible:
            return min(capture, t), None
        k = self.features.n_points
        points = np.array(frame.points, dtype=float)
        depths = np.array(frame.depths, dtype=float)
        if points.shape != (k, 2):
            raise ShapeError("frame.points", (k, 2), points.shape)
        if depths.shape != (k,):
            raise ShapeError("frame.depths", (k,), depths.shape)
        return min(capture, t), (points, depths)

    def _take(
        self,
        capture: float,
        shown: tuple[np.ndarray, np.ndarray] | None,
        t: float,
        velocity: np.ndarray,
    ) -> str:
        """Give the tracker a frame at its capture configuration; why not, if it is not used.

        Args:
            capture: The frame's capture time [s].
            shown: Its points [px] (k, 2) and depths [m] (k,); None when not visible.
            t: Now [s].
            velocity: ``phat_dot`` before the frame [m/s]. Shape (3,).
        """
        if not capture > self._newest_capture:
            newest = self._newest_capture
            return f"captured at {capture:g} s, not after the newest frame ({newest:g} s)"
        q_capture = self.history.at(capture)
        if q_capture is None:
            oldest, span = self.history.oldest_time, self.settings.history
            return (
                f"captured at {capture:g} s, before the encoder history ({oldest:g} s; "
                f"settings.history = {span:g} s)"
            )
        measurement, rejected = _usable(shown)
        if measurement is not None:
            camera = self.model.camera
            fault = bounds.frame_fault(*shown, camera.width, camera.height)
            if fault:
                self.counts.frames_out_of_bounds += 1
                return fault
        self._newest_capture = capture
        self._observe_latency(t - capture)
        reason = self.tracker.take(measurement, capture, q_capture, velocity)
        self._set_margin()
        return reason or rejected

    def _observe_latency(self, latency: float) -> None:
        """Note the frames' latency: it sets the loop-gain margin (without prediction)."""
        latency = round(latency / LATENCY_RESOLUTION) * LATENCY_RESOLUTION
        self._latency_seen = latency
        if latency != self.latency and not self.settings.estimator.predict:
            self.latency = latency

    def _set_margin(self) -> None:
        """Set the loop-gain margin for the latency and the measured pixel noise.

        :func:`~pbvs_pin.control.settings.loop_gain_margin`; only a change of 1e-3 or more.
        """
        margin = loop_gain_margin(self.settings, self.latency, self.tracker.noise.noise_px)
        if abs(margin - self.law.gains.loop_gain_margin) < 1e-3:
            return
        gains = replace(self.law.gains, loop_gain_margin=margin)
        self.law.gains, self.law.safety = gains, self.law.safety._replace(loop_gain_margin=margin)
        self.fused.settings[self._margin_slot] = margin

    def _command(
        self, t: float, q: np.ndarray, v: np.ndarray, velocity: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, bool]:
        """``u``, ``v_ref``, ``V2``, the error, and whether anything was servoed on.

        One compiled call, seen or not (:class:`~pbvs_pin.control.step.FusedControlStep`).
        """
        fused, tracker = self.fused, self.tracker
        measurement = tracker.choose(t)
        predict_from = None
        if measurement is not None and tracker.predicting:  # the step writes the prediction
            predict_from = (tracker.world, t - tracker.capture_time)
        u, v_ref, v2 = fused.step(q, v, measurement, velocity, self.laser, dt, predict_from)
        if measurement is None:
            return u, v_ref, v2, np.full(self.features.size, np.nan), False
        return u, v_ref, v2, fused.views.xi - self.xi_d, True

    def _warm_up(self) -> None:
        """Step once seen and once unseen on the home posture, then forget: compiles the step."""
        model = self.model
        q, v = model.home(), np.zeros(model.n)
        k = self.features.n_points  # the paper's two: one above the other
        angles = np.pi / 2 + 2 * np.pi * np.arange(k) / k
        points = 30.0 * np.column_stack([np.cos(angles), np.sin(angles)]).round(12)
        self.step(0.0, q, v, CameraFrame.seen(0.0, points, np.ones(k)), laser=(1.0, 0.0),
                  target_velocity=np.zeros(3))  # fmt: skip
        self.step(self.period, q, v, CameraFrame.not_visible(self.period),
                  target_velocity=np.zeros(3))  # fmt: skip
        self.reset()


def _plain(value: object, size: int) -> bool:
    """Whether ``value`` is already a C-ordered, writable float64 vector of ``size`` (fast path)."""
    return (
        type(value) is np.ndarray
        and value.dtype is FLOAT64
        and value.shape == (size,)
        and value.flags.c_contiguous
        and value.flags.writeable
    )


def _usable(shown: tuple[np.ndarray, np.ndarray] | None) -> tuple[ImageMeasurement | None, str]:
    """The frame's measurement, or None and why its values cannot be used."""
    if shown is None:
        return None, ""
    points, depths = shown
    if not (np.isfinite(points).all() and np.isfinite(depths).all()):
        return None, "non-finite points or depths: taken as not visible"
    if not (depths > MIN_DEPTH).all():
        return None, f"depths {depths.tolist()} not above {MIN_DEPTH} m: taken as not visible"
    return ImageMeasurement(points, depths), ""
