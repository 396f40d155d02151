r"""Dynamic compensation, eq. (20).

.. math:: v_{ref} = M(q)\left(\dot u - K_D (v - u)\right) + C(q, v)\, v + g(q)

with ``M``, ``C``, ``g`` the velocity-reference model of eq. (1) built from the controller's
own Pinocchio model and its model of the servos (the matrices of
:meth:`pbvs_pin.model.servo.ServoModel.reference_model`, applied in the compiled
:func:`compensation_law`, with the servo's loop gain recomputed from the mass matrix at every
step). With an exact
model it gives ``d/dt (v - u) = -K_D (v - u)``, eq. (21). The paper compensates the platform
only; here the rows compensated are a setting.

``udot`` is not measured: it is the derivative of the command, filtered with a first-order
low-pass of time constant ``derivative_time_constant`` so that the camera's frame-to-frame
jumps do not become spikes.
"""

from __future__ import annotations

from enum import Enum
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from numba import njit

from pbvs_pin.exceptions import GainError
from pbvs_pin.model.dynamics import actuated_terms
from pbvs_pin.model.servo import scheduled_stiffness

if TYPE_CHECKING:
    from pbvs_pin.model.robot import MobileManipulator
    from pbvs_pin.model.servo import ServoModel


@njit(cache=True, inline="always")
def filter_derivative(
    u: np.ndarray,
    u_previous: np.ndarray,
    u_dot: np.ndarray,
    has_previous: bool,
    dt: float,
    time_constant: float,
) -> None:
    r"""``udot``: the command's derivative through a first-order low-pass, updated in place.

    .. math:: \dot u \leftarrow \dot u + \frac{T}{\tau + T}
              \left(\frac{u - u_{prev}}{T} - \dot u\right),\qquad u_{prev} \leftarrow u

    Args:
        u: The command now. Shape (n,).
        u_previous: Updated: the previous command. Shape (n,).
        u_dot: Updated: the filtered derivative. Shape (n,).
        has_previous: Whether ``u_previous`` holds a command (else ``u_dot`` is kept).
        dt: Time since the previous command ``T`` [s].
        time_constant: ``tau`` [s].
    """
    if has_previous and dt > 0.0:
        blend = dt / (time_constant + dt)
        for j in range(u.shape[0]):
            u_dot[j] += blend * ((u[j] - u_previous[j]) / dt - u_dot[j])
    u_previous[:] = u


@njit(cache=True, inline="always")
def compensation_law(
    mass_upper: np.ndarray,
    bias: np.ndarray,
    gravity: np.ndarray,
    selection: np.ndarray,
    gain_per_mass: np.ndarray,
    gain_constant: np.ndarray,
    gravity_weight: np.ndarray,
    rows: np.ndarray,
    k_d: np.ndarray,
    v: np.ndarray,
    u: np.ndarray,
    u_dot: np.ndarray,
    limits: np.ndarray,
) -> tuple[np.ndarray, float]:
    r"""Eq. (20) on the velocity-reference model of eq. (1), from Pinocchio's terms.

    .. math:: M = K_e^{-1} S^T M_{rb} S,\quad C = K_e^{-1} S^T C_{rb} S + I,\quad
              g = K_e^{-1} (I - G) S^T g_{rb},

    with the servos' loop gain ``K_e,i = a_i sum_j |M_v,ij(q)| + b_i`` at this ``q``
    (:func:`pbvs_pin.model.servo.scheduled_stiffness`; :class:`pbvs_pin.model.servo.ServoModel` has
    ``a = 1 / T`` and ``b = D``, its damping fed forward),

    .. math:: v_{ref} = M(\dot u - K_D (v - u)) + C v + g

    Args:
        mass_upper: CRBA mass matrix, upper triangle filled (``pin.crba``). Shape (nv, nv).
        bias: ``C_rb(q, S v) S v + g_rb`` (``pin.nonLinearEffects``). Shape (nv,).
        gravity: Generalised gravity ``g_rb``. Shape (nv,).
        selection: ``S``. Shape (nv, n).
        gain_per_mass: ``a`` of the loop gain [1/s]. Shape (n,).
        gain_constant: ``b`` of the loop gain [N s/m or N m s/rad]. Shape (n,).
        gravity_weight: Diagonal of ``I - G`` (0 where the servo cancels gravity). Shape (n,).
        rows: Which rows are compensated (the others pass ``u`` through). Shape (n,).
        k_d: Diagonal of ``K_D`` [1/s]. Shape (n,).
        v: Measured actuated velocity. Shape (n,).
        u: Kinematic command. Shape (n,).
        u_dot: Command derivative. Shape (n,).
        limits: Velocity limits the low-level loops accept; ``v_ref`` is clipped to them.
            Shape (n,).

    Returns:
        ``v_ref`` (n,) and ``V2 = |v - u|^2 / 2`` (eq. 22).
    """
    n = v.shape[0]
    mass_v, bias_v = actuated_terms(mass_upper, bias, gravity, selection, gravity_weight)
    gains = scheduled_stiffness(mass_v, gain_per_mass, gain_constant)
    acceleration = np.empty(n)
    storage = 0.0
    for j in range(n):
        error = v[j] - u[j]
        storage += 0.5 * error * error
        acceleration[j] = u_dot[j] - k_d[j] * error
    v_ref = np.empty(n)
    for i in range(n):
        value = u[i]
        if rows[i]:
            inertial = bias_v[i]
            for j in range(n):
                inertial += mass_v[i, j] * acceleration[j]
            value = inertial / gains[i] + v[i]
        v_ref[i] = min(max(value, -limits[i]), limits[i])
    return v_ref, storage


