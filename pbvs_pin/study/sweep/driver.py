"""A whole sweep: read the spec, lock the folder, run what is missing, write the outputs."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Iterator
from pathlib import Path

from pbvs_pin.exceptions import PbvsError, SweepIncomplete
from pbvs_pin.study.sweep.executors import (
    dask_executor,
    execute,
    probe_scheduler,
    process_pool,
    worker_environment,
)
from pbvs_pin.study.sweep.spec import load_sweep
from pbvs_pin.study.sweep.summary_plots import plot_sweep
from pbvs_pin.study.sweep.table import (
    TABLE,
    TIMINGS,
    ResultTable,
    append_timing,
    check_folder,
    exclusive,
    format_cell,
    write_parquet,
)


def run_sweep(
    spec: Path,
    out: Path,
    scheduler: str | None = None,
    workers: int | None = None,
    *,
    max_runs: int | None = None,
    retry_failed: bool = False,
    progress: bool = True,
    force: bool = False,
) -> Path:
    """Run (or resume) a sweep; return the path of its results table (``results.csv``).

    Args:
        spec: Sweep spec (TOML path, or a shipped spec's name).
        out: Output folder (created): ``results.csv``, ``timings.csv``, ``sweep.json``,
            ``results.parquet`` (with pyarrow) and the summary plots.
        scheduler: Dask scheduler address (e.g. ``tcp://127.0.0.1:8786``); None for a local
            process pool.
        workers: Local worker processes (default: the CPU count); ignored with Dask.
        max_runs: Stop after this many new runs (the rest are left for a resume).
        retry_failed: Run again the runs recorded as failed.
        progress: Show a progress bar (tqdm) on stderr.
        force: Adopt a folder that holds results but whose ``sweep.json`` is missing or
            unreadable (it is rewritten for this spec).

    Raises:
        ScenarioError: If the spec is invalid, or ``out`` holds another sweep's results (or
            results without a readable ``sweep.json``, unless ``force``).
        PbvsError: If ``workers`` or ``max_runs`` is not positive, the Dask scheduler cannot
            be reached or is not one, or another sweep is writing into ``out``.
        SweepIncomplete: If runs could not finish (a lost scheduler or workers, Ctrl-C,
            SIGTERM): the finished ones are saved, the others are run by a resume.
    """
    from tqdm import tqdm

    sweep = load_sweep(spec)
    for name, value in (("--workers", workers), ("--max-runs", max_runs)):
        if value is not None and (isinstance(value, bool) or value < 1):
            raise PbvsError(f"{name}: expected a positive whole number, got {value}")
    if scheduler:
        probe_scheduler(scheduler)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with exclusive(out), _signals_as_stop() as stop:
        check_folder(sweep, out, force)
        table = ResultTable(out / TABLE)
        if retry_failed:
            table.remove({i for i, row in table.rows.items() if row.get("status") != "ok"})
        tasks = sweep.tasks(out / "logs" if sweep.save_logs else None)
        pending = [task for task in tasks if task.run_id not in table.rows]
        if max_runs is not None:
            pending = pending[:max_runs]
        unfinished: list = []
        with contextlib.ExitStack() as stack:
            if scheduler:
                make_executor, threads = stack.enter_context(dask_executor(scheduler))
                window = 2 * threads
            else:
                stack.enter_context(worker_environment())
                count = workers or os.cpu_count() or 1
                make_executor, window = (lambda: process_pool(count)), 2 * count
            done = sum(task.run_id in table.rows for task in tasks)
            bar = stack.enter_context(
                tqdm(
                    total=len(tasks),
                    initial=done,
                    desc=sweep.name,
                    unit="run",
                    disable=not progress,
                )
            )
            try:
                for row, timing in execute(make_executor, pending, window, unfinished, stop):
                    table.append(row)
                    append_timing(out / TIMINGS, timing)
                    bar.update(1)
                    if row["status"] != "ok":
                        bar.write(f"{row['run_id']} failed: {format_cell(row['reason'])[:200]}")
                if stop.is_set():
                    raise KeyboardInterrupt
            except KeyboardInterrupt:
                missing = sum(task.run_id not in table.rows for task in tasks)
                raise SweepIncomplete(str(out), missing, len(tasks), "interrupted") from None
        if table.rows:
            table.finalize(sweep.fields)
            write_parquet(table.path, out / "results.parquet")
            plot_sweep(table.path, out)
        if unfinished:
            cause = "a lost Dask scheduler or worker" if scheduler else "lost worker processes"
            reason = f"{cause}: {format_cell(unfinished[0][1])[:200]}"
            raise SweepIncomplete(str(out), len(unfinished), len(tasks), reason)
    return table.path


@contextlib.contextmanager
def _signals_as_stop() -> Iterator[threading.Event]:
    """An event that SIGTERM and SIGINT set; :func:`execute` stops at its next step.

    The sweep stops between steps, never inside one (a worker half started by the fork
    server would print a traceback). SIGINT is handled explicitly too, because a shell starts
    background jobs with it ignored.
    """
    stop = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def interrupt(signum: int, frame: object) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, interrupt) for sig in (signal.SIGTERM, signal.SIGINT)}
    try:
        yield stop
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
