"""Stroboscopic plot of a run, in the style of the paper's Figs. 14, 15 and 20.

The robot is drawn at a few instants from the logged configurations: the platform footprint
(a rectangle at the base pose), the arm (the chain through the Pinocchio placements of its
joints, up to the camera frame) and the camera with its optical axis; the two target spheres
are drawn at the same instants, in the same colour. Left: top view (X-Y, equal axes, obstacles
in grey). Right: side view (X-Z, equal axes, from the ground to above the camera and target).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.sim.log import RunLog
from pbvs_pin.viz.plotting import pyplot, run_title

DEFAULT_FOOTPRINT = (0.50, 0.49)
"""Platform footprint length and width [m] when the caller gives none (the scenario default)."""
AXIS_LENGTH = 0.12
"""Length of the drawn optical axis [m]."""


def instants(count: int, samples: int) -> np.ndarray:
    """``count`` sample indices spread evenly over ``samples`` samples, first and last included."""
    return np.unique(np.linspace(0, samples - 1, count).round().astype(int))


def robot_points(robot: MobileManipulator, q: np.ndarray) -> tuple[np.ndarray, pin.SE3]:
    """World positions [m] of the base origin, every arm joint, then the camera; camera pose.

    Returns:
        Chain points, shape (n_arm + 2, 3), and ``world_T_camera``.
    """
    model, data = robot.model, robot.data
    pin.framesForwardKinematics(model, data, q)
    joints = [model.getJointId(name) for name in robot.arm_joint_names]
    camera = pin.SE3(data.oMf[robot.camera_frame_id])
    points = [data.oMi[1].translation] + [data.oMi[j].translation for j in joints]
    return np.array([*points, camera.translation]), camera


def _footprint(base: pin.SE3, length: float, width: float) -> np.ndarray:
    """Corners [m] of the footprint rectangle at a base pose, in the X-Y plane. Shape (4, 2)."""
    corners = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]]) * [length / 2, width / 2]
    rotation = base.rotation[:2, :2]
    return corners @ rotation.T + base.translation[:2]


def plot_stroboscope(
    log: RunLog,
    robot: MobileManipulator,
    path: str | Path,
    count: int = 6,
    footprint: tuple[float, float] = DEFAULT_FOOTPRINT,
):
    """Write the stroboscopic plot of a run; return the figure's path and its two axes.

    Args:
        log: The run's log (``q``, ``t``, ``target``, meta's robot/scenario/law/obstacles).
        robot: The robot the log was recorded with.
        path: Output PNG.
        count: Number of instants drawn (5-7 in the paper).
        footprint: Platform length and width [m].

    Returns:
        ``(path, top, side)``: the written file and the X-Y and X-Z matplotlib axes (the
        figure is closed; the axes keep their artists, for tests).
    """
    plt = pyplot()
    q, t, target = log["q"], log["t"], log["target"]
    half = log.meta["target_separation"] / 2
    radius = log.meta["target_diameter"] / 2
    drawn = instants(count, len(q))
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 1.0, len(drawn)))
    poses = [(robot.base_pose(q[i]), *robot_points(robot, q[i])) for i in drawn]
    corners = np.vstack([_footprint(base, *footprint) for base, _, _ in poses])
    chains = np.vstack([chain for _, chain, _ in poses])
    x = np.concatenate([corners[:, 0], chains[:, 0], target[:, 0]])
    y = np.concatenate([corners[:, 1], chains[:, 1], target[:, 1]])
    for obstacle in log.meta.get("obstacles", []):
        diagonal = np.hypot(obstacle.get("size_x", 0.0), obstacle.get("size_y", 0.0)) / 2
        reach = obstacle.get("radius", diagonal)
        x = np.append(x, [obstacle["x"] - reach, obstacle["x"] + reach])
        y = np.append(y, [obstacle["y"] - reach, obstacle["y"] + reach])
    z_top = max(chains[:, 2].max(), (target[:, 2] + half + radius).max()) + 0.1
    margin = 0.15
    x_span, y_span = np.ptp(x) + 2 * margin, np.ptp(y) + 2 * margin
    fig, (top, side) = plt.subplots(
        2, 1, sharex=True, figsize=(10, 2.0 + 7.5 * (y_span + z_top) / x_span),
        height_ratios=(y_span, z_top + 0.05), layout="constrained",
    )  # fmt: skip
    top.plot(q[:, 0], q[:, 1], color="0.5", linewidth=0.8, linestyle="--")
    top.plot(target[:, 0], target[:, 1], color="tab:blue", linewidth=0.8, linestyle=":")
    for colour, (base, chain, camera), index in zip(colours, poses, drawn, strict=True):
        top.add_patch(plt.Polygon(_footprint(base, *footprint), closed=True, facecolor=colour,
                                  alpha=0.25, edgecolor=colour, gid="footprint"))  # fmt: skip
        side.plot([base.translation[0] - footprint[0] / 2, base.translation[0] + footprint[0] / 2],
                  [0.0, 0.0], color=colour, linewidth=5, alpha=0.5, solid_capstyle="butt",
                  gid="footprint")  # fmt: skip
        axis = camera.translation + AXIS_LENGTH * camera.rotation[:, 2]
        centres = target[index] + np.array([[0.0, 0.0, half], [0.0, 0.0, -half]])
        for ax, (a, b) in ((top, (0, 1)), (side, (0, 2))):
            ax.plot(chain[:, a], chain[:, b], "-o", color=colour, markersize=2.5, linewidth=1.8)
            ax.plot(*camera.translation[[a, b]], "s", color=colour, markersize=6,
                    markeredgecolor="k", gid="camera")  # fmt: skip
            ax.plot([camera.translation[a], axis[a]], [camera.translation[b], axis[b]],
                    color=colour, linewidth=1.0)  # fmt: skip
            for centre in centres:
                ax.add_patch(plt.Circle(centre[[a, b]], radius, facecolor=colour,
                                        edgecolor="k", linewidth=0.6, gid="target"))  # fmt: skip
    for obstacle in log.meta.get("obstacles", []):
        _obstacle(plt, top, side, obstacle)
    top.set(ylabel="Y [m]", title="Top view (X-Y)", aspect="equal",
            xlim=(x.min() - margin, x.max() + margin), ylim=(y.min() - margin, y.max() + margin))
    side.set(xlabel="X [m]", ylabel="Z [m]", title="Side view (X-Z)", aspect="equal",
             ylim=(-0.05, z_top))  # fmt: skip
    for ax in (top, side):
        ax.grid(alpha=0.3)
    handles = [
        plt.Line2D([], [], color="0.5", linestyle="--", label="platform path"),
        plt.Line2D([], [], color="tab:blue", linestyle=":", label="target path"),
        plt.Line2D([], [], color="k", marker="o", markersize=3, label="arm joints"),
        plt.Line2D([], [], color="k", marker="s", linestyle="", label="camera (and optical axis)"),
        plt.Line2D([], [], color="k", marker="o", linestyle="", markerfacecolor="w",
                   label="target spheres"),
        plt.Rectangle((0, 0), 1, 1, color="k", alpha=0.25, label="platform footprint"),
    ]  # fmt: skip
    fig.legend(handles=handles, loc="outside lower center", ncol=6, fontsize=8, frameon=False)
    bounds = np.append(t[drawn], 2 * t[drawn[-1]] - t[drawn[-2]]) if len(drawn) > 1 else None
    colour_map = plt.matplotlib.colors.ListedColormap(colours)
    mappable = plt.cm.ScalarMappable(
        cmap=colour_map, norm=plt.matplotlib.colors.BoundaryNorm(bounds, len(drawn))
    )
    bar = fig.colorbar(mappable, ax=[top, side], fraction=0.03, pad=0.01)
    bar.set_ticks((bounds[:-1] + bounds[1:]) / 2, labels=[f"{t[i]:.0f} s" for i in drawn])
    bar.set_label("instant drawn", fontsize=8)
    fig.suptitle(f"Stroboscopic motion: {run_title(log)}")
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path, top, side


def _obstacle(plt, top, side, obstacle: dict) -> None:
    """An obstacle in grey: its outline from above, its extent and height from the side."""
    height = float(obstacle.get("height", 0.4))
    if obstacle["kind"] == "circle":
        top.add_patch(plt.Circle((obstacle["x"], obstacle["y"]), obstacle["radius"],
                                 color="grey", alpha=0.6))  # fmt: skip
        half_x = obstacle["radius"]
    else:
        top.add_patch(plt.Rectangle(
            (obstacle["x"] - obstacle["size_x"] / 2, obstacle["y"] - obstacle["size_y"] / 2),
            obstacle["size_x"], obstacle["size_y"], angle=np.degrees(obstacle.get("yaw", 0.0)),
            rotation_point="center", color="grey", alpha=0.6))  # fmt: skip
        half_x = obstacle["size_x"] / 2
    side.add_patch(plt.Rectangle((obstacle["x"] - half_x, 0.0), 2 * half_x, height,
                                 color="grey", alpha=0.35))  # fmt: skip
