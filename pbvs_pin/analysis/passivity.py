r"""Passivity of the servo loop over a run: the paper's §3.2, inequalities (9) and (13)/(14).

Notation as in :mod:`pbvs_pin.analysis`: ``nu`` and the passivity input
``v + J^# J_o pdot`` are logged by the simulation, with the storage function ``V1`` of eq. (7).

.. math::
    \int_0^T \nu^T [v + J^\# J_o \dot p]\, dt \ge -V_1(0) \quad (9),\qquad
    \int_0^T \|\nu\|^2 dt \le \beta = V_1(0) + \beta_1 \quad (13)/(14)
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pbvs_pin.analysis.signals import TOLERANCE, integrate
from pbvs_pin.sim.log import RunLog


def passivity_inequalities(log: RunLog, t: np.ndarray) -> dict[str, Any]:
    """Eqs. (9) and (13)/(14) over the whole run, from the logged ``nu``, input and ``V1``.

    In continuous time with ``J J# = I`` the supply equals ``V1(T) - V1(0)`` (the identity behind
    (9)), so the margin of (9) is ``V1(T)``, close to zero on a converged run: there the camera's
    sample-and-hold, measurement noise and the trapezoidal integration at the log rate decide
    the sign. ``identity_residual`` (supply minus storage change) measures them.

    (13), ``-int nu^T [v + J# J_o pdot] >= -beta_1 + int ||nu||^2``, holds for every
    ``beta_1 >= int ||nu||^2 + int nu^T [v + J# J_o pdot]``; the smallest such ``beta_1 >= 0``
    is used (zero under the perfect tracking of (12)). With it, (14) is equivalent to (9); the
    perfect-tracking form ``int ||nu||^2 <= V1(0)`` is reported too.

    Args:
        log: A run's log with the channels ``nu``, ``passivity_input`` and ``storage``.
        t: The log's sample instants [s]. Shape (T,).

    Returns:
        ``passivity_9`` and ``passivity_14`` of :func:`pbvs_pin.analysis.analyze_log`.
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
