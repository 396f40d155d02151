"""The one check of every file or folder a command writes, made before any work starts.

Every ``pbvs-pin`` command declares its outputs (:func:`output_option`); the
command line checks them all with :func:`check_output` before the command runs, so that a
path that cannot be written is refused in one line, never after a long run or in a traceback.
The check creates nothing: a refused command leaves the disk as it was.
"""

from __future__ import annotations

import argparse
import enum
import os
import shutil
from pathlib import Path

from pbvs_pin.exceptions import OutputError


class Output(enum.Enum):
    """What a command writes at a path."""

    FILE = "file"
    """One file (an HTML replay); an existing file is replaced."""
    FOLDER = "folder"
    """A folder of results that the command adds to (analysis, sweep: it resumes)."""
    RUN_FOLDER = "run folder"
    """A folder a run fills: it must be new or empty, or hold an earlier run to replace."""
    NEW_FOLDER = "new folder"
    """A folder written whole, that must not exist yet (a ROS bag)."""


RUN_MARKERS = ("log.npz", "summary.json", "report.md", "sweep.json", "analysis.json")
"""Files whose presence marks a folder as written by pbvs-pin (so ``--force`` may empty it)."""


def check_output(path: Path, kind: Output, force: bool = False) -> None:
    """Refuse an output path that cannot be written, without creating anything.

    Args:
        path: The file or folder.
        kind: What is written there.
        force: For a :attr:`Output.RUN_FOLDER`: accept a folder holding an earlier run (it
            is emptied by :func:`replace_run_folder`).

    Raises:
        OutputError: If a file is a folder, a folder is a file, a parent is a file, the
            nearest existing folder is not writable, or a used run folder without ``force``.
    """
    path = Path(path)
    if kind is Output.FILE:
        if path.is_dir():
            raise OutputError(str(path), "is a folder; expected a file name; nothing was run")
        folder = path.parent
    else:
        folder = path
    if folder.exists() and not folder.is_dir():
        raise OutputError(str(folder), "is a file; expected a folder; nothing was run")
    existing = next(p for p in (folder, *folder.parents) if p.exists() or p == p.parent)
    if not existing.is_dir():
        raise OutputError(
            str(path), f"cannot be created: {existing} is a file, not a folder; nothing was run"
        )
    if not os.access(existing, os.W_OK | os.X_OK):
        raise OutputError(
            str(path), f"cannot be written: {existing} is not writable; nothing was run"
        )
    if kind is Output.RUN_FOLDER:
        _check_run_folder(path, force)
    if kind is Output.NEW_FOLDER and path.exists():
        raise OutputError(str(path), "exists; expected a new folder; nothing was run")


def _check_run_folder(path: Path, force: bool) -> None:
    """A run folder must be new or empty, or hold an earlier pbvs-pin run and ``force``."""
    if not path.is_dir() or not any(path.iterdir()):
        return
    if not any((path / name).exists() for name in RUN_MARKERS):
        raise OutputError(
            str(path),
            "holds files that are not a pbvs-pin run; choose a new or empty folder",
        )
    if not force:
        raise OutputError(
            str(path),
            "holds an earlier run; add --force to replace all of its files, or choose a new folder",
        )


def replace_run_folder(path: Path) -> None:
    """Empty a run folder that :func:`check_output` accepted with ``force``.

    Raises:
        OutputError: If an entry cannot be removed.
    """
    path = Path(path)
    if not path.is_dir():
        return
    for entry in path.iterdir():
        try:
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry)
            else:
                entry.unlink()
        except OSError as err:
            raise OutputError(str(entry), f"cannot be removed ({err.strerror or err})") from err


def output_option(
    parser: argparse.ArgumentParser, flag: str, kind: Output, **kwargs
) -> argparse.Action:
    """Add an option or argument naming something the command writes, checked before it runs.

    Every file or folder a command writes goes through here: the command line's ``main``
    checks each one with :func:`check_output` (:func:`check_outputs`) before calling the command.

    Args:
        parser: The command's parser.
        flag: The option, e.g. ``"--out"``.
        kind: What is written there.
        kwargs: As :meth:`argparse.ArgumentParser.add_argument`.
    """
    action = parser.add_argument(flag, **kwargs)
    declared = parser.get_default("outputs") or ()
    parser.set_defaults(outputs=(*declared, (action.dest, kind)))
    return action


def check_outputs(args: argparse.Namespace) -> None:
    """Check every output the command declared (:func:`output_option`), creating nothing.

    Raises:
        OutputError: For the first path that cannot be written.
    """
    for dest, kind in getattr(args, "outputs", ()):
        value = getattr(args, dest)
        if value is not None:
            check_output(Path(value), kind, force=getattr(args, "force", False))
