r"""Secondary objectives: the vector ``Lambda`` of eq. (16), projected into J's null space.

.. math:: \Lambda = [-u_{obs},\ \omega_{obs},\ f_1(\tilde\theta_1), \dots,
          f_{n_a}(\tilde\theta_{n_a})]^T

(a holonomic base's ``vy`` gets the lateral repulsion of :func:`obstacle_force`).

Each objective adds its contribution to ``Lambda`` (shape (n,)); a scenario switches each
one on or off.
"""

from __future__ import annotations

import abc
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from pbvs_pin.exceptions import GainError, NonFiniteValue, ShapeError, WrongType
from pbvs_pin.model.joint_angles import arm_angles, arm_difference
from pbvs_pin.validation import as_instance

if TYPE_CHECKING:  # pragma: no cover - typing only
    from pbvs_pin.model.robot import MobileManipulator


@njit(cache=True, inline="always")
def posture_term(
    arm: np.ndarray, target: np.ndarray, gain: float, continuous: np.ndarray
) -> np.ndarray:
    r"""Eq. (19): ``f_i = k_Lambda (theta_id - theta_i)``. Shape (n_arm,).

    A continuous joint's ``theta_id - theta_i`` is the shortest way round
    (:func:`~pbvs_pin.model.joint_angles.arm_difference`): 0.02 rad across ``+-pi`` is 0.02 rad, not
    ``2 pi - 0.02``.
    """
    return gain * arm_difference(target, arm, continuous)


LIMIT_MARGIN = 0.2
"""Width of each joint-limit zone of :class:`JointLimitAvoidance` [rad or m]."""


def rest_outside_limit_zones(
    target: np.ndarray, lower: np.ndarray, upper: np.ndarray, continuous: np.ndarray
) -> np.ndarray:
    """``theta_d`` moved to where the joint-limit objective rests. Shape (n_arm,).

    :func:`joint_limit_term` pulls a joint out of the zone within :data:`LIMIT_MARGIN` of
    each limit, and eq. (19) pulls it to ``theta_d``: a ``theta_d`` inside a zone is where
    neither rests, and the joint settles between them, off ``theta_d`` for good. So each
    target is clipped to ``[lower + margin, upper - margin]``; a joint whose zones overlap
    (range under ``2 margin``: PR2's, TIAGo's and Fetch's torso lifts, Stretch's telescoping
    segments) is always in one, and its target is its mid-travel, where the two pulls cancel.
    Continuous joints and infinite limits keep theirs.

    Args:
        target: ``theta_d`` [rad or m]. Shape (n_arm,).
        lower: Lower limits. Shape (n_arm,).
        upper: Upper limits. Shape (n_arm,).
        continuous: Whether each joint is continuous. Shape (n_arm,).
    """
    out = np.array(target, dtype=float)
    limited = ~np.asarray(continuous) & np.isfinite(lower) & np.isfinite(upper)
    low, high = lower[limited] + LIMIT_MARGIN, upper[limited] - LIMIT_MARGIN
    middle = 0.5 * (lower[limited] + upper[limited])
    out[limited] = np.where(low > high, middle, np.clip(out[limited], low, high))
    return out


@njit(cache=True, inline="always")
def joint_limit_term(
    arm: np.ndarray, lower: np.ndarray, upper: np.ndarray, margin: float, gain: float
) -> np.ndarray:
    """Restoring rates within ``margin`` of a limit; infinite limits give 0. Shape (n_arm,)."""
    above = np.maximum(arm - (upper - margin), 0.0)
    below = np.minimum(arm - (lower + margin), 0.0)
    return -gain * (above + below)


