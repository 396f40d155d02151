"""Damaged or foreign files at every file door (issue 31): one line naming the file, exit 2.

Each file is written in ``tmp_path``: a ``.npy`` array, a truncated ``.npz``, a log whose
meta lacks a fact or holds a NaN, a non-UTF-8 TOML file (scenario, robot file, sweep spec,
also on a sweep's resume), and names of 300 characters. Every command runs in-process
(:func:`pbvs_pin.cli.main`); the expected words are written here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import URDF_DIR
from test_bad_cli import SPEC  # a valid sweep spec

from pbvs_pin.cli import main
from pbvs_pin.exceptions import LogError, ScenarioError, WrongType
from pbvs_pin.sim.log import CHANNELS, RunLog
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.study.analysis import analyze_log
from pbvs_pin.study.sweep.spec import load_sweep
from pbvs_pin.study.zoo import load_zoo

LONG = "x" * 300
"""A file name longer than any file system's limit (255 bytes)."""

NOT_UTF8 = b"duration = 1.0\n# caf\xe9 \xff\xfe\n"
"""TOML text with Latin-1 bytes: not UTF-8."""

META = {"scenario": "experiment1", "robot": "pioneer_cyton", "feature_scale": 150.0,
        "k": [1.0, 1.0, 1.0]}  # fmt: skip
"""The facts of a log's meta that the analysis reads, valid."""


def _log(folder, meta: dict) -> str:
    """A log with every channel ``analyze`` asks for (zeros, 3 samples) and ``meta``."""
    channels = {name: np.zeros(3) for name in CHANNELS}
    channels["t"] = np.array([0.0, 0.1, 0.2])
    folder.mkdir()
    return str(RunLog(channels, meta).save(folder))


def _one_line(capsys, status: int) -> str:
    """The error line of a refused command (exit 2, one line, no traceback)."""
    err = capsys.readouterr().err
    assert status == 2, err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("pbvs-pin: error: ")
    return lines[0]


def test_analyze_of_a_npy_file(tmp_path, capsys):
    path = tmp_path / "log.npy"
    np.save(path, np.zeros(3))
    line = _one_line(capsys, main(["analyze", str(path)]))
    assert f"{path}: one NumPy array (.npy), not a run log" in line


