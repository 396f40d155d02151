"""The upright-image projection and the loop-gain safety net (issue 8, items 3 and 5).

References are written here: the upright angle from its definition (world up in the optical
frame), its rate by central finite differences through ``pin.integrate`` of ``S v dt``, the
largest eigenvalue of ``J J^T`` by numpy, the paper's law by hand.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from pbvs_pin.control.kinematic import PassivityController, ServoGains
from pbvs_pin.control.step import FusedControlStep
from pbvs_pin.control.upright import LOOP_GAIN_MARGIN, RESTORING_RATE, upright_row
from pbvs_pin.sim import loop
from pbvs_pin.sim.loop import _control_step
from pbvs_pin.sim.perception import Perception
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.setup import build

SCALE = 150.0
ROLLING_ARMS = ("tiago", "pioneer_panda", "pioneer_xarm7", "pioneer_ur5")
"""Shipped robots whose arm can roll the camera about its optical axis."""

STEP = 1e-6
"""Finite-difference step [s] with a unit velocity."""


def _phi(robot, q: np.ndarray) -> float:
    """Upright angle by its definition: ``c = wRc^T e_z``, ``atan2(c_x, -c_y)``."""
    pin.framesForwardKinematics(robot.model, robot.data, q)
    up = robot.data.oMf[robot.camera_frame_id].rotation.T @ np.array([0.0, 0.0, 1.0])
    return float(np.arctan2(up[0], -up[1]))


def _moved(robot, q: np.ndarray, v: np.ndarray, dt: float) -> np.ndarray:
    return pin.integrate(robot.model, q, robot.selection @ v * dt)


def _phi_rate(robot, q: np.ndarray, v: np.ndarray) -> float:
    """``d phi / dt`` along actuated velocity ``v``, central differences."""
    ahead, behind = _phi(robot, _moved(robot, q, v, STEP)), _phi(robot, _moved(robot, q, v, -STEP))
    return (ahead - behind) / (2.0 * STEP)


def _posture(robot, seed: int) -> np.ndarray:
    """A posture near home, base moved and turned, arm perturbed (the image somewhat rolled)."""
    rng = np.random.default_rng(seed)
    return _moved(robot, robot.home(), rng.uniform(-0.4, 0.4, robot.n), 1.0)


def _row(robot, q: np.ndarray) -> np.ndarray:
    jacobian = robot.camera_jacobian(q)
    return upright_row(robot.camera_pose(q).rotation, jacobian)


# ---------------------------------------------------------------- j_phi
@pytest.mark.parametrize("name", [*ROLLING_ARMS, "pioneer_cyton", "pioneer_kinova"])
@pytest.mark.parametrize("seed", range(2))
def test_upright_row_is_the_finite_difference_of_phi(load, name, seed):
    robot = load(name)
    q = _posture(robot, seed)
    row = _row(robot, q)
    assert row[0] == pytest.approx(_phi(robot, q), abs=1e-12)
    expected = np.array([_phi_rate(robot, q, e) for e in np.eye(robot.n)])
    np.testing.assert_allclose(row[1:], expected, atol=1e-7)
    if name == "pioneer_cyton":  # yaw, pitch, pitch: the image cannot roll (URDF round-off)
        assert np.max(np.abs(row[1:])) < 1e-3 * ServoGains().damping_threshold
    else:
        assert np.max(np.abs(row[1:])) > 0.3


def test_base_motion_and_camera_pitch_leave_an_upright_image_upright(load):
    """At home (image upright) neither the platform nor a pitch of the camera changes phi."""
    robot = load("pioneer_panda")
    q = robot.home()
    row = _row(robot, q)
    assert abs(row[0]) < 1e-3
    np.testing.assert_allclose(row[1:3], 0.0, atol=1e-12)  # platform: u, omega
    pitch = np.linalg.lstsq(robot.camera_jacobian(q)[3:], [1.0, 0.0, 0.0], rcond=None)[0]
    assert abs(row[1:] @ pitch) < 1e-3


# ---------------------------------------------------------------- projected null space
def _setup(name: str, experiment: str = "experiment4", **gains):
    """A loop setup on ``name`` with a first frame taken, the controller's gains replaced."""
    scenario = load_scenario(experiment).with_values(
        **{"robot.name": name, "camera.latency": 0.0, "estimator.predict": False}  # a frame at once, as it is
    )
    setup = build(scenario)
    if gains:
        setup.controller = PassivityController(
            dataclasses.replace(setup.controller.gains, **gains), setup.controller.velocity_limits
        )
    perception = Perception(setup)
    q = setup.plant.q
    setup.sensor.capture(0.0, setup.robot.camera_pose(q), setup.target.centres(0.0), q)
    perception.take(setup.sensor.deliver(0.0))
    return setup, perception


@pytest.mark.parametrize("name", ["pioneer_panda", "tiago"])
@pytest.mark.parametrize("seed", range(2))
def test_projected_null_space_does_not_roll_the_image(name, seed):
    """With the feature, phi changes only at the restoring rate; without, the posture rolls."""
    on, perception = _setup(name)
    off, _ = _setup(name, upright=False)
    robot = on.model
    q = _posture(robot, seed)
    output, (jacobian, _) = _control_step(on, perception, q, (np.inf, 0.0), 0.0, 0.01)
    paper, _ = _control_step(off, perception, q, (np.inf, 0.0), 0.0, 0.01)
    phi = _phi(robot, q)
    assert abs(phi) > 0.02 and output.upright_weight == 1.0
    assert abs(_phi_rate(robot, q, paper.null_space)) > 1e-3  # the paper's law rolls the image
    assert _phi_rate(robot, q, output.null_space) == pytest.approx(-RESTORING_RATE * phi, abs=1e-7)
    # still a self-motion: the features do not move (J in px)
    assert np.linalg.norm(jacobian @ output.null_space) < 1e-9 * SCALE


