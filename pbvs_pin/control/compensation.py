r"""Dynamic compensation, eq. (20).

.. math:: v_{ref} = M(q)\left(\dot u - K_D (v - u)\right) + C(q, v)\, v + g(q)

with ``M``, ``C``, ``g`` the velocity-reference model of eq. (1) built from the controller's
own Pinocchio model (the matrices of :meth:`pbvs_pin.dynamics.VelocityLoop.reference_model`,
applied in the compiled :func:`pbvs_pin.kernels.compensation_law`). With an exact
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

from pbvs_pin.exceptions import GainError
from pbvs_pin.kernels import compensation_law

if TYPE_CHECKING:
    from pbvs_pin.dynamics import VelocityLoop
    from pbvs_pin.robot import MobileManipulator


class Compensation(Enum):
    """Which rows of eq. (20) are applied."""

    OFF = "off"
    PLATFORM = "platform"
    ALL = "all"


class DynamicCompensator:
    """Eq. (20) with a filtered command derivative.

    Args:
        robot: The controller's model of the robot.
        loop: The controller's model of the low-level velocity loops.
        mode: Rows to compensate.
        k_d: Diagonal of ``K_D`` [1/s], one value or one per actuated velocity.
        derivative_time_constant: Low-pass time constant of ``udot`` [s].
    """

    def __init__(
        self,
        robot: MobileManipulator,
        loop: VelocityLoop,
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
        self.gain_inverse = 1.0 / loop.gains
        self.previous_u: np.ndarray | None = None
        self.u_dot = np.zeros(robot.n)

    def step(
        self, q: np.ndarray, v: np.ndarray, u: np.ndarray, dt: float
    ) -> tuple[np.ndarray, float]:
        """Velocity reference for the robot's low-level loops.

        Pinocchio gives the rigid-body terms; :func:`~pbvs_pin.kernels.compensation_law`
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
        if self.previous_u is not None and dt > 0:
            blend = dt / (self.tau + dt)
            self.u_dot = self.u_dot + blend * ((u - self.previous_u) / dt - self.u_dot)
        self.previous_u = u.copy()
        if not self.any_row:
            error = v - u
            limits = self.robot.velocity_limits
            return np.clip(u, -limits, limits), 0.5 * float(error @ error)
        model, data, selection = self.robot.model, self.robot.data, self.robot.selection
        mass = pin.crba(model, data, q)
        bias = pin.nonLinearEffects(model, data, q, selection @ v)
        gravity = pin.computeGeneralizedGravity(model, data, q)
        return compensation_law(
            mass, bias, gravity, selection, self.gain_inverse, self.loop.damping,
            self.loop.gravity_weight, self.rows, self.k_d, v, u, self.u_dot,
            self.robot.velocity_limits,
        )  # fmt: skip
