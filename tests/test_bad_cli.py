"""Catalogue of bad command lines (issue 12): exit status 2 and one line, never a traceback.

Each case runs ``pbvs-pin`` in-process (:func:`pbvs_pin.cli.main`) on a bad file or argument
made in ``tmp_path``; every one is refused before a simulation starts, and within a bounded
time for a scheduler address that is not a Dask scheduler.
"""

from __future__ import annotations

import socket
import time

import pytest
from conftest import URDF_DIR

from pbvs_pin.cli import main

CYTON = (URDF_DIR / "pioneer_cyton.urdf").read_text()
EXPERIMENT = """
duration = 5.0
[robot]
name = "pioneer_cyton"
[target]
xi0 = [-150.0, 20.0, -100.0]
xi_d = [0.0, 60.0, -60.0]
"""
SPEC = """
[sweep]
scenario = "experiment1"
seed = 5
[fixed]
duration = 1.0
[grid]
estimator.alpha = [0.5, 0.6]
"""


def _files(tmp_path):
    """Write the bad inputs; return name -> path."""
    files = {
        "loop.urdf": CYTON.replace(
            "</robot>",
            '<joint name="loop" type="fixed"><parent link="upper_arm_link"/>'
            '<child link="chassis_link"/></joint></robot>',
        ),
        "heavy.urdf": CYTON.replace('<mass value="0.6"/>', '<mass value="-1.0"/>', 1),
        "garbage.urdf": "\x00\x01 not xml",
        "garbage.toml": "",
        "empty.toml": "",
        "inf.toml": EXPERIMENT.replace("duration = 5.0", "duration = inf"),
        "swapped.toml": EXPERIMENT.replace("[0.0, 60.0, -60.0]", "[0.0, -60.0, 60.0]"),
        "obstacle.toml": EXPERIMENT
        + '[[obstacles]]\nkind = "circle"\nx = 0.0\ny = 0.0\nradius = 0.3\n',
        "rate.toml": EXPERIMENT + "[controller]\nrate = 33.0\n",
        "latency.toml": EXPERIMENT + "[camera]\nlatency = 100.0\n",
        "norobot.toml": "[camera]\nrate = 30.0\n",
        "spec.toml": SPEC,
        "badspec.toml": SPEC.replace("seed = 5", "seed = -5"),
    }
    paths = {}
    for name, text in files.items():
        paths[name] = tmp_path / name
        paths[name].write_text(text)
    paths["garbage.toml"].write_bytes(bytes(range(256)) * 2)
    return paths


# (id, argv with {name} placeholders for the files, text the line must contain)
CASES = [
    ("info-loop-urdf", ["info", "{loop.urdf}"], "two parents"),
    ("info-negative-mass", ["info", "{heavy.urdf}"], "front_left_wheel_link"),
    ("info-garbage-urdf", ["info", "{garbage.urdf}"], "not well-formed XML"),
    ("info-missing-urdf", ["info", "{missing.urdf}"], "file not found"),
    ("info-unknown-robot", ["info", "no_such_robot"], "no_such_robot"),
    ("info-toml-without-robot", ["info", "{norobot.toml}"], "robot"),
    ("run-binary-scenario", ["run", "{garbage.toml}"], "not UTF-8"),
    ("run-empty-scenario", ["run", "{empty.toml}"], "empty scenario"),
    ("run-duration-inf", ["run", "{inf.toml}"], "duration"),
    ("run-xi_d-swapped", ["run", "{swapped.toml}"], "target.xi_d"),
    ("run-obstacle-over-start", ["run", "{obstacle.toml}"], "obstacles[0]"),
    ("run-controller-33Hz", ["run", "{rate.toml}"], "controller.rate"),
    ("run-latency-100s", ["run", "{latency.toml}"], "camera.latency"),
    ("run-missing", ["run", "{missing.toml}"], "no such scenario"),
    ("sweep-unknown-scheme", ["sweep", "{spec.toml}", "--scheduler", "foo://x:1"],
     "unknown scheme 'foo'"),
    ("sweep-bad-port", ["sweep", "{spec.toml}", "--scheduler", "tcp://127.0.0.1:abc"],
     "--scheduler"),
    ("sweep-closed-port", ["sweep", "{spec.toml}", "--scheduler", "tcp://127.0.0.1:1"],
     "not a Dask scheduler"),
    ("sweep-max-runs-0", ["sweep", "{spec.toml}", "--max-runs", "0"], "--max-runs"),
    ("sweep-max-runs-negative", ["sweep", "{spec.toml}", "--max-runs", "-3"], "--max-runs"),
    ("sweep-workers-0", ["sweep", "{spec.toml}", "--workers", "0"], "--workers"),
    ("sweep-bad-spec", ["sweep", "{badspec.toml}"], "seed"),
    ("sweep-missing-spec", ["sweep", "{missing.toml}"], "missing.toml"),
    ("analyze-missing-log", ["analyze", "{missing.npz}"], "missing.npz"),
]  # fmt: skip


def _argv(template: list[str], paths: dict, tmp_path) -> list[str]:
    argv = []
    for arg in template:
        if arg.startswith("{"):
            name = arg.strip("{}")
            arg = str(paths.get(name, tmp_path / name))
        argv.append(arg)
    return [*argv, "--out", str(tmp_path / "out")] if argv[0] in ("run", "sweep") else argv


def _one_line_error(capsys, status: int, named: str) -> None:
    err = capsys.readouterr().err
    assert status == 2
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("pbvs-pin: error: ")
    assert named in lines[0]


@pytest.mark.parametrize(("argv", "named"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_command_line_exits_2_with_one_line(tmp_path, capsys, argv, named):
    paths = _files(tmp_path)
    status = main(_argv(argv, paths, tmp_path))
    _one_line_error(capsys, status, named)
    assert not (tmp_path / "out" / "log.npz").exists()


def test_a_silent_scheduler_port_is_refused_in_bounded_time(tmp_path, capsys):
    """A socket that accepts and never speaks (a dashboard, any other service) used to hang."""
    paths = _files(tmp_path)
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
        started = time.monotonic()
        status = main(["sweep", str(paths["spec.toml"]), "--scheduler", address,
                       "--out", str(tmp_path / "out")])  # fmt: skip
        elapsed = time.monotonic() - started
    _one_line_error(capsys, status, "not a Dask scheduler")
    assert elapsed < 15.0
    assert not (tmp_path / "out").exists()  # refused before the folder is touched


@pytest.mark.parametrize("argv", [["sweep", "x.toml", "--workers", "two"],
                                  ["run", "x.toml", "--speed", "-1"], ["unknown-command"]])
def test_malformed_arguments_exit_2_without_traceback(capsys, argv):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    err = capsys.readouterr().err
    assert exit_info.value.code == 2
    assert "Traceback" not in err
    assert "error:" in err.splitlines()[-1]
