"""Matplotlib figures of a run, in the style of the paper's Figs. 7-23.

Titles name the robot, experiment and law; legends sit outside the axes, off the data.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pbvs_pin.sim.log import RunLog
from pbvs_pin.viz.plotting import pyplot, run_title
from pbvs_pin.viz.stroboscope import DEFAULT_FOOTPRINT, plot_stroboscope


def _series(
    path: Path, t: np.ndarray, values: np.ndarray, labels: list[str], title: str, unit: str
) -> Path:
    """One time-series figure with a line per column, its legend right of the axes."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 3.4))
    for column, label in zip(np.atleast_2d(values.T), labels, strict=True):
        ax.plot(t, column, label=label, linewidth=1.2)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(unit)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_run(
    log: RunLog, folder: str | Path, footprint: tuple[float, float] = DEFAULT_FOOTPRINT
) -> list[Path]:
    """Write the paper's figures for one run as PNG files; return their paths.

    Feature errors (px), platform commands, arm joint commands, estimated target speed, and
    the stroboscopic motion of robot and target (X-Y and X-Z,
    :func:`~pbvs_pin.viz.stroboscope.plot_stroboscope`). Titles name robot, experiment and law.

    Args:
        log: The run's log.
        folder: Output folder (created).
        footprint: Platform length and width [m], for the stroboscopic plot.
    """
    from pbvs_pin.viz.run_scene import log_robot

    name = run_title(log)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    t = log["t"]
    names = log.meta["velocity_names"]
    n_base = 2 if names[:2] == ["u", "omega"] else (3 if names[:1] == ["vx"] else 0)
    error = log["xi_true"] - log["xi_d"]
    paths = [
        _series(folder / "feature_errors.png", t, error, ["u1", "v1", "v2"],
                f"Feature errors: {name}", "error [px]"),
        _series(folder / "platform_commands.png", t, log["u"][:, :n_base], names[:n_base],
                f"Platform velocity commands: {name}", "[m/s], [rad/s]"),
        _series(folder / "arm_commands.png", t, log["u"][:, n_base:], names[n_base:],
                f"Arm joint velocity commands: {name}", "[rad/s]"),
        _series(folder / "target_speed.png", t,
                np.column_stack([np.linalg.norm(log["target_velocity_estimate"], axis=1),
                                 np.linalg.norm(log["target_velocity"], axis=1)]),
                ["estimated", "true"], f"Target speed: {name}", "[m/s]"),
    ]  # fmt: skip
    paths.append(
        plot_stroboscope(log, log_robot(log), folder / "motion_xyz.png", footprint=footprint)[0]
    )
    return paths
