"""A run log as a standalone Meshcat HTML replay.

The replay draws the same :class:`~pbvs_pin.viz.run_scene.RunScene` as the live view (robot,
target spheres, obstacles, camera frustum and triad, virtual image plane with desired and
current feature points, platform and target trails) and keys its moving parts at
:data:`REPLAY_RATE` into one animation. The page is written from an offline scene
(:func:`~pbvs_pin.viz.recorder.offline_visualizer`), so no meshcat server is needed to write it,
and none to open it.

What makes it readable (:mod:`pbvs_pin.viz.replay_page`): the page is titled with the robot
and the experiment; a play/pause button, a time slider and a readout of the time and the
largest feature error sit along the bottom; an inset draws the camera image with the current
and the desired image points. Meshcat's endless floor grid is hidden and a floor just larger
than the run's paths drawn instead, and the viewing camera stands back far enough to frame the
platform and the target (:func:`follow_offset`).
"""

from __future__ import annotations

import base64
import json
from pathlib import Path

import numpy as np

from pbvs_pin.exceptions import PointBehindCamera
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.sim.log import RunLog
from pbvs_pin.sim.targets import centres_from
from pbvs_pin.viz.animation import write_replay_html
from pbvs_pin.viz.primitives import ROOT_PREFIX, _material, set_camera_view, translation_pose
from pbvs_pin.viz.recorder import offline_visualizer
from pbvs_pin.viz.replay_page import ReplayOverlay, add_overlay
from pbvs_pin.viz.run_scene import RunScene, log_facts, log_robot

REPLAY_RATE = 10.0
"""Frames per second kept in a replay [Hz] (the log is downsampled to this)."""
FOLLOW_PATH = f"{ROOT_PREFIX}/follow"
"""Meshcat path of the empty node the replay's viewing camera follows (animated)."""
FOLLOW_VIEW = (-0.6, -0.75, 0.7)
"""Viewing camera position relative to the followed point [m] when platform and target are
close, near enough that the 5 cm target spheres are tens of pixels wide; it is stretched along
the same direction to frame them when they are apart (:func:`follow_offset`)."""
FLOOR_PATH = f"{ROOT_PREFIX}/floor"
"""Meshcat path of the floor drawn under the run."""
FLOOR_MARGIN = 1.5
"""Floor beyond the run's paths on each side [m]."""
FLOOR_COLOR = (0.78, 0.78, 0.74)
"""Floor colour."""
FOLLOW_HEIGHT = 0.3
"""Height of the followed point [m] (about the camera's and the target's)."""
FOLLOW_SCRIPT = """<script>
(function () {
  // Keep the orbit target on the followed node and move the viewing camera with it,
  // so that the platform stays in frame; the user can still orbit and zoom.
  const path = %s;
  const render = viewer.render.bind(viewer);
  viewer.render = function () {
    let node = viewer.scene_tree;
    for (const name of path) { node = node && node.children[name]; }
    if (node) {
      node.object.updateMatrixWorld(true);
      const p = viewer.camera.position.clone().setFromMatrixPosition(node.object.matrixWorld);
      viewer.camera.parent.worldToLocal(p);
      const shift = p.clone().sub(viewer.controls.target);
      viewer.controls.target.copy(p);
      viewer.camera.position.add(shift);
    }
    render();
  };
})();
</script>
</body>"""
"""Script appended to the replay page: the viewing camera follows :data:`FOLLOW_PATH`."""


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


EYE_VIEW_SCRIPT = """<img id="eye-view" alt="robot's-eye view"
 style="position:fixed;right:8px;bottom:54px;border:2px solid #444;z-index:10">
<script>
(function () {
  // The robot's-eye view beside the scene: the image of the replay's current key.
  const frames = %s, times = %s, image = document.getElementById("eye-view");
  const render = viewer.render.bind(viewer);
  viewer.render = function () {
    const actions = viewer.animator.actions, t = actions.length ? actions[0].time : 0;
    let k = 0;
    for (let j = 1; j < times.length; j++) {
      if (Math.abs(times[j] - t) < Math.abs(times[k] - t)) { k = j; }
    }
    if (image.dataset.key !== String(k)) { image.src = frames[k]; image.dataset.key = k; }
    render();
  };
})();
</script>"""
"""Panel and script appended to a replay with the robot's-eye view: a JPEG per key, shown at
the animation's time (the key nearest to it), in the lower right corner above the overlay's
46 px bar of play button, time slider and readout (:mod:`pbvs_pin.viz.replay_page`), which it
would otherwise cover."""


