"""The report's findings: every sentence follows from the figures it is given.

The summaries and analyses here are written by hand, so each expected sentence is known
without running anything: which experiments meet their rule (and that the verdict names the
rule), which law has the smaller error, what compensation changes and where it makes things
worse, and which idealisation a failing passivity inequality needs.
"""

from __future__ import annotations

import pytest

from pbvs_pin.study.findings import IDEALISATIONS, IDEALISED, findings_section, without
from pbvs_pin.study.report import CLAIMS, engine_row, run_row, verdict

EXPERIMENTS = list(CLAIMS)


def summary(name: str, final: float = 1.0, **changes) -> dict:
    """A run summary that meets every rule unless changed."""
    s = {
        "robot": "pioneer_cyton", "scenario": name, "law": "passivity", "engine": "pinocchio",
        "compensation": "platform", "max_abs_error_final_window_px": final,
        "max_abs_error_after_transient_px": 10.0, "rms_error_after_transient_px": 2.0,
        "image_height_px": 582, "min_clearance_m": 0.1, "posture_error_final_window_rad": 0.05,
        "target_lost_samples": 0, "target_lost_first_s": None, "joint_limit_violation": 0.0,
        "oscillation_rms_px": 0.5, "oscillation_window_start_s": 0.0, "saturated_fraction": 0.0,
        "v_ref_at_limit_fraction": 0.0, "velocity_tracking_rms": 0.05,
        "velocity_tracking_rms_platform": 0.04, "velocity_tracking_rms_arm": 0.01,
        "odometry_drift_m": 0.0, "odometry_drift_rad": 0.0, "lateral_slip_rms_mps": 0.0,
        "yaw_rate_ratio": None, "real_time_factor": 30.0, "duration_s": 30.0,
    }  # fmt: skip
    s.update(changes)
    return s


def analysis(p9: bool = True, p14: bool = True, p27: bool = True) -> dict:
    return {
        "passivity_9": {"holds": p9},
        "passivity_14": {"holds_with_beta_1_zero": p14},
        "passivity_27": {"holds": p27},
    }


def test_the_verdict_names_the_rule_it_was_judged_by_and_the_failed_clauses():
    met, failed = summary("experiment3"), summary("experiment1", final=9.0)
    assert verdict(met) == "met (experiment3's rule)"
    assert verdict(failed) == "NOT met (experiment1's rule: last 5 s: 9 px >= 8 px)"
    assert verdict(summary("my_scenario")) == "-"
    assert "| met (experiment3's rule) |" in run_row(met)
    assert "| NOT met (experiment1's rule: last 5 s: 9 px >= 8 px) |" in engine_row(failed)
    short = summary("experiment1", duration_s=2.98)
    assert verdict(short) == (
        "not judged (experiment1's rule: run logged to 2.98 s, shorter than the rule's 5 s window)"
    )


def test_other_robots_not_met_name_their_failed_clauses():
    others = [
        summary("experiment1", robot="pioneer_ur5"),
        summary("experiment2", robot="stretch_re1", final=47.6, oscillation_rms_px=4.1),
        summary("experiment3", robot="stretch_re1", duration_s=3.0),
    ]
    text = findings_section([], others, [], [], [])
    assert (
        "- **Other robots**: 1 of 3 runs meet their experiment's rule; not met: stretch_re1 "
        "Experiment 2 (last 5 s, oscillation), stretch_re1 Experiment 3 (not judged)."
    ) in text


def test_claims_are_counted_and_each_rule_is_quoted():
    reference = [summary(n, final=0.2) for n in EXPERIMENTS]
    reference[0] = summary("experiment1", final=9.5)
    text = findings_section(reference, [], [], [], [])
    assert "met in 3 of 4 experiments" in text
    assert (
        'Experiment 1: NOT met by the rule "max abs(e) over the last 5 s < 8 px": 9.50 px'
        in text
    )
    assert 'Experiment 4: met by the rule "max abs(e) over the last 5 s < 0.5 px": 0.20 px' in text
    lost = summary("experiment4", final=0.2, target_lost_samples=3, target_lost_first_s=1.0)
    assert "Experiment 4: NOT met" in findings_section([lost], [], [], [], [])
    assert "lost 3 from 1.00 s" in findings_section([lost], [], [], [], [])


