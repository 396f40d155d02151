"""Where the runs of a sweep execute: a local process pool or a Dask cluster.

A local process pool (``concurrent.futures.ProcessPoolExecutor``, workers
forked from a clean fork server that has the simulation imported, one BLAS thread each) by
default, or a Dask distributed cluster when a scheduler address is given
(``dask[distributed]`` needed). Runs are submitted a few at a time per worker
and recorded as they complete. A run's failure (exception, divergence, timeout) is recorded in
its row and the sweep goes on; a worker process that dies is replaced and its runs are retried
once. The timeout is checked by the run itself at every logged instant, so it works on every
executor.

**Lost infrastructure.** A run that could not finish because its executor failed (a worker
process that died twice while running it, a lost Dask scheduler, a Dask worker killed
repeatedly) is not recorded: :func:`execute` stops submitting, lets the runs in flight end,
and :func:`pbvs_pin.study.sweep.driver.run_sweep` then raises
:class:`~pbvs_pin.exceptions.SweepIncomplete`, so that the sweep exits non-zero and a resume
runs them again. A scheduler address is probed first (:func:`probe_scheduler`): an unknown
scheme, an unreachable port, or a service that does not greet like a Dask scheduler within
:data:`PROBE_TIMEOUT` seconds is refused.

**No orphans.** Each local worker process watches the sweep's process and exits within
:data:`PARENT_POLL` seconds of its death (even a SIGKILL), and an interrupted sweep
(Ctrl-C, SIGTERM) terminates its workers before it returns.
"""

from __future__ import annotations

import contextlib
import logging
import os
import socket
import struct
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Executor, Future, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from pbvs_pin.exceptions import PbvsError
from pbvs_pin.study.sweep.runner import run_one
from pbvs_pin.study.sweep.spec import RunTask

RETRIES_AFTER_CRASH = 1
"""How many times a run in flight when its worker process died is run again."""

PROBE_TIMEOUT = 5.0
"""Seconds a scheduler address has to accept a connection and send Dask's greeting."""

STOP_POLL = 0.2
"""Seconds between the sweep's checks of its stop event (SIGTERM, SIGINT)."""

PARENT_POLL = 1.0
"""Seconds between a local worker's checks that the sweep's process is alive."""

DASK_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx", "inproc")
"""Address schemes of Dask's communication layer (no scheme means tcp)."""


SINGLE_THREAD_ENVIRONMENT = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}
"""Environment of the worker processes: one BLAS thread each, as Dask's workers have. The
matrices of a run are tiny, and two processes each spinning several BLAS threads on a small
machine run twice as slowly per run (measured: 3.1 s instead of 0.8 s on 2 cores)."""


@contextlib.contextmanager
def worker_environment() -> Iterator[None]:
    """Set :data:`SINGLE_THREAD_ENVIRONMENT` (unless the user set it) while workers spawn."""
    previous = {key: os.environ.get(key) for key in SINGLE_THREAD_ENVIRONMENT}
    for key, value in SINGLE_THREAD_ENVIRONMENT.items():
        os.environ.setdefault(key, value)
    try:
        yield
    finally:
        for key, old in previous.items():
            if old is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = old


WORKER_PRELOAD = ["pbvs_pin.study.sweep", "pbvs_pin.sim.loop", "pbvs_pin.study.analysis"]
"""Modules the fork server imports once, so that each worker starts with them loaded."""


