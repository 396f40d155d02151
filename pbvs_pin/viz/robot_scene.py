"""A robot's visual geometries in meshcat, posed from Pinocchio (:class:`RobotScene`)."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from pbvs_pin.viz.primitives import ROBOT_PREFIX

if TYPE_CHECKING:  # pragma: no cover - typing only
    import meshcat

__all__ = ["RobotScene"]

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
