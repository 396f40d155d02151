"""The robot's-eye view of a logged run: what the camera saw, drawn again from the log.

The log keeps the true configuration ``q`` and the target's midpoint at every logged instant,
and its meta the robot, the camera, the target's size and the obstacles; so the view is drawn
after the run by the rendered camera's own scene (:class:`pbvs_pin.sim.render.SceneRenderer`),
for a run with either camera model. On each image the default detector's finds are circled
(white: the detected centre and apparent diameter) and the desired features ``xi_d`` are
marked (cyan crosses). :func:`write_eye_view` writes an image strip (PNG) or a video (MP4).
:func:`mark` draws those marks on any image; the live view
(:mod:`pbvs_pin.viz.eye_panel`) draws them with the detections the run's own detector made.
MuJoCo is imported only to draw a log's images (:func:`eye_views`).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from pbvs_pin.exceptions import GainError
from pbvs_pin.model.camera import CameraIntrinsics
from pbvs_pin.perception.detection import ColourDetector, Detector
from pbvs_pin.sim.log import RunLog
from pbvs_pin.sim.scenario import OBSTACLE_KINDS
from pbvs_pin.sim.targets import centres_from
from pbvs_pin.viz.run_scene import log_facts, log_robot

DETECTION_BGR = (255, 255, 255)
DESIRED_BGR = (255, 255, 0)
STRIP_PANELS = 8
"""Images in a strip, evenly spread over the run."""


def eye_views(log: RunLog, samples: np.ndarray, marked: bool = True) -> list[np.ndarray]:
    """The camera images at the logged ``samples`` (indices), RGB ``uint8``.

    Args:
        log: A run's log.
        samples: Indices into the log's instants. Shape (k,).
        marked: Mark the detections and the desired features; False: as the camera saw.

    Returns:
        One image per sample, shape (H, W, 3).
    """
    from pbvs_pin.sim.render import SceneRenderer  # MuJoCo, only to draw

    robot, facts = log_robot(log), log_facts(log)
    camera = robot.camera
    obstacles = [
        OBSTACLE_KINDS[table["kind"]](**{k: v for k, v in table.items() if k != "kind"})
        for table in facts.obstacles
    ]
    scene = SceneRenderer(robot, camera, facts.target_diameter, obstacles)
    detector = ColourDetector(camera)
    half = np.array([0.0, 0.0, facts.target_separation / 2])
    images = []
    try:
        for i in samples:
            q = log["q"][i]
            centres = centres_from(log["target"][i] + half, facts.target_separation)
            image = scene.render(q, robot.camera_pose(q), centres)
            images.append(annotate(image, camera, detector, facts.desired_points) if marked
                          else image.copy())  # fmt: skip
    finally:
        scene.close()
    return images


def annotate(
    image: np.ndarray, camera: CameraIntrinsics, detector: Detector, desired: np.ndarray
) -> np.ndarray:
    """A copy of ``image`` with the detections circled and the desired points crossed.

    Args:
        image: RGB ``uint8``. Shape (H, W, 3).
        camera: Intrinsics (pixel positions of image points).
        detector: Finds the spheres.
        desired: Desired ``[u, v]`` of both spheres [px] (NaN: not drawn). Shape (2, 2).
    """
    points, diameters, visible = detector.detect(image)
    return mark(image, camera, points if visible else None, diameters, desired)


def mark(
    image: np.ndarray,
    camera: CameraIntrinsics,
    points: np.ndarray | None,
    diameters: np.ndarray,
    desired: np.ndarray,
    thickness: int = 1,
) -> np.ndarray:
    """A copy of ``image`` with found spheres circled and the desired points crossed.

    Args:
        image: RGB ``uint8``. Shape (H, W, 3).
        camera: Intrinsics (pixel positions of image points).
        points: Found ``[u, v]`` of both spheres [px], circled in white; None: nothing
            found. Shape (2, 2).
        diameters: Their apparent diameters [px] (the circles'). Shape (2,).
        desired: Desired ``[u, v]`` of both spheres [px] (NaN: not drawn), crossed in cyan.
            Shape (2, 2).
        thickness: Line width of the marks [px of the image].
    """
    out = np.ascontiguousarray(image).copy()
    if points is not None:
        for (col, row), diameter in zip(camera.to_pixel(points), diameters, strict=True):
            if _drawable(col, row) and np.isfinite(diameter):
                centre = (round(col - 0.5), round(row - 0.5))  # OpenCV's pixel centres at ints
                cv2.circle(out, centre, round(diameter / 2), DETECTION_BGR[::-1], thickness)
    for col, row in camera.to_pixel(desired):
        if _drawable(col, row):
            centre = (round(col - 0.5), round(row - 0.5))
            size = 12 * thickness
            cv2.drawMarker(out, centre, DESIRED_BGR[::-1], cv2.MARKER_CROSS, size, thickness)
    return out


def _drawable(col: float, row: float) -> bool:
    """Whether OpenCV can draw at pixel ``(col, row)`` (finite, within its integer range)."""
    return bool(np.isfinite(col) and np.isfinite(row) and max(abs(col), abs(row)) < 1e6)


def write_eye_view(log: RunLog, path: str | Path, kind: str = "strip") -> Path:
    """Write the robot's-eye view of ``log``: an image strip or a video.

    Args:
        log: A run's log.
        path: The file to write (``.png`` for a strip, ``.mp4`` for a video).
        kind: ``"strip"``: :data:`STRIP_PANELS` images evenly spread over the run, at half
            size, side by side; ``"video"``: every logged instant at the log's rate.

    Returns:
        The path written.

    Raises:
        GainError: If ``kind`` is neither, naming it.
    """
    path = Path(path)
    count = len(log["t"])
    if kind == "strip":
        samples = np.linspace(0, count - 1, min(STRIP_PANELS, count)).round().astype(int)
        panels = [cv2.resize(image, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
                  for image in eye_views(log, samples)]  # fmt: skip
        cv2.imwrite(str(path), cv2.cvtColor(np.hstack(panels), cv2.COLOR_RGB2BGR))
        return path
    if kind != "video":
        raise GainError(f"eye view: expected 'strip' or 'video', got {kind!r}", "kind")
    rate = 1.0 / float(np.median(np.diff(log["t"]))) if count > 1 else 1.0
    camera = log_robot(log).camera
    writer = cv2.VideoWriter(
        str(path), cv2.VideoWriter_fourcc(*"mp4v"), rate, (camera.width, camera.height)
    )
    try:
        for image in eye_views(log, np.arange(count)):
            writer.write(cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    finally:
        writer.release()
    return path
