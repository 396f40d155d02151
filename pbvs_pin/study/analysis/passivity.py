r"""Passivity of the servo loop over a run: the paper's §3.2-3.3, (9), (13)/(14) and (27).

Notation as in :mod:`pbvs_pin.study.analysis`; ``V1`` is the storage function of eq. (7),
``nu = J^T K_c(e) e`` and ``v~ = v - u`` the velocity-tracking error.

.. math::
    \int_0^T \nu^T [v + J^\# J_o \dot p]\, dt \ge -V_1(0) \quad (9),\qquad
    \int_0^T \nu^T \nu_{fb}\, dt \le \beta = V_1(0) + \beta_1 \quad (13)/(14)

    \int_0^T \nu^T \nu_{fb}\, dt \le V_1(0) + \int_0^T \nu^T \tilde v\, dt \quad (27)

with ``nu_fb`` the law's feedback term (``u = -nu_fb - J# J_o phat_dot + ...``): ``nu`` itself
for the paper's law, so that ``nu^T nu_fb = |nu|^2`` as the paper writes (13)-(27); ``H nu``
for the balanced law (:mod:`pbvs_pin.control.balanced`), whose controller draws the power
``nu^T H nu`` from the passive output instead.

**Which signals.** The inequalities are evaluated on one consistent set of signals,
:data:`SIGNAL_SETS` ``["true_state"]``: ``nu``, ``V1`` and the input ``v + J# J_o pdot`` all
from the true configuration, the true target position and velocity and the true robot's
``J``, ``J_o`` (:mod:`pbvs_pin.sim.log`). (9) rests on the identity
``dV1/dt = nu^T (v + J# J_o pdot)`` (``J J# = I``), which holds only when every term comes
from the same state. The controller's own signals (``["controller"]``: its last camera
measurement, stale between frames, noisy and, in Experiment 3, computed with a wrong
kinematic model) mixed with the true ``v`` and ``pdot`` break that identity; they are
evaluated too, as a separate diagnostic, never as the paper's claim.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pbvs_pin.study.analysis.signals import TOLERANCE, integrate

SIGNAL_SETS = {
    "true_state": ("nu_true", "passivity_input_true", "storage_true"),
    "controller": ("nu", "passivity_input", "storage"),
}
"""Log channels ``(nu, v + J# J_o pdot, V1)`` of each signal set."""

FEEDBACK_CHANNELS = {"true_state": "feedback_true", "controller": "feedback"}
"""The law's feedback term ``nu_fb`` of each set; a log without it (the paper's law, logs
written before the balanced law) counts ``nu``."""


def passivity_inequalities(
    t: np.ndarray,
    nu: np.ndarray,
    inputs: np.ndarray,
    storage: np.ndarray,
    velocity_error: np.ndarray,
    feedback: np.ndarray | None = None,
) -> dict[str, Any]:
    """Eqs. (9), (13)/(14) and (27) over the whole run, from one set of signals.

    In continuous time with ``J J# = I`` the supply equals ``V1(T) - V1(0)`` (the identity behind
    (9)), so the margin of (9) is ``V1(T)``, close to zero on a converged run: there sampling
    and the trapezoidal integration at the log rate decide the sign. ``identity_residual``
    (supply minus storage change) measures them.

    (13), ``-int nu^T [v + J# J_o pdot] >= -beta_1 + int ||nu||^2``, holds for every
    ``beta_1 >= int ||nu||^2 + int nu^T [v + J# J_o pdot]``; the smallest such ``beta_1 >= 0``
    is reported, and so is the perfect-tracking form ``beta_1 = 0`` (eq. 12), which the paper
    expects to fail once the velocity error enters (§3.3); (27) is its replacement.

    Args:
        t: Sample instants [s]. Shape (T,).
        nu: ``nu`` [controller units / s]. Shape (T, n).
        inputs: ``v + J# J_o pdot``. Shape (T, n).
        storage: ``V1`` [controller units / s]. Shape (T,).
        velocity_error: ``v - u`` [m/s, rad/s]. Shape (T, n).
        feedback: The law's feedback term ``nu_fb``; None: ``nu`` (the paper's law). Shape (T, n).

    Returns:
        ``passivity_9``, ``passivity_14`` and ``passivity_27``, both sides of each.
    """
    supply, dropped = integrate(t, np.sum(nu * inputs, axis=1))
    feedback = nu if feedback is None else feedback
    drawn, dropped_drawn = integrate(t, np.sum(nu * feedback, axis=1))
    cross, dropped_cross = integrate(t, np.sum(nu * velocity_error, axis=1))
    finite_storage = storage[np.isfinite(storage)]
    v1_0 = float(finite_storage[0]) if finite_storage.size else math.nan
    v1_t = float(finite_storage[-1]) if finite_storage.size else math.nan
    beta1 = max(0.0, drawn + supply)
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
            "lhs_integral_nu_feedback": drawn,
            "beta_1": beta1,
            "rhs_beta": beta,
            "holds": bool(drawn <= beta + slack),
            "perfect_tracking_rhs_V1_0": v1_0,
            "holds_with_beta_1_zero": bool(drawn <= v1_0 + slack),
            "dropped_samples": dropped_drawn,
        },
        "passivity_27": {
            "lhs_integral_nu_feedback": drawn,
            "integral_nu_velocity_error": cross,
            "rhs": v1_0 + cross,
            "holds": bool(drawn <= v1_0 + cross + slack),
            "dropped_samples": dropped_drawn + dropped_cross,
        },
    }


def passivity_of_log(channels: dict[str, np.ndarray], t: np.ndarray, which: str) -> dict:
    """:func:`passivity_inequalities` on one of :data:`SIGNAL_SETS`.

    Args:
        channels: A log's channels (``u``, ``v`` and the set's three channels).
        t: The log's sample instants [s]. Shape (T,).
        which: A key of :data:`SIGNAL_SETS`.
    """
    nu, inputs, storage = (np.asarray(channels[name], dtype=float) for name in SIGNAL_SETS[which])
    velocity_error = np.asarray(channels["v"], dtype=float) - np.asarray(channels["u"], dtype=float)
    feedback = channels.get(FEEDBACK_CHANNELS[which])
    if feedback is not None:
        feedback = np.asarray(feedback, dtype=float)
    return passivity_inequalities(t, nu, inputs, storage, velocity_error, feedback)
