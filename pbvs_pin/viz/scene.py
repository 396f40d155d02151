"""Meshcat scene helpers and a standalone HTML replay writer.

Everything here works on plain Pinocchio objects (``pin.Model``,
``pin.GeometryModel``, ``pin.SE3`` / 4x4 arrays) and on a
``meshcat.Visualizer``.  :mod:`meshcat` and :mod:`pinocchio.visualize` are
imported lazily inside the functions that need them, so importing this module
never pulls meshcat in, and the control core must never import this module.

Conventions
-----------
* Units are SI: metres, radians, seconds.  Image quantities are in pixels.
* Poses are 4x4 homogeneous transforms ``T`` (numpy, float) mapping child
  coordinates to parent coordinates; for objects at the top of the ``pbvs``
  tree the parent is the world (Pinocchio's universe frame).
* Meshcat paths are given *relative to the visualizer root* (``/meshcat``),
  e.g. ``"pbvs/robot/wrist_3_link_0"``.  Pose dictionaries map such paths to
  transforms.
* Meshcat is Z-up like Pinocchio.  The three.js scene of the browser viewer is
  Y-up; the viewer rotates its scene root by -pi/2 about X, so a world matrix
  read in the page (``object.matrixWorld``) equals
  ``MESHCAT_TO_THREEJS @ T_meshcat``.
* Cameras follow the optical-frame convention of :mod:`pbvs_pin.camera`:
  +z forward (optical axis), +x right, +y down.  The image helpers here take
  *pixels* ``(col, row)`` from the top-left corner, which back-project to the
  ray ``((col - cx) / f, (row - cy) / f, 1)``.  Image coordinates ``xi`` in
  the paper's eq. (2) sign convention (``xi = -(f / z) [x, y]``) convert with
  ``pbvs_pin.camera.CameraIntrinsics.to_pixel(xi)`` (``col = cx - u``,
  ``row = cy - v``).
* Colours are RGB triples in [0, 1] or 0xRRGGBB integers.

Typical use::

    with open_visualizer() as vis:
        robot = RobotScene(vis, model, visual_model)
        add_target_spheres(vis, centers, diameter=0.05, color=(1, 0, 0))
        poses = robot.trajectory_poses(qs)            # {path: (T, 4, 4)}
        write_replay_html("run.html", vis, times, poses)
"""

from __future__ import annotations

import contextlib
import io
import math
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
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
    "RobotScene",
    "add_box_obstacle",
    "add_camera_frustum",
    "add_cylinder_obstacle",
    "add_image_plane",
    "add_sphere",
    "add_target_spheres",
    "add_trail",
    "feature_point_poses",
    "frustum_corners",
    "open_visualizer",
    "pixels_to_image_plane",
    "rgb_to_int",
    "set_camera_view",
    "translation_pose",
    "write_replay_html",
]

Color = int | Sequence[float]
PoseSource = Mapping[str, np.ndarray] | Callable[[int, float], Mapping[str, np.ndarray]]

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


@contextlib.contextmanager
def open_visualizer(zmq_url: str | None = None) -> Iterator[meshcat.Visualizer]:
    """Start (or connect to) a meshcat server and stop it on exit.

    ``Visualizer.static_html()`` asks the running zmq server for the scene,
    so a server must be alive while a replay is written.  With
    ``zmq_url=None`` meshcat starts its own server on the loopback interface;
    this context manager kills exactly that process when leaving.

    Args:
        zmq_url: URL of an already running ``meshcat-server``; ``None`` starts
            a private one.

    Yields:
        A connected ``meshcat.Visualizer`` rooted at ``/meshcat``.
    """
    import meshcat

    with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints its URL
        vis = meshcat.Visualizer(zmq_url=zmq_url)
    try:
        yield vis
    finally:
        window = vis.window
        with contextlib.suppress(Exception):
            window.zmq_socket.close(linger=0)
        proc = getattr(window, "server_proc", None)
        if proc is not None and proc.poll() is None:
            proc.kill()
            with contextlib.suppress(Exception):
                proc.wait(timeout=10)


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
# robot
# --------------------------------------------------------------------------
# pinocchio's MeshcatVisualizer.loadViewerGeometryObject() never raises: it
# reports unconvertible geometries with warnings containing these phrases.
_LOAD_FAILURE_KEYS = (
    "not supported",
    "supported only",
    "Unsupported",
    "Unknown mesh",
    "Error while loading",
)


