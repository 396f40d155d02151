"""A new user's first hour with ``pbvs-pin`` (issue 11): version, list, help, progress, and
nothing lost or corrupt when a run is stopped, the disk is full or the viewer cannot start."""

from __future__ import annotations

import argparse
import errno
import os
import re
import signal
import subprocess
import sys
import time
from importlib.metadata import version
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO_ROOT

import pbvs_pin
from pbvs_pin.bringup.catalogue import OTHER_ROBOTS
from pbvs_pin.cli import build_parser, main
from pbvs_pin.exceptions import OutputError
from pbvs_pin.sim.log import RunLog
from pbvs_pin.sim.scenario import scenario_dir
from pbvs_pin.study.report import ENGINE_ROBOTS


def _scenario_file(tmp_path: Path, duration: float, name: str = "short") -> Path:
    """experiment1 with another duration, as a TOML file of its own."""
    text = (scenario_dir() / "experiment1.toml").read_text()
    text, count = re.subn(r"(?m)^duration = .*$", f"duration = {duration}", text)
    assert count == 1
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def _cli(*args: str, env: dict | None = None, cwd: Path | None = None, **kwargs):
    return subprocess.Popen(
        [sys.executable, "-m", "pbvs_pin.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(REPO_ROOT), **(env or {})},
        cwd=cwd,
        **kwargs,
    )


# ---------------------------------------------------------------- version, list, help
def test_version_is_the_package_metadata(capsys):
    assert pbvs_pin.__version__ == version("pbvs_pin")
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"pbvs-pin {version('pbvs_pin')}"


def test_list_names_robots_arms_scenarios_and_sweeps(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    shipped, arms = out.split("example-robot-data arms")[:2]
    for robot in ("pioneer_cyton", "pioneer_ur5", "tiago"):
        assert f"  {robot}\n" in shipped
    for arm in ("ur5", "panda", "z1"):
        assert f"  {arm}\n" in arms
    for legged in ("anymal", "solo12", "talos"):  # free-flyer roots: not arms
        assert f"  {legged}\n" not in out
    for scenario in ("experiment1", "experiment2", "experiment3", "experiment4"):
        assert f"  {scenario}\n" in out
    assert "sweeps" in out and "  target_speed\n" in out


def _parsers(parser, path=()):
    """Every (sub)command's parser, with its words."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, (*path, name))


def test_no_option_states_its_default_twice():
    """The formatter adds "(default: X)"; a help text that says it too read "(default mujoco)
    (default: mujoco)" (ros sim's --engine, --rate-factor, --command-timeout)."""
    parsers = list(_parsers(build_parser()))
    assert len(parsers) > 12  # run, reproduce, ..., ros control/sim/replay-bag
    for path, parser in parsers:
        formatter = parser._get_formatter()
        for action in parser._actions:
            if action.help and action.help is not argparse.SUPPRESS:
                text = formatter._expand_help(action)
                assert text.count("(default") <= 1, (" ".join(path), action.dest, text)
                assert ",," not in text and ", ," not in text, (" ".join(path), text)


@pytest.mark.parametrize(
    ("command", "fragments"),
    [
        ("run", ("(default: results/run)", "(default 1, real time)", "shipped scenario name")),
        (
            "reproduce",
            (
                "(default: results)",
                f"(default: {' '.join(OTHER_ROBOTS)})",
                "--no-replay",
                "--robots",
                f"(default: {' '.join(ENGINE_ROBOTS)})",
            ),
        ),
        ("analyze", ("(default: 0.5)",)),
    ],
)
def test_help_shows_defaults(capsys, command, fragments):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    out = " ".join(capsys.readouterr().out.split())  # undo the wrapping
    for fragment in fragments:
        assert fragment in out
    assert "(default: None)" not in out and "(default: False)" not in out


@pytest.mark.parametrize("command", ["info", "list", "run", "compile", "reproduce", "view",
                                     "analyze", "sweep", "zoo"])  # fmt: skip
def test_help_has_no_stray_comma_empty_or_doubled_default(capsys, command):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert ",," not in out and "(default: )" not in out
    options = re.split(r" (?=--[a-z])", out.split("options:")[1])
    for option in options:  # each option's text shows its default at most once
        assert option.count("(default") <= 1, option


def test_set_is_explained_and_its_keys_listed(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "a dotted key (TABLE.KEY, or KEY at the top) and a TOML value" in out
    assert "`pbvs-pin list --keys` lists every key" in out
    assert main(["list", "--keys"]) == 0
    keys = capsys.readouterr().out.splitlines()
    assert any(k.startswith("  camera.rate = ") and "  # " in k for k in keys)
    from pbvs_pin.sim.scenario import SCHEMA

    listed = {k.split(" = ")[0].strip() for k in keys[1:]}
    assert listed == {f"{t}.{k}" if t else k for t, table in SCHEMA.items() for k in table}


def test_reproduce_refuses_an_unknown_robot_before_running(capsys, tmp_path):
    status = main(["reproduce", "--robots", "pioneer_ur5", "iiwa", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert status == 2
    assert err.count("\n") == 1 and "'iiwa'" in err and "pioneer_cyton" in err


# ---------------------------------------------------------------- compile notice, progress
def test_progress_is_labelled_with_scenario_robot_and_law(tmp_path):
    scenario = _scenario_file(tmp_path, 1.0)
    text = scenario.read_text().replace('name = "pioneer_cyton"', 'name = "pioneer_ur5"')
    scenario.write_text(text)
    process = _cli("run", str(scenario), "--out", str(tmp_path / "out"))
    _, err = process.communicate(timeout=600)
    assert process.returncode == 0, err
    assert "pioneer_ur5 passivity" in err
    assert "experiment1:" not in err


# ---------------------------------------------------------------- nothing lost, nothing corrupt
@pytest.mark.parametrize("option", ["--out", "--html"])
def test_unwritable_output_is_refused_before_the_run(tmp_path, capsys, monkeypatch, option):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    simulated = []
    monkeypatch.setattr("pbvs_pin.study.experiments.simulate", lambda *a, **k: simulated.append(1))
    target = str(blocker / "sub" / ("replay.html" if option == "--html" else "run"))
    args = ["run", "experiment1", "--out", str(tmp_path / "ok"), option, target]
    status = main(args)
    err = capsys.readouterr().err
    assert status == 2
    assert simulated == []
    assert err.count("\n") == 1 and "Traceback" not in err
    assert str(blocker) in err and "nothing was run" in err


def test_html_that_is_a_folder_is_refused(tmp_path, capsys):
    status = main(["run", "experiment1", "--out", str(tmp_path), "--html", str(tmp_path)])
    assert status == 2
    assert "is a folder" in capsys.readouterr().err


def test_log_is_written_atomically(tmp_path, monkeypatch):
    log = RunLog({"t": np.arange(3.0)}, {"scenario": "x"})
    log.save(tmp_path)

    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(np, "savez_compressed", full_disk)
    with pytest.raises(OutputError, match=r"No space left on device\); nothing was written"):
        RunLog({"t": np.arange(5.0)}, {"scenario": "y"}).save(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.npz"]  # no temporary left
    assert RunLog.load(tmp_path).meta["scenario"] == "x"  # the old log is untouched


def test_full_disk_is_one_line_and_leaves_no_log(tmp_path, capsys, monkeypatch):
    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(np, "savez_compressed", full_disk)
    status = main(["run", str(_scenario_file(tmp_path, 0.2)), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert status == 2
    assert err.splitlines()[-1].startswith("pbvs-pin: error: ")
    assert "No space left on device" in err and "Traceback" not in err
    assert list((tmp_path / "out").iterdir()) == []  # nothing analyze or a resume would trust


def test_full_tmpfs_leaves_no_log(tmp_path, capsys):
    """A real full disk: a 64 kB tmpfs (needs root; skipped where mounting is refused)."""
    full = tmp_path / "full"
    full.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(full)], capture_output=True
    )
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    try:
        status = main(["run", str(_scenario_file(tmp_path, 20.0)), "--out", str(full)])
        err = capsys.readouterr().err.strip()
        assert status == 2
        assert "No space left on device" in err.splitlines()[-1]
        assert "Traceback" not in err
        assert not (full / "log.npz").exists()
        assert [p for p in full.iterdir() if p.name.startswith(".")] == []
    finally:
        subprocess.run(["umount", str(full)], check=True)


def test_ctrl_c_saves_the_run_so_far(tmp_path):
    """SIGINT once the progress bar has counted some steps (a 600 s run lasts > 20 s)."""
    out = tmp_path / "out"
    process = _cli("run", str(_scenario_file(tmp_path, 600.0)), "--out", str(out))
    seen = ""
    deadline = time.monotonic() + 600
    while not re.search(r"\| *[1-9]\d*/\d+ \[", seen) and time.monotonic() < deadline:
        seen += process.stderr.read(1)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    lines = (seen + err).replace("\r", "\n").strip().splitlines()
    assert process.returncode == 130, seen + err
    assert lines[-1].startswith("pbvs-pin: interrupted at t = ")
    assert "Traceback" not in err
    assert [line for line in lines if line.startswith("pbvs-pin")] == [lines[-1]]
    log = RunLog.load(out)
    assert log.interrupted and log.meta["interrupted"] is True
    t = log["t"]
    assert 0.0 < t[-1] < 600.0
    assert all(len(channel) == len(t) for channel in log.channels.values())
    assert f"t = {t[-1]:.2f} s of 600 s" in lines[-1] and str(out / "log.npz") in lines[-1]
    assert not (out / "summary.json").exists()


def test_run_goes_on_without_a_live_view(tmp_path, capsys, monkeypatch):
    import meshcat.visualizer

    def server_dies(*args, **kwargs):
        raise RuntimeError("the meshcat server process exited prematurely with exit code 1")

    monkeypatch.setattr(meshcat.visualizer, "start_zmq_server_as_subprocess", server_dies)
    out = tmp_path / "out"
    status = main(["run", str(_scenario_file(tmp_path, 0.3)), "--out", str(out), "--meshcat"])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    hint = [line for line in captured.err.splitlines() if line.startswith("pbvs-pin:")]
    assert len(hint) == 1
    assert "no live view" in hint[0] and "--html FILE" in hint[0]
    assert RunLog.load(out)["t"][-1] > 0.2


def test_compile_command_announces_the_compile_and_its_time(capsys):
    """`pbvs-pin compile` says what it does, then how long it took (warm here: a check)."""
    assert main(["compile"]) in (0, None)
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(("compiling the control kernels", "control kernels already"))
    assert re.fullmatch(r"done in \d+\.\d s; runs start at once from now on", out[-1])
