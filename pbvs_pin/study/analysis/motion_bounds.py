r"""Robustness of the servo to the target's motion: the paper's §4, eqs. (31)-(42).

Notation as in :mod:`pbvs_pin.study.analysis` (controller units): ``e`` the true feature error,
``K_c(e) e`` of eq. (8), ``gamma = J_o (pdot - phat_dot)`` of eq. (31).

.. math::
    \lambda = \min_t \lambda_{min}(J J^T),\quad \lambda' = \varepsilon\lambda,\quad
    k_{min} = \min_i k_i,\quad
    \|\gamma\|_\infty = \sup_{t\in[t_1,T]}\|\gamma(t)\| < \lambda' k_{min} \quad (31)

    \|K_c(e)\, e\| \le \|\gamma\|_\infty / \lambda' \quad (38),\qquad
    \|e(t)\| \le \frac{\|\gamma\|_\infty}{\lambda' k_{min} - \|\gamma\|_\infty} \quad (39)

    \int_{t_1}^T \|e\|^2 dt \le \varsigma^2 \int_{t_1}^T \|\gamma\|^2 dt + \zeta,\quad
    \varsigma = \frac{1}{\lambda' k_{min} - \|\gamma\|_\infty},\quad
    \zeta = \lambda'\varsigma^2 V_1(t_1) \quad (42)

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

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from pbvs_pin.control.kinematic import storage_function
from pbvs_pin.study.analysis.signals import TOLERANCE, finite_max, integrate, suffix_max


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
    stays = suffix_max(np.asarray(kc_error_norm, dtype=float), math.inf)
    gamma_sup = suffix_max(np.asarray(gamma_norm, dtype=float), 0.0)

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


def bounds_after_t1(
    t: np.ndarray,
    start: int,
    error: np.ndarray,
    error_norm: np.ndarray,
    kc_error_norm: np.ndarray,
    gamma_norm: np.ndarray,
    k: np.ndarray,
    scale: float,
    lambda_prime: float,
) -> dict[str, Any]:
    """Eqs. (31), (38), (39) and (42) on ``[t1, T]``.

    Args:
        t: Sample instants [s]. Shape (T,).
        start: Index of t1.
        error: True feature error ``e`` [controller units]. Shape (T, r).
        error_norm: ``||e||`` per sample. Shape (T,).
        kc_error_norm: ``||K_c(e) e||`` per sample. Shape (T,).
        gamma_norm: ``||gamma||`` per sample. Shape (T,).
        k: ``k_i`` [1/s]. Shape (r,).
        scale: Pixels per controller unit.
        lambda_prime: ``lambda' = eps lambda``.

    Returns:
        ``gamma_inf``, ``condition_31``, ``bound_38``, ``bound_39`` and ``l2_gain_42`` of
        :func:`pbvs_pin.study.analysis.analyze_log`.
    """
    k_min = float(k.min())
    after = slice(start, None)
    gamma_inf = finite_max(gamma_norm[after]) or 0.0
    holds_31 = gamma_inf < lambda_prime * k_min
    kc_bound = gamma_inf / lambda_prime
    above = kc_error_norm[after] > kc_bound * (1 + TOLERANCE)
    entry = np.flatnonzero(kc_error_norm <= kc_bound)
    measured_sup = finite_max(error_norm[after])
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
            "measured_sup_kc_error": finite_max(kc_error_norm[after]),
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
