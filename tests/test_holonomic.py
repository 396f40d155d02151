"""A holonomic base (``drive = "omnidirectional"``): gains, both plants, the obstacle.

References written here: Pinocchio's mass matrix in the actuated velocities ``S^T M S``
against MuJoCo's in its planar joints turned into the platform frame; the closed form of a
first-order lag's step and of its travel; the obstacle's clearance with and without
avoidance.
"""

from __future__ import annotations

from types import SimpleNamespace

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from docs_figures import stated

from pbvs_pin.control.settings import ControllerSettings, _reference_gains, kinematic_law
from pbvs_pin.exceptions import GainError
from pbvs_pin.model.base import DifferentialDrive, FixedBase, Omnidirectional
from pbvs_pin.model.servo import ServoModel
from pbvs_pin.plant.mujoco_plant import MujocoPlant
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.metrics import summarize
from pbvs_pin.sim.scenario import load_scenario


def test_the_paper_gains_and_lags_fit_a_holonomic_base(tiago_pro):
    """Written for (u, omega): the forward value goes to vx and vy, the yaw value to omega."""
    assert tiago_pro.velocity_names[:3] == ("vx", "vy", "omega")
    settings = ControllerSettings.from_scenario(load_scenario("experiment1"))
    gains = kinematic_law(settings, tiago_pro, 0.0).gains
    np.testing.assert_array_equal(gains.k1[:3], [0.7, 0.7, 1.0])
    np.testing.assert_array_equal(gains.k1[3:], 0.1)
    lags = ServoModel.from_robot(tiago_pro).time_constants
    np.testing.assert_array_equal(lags[:3], [0.26, 0.26, 0.23])
    with pytest.raises(GainError, match="platform: expected 1, 2 or 3 time constants"):
        ServoModel.from_robot(tiago_pro, platform=(0.2, 0.2, 0.2, 0.2))


def test_per_velocity_fits_each_base():
    assert DifferentialDrive(0.1, 0.4, 5.0).per_velocity(0.7, 1.0) == (0.7, 1.0)
    assert Omnidirectional().per_velocity(0.7, 1.0) == (0.7, 0.7, 1.0)
    assert FixedBase().per_velocity(0.7, 1.0) == ()


def test_five_gains_on_a_five_dof_robot_are_its_own(tiago_pro):
    """Five values fit any robot as the paper's (2 base + 3 arm) unless the robot has five
    velocities: then they are its own, one per velocity, whatever its base."""
    five = (0.5, 0.6, 0.7, 0.8, 0.9)
    holonomic_two_joints = SimpleNamespace(n=5, n_base=3, n_arm=2, base=Omnidirectional())
    assert _reference_gains(five, holonomic_two_joints) == five
    fitted = _reference_gains(five, tiago_pro)  # 3 base + 8 arm velocities
    assert fitted == (0.5, 0.5, 0.6, *([0.9] * 8))


def test_mujoco_mass_matrix_is_pinocchios_in_the_platform_frame(tiago_pro):
    """MuJoCo's planar joints move along the world's x, y: ``v_mj = T v`` with ``T`` the
    heading's rotation on (vx, vy), so ``T^T M_mj T`` must be Pinocchio's ``S^T M S``."""
    robot = tiago_pro
    plant = MujocoPlant(robot, ServoModel.from_robot(robot), robot.home())
    dofs = [0, 1, 2, *plant._arm_dof]
    lower, upper = robot.arm_position_limits()
    rng = np.random.default_rng(11)
    full = np.zeros((plant.model.nv, plant.model.nv))
    for _ in range(3):
        q = robot.with_arm_positions(robot.neutral(), rng.uniform(lower, upper))
        yaw = rng.uniform(-np.pi, np.pi)
        q[:4] = *rng.uniform(-2, 2, 2), np.cos(yaw), np.sin(yaw)
        plant.reset(q)
        assert np.allclose(plant.q, q, atol=1e-12)
        mujoco.mj_fullM(plant.model, plant.data, full)
        turn = np.eye(len(dofs))
        turn[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
        mass_mj = turn.T @ full[np.ix_(dofs, dofs)] @ turn
        mass_pin = pin.crba(robot.model, robot.data, q)
        mass_pin = np.triu(mass_pin) + np.triu(mass_pin, 1).T
        mass_pin = robot.selection.T @ mass_pin @ robot.selection
        assert np.linalg.norm(mass_mj - mass_pin) <= 1e-6 * np.linalg.norm(mass_pin)


@pytest.mark.parametrize(("index", "command"), [(0, 0.3), (1, 0.3), (2, 0.4)])
def test_each_base_velocity_follows_the_platform_lag_along_its_own_axis(tiago_pro, index, command):
    """On the MuJoCo plant, a step ``c`` of vx, vy or omega follows the platform's first-order
    lag ``c (1 - exp(-t / T))`` (to 5 % of the step: the joint servos' own 0.01 s lag adds up to
    ``c 0.01 / T``, 4 %), and
    moves the base along its own axis from a turned heading by ``c (t - T (1 - exp(-t / T)))``;
    the other two velocities stay near zero."""
    robot = tiago_pro
    servo = ServoModel.from_robot(robot)
    start = robot.home()
    heading = 0.5
    start[2:4] = np.cos(heading), np.sin(heading)
    plant = MujocoPlant(robot, servo, start)
    v_ref = np.zeros(robot.n)
    v_ref[index] = command
    lag = servo.time_constants[index]
    for step in range(1, 1501):
        plant.step(v_ref)
        expected = command * (1.0 - np.exp(-step * plant.dt / lag))
        assert plant.v[index] == pytest.approx(expected, abs=0.05 * command)
        assert np.abs(np.delete(plant.v[:3], index)).max() < 0.05 * command
    travel = command * (1.5 - lag * (1 - np.exp(-1.5 / lag)))
    moved = plant.q[:2] - start[:2]
    turned = np.arctan2(plant.q[3], plant.q[2]) - heading
    if index == 2:
        assert np.hypot(*moved) < 0.01 and turned == pytest.approx(travel, abs=0.02)
    else:
        axis = (np.cos(heading), np.sin(heading)) if index == 0 else (-np.sin(heading),
                                                                     np.cos(heading))
        np.testing.assert_allclose(moved, travel * np.asarray(axis), atol=0.01)
        assert abs(turned) < 0.01


def test_a_holonomic_base_steers_clear_of_the_obstacle(tiago_pro):
    """Experiment 3 on the Pinocchio plant: with avoidance (the lateral repulsion of
    ``obstacle_force``) TIAGo Pro keeps clear of the obstacle and holds the target; without
    it the platform runs into it. docs/departures.md quotes both clearances."""
    scenario = load_scenario("experiment3")
    clearance = {}
    for avoid in (True, False):
        run = scenario.with_values(**{"secondary.obstacle_avoidance": avoid})
        summary = summarize(simulate(run, robot=tiago_pro))
        clearance[avoid] = summary["min_clearance_m"]
        if avoid:
            assert summary["max_abs_error_final_window_px"] < 12.0
            assert summary["target_lost_samples"] == 0
    assert clearance[True] > 0.2 and clearance[False] < 0.0, clearance
    stated(
        f"With it, TIAGo Pro keeps {clearance[True]:.3f} m clear in Experiment 3; without any "
        f"avoidance it reaches {clearance[False]:.3f} m."
    )
