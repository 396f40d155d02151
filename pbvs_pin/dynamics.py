r"""Dynamics in actuated coordinates, and the velocity-reference model of eq. (1).

Pinocchio gives the rigid-body terms in its own coordinates (CRBA mass matrix, Coriolis
matrix, generalised gravity). With the constant selection ``v_pin = S v`` the nonholonomic
constraint forces drop out when projecting with ``S^T``:

.. math:: M_v = S^T M S,\quad C_v = S^T C S,\quad g_v = S^T g.

Commercial mobile manipulators take velocity references: low-level loops apply
``tau = K_v (v_ref - v) - D v + G g_v``, where the diagonal ``G`` marks the joints whose servo
cancels its own gravity load (arm servos do; a platform has no gravity load on its wheels).
Substituting gives eq. (1) of the paper,

.. math:: M(q)\dot v + C(q, v) v + g(q) = v_{ref},\quad
          M = K_v^{-1} M_v,\quad C = K_v^{-1}(C_v + D) + I,\quad g = K_v^{-1} (I - G) g_v.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from numba import njit

from pbvs_pin.exceptions import GainError
from pbvs_pin.linalg import cholesky_solve, matvec

if TYPE_CHECKING:
    from pbvs_pin.robot import MobileManipulator

PIONEER_TIME_CONSTANTS = (0.26, 0.23)
"""Time constants [s] of a Pioneer's forward speed and yaw rate loops (theta1/theta4 and
theta2/theta6 of the model identified by Martins et al., 2008)."""

ARM_TIME_CONSTANT = 0.02
"""Default time constant [s] of an arm joint's velocity loop."""


@dataclass(frozen=True)
class DynamicTerms:
    """Mass, Coriolis and gravity terms at one state.

    Attributes:
        mass: Shape (n, n).
        coriolis: Shape (n, n); ``coriolis @ v`` is the Coriolis/centrifugal term.
        gravity: Shape (n,).
    """

    mass: np.ndarray
    coriolis: np.ndarray
    gravity: np.ndarray


def rigid_body_terms(robot: MobileManipulator, q: npt.ArrayLike, v: npt.ArrayLike) -> DynamicTerms:
    """``M_v``, ``C_v``, ``g_v`` in actuated coordinates, from Pinocchio.

    Args:
        robot: The robot.
        q: Configuration. Shape (nq,).
        v: Actuated velocity. Shape (n,).

    Returns:
        Terms in SI units (kg, kg m^2, N, N m).
    """
    model, data, selection = robot.model, robot.data, robot.selection
    q, v = robot.check_configuration(q), robot.check_velocity(v)
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    coriolis = pin.computeCoriolisMatrix(model, data, q, selection @ v)
    gravity = pin.computeGeneralizedGravity(model, data, q)
    return DynamicTerms(
        selection.T @ mass @ selection, selection.T @ coriolis @ selection, selection.T @ gravity
    )


@dataclass(frozen=True)
class VelocityLoop:
    """Low-level velocity loops ``tau = K_v (v_ref - v) - D v + G g_v`` of each velocity.

    Attributes:
        gains: ``K_v`` [N s/m for a linear speed, N m s/rad for a rate]. Shape (n,).
        damping: Viscous friction ``D``, same units. Shape (n,).
        gravity_compensated: Diagonal of ``G``: the loop cancels its joint's gravity load.
            Shape (n,), bool; None for no compensation anywhere.
    """

    gains: np.ndarray
    damping: np.ndarray
    gravity_compensated: np.ndarray | None = None

    @property
    def gravity_weight(self) -> np.ndarray:
        """Diagonal of ``I - G``: 1 where gravity acts on the loop, 0 where it is cancelled."""
        if self.gravity_compensated is None:
            return np.ones(len(self.gains))
        return 1.0 - np.asarray(self.gravity_compensated, dtype=float)

    def __post_init__(self) -> None:
        """Reject non-positive gains and negative damping."""
        if np.any(~np.isfinite(self.gains)) or np.any(self.gains <= 0):
            raise GainError(f"VelocityLoop.gains: expected > 0, got {self.gains}")
        if np.any(~np.isfinite(self.damping)) or np.any(self.damping < 0):
            raise GainError(f"VelocityLoop.damping: expected >= 0, got {self.damping}")

    @classmethod
    def from_time_constants(
        cls,
        robot: MobileManipulator,
        base: tuple[float, ...] = PIONEER_TIME_CONSTANTS,
        arm: float = ARM_TIME_CONSTANT,
        arm_gravity_compensation: bool = True,
    ) -> VelocityLoop:
        """Gains from time constants at the home posture.

        ``K_v,i = M_v,ii(q_home) / tau_i`` for the base. An arm joint gets
        ``sum_j |M_v,ij| / tau_arm``: the row sum (not only the diagonal) keeps a light joint
        on a heavy platform from being dragged by the platform's accelerations. The damping
        is the URDF's joint damping (zero for the base).

        Args:
            robot: The robot.
            base: Time constants of the base velocities [s]; the Pioneer's by default.
            arm: Time constant of an arm joint [s].
            arm_gravity_compensation: Arm servos cancel their own gravity load, as the servos
                of commercial arms do; without it a light arm sags by ``g / K_v``.
        """
        if len(base) != robot.n_base:
            base = (base[0],) * robot.n_base
        taus = np.array([*base, *([arm] * robot.n_arm)], dtype=float)
        if np.any(taus <= 0):
            raise GainError(f"velocity loop time constants: expected > 0 s, got {taus}")
        terms = rigid_body_terms(robot, robot.home(), np.zeros(robot.n))
        gains = np.diag(terms.mass) / taus
        gains[robot.n_base :] = (np.abs(terms.mass).sum(axis=1) / taus)[robot.n_base :]
        damping = np.concatenate(
            [
                np.zeros(robot.n_base),
                np.asarray(robot.model.damping)[robot.model.nv - robot.n_arm :],
            ]
        )
        compensated = np.arange(robot.n) >= robot.n_base if arm_gravity_compensation else None
        return cls(
            gains, damping, np.zeros(robot.n, dtype=bool) if compensated is None else compensated
        )

    def reference_model(
        self, robot: MobileManipulator, q: npt.ArrayLike, v: npt.ArrayLike
    ) -> DynamicTerms:
        r"""The matrices of eq. (1).

        .. math:: M = K_v^{-1} M_v,\quad C = K_v^{-1}(C_v + D) + I,\quad
                  g = K_v^{-1} (I - G) g_v

        Args:
            robot: The robot.
            q: Configuration. Shape (nq,).
            v: Actuated velocity. Shape (n,).

        Returns:
            ``M`` [s], ``C`` [1], ``g`` [m/s or rad/s], so that ``M vdot + C v + g = v_ref``.
        """
        terms = rigid_body_terms(robot, q, v)
        inverse = 1.0 / self.gains
        return DynamicTerms(
            inverse[:, None] * terms.mass,
            inverse[:, None] * (terms.coriolis + np.diag(self.damping)) + np.eye(len(inverse)),
            inverse * self.gravity_weight * terms.gravity,
        )


