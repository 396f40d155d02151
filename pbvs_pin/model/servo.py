r"""The robot's low-level velocity servos, as the URDF describes the joints: eq. (1)'s plant.

One servo per actuated velocity ``v_i`` (platform forward speed and yaw rate, arm joint rates)
applies

.. math:: \tau_i = K_i(q)\,(r_i - v_i + e_i / T_{I,i}) + D_i r_i + F_i \tanh(r_i / v_s)
          + G_i g_{v,i},\quad |\tau_i| \le \tau_{max,i},\quad r_i = \mathrm{clip}(v_{ref,i},
          \pm v_{max,i}),\quad \dot e_i = r_i - v_i

to the rigid-body dynamics with the URDF's viscous damping ``D`` and Coulomb friction ``F``
(Pinocchio ``model.damping``, ``model.friction``; friction smoothed over ``v_s``),

.. math:: M_v \dot v + C_v v + g_v + D v + F \tanh(v / v_s) = \tau + \tau_{stop}.

- **Stiffness scheduled with the current mass matrix**:
  ``K_i(q) = sum_j |M_v,ij(q)| / T_i``, with ``T_i`` the time constant of the joint's class
  (:data:`PLATFORM_TIME_CONSTANTS`, :data:`REVOLUTE_TIME_CONSTANT`,
  :data:`PRISMATIC_TIME_CONSTANT`). The row sum keeps a light joint from being dragged by a
  heavy neighbour's accelerations; scheduling keeps the time constant at every posture (a
  servo tuned once at home goes soft when the arm extends).
- **Feed-forward of damping and friction**: at a constant reference the plant's ``D v +
  F tanh(v / v_s)`` cancels the feed-forward exactly at ``v = r``, so a commanded speed is
  reached (no ``K / (K + D)`` shortfall). The closed loop of one uncoupled joint is then a lag
  of time constant ``M_ii / (K_i + D_i) <= T_i``.
- **Integral action** on the arm joints (``T_I = 5 T``, :data:`INTEGRAL_TIME_RATIO`), as arm
  drives have: a steady load the feed-forward does not know of (an unknown payload's weight)
  is taken by the integral instead of leaving a velocity error ``load / K``. It overshoots a
  step of the reference by about 1 %. Eq. (1) and the compensation of eq. (20) model the
  proportional part only.
- **Limits**: references are clipped to the URDF speed limits, torques to its ``effort``
  limits (``effort <= 0`` in a URDF means "not given": no limit), and ``tau_stop`` is a
  unilateral, inelastic joint stop: a joint never passes its position limits (continuous
  joints have none); the stop only pushes, so a joint leaves its limit when commanded away.

Eq. (1) of the paper follows with the loop gain ``K_e(q) = K(q) + D`` (friction taken as
cancelled by its feed-forward, exact when ``sign v = sign r`` away from zero speed):

.. math:: M = K_e^{-1} M_v,\quad C = K_e^{-1} C_v + I,\quad g = K_e^{-1}(I - G) g_v,

which :meth:`ServoModel.reference_model` returns and the dynamic compensation (eq. 20) applies
with the coefficients of :meth:`ServoModel.loop_gain_coefficients`
(``K_e,i = a_i sum_j |M_v,ij| + b_i``, :func:`scheduled_stiffness`).

The plant steps these servos with :func:`servo_step`; :class:`ServoModel` keeps every parameter
as a named attribute, so another plant can apply the same servos.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import numpy.typing as npt
from numba import njit

from pbvs_pin.exceptions import GainError, UrdfError
from pbvs_pin.linalg import cut
from pbvs_pin.model.dynamics import DynamicTerms, actuated_terms, rigid_body_terms
from pbvs_pin.validation import as_number, as_numbers

if TYPE_CHECKING:
    from pbvs_pin.model.robot import MobileManipulator

PLATFORM_TIME_CONSTANTS = (0.26, 0.23)
"""Time constants [s] of the platform's forward speed and yaw rate servos: a Pioneer's
(Martins et al., 2008: theta1/theta4 and theta2/theta6 of the identified model, 0.26 s and
0.23 s). A platform with other velocities repeats the first."""

REVOLUTE_TIME_CONSTANT = 0.02
"""Time constant [s] of a revolute arm joint's servo, 0.02 s (a hobby-grade or industrial arm
servo tracks speed within a few tens of milliseconds)."""

PRISMATIC_TIME_CONSTANT = 0.05
"""Time constant [s] of a prismatic joint's servo (lifts and telescopes move whole arm
sections through a screw or belt: slower than a revolute joint)."""

INTEGRAL_TIME_RATIO = 5.0
"""An arm servo's integral time over its time constant, ``T_I = 5 T``: one joint's PI loop
``M_ii vdot = K (e + e_I / T_I)`` with ``M_ii / K = T`` has damping ratio ``sqrt(T_I / T) / 2``
= 1.1, so the integral removes a steady load (an unknown payload's weight) without overshoot to
speak of. The platform's servos have none: the Pioneer's identified response is first order."""

FRICTION_SPEED = 1e-3
"""Speed ``v_s`` [m/s or rad/s] over which Coulomb friction ``F tanh(v / v_s)`` changes sign.

A joint's band is widened to at least ``F h / M_v,ii`` (the speed one plant step of full
friction gives it), so that the semi-implicit step cannot carry it across the band: a light
wrist joint with URDF friction otherwise chatters (TIAGo Pro's ``arm_right_7_joint`` jumped
to 0.21 rad/s under a zero command)."""


def _check_joints_move_mass(robot: MobileManipulator) -> None:
    """UrdfError naming the arm joints below which every link is massless."""
    model = robot.model
    massless = [
        name
        for name in robot.arm_joint_names
        if all(
            model.inertias[j].mass == 0.0 and not np.any(model.inertias[j].inertia)
            for j in model.subtrees[model.getJointId(name)]
        )
    ]
    if massless:
        raise UrdfError(
            robot.source,
            f"arm joints {massless} move no mass (the links below them have no <inertial>): "
            "the simulated servos and the dynamic compensation need the links' masses; "
            "expected <inertial> with <mass> and <inertia> on each link, or set "
            "geometry_density = 1000.0 in [robot] (geometry_density=1000.0 in Python) to take "
            "them from the links' collision geometry at that density [kg/m^3]",
        )


@njit(cache=True)
def scheduled_stiffness(
    mass_v: np.ndarray, per_mass: np.ndarray, constant: np.ndarray
) -> np.ndarray:
    """Servo gains ``K_i = a_i sum_j |M_v,ij| + b_i`` scheduled with the current mass matrix.

    Args:
        mass_v: ``M_v`` [kg, kg m, kg m^2]. Shape (n, n).
        per_mass: ``a`` [1/s] (the inverse of a time constant). Shape (n,).
        constant: ``b`` [N s/m or N m s/rad]. Shape (n,).

    Returns:
        ``K`` [N s/m or N m s/rad]. Shape (n,).
    """
    n = mass_v.shape[0]
    gains = np.empty(n)
    for i in range(n):
        row = 0.0
        for j in range(n):
            row += abs(mass_v[i, j])
        gains[i] = per_mass[i] * row + constant[i]
    return gains


@dataclass(frozen=True)
class ServoModel:
    """The low-level servos of every actuated velocity (see the module docstring).

    Attributes:
        time_constants: ``T_i`` [s]. Shape (n,).
        damping: URDF viscous damping ``D`` [N s/m or N m s/rad]. Shape (n,).
        friction: URDF Coulomb friction ``F`` [N or N m]. Shape (n,).
        effort: Torque (force) limits [N m or N]; ``inf`` for none. Shape (n,).
        speed_limits: Largest reference accepted [m/s or rad/s]. Shape (n,).
        gravity_compensated: Diagonal of ``G``: the servo cancels its joint's gravity load
            (arm servos do). Shape (n,), bool.
        stop_index: Actuated index of each joint with position stops. Shape (k,), int.
        stop_q_index: Its index in ``q``. Shape (k,), int.
        lower: Its lower limit [rad or m]. Shape (k,).
        upper: Its upper limit [rad or m]. Shape (k,).
        integral_rates: ``1 / T_I`` of each servo's integral action [1/s] (0: none).
            Shape (n,).
        friction_speed: ``v_s`` [m/s or rad/s].
    """

    time_constants: np.ndarray
    damping: np.ndarray
    friction: np.ndarray
    effort: np.ndarray
    speed_limits: np.ndarray
    gravity_compensated: np.ndarray
    stop_index: np.ndarray
    stop_q_index: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    integral_rates: np.ndarray
    friction_speed: float = FRICTION_SPEED

    def __post_init__(self) -> None:
        """Reject non-positive time constants, effort or speed limits, negative friction."""
        checks = (
            ("time_constants", self.time_constants, lambda a: a > 0, "> 0 s"),
            ("damping", self.damping, lambda a: a >= 0, ">= 0"),
            ("friction", self.friction, lambda a: a >= 0, ">= 0"),
            ("effort", self.effort, lambda a: a > 0, "> 0"),
            ("speed_limits", self.speed_limits, lambda a: a > 0, "> 0"),
            ("integral_rates", self.integral_rates, lambda a: a >= 0, ">= 0 1/s"),
        )
        for name, values, valid, expected in checks:
            values = np.asarray(values, dtype=float)
            if np.any(np.isnan(values)) or not np.all(valid(values)):
                raise GainError(f"ServoModel.{name}: expected {expected}, got {values}")
        if not self.friction_speed > 0:
            raise GainError(f"ServoModel.friction_speed: expected > 0, got {self.friction_speed}")

    @classmethod
    def from_robot(
        cls,
        robot: MobileManipulator,
        platform: tuple[float, ...] = PLATFORM_TIME_CONSTANTS,
        revolute: float = REVOLUTE_TIME_CONSTANT,
        prismatic: float = PRISMATIC_TIME_CONSTANT,
    ) -> ServoModel:
        """The servos of a robot: time constants by joint class, the rest from its URDF.

        Args:
            robot: The robot.
            platform: Time constants of the platform's velocities [s].
            revolute: Time constant of a revolute (or continuous) arm joint [s].
            prismatic: Time constant of a prismatic arm joint [s].

        Raises:
            UrdfError: If an arm joint moves no mass (a URDF without ``<inertial>``): its
                servo's stiffness, scheduled on the mass matrix, would be zero.
        """
        model = robot.model
        platform = tuple(as_numbers("platform", platform).ravel())
        revolute, prismatic = as_number("revolute", revolute), as_number("prismatic", prismatic)
        _check_joints_move_mass(robot)
        if len(platform) != robot.n_base:  # forward and yaw (or one value) per base velocity
            if len(platform) not in (1, 2):
                raise GainError(
                    f"ServoModel.from_robot: platform: expected 1, 2 or {robot.n_base} time "
                    f"constants [s], got {len(platform)}"
                )
            platform = robot.base.per_velocity(platform[0], platform[-1])
        taus, damping, friction = [*platform], [0.0] * robot.n_base, [0.0] * robot.n_base
        effort = [np.inf] * robot.n_base
        stop_index, stop_q_index, lower, upper = [], [], [], []
        for i, name in enumerate(robot.arm_joint_names):
            joint = model.joints[model.getJointId(name)]
            kind = joint.shortname()
            linear = "Prismatic" in kind or kind in ("JointModelPX", "JointModelPY", "JointModelPZ")
            taus.append(prismatic if linear else revolute)
            damping.append(float(model.damping[joint.idx_v]))
            friction.append(float(model.friction[joint.idx_v]))
            limit = float(model.effortLimit[joint.idx_v])
            effort.append(limit if np.isfinite(limit) and limit > 0 else np.inf)
            if joint.nq == 1:
                low, high = (
                    model.lowerPositionLimit[joint.idx_q],
                    model.upperPositionLimit[joint.idx_q],
                )
                if np.isfinite(low) or np.isfinite(high):
                    stop_index.append(robot.n_base + i)
                    stop_q_index.append(joint.idx_q)
                    lower.append(low)
                    upper.append(high)
        arm = np.arange(robot.n) >= robot.n_base
        return cls(
            np.array(taus, dtype=float),
            np.array(damping),
            np.array(friction),
            np.array(effort),
            np.asarray(robot.velocity_limits, dtype=float).copy(),
            arm,
            np.array(stop_index, dtype=np.int64),
            np.array(stop_q_index, dtype=np.int64),
            np.array(lower, dtype=float),
            np.array(upper, dtype=float),
            np.where(arm, 1.0 / (INTEGRAL_TIME_RATIO * np.array(taus)), 0.0),
        )

    @property
    def gravity_weight(self) -> np.ndarray:
        """Diagonal of ``I - G``: 1 where gravity acts on the servo, 0 where it is cancelled."""
        return 1.0 - np.asarray(self.gravity_compensated, dtype=float)

    def loop_gain_coefficients(self) -> tuple[np.ndarray, np.ndarray]:
        """``a``, ``b`` of eq. (1)'s loop gain ``K_e,i(q) = a_i sum_j |M_v,ij(q)| + b_i``.

        The gain itself is :func:`scheduled_stiffness` of the current ``M_v``.

        Returns:
            ``a = 1 / T`` [1/s] and ``b = D`` [N s/m or N m s/rad] (the damping is fed forward,
            so it adds to the gain and leaves ``C``). Each shape (n,).
        """
        return 1.0 / self.time_constants, self.damping.copy()

    def reference_model(
        self, robot: MobileManipulator, q: npt.ArrayLike, v: npt.ArrayLike
    ) -> DynamicTerms:
        r"""The matrices of eq. (1) for these servos (see the module docstring).

        Args:
            robot: The robot.
            q: Configuration. Shape (nq,).
            v: Actuated velocity. Shape (n,).

        Returns:
            ``M`` [s], ``C`` [1], ``g`` [m/s or rad/s], so that ``M vdot + C v + g = v_ref``.
        """
        terms = rigid_body_terms(robot, q, v)
        inverse = 1.0 / scheduled_stiffness(terms.mass, *self.loop_gain_coefficients())
        return DynamicTerms(
            inverse[:, None] * terms.mass,
            inverse[:, None] * terms.coriolis + np.eye(len(inverse)),
            inverse * self.gravity_weight * terms.gravity,
        )


class ServoConstants(NamedTuple):
    """The servos' constants as :func:`servo_step` reads them, by name.

    In a plant's 1 kHz step they are views of the two buffers of :func:`pack_servos`
    (:func:`servo_constants`); built directly, any arrays of these shapes.
    """

    inverse_time_constants: np.ndarray
    """``1 / T`` [1/s]. Shape (n,)."""
    damping: np.ndarray
    """``D``. Shape (n,)."""
    friction: np.ndarray
    """``F``. Shape (n,)."""
    effort: np.ndarray
    """Torque (force) limits, ``inf`` for none. Shape (n,)."""
    speed_limits: np.ndarray
    """Largest reference accepted. Shape (n,)."""
    gravity_weight: np.ndarray
    """Diagonal of ``I - G``. Shape (n,)."""
    integral_rates: np.ndarray
    """``1 / T_I`` [1/s] (0: no integral action). Shape (n,)."""
    lower: np.ndarray
    """Lower limit of each joint with stops. Shape (k,)."""
    upper: np.ndarray
    """Its upper limit. Shape (k,)."""
    selection: np.ndarray
    """``S``. Shape (nv, n)."""
    friction_speed: float
    """``v_s`` [m/s or rad/s]."""
    h: float
    """The step [s]."""
    stop_index: np.ndarray
    """Actuated index of each joint with stops. Shape (k,), int."""
    stop_q_index: np.ndarray
    """Its index in ``q``. Shape (k,), int."""


def pack_servos(
    servo: ServoModel, selection: np.ndarray, gravity_weight: np.ndarray, h: float
) -> tuple[np.ndarray, np.ndarray]:
    """:class:`ServoConstants` in one float and one integer array, in its fields' order.

    A compiled call from Python costs about 0.07 us per argument, so the plant's 1 kHz step
    passes these two arrays (named again by :func:`servo_constants`) instead of 14 values.

    Args:
        servo: The servos.
        selection: ``S``. Shape (nv, n).
        gravity_weight: Diagonal of ``I - G``. Shape (n,).
        h: Step [s].

    Returns:
        ``params`` (the float fields, ``S`` row-major) and ``indices`` (``n, nv, k``, then
        the integer fields).
    """
    nv, n = selection.shape
    params = np.concatenate(
        [
            1.0 / servo.time_constants, servo.damping, servo.friction, servo.effort,
            servo.speed_limits, gravity_weight, servo.integral_rates, servo.lower, servo.upper,
            selection.ravel(), [servo.friction_speed, h],
        ]
    ).astype(float)  # fmt: skip
    k = servo.stop_index.shape[0]
    indices = np.concatenate([[n, nv, k], servo.stop_index, servo.stop_q_index])
    return params, indices.astype(np.int64)


@njit(cache=True, inline="always")
def servo_constants(params: np.ndarray, indices: np.ndarray) -> ServoConstants:
    """Named views of :func:`pack_servos`' buffers, cut in :class:`ServoConstants`' order."""
    n, nv, k = indices[0], indices[1], indices[2]
    inverse_time_constants, a = cut(params, 0, n)
    damping, a = cut(params, a, n)
    friction, a = cut(params, a, n)
    effort, a = cut(params, a, n)
    speed_limits, a = cut(params, a, n)
    gravity_weight, a = cut(params, a, n)
    integral_rates, a = cut(params, a, n)
    lower, a = cut(params, a, k)
    upper, a = cut(params, a, k)
    selection, a = cut(params, a, nv * n)
    stop_index, b = cut(indices, 3, k)
    stop_q_index, b = cut(indices, b, k)
    return ServoConstants(
        inverse_time_constants, damping, friction, effort, speed_limits, gravity_weight,
        integral_rates, lower, upper, selection.reshape((nv, n)), params[a], params[a + 1],
        stop_index, stop_q_index,
    )  # fmt: skip


@njit(cache=True)
def packed_servo_step(
    mass_upper: np.ndarray,
    servo_mass_upper: np.ndarray,
    bias: np.ndarray,
    gravity: np.ndarray,
    params: np.ndarray,
    indices: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
    v_ref: np.ndarray,
    integral: np.ndarray,
    v_pin_out: np.ndarray,
    displacement_out: np.ndarray,
) -> np.ndarray:
    """:func:`servo_step` with its constants packed by :func:`pack_servos`.

    Args:
        mass_upper: CRBA mass matrix, upper triangle filled. Shape (nv, nv).
        servo_mass_upper: The mass matrix the servos' stiffness is scheduled with
            (:func:`servo_step`). Shape (nv, nv).
        bias: ``pin.nonLinearEffects`` at ``S v``. Shape (nv,).
        gravity: The gravity load the servos cancel (:func:`servo_step`). Shape (nv,).
        params: Float constants of :func:`pack_servos`.
        indices: Integer constants of :func:`pack_servos`.
        q: Configuration now (the stops' positions are read from it). Shape (nq,).
        v: Actuated velocity now. Shape (n,).
        v_ref: Velocity reference. Shape (n,).
        integral: Updated: the servos' integral states (:func:`servo_step`). Shape (n,).
        v_pin_out: Written: ``S v_{k+1}``. Shape (nv,).
        displacement_out: Written: ``S v_{k+1} h``. Shape (nv,).

    Returns:
        ``v_{k+1}``. Shape (n,).
    """
    constants = servo_constants(params, indices)
    k = constants.stop_q_index.shape[0]
    positions = np.empty(k)
    for s in range(k):
        positions[s] = q[constants.stop_q_index[s]]
    return servo_step(
        mass_upper, servo_mass_upper, bias, gravity, constants, positions, v, v_ref, integral,
        v_pin_out, displacement_out,
    )  # fmt: skip


@njit(cache=True)
def servo_step(
    mass_upper: np.ndarray,
    servo_mass_upper: np.ndarray,
    bias: np.ndarray,
    gravity: np.ndarray,
    constants: ServoConstants,
    positions: np.ndarray,
    v: np.ndarray,
    v_ref: np.ndarray,
    integral: np.ndarray,
    v_pin_out: np.ndarray,
    displacement_out: np.ndarray,
) -> np.ndarray:
    r"""One linearly implicit step of the servoed dynamics, with torque limits and stops.

    The servo's stiffness, the damping and the friction's slope are taken at the new
    velocity (stable for stiff servos at a 1 ms step):

    .. math:: (M_v + h (K' + D + F'))\, v_{k+1} = M_v v_k
              + h (K' r + K e_k / T_I + \tau_{ff} - C_v v_k - g_v - F(v_k) + F' v_k)
              + h \tau_{stop}

    with the integral action ``K e / T_I``, ``e_{k+1} = e_k + h (r - v_{k+1})``, taken at the
    new velocity too: ``K' = K (1 + h / T_I)``. A saturated servo holds its integral, and
    ``|K e / T_I|`` never exceeds the effort limit (anti-windup).

    A small active set decides which servos saturate (their torque becomes ``+-effort``) and
    which stops act (the joint's new velocity lands it on the limit, and the stop's reaction
    must push away from the limit, else the stop is released).

    Args:
        mass_upper: CRBA mass matrix, upper triangle filled. Shape (nv, nv).
        servo_mass_upper: The mass matrix the servos' stiffness is scheduled with (the robot
            they were tuned on; ``mass_upper`` when that is the true robot). Shape (nv, nv).
        bias: ``pin.nonLinearEffects`` at ``S v``. Shape (nv,).
        gravity: The gravity load the servos cancel (``pin.computeGeneralizedGravity`` of the
            robot they were tuned on). Shape (nv,).
        constants: The servos' constants.
        positions: The stopped joints' positions now. Shape (k,).
        v: Actuated velocity now. Shape (n,).
        v_ref: Velocity reference. Shape (n,).
        integral: Updated: ``e``, each servo's integral of ``r - v`` [rad or m]. Shape (n,).
        v_pin_out: Written: ``S v_{k+1}``. Shape (nv,).
        displacement_out: Written: ``S v_{k+1} h`` for ``pin.integrate``. Shape (nv,).

    Returns:
        ``v_{k+1}``. Shape (n,).
    """
    selection, inverse_time_constants = constants.selection, constants.inverse_time_constants
    damping, friction = constants.damping, constants.friction
    friction_speed = constants.friction_speed
    effort, speed_limits, h = constants.effort, constants.speed_limits, constants.h
    gravity_weight, integral_rates = constants.gravity_weight, constants.integral_rates
    stop_index, lower, upper = constants.stop_index, constants.lower, constants.upper
    n = v.shape[0]
    mass_v, bias_v = actuated_terms(mass_upper, bias, gravity, selection, np.ones(n))
    servo_mass_v = mass_v
    if servo_mass_upper is not mass_upper:
        servo_mass_v, _ = actuated_terms(servo_mass_upper, bias, gravity, selection, np.ones(n))
    stiffness = scheduled_stiffness(servo_mass_v, inverse_time_constants, np.zeros(n))
    gains = stiffness * (1.0 + h * integral_rates)
    reference = np.empty(n)
    feed_forward = np.empty(n)
    slope = np.empty(n)
    base_rhs = np.empty(n)
    for i in range(n):
        reference[i] = min(max(v_ref[i], -speed_limits[i]), speed_limits[i])
        gravity_v = 0.0
        for a in range(selection.shape[0]):
            gravity_v += selection[a, i] * gravity[a]
        # one step of full friction must not carry the joint across the smoothing band
        width = max(friction_speed, friction[i] * h / mass_v[i, i])
        feed_forward[i] = (
            damping[i] * reference[i]
            + friction[i] * np.tanh(reference[i] / width)
            + (1.0 - gravity_weight[i]) * gravity_v
            + stiffness[i] * integral_rates[i] * integral[i]
        )
        now = np.tanh(v[i] / width)
        slope[i] = friction[i] / width * (1.0 - now * now)
        momentum = 0.0
        for j in range(n):
            momentum += mass_v[i, j] * v[j]
        base_rhs[i] = momentum + h * (-bias_v[i] - friction[i] * now + slope[i] * v[i])
    saturated = np.zeros(n)  # -1, 0, +1
    stopped = np.zeros(n)  # -1 (lower), 0, +1 (upper)
    target = np.zeros(n)
    k = stop_index.shape[0]
    v_next = v.copy()
    for _ in range(3 * n + 3):
        lhs = mass_v.copy()
        rhs = base_rhs.copy()
        for i in range(n):
            lhs[i, i] += h * (damping[i] + slope[i])
            if saturated[i] == 0.0:
                lhs[i, i] += h * gains[i]
                rhs[i] += h * (gains[i] * reference[i] + feed_forward[i])
            else:
                rhs[i] += h * saturated[i] * effort[i]
        full_lhs, full_rhs = lhs.copy(), rhs.copy()
        for i in range(n):
            if stopped[i] != 0.0:
                lhs[i, :] = 0.0
                lhs[i, i] = 1.0
                rhs[i] = target[i]
        v_next = np.linalg.solve(lhs, rhs)
        changed = False
        for i in range(n):
            torque = gains[i] * (reference[i] - v_next[i]) + feed_forward[i]
            if saturated[i] == 0.0 and abs(torque) > effort[i]:
                saturated[i] = np.sign(torque)
                changed = True
            elif saturated[i] != 0.0 and abs(torque) <= effort[i]:
                saturated[i] = 0.0
                changed = True
        for s in range(k):
            i = stop_index[s]
            if stopped[i] != 0.0:
                reaction = 0.0  # tau_stop = (lhs v - rhs)_i / h of the unconstrained row
                for j in range(n):
                    reaction += full_lhs[i, j] * v_next[j]
                reaction -= full_rhs[i]
                if reaction * stopped[i] > 0.0:  # it would pull the joint into its limit
                    stopped[i] = 0.0
                    changed = True
            elif positions[s] + h * v_next[i] > upper[s]:
                stopped[i], target[i] = 1.0, (upper[s] - positions[s]) / h
                changed = True
            elif positions[s] + h * v_next[i] < lower[s]:
                stopped[i], target[i] = -1.0, (lower[s] - positions[s]) / h
                changed = True
        if not changed:
            break
    for s in range(k):  # should the active set not settle, the stops still hold
        i = stop_index[s]
        v_next[i] = min(
            max(v_next[i], (lower[s] - positions[s]) / h), (upper[s] - positions[s]) / h
        )
    for i in range(n):  # the integral, held while its servo saturates
        if integral_rates[i] > 0.0 and saturated[i] == 0.0:
            bound = effort[i] / (stiffness[i] * integral_rates[i])
            integral[i] = min(max(integral[i] + h * (reference[i] - v_next[i]), -bound), bound)
    for a in range(selection.shape[0]):
        total = 0.0
        for j in range(n):
            total += selection[a, j] * v_next[j]
        v_pin_out[a] = total
        displacement_out[a] = h * total
    return v_next
