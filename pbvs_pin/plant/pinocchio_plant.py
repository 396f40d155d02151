r"""The simulated robot: eq. (1) with the robot's *true* parameters and its URDF's servos.

The servos of :mod:`pbvs_pin.model.servo` apply their torque to the rigid-body dynamics in actuated
coordinates, with the URDF's damping and friction, effort and speed limits, and joint stops:

.. math:: M_v \dot v + C_v v + g_v + D v + F \tanh(v / v_s) = \tau + \tau_{stop}.

The step is linearly implicit (:func:`pbvs_pin.model.servo.servo_step`): the stiff servo, damping
and friction slope are taken at the new velocity, so stiff servos stay stable at a 1 ms step;
then ``q_{k+1} = integrate(q_k, S v_{k+1} h)`` on the configuration manifold.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from pbvs_pin.exceptions import GainError
from pbvs_pin.model.base import DifferentialDrive
from pbvs_pin.model.servo import pack_servos, packed_servo_step

if TYPE_CHECKING:
    from pbvs_pin.model.robot import MobileManipulator
    from pbvs_pin.model.servo import ServoModel


class Plant:
    """State ``(q, v)`` of the true robot, advanced by velocity references.

    A differential drive's wheels are not in the state; :attr:`wheel_angles` integrates the
    wheel rotations that the no-slip motion implies, ``w = W [v_x, v_y, omega_z]``
    (:meth:`pbvs_pin.model.base.DifferentialDrive.wheel_map`), so that the wheel encoders read the
    same quantity on both engines (:class:`pbvs_pin.plant.mujoco_plant.MujocoPlant`).

    Args:
        robot: The true robot.
        loop: The true robot's servos.
        q: Initial configuration. Shape (nq,).
        dt: Integration step [s].
        tuned: The robot the servos were tuned on, when it is not the true robot (a payload
            they do not know of): their stiffness is scheduled with its mass matrix and they
            cancel its gravity load. Same joints as ``robot``.
    """

    def __init__(
        self,
        robot: MobileManipulator,
        loop: ServoModel,
        q: npt.ArrayLike,
        dt: float = 1e-3,
        tuned: MobileManipulator | None = None,
    ) -> None:
        if not 0 < dt <= 0.05:
            raise GainError(f"plant step: expected 0 < dt <= 0.05 s, got {dt}")
        self.robot, self.loop, self.dt, self.tuned = robot, loop, dt, tuned
        self.q = robot.check_configuration(q).copy()
        self.gravity_weight = loop.gravity_weight
        self._params, self._indices = pack_servos(loop, robot.selection, self.gravity_weight, dt)
        self._v_pin = np.zeros(robot.model.nv)
        self._displacement = np.zeros(robot.model.nv)
        self.integral = np.zeros(robot.n)  # the servos' integral states
        self.v = np.zeros(robot.n)
        drive = robot.base
        self._wheel_map = drive.wheel_map() if isinstance(drive, DifferentialDrive) else None
        self.wheel_angles = np.zeros(2)
        """Left and right wheel angles [rad] (zero at the start). Shape (2,)."""

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

        Pinocchio gives the rigid-body terms; :func:`pbvs_pin.model.servo.servo_step` solves the
        linearly implicit step; ``pin.integrate`` moves ``q`` on its manifold.
        """
        model, data = self.robot.model, self.robot.data
        mass = pin.crba(model, data, self.q)
        bias = pin.nonLinearEffects(model, data, self.q, self._v_pin)
        gravity = pin.computeGeneralizedGravity(model, data, self.q)
        servo_mass = mass
        if self.tuned is not None:  # the servos' own view: the robot they were tuned on
            tuned = self.tuned
            servo_mass = pin.crba(tuned.model, tuned.data, self.q)
            gravity = pin.computeGeneralizedGravity(tuned.model, tuned.data, self.q)
        self._v = packed_servo_step(
            mass, servo_mass, bias, gravity, self._params, self._indices, self.q, self._v,
            np.asarray(v_ref, dtype=float), self.integral, self._v_pin, self._displacement,
        )  # fmt: skip
        self.q = pin.integrate(model, self.q, self._displacement)
        if self._wheel_map is not None:
            self.wheel_angles += self._wheel_map @ self._displacement[:3]