class RobotScene:
    """A robot's visual geometries in meshcat, posed from Pinocchio.

    Every ``pin.GeometryObject`` of the visual model is loaded at
    ``<prefix>/<geometry name>`` (meshes: STL/DAE/OBJ files, primitives:
    Box/Cylinder/Sphere/Capsule/... from a URDF) using the converters of
    :class:`pinocchio.visualize.MeshcatVisualizer`.  The transform of each
    such node is the geometry placement ``oMg`` (times its ``meshScale``), so
    the node's world matrix in the browser is Pinocchio's placement.

    Attributes:
        vis: The meshcat visualizer the robot was loaded into.
        model: The kinematic model.
        visual_model: The visual geometry model.
        prefix: Meshcat path prefix of the robot.
        paths: Geometry name -> meshcat path, for every loaded geometry.
        failed: Names of geometries that could not be converted (only
            non-empty when ``strict=False``).
    """

    def __init__(
        self,
        vis: meshcat.Visualizer,
        model: pin.Model,
        visual_model: pin.GeometryModel,
        prefix: str = ROBOT_PREFIX,
        color: Sequence[float] | None = None,
        strict: bool = True,
    ) -> None:
        """Load all visual geometries into ``vis``.

        Args:
            vis: Visualizer; ``prefix`` is relative to its path.
            model: Kinematic model, ``nq`` configuration entries.
            visual_model: VISUAL geometry model of ``model``.
            prefix: Meshcat path prefix, e.g. ``"pbvs/robot"``.
            color: Optional RGBA override in [0, 1], shape (4,).  Applied to
                primitives and STL/OBJ meshes; DAE files keep their own
                materials unless the geometry sets ``overrideMaterial``.
            strict: Raise ``RuntimeError`` if a geometry cannot be converted
                (otherwise it is skipped and listed in ``failed``).

        Raises:
            RuntimeError: ``strict`` and some geometry failed to load.
        """
        from pinocchio.visualize import MeshcatVisualizer

        self.vis = vis
        self.model = model
        self.visual_model = visual_model
        self.prefix = prefix.strip("/")
        self.data = model.createData()
        self.geom_data = visual_model.createData()

        helper = MeshcatVisualizer(model, None, visual_model, data=self.data)
        helper.viewer = vis
        # getViewerNodeName() returns viewerVisualGroupName + "/" + name.
        helper.viewerRootNodeName = self.prefix
        helper.viewerVisualGroupName = self.prefix
        self._helper = helper

        self.paths: dict[str, str] = {}
        self.failed: list[str] = []
        rgba = None if color is None else list(np.asarray(color, dtype=float))
        if rgba is not None and len(rgba) == 3:
            rgba.append(1.0)
        for geom in visual_model.geometryObjects:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                helper.loadViewerGeometryObject(geom, pin.GeometryType.VISUAL, rgba)
            # pinocchio reports conversion failures only as warnings.
            problems = [
                str(w.message)
                for w in caught
                if any(key in str(w.message) for key in _LOAD_FAILURE_KEYS)
            ]
            if problems:
                self.failed.append(geom.name)
                if strict:
                    raise RuntimeError(f"could not load geometry {geom.name!r}: {problems[0]}")
                continue
            self.paths[geom.name] = f"{self.prefix}/{geom.name}"

    def poses(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """World poses of all loaded geometries at configuration ``q``.

        Args:
            q: Configuration, shape (model.nq,).

        Returns:
            Meshcat path -> 4x4 transform ``oMg`` (world <- geometry) with
            the geometry's ``meshScale`` applied to the rotation columns.
        """
        q = np.asarray(q, dtype=float).reshape(self.model.nq)
        pin.forwardKinematics(self.model, self.data, q)
        pin.updateGeometryPlacements(self.model, self.data, self.visual_model, self.geom_data)
        out: dict[str, np.ndarray] = {}
        for gid, geom in enumerate(self.visual_model.geometryObjects):
            path = self.paths.get(geom.name)
            if path is None:
                continue
            M = self.geom_data.oMg[gid]
            T = np.array(M.homogeneous)
            shape = geom.geometry
            # Same special case as pinocchio's MeshcatVisualizer: planes are
            # drawn at their offset d along the normal.
            if type(shape).__name__ in ("Plane", "Halfspace"):
                T[:3, 3] += M.rotation @ (shape.d * np.asarray(shape.n))
            T[:3, :3] = T[:3, :3] * np.asarray(geom.meshScale, dtype=float)[None, :]
            out[path] = T
        return out

    def trajectory_poses(self, qs: np.ndarray) -> dict[str, np.ndarray]:
        """World poses of all loaded geometries along a trajectory.

        Args:
            qs: Configurations, shape (T, model.nq).

        Returns:
            Meshcat path -> stacked transforms, shape (T, 4, 4).
        """
        qs = np.asarray(qs, dtype=float)
        if qs.ndim != 2 or qs.shape[1] != self.model.nq:
            raise ValueError(f"qs must have shape (T, {self.model.nq}), got {qs.shape}")
        frames = [self.poses(q) for q in qs]
        return {p: np.stack([f[p] for f in frames]) for p in self.paths.values()}

    def display(self, q: np.ndarray) -> None:
        """Set the live meshcat transforms of all geometries for ``q``.

        Args:
            q: Configuration, shape (model.nq,).
        """
        for path, T in self.poses(q).items():
            self.vis[path].set_transform(T)

    def set_visible(self, visible: bool) -> None:
        """Show or hide the whole robot (property ``visible`` of the prefix)."""
        self.vis[self.prefix].set_property("visible", bool(visible))


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


# --------------------------------------------------------------------------
# camera: frustum, image plane, feature points
# --------------------------------------------------------------------------
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
    here with ``pose`` or per frame in :func:`write_replay_html`).

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


