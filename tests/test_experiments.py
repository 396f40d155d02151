"""Acceptance: the paper's four experiments on the reference robot, full shipped scenarios.

Each experiment runs once per module (about 40 s in all). Every figure asserted here is
computed from the log in this file; :func:`pbvs_pin.sim.metrics.summarize` is checked against
the same computation, and the report is built from the summaries of these runs (running
:func:`pbvs_pin.study.reproduction.reproduce` would repeat the four runs with figures and replays).
The README's results table is checked against these fresh runs, and rows are checked to flag
a lost target, a collision, a joint past its limit and v_ref at its limit.

Stated bounds (DESIGN.md §4, the paper's §5):

- Exp. 1: max |error| over the last 5 s < 8 px (the paper's figure).
- Exp. 2: after the 2 s transient every feature stays within half the image height (291 px)
  of its desired value while the platform avoids the obstacle; min clearance > 0; the arm
  ends within 0.1 rad of theta_d; and the error settles (last 5 s < 8 px, as Exp. 1).
- Exp. 3 (20 % kinematic error): same 291 px bound after the transient, min clearance > 0,
  and "degraded but acceptable": last 5 s < 12 px (1.5 times Exp. 1's 8 px).
- Exp. 4 (perfect knowledge): last 5 s < 0.5 px; V1 non-increasing after the transient
  without camera latency and with exact sensing, except right after the target's abrupt stop (the robot's velocity
  cannot jump), where the total increase stays below 5 % of V1(2 s); with the default one
  frame of latency V1 may ripple by at most 1e-4 V1(2 s).
"""

from __future__ import annotations

import numpy as np
import pytest
from docs_figures import EXPERIMENTS, OSCILLATION_FLAG_PX, run, stated
from simhelpers import IMAGE_HEIGHT_PX, TRANSIENT_S, feature_error

from pbvs_pin.sim.log import RunLog
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.metrics import FINAL_WINDOW, oscillation_rms, summarize
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.study.claims import claim_met
from pbvs_pin.study.experiments import PAPER_CLAIMS
from pbvs_pin.study.report import readme_block, readme_results, run_row
from pbvs_pin.study.reproduction import _report

HALF_IMAGE_HEIGHT_PX = IMAGE_HEIGHT_PX / 2


@pytest.fixture(scope="module")
def runs() -> dict[str, tuple[RunLog, dict]]:
    """Each experiment's log and summary (one run each per test session)."""
    results = {}
    for name in PAPER_CLAIMS:
        log = simulate(load_scenario(name))
        results[name] = (log, summarize(log))
    return results


def _final_window(log: RunLog) -> np.ndarray:
    t = log["t"]
    return t >= t[-1] - 5.0


def _max_final_error(log: RunLog) -> float:
    return float(np.max(np.abs(feature_error(log)[_final_window(log)])))


def _assert_sound(log: RunLog) -> None:
    """The report's sound rule, from the log: target never lost, no joint past its limits,
    no sustained oscillation (the error's part above the cut-off under 3 px RMS in every
    5 s window)."""
    assert not log["target_lost"].any()
    low, high = log.meta["arm_position_limits"]  # None: a continuous joint
    lower = np.array([-np.inf if x is None else x for x in low])
    upper = np.array([np.inf if x is None else x for x in high])
    assert np.all(log["arm"] >= lower - 0.01) and np.all(log["arm"] <= upper + 0.01)
    t = log["t"]
    assert oscillation_rms(t, feature_error(log))[0] < 3.0


def _max_error_after_transient(log: RunLog) -> float:
    return float(np.max(np.abs(feature_error(log)[log["t"] >= TRANSIENT_S])))


