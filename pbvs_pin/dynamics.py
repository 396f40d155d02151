r"""Dynamics in actuated coordinates, and the velocity-reference model of eq. (1).

Pinocchio gives the rigid-body terms in its own coordinates (CRBA mass matrix, Coriolis
matrix, generalised gravity). With the constant selection ``v_pin = S v`` the nonholonomic
constraint forces drop out when projecting with ``S^T``:

.. math:: M_v = S^T M S,\quad C_v = S^T C S,\quad g_v = S^T g.

Commercial mobile manipulators take velocity references: low-level servos turn them into
torques, where a diagonal ``G`` marks the joints whose servo cancels its own gravity load (arm
servos do; a platform has no gravity load on its wheels). Substituting the servo's torque gives
eq. (1) of the paper,

.. math:: M(q)\dot v + C(q, v) v + g(q) = v_{ref},\quad
          M = K_e^{-1} M_v,\quad C = K_e^{-1} C_v + I,\quad g = K_e^{-1} (I - G) g_v,

with ``K_e`` the servos' loop gain; :mod:`pbvs_pin.servo` models the servos (the plant's and
the dynamic compensation's). :class:`VelocityLoop` holds fixed-gain arm servos for the MuJoCo
plant (:mod:`pbvs_pin.mujoco_plant`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from numba import njit

from pbvs_pin.exceptions import GainError

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
    """Fixed-gain velocity loops ``tau = K_v (v_ref - v) - D v + G g_v`` of each velocity.

    Gains set once at the home posture: the arm servos of the MuJoCo plant
    (:class:`pbvs_pin.mujoco_plant.MujocoPlant`). The Pinocchio plant and the dynamic
    compensation use the URDF's servos of :class:`pbvs_pin.servo.ServoModel`.

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
