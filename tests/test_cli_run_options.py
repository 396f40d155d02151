"""The command line's run options, contradictions, verdict, arm list and Ctrl-C (issue 23).

``run --robot/--set/--engine/--duration`` change the scenario before the run (checked with the
run itself replaced by a trap, so no simulation is needed); contradictory options are refused
in one line; ``list`` offers only arms; Ctrl-C sent at many instants of a real run, inside
compiled kernels too, always ends with status 130 or a finished run, never a traceback, and a
saved run so far is whole.
"""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest
from conftest import URDF_DIR

from pbvs_pin.bringup.catalogue import chain_joints
from pbvs_pin.cli import main
from pbvs_pin.interrupts import (
    held_interrupts,
    interrupt_point,
    interrupted_in_compiled_code,
    simulating,
)
from pbvs_pin.sim.log import RunLog
from pbvs_pin.study.claims import verdict_lines


@pytest.fixture
def scenario_of_run(monkeypatch):
    """The scenario ``run`` would simulate, caught before the simulation."""
    caught = []

    def trap(scenario, out, html=None, observer=None, eye_view=None, bag=None):
        caught.append(scenario)
        raise SystemExit(0)

    monkeypatch.setattr("pbvs_pin.study.experiments.run_scenario", trap)
    return caught


def _run(tmp_path, *options: str) -> int:
    try:
        return main(["run", "experiment1", "--out", str(tmp_path / "out"), *options])
    except SystemExit as stop:  # the trap
        return int(stop.code)


def test_set_duration_engine_and_robot_change_the_scenario(tmp_path, scenario_of_run):
    status = _run(tmp_path, "--set", "camera.rate=60", "--set", "target.xi_d=[0, 50, -50]",
                  "--set", "controller.law=ibvs", "--duration", "2.5", "--engine", "mujoco",
                  "--robot", "pioneer_ur5")  # fmt: skip
    assert status == 0
    (scenario,) = scenario_of_run
    assert scenario.camera.rate == 60.0
    assert scenario.target.xi_d == (0.0, 50.0, -50.0)
    assert scenario.controller.law == "ibvs"
    assert scenario.duration == 2.5
    assert scenario.plant.engine == "mujoco"
    assert scenario.robot.name == "pioneer_ur5"


def test_robot_as_a_urdf_or_a_robot_file(tmp_path, scenario_of_run):
    urdf = URDF_DIR / "pioneer_cyton.urdf"
    assert _run(tmp_path, "--robot", str(urdf)) == 0
    robot_file = tmp_path / "my_robot.toml"
    robot_file.write_text(f'[robot]\nurdf = "{urdf}"\ncamera_frame = "camera_optical_frame"\n')
    assert _run(tmp_path, "--robot", str(robot_file)) == 0
    assert [s.robot.urdf for s in scenario_of_run] == [str(urdf.resolve()), str(urdf)]


@pytest.mark.parametrize(
    ("options", "named"),
    [
        (["--speed", "2"], "--speed: only applies to the live view"),
        (["--set", "camera.rate"], "--set: expected key=value"),
        (["--set", "camera.speed=3"], "camera.speed"),
        (["--set", "camera.rate=-3"], "camera.rate"),
        (["--robot", "no_such_robot"], "no_such_robot"),
    ],
)
def test_contradictory_or_bad_options_are_one_line(tmp_path, capsys, scenario_of_run, options,
                                                   named):  # fmt: skip
    assert _run(tmp_path, *options) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and named in err, err
    assert scenario_of_run == []


def test_robot_file_without_a_robot_table_is_refused(tmp_path, capsys, scenario_of_run):
    robot_file = tmp_path / "camera_only.toml"
    robot_file.write_text("[camera]\nrate = 30.0\n")
    assert _run(tmp_path, "--robot", str(robot_file)) == 2
    assert "no [robot] table" in capsys.readouterr().err


def test_reproduce_takes_a_robot_file(tmp_path, monkeypatch):
    robot_file = tmp_path / "my_robot.toml"
    robot_file.write_text('[robot]\nname = "pioneer_z1"\n')
    asked = []
    monkeypatch.setattr("pbvs_pin.study.reproduction.reproduce", lambda out, **kw: asked.append(kw))
    status = main(["reproduce", "--robots", str(robot_file), "pioneer_ur5", "--engines",
                   "--out", str(tmp_path / "results")])  # fmt: skip
    assert status == 0
    assert asked[0]["robots"] == (str(robot_file), "pioneer_ur5")


