"""A run log as a standalone Meshcat HTML replay: robot, target, obstacles, camera, trails."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pbvs_pin.catalogue import build_robot
from pbvs_pin.sim.log import RunLog
from pbvs_pin.sim.targets import centres_from
from pbvs_pin.viz import scene

REPLAY_RATE = 10.0
"""Frames per second kept in a replay [Hz] (the log is downsampled to this)."""


def write_run_replay(log: RunLog, path: str | Path, rate: float = REPLAY_RATE) -> Path:
    """Write an HTML replay of a run that plays and scrubs in a browser without a server.

    Args:
        log: The run's log (its ``meta["robot"]`` names the robot to draw).
        path: Output HTML file.
        rate: Frames per second kept in the replay [Hz].

    Returns:
        The written path.
    """
    robot = build_robot(log.meta["robot"])
    t = log["t"]
    keep = np.unique(np.searchsorted(t, np.arange(0.0, t[-1] + 1e-9, 1.0 / rate)))
    keep = keep[keep < len(t)]
    times, qs = t[keep] - t[keep[0]], log["q"][keep]
    separation = log.meta["target_separation"]
    tops = log["target"][keep] + [0.0, 0.0, separation / 2]
    camera = log.meta["camera"]
    with scene.open_visualizer() as vis:
        robot_scene = scene.RobotScene(vis, robot.model, robot.visual_model, strict=False)
        spheres = scene.add_target_spheres(
            vis, centres_from(tops[0], separation), log.meta["target_diameter"],
            [(0.9, 0.1, 0.1), (0.1, 0.3, 0.9)],
        )  # fmt: skip
        for i, obstacle in enumerate(log.meta.get("obstacles", [])):
            height = obstacle.get("height", 0.4)
            if obstacle["kind"] == "circle":
                scene.add_cylinder_obstacle(
                    vis, f"obstacle_{i}", (obstacle["x"], obstacle["y"]), obstacle["radius"],
                    height,
                )  # fmt: skip
            else:
                scene.add_box_obstacle(
                    vis, f"obstacle_{i}", (obstacle["x"], obstacle["y"]),
                    (obstacle["size_x"], obstacle["size_y"], height), obstacle.get("yaw", 0.0),
                )  # fmt: skip
        scene.add_trail(
            vis, log["target"][keep], (0.1, 0.3, 0.9), path=f"{scene.TRAIL_PATH}_target"
        )
        base = np.column_stack([log["q"][keep, :2], np.full(len(keep), 0.01)])
        scene.add_trail(vis, base, (0.9, 0.2, 0.1), path=f"{scene.TRAIL_PATH}_platform")
        scene.add_camera_frustum(vis, camera["focal_px"], camera["width"], camera["height"])
        poses = robot_scene.trajectory_poses(qs)
        for index, sphere in enumerate(spheres):
            centres = tops - [0.0, 0.0, index * separation]
            poses[sphere] = np.array([scene.translation_pose(c) for c in centres])
        poses[scene.CAMERA_PREFIX] = np.array([robot.camera_pose(q).homogeneous for q in qs])
        return scene.write_replay_html(path, vis, times, poses, fps=rate)