def process_pool(workers: int) -> Executor:
    """A pool of ``workers`` processes, forked from a clean fork server (spawned if none).

    The fork server is a fresh single-threaded interpreter (safe to fork, unlike this
    process, which may run threads) that has imported :data:`WORKER_PRELOAD`; it lives as
    long as this process, so later pools start at once.
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    watch = {"initializer": watch_parent, "initargs": (os.getpid(),)}
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return ProcessPoolExecutor(
            workers, mp_context=multiprocessing.get_context("spawn"), **watch
        )
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(WORKER_PRELOAD)
    return ProcessPoolExecutor(workers, mp_context=context, **watch)


def watch_parent(pid: int) -> None:
    """In a worker: exit as soon as process ``pid`` (the sweep) is gone (a daemon thread)."""

    def watch() -> None:
        while _alive(pid):
            time.sleep(PARENT_POLL)
        os._exit(1)

    threading.Thread(target=watch, name="watch-sweep", daemon=True).start()


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, dead but not yet reaped, does not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by another user
        return True
    try:
        with open(f"/proc/{pid}/stat") as handle:
            return handle.read().rpartition(")")[2].split()[0] != "Z"
    except OSError:  # no /proc (not Linux): kill() said it exists
        return True


def probe_scheduler(address: str, timeout: float = PROBE_TIMEOUT) -> None:
    """Refuse an address that is not a reachable Dask scheduler, within ``timeout`` seconds.

    A Dask scheduler greets every TCP connection at once with a handshake frame (an 8-byte
    length, then a msgpack map holding ``compression``); a web server (such as the Dask
    dashboard) or a silent socket sends nothing, and is refused instead of waited on forever.
    Encrypted and non-TCP schemes are only checked for their scheme.

    Raises:
        PbvsError: Naming ``--scheduler``, the address and what was expected.
    """
    scheme, _, rest = address.rpartition("://")
    if scheme and scheme not in DASK_SCHEMES:
        raise PbvsError(
            f"--scheduler {address}: unknown scheme {scheme!r}; expected one of "
            f"{', '.join(DASK_SCHEMES)} (e.g. tcp://127.0.0.1:8786)"
        )
    if scheme not in ("", "tcp"):
        return
    host, _, port = rest.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise PbvsError(f"--scheduler {address}: expected tcp://HOST:PORT with a port in 1..65535")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout) as conn:
            conn.settimeout(timeout)
            greeting = _receive(conn, 8)
            length = struct.unpack("<Q", greeting)[0]
            body = _receive(conn, length) if 0 < length <= 1 << 16 else b""
    except (OSError, struct.error) as err:
        timed_out = isinstance(err, TimeoutError)
        reason = f"no answer within {timeout:g} s" if timed_out else (err.strerror or str(err))
        raise PbvsError(
            f"--scheduler {address}: not a Dask scheduler ({reason}); "
            "expected the scheduler's address (default port 8786), not its dashboard"
        ) from err
    if b"compression" not in body:
        raise PbvsError(
            f"--scheduler {address}: the service there does not speak Dask's protocol; "
            "expected the scheduler's address (default port 8786), not its dashboard"
        )


def _receive(conn: socket.socket, size: int) -> bytes:
    """Exactly ``size`` bytes (the socket's timeout applies), or OSError."""
    data = b""
    while len(data) < size:
        chunk = conn.recv(size - len(data))
        if not chunk:
            raise OSError(0, "connection closed")
        data += chunk
    return data


@contextlib.contextmanager
def dask_executor(address: str) -> Iterator[tuple[Callable[[], Executor], int]]:
    """A concurrent.futures view of a Dask cluster, and its number of worker threads.

    Call :func:`probe_scheduler` first: Dask itself may wait forever on a non-Dask service.
    """
    try:
        from distributed import Client
    except ImportError as err:
        raise PbvsError("--scheduler needs Dask: pip install 'dask[distributed]'") from err
    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError, ValueError) as err:
        raise PbvsError(f"--scheduler {address}: cannot connect: {err}") from err
    loggers = [logging.getLogger(name) for name in ("distributed", "distributed.client")]
    levels = [logger.level for logger in loggers]
    for logger in loggers:  # a lost scheduler is reported once, by SweepIncomplete
        logger.setLevel(logging.CRITICAL)
    try:
        threads = max(1, sum(client.nthreads().values()))
        yield (lambda: client.get_executor(pure=False)), threads
    finally:
        with contextlib.suppress(Exception):
            client.close(timeout=10)
        for logger, level in zip(loggers, levels, strict=True):
            logger.setLevel(level)


def execute(
    make_executor: Callable[[], Executor],
    tasks: list[RunTask],
    window: int,
    unfinished: list[tuple[RunTask, str]],
    stop: threading.Event | None = None,
) -> Iterator[tuple[dict[str, Any], dict[str, Any]]]:
    """Run tasks with at most ``window`` in flight; yield each result as it completes.

    A broken process pool is replaced; its runs in flight are retried
    :data:`RETRIES_AFTER_CRASH` times. A run the executor could not finish (crashed again,
    or any executor error such as a lost Dask scheduler) is appended to ``unfinished`` with
    the reason, not yielded; after the first such failure nothing new is submitted.
    When ``stop`` is set (checked every :data:`STOP_POLL` seconds) or on KeyboardInterrupt,
    the local workers are terminated and KeyboardInterrupt is raised.
    """
    queue = deque(tasks)
    crashes: dict[str, int] = {}
    executor = make_executor()
    in_flight: dict[Future, RunTask] = {}
    try:
        while queue or in_flight:
            while queue and len(in_flight) < window and not unfinished:
                task = queue.popleft()
                in_flight[executor.submit(run_one, task)] = task
            if not in_flight:
                break
            done, _ = wait(in_flight, timeout=STOP_POLL, return_when=FIRST_COMPLETED)
            if stop is not None and stop.is_set():
                raise KeyboardInterrupt
            broken = False
            for future in done:
                task = in_flight.pop(future)
                try:
                    yield future.result()
                except BrokenProcessPool:
                    broken = True
                    crashes[task.run_id] = crashes.get(task.run_id, 0) + 1
                    if crashes[task.run_id] > RETRIES_AFTER_CRASH:
                        unfinished.append((task, "its worker process died while running it"))
                    else:
                        queue.appendleft(task)
                except Exception as err:  # infrastructure failure (e.g. Dask scheduler lost)
                    reason = ": ".join(filter(None, [type(err).__name__, str(err)]))
                    unfinished.append((task, reason))
            if broken:
                for future, task in in_flight.items():
                    future.cancel()
                    queue.appendleft(task)
                in_flight.clear()
                _shutdown(executor, wait=False)
                executor = make_executor()
        unfinished.extend((task, "not started after an executor failure") for task in queue)
    except BaseException:
        _terminate(executor)
        raise
    finally:
        for future in in_flight:
            future.cancel()
        _shutdown(executor, wait=not in_flight)


def _terminate(executor: Executor) -> None:
    """Kill a local pool's worker processes at once (an interrupted sweep leaves none)."""
    for process in list((getattr(executor, "_processes", None) or {}).values()):
        with contextlib.suppress(Exception):
            process.terminate()


def _shutdown(executor: Executor, wait: bool) -> None:
    """Shut an executor down; without waiting, cancel what has not started."""
    if wait:
        executor.shutdown(wait=True)
        return
    try:
        executor.shutdown(wait=False, cancel_futures=True)
    except TypeError:  # Dask's ClientExecutor cancels without being asked
        executor.shutdown(wait=False)