def test_the_verdict_names_the_claim_the_failed_clauses_and_the_rule():
    summary = {"scenario": "experiment4", "max_abs_error_final_window_px": 0.2,
               "target_lost_samples": 0, "joint_limit_violation": 0.0,
               "oscillation_rms_px": 0.0, "duration_s": 99.98}  # fmt: skip
    verdict, rule = verdict_lines(summary).split("\n")
    assert verdict == (
        "verdict: experiment4 meets the paper's claim (errors converge to zero (perfect "
        "knowledge)): last 5 s: 0.2 px < 0.5 px; target lost: 0 samples <= 0 samples; "
        "past joint limits: 0 rad or m <= 0.01 rad or m; oscillation: 0 px < 3 px"
    )
    assert rule.startswith("rule: max abs(e) over the last 5 s < 0.5 px; target never lost")
    summary |= {"max_abs_error_final_window_px": 0.7, "oscillation_rms_px": 3.25}
    verdict = verdict_lines(summary).split("\n")[0]
    assert verdict.endswith(
        "does NOT meet the paper's claim (errors converge to zero (perfect knowledge)): "
        "last 5 s: 0.7 px >= 0.5 px; oscillation: 3.25 px >= 3 px"
    )
    summary["duration_s"] = 2.98
    assert verdict_lines(summary).split("\n")[0].endswith(
        "is not judged against the paper's claim (errors converge to zero (perfect "
        "knowledge)): run logged to 2.98 s, shorter than the rule's 5 s window"
    )
    assert verdict_lines({**summary, "scenario": "my_own"}) is None