def test_analyze_of_a_truncated_npz(tmp_path, capsys):
    path = _log(tmp_path / "run", META)
    whole = open(path, "rb").read()
    with open(path, "wb") as handle:
        handle.write(whole[: len(whole) // 2])
    line = _one_line(capsys, main(["analyze", path]))
    assert f"{path}: not a readable run log" in line


@pytest.mark.parametrize("key", sorted(META))
def test_analyze_of_a_log_missing_a_meta_key(tmp_path, capsys, key):
    path = _log(tmp_path / "run", {k: v for k, v in META.items() if k != key})
    line = _one_line(capsys, main(["analyze", path, "--out", str(tmp_path / "out")]))
    assert f"{path}: not a whole run log: its meta has no '{key}'" in line
    assert not (tmp_path / "out" / "analysis.json").exists()


@pytest.mark.parametrize(("key", "value", "expected"), [
    ("robot", math.nan, "meta 'robot': expected a robot name (text), got nan"),
    ("scenario", 3, "meta 'scenario': expected a scenario name (text), got 3"),
    ("feature_scale", -1.0, "meta 'feature_scale': expected a positive number [px], got -1.0"),
    ("k", "fast", "meta 'k': expected a list of positive numbers (the gains), got 'fast'"),
])  # fmt: skip
def test_analyze_of_a_log_with_a_wrong_meta_value(tmp_path, capsys, key, value, expected):
    path = _log(tmp_path / "run", {**META, key: value})
    line = _one_line(capsys, main(["analyze", path]))
    assert f"{path}: {expected}" in line


def test_analyze_log_refuses_what_is_not_a_log():
    with pytest.raises(WrongType, match=r"log: expected a RunLog"):
        analyze_log({"t": [0.0, 1.0]})
    log = RunLog({"t": np.zeros(2)}, dict(META))
    with pytest.raises(WrongType, match=r"epsilon: expected numbers, got 'half'"):
        analyze_log(log, epsilon="half")
    with pytest.raises(LogError, match=r"its meta has no 'robot'"):
        analyze_log(RunLog({"t": np.zeros(2)}, {k: v for k, v in META.items() if k != "robot"}))


def test_non_utf8_toml_at_every_toml_door(tmp_path, capsys):
    path = tmp_path / "latin1.toml"
    path.write_bytes(NOT_UTF8)
    for argv in (["run", str(path), "--out", str(tmp_path / "o1")],
                 ["run", "experiment1", "--robot", str(path), "--out", str(tmp_path / "o2")],
                 ["info", str(path)], ["view", str(path)],
                 ["sweep", str(path), "--out", str(tmp_path / "o3")]):  # fmt: skip
        line = _one_line(capsys, main(argv))
        assert f"{path}: not UTF-8 text (expected a" in line, argv
    with pytest.raises(ScenarioError, match=r"not UTF-8 text \(expected a sweep spec"):
        load_sweep(path)


def test_sweep_resume_of_a_spec_turned_non_utf8(tmp_path, capsys, monkeypatch):
    """The spec is refused on resume, before the folder's runs are looked at."""
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    out = tmp_path / "sweep"
    out.mkdir()
    (out / "results.csv").write_text("run,alpha\n")  # a started sweep
    spec.write_bytes(SPEC.encode() + b"# \xff\n")
    line = _one_line(capsys, main(["sweep", str(spec), "--out", str(out)]))
    assert f"{spec}: not UTF-8 text (expected a sweep spec, a TOML file)" in line


@pytest.mark.parametrize("argv", [
    ["analyze", LONG], ["analyze", f"{LONG}.npz"], ["run", f"{LONG}.toml"],
    ["run", "experiment1", "--robot", f"{LONG}.toml"], ["info", f"{LONG}.toml"],
    ["view", f"{LONG}.toml"], ["info", f"{LONG}.urdf"], ["sweep", f"{LONG}.toml"],
], ids=["analyze", "analyze-npz", "run", "run-robot", "info", "view", "info-urdf", "sweep"])  # fmt: skip
def test_a_name_of_300_characters(tmp_path, capsys, monkeypatch, argv):
    monkeypatch.chdir(tmp_path)
    line = _one_line(capsys, main(argv))
    assert "at most 255 bytes" in line or "File name too long" in line


def test_a_name_of_300_characters_in_the_api():
    with pytest.raises(WrongType, match=r"name_or_path: expected a path whose names have at most"):
        load_scenario(f"{LONG}.toml")
    with pytest.raises(WrongType, match=r"path: expected a path whose names have at most 255"):
        RunLog.load(LONG)


def test_a_non_utf8_robot_file_in_a_zoo_folder(tmp_path):
    (tmp_path / "a.toml").write_bytes(b'[robot]\nname = "pioneer_cyton"\n')
    (tmp_path / "b.toml").write_bytes(NOT_UTF8)
    with pytest.raises(ScenarioError, match=r"b\.toml: not UTF-8 text \(expected a robot file"):
        load_zoo(tmp_path)


def test_analyze_of_a_log_with_an_unknown_compression_method(tmp_path, capsys):
    """A zip whose members name compression method 99: zipfile's NotImplementedError."""
    path = _log(tmp_path / "run", META)
    data = bytearray(open(path, "rb").read())
    for signature, offset in ((b"PK\x03\x04", 8), (b"PK\x01\x02", 10)):  # local, central
        at = data.find(signature)
        while at != -1:
            data[at + offset : at + offset + 2] = (99).to_bytes(2, "little")
            at = data.find(signature, at + 4)
    open(path, "wb").write(bytes(data))
    line = _one_line(capsys, main(["analyze", path]))
    assert f"{path}: not a readable run log (NotImplementedError)" in line


def test_a_urdf_joint_axis_of_one_number(tmp_path, capsys):
    """``<axis xyz="0"/>`` (found by the fuzz at 5x): refused, not a matmul ValueError."""
    path = tmp_path / "axis.urdf"
    text = (URDF_DIR / "pioneer_cyton.urdf").read_text()
    start = text.index('<joint name="front_left_wheel_joint"')
    at = text.index('<axis xyz="', start)
    end = text.index('"', at + len('<axis xyz="'))
    path.write_text(text[:at] + '<axis xyz="0' + text[end:])
    line = _one_line(capsys, main(["info", str(path)]))
    assert "joint 'front_left_wheel_joint': <axis xyz=\"0\">: expected three finite numbers" in line
