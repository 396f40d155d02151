"""The plant's servos are the URDF's robot: damping and friction, limits, stops, time constants.

``tests/data/damped_arm.urdf`` carries URDF damping and friction on every joint (a heavily
damped revolute pan, a torque-limited pitch, a damped prismatic slide). Expected values come
from the URDF (speeds, limits, efforts) or from Pinocchio's rigid-body algorithms called here,
never from the servo code under test.
"""

from __future__ import annotations

import itertools
import re
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest
from conftest import DATA_DIR, URDF_DIR, random_configuration

from pbvs_pin.exceptions import GainError, UrdfError
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.model.servo import (
    PLATFORM_TIME_CONSTANTS,
    PRISMATIC_TIME_CONSTANT,
    REVOLUTE_TIME_CONSTANT,
    ServoModel,
)
from pbvs_pin.plant.pinocchio_plant import Plant

DT = 1e-3
PAN, PITCH, SLIDE = 2, 3, 4
"""Actuated indices of the damped arm's joints (after the platform's u, omega)."""


@pytest.fixture(scope="module")
def damped():
    return MobileManipulator.assemble(
        base="pioneer3at",
        arm=str(DATA_DIR / "damped_arm.urdf"),
        mount=(0.1, 0.0, 0.27, 0.0, 0.0, 0.0),
        camera_link="tool_link",
    )


def _start(robot):
    return robot.with_arm_positions(robot.home(), [0.0, 0.0, 0.05])


def _run(robot, servo, q0, v_ref, seconds):
    """Plant under a constant reference; returns the velocities and configurations per step."""
    plant = Plant(robot, servo, q0, DT)
    velocities, configurations = [], []
    for _ in range(round(seconds / DT)):
        plant.step(v_ref)
        velocities.append(plant.v.copy())
        configurations.append(plant.q.copy())
    return np.array(velocities), np.array(configurations)


def test_servo_reads_the_urdf(damped):
    servo = ServoModel.from_robot(damped)
    np.testing.assert_allclose(servo.damping, [0, 0, 5.0, 0.05, 40.0])
    np.testing.assert_allclose(servo.friction, [0, 0, 0.3, 0.0, 2.0])
    np.testing.assert_allclose(servo.effort[2:], [20.0, 1.5, 50.0])
    np.testing.assert_allclose(servo.lower, [-1.0, -1.2, 0.0])
    np.testing.assert_allclose(servo.upper, [1.0, 1.2, 0.15])
    expected = [*PLATFORM_TIME_CONSTANTS, REVOLUTE_TIME_CONSTANT, REVOLUTE_TIME_CONSTANT]
    np.testing.assert_allclose(servo.time_constants, [*expected, PRISMATIC_TIME_CONSTANT])


def test_servo_damping_from_the_reference_robots_urdf(cyton, cyton_urdf):
    servo = ServoModel.from_robot(cyton)
    root = ET.parse(cyton_urdf).getroot()
    damping = {
        j.get("name"): float(j.find("dynamics").get("damping"))
        for j in root.findall("joint")
        if j.find("dynamics") is not None
    }
    expected = [0.0, 0.0, *[damping[name] for name in cyton.arm_joint_names]]
    assert np.count_nonzero(expected) > 0
    np.testing.assert_allclose(servo.damping, expected)


