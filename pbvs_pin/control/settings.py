"""What :class:`pbvs_pin.Controller` is built from besides the robot: typed, checked settings.

:class:`ControllerSettings` holds the controller's part of a scenario, the same typed sections
(:mod:`pbvs_pin.control.tables`) with the same defaults and checks, so that a controller can be
built in Python without a scenario file and a scenario's controller is built the same way. The
functions below fit the settings to a robot (per-dof vectors, ``W``, the objectives, the
compensator) and name the field at fault when a value does not fit.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from pbvs_pin.control.compensation import Compensation, DynamicCompensator
from pbvs_pin.control.gains import ServoGains
from pbvs_pin.control.ibvs import ClassicIbvs
from pbvs_pin.control.kinematic import PassivityController
from pbvs_pin.control.noise import noise_margin
from pbvs_pin.control.secondary import (
    ArmPosture,
    BaseHeading,
    JointLimitAvoidance,
    ObstacleAvoidance,
    SecondaryObjective,
    arm_depth_reach,
    heading_at,
    heading_factor,
    rest_outside_limit_zones,
)
from pbvs_pin.control.support import EDGE_TURN, KeepSupported
from pbvs_pin.control.tables import (
    CameraSection,
    CompensationSection,
    ControllerSection,
    EstimatorSection,
    SecondarySection,
    TargetSection,
)
from pbvs_pin.control.upright import delayed_margin
from pbvs_pin.exceptions import ScenarioError
from pbvs_pin.model.manipulability import max_manipulability_posture
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.model.servo import ServoModel
from pbvs_pin.validation import as_number, as_numbers, positive_number

HISTORY_SECONDS = 2.0
"""Default span of the encoder history [s]: the oldest frame the controller can place."""


class ScenarioTables(Protocol):
    """What :meth:`ControllerSettings.from_scenario` reads of a scenario.

    The controller's tables (:mod:`pbvs_pin.control.tables`) and the file they came from; a
    :class:`pbvs_pin.sim.scenario.Scenario` is one.
    """

    camera: CameraSection
    target: TargetSection
    estimator: EstimatorSection
    controller: ControllerSection
    compensation: CompensationSection
    secondary: SecondarySection
    source: str


@dataclass(frozen=True)
class ControllerSettings:
    """The controller's settings (each section checks its own keys when it is built).

    Attributes:
        camera: Intrinsics and frame rate (its latency keys are the simulator's; the
            controller measures the latency of the frames it is given).
        target: Sphere diameter and desired features ``xi_d``.
        estimator: Velocity filter, prediction, hold, smoothing.
        controller: Law, gains, control rate, upright row, loop-gain net.
        compensation: Rows of eq. (20), ``K_D``, derivative filter.
        secondary: Obstacle avoidance, posture, joint limits.
        servo_time_constants: The robot's own velocity loops' lags ``T_i`` [s], one per
            actuated velocity ``[u, omega, arm joints]``; None: the URDF model's
            (:meth:`pbvs_pin.ServoModel.from_robot`).
        history: How far back a frame's capture time may lie [s].
        source: Where the settings came from, for error messages.
    """

    camera: CameraSection = field(default_factory=CameraSection)
    target: TargetSection = field(default_factory=TargetSection)
    estimator: EstimatorSection = field(default_factory=EstimatorSection)
    controller: ControllerSection = field(default_factory=ControllerSection)
    compensation: CompensationSection = field(default_factory=CompensationSection)
    secondary: SecondarySection = field(default_factory=SecondarySection)
    servo_time_constants: tuple[float, ...] | None = None
    history: float = HISTORY_SECONDS
    source: str = "ControllerSettings"

    def __post_init__(self) -> None:
        """Convert ``history`` and ``servo_time_constants``; they must be positive.

        Raises:
            WrongType: If one is not numbers.
            GainError: If one is not positive, naming it.
        """
        object.__setattr__(self, "history", positive_number("history", as_number(
            "history", self.history)))  # fmt: skip
        if self.servo_time_constants is not None:
            lags = as_numbers("servo_time_constants", self.servo_time_constants).ravel()
            for lag in lags:
                positive_number("servo_time_constants", lag)
            object.__setattr__(self, "servo_time_constants", tuple(lags.tolist()))

    @classmethod
    def from_scenario(cls, scenario: ScenarioTables) -> ControllerSettings:
        """The controller's part of a scenario.

        The encoder history spans at least twice the oldest age a frame of the scenario's
        camera can have on arrival (latency, jitter, exposure delay and a frame period).
        """
        camera = scenario.camera
        oldest = camera.delivery_latency + camera.latency_jitter + camera.exposure_delay
        return cls(
            camera=camera, target=scenario.target, estimator=scenario.estimator,
            controller=scenario.controller, compensation=scenario.compensation,
            secondary=scenario.secondary, source=scenario.source,
            history=max(HISTORY_SECONDS, 2.0 * (oldest + 1.0 / camera.rate)),
        )  # fmt: skip

    def error(self, field: str, problem: str) -> ScenarioError:
        """The error for a value that does not fit the robot, naming the dotted field."""
        return ScenarioError(self.source, field, problem)

    @property
    def control_period(self) -> float:
        """``1 / controller.rate`` [s]: the period the controller expects to be stepped at."""
        return 1.0 / self.controller.rate

    @property
    def sample_period(self) -> float:
        """The loop-gain net's sample [s]: a camera frame, or a control step if longer."""
        return max(1.0 / self.camera.rate, self.control_period)


