r"""Robustness and L2-gain figures of a run: the paper's §4, eqs. (30)-(42), and §3.2, (9)-(14).

Everything is computed from a :class:`~pbvs_pin.sim.log.RunLog`, in the controller's feature
units (``meta["feature_scale"]`` px each, DESIGN.md §3), the units in which the proofs hold;
error bounds are also given in pixels. Notation (controller units):

- ``e = (xi_true - xi_d) / feature_scale``: the *true* feature error (the physical error, as in
  :func:`pbvs_pin.sim.metrics.summarize`), shape (T, r).
- ``K_c(e) e``, with ``K_c(e) = diag(k_i / (1 + |e_i|))`` (eq. 8), shape (T, r).
- ``gamma = J_o (pdot - phat_dot)`` (eq. 31), logged by the simulation, shape (T, r).

The quantities:

.. math::
    \lambda = \min_t \lambda_{min}(J J^T),\quad \lambda' = \varepsilon\lambda,\quad
    k_{min} = \min_i k_i,\quad
    \|\gamma\|_\infty = \sup_{t\in[t_1,T]}\|\gamma(t)\| < \lambda' k_{min} \quad (31)

    \|K_c(e)\, e\| \le \|\gamma\|_\infty / \lambda' \quad (38),\qquad
    \|e(t)\| \le \frac{\|\gamma\|_\infty}{\lambda' k_{min} - \|\gamma\|_\infty} \quad (39)

    \int_{t_1}^T \|e\|^2 dt \le \varsigma^2 \int_{t_1}^T \|\gamma\|^2 dt + \zeta,\quad
    \varsigma = \frac{1}{\lambda' k_{min} - \|\gamma\|_\infty},\quad
    \zeta = \lambda'\varsigma^2 V_1(t_1) \quad (42)

    \int_0^T \nu^T [v + J^\# J_o \dot p]\, dt \ge -V_1(0) \quad (9),\qquad
    \int_0^T \|\nu\|^2 dt \le \beta = V_1(0) + \beta_1 \quad (13)/(14)

The paper's ``lambda`` is an infimum over every ``q`` and ``xi``; here it is the minimum along
the run (samples without a measurement, logged as NaN, are ignored), which is what the run's
bound can use.

**Choice of t1.** The paper only says that (38) holds "for a finite t1" and assumes (31) on
``[t1, T]``. By default t1 is the first logged instant from which both hold: (31), and
``||K_c e||`` staying at or below ``||gamma||_inf / lambda'`` (38), where ``||gamma||_inf`` is
itself the supremum over ``[t1, T]``. The definition is circular, so t1 is a least fixed point,
found by a monotone iteration (:func:`choose_t1`). This skips the estimator's start-up transient
(the alpha-beta filter starts from zero velocity, so ``gamma`` is large for a few tenths of a
second) and any later transient (the abrupt stop of Experiment 1) that (31) cannot cover. When
(31) holds on no final interval, t1 is the first instant from which (38) alone holds, and the
report says that (31) fails. When there is no such instant either (e.g. ``gamma = 0`` with an
exact estimator, where the theory only promises asymptotic convergence), t1 is ``None`` and the
figures "after t1" are not computed. A caller may give t1 instead.

With the default t1, (38) holds after t1 by construction, and (39) then follows from it
algebraically (``||K_c e|| >= k_min ||e|| / (1 + ||e||)``), so the measured-versus-predicted
comparison checks the bound's arithmetic and units; t1 itself, ``t_enter`` (first entry into
the ball of (38)) and the L2 ratio of (42) carry the information. With a given t1 the
comparison is a real test of the theory.

What ``gamma`` leaves out: the paper's analysis assumes perfect velocity tracking (``v = u``),
continuous noise-free measurements and exact models. The velocity-tracking error, the camera's
sampling, latency and noise, and model errors act as further disturbances (the paper notes that
``v - u`` belongs in ``gamma``); the log does not hold ``J``, so they are not added here, and a
run with them may exceed a bound computed from ``gamma`` alone.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from pbvs_pin.control.kinematic import storage_function
from pbvs_pin.exceptions import GainError, NonFiniteValue, PbvsError
from pbvs_pin.sim.log import RunLog

REQUIRED_CHANNELS = (
    "t",
    "xi_true",
    "xi_d",
    "lambda_min",
    "gamma",
    "nu",
    "passivity_input",
    "storage",
)
"""Log channels the analysis reads."""

TOLERANCE = 1e-9
"""Relative slack of the inequality checks (floating-point rounding of the integrals)."""


# ----------------------------------------------------------------------------- kernels
def gain_times_error(error_units: npt.ArrayLike, k: npt.ArrayLike) -> npt.NDArray[np.float64]:
    r"""``K_c(e) e`` of eq. (8), row by row.

    .. math:: [K_c(e)\, e]_i = \frac{k_i\, e_i}{1 + |e_i|}

    Args:
        error_units: Feature error in controller units. Shape (T, r) or (r,).
        k: ``k_i`` [1/s]. Shape (r,).

    Returns:
        ``K_c(e) e`` [controller units / s], same shape as ``error_units``.
    """
    error = np.asarray(error_units, dtype=float)
    return np.asarray(k, dtype=float) * error / (1.0 + np.abs(error))


def min_eigenvalue_jjt(jacobian: npt.ArrayLike) -> float:
    """``lambda_min(J J^T)`` of one Jacobian (the quantity behind eq. (31)'s ``lambda``).

    Args:
        jacobian: ``J`` in controller units. Shape (r, n).
    """
    jacobian = np.asarray(jacobian, dtype=float)
    return float(np.linalg.eigvalsh(jacobian @ jacobian.T)[0])


def ultimate_bound(gamma_inf: float, lambda_prime: float, k_min: float) -> float | None:
    r"""Eq. (39): the ultimate bound on ``||e||`` [controller units], or None if (31) fails.

    .. math:: \|e\| \le \frac{\|\gamma\|_\infty}{\lambda' k_{min} - \|\gamma\|_\infty}
    """
    margin = lambda_prime * k_min - gamma_inf
    return gamma_inf / margin if margin > 0 else None


def integrate(t: npt.ArrayLike, values: npt.ArrayLike) -> tuple[float, int]:
    """Trapezoidal integral of a sampled signal, dropping non-finite samples.

    Args:
        t: Sample instants [s]. Shape (T,).
        values: Integrand. Shape (T,).

    Returns:
        The integral, and how many samples were dropped (the trapezoid bridges them).
    """
    t = np.asarray(t, dtype=float)
    values = np.asarray(values, dtype=float)
    finite = np.isfinite(values)
    if finite.sum() < 2:
        return 0.0, int((~finite).sum())
    return float(np.trapezoid(values[finite], t[finite])), int((~finite).sum())


def _suffix_max(values: np.ndarray, missing: float) -> np.ndarray:
    """``out[i] = max(values[i:])`` with non-finite entries replaced by ``missing``."""
    clean = np.where(np.isfinite(values), values, missing)
    return np.maximum.accumulate(clean[::-1])[::-1]


def choose_t1(
    kc_error_norm: npt.ArrayLike,
    gamma_norm: npt.ArrayLike,
    lambda_prime: float,
    k_min: float,
) -> int | None:
    """Index of the default t1 (see the module docstring), or None when there is none.

    With ``a = ||K_c e||`` (a missing sample counts as infinite: never below a bound) and
    ``g = ||gamma||`` (a missing sample is ignored), ``G(i) = max(g[i:])``, t1 is the least fixed
    point ``i = f(i)`` of ``f(i) = min{j >= i : max(a[j:]) <= G(i) / lambda'}`` that is not
    before the first index from which (31) holds, ``G(i) < lambda' k_min``. ``f`` is monotone
    (``G`` does not increase), so iterating it from that index reaches the least such fixed
    point. If there is none, the least fixed point from index 0 is returned (then (31) fails at
    t1); if there is none either, None.

    Args:
        kc_error_norm: ``||K_c(e) e||`` per sample. Shape (T,).
        gamma_norm: ``||gamma||`` per sample. Shape (T,).
        lambda_prime: ``lambda' = eps lambda``.
        k_min: Smallest ``k_i`` [1/s].
    """
    stays = _suffix_max(np.asarray(kc_error_norm, dtype=float), math.inf)
    gamma_sup = _suffix_max(np.asarray(gamma_norm, dtype=float), 0.0)

    def least_fixed_point(index: int) -> int | None:
        while True:
            below = np.flatnonzero(stays[index:] <= gamma_sup[index] / lambda_prime)
            if below.size == 0:
                return None
            if below[0] == 0:
                return index
            index += int(below[0])

    holds_31 = np.flatnonzero(gamma_sup < lambda_prime * k_min)
    if holds_31.size:
        found = least_fixed_point(int(holds_31[0]))
        if found is not None:
            return found
    return least_fixed_point(0)


# ----------------------------------------------------------------------------- the analysis
def analyze_log(
    log: RunLog, epsilon: float = 0.5, t1: float | None = None, source: str = "log"
) -> dict[str, Any]:
    """The §4 robustness figures and the passivity inequalities of one run.

    Args:
        log: A run's log.
        epsilon: ``eps`` of eq. (31), ``0 < eps < 1``.
        t1: Start [s] of the ultimate-bound phase; None for the default rule (module docstring).
        source: Name of the log, for error messages and the report.

    Returns:
        A JSON-serialisable dict (non-finite numbers become None): ``lambda``, ``lambda_prime``,
        ``k_min``, ``t1_s``, ``gamma_inf``, ``condition_31``, ``bound_38``, ``bound_39``,
        ``l2_gain_42``, ``passivity_9`` and ``passivity_14``; error figures in controller units
        and in pixels (``*_px``).

    Raises:
        GainError: If ``epsilon`` is not in (0, 1) or ``t1`` is outside the run.
        PbvsError: If a channel the analysis needs is missing.
        NonFiniteValue: If ``lambda_min`` holds no finite sample (the target was never seen).
    """
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
        "gamma_inf_whole_run": _finite_max(gamma_norm),
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
            _after_t1(
                t, start, error, error_norm, kc_error_norm, gamma_norm, k, scale, lam, lambda_prime
            )
        )
    result.update(_passivity(log, t))
    return _jsonable(result)


def _after_t1(
    t: np.ndarray,
    start: int,
    error: np.ndarray,
    error_norm: np.ndarray,
    kc_error_norm: np.ndarray,
    gamma_norm: np.ndarray,
    k: np.ndarray,
    scale: float,
    lam: float,
    lambda_prime: float,
) -> dict[str, Any]:
    """Eqs. (31), (38), (39) and (42) on ``[t1, T]``."""
    k_min = float(k.min())
    after = slice(start, None)
    gamma_inf = _finite_max(gamma_norm[after]) or 0.0
    holds_31 = gamma_inf < lambda_prime * k_min
    kc_bound = gamma_inf / lambda_prime
    above = kc_error_norm[after] > kc_bound * (1 + TOLERANCE)
    entry = np.flatnonzero(kc_error_norm <= kc_bound)
    measured_sup = _finite_max(error_norm[after])
    out: dict[str, Any] = {
        "gamma_inf": gamma_inf,
        "condition_31": {
            "holds": bool(holds_31),
            "gamma_inf": gamma_inf,
            "lambda_prime_k_min": lambda_prime * k_min,
            "margin": lambda_prime * k_min - gamma_inf,
        },
        "bound_38": {
            "kc_error_bound": kc_bound,
            "measured_sup_kc_error": _finite_max(kc_error_norm[after]),
            "samples_above_after_t1": int(np.sum(above | ~np.isfinite(kc_error_norm[after]))),
            "t_enter_s": float(t[entry[0]]) if entry.size else None,
        },
    }
    bound = ultimate_bound(gamma_inf, lambda_prime, k_min)
    measured = {
        "measured_sup_units": measured_sup,
        "measured_sup_px": None if measured_sup is None else measured_sup * scale,
        "measured_final_px": float(error_norm[-1] * scale),
        "missing_samples_after_t1": int(np.sum(~np.isfinite(error_norm[after]))),
    }
    if bound is None:
        reason = (
            f"condition (31) fails: ||gamma||_inf = {gamma_inf:.4g} >= lambda' k_min = "
            f"{lambda_prime * k_min:.4g}, so (39) gives no bound and (42) no L2 gain"
        )
        out["bound_39"] = {"reason": reason, **measured}
        out["l2_gain_42"] = {"reason": reason}
        return out
    out["bound_39"] = {
        "predicted_units": bound,
        "predicted_px": bound * scale,
        **measured,
        "holds": bool(measured_sup is not None and measured_sup <= bound * (1 + TOLERANCE)),
    }
    varsigma = 1.0 / (lambda_prime * k_min - gamma_inf)
    v1_t1 = storage_function(error[start], k) if np.all(np.isfinite(error[start])) else math.nan
    zeta = lambda_prime * varsigma**2 * v1_t1
    error_sq, dropped_e = integrate(t[after], error_norm[after] ** 2)
    gamma_sq, dropped_g = integrate(t[after], gamma_norm[after] ** 2)
    rhs = varsigma**2 * gamma_sq + zeta
    out["l2_gain_42"] = {
        "varsigma": varsigma,
        "varsigma_squared": varsigma**2,
        "zeta": zeta,
        "V1_t1": v1_t1,
        "integral_error_sq": error_sq,
        "integral_gamma_sq": gamma_sq,
        "measured_ratio": error_sq / gamma_sq if gamma_sq > 0 else None,
        "rhs": rhs,
        "holds": bool(error_sq <= rhs * (1 + TOLERANCE)),
        "dropped_samples": dropped_e + dropped_g,
    }
    return out


def _passivity(log: RunLog, t: np.ndarray) -> dict[str, Any]:
    """Eqs. (9) and (13)/(14) over the whole run, from the logged ``nu``, input and ``V1``.

    In continuous time with ``J J# = I`` the supply equals ``V1(T) - V1(0)`` (the identity behind
    (9)), so the margin of (9) is ``V1(T)``, close to zero on a converged run: there the camera's
    sample-and-hold, measurement noise and the trapezoidal integration at the log rate decide
    the sign. ``identity_residual`` (supply minus storage change) measures them.

    (13), ``-int nu^T [v + J# J_o pdot] >= -beta_1 + int ||nu||^2``, holds for every
    ``beta_1 >= int ||nu||^2 + int nu^T [v + J# J_o pdot]``; the smallest such ``beta_1 >= 0``
    is used (zero under the perfect tracking of (12)). With it, (14) is equivalent to (9); the
    perfect-tracking form ``int ||nu||^2 <= V1(0)`` is reported too.
    """
    nu = np.asarray(log["nu"], dtype=float)
    inputs = np.asarray(log["passivity_input"], dtype=float)
    storage = np.asarray(log["storage"], dtype=float)
    supply, dropped = integrate(t, np.sum(nu * inputs, axis=1))
    nu_sq, dropped_nu = integrate(t, np.sum(nu * nu, axis=1))
    finite_storage = storage[np.isfinite(storage)]
    v1_0 = float(finite_storage[0]) if finite_storage.size else math.nan
    v1_t = float(finite_storage[-1]) if finite_storage.size else math.nan
    beta1 = max(0.0, nu_sq + supply)
    beta = v1_0 + beta1
    slack = TOLERANCE * max(abs(v1_0), abs(supply), 1e-12)
    return {
        "passivity_9": {
            "lhs_integral_nu_input": supply,
            "rhs_minus_V1_0": -v1_0,
            "holds": bool(supply >= -v1_0 - slack),
            "V1_0": v1_0,
            "V1_T_minus_V1_0": v1_t - v1_0,
            "margin_V1_T": v1_t,
            "identity_residual": supply - (v1_t - v1_0),
            "dropped_samples": dropped,
        },
        "passivity_14": {
            "lhs_integral_nu_sq": nu_sq,
            "beta_1": beta1,
            "rhs_beta": beta,
            "holds": bool(nu_sq <= beta + slack),
            "perfect_tracking_rhs_V1_0": v1_0,
            "holds_with_beta_1_zero": bool(nu_sq <= v1_0 + slack),
            "dropped_samples": dropped_nu,
        },
    }


def _finite_max(values: np.ndarray) -> float | None:
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else None


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


# ----------------------------------------------------------------------------- files
def analyze_run(
    path: Path, epsilon: float = 0.5, out: Path | None = None, t1: float | None = None
) -> dict[str, Any]:
    """Analyse a saved run; with ``out``, also write the report and the plots.

    Args:
        path: A run's ``log.npz`` or the folder holding it.
        epsilon: ``eps`` of eq. (31), ``0 < eps < 1``.
        out: Folder for ``analysis.json``, ``analysis.md`` and the PNG plots (created); None
            to write nothing.
        t1: Start [s] of the ultimate-bound phase; None for the default rule.

    Returns:
        The figures of :func:`analyze_log`, plus ``files`` (paths written) when ``out`` is given.

    Raises:
        PbvsError: If there is no readable log at ``path``.
        GainError: If ``epsilon`` or ``t1`` is out of range.
        NonFiniteValue: If the run never measured the target.
    """
    path = Path(path)
    log_file = path / "log.npz" if path.is_dir() else path
    if not log_file.is_file():
        raise PbvsError(
            f"{path}: no run log here (expected a log.npz of pbvs-pin run, or its folder)"
        )
    try:
        log = RunLog.load(log_file)
    except (OSError, ValueError, KeyError) as err:
        raise PbvsError(f"{log_file}: not a readable run log ({err})") from err
    result = analyze_log(log, epsilon, t1, str(log_file))
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        files = [out / "analysis.json", out / "analysis.md"]
        files[1].write_text(report_markdown(result))
        files += plot_analysis(log, result, out)
        result["files"] = [str(f) for f in files]
        files[0].write_text(json.dumps(result, indent=2))
    return result


def _fmt(value: Any, digits: int = 4) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def report_markdown(result: dict[str, Any]) -> str:
    """The analysis as a markdown page (both sides of every inequality).

    Norms are written ``‖x‖`` so that their bars do not split the table's cells.
    """
    r = result
    b39, l2 = r["bound_39"], r["l2_gain_42"]
    p9, p14 = r["passivity_9"], r["passivity_14"]
    c31 = r["condition_31"]
    rows = [
        (
            "lambda = min_t lambda_min(J J^T) (controller units)",
            f"{_fmt(r['lambda'])} (at t = {_fmt(r['lambda_at_s'])} s)",
        ),
        ("lambda' = eps lambda", _fmt(r["lambda_prime"])),
        ("k_min [1/s]", _fmt(r["k_min"])),
        ("lambda' k_min", _fmt(r["lambda_prime_k_min"])),
        ("t1 [s]", _fmt(r["t1_s"])),
        ("sup ||gamma|| over the whole run", _fmt(r["gamma_inf_whole_run"])),
        ("||gamma||_inf over [t1, T]", _fmt(r["gamma_inf"])),
        ("condition (31): ||gamma||_inf < lambda' k_min", _fmt(c31.get("holds"))),
    ]
    if "predicted_px" in b39:
        rows += [
            (
                "(39) predicted bound on ||e||",
                f"{_fmt(b39['predicted_px'])} px ({_fmt(b39['predicted_units'])} units)",
            ),
            (
                "measured sup ||e|| after t1",
                f"{_fmt(b39['measured_sup_px'])} px ({_fmt(b39['measured_sup_units'])} units)",
            ),
            ("(39) holds", _fmt(b39["holds"])),
        ]
    if "varsigma" in l2:
        rows += [
            ("varsigma, zeta of (42)", f"{_fmt(l2['varsigma'])}, {_fmt(l2['zeta'])}"),
            (
                "measured int ||e||^2 / int ||gamma||^2 vs varsigma^2",
                f"{_fmt(l2['measured_ratio'])} vs {_fmt(l2['varsigma_squared'])}",
            ),
            (
                "(42): int ||e||^2 <= varsigma^2 int ||gamma||^2 + zeta",
                f"{_fmt(l2['integral_error_sq'])} <= {_fmt(l2['rhs'])}: {_fmt(l2['holds'])}",
            ),
        ]
    rows += [
        ("(9): int nu^T (v + J# J_o pdot) dt >= -V1(0)",
         f"{_fmt(p9['lhs_integral_nu_input'])} >= {_fmt(p9['rhs_minus_V1_0'])}: "
         f"{_fmt(p9['holds'])}"),
        ("V1(T) - V1(0); identity residual int nu^T (...) dt - (V1(T) - V1(0))",
         f"{_fmt(p9['V1_T_minus_V1_0'])}; {_fmt(p9['identity_residual'])}"),
        ("(13)/(14): int ||nu||^2 dt <= beta = V1(0) + beta_1",
         f"{_fmt(p14['lhs_integral_nu_sq'])} <= {_fmt(p14['rhs_beta'])} "
         f"(beta_1 = {_fmt(p14['beta_1'])}): {_fmt(p14['holds'])}"),
        ("(14) with beta_1 = 0 (perfect tracking): int ||nu||^2 dt <= V1(0)",
         f"{_fmt(p14['lhs_integral_nu_sq'])} <= {_fmt(p14['perfect_tracking_rhs_V1_0'])}: "
         f"{_fmt(p14['holds_with_beta_1_zero'])}"),
    ]  # fmt: skip
    lines = [
        f"# Robustness and L2-gain analysis: {r['scenario']} ({r['robot']})",
        "",
        f"Log: `{r['log']}`. Controller unit: {r['feature_scale_px']:g} px; "
        f"epsilon = {r['epsilon']:g}; t1 rule: {r['t1_rule']}.".replace("||", "‖"),
        "",
        "| quantity | value |",
        "|---|---|",
        *(f"| {q} | {v} |".replace("||", "‖") for q, v in rows),
    ]
    for part in (c31, b39, l2):
        if part and "reason" in part:
            lines += ["", f"Note: {part['reason']}."]
            break
    lines += [
        "",
        "gamma = J_o (pdot - phat_dot) covers the target-velocity estimation error only; the "
        "velocity-tracking error, camera sampling, latency and noise are further disturbances "
        "that the paper's bound does not include.",
        "",
        "The margin of (9) is V1(T) (the supply equals V1(T) - V1(0) in continuous time), near "
        "zero once the error has converged; the camera's sample-and-hold, measurement noise and "
        "the integration at the log rate then decide its sign (see the identity residual). "
        "(14) with the smallest beta_1 of (13) is equivalent to (9).",
    ]
    return "\n".join(lines) + "\n"


def plot_analysis(log: RunLog, result: dict[str, Any], folder: Path) -> list[Path]:
    """Write ``bound.png``, ``gamma.png`` and ``storage.png``; return their paths.

    - ``bound.png``: measured ``||e(t)||`` [px] against the predicted bound (39) from t1, and
      the running bound computed with ``sup_[t, T] ||gamma||``.
    - ``gamma.png``: ``||gamma(t)||`` with ``||gamma||_inf`` and ``lambda' k_min`` (31); and
      ``||K_c e||`` against ``||gamma||_inf / lambda'`` (38).
    - ``storage.png``: ``V1(t)``, the supply ``int nu^T (v + J# J_o pdot)`` against ``-V1(0)``
      (9), and ``int ||nu||^2`` against ``beta`` (14).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.asarray(log["t"], dtype=float)
    scale = result["feature_scale_px"]
    k = np.asarray(log.meta["k"], dtype=float)
    error = (np.asarray(log["xi_true"]) - np.asarray(log["xi_d"])) / scale
    error_px = np.linalg.norm(error, axis=1) * scale
    gamma_norm = np.linalg.norm(np.asarray(log["gamma"], dtype=float), axis=1)
    kc_norm = np.linalg.norm(gain_times_error(error, k), axis=1)
    lambda_prime, k_min, t1 = result["lambda_prime"], result["k_min"], result["t1_s"]
    paths = []

    fig, ax = plt.subplots(figsize=(7, 3.4))
    ax.semilogy(t, error_px, label="measured ||e(t)|| (true features)", linewidth=1.2)
    running = _suffix_max(gamma_norm, 0.0)
    margin = lambda_prime * k_min - running
    with np.errstate(divide="ignore", invalid="ignore"):
        running_bound = np.where(margin > 0, running / margin * scale, np.nan)
    ax.semilogy(
        t,
        running_bound,
        "--",
        color="tab:gray",
        linewidth=1,
        label="(39) with sup over [t, T] of ||gamma||",
    )
    if "predicted_px" in result["bound_39"]:
        ax.hlines(
            result["bound_39"]["predicted_px"],
            t1,
            t[-1],
            color="tab:red",
            label="(39) predicted bound after t1",
        )
    if t1 is not None:
        ax.axvline(t1, color="k", linestyle=":", linewidth=1, label="t1")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("||xi - xi_d|| [px]")
    ax.set_title("Ultimate bound (39): predicted vs measured")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    paths.append(folder / "bound.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    top.plot(t, gamma_norm, label="||gamma(t)||", linewidth=1.2)
    top.axhline(lambda_prime * k_min, color="tab:red", label="lambda' k_min (31)")
    if result["gamma_inf"] is not None:
        top.hlines(
            result["gamma_inf"], t1, t[-1], color="tab:green", label="||gamma||_inf over [t1, T]"
        )
    top.set_ylabel("controller units / s")
    top.set_title("Disturbance gamma = J_o (pdot - phat_dot)")
    bottom.semilogy(t, kc_norm, label="||K_c(e) e||", linewidth=1.2)
    if result["gamma_inf"] is not None:
        bottom.hlines(
            result["gamma_inf"] / lambda_prime,
            t1,
            t[-1],
            color="tab:red",
            label="||gamma||_inf / lambda' (38)",
        )
    bottom.set_xlabel("time [s]")
    bottom.set_ylabel("controller units / s")
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
        if t1 is not None:
            ax.axvline(t1, color="k", linestyle=":", linewidth=1)
    fig.tight_layout()
    paths.append(folder / "gamma.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    nu = np.asarray(log["nu"], dtype=float)
    supply = np.nan_to_num(np.sum(nu * np.asarray(log["passivity_input"], dtype=float), axis=1))
    nu_sq = np.nan_to_num(np.sum(nu * nu, axis=1))
    cumulative = np.concatenate([[0.0], np.cumsum(0.5 * (supply[1:] + supply[:-1]) * np.diff(t))])
    cumulative_sq = np.concatenate([[0.0], np.cumsum(0.5 * (nu_sq[1:] + nu_sq[:-1]) * np.diff(t))])
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ax.plot(t, log["storage"], label="V1(t) (7)", linewidth=1.2)
    ax.plot(t, cumulative, label="int_0^t nu^T (v + J# J_o pdot) (9)", linewidth=1.2)
    ax.axhline(
        -result["passivity_9"]["V1_0"],
        color="tab:red",
        linestyle="--",
        label="-V1(0): lower bound of (9)",
    )
    ax.plot(t, cumulative_sq, label="int_0^t ||nu||^2 (14)", linewidth=1.2)
    ax.axhline(
        result["passivity_14"]["rhs_beta"],
        color="tab:purple",
        linestyle="--",
        label="beta: upper bound of (14)",
    )
    ax.set_xlabel("time [s]")
    ax.set_ylabel("controller units")
    ax.set_title("Storage and passivity inequalities")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    paths.append(folder / "storage.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    return paths
