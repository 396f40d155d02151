r"""The passivity-based kinematic visual controller, eqs. (10) and (34).

.. math:: u = -J^T K_c(\tilde\xi)\, \tilde\xi - J^\# J_o \hat{\dot p}
              + (I - J^\# J)\, k_1 \tanh(k_2 \Lambda),\qquad
          K_c(\tilde\xi) = \mathrm{diag}\!\left(\frac{k_i}{1 + |\tilde\xi_i|}\right),\qquad
          J^\# = W^{-1} J^T (J W^{-1} J^T)^{-1}.

Features enter the controller in *controller units* of ``feature_scale`` pixels
(the design notes, §3): the feedback term scales with ``|J|^2``, and in raw pixels (``|J|`` of a few
hundred) the paper's ``k_i = 0.15`` makes the sampled loop diverge. ``J# J_o`` and the
null-space projector do not depend on the unit.

**Feedback laws** (``controller.feedback``): the paper's ``transpose`` (``nu = J^T K_c e``),
``pseudoinverse`` (``J# K_c e``) and ``balanced``, every direction of ``J J^T`` at one stated gain
per camera frame (:mod:`pbvs_pin.control.balanced`, which derives it and says what it does to
the passivity argument).

Near a singular ``J W^-1 J^T`` the pseudo-inverse is damped (variable damping, Nakamura and
Hanafusa 1986), and every command is scaled down uniformly, keeping its direction, to respect
the robot's velocity limits. Non-finite inputs give a zero command and a flag, never NaN.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from numba import njit

from pbvs_pin.control.balanced import BALANCED_SHARE, balanced_feedback, balanced_gain
from pbvs_pin.control.gains import ServoGains, positive_vector
from pbvs_pin.control.stops import stop_weights, weighted_inverse
from pbvs_pin.control.support import keep_inside
from pbvs_pin.control.upright import (
    Safety,
    SafetyOutput,
    loop_gain_factor,
    upright_null_space,
)
from pbvs_pin.exceptions import ShapeError
from pbvs_pin.linalg import all_finite, cholesky_solve, matmul, matvec, smallest_eigenvalue

__all__ = [
    "ControlOutput",
    "PassivityController",
    "saturate",
    "storage_function",
]


TRANSPOSE, PSEUDOINVERSE, BALANCED, IBVS = 0, 1, 2, 3
"""The feedback laws, by their code in the compiled step, in the order of their names
(:data:`~pbvs_pin.control.gains.FEEDBACK_LAWS`); :data:`IBVS` is the classic law of
the baseline (:mod:`pbvs_pin.control.ibvs`, ``controller.law = "ibvs"``), not a
``controller.feedback`` value."""

ROUNDOFF_FLOOR = 1e-12
"""Smallest eigenvalue of the regularised ``J W^-1 J^T``, relative to its trace."""


@njit(cache=True, inline="always")
def storage_function(error_units: np.ndarray, k: np.ndarray) -> float:
    r"""``V1`` of eq. (7) in closed form.

    .. math:: V_1 = \int_0^{\tilde\xi} \eta^T K_c(\eta)\, d\eta
              = \sum_i k_i \left(|\tilde\xi_i| - \ln(1 + |\tilde\xi_i|)\right)

    Args:
        error_units: Feature error in controller units. Shape (r,).
        k: ``k_i``. Shape (r,).
    """
    total = 0.0
    for i in range(error_units.shape[0]):
        magnitude = abs(error_units[i])
        total += k[i] * (magnitude - np.log1p(magnitude))
    return total


@njit(cache=True, inline="always")
def saturate(u: np.ndarray, limits: np.ndarray) -> tuple[np.ndarray, float]:
    """Scale ``u`` uniformly so that ``|u_i| <= limits_i``; return it and the factor."""
    ratio = 0.0
    for i in range(u.shape[0]):
        ratio = max(ratio, abs(u[i]) / limits[i])
    if ratio <= 1.0:
        return u, 1.0
    return u / ratio, 1.0 / ratio


@njit(cache=True, inline="always")
def damped_pseudo_inverse(
    jacobian: np.ndarray, weight_inverse: np.ndarray, threshold: float, max_damping: float
) -> tuple[np.ndarray, float, bool]:
    r"""Weighted right pseudo-inverse, damped near singularities (Nakamura & Hanafusa 1986).

    .. math:: J^\# = W^{-1} J^T (J W^{-1} J^T + \mu^2 I)^{-1},\quad
              \mu^2 = \mu_{max}^2 \left(1 - (\sigma_{min}/\sigma_0)^2\right)
              \text{ if } \sigma_{min} < \sigma_0 \text{ else } 0

    If that leaves ``J W^-1 J^T + mu^2 I`` with an eigenvalue below :data:`ROUNDOFF_FLOOR`
    times its trace (``J`` singular to round-off and a tiny ``sigma_0``), ``mu^2`` is raised
    to that floor, so that no division by zero can happen.

    Args:
        jacobian: ``J``. Shape (r, n).
        weight_inverse: ``W^-1``. Shape (n, n).
        threshold: ``sigma_0``.
        max_damping: ``mu_max``.

    Returns:
        ``J#`` (n, r), ``sigma_min`` of ``J W^-1/2``, whether it was damped.
    """
    right = matmul(weight_inverse, jacobian.T)
    gram = matmul(jacobian, right)
    smallest = smallest_eigenvalue(gram)
    sigma_min = np.sqrt(max(smallest, 0.0))
    damped = sigma_min < threshold
    mu2 = max_damping * max_damping * (1.0 - (sigma_min / threshold) ** 2) if damped else 0.0
    # a J singular to round-off with a tiny threshold: keep the Cholesky factor real
    floor = ROUNDOFF_FLOOR * np.trace(gram)
    if smallest + mu2 < floor:
        mu2 = floor - min(smallest, 0.0)
    if mu2 > 0.0:
        gram = gram + mu2 * np.eye(gram.shape[0])
    cholesky_solve(gram, right.T)  # right becomes J# in place
    return right, sigma_min, damped


class LawOutput(NamedTuple):
    """What :func:`passivity_law` gives at one step (controller units unless noted)."""

    valid: bool
    """False when an input was not finite (then ``u`` is zero)."""
    u: np.ndarray
    """The command of eq. (34) [m/s, rad/s]. Shape (n,)."""
    nu: np.ndarray
    """``nu = J^T K_c e``. Shape (n,)."""
    feedforward: np.ndarray
    """``J# J_o phat_dot``. Shape (n,)."""
    null_space: np.ndarray
    """``(I - J# J) k1 tanh(k2 Lambda)``, kept upright. Shape (n,)."""
    storage: float
    """``V1`` of eq. (7)."""
    sigma_min: float
    """Smallest singular value of ``J W^-1/2``."""
    damped: bool
    """The pseudo-inverse was damped."""
    factor: float
    """The saturation's factor on the raw command (1: not saturated)."""
    gains: SafetyOutput
    """What the loop-gain net and the upright projection did."""


