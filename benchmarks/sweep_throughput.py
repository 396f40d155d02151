"""Sweep throughput: runs per minute against the number of worker processes.

Each repeat runs a fresh sweep (new output folder, so nothing is resumed) of ``--runs`` short
Experiment-1 runs that differ only in the filter gain alpha, on a local process pool; the wall
time includes starting the pool, as a user would see it. Prints, per worker count, the median
over the repeats (and the range), the speed-up over one worker, and the median time of one
run inside its worker (which grows when the workers contend for the cores)::

    python benchmarks/sweep_throughput.py                  # 1, 2, ... cpu_count workers
    python benchmarks/sweep_throughput.py --workers 1 2 4 --runs 12 --repeats 5 --dask
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from pbvs_pin.study.sweep import read_table, run_sweep


def write_spec(folder: Path, runs: int, duration: float) -> Path:
    """A grid of ``runs`` alpha values on Experiment 1, ``duration`` seconds each."""
    alphas = ", ".join(f"{a:.6f}" for a in np.linspace(0.3, 0.7, runs))
    path = folder / "throughput.toml"
    path.write_text(
        '[sweep]\nname = "throughput"\nscenario = "experiment1"\nseed = 0\n'
        f'[fixed]\nduration = {duration}\n[grid]\n"estimator.alpha" = [{alphas}]\n'
    )
    return path


def one_sweep(spec: Path, workers: int, scheduler: str | None = None) -> tuple[float, float]:
    """Wall time [s] of one complete sweep into a fresh folder, and its median run time [s]."""
    with tempfile.TemporaryDirectory() as out:
        started = time.perf_counter()
        table = run_sweep(spec, Path(out), scheduler, workers, progress=False)
        elapsed = time.perf_counter() - started
        failed = [row for row in read_table(table) if row["status"] != "ok"]
        if failed:
            raise RuntimeError(f"benchmark runs failed: {failed[0]['reason']}")
        runs = [row["run_wall_time_s"] for row in read_table(Path(out) / "timings.csv")]
    return elapsed, statistics.median(runs)


def main() -> None:
    """Parse the options, run the sweeps, print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cpus = os.cpu_count() or 1
    parser.add_argument("--workers", type=int, nargs="+", default=list(range(1, cpus + 1)))
    parser.add_argument("--runs", type=int, default=16, help="runs per sweep")
    parser.add_argument("--duration", type=float, default=30.0, help="simulated s per run")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--dask", action="store_true", help="also a Dask LocalCluster")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as folder:
        spec = write_spec(Path(folder), args.runs, args.duration)
        results = []
        for workers in args.workers:
            times = [one_sweep(spec, workers) for _ in range(args.repeats)]
            results.append((f"process pool, {workers}", times))
            print(f"  {workers} worker(s): {', '.join(f'{t:.1f}' for t, _ in times)} s", flush=True)
        if args.dask:
            from distributed import LocalCluster

            for workers in args.workers:
                with LocalCluster(
                    n_workers=workers,
                    threads_per_worker=1,
                    processes=True,
                    host="127.0.0.1",
                    dashboard_address=None,
                ) as cluster:
                    address = cluster.scheduler_address
                    times = [one_sweep(spec, workers, address) for _ in range(args.repeats)]
                results.append((f"dask LocalCluster, {workers}", times))
                print(f"  dask {workers}: {', '.join(f'{t:.1f}' for t, _ in times)} s", flush=True)

    print(
        f"\n{args.runs} runs of {args.duration:g} s simulated per sweep, {args.repeats} repeats, "
        f"{cpus} CPUs, load average {os.getloadavg()[0]:.2f}"
    )
    header = f"{'executor, workers':<24}{'sweep wall [s]':>15}{'runs/min':>10}"
    header += f"{'range runs/min':>16}{'speed-up':>10}{'one run [s]':>13}"
    print(header)
    print("-" * len(header))
    baseline = None
    for label, pairs in results:
        times = [t for t, _ in pairs]
        median = statistics.median(times)
        rate = 60.0 * args.runs / median
        low, high = 60.0 * args.runs / max(times), 60.0 * args.runs / min(times)
        baseline = baseline or rate
        per_run = statistics.median(r for _, r in pairs)
        print(
            f"{label:<24}{median:>15.2f}{rate:>10.1f}{f'{low:.1f}-{high:.1f}':>16}"
            f"{rate / baseline:>10.2f}{per_run:>13.2f}"
        )
    print(
        "sweep wall: whole sweep, pool start-up included (a LocalCluster is started before "
        "and kept across repeats); one run: median wall time of a run inside its worker"
    )


if __name__ == "__main__":
    main()