@pytest.mark.parametrize("options", [[], ["--json"], ["--eye-view", "strip", "--json"]])
def test_run_prints_its_verdict_first_and_json_only_when_asked(tmp_path, capsys, monkeypatch,
                                                                options):  # fmt: skip
    """The printout of a finished run (the run itself replaced by a hand-built summary)."""
    import json

    summary = {"scenario": "experiment4", "max_abs_error_final_window_px": 0.2,
               "target_lost_samples": 0, "joint_limit_violation": 0.0,
               "oscillation_rms_px": 0.0, "duration_s": 60.0}  # fmt: skip
    asked = []

    def finished(scenario, out, html=None, observer=None, eye_view=None, bag=None):
        asked.append(eye_view)
        return None, summary

    monkeypatch.setattr("pbvs_pin.study.experiments.run_scenario", finished)
    out = tmp_path / "out"
    assert main(["run", "experiment4", "--out", str(out), *options]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("verdict: experiment4 meets the paper's claim")
    assert lines[-1].startswith("log, summary (summary.json") and str(out) in lines[-1]
    assert lines[1].startswith("rule: ")
    if "--json" in options:
        assert json.loads("\n".join(lines[2:-1])) == summary
    else:
        assert len(lines) == 3 and "--json prints it" in lines[-1]
    assert asked == [options[1] if "--eye-view" in options else None]
    if "--eye-view" in options:
        assert lines[-1].endswith(f"robot's-eye view: {out / 'eye_view.png'}")


# ---------------------------------------------------------------- list: arms only
def _urdf(tmp_path, joints: list[tuple[str, str, str]]) -> str:
    links = sorted({name for joint in joints for name in joint[1:]})
    text = "<robot name='r'>" + "".join(f"<link name='{n}'/>" for n in links)
    text += "".join(f"<joint name='j{i}' type='{kind}'><parent link='{p}'/><child link='{c}'/>"
                    "</joint>" for i, (kind, p, c) in enumerate(joints))  # fmt: skip
    path = tmp_path / "r.urdf"
    path.write_text(text + "</robot>")
    return path


@pytest.mark.parametrize(
    ("joints", "expected"),
    [
        ([("revolute", "a", "b"), ("fixed", "b", "c"), ("revolute", "c", "d"),
          ("prismatic", "d", "e")], (3, 3)),  # a chain through a fixed joint
        ([("revolute", "palm", "f1"), ("revolute", "f1", "f1b"), ("revolute", "palm", "f2"),
          ("revolute", "f2", "f2b")], (0, 4)),  # a hand: fingers branch at the palm
        ([("revolute", "a", "b"), ("revolute", "b", "c"), ("revolute", "c", "d"),
          ("revolute", "d", "l"), ("revolute", "d", "r")], (3, 5)),  # an arm with a gripper
        ([("revolute", "a", "b"), ("continuous", "b", "c")], (2, 2)),  # a double pendulum
    ],
)  # fmt: skip
def test_chain_joints_counts_the_unbranched_chain(tmp_path, joints, expected):
    assert chain_joints(_urdf(tmp_path, joints)) == expected


def test_list_offers_no_hand_and_no_pendulum(capsys):
    assert main(["list"]) == 0
    arms = capsys.readouterr().out.split("example-robot-data arms")[1].split("scenarios")[0]
    for arm in ("ur5", "panda", "z1", "kinova", "xarm7"):
        assert f"  {arm}\n" in arms
    for other in ("allegro_left_hand", "double_pendulum", "asr_twodof", "alex_nub_hands",
                  "baxter", "tiago"):  # fmt: skip
        assert f"  {other}\n" not in arms
    # example-robot-data's "ur3" loads the UR5 (its UR5Loader); the UR3's own names stay
    assert "  ur3\n" not in arms and "  ur3_limited\n" in arms


# ---------------------------------------------------------------- Ctrl-C
def test_a_held_ctrl_c_is_raised_at_the_next_interrupt_point():
    with held_interrupts(), simulating():
        signal.raise_signal(signal.SIGINT)  # held: no KeyboardInterrupt here
        with pytest.raises(KeyboardInterrupt):
            interrupt_point()
        interrupt_point()  # raised once only
        signal.raise_signal(signal.SIGINT)
        with pytest.raises(KeyboardInterrupt):
            signal.raise_signal(signal.SIGINT)  # a second Ctrl-C stops at once


def test_outside_a_simulation_ctrl_c_is_not_held():
    with held_interrupts(), pytest.raises(KeyboardInterrupt):
        signal.raise_signal(signal.SIGINT)


def test_a_ctrl_c_inside_a_kernel_is_recognised():
    error = SystemError("CPUDispatcher(<function f>) returned a result with an exception set")
    error.__context__ = KeyboardInterrupt()
    assert interrupted_in_compiled_code(error)
    assert not interrupted_in_compiled_code(SystemError("something else"))


DURATION_S = 12.0
"""Simulated time of the interrupted runs: about a second of simulation on a quiet 2-core
machine, so that the five instants during it stay apart by more than the timer's and the
machine's jitter (with 3 s, 0.25 s of simulation, one instant in six landed after the end)."""


def _run_with_ctrl_c(tmp_path, capsys, delay: float | None) -> str:
    """Run a short scenario, Ctrl-C after ``delay`` [s]; check nothing is lost; say what
    happened."""
    scenario = tmp_path / "short.toml"
    scenario.write_text(f'name = "short"\nduration = {DURATION_S}\n[robot]\nname = "pioneer_cyton"\n')
    out = tmp_path / f"out{delay}"
    previous = signal.signal(signal.SIGINT, lambda *args: None)  # a late Ctrl-C: ignored
    timer = threading.Timer(delay or 0.0, os.kill, (os.getpid(), signal.SIGINT))  # a user's
    try:
        if delay is not None:
            timer.start()
        status = main(["run", str(scenario), "--out", str(out)])
    finally:
        timer.cancel()
        if delay is not None:
            timer.join()
        signal.signal(signal.SIGINT, previous)
    err = capsys.readouterr().err
    assert "Traceback" not in err and "SystemError" not in err
    assert status in (0, 130), err
    if status == 0:
        assert (out / "summary.json").is_file()
        return "finished"
    line = [x for x in err.splitlines() if x.startswith("pbvs-pin:")][-1]
    if not (out / "log.npz").exists():
        assert line.endswith(("nothing was written", "nothing was saved")), line
        return "stopped before the simulation"
    log = RunLog.load(out)
    assert all(len(channel) == len(log["t"]) for channel in log.channels.values())
    assert np.isfinite(log["q"]).all()
    if not log.interrupted:
        assert (out / "summary.json").is_file()
        assert line.startswith("pbvs-pin: interrupted ") and (
            f"kept: the log {out / 'log.npz'}, the summary {out / 'summary.json'}" in line
            or line.endswith("after the outputs were written; nothing was lost")
        ), line
        return "stopped after the run was saved"
    assert f"t = {log['t'][-1]:.2f} s of {DURATION_S:g} s" in line
    assert not (out / "summary.json").exists()
    return "partial run saved"


def test_ctrl_c_at_any_instant_loses_nothing(tmp_path, capsys, monkeypatch):
    """Ctrl-C before, at five instants during and twice after the simulation of a real run.

    The instants come from an uninterrupted run (after a warm-up run loads the kernels).
    """
    import pbvs_pin.study.experiments as experiments

    window: dict[str, float] = {}
    simulate = experiments.simulate

    def timed(*args, **kwargs):
        window["start"] = time.monotonic()
        try:
            return simulate(*args, **kwargs)
        finally:
            window["end"] = time.monotonic()

    monkeypatch.setattr(experiments, "simulate", timed)
    (tmp_path / "warm").mkdir()
    assert _run_with_ctrl_c(tmp_path / "warm", capsys, None) == "finished"  # loads the kernels
    started = time.monotonic()
    assert _run_with_ctrl_c(tmp_path, capsys, None) == "finished"
    total = time.monotonic() - started
    begin, end = window["start"] - started, window["end"] - started
    during = [begin + f * (end - begin) for f in (0.1, 0.3, 0.5, 0.7, 0.9)]
    delays = [0.5 * begin, *during, end + 0.3 * (total - end), end + 0.8 * (total - end)]
    outcomes = {round(d, 2): _run_with_ctrl_c(tmp_path, capsys, d) for d in delays}
    assert list(outcomes.values()).count("partial run saved") >= 3, outcomes
