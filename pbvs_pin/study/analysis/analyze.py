"""All the analysis figures of one run's log, as a JSON-serialisable dict.

Composes :mod:`~pbvs_pin.study.analysis.motion_bounds` (eqs. (31)-(42)) and
:mod:`~pbvs_pin.study.analysis.passivity` (eqs. (9), (13)/(14)); notation in
:mod:`pbvs_pin.study.analysis`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pbvs_pin.exceptions import GainError, LogError, NonFiniteValue, PbvsError, WrongType
from pbvs_pin.sim.log import RunLog
from pbvs_pin.study.analysis.motion_bounds import bounds_after_t1, choose_t1
from pbvs_pin.study.analysis.passivity import SIGNAL_SETS, passivity_of_log
from pbvs_pin.study.analysis.signals import finite_max, gain_times_error
from pbvs_pin.validation import as_number, as_numbers

REQUIRED_CHANNELS = (
    "t",
    "xi_true",
    "xi_d",
    "u",
    "v",
    "lambda_min",
    "gamma",
    *SIGNAL_SETS["true_state"],
    *SIGNAL_SETS["controller"],
)
"""Log channels the analysis reads."""


META = {
    "scenario": ("a scenario name (text)", lambda v: isinstance(v, str) and v != ""),
    "robot": ("a robot name (text)", lambda v: isinstance(v, str) and v != ""),
    "feature_scale": ("a positive number [px]", lambda v: _positive(v) and np.ndim(v) == 0),
    "k": ("a list of positive numbers (the gains)", lambda v: isinstance(v, list) and _positive(v)),
}
"""Facts of a log's meta the analysis reads: key -> (what is expected, its test)."""


def _positive(value: object) -> bool:
    """Whether ``value`` is a finite positive number, or a non-empty list of them."""
    try:
        array = as_numbers("value", value)
    except PbvsError:
        return False
    return array.size > 0 and bool(np.all(np.isfinite(array) & (array > 0)))


def check_meta(log: RunLog, source: str) -> None:
    """Refuse a log whose meta lacks a fact the analysis reads, or holds a wrong one.

    Raises:
        LogError: Naming the file, the key and what was expected.
    """
    for key, (expected, valid) in META.items():
        if key not in log.meta:
            raise LogError(source, f"not a whole run log: its meta has no {key!r} ({expected})")
        if not valid(log.meta[key]):
            raise LogError(source, f"meta {key!r}: expected {expected}, got {log.meta[key]!r}")


