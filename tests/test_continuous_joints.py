"""Continuous joints (issue 32, item 3): an angle and the same angle plus 2 pi are one posture.

The arm is ``data/continuous_arm.urdf``, a hobby arm of three continuous joints without
``<limit>`` whose pan joint's origin turns it round, so that its forward-looking home is at
pan = +-pi: an offset of 0.02 rad across the wrap must read 0.02 rad in the home solver, the
controller's posture objective (both the modular and the compiled step) and the run's
metrics, never ``2 pi - 0.02``.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import DATA_DIR
from simhelpers import controller_with_first_frame

from pbvs_pin import MobileManipulator
from pbvs_pin.bringup.catalogue import OPTICAL_FROM_BODY, PIONEER_MOUNT
from pbvs_pin.bringup.home import assess_home, compute_home
from pbvs_pin.control.secondary import ArmPosture, SecondaryInput, posture_term
from pbvs_pin.model.joint_angles import arm_difference
from pbvs_pin.model.manipulability import max_manipulability_posture
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.metrics import posture_error, summarize
from pbvs_pin.sim.scenario import load_scenario

ARM = DATA_DIR / "continuous_arm.urdf"
OFFSET = 0.02  # [rad], across the wrap
NEAR_PI = np.pi - OFFSET / 2  # pan of the posture target
ACROSS = -np.pi + OFFSET / 2  # pan of the arm: NEAR_PI + OFFSET, wrapped


@pytest.fixture(scope="module")
def hobby():
    return MobileManipulator.assemble(
        "pioneer3at", str(ARM), PIONEER_MOUNT, "tool_link", OPTICAL_FROM_BODY
    )


def test_the_arms_joints_are_continuous_without_limits(hobby):
    assert hobby.arm_joint_names == ("pan_joint", "shoulder_joint", "elbow_joint")
    assert hobby.arm_continuous.all()
    lower, upper = hobby.arm_position_limits()
    assert np.all(lower == -np.inf) and np.all(upper == np.inf)


@pytest.mark.parametrize(
    ("a", "b", "expected"),
    [
        (ACROSS, NEAR_PI, OFFSET),  # across the wrap: the short way
        (NEAR_PI, ACROSS, -OFFSET),
        (0.3 + 4 * np.pi, 0.1, 0.2),  # whole turns do not count
        (0.1, 0.3, -0.2),
    ],
)
def test_a_continuous_joints_difference_is_the_shortest_way_round(a, b, expected):
    got = arm_difference(np.array([a, a]), np.array([b, b]), np.array([True, False]))
    assert got[0] == pytest.approx(expected, abs=1e-12)
    assert got[1] == pytest.approx(a - b, abs=1e-12)  # not continuous: as it is


def test_the_posture_objective_pulls_the_short_way_across_the_wrap():
    """Eq. (19) with the arm 0.02 rad past pi: -k 0.02, not k (2 pi - 0.02)."""
    gain = 1.5
    arm, target = np.array([ACROSS, 0.2]), np.array([NEAR_PI, 0.2])
    np.testing.assert_allclose(
        posture_term(arm, target, gain, np.array([1, 1])), [-gain * OFFSET, 0.0], atol=1e-12
    )
    state = SecondaryInput(arm, np.inf, 0.0, 0.01)
    modular = ArmPosture(target, gain, np.array([True, False])).contribution(state, 2, 4)
    np.testing.assert_allclose(modular, [0.0, 0.0, -gain * OFFSET, 0.0], atol=1e-12)
    revolute = ArmPosture(target, gain).contribution(state, 2, 4)  # no joint continuous
    assert revolute[2] == pytest.approx(gain * (2 * np.pi - OFFSET))


def test_the_posture_error_metric_wraps_continuous_joints_only():
    arm = np.array([[ACROSS, ACROSS], [NEAR_PI, NEAR_PI]])
    target = np.array([NEAR_PI, NEAR_PI])
    error = posture_error(arm, target, [True, False])
    np.testing.assert_allclose(error[:, 0], [OFFSET, 0.0], atol=1e-12)
    np.testing.assert_allclose(error[:, 1], [-2 * np.pi + OFFSET, 0.0], atol=1e-12)
    # a log written before meta["arm_continuous"] existed: nothing wraps
    np.testing.assert_allclose(posture_error(arm, target, None), arm - target)


def test_the_home_is_found_across_the_wrap_and_given_in_minus_pi_pi(hobby):
    home = compute_home(hobby)
    assert -np.pi <= home[0] < np.pi
    assert abs(arm_difference(home[:1], np.array([np.pi]), np.array([True]))[0]) < 1e-6
    found = assess_home(hobby, home)
    assert found.forward_error < 1e-6 and abs(found.roll) < 1e-6
    # Independent check: pan pi undoes the origin's yaw pi, so the forearm (the camera's
    # body x) points along the platform's x; the pitches cancel for a level camera.
    assert home[1] + home[2] == pytest.approx(0.0, abs=1e-6)


def test_the_most_manipulable_posture_stays_nearest_home_the_short_way(hobby):
    hobby.home_arm = np.array([ACROSS, 0.5, -0.5])
    theta_d = max_manipulability_posture(hobby)
    assert np.all((-np.pi <= theta_d) & (theta_d < np.pi))
    # the yaw joint does not change manipulability: it stays at home's pan
    assert arm_difference(theta_d[:1], hobby.home_arm[:1], np.array([True]))[0] == (
        pytest.approx(0.0, abs=1e-3)
    )


def _scenario(duration: float):
    """Experiment 1 on the hobby arm, home 0.01 rad short of pi, starting 0.01 rad past it."""
    robot = {"name": "", "base": "pioneer3at", "arm": str(ARM), "mount": list(PIONEER_MOUNT),
             "camera_link": "tool_link", "camera_pose": list(OPTICAL_FROM_BODY),
             "home": [NEAR_PI, 0.5, -0.5], "initial_arm": [ACROSS, 0.5, -0.5]}  # fmt: skip
    values = {f"robot.{key}": value for key, value in robot.items()}
    values["secondary.posture"] = True  # eq. (19) on: off in Experiment 1
    return load_scenario("experiment1").with_values(duration=duration, **values)


def test_the_compiled_step_pulls_the_short_way_as_the_modular_blocks_do():
    """At the start, the pan 0.02 rad across the wrap from its target: the compiled step's
    null-space term equals the modular blocks' (whose wrap the test above checks), and is as
    small as a pull of k 0.02 gives, not k (2 pi - 0.02)."""
    scenario = _scenario(1.0).with_values(**{"camera.latency": 0.0, "estimator.predict": False})
    setup, modular = controller_with_first_frame(scenario, modular=True)
    _, fused = controller_with_first_frame(scenario)
    q = setup.plant.q
    assert arm_difference(setup.model.arm_positions(q), modular.posture_target,
                          np.ones(3, bool))[0] == pytest.approx(OFFSET)  # fmt: skip
    for control in (modular, fused):
        control.step(0.1, q, np.zeros(setup.model.n), target_velocity=np.zeros(3))
    null_space = [control.diagnostics()[0].null_space for control in (modular, fused)]
    np.testing.assert_allclose(null_space[1], null_space[0], atol=1e-12)
    # measured: 3.0e-4 here; 6.3e-2 with the pan's difference unwrapped (2 pi - 0.02)
    assert 0.0 < np.linalg.norm(null_space[1]) < 0.1 * OFFSET


def test_a_run_across_the_wrap_reads_the_offset_not_a_turn():
    """Experiment 1 with eq. (19) on, the pan starting 0.02 rad across the wrap from its
    target: the summary reads the posture error the short way round, as the reference (which
    wraps with complex exponentials) does; unwrapped, it read 6.27 rad."""
    log = simulate(_scenario(1.0))
    posture = np.array(log.meta["posture_target"])
    error = np.abs(np.angle(np.exp(1j * (log["arm"] - posture))))
    assert error[0, 0] == pytest.approx(OFFSET, abs=1e-6)
    summary = summarize(log)
    assert log.meta["arm_continuous"] == [True, True, True]
    assert log["t"][-1] < 5.0  # the final window is the whole run
    assert summary["posture_error_final_window_rad"] == pytest.approx(error.max(), abs=1e-9)
    assert summary["posture_error_final_window_rad"] < 0.2
    assert summary["joint_limit_violation"] == 0.0
