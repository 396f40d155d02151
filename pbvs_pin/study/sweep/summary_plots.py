"""The two summary plots of a sweep, drawn from its results table (matplotlib, imported lazily)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pbvs_pin.study.sweep.table import read_table


def plot_sweep(table_path: Path, folder: Path) -> list[Path]:
    """Write the two summary plots of a sweep; return their paths.

    - ``final_error_vs_speed.png``: largest absolute feature error over the final window [px]
      against the target speed [m/s], failed runs marked.
    - ``bound_measured_vs_predicted.png``: measured sup ``||e||`` after t1 against the bound
      (39) [px], for the runs where (31) holds; the diagonal is ``measured = predicted``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = read_table(table_path)

    def numbers(rows: list[dict[str, Any]], x: str, y: str) -> tuple[list, list]:
        pairs = [(r.get(x), r.get(y)) for r in rows]
        pairs = [
            (a, b) for a, b in pairs if isinstance(a, int | float) and isinstance(b, int | float)
        ]
        return [a for a, _ in pairs], [b for _, b in pairs]

    paths = []
    fig, ax = plt.subplots(figsize=(6, 4))
    plotted = False
    for status, marker in (("ok", "o"), ("failed", "x")):
        x, y = numbers(
            [r for r in rows if r.get("status") == status],
            "target_speed_m_s",
            "max_abs_error_final_window_px",
        )
        if x:
            ax.scatter(x, y, marker=marker, label=f"{status} ({len(x)})")
            plotted = True
    if not plotted:
        ax.text(0.5, 0.5, "no run with a final error", ha="center", transform=ax.transAxes)
    ax.set_xlabel("target speed [m/s]")
    ax.set_ylabel("max |error|, final window [px]")
    ax.set_title("Final feature error vs target speed")
    ax.grid(alpha=0.3)
    if plotted:
        ax.legend(fontsize=8)
    fig.tight_layout()
    paths.append(folder / "final_error_vs_speed.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(5, 5))
    x, y = numbers(
        [r for r in rows if r.get("condition_31") is True],
        "bound39_predicted_px",
        "bound39_measured_sup_px",
    )
    if x:
        ax.loglog(x, y, "o", label=f"runs where (31) holds ({len(x)})")
        low = max(min(min(x), min(y)), 1e-6)
        high = max(max(x), max(y))
        ax.loglog([low, high], [low, high], "k--", linewidth=1, label="measured = predicted")
        ax.legend(fontsize=8)
    else:
        ax.text(0.5, 0.5, "no run where (31) holds", ha="center", transform=ax.transAxes)
    ax.set_xlabel("predicted bound (39) [px]")
    ax.set_ylabel("measured sup ||e|| after t1 [px]")
    ax.set_title("Ultimate bound: measured vs predicted")
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    paths.append(folder / "bound_measured_vs_predicted.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    return paths
