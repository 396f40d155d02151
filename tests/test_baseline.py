"""The classic IBVS baseline: its stated gain rule and its null-space objectives."""

from __future__ import annotations

import numpy as np
import pytest

from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.setup import build, solve_target_start
from pbvs_pin.study.baseline import (
    GAIN_RULE,
    baseline_scenario,
    baseline_section,
    comparison_figures,
    matched_ibvs_gain,
)

FEATURE_ROWS = [0, 1, 3]  # u1, v1, v2 of the two flattened image points


def _features(robot, q, centres):
    image, _ = robot.camera.project_world(robot.camera_pose(q), centres)
    return image.reshape(-1)[FEATURE_ROWS]


def test_gain_is_the_passivity_laws_mean_small_error_rate():
    """lambda = k tr(J J^T) / (3 scale^2), J by finite differences of the projection at xi_d."""
    scenario = load_scenario("experiment1")
    setup = build(scenario)
    robot, q0 = setup.robot, setup.plant.q.copy()
    separation = scenario.target.separation
    top = solve_target_start(robot, q0, setup.features, separation, np.array(scenario.target.xi_d))
    centres = np.array([top, top - [0.0, 0.0, separation]])
    np.testing.assert_allclose(_features(robot, q0, centres), scenario.target.xi_d, atol=1e-6)
    h = 1e-6
    jacobian = np.column_stack([
        (_features(robot, robot.integrate(q0, e, h), centres)
         - _features(robot, robot.integrate(q0, -e, h), centres)) / (2 * h)
        for e in np.eye(robot.n)
    ])  # fmt: skip
    k, scale = scenario.controller.k[0], scenario.controller.feature_scale
    expected = k * np.trace(jacobian @ jacobian.T) / (3 * scale**2)
    assert matched_ibvs_gain("experiment1") == pytest.approx(expected, rel=1e-5)
    assert 5.0 < expected < 20.0  # far above the old fixed 0.5 /s
    assert baseline_scenario("experiment2", expected).controller.ibvs_gain == expected


@pytest.fixture(scope="module")
def ibvs_experiment2():
    return simulate(baseline_scenario("experiment2", matched_ibvs_gain()), progress=False)


def test_null_space_objectives_act_and_avoid_the_obstacle(ibvs_experiment2):
    gain = matched_ibvs_gain()
    short = {"duration": 3.0}
    with_objectives = simulate(
        baseline_scenario("experiment2", gain).with_values(**short), progress=False
    )
    without = simulate(
        baseline_scenario("experiment2", gain).with_values(
            **short, **{"secondary.obstacle_avoidance": False, "secondary.posture": False}
        ),
        progress=False,
    )
    assert np.max(np.abs(with_objectives["u"] - without["u"])) > 1e-2
    assert np.nanmin(ibvs_experiment2["clearance"]) > 0.0


def test_comparison_figures_and_section(ibvs_experiment2):
    figures = comparison_figures(ibvs_experiment2)
    t = ibvs_experiment2["t"]
    error = ibvs_experiment2["xi_true"] - ibvs_experiment2["xi_d"]
    settle = figures["time_to_settle_s"]
    assert settle is not None
    assert np.all(np.abs(error[t >= settle]) < 10.0)
    assert np.max(np.abs(error[t < settle][-1])) >= 10.0
    rms = np.sqrt(np.mean(np.linalg.norm(error[t >= 2.0], axis=1) ** 2))  # the run tables' RMS
    assert figures["rms_after_transient_px"] == pytest.approx(rms)
    text = baseline_section([("experiment2", figures, figures)], 10.0)
    assert GAIN_RULE in text and text.count("| experiment2 |") == 2
    assert f"{rms:.2f}" in text


def test_saturation_is_counted_for_the_baseline_law():
    """The IBVS rows count the samples where u was scaled and where v_ref sits at a limit."""
    from pbvs_pin.sim.log import RunLog

    t = np.arange(6) * 1.0
    limits = [1.0, 2.0]
    v_ref = np.array([[0.5, 0.0], [1.0, 0.0], [0.2, -2.0], [0.0, 1.999], [-1.0, 2.0], [0, 0]])
    log = RunLog({"t": t, "xi_true": np.zeros((6, 3)), "xi_d": np.zeros((6, 3)),
                  "clearance": np.full(6, np.inf), "v_ref": v_ref,
                  "saturated": np.array([0, 0, 1, 0, 0, 0], dtype=bool)},
                 {"velocity_limits": limits})  # fmt: skip
    figures = comparison_figures(log)
    assert figures["saturated_samples"] == 1
    assert figures["v_ref_at_limit_samples"] == 3  # rows 1, 2 and 4; 1.999 is below 2
    text = baseline_section([("experiment1", figures, figures)], 1.0)
    assert text.count("| 1 | 3 |") == 2


def test_a_command_cut_by_the_limits_is_saturated_whoever_cut_it():
    """The law's scaling of u, or the compensator's clip of v_ref onto a limit, both count."""
    from pbvs_pin.sim.log import command_limited

    limits = np.array([1.0, 2.0])
    assert command_limited(True, np.array([0.1, 0.1]), limits)  # u scaled, v_ref inside
    assert command_limited(False, np.array([0.1, -2.0]), limits)  # v_ref clipped at -2
    assert command_limited(False, np.array([1.0, 0.0]), limits)
    assert not command_limited(False, np.array([0.999, 1.999]), limits)
    assert not command_limited(False, np.zeros(2), limits)


def test_the_baseline_runs_saturation_is_in_its_saturated_channel(ibvs_experiment2):
    """Experiment 2's IBVS run puts v_ref on a limit (28 samples when measured) while its u
    stays inside them: every such sample is saturated, and the summary's fraction is not 0."""
    from pbvs_pin.sim.metrics import summarize

    log = ibvs_experiment2
    limits = np.asarray(log.meta["velocity_limits"])
    at_limit = np.any(np.abs(log["v_ref"]) >= (1 - 1e-6) * limits, axis=1)
    assert at_limit.sum() > 0
    assert np.all(log["saturated"][at_limit])
    figures = comparison_figures(log)
    assert figures["saturated_samples"] >= figures["v_ref_at_limit_samples"] == at_limit.sum()
    assert summarize(log)["saturated_fraction"] >= at_limit.mean() > 0