def per_dof(settings: ControllerSettings, field: str, values: tuple, n: int) -> np.ndarray:
    """A vector of n entries (per dof or feature) given as 1 or n values, or the error."""
    array = np.asarray(values, dtype=float)
    if array.size == 1:
        return np.full(n, float(array[0]))
    if array.size != n:
        raise settings.error(field, f"expected 1 or {n} values for this robot, got {array.size}")
    return array


def loop_gain_margin(settings: ControllerSettings, latency: float, noise_px: float = 0.0) -> float:
    """The net's margin for frames ``latency`` [s] old on arrival (0 when they are predicted).

    Lowered for the measured pixel noise ``noise_px`` [px] (0: none measured;
    :func:`pbvs_pin.control.noise.noise_margin`).
    """
    delay = 0.0 if settings.estimator.predict else latency / settings.sample_period
    return min(delayed_margin(settings.controller.loop_gain_margin, delay), noise_margin(noise_px))


def kinematic_law(
    settings: ControllerSettings, model: MobileManipulator, latency: float, features: int = 3
) -> PassivityController:
    """The kinematic controller, its gains fitted to the model's dof and the features.

    Args:
        settings: The settings.
        model: The controller's model of the robot.
        latency: The frames' expected age on arrival [s], for the loop-gain margin.
        features: The number of features r (the paper's three unless the controller was
            given its own feature set): ``controller.k`` has 1 or r values.
    """
    spec = settings.controller
    n = model.n
    gains = ServoGains(
        k=tuple(per_dof(settings, "controller.k", spec.k, features)),
        k1=tuple(per_dof(settings, "controller.k1", _reference_gains(spec.k1, model), n)),
        k2=tuple(per_dof(settings, "controller.k2", _reference_gains(spec.k2, model), n)),
        feature_scale=spec.feature_scale,
        weights=_weights(settings, spec.weights, n),
        feedback=spec.feedback,
        upright=spec.upright,
        upright_rate=spec.upright_rate,
        camera_period=settings.sample_period,
        loop_gain_margin=loop_gain_margin(settings, latency),
    )
    if spec.law == "ibvs":
        return ClassicIbvs(spec.ibvs_gain, model.velocity_limits, gains)
    return PassivityController(gains, model.velocity_limits)


def _reference_gains(values: tuple, model: MobileManipulator) -> tuple:
    """Gains written for the paper's robot (2 base + 3 arm values) fit any robot.

    The base values go to the robot's base velocities
    (:meth:`pbvs_pin.model.base.BaseAdapter.per_velocity`: the forward speed's to ``vx`` and ``vy``
    of a holonomic base) and the last arm value is repeated for every arm joint.
    """
    if len(values) == 5 and model.n != 5 and model.n_base in (2, 3):
        return (*model.base.per_velocity(*values[:2]), *([values[-1]] * model.n_arm))
    return values


def _weights(settings: ControllerSettings, weights: tuple, n: int) -> tuple:
    """``W`` as a diagonal or a full matrix, checked for size (the section checked the rest)."""
    if weights and isinstance(weights[0], tuple):
        if len(weights) != n or any(len(row) != n for row in weights):
            raise settings.error("controller.weights", f"expected a {n} x {n} matrix")
        return tuple(tuple(row) for row in weights)
    return tuple(per_dof(settings, "controller.weights", weights, n))