def test_the_baseline_comparison_says_which_law_wins_with_its_figures():
    pairs = [
        ("experiment1", {"rms_after_transient_px": 2.0}, {"rms_after_transient_px": 1.5}),
        ("experiment2", {"rms_after_transient_px": 1.0}, {"rms_after_transient_px": 3.0}),
    ]
    text = findings_section([summary("experiment1")], [], pairs, [], [])
    assert "the classic IBVS baseline has the smaller RMS error after 2 s in 1 of 2" in text
    assert "Experiment 1 2.00 against 1.50 px, Experiment 2 1.00 against 3.00 px" in text
    assert "weakest direction here is the depth" in text  # the paper's law's reason


def test_the_baseline_comparison_gives_the_jt_reason_only_for_the_papers_law():
    pairs = [("experiment1", {"rms_after_transient_px": 2.0, "feedback": "balanced"},
              {"rms_after_transient_px": 1.5, "feedback": "balanced"})]  # fmt: skip
    text = findings_section([summary("experiment1")], [], pairs, [], [])
    assert "weakest direction" not in text
    assert "The passivity law ran with the balanced feedback" in text


def test_compensation_says_what_it_changes_and_where_it_is_worse():
    modes = []
    for name, (off, on) in zip(EXPERIMENTS[:2], ((3.0, 2.0), (3.77, 6.14)), strict=True):
        modes.append(summary(name, final=off, compensation="off", velocity_tracking_rms=0.05))
        modes.append(summary(name, final=on, compensation="platform", velocity_tracking_rms=0.049))
    text = findings_section([summary("experiment1")], [], [], modes, [])
    assert "changes the velocity error by at most 2.0 % (it rises in none of the 2 experiments)" in text
    assert "RMS of abs(v - u) 0.0500 -> 0.0490, 0.0500 -> 0.0490" in text
    assert "It makes the error worse in Experiment 2 (6.14 against 3.77 px)." in text
    assert "worse in Experiment 1" not in text


def test_passivity_counts_and_the_idealisation_each_inequality_needs():
    analyses = [analysis(p14=False, p27=False) for _ in EXPERIMENTS]
    idealised = {"all": [analysis() for _ in EXPERIMENTS]}
    # without exact sensing (27) fails again; without the others it still holds
    idealised["exact sensing"] = [analysis(p27=False) for _ in EXPERIMENTS]
    idealised["no latency"] = [analysis() for _ in EXPERIMENTS]
    idealised["a 1 kHz camera without noise"] = [analysis(p14=False) for _ in EXPERIMENTS]
    text = findings_section([summary("experiment1")], [], [], [], analyses, idealised)
    assert "(9) holds in all 4 experiments" in text
    assert "(14) with beta_1 = 0 holds in none of the 4 experiments" in text
    assert "(27) holds in none of the 4 experiments" in text
    lines = {line.split(" with every")[0].strip(" -"): line for line in text.splitlines()
             if "with every idealisation" in line}  # fmt: skip
    assert "It needs a 1 kHz camera without noise (without it: none of the 4)" in lines["(14)"]
    assert "It needs exact sensing (without it: none of the 4)" in lines["(27)"]
    assert "holds in all 4 experiments" in lines["(27)"]


def test_14_failing_where_27_holds_is_put_down_to_the_velocity_error():
    analyses = [analysis(p14=False, p27=False)]
    idealised = {name: [analysis(p14=False)] for name in ("all", *IDEALISATIONS)}
    text = findings_section([summary("experiment1")], [], [], [], analyses, idealised)
    line = next(x for x in text.splitlines() if x.strip().startswith("- (14) with every"))
    assert "What it lacks is the velocity error" in line


def test_compensation_within_ten_percent_is_not_called_worse():
    modes = [
        summary("experiment4", final=0.13, compensation="off"),
        summary("experiment4", final=0.14, compensation="platform"),
    ]
    assert "worse" not in findings_section([summary("experiment4")], [], [], modes, [])


def test_passivity_without_idealised_runs_says_nothing_it_did_not_measure():
    text = findings_section([summary("experiment1")], [], [], [], [analysis(p27=False)])
    assert "(27) holds in none of the 1 experiments" in text
    assert "It needs" not in text and "idealisation" not in text


