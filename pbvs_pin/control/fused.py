"""The whole control step in one compiled call, for the 1 kHz loop.

:class:`FusedControlStep` packs the controller's model, gains and built-in secondary objectives
once, then each step makes its Pinocchio calls and one call of
:func:`pbvs_pin.kernels.fused_control_step`, which chains the same kernels the modular classes
use. A scenario with the IBVS baseline or a user-defined objective uses the modular classes.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from pbvs_pin import kernels
from pbvs_pin.control.compensation import DynamicCompensator
from pbvs_pin.control.ibvs import ClassicIbvs
from pbvs_pin.control.kinematic import ControlOutput, PassivityController
from pbvs_pin.control.secondary import (
    ArmPosture,
    JointLimitAvoidance,
    ObstacleAvoidance,
    SecondaryObjective,
)

LOCAL = pin.LOCAL

if TYPE_CHECKING:
    from pbvs_pin.features import FeatureSet, ImageMeasurement
    from pbvs_pin.robot import MobileManipulator


class FusedControlStep:
    """Eqs. (16)-(20) with one compiled call per step.

    Args:
        model: The controller's model of the robot.
        features: The feature set.
        xi_d: Desired features [px]. Shape (r,).
        controller: The passivity controller (its gains).
        compensator: The dynamic compensator (its loop model, rows, ``K_D``).
        objectives: Built-in secondary objectives (at most one of each kind).
    """

    def __init__(
        self,
        model: MobileManipulator,
        features: FeatureSet,
        xi_d: np.ndarray,
        controller: PassivityController,
        compensator: DynamicCompensator,
        objectives: list[SecondaryObjective],
    ) -> None:
        self.model = model
        n, r = model.n, features.size
        n_arm = model.n_arm
        self.indices = np.concatenate(
            [
                [n, r, model.model.nv, n_arm],
                features.rows,
                model.arm_q_indices,
                model.arm_continuous,
            ]
        ).astype(np.int64)
        self.params = np.zeros(kernels.parameter_size(self.indices))
        desired, k, dof, weight_inverse, arm, scalars, selection = kernels.parameter_views(
            self.params, self.indices
        )
        desired[:] = xi_d
        k[:] = controller.feature_gains(r)
        loop = compensator.loop
        dof[:] = (
            controller.k1, controller.k2, controller.velocity_limits, 1.0 / loop.gains,
            loop.damping, loop.gravity_weight, compensator.rows, compensator.k_d,
        )  # fmt: skip
        weight_inverse[:] = controller.weight_inverse
        arm[1], arm[2] = model.arm_position_limits()
        selection[:] = model.selection
        gains = controller.gains
        scalars[:7] = (
            model.camera.focal_px,
            gains.feature_scale,
            gains.damping_threshold,
            gains.max_damping,
            float(gains.use_pseudoinverse_feedback),
            compensator.tau,
            model.n_base,
        )
        for objective in objectives:
            if isinstance(objective, ArmPosture):
                arm[0] = objective.target
                scalars[7:9] = 1.0, objective.gain
            elif isinstance(objective, JointLimitAvoidance):
                arm[1], arm[2] = objective.lower, objective.upper
                scalars[9:12] = 1.0, objective.margin, objective.gain
            elif isinstance(objective, ObstacleAvoidance):
                scalars[12:18] = (
                    1.0, objective.k_u, objective.k_w, objective.d0, objective.mass,
                    objective.damping,
                )  # fmt: skip
        self.xi_d = desired
        self.state = np.zeros(kernels.state_size(self.indices))
        self.memory, self.out, self.jacobian, self.object_jacobian = kernels.state_views(
            self.state, self.indices
        )
        self.n, self.r = n, r
        self._u, self._v_ref = self.out[0, :n], self.out[1, :n]
        self._pinocchio = (
            model.model,
            model.data,
            model.camera_frame_id,
            model.selection,
            np.zeros(model.model.nv),
        )

    @staticmethod
    def supports(controller: PassivityController, objectives: list[SecondaryObjective]) -> bool:
        """Whether the fused step reproduces this controller and these objectives."""
        kinds = [type(objective) for objective in objectives]
        built_in = all(
            kind in (ArmPosture, JointLimitAvoidance, ObstacleAvoidance) for kind in kinds
        )
        return (
            not isinstance(controller, ClassicIbvs) and built_in and len(set(kinds)) == len(kinds)
        )

    def step(
        self,
        q: np.ndarray,
        v: np.ndarray,
        measurement: ImageMeasurement,
        target_velocity: np.ndarray,
        laser: np.ndarray,
        dt: float,
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """Command and velocity reference for one control period.

        Args:
            q: Configuration. Shape (nq,).
            v: Measured actuated velocity. Shape (n,).
            measurement: The newest image measurement.
            target_velocity: ``phat_dot`` [m/s]. Shape (3,).
            laser: ``[d, alpha]``. Shape (2,).
            dt: Control period [s].

        Returns:
            ``u`` (n,), ``v_ref`` (n,), ``V2``: views into a buffer that the next step
            overwrites. Zero ``u`` when an input is not finite.
        """
        model, data, frame, selection, v_pin = self._pinocchio
        pin.computeJointJacobians(model, data, q)
        rotation = pin.updateFramePlacement(model, data, frame).rotation
        jacobian = pin.getFrameJacobian(model, data, frame, LOCAL)
        mass = pin.crba(model, data, q)
        np.dot(selection, v, out=v_pin)
        bias = pin.nonLinearEffects(model, data, q, v_pin)
        gravity = pin.computeGeneralizedGravity(model, data, q)
        kernels.fused_control_step(
            jacobian, rotation, mass, bias, gravity, q, v, measurement.points,
            measurement.depths, target_velocity, laser, dt, self.params, self.indices, self.state,
        )  # fmt: skip
        return self._u, self._v_ref, self.out[5, 5]

    def output(self) -> tuple[ControlOutput, tuple[np.ndarray, np.ndarray]]:
        """The last step's diagnostics, as the modular controller reports them."""
        out, n = self.out.copy(), self.n
        valid, storage, sigma_min, damped, factor, _ = out[5, :6]
        output = ControlOutput(
            u=out[0, :n], error=out[6, : self.r] - self.xi_d, storage=storage, nu=out[2, :n],
            feedforward=out[3, :n], null_space=out[4, :n], min_singular_value=sigma_min,
            damped=bool(damped), saturated=factor < 1.0, scale=factor, valid=bool(valid),
        )  # fmt: skip
        return output, (self.jacobian.copy(), self.object_jacobian.copy())
