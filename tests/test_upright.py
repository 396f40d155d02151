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
from simhelpers import controller_with_first_frame

from pbvs_pin.control.gains import ServoGains
from pbvs_pin.control.kinematic import PassivityController
from pbvs_pin.control.step import FusedControlStep, split_objectives
from pbvs_pin.control.upright import (
    LOOP_GAIN_MARGIN,
    RESTORING_RATE,
    delayed_margin,
    loop_gain_factor,
    upright_row,
)
from pbvs_pin.sim import loop
from pbvs_pin.sim.scenario import load_scenario

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
def _setup(name: str, experiment: str = "experiment4", modular: bool = True, **gains):
    """The public controller on ``name`` with a first frame taken, its law's gains replaced."""
    scenario = load_scenario(experiment).with_values(
        **{
            "robot.name": name,
            "camera.latency": 0.0,
            "estimator.predict": False,
        }  # a frame at once, as it is
    )
    setup, control = controller_with_first_frame(scenario, modular)
    if gains:
        control.law = PassivityController(
            dataclasses.replace(control.law.gains, **gains), control.law.velocity_limits
        )
        if not modular:  # the compiled step packs the law's gains when it is built
            control.fused = FusedControlStep(
                control.model, control.features, control.xi_d, control.law,
                control.compensator, *split_objectives(control.objectives, ()),
            )  # fmt: skip
    return setup, control


def _output(control, q, t: float = 1.0, v=None, laser=None):
    """The kinematic output and ``(J, J_o)`` of a step at ``(t, q)`` on the first frame."""
    v = np.zeros(control.model.n) if v is None else v
    command = control.step(t, q, v, laser=laser, target_velocity=np.zeros(3))
    output, jacobians = control.diagnostics()
    return output, jacobians, command


@pytest.mark.parametrize("name", ["pioneer_panda", "tiago"])
@pytest.mark.parametrize("seed", range(2))
def test_projected_null_space_does_not_roll_the_image(name, seed):
    """With the feature, phi changes only at the restoring rate; without, the posture rolls."""
    setup, on = _setup(name)
    _, off = _setup(name, upright=False)
    robot = setup.model
    q = _posture(robot, seed)
    output, (jacobian, _), _ = _output(on, q)
    paper, _, _ = _output(off, q)
    phi = _phi(robot, q)
    assert abs(phi) > 0.005 and output.upright_weight == 1.0  # the image somewhat rolled
    assert abs(_phi_rate(robot, q, paper.null_space)) > 1e-3  # the paper's law rolls the image
    assert _phi_rate(robot, q, output.null_space) == pytest.approx(-RESTORING_RATE * phi, abs=1e-7)
    # still a self-motion: the features do not move (J in px)
    assert np.linalg.norm(jacobian @ output.null_space) < 1e-9 * SCALE


def test_restoring_term_is_off_without_roll_at_home(load):
    """At the upright home only the removal acts: phi's rate along eta is zero."""
    setup, on = _setup("pioneer_panda")
    q = setup.plant.q
    output, _, _ = _output(on, q)
    assert abs(_phi_rate(setup.model, q, output.null_space)) < 1e-3 * RESTORING_RATE + 1e-7


# ---------------------------------------------------------------- reference robot unchanged
def test_reference_robot_output_is_bit_identical_with_and_without():
    """Experiment 2 (every objective on), 3 s: same u, v_ref and q to the last bit.

    Without the camera's latency: the net's margin is then the full one, which the reference
    robot stays below (with one frame of latency the halved margin acts).
    """
    scenario = load_scenario("experiment2").with_values(
        duration=3.0, **{"camera.latency": 0.0, "controller.feedback": "transpose"}
    )  # the net acts on the paper's law (the balanced law has nothing for it to cut)
    with_feature = loop.simulate(scenario)
    without = loop.simulate(
        scenario.with_values(**{"controller.upright": False, "controller.loop_gain_margin": 1e12})
    )
    for name in ("u", "v_ref", "q", "xi"):
        assert np.array_equal(with_feature[name], without[name], equal_nan=True), name
    assert not with_feature["gain_limited"].any()
    assert np.nanmax(with_feature["loop_gain"]) < LOOP_GAIN_MARGIN


@pytest.mark.parametrize("feedback", ["transpose", "balanced"])
def test_fused_step_equals_modular_on_an_arm_that_rolls(feedback):
    """The compiled step applies the projection, the net (the paper's law) and the balanced
    feedback with its joints' room as the modular controller does."""
    gains = {"camera_period": 0.5, "feedback": feedback}
    setup, modular = _setup("pioneer_panda", "experiment2", **gains)
    _, fused = _setup("pioneer_panda", "experiment2", modular=False, **gains)
    assert fused.fused is not None
    rng = np.random.default_rng(5)
    q = setup.plant.q
    for step in range(1, 4):
        q = setup.model.integrate(q, rng.uniform(-0.05, 0.05, setup.model.n), 1.0)
        v = rng.uniform(-0.2, 0.2, setup.model.n)
        output, _, command = _output(modular, q, step, v)
        fused_output, _, fused_command = _output(fused, q, step, v)
        np.testing.assert_allclose(fused_command.u, command.u, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(fused_output.null_space, output.null_space, atol=1e-12)
        assert fused_output.upright_weight == output.upright_weight == 1.0
        assert fused_output.gain_limited == output.gain_limited == (feedback == "transpose")
        assert fused_output.loop_gain == pytest.approx(output.loop_gain, rel=1e-10)


# ---------------------------------------------------------------- loop-gain net, by hand
def test_loop_gain_factor_below_and_above_the_margin():
    """``g = k T lambda_max``; the factor is 1 up to the margin, then ``margin / g``."""
    factor, gain = loop_gain_factor(4.0, 0.15, 1.0 / 30.0, 1.0)
    assert gain == pytest.approx(0.15 / 30.0 * 4.0, rel=1e-12) and factor == 1.0
    factor, gain = loop_gain_factor(400.0, 0.15, 1.0 / 30.0, 1.0)
    assert gain == pytest.approx(2.0, rel=1e-12) and factor == pytest.approx(0.5, rel=1e-12)
    assert loop_gain_factor(1.0, 1.0, 1.0, 1.0) == (1.0, 1.0)  # at the margin: not limited


@pytest.mark.parametrize("delay", [0, 1, 2, 3])
def test_delayed_margin_is_the_stability_limit_of_the_delayed_loop(delay):
    """``e_{k+1} = e_k - g e_{k-d}``: the roots of ``z^{d+1} - z^d + g`` leave the unit circle
    at twice the delayed margin (numpy's roots, not the closed form)."""
    limit = 2.0 * delayed_margin(1.0, delay)

    def spectral_radius(g: float) -> float:
        return max(
            abs(np.roots([1.0, -1.0, *([0.0] * (delay - 1)), g] if delay else [1.0, g - 1.0]))
        )

    assert spectral_radius(0.999 * limit) < 1.0 < spectral_radius(1.001 * limit)
    assert delayed_margin(0.7, delay) == pytest.approx(0.7 * limit / 2.0, rel=1e-12)
    assert delayed_margin(1.0, 0) == 1.0 and delayed_margin(1.0, 1) == pytest.approx(0.5)