@pytest.mark.parametrize("name", list(IDEALISATIONS))
def test_each_variant_drops_only_its_own_keys(name):
    values = without(name)
    assert set(values) == set(IDEALISED) - set(IDEALISATIONS[name])
    assert all(values[k] == IDEALISED[k] for k in values)


def test_the_report_tables_the_idealised_runs_behind_the_findings():
    """Every run the findings' idealisation lines count is a row, its inequalities written out."""
    from pbvs_pin.study.reproduction import _idealised_section

    def result(name: str, lhs27: float) -> dict:
        return {
            "scenario": name,
            "passivity_9": {"lhs_integral_nu_input": -0.05, "rhs_minus_V1_0": -0.06,
                            "holds": True},
            "passivity_14": {"lhs_integral_nu_feedback": 0.09, "perfect_tracking_rhs_V1_0": 0.06,
                             "holds_with_beta_1_zero": False},
            "passivity_27": {"lhs_integral_nu_feedback": lhs27, "rhs": 0.1, "holds": lhs27 <= 0.1},
        }  # fmt: skip

    ideal = {"all": [result(n, 0.09) for n in EXPERIMENTS]}
    ideal |= {name: [result(n, 0.2) for n in EXPERIMENTS] for name in IDEALISATIONS}
    text = _idealised_section(ideal)
    rows = [line for line in text.splitlines() if line.startswith("| ") and "experiment" in line]
    assert len(rows) == 1 + 4 * (1 + len(IDEALISATIONS))  # the header, then every run
    assert (
        "| every idealisation | experiment1 | -0.05 >= -0.06: holds | 0.09 <= 0.06: FAILS | "
        "0.09 <= 0.1: holds |" in text
    )
    assert "| all but no latency | experiment4 | " in text and "0.2 <= 0.1: FAILS |" in text
    assert _idealised_section(None) == ""


def test_every_comparison_run_that_fails_its_rule_is_named():
    """Mode `all` failing Experiment 4 (5.68 against 0.5 px) is named; the own mode is not
    repeated (the claims line has it); the IBVS baseline and the MuJoCo plant are named too."""
    reference = [summary(n, final=0.2) for n in EXPERIMENTS]
    modes = [summary(n, final=0.2, compensation=m) for n in EXPERIMENTS
             for m in ("off", "platform", "all")]  # fmt: skip
    modes[-1] = summary("experiment4", final=5.68, compensation="all")
    text = findings_section(reference, [], [], modes, [])
    assert "**Comparison runs that fail their experiment's rule**: 1 of 8" in text
    assert (
        '- compensation mode `all` in Experiment 4: NOT met by the rule "max abs(e) over the '
        'last 5 s < 0.5 px": 5.68 px over the last 5 s' in text
    )
    classic = [summary("experiment2", final=9.0, law="ibvs")]
    plants = [summary("experiment1", engine="mujoco", robot="tiago", target_lost_samples=2,
                      target_lost_first_s=3.0), summary("experiment1", robot="tiago")]  # fmt: skip
    text = findings_section(reference, [], [], modes, [], classic=classic, plants=plants)
    assert "1 of 8" not in text and "3 of 10" in text
    assert "- the classic IBVS baseline in Experiment 2: NOT met by the rule" in text
    assert "- the MuJoCo plant (tiago) in Experiment 1: NOT met" in text
    assert "lost 2 from 3.00 s" in text
    passing = findings_section(reference, [], [], modes[:-1], [])
    assert "**Comparison runs**: all 7 meet their experiment's rule." in passing
    assert "fail their experiment's rule" not in passing
    assert "Comparison runs" not in findings_section(reference, [], [], [], [])


def test_reproduce_progress_rows_name_the_plant_and_the_compensation_mode():
    from pbvs_pin.study.reproduction import progress_row

    s = summary("experiment4", final=5.68, compensation="all", engine="mujoco")
    row = progress_row(7, 60, s)
    assert row.startswith("[7/60] mujoco plant, compensation all: | pioneer_cyton | experiment4 |")
    assert row.endswith(run_row(s))
    assert "| NOT met (experiment4's rule: last 5 s: 5.68 px >= 0.5 px) | 5.68 |" in row