@njit(cache=True, inline="always")
def passivity_law(
    error: np.ndarray,
    jacobian: np.ndarray,
    object_jacobian: np.ndarray,
    target_velocity: np.ndarray,
    secondary: np.ndarray,
    k: np.ndarray,
    k1: np.ndarray,
    k2: np.ndarray,
    weight_inverse: np.ndarray,
    damping: np.ndarray,
    limits: np.ndarray,
    feedback_law: int,
    upright: np.ndarray,
    safety: Safety,
    room_up: np.ndarray,
    room_down: np.ndarray,
    barrier: np.ndarray,
) -> LawOutput:
    r"""Eq. (10)/(34) in controller units, saturated uniformly to the velocity limits.

    .. math:: \nu = J^T K_c(\tilde\xi)\tilde\xi,\quad
              K_c = \mathrm{diag}\!\left(\frac{k_i}{1 + |\tilde\xi_i|}\right),\quad
              u = -\nu - J^\# J_o \hat{\dot p} + (I - J^\# J)\, k_1 \tanh(k_2 \Lambda)

    and ``V1 = sum_i k_i (|e_i| - ln(1 + |e_i|))`` (eq. 7 in closed form). Two departures
    from the paper (:mod:`pbvs_pin.control.upright`): ``k_i`` is scaled so that the gain per
    camera sample stays below a margin, and the null-space term is kept from rolling the image.

    Args:
        error: ``xi - xi_d`` in controller units. Shape (r,).
        jacobian: ``J`` in controller units. Shape (r, n).
        object_jacobian: ``J_o`` in controller units. Shape (r, 3).
        target_velocity: ``phat_dot`` [m/s]. Shape (3,).
        secondary: ``Lambda``. Shape (n,).
        k: ``k_i`` [1/s]. Shape (r,).
        k1: Diagonal of ``k_1``. Shape (n,).
        k2: Diagonal of ``k_2``. Shape (n,).
        weight_inverse: ``W^-1``. Shape (n, n).
        damping: ``[sigma_0, mu_max]`` of the pseudo-inverse. Shape (2,).
        limits: Velocity limits. Shape (n,).
        feedback_law: :data:`TRANSPOSE` (the paper's ``nu``), :data:`PSEUDOINVERSE`
            (``J# K_c e``), :data:`BALANCED` (:func:`balanced_feedback`) or :data:`IBVS`
            (``J# k e``, constant ``k = lambda``: the classic law, :mod:`~pbvs_pin.control.ibvs`).
        upright: ``[phi, j_phi]`` (:func:`~pbvs_pin.control.upright.upright_row`). Shape (n + 1,).
        safety: The departures' settings; ``camera_period = 0`` turns the loop-gain net off.
        room_up: Each velocity's room towards its upper limit (:func:`joint_room`). Shape (n,).
        room_down: Its room towards the lower limit. Shape (n,).
        barrier: ``[b, g]``: keep ``g u >= b`` (:func:`~pbvs_pin.control.support.keep_inside`,
            the support's barrier); ``b = -inf`` leaves ``u`` as it is. Shape (n + 1,).

    Returns:
        The command and its diagnostics; ``valid`` is False (and ``u`` zero) when an input
        is not finite.
    """
    n = secondary.shape[0]
    zero = np.zeros(n)
    finite = (
        all_finite(error)
        and all_finite(jacobian)
        and all_finite(object_jacobian)
        and all_finite(target_velocity)
        and all_finite(secondary)
    )
    loop_gain, gain_factor, sigma_phi, upright_weight = np.nan, 1.0, 0.0, 0.0
    if not finite:
        gains = SafetyOutput(loop_gain, gain_factor, sigma_phi, upright_weight)
        return LawOutput(False, zero, zero, zero, zero, np.nan, np.nan, False, 1.0, gains)
    r = error.shape[0]
    if feedback_law == BALANCED:  # every direction at its stated gain: nothing for the net to cut
        loop_gain = BALANCED_SHARE * safety.loop_gain_margin
    elif safety.camera_period > 0.0:  # loop-gain safety net
        largest = 1.0
        if feedback_law == TRANSPOSE:
            negated = matmul(jacobian, jacobian.T)
            for a in range(r):
                for b in range(r):
                    negated[a, b] = -negated[a, b]
            largest = -smallest_eigenvalue(negated)
        gain_factor, loop_gain = loop_gain_factor(
            largest, np.max(k), safety.camera_period, safety.loop_gain_margin
        )
        if gain_factor < 1.0:
            k = gain_factor * k
    kc_error = np.empty(r)
    for i in range(r):
        if feedback_law == IBVS:  # a constant gain: no K_c shaping
            kc_error[i] = k[i] * error[i]
        else:
            kc_error[i] = k[i] / (1.0 + abs(error[i])) * error[i]
    shaped = np.empty(n)
    for j in range(n):
        shaped[j] = k1[j] * np.tanh(k2[j] * secondary[j])
    nu = matvec(jacobian.T, kc_error)
    if feedback_law == BALANCED:
        gain = balanced_gain(safety.loop_gain_margin, safety.camera_period, np.max(k))
        feedback = balanced_feedback(kc_error, jacobian, limits, room_up, room_down, gain)
    else:
        feedback = nu
    demand = matvec(object_jacobian, target_velocity)
    weights = np.ones(n)
    for _ in range(2):  # the second pass without the joints at their stops (.stops)
        inverse = weighted_inverse(weight_inverse, weights)
        pinv, sigma_min, damped = damped_pseudo_inverse(jacobian, inverse, damping[0], damping[1])
        if feedback_law == PSEUDOINVERSE or feedback_law == IBVS:
            feedback = matvec(pinv, kc_error)
        feedforward = matvec(pinv, demand)
        held = weights * shaped
        null_space = held - matvec(pinv, matvec(jacobian, held))
        if safety.upright:  # keep the image upright
            null_space, sigma_phi, upright_weight = upright_null_space(
                null_space, pinv, jacobian, inverse, upright, damping[0], safety.upright_rate
            )
        raw = null_space - feedback - feedforward
        weights = stop_weights(raw, room_up, room_down)
        if np.min(weights) >= 1.0:
            break
    gains = SafetyOutput(loop_gain, gain_factor, sigma_phi, upright_weight)
    keep_inside(raw, inverse, barrier)  # standing, above the image task
    u, factor = saturate(raw, limits)
    if not all_finite(u):
        return LawOutput(False, zero, zero, zero, zero, np.nan, np.nan, False, 1.0, gains)
    storage = storage_function(error, k)
    return LawOutput(
        True, u, nu, feedforward, null_space, storage, sigma_min, damped, factor, gains
    )


