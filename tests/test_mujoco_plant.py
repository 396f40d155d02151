"""The MuJoCo plant against Pinocchio (same URDF) and against the unicycle it does not assume."""

from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from pbvs_pin import MobileManipulator, load_robot
from pbvs_pin.exceptions import GainError
from pbvs_pin.model.servo import REVOLUTE_TIME_CONSTANT, ServoModel
from pbvs_pin.plant.mujoco_plant import MujocoPlant
from pbvs_pin.plant.pinocchio_plant import Plant

TWO_WHEELS = Path(__file__).parent / "data" / "two_wheel_platform.urdf"


def _plant(robot, **options):
    return MujocoPlant(robot, ServoModel.from_robot(robot), robot.home(), **options)


def _run(plant, v_ref, seconds):
    for _ in range(round(seconds / plant.dt)):
        plant.step(np.asarray(v_ref, dtype=float))


def _mujoco_state(plant, q, v):
    """Put the Pinocchio state (q, actuated v with zero platform velocity) into MuJoCo."""
    plant.reset(q)
    plant.data.qvel[plant._arm_dof] = v[plant.robot.n_base :]
    mujoco.mj_forward(plant.model, plant.data)


@pytest.mark.parametrize("name", ["pioneer_cyton", "pioneer_ur5"])
def test_arm_mass_matrix_and_bias_match_pinocchio(name):
    robot = load_robot(name)
    plant = _plant(robot)
    model = plant.model
    assert np.all(model.dof_armature == 0.0)
    pin_dofs = [robot.model.joints[robot.model.getJointId(n)].idx_v for n in robot.arm_joint_names]
    lower, upper = robot.arm_position_limits()
    lower, upper = np.maximum(lower, -np.pi), np.minimum(upper, np.pi)
    rng = np.random.default_rng(7)
    full = np.zeros((model.nv, model.nv))
    for _ in range(5):
        q = robot.with_arm_positions(robot.neutral(), rng.uniform(lower, upper))
        yaw = rng.uniform(-np.pi, np.pi)
        q[:4] = *rng.uniform(-2, 2, 2), np.cos(yaw), np.sin(yaw)
        v = np.concatenate([np.zeros(robot.n_base), rng.uniform(-1, 1, robot.n_arm)])
        _mujoco_state(plant, q, v)
        mujoco.mj_fullM(model, plant.data, full)
        mass_mj = full[np.ix_(plant._arm_dof, plant._arm_dof)]
        bias_mj = plant.data.qfrc_bias[plant._arm_dof]
        mass_pin = pin.crba(robot.model, robot.data, q)
        mass_pin = np.triu(mass_pin) + np.triu(mass_pin, 1).T
        mass_pin = mass_pin[np.ix_(pin_dofs, pin_dofs)]
        bias_pin = pin.nonLinearEffects(robot.model, robot.data, q, robot.selection @ v)[pin_dofs]
        assert np.linalg.norm(mass_mj - mass_pin) <= 1e-6 * np.linalg.norm(mass_pin)
        assert np.linalg.norm(bias_mj - bias_pin) <= 1e-6 * np.linalg.norm(bias_pin)
        assert np.allclose(plant.q, q, atol=1e-12)
        # the servos' gravity compensation is the gravity part of the same bias
        plant.data.qvel[:] = 0.0
        mujoco.mj_forward(model, plant.data)
        gravity_pin = pin.computeGeneralizedGravity(robot.model, robot.data, q)[pin_dofs]
        assert np.allclose(plant.arm_gravity(), gravity_pin, rtol=1e-6, atol=1e-9)


def test_urdf_damping_limits_and_efforts_are_mujoco_joint_properties():
    robot = load_robot("pioneer_cyton")
    model = _plant(robot).model
    for name in robot.arm_joint_names:
        joint = robot.model.joints[robot.model.getJointId(name)]
        mj = model.joint(name)
        assert model.dof_damping[mj.dofadr[0]] == pytest.approx(robot.model.damping[joint.idx_v])
        assert mj.limited[0] == 1
        assert np.allclose(
            mj.range,
            [
                robot.model.lowerPositionLimit[joint.idx_q],
                robot.model.upperPositionLimit[joint.idx_q],
            ],
        )
        assert model.jnt_actfrcrange[mj.id, 1] == pytest.approx(
            robot.model.effortLimit[joint.idx_v]
        )


