"""Start-up and shut-down of a served meshcat viewer (a ``meshcat-server`` subprocess).

A server that cannot start raises :class:`~pbvs_pin.exceptions.ViewerUnavailable` with
advice (by default :data:`VIEWER_ADVICE`: write a standalone HTML file instead, which
needs no server; see :mod:`pbvs_pin.viz.recorder`).
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Iterator
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover - typing only
    import meshcat

__all__ = [
    "VIEWER_ADVICE",
    "open_visualizer",
    "start_visualizer",
    "stop_visualizer",
]

VIEWER_ADVICE = (
    "write a standalone HTML file instead, which needs no server: "
    "`pbvs-pin view ROBOT --html FILE`, or `pbvs-pin run SCENARIO --html FILE` "
    "(the replay is written next to the results); then open that file in a browser"
)
"""What :class:`~pbvs_pin.exceptions.ViewerUnavailable` advises by default."""


def _last_line(text: str) -> str:
    """The last non-empty line of ``text`` (meshcat reports server failures on stdout)."""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[-1] if lines else ""


def start_visualizer(
    zmq_url: str | None = None,
    timeout: float | None = None,
    advice: str = VIEWER_ADVICE,
) -> meshcat.Visualizer:
    """Start a private meshcat server (or connect to one) and return its visualizer.

    Stop it with :func:`stop_visualizer`.  Meshcat's own messages (its URL,
    and the server's output when it dies) are captured, not printed; the
    error message quotes the last line of them.

    Args:
        zmq_url: URL of an already running ``meshcat-server``; ``None`` starts
            a private one on the loopback interface.
        timeout: If given, every later command waits at most this long for
            the server [s] and then raises ``zmq.Again`` instead of blocking
            forever on a dead server.
        advice: What the error message tells the user to do instead.

    Returns:
        A connected ``meshcat.Visualizer`` rooted at ``/meshcat``.

    Raises:
        ViewerUnavailable: If the server cannot be started or reached (zmq
            port or permission errors, ``meshcat.servers.zmqserver`` missing
            or crashing, ...).
    """
    from pbvs_pin.exceptions import ViewerUnavailable

    captured = io.StringIO()
    try:
        import meshcat

        with contextlib.redirect_stdout(captured):  # meshcat prints its URL
            vis = meshcat.Visualizer(zmq_url=zmq_url)
    # meshcat reports failures as RuntimeError, ValueError, zmq.ZMQError, OSError or a bare
    # Exception from the server subprocess: all of them mean "no viewer".
    except Exception as err:
        detail = _last_line(captured.getvalue())
        reason = f"{type(err).__name__}: {err}".replace("\n", " ")
        if detail and detail not in reason:
            reason = f"{reason} ({detail})"
        raise ViewerUnavailable(f"could not start the meshcat server: {reason}", advice) from err
    if timeout is not None:
        import zmq

        socket = vis.window.zmq_socket
        milliseconds = max(1, round(1000 * float(timeout)))
        socket.setsockopt(zmq.RCVTIMEO, milliseconds)
        socket.setsockopt(zmq.SNDTIMEO, milliseconds)
        socket.setsockopt(zmq.LINGER, 0)
    return vis


def stop_visualizer(vis: meshcat.Visualizer) -> None:
    """Close the connection of ``vis`` and kill the server process it started (if any).

    Never raises; a visualizer from :func:`~pbvs_pin.viz.recorder.offline_visualizer`
    is left alone.

    Args:
        vis: A visualizer from :func:`start_visualizer`.
    """
    window = vis.window
    socket = getattr(window, "zmq_socket", None)
    if socket is not None:
        with contextlib.suppress(Exception):
            socket.close(linger=0)
    proc = getattr(window, "server_proc", None)
    if proc is not None and proc.poll() is None:
        proc.kill()
        with contextlib.suppress(Exception):
            proc.wait(timeout=10)


@contextlib.contextmanager
def open_visualizer(zmq_url: str | None = None) -> Iterator[meshcat.Visualizer]:
    """Start (or connect to) a meshcat server and stop it on exit.

    ``Visualizer.static_html()`` asks the running zmq server for the scene,
    so a server must be alive while a replay is written (or use
    :func:`~pbvs_pin.viz.recorder.offline_visualizer`, which needs none).  With
    ``zmq_url=None`` meshcat starts its own server on the loopback interface; this
    context manager kills exactly that process when leaving.

    Args:
        zmq_url: URL of an already running ``meshcat-server``; ``None`` starts
            a private one.

    Yields:
        A connected ``meshcat.Visualizer`` rooted at ``/meshcat``.

    Raises:
        ViewerUnavailable: If the server cannot be started or reached.
    """
    vis = start_visualizer(zmq_url)
    try:
        yield vis
    finally:
        stop_visualizer(vis)
