r"""Compiled kernels of :class:`pbvs_pin.plant.mujoco_plant.MujocoPlant`: its state and its servos.

One call per MuJoCo step: :func:`servo_commands` sets every actuator's gain and command from
the state ``mj_step1`` computed (:func:`arm_gravity_load` is its gravity part); and, once per
step when the loop asks, :func:`true_state` reads the controller's ``q`` and ``v`` from
MuJoCo's ``qpos`` and ``qvel``. The arrays are MuJoCo's own (``data.qvel``, ``data.xaxis``,
``model.actuator_gainprm``, ...), passed without copies.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def true_state(
    qpos: np.ndarray,
    qvel: np.ndarray,
    arm_qpos: np.ndarray,
    arm_dof: np.ndarray,
    arm_q_index: np.ndarray,
    continuous: np.ndarray,
    holonomic: bool,
    q: np.ndarray,
    v: np.ndarray,
    body: np.ndarray,
) -> None:
    r"""The controller's ``q`` and ``v`` and the footprint's body velocity from MuJoCo's state.

    A differential drive's root has a free joint: its quaternion ``(w, x, y, z) = qpos[3:7]``
    gives the footprint's rotation ``R``; its heading is the normalised
    ``(R_00, R_10) = (1 - 2 (y^2 + z^2), 2 (x y + w z))``. MuJoCo's free-joint velocity is
    ``qvel[0:3]`` (linear, world) and ``qvel[3:6]`` (angular, body): forward and lateral speeds
    are ``(R^T qvel[0:3])_{0,1}``, the yaw rate ``(R qvel[3:6])_2``; ``v`` starts with
    ``[u, omega]``.

    A holonomic base's root has planar joints, a slide along the world's x, one along its y
    and a hinge about z: ``qpos[0:3] = (x, y, theta)``, ``qvel[0:3]`` the world velocity and the
    yaw rate. The body velocity is ``[R(theta)^T qvel[0:2], qvel[2]]``, which is also ``v``'s
    ``[vx, vy, omega]``.

    Args:
        qpos: ``data.qpos``. Shape (nq_mj,).
        qvel: ``data.qvel``. Shape (nv_mj,).
        arm_qpos: The arm joints' qpos addresses. Shape (n_arm,).
        arm_dof: Their dof addresses. Shape (n_arm,).
        arm_q_index: Their index in the controller's ``q``. Shape (n_arm,).
        continuous: Whether each is stored as (cos, sin) in ``q``. Shape (n_arm,).
        holonomic: The root has planar joints (else a free joint).
        q: Written: configuration (other entries kept). Shape (nq,).
        v: Written: ``[base velocities, arm rates]``. Shape (n,).
        body: Written: forward and lateral speed [m/s], yaw rate [rad/s]. Shape (3,).
    """
    if holonomic:
        c, s = np.cos(qpos[2]), np.sin(qpos[2])
        q[0], q[1], q[2], q[3] = qpos[0], qpos[1], c, s
        body[0] = c * qvel[0] + s * qvel[1]
        body[1] = -s * qvel[0] + c * qvel[1]
        body[2] = qvel[2]
        v[0], v[1], v[2] = body[0], body[1], body[2]
    else:
        w, x, y, z = qpos[3], qpos[4], qpos[5], qpos[6]
        r00, r01 = 1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z)
        r10, r11 = 2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z)
        r20, r21, r22 = 2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)
        norm = np.hypot(r00, r10)
        q[0], q[1], q[2], q[3] = qpos[0], qpos[1], r00 / norm, r10 / norm
        body[0] = r00 * qvel[0] + r10 * qvel[1] + r20 * qvel[2]
        body[1] = r01 * qvel[0] + r11 * qvel[1] + r21 * qvel[2]
        body[2] = r20 * qvel[3] + r21 * qvel[4] + r22 * qvel[5]
        v[0], v[1] = body[0], body[2]
    n_base = 3 if holonomic else 2
    for j in range(arm_qpos.shape[0]):
        angle, index = qpos[arm_qpos[j]], arm_q_index[j]
        if continuous[j]:
            q[index], q[index + 1] = np.cos(angle), np.sin(angle)
        else:
            q[index] = angle
        v[n_base + j] = qvel[arm_dof[j]]


@njit(cache=True)
def arm_gravity_load(
    xaxis: np.ndarray,
    xanchor: np.ndarray,
    subtree_com: np.ndarray,
    arm_joint: np.ndarray,
    arm_body: np.ndarray,
    slide: np.ndarray,
    weight: np.ndarray,
    out: np.ndarray,
) -> None:
    r"""Gravity load of each arm joint, ``g_j = -a_j \cdot ((c_j - p_j) \times m_j g)``.

    ``m_j`` and ``c_j`` are the mass and centre of mass of the subtree the joint moves,
    ``p_j`` and ``a_j`` the joint's anchor and axis (a slide joint: ``-a_j \cdot m_j g``);
    gravity is along the world's -z, ``g = (0, 0, -g_0)``, so that
    ``g_j = m_j g_0 (a_x l_y - a_y l_x)`` with ``l = c_j - p_j``.

    Args:
        xaxis: MuJoCo's ``data.xaxis`` (joint axes, world). Shape (njnt, 3).
        xanchor: ``data.xanchor`` (joint anchors, world) [m]. Shape (njnt, 3).
        subtree_com: ``data.subtree_com`` [m]. Shape (nbody, 3).
        arm_joint: Joint id of each arm joint. Shape (n_arm,).
        arm_body: Its body id. Shape (n_arm,).
        slide: Whether it is a slide joint. Shape (n_arm,).
        weight: ``m_j g_0`` [N]. Shape (n_arm,).
        out: Written: ``g_j`` [N m or N]. Shape (n_arm,).
    """
    for j in range(arm_joint.shape[0]):
        joint, body = arm_joint[j], arm_body[j]
        if slide[j]:
            out[j] = weight[j] * xaxis[joint, 2]
        else:
            lever_x = subtree_com[body, 0] - xanchor[joint, 0]
            lever_y = subtree_com[body, 1] - xanchor[joint, 1]
            out[j] = weight[j] * (xaxis[joint, 0] * lever_y - xaxis[joint, 1] * lever_x)


@njit(cache=True)
def servo_commands(
    mass: np.ndarray,
    qvel: np.ndarray,
    footprint_rotation: np.ndarray,
    xaxis: np.ndarray,
    xanchor: np.ndarray,
    subtree_com: np.ndarray,
    v_ref: np.ndarray,
    speed_limits: np.ndarray,
    n_base: int,
    platform_state: np.ndarray,
    platform_blend: np.ndarray,
    wheel_map: np.ndarray,
    wheel_dof: np.ndarray,
    wheel_speed_limit: float,
    wheel_integral: np.ndarray,
    integral_limit: np.ndarray,
    integral_time: float,
    yaw_integral: np.ndarray,
    yaw_gain: float,
    yaw_integral_limit: float,
    holonomic: bool,
    arm_dof: np.ndarray,
    arm_joint: np.ndarray,
    arm_body: np.ndarray,
    slide: np.ndarray,
    weight: np.ndarray,
    inverse_time_constants: np.ndarray,
    damping: np.ndarray,
    friction: np.ndarray,
    friction_speed: float,
    compensated: np.ndarray,
    integral_rates: np.ndarray,
    arm_effort: np.ndarray,
    arm_integral: np.ndarray,
    h: float,
    gainprm: np.ndarray,
    biasprm: np.ndarray,
    ctrl: np.ndarray,
) -> None:
    r"""Set the wheel, arm and holonomic base servos' gains and commands for one MuJoCo step.

    Platform: the clipped reference ``clip(v_ref[:n_base])`` passes the platform's first-order
    lags (time constants ``T_k`` of :class:`pbvs_pin.model.servo.ServoModel`), exactly discretised,
    ``p += (1 - exp(-h / T_k)) (clip(v_ref_k) - p)``; the gyro loop's integral
    ``e_g += h (p_omega - omega_gyro)``, clamped at ``yaw_integral_limit``, adds
    ``yaw_gain e_g`` to the yaw rate ``p_omega`` (its last entry), with ``omega_gyro`` the
    footprint's yaw rate ``(R qvel[3:6])_2``.

    Wheels (actuators ``0 .. n_w - 1``): ``w_ref = clip(W p, +-wheel_speed_limit)``, the
    integral ``e += h (w_ref - w)`` clamped at ``integral_limit``, command
    ``w_ref + e / T_i``.

    Arm joint ``j`` (actuator ``n_w + j``): the stiffness of
    :class:`pbvs_pin.model.servo.ServoModel`, ``K_j = (sum_k |M_v,jk|) / T_j``, with ``M_v = S^T M
    S`` in the actuated velocities ``[u, omega, arm]`` (``u`` moves the free joint along the
    heading, ``omega`` turns it about z; a holonomic base's ``vy`` moves it across the heading;
    the wheels, on other branches, do not couple with the arm), is the velocity actuator's gain
    (``gainprm = K``, ``biasprm[2] = -K``); its command is
    ``r + (D r + F tanh(r / w) + G g + K e / T_I) / K`` with ``r`` the clipped reference, the
    friction band ``w = max(v_s, F h / M_jj)`` and the integral action ``K e / T_I``,
    ``e += h (r - v)``, of :func:`pbvs_pin.model.servo.servo_step`.

    Args:
        mass: MuJoCo's dense mass matrix (``mj_fullM``). Shape (nv, nv).
        qvel: ``data.qvel``. Shape (nv,).
        footprint_rotation: ``data.xmat`` of the free body (row-major 3 x 3). Shape (9,).
        xaxis: ``data.xaxis``. Shape (njnt, 3).
        xanchor: ``data.xanchor``. Shape (njnt, 3).
        subtree_com: ``data.subtree_com``. Shape (nbody, 3).
        v_ref: Velocity reference ``[u, omega, arm rates]``. Shape (n,).
        speed_limits: Largest reference per velocity. Shape (n,).
        n_base: Number of platform velocities.
        platform_state: Updated: the lagged platform reference ``p``. Shape (n_base,).
        platform_blend: ``1 - exp(-h / T_k)``. Shape (n_base,).
        wheel_map: ``W``, wheel speeds from ``[u, omega]``. Shape (n_w, n_base).
        wheel_dof: The wheels' dof addresses. Shape (n_w,).
        wheel_speed_limit: Largest wheel speed reference [rad/s].
        wheel_integral: Updated: the wheels' integral ``e`` [rad]. Shape (n_w,).
        integral_limit: Its clamp [rad]. Shape (n_w,).
        integral_time: ``T_i`` [s].
        yaw_integral: Updated: the gyro loop's integral ``e_g`` [rad]. Shape (1,).
        yaw_gain: ``1 / T_g`` [1/s] (0: no gyro loop).
        yaw_integral_limit: Clamp of ``e_g`` [rad].
        holonomic: The root is MuJoCo's planar joints (:func:`true_state`): no wheels,
            no gyro loop; the platform actuators follow the arm's, their commands the lagged
            platform reference turned into the world frame.
        arm_dof: The arm joints' dof addresses. Shape (n_arm,).
        arm_joint: Joint id of each arm joint (:func:`arm_gravity_load`). Shape (n_arm,).
        arm_body: Its body id. Shape (n_arm,).
        slide: Whether it is a slide joint. Shape (n_arm,).
        weight: ``m_j g_0`` of its subtree [N]. Shape (n_arm,).
        inverse_time_constants: ``1 / T_j`` of the arm servos. Shape (n_arm,).
        damping: ``D_j``. Shape (n_arm,).
        friction: ``F_j``. Shape (n_arm,).
        friction_speed: ``v_s``.
        compensated: Diagonal of ``G`` (1.0 or 0.0). Shape (n_arm,).
        integral_rates: ``1 / T_I`` of the arm servos' integral action [1/s]. Shape (n_arm,).
        arm_effort: The arm servos' effort limits (``inf``: none). Shape (n_arm,).
        arm_integral: Updated: each arm servo's integral ``e`` of ``r - v``, held within
            ``|K e / T_I| <= effort``. Shape (n_arm,).
        h: Step [s].
        gainprm: Written: ``model.actuator_gainprm``. Shape (nu, 10).
        biasprm: Written: ``model.actuator_biasprm``. Shape (nu, 10).
        ctrl: Written: ``data.ctrl``. Shape (nu,).
    """
    platform = np.empty(n_base)
    for k in range(n_base):
        clipped = min(max(v_ref[k], -speed_limits[k]), speed_limits[k])
        platform_state[k] += platform_blend[k] * (clipped - platform_state[k])
        platform[k] = platform_state[k]
    if yaw_gain > 0.0:
        yaw_rate = (
            footprint_rotation[6] * qvel[3] + footprint_rotation[7] * qvel[4]
            + footprint_rotation[8] * qvel[5]
        )  # fmt: skip
        yaw_error = yaw_integral[0] + h * (platform[n_base - 1] - yaw_rate)
        yaw_integral[0] = min(max(yaw_error, -yaw_integral_limit), yaw_integral_limit)
        platform[n_base - 1] += yaw_gain * yaw_integral[0]
    n_wheels = wheel_dof.shape[0]
    for i in range(n_wheels):
        wheel_ref = 0.0
        for k in range(n_base):
            wheel_ref += wheel_map[i, k] * platform[k]
        wheel_ref = min(max(wheel_ref, -wheel_speed_limit), wheel_speed_limit)
        error = wheel_integral[i] + h * (wheel_ref - qvel[wheel_dof[i]])
        wheel_integral[i] = min(max(error, -integral_limit[i]), integral_limit[i])
        ctrl[i] = wheel_ref + wheel_integral[i] / integral_time
    n_arm = arm_dof.shape[0]
    gravity = np.empty(n_arm)
    arm_gravity_load(xaxis, xanchor, subtree_com, arm_joint, arm_body, slide, weight, gravity)
    heading_x, heading_y = footprint_rotation[0], footprint_rotation[3]
    norm = np.hypot(heading_x, heading_y)
    yaw_dof = 2 if holonomic else 5
    for j in range(n_arm):
        a = arm_dof[j]
        row = abs((mass[a, 0] * heading_x + mass[a, 1] * heading_y) / norm) + abs(mass[a, yaw_dof])
        if holonomic:  # vy: the lateral direction's coupling
            row += abs((mass[a, 1] * heading_x - mass[a, 0] * heading_y) / norm)
        for k in range(n_arm):
            row += abs(mass[a, arm_dof[k]])
        gain = inverse_time_constants[j] * row
        limit = speed_limits[n_base + j]
        reference = min(max(v_ref[n_base + j], -limit), limit)
        width = max(friction_speed, friction[j] * h / mass[a, a])
        if integral_rates[j] > 0.0:
            bound = arm_effort[j] / (gain * integral_rates[j])
            error = arm_integral[j] + h * (reference - qvel[a])
            arm_integral[j] = min(max(error, -bound), bound)
        feed_forward = (
            damping[j] * reference
            + friction[j] * np.tanh(reference / width)
            + compensated[j] * gravity[j]
            + gain * integral_rates[j] * arm_integral[j]
        )
        actuator = n_wheels + j
        gainprm[actuator, 0] = gain
        biasprm[actuator, 2] = -gain
        ctrl[actuator] = reference + feed_forward / gain
    if holonomic:  # the base's slides move along the world's x and y
        first = n_wheels + n_arm
        ctrl[first] = (heading_x * platform[0] - heading_y * platform[1]) / norm
        ctrl[first + 1] = (heading_y * platform[0] + heading_x * platform[1]) / norm
        ctrl[first + 2] = platform[2]
