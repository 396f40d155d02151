"""Matplotlib figures of a run, in the style of the paper's Figs. 7-23.

matplotlib is imported inside the functions so that the control core never loads it; the
Agg backend is used, so figures are written without a display.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pbvs_pin.sim.log import RunLog


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _series(
    path: Path, t: np.ndarray, values: np.ndarray, labels: list[str], title: str, unit: str
) -> Path:
    """One time-series figure with a line per column."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 3.2))
    for column, label in zip(np.atleast_2d(values.T), labels, strict=True):
        ax.plot(t, column, label=label, linewidth=1.2)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(unit)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_run(log: RunLog, folder: str | Path) -> list[Path]:
    """Write the paper's figures for one run as PNG files; return their paths.

    Feature errors (px), platform commands, arm joint commands, estimated target speed, and
    the stroboscopic motion of robot and target (X-Y and X-Z).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    t = log["t"]
    names = log.meta["velocity_names"]
    n_base = 2 if names[:2] == ["u", "omega"] else (3 if names[:1] == ["vx"] else 0)
    error = log["xi_true"] - log["xi_d"]
    paths = [
        _series(folder / "feature_errors.png", t, error, ["u1", "v1", "v2"],
                "Feature errors", "error [px]"),
        _series(folder / "platform_commands.png", t, log["u"][:, :n_base], names[:n_base],
                "Platform velocity commands", "[m/s], [rad/s]"),
        _series(folder / "arm_commands.png", t, log["u"][:, n_base:], names[n_base:],
                "Arm joint velocity commands", "[rad/s]"),
        _series(folder / "target_speed.png", t,
                np.column_stack([np.linalg.norm(log["target_velocity_estimate"], axis=1),
                                 np.linalg.norm(log["target_velocity"], axis=1)]),
                ["estimated", "true"], "Target speed", "[m/s]"),
    ]  # fmt: skip
    paths.append(_stroboscope(log, folder / "motion_xyz.png"))
    return paths


def _stroboscope(log: RunLog, path: Path, instants: int = 7) -> Path:
    """Platform and target positions at a few instants, top and side views."""
    plt = _pyplot()
    q, target = log["q"], log["target"]
    fig, (top, side) = plt.subplots(1, 2, figsize=(10, 4))
    top.plot(q[:, 0], q[:, 1], color="tab:red", label="platform")
    top.plot(target[:, 0], target[:, 1], color="tab:blue", label="target")
    side.plot(target[:, 0], target[:, 2], color="tab:blue", label="target")
    for index in np.linspace(0, len(q) - 1, instants).astype(int):
        heading = np.arctan2(q[index, 3], q[index, 2])
        top.arrow(q[index, 0], q[index, 1], 0.2 * np.cos(heading), 0.2 * np.sin(heading),
                  width=0.01, color="tab:red")  # fmt: skip
        top.plot(*target[index, :2], "o", color="tab:blue")
        top.annotate(f"{log['t'][index]:.0f}s", target[index, :2], fontsize=7)
        side.plot(target[index, 0], target[index, 2], "o", color="tab:blue")
    for obstacle in log.meta.get("obstacles", []):
        if obstacle["kind"] == "circle":
            top.add_patch(plt.Circle((obstacle["x"], obstacle["y"]), obstacle["radius"],
                                     color="grey", alpha=0.6))  # fmt: skip
        else:
            top.add_patch(plt.Rectangle(
                (obstacle["x"] - obstacle["size_x"] / 2, obstacle["y"] - obstacle["size_y"] / 2),
                obstacle["size_x"], obstacle["size_y"], color="grey", alpha=0.6))  # fmt: skip
    top.set(xlabel="X [m]", ylabel="Y [m]", title="Top view (X-Y)", aspect="equal")
    side.set(xlabel="X [m]", ylabel="Z [m]", title="Side view (X-Z)")
    for ax in (top, side):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