@njit(cache=True, inline="always")
def heading_share(distance: float, angle: float, d0: float) -> float:
    r"""The base-heading objective's share ``s`` in [0, 1]: obstacle avoidance keeps the yaw.

    .. math:: s = 1 - \left(1 - \mathrm{clip}\!\left(\frac{d - d_0}{d_0 / 2}, 0, 1\right)
              \right) \left(1 - \frac{2 |\alpha|}{\pi}\right)

    0 for an obstacle dead ahead within ``d_0`` (where (17)-(18) turn the platform away), 1 for
    one abeam (``|alpha| = pi/2``, where the forward repulsion of (17) vanishes too), for one
    beyond ``1.5 d_0``, when nothing is seen (``d`` infinite or NaN) and without avoidance
    (``d0 <= 0``). Continuous as an obstacle leaves the laser's field of view abeam: a share
    that jumped there switched the objective on and off (the reference robot's Experiment 2
    oscillated at 5 px RMS), and none let the reference robot drive into the obstacle
    (clearance -0.14 m).

    Args:
        distance: Shortest laser range ``d`` [m].
        angle: Its incidence angle ``alpha`` [rad] (:class:`SecondaryInput`).
        d0: Distance at which avoidance starts [m].
    """
    if not (d0 > 0.0 and distance < 1.5 * d0):  # NaN compares False: nothing seen
        return 1.0
    near = 1.0 - max(0.0, (distance - d0) / (0.5 * d0))
    ahead = max(0.0, 1.0 - 2.0 * abs(angle) / np.pi)
    return 1.0 - near * ahead


@njit(cache=True, inline="always")
def camera_heading(rotation: np.ndarray, q: np.ndarray) -> float:
    """``psi``: the optical axis's heading on the floor from the platform's forward axis [rad].

    Args:
        rotation: ``wRc``. Shape (3, 3).
        q: Configuration, a planar root joint first (``q[2:4]``: its cos and sin). Shape (nq,).
    """
    cx, cy = rotation[0, 2], rotation[1, 2]
    bx, by = q[2], q[3]
    return np.arctan2(bx * cy - by * cx, bx * cx + by * cy)


@njit(cache=True, inline="always")
def heading_term(rotation: np.ndarray, q: np.ndarray, gain: float, offset: float = 0.0) -> float:
    r"""The base-heading objective: turn the platform to where the camera looks.

    .. math:: \Lambda_\omega \mathrel{+}= s\, k_\psi\, \|c_h\|\, (\psi - \psi_d),\qquad
              \psi = \operatorname{atan2}(b \times c_h,\ b \cdot c_h)

    (``s`` from :func:`heading_share`, applied by the caller) with ``c_h`` the optical axis
    ``wRc e_z`` on the floor (its x and y in the world) and ``b``
    the platform's forward axis ``[cos, sin]`` of the planar root joint (``q[2:4]``). ``psi``
    is the camera's heading relative to the drive direction [rad], and ``psi_d`` (``offset``)
    its value at ``theta_d`` (eq. 19), so that this objective rests where the posture does (0
    for a computed home, :mod:`pbvs_pin.bringup.home`, whose camera looks forward; a shipped
    recipe's may look a little aside); ``|c_h|`` fades the term out for a camera looking up
    or down.
    In the null space of ``J`` it turns the platform and counter-rotates the arm, so that the
    camera's depth, the largest motion the task asks for, lies along the way the platform
    drives. A platform that cannot move sideways needs that: a camera that looks across it
    can close its depth only with the arm, and a telescoping arm at its stops cannot.
    Without ``s`` the reference robot drove into Experiment 2's obstacle (clearance -0.14 m).
    A holonomic platform (``Lambda_omega`` is its third velocity) shares the camera's heading
    between its yaw and the arm, and nothing else brings the yaw back: after Experiment 2's
    obstacle the PR2's platform stood 2.35 rad turned and its shoulder pan 0.96 rad off
    ``theta_d``, returning with a time constant of about 10 s (posture 0.113 rad over the
    last 5 s, rule 0.1). The term turns such a platform back, and eq. (19) returns the arm.

    Args:
        rotation: ``wRc``. Shape (3, 3).
        q: Configuration, a planar root joint first. Shape (nq,).
        gain: ``k_psi`` [1/s].
        offset: ``psi_d`` [rad].

    Returns:
        ``k_psi |c_h| (psi - psi_d)`` [rad/s], the difference wrapped to ``(-pi, pi]``.
    """
    cx, cy = rotation[0, 2], rotation[1, 2]
    psi = camera_heading(rotation, q) - offset
    psi = np.arctan2(np.sin(psi), np.cos(psi))
    return gain * np.sqrt(cx * cx + cy * cy) * psi


def heading_at(model: MobileManipulator, arm: np.ndarray) -> float:
    """``psi_d``: the camera's heading from the platform's forward axis at arm posture ``arm``.

    Args:
        model: The robot.
        arm: Arm positions [rad or m]. Shape (n_arm,).

    Returns:
        The heading [rad] (:func:`camera_heading`, platform at the origin).
    """
    q = model.with_arm_positions(model.neutral(), arm)
    return float(camera_heading(model.camera_pose(q).rotation, q))