# ---------------------------------------------------------------- every run
@pytest.mark.parametrize("name", list(PAPER_CLAIMS))
def test_summary_matches_figures_computed_from_the_log(runs, name):
    log, summary = runs[name]
    assert FINAL_WINDOW == 5.0
    t = log["t"]
    assert summary["scenario"] == name and summary["robot"] == "pioneer_cyton"
    assert summary["duration_s"] == pytest.approx(load_scenario(name).duration, abs=0.05)
    assert summary["max_abs_error_final_window_px"] == pytest.approx(_max_final_error(log))
    assert summary["max_abs_error_after_transient_px"] == pytest.approx(
        _max_error_after_transient(log)
    )
    np.testing.assert_allclose(
        summary["final_abs_error_px"], np.abs(feature_error(log)[-1]), atol=1e-3
    )
    posture = np.abs(log["arm"][_final_window(log)] - np.asarray(log.meta["posture_target"]))
    assert summary["posture_error_final_window_rad"] == pytest.approx(np.max(posture))
    clearance = log["clearance"]
    if np.all(np.isinf(clearance)):
        assert summary["min_clearance_m"] is None or np.isinf(summary["min_clearance_m"])
    else:
        assert summary["min_clearance_m"] == pytest.approx(np.min(clearance))
    steps = np.diff(log["storage"][t >= TRANSIENT_S])
    assert summary["storage_increase_after_transient"] == pytest.approx(
        np.sum(steps[steps > 0]), abs=1e-15
    )
    assert summary["storage_decrease_after_transient"] == pytest.approx(
        -np.sum(steps[steps < 0]), abs=1e-15
    )
    assert summary["saturated_fraction"] == pytest.approx(np.mean(log["saturated"]))
    assert summary["target_lost_samples"] == int(np.sum(log["target_lost"]))


@pytest.mark.parametrize("name", list(PAPER_CLAIMS))
def test_commands_valid_finite_and_within_limits(runs, name):
    log, _ = runs[name]
    assert not log["target_lost"].any()
    # no command before the first frame arrives, one frame period after the start
    assert log["valid"][log["t"] >= load_scenario(name).camera.delivery_latency].all()
    limits = np.asarray(log.meta["velocity_limits"])
    for channel in ("u", "v_ref", "v"):
        assert np.all(np.isfinite(log[channel])), channel
    assert np.all(np.abs(log["u"]) <= limits * (1 + 1e-9))
    assert np.all(np.abs(log["v_ref"]) <= limits * (1 + 1e-9))


# ---------------------------------------------------------------- each experiment's claim
def test_experiment1_final_error_below_8px(runs):
    log, _ = runs["experiment1"]
    _assert_sound(log)
    assert _max_final_error(log) < 8.0
    # Ultimately bounded after the abrupt stop at 20 s: below 8 px from 25 s on.
    after_stop = log["t"] >= 25.0
    assert np.max(np.abs(feature_error(log)[after_stop])) < 8.0
    # The start really was far: xi(0) - xi_d = [-150, -40, -40] px.
    np.testing.assert_allclose(feature_error(log)[0], [-150, -40, -40], atol=0.5)


def test_experiment2_bounded_while_avoiding_and_posture_recovered(runs):
    log, _ = runs["experiment2"]
    _assert_sound(log)
    assert _max_error_after_transient(log) < HALF_IMAGE_HEIGHT_PX
    assert np.min(log["clearance"]) > 0.0
    assert np.min(log["obstacle_distance"]) < 1.2  # within d0: avoidance was active
    posture = np.abs(log["arm"][_final_window(log)] - np.asarray(log.meta["posture_target"]))
    assert np.max(posture) < 0.1
    assert _max_final_error(log) < 8.0


def test_experiment3_bounded_with_kinematic_error(runs):
    log, _ = runs["experiment3"]
    _assert_sound(log)
    assert load_scenario("experiment3").model_error.kinematic_scale == 1.2
    assert _max_error_after_transient(log) < HALF_IMAGE_HEIGHT_PX
    assert np.min(log["clearance"]) > 0.0
    assert _max_final_error(log) < 12.0