def write_run_replay(
    log: RunLog, path: str | Path, rate: float = REPLAY_RATE, eye_view: bool = False
) -> Path:
    """Write an HTML replay of a run that plays and scrubs in a browser without a server.

    The robot, spheres, camera and current image points are keyed at ``rate``; three.js
    interpolates between keys. The log keeps only three measured features (``u1, v1, v2``),
    so the current image points shown are the exact projections of the logged sphere
    centres from the logged configuration (where a centre is behind the camera, the last
    visible position is held). The trails use every logged sample. The viewing camera
    follows the platform (:func:`follow_point`, :data:`FOLLOW_SCRIPT`).

    Args:
        log: The run's log (its ``meta["robot"]`` names the robot to draw).
        path: Output HTML file.
        rate: Frames per second kept in the replay [Hz]: every ``1 / (rate * dt)``-th
            sample of a log sampled every ``dt``, and the last one.
        eye_view: Also show the robot's-eye view beside the scene, at each kept sample
            (:func:`pbvs_pin.viz.eye_view.eye_views`, at half size; :data:`EYE_VIEW_SCRIPT`).

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
    platform = np.array([run.platform_point(q) for q in log["q"]])
    run.draw_trails(platform, log["target"])
    draw_floor(vis, np.vstack([platform[:, :2], log["target"][:, :2]]))
    set_camera_view(vis, follow_offset(platform, log["target"]))
    last_seen = np.asarray(facts.desired_points, dtype=float)
    frames, points_px = [], []
    for k in keep:
        centres = centres_from(tops[k], separation)
        points = true_image_points(robot, log["q"][k], centres)
        last_seen = np.where(np.isfinite(points), points, last_seen)
        points_px.append(robot.camera.to_pixel(last_seen))
        poses = run.poses(log["q"][k], centres, last_seen)
        poses[FOLLOW_PATH] = translation_pose(follow_point(run.platform_point(log["q"][k]),
                                                          log["target"][k]))  # fmt: skip
        frames.append(poses)
    out = write_replay_html(path, vis, times, lambda k, _t: frames[k], fps=rate)
    names = json.dumps(["meshcat", *FOLLOW_PATH.split("/")])
    error = np.abs(log["xi"] - log["xi_d"])[keep]
    overlay = ReplayOverlay(
        title=f"{log.meta.get('robot', 'robot')} · {log.meta.get('scenario', 'run')}",
        subtitle=str(log.meta.get("description", "")).split("\n")[0],
        times=times,
        error_px=np.where(np.all(np.isfinite(error), axis=1), np.max(error, axis=1), np.nan),
        points_px=np.array(points_px),
        desired_px=robot.camera.to_pixel(np.asarray(facts.desired_points, dtype=float)),
        image_size=(robot.camera.width, robot.camera.height),
    )
    html = out.read_text(encoding="utf-8")
    head, _, tail = html.rpartition("</body>")
    extra = FOLLOW_SCRIPT % names
    if eye_view:
        frames = json.dumps(_eye_view_frames(log, keep))
        extra += EYE_VIEW_SCRIPT % (frames, json.dumps(times.tolist()))
    html = add_overlay(head + extra + tail, overlay)
    out.write_text(html, encoding="utf-8")
    return out


def _eye_view_frames(log: RunLog, samples: np.ndarray) -> list[str]:
    """The robot's-eye view at ``samples`` as half-size JPEG data URLs."""
    import cv2

    from pbvs_pin.viz.eye_view import eye_views

    urls = []
    for image in eye_views(log, samples):
        half = cv2.resize(image, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
        _, jpeg = cv2.imencode(".jpg", cv2.cvtColor(half, cv2.COLOR_RGB2BGR))
        urls.append("data:image/jpeg;base64," + base64.b64encode(jpeg.tobytes()).decode())
    return urls


def follow_offset(platform: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Viewing camera position relative to the followed point [m]. Shape (3,).

    Along :data:`FOLLOW_VIEW`, at least as far as it, and far enough that the largest
    platform-to-target distance of the run fits in the view (meshcat's camera sees 75 degrees
    vertically: a span ``d`` fits at about ``0.8 d`` plus room for the robot).

    Args:
        platform: The platform point over the run [m]. Shape (N, 3).
        target: The target over the run [m]. Shape (N, 3).
    """
    gap = np.linalg.norm(np.asarray(platform)[:, :2] - np.asarray(target)[:, :2], axis=1)
    base = np.asarray(FOLLOW_VIEW, dtype=float)
    distance = max(float(np.linalg.norm(base)), 0.8 * float(np.max(gap, initial=0.0)) + 0.5)
    return base / np.linalg.norm(base) * distance


def draw_floor(vis, xy: np.ndarray) -> None:
    """Hide meshcat's endless grid and draw a floor under the run, with a 1 m grid on it.

    Args:
        vis: Visualizer.
        xy: Every point the run visits in the plane [m]. Shape (N, 2).
    """
    import meshcat.geometry as mg

    vis["/Grid"].set_property("visible", False)
    low = np.floor(np.min(xy, axis=0) - FLOOR_MARGIN)
    high = np.ceil(np.max(xy, axis=0) + FLOOR_MARGIN)
    size = high - low
    vis[FLOOR_PATH].set_object(mg.Box([*size, 0.002]), _material(FLOOR_COLOR, kind="basic"))
    vis[FLOOR_PATH].set_transform(translation_pose([*(low + size / 2), -0.002]))
    lines = []
    for x in np.arange(low[0], high[0] + 0.5):
        lines += [[x, low[1], 0.0005], [x, high[1], 0.0005]]
    for y in np.arange(low[1], high[1] + 0.5):
        lines += [[low[0], y, 0.0005], [high[0], y, 0.0005]]
    grid = np.asarray(lines, dtype=np.float32).T
    vis[f"{FLOOR_PATH}_grid"].set_object(
        mg.LineSegments(mg.PointsGeometry(grid), mg.LineBasicMaterial(color=0x999990))
    )


def follow_point(platform: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Point the replay's viewing camera follows [m]. Shape (3,).

    Halfway between the platform point and the target in X-Y, at :data:`FOLLOW_HEIGHT`.
    """
    middle = (np.asarray(platform[:2], dtype=float) + np.asarray(target[:2], dtype=float)) / 2
    return np.array([*middle, FOLLOW_HEIGHT])
