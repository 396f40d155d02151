"""``[model_error] payload``: a mass at the end-effector in the true robot, unknown to its servos.

References that do not come from the code under test: a point mass ``m`` at a point with
translational Jacobian ``J_p`` adds ``m J_p^T J_p`` to the mass matrix and ``m g_0 (J_p)_z`` to
the gravity load (a solid sphere of moment ``i`` adds ``i J_r^T J_r`` too); MuJoCo's model of the same robot with the same payload.
"""

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import random_configuration

from pbvs_pin import load_robot
from pbvs_pin.exceptions import GainError
from pbvs_pin.model.robot import PAYLOAD_RADIUS
from pbvs_pin.model.servo import ServoModel
from pbvs_pin.plant.mujoco_plant import MujocoPlant
from pbvs_pin.plant.pinocchio_plant import Plant

PAYLOAD_KG = 0.5


def _full(mass_upper):
    return np.triu(mass_upper) + np.triu(mass_upper, 1).T


def _camera_jacobian(robot, q):
    """Translational and rotational Jacobians of the camera frame (world axes)."""
    pin.computeJointJacobians(robot.model, robot.data, q)
    pin.updateFramePlacements(robot.model, robot.data)
    frame = robot.camera_frame_id
    jacobian = pin.getFrameJacobian(robot.model, robot.data, frame, pin.LOCAL_WORLD_ALIGNED)
    return jacobian[:3], jacobian[3:]


def _random_configurations(robot, count=4, seed=3):
    rng = np.random.default_rng(seed)
    return [random_configuration(robot, rng) for _ in range(count)]


@pytest.mark.parametrize("name", ["pioneer_cyton", "pioneer_ur5"])
def test_payload_adds_a_point_mass_at_the_camera_frame(name):
    robot = load_robot(name)
    loaded = robot.with_payload(PAYLOAD_KG)
    assert pin.computeTotalMass(loaded.model) == pytest.approx(
        pin.computeTotalMass(robot.model) + PAYLOAD_KG
    )
    for q in _random_configurations(robot):
        linear, angular = _camera_jacobian(robot, q)
        added = _full(pin.crba(loaded.model, loaded.data, q)) - _full(
            pin.crba(robot.model, robot.data, q)
        )
        moment = 0.4 * PAYLOAD_KG * PAYLOAD_RADIUS**2  # solid sphere
        expected = PAYLOAD_KG * linear.T @ linear + moment * angular.T @ angular
        assert np.allclose(added, expected, atol=1e-12)
        load = pin.computeGeneralizedGravity(loaded.model, loaded.data, q)
        load = load - pin.computeGeneralizedGravity(robot.model, robot.data, q)
        assert np.allclose(load, PAYLOAD_KG * 9.81 * linear[2], atol=1e-12)


def test_no_payload_is_the_robot_itself_and_a_negative_one_is_refused():
    robot = load_robot("pioneer_cyton")
    assert robot.with_payload(0.0) is robot
    with pytest.raises(GainError, match="payload"):
        robot.with_payload(-0.1)
    with pytest.raises(GainError, match="payload"):
        MujocoPlant(robot, ServoModel.from_robot(robot), robot.home(), payload=-0.1)


@pytest.mark.parametrize("name", ["pioneer_cyton", "pioneer_ur5"])
def test_mujoco_payload_matches_pinocchio_and_its_servos_see_the_robot_without_it(name):
    robot = load_robot(name)
    loaded = robot.with_payload(PAYLOAD_KG)
    servo = ServoModel.from_robot(robot)
    plant = MujocoPlant(robot, servo, robot.home(), payload=PAYLOAD_KG)
    bare = MujocoPlant(robot, servo, robot.home())
    model, data = plant.model, plant.data
    pin_dofs = [robot.model.joints[robot.model.getJointId(n)].idx_v for n in robot.arm_joint_names]
    arm = np.ix_(plant._arm_dof, plant._arm_dof)
    full = np.zeros((model.nv, model.nv))
    bare_full = np.zeros((model.nv, model.nv))
    for q in _random_configurations(robot):
        for each in (plant, bare):
            each.reset(q)
            mujoco.mj_forward(each.model, each.data)
        mujoco.mj_fullM(model, data, full)
        mass_pin = _full(pin.crba(loaded.model, loaded.data, q))[np.ix_(pin_dofs, pin_dofs)]
        assert np.linalg.norm(full[arm] - mass_pin) <= 1e-6 * np.linalg.norm(mass_pin)
        gravity_pin = pin.computeGeneralizedGravity(loaded.model, loaded.data, q)[pin_dofs]
        assert np.allclose(data.qfrc_bias[plant._arm_dof], gravity_pin, rtol=1e-6, atol=1e-9)
        # what the servos schedule with and cancel: the robot without the payload
        plant.payload.servo_view(model, data, full)
        mass, subtree_com = plant.payload.servo_mass, plant.payload.servo_com
        weight = plant.payload.servo_weight
        mujoco.mj_fullM(bare.model, bare.data, bare_full)
        assert np.allclose(mass[arm], bare_full[arm], rtol=1e-9, atol=1e-12)
        assert np.allclose(weight, bare._weight, rtol=1e-12)
        bodies = plant._arm_body
        assert np.allclose(subtree_com[bodies], bare.data.subtree_com[bodies], atol=1e-9)


@pytest.mark.parametrize("engine", ["pinocchio", "mujoco"])
def test_servos_that_do_not_know_the_payload_take_its_weight_by_their_integral(engine):
    """Under a zero reference the unknown payload's weight first moves the arm down; the
    servos' integral action then takes the load (T_I = 5 T): the arm comes to rest, its sag
    bounded, on both engines. Servos tuned with the payload hold the arm still from the start."""
    robot = load_robot("pioneer_cyton")
    servo = ServoModel.from_robot(robot)
    loaded = robot.with_payload(PAYLOAD_KG)
    if engine == "pinocchio":
        unknown = Plant(loaded, servo, robot.home(), tuned=robot)
    else:
        unknown = MujocoPlant(robot, servo, robot.home(), payload=PAYLOAD_KG)
    arm = np.arange(robot.n) >= robot.n_base
    heights, speeds = [], []
    for _ in range(1000):
        unknown.step(np.zeros(robot.n))
        heights.append(robot.camera_pose(unknown.q).translation[2])
        speeds.append(np.abs(unknown.v[arm]).max())
    drop = robot.camera_pose(robot.home()).translation[2] - np.array(heights)
    assert drop.max() > 1e-4  # it sagged: the servos did not know of the payload
    assert drop.max() < 0.02  # by less than 2 cm
    assert max(speeds[-100:]) < 1e-3  # and came to rest
    if engine == "pinocchio":
        known = Plant(loaded, ServoModel.from_robot(loaded), robot.home())
        for _ in range(300):
            known.step(np.zeros(robot.n))
        assert np.abs(known.q - robot.home()).max() < 1e-6
