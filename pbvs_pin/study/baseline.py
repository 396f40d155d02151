r"""The classic IBVS baseline: its gain rule and its comparison with the passivity law.

**Gain rule (stated).** Near the goal (``|e_i| << 1`` controller unit, ``K_c -> K = diag(k)``)
the passivity law (34) closes the loop ``e_dot = -J J^T K e`` (controller units, target
still), whose convergence rates are the eigenvalues of ``K J J^T``; the classic law closes
``e_dot = -lambda e``, every mode at rate ``lambda``. The baseline's ``lambda`` is the passivity
law's *mean* small-error rate,

.. math:: \lambda = \tfrac{1}{r}\,\mathrm{tr}\!\left(K J J^T\right),

with ``J`` (controller units, ``feature_scale`` px each) evaluated at the desired features
``xi_d``, from the scenario's initial configuration of the reference robot (the target placed
where its image is ``xi_d``). Both laws then contract the error volume at the same rate
(``d/dt ln det = -tr``). The rule is applied to Experiment 1 and the gain then fixed for all
experiments.

**Comparison.** Both laws get the same secondary objectives in the null space, the same
saturation, the same dynamics; the report gives the time at which the largest feature error
first stays below :data:`SETTLED_PX`, and the RMS feature error after the transient (the
figure of the run tables: :data:`pbvs_pin.sim.metrics.TRANSIENT`, the RMS over the samples of
the error vector's norm).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pbvs_pin.sim.log import AT_LIMIT, RunLog
from pbvs_pin.sim.metrics import TRANSIENT
from pbvs_pin.sim.scenario import Scenario, load_scenario

GAIN_RULE_SCENARIO = "experiment1"
"""The scenario the baseline's gain is computed on, then fixed for every experiment."""
SETTLED_PX = 10.0
"""Threshold [px] on the largest absolute feature error for 'time to reach'."""
GAIN_RULE = (
    "lambda = tr(K J J^T) / r, the passivity law's mean small-error convergence rate, with J "
    "(controller units) at the desired features from the initial configuration of Experiment 1 "
    "on the reference robot; fixed for all experiments"
)
"""The rule, as printed in the report."""


def matched_ibvs_gain(scenario: str | Scenario = GAIN_RULE_SCENARIO) -> float:
    """The baseline's ``lambda`` [1/s] by the rule of this module's docstring.

    Args:
        scenario: The scenario (name, path or loaded) whose robot, initial configuration,
            target, ``xi_d``, ``k`` and ``feature_scale`` are used.

    Returns:
        ``tr(K J J^T) / r`` [1/s].
    """
    from pbvs_pin.sim.setup import build, solve_target_start

    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    setup = build(scenario)
    q0 = setup.plant.q.copy()
    separation = setup.target.separation
    top = solve_target_start(setup.robot, q0, setup.features, separation, setup.xi_d)
    _, jacobian, _ = setup.features.jacobians(
        setup.robot, q0, top, top - np.array([0.0, 0.0, separation])
    )
    jacobian = jacobian / scenario.controller.feature_scale
    k = setup.law.feature_gains(jacobian.shape[0])
    return float(np.trace(np.diag(k) @ jacobian @ jacobian.T) / jacobian.shape[0])


def baseline_scenario(name: str | Scenario, gain: float) -> Scenario:
    """Scenario ``name`` with the classic IBVS law at gain ``gain`` [1/s]; objectives kept."""
    scenario = name if isinstance(name, Scenario) else load_scenario(name)
    return scenario.with_values(**{"controller.law": "ibvs", "controller.ibvs_gain": gain})


def comparison_figures(log: RunLog) -> dict[str, Any]:
    """Time to reach :data:`SETTLED_PX` and RMS error after the transient of one run.

    Args:
        log: A run's log (true features ``xi_true``, ``xi_d``, ``t``, ``clearance``).

    Returns:
        ``time_to_settle_s``: first time after which the largest absolute feature error
        stays below :data:`SETTLED_PX` until the end (None if it never does);
        ``rms_after_transient_px``: RMS over the samples after
        :data:`~pbvs_pin.sim.metrics.TRANSIENT` of the feature error's norm, as the run
        tables' ``rms_error_after_transient_px``; ``min_clearance_m`` (None without obstacles);
        ``saturated_samples``, the samples in which the limits cut the command (the law
        scaled ``u`` down, or the compensator clipped ``v_ref``:
        :func:`pbvs_pin.sim.log.command_limited`; the classic IBVS law reaches its limits
        through the compensation), and ``v_ref_at_limit_samples``, those in which a component
        of the commanded velocity ``v_ref`` sits at its limit
        (:data:`pbvs_pin.sim.log.AT_LIMIT`); ``feedback``, the run's ``controller.feedback``.
    """
    t = log["t"]
    largest = np.max(np.abs(log["xi_true"] - log["xi_d"]), axis=1)
    above = np.flatnonzero(~(largest < SETTLED_PX))
    if above.size == 0:
        settle: float | None = float(t[0])
    elif above[-1] == len(t) - 1:
        settle = None
    else:
        settle = float(t[above[-1] + 1])
    error = (log["xi_true"] - log["xi_d"])[t >= TRANSIENT]
    clearance = log["clearance"]
    finite = clearance[np.isfinite(clearance)]
    limits = np.asarray(log.meta["velocity_limits"], dtype=float)
    return {
        "time_to_settle_s": settle,
        "rms_after_transient_px": float(np.sqrt(np.nanmean(np.sum(error**2, axis=1)))),
        "min_clearance_m": float(finite.min()) if finite.size else None,
        "saturated_samples": int(np.count_nonzero(log["saturated"])),
        "v_ref_at_limit_samples": int(
            np.count_nonzero(np.any(np.abs(log["v_ref"]) >= AT_LIMIT * limits, axis=1))
        ),
        "feedback": log.meta.get("feedback", "transpose"),
    }


def baseline_section(pairs: list[tuple[str, dict, dict]], gain: float) -> str:
    """Markdown: both laws per experiment, figures of :func:`comparison_figures`.

    Args:
        pairs: ``(experiment, passivity figures, IBVS figures)`` per experiment.
        gain: The baseline's ``lambda`` [1/s].
    """
    lines = [
        "",
        f"## Passivity law against the classic IBVS baseline (lambda = {gain:.3g} /s)",
        "",
        "u = -lambda J# e - J# J_o phat_dot + (I - J# J) k1 tanh(k2 Lambda), in the same compiled "
        "step as the passivity law: the same null-space objectives, upright row, joint stops, "
        "loop-gain net, saturation and dynamics. Gain rule: " + GAIN_RULE + ".",
        "",
        f"| experiment | law | time to max abs error < {SETTLED_PX:g} px for good [s] | "
        f"RMS error after {TRANSIENT:g} s [px] | min clearance [m] | command limited "
        "[samples] | v_ref at a limit [samples] | better RMS |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, passivity, ibvs in pairs:
        better = "passivity" if passivity["rms_after_transient_px"] < ibvs[
            "rms_after_transient_px"] else "IBVS"  # fmt: skip
        for law, figures in (("passivity", passivity), ("IBVS", ibvs)):
            settle, clearance = figures["time_to_settle_s"], figures["min_clearance_m"]
            lines.append(
                f"| {name} | {law} | {'never' if settle is None else f'{settle:.2f}'} | "
                f"{figures['rms_after_transient_px']:.2f} | "
                f"{'-' if clearance is None else f'{clearance:.3f}'} | "
                f"{figures['saturated_samples']} | {figures['v_ref_at_limit_samples']} | "
                f"{better} |"
            )
    return "\n".join(lines) + "\n"