def _storage_steps(log: RunLog) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Exp. 4's V1 steps after the transient, V1 before each step, the 1 s after the stop,
    and V1 at the first frame (the scale: it does not depend on the feedback law)."""
    t, storage = log["t"], log["storage"]
    stop = load_scenario("experiment4").motion.stop_time
    after = t >= TRANSIENT_S
    steps = np.diff(storage[after])
    step_times = t[after][1:]
    bump = (step_times >= stop) & (step_times <= stop + 1.0)
    return steps, storage[after][:-1], bump, storage[np.isfinite(storage)][0]


def test_experiment4_converges_and_storage_does_not_increase(runs):
    """With a frame of latency (predicted over), 0.5 px of pixel noise, encoder noise and the
    gyro's drift in the odometry, V1 may rise from frame to frame by the noise's ripple
    (measured with the balanced law: each rise at most 4.9e-6 V1(0), in all 1.3e-3 V1(0); with
    the paper's law 2.3e-6 and 3.0e-4); without latency and with exact sensing it rises only
    at the sampled loop's floor (the next test). V1 ends below 1e-6 V1(0) (measured 1.4e-7)."""
    log, summary = runs["experiment4"]
    _assert_sound(log)
    assert _max_final_error(log) < 0.5
    storage = log["storage"]
    steps, _, bump, v1_start = _storage_steps(log)
    assert v1_start > 0
    assert np.max(steps[~bump]) <= 1e-5 * v1_start, "V1 increased away from the stop"
    increase = np.sum(np.maximum(steps, 0.0))
    assert increase <= 5e-3 * v1_start
    assert summary["storage_increase_after_transient"] == pytest.approx(increase, abs=1e-15)
    assert storage[-1] < 1e-6 * v1_start


def test_experiment4_storage_does_not_increase_without_latency():
    """The paper's claim: with frames delivered at once and the robot's state read exactly
    (perfect knowledge), V1 does not rise away from the stop. With the balanced law it rises
    only at the sampled loop's floor, below 1e-8 V1(0) (an error 1e-4 of the first frame's;
    measured: rises from at most 1.1e-9 V1(0), by at most 1.0e-9 V1(0)); the paper's law
    never rises there (its error is still far above that floor)."""
    exact = {"camera.latency": 0.0, "sensing.exact": True}
    for feedback in ("balanced", "transpose"):
        scenario = load_scenario("experiment4").with_values(
            **exact, **{"controller.feedback": feedback}
        )
        steps, before, bump, v1_start = _storage_steps(simulate(scenario))
        rises = (steps > 0) & ~bump
        assert v1_start > 0
        assert np.all(before[rises] <= 1e-8 * v1_start), f"{feedback}: V1 rose above its floor"
        assert np.all(steps[rises] <= 1e-8 * v1_start), feedback


# ---------------------------------------------------------------- the report
def test_report_states_each_claim_and_measured_figures(runs):
    reference = [runs[name][1] for name in PAPER_CLAIMS]
    others = [dict(s, robot="pioneer_ur5") for s in reference[:1]]
    classic = [dict(s, law="ibvs") for s in reference]
    report = _report(reference, others, classic, reference)
    for summary in reference:
        name = summary["scenario"]
        claim_rows = [line for line in report.splitlines() if line.startswith(f"| {name} | ")]
        assert PAPER_CLAIMS[name].replace("|", "&#124;") in claim_rows[0]
        assert "target never lost" in claim_rows[0]
        rows = [r for r in report.splitlines() if r.startswith(f"| pioneer_cyton | {name} |")]
        assert rows, name
        assert f"{summary['max_abs_error_final_window_px']:.2f}" in rows[0]
        assert f"{summary['max_abs_error_after_transient_px']:.1f}" in rows[0]
        assert f"{summary['posture_error_final_window_rad']:.3f}" in rows[0]
        assert f"{summary['v_ref_at_limit_fraction']:.3f}" in rows[0]
        clearance = summary["min_clearance_m"]
        if clearance is not None:
            assert f"{clearance:.3f}" in rows[0]
    assert "## Other robots" in report and "| pioneer_ur5 | experiment1 |" in report
    assert "## Classic IBVS baseline" in report
    assert report.count("| ibvs |") == len(PAPER_CLAIMS)
    assert "## Dynamic compensation" in report
    assert "## Other robots" not in _report(reference, [], [])


def test_report_row_does_not_hide_a_lost_target(runs):
    """A run that loses the target is flagged in its row and cannot meet its claim."""
    log, summary = runs["experiment1"]
    assert claim_met(summary) is True
    lost = RunLog(dict(log.channels), dict(log.meta))
    flags = np.zeros_like(log["target_lost"], dtype=bool)
    flags[800:1100] = True
    lost.channels["target_lost"] = flags
    lost_summary = summarize(lost)
    row = run_row(lost_summary)
    first = log["t"][800]
    assert f"lost 300 from {first:.2f} s" in row
    assert "NOT met" in row and claim_met(lost_summary) is False


def test_rows_flag_collisions_joint_limits_and_v_ref_at_its_limit(runs):
    log, _ = runs["experiment2"]
    bad = RunLog(dict(log.channels), dict(log.meta))
    clearance = log["clearance"].copy()
    clearance[500] = -0.02
    arm = log["arm"].copy()
    upper = log.meta["arm_position_limits"][1][1]
    arm[600, 1] = upper + 0.3
    v_ref = log["v_ref"].copy()
    limits = np.asarray(log.meta["velocity_limits"])
    v_ref[:100, 0] = -limits[0]
    bad.channels.update(clearance=clearance, arm=arm, v_ref=v_ref)
    summary = summarize(bad)
    row = run_row(summary)
    assert "collision -0.020 m" in row and "joints +0.3" in row
    at_limit = np.mean(np.any(np.abs(v_ref) >= limits * (1 - 1e-6), axis=1))
    assert at_limit >= 100 / len(v_ref)
    assert summary["v_ref_at_limit_fraction"] == pytest.approx(at_limit)
    assert claim_met(summary) is False


def test_oscillation_measures_the_part_above_half_a_hertz():
    t = np.arange(0.0, 30.0, 0.02)
    slow = np.column_stack([20 * np.exp(-t / 5), 0.2 * t, np.zeros_like(t)])
    assert oscillation_rms(t, slow)[0] < 0.05
    fast = slow.copy()
    fast[(t >= 10) & (t < 20), 2] += 4.0 * np.sin(2 * np.pi * 3.0 * t[(t >= 10) & (t < 20)])
    rms, start = oscillation_rms(t, fast)
    assert rms == pytest.approx(4.0 / np.sqrt(2), rel=0.05)
    assert 9.5 <= start <= 15.5


def test_readme_results_match_fresh_runs(runs):
    """The README's results table is the one generated from these fresh runs' summaries."""
    from conftest import REPO_ROOT

    reference = [runs[name][1] for name in PAPER_CLAIMS]
    readme = readme_block((REPO_ROOT / "README.md").read_text())
    assert readme == readme_results(reference), (
        "README results differ from fresh runs: regenerate with pbvs-pin reproduce --out "
        "results && python -m pbvs_pin.study.report README.md docs/gallery.md results"
    )
    report = _report(reference, [], [])
    numbers = [cell for line in readme.splitlines()[3:-1] for cell in line.split(" | ")[3:7]]
    for number in numbers:
        assert number.strip() in report, number


def test_the_servos_leave_no_oscillation(runs):
    """docs: the default runs of Experiments 2 and 3 (this module's) do not oscillate."""
    second, third = (runs[name][1]["oscillation_rms_px"] for name in EXPERIMENTS[1:3])
    stated(f"now {second:.2f} and {third:.2f} px RMS")
    assert max(second, third) < OSCILLATION_FLAG_PX


def test_compensating_the_arm_too(runs):
    """docs: compensating every dof against the default (``platform``, this module's run)."""
    platform = runs["experiment4"][1]
    arm_too = [run(name, **{"compensation.mode": "all"})[0] for name in EXPERIMENTS]
    stated(
        f"the arm's |v - u| RMS rose from {platform['velocity_tracking_rms_arm']:.4f} "
        f"(`platform`) to {arm_too[3]['velocity_tracking_rms_arm']:.4f} and the error over the "
        f"last 5 s from {platform['max_abs_error_final_window_px']:.2f} to "
        f"{arm_too[3]['max_abs_error_final_window_px']:.2f} px",
        "limitations",
    )
    assert arm_too[3]["velocity_tracking_rms_arm"] > platform["velocity_tracking_rms_arm"]
    error = "max_abs_error_final_window_px"
    assert arm_too[3][error] > platform[error]  # "rose": compensating the arm does worse
    oscillation = [summary["oscillation_rms_px"] for summary in arm_too]
    assert 0.0 < min(oscillation)
    over = [i + 1 for i, rms in enumerate(oscillation) if rms >= OSCILLATION_FLAG_PX]
    stated(
        f"oscillate by {min(oscillation):.1f}-{max(oscillation):.1f} px RMS above 0.5 Hz "
        f"(Experiments {' and '.join(map(str, over)) or 'none'} at or above the rules' "
        f"{OSCILLATION_FLAG_PX:.0f} px)",
        "limitations",
    )