def test_two_wheel_drive_follows_the_unicycle_without_slip():
    """Arc of radius u / omega = 0.5 m: after the servo transient (1 s), 2 s of motion from the
    pose reached match the closed-form arc to 1 cm and 0.02 rad; straight driving keeps y and
    heading at zero."""
    robot = MobileManipulator.from_urdf(str(TWO_WHEELS))
    plant = _plant(robot)
    u, omega = 0.2, 0.4
    _run(plant, [u, omega, 0.0], 1.0)
    x0, y0, c0, s0 = plant.q[:4]
    theta0 = np.arctan2(s0, c0)
    _run(plant, [u, omega, 0.0], 2.0)
    theta = theta0 + 2.0 * omega
    expected = [
        x0 + u / omega * (np.sin(theta) - np.sin(theta0)),
        y0 - u / omega * (np.cos(theta) - np.cos(theta0)),
    ]
    assert np.hypot(*(plant.q[:2] - expected)) < 0.01
    heading = np.arctan2(plant.q[3], plant.q[2])
    assert abs(np.angle(np.exp(1j * (heading - theta)))) < 0.02
    forward, lateral, yaw_rate = plant.body_velocity()
    assert forward == pytest.approx(u, rel=0.01)
    assert yaw_rate == pytest.approx(omega, rel=0.03)
    assert abs(lateral) < 2e-3

    plant.reset(robot.home())
    _run(plant, [0.3, 0.0, 0.0], 2.0)
    lag = plant.servo.time_constants[0]  # the platform's first-order lag
    assert plant.q[0] == pytest.approx(0.3 * (2.0 - lag * (1 - np.exp(-2.0 / lag))), abs=0.01)
    assert abs(plant.q[1]) < 1e-3
    assert abs(plant.q[3]) < 1e-3


@pytest.mark.parametrize(
    ("name", "index", "tolerance"),
    [("two_wheels", 0, 0.04), ("two_wheels", 1, 0.06), ("pioneer_cyton", 0, 0.04),
     ("tiago", 0, 0.04)],
)  # fmt: skip
def test_platform_speed_steps_like_the_pinocchio_plant(name, index, tolerance):
    """One servo definition on both engines: a step of the forward speed (0.3 m/s) or of the
    yaw rate (0.4 rad/s) follows the same response on the MuJoCo plant, wheels on the floor,
    as on the Pinocchio plant (the platform's time constants of ServoModel), within
    ``tolerance`` at every step of 1.5 s."""
    robot = MobileManipulator.from_urdf(str(TWO_WHEELS)) if name == "two_wheels" else load_robot(name)
    servo = ServoModel.from_robot(robot)
    mujoco_plant = MujocoPlant(robot, servo, robot.home(), settle=0.3)
    pinocchio_plant = Plant(robot, servo, robot.home())
    v_ref = np.zeros(robot.n)
    v_ref[index] = (0.3, 0.4)[index]
    difference = []
    for _ in range(1500):
        mujoco_plant.step(v_ref)
        pinocchio_plant.step(v_ref)
        difference.append(mujoco_plant.v[index] - pinocchio_plant.v[index])
    assert np.abs(difference).max() < tolerance
    assert mujoco_plant.v[index] == pytest.approx(v_ref[index], rel=0.03)


def test_skid_steer_platform_slips_when_turning():
    """Pioneer 3-AT: the yaw rate falls short of r (w_r - w_l) / b of its own measured wheel
    speeds, and the platform drifts sideways; driving straight it does not."""
    robot = load_robot("pioneer_cyton")
    plant = _plant(robot)
    _run(plant, [0.2, 0.4, 0, 0, 0], 2.0)
    yaw_rates, unicycle, lateral = [], [], []
    drive, left = robot.base, plant._wheel_map[:, 1] < 0
    for _ in range(1000):
        plant.step(np.array([0.2, 0.4, 0, 0, 0]))
        wheels = plant.wheel_speeds()
        unicycle.append(
            drive.wheel_radius * (wheels[~left].mean() - wheels[left].mean()) / drive.track
        )
        yaw_rates.append(plant.body_velocity()[2])
        lateral.append(plant.body_velocity()[1])
    assert np.mean(yaw_rates) < 0.8 * np.mean(unicycle)
    assert abs(np.mean(lateral)) > 5e-4


def _mean_body_velocity(plant, v_ref, settle_s=2.0, measure_s=2.0):
    """Forward, lateral speed and yaw rate averaged over ``measure_s`` after ``settle_s``."""
    _run(plant, v_ref, settle_s)
    samples = []
    for _ in range(round(measure_s / plant.dt)):
        plant.step(np.asarray(v_ref, dtype=float))
        samples.append(plant.body_velocity())
    return np.mean(samples, axis=0)