def test_restoring_term_is_off_without_roll_at_home(load):
    """At the upright home only the removal acts: phi's rate along eta is zero."""
    on, perception = _setup("pioneer_panda")
    q = on.plant.q
    output, _ = _control_step(on, perception, q, (np.inf, 0.0), 0.0, 0.01)
    assert abs(_phi_rate(on.model, q, output.null_space)) < 1e-3 * RESTORING_RATE + 1e-7


# ---------------------------------------------------------------- reference robot unchanged
def test_reference_robot_output_is_bit_identical_with_and_without():
    """Experiment 2 (every objective on), 3 s: same u, v_ref and q to the last bit.

    Without the camera's latency: the net's margin is then the full one, which the reference
    robot stays below (with one frame of latency the halved margin acts).
    """
    scenario = load_scenario("experiment2").with_values(
        duration=3.0, **{"camera.latency": 0.0}
    )
    with_feature = loop.simulate(scenario)
    without = loop.simulate(
        scenario.with_values(**{"controller.upright": False, "controller.loop_gain_margin": 1e12})
    )
    for name in ("u", "v_ref", "q", "xi"):
        assert np.array_equal(with_feature[name], without[name], equal_nan=True), name
    assert not with_feature["gain_limited"].any()
    assert np.nanmax(with_feature["loop_gain"]) < LOOP_GAIN_MARGIN


def test_fused_step_equals_modular_on_an_arm_that_rolls():
    """The compiled step applies the projection and the net as the modular controller does."""
    modular, perception = _setup("pioneer_panda", "experiment2", camera_period=0.5)
    fused_setup, _ = _setup("pioneer_panda", "experiment2", camera_period=0.5)
    fused = FusedControlStep(
        fused_setup.model, fused_setup.features, fused_setup.xi_d, fused_setup.controller,
        fused_setup.compensator, fused_setup.objectives,
    )  # fmt: skip
    rng = np.random.default_rng(5)
    q = modular.plant.q
    for step in range(3):
        q = modular.model.integrate(q, rng.uniform(-0.2, 0.2, modular.model.n), 1.0)
        v = rng.uniform(-0.2, 0.2, modular.model.n)
        perception.velocity = lambda t: np.zeros(3)
        output, _ = _control_step(modular, perception, q, (np.inf, 0.0), 0.0, 0.01)
        u_f, _, _ = fused.step(
            q, v, perception.measurement, np.zeros(3), np.array([np.inf, 0]), 0.01
        )
        fused_output, _ = fused.output()
        np.testing.assert_allclose(u_f, output.u, rtol=1e-10, atol=1e-12, err_msg=f"u {step}")
        np.testing.assert_allclose(fused_output.null_space, output.null_space, atol=1e-12)
        assert fused_output.upright_weight == output.upright_weight == 1.0
        assert fused_output.gain_limited and output.gain_limited
        assert fused_output.loop_gain == pytest.approx(output.loop_gain, rel=1e-10)
        assert fused_output.upright_angle == pytest.approx(output.upright_angle, abs=1e-12)


# ---------------------------------------------------------------- loop-gain safety net
@pytest.mark.parametrize("stretch", [0.2, 3.0, 30.0])
def test_loop_gain_net_caps_the_gain_per_sample(stretch):
    """Feedback scaled by min(1, margin / (k T lambda_max(J J^T))), flagged when it acts."""
    n, period = 5, 1.0 / 30.0
    rng = np.random.default_rng(11)
    jacobian = stretch * rng.standard_normal((3, n))  # controller units
    gains = ServoGains(k=(0.15, 0.1, 0.12), k1=(0.1,), k2=(0.2,), camera_period=period)
    controller = PassivityController(gains, np.full(n, 1e9))
    error = rng.uniform(-0.5, 0.5, 3)

    out = controller.step(
        error * SCALE, jacobian * SCALE, np.zeros((3, 3)), np.zeros(3), np.zeros(n)
    )

    largest = np.linalg.eigvalsh(jacobian @ jacobian.T)[-1]
    g = 0.15 * period * largest
    factor = min(1.0, LOOP_GAIN_MARGIN / g)
    k = factor * np.array([0.15, 0.1, 0.12])
    expected = -jacobian.T @ (k / (1.0 + np.abs(error)) * error)
    assert out.loop_gain == pytest.approx(g, rel=1e-9)
    assert out.gain_limited == (g > LOOP_GAIN_MARGIN)
    np.testing.assert_allclose(out.u, expected, rtol=1e-9, atol=1e-14)
    limited = 0.15 * factor * period * largest
    assert limited <= LOOP_GAIN_MARGIN * (1 + 1e-12)


def test_loop_gain_net_is_flagged_in_the_log():
    """A margin the reference robot exceeds: the log's gain_limited channel says so."""
    scenario = load_scenario("experiment1").with_values(
        duration=1.0, **{"controller.loop_gain_margin": 1e-3}
    )
    log = loop.simulate(scenario)
    seen = np.isfinite(log["loop_gain"])
    assert seen.sum() > 10
    np.testing.assert_array_equal(log["gain_limited"][seen], log["loop_gain"][seen] > 1e-3)
    assert log["gain_limited"][seen].all()
