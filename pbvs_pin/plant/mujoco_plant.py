r"""An independent plant: MuJoCo physics of the controller's URDF, wheels rolling on the ground.

The :class:`pbvs_pin.plant.pinocchio_plant.Plant` integrates the controller's own Pinocchio model
with the no-side-slip constraint built in. :class:`MujocoPlant` instead builds a MuJoCo model from
the *same assembled URDF* (:attr:`pbvs_pin.model.robot.MobileManipulator.urdf_xml`, through MuJoCo's
own URDF importer and ``MjSpec``): the platform's root body gets a free joint, its drive wheels are
cylinders (the URDF's, or built from the drive keys) that roll with friction on a ground plane,
and every wheel and arm joint is driven by a velocity servo

.. math:: \tau_j = \mathrm{clip}\big(K_j(q) (r_j - \dot q_j) + D_j r_j + F_j \tanh(r_j / v_s)
          + G_j\, g_j(q),\ \pm \tau_{j,max}\big),\quad r_j = \mathrm{clip}(\dot q_{j,ref},
          \pm v_{j,max}),

the servo of :class:`pbvs_pin.model.servo.ServoModel` (the one the Pinocchio plant applies): the
stiffness ``K_j(q) = sum_k |M_v,jk(q)| / T_j`` scheduled with MuJoCo's own mass matrix in the
actuated velocities, the URDF's effort as ``tau_max`` (MuJoCo joint ``actuatorfrcrange``), the
URDF's damping and friction as MuJoCo joint ``damping``/``frictionloss`` (fed forward by the
servo), and the URDF's limits as MuJoCo joint limits; ``G_j g_j`` is the servo's cancellation
of its own gravity load. The platform command ``[u, omega]`` (clipped to the servo's speed
limits) passes the first-order lags of the platform's time constants in
:class:`pbvs_pin.model.servo.ServoModel` (0.26 s and 0.23 s, a Pioneer's identified response), as a
platform's controller shapes its speed commands; so the platform responds as on the Pinocchio
plant and as the dynamic compensation (eq. 20) assumes. (Without the lags the wheels' servos
of the time, 0.05 s, drove the platform five times faster than eq. 20's model, which then
over-compensated: TIAGo's Experiment 2 oscillated at 9.5 px RMS above 0.5 Hz, 1.8 px with
compensation off.) The wheel servos are stiff enough that the platform's response is those
lags (:data:`WHEEL_TIME_CONSTANT`, :data:`SKID_STEER_WHEEL_TIME_CONSTANT` say how it was
measured). The lagged command becomes wheel speeds ``w_l = (u - omega b / 2) / r``,
``w_r = (u + omega b / 2) / r``
(wheel radius ``r``, each clipped at the wheels' speed limit), the inverse of
``u = r (w_l + w_r) / 2``, ``omega = r (w_r - w_l) / b``, with ``b`` the drive's *effective*
track ``chi * track`` (:class:`pbvs_pin.model.base.DifferentialDrive`; ``chi = 1`` for two wheels).
Whether the platform then moves as a unicycle is up to the contacts: a skid-steer platform
slips, sideways and, in MuJoCo, more than ``chi`` predicts (a Pioneer 3-AT spinning in place at
0.4 rad/s turns at 0.30 of ``r (w_r - w_l) / b`` with ``chi`` = 1.46, at 0.24 with ``chi``
= 1; its wheels stick and slip, their speeds' standard deviation 0.3-0.5 rad/s about their
0.73 rad/s; the Coulomb balance behind ``chi`` gives 1 / chi = 0.68). So a
skid-steer platform closes a yaw-rate loop on its gyro (:data:`YAW_INTEGRAL_TIME`), as the
Pioneer 3-AT's controller can: the yaw rate the wheels are asked for is
``omega + e_g / T_g``, ``e_g = \int (omega - omega_gyro) dt``, clamped at the yaw-rate limit.

Contacts (:mod:`pbvs_pin.plant.mujoco_spec` builds them): only platform geometry meets the
ground. Drive wheels have Coulomb friction :data:`~pbvs_pin.plant.mujoco_spec.WHEEL_FRICTION`
(condim 3; MuJoCo's default pyramidal cone and Newton solver, 2x faster than the elliptic cone
here); the platform's other primitive collision shapes (chassis, ball casters) are frictionless
supports; arm geometry and meshes are dropped (visual meshes are optional, inertias come from
the URDF's ``<inertial>`` only). The step is ``implicitfast``, so servo gains and damping are
integrated implicitly and stiff servos are
stable at a 1 ms step.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from pbvs_pin.exceptions import GainError, UrdfError
from pbvs_pin.plant.mujoco_kernels import arm_gravity_load, servo_commands, true_state
from pbvs_pin.plant.mujoco_payload import UnknownPayload
from pbvs_pin.plant.mujoco_spec import PLANAR_JOINTS, WHEEL_FRICTION, build_spec
from pbvs_pin.plant.mujoco_stability import warn_if_tipping

if TYPE_CHECKING:
    from pbvs_pin.model.robot import MobileManipulator
    from pbvs_pin.model.servo import ServoModel

WHEEL_TIME_CONSTANT = 0.02
"""Time constant [s] of the wheel servos' proportional action on the forward speed, wheels
not slipping: ``k_w = m r^2 / (N tau_w)`` for a robot of mass ``m`` on ``N`` drive wheels; for
one wheel per side, chosen so that the yaw rate follows the controller's platform lag
(``docs/zoo.rst`` has the open-loop measurements; ``tests/test_mujoco_plant.py`` checks it)."""

SKID_STEER_WHEEL_TIME_CONSTANT = 0.005
"""``tau_w`` [s] of a skid-steer platform's wheel servos (``track_factor`` above 1): to turn,
its wheels scrub sideways against Coulomb friction, which 0.05 s servos overcame only after a
large speed error (the yaw rate lagged the model's by 125 degrees at 0.7 Hz, ``docs/zoo.rst``)."""

WHEEL_INTEGRAL_TIME = 0.1
r"""Integral time ``T_i`` [s] of the wheel servos: the forward loop
``m r^2 / N \ddot e + k_w \dot e + k_w / T_i e = 0`` has damping ratio ``sqrt(T_i / tau_w) / 2``
(1.1 with :data:`WHEEL_TIME_CONSTANT`, 1.6 with the skid-steer pair)."""

SKID_STEER_WHEEL_INTEGRAL_TIME = 0.05
"""``T_i`` [s] of a skid-steer platform's wheel servos."""

YAW_INTEGRAL_TIME = 0.05
r"""Integral time ``T_g`` [s] of the platform's yaw-rate loop on its gyro: the yaw rate that
the wheels are asked for is ``omega + e_g / T_g`` with ``e_g = \int (omega - omega_gyro) dt``.
A skid-steer platform whose wheels reach their speeds turns at ``rho omega`` with ``rho < 1``
(its slip, which depends on the load, the floor and the rate); the loop's closed-loop time
constant is then ``T_g / rho``, 0.1-0.5 s, no slower than the platform servo the controller's
model assumes."""

JOINT_LIMIT_TIME_CONSTANT = 0.004
"""Time constant [s] of an arm joint's limit in MuJoCo (``solref``; MuJoCo's default 0.02 s,
and never below two steps): a stop, not a rubber pad. With the default, Stretch RE1's servo
drove a telescoping segment 12.6 mm past its stop in Experiment 4's first 3 s (the rule allows
10); with 0.004 s, 1.0 mm."""

HOLONOMIC_TIME_CONSTANT = 0.01
"""Time constant [s] of a holonomic base's joint servos (its slides': mass over gain; its yaw's:
inertia over gain): fast beside the platform's lags of :class:`pbvs_pin.model.servo.ServoModel`,
so that the base responds as the Pinocchio plant's does."""


class MujocoPlant:
    """The robot simulated by MuJoCo, with the Pinocchio plant's interface.

    That of :class:`pbvs_pin.plant.pinocchio_plant.Plant`.

    Args:
        robot: The true robot (its ``urdf_xml`` is the MuJoCo model's source).
        servo: The robot's servos (:meth:`pbvs_pin.model.servo.ServoModel.from_robot`): the arm
            joints' time constants, damping and friction feed-forward, effort and speed limits
            and gravity compensation; the platform's speed limits bound the wheel references.
            The wheels have their own servos (a skid-steer platform has no servo on ``u`` and
            ``omega``; each wheel's motor controller has one). A holonomic base has no wheels:
            its planar joints' servos (:data:`HOLONOMIC_TIME_CONSTANT`) replace them, and the
            wheel and yaw-loop arguments below do not apply to it.
        q: Initial configuration of the controller's model. Shape (nq,).
        dt: Integration step [s].
        friction: Sliding friction coefficient of the drive wheels on the ground.
        wheel_time_constant: Forward-speed time constant ``tau_w`` [s] of the wheel servos'
            proportional action, wheels not slipping, on the URDF's masses; None: by the
            drive (:data:`WHEEL_TIME_CONSTANT`, :data:`SKID_STEER_WHEEL_TIME_CONSTANT`).
        wheel_integral_time: Integral time ``T_i`` [s] of the wheel servos' integral action;
            None: by the drive (:data:`WHEEL_INTEGRAL_TIME`,
            :data:`SKID_STEER_WHEEL_INTEGRAL_TIME`).
        yaw_integral_time: Integral time ``T_g`` [s] of a skid-steer platform's yaw-rate loop
            on its gyro (:data:`YAW_INTEGRAL_TIME`); None: no gyro, the wheels get the speeds
            of ``[u, omega]`` only. A platform with one wheel per side (``track_factor`` 1)
            does not slip sideways and has no yaw loop (on TIAGo the loop's integral would
            only add overshoot to its yaw servo).
        mass_scale: Factor on every body's mass and inertia of the URDF (a model error: the
            true robot heavier than the URDF says).
        payload: Mass [kg] at the camera frame's origin that the servos do not know of
            (:class:`pbvs_pin.plant.mujoco_payload.UnknownPayload`; 0: none).
        settle: Time [s] the robot stands still under zero references before the run starts,
            so that the wheels settle on the ground (0: start as placed).

    Attributes:
        model: The ``mujoco.MjModel``.
        data: Its ``mujoco.MjData``.
        axle: The drive axle found in the URDF.
    """

    def __init__(
        self,
        robot: MobileManipulator,
        servo: ServoModel,
        q: npt.ArrayLike,
        dt: float = 1e-3,
        friction: float = WHEEL_FRICTION,
        wheel_time_constant: float | None = None,
        wheel_integral_time: float | None = None,
        yaw_integral_time: float | None = YAW_INTEGRAL_TIME,
        mass_scale: float = 1.0,
        payload: float = 0.0,
        settle: float = 0.0,
    ) -> None:
        if not 0 < dt <= 0.05:
            raise GainError(f"plant step: expected 0 < dt <= 0.05 s, got {dt}")
        skid = getattr(robot.base, "track_factor", 1.0) != 1.0  # a skid-steer platform
        if wheel_time_constant is None:
            wheel_time_constant = SKID_STEER_WHEEL_TIME_CONSTANT if skid else WHEEL_TIME_CONSTANT
        if wheel_integral_time is None:
            wheel_integral_time = SKID_STEER_WHEEL_INTEGRAL_TIME if skid else WHEEL_INTEGRAL_TIME
        for name, value in (
            ("wheel_time_constant", wheel_time_constant),
            ("wheel_integral_time", wheel_integral_time),
            ("yaw_integral_time", 1.0 if yaw_integral_time is None else yaw_integral_time),
            ("mass_scale", mass_scale),
        ):
            if not (np.isfinite(value) and value > 0):
                raise GainError(f"{name}: expected > 0, got {value}")
        if not (np.isfinite(settle) and settle >= 0):
            raise GainError(f"settle: expected >= 0 s, got {settle}")
        self.robot, self.servo, self.dt = robot, servo, dt
        self.wheel_integral_time = wheel_integral_time
        spec, self.axle = build_spec(robot, friction)
        spec.option.timestep = dt
        mass = sum(body.mass for body in spec.bodies)  # the URDF's, which the servos are tuned on
        for body in spec.bodies:
            body.mass *= mass_scale
            body.inertia = np.asarray(body.inertia) * mass_scale
            body.fullinertia = np.asarray(body.fullinertia) * mass_scale  # NaN when unused
        self.payload = UnknownPayload(spec, robot, payload) if payload != 0 else None
        drive = robot.base
        self.holonomic = self.axle is None
        wheel_joints = () if self.holonomic else self.axle.wheel_joints
        wheel_gain = 1.0
        if not self.holonomic:
            wheel_gain = mass * drive.wheel_radius**2 / (len(wheel_joints) * wheel_time_constant)
        for name in wheel_joints:
            spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            spec.actuator(name).set_to_velocity(kv=wheel_gain)
        n_base = robot.n_base
        for name, effort in zip(robot.arm_joint_names, servo.effort[n_base:], strict=True):
            spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            spec.actuator(name).set_to_velocity(kv=1.0)  # scheduled at every step
            joint = spec.joint(name)
            joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_TRUE
            joint.solref_limit = [JOINT_LIMIT_TIME_CONSTANT, 1.0]
            if not np.isfinite(effort):
                joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE
            else:
                joint.actfrcrange = [-effort, effort]
        for name, _, _ in PLANAR_JOINTS if self.holonomic else ():
            spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            spec.actuator(name).set_to_velocity(kv=mass / HOLONOMIC_TIME_CONSTANT)  # yaw: below
        try:
            self.model = spec.compile()
        except ValueError as err:
            raise UrdfError(robot.source, f"MuJoCo cannot compile the model: {err}") from err
        self.data = mujoco.MjData(self.model)
        model = self.model
        joint = [model.joint(name) for name in robot.arm_joint_names]
        self._arm_qpos = np.array([j.qposadr[0] for j in joint])
        self._arm_dof = np.array([j.dofadr[0] for j in joint])
        self._arm_joint = np.array([j.id for j in joint])
        self._arm_body = model.jnt_bodyid[self._arm_joint]
        self._arm_slide = model.jnt_type[self._arm_joint] == mujoco.mjtJoint.mjJNT_SLIDE
        self._weight = model.body_subtreemass[self._arm_body] * -model.opt.gravity[2]
        self._inverse_time_constants = 1.0 / servo.time_constants[n_base:]
        self._damping = np.ascontiguousarray(servo.damping[n_base:], dtype=float)
        self._friction = np.ascontiguousarray(servo.friction[n_base:], dtype=float)
        self._compensated = np.asarray(servo.gravity_compensated[n_base:], dtype=float)
        self._integral_rates = np.ascontiguousarray(servo.integral_rates[n_base:], dtype=float)
        self._arm_effort = np.ascontiguousarray(servo.effort[n_base:], dtype=float)
        self.arm_integral = np.zeros(robot.n_arm)  # the arm servos' integral states
        self._full_mass = np.zeros((model.nv, model.nv))
        wheels = [model.joint(name) for name in wheel_joints]
        left = model.body_pos[[j.bodyid[0] for j in wheels], 1] > 0.0
        self._wheel_dof = np.array([j.dofadr[0] for j in wheels], dtype=np.int64)
        self._wheel_qpos = np.array([j.qposadr[0] for j in wheels], dtype=np.int64)
        self._wheel_map = np.zeros((0, n_base))  # a holonomic base: no wheels
        self._wheel_sides = np.zeros((2, 0))
        if wheels:
            # each wheel's row of the drive's map from [u, omega] (its side's)
            self._wheel_map = drive.wheel_map()[np.where(left, 0, 1)][:, [0, 2]].copy()
            sides = np.array([left, ~left], dtype=float)  # rows: left, right
            self._wheel_sides = sides / sides.sum(axis=1, keepdims=True)
        self._n_wheels = len(wheels)
        # a wheel without an effort limit (wheels built from the drive keys, a URDF's 0) gets
        # the torque its share of the weight lets the floor take: more only spins the wheel
        effort = model.jnt_actfrcrange[[j.id for j in wheels], 1]
        if wheels:
            weight = mass * -model.opt.gravity[2]
            traction = friction * weight * drive.wheel_radius / len(wheels)
            effort = np.where(effort > 0.0, effort, traction)
        self._integral_limit = effort * wheel_integral_time / wheel_gain
        self._wheel_integral = np.zeros(len(wheels))
        self._wheel_speed_limit = 0.0 if self.holonomic else drive.max_wheel_speed
        if not skid:  # a holonomic base, or one wheel per side: no yaw loop
            yaw_integral_time = None
        self._yaw_gain = 0.0 if yaw_integral_time is None else 1.0 / yaw_integral_time
        self._yaw_integral_limit = (
            0.0 if yaw_integral_time is None else servo.speed_limits[1] * yaw_integral_time
        )
        self._yaw_integral = np.zeros(1)
        self._platform_state = np.zeros(n_base)
        self._platform_blend = 1.0 - np.exp(-dt / servo.time_constants[:n_base])
        self._neutral = robot.neutral()
        self._qpos, self._qvel = self.data.qpos, self.data.qvel  # views, valid for data's life
        self._q: np.ndarray | None = None
        data = self.data  # the arguments of servo_commands, views that stay valid
        servo_mass, servo_com, servo_weight = self._full_mass, data.subtree_com, self._weight
        if self.payload is not None:  # the servos see the robot without it
            servo_mass, servo_com, servo_weight = self.payload.attach(
                model, self._arm_joint, self._arm_body, self._weight
            )
        self._state_arguments = (
            servo_mass, data.qvel, data.xmat[1], data.xaxis, data.xanchor, servo_com,
        )  # fmt: skip
        self._servo_arguments = (
            servo.speed_limits, robot.n_base, self._platform_state, self._platform_blend,
            self._wheel_map, self._wheel_dof,
            self._wheel_speed_limit, self._wheel_integral, self._integral_limit,
            wheel_integral_time, self._yaw_integral, self._yaw_gain, self._yaw_integral_limit,
            self.holonomic,
            self._arm_dof, self._arm_joint, self._arm_body, self._arm_slide, servo_weight,
            self._inverse_time_constants, self._damping, self._friction, servo.friction_speed,
            self._compensated, self._integral_rates, self._arm_effort, self.arm_integral, dt,
            model.actuator_gainprm, model.actuator_biasprm, data.ctrl,
        )  # fmt: skip
        self.reset(q)
        if self.holonomic:
            self._set_yaw_servo(HOLONOMIC_TIME_CONSTANT, q)
        else:
            warn_if_tipping(self.data, robot.source)
        if settle > 0:
            for _ in range(round(settle / dt)):
                self.step(np.zeros(robot.n))
            self._wheel_integral[:] = 0.0
            self._yaw_integral[:] = 0.0
            self._platform_state[:] = 0.0
            self.data.time = 0.0

    def _set_yaw_servo(self, time_constant: float, q: np.ndarray) -> None:
        """The yaw servo's gain: the robot's inertia about the yaw axis at ``q`` over ``T``.

        The inertia is the URDF's, from the controller's model (Pinocchio's ``S^T M S``), which
        the servos are tuned on: without ``mass_scale`` or an unknown payload. The slides' gain
        is the URDF's mass over ``T`` (set when the actuators were added), so that the base
        follows its lagged reference within about ``T``.
        """
        robot = self.robot
        mass = pin.crba(robot.model, robot.data, robot.check_configuration(q))
        gain = (robot.selection.T @ mass @ robot.selection)[2, 2] / time_constant
        yaw = self.model.actuator(PLANAR_JOINTS[2][0]).id
        self.model.actuator_gainprm[yaw, 0] = gain
        self.model.actuator_biasprm[yaw, 2] = -gain

    # ------------------------------------------------------------------ state
    def reset(self, q: npt.ArrayLike) -> None:
        """Place the robot at configuration ``q`` (shape (nq,)), at rest, wheels on the floor."""
        q = self.robot.check_configuration(q)
        mujoco.mj_resetData(self.model, self.data)
        self._q = None
        self._wheel_integral[:] = 0.0
        self._yaw_integral[:] = 0.0
        self.arm_integral[:] = 0.0
        self._platform_state[:] = 0.0
        yaw = np.arctan2(q[3], q[2])
        if self.holonomic:
            self.data.qpos[:3] = [q[0], q[1], yaw]
        else:
            self.data.qpos[:7] = [q[0], q[1], 0.0, np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
        self.data.qpos[self._arm_qpos] = self.robot.arm_positions(q)
        mujoco.mj_forward(self.model, self.data)

    def _state(self) -> None:
        """Read ``q``, ``v`` and the body velocity from MuJoCo's state, once per step.

        New arrays every step: a caller may keep the previous step's.
        """
        self._q, self._v, self._body = self._neutral.copy(), np.empty(self.robot.n), np.empty(3)
        true_state(
            self._qpos, self._qvel, self._arm_qpos, self._arm_dof, self.robot.arm_q_indices,
            self.robot.arm_continuous, self.holonomic, self._q, self._v, self._body,
        )  # fmt: skip

    @property
    def q(self) -> np.ndarray:
        """Configuration of the controller's model. Shape (nq,).

        The planar pose of the drive footprint (x, y, cos and sin of its heading), then the arm
        joints. Read once per step (:func:`true_state`); do not write to it.
        """
        if self._q is None:
            self._state()
        return self._q

    def body_velocity(self) -> np.ndarray:
        """Forward and lateral speed [m/s], yaw rate [rad/s] of the drive footprint. Shape (3,).

        Speeds are in the footprint's own frame; the lateral speed is the side slip that the
        unicycle model excludes.
        """
        if self._q is None:
            self._state()
        return self._body.copy()

    @property
    def v(self) -> np.ndarray:
        """Actuated velocity ``[u, omega, arm rates]`` of the true motion. Shape (n,).

        Read once per step; do not write to it.
        """
        if self._q is None:
            self._state()
        return self._v

    def wheel_speeds(self) -> np.ndarray:
        """Drive wheel angular speeds [rad/s], in the order of ``axle.wheel_joints``."""
        return self.data.qvel[self._wheel_dof].copy()

    @property
    def wheel_angles(self) -> np.ndarray:
        """Mean angle [rad] of the left and of the right drive wheels. Shape (2,).

        What a skid-steer platform's wheel encoders give (the wheels of a side are geared
        together on the Pioneer 3-AT); zero at the start of the run
        (:meth:`pbvs_pin.sim.sensing.Sensing` takes differences).
        """
        return self._wheel_sides @ self.data.qpos[self._wheel_qpos]

    # ------------------------------------------------------------------ step
    def arm_gravity(self) -> np.ndarray:
        """Gravity load [N m or N] of the arm joints (:func:`arm_gravity_load`). Shape (n_arm,).

        Uses the positions of the last ``mj_forward`` or ``mj_step1``.
        """
        out = np.empty(len(self._arm_joint))
        data = self.data
        arm_gravity_load(
            data.xaxis, data.xanchor, data.subtree_com, self._arm_joint, self._arm_body,
            self._arm_slide, self._weight, out,
        )  # fmt: skip
        return out

    def step(self, v_ref: np.ndarray) -> None:
        r"""Advance by one step ``dt`` under the velocity reference ``v_ref`` (shape (n,)).

        ``mj_step1`` computes the current kinematics and mass matrix; the servo commands are
        set (:func:`servo_commands`) and ``mj_step2`` integrates. Wheel references come from
        ``[u, omega]`` and the gyro loop's correction of ``omega``; each wheel servo adds
        integral action ``k_w e_i / T_i`` with ``e_i = \int (w_{ref} - w) dt`` (clamped at the
        wheel's effort), as a wheel's motor controller does, so that a skid-steer platform keeps
        turning against its wheels' side friction. An arm servo's velocity actuator gets the
        scheduled stiffness ``K_j`` as its gain and ``r + (D r + F tanh(r / v_s) + G g) / K``
        as its command (the module docstring's law).
        """
        model, data = self.model, self.data
        mujoco.mj_step1(model, data)
        mujoco.mj_fullM(model, data, self._full_mass)
        if self.payload is not None:  # the servos do not know of it
            self.payload.servo_view(model, data, self._full_mass)
        servo_commands(
            *self._state_arguments, np.asarray(v_ref, dtype=float), *self._servo_arguments
        )
        mujoco.mj_step2(model, data)
        self._q = None
