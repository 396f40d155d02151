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

A file needs no server: :func:`offline_visualizer` records the scene in this
process and its ``static_html()`` is the page a server would return.  A
closed-loop run is drawn by :class:`RunScene` (robot, target, obstacles,
camera frustum, image plane, trails), shared by the live view
(:mod:`pbvs_pin.viz.live`) and the replay (:mod:`pbvs_pin.viz.replay`).
Starting a server that cannot start raises
:class:`~pbvs_pin.exceptions.ViewerUnavailable`.
"""

from __future__ import annotations

import contextlib
import io
import math
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

if TYPE_CHECKING:  # pragma: no cover - typing only
    import meshcat

    from pbvs_pin.robot import MobileManipulator

__all__ = [
    "CAMERA_PREFIX",
    "FRUSTUM_DEPTH",
    "IMAGE_PLANE_DEPTH",
    "MESHCAT_TO_THREEJS",
    "OBSTACLES_PREFIX",
    "PLATFORM_TRAIL_PATH",
    "ROBOT_PREFIX",
    "ROOT_PREFIX",
    "TARGETS_PREFIX",
    "TARGET_TRAIL_PATH",
    "TRAIL_PATH",
    "VIEWER_ADVICE",
    "RobotScene",
    "RunFacts",
    "RunScene",
    "add_box_obstacle",
    "add_camera_frustum",
    "add_camera_triad",
    "add_cylinder_obstacle",
    "add_image_plane",
    "add_sphere",
    "add_target_spheres",
    "add_trail",
    "feature_point_poses",
    "frustum_corners",
    "offline_visualizer",
    "open_visualizer",
    "pixels_to_image_plane",
    "rgb_to_int",
    "set_camera_view",
    "start_visualizer",
    "stop_visualizer",
    "translation_pose",
    "two_sphere_points",
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


# --------------------------------------------------------------------------
# viewers: served (a meshcat server) or offline (a file only)
# --------------------------------------------------------------------------
VIEWER_ADVICE = (
    "write a standalone HTML file instead, which needs no server: "
    "`pbvs-pin view ROBOT --html FILE`, or `pbvs-pin run SCENARIO --html FILE` "
    "(the replay is written next to the results); then open that file in a browser"
)
"""What :class:`~pbvs_pin.exceptions.ViewerUnavailable` advises by default."""


def _last_line(text: str) -> str:
    """The last non-empty line of ``text`` (meshcat reports server failures on stdout)."""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[-1] if lines else ""


def start_visualizer(
    zmq_url: str | None = None,
    timeout: float | None = None,
    advice: str = VIEWER_ADVICE,
) -> meshcat.Visualizer:
    """Start a private meshcat server (or connect to one) and return its visualizer.

    Stop it with :func:`stop_visualizer`.  Meshcat's own messages (its URL,
    and the server's output when it dies) are captured, not printed; the
    error message quotes the last line of them.

    Args:
        zmq_url: URL of an already running ``meshcat-server``; ``None`` starts
            a private one on the loopback interface.
        timeout: If given, every later command waits at most this long for
            the server [s] and then raises ``zmq.Again`` instead of blocking
            forever on a dead server.
        advice: What the error message tells the user to do instead.

    Returns:
        A connected ``meshcat.Visualizer`` rooted at ``/meshcat``.

    Raises:
        ViewerUnavailable: If the server cannot be started or reached (zmq
            port or permission errors, ``meshcat.servers.zmqserver`` missing
            or crashing, ...).
    """
    from pbvs_pin.exceptions import ViewerUnavailable

    captured = io.StringIO()
    try:
        import meshcat

        with contextlib.redirect_stdout(captured):  # meshcat prints its URL
            vis = meshcat.Visualizer(zmq_url=zmq_url)
    # meshcat reports failures as RuntimeError, ValueError, zmq.ZMQError, OSError or a bare
    # Exception from the server subprocess: all of them mean "no viewer".
    except Exception as err:
        detail = _last_line(captured.getvalue())
        reason = f"{type(err).__name__}: {err}".replace("\n", " ")
        if detail and detail not in reason:
            reason = f"{reason} ({detail})"
        raise ViewerUnavailable(f"could not start the meshcat server: {reason}", advice) from err
    if timeout is not None:
        import zmq

        socket = vis.window.zmq_socket
        milliseconds = max(1, round(1000 * float(timeout)))
        socket.setsockopt(zmq.RCVTIMEO, milliseconds)
        socket.setsockopt(zmq.SNDTIMEO, milliseconds)
        socket.setsockopt(zmq.LINGER, 0)
    return vis


def stop_visualizer(vis: meshcat.Visualizer) -> None:
    """Close the connection of ``vis`` and kill the server process it started (if any).

    Never raises; a visualizer from :func:`offline_visualizer` is left alone.

    Args:
        vis: A visualizer from :func:`start_visualizer`.
    """
    window = vis.window
    socket = getattr(window, "zmq_socket", None)
    if socket is not None:
        with contextlib.suppress(Exception):
            socket.close(linger=0)
    proc = getattr(window, "server_proc", None)
    if proc is not None and proc.poll() is None:
        proc.kill()
        with contextlib.suppress(Exception):
            proc.wait(timeout=10)


@contextlib.contextmanager
def open_visualizer(zmq_url: str | None = None) -> Iterator[meshcat.Visualizer]:
    """Start (or connect to) a meshcat server and stop it on exit.

    ``Visualizer.static_html()`` asks the running zmq server for the scene,
    so a server must be alive while a replay is written (or use
    :func:`offline_visualizer`, which needs none).  With ``zmq_url=None``
    meshcat starts its own server on the loopback interface; this context
    manager kills exactly that process when leaving.

    Args:
        zmq_url: URL of an already running ``meshcat-server``; ``None`` starts
            a private one.

    Yields:
        A connected ``meshcat.Visualizer`` rooted at ``/meshcat``.

    Raises:
        ViewerUnavailable: If the server cannot be started or reached.
    """
    vis = start_visualizer(zmq_url)
    try:
        yield vis
    finally:
        stop_visualizer(vis)


# The page meshcat 0.3.2's server returns for "get_scene" (zmqserver.py), verbatim, so that
# an offline scene gives byte for byte the file the server would.
_STATIC_HTML = """
                <!DOCTYPE html>
                <html>
                    <head> <meta charset=utf-8> <title>MeshCat</title> </head>
                    <body>
                        <div id="meshcat-pane">
                        </div>
                        <script>
                            {mainminjs}
                        </script>
                        <script>
                            var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
                            {commands}
                        </script>
                         <style>
                            body {{margin: 0; }}
                            #meshcat-pane {{
                                width: 100vw;
                                height: 100vh;
                                overflow: hidden;
                            }}
                        </style>
                        <script id="embedded-json"></script>
                    </body>
                </html>
            """  # noqa: E501


class _SceneRecorder:
    """Stands in for meshcat's ``ViewerWindow``: keeps the scene tree in this process.

    It stores every command exactly as meshcat's zmq server does (last object and transform
    of each node, its properties in order, its animation) and builds the same standalone page
    from them, so writing HTML needs no server, no port and no subprocess.
    """

    server_proc = None
    zmq_url = None
    web_url = None

    def __init__(self) -> None:
        from meshcat.servers.tree import SceneTree

        self.tree = SceneTree()

    def send(self, command: Any) -> None:
        """Record one meshcat command (``SetObject``, ``SetTransform``, ...)."""
        import umsgpack
        from meshcat.servers.tree import SceneTree, find_node

        data = command.lower()
        kind = data["type"]
        path = [name for name in data["path"].split("/") if name]
        packed = umsgpack.packb(data)
        if kind == "delete":
            if path:
                find_node(self.tree, path[:-1]).pop(path[-1], None)
            else:
                self.tree = SceneTree()
            return
        node = find_node(self.tree, path)
        if kind == "set_transform":
            node.transform = packed
        elif kind == "set_object":
            node.object = packed
            node.properties = []
        elif kind == "set_property":
            node.properties.append(packed)
        elif kind == "set_animation":
            node.animation = packed
        else:
            raise ValueError(f"an offline scene cannot handle meshcat command {kind!r}")

    def get_scene(self) -> str:
        """The standalone HTML page of the recorded scene."""
        import meshcat.servers.zmqserver as server
        from meshcat.servers.tree import walk

        commands = ""
        for node in walk(self.tree):
            for blob in (node.object, *node.properties, node.transform, node.animation):
                if blob is not None:
                    commands += server.create_command(blob)
        script = Path(server.VIEWER_ROOT) / "main.min.js"
        return _STATIC_HTML.format(mainminjs=script.read_text(encoding="utf-8"), commands=commands)


def offline_visualizer() -> meshcat.Visualizer:
    """A visualizer that records the scene in-process, for writing standalone HTML.

    It accepts every scene command of a served visualizer and its
    ``static_html()`` returns the page a meshcat server would return for the
    same commands, but there is no server and no URL: nothing can fail to
    start and nothing needs stopping.  Use it whenever only a file is wanted.

    Returns:
        A ``meshcat.Visualizer`` rooted at ``/meshcat``.
    """
    import meshcat

    return meshcat.Visualizer(window=_SceneRecorder())


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


def _shaped(placement: pin.SE3, geom: pin.GeometryObject) -> np.ndarray:
    """Transform of a geometry node drawn at ``placement``, with its offset and scale.

    Same special case as pinocchio's MeshcatVisualizer: planes are drawn at
    their offset ``d`` along the normal; ``meshScale`` scales the rotation
    columns.
    """
    T = np.array(placement.homogeneous)
    shape = geom.geometry
    if type(shape).__name__ in ("Plane", "Halfspace"):
        T[:3, 3] += placement.rotation @ (shape.d * np.asarray(shape.n))
    T[:3, :3] = T[:3, :3] * np.asarray(geom.meshScale, dtype=float)[None, :]
    return T


class RobotScene:
    """A robot's visual geometries in meshcat, posed from Pinocchio.

    Every ``pin.GeometryObject`` of the visual model is loaded at
    ``<prefix>/<geometry name>`` (meshes: STL/DAE/OBJ files, primitives:
    Box/Cylinder/Sphere/Capsule/... from a URDF) using the converters of
    :class:`pinocchio.visualize.MeshcatVisualizer`.  The transform of each
    such node is the geometry placement ``oMg`` (times its ``meshScale``), so
    the node's world matrix in the browser is Pinocchio's placement.

    With ``group_by_joint=True`` the geometries are loaded at
    ``<prefix>/<joint name>/<geometry name>`` instead, each with its fixed
    placement in the joint frame (``jMg`` times ``meshScale``), and only the
    joint nodes move (transform ``oMi``).  The world matrix of every geometry
    node is the same, but a pose update takes one transform per joint rather
    than one per geometry (TIAGo: 9 instead of 65).

    Attributes:
        vis: The meshcat visualizer the robot was loaded into.
        model: The kinematic model.
        visual_model: The visual geometry model.
        prefix: Meshcat path prefix of the robot.
        paths: Geometry name -> meshcat path, for every loaded geometry.
        joint_paths: Joint index -> meshcat path of its node, for every moving
            joint carrying a loaded geometry (empty unless ``group_by_joint``).
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
        group_by_joint: bool = False,
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
            group_by_joint: Put geometries under one node per joint (see above).

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

        self.group_by_joint = bool(group_by_joint)
        self.paths: dict[str, str] = {}
        self.joint_paths: dict[int, str] = {}
        self.failed: list[str] = []
        rgba = None if color is None else list(np.asarray(color, dtype=float))
        if rgba is not None and len(rgba) == 3:
            rgba.append(1.0)
        for geom in visual_model.geometryObjects:
            group = self.prefix
            if self.group_by_joint:
                group = f"{self.prefix}/{model.names[geom.parentJoint].replace('/', '_')}"
                helper.viewerVisualGroupName = group
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
            self.paths[geom.name] = f"{group}/{geom.name}"
            if self.group_by_joint:
                vis[self.paths[geom.name]].set_transform(_shaped(geom.placement, geom))
                if geom.parentJoint > 0:
                    self.joint_paths[geom.parentJoint] = group

    def poses(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """World poses of all loaded geometries at configuration ``q``.

        Args:
            q: Configuration, shape (model.nq,).

        Returns:
            Meshcat path -> 4x4 transform ``oMg`` (world <- geometry) with
            the geometry's ``meshScale`` applied to the rotation columns; with
            ``group_by_joint``, joint node path -> ``oMi`` (world <- joint).
        """
        q = np.asarray(q, dtype=float).reshape(self.model.nq)
        pin.forwardKinematics(self.model, self.data, q)
        if self.group_by_joint:
            return {
                path: np.array(self.data.oMi[joint].homogeneous)
                for joint, path in self.joint_paths.items()
            }
        pin.updateGeometryPlacements(self.model, self.data, self.visual_model, self.geom_data)
        out: dict[str, np.ndarray] = {}
        for gid, geom in enumerate(self.visual_model.geometryObjects):
            path = self.paths.get(geom.name)
            if path is None:
                continue
            out[path] = _shaped(self.geom_data.oMg[gid], geom)
        return out

    def trajectory_poses(self, qs: np.ndarray) -> dict[str, np.ndarray]:
        """World poses of all loaded geometries (or joint nodes) along a trajectory.

        Args:
            qs: Configurations, shape (T, model.nq).

        Returns:
            Meshcat path -> stacked transforms, shape (T, 4, 4).
        """
        qs = np.asarray(qs, dtype=float)
        if qs.ndim != 2 or qs.shape[1] != self.model.nq:
            raise ValueError(f"qs must have shape (T, {self.model.nq}), got {qs.shape}")
        frames = [self.poses(q) for q in qs]
        return {p: np.stack([f[p] for f in frames]) for p in frames[0]}

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


# --------------------------------------------------------------------------
# the scene of a closed-loop run (shared by the live view and the replay)
# --------------------------------------------------------------------------
FRUSTUM_DEPTH = 0.2
"""Length of a run's camera frustum along the optical axis [m]."""
IMAGE_PLANE_DEPTH = 0.15
"""Distance of a run's virtual image plane in front of the camera [m] (inside the frustum)."""
TRIAD_SCALE = 0.08
"""Axis length of the camera triad [m]."""
PLATFORM_TRAIL_PATH = f"{TRAIL_PATH}_platform"
"""Meshcat path of the platform's path on the ground."""
TARGET_TRAIL_PATH = f"{TRAIL_PATH}_target"
"""Meshcat path of the target's path (midpoint of the two sphere centres)."""
TRAIL_HEIGHT = 0.01
"""Height of the platform trail above the ground [m], so that it is not hidden by it."""
SPHERE_COLORS = ((0.9, 0.1, 0.1), (0.1, 0.3, 0.9))
"""Upper and lower target sphere colours."""
RUN_VIEW = (-0.9, -1.3, 0.9)
"""Initial position of the browser's viewing camera for a run [m] (it looks at the origin)."""


def two_sphere_points(xi: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Image points of both spheres from the paper's features ``xi = [u1, v1, v2]``.

    The features leave out ``u2``; the two spheres are vertically aligned, so
    the lower one is drawn at ``u2 = u1``.

    Args:
        xi: Features in the paper's sign convention [px]. Shape (3,).

    Returns:
        ``[[u1, v1], [u1, v2]]`` [px]. Shape (2, 2).
    """
    u1, v1, v2 = np.asarray(xi, dtype=float).reshape(3)
    return np.array([[u1, v1], [u1, v2]])


@dataclass(frozen=True)
class RunFacts:
    """What a run's scene is drawn from, besides the robot (a scenario or a log's meta).

    Attributes:
        target_diameter: Diameter of each target sphere [m].
        target_separation: Distance between the two sphere centres [m].
        desired_points: Desired image points ``[u, v]`` of both spheres, in the
            paper's sign convention [px]. Shape (2, 2).
        obstacles: Obstacle tables as in a scenario: ``kind`` ("circle" or
            "box"), ``x``, ``y`` [m], then ``radius`` [m] or ``size_x``,
            ``size_y`` [m] and ``yaw`` [rad], and an optional ``height`` [m].
    """

    target_diameter: float
    target_separation: float
    desired_points: np.ndarray
    obstacles: tuple[Mapping[str, Any], ...] = ()


def _add_obstacle(vis: meshcat.Visualizer, index: int, table: Mapping[str, Any]) -> str:
    """Draw one scenario obstacle table; return its path."""
    height = float(table.get("height", 0.4))
    name = f"obstacle_{index}"
    if table["kind"] == "circle":
        return add_cylinder_obstacle(vis, name, (table["x"], table["y"]), table["radius"], height)
    size = (table["size_x"], table["size_y"], height)
    return add_box_obstacle(vis, name, (table["x"], table["y"]), size, table.get("yaw", 0.0))


class RunScene:
    """The scene of a closed-loop run, built once and posed per instant.

    It holds the robot (:class:`RobotScene`, one node per joint), the two target spheres, the
    obstacles, the camera node (frustum, axis triad and a virtual image plane
    with the fixed desired points and the moving current points) and two
    trails (platform and target paths).  The live view sends
    :meth:`poses` to a served visualizer at every update; the replay keys
    them into an animation.  Both therefore draw exactly the same scene.

    Attributes:
        vis: The visualizer the scene lives in.
        robot: The robot drawn (a :class:`pbvs_pin.robot.MobileManipulator`).
        facts: Target, desired features and obstacles.
        robot_scene: The robot's geometries.
        spheres: Meshcat paths of the upper and lower sphere.
        obstacles: Meshcat paths of the obstacles.
        frustum: Meshcat path of the frustum.
        image: ``{"plane": [...], "desired": [...], "current": [...]}`` paths.
    """

    def __init__(
        self,
        vis: meshcat.Visualizer,
        robot: MobileManipulator,
        facts: RunFacts,
        strict: bool = False,
    ) -> None:
        """Draw everything (the robot at its home configuration, spheres at the origin).

        Args:
            vis: Visualizer (served or offline).
            robot: The robot; its ``camera`` gives the intrinsics drawn.
            facts: Target, desired features and obstacles.
            strict: Raise if a robot geometry cannot be converted (otherwise it
                is skipped and listed in ``robot_scene.failed``).

        Raises:
            RuntimeError: ``strict`` and some geometry failed to load.
        """
        self.vis = vis
        self.robot = robot
        self.facts = facts
        camera = robot.camera
        self.robot_scene = RobotScene(
            vis, robot.model, robot.visual_model, strict=strict, group_by_joint=True
        )
        self.spheres = add_target_spheres(
            vis, np.zeros((2, 3)), facts.target_diameter, list(SPHERE_COLORS)
        )
        self.obstacles = [_add_obstacle(vis, i, o) for i, o in enumerate(facts.obstacles)]
        intrinsics = (camera.focal_px, camera.width, camera.height)
        self.frustum = add_camera_frustum(
            vis, *intrinsics, FRUSTUM_DEPTH, principal_point=camera.principal_point
        )
        add_camera_triad(vis, TRIAD_SCALE)
        plane_width = camera.width / camera.focal_px * IMAGE_PLANE_DEPTH
        desired = camera.to_pixel(np.asarray(facts.desired_points, dtype=float).reshape(2, 2))
        self.image = add_image_plane(
            vis, *intrinsics, desired, depth=IMAGE_PLANE_DEPTH,
            point_diameter=0.04 * plane_width, principal_point=camera.principal_point,
        )  # fmt: skip
        self.trails = (PLATFORM_TRAIL_PATH, TARGET_TRAIL_PATH)
        set_camera_view(vis, RUN_VIEW)
        self._nodes: dict[str, meshcat.Visualizer] = {}
        self._sent: dict[str, np.ndarray] = {}

    def image_point_poses(self, points: npt.ArrayLike) -> dict[str, np.ndarray]:
        """Transforms of the current feature points in the camera frame.

        Args:
            points: Image points ``[u, v]`` of both spheres in the paper's sign
                convention [px]; rows with NaN are left out. Shape (2, 2).

        Returns:
            Path -> 4x4 translation on the image plane, for the finite rows.
        """
        camera = self.robot.camera
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        poses = feature_point_poses(
            camera.to_pixel(points), camera.focal_px, camera.width, camera.height,
            IMAGE_PLANE_DEPTH, principal_point=camera.principal_point,
        )  # fmt: skip
        finite = np.all(np.isfinite(points), axis=1)
        return {path: T for (path, T), ok in zip(poses.items(), finite, strict=True) if ok}

    def poses(
        self, q: npt.ArrayLike, centres: npt.ArrayLike, points: npt.ArrayLike | None = None
    ) -> dict[str, np.ndarray]:
        """Every moving transform at one instant.

        Args:
            q: Robot configuration. Shape (nq,).
            centres: Upper and lower sphere centres in the world [m]. Shape (2, 3).
            points: Current image points ``[u, v]`` [px] (see
                :meth:`image_point_poses`); ``None`` leaves them out.

        Returns:
            Meshcat path -> 4x4 transform (relative to the parent node): robot
            geometries and spheres in the world, the camera node
            (``transform_camera_to_world``), current points in the camera frame.
        """
        q = np.asarray(q, dtype=float)
        out = self.robot_scene.poses(q)
        centres = np.asarray(centres, dtype=float).reshape(2, 3)
        for path, centre in zip(self.spheres, centres, strict=True):
            out[path] = translation_pose(centre)
        out[CAMERA_PREFIX] = np.array(self.robot.camera_pose(q).homogeneous)
        if points is not None:
            out.update(self.image_point_poses(points))
        return out

    def platform_point(self, q: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Point of the platform trail: the base origin, just above the ground [m]. Shape (3,)."""
        point = np.array(self.robot.base_pose(np.asarray(q, dtype=float)).translation, float)
        point[2] = TRAIL_HEIGHT
        return point

    def apply(self, poses: Mapping[str, np.ndarray]) -> None:
        """Send the transforms that changed since the last call (one meshcat command each).

        Args:
            poses: Meshcat path -> 4x4 transform, e.g. from :meth:`poses`.
        """
        for path, T in poses.items():
            if path in self._sent and np.array_equal(self._sent[path], T):
                continue
            node = self._nodes.get(path)
            if node is None:
                node = self._nodes[path] = self.vis[path]
            node.set_transform(T)
            self._sent[path] = T

    def draw_trails(self, platform: npt.ArrayLike, target: npt.ArrayLike) -> None:
        """(Re)draw the platform and target trails; a trail with < 2 points is skipped.

        Args:
            platform: Platform trail points in the world [m]. Shape (N, 3).
            target: Target trail points in the world [m]. Shape (M, 3).
        """
        colours = ((0.9, 0.2, 0.1), (0.1, 0.3, 0.9))
        for path, points, colour in zip(self.trails, (platform, target), colours, strict=True):
            points = np.asarray(points, dtype=float).reshape(-1, 3)
            if len(points) >= 2:
                add_trail(self.vis, points, colour, path=path)