def compensator(settings: ControllerSettings, model: MobileManipulator) -> DynamicCompensator:
    """Eq. (20) on the model of the robot's velocity loops (the URDF's, or the lags given)."""
    loop = ServoModel.from_robot(model)
    if settings.servo_time_constants is not None:
        lags = per_dof(settings, "servo_time_constants", settings.servo_time_constants, model.n)
        if not np.all(np.isfinite(lags) & (lags > 0)):
            raise settings.error("servo_time_constants", f"expected > 0 s, got {lags.tolist()}")
        loop = replace(loop, time_constants=lags)
    spec = settings.compensation
    return DynamicCompensator(
        model, loop, Compensation(spec.mode),
        per_dof(settings, "compensation.k_d", spec.k_d, model.n), spec.derivative_time_constant,
    )  # fmt: skip


def posture_target(settings: ControllerSettings, model: MobileManipulator) -> np.ndarray:
    r"""``theta_d`` of eq. (19) [rad or m], shape (n_arm,), as ``secondary.posture_target`` says.

    The paper maximises the arm's manipulability alone. On an arm whose maximum cannot hold
    the camera on the target (most 6- and 7-joint arms), that posture pulls through the null
    space for the whole run, and the pull leaks into the features along the weakest direction
    of the ``J^T`` feedback (the depth): xArm7 Experiment 4 ends 9 px off, TIAGo 2 px. The
    default ``"home"`` is the most manipulable posture among those in which the camera looks
    forward, upright (:func:`pbvs_pin.bringup.home.compute_home`), which the task can reach.
    With ``secondary.joint_limits``, the home is moved out of the joint-limit zones, to where
    that objective rests (:func:`~pbvs_pin.control.secondary.rest_outside_limit_zones`); the
    paper's maximum is taken as it is.
    """
    if settings.secondary.posture_target != "home":
        return max_manipulability_posture(model)
    if not settings.secondary.joint_limits:
        return model.home_arm.copy()
    lower, upper = model.arm_position_limits()
    return rest_outside_limit_zones(model.home_arm, lower, upper, model.arm_continuous)


def secondary_objectives(
    settings: ControllerSettings, model: MobileManipulator, target: np.ndarray
) -> list[SecondaryObjective]:
    """The objectives switched on, summed into ``Lambda`` of eq. (16).

    Args:
        settings: The settings.
        model: The controller's model of the robot.
        target: ``theta_d`` of eq. (19) (:func:`posture_target`). Shape (n_arm,).
    """
    spec = settings.secondary
    objectives: list[SecondaryObjective] = []
    if spec.obstacle_avoidance:
        objectives.append(
            ObstacleAvoidance(
                spec.k_uobs, spec.k_wobs, spec.d0, spec.impedance_mass, spec.impedance_damping
            )
        )
    if spec.posture:
        objectives.append(ArmPosture(target, spec.k_lambda, model.arm_continuous))
    if spec.joint_limits:
        lower, upper = model.arm_position_limits()
        objectives.append(JointLimitAvoidance(lower, upper))
    gain = 0.0
    if spec.k_heading > 0.0 and model.n_base == 3:  # a holonomic base: its yaw returns the arm
        gain = spec.k_heading
    if spec.k_heading > 0.0 and model.n_base == 2:
        jacobian = model.camera_jacobian(model.home())
        reach = arm_depth_reach(jacobian, model.velocity_limits, model.n_base)
        gain = spec.k_heading * heading_factor(reach)
    d0 = spec.d0 if spec.obstacle_avoidance else 0.0
    if gain > 0.0:  # two wheels and an arm that moves the camera along its axis: off
        objectives.append(BaseHeading(gain, d0, heading_at(model, target)))
    if spec.support and model.support is not None:
        # with the heading objective off, the platform turns when the arm is at the edge
        turns = spec.posture and gain == 0.0 and model.n_base == 2
        at_edge = EDGE_TURN * spec.k_heading if turns else 0.0
        offset = heading_at(model, target) if at_edge > 0.0 else 0.0
        support = KeepSupported(
            model, model.support, spec.k_support, target=target, heading_gain=at_edge,
            heading_offset=offset, d0=d0,
        )  # fmt: skip
        objectives.append(support)
    return objectives
