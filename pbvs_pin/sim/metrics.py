"""Figures of merit of a run, written to ``summary.json`` beside its log."""

from __future__ import annotations

from typing import Any

import numpy as np

from pbvs_pin.sim.log import RunLog

FINAL_WINDOW = 5.0
"""Length [s] of the window at the end of a run over which the final error is taken."""

TRANSIENT = 2.0
"""Time [s] after which errors count as 'throughout' (the initial transient excluded)."""


def summarize(log: RunLog) -> dict[str, Any]:
    """Acceptance figures of one run (pixels, metres, radians, seconds).

    Returns:
        JSON-serialisable figures: the largest absolute feature error over the final window
        and after the transient, the final error, the smallest platform clearance, the arm's
        distance from the maximum-manipulability posture over the final window, whether the
        storage function decreased after the transient, and counts of saturated, damped and
        target-lost samples.
    """
    t = log["t"]
    error = log["xi_true"] - log["xi_d"]
    final = t >= t[-1] - FINAL_WINDOW
    after = t >= TRANSIENT
    posture = np.asarray(log.meta["posture_target"])
    storage = log["storage"][after]
    increases = np.diff(storage[np.isfinite(storage)])
    return {
        "scenario": log.meta["scenario"],
        "robot": log.meta["robot"],
        "law": log.meta["law"],
        "duration_s": float(t[-1]),
        "max_abs_error_final_window_px": _max(error[final]),
        "max_abs_error_after_transient_px": _max(error[after]),
        "final_abs_error_px": np.abs(error[-1]).round(3).tolist(),
        "min_clearance_m": _min(log["clearance"]),
        "posture_error_final_window_rad": _max(log["arm"][final] - posture),
        "storage_increase_after_transient": float(np.sum(np.maximum(increases, 0.0))),
        "storage_decrease_after_transient": float(-np.sum(np.minimum(increases, 0.0))),
        "saturated_fraction": float(np.mean(log["saturated"])),
        "damped_fraction": float(np.mean(log["damped"])),
        "target_lost_samples": int(np.sum(log["target_lost"])),
        "wall_time_s": float(log.meta["wall_time"]),
        "real_time_factor": float(t[-1] / max(log.meta["wall_time"], 1e-9)),
    }


def _max(values: np.ndarray) -> float:
    finite = np.abs(values[np.isfinite(values)])
    return float(finite.max()) if finite.size else float("nan")


def _min(values: np.ndarray) -> float | None:
    finite = values[np.isfinite(values)]
    return float(finite.min()) if finite.size else None
