"""Ctrl-C during a simulation, held until Python code can take it.

A ``KeyboardInterrupt`` raised while a compiled (Numba) kernel runs escapes as
``SystemError: CPUDispatcher(...) returned a result with an exception set``, which the loop
cannot catch and whose run is lost. Inside :func:`held_interrupts` and while a simulation runs
(:func:`simulating`), the first Ctrl-C only sets a flag; :func:`interrupt_point`, called by
the simulation at every logged instant (through :func:`with_interrupt_point`), raises the
``KeyboardInterrupt`` there, in Python code, where the loop saves the run so far. A second
Ctrl-C, or one outside a simulation, raises at once.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

_held = {"active": False, "pending": False, "simulating": False}


def _hold(signum: int, frame: object) -> None:
    """SIGINT handler: hold the first Ctrl-C of a simulation, raise on the second."""
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
