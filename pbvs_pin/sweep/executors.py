"""Where the runs of a sweep execute: a local process pool or a Dask cluster.

A local process pool (``concurrent.futures.ProcessPoolExecutor``, workers
forked from a clean fork server that has the simulation imported, one BLAS thread each) by
default, or a Dask distributed cluster when a scheduler address is given
(``dask[distributed]`` needed). Runs are submitted a few at a time per worker
and recorded as they complete. A run's failure (exception, divergence, timeout) is recorded in
its row and the sweep goes on; a worker process that dies is replaced and its runs are retried
once, then recorded as failed. The timeout is checked by the run itself at every logged
instant, so it works on every executor.
"""

from __future__ import annotations

import contextlib
import os
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Executor, Future, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from pbvs_pin.exceptions import PbvsError
from pbvs_pin.sweep.runner import failed_run, run_one
from pbvs_pin.sweep.spec import RunTask

RETRIES_AFTER_CRASH = 1
"""How many times a run in flight when its worker process died is run again."""


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


WORKER_PRELOAD = ["pbvs_pin.sweep", "pbvs_pin.sim.loop", "pbvs_pin.analysis"]
"""Modules the fork server imports once, so that each worker starts with them loaded."""


def process_pool(workers: int) -> Executor:
    """A pool of ``workers`` processes, forked from a clean fork server (spawned if none).

    The fork server is a fresh single-threaded interpreter (safe to fork, unlike this
    process, which may run threads) that has imported :data:`WORKER_PRELOAD`; it lives as
    long as this process, so later pools start at once.
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(WORKER_PRELOAD)
    return ProcessPoolExecutor(workers, mp_context=context)


@contextlib.contextmanager
def dask_executor(address: str) -> Iterator[tuple[Callable[[], Executor], int]]:
    """A concurrent.futures view of a Dask cluster, and its number of worker threads."""
    try:
        from distributed import Client
    except ImportError as err:
        raise PbvsError("--scheduler needs Dask: pip install 'dask[distributed]'") from err
    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError) as err:
        raise PbvsError(f"cannot reach the Dask scheduler at {address}: {err}") from err
    try:
        threads = max(1, sum(client.nthreads().values()))
        yield (lambda: client.get_executor(pure=False)), threads
    finally:
        client.close()


def execute(
    make_executor: Callable[[], Executor], tasks: list[RunTask], window: int
) -> Iterator[tuple[dict[str, Any], dict[str, Any]]]:
    """Run tasks with at most ``window`` in flight; yield each result as it completes.

    A broken process pool is replaced; its runs in flight are retried
    :data:`RETRIES_AFTER_CRASH` times, then recorded as failed.
    """
    queue = deque(tasks)
    crashes: dict[str, int] = {}
    executor = make_executor()
    in_flight: dict[Future, RunTask] = {}
    try:
        while queue or in_flight:
            while queue and len(in_flight) < window:
                task = queue.popleft()
                in_flight[executor.submit(run_one, task)] = task
            done, _ = wait(in_flight, return_when=FIRST_COMPLETED)
            broken = False
            for future in done:
                task = in_flight.pop(future)
                try:
                    yield future.result()
                except BrokenProcessPool:
                    broken = True
                    crashes[task.run_id] = crashes.get(task.run_id, 0) + 1
                    if crashes[task.run_id] > RETRIES_AFTER_CRASH:
                        yield failed_run(task, "worker process died while running it")
                    else:
                        queue.appendleft(task)
                except Exception as err:  # infrastructure failure (e.g. Dask KilledWorker)
                    yield failed_run(task, f"worker error: {type(err).__name__}: {err}")
            if broken:
                for future, task in in_flight.items():
                    future.cancel()
                    queue.appendleft(task)
                in_flight.clear()
                _shutdown(executor, wait=False)
                executor = make_executor()
    finally:
        for future in in_flight:
            future.cancel()
        _shutdown(executor, wait=not in_flight)


def _shutdown(executor: Executor, wait: bool) -> None:
    """Shut an executor down; without waiting, cancel what has not started."""
    if wait:
        executor.shutdown(wait=True)
        return
    try:
        executor.shutdown(wait=False, cancel_futures=True)
    except TypeError:  # Dask's ClientExecutor cancels without being asked
        executor.shutdown(wait=False)
