r"""A payload in the MuJoCo plant that the robot's servos do not know of.

``[model_error] payload`` puts a small solid sphere of mass ``m`` at the camera frame's origin
(the end-effector) of the true robot only. MuJoCo simulates it (it is welded to the body of the
camera frame's parent joint, whose inertia it joins when the model compiles). The servos were
tuned on the robot without it, so the arm servos of :mod:`pbvs_pin.plant.mujoco_plant` schedule
their stiffness with the mass matrix without the payload,

.. math:: M_{nominal} = M - m J_p^T J_p - i J_r^T J_r,

and cancel the gravity load without it, ``g_{nominal,j} = g_j - m g_0 (J_p)_{z j}``: ``J_p`` and
``J_r`` are the translational and rotational Jacobians of the payload's centre (``mj_jac``)
and ``i = 2 m \rho^2 / 5`` the moment of inertia of the sphere of
:meth:`pbvs_pin.model.robot.MobileManipulator.with_payload`. The gravity correction is passed to
the servo law as the subtree masses and centres of mass without the payload, which give
exactly that load in :func:`pbvs_pin.plant.mujoco_plant.arm_gravity_load`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

from pbvs_pin.exceptions import GainError
from pbvs_pin.model.robot import PAYLOAD_RADIUS

if TYPE_CHECKING:
    from pbvs_pin.model.robot import MobileManipulator


class UnknownPayload:
    """A payload welded at the camera frame's origin, and the servos' view without it.

    Args:
        spec: The MuJoCo spec of the true robot (modified: the payload body is added).
        robot: The true robot (its camera frame places the payload).
        mass: Payload [kg], > 0.
    """

    def __init__(self, spec: mujoco.MjSpec, robot: MobileManipulator, mass: float) -> None:
        if not (np.isfinite(mass) and mass > 0):
            raise GainError(f"payload: expected a mass > 0 kg, got {mass}")
        frame = robot.model.frames[robot.camera_frame_id]
        self.parent = spec.joint(robot.model.names[frame.parentJoint]).parent.name
        self.offset = np.array(frame.placement.translation, dtype=float)
        self.mass = float(mass)
        self.moment = 0.4 * mass * PAYLOAD_RADIUS**2
        spec.body(self.parent).add_body(
            name="payload",
            pos=self.offset,
            ipos=[0.0, 0.0, 0.0],  # explicit: left unset, MuJoCo places the centre elsewhere
            mass=self.mass,
            inertia=[self.moment] * 3,
        )

    def attach(
        self,
        model: mujoco.MjModel,
        arm_joint: np.ndarray,
        arm_body: np.ndarray,
        weight: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bind to the compiled model; the arrays :meth:`servo_view` keeps current.

        Args:
            model: The compiled model.
            arm_joint: Joint id of each arm joint. Shape (n_arm,).
            arm_body: Its body id. Shape (n_arm,).
            weight: ``m_j g_0`` of each arm joint's subtree, with the payload [N].
                Shape (n_arm,).

        Returns:
            The mass matrix (nv, nv) and the subtree centres of mass (nbody, 3) without the
            payload, written by every :meth:`servo_view`, and the subtree weights without it
            (n_arm,), constant.
        """
        self._body = model.body(self.parent).id
        carried = []
        for joint in arm_joint:
            body, above = self._body, model.jnt_bodyid[joint]
            while body > 0 and body != above:
                body = model.body_parentid[body]
            carried.append(body == above)
        self._carried = np.flatnonzero(carried)
        self._arm_body = arm_body
        self._payload_weight = self.mass * -model.opt.gravity[2]
        self._weight = weight
        self._jacp = np.zeros((3, model.nv))
        self._jacr = np.zeros((3, model.nv))
        self.servo_mass = np.zeros((model.nv, model.nv))
        self.servo_com = np.zeros((model.nbody, 3))
        self.servo_weight = weight.copy()
        self.servo_weight[self._carried] -= self._payload_weight
        return self.servo_mass, self.servo_com, self.servo_weight

    def servo_view(self, model: mujoco.MjModel, data: mujoco.MjData, full_mass: np.ndarray) -> None:
        """Write the mass matrix and subtree centres of mass without the payload.

        Args:
            model: The compiled model.
            data: Its data after ``mj_step1`` (positions and kinematics current).
            full_mass: MuJoCo's dense mass matrix with the payload. Shape (nv, nv).
        """
        point = data.xpos[self._body] + data.xmat[self._body].reshape(3, 3) @ self.offset
        mujoco.mj_jac(model, data, self._jacp, self._jacr, point, self._body)
        self.servo_mass[:] = (
            full_mass
            - self.mass * self._jacp.T @ self._jacp
            - self.moment * self._jacr.T @ self._jacr
        )
        self.servo_com[:] = data.subtree_com
        for j in self._carried:
            body = self._arm_body[j]
            self.servo_com[body] = (
                self._weight[j] * data.subtree_com[body] - self._payload_weight * point
            ) / self.servo_weight[j]