@pytest.mark.parametrize(("u", "omega"), [(0.0, 0.1), (0.0, 0.4), (0.2, 0.2)])
def test_skid_steer_platform_reaches_its_yaw_rate_with_its_gyro_loop(u, omega):
    """Spin test of the Pioneer 3-AT: with the gyro loop the commanded yaw rate is reached
    within 5 % on average; without it the platform turns at well under the command, even
    with the effective track chi * b in the wheel speeds (the slip is the contacts')."""
    robot = load_robot("pioneer_cyton")
    v_ref = [u, omega, 0.0, 0.0, 0.0]
    assert robot.base.track_factor > 1.4
    forward, lateral, yaw_rate = _mean_body_velocity(_plant(robot, settle=0.3), v_ref)
    assert yaw_rate == pytest.approx(omega, rel=0.05)
    assert forward == pytest.approx(u, abs=0.02)
    assert abs(lateral) > 5e-4  # it still slips sideways
    open_loop = _mean_body_velocity(_plant(robot, settle=0.3, yaw_integral_time=None), v_ref)
    assert open_loop[2] < 0.9 * omega


@pytest.mark.parametrize("name", ["pioneer_cyton", "tiago"])
def test_yaw_rate_answers_a_small_sine_as_the_controllers_platform_lag(name):
    """Frequency response of the yaw rate, wheels on the floor: a 0.1 rad/s sine at 0.7 Hz
    (the band where the skid-steer platform oscillated in closed loop) is answered as the
    first-order lag ``1 / (1 + j w T)`` that eq. (20) models (``T`` the platform's yaw time
    constant of ServoModel), within 0.1 in gain and 15 degrees in phase. The reference is that
    formula. With the wheel servos of the time (0.05 s) the Pioneer 3-AT (skid-steer) answered
    0.18 at -170 degrees against 0.70 at -45, TIAGo (two wheels) 0.72 at -54."""
    robot = load_robot(name)
    plant = _plant(robot, settle=0.3)
    frequency, amplitude, settle_s = 0.7, 0.1, 2.0
    steps = round((settle_s + 4 / frequency) / plant.dt)
    t = np.arange(steps) * plant.dt
    command, yaw_rate = amplitude * np.sin(2 * np.pi * frequency * t), np.zeros(steps)
    v_ref = np.zeros(robot.n)
    for k in range(steps):
        v_ref[1] = command[k]
        plant.step(v_ref)
        yaw_rate[k] = plant.v[1]
    kept = t >= settle_s  # four whole periods
    phasor = np.exp(-2j * np.pi * frequency * t[kept])
    answer = (yaw_rate[kept] @ phasor) / (command[kept] @ phasor)
    lag = 1.0 / (1.0 + 2j * np.pi * frequency * ServoModel.from_robot(robot).time_constants[1])
    assert abs(answer) == pytest.approx(abs(lag), abs=0.1)
    assert np.degrees(np.angle(answer / lag)) == pytest.approx(0.0, abs=15.0)


def test_a_two_wheel_platform_has_no_yaw_loop():
    """One wheel per side: chi = 1, wheel speeds from the geometric track, no gyro."""
    robot = MobileManipulator.from_urdf(str(TWO_WHEELS))
    plant = _plant(robot)
    assert robot.base.track_factor == 1.0
    assert plant._yaw_gain == 0.0
    assert np.allclose(
        np.abs(plant._wheel_map[:, 1]), 0.5 * robot.base.track / robot.base.wheel_radius
    )


def test_state_matches_mujocos_rotation_and_is_new_each_step():
    """q and v (read from qpos and qvel by a compiled kernel) against MuJoCo's own body
    rotation after mj_forward; the arrays of an earlier step are left as they were."""
    robot = load_robot("pioneer_cyton")
    plant = _plant(robot)
    _run(plant, [0.2, 0.4, 0.3, -0.2, 0.1], 0.5)
    earlier_q, earlier_v = plant.q.copy(), plant.v.copy()
    kept_q, kept_v = plant.q, plant.v
    _run(plant, [0.2, 0.4, 0.3, -0.2, 0.1], 0.1)
    assert np.array_equal(kept_q, earlier_q) and np.array_equal(kept_v, earlier_v)
    mujoco.mj_forward(plant.model, plant.data)
    rotation = plant.data.xmat[1].reshape(3, 3)
    heading = rotation[:2, 0] / np.hypot(*rotation[:2, 0])
    q, v = plant.q, plant.v
    assert np.allclose(q[2:4], heading, atol=1e-12)
    assert np.allclose(q[:2], plant.data.qpos[:2], atol=0)
    linear = rotation.T @ plant.data.qvel[:3]
    yaw_rate = (rotation @ plant.data.qvel[3:6])[2]
    assert np.allclose(plant.body_velocity(), [linear[0], linear[1], yaw_rate], atol=1e-12)
    assert np.allclose(v, [linear[0], yaw_rate, *plant.data.qvel[plant._arm_dof]], atol=1e-12)
    assert np.allclose(robot.arm_positions(q), plant.data.qpos[plant._arm_qpos], atol=1e-12)


