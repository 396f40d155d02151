"""Meshcat path conventions and the basic drawables: spheres, obstacles, trails.

It holds the paths everything in :mod:`pbvs_pin.viz` draws under (``pbvs/...``), the
meshcat-to-three.js transform of the browser page, colour and transform helpers, the target
spheres, the cylinder and box obstacles, polyline trails and the placement of the browser's
viewing camera.  See :mod:`pbvs_pin.viz` for the conventions (paths, frames, units).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

if TYPE_CHECKING:  # pragma: no cover - typing only
    import meshcat

__all__ = [
    "CAMERA_PREFIX",
    "MESHCAT_TO_THREEJS",
    "OBSTACLES_PREFIX",
    "ROBOT_PREFIX",
    "ROOT_PREFIX",
    "TARGETS_PREFIX",
    "TRAIL_PATH",
    "add_box_obstacle",
    "add_cylinder_obstacle",
    "add_sphere",
    "add_target_spheres",
    "add_trail",
    "rgb_to_int",
    "set_camera_view",
    "translation_pose",
]

Color = int | Sequence[float]

#: Root of everything this package draws.
ROOT_PREFIX = "pbvs"
#: Default prefix of the robot geometries: ``pbvs/robot/<geometry name>``.
ROBOT_PREFIX = f"{ROOT_PREFIX}/robot"
#: Default prefix of the target spheres.
TARGETS_PREFIX = f"{ROOT_PREFIX}/targets"
#: Default prefix of the obstacles.
OBSTACLES_PREFIX = f"{ROOT_PREFIX}/obstacles"
#: Default camera node; its transform is the camera pose in the world.
CAMERA_PREFIX = f"{ROOT_PREFIX}/camera"
#: Default path of the end-effector / camera trail.
TRAIL_PATH = f"{ROOT_PREFIX}/trail"

#: Transform of the three.js scene root in the browser page (rotation of
#: -pi/2 about X): ``matrixWorld = MESHCAT_TO_THREEJS @ T_meshcat``.
MESHCAT_TO_THREEJS = np.array(
    [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
)


# --------------------------------------------------------------------------
# small utilities
# --------------------------------------------------------------------------
def rgb_to_int(color: Color) -> int:
    """Convert a colour to the 0xRRGGBB integer meshcat materials expect.

    Args:
        color: RGB triple of floats in [0, 1] (an optional 4th alpha entry is
            ignored), or an integer already in 0xRRGGBB form.

    Returns:
        The colour as an integer in [0, 0xFFFFFF].
    """
    if isinstance(color, (int, np.integer)):
        return int(color) & 0xFFFFFF
    rgb = np.clip(np.asarray(color, dtype=float)[:3], 0.0, 1.0)
    r, g, b = (round(float(255 * c)) for c in rgb)
    return (r << 16) | (g << 8) | b


def _is_single_color(color: Any) -> bool:
    """True for one colour (int or RGB(A) in [0, 1]), False for a list of them."""
    if isinstance(color, (int, np.integer)):
        return True
    arr = np.asarray(color)
    return bool(arr.ndim == 1 and len(arr) in (3, 4) and np.all((arr >= 0) & (arr <= 1)))


def translation_pose(position: Sequence[float]) -> np.ndarray:
    """Homogeneous transform of a pure translation.

    Args:
        position: Translation, shape (3,), metres.

    Returns:
        4x4 transform with identity rotation.
    """
    T = np.eye(4)
    T[:3, 3] = np.asarray(position, dtype=float).reshape(3)
    return T


def _as_homogeneous(pose: Any) -> np.ndarray:
    """Return ``pose`` (``pin.SE3`` or array-like 4x4) as a float 4x4 array."""
    if isinstance(pose, pin.SE3):
        return np.array(pose.homogeneous, dtype=float)
    T = np.asarray(pose, dtype=float)
    if T.shape != (4, 4):
        raise ValueError(f"expected a 4x4 transform, got shape {T.shape}")
    return T


def _material(color: Color, opacity: float = 1.0, kind: str = "phong"):
    """Build a meshcat material of the given colour and opacity."""
    import meshcat.geometry as mg

    cls = {
        "phong": mg.MeshPhongMaterial,
        "lambert": mg.MeshLambertMaterial,
        "basic": mg.MeshBasicMaterial,
        "line": mg.LineBasicMaterial,
    }[kind]
    kwargs: dict[str, Any] = {"color": rgb_to_int(color)}
    if opacity < 1.0:
        kwargs.update(transparent=True, opacity=float(opacity))
    return cls(**kwargs)


def _intrinsic(T: np.ndarray):
    """Return a meshcat ``intrinsic_transform`` method returning ``T``.

    Pitfall: ``meshcat.geometry.Object.lower`` serialises the intrinsic
    transform with a row-major ``flatten()`` while three.js reads
    ``Matrix4.fromArray`` column-major.  Returning the transpose makes the
    browser see ``T`` itself.
    """
    Tt = np.array(T, dtype=float).T.copy()
    return lambda self: Tt


# --------------------------------------------------------------------------
# browser viewing camera
# --------------------------------------------------------------------------
def set_camera_view(vis: meshcat.Visualizer, position: Sequence[float]) -> None:
    """Place the browser's default viewing camera (it looks at the origin).

    The viewer's orbit controls always aim at the world origin; only the
    camera position can be set through meshcat commands.

    Args:
        vis: Visualizer (any sub-path; absolute camera path is used).
        position: Camera position in world (Z-up) coordinates, shape (3,), m.
    """
    x, y, z = (float(c) for c in position)
    # The camera node "rotated" is rotated by +pi/2 about X under the Y-up
    # scene root, so its local coordinates are (x, z, -y) of the world.
    vis["/Cameras/default/rotated/<object>"].set_property("position", [x, z, -y])


# --------------------------------------------------------------------------
# targets, obstacles, trail
# --------------------------------------------------------------------------
def add_sphere(
    vis: meshcat.Visualizer,
    path: str,
    diameter: float,
    color: Color,
    position: Sequence[float] | None = None,
    opacity: float = 1.0,
) -> str:
    """Add a sphere.

    Args:
        vis: Visualizer.
        path: Meshcat path of the sphere node.
        diameter: Sphere diameter, m.
        color: Colour (RGB in [0, 1] or 0xRRGGBB).
        position: Optional centre in the parent frame, shape (3,), m.
        opacity: 1 is opaque.

    Returns:
        ``path``.
    """
    import meshcat.geometry as mg

    vis[path].set_object(mg.Sphere(0.5 * float(diameter)), _material(color, opacity))
    if position is not None:
        vis[path].set_transform(translation_pose(position))
    return path


def add_target_spheres(
    vis: meshcat.Visualizer,
    centers: np.ndarray,
    diameter: float,
    color: Color | Sequence[Color],
    prefix: str = TARGETS_PREFIX,
) -> list[str]:
    """Add the target spheres (two in the PBVS task).

    Args:
        vis: Visualizer.
        centers: Sphere centres in the world, shape (N, 3), m.
        diameter: Diameter of every sphere, m.
        color: One colour for all spheres (0xRRGGBB or RGB in [0, 1]), or a
            list with one colour per sphere.
        prefix: Meshcat path prefix; spheres are ``<prefix>/sphere_<i>``.

    Returns:
        The N meshcat paths.
    """
    centers = np.asarray(centers, dtype=float).reshape(-1, 3)
    colors = [color] * len(centers) if _is_single_color(color) else list(color)
    if len(colors) != len(centers):
        raise ValueError(f"got {len(colors)} colours for {len(centers)} spheres")
    return [
        add_sphere(vis, f"{prefix}/sphere_{i}", diameter, c, position=p)
        for i, (p, c) in enumerate(zip(centers, colors, strict=True))
    ]


def add_cylinder_obstacle(
    vis: meshcat.Visualizer,
    name: str,
    center_xy: Sequence[float],
    radius: float,
    height: float,
    color: Color = (0.6, 0.3, 0.2),
    opacity: float = 1.0,
    prefix: str = OBSTACLES_PREFIX,
) -> str:
    """Add a vertical cylinder standing on the ground (z = 0).

    The node transform is a pure translation to the cylinder centre
    ``(x, y, height/2)``; the Y-up three.js cylinder is turned Z-up by an
    intrinsic rotation of the mesh.

    Args:
        vis: Visualizer.
        name: Obstacle name; node is ``<prefix>/<name>``.
        center_xy: Axis position on the ground, shape (2,), m.
        radius: Radius, m.
        height: Height, m.
        color: Colour.
        opacity: 1 is opaque.
        prefix: Meshcat path prefix.

    Returns:
        The meshcat path of the obstacle.
    """
    import meshcat.geometry as mg

    rot_y_to_z = np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])
    ZCylinder = type("ZCylinder", (mg.Cylinder,), {"intrinsic_transform": _intrinsic(rot_y_to_z)})
    path = f"{prefix}/{name}"
    vis[path].set_object(ZCylinder(float(height), float(radius)), _material(color, opacity))
    x, y = (float(c) for c in center_xy)
    vis[path].set_transform(translation_pose([x, y, 0.5 * float(height)]))
    return path


def add_box_obstacle(
    vis: meshcat.Visualizer,
    name: str,
    center_xy: Sequence[float],
    size: Sequence[float],
    yaw: float = 0.0,
    color: Color = (0.5, 0.5, 0.55),
    opacity: float = 1.0,
    prefix: str = OBSTACLES_PREFIX,
) -> str:
    """Add a box resting on the ground (z = 0).

    Args:
        vis: Visualizer.
        name: Obstacle name; node is ``<prefix>/<name>``.
        center_xy: Centre of the footprint, shape (2,), m.
        size: Edge lengths (sx, sy, sz) along the box axes, shape (3,), m.
        yaw: Rotation about the world z axis, rad.
        color: Colour.
        opacity: 1 is opaque.
        prefix: Meshcat path prefix.

    Returns:
        The meshcat path of the obstacle.
    """
    import meshcat.geometry as mg

    size = [float(s) for s in size]
    path = f"{prefix}/{name}"
    vis[path].set_object(mg.Box(size), _material(color, opacity))
    T = translation_pose([float(center_xy[0]), float(center_xy[1]), 0.5 * size[2]])
    c, s = math.cos(yaw), math.sin(yaw)
    T[:2, :2] = [[c, -s], [s, c]]
    vis[path].set_transform(T)
    return path


def add_trail(
    vis: meshcat.Visualizer,
    points: np.ndarray,
    color: Color = (1.0, 0.8, 0.0),
    path: str = TRAIL_PATH,
    linewidth: float = 2.0,
) -> str:
    """Add a polyline (e.g. the end-effector or camera path).

    Args:
        vis: Visualizer.
        points: Vertices in the parent frame (world for the default path),
            shape (N, 3), m, N >= 2.
        color: Line colour.
        path: Meshcat path of the line.
        linewidth: Line width in px (browsers usually render 1 px only).

    Returns:
        ``path``.
    """
    import meshcat.geometry as mg

    pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    if len(pts) < 2:
        raise ValueError("a trail needs at least 2 points")
    material = mg.LineBasicMaterial(color=rgb_to_int(color), linewidth=float(linewidth))
    vis[path].set_object(mg.Line(mg.PointsGeometry(pts.T), material))
    return path
