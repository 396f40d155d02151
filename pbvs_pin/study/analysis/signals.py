r"""Sampled-signal helpers of the analysis: ``K_c(e) e`` of eq. (8), integrals, running maxima.

Shared by :mod:`~pbvs_pin.study.analysis.motion_bounds`,
:mod:`~pbvs_pin.study.analysis.passivity` and :mod:`~pbvs_pin.study.analysis.bound_plots`.
Samples logged as NaN (no measurement) are skipped or given an explicit value, as each function
says.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

TOLERANCE = 1e-9
"""Relative slack of the inequality checks (floating-point rounding of the integrals)."""


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


def suffix_max(values: np.ndarray, missing: float) -> np.ndarray:
    """``out[i] = max(values[i:])`` with non-finite entries replaced by ``missing``.

    Args:
        values: Samples. Shape (T,).
        missing: Value that stands for a non-finite sample.

    Returns:
        The running maximum from each sample to the end. Shape (T,).
    """
    clean = np.where(np.isfinite(values), values, missing)
    return np.maximum.accumulate(clean[::-1])[::-1]


def finite_max(values: np.ndarray) -> float | None:
    """Largest finite entry of ``values``, or None when there is none."""
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else None
