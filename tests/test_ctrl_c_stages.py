"""Ctrl-C at every stage of ``pbvs-pin run`` (issue 31): one line, exit status 130, naming
what was kept and what was lost, and the files on disk agree with the line.

Each stage is reached without timing races: ``PBVS_PIN_INTERRUPT_AT`` makes the command send
itself SIGINT on entering the stage (:mod:`pbvs_pin.interrupts`), as a user's Ctrl-C would
arrive there. One more run is interrupted from outside while it loads its modules.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPO_ROOT

from pbvs_pin.interrupts import INTERRUPT_AT, INTERRUPTED, STAGES

PNG = "feature_errors.png"
"""One of the run's figures."""


def _run(tmp_path: Path, **env: str) -> subprocess.Popen:
    """``python -m pbvs_pin.cli run experiment1`` for 0.3 s with a replay, started."""
    return subprocess.Popen(
        [sys.executable, "-m", "pbvs_pin.cli", "run", "experiment1", "--duration", "0.3",
         "--out", str(tmp_path / "out"), "--html", str(tmp_path / "replay.html")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONPATH": str(REPO_ROOT), **env},
    )  # fmt: skip


def _said(process: subprocess.Popen) -> str:
    """The one line the interrupted command printed (checked to be the only one)."""
    out, err = process.communicate(timeout=600)
    assert process.returncode == INTERRUPTED, err
    assert "Traceback" not in err and "Error" not in err, err
    lines = [x for x in err.replace("\r", "\n").splitlines() if x.startswith("pbvs-pin")]
    assert len(lines) == 1, err
    assert "verdict" not in out and "{" not in out  # the run's printout never came
    return lines[0]


@pytest.mark.parametrize("stage", [s for s in STAGES if s not in ("command", "exit")])
def test_ctrl_c_at_each_stage_names_what_was_kept_and_lost(tmp_path, stage):
    line = _said(_run(tmp_path, **{INTERRUPT_AT: stage}))
    out, replay = tmp_path / "out", tmp_path / "replay.html"
    log, summary = out / "log.npz", out / "summary.json"
    written = {p.name for p in out.iterdir()} if out.is_dir() else set()
    if stage == "imports":
        assert line == "pbvs-pin: interrupted while loading its modules; nothing was run or written"
    if stage == "start-up":
        assert line == (
            "pbvs-pin: interrupted while starting, before any simulation; nothing was written"
        )
    if stage in ("imports", "start-up"):
        assert written == set() and not replay.exists()
    if stage == "simulation":
        assert line.startswith("pbvs-pin: interrupted at t = 0.00 s of 0.3 s; ")
        assert f"the run so far is in {log} (meta interrupted = true)" in line
        assert line.endswith(
            f"; lost: the summary {summary}, the figures in {out}, the replay {replay}"
        )
        assert written == {"log.npz"} and not replay.exists()
    if stage == "outputs":
        assert line == (
            f"pbvs-pin: interrupted while writing the outputs; kept: the log {log}, the summary "
            f"{summary}; lost: the figures in {out}, the replay {replay}"
        )
        assert written == {"log.npz", "summary.json"} and not replay.exists()
    if stage == "written":
        assert line == "pbvs-pin: interrupted after the outputs were written; nothing was lost"
        assert {"log.npz", "summary.json", PNG} <= written and replay.is_file()


def test_ctrl_c_once_the_command_is_done_is_ignored(tmp_path):
    """As the interpreter shuts down it could only kill the process by the signal (no line,
    status -2) and lose nothing: it is ignored, the status stays 0."""
    process = _run(tmp_path, **{INTERRUPT_AT: "exit"})
    out, err = process.communicate(timeout=600)
    assert process.returncode == 0, err
    assert "Traceback" not in err and "pbvs-pin:" not in err
    assert out.splitlines()[-1].startswith("log, summary (summary.json")
    assert (tmp_path / "out" / "summary.json").is_file() and (tmp_path / "replay.html").is_file()


def test_ctrl_c_while_the_modules_load_is_one_line(tmp_path):
    """A real SIGINT 0.5 s after the start, while the modules load or the run starts.

    Where it lands depends on the machine (with Pinocchio 4 the 0.3 s run can already be under
    way): whatever the stage, the command says one line, and the files agree with it.
    """
    process = _run(tmp_path)
    try:
        process.wait(timeout=0.5)
    except subprocess.TimeoutExpired:
        process.send_signal(signal.SIGINT)
    line = _said(process)
    assert line.startswith("pbvs-pin: interrupted ")
    if "nothing was" in line:  # while loading or starting
        assert not (tmp_path / "out").exists()
    else:  # the run had started: what the line says was kept is there
        assert (tmp_path / "out" / "log.npz").is_file()


def test_ctrl_c_that_a_library_swallows_while_starting_still_ends_the_run():
    """trimesh guards its optional imports with ``except BaseException``: a Ctrl-C raised
    inside one was swallowed, and the run went on to exit 0 (found by the test above, run
    where the start-up imports the libraries lazily)."""
    code = (
        "import signal\n"
        "from pbvs_pin import interrupts\n"
        "from pbvs_pin.interrupts import held_interrupts, stage\n"
        "interrupts.launched_as_command = lambda: True  # as pbvs-pin is\n"
        "stage('start-up')\n"
        "with held_interrupts():\n"
        "    try:\n"
        "        signal.raise_signal(signal.SIGINT)  # inside a library's guarded import\n"
        "    except BaseException:\n"
        "        pass\n"
        "    print('went on')\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, env={**os.environ, "PYTHONPATH": str(REPO_ROOT)})  # fmt: skip
    assert done.returncode == INTERRUPTED, done.stderr
    assert done.stdout == ""
    assert done.stderr == (
        "pbvs-pin: interrupted while starting, before any simulation; nothing was written\n"
    )


def test_each_command_says_what_an_interruption_leaves():
    """reproduce keeps its finished runs but not its report; analyze names its folder; info
    writes nothing; run's own line says it all (no note)."""
    from pbvs_pin.cli import _interrupt_note, build_parser
    from pbvs_pin.exceptions import OutputsInterrupted
    from pbvs_pin.interrupts import interrupted_line

    def note(*argv: str) -> str:
        return _interrupt_note(build_parser().parse_args(argv))

    assert note("reproduce", "--out", "R") == (
        "the runs finished before it are kept in R; the report was not written"
    )
    assert note("analyze", "log.npz", "--out", "A") == (
        "what it wrote to A before it is kept; the rest was not written"
    )
    assert note("info", "pioneer_cyton") == "nothing was written"
    assert note("run", "experiment1") == ""
    stop = OutputsInterrupted(["the log L"], ["the figures in F"])
    assert interrupted_line(stop, note("reproduce", "--out", "R")) == (
        "interrupted while writing the outputs; kept: the log L; lost: the figures in F; the "
        "runs finished before it are kept in R; the report was not written"
    )


@pytest.mark.parametrize(
    ("orig_argv", "launched"),
    [
        (["/venv/bin/python3", "/venv/bin/pbvs-pin", "run", "experiment1"], True),
        (["python", "-m", "pbvs_pin.cli", "list"], True),
        (["pbvs-pin.exe", "list"], True),
        (["python", "-c", "from multiprocessing.spawn import spawn_main; spawn_main()",
          "--multiprocessing-fork"], False),  # a sweep's worker: the parent's argv, not its own
        (["python", "-m", "pytest", "tests"], False),
        (["python", "my_script.py"], False),
    ],
)  # fmt: skip
def test_only_the_command_takes_ctrl_c_over_while_loading(monkeypatch, orig_argv, launched):
    from pbvs_pin.interrupts import launched_as_command

    monkeypatch.setattr(sys, "orig_argv", orig_argv)
    monkeypatch.setattr(sys, "argv", ["/venv/bin/pbvs-pin", "run"])  # as a spawned worker has
    assert launched_as_command() is launched