DEPTH_REACH_FULL = 0.1
"""Arm depth reach (:func:`arm_depth_reach`) at and above which the heading objective is off:
between Stretch's (below 1e-4) and the smallest of the other two-wheel robots' (the Reach
Bravo 7's 0.14), measured on every shipped and zoo robot at its home."""


def arm_depth_reach(camera_jacobian: np.ndarray, velocity_limits: np.ndarray, n_base: int) -> float:
    r"""How fast the arm alone moves the camera along its optical axis, without turning it.

    .. math:: r = \frac{\| N(A_\omega)\, a_z \|}{|J_{z,1}|\, \bar u_1},\qquad
              A = J_{arm} \operatorname{diag}(\bar u_{arm})

    with ``a_z`` the row of ``A`` for the camera's speed along its optical axis (``v_z``),
    ``N(A_omega)`` the projector onto the null space of its rows ``omega_x, omega_y`` (the
    rotations that turn the optical axis), ``u_bar`` the velocity limits and the denominator
    the platform's forward drive along the axis. ``r`` is the largest depth rate the arm makes
    at its velocity limits while the camera keeps looking where it looks, per the platform's:
    below 1e-4 for Stretch's lift and telescoping arm (they move the camera across its axis),
    0.14-5.1 for every other shipped and zoo robot on a two-wheel platform (the reference
    robot 0.24).

    Args:
        camera_jacobian: Camera twist in the camera frame, ``[v; omega]`` (6, n), at home.
        velocity_limits: ``u_bar``. Shape (n,).
        n_base: Number of base velocities (forward speed first).
    """
    arm = camera_jacobian[:, n_base:] * velocity_limits[n_base:]
    _, singular, vt = np.linalg.svd(arm[3:5])
    rank = int(np.sum(singular > 1e-9 * max(float(singular.max(initial=0.0)), 1.0)))
    null = vt[rank:]
    depth = float(np.linalg.norm(null @ arm[2]))
    forward = abs(camera_jacobian[2, 0] * velocity_limits[0])
    return depth / max(forward, 1e-9)


def heading_factor(reach: float) -> float:
    """The heading objective's share of ``k_psi``: 1 - reach / :data:`DEPTH_REACH_FULL`, at least 0.

    1 for an arm that cannot move the camera along its axis (:func:`arm_depth_reach`), 0 for
    one that can: its platform need not turn to where the camera looks.
    """
    return max(0.0, 1.0 - reach / DEPTH_REACH_FULL)


TURN_RAMP = 0.1
"""``alpha_r`` [rad]: the incidence angle over which a holonomic base's avoidance turn
(:func:`obstacle_force`) grows from zero to full, on either side of dead ahead (5.7 deg).
Chosen by measurement: 0.3 rad let Vega-1 into Experiment 2's obstacle (clearance -0.15 m on
MuJoCo); 0.1 kept 0.28 m."""


@njit(cache=True, inline="always")
def obstacle_force(
    distance: float, angle: float, k_u: float, k_w: float, d0: float, holonomic: bool = False
) -> np.ndarray:
    r"""Fictitious force of eqs. (17)-(18) before the impedance, ``[F_u, F_w, F_y]``.

    .. math:: F_u = k_{uobs} (d_0 - d)(\tfrac{\pi}{2} - |\alpha|),

    .. math:: F_\omega = k_{\omega obs} (d_0 - d)\, \mathrm{sign}(\alpha)
              (\tfrac{\pi}{2} - |\alpha|),

    zero when ``d >= d_0`` or nothing is seen (``d`` infinite). ``F_y`` pushes a holonomic
    base sideways, away from the obstacle (an extension: the paper's platform cannot move
    sideways). As ``pi/2 - |alpha|`` stands for the repulsion's forward part ``cos alpha``, its
    lateral part ``sin alpha`` is taken as the same triangle shifted by ``pi/2``:

    .. math:: F_y = k_{uobs} (d_0 - d)\, \mathrm{sign}(\alpha)
              \big(\tfrac{\pi}{2} - |\tfrac{\pi}{2} - |\alpha||\big),

    largest for an obstacle abeam, positive (to the left) for one on the right.

    For a holonomic base (``holonomic``) the ``sign(alpha)`` of ``F_w`` becomes the ramp
    ``clip(alpha / alpha_r, -1, 1)``, ``alpha_r`` = :data:`TURN_RAMP` (an extension). A
    platform that can only drive forward meets ``alpha = 0`` when it heads straight at the
    obstacle, and the sign is the paper's choice of a side to turn to. A holonomic platform
    travels sideways as often as forward, and an obstacle it passes sweeps through its forward
    axis while it turns: the sign then reversed the yaw rate at full strength (TIAGo Pro,
    Experiment 3 on MuJoCo: -0.34 to +0.41 rad/s within 1 s at 16 s, the feature error up to
    32 px, oscillation 3.24 px RMS against the rule's 3; with the ramp 1.84).
    """
    force = np.zeros(3)
    if np.isfinite(distance) and distance < d0:
        reach = (d0 - distance) * (0.5 * np.pi - abs(angle))
        force[0] = k_u * reach
        side = min(1.0, max(-1.0, angle / TURN_RAMP)) if holonomic else np.sign(angle)
        force[1] = k_w * side * reach
        abeam = 0.5 * np.pi - abs(0.5 * np.pi - abs(angle))
        force[2] = k_u * (d0 - distance) * np.sign(angle) * abeam
    return force


