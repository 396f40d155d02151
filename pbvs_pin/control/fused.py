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

from pbvs_pin.control.compensation import DynamicCompensator
from pbvs_pin.control.ibvs import ClassicIbvs
from pbvs_pin.control.kinematic import ControlOutput, PassivityController
from pbvs_pin.control.secondary import (
    ArmPosture,
    JointLimitAvoidance,
    ObstacleAvoidance,
    SecondaryObjective,
)
from pbvs_pin.kernels import fused_control_step

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
        gains = controller.gains
        loop = compensator.loop
        self.rows = np.asarray(features.rows, dtype=np.int64)
        self.xi_d = np.asarray(xi_d, dtype=float)
        self.k = controller.feature_gains(r)
        self.dof = np.vstack(
            [
                controller.k1,
                controller.k2,
                controller.velocity_limits,
                1.0 / loop.gains,
                loop.damping,
                loop.gravity_weight,
                compensator.rows.astype(float),
                compensator.k_d,
            ]
        )
        self.weight_inverse = controller.weight_inverse
        self.arm = np.zeros((3, model.n_arm))
        self.arm[1], self.arm[2] = model.arm_position_limits()
        scalars = np.zeros(18)
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
                self.arm[0] = objective.target
                scalars[7:9] = 1.0, objective.gain
            elif isinstance(objective, JointLimitAvoidance):
                self.arm[1], self.arm[2] = objective.lower, objective.upper
                scalars[9:12] = 1.0, objective.margin, objective.gain
            elif isinstance(objective, ObstacleAvoidance):
                scalars[12:18] = (
                    1.0, objective.k_u, objective.k_w, objective.d0, objective.mass,
                    objective.damping,
                )  # fmt: skip
        self.scalars = scalars
        self.memory = np.zeros((3, max(n, 3)))
        self.out = np.zeros((7, max(n, r, 6)))
        self.jacobian = np.zeros((r, n))
        self.object_jacobian = np.zeros((r, 3))
        self.n, self.r = n, r

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
        robot = self.model
        model, data, frame = robot.model, robot.data, robot.camera_frame_id
        pin.computeJointJacobians(model, data, q)
        rotation = pin.updateFramePlacement(model, data, frame).rotation
        jacobian = pin.getFrameJacobian(model, data, frame, pin.LOCAL)
        mass = pin.crba(model, data, q)
        bias = pin.nonLinearEffects(model, data, q, robot.selection.dot(v))
        gravity = pin.computeGeneralizedGravity(model, data, q)
        out = self.out
        fused_control_step(
            jacobian, rotation, mass, bias, gravity, q, v, measurement.points,
            measurement.depths, target_velocity, laser, dt, self.memory, robot.selection,
            self.rows, self.xi_d, self.k, self.dof, self.weight_inverse, self.arm,
            robot.arm_q_indices, robot.arm_continuous, self.scalars, out, self.jacobian,
            self.object_jacobian,
        )  # fmt: skip
        return out[0, : self.n], out[1, : self.n], out[5, 5]

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
