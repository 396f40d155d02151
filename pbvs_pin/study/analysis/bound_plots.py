"""The analysis plots: ``bound.png`` (39), ``gamma.png`` (31)/(38), ``storage.png`` (9)/(14).

Matplotlib is imported lazily (Agg backend), so that the analysis imports fast and works
headless.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pbvs_pin.sim.log import RunLog
from pbvs_pin.study.analysis.passivity import SIGNAL_SETS
from pbvs_pin.study.analysis.signals import gain_times_error, suffix_max


def plot_analysis(log: RunLog, result: dict[str, Any], folder: Path) -> list[Path]:
    """Write ``bound.png``, ``gamma.png`` and ``storage.png``; return their paths.

    - ``bound.png``: measured ``||e(t)||`` [px] against the predicted bound (39) from t1, and
      the running bound computed with ``sup_[t, T] ||gamma||``.
    - ``gamma.png``: ``||gamma(t)||`` with ``||gamma||_inf`` and ``lambda' k_min`` (31); and
      ``||K_c e||`` against ``||gamma||_inf / lambda'`` (38).
    - ``storage.png``: ``V1(t)``, the supply ``int nu^T (v + J# J_o pdot)`` against ``-V1(0)``
      (9), and ``int ||nu||^2`` against ``beta`` (14), on the true-state signals
      (:data:`pbvs_pin.study.analysis.passivity.SIGNAL_SETS`).
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

    fig, ax = plt.subplots(figsize=(7, 4.0))
    ax.semilogy(t, error_px, label="measured ||e(t)|| (true features)", linewidth=1.2)
    running = suffix_max(gamma_norm, 0.0)
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
    # below the axes: inside, it covered the first second of the measured error
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2)
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

    nu_name, input_name, storage_name = SIGNAL_SETS["true_state"]
    nu = np.asarray(log[nu_name], dtype=float)
    supply = np.nan_to_num(np.sum(nu * np.asarray(log[input_name], dtype=float), axis=1))
    nu_sq = np.nan_to_num(np.sum(nu * nu, axis=1))
    cumulative = np.concatenate([[0.0], np.cumsum(0.5 * (supply[1:] + supply[:-1]) * np.diff(t))])
    cumulative_sq = np.concatenate([[0.0], np.cumsum(0.5 * (nu_sq[1:] + nu_sq[:-1]) * np.diff(t))])
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ax.plot(t, log[storage_name], label="V1(t) (7)", linewidth=1.2)
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
    ax.set_title(
        f"Storage and passivity inequalities (true state): {result['scenario']}, "
        f"{result['robot']}"
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    paths.append(folder / "storage.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    return paths
