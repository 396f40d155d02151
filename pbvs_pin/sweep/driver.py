"""A whole sweep: read the spec, lock the folder, run what is missing, write the outputs."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

from pbvs_pin.exceptions import PbvsError
from pbvs_pin.sweep.executors import dask_executor, execute, process_pool, worker_environment
from pbvs_pin.sweep.plots import plot_sweep
from pbvs_pin.sweep.spec import load_sweep
from pbvs_pin.sweep.table import (
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

    Raises:
        ScenarioError: If the spec is invalid, or ``out`` holds another sweep's results.
        PbvsError: If ``workers`` is not positive, the Dask scheduler cannot be reached, or
            another sweep is writing into ``out``.
    """
    from tqdm import tqdm

    sweep = load_sweep(spec)
    if workers is not None and workers < 1:
        raise PbvsError(f"--workers: expected a positive number of processes, got {workers}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with exclusive(out):
        check_folder(sweep, out)
        table = ResultTable(out / TABLE)
        if retry_failed:
            table.remove({i for i, row in table.rows.items() if row.get("status") != "ok"})
        tasks = sweep.tasks(out / "logs" if sweep.save_logs else None)
        pending = [task for task in tasks if task.run_id not in table.rows]
        if max_runs is not None:
            pending = pending[: max(0, max_runs)]
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
            if pending:
                for row, timing in execute(make_executor, pending, window):
                    table.append(row)
                    append_timing(out / TIMINGS, timing)
                    bar.update(1)
                    if row["status"] != "ok":
                        bar.write(f"{row['run_id']} failed: {format_cell(row['reason'])[:200]}")
        table.finalize(sweep.fields)
        write_parquet(table.path, out / "results.parquet")
        if table.rows:
            plot_sweep(table.path, out)
    return table.path