@njit(cache=True, inline="always")
def add_obstacle_terms(secondary: np.ndarray, impedance: np.ndarray, n_base: int) -> None:
    """Add ``-u_obs`` to the forward speed and ``omega_obs`` to the yaw rate of ``Lambda``.

    With a holonomic base (``n_base`` 3: ``vx, vy, omega``) the lateral output goes to ``vy``.

    Args:
        secondary: ``Lambda``, updated. Shape (n,).
        impedance: ``[u_obs, omega_obs, vy_obs]``, the impedance's output. Shape (3,).
        n_base: Number of base velocities (0: a fixed base, no terms).
    """
    if n_base >= 2:
        secondary[0] -= impedance[0]
        secondary[n_base - 1] += impedance[1]
    if n_base == 3:
        secondary[1] += impedance[2]


@njit(cache=True, inline="always")
def impedance_step(
    velocity: np.ndarray, force: np.ndarray, mass: float, damping: float, dt: float
) -> np.ndarray:
    """Exact step of ``m du/dt + b u = F`` over ``dt`` with ``F`` held (the ``Z^-1`` of (17))."""
    decay = np.exp(-damping / mass * dt)
    return decay * velocity + (1.0 - decay) * force / damping


@dataclass(frozen=True)
class SecondaryInput:
    """What the secondary objectives see at one control step.

    Attributes:
        arm_positions: Arm joint positions from the encoders [rad or m]. Shape (n_arm,).
        obstacle_distance: Shortest laser range d [m] (``inf`` when nothing is seen).
        obstacle_angle: Incidence angle alpha [rad] of that range, measured clockwise from
            the platform's forward axis (positive: obstacle to the right).
        dt: Time since the previous control step [s].
        camera_rotation: ``wRc`` (:class:`BaseHeading`); None: not known. Shape (3, 3).
        q: Configuration, a planar root joint first (:class:`BaseHeading`). Shape (nq,).
    """

    arm_positions: np.ndarray
    obstacle_distance: float
    obstacle_angle: float
    dt: float
    camera_rotation: np.ndarray | None = None
    q: np.ndarray | None = None


def secondary_input(
    model: MobileManipulator,
    q: np.ndarray,
    laser: np.ndarray,
    dt: float,
    camera_rotation: np.ndarray,
) -> SecondaryInput:
    """What the objectives see at ``q``: the arm's angles and the laser's nearest return.

    Args:
        model: The controller's robot.
        q: Configuration, already checked. Shape (nq,).
        laser: ``[d, alpha]``, the nearest return's range [m] and angle [rad]. Shape (2,).
        dt: Time since the previous control step [s].
        camera_rotation: ``wRc``. Shape (3, 3).
    """
    theta = arm_angles(q, model.arm_q_indices, model.arm_continuous)
    return SecondaryInput(theta, float(laser[0]), float(laser[1]), dt, camera_rotation, q)


class SecondaryObjective(abc.ABC):
    """One term of ``Lambda``."""

    @abc.abstractmethod
    def contribution(self, state: SecondaryInput, n_base: int, n: int) -> np.ndarray:
        """This objective's part of ``Lambda``. Shape (n,)."""


