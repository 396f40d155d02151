"""The camera in the scene: frustum, axis triad, virtual image plane and feature points.

Pixels ``(col, row)`` are back-projected with the pinhole model onto a plane at a given depth
of the camera's optical frame (x right, y down, z forward); everything here is drawn under
the camera node (:data:`~pbvs_pin.viz.primitives.CAMERA_PREFIX` by default), whose transform
is the camera pose in the world.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from pbvs_pin.viz.primitives import (
    CAMERA_PREFIX,
    Color,
    _as_homogeneous,
    _material,
    add_sphere,
    rgb_to_int,
    translation_pose,
)

if TYPE_CHECKING:  # pragma: no cover - typing only
    import meshcat

__all__ = [
    "add_camera_frustum",
    "add_camera_triad",
    "add_image_plane",
    "feature_point_poses",
    "frustum_corners",
    "pixels_to_image_plane",
]


def _principal_point(
    width_px: float, height_px: float, principal_point: Sequence[float] | None
) -> tuple[float, float]:
    if principal_point is None:
        return 0.5 * float(width_px), 0.5 * float(height_px)
    return float(principal_point[0]), float(principal_point[1])


def pixels_to_image_plane(
    uv: np.ndarray,
    focal_px: float,
    width_px: float,
    height_px: float,
    depth: float,
    principal_point: Sequence[float] | None = None,
) -> np.ndarray:
    """Back-project pixels onto the plane z = ``depth`` of the camera frame.

    Pinhole model: ``X = (u - cx) / f * depth``, ``Y = (v - cy) / f * depth``,
    ``Z = depth`` (camera frame: x right, y down, z forward).

    Args:
        uv: Pixels ``(col, row)`` from the top-left corner, shape (N, 2), px.
        focal_px: Focal length, px (same for u and v).
        width_px: Image width, px.
        height_px: Image height, px.
        depth: Distance of the plane in front of the camera, m.
        principal_point: (cx, cy) in px; default is the image centre.

    Returns:
        Points in the camera frame, shape (N, 3), m.
    """
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    cx, cy = _principal_point(width_px, height_px, principal_point)
    f = float(focal_px)
    out = np.empty((len(uv), 3))
    out[:, 0] = (uv[:, 0] - cx) / f * depth
    out[:, 1] = (uv[:, 1] - cy) / f * depth
    out[:, 2] = depth
    return out


def frustum_corners(
    focal_px: float,
    width_px: float,
    height_px: float,
    depth: float,
    principal_point: Sequence[float] | None = None,
) -> np.ndarray:
    """Corners of the image rectangle at distance ``depth``, camera frame.

    Args:
        focal_px: Focal length, px.
        width_px: Image width, px.
        height_px: Image height, px.
        depth: Distance in front of the camera, m.
        principal_point: (cx, cy) in px; default is the image centre.

    Returns:
        Corners for pixels (0,0), (W,0), (W,H), (0,H), shape (4, 3), m.
    """
    w, h = float(width_px), float(height_px)
    uv = np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])
    return pixels_to_image_plane(uv, focal_px, w, h, depth, principal_point)


def add_camera_frustum(
    vis: meshcat.Visualizer,
    focal_px: float,
    width_px: float,
    height_px: float,
    depth: float = 0.15,
    color: Color = (0.1, 0.1, 0.1),
    camera_path: str = CAMERA_PREFIX,
    pose: Any | None = None,
    principal_point: Sequence[float] | None = None,
) -> str:
    """Add a pinhole camera frustum (line segments) attached to a camera node.

    The frustum lines live at ``<camera_path>/frustum`` in the camera frame;
    the camera pose in the world is the transform of ``camera_path`` (set it
    here with ``pose`` or per frame in
    :func:`~pbvs_pin.viz.animation.write_replay_html`).

    Args:
        vis: Visualizer.
        focal_px: Focal length, px.
        width_px: Image width, px.
        height_px: Image height, px.
        depth: Length of the frustum along the optical axis, m.
        color: Line colour.
        camera_path: Meshcat path of the camera node.
        pose: Optional world pose of the camera (``pin.SE3`` or 4x4).
        principal_point: (cx, cy) in px; default is the image centre.

    Returns:
        Path of the frustum node (``<camera_path>/frustum``).
    """
    import meshcat.geometry as mg

    c = frustum_corners(focal_px, width_px, height_px, depth, principal_point)
    o = np.zeros(3)
    segments = []
    for i in range(4):
        segments += [o, c[i], c[i], c[(i + 1) % 4]]
    # small tick on the top edge (v = 0) to show image "up"
    top_mid = 0.5 * (c[0] + c[1])
    segments += [top_mid, top_mid + np.array([0.0, -0.15 * abs(c[0, 1]), 0.0])]
    pts = np.asarray(segments, dtype=np.float32)
    path = f"{camera_path}/frustum"
    vis[path].set_object(
        mg.LineSegments(mg.PointsGeometry(pts.T), mg.LineBasicMaterial(color=rgb_to_int(color)))
    )
    if pose is not None:
        vis[camera_path].set_transform(_as_homogeneous(pose))
    return path


def add_image_plane(
    vis: meshcat.Visualizer,
    focal_px: float,
    width_px: float,
    height_px: float,
    desired_uv: np.ndarray,
    current_uv: np.ndarray | None = None,
    depth: float = 0.1,
    point_diameter: float | None = None,
    plane_color: Color = (1.0, 1.0, 1.0),
    plane_opacity: float = 0.35,
    desired_color: Color = (0.0, 0.8, 0.0),
    current_color: Color = (0.9, 0.0, 0.0),
    camera_path: str = CAMERA_PREFIX,
    principal_point: Sequence[float] | None = None,
) -> dict[str, list[str]]:
    """Add a virtual image plane with desired and current feature points.

    The plane is the image rectangle back-projected at ``depth`` (put it
    inside the frustum: ``depth`` < frustum depth) in the camera frame, under
    ``<camera_path>/image``.  Feature points are small spheres: desired ones
    are static, current ones are nodes whose transform (a translation in the
    camera frame) can be animated with :func:`feature_point_poses`.

    Args:
        vis: Visualizer.
        focal_px: Focal length, px.
        width_px: Image width, px.
        height_px: Image height, px.
        desired_uv: Desired feature pixels ``(col, row)``, shape (N, 2), px.
        current_uv: Initial current feature pixels ``(col, row)``, shape (M, 2), px;
            defaults to ``desired_uv``.
        depth: Distance of the plane in front of the camera, m.
        point_diameter: Sphere diameter, m; default 2.5 % of the plane width.
        plane_color: Plane colour.
        plane_opacity: Plane opacity in [0, 1].
        desired_color: Colour of desired points.
        current_color: Colour of current points.
        camera_path: Meshcat path of the camera node.
        principal_point: (cx, cy) in px; default is the image centre.

    Returns:
        ``{"plane": [path], "desired": [paths], "current": [paths]}``.
    """
    import meshcat.geometry as mg

    desired_uv = np.asarray(desired_uv, dtype=float).reshape(-1, 2)
    current_uv = desired_uv if current_uv is None else np.asarray(current_uv, float).reshape(-1, 2)
    c = frustum_corners(focal_px, width_px, height_px, depth, principal_point)
    plane_w = float(np.linalg.norm(c[1] - c[0]))
    plane_h = float(np.linalg.norm(c[3] - c[0]))
    if point_diameter is None:
        point_diameter = 0.025 * plane_w
    base = f"{camera_path}/image"

    plane_path = f"{base}/plane"
    vis[plane_path].set_object(
        mg.Box([plane_w, plane_h, 1e-4]),
        _material(plane_color, plane_opacity, kind="basic"),
    )
    vis[plane_path].set_transform(translation_pose(0.25 * c.sum(axis=0)))
    border = np.vstack([c, c[:1]]).astype(np.float32)
    vis[f"{base}/border"].set_object(
        mg.Line(mg.PointsGeometry(border.T), mg.LineBasicMaterial(color=0x000000))
    )

    paths: dict[str, list[str]] = {"plane": [plane_path], "desired": [], "current": []}
    for kind, uv, color in (
        ("desired", desired_uv, desired_color),
        ("current", current_uv, current_color),
    ):
        pts = pixels_to_image_plane(uv, focal_px, width_px, height_px, depth, principal_point)
        for i, p in enumerate(pts):
            paths[kind].append(
                add_sphere(vis, f"{base}/{kind}/{i}", point_diameter, color, position=p)
            )
    return paths


def feature_point_poses(
    uv: np.ndarray,
    focal_px: float,
    width_px: float,
    height_px: float,
    depth: float = 0.1,
    kind: str = "current",
    camera_path: str = CAMERA_PREFIX,
    principal_point: Sequence[float] | None = None,
) -> dict[str, np.ndarray]:
    """Poses of feature-point spheres for one frame (for animation).

    Args:
        uv: Feature pixels ``(col, row)``, shape (N, 2), px.
        focal_px: Focal length, px.
        width_px: Image width, px.
        height_px: Image height, px.
        depth: Image-plane distance used in :func:`add_image_plane`, m.
        kind: ``"current"`` or ``"desired"``.
        camera_path: Meshcat path of the camera node.
        principal_point: (cx, cy) in px; default is the image centre.

    Returns:
        Path ``<camera_path>/image/<kind>/<i>`` -> 4x4 translation in the
        camera frame.
    """
    pts = pixels_to_image_plane(uv, focal_px, width_px, height_px, depth, principal_point)
    return {f"{camera_path}/image/{kind}/{i}": translation_pose(p) for i, p in enumerate(pts)}


def add_camera_triad(
    vis: meshcat.Visualizer, scale: float = 0.08, camera_path: str = CAMERA_PREFIX
) -> str:
    """Add a small axis triad (x red, y green, z blue) at the camera frame.

    With the optical-frame convention, blue is the optical axis, red points
    right and green points down in the image.

    Args:
        vis: Visualizer.
        scale: Length of each axis, m.
        camera_path: Meshcat path of the camera node.

    Returns:
        Path of the triad node (``<camera_path>/triad``).
    """
    import meshcat.geometry as mg

    path = f"{camera_path}/triad"
    vis[path].set_object(mg.triad(float(scale)))
    return path