class Compensation(Enum):
    """Which rows of eq. (20) are applied."""

    OFF = "off"
    PLATFORM = "platform"
    ALL = "all"


class DynamicCompensator:
    """Eq. (20) with a filtered command derivative.

    Args:
        robot: The controller's model of the robot.
        loop: The controller's model of the robot's servos.
        mode: Rows to compensate.
        k_d: Diagonal of ``K_D`` [1/s], one value or one per actuated velocity.
        derivative_time_constant: Low-pass time constant of ``udot`` [s].
    """

    def __init__(
        self,
        robot: MobileManipulator,
        loop: ServoModel,
        mode: Compensation = Compensation.PLATFORM,
        k_d: npt.ArrayLike = 0.3,
        derivative_time_constant: float = 0.05,
    ) -> None:
        k_d = np.broadcast_to(np.asarray(k_d, dtype=float), (robot.n,)).copy()
        if np.any(~np.isfinite(k_d)) or np.any(k_d <= 0):
            raise GainError(f"DynamicCompensator.k_d: expected > 0 [1/s], got {k_d}")
        if not derivative_time_constant > 0:
            raise GainError(
                "DynamicCompensator.derivative_time_constant: expected > 0 s, "
                f"got {derivative_time_constant}"
            )
        self.robot, self.loop, self.mode = robot, loop, mode
        self.k_d = k_d
        self.tau = derivative_time_constant
        self.rows = {
            Compensation.OFF: np.zeros(robot.n, dtype=bool),
            Compensation.PLATFORM: np.arange(robot.n) < robot.n_base,
            Compensation.ALL: np.ones(robot.n, dtype=bool),
        }[mode]
        self.any_row = bool(self.rows.any())
        self.gain_per_mass, self.gain_constant = loop.loop_gain_coefficients()
        self.previous_u = np.zeros(robot.n)
        self.u_dot = np.zeros(robot.n)
        self.has_previous = False
        """Whether ``previous_u`` holds a command yet."""

    def step(
        self, q: np.ndarray, v: np.ndarray, u: np.ndarray, dt: float
    ) -> tuple[np.ndarray, float]:
        """Velocity reference for the robot's low-level loops.

        Pinocchio gives the rigid-body terms; :func:`compensation_law`
        applies eq. (20) on the model of eq. (1).

        Args:
            q: Configuration. Shape (nq,).
            v: Measured actuated velocity. Shape (n,).
            u: Kinematic command. Shape (n,).
            dt: Time since the previous call [s].

        Returns:
            ``v_ref`` clipped to the velocity limits (shape (n,)), and ``V2 = |v - u|^2 / 2``
            of eq. (22).
        """
        filter_derivative(u, self.previous_u, self.u_dot, self.has_previous, dt, self.tau)
        self.has_previous = True
        if not self.any_row:
            error = v - u
            limits = self.robot.velocity_limits
            return np.clip(u, -limits, limits), 0.5 * float(error @ error)
        model, data, selection = self.robot.model, self.robot.data, self.robot.selection
        mass = pin.crba(model, data, q)
        bias = pin.nonLinearEffects(model, data, q, selection @ v)
        gravity = pin.computeGeneralizedGravity(model, data, q)
        return compensation_law(
            mass, bias, gravity, selection, self.gain_per_mass, self.gain_constant,
            self.loop.gravity_weight, self.rows, self.k_d, v, u, self.u_dot,
            self.robot.velocity_limits,
        )  # fmt: skip
