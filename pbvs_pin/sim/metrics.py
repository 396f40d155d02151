"""Figures of merit of a run, written to ``summary.json`` beside its log.

Besides the error figures, every summary carries the flags a reader needs before trusting
them (:func:`summarize`):

- **target lost**: samples with ``target_lost`` set, and the first such time;
- **joints past limits**: the largest excursion of an arm joint beyond its position limits
  (``meta["arm_position_limits"]``) [rad or m], 0 when none (a continuous joint has none);
- **collision**: the smallest platform clearance < 0;
- **sustained oscillation**: the part of the true feature error above
  :data:`OSCILLATION_CUTOFF_HZ`, RMS over the worst :data:`FINAL_WINDOW`-long window after
  the transient (:func:`oscillation_rms`);
- **detection** (a rendered camera): frames in which the target projects inside the image
  but is not detected, and the detection error (detected minus projected) RMS and maximum;
- **saturation**: the fraction of samples in which the velocity limits cut the command (the
  law scaled ``u`` down, or the compensator clipped ``v_ref``:
  :func:`pbvs_pin.sim.log.command_limited`), and the fraction in which some ``v_ref``
  component sits at its limit.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # the rules' constants load without the log's modules (claims, the CLI)
    from pbvs_pin.sim.log import RunLog

FINAL_WINDOW = 5.0
"""Length [s] of the window at the end of a run over which the final error is taken."""

TRANSIENT = 2.0
"""Time [s] after which errors count as 'throughout' (the initial transient excluded)."""

OSCILLATION_CUTOFF_HZ = 0.5
"""Cut-off [Hz] of the high-pass filter that isolates the oscillating part of the error."""

OSCILLATION_FLAG_PX = 2.0
"""Oscillation RMS [px] above which a run is flagged as oscillating."""

def summarize(log: RunLog) -> dict[str, Any]:
    """Acceptance figures and flags of one run (pixels, metres, radians, seconds).

    Returns:
        JSON-serialisable figures: the largest absolute feature error over the final window
        and after the transient, the final error, its RMS after the transient, the smallest
        platform clearance, the arm's distance from the maximum-manipulability posture over
        the final window, the frames the innovation gate rejected and the estimator's
        restarts (:class:`pbvs_pin.control.gating.FaultCounts`; None for a log without them),
        the storage function's increase and decrease after the transient,
        the velocity-tracking error ``|v - u|`` (RMS of the Euclidean norm in SI units, and
        per platform/arm part), the odometry drift at the end and the platform's slip
        (:func:`pbvs_pin.sim.log.sensing_meta`; None for a log without them), and the flags
        of the module docstring.
    """
    from pbvs_pin.sim.log import AT_LIMIT

    t = log["t"]
    error = log["xi_true"] - log["xi_d"]
    final = t >= t[-1] - FINAL_WINDOW
    after = t >= TRANSIENT
    posture = np.asarray(log.meta["posture_target"])
    storage = log["storage"][after]
    increases = np.diff(storage[np.isfinite(storage)])
    lost = np.asarray(log["target_lost"], dtype=bool)
    oscillation, window_start = oscillation_rms(t, error)
    tracking = log["v"] - log["u"]
    n_base = len(log["v"][0]) - len(posture)
    limits = np.asarray(log.meta["velocity_limits"], dtype=float)
    drift, slip = log.meta.get("odometry_drift", {}), log.meta.get("slip", {})
    counts = log.meta.get("controller_counts", {})  # control.gating.FaultCounts
    return {
        "scenario": log.meta["scenario"],
        "robot": log.meta["robot"],
        "law": log.meta["law"],
        "feedback": log.meta.get("feedback", "transpose"),
        "engine": log.meta.get("engine", "pinocchio"),
        "compensation": log.meta.get("compensation"),
        "duration_s": float(t[-1]),
        "image_height_px": int(log.meta["camera"]["height"]),
        "max_abs_error_final_window_px": _max(error[final]),
        "max_abs_error_after_transient_px": _max(error[after]),
        "rms_error_after_transient_px": _rms(np.linalg.norm(error[after], axis=1)),
        "final_abs_error_px": np.abs(error[-1]).round(3).tolist(),
        "min_clearance_m": _min(log["clearance"]),
        "posture_error_final_window_rad": _max(
            posture_error(log["arm"][final], posture, log.meta.get("arm_continuous"))
        ),
        "storage_increase_after_transient": float(np.sum(np.maximum(increases, 0.0))),
        "storage_decrease_after_transient": float(-np.sum(np.minimum(increases, 0.0))),
        "velocity_tracking_rms": _rms(np.linalg.norm(tracking, axis=1)),
        "velocity_tracking_rms_platform": _rms(np.linalg.norm(tracking[:, :n_base], axis=1)),
        "velocity_tracking_rms_arm": _rms(np.linalg.norm(tracking[:, n_base:], axis=1)),
        "saturated_fraction": float(np.mean(log["saturated"])),
        "v_ref_at_limit_fraction": float(
            np.mean(np.any(np.abs(log["v_ref"]) >= AT_LIMIT * limits, axis=1))
        ),
        "damped_fraction": float(np.mean(log["damped"])),
        "target_lost_samples": int(np.sum(lost)),
        "target_lost_first_s": float(t[np.argmax(lost)]) if lost.any() else None,
        "frames_gated": counts.get("frames_gated"),
        "estimator_restarts": counts.get("restarts"),
        "joint_limit_violation": joint_limit_violation(log),
        "oscillation_rms_px": oscillation,
        "oscillation_window_start_s": window_start,
        "odometry_drift_m": drift.get("position"),
        "odometry_drift_rad": drift.get("heading"),
        "lateral_slip_rms_mps": slip.get("lateral_speed_rms"),
        "yaw_rate_ratio": slip.get("yaw_rate_ratio"),
        **detection_summary(log.meta.get("detection")),
        "wall_time_s": float(log.meta["wall_time"]),
        "real_time_factor": float(t[-1] / max(log.meta["wall_time"], 1e-9)),
    }


def detection_summary(meta: dict[str, Any] | None) -> dict[str, Any]:
    """Figures of a rendered camera's detections for a run's summary.

    Args:
        meta: ``meta["detection"]`` of the log
            (:meth:`pbvs_pin.sim.rendered_camera.RenderedCamera.detection_meta`).

    Returns:
        ``detection_frames``; ``detection_missed_frames`` (both centres projected inside the
        image, not detected: occluded, or refused); ``detection_error_rms_px`` and
        ``detection_error_max_px`` over the detected points' ``[du, dv]``;
        ``detection_diameter_error_rms_px``. All None for the point camera (``meta`` None).
    """
    names = (
        "detection_frames", "detection_missed_frames", "detection_error_rms_px",
        "detection_error_max_px", "detection_diameter_error_rms_px",
    )  # fmt: skip
    if meta is None:
        return dict.fromkeys(names)
    errors = np.array(
        [[np.nan if x is None else x for x in row] for row in meta["error_px"]], dtype=float
    ).reshape(-1, 6)
    detected = np.asarray(meta["detected"], dtype=bool)
    inside = np.asarray(meta["projected_inside"], dtype=bool)
    points, diameters = errors[detected, :4], errors[detected, 4:]
    found = points.size > 0
    return dict(
        zip(
            names,
            (
                len(detected),
                int(np.sum(inside & ~detected)),
                float(np.sqrt(np.mean(points**2))) if found else None,
                float(np.max(np.abs(points))) if found else None,
                float(np.sqrt(np.mean(diameters**2))) if found else None,
            ),
            strict=True,
        )
    )


def oscillation_rms(t: np.ndarray, error: np.ndarray) -> tuple[float, float | None]:
    """RMS of the error's part above :data:`OSCILLATION_CUTOFF_HZ` over its worst window.

    Method: the feature error after :data:`TRANSIENT` (samples without a finite value are
    filled by linear interpolation) is high-passed per component by a 4th-order Butterworth
    filter at 0.5 Hz, run forward and backward (``scipy.signal.sosfiltfilt``, zero phase).
    The norm of the filtered error over the components, squared, is averaged over every
    window of :data:`FINAL_WINDOW` seconds (a moving mean); the largest mean's square root is
    the result. A steady offset or a slow drift gives about 0; a limit cycle of amplitude
    ``a`` px in one feature gives about ``a / sqrt(2)``.

    Args:
        t: Sample instants [s], uniformly spaced. Shape (T,).
        error: Feature error [px]. Shape (T, r).

    Returns:
        The RMS [px] and the start [s] of the worst window; ``(0.0, None)`` when the run
        after the transient is shorter than a window.
    """
    after = t >= TRANSIENT
    times, values = t[after], np.asarray(error, dtype=float)[after]
    if times.size < 2 or times[-1] - times[0] < FINAL_WINDOW:
        return 0.0, None
    rate = 1.0 / float(np.median(np.diff(times)))
    filled = np.empty_like(values)
    for j in range(values.shape[1]):
        finite = np.isfinite(values[:, j])
        if not finite.any():
            return 0.0, None
        filled[:, j] = np.interp(times, times[finite], values[finite, j])
    from scipy import signal

    sos = signal.butter(4, OSCILLATION_CUTOFF_HZ, "highpass", fs=rate, output="sos")
    high = signal.sosfiltfilt(sos, filled, axis=0)
    width = max(1, round(FINAL_WINDOW * rate))
    power = np.convolve(np.sum(high**2, axis=1), np.ones(width) / width, mode="valid")
    worst = int(np.argmax(power))
    return float(np.sqrt(power[worst])), float(times[worst])


def posture_error(
    arm: np.ndarray, posture: np.ndarray, continuous: list[bool] | None
) -> np.ndarray:
    """The arm's distance from ``posture`` per sample and joint [rad or m].

    A continuous joint's is the shortest way round, in ``[-pi, pi)``
    (:func:`pbvs_pin.model.joint_angles.arm_difference`): an angle and the same angle plus ``2 pi``
    are one posture.

    Args:
        arm: Arm positions. Shape (T, n_arm).
        posture: The posture target. Shape (n_arm,).
        continuous: Whether each joint is continuous (``meta["arm_continuous"]``); None
            (a log written before it was recorded): none is.

    Returns:
        Shape (T, n_arm).
    """
    error = np.asarray(arm, dtype=float) - posture
    wrapped = np.zeros(error.shape[1], dtype=bool) if continuous is None else np.array(continuous)
    error[:, wrapped] = np.mod(error[:, wrapped] + np.pi, 2.0 * np.pi) - np.pi
    return error


def joint_limit_violation(log: RunLog) -> float | None:
    """Largest excursion of an arm joint beyond its position limits [rad or m]; 0 if none.

    None when the log does not record the limits.
    """
    limits = log.meta.get("arm_position_limits")
    if limits is None:
        return None
    lower, upper = (np.array([np.nan if x is None else x for x in side]) for side in limits)
    arm = np.asarray(log["arm"], dtype=float)
    below = np.nan_to_num(lower - arm, nan=0.0)
    above = np.nan_to_num(arm - upper, nan=0.0)
    return float(max(0.0, below.max(initial=0.0), above.max(initial=0.0)))


def _rms(values: np.ndarray) -> float:
    finite = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(finite**2))) if finite.size else float("nan")


def _max(values: np.ndarray) -> float:
    finite = np.abs(values[np.isfinite(values)])
    return float(finite.max()) if finite.size else float("nan")


def _min(values: np.ndarray) -> float | None:
    finite = values[np.isfinite(values)]
    return float(finite.min()) if finite.size else None