def analyze_log(
    log: RunLog, epsilon: float = 0.5, t1: float | None = None, source: str = "log"
) -> dict[str, Any]:
    """The §4 robustness figures and the passivity inequalities of one run.

    Args:
        log: A run's log.
        epsilon: ``eps`` of eq. (31), ``0 < eps < 1``.
        t1: Start [s] of the ultimate-bound phase; None for the default rule
            (:mod:`pbvs_pin.study.analysis.motion_bounds`).
        source: Name of the log, for error messages and the report.

    Returns:
        A JSON-serialisable dict (non-finite numbers become None): ``lambda``, ``lambda_prime``,
        ``k_min``, ``t1_s``, ``gamma_inf``, ``condition_31``, ``bound_38``, ``bound_39``,
        ``l2_gain_42``; ``passivity_9``, ``passivity_14`` and ``passivity_27`` on the true-state
        signals (named in ``passivity_signals``); ``passivity_controller_signals``: the same
        three on the controller's own signals, a diagnostic (:mod:`.passivity`). Error figures
        in controller units and in pixels (``*_px``).

    Raises:
        WrongType: If ``log`` is not a RunLog, or ``epsilon`` or ``t1`` not a number.
        LogError: If the meta lacks a fact of :data:`META`, or holds a wrong one.
        GainError: If ``epsilon`` is not in (0, 1) or ``t1`` is outside the run.
        PbvsError: If a channel the analysis needs is missing.
        NonFiniteValue: If ``lambda_min`` holds no finite sample (the target was never seen).
    """
    if not isinstance(log, RunLog):
        raise WrongType("log", "a RunLog (RunLog.load of a run's log.npz)", log)
    epsilon = as_number("epsilon", epsilon)
    t1 = None if t1 is None else as_number("t1", t1)
    check_meta(log, source)
    if not 0.0 < epsilon < 1.0:
        raise GainError(f"epsilon: expected 0 < epsilon < 1 (eq. 31), got {epsilon}")
    missing = [name for name in REQUIRED_CHANNELS if name not in log.channels]
    if missing:
        raise PbvsError(f"{source}: channels {missing} missing; expected a log of pbvs-pin run")
    t = np.asarray(log["t"], dtype=float)
    scale = float(log.meta["feature_scale"])
    k = np.asarray(log.meta["k"], dtype=float)
    k_min = float(k.min())
    error = (np.asarray(log["xi_true"]) - np.asarray(log["xi_d"])) / scale
    error_norm = np.linalg.norm(error, axis=1)
    kc_error_norm = np.linalg.norm(gain_times_error(error, k), axis=1)
    gamma_norm = np.linalg.norm(np.asarray(log["gamma"], dtype=float), axis=1)
    lambda_samples = np.asarray(log["lambda_min"], dtype=float)
    if not np.any(np.isfinite(lambda_samples)):
        raise NonFiniteValue(f"{source}: lambda_min")

    # (31): lambda, lambda', k_min
    lam_index = int(np.nanargmin(lambda_samples))
    lam = float(lambda_samples[lam_index])
    lambda_prime = epsilon * lam

    # t1
    if t1 is None:
        start = choose_t1(kc_error_norm, gamma_norm, lambda_prime, k_min)
        rule = (
            "earliest t1 from which (31) holds and ||K_c e|| stays <= sup_[t1,T] ||gamma|| / "
            "lambda' (38); if none, earliest t1 from which (38) holds"
        )
    else:
        if not t[0] <= t1 <= t[-1]:
            raise GainError(f"t1: expected a time in [{t[0]:g}, {t[-1]:g}] s, got {t1}")
        start = int(np.searchsorted(t, t1))
        rule = "given"
    result: dict[str, Any] = {
        "log": source,
        "scenario": log.meta.get("scenario"),
        "robot": log.meta.get("robot"),
        "feature_scale_px": scale,
        "epsilon": epsilon,
        "duration_s": float(t[-1]),
        "samples": int(t.size),
        "lambda": lam,
        "lambda_at_s": float(t[lam_index]),
        "lambda_missing_samples": int(np.sum(~np.isfinite(lambda_samples))),
        "lambda_prime": lambda_prime,
        "k_min": k_min,
        "lambda_prime_k_min": lambda_prime * k_min,
        "gamma_inf_whole_run": finite_max(gamma_norm),
        "t1_rule": rule,
        "t1_s": None if start is None else float(t[start]),
    }
    if start is None:
        reason = (
            "no t1: ||K_c e|| never stays below sup ||gamma|| / lambda' until the end of the "
            "run, so the ultimate-bound phase of (38) is not reached"
            + (
                " (gamma = 0: the theory then promises only asymptotic convergence)"
                if not np.nanmax(gamma_norm, initial=0.0) > 0
                else ""
            )
        )
        result.update(
            gamma_inf=None,
            condition_31={"holds": None, "reason": reason},
            bound_38=None,
            bound_39={"reason": reason},
            l2_gain_42={"reason": reason},
        )
    else:
        result.update(
            bounds_after_t1(
                t, start, error, error_norm, kc_error_norm, gamma_norm, k, scale, lambda_prime
            )
        )
    result["condition_31"]["explanation"] = _explain_31(result, t, gamma_norm)
    result["passivity_signals"] = PASSIVITY_SIGNALS
    result.update(passivity_of_log(log.channels, t, "true_state"))
    result["passivity_controller_signals"] = {
        "signals": CONTROLLER_SIGNALS,
        **passivity_of_log(log.channels, t, "controller"),
    }
    return _jsonable(result)


PASSIVITY_SIGNALS = (
    "true state: nu, V1 and v + J# J_o pdot from the true configuration, target position and "
    "velocity, and the true robot's J and J_o"
)
"""How (9), (13)/(14) and (27) are evaluated (:mod:`.passivity`)."""

CONTROLLER_SIGNALS = (
    "diagnostic: the controller's nu, V1 and J from its last (stale, noisy, possibly wrong-model) "
    "measurement, with the true v and pdot"
)
"""How the diagnostic version of the passivity inequalities is evaluated."""


def _explain_31(result: dict[str, Any], t: np.ndarray, gamma_norm: np.ndarray) -> str:
    """Why (31) holds or fails, naming t1 and where ``||gamma||_inf`` and ``lambda`` occur."""
    start = result["t1_s"]
    lam_part = (
        f"lambda = {result['lambda']:.4g} at t = {result['lambda_at_s']:.2f} s, so lambda' k_min "
        f"= {result['lambda_prime_k_min']:.4g}"
    )
    if start is None:
        return f"{result['condition_31']['reason']}; {lam_part}"
    after = np.flatnonzero((t >= start) & np.isfinite(gamma_norm))
    peak = float(t[after[np.argmax(gamma_norm[after])]]) if after.size else start
    verdict = "holds" if result["condition_31"]["holds"] else "fails"
    above = np.flatnonzero(gamma_norm >= result["lambda_prime_k_min"])
    last = (
        f"; ||gamma|| >= lambda' k_min last at t = {t[above[-1]]:.2f} s of {t[-1]:.2f} s"
        if above.size
        else ""
    )
    return (
        f"(31) {verdict} with t1 = {start:.2f} s: sup ||gamma|| over [t1, T] = "
        f"{result['gamma_inf']:.4g}, reached at t = {peak:.2f} s; {lam_part}{last}"
    )


def _jsonable(value: Any) -> Any:
    """Plain Python types, non-finite floats as None."""
    if isinstance(value, dict):
        return {key: _jsonable(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(item) for item in value]
    if isinstance(value, np.bool_ | bool):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    return value
