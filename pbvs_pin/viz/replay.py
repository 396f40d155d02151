"""A run log as a standalone Meshcat HTML replay.

The replay draws the same :class:`~pbvs_pin.viz.run_scene.RunScene` as the live view (robot,
target spheres, obstacles, camera frustum and triad, virtual image plane with desired and
current feature points, platform and target trails) and keys its moving parts at
:data:`REPLAY_RATE` into one animation. The page is written from an offline scene
(:func:`~pbvs_pin.viz.recorder.offline_visualizer`), so no meshcat server is needed to write it,
and none to open it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pbvs_pin.camera import CameraIntrinsics
from pbvs_pin.catalogue import build_robot
from pbvs_pin.exceptions import PointBehindCamera
from pbvs_pin.robot import MobileManipulator
from pbvs_pin.sim.log import RunLog
from pbvs_pin.sim.sections import RobotSection
from pbvs_pin.sim.targets import centres_from
from pbvs_pin.viz.animation import write_replay_html
from pbvs_pin.viz.recorder import offline_visualizer
from pbvs_pin.viz.run_scene import RunFacts, RunScene, two_sphere_points

REPLAY_RATE = 10.0
"""Frames per second kept in a replay [Hz] (the log is downsampled to this)."""


def log_robot(log: RunLog) -> MobileManipulator:
    """The robot a log was recorded with (its ``[robot]`` table, or name, and intrinsics).

    Raises:
        RobotNotFound: If the logged robot name is no longer known.
        ScenarioError: If the logged ``[robot]`` table no longer builds.
    """
    camera = log.meta["camera"]
    intrinsics = CameraIntrinsics(camera["focal_px"], camera["width"], camera["height"])
    table = log.meta.get("robot_table")
    if table:
        return RobotSection.from_toml(table, log.meta.get("source", "")).build(intrinsics)
    return build_robot(log.meta["robot"], intrinsics)


def log_facts(log: RunLog) -> RunFacts:
    """Target size, desired features and obstacles of a logged run."""
    return RunFacts(
        target_diameter=log.meta["target_diameter"],
        target_separation=log.meta["target_separation"],
        desired_points=two_sphere_points(log["xi_d"][0]),
        obstacles=tuple(log.meta.get("obstacles", [])),
    )


def true_image_points(robot: MobileManipulator, q: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Image points of the sphere centres seen from the camera at ``q``, eq. (2).

    Args:
        robot: The robot (its camera pose and intrinsics).
        q: Configuration. Shape (nq,).
        centres: Sphere centres in the world [m]. Shape (2, 3).

    Returns:
        ``[u, v]`` of each centre in the paper's sign convention [px]; NaN for a centre
        behind the camera. Shape (2, 2).
    """
    pose = robot.camera_pose(q)
    points = np.full((len(centres), 2), np.nan)
    for i, centre in enumerate(centres):
        try:
            points[i] = robot.camera.project(pose.actInv(np.asarray(centre, dtype=float)))
        except PointBehindCamera:
            pass
    return points


def write_run_replay(log: RunLog, path: str | Path, rate: float = REPLAY_RATE) -> Path:
    """Write an HTML replay of a run that plays and scrubs in a browser without a server.

    The robot, spheres, camera and current image points are keyed at ``rate``; three.js
    interpolates between keys. The log keeps only three measured features (``u1, v1, v2``),
    so the current image points shown are the exact projections of the logged sphere
    centres from the logged configuration (where a centre is behind the camera, the last
    visible position is held). The trails use every logged sample.

    Args:
        log: The run's log (its ``meta["robot"]`` names the robot to draw).
        path: Output HTML file.
        rate: Frames per second kept in the replay [Hz]: every ``1 / (rate * dt)``-th
            sample of a log sampled every ``dt``, and the last one.

    Returns:
        The written path.

    Raises:
        RobotNotFound: If the logged robot name is no longer known.
    """
    robot = log_robot(log)
    facts = log_facts(log)
    t = log["t"]
    step = max(1, round(1.0 / (rate * np.median(np.diff(t))))) if len(t) > 1 else 1
    keep = np.unique(np.append(np.arange(0, len(t), step), len(t) - 1))
    times = t[keep] - t[keep[0]]
    separation = facts.target_separation
    tops = log["target"] + [0.0, 0.0, separation / 2]
    vis = offline_visualizer()
    run = RunScene(vis, robot, facts)
    run.draw_trails([run.platform_point(q) for q in log["q"]], log["target"])
    last_seen = np.asarray(facts.desired_points, dtype=float)
    frames = []
    for k in keep:
        centres = centres_from(tops[k], separation)
        points = true_image_points(robot, log["q"][k], centres)
        last_seen = np.where(np.isfinite(points), points, last_seen)
        frames.append(run.poses(log["q"][k], centres, last_seen))
    return write_replay_html(path, vis, times, lambda k, _t: frames[k], fps=rate)