def check_positive(owner: str, **values: float) -> None:
    """GainError naming the first non-positive or non-finite value."""
    for name, value in values.items():
        if not np.isfinite(value) or value <= 0:
            raise GainError(f"{owner}.{name}: expected > 0, got {value}")


class ObstacleAvoidance(SecondaryObjective):
    r"""Fictitious repulsion from the nearest obstacle through an impedance, eqs. (17)-(18).

    .. math:: u_{obs} = Z^{-1}\!\left(k_{uobs} (d_0 - d) (\tfrac{\pi}{2} - |\alpha|)\right),\quad
              \omega_{obs} = Z^{-1}\!\left(k_{\omega obs} (d_0 - d)\, \mathrm{sign}(\alpha)
              (\tfrac{\pi}{2} - |\alpha|)\right)

    for ``d < d_0`` (zero force beyond); on a holonomic base a lateral repulsion drives ``vy``
    and ``sign(alpha)`` is a ramp over :data:`TURN_RAMP` (:func:`obstacle_force`, extensions).
    The paper leaves ``Z`` open; here it is a
    mass-damper ``Z(s) = m s + b`` acting from the fictitious force to the velocity, so
    ``m du/dt + b u = F`` (first-order, static gain ``1/b``, time constant ``m/b``).

    Args:
        k_u: ``k_uobs`` [1/(rad s)].
        k_w: ``k_wobs`` [1/s].
        d0: Distance at which avoidance starts [m].
        mass: Impedance inertia ``m`` [s].
        damping: Impedance damping ``b`` [1].
    """

    def __init__(
        self,
        k_u: float = 0.5,
        k_w: float = 0.9,
        d0: float = 1.0,
        mass: float = 0.5,
        damping: float = 1.0,
    ) -> None:
        check_positive("ObstacleAvoidance", k_u=k_u, k_w=k_w, d0=d0, mass=mass, damping=damping)
        self.k_u, self.k_w, self.d0 = k_u, k_w, d0
        self.mass, self.damping = mass, damping
        self.velocity = np.zeros(3)

    def force(self, distance: float, angle: float, holonomic: bool = False) -> np.ndarray:
        """Fictitious force ``[F_u, F_w, F_y]`` of eqs. (17)-(18) before the impedance.

        ``holonomic``: the turn's ramp of :func:`obstacle_force`.
        """
        return obstacle_force(distance, angle, self.k_u, self.k_w, self.d0, holonomic)

    def contribution(self, state: SecondaryInput, n_base: int, n: int) -> np.ndarray:
        """``[-u_obs, omega_obs, 0, ...]`` (:func:`add_obstacle_terms`), advancing the impedance.

        The impedance state advances by ``state.dt``.
        """
        force = self.force(state.obstacle_distance, state.obstacle_angle, n_base == 3)
        self.velocity = impedance_step(self.velocity, force, self.mass, self.damping, state.dt)
        out = np.zeros(n)
        add_obstacle_terms(out, self.velocity, n_base)
        return out


@dataclass(frozen=True)
class ArmPosture(SecondaryObjective):
    r"""Pull the arm towards ``theta_d`` (maximum manipulability), eq. (19).

    .. math:: f_i(\tilde\theta_i) = k_{\Lambda i}\, (\theta_{id} - \theta_i)

    Attributes:
        target: ``theta_d`` [rad or m]. Shape (n_arm,).
        gain: ``k_Lambda`` [1/s].
        continuous: Whether each arm joint is continuous (its difference wraps,
            :func:`posture_term`); None: none is. Shape (n_arm,).
    """

    target: np.ndarray
    gain: float = 1.0
    continuous: np.ndarray | None = None

    def __post_init__(self) -> None:
        """Reject a non-positive gain."""
        check_positive("ArmPosture", gain=self.gain)

    def contribution(self, state: SecondaryInput, n_base: int, n: int) -> np.ndarray:
        """``[0, ..., k (theta_d - theta)]``."""
        target = np.asarray(self.target, dtype=float)
        continuous = np.zeros(target.shape[0], dtype=np.bool_)
        if self.continuous is not None:
            continuous = np.asarray(self.continuous, dtype=np.bool_)
        out = np.zeros(n)
        out[n_base:] = posture_term(state.arm_positions, target, self.gain, continuous)
        return out


