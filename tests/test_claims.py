"""A run's verdict clause by clause (issue 32, item 5).

The summaries are written by hand, so every clause's value, threshold and outcome is known
without running anything: a met run lists each clause holding, a failed one names the
clauses that fail with their figures, and a run shorter than the rule's window (or whose
window would hold the start-up transient) is not judged. One short real run checks the
fields of ``summary.json`` and the verdict ``pbvs-pin run`` prints.
"""

from __future__ import annotations

import json
import math

import pytest

from pbvs_pin.cli import main
from pbvs_pin.exceptions import PbvsError
from pbvs_pin.study.claims import (
    CLAIMS,
    Clause,
    clause_text,
    failed,
    judge,
    too_short,
    verdict_text,
)
from pbvs_pin.study.report import readme_results
from pbvs_pin.study.zoo import progress_line, zoo_table


def summary(name: str = "experiment2", **changes) -> dict:
    """A run's figures that meet every rule unless changed."""
    s = {
        "scenario": name, "robot": "pioneer_cyton", "duration_s": 59.98, "image_height_px": 582,
        "max_abs_error_final_window_px": 1.45, "max_abs_error_after_transient_px": 3.5,
        "min_clearance_m": 0.062, "posture_error_final_window_rad": 0.037,
        "target_lost_samples": 0, "target_lost_first_s": None, "joint_limit_violation": 0.0,
        "oscillation_rms_px": 0.4, "oscillation_window_start_s": 2.0,
        "storage_increase_after_transient": 0.0058,
    }  # fmt: skip
    s.update(changes)
    return s


def test_a_met_run_lists_every_clause_of_its_rule_holding():
    verdict = judge(summary())
    assert verdict["met"] is True and verdict["not_judged"] is None
    assert verdict["rule"] == CLAIMS["experiment2"].rule
    expected = [  # name, figure, value, relation, threshold, unit
        ("after 2 s", "max_abs_error_after_transient_px", 3.5, "<", 291.0, "px"),
        ("clearance", "min_clearance_m", 0.062, ">", 0.0, "m"),
        ("arm to theta_d", "posture_error_final_window_rad", 0.037, "<", 0.1, "rad"),
        ("last 5 s", "max_abs_error_final_window_px", 1.45, "<", 8.0, "px"),
        ("target lost", "target_lost_samples", 0, "<=", 0.0, "samples"),
        ("past joint limits", "joint_limit_violation", 0.0, "<=", 0.01, "rad or m"),
        ("oscillation", "oscillation_rms_px", 0.4, "<", 3.0, "px"),
    ]
    keys = ("name", "figure", "value", "relation", "threshold", "unit")
    assert [tuple(c[k] for k in keys) for c in verdict["clauses"]] == expected
    assert all(c["holds"] for c in verdict["clauses"]) and failed(verdict) == []
    assert verdict_text(verdict) == "met"
    assert clause_text(verdict["clauses"][2]) == "arm to theta_d: 0.037 rad < 0.1 rad"


def test_a_failed_run_names_each_failed_clause_with_its_figures():
    verdict = judge(summary(max_abs_error_final_window_px=47.6123,
                            posture_error_final_window_rad=0.66))  # fmt: skip
    assert verdict["met"] is False
    assert [c["name"] for c in failed(verdict)] == ["arm to theta_d", "last 5 s"]
    assert verdict_text(verdict) == (
        "NOT met: arm to theta_d: 0.66 rad >= 0.1 rad; last 5 s: 47.6 px >= 8 px"
    )
    lost = judge(summary("experiment1", target_lost_samples=12, joint_limit_violation=0.3,
                         min_clearance_m=-0.02))  # fmt: skip
    assert verdict_text(lost) == (
        "NOT met: target lost: 12 samples > 0 samples; "
        "past joint limits: 0.3 rad or m > 0.01 rad or m"
    )  # Experiment 1 has no clearance clause
    crash = judge(summary("experiment3", min_clearance_m=-0.02))
    assert verdict_text(crash) == "NOT met: clearance: -0.02 m <= 0 m"


def test_the_value_gets_the_digits_that_tell_it_from_the_threshold():
    verdict = judge(summary("experiment4", max_abs_error_final_window_px=0.50004))
    assert verdict_text(verdict) == "NOT met: last 5 s: 0.50004 px >= 0.5 px"


def test_a_missing_figure_fails_unless_the_clause_is_optional():
    no_obstacle = judge(summary("experiment3", min_clearance_m=None, joint_limit_violation=None))
    assert no_obstacle["met"] is True
    assert clause_text(no_obstacle["clauses"][1]) == "clearance: no figure"
    no_error = judge(summary("experiment1", max_abs_error_final_window_px=None))  # all NaN
    assert no_error["met"] is False
    assert verdict_text(no_error) == "NOT met: last 5 s: no figure"
    nan = judge(summary("experiment1", max_abs_error_final_window_px=math.nan))
    assert nan["met"] is False


