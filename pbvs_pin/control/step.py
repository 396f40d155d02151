r"""The whole control step in one compiled call, for the 1 kHz loop.

:func:`fused_control_step` composes the equations' compiled kernels exactly as the modular
classes do, each from the module named for it: the secondary objectives of eqs. (16)-(19)
(:mod:`pbvs_pin.control.secondary`), the features and Jacobians of eq. (3)
(:mod:`pbvs_pin.perception.features`), the passivity law of eq. (34)
(:mod:`pbvs_pin.control.kinematic`) and the dynamic compensation of eq. (20)
(:mod:`pbvs_pin.control.compensation`).
:class:`FusedControlStep` packs the controller's model, gains and built-in secondary
objectives once, in the buffers named by :mod:`pbvs_pin.control.layout`; then each step makes
its Pinocchio calls and one call of :func:`fused_control_step`, which also brings the newest
frame up to now when the tracker predicts (:func:`pbvs_pin.control.tracking.predict_points`,
which the tracker's NumPy reference calls too). A user's own secondary objectives
(:class:`~pbvs_pin.control.secondary.SecondaryObjective` subclasses) are evaluated in Python
before the call and enter it as one input, added to the built-in terms of ``Lambda``. It is
the controller's only path: the IBVS baseline is its feedback law
:data:`~pbvs_pin.control.kinematic.IBVS` (:mod:`pbvs_pin.control.ibvs`), and a step with
nothing to servo on runs it too (the objectives' state steps, the command is zero, eq. (20)
brakes and the command's derivative restarts from zero). The modular classes
(:meth:`PassivityController.step <pbvs_pin.control.kinematic.PassivityController.step>`,
:meth:`DynamicCompensator.step <pbvs_pin.control.compensation.DynamicCompensator.step>`, the
objectives' ``contribution``) are the reference the tests compare it with.

The equations' kernels are declared ``inline="always"``: Numba compiles their bodies into the
fused step, so that no call and no tuple of returned arrays passes between them (on the
reference robot the compiled call went from about 4.5 to 3.9 us; the modular classes call
the same kernels, compiled on their own).

Numba keys its on-disk cache on each compiled function's own file, so the cached
:func:`fused_control_step` does not notice an edit of a kernel it composes from another module.
After editing a kernel, delete the caches (``find pbvs_pin -name '*.nb[ci]' -delete``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from numba import njit

from pbvs_pin.control import layout
from pbvs_pin.control.balanced import joint_room
from pbvs_pin.control.compensation import (
    DynamicCompensator,
    compensation_law,
    filter_derivative,
)
from pbvs_pin.control.kinematic import ControlOutput, PassivityController, passivity_law
from pbvs_pin.control.secondary import (
    BUILT_IN,
    ArmPosture,
    BaseHeading,
    JointLimitAvoidance,
    ObstacleAvoidance,
    SecondaryObjective,
    add_obstacle_terms,
    heading_share,
    heading_term,
    impedance_step,
    joint_limit_term,
    obstacle_force,
    posture_term,
    secondary_input,
    secondary_vector,
)
from pbvs_pin.control.support import KeepSupported, support_barrier, support_term
from pbvs_pin.control.tracking import predict_points
from pbvs_pin.control.upright import Safety, upright_row
from pbvs_pin.exceptions import GainError
from pbvs_pin.linalg import matmul
from pbvs_pin.model.joint_angles import arm_angles
from pbvs_pin.model.support import at_origin
from pbvs_pin.perception.features import ImageMeasurement, feature_jacobians

LOCAL = pin.LOCAL
NAN = float("nan")
_NO_WORLD = np.zeros((0, 3))
"""``world`` when the step does not predict."""

if TYPE_CHECKING:
    from pbvs_pin.model.robot import MobileManipulator
    from pbvs_pin.perception.features import FeatureSet


COMPILED = (*BUILT_IN, KeepSupported)
"""The kinds of objective the compiled step computes itself, from the settings; a user's own
objectives (of any kind) are evaluated in Python at each step
(:func:`~pbvs_pin.control.secondary.contribution_of`)."""


def split_objectives(
    built_in: Sequence[SecondaryObjective], users: Sequence[SecondaryObjective]
) -> tuple[list[SecondaryObjective], tuple[SecondaryObjective, ...]]:
    """The objectives the compiled step computes, and those evaluated in Python before it.

    Compiled: the settings' objectives of the :data:`COMPILED` kinds; in Python: the settings'
    others, then the user's own.
    """
    compiled = [objective for objective in built_in if type(objective) in COMPILED]
    return compiled, (*(o for o in built_in if type(o) not in COMPILED), *users)


@njit(cache=True)
def fused_control_step(
    frame_jacobian: np.ndarray,
    rotation: np.ndarray,
    translation: np.ndarray,
    mass_upper: np.ndarray,
    bias: np.ndarray,
    gravity: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
    points: np.ndarray,
    depths: np.ndarray,
    world: np.ndarray,
    age: float,
    target_velocity: np.ndarray,
    laser: np.ndarray,
    centre: np.ndarray,
    centre_jacobian: np.ndarray,
    user_secondary: np.ndarray,
    seen: bool,
    dt: float,
    params: np.ndarray,
    indices: np.ndarray,
    state: np.ndarray,
) -> None:
    """One whole control step in one call: eqs. (16)-(19), (3), (34) and (20).

    The secondary objectives (and the obstacle impedance's state) step whether or not the
    target is seen; unseen, the command is zero and eq. (20) brakes.

    Args:
        frame_jacobian: Camera frame Jacobian, ``pin.LOCAL``. Shape (6, nv).
        rotation: ``wRc``. Shape (3, 3).
        translation: ``wtc`` [m]. Shape (3,).
        mass_upper: ``pin.crba``. Shape (nv, nv).
        bias: ``pin.nonLinearEffects`` at ``S v``. Shape (nv,).
        gravity: ``pin.computeGeneralizedGravity``. Shape (nv,).
        q: Configuration. Shape (nq,).
        v: Actuated velocity. Shape (n,).
        points: Image points [px] to servo on. Shape (k, 2). With a finite ``age``, the
            prediction is written into it.
        depths: Their depths [m]. Shape (k,); written into with a finite ``age``.
        world: The newest frame's points in the world [m]. Shape (k, 3).
        age: Time since that frame's capture [s]: predict from ``world``
            (:mod:`~pbvs_pin.control.tracking`); NaN: servo on ``points`` as given.
        target_velocity: ``phat_dot`` [m/s]. Shape (3,).
        laser: ``[d, alpha]`` of the nearest return [m, rad]. Shape (2,).
        centre: The centre of mass with the platform at the origin [m], for the support
            objective (not read when it is off). Shape (3,).
        centre_jacobian: Its Jacobian (``pin.jacobianCenterOfMass`` there). Shape (3, nv).
        user_secondary: The user's objectives' part of ``Lambda``, added to the built-in
            terms. Shape (n,).
        seen: There is a measurement (``points``, ``depths``, or the prediction) to servo on;
            False: the command is zero and ``points``, ``depths`` are not read.
        dt: Control period [s].
        params: Constant floats, :class:`~pbvs_pin.control.layout.Parameters`.
        indices: Sizes and constant integers, :class:`~pbvs_pin.control.layout.Indices`.
        state: Memory and outputs, :class:`~pbvs_pin.control.layout.State`; updated in place.
    """
    p = layout.parameter_views(params, indices)
    setting = layout.settings(p.settings)
    index = layout.index_views(indices)
    out = layout.state_views(state, indices)
    n, n_base = p.selection.shape[1], setting.n_base
    # eq. (16): Lambda from the objectives switched on
    theta = arm_angles(q, index.arm_q_indices, index.arm_continuous)
    secondary = np.zeros(n)
    if setting.posture:
        secondary[n_base:] += posture_term(
            theta, p.posture_target, setting.posture_gain, index.arm_continuous
        )
    if setting.joint_limits:
        secondary[n_base:] += joint_limit_term(
            theta, p.lower, p.upper, setting.limit_margin, setting.limit_gain
        )
    if setting.obstacle:
        distance, angle = laser[0], laser[1]
        force = obstacle_force(distance, angle, setting.k_u, setting.k_w, setting.d0, n_base == 3)
        impedance = impedance_step(
            out.impedance_velocity, force, setting.impedance_mass, setting.impedance_damping, dt
        )
        out.impedance_velocity[:] = impedance
        add_obstacle_terms(secondary, impedance, n_base)
    if setting.heading_gain > 0.0 and n_base >= 2:
        d0 = setting.d0 if setting.obstacle else 0.0
        share = heading_share(laser[0], laser[1], d0)
        heading = heading_term(rotation, q, setting.heading_gain, setting.heading_offset)
        secondary[n_base - 1] += share * heading
    others = np.zeros(n)  # the support objective's, then the user's objectives'
    if setting.support_gain > 0.0:
        turn, share = 0.0, 0.0
        if setting.support_turn_gain > 0.0 and n_base >= 2:
            turn = heading_term(rotation, q, setting.support_turn_gain, setting.support_turn_offset)
            share = heading_share(laser[0], 0.0, setting.support_d0)  # at any angle
        support_term(
            centre, centre_jacobian, p.selection[:, n_base:], p.support_normals,
            p.support_offsets, setting.support_gain, theta, p.support_target,
            index.arm_continuous, turn, share, others,
        )  # fmt: skip
    for j in range(n):  # the user's objectives, evaluated before the call
        secondary[j] += others[j] + user_secondary[j]
    if seen:
        barrier = np.zeros(n + 1)  # standing, above the image task
        barrier[0] = -np.inf
        if setting.support_gain > 0.0:
            support_barrier(
                centre, centre_jacobian, p.selection[:, n_base:], p.support_normals,
                p.support_barrier_offsets, barrier,
            )  # fmt: skip
        _servo(
            frame_jacobian, rotation, translation, points, depths, world, age, target_velocity,
            secondary, theta, barrier, dt, p, setting, index, out,
        )  # fmt: skip
    else:  # nothing to servo on: eq. (20) brakes a zero command; its derivative restarts
        _brake(out)
    # eq. (20) on the command and its derivative
    v_ref, v2 = compensation_law(
        mass_upper, bias, gravity, p.selection, p.gain_per_mass, p.gain_constant,
        p.gravity_weight, p.compensated, p.k_d, v, out.u, out.u_dot, p.velocity_limits,
    )  # fmt: skip
    out.v_ref[:] = v_ref
    out.scalars[layout.V2_SLOT] = v2


@njit(cache=True, inline="always")
def _servo(
    frame_jacobian, rotation, translation, points, depths, world, age, target_velocity,
    secondary, theta, barrier, dt, p, setting, index, out,
) -> None:  # fmt: skip
    """Eqs. (3) and (34) on what is seen, and the command's filtered derivative for eq. (20).

    Arguments as :func:`fused_control_step`'s, and ``barrier``, the support's ``[b, g]``
    (:func:`~pbvs_pin.control.support.support_barrier`); ``u`` and ``udot`` go into ``out``.
    """
    n = secondary.shape[0]
    if not np.isnan(age):  # the prediction: the frame's points moved by phat_dot, eq. (2) at q
        image, image_depths = predict_points(
            world, target_velocity, age, translation, rotation, setting.focal
        )
        points[:, :] = image
        depths[:] = image_depths
    # eq. (3)
    camera_jacobian = matmul(frame_jacobian, p.selection)
    xi, jacobian, object_jacobian = feature_jacobians(
        points, depths, index.rows, setting.focal, camera_jacobian, rotation.T
    )
    upright = upright_row(rotation, camera_jacobian)
    out.xi[:] = xi
    out.jacobian[:, :] = jacobian
    out.object_jacobian[:, :] = object_jacobian
    # eq. (34), in controller units of feature_scale px
    scale = setting.feature_scale
    error = (xi - p.xi_d) / scale
    jacobian /= scale
    object_jacobian /= scale
    safety = Safety(
        setting.upright, setting.upright_rate, setting.camera_period, setting.loop_gain_margin
    )
    room_up, room_down = joint_room(theta, p.lower, p.upper, setting.n_base, n)
    law = passivity_law(
        error, jacobian, object_jacobian, target_velocity, secondary, p.k, p.k1, p.k2,
        p.weight_inverse, p.pseudo_inverse_damping, p.velocity_limits, setting.feedback_law,
        upright, safety, room_up, room_down, barrier,
    )  # fmt: skip
    u = law.u
    # the low-pass filtered derivative of the command, for eq. (20)
    filter_derivative(
        u, out.u_previous, out.u_dot, layout.step_scalars(out.scalars).has_previous > 0.0, dt,
        setting.derivative_time_constant,
    )  # fmt: skip
    out.u[:] = u
    out.nu[:] = law.nu
    out.feedforward[:] = law.feedforward
    out.null_space[:] = law.null_space
    layout.store(
        out.scalars,
        layout.StepScalars(
            has_previous=1.0,
            valid=1.0 if law.valid else 0.0,
            storage=law.storage,
            sigma_min=law.sigma_min,
            damped=1.0 if law.damped else 0.0,
            factor=law.factor,
            v2=np.nan,  # eq. (20)'s, written after it
            loop_gain=law.gains.loop_gain,
            gain_factor=law.gains.gain_factor,
            sigma_phi=law.gains.sigma_phi,
            upright_weight=law.gains.upright_weight,
            upright_angle=upright[0],
            seen=1.0,
        ),
    )


@njit(cache=True, inline="always")
def _brake(out) -> None:
    """``u = 0`` with ``udot = 0`` for eq. (20); the next seen step restarts the derivative."""
    out.u[:] = 0.0
    out.u_previous[:] = 0.0
    out.u_dot[:] = 0.0
    out.nu[:] = 0.0
    out.feedforward[:] = 0.0
    out.null_space[:] = 0.0
    nan = np.nan
    layout.store(
        out.scalars,
        layout.StepScalars(
            has_previous=0.0, valid=0.0, storage=nan, sigma_min=nan, damped=0.0, factor=1.0,
            v2=nan, loop_gain=nan, gain_factor=1.0, sigma_phi=0.0, upright_weight=0.0,
            upright_angle=nan, seen=0.0,
        ),
    )  # fmt: skip


class FusedControlStep:
    """Eqs. (16)-(20) with one compiled call per step.

    Args:
        model: The controller's model of the robot.
        features: The feature set.
        xi_d: Desired features [px]. Shape (r,).
        controller: The kinematic controller (its gains and feedback law: the passivity law's
            or the IBVS baseline's).
        compensator: The dynamic compensator (its loop model, rows, ``K_D``).
        objectives: The settings' secondary objectives of the kinds in :data:`COMPILED` (at
            most one of each), computed inside the compiled step.
        user_objectives: The user's own objectives (whatever their kind), evaluated in Python
            before each call.

    Raises:
        GainError: If ``objectives`` holds two of one kind, or one not built in.
    """

    def __init__(
        self,
        model: MobileManipulator,
        features: FeatureSet,
        xi_d: np.ndarray,
        controller: PassivityController,
        compensator: DynamicCompensator,
        objectives: list[SecondaryObjective],
        user_objectives: tuple[SecondaryObjective, ...] = (),
    ) -> None:
        self.model = model
        n, r = model.n, features.size
        supports = [o for o in objectives if isinstance(o, KeepSupported)]
        support = supports[0] if supports else None  # two are refused below
        rows = 0 if support is None else len(support.rows.offsets)
        size = layout.Sizes(n=n, r=r, nv=model.model.nv, n_arm=model.n_arm, n_support=rows)
        self.indices = layout.pack_indices(
            size, features.rows, model.arm_q_indices, model.arm_continuous
        )
        self.params = np.zeros(layout.parameter_size(self.indices))
        p = layout.parameter_views(self.params, self.indices)
        loop = compensator.loop
        p.xi_d[:] = xi_d
        p.k[:] = controller.feature_gains(r)
        p.k1[:] = controller.k1
        p.k2[:] = controller.k2
        p.velocity_limits[:] = controller.velocity_limits
        p.pseudo_inverse_damping[:] = controller.damping
        p.gain_per_mass[:], p.gain_constant[:] = loop.loop_gain_coefficients()
        p.gravity_weight[:] = loop.gravity_weight
        p.compensated[:] = compensator.rows
        p.k_d[:] = compensator.k_d
        p.weight_inverse[:] = controller.weight_inverse
        p.lower[:], p.upper[:] = model.arm_position_limits()
        p.selection[:] = model.selection
        kinds = [type(objective) for objective in objectives]
        if len(set(kinds)) != len(kinds) or not all(kind in COMPILED for kind in kinds):
            names = ", ".join(kind.__name__ for kind in kinds)
            raise GainError(
                f"FusedControlStep objectives: expected at most one of each built-in kind "
                f"({', '.join(kind.__name__ for kind in COMPILED)}), got {names}; give others "
                "as user_objectives"
            )
        switched_on = {}
        self.user_objectives = tuple(user_objectives)
        """The user's objectives, evaluated in Python before each compiled call."""
        self._user_secondary = np.zeros(n)
        for objective in objectives:
            if isinstance(objective, ArmPosture):
                p.posture_target[:] = objective.target
                switched_on.update(posture=True, posture_gain=objective.gain)
            elif isinstance(objective, JointLimitAvoidance):
                p.lower[:], p.upper[:] = objective.lower, objective.upper
                switched_on.update(
                    joint_limits=True, limit_margin=objective.margin, limit_gain=objective.gain
                )
            elif isinstance(objective, BaseHeading):
                switched_on.update(heading_gain=objective.gain, heading_offset=objective.offset)
            elif isinstance(objective, ObstacleAvoidance):
                switched_on.update(
                    obstacle=True, k_u=objective.k_u, k_w=objective.k_w, d0=objective.d0,
                    impedance_mass=objective.mass, impedance_damping=objective.damping,
                )  # fmt: skip
            elif isinstance(objective, KeepSupported):
                p.support_normals[:] = objective.rows.normals
                p.support_offsets[:] = objective.rows.offsets
                p.support_barrier_offsets[:] = objective.barrier_offsets
                p.support_target[:] = objective.target_or_zero
                turn = objective.heading_gain if objective.turns(model.n_base) else 0.0
                switched_on.update(
                    support_gain=objective.gain, support_turn_gain=turn,
                    support_turn_offset=objective.heading_offset, support_d0=objective.d0,
                )  # fmt: skip
        p.settings[:] = layout.Settings(
            focal=model.camera.focal_px,
            feature_scale=controller.gains.feature_scale,
            feedback_law=controller.feedback_law,
            derivative_time_constant=compensator.tau,
            n_base=model.n_base,
            upright=controller.gains.upright,
            upright_rate=controller.gains.upright_rate,
            camera_period=controller.gains.camera_period,
            loop_gain_margin=controller.gains.loop_gain_margin,
            **switched_on,
        )
        self.state = np.zeros(layout.state_size(self.indices))
        self._bind_views()
        self._v2 = layout.slot(layout.StepScalars, "v2")
        self._law = controller
        k = features.n_points
        self._unseen = (np.zeros((k, 2)), np.ones(k))
        """Points and depths handed to the compiled step when nothing is seen (not read)."""
        self._pinocchio = (
            model.model,
            model.data,
            model.camera_frame_id,
            model.selection,
            np.zeros(model.model.nv),
        )
        self.support = None if support is None else (support.data, at_origin(model.neutral()))
        """The support objective's scratch ``pin.Data`` and configuration, its platform at the
        origin (:func:`~pbvs_pin.model.support.at_origin`), for the centre of mass and its
        Jacobian; None: the objective is off."""
        self._no_centre = (np.zeros(3), np.zeros((3, model.model.nv)))
        """``centre`` and ``centre_jacobian`` handed to the compiled step when the support
        objective is off (not read)."""

    def _bind_views(self) -> None:
        """Set the named views into ``params`` and ``state`` (after building or copying)."""
        p = layout.parameter_views(self.params, self.indices)
        self.xi_d = p.xi_d
        self.settings = p.settings
        """View of the constant scalars (:class:`~pbvs_pin.control.layout.Settings`)."""
        self.views = layout.state_views(self.state, self.indices)
        """Named views of ``state``, the last step's memory and outputs."""
        self._u, self._v_ref, self._scalars = self.views.u, self.views.v_ref, self.views.scalars

    def __getstate__(self) -> dict:
        """The buffers without their views: a copy (``copy.deepcopy``, pickle) rebinds them.

        A view copied on its own would be a separate array, no longer written by the step.
        """
        state = dict(self.__dict__)
        for name in ("xi_d", "settings", "views", "_u", "_v_ref", "_scalars"):
            del state[name]
        return state

    def __setstate__(self, state: dict) -> None:
        """Restore the buffers and bind the views to them."""
        self.__dict__.update(state)
        self._bind_views()

    def step(
        self,
        q: np.ndarray,
        v: np.ndarray,
        measurement: ImageMeasurement | None,
        target_velocity: np.ndarray,
        laser: np.ndarray,
        dt: float,
        predict_from: tuple[np.ndarray, float] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """Command and velocity reference for one control period.

        Args:
            q: Configuration. Shape (nq,).
            v: Measured actuated velocity. Shape (n,).
            measurement: The measurement to servo on; with ``predict_from``, the buffers the
                prediction is written into (:attr:`TargetTracker.prediction
                <pbvs_pin.control.tracking.TargetTracker.prediction>`). None: nothing to
                servo on (zero command, braked by eq. 20; the objectives' state still steps).
            target_velocity: ``phat_dot`` [m/s]. Shape (3,).
            laser: ``[d, alpha]``. Shape (2,).
            dt: Control period [s].
            predict_from: The newest frame's points in the world [m] (k, 3) and their age
                [s]: servo on their prediction (:func:`~pbvs_pin.control.tracking.predict_points`),
                written into ``measurement``.

        Returns:
            ``u`` (n,), ``v_ref`` (n,), ``V2``: views into a buffer that the next step
            overwrites. Zero ``u`` when an input is not finite.
        """
        model, data, frame, selection, v_pin = self._pinocchio
        pin.computeJointJacobians(model, data, q)
        placement = pin.updateFramePlacement(model, data, frame)
        jacobian = pin.getFrameJacobian(model, data, frame, LOCAL)
        mass = pin.crba(model, data, q)
        np.dot(selection, v, out=v_pin)
        bias = pin.nonLinearEffects(model, data, q, v_pin)
        gravity = pin.computeGeneralizedGravity(model, data, q)
        world, age = (_NO_WORLD, NAN) if predict_from is None else predict_from
        centre, centre_jacobian = self.centre_of_mass(q)
        if self.user_objectives:
            self._evaluate_user_objectives(q, placement.rotation, laser, dt)
        seen = measurement is not None
        points, depths = (measurement.points, measurement.depths) if seen else self._unseen
        fused_control_step(
            jacobian, placement.rotation, placement.translation, mass, bias, gravity, q, v,
            points, depths, world, age, target_velocity, laser, centre, centre_jacobian,
            self._user_secondary, seen, dt, self.params, self.indices, self.state,
        )  # fmt: skip
        return self._u, self._v_ref, self._scalars[self._v2]

    def centre_of_mass(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The centre of mass [m] (3,) and its Jacobian (3, nv), platform at the origin.

        The support objective's inputs (:mod:`pbvs_pin.model.support`); zeros when it is off.
        """
        if self.support is None:
            return self._no_centre
        support_data, at_origin_q = self.support
        at_origin_q[4:] = q[4:]
        jacobian = pin.jacobianCenterOfMass(self.model.model, support_data, at_origin_q)
        return support_data.com[0], jacobian

    def _evaluate_user_objectives(
        self, q: np.ndarray, rotation: np.ndarray, laser: np.ndarray, dt: float
    ) -> None:
        """The user's objectives' part of ``Lambda`` at ``q``, into ``_user_secondary``."""
        model = self.model
        state = secondary_input(model, q, laser, dt, rotation)
        self._user_secondary[:] = secondary_vector(
            self.user_objectives, state, model.n_base, model.n
        )

    def output(self) -> tuple[ControlOutput, tuple[np.ndarray, np.ndarray] | None]:
        """The last step's kinematic output and ``(J, J_o)`` [px per unit]; unseen: zeros, None.

        As :meth:`PassivityController.step
        <pbvs_pin.control.kinematic.PassivityController.step>` reports them.
        """
        views = self.views
        scalars = layout.StepScalars._make(views.scalars.tolist())
        if not scalars.seen:
            return self._law.zero_output(self.xi_d.size), None
        output = ControlOutput(
            u=views.u.copy(), error=views.xi - self.xi_d, storage=scalars.storage,
            nu=views.nu.copy(), feedforward=views.feedforward.copy(),
            null_space=views.null_space.copy(), min_singular_value=scalars.sigma_min,
            damped=bool(scalars.damped), saturated=scalars.factor < 1.0, scale=scalars.factor,
            valid=bool(scalars.valid), loop_gain=scalars.loop_gain,
            gain_limited=scalars.gain_factor < 1.0, upright_angle=scalars.upright_angle,
            upright_weight=scalars.upright_weight,
        )  # fmt: skip
        return output, (views.jacobian.copy(), views.object_jacobian.copy())