# --------------------------------------------------------------------------
# replay
# --------------------------------------------------------------------------
def _decompose(T: np.ndarray) -> tuple[list[float], np.ndarray, list[float]]:
    """Split a 4x4 transform into position, xyzw quaternion and column scale."""
    scale = np.linalg.norm(T[:3, :3], axis=0)
    if np.any(scale <= 0):
        raise ValueError("degenerate transform (zero scale)")
    R = T[:3, :3] / scale[None, :]
    if np.linalg.det(R) < 0:
        raise ValueError("mirroring transforms cannot be animated")
    quat = pin.Quaternion(R).normalized().coeffs()  # x, y, z, w
    return list(map(float, T[:3, 3])), np.array(quat, dtype=float), list(map(float, scale))


def _collect_poses(times: np.ndarray, poses: PoseSource) -> dict[str, np.ndarray]:
    """Normalise ``poses`` to ``{path: (T, 4, 4)}``."""
    n = len(times)
    if callable(poses):
        per_frame = [poses(k, float(t)) for k, t in enumerate(times)]
        keys = list(per_frame[0].keys())
        for k, frame in enumerate(per_frame):
            if set(frame.keys()) != set(keys):
                raise ValueError(f"frame {k} animates different paths than frame 0")
        return {p: np.stack([_as_homogeneous(f[p]) for f in per_frame]) for p in keys}
    out: dict[str, np.ndarray] = {}
    for p, arr in poses.items():
        arr = np.asarray(arr, dtype=float)
        if arr.shape != (n, 4, 4):
            raise ValueError(f"poses[{p!r}] must have shape ({n}, 4, 4), got {arr.shape}")
        out[p] = arr
    return out


def write_replay_html(
    path: str | Path,
    vis: meshcat.Visualizer,
    times: np.ndarray,
    poses: PoseSource,
    fps: float = 30.0,
    play: bool = True,
    repetitions: int = 1,
) -> Path:
    """Animate objects and write a standalone HTML replay.

    For every frame ``k`` and every animated path, the object's position and
    quaternion (and scale, if not 1) are keyed at time ``times[k]`` in a
    ``meshcat.animation.Animation``; frame 0 is also set as the static
    transform.  The animation is sent with ``vis.set_animation(anim,
    play=play)`` and ``vis.static_html()`` (which needs the meshcat server
    that ``vis`` talks to) is written to ``path``.  The file embeds the viewer
    JavaScript, all meshes and the animation, so it opens from ``file://``
    without any server.  In the page, ``viewer.animator.seek(t)`` jumps to
    time ``t`` (seconds); three.js interpolates linearly (slerp for
    rotations) between keys.

    Args:
        path: Output HTML file.
        vis: Visualizer holding the scene (objects must already be added).
        times: Key times, shape (T,), seconds, non-negative, increasing.
        poses: Either ``{path: array (T, 4, 4)}`` or a callable
            ``poses(k, t) -> {path: 4x4 or pin.SE3}`` called for every frame
            (all frames must return the same paths).  Paths are relative to
            ``vis`` (e.g. ``"pbvs/robot/base_link_0"``); a node's transform is
            relative to its parent node.
        fps: Nominal frame rate of the clip; only changes the key numbering
            (frame = t * fps), not the timing.
        play: Start playing on load.  Must be True for the page's
            ``viewer.animator.seek`` to work: the three.js actions exist
            either way, but only ``action.play()`` activates them in the
            mixer, and seeking an inactive action moves nothing.
        repetitions: Number of plays before stopping.

    Returns:
        The path of the written file.
    """
    from meshcat.animation import Animation

    times = np.asarray(times, dtype=float).reshape(-1)
    if times.size == 0:
        raise ValueError("times is empty")
    if np.any(times < 0) or np.any(np.diff(times) <= 0):
        raise ValueError("times must be non-negative and strictly increasing")
    tracks = _collect_poses(times, poses)

    anim = Animation(default_framerate=fps)
    for obj_path, arr in tracks.items():
        decomposed = [_decompose(T) for T in arr]
        has_scale = any(np.max(np.abs(np.array(s) - 1.0)) > 1e-9 for _, _, s in decomposed)
        prev_q = None
        node = anim.at_frame(vis, 0)[obj_path]
        for t, (pos, quat, scale) in zip(times, decomposed, strict=True):
            if prev_q is not None and float(np.dot(prev_q, quat)) < 0.0:
                quat = -quat  # keep the quaternion track continuous
            prev_q = quat
            node.current_frame = float(t) * fps
            node.set_property("position", "vector3", pos)
            node.set_property("quaternion", "quaternion", list(map(float, quat)))
            if has_scale:
                node.set_property("scale", "vector3", scale)
        vis[obj_path].set_transform(arr[0])

    vis.set_animation(anim, play=play, repetitions=repetitions)
    html = vis.static_html()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(html, encoding="utf-8")
    return out