@dataclass(frozen=True)
class ControlOutput:
    """One step of the kinematic controller.

    Attributes:
        u: Velocity command [m/s, rad/s]. Shape (n,).
        error: Feature error ``xi - xi_d`` [px]. Shape (r,).
        storage: ``V1`` of eq. (7) in controller units [1/s].
        nu: ``nu = J^T K_c e`` of eq. (9) in controller units. Shape (n,).
        feedforward: ``J# J_o phat_dot`` [m/s, rad/s]. Shape (n,).
        null_space: ``(I - J# J) k1 tanh(k2 Lambda)``. Shape (n,).
        min_singular_value: Smallest singular value of ``J W^-1/2``, controller units.
        damped: The pseudo-inverse was damped (near-singular J).
        saturated: The command was scaled down to respect the velocity limits.
        scale: Factor applied to the raw command (1 when not saturated).
        valid: False when an input was missing or not finite (then ``u`` is zero).
        loop_gain: Gain per camera sample ``k T lambda_max(J J^T)`` before the net.
        gain_limited: The loop-gain net scaled the feature gains down.
        upright_angle: The image's upright angle ``phi`` [rad].
        upright_weight: ``beta``, how much of the roll was removed from the null space.
    """

    u: np.ndarray
    error: np.ndarray
    storage: float
    nu: np.ndarray
    feedforward: np.ndarray
    null_space: np.ndarray
    min_singular_value: float
    damped: bool
    saturated: bool
    scale: float = 1.0
    valid: bool = True
    loop_gain: float = float("nan")
    gain_limited: bool = False
    upright_angle: float = float("nan")
    upright_weight: float = 0.0


