"""Robustness sweeps: many runs of one scenario with some fields varied, one table of results.

One module per step of a sweep, imported in this order (each only from the ones above it):

- :mod:`~pbvs_pin.study.sweep.sampling`: run parameters from ``[grid]`` or ``[random]``.
- :mod:`~pbvs_pin.study.sweep.spec`: the TOML spec (format described there), run ids and seeds.
- :mod:`~pbvs_pin.study.sweep.runner`: one run (watchdog, divergence) and its table row.
- :mod:`~pbvs_pin.study.sweep.table`: ``results.csv``, ``timings.csv``, folder lock, resume.
- :mod:`~pbvs_pin.study.sweep.executors`: local process pool or Dask cluster, crash retries.
- :mod:`~pbvs_pin.study.sweep.summary_plots`: the two summary plots.
- :mod:`~pbvs_pin.study.sweep.driver`: :func:`run_sweep`, which ties them together.
"""

from pbvs_pin.study.sweep.driver import run_sweep
from pbvs_pin.study.sweep.runner import divergence, run_one
from pbvs_pin.study.sweep.spec import RunTask, SweepSpec, derive_seed, load_sweep, run_id_of
from pbvs_pin.study.sweep.table import TABLE, TIMINGS, read_table

__all__ = [
    "TABLE",
    "TIMINGS",
    "RunTask",
    "SweepSpec",
    "derive_seed",
    "divergence",
    "load_sweep",
    "read_table",
    "run_id_of",
    "run_one",
    "run_sweep",
]
