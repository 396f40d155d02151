"""The scene of a closed-loop run, shared by the live view and the replay (:class:`RunScene`).

A run is drawn as the robot (:class:`~pbvs_pin.viz.robot_scene.RobotScene`), the two target
spheres, the obstacles, the camera (frustum, triad, image plane with desired and current
points) and the platform and target trails.  The live view (:mod:`pbvs_pin.viz.live`) sends
its poses to a server; the replay (:mod:`pbvs_pin.viz.html_replay`) keys them into an animation.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from pbvs_pin.bringup.catalogue import build_robot
from pbvs_pin.model.camera import CameraIntrinsics
from pbvs_pin.sim.log import RunLog
from pbvs_pin.sim.sections import RobotSection
from pbvs_pin.viz.frustum import (
    add_camera_frustum,
    add_camera_triad,
    add_image_plane,
    feature_point_poses,
)
from pbvs_pin.viz.primitives import (
    CAMERA_PREFIX,
    TRAIL_PATH,
    add_box_obstacle,
    add_cylinder_obstacle,
    add_target_spheres,
    add_trail,
    set_camera_view,
    translation_pose,
)
from pbvs_pin.viz.robot_scene import RobotScene

if TYPE_CHECKING:  # pragma: no cover - typing only
    import meshcat

    from pbvs_pin.model.robot import MobileManipulator

__all__ = [
    "FRUSTUM_DEPTH",
    "IMAGE_PLANE_DEPTH",
    "PLATFORM_TRAIL_PATH",
    "TARGET_TRAIL_PATH",
    "RunFacts",
    "RunScene",
    "two_sphere_points",
]

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
        robot: The robot drawn (a :class:`pbvs_pin.model.robot.MobileManipulator`).
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
        source = log.meta.get("robot_source") or log.meta.get("source", "")  # older logs
        return RobotSection.from_toml(table, source).build(intrinsics)
    return build_robot(log.meta["robot"], intrinsics)


def log_facts(log: RunLog) -> RunFacts:
    """Target size, desired features and obstacles of a logged run."""
    return RunFacts(
        target_diameter=log.meta["target_diameter"],
        target_separation=log.meta["target_separation"],
        desired_points=two_sphere_points(log["xi_d"][0]),
        obstacles=tuple(log.meta.get("obstacles", [])),
    )