def law_output(law: LawOutput, error_px: np.ndarray, upright_angle: float) -> ControlOutput:
    """A valid step of :func:`passivity_law` as a :class:`ControlOutput`.

    Args:
        law: The law's output.
        error_px: ``xi - xi_d`` [px]. Shape (r,).
        upright_angle: The image's upright angle ``phi`` [rad].
    """
    return ControlOutput(
        u=law.u, error=error_px, storage=law.storage, nu=law.nu, feedforward=law.feedforward,
        null_space=law.null_space, min_singular_value=law.sigma_min, damped=law.damped,
        saturated=law.factor < 1.0, scale=law.factor, loop_gain=law.gains.loop_gain,
        gain_limited=bool(law.gains.gain_factor < 1.0), upright_angle=upright_angle,
        upright_weight=law.gains.upright_weight,
    )  # fmt: skip


class PassivityController:
    """Eq. (10)/(34) for one robot and one feature set.

    Args:
        gains: Controller gains.
        velocity_limits: Largest magnitude of each command, SI units. Shape (n,).
    """

    def __init__(self, gains: ServoGains, velocity_limits: npt.ArrayLike) -> None:
        self.gains = gains
        self.velocity_limits = positive_vector("velocity_limits", velocity_limits)
        n = self.velocity_limits.size
        self.n = n
        self.k1 = gains.expand("k1", n)
        self.k2 = gains.expand("k2", n)
        self.weight_inverse = gains.weight_inverse(n)
        self.damping = np.array([gains.damping_threshold, gains.max_damping])
        self.safety = Safety(
            bool(gains.upright),
            float(gains.upright_rate),
            float(gains.camera_period),
            float(gains.loop_gain_margin),
        )
        self.feedback_law = gains.feedback_law
        """The feedback's code in :func:`passivity_law` (:data:`TRANSPOSE`, ...)."""
        self._k: np.ndarray | None = None
        self.room = np.ones(n)
        """Room of each velocity towards its limits (:func:`joint_room`): none is near one."""
        self._no_barrier = np.r_[-np.inf, np.zeros(n)]
        """``[b, g]`` of no barrier (``b = -inf``)."""

    def pseudo_inverse(self, jacobian: np.ndarray) -> tuple[np.ndarray, float, bool]:
        """Weighted right pseudo-inverse ``J#``, damped near singularities.

        See :func:`damped_pseudo_inverse`.

        Args:
            jacobian: ``J`` in controller units. Shape (r, n).

        Returns:
            ``J#`` (shape (n, r)), ``sigma_min`` of ``J W^-1/2``, whether it was damped.
        """
        return damped_pseudo_inverse(
            np.ascontiguousarray(jacobian, dtype=float), self.weight_inverse, *self.damping
        )

    def step(
        self,
        error_px: npt.ArrayLike,
        jacobian_px: npt.ArrayLike,
        object_jacobian_px: npt.ArrayLike,
        target_velocity: npt.ArrayLike,
        secondary: npt.ArrayLike,
        upright: np.ndarray | None = None,
        room: tuple[np.ndarray, np.ndarray] | None = None,
        barrier: np.ndarray | None = None,
    ) -> ControlOutput:
        """Compute the command ``u`` of eq. (34) (:func:`passivity_law`).

        Args:
            error_px: ``xi - xi_d`` [px]. Shape (r,).
            jacobian_px: ``J`` [px per unit of v]. Shape (r, n).
            object_jacobian_px: ``J_o`` [px/m]. Shape (r, 3).
            target_velocity: Estimated target velocity ``phat_dot`` [m/s]. Shape (3,).
            secondary: ``Lambda`` of eq. (16). Shape (n,).
            upright: ``[phi, j_phi]`` (:func:`~pbvs_pin.control.upright.upright_row`);
                None leaves the null-space term as the paper has it. Shape (n + 1,).
            room: Each velocity's room towards its upper and lower limits
                (:func:`joint_room`), for the balanced feedback; None: no joint near a limit.
                Shapes (n,), (n,).
            barrier: ``[b, g]``, the support's barrier
                (:func:`~pbvs_pin.control.support.support_barrier`); None: none. Shape (n + 1,).

        Returns:
            The command and its diagnostics. A non-finite input gives ``u = 0``,
            ``valid = False``.

        Raises:
            ShapeError: If a shape is inconsistent.
        """
        error_px, jacobian_px, object_jacobian_px, target_velocity, secondary = self._inputs(
            error_px, jacobian_px, object_jacobian_px, target_velocity, secondary
        )
        r = error_px.shape[0]
        scale = self.gains.feature_scale
        upright = self._row("upright", upright, np.zeros(self.n + 1))  # j_phi = 0: no removal
        law = passivity_law(
            error_px / scale, jacobian_px / scale, object_jacobian_px / scale, target_velocity,
            secondary, self.feature_gains(r), self.k1, self.k2, self.weight_inverse,
            self.damping, self.velocity_limits, self.feedback_law, upright, self.safety,
            *(room if room is not None else (self.room, self.room)),
            self._row("barrier", barrier, self._no_barrier),
        )  # fmt: skip
        if not law.valid:
            return self.zero_output(r)
        return law_output(law, error_px, upright[0])

    def _row(self, name: str, row: np.ndarray | None, absent: np.ndarray) -> np.ndarray:
        """A row of n + 1 entries as a float array (``upright``, ``barrier``); ``absent`` for None.

        Raises:
            ShapeError: If it does not have n + 1 entries, naming it.
        """
        if row is None:
            return absent
        row = np.asarray(row, dtype=float)
        if row.shape != (self.n + 1,):
            raise ShapeError(name, (self.n + 1,), row.shape)
        return row

    def feature_gains(self, r: int) -> np.ndarray:
        """``k_i`` for ``r`` features [1/s]. Shape (r,)."""
        if self._k is None or self._k.size != r:
            self._k = self.gains.expand("k", r)
        return self._k

    def zero_output(self, r: int) -> ControlOutput:
        """The safe command for a step without valid measurements: zero velocity."""
        zero = np.zeros(self.n)
        return ControlOutput(
            u=zero,
            error=np.full(r, np.nan),
            storage=float("nan"),
            nu=zero,
            feedforward=zero,
            null_space=zero,
            min_singular_value=float("nan"),
            damped=False,
            saturated=False,
            valid=False,
        )

    def _inputs(self, *arrays: npt.ArrayLike) -> list[np.ndarray]:
        """``(error, J, J_o, target_velocity, Lambda)`` as float arrays, shapes checked.

        Raises:
            ShapeError: If a shape is inconsistent.
        """
        converted = [np.asarray(array, dtype=float) for array in arrays]
        error, jacobian, object_jacobian, target_velocity, secondary = converted
        r = error.shape[0]
        for name, got, want in (
            ("jacobian", jacobian.shape, (r, self.n)),
            ("object_jacobian", object_jacobian.shape, (r, 3)),
            ("target_velocity", target_velocity.shape, (3,)),
            ("secondary", secondary.shape, (self.n,)),
        ):
            if got != want:
                raise ShapeError(name, want, got)
        return converted
