r"""Dynamics in actuated coordinates, and the velocity-reference model of eq. (1).

Pinocchio gives the rigid-body terms in its own coordinates (CRBA mass matrix, Coriolis
matrix, generalised gravity). With the constant selection ``v_pin = S v`` the nonholonomic
constraint forces drop out when projecting with ``S^T``:

.. math:: M_v = S^T M S,\quad C_v = S^T C S,\quad g_v = S^T g.

Commercial mobile manipulators take velocity references: low-level loops apply
``tau = K_v (v_ref - v) - D v``. Substituting gives eq. (1) of the paper,

.. math:: M(q)\dot v + C(q, v) v + g(q) = v_{ref},\quad
          M = K_v^{-1} M_v,\quad C = K_v^{-1}(C_v + D) + I,\quad g = K_v^{-1} g_v.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from pbvs_pin.exceptions import GainError

if TYPE_CHECKING:
    from pbvs_pin.robot import MobileManipulator

PIONEER_TIME_CONSTANTS = (0.26, 0.23)
"""Time constants [s] of a Pioneer's forward speed and yaw rate loops (theta1/theta4 and
theta2/theta6 of the model identified by Martins et al., 2008)."""

ARM_TIME_CONSTANT = 0.05
"""Default longest time constant [s] of an arm joint's velocity loop."""

GRAVITY_SPEED_ERROR = 1e-5
"""Default largest steady velocity error [rad/s or m/s] gravity may cause on an arm joint at
home: servo loops are stiff enough that the arm does not sag visibly."""


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
    q = np.asarray(q, dtype=float)
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    coriolis = pin.computeCoriolisMatrix(model, data, q, selection @ np.asarray(v, dtype=float))
    gravity = pin.computeGeneralizedGravity(model, data, q)
    return DynamicTerms(
        selection.T @ mass @ selection, selection.T @ coriolis @ selection, selection.T @ gravity
    )


@dataclass(frozen=True)
class VelocityLoop:
    """Low-level velocity loops ``tau = K_v (v_ref - v) - D v`` of each actuated velocity.

    Attributes:
        gains: ``K_v`` [N s/m for a linear speed, N m s/rad for a rate]. Shape (n,).
        damping: Viscous friction ``D``, same units. Shape (n,).
    """

    gains: np.ndarray
    damping: np.ndarray

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
        gravity_error: float = GRAVITY_SPEED_ERROR,
    ) -> VelocityLoop:
        """Gains from time constants at the home posture.

        ``K_v,i = M_v,ii(q_home) / tau_i`` for the base. An arm joint gets the larger of
        ``sum_j |M_v,ij| / tau_arm`` and ``|g_v,i(q_home)| / gravity_error``: the row sum
        (not only the diagonal) keeps a light joint on a heavy platform from being dragged by
        the platform's accelerations, and gravity alone moves it by at most
        ``gravity_error``. The damping is the URDF's joint damping (zero for the base).

        Args:
            robot: The robot.
            base: Time constants of the base velocities [s]; the Pioneer's by default.
            arm: Longest time constant of an arm joint [s].
            gravity_error: Largest velocity error gravity may cause at home [rad/s or m/s].
        """
        if len(base) != robot.n_base:
            base = (base[0],) * robot.n_base
        taus = np.array([*base, *([arm] * robot.n_arm)], dtype=float)
        if np.any(taus <= 0):
            raise GainError(f"velocity loop time constants: expected > 0 s, got {taus}")
        terms = rigid_body_terms(robot, robot.home(), np.zeros(robot.n))
        gains = np.diag(terms.mass) / taus
        coupled = np.abs(terms.mass).sum(axis=1) / taus
        stiff = np.maximum(coupled, np.abs(terms.gravity) / gravity_error)
        gains[robot.n_base :] = stiff[robot.n_base :]
        damping = np.concatenate(
            [
                np.zeros(robot.n_base),
                np.asarray(robot.model.damping)[robot.model.nv - robot.n_arm :],
            ]
        )
        return cls(gains, damping)

    def reference_model(
        self, robot: MobileManipulator, q: npt.ArrayLike, v: npt.ArrayLike
    ) -> DynamicTerms:
        r"""The matrices of eq. (1).

        .. math:: M = K_v^{-1} M_v,\quad C = K_v^{-1}(C_v + D) + I,\quad g = K_v^{-1} g_v

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
            inverse * terms.gravity,
        )
