"""One run of a sweep: simulate, watch, analyse, and turn the outcome into a table row.

Runs in a worker process. A run's failure (invalid scenario value, exception, divergence,
timeout) is recorded in its row instead of raised. The timeout is checked by the run itself
at every logged instant (a watchdog observer of the simulation), so it works on every
executor.
"""

from __future__ import annotations

import math
import os
import socket
import time
from typing import Any

import numpy as np

from pbvs_pin.study.sweep.spec import RunTask

ANALYSIS_COLUMNS = (
    "lambda",
    "lambda_prime",
    "k_min",
    "t1_s",
    "gamma_inf",
    "condition_31",
    "bound39_predicted_px",
    "bound39_measured_sup_px",
    "bound39_holds",
    "l2_varsigma",
    "l2_zeta",
    "l2_measured_ratio",
    "l2_varsigma_squared",
    "l2_holds",
    "passivity9_lhs",
    "passivity9_rhs",
    "passivity9_holds",
    "passivity14_lhs",
    "passivity14_rhs",
    "passivity14_holds",
)
"""Analysis figures in the table (see :func:`pbvs_pin.study.analysis.analyze_log`)."""

TIMING_KEYS = ("wall_time_s", "real_time_factor")
"""Figures of ``summarize`` that depend on the machine; written to ``timings.csv``."""


class _RunTimeout(Exception):
    """Raised inside a run (never escapes it) when it exceeds the sweep's timeout."""


class _RunDiverged(Exception):
    """Raised inside a run (never escapes it) when its configuration becomes non-finite."""


def run_one(task: RunTask) -> tuple[dict[str, Any], dict[str, Any]]:
    """Simulate and analyse one run; never raises for a failing run.

    Runs in a worker process. Its row holds ``status = "failed"`` and the reason when the
    scenario is invalid, the simulation raises, diverges, or exceeds the timeout.

    Returns:
        The table row (JSON-able scalars and lists) and the timing row.
    """
    from pbvs_pin.sim.loop import simulate
    from pbvs_pin.sim.metrics import summarize
    from pbvs_pin.study.analysis import analyze_log

    started = time.perf_counter()
    row: dict[str, Any] = {
        "run_id": task.run_id,
        "status": "ok",
        "reason": "",
        "seed": task.seed,
        **task.params,
    }
    timing: dict[str, Any] = {
        "run_id": task.run_id,
        "worker": f"{socket.gethostname()}:{os.getpid()}",
    }

    def watchdog(snapshot: Any) -> None:
        elapsed = time.perf_counter() - started
        if elapsed > task.timeout:
            raise _RunTimeout(
                f"timeout: {elapsed:.1f} s > {task.timeout:g} s at simulated t = {snapshot.t:.2f} s"
            )
        if not np.all(np.isfinite(snapshot.q)):
            raise _RunDiverged(f"diverged: non-finite configuration at t = {snapshot.t:.2f} s")

    try:
        changes = dict(task.params)
        changes.setdefault("simulation.seed", task.seed)
        scenario = task.scenario.with_values(**changes)
        motion = scenario.motion
        speed = 0.0 if motion.kind == "still" else float(np.linalg.norm(motion.velocity))
        row["target_speed_m_s"] = speed
        log = simulate(scenario, observer=watchdog)
    except (_RunTimeout, _RunDiverged) as err:
        row.update(status="failed", reason=str(err))
        log = None
    except Exception as err:  # the sweep goes on whatever a run raises
        row.update(status="failed", reason=f"{type(err).__name__}: {err}")
        log = None
    if log is not None:
        diverged = divergence(log)
        if diverged:
            row.update(status="failed", reason=f"diverged: {diverged}")
        try:
            if task.log_dir is not None:
                log.save(task.log_dir)
            row.update(_summary_columns(summarize(log), timing))
            row.update(analysis_columns(analyze_log(log, task.epsilon, source=task.run_id)))
        except Exception as err:  # the run finished: keep its row, say what is missing
            note = f"analysis: {type(err).__name__}: {err}"
            row["reason"] = "; ".join(filter(None, [row["reason"], note]))
    timing["run_wall_time_s"] = time.perf_counter() - started
    return row, timing


def divergence(log: Any) -> str | None:
    """Why a finished run counts as diverged, or None.

    Diverged: a non-finite configuration or velocity, or at the last sample the target
    behind the camera or outside the image (the feature error then exceeds the image).
    """
    for name in ("q", "v"):
        bad = ~np.all(np.isfinite(log[name]), axis=tuple(range(1, np.ndim(log[name]))))
        if np.any(bad):
            return f"non-finite {name} from t = {float(log['t'][np.argmax(bad)]):.2f} s"
    final = np.asarray(log["xi_true"][-1], dtype=float)
    if not np.all(np.isfinite(final)):
        return "target behind the camera at the end"
    camera = log.meta.get("camera", {})
    width, height = camera.get("width", math.inf), camera.get("height", math.inf)
    # xi = [u1, v1, v2], centred on the principal point
    if abs(final[0]) > width / 2 or np.any(np.abs(final[1:]) > height / 2):
        return f"target outside the image at the end (xi = {np.round(final, 1).tolist()} px)"
    return None


def _summary_columns(summary: dict[str, Any], timing: dict[str, Any]) -> dict[str, Any]:
    """``summarize`` figures as flat columns; wall-clock figures moved to ``timing``."""
    columns: dict[str, Any] = {}
    for key, value in summary.items():
        if key in TIMING_KEYS:
            timing[key] = value
        elif isinstance(value, list | tuple):
            columns.update({f"{key}_{i}": item for i, item in enumerate(value)})
        else:
            columns[key] = value
    return columns


def analysis_columns(result: dict[str, Any]) -> dict[str, Any]:
    """The table's analysis columns (:data:`ANALYSIS_COLUMNS`) from an analysis dict."""
    b39, l2 = result.get("bound_39") or {}, result.get("l2_gain_42") or {}
    p9, p14 = result["passivity_9"], result["passivity_14"]
    values = {
        "lambda": result["lambda"],
        "lambda_prime": result["lambda_prime"],
        "k_min": result["k_min"],
        "t1_s": result["t1_s"],
        "gamma_inf": result["gamma_inf"],
        "condition_31": (result.get("condition_31") or {}).get("holds"),
        "bound39_predicted_px": b39.get("predicted_px"),
        "bound39_measured_sup_px": b39.get("measured_sup_px"),
        "bound39_holds": b39.get("holds"),
        "l2_varsigma": l2.get("varsigma"),
        "l2_zeta": l2.get("zeta"),
        "l2_measured_ratio": l2.get("measured_ratio"),
        "l2_varsigma_squared": l2.get("varsigma_squared"),
        "l2_holds": l2.get("holds"),
        "passivity9_lhs": p9["lhs_integral_nu_input"],
        "passivity9_rhs": p9["rhs_minus_V1_0"],
        "passivity9_holds": p9["holds"],
        "passivity14_lhs": p14["lhs_integral_nu_feedback"],
        "passivity14_rhs": p14["rhs_beta"],
        "passivity14_holds": p14["holds"],
    }
    return {column: values[column] for column in ANALYSIS_COLUMNS}
