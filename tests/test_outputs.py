"""The one output guard (issue 24 item 1): every command, enumerated from the parser.

Every option a command writes to is declared with :func:`pbvs_pin.outputs.output_option`; a new
command or option that writes without declaring it fails
:func:`test_every_writing_option_is_declared`. Each declared output is then tried on paths
that cannot be written, with the command itself replaced by a trap: the refusal must come
before the command starts, in one line, leaving the disk as it was.
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from pbvs_pin import cli
from pbvs_pin.cli import build_parser, main
from pbvs_pin.exceptions import LogError, OutputError
from pbvs_pin.outputs import Output, check_output, replace_run_folder
from pbvs_pin.sim.log import RunLog, json_safe, write_json_atomically

WRITING_WORDS = ("write", "folder", "output", "file")
"""Words in an option's help that say it names something written (or read: then it must be
listed in READ_OPTIONS)."""

READ_OPTIONS = {("analyze", "log"), ("sweep", "spec"), ("run", "scenario"), ("run", "robot"),
                ("info", "robot"), ("view", "robot"), ("reproduce", "robots"),
                ("zoo", "folder")}  # fmt: skip
"""Options whose help mentions files but which name inputs: read, never written."""


def _commands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    (subparsers,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(subparsers.choices)


def _declared() -> list[tuple[str, str, Output]]:
    return [(name, dest, kind) for name, sub in _commands().items()
            for dest, kind in sub.get_default("outputs") or ()]  # fmt: skip


def test_the_commands_that_write_are_found():
    writers = {name for name, _, _ in _declared()}
    assert writers == {"run", "reproduce", "view", "analyze", "sweep", "zoo"}


def test_every_writing_option_is_declared():
    for name, sub in _commands().items():
        declared = {dest for dest, _ in sub.get_default("outputs") or ()}
        for action in sub._actions:
            if action.dest in ("help", "force") or action.help is None:
                continue
            says_file = any(word in action.help.lower() for word in WRITING_WORDS)
            if says_file and (name, action.dest) not in READ_OPTIONS:
                assert action.dest in declared, (name, action.dest, action.help)


def _argv(command: str, dest: str, value: str) -> list[str]:
    sub = _commands()[command]
    argv = [command]
    for action in sub._actions:
        if not action.option_strings and action.dest != "help":
            argv.append(value if action.dest == dest else "x")
    option = next((a for a in sub._actions if a.dest == dest and a.option_strings), None)
    return argv + ([option.option_strings[0], value] if option is not None else [])


def _bad_paths(tmp_path, kind: Output) -> list[str]:
    blocker = tmp_path / "a_file"
    blocker.write_text("a file, not a folder")
    folder = tmp_path / "a_folder"
    folder.mkdir()
    paths = [str(blocker / "sub"), str(blocker / "sub" / "deeper")]
    return paths + ([str(folder)] if kind is Output.FILE else [str(blocker)])


@pytest.mark.parametrize(("command", "dest", "kind"), _declared(),
                         ids=[f"{c}-{d}" for c, d, _ in _declared()])  # fmt: skip
def test_every_output_is_refused_before_the_command_starts(
    tmp_path, capsys, monkeypatch, command, dest, kind
):
    handler = _commands()[command].get_default("handler")
    started = []
    monkeypatch.setattr(cli, handler.__name__, lambda args: started.append(args))
    for bad in _bad_paths(tmp_path, kind):
        before = sorted(p.name for p in tmp_path.rglob("*"))
        status = main(_argv(command, dest, bad))
        err = capsys.readouterr().err
        assert status == 2, (bad, err)
        assert started == []
        assert err.count("\n") == 1 and err.startswith("pbvs-pin: error: "), err
        assert "nothing was run" in err
        assert sorted(p.name for p in tmp_path.rglob("*")) == before


def test_a_good_output_lets_the_command_start(tmp_path, monkeypatch):
    started = []
    monkeypatch.setattr(cli, "_analyze", lambda args: started.append(args.out))
    assert main(["analyze", "x", "--out", str(tmp_path / "new" / "analysis")]) == 0
    assert started == [str(tmp_path / "new" / "analysis")]
    assert not (tmp_path / "new").exists()  # the guard creates nothing


def test_a_read_only_folder_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr("os.access", lambda path, mode: False)  # root may write anywhere
    with pytest.raises(OutputError, match="is not writable"):
        check_output(tmp_path / "run", Output.RUN_FOLDER)


# ---------------------------------------------------------------- a used run folder
def test_a_used_run_folder_is_refused_without_force(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cli, "_run", lambda args: None)
    RunLog({"t": np.arange(3.0)}, {"scenario": "old"}).save(tmp_path / "out")
    assert main(["run", "experiment1", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "holds an earlier run; add --force" in err
    assert main(["run", "experiment1", "--out", str(tmp_path / "out"), "--force"]) == 0


def test_a_folder_of_other_files_is_refused_even_with_force(tmp_path):
    (tmp_path / "thesis.tex").write_text("precious")
    with pytest.raises(OutputError, match="not a pbvs-pin run"):
        check_output(tmp_path, Output.RUN_FOLDER, force=True)
    assert (tmp_path / "thesis.tex").read_text() == "precious"


def test_force_replaces_every_file_of_the_earlier_run(tmp_path):
    RunLog({"t": np.arange(3.0)}, {"scenario": "old"}).save(tmp_path)
    (tmp_path / "replay.html").write_text("old replay")
    (tmp_path / "figures").mkdir()
    (tmp_path / "figures" / "xi.png").write_bytes(b"png")
    check_output(tmp_path, Output.RUN_FOLDER, force=True)
    replace_run_folder(tmp_path)
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- logs read back
def _log(tmp_path) -> bytes:
    RunLog({"t": np.arange(50.0), "xi": np.zeros((50, 3))}, {"scenario": "x"}).save(tmp_path)
    return (tmp_path / "log.npz").read_bytes()


@pytest.mark.parametrize("cut", [0, 10, 100, -30, -1])
def test_a_truncated_log_is_a_log_error(tmp_path, cut):
    whole = _log(tmp_path)
    (tmp_path / "log.npz").write_bytes(whole[:cut])
    with pytest.raises(LogError, match=r"log\.npz"):
        RunLog.load(tmp_path)


def test_analyze_on_a_truncated_log_is_one_line(tmp_path, capsys):
    whole = _log(tmp_path)
    (tmp_path / "log.npz").write_bytes(whole[: len(whole) // 2])
    assert main(["analyze", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a readable run log" in err


def test_analyze_on_a_log_without_its_channels_names_them(tmp_path, capsys):
    _log(tmp_path)
    assert main(["analyze", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no channel" in err and "storage" in err


@pytest.mark.parametrize(
    ("channels", "meta", "problem"),
    [
        ({"xi": np.zeros((3, 3))}, {}, "no time channel"),
        ({"t": np.zeros(3), "xi": np.zeros((2, 3))}, {}, "do not have the 3 samples"),
        ({"t": np.zeros(3), "k": np.float64(1.0)}, {}, "do not have the 3 samples"),
    ],
)
def test_a_foreign_log_is_a_log_error(tmp_path, channels, meta, problem):
    RunLog(channels, meta).save(tmp_path)
    with pytest.raises(LogError, match=problem):
        RunLog.load(tmp_path)


def test_a_pickle_in_a_log_is_never_read(tmp_path):
    np.savez(tmp_path / "log.npz", meta=json.dumps({}), t=np.array([object()], dtype=object))
    with pytest.raises(LogError, match="not a readable run log"):
        RunLog.load(tmp_path)


# ---------------------------------------------------------------- JSON outputs
def test_json_outputs_hold_no_nan(tmp_path):
    data = {"a": float("nan"), "b": [1.0, float("inf"), np.float64("-inf")], "c": {"d": 2.5}}
    write_json_atomically(tmp_path / "s.json", data)
    text = (tmp_path / "s.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    assert json.loads(text) == {"a": None, "b": [1.0, None, None], "c": {"d": 2.5}}
    assert json_safe({"x": (1, 2)}) == {"x": [1, 2]}