def test_arm_servo_reaches_its_speed_within_a_few_time_constants():
    """The ServoModel's feed-forward of the URDF damping leaves no steady-state shortfall."""
    robot = load_robot("pioneer_cyton")
    plant = _plant(robot)
    index = robot.velocity_names.index("shoulder_yaw_joint")
    v_ref = np.zeros(robot.n)
    v_ref[index] = 0.5
    _run(plant, v_ref, REVOLUTE_TIME_CONSTANT)
    assert 0.5 * (1 - np.exp(-1)) - 0.1 < plant.v[index] < 0.5
    _run(plant, v_ref, 4 * REVOLUTE_TIME_CONSTANT)
    assert plant.v[index] == pytest.approx(0.5, rel=0.05)  # the integral's overshoot
    _run(plant, v_ref, 15 * REVOLUTE_TIME_CONSTANT)
    assert plant.v[index] == pytest.approx(0.5, rel=0.005)


def test_arm_servo_is_clipped_at_its_speed_limit():
    robot = load_robot("pioneer_cyton")
    plant = _plant(robot)
    index = robot.velocity_names.index("shoulder_yaw_joint")
    v_ref = np.zeros(robot.n)
    v_ref[index] = 10.0 * robot.velocity_limits[index]
    _run(plant, v_ref, 0.5)
    assert plant.v[index] == pytest.approx(robot.velocity_limits[index], rel=0.01)


def test_mass_scale_makes_the_true_robot_heavier():
    """Twice the masses: every body's mass and inertia doubles."""
    robot = load_robot("pioneer_cyton")
    light, heavy = _plant(robot), _plant(robot, mass_scale=2.0)
    assert np.allclose(heavy.model.body_mass, 2.0 * light.model.body_mass)
    assert np.allclose(heavy.model.body_inertia, 2.0 * light.model.body_inertia)


def test_settling_leaves_the_robot_at_rest_on_the_ground():
    robot = load_robot("pioneer_cyton")
    plant = _plant(robot, settle=0.3)
    assert np.abs(plant.v).max() < 1e-3
    assert np.abs(plant.q - robot.home()).max() < 1e-3
    assert plant.data.ncon >= len(plant.axle.wheel_joints)


@pytest.mark.parametrize(
    ("option", "value"), [("mass_scale", 0.0), ("settle", -1.0), ("yaw_integral_time", 0.0)]
)
def test_bad_options_are_gain_errors(option, value):
    robot = load_robot("pioneer_cyton")
    with pytest.raises(GainError, match=option):
        _plant(robot, **{option: value})


def test_an_inertia_mujoco_refuses_is_replaced_by_its_diagonal():
    """TIAGo's antenna links (1e-6 kg) have products of inertia above their moments: Pinocchio
    takes them, MuJoCo refuses them; the plant compiles with their diagonal."""
    robot = load_robot("tiago")
    plant = _plant(robot)
    assert np.all(plant.model.body_inertia[plant.model.body_mass > 0] > 0)
    assert plant.model.nu == len(plant.axle.wheel_joints) + robot.n_arm


def test_an_arm_whose_root_link_is_named_world_rides_on_the_platform(load):
    """example-robot-data's UR5 roots at a link named ``world``, which MuJoCo's URDF importer
    reads as its world body: the arm stood on the floor beside the platform. Every body now
    hangs from the platform, and the platform carries the URDF's whole mass (Pinocchio's)."""
    robot = load("pioneer_ur5")
    xml = robot.urdf_xml
    assert '<link name="world"' in (xml.decode() if isinstance(xml, bytes) else xml)
    model = MujocoPlant(robot, ServoModel.from_robot(robot), robot.home()).model
    assert all(model.body_rootid[body] == 1 for body in range(1, model.nbody))
    assert model.body_subtreemass[1] == pytest.approx(pin.computeTotalMass(robot.model))


def test_an_arm_joint_driven_into_its_stop_stays_at_it():
    """A joint commanded at its speed limit into its upper stop for 4 s: MuJoCo's limit
    (``JOINT_LIMIT_TIME_CONSTANT``) holds it within 2 mrad of the URDF's limit; with MuJoCo's
    default soft limit (0.02 s) it went 10.7 mrad past, and Stretch's segment 12.6 mm."""
    robot = load_robot("pioneer_cyton")
    plant = _plant(robot, settle=0.3)
    upper = robot.model.upperPositionLimit[robot.model.joints[robot.model.getJointId(
        robot.arm_joint_names[1])].idx_q]
    v_ref = np.zeros(robot.n)
    v_ref[robot.n_base + 1] = ServoModel.from_robot(robot).speed_limits[robot.n_base + 1]
    past = 0.0
    for _ in range(4000):
        plant.step(v_ref)
        past = max(past, robot.arm_positions(plant.q)[1] - upper)
    assert 0.0 < past + 1e-3  # it reached the stop
    assert past < 2e-3, past
