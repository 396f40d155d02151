"""Ctrl-C during a simulation, held until Python code can take it.

A ``KeyboardInterrupt`` raised while a compiled (Numba) kernel runs escapes as
``SystemError: CPUDispatcher(...) returned a result with an exception set``, which the loop
cannot catch and whose run is lost. Inside :func:`held_interrupts` and while a simulation runs
(:func:`simulating`), the first Ctrl-C only sets a flag; :func:`interrupt_point`, called by
the simulation at every logged instant (through :func:`with_interrupt_point`), raises the
``KeyboardInterrupt`` there, in Python code, where the loop saves the run so far. A second
Ctrl-C, or one outside a simulation, raises at once.

The ``pbvs-pin`` command passes through the :data:`STAGES`, each entered with :func:`stage`.
While it loads its modules (this module is the package's first import), Ctrl-C prints one line
and ends the process with status :data:`INTERRUPTED` at once (nothing has run or been
written); :func:`loaded` hands Ctrl-C back to Python. After that the command turns any
Ctrl-C into one line that says what was kept and what was lost (:func:`interrupted_line`).
The environment variable :data:`INTERRUPT_AT` makes the process send itself Ctrl-C on entering
a named stage, as a user's would arrive there (for tests, without timing races).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

_held = {"active": False, "pending": False, "simulating": False, "stage": "imports"}

INTERRUPTED = 130
"""Exit status after Ctrl-C (128 + SIGINT), as a shell reports it."""

STAGES = ("imports", "start-up", "simulation", "outputs", "written", "command", "exit")
"""The stages of a ``pbvs-pin`` command: loading its modules, reading its inputs and
compiling, simulating, writing a finished run's outputs, and after they are written; or
running a command that holds no Ctrl-C (``info``, ``analyze``, ...); and its exit, once its
status is decided (:func:`finished`: a Ctrl-C is ignored)."""

INTERRUPT_AT = "PBVS_PIN_INTERRUPT_AT"
"""Environment variable: the stage (of :data:`STAGES`) on whose entry the process sends
itself SIGINT."""

LOADING = "interrupted while loading its modules; nothing was run or written"
"""What a Ctrl-C during the ``imports`` stage did."""

_SAID = {
    "imports": LOADING,
    "start-up": "interrupted while starting, before any simulation; nothing was written",
    "simulation": "interrupted during the simulation; nothing was saved",
    "outputs": "interrupted while writing the outputs",
    "written": "interrupted after the outputs were written; nothing was lost",
    "command": "interrupted",
    "exit": "interrupted as it exited; nothing was lost",
}


def stage(name: str) -> None:
    """Enter a stage of :data:`STAGES`; where :data:`INTERRUPT_AT` names it, Ctrl-C arrives.

    Raises:
        KeyboardInterrupt: Where :data:`INTERRUPT_AT` names this stage and Ctrl-C is not
            held (as a user's Ctrl-C would).
    """
    _held["stage"] = name
    if os.environ.get(INTERRUPT_AT) == name:
        signal.raise_signal(signal.SIGINT)


def current_stage() -> str:
    """The stage last entered with :func:`stage`."""
    return str(_held["stage"])


def _while_loading(signum: int, frame: object) -> None:
    """SIGINT handler while the command loads its modules: one line, exit at once."""
    os.write(2, f"pbvs-pin: {LOADING}\n".encode())
    os._exit(INTERRUPTED)  # a KeyboardInterrupt here prints a traceback of some import


def launched_as_command() -> bool:
    """Whether this process is the ``pbvs-pin`` command (or ``python -m pbvs_pin.cli``).

    Read from the process's own command line (``sys.orig_argv``), which a multiprocessing
    worker does not share with its parent (it gets the parent's ``sys.argv``).
    """
    argv = getattr(sys, "orig_argv", [])
    if "-m" in argv[:-1]:
        return argv[argv.index("-m") + 1] == "pbvs_pin.cli"
    names = [os.path.basename(arg).removesuffix(".exe") for arg in argv[:2]]
    return "pbvs-pin" in names or "pbvs-pin-script.py" in names


def loaded() -> None:
    """The command's modules are loaded: Ctrl-C raises ``KeyboardInterrupt`` again."""
    if signal.getsignal(signal.SIGINT) is _while_loading:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def finished() -> None:
    """The command is done and its status decided: ignore a later Ctrl-C.

    In the ``pbvs-pin`` process only, where a Ctrl-C while the interpreter shuts down could
    only end it by the signal, without a line, and lose nothing.
    """
    if launched_as_command() and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        stage("exit")


def interrupted_line(stop: BaseException, note: str = "") -> str:
    """One line: what a Ctrl-C interrupted, what it kept and what it lost.

    Args:
        stop: The ``KeyboardInterrupt`` (a :class:`~pbvs_pin.exceptions.RunInterrupted`
            carries the run so far, an :class:`~pbvs_pin.exceptions.OutputsInterrupted` the
            outputs written and not written); another one is described by the stage.
        note: What the command adds (e.g. that its report was not written).
    """
    from pbvs_pin.exceptions import OutputsInterrupted, RunInterrupted

    if isinstance(stop, OutputsInterrupted):
        said = f"interrupted while writing the outputs; kept: {', '.join(stop.kept)}"
        said += f"; lost: {', '.join(stop.lost)}" if stop.lost else ""
    elif isinstance(stop, RunInterrupted):
        said = _run_so_far(stop)
    else:
        said = _SAID[current_stage()]
    return said + (f"; {note}" if note else "")


def _run_so_far(stop: Any) -> str:
    """Where an interrupted simulation stopped, where its run so far is, what was not written."""
    lost = f"; lost: {', '.join(stop.lost)}" if stop.lost else ""
    if stop.log is None:
        return "interrupted before the first logged step; nothing was saved" + lost
    log = stop.log
    stopped = f"interrupted at t = {log['t'][-1]:.2f} s of {log.meta['duration']:g} s"
    if stop.saved is None:
        return f"{stopped}; the run so far was not saved{lost}"
    return f"{stopped}; the run so far is in {stop.saved} (meta interrupted = true){lost}"


def _hold(signum: int, frame: object) -> None:
    """SIGINT handler: hold the first Ctrl-C of a simulation, raise on the second.

    While the ``pbvs-pin`` command starts (nothing written yet) it ends the process at once,
    with one line, as while loading: the start-up imports libraries lazily, and a
    ``KeyboardInterrupt`` raised inside one of their imports can be swallowed (trimesh guards
    its optional imports with ``except BaseException``), after which the run went on and
    exited 0.
    """
    if _held["stage"] == "start-up" and launched_as_command():  # never a test's process
        os.write(2, f"pbvs-pin: {_SAID['start-up']}\n".encode())
        os._exit(INTERRUPTED)
    if _held["pending"] or not _held["simulating"]:
        _held["pending"] = False
        raise KeyboardInterrupt
    _held["pending"] = True


@contextmanager
def held_interrupts() -> Iterator[None]:
    """Hold Ctrl-C until the next :func:`interrupt_point` (main thread only; else a no-op).

    Raises:
        KeyboardInterrupt: On leaving, if a Ctrl-C was held and not yet raised.
    """
    if threading.current_thread() is not threading.main_thread() or _held["active"]:
        yield
        return
    previous = signal.signal(signal.SIGINT, _hold)
    _held.update(active=True, pending=False)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        pending = _held["pending"]
        _held.update(active=False, pending=False)
    if pending:
        raise KeyboardInterrupt


@contextmanager
def simulating() -> Iterator[None]:
    """Mark a simulation: Ctrl-C is held (inside :func:`held_interrupts`) while it runs.

    A Ctrl-C held after the last logged instant stays pending: the caller raises it with
    :func:`interrupt_point` once the finished run is saved.
    """
    _held["simulating"] = True
    try:
        yield
    finally:
        _held["simulating"] = False


def interrupts_held() -> bool:
    """Whether Ctrl-C is being held (inside :func:`held_interrupts`)."""
    return _held["active"]


def interrupt_point() -> None:
    """Raise the held Ctrl-C, if any.

    Raises:
        KeyboardInterrupt: If a Ctrl-C was held.
    """
    if _held["pending"]:
        _held["pending"] = False
        raise KeyboardInterrupt


def with_interrupt_point(
    observer: Callable[[Any], None] | None,
) -> Callable[[Any], None]:
    """``observer`` (or nothing) preceded by :func:`interrupt_point`."""

    def observe(snapshot: Any) -> None:
        interrupt_point()
        if observer is not None:
            observer(snapshot)

    return observe


def interrupted_in_compiled_code(error: BaseException) -> bool:
    """Whether ``error`` (a ``SystemError``) is a Ctrl-C that landed in compiled code."""
    seen: BaseException | None = error
    while seen is not None:
        if isinstance(seen, KeyboardInterrupt):
            return True
        seen = seen.__cause__ or seen.__context__
    return False


if launched_as_command() and threading.current_thread() is threading.main_thread():
    signal.signal(signal.SIGINT, _while_loading)  # until the command's main calls loaded()
    stage("imports")