@pytest.mark.parametrize(
    ("end", "reason"),
    [
        (2.98, "run logged to 2.98 s, shorter than the rule's 5 s window"),
        (
            6.98,
            "run logged to 6.98 s: the rule's last 5 s would start at 1.98 s, inside the 2 s "
            "start-up transient (a run is judged from 7 s logged on: a duration above 7 s)",
        ),
        (7.0, None),
    ],
)
def test_a_run_too_short_for_the_rules_window_is_not_judged(end, reason):
    assert too_short(end) == reason
    verdict = judge(summary(duration_s=end, max_abs_error_final_window_px=40.0))
    if reason is None:
        assert verdict["met"] is False
    else:
        assert verdict["met"] is None and verdict["not_judged"] == reason
        assert verdict_text(verdict) == f"not judged: {reason}"
        assert failed(verdict)[0]["value"] == 40.0  # the figures are still given


def test_a_clause_with_an_unknown_relation_is_refused():
    with pytest.raises(PbvsError, match=r"clause 'last 5 s': relation '=<'; expected one of"):
        Clause("last 5 s", "max abs(e) < 8 px", "max_abs_error_final_window_px", "=<", 8.0, "px")


def test_a_scenario_without_a_claim_is_not_judged():
    verdict = judge(summary("my_scenario"))
    assert verdict == {
        "met": None, "not_judged": "scenario 'my_scenario' is none of the paper's experiments",
        "rule": None, "clauses": [],
    }  # fmt: skip


def test_the_readme_met_column_names_the_failed_clauses():
    block = readme_results([summary(), summary(max_abs_error_final_window_px=9.5)])
    met, failed_row = (line for line in block.splitlines() if line.startswith("| experiment2 "))
    assert "| met | 1.45 |" in met
    assert "| NOT met: last 5 s: 9.5 px >= 8 px | 9.50 |" in failed_row


def test_the_zoo_table_and_progress_name_the_failed_clauses():
    base = {"robot": "stretch_re1", "package": "p", "experiment": "experiment2",
            "engine": "pinocchio", "max_error_last_5s_px": 47.6, "target_lost_samples": 0,
            "joint_limit_violation": 0.0, "oscillation_rms_px": 4.1, "net_share": 0.0}  # fmt: skip
    verdict = judge(summary(max_abs_error_final_window_px=47.6, oscillation_rms_px=4.1))
    row = base | {"claim_met": False, "not_judged": None, "clauses": verdict["clauses"]}
    assert "     - **no** (last 5 s, oscillation)" in zoo_table([row], ("pinocchio",))
    assert progress_line(row) == (
        "stretch_re1 experiment2 pinocchio: NOT met: last 5 s: 47.6 px >= 8 px; "
        "oscillation: 4.1 px >= 3 px"
    )
    older = base | {"claim_met": False}  # a row saved before the clauses were kept
    assert "     - **no**\n" in zoo_table([older], ("pinocchio",))
    short = base | {"claim_met": None, "not_judged": "run logged to 0.98 s, shorter than ..."}
    assert "     - not judged" in zoo_table([short], ("pinocchio",))
    broken = base | {"error": "no camera link"}
    assert progress_line(broken) == "stretch_re1 experiment2 pinocchio: error: no camera link"


def test_summary_json_and_the_terminal_give_the_verdict_of_a_short_run(tmp_path, capsys):
    """A 3 s run of Experiment 1: logged to 2.98 s (50 Hz log), not judged."""
    assert main(["run", "experiment1", "--duration", "3", "--out", str(tmp_path)]) == 0
    saved = json.loads((tmp_path / "summary.json").read_text())
    reason = "run logged to 2.98 s, shorter than the rule's 5 s window"
    assert saved["met"] is None and saved["not_judged"] == reason
    assert saved["rule"] == CLAIMS["experiment1"].rule
    assert [c["name"] for c in saved["clauses"]] == [
        "last 5 s", "target lost", "past joint limits", "oscillation"
    ]  # fmt: skip
    last = saved["clauses"][0]
    assert last["value"] == saved["max_abs_error_final_window_px"]
    assert (last["threshold"], last["relation"], last["unit"]) == (8.0, "<", "px")
    assert last["holds"] is (last["value"] < 8.0)
    out = capsys.readouterr().out.splitlines()
    assert out[-3] == (
        "verdict: experiment1 is not judged against the paper's claim (errors ultimately "
        f"bounded, final max |error| < 8 px): {reason}"
    )
    assert out[-2] == f"rule: {CLAIMS['experiment1'].rule}"
    assert out[-1].startswith("log, summary (summary.json")


def test_the_docs_verdict_is_a_fresh_runs():
    """docs/scenarios.md quotes the verdict and rule of the PR2's Experiment 1 under the paper's
    law (30 s of simulation, about 6 s)."""
    from conftest import REPO_ROOT

    from pbvs_pin.sim.loop import simulate
    from pbvs_pin.sim.metrics import summarize
    from pbvs_pin.sim.scenario import load_scenario
    from pbvs_pin.study.claims import verdict_lines
    from pbvs_pin.study.experiments import with_robot

    robot = str(REPO_ROOT / "robots" / "pr2.toml")
    scenario = with_robot(load_scenario("experiment1"), robot).with_values(
        **{"controller.feedback": "transpose"}
    )
    lines = verdict_lines(summarize(simulate(scenario, progress=False))).split("\n")
    assert lines[0].startswith("verdict: experiment1 does NOT meet")
    page = (REPO_ROOT / "docs" / "scenarios.md").read_text()
    for line in lines[:2]:
        assert f"\n{line}\n" in page, f"docs/scenarios.md no longer quotes {line!r}: measure again"