@dataclass(frozen=True)
class JointLimitAvoidance(SecondaryObjective):
    """Push arm joints back when they come within ``margin`` of a position limit.

    ``f_i = -gain (theta_i - (upper_i - margin))`` above ``upper - margin``, and symmetrically
    near the lower limit; zero elsewhere and for continuous joints.

    Attributes:
        lower: Lower limits [rad or m]. Shape (n_arm,).
        upper: Upper limits. Shape (n_arm,).
        margin: Width of the active zone [rad or m].
        gain: [1/s].
    """

    lower: np.ndarray
    upper: np.ndarray
    margin: float = LIMIT_MARGIN
    gain: float = 2.0

    def __post_init__(self) -> None:
        """Reject non-positive margin or gain."""
        check_positive("JointLimitAvoidance", margin=self.margin, gain=self.gain)

    def contribution(self, state: SecondaryInput, n_base: int, n: int) -> np.ndarray:
        """Restoring rates near the limits."""
        out = np.zeros(n)
        out[n_base:] = joint_limit_term(
            state.arm_positions, self.lower, self.upper, self.margin, self.gain
        )
        return out


class BaseHeading(SecondaryObjective):
    """Turn the platform to where the camera looks (:func:`heading_term`).

    Args:
        gain: ``k_psi`` [1/s].
        d0: Distance at which obstacle avoidance starts [m]; 0: no avoidance.
        offset: ``psi_d``, the heading at ``theta_d`` [rad] (:func:`heading_at`).
    """

    def __init__(self, gain: float = 1.0, d0: float = 0.0, offset: float = 0.0) -> None:
        check_positive("BaseHeading", gain=gain)
        self.gain, self.d0, self.offset = gain, d0, offset

    def contribution(self, state: SecondaryInput, n_base: int, n: int) -> np.ndarray:
        """``s k_psi |c_h| psi`` in the platform's yaw rate (:func:`heading_share`). Shape (n,)."""
        out = np.zeros(n)
        if n_base >= 2 and state.camera_rotation is not None and state.q is not None:
            rotation = np.asarray(state.camera_rotation, dtype=float)
            q = np.asarray(state.q, dtype=float)
            share = heading_share(state.obstacle_distance, state.obstacle_angle, self.d0)
            out[n_base - 1] = share * heading_term(rotation, q, self.gain, self.offset)
        return out


BUILT_IN = (ArmPosture, BaseHeading, JointLimitAvoidance, ObstacleAvoidance)
"""The objectives of eqs. (16)-(19) (with the heading objective); the compiled step computes
them and the support objective (:data:`pbvs_pin.control.step.COMPILED`)."""


def contribution_of(
    objective: SecondaryObjective, state: SecondaryInput, n_base: int, n: int
) -> np.ndarray:
    """One objective's part of ``Lambda``, as a finite float vector of shape (n,).

    Raises:
        ShapeError: If the objective returned another shape (named by its class).
        NonFiniteValue: If it returned NaN or infinity (named by its class).
    """
    name = f"{type(objective).__name__}.contribution"
    part = np.asarray(objective.contribution(state, n_base, n), dtype=float)
    if part.shape != (n,):
        raise ShapeError(name, (n,), part.shape)
    if not np.isfinite(part).all():
        raise NonFiniteValue(name)
    return part


def secondary_vector(
    objectives: Sequence[SecondaryObjective], state: SecondaryInput, n_base: int, n: int
) -> np.ndarray:
    """``Lambda``: the sum of every objective's contribution. Shape (n,)."""
    total = np.zeros(n)
    for objective in objectives:
        total += contribution_of(objective, state, n_base, n)
    return total


def user_objectives(objectives: object) -> tuple[SecondaryObjective, ...]:
    """The user's secondary objectives as a tuple, each checked to be a SecondaryObjective.

    Raises:
        WrongType: If ``objectives`` is not a sequence of
            :class:`~pbvs_pin.control.secondary.SecondaryObjective` (a single objective
            included: wrap it in a list), naming the item at fault.
    """
    if isinstance(objectives, SecondaryObjective) or not isinstance(objectives, list | tuple):
        raise WrongType("objectives", "a list or tuple of SecondaryObjective", objectives)
    return tuple(
        as_instance(f"objectives[{i}]", objective, SecondaryObjective)
        for i, objective in enumerate(objectives)
    )