@njit(cache=True)
def actuated_terms(
    mass_upper: np.ndarray,
    bias: np.ndarray,
    gravity: np.ndarray,
    selection: np.ndarray,
    gravity_weight: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    r"""Rigid-body terms in actuated coordinates, for eq. (1).

    .. math:: M_v = S^T M_{rb} S,\qquad C_v v + (I - G) g_v = S^T b - G\, S^T g_{rb}

    with ``b = C_rb(q, S v) S v + g_rb`` from ``pin.nonLinearEffects``.

    Args:
        mass_upper: CRBA mass matrix, upper triangle filled (``pin.crba``). Shape (nv, nv).
        bias: ``b``. Shape (nv,).
        gravity: ``g_rb``. Shape (nv,).
        selection: ``S``; mostly zeros, which are skipped. Shape (nv, n).
        gravity_weight: Diagonal of ``I - G``. Shape (n,).

    Returns:
        ``M_v`` (n, n) and ``C_v v + (I - G) g_v`` (n,).
    """
    nv, n = selection.shape
    mass_v = np.zeros((n, n))
    bias_v = np.zeros(n)
    for a in range(nv):
        for i in range(n):
            s_ai = selection[a, i]
            if s_ai == 0.0:
                continue
            bias_v[i] += s_ai * (bias[a] - (1.0 - gravity_weight[i]) * gravity[a])
            for b in range(nv):
                m_ab = mass_upper[a, b] if a <= b else mass_upper[b, a]
                for j in range(n):
                    mass_v[i, j] += s_ai * m_ab * selection[b, j]
    return mass_v, bias_v


@njit(cache=True)
def velocity_loop_step(
    mass_upper: np.ndarray,
    bias: np.ndarray,
    gravity: np.ndarray,
    selection: np.ndarray,
    gains: np.ndarray,
    damping: np.ndarray,
    gravity_weight: np.ndarray,
    v: np.ndarray,
    v_ref: np.ndarray,
    h: float,
    v_pin_out: np.ndarray,
    displacement_out: np.ndarray,
) -> np.ndarray:
    r"""One semi-implicit step of eq. (1) times ``K_v``: the plant's velocity update.

    .. math:: (M_v + h (K_v + D))\, v_{k+1} = M_v v_k + h (K_v v_{ref} - C_v v_k - (I - G) g_v)

    Args:
        mass_upper: CRBA mass matrix, upper triangle filled. Shape (nv, nv).
        bias: ``C_rb(q, S v) S v + g_rb`` (``pin.nonLinearEffects``). Shape (nv,).
        gravity: Generalised gravity ``g_rb``. Shape (nv,).
        selection: ``S``. Shape (nv, n).
        gains: ``K_v``. Shape (n,).
        damping: ``D``. Shape (n,).
        gravity_weight: Diagonal of ``I - G`` (0 where the servo cancels gravity). Shape (n,).
        v: Actuated velocity. Shape (n,).
        v_ref: Velocity reference. Shape (n,).
        h: Step [s].
        v_pin_out: Written: ``S v_{k+1}``. Shape (nv,).
        displacement_out: Written: ``S v_{k+1} h`` for ``pin.integrate``. Shape (nv,).

    Returns:
        ``v_{k+1}``. Shape (n,).
    """
    mass_v, bias_v = actuated_terms(mass_upper, bias, gravity, selection, gravity_weight)
    lhs = mass_v + h * np.diag(gains + damping)
    rhs = matvec(mass_v, v) + h * (gains * v_ref - bias_v)
    v_next = cholesky_solve(lhs, rhs.reshape(-1, 1))[:, 0]
    v_pin_out[:] = matvec(selection, v_next)
    displacement_out[:] = h * v_pin_out
    return v_next
