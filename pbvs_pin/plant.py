r"""The simulated robot: eq. (1) with the robot's *true* parameters.

The low-level loops apply ``tau = K_v (v_ref - v) - D v + G g_v`` to the rigid-body dynamics
in actuated coordinates,

.. math:: M_v \dot v + C_v v + g_v = K_v (v_{ref} - v) - D v + G g_v,

which is eq. (1) multiplied by ``K_v``. The step is semi-implicit: the stiff loop and friction
terms are taken at the new velocity, so stiff servo gains stay stable at a 1 ms step,

.. math:: (M_v + h (K_v + D))\, v_{k+1} = M_v v_k + h (K_v v_{ref} - C_v v_k - (I - G) g_v),

then ``q_{k+1} = integrate(q_k, S v_{k+1} h)`` on the configuration manifold.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from pbvs_pin.dynamics import velocity_loop_step
from pbvs_pin.exceptions import GainError

if TYPE_CHECKING:
    from pbvs_pin.dynamics import VelocityLoop
    from pbvs_pin.robot import MobileManipulator


class Plant:
    """State ``(q, v)`` of the true robot, advanced by velocity references.

    Args:
        robot: The true robot.
        loop: The true low-level velocity loops.
        q: Initial configuration. Shape (nq,).
        dt: Integration step [s].
    """

    def __init__(
        self, robot: MobileManipulator, loop: VelocityLoop, q: npt.ArrayLike, dt: float = 1e-3
    ) -> None:
        if not 0 < dt <= 0.05:
            raise GainError(f"plant step: expected 0 < dt <= 0.05 s, got {dt}")
        self.robot, self.loop, self.dt = robot, loop, dt
        self.q = robot.check_configuration(q).copy()
        self.gravity_weight = loop.gravity_weight
        self._v_pin = np.zeros(robot.model.nv)
        self._displacement = np.zeros(robot.model.nv)
        self.v = np.zeros(robot.n)

    @property
    def v(self) -> np.ndarray:
        """Actuated velocity. Shape (n,)."""
        return self._v

    @v.setter
    def v(self, value: np.ndarray) -> None:
        self._v = np.asarray(value, dtype=float)
        self._v_pin = self.robot.selection @ self._v

    def step(self, v_ref: np.ndarray) -> None:
        """Advance by one step ``dt`` under the velocity reference ``v_ref`` (shape (n,)).

        Pinocchio gives the rigid-body terms; :func:`pbvs_pin.dynamics.velocity_loop_step`
        solves the semi-implicit step; ``pin.integrate`` moves ``q`` on its manifold.
        """
        model, data, selection = self.robot.model, self.robot.data, self.robot.selection
        mass = pin.crba(model, data, self.q)
        bias = pin.nonLinearEffects(model, data, self.q, self._v_pin)
        gravity = pin.computeGeneralizedGravity(model, data, self.q)
        self._v = velocity_loop_step(
            mass, bias, gravity, selection, self.loop.gains, self.loop.damping,
            self.gravity_weight, self._v, v_ref, self.dt, self._v_pin, self._displacement,
        )  # fmt: skip
        self.q = pin.integrate(model, self.q, self._displacement)
