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

with ``K_e`` the servos' loop gain; :mod:`pbvs_pin.model.servo` models the servos (the plant's and
the dynamic compensation's, and the MuJoCo plant's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from numba import njit

from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.validation import as_instance


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
    robot = as_instance("robot", robot, MobileManipulator)
    model, data, selection = robot.model, robot.data, robot.selection
    q, v = robot.check_configuration(q), robot.check_velocity(v)
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    coriolis = pin.computeCoriolisMatrix(model, data, q, selection @ v)
    gravity = pin.computeGeneralizedGravity(model, data, q)
    return DynamicTerms(
        selection.T @ mass @ selection, selection.T @ coriolis @ selection, selection.T @ gravity
    )


@njit(cache=True, inline="always")
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