@pytest.mark.parametrize(("index", "speed"), [(PAN, 0.4), (PAN, -0.05), (SLIDE, 0.1)])
def test_damped_joint_reaches_the_commanded_speed(damped, index, speed):
    """With URDF damping D and friction, v reaches v_ref to 2 % within 3 time constants (the
    integral action's transient overshoots by about 1 % and then decays slowly) and to 0.5 %
    after 20 (before the slide reaches its stop).

    A servo without feed-forward would first stop near K / (K + D) of the command.
    """
    servo = ServoModel.from_robot(damped)
    v_ref = np.zeros(damped.n)
    v_ref[index] = speed
    later = 20 * servo.time_constants[index]
    velocities, _ = _run(damped, servo, _start(damped), v_ref, later)
    assert velocities[len(velocities) * 3 // 20 - 1, index] == pytest.approx(speed, rel=0.02)
    assert velocities[-1, index] == pytest.approx(speed, rel=0.005)


def _rise_time(velocities, index, target):
    """First time [s] the velocity reaches 1 - 1/e of ``target`` (linear interpolation)."""
    normalised = velocities[:, index] / target
    k = int(np.argmax(normalised >= 1 - np.exp(-1)))
    assert k > 0
    a, b = normalised[k - 1], normalised[k]
    return (k + (1 - np.exp(-1) - a) / (b - a)) * DT


@pytest.mark.parametrize(
    ("name", "arm"),
    [("pioneer_cyton", [0.0, 0.0, 0.0]), ("pioneer_cyton", [0.0, -1.2, 0.4]), ("tiago", None)],
)
def test_platform_time_constants_are_pioneer_like_at_any_posture(load, name, arm):
    """The platform is a lag of 0.1-0.6 s, folded or extended arm alike (TIAGo: at home)."""
    robot = load(name)
    servo = ServoModel.from_robot(robot)
    q0 = robot.home() if arm is None else robot.with_arm_positions(robot.home(), arm)
    for index, amplitude in ((0, 0.3), (1, 0.5)):
        v_ref = np.zeros(robot.n)
        v_ref[index] = amplitude
        velocities, _ = _run(robot, servo, q0, v_ref, 2.0)
        assert velocities[-1, index] == pytest.approx(amplitude, rel=0.01)
        assert np.all(np.abs(velocities[:, index]) <= 1.01 * amplitude)  # a lag, no overshoot
        tau = _rise_time(velocities, index, amplitude)
        assert 0.1 < tau < 0.6, f"{robot.velocity_names[index]}: {tau:.3f} s"


def test_requested_platform_time_constants_bound_the_lag(cyton):
    """``K_i = sum_j |M_v,ij| / T_i`` makes a joint's lag ``M_ii / K_i``: at most ``T_i``.

    On the reference robot the platform's rows are nearly diagonal, so the lag is ``T_i``
    within 5 %.
    """
    requested = (0.45, 0.15)
    servo = ServoModel.from_robot(cyton, platform=requested)
    for index, amplitude in ((0, 0.2), (1, -0.4)):
        v_ref = np.zeros(cyton.n)
        v_ref[index] = amplitude
        velocities, _ = _run(cyton, servo, cyton.home(), v_ref, 3.0)
        tau = _rise_time(velocities, index, amplitude)
        assert 0.95 * requested[index] < tau <= 1.01 * requested[index]


@pytest.mark.parametrize(("index", "speed", "limit"), [(PAN, 1.0, 1.0), (SLIDE, -0.3, 0.0)])
def test_joint_stops_at_its_limit_and_leaves_it(damped, index, speed, limit):
    servo = ServoModel.from_robot(damped)
    q_index = damped.model.joints[damped.model.getJointId(damped.velocity_names[index])].idx_q
    v_ref = np.zeros(damped.n)
    v_ref[index] = speed
    velocities, configurations = _run(damped, servo, _start(damped), v_ref, 1.5)
    positions = configurations[:, q_index]
    past = (positions - limit) * np.sign(speed)
    assert past.max() <= 1e-9  # never past the URDF limit
    assert positions[-1] == pytest.approx(limit, abs=1e-9)  # it got there and stays
    assert abs(velocities[-1, index]) <= 1e-9  # no velocity into the stop
    plant = Plant(damped, servo, configurations[-1], DT)
    plant.v = velocities[-1]
    for _ in range(200):
        plant.step(-v_ref / 2)
    assert (plant.q[q_index] - limit) * np.sign(speed) < -0.02  # left the stop
    assert plant.v[index] == pytest.approx(-speed / 2, rel=0.02)


def test_continuous_platform_yaw_has_no_stop(load):
    robot = load("pioneer_cyton")
    servo = ServoModel.from_robot(robot)
    assert set(servo.stop_index.tolist()) == set(range(robot.n_base, robot.n))
    v_ref = np.zeros(robot.n)
    v_ref[1] = robot.velocity_limits[1]
    _, configurations = _run(robot, servo, robot.home(), v_ref, 3.0 * np.pi / v_ref[1])
    yaw = np.unwrap(np.arctan2(configurations[:, 3], configurations[:, 2]))
    assert yaw[-1] - yaw[0] > 2 * np.pi  # more than a full turn


def test_torque_limits_are_respected(damped):
    """The torque each servo applies, recovered from the motion with Pinocchio's dynamics.

    The step is ``tau = M_v (v+ - v) / h + b(q, v) + D v+`` (friction is zero on the pitch
    joint), with ``b`` Pinocchio's nonlinear effects at the old velocity.
    """
    servo = ServoModel.from_robot(damped)
    model, data, s = damped.model, damped.model.createData(), damped.selection
    plant = Plant(damped, servo, _start(damped), DT)
    v_ref = np.zeros(damped.n)
    v_ref[PITCH] = -1.5  # a full-speed step: the servo asks for more than the effort limit
    torques = []
    for _ in range(150):
        q, v = plant.q.copy(), plant.v.copy()
        plant.step(v_ref)
        mass = pin.crba(model, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        bias = pin.nonLinearEffects(model, data, q, s @ v)
        torque = s.T @ (mass @ (s @ (plant.v - v)) / DT + bias) + servo.damping * plant.v
        torques.append(torque[PITCH])
    torques = np.abs(torques)
    assert torques.max() <= 1.5 + 1e-9
    assert torques.max() >= 1.5 - 1e-6  # the limit was reached, so it was tested
    assert plant.v[PITCH] == pytest.approx(-1.5, rel=0.02)


@pytest.mark.parametrize("name", ["damped", "pioneer_panda"])
def test_reference_model_is_the_servoed_robot(request, load, name):
    """M vdot + C v + g = v_ref of eq. (1) <=> the servo's torque moves the rigid body.

    The servo torque is written here from its definition, with ``K_i = sum_j |M_v,ij| / T_i``
    (friction left out: its feed-forward cancels it once ``sign v = sign v_ref``). The arm
    servos cancel their own gravity load, the platform's have none to cancel.
    """
    robot = request.getfixturevalue("damped") if name == "damped" else load(name)
    servo = ServoModel.from_robot(robot)
    assert servo.gravity_compensated[robot.n_base :].all()
    assert not servo.gravity_compensated[: robot.n_base].any()
    rng = np.random.default_rng(8)
    q = random_configuration(robot, rng)
    v, acc = rng.uniform(-0.3, 0.3, robot.n), rng.uniform(-1, 1, robot.n)
    terms = servo.reference_model(robot, q, v)
    v_ref = terms.mass @ acc + terms.coriolis @ v + terms.gravity
    model, data, s = robot.model, robot.model.createData(), robot.selection
    mass_v = s.T @ pin.crba(model, data, q) @ s
    mass_v = np.triu(mass_v) + np.triu(mass_v, 1).T
    gains = np.abs(mass_v).sum(axis=1) / servo.time_constants
    gravity = s.T @ pin.computeGeneralizedGravity(model, data, q)
    servo_torque = gains * (v_ref - v) + servo.damping * v_ref + servo.gravity_compensated * gravity
    needed = s.T @ pin.rnea(model, data, q, s @ v, s @ acc) + servo.damping * v
    np.testing.assert_allclose(servo_torque, needed, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize(
    "field", ["time_constants", "damping", "friction", "effort", "speed_limits", "integral_rates"]
)
def test_invalid_servo_parameters_raise(damped, field):
    servo = ServoModel.from_robot(damped)
    values = {name: getattr(servo, name) for name in servo.__dataclass_fields__}
    values[field] = -values[field] - 1.0
    with pytest.raises(GainError, match=field):
        ServoModel(**values)


def test_light_joint_with_friction_does_not_chatter(tmp_path):
    """A light link with URDF friction, commanded small speeds that change sign, follows them.

    One plant step of full friction would change the joint's speed by F h / I = 1 N m * 1 ms
    / 1e-4 kg m^2 = 10 rad/s: without a smoothing band at least that wide the semi-implicit
    step jumps across it and the joint chatters at a large fraction of its speed limit.
    """
    text = (DATA_DIR / "damped_arm.urdf").read_text()
    text = text.replace(
        '<inertial><origin xyz="0.1 0 0"/><mass value="0.4"/><inertia ixx="0.001" ixy="0" '
        'ixz="0" iyy="0.002" iyz="0" izz="0.002"/></inertial>',
        '<inertial><mass value="0.05"/><inertia ixx="0.0001" ixy="0" ixz="0" iyy="0.0001" '
        'iyz="0" izz="0.0001"/></inertial>',
    )
    text = text.replace('<dynamics damping="0.05"/>', '<dynamics damping="1.0" friction="1.0"/>')
    assert 'friction="1.0"' in text and 'mass value="0.05"' in text
    urdf = tmp_path / "light_wrist.urdf"
    urdf.write_text(text)
    robot = MobileManipulator.assemble(
        base="pioneer3at", arm=str(urdf), mount=(0.1, 0.0, 0.27, 0.0, 0.0, 0.0),
        camera_link="tool_link",
    )  # fmt: skip
    plant = Plant(robot, ServoModel.from_robot(robot), _start(robot), DT)
    pitch = robot.n_base + 1
    worst = 0.0
    for step in range(1000):
        v_ref = np.zeros(robot.n)
        v_ref[pitch] = 0.003 * np.sign(np.sin(2 * np.pi * 5 * step * DT) + 1e-9)
        plant.step(v_ref)
        worst = max(worst, abs(plant.v[pitch]))
    assert worst < 0.01, f"pitch joint reached {worst:.3f} rad/s under a 0.003 rad/s command"


def test_packed_servo_step_is_servo_step_with_its_constants_packed(damped):
    """Every constant lands where servo_step reads it: stops, friction, limits, S, h."""
    from pbvs_pin.model.servo import ServoConstants, pack_servos, packed_servo_step, servo_step

    servo = ServoModel.from_robot(damped)
    model, data = damped.model, damped.data
    rng = np.random.default_rng(15)
    params, indices = pack_servos(servo, damped.selection, servo.gravity_weight, DT)
    for _ in range(5):
        q = random_configuration(damped, rng)
        v, v_ref = rng.normal(size=damped.n), 3.0 * rng.normal(size=damped.n)
        terms = (
            pin.crba(model, data, q).copy(),
            pin.nonLinearEffects(model, data, q, damped.selection @ v).copy(),
            pin.computeGeneralizedGravity(model, data, q).copy(),
        )
        outputs = [np.zeros(model.nv) for _ in range(4)]
        mass, bias, gravity = terms
        tuned = 1.5 * mass  # the servos' own mass matrix (a payload they do not know of)
        integral = 0.01 * rng.normal(size=damped.n)
        integrals = [integral.copy(), integral.copy()]
        packed = packed_servo_step(
            mass, tuned, bias, gravity, params, indices, q, v, v_ref, integrals[0], *outputs[:2]
        )
        constants = ServoConstants(
            inverse_time_constants=1.0 / servo.time_constants,
            damping=servo.damping,
            friction=servo.friction,
            effort=servo.effort,
            speed_limits=servo.speed_limits,
            gravity_weight=servo.gravity_weight,
            integral_rates=servo.integral_rates,
            lower=servo.lower,
            upper=servo.upper,
            selection=damped.selection,
            friction_speed=servo.friction_speed,
            h=DT,
            stop_index=servo.stop_index,
            stop_q_index=servo.stop_q_index,
        )
        direct = servo_step(
            mass, tuned, bias, gravity, constants, q[servo.stop_q_index], v, v_ref, integrals[1],
            *outputs[2:],
        )  # fmt: skip
        np.testing.assert_array_equal(packed, direct)
        np.testing.assert_array_equal(integrals[0], integrals[1])
        assert not np.array_equal(integrals[0], integral)  # the integral moved
        np.testing.assert_array_equal(outputs[0], outputs[2])
        np.testing.assert_array_equal(outputs[1], outputs[3])
    assert servo.stop_index.size > 0 and np.any(servo.friction > 0)


def test_an_arm_that_moves_no_mass_is_refused(tmp_path):
    """A URDF without <inertial> (rtb-data's arms) would give its servos zero stiffness."""
    text = (URDF_DIR / "pioneer_cyton.urdf").read_text()
    path = tmp_path / "massless.urdf"
    path.write_text(re.sub(r"<inertial>.*?</inertial>", "", text, flags=re.DOTALL))
    robot = MobileManipulator.from_urdf(str(path))  # kinematics need no mass
    with pytest.raises(UrdfError, match=r"move no mass") as err:
        ServoModel.from_robot(robot)
    assert all(name in str(err.value) for name in robot.arm_joint_names)


def _one_joint(friction: float, integral_rate: float = 0.0, h: float = DT):
    """:class:`ServoConstants` of a single joint: no damping, no limits, no stops."""
    from pbvs_pin.model.servo import FRICTION_SPEED, ServoConstants

    one, empty = np.ones(1), np.zeros(0)
    return ServoConstants(
        inverse_time_constants=one / 0.02, damping=0.0 * one, friction=friction * one,
        effort=np.full(1, np.inf), speed_limits=10.0 * one, gravity_weight=one,
        integral_rates=integral_rate * one, lower=empty, upper=empty, selection=np.eye(1),
        friction_speed=FRICTION_SPEED, h=h, stop_index=np.zeros(0, dtype=np.int64),
        stop_q_index=np.zeros(0, dtype=np.int64),
    )  # fmt: skip


@pytest.mark.parametrize(("friction", "v", "r"), [(1.0, 0.02, 0.05), (0.004, -0.003, 0.001)])
def test_one_step_of_one_joint_is_the_linearly_implicit_equation(friction, v, r):
    """One joint of inertia M: ``(M + h (K + F')) v1 = M v + h (K r + F tanh(r / w) - F tanh(v /
    w) + F' v)``, ``F' = F / w (1 - tanh^2(v / w))``, ``K = M / T``, the band ``w = max(v_s,
    F h / M)`` (servo_step's docstring and FRICTION_SPEED's, written out here)."""
    from pbvs_pin.model.servo import FRICTION_SPEED, servo_step

    mass = 0.01  # [kg m^2]: F h / M = 0.1 rad/s for F = 1 N m, above v_s
    width = max(FRICTION_SPEED, friction * DT / mass)
    stiffness = mass / 0.02
    slope = friction / width * (1.0 - np.tanh(v / width) ** 2)
    rhs = mass * v + DT * (
        stiffness * r + friction * np.tanh(r / width) - friction * np.tanh(v / width) + slope * v
    )
    expected = rhs / (mass + DT * (stiffness + slope))
    outputs = np.zeros(1), np.zeros(1)
    zero = np.zeros(1)
    v_next = servo_step(
        np.full((1, 1), mass), np.full((1, 1), mass), zero, zero, _one_joint(friction),
        np.zeros(0), np.array([v]), np.array([r]), np.zeros(1), *outputs,
    )  # fmt: skip
    assert v_next[0] == pytest.approx(expected, rel=1e-12)
    assert outputs[0][0] == v_next[0] and outputs[1][0] == pytest.approx(DT * v_next[0])


def test_the_integral_moves_only_where_there_is_integral_action():
    """``e_{k+1} = e_k + h (r - v_{k+1})`` with ``K' = K (1 + h / T_I)``; none without it."""
    from pbvs_pin.model.servo import servo_step

    mass, rate, r = 0.01, 1.0 / (5 * 0.02), 0.05
    zero = np.zeros(1)
    for integral_rate in (0.0, rate):
        integral = np.array([0.002])
        v_next = servo_step(
            np.full((1, 1), mass), np.full((1, 1), mass), zero, zero, _one_joint(0.0, integral_rate),
            np.zeros(0), zero, np.array([r]), integral, zero.copy(), zero.copy(),
        )  # fmt: skip
        stiffness = mass / 0.02
        gain = stiffness * (1 + DT * integral_rate)
        expected = DT * (gain * r + stiffness * integral_rate * 0.002) / (mass + DT * gain)
        assert v_next[0] == pytest.approx(expected, rel=1e-12)
        moved = 0.002 + DT * (r - v_next[0]) if integral_rate else 0.002
        assert integral[0] == pytest.approx(moved, rel=1e-12)


def test_packed_constants_are_the_servos_own(damped):
    """Each named view of :func:`pack_servos`' buffers holds the servo's field; ``h`` and ``v_s``
    distinct (4 ms against 1 ms)."""
    from pbvs_pin.model.servo import pack_servos, servo_constants

    servo = ServoModel.from_robot(damped)
    constants = servo_constants(*pack_servos(servo, damped.selection, servo.gravity_weight, 0.004))
    assert constants.h == 0.004 and constants.friction_speed == servo.friction_speed
    np.testing.assert_array_equal(constants.inverse_time_constants, 1.0 / servo.time_constants)
    for name in ("damping", "friction", "effort", "speed_limits", "gravity_weight",
                 "integral_rates", "lower", "upper", "stop_index", "stop_q_index"):  # fmt: skip
        np.testing.assert_array_equal(getattr(constants, name), getattr(servo, name), name)
    np.testing.assert_array_equal(constants.selection, damped.selection)


def _active_sets(mass, bias, v, r, effort, positions, lower, upper):
    """Every ``v_{k+1}`` that a choice of saturated servos and acting stops makes consistent.

    The frictionless, undamped servos of ``servo_step``'s docstring written out: ``(M + h K)
    v1 = M v - h b + h K r`` on a free row, ``h (+-effort)`` in place of ``h K (r - v1)`` on a
    saturated one, ``v1_i = (limit - q_i) / h`` on a stopped one; ``K_i = sum_j |M_ij| / T``.
    Consistent: a free servo's torque within its effort, a saturated one's beyond it with its
    sign; a free joint within its limits; a stop's reaction pushing away from its limit.
    """
    n, h, time_constant = len(v), DT, 0.02
    gains = np.abs(mass).sum(axis=1) / time_constant
    found = []
    for saturated in itertools.product((-1, 0, 1), repeat=n):
        for stopped in itertools.product((-1, 0, 1), repeat=n):
            lhs, rhs = mass.copy(), mass @ v - h * bias
            for i in range(n):
                if saturated[i]:
                    rhs[i] += h * saturated[i] * effort[i]
                else:
                    lhs[i, i] += h * gains[i]
                    rhs[i] += h * gains[i] * r[i]
            free_lhs, free_rhs = lhs.copy(), rhs.copy()
            for i in np.flatnonzero(stopped):
                limit = upper[i] if stopped[i] > 0 else lower[i]
                lhs[i], lhs[i, i], rhs[i] = 0.0, 1.0, (limit - positions[i]) / h
            v1 = np.linalg.solve(lhs, rhs)
            torque = gains * (r - v1)
            landed = positions + h * v1
            consistent = all(
                (abs(torque[i]) <= effort[i] if not saturated[i]
                 else abs(torque[i]) > effort[i] and np.sign(torque[i]) == saturated[i])
                and (lower[i] <= landed[i] <= upper[i] if not stopped[i]
                     else (free_lhs[i] @ v1 - free_rhs[i]) * stopped[i] <= 0.0)
                for i in range(n)
            )  # fmt: skip
            if consistent:
                found.append(v1)
    return found


def test_a_stop_set_and_released_in_one_step_gives_the_consistent_active_set():
    """Two coupled joints near their limits: the first pass stops a joint whose stop, once the
    other servo saturates, would pull it into its limit; the step must release it again and
    solve once more. The reference enumerates every active set (``_active_sets``)."""
    from pbvs_pin.model.servo import FRICTION_SPEED, ServoConstants, servo_step

    mass = np.array([[1.1362882, -0.56372767], [-0.56372767, 0.37876809]])
    bias = np.array([0.08807699, -0.31913038])
    v, r = np.array([0.23360645, -0.34348303]), np.array([2.5861039, -2.75693573])
    effort, positions = np.array([2.45194083, 1.23862731]), np.array([0.9990094, -0.99961765])
    lower, upper, zero = np.full(2, -1.0), np.full(2, 1.0), np.zeros(2)
    constants = ServoConstants(
        inverse_time_constants=np.full(2, 1 / 0.02), damping=zero, friction=zero, effort=effort,
        speed_limits=np.full(2, 3.0), gravity_weight=np.ones(2), integral_rates=zero,
        lower=lower, upper=upper, selection=np.eye(2), friction_speed=FRICTION_SPEED, h=DT,
        stop_index=np.arange(2), stop_q_index=np.arange(2),
    )  # fmt: skip
    expected = _active_sets(mass, bias, v, r, effort, positions, lower, upper)
    assert len(expected) == 1
    v_next = servo_step(
        mass, mass, bias, zero, constants, positions, v.copy(), r, zero.copy(), zero.copy(),
        zero.copy(),
    )  # fmt: skip
    np.testing.assert_allclose(v_next, expected[0], rtol=1e-12, atol=1e-12)
