"""MobileManipulator: one Pinocchio model of platform, arm and camera frame.

The model's root joint comes from the base adapter (planar at the drive-axle midpoint for a
differential drive). Only the joints between the root and the camera frame stay movable; any
other joint (wheels, fingers, a head) is locked at its neutral position with
``pin.buildReducedModel``. Queries take the configuration ``q`` explicitly, following
Pinocchio's Model/Data split; the robot owns one ``pin.Data`` as scratch space.

Velocities come in two flavours: Pinocchio's ``v_pin`` (``nv`` entries) and the actuated
velocities ``v = [base velocities, arm joint rates]`` (``n`` entries), with ``v_pin = S v``.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from pbvs_pin.exceptions import FrameNotFound, GainError, NoMovableJoint, UrdfError, WrongType
from pbvs_pin.model import frames
from pbvs_pin.model.arm_chain import keep_chain, lock_outside_chain
from pbvs_pin.model.assembly import (
    UrdfSource,
    add_drive_footprint,
    add_fixed_frame,
    find_drive_axle,
    load_urdf,
    mount_arm,
    to_xml,
    write_urdf,
)
from pbvs_pin.model.base import BaseAdapter, FixedBase, Omnidirectional
from pbvs_pin.model.camera import CameraIntrinsics
from pbvs_pin.model.joint_angles import arm_angles
from pbvs_pin.model.platform_frame import PlatformFrame, fix_base_joints, turn_platform
from pbvs_pin.model.urdf_checks import check_meshes
from pbvs_pin.validation import as_array, as_number, as_path, as_se3

PAYLOAD_RADIUS = 0.02
"""Radius [m] of a payload's solid sphere (:meth:`MobileManipulator.with_payload`)."""

UNIT_TOLERANCE = 1e-6
"""Largest deviation from 1 of the norm of an angle's ``(cos, sin)`` pair in a configuration."""

DEFAULT_JOINT_SPEED = 1.0
"""Velocity limit [rad/s or m/s] used for a joint whose URDF gives none."""

BASE_KINDS = ("differential", "omnidirectional", "fixed")
"""Base kinds accepted by name."""


def _base_adapter(kind: str | BaseAdapter, source: UrdfSource) -> BaseAdapter:
    """Adapter for a base kind, editing ``source`` to add the drive footprint if needed."""
    if isinstance(kind, BaseAdapter):
        return kind
    if kind == "differential":
        axle = find_drive_axle(source)
        add_drive_footprint(source, axle)
        return axle.drive
    if kind == "omnidirectional":
        return Omnidirectional()
    if kind == "fixed":
        return FixedBase()
    raise GainError(f"base: expected one of {BASE_KINDS} or a BaseAdapter, got {kind!r}")


def _build_model(xml: str, label: str, root: pin.JointModel | None) -> pin.Model:
    """Pinocchio model from a URDF string, with errors that name the source."""
    try:
        if root is None:
            return pin.buildModelFromXML(xml)
        return pin.buildModelFromXML(xml, root)
    except (RuntimeError, ValueError) as err:
        raise UrdfError(label, f"Pinocchio cannot build a model: {_one_line(err)}") from err


def _build_visuals(
    model: pin.Model, xml: str, label: str, package_dirs: tuple[str, ...]
) -> pin.GeometryModel:
    """Visual geometry model; a missing mesh is an error naming the file."""
    try:
        return pin.buildGeomFromUrdfString(
            model, xml, pin.GeometryType.VISUAL, package_dirs=list(package_dirs)
        )
    except (RuntimeError, ValueError) as err:
        raise UrdfError(label, f"cannot load visual geometry: {_one_line(err)}") from err


def _one_line(err: Exception) -> str:
    """An exception's (C++, multi-line) message on one line."""
    return " ".join(str(err).split())


class MobileManipulator:
    """A mobile manipulator with an eye-in-hand camera, as one Pinocchio model.

    Attributes:
        model: The reduced Pinocchio model (root joint, then the camera chain's joints).
        data: Scratch ``pin.Data`` for ``model``.
        visual_model: Visual geometry, for viewers.
        base: The base adapter.
        camera: Camera intrinsics.
        camera_frame: Name of the camera optical frame.
        selection: ``S``, actuated to Pinocchio velocities. Shape (nv, n).
        velocity_names: Names of the actuated velocities. Length n.
        velocity_limits: Largest magnitude of each actuated velocity, SI units. Shape (n,).
        source: File or name the robot was built from.
        home_arm: Arm posture [rad or m] of :meth:`home`; zeros until set (a shipped recipe's,
            a scenario's ``robot.home`` or :func:`pbvs_pin.bringup.home.compute_home`).
        arm_q_indices: Index in ``q`` of each arm joint. Shape (n_arm,).
        arm_continuous: Whether each arm joint is continuous (stored as cos, sin). Shape (n_arm,).
        urdf_xml: The assembled URDF the model was built from (drive footprint and camera frame
            included), for an independent plant such as :mod:`pbvs_pin.plant.mujoco_plant`; None
            when the robot was built from a Pinocchio model directly.
        repaired_inertias: Links whose inertia was repaired on loading (``repair_inertia``).
        filled_inertias: Links given their geometry's inertia on loading (``geometry_density``).
        mounted_links: Links of the arm mounted by :meth:`assemble` (their names in the
            model); empty when the platform carries its own arm.
        support: Support polygon [m], platform frame, (m, 2) (:mod:`pbvs_pin.model.support`).
    """

    def __init__(
        self,
        model: pin.Model,
        visual_model: pin.GeometryModel,
        base: BaseAdapter,
        camera_frame: str,
        camera: CameraIntrinsics,
        source: str,
        locked: tuple[str, ...] = (),
    ) -> None:
        """Wrap a Pinocchio model whose root joint matches ``base``.

        Prefer :meth:`from_urdf`, :meth:`assemble` or :func:`pbvs_pin.load_robot`. ``locked``
        names joints held at neutral even where they carry the camera (outside ``arm_root`` to
        ``arm_tip``).

        Raises:
            FrameNotFound: If ``camera_frame`` is not a frame of ``model``.
            NoMovableJoint: If no joint moves the camera other than the root joint.
        """
        if not model.existFrame(camera_frame):
            raise FrameNotFound(camera_frame, [f.name for f in model.frames], source)
        self.source = source
        self.base = base
        self.camera = camera
        self.camera_frame = camera_frame
        self.model, self.visual_model = _lock_off_chain(model, visual_model, camera_frame, locked)
        self.data = self.model.createData()
        self.camera_frame_id = self.model.getFrameId(camera_frame)
        n_root = base.selection().shape[0]
        arm_joints = [
            j for j in range(1, self.model.njoints) if self.model.joints[j].idx_v >= n_root
        ]
        if not arm_joints:
            raise NoMovableJoint(
                source, f"no movable joint between the base and camera frame {camera_frame!r}"
            )
        self.arm_joint_names = tuple(self.model.names[j] for j in arm_joints)
        self.arm_q_indices = np.array([self.model.joints[j].idx_q for j in arm_joints])
        self.arm_continuous = np.array([self.model.joints[j].nq == 2 for j in arm_joints])
        n_arm = self.model.nv - n_root
        self.selection = np.zeros((self.model.nv, base.selection().shape[1] + n_arm))
        self.selection[:n_root, : base.selection().shape[1]] = base.selection()
        self.selection[n_root:, base.selection().shape[1] :] = np.eye(n_arm)
        self.velocity_names = (*base.velocity_names, *self.arm_joint_names)
        arm_limits = np.array(self.model.velocityLimit[n_root:], dtype=float)
        arm_limits[~np.isfinite(arm_limits) | (arm_limits <= 0) | (arm_limits > 1e6)] = (
            DEFAULT_JOINT_SPEED
        )
        self.velocity_limits = np.concatenate([base.velocity_limits(), arm_limits])
        self.home_arm = np.zeros(self.n_arm)
        self.urdf_xml: str | None = None
        self.repaired_inertias: tuple[str, ...] = ()
        self.filled_inertias: tuple[str, ...] = ()
        self.mounted_links: tuple[str, ...] = ()
        self.support: np.ndarray | None = None

    # ------------------------------------------------------------------ builders
    @classmethod
    def from_urdf(
        cls,
        path: str,
        camera_frame: str = frames.CAMERA_OPTICAL,
        base: str | BaseAdapter = "differential",
        camera: CameraIntrinsics | None = None,
        repair_inertia: bool = False,
        geometry_density: float | None = None,
        platform_frame: PlatformFrame | None = None,
        arm_root: str | None = None,
        arm_tip: str | None = None,
    ) -> MobileManipulator:
        """Load one URDF that holds platform, arm and camera frame.

        Args:
            path: URDF file (or a shipped or example-robot-data name).
            camera_frame: Name of the camera optical frame (z forward, x right, y down).
            base: ``"differential"`` (drive axle found in the URDF), ``"omnidirectional"``,
                ``"fixed"``, or a :class:`BaseAdapter`.
            camera: Intrinsics; the paper's camera by default.
            repair_inertia: Repair inertias that break the triangle inequality
                (:func:`pbvs_pin.model.urdf_checks.balance_inertia`) instead of refusing the file;
                the links changed are in :attr:`repaired_inertias`.
            geometry_density: Give each link without ``<inertial>`` the inertia of its
                geometry at this density [kg/m^3] (:mod:`pbvs_pin.model.link_inertia`); the links
                are in :attr:`filled_inertias`. None: leave them massless.
            platform_frame: The joints that model the base and the forward axis
                (:mod:`pbvs_pin.model.platform_frame`); base joints recognised, x forward if None.
            arm_root: With or without ``arm_tip``: the arm is the URDF's chain from this link
                (the URDF's root link when None) down to ``arm_tip``; every other movable joint
                is locked at neutral (:func:`~pbvs_pin.model.arm_chain.lock_outside_chain`).
            arm_tip: Last link of the arm; ``camera_frame`` when None. Neither given: every
                joint between the root and the camera frame moves.

        Raises:
            UrdfError: Malformed file, or a platform without a usable drive axle.
            ChainError: If ``arm_tip`` does not hang below ``arm_root``, or the camera frame
                below ``arm_tip``.
            FrameNotFound: If ``camera_frame``, ``arm_root`` or ``arm_tip`` does not exist.
            NoMovableJoint: If no joint moves the camera.
        """
        source = load_urdf(path, repair_inertia, geometry_density)
        source.require_link(camera_frame)
        fix_base_joints(source, (platform_frame or PlatformFrame()).base_joints)
        if arm_root is not None or arm_tip is not None:
            lock_outside_chain(source, arm_root, arm_tip or camera_frame, camera_frame)
        return cls._from_source(source, camera_frame, base, camera, platform_frame)

    @classmethod
    def assemble(
        cls,
        base: str,
        arm: str | None,
        mount: pin.SE3 | npt.ArrayLike = (0, 0, 0, 0, 0, 0),
        camera_link: str = "tool0",
        camera_pose: pin.SE3 | npt.ArrayLike = (0, 0, 0, 0, 0, 0),
        camera: CameraIntrinsics | None = None,
        base_kind: str | BaseAdapter = "differential",
        repair_inertia: bool = False,
        geometry_density: float | None = None,
        arm_root: str | None = None,
        arm_tip: str | None = None,
        platform_frame: PlatformFrame | None = None,
    ) -> MobileManipulator:
        """Mount an arm on a platform and attach the camera optical frame.

        Args:
            base: Platform URDF (path, ``"pioneer3at"``, or an example-robot-data name such as
                ``"tiago"``, which then brings its own arm).
            arm: Arm URDF (path or example-robot-data name), or None when ``base`` already
                carries the arm.
            mount: Pose of the arm's root link in the platform's root link, a ``pin.SE3`` or
                ``(x, y, z, roll, pitch, yaw)`` [m, rad].
            camera_link: Link (of the arm, by its own name) the camera is fixed to; an arm
                that already has a ``camera_optical_frame`` can name it here.
            camera_pose: Pose of the optical frame (z forward, x right, y down) in
                ``camera_link``.
            camera: Intrinsics; the paper's camera by default.
            base_kind: See :meth:`from_urdf`.
            repair_inertia: See :meth:`from_urdf`; applies to the base and the arm.
            geometry_density: See :meth:`from_urdf`; applies to the base and the arm.
            arm_root: With ``arm_tip``, mount only the arm's chain from this link (placed at
                ``mount``) down to ``arm_tip``, dropping the rest of the arm's URDF (a second
                arm, a pedestal); the arm URDF's root link when None. Without ``arm`` (a
                ``base`` that carries its arm): the arm is the base URDF's chain from this link
                down to ``arm_tip``, every other movable joint locked at neutral
                (:func:`~pbvs_pin.model.arm_chain.lock_outside_chain`).
            arm_tip: Last link of the chain; ``camera_link`` when None. Neither given: the
                whole arm URDF is mounted (without ``arm``: every joint between the root and
                the camera moves).
            platform_frame: See :meth:`from_urdf`; applies to the base (``mount`` stays in
                its root link).

        Raises:
            UrdfError: Malformed file, a platform without a usable drive axle.
            ChainError: If ``arm_tip`` does not hang below ``arm_root`` (without ``arm``: or
                ``camera_link`` below ``arm_tip``).
            FrameNotFound: If ``camera_link``, ``arm_root`` or ``arm_tip`` does not exist.
            NoMovableJoint: If no joint moves the camera.
        """
        mount_pose = as_se3("mount", mount)
        optical_pose = as_se3("camera_pose", camera_pose)
        platform = load_urdf(base, repair_inertia, geometry_density)
        fix_base_joints(platform, (platform_frame or PlatformFrame()).base_joints)
        chain = arm_root is not None or arm_tip is not None
        if chain and arm is None:  # the base carries its arm: the chain moves, the rest is locked
            lock_outside_chain(platform, arm_root, arm_tip or camera_link, camera_link)
        if arm is not None:
            arm_source = load_urdf(arm, repair_inertia, geometry_density)
            arm_source.require_link(camera_link)
            if chain:
                keep_chain(arm_source, arm_root, arm_tip or camera_link)
                arm_source.require_link(camera_link)
            names = mount_arm(platform, arm_source, mount_pose)
            camera_link = names[camera_link]
        if camera_link != frames.CAMERA_OPTICAL:
            add_fixed_frame(platform, camera_link, frames.CAMERA_OPTICAL, optical_pose)
        elif optical_pose != pin.SE3.Identity():
            raise UrdfError(
                platform.label,
                f"camera_link is already the optical frame {frames.CAMERA_OPTICAL!r}: expected "
                "an identity camera_pose",
            )
        robot = cls._from_source(platform, frames.CAMERA_OPTICAL, base_kind, camera, platform_frame)
        robot.mounted_links = tuple(names.values()) if arm is not None else ()
        return robot

    @classmethod
    def _from_source(
        cls,
        source: UrdfSource,
        camera_frame: str,
        base: str | BaseAdapter,
        camera: CameraIntrinsics | None,
        platform_frame: PlatformFrame | None = None,
    ) -> MobileManipulator:
        turn_platform(source, (platform_frame or PlatformFrame()).forward_axis)
        description = copy.deepcopy(source)  # as built, before the base adapter edits it
        adapter = _base_adapter(base, source)
        xml = to_xml(source)
        model = _build_model(xml, source.label, adapter.root_joint())
        check_meshes(source.robot, source.label)
        visuals = _build_visuals(model, xml, source.label, source.package_dirs)
        robot = cls(
            model, visuals, adapter, camera_frame, camera or CameraIntrinsics(), source.label,
            source.locked,
        )  # fmt: skip
        robot._description = description
        robot.urdf_xml = xml
        robot.repaired_inertias = source.repaired_inertias
        robot.filled_inertias = source.filled_inertias
        return robot

    def write_urdf(self, path: str | Path) -> Path:
        """Write the robot as built (platform, arm, mount, camera frame) as one URDF file.

        :meth:`from_urdf` on the written file, with this robot's ``camera_frame`` and base,
        gives the same model: the differential drive is found again from the wheel joints,
        which the file keeps. Mesh paths are absolute. An explicit base adapter object is not
        written, nor are the joints locked off an ``arm_root``/``arm_tip`` chain of a URDF
        carrying its arm; pass them to :meth:`from_urdf` again.

        Args:
            path: File to write (``.urdf``).

        Returns:
            The path written.

        Raises:
            UrdfError: If the robot was not built from a URDF description.
        """
        description = getattr(self, "_description", None)
        path = as_path("path", path)
        if description is None:
            raise UrdfError(self.source, "no URDF description to write: build with from_urdf")
        return write_urdf(description, path)

    def with_model_error(
        self, kinematic_scale: float = 1.0, mass_scale: float = 1.0
    ) -> MobileManipulator:
        """A copy whose model is wrong by a factor: a controller's imperfect knowledge.

        Args:
            kinematic_scale: Factor on every joint and frame offset (1.2 is a 20% error).
            mass_scale: Factor on every body's mass and rotational inertia.

        Returns:
            A new robot sharing nothing mutable with this one.
        """
        kinematic_scale = as_number("kinematic_scale", kinematic_scale)
        mass_scale = as_number("mass_scale", mass_scale)
        if not (kinematic_scale > 0 and mass_scale > 0):
            raise GainError(
                f"model error: expected positive scales, got {kinematic_scale}, {mass_scale}"
            )
        twin = copy.copy(self)
        model = self.model.copy()
        for i in range(model.njoints):
            placement = model.jointPlacements[i]
            model.jointPlacements[i] = pin.SE3(
                placement.rotation, kinematic_scale * placement.translation
            )
            inertia = model.inertias[i]
            model.inertias[i] = pin.Inertia(
                mass_scale * inertia.mass,
                kinematic_scale * inertia.lever,
                mass_scale * inertia.inertia,
            )
        for frame in model.frames:
            frame.placement = pin.SE3(
                frame.placement.rotation, kinematic_scale * frame.placement.translation
            )
        twin.model, twin.data = model, model.createData()
        return twin

    def with_payload(self, mass: float) -> MobileManipulator:
        """A copy carrying a payload at the camera frame's origin (the end-effector).

        The payload, a solid sphere of radius :data:`PAYLOAD_RADIUS`, is added to the inertia
        of the camera frame's parent joint, at the camera frame's placement in it.

        Args:
            mass: Payload [kg], >= 0.

        Returns:
            A new robot sharing nothing mutable with this one (this robot when ``mass`` is 0).
        """
        mass = as_number("mass", mass)
        if not (np.isfinite(mass) and mass >= 0):
            raise GainError(f"payload: expected a mass >= 0 kg, got {mass}")
        if mass == 0:
            return self
        twin = copy.copy(self)
        model = self.model.copy()
        frame = model.frames[self.camera_frame_id]
        sphere = pin.Inertia.FromSphere(mass, PAYLOAD_RADIUS)
        model.inertias[frame.parentJoint] += frame.placement.act(sphere)
        twin.model, twin.data = model, model.createData()
        return twin

    # ------------------------------------------------------------------ sizes
    @property
    def n(self) -> int:
        """Number of actuated velocities."""
        return self.selection.shape[1]

    @property
    def n_base(self) -> int:
        """Number of actuated base velocities (2 for a differential drive)."""
        return len(self.base.velocity_names)

    @property
    def n_arm(self) -> int:
        """Number of arm joint rates."""
        return self.n - self.n_base

    # ------------------------------------------------------------------ configurations
    def neutral(self) -> np.ndarray:
        """Pinocchio's neutral configuration (base at the origin, arm joints at zero)."""
        return pin.neutral(self.model)

    def home(self) -> np.ndarray:
        """Base at the origin, arm at ``home_arm`` (the camera looks forward)."""
        return self.with_arm_positions(self.neutral(), self.home_arm)

    def check_configuration(self, q: npt.ArrayLike) -> np.ndarray:
        """``q`` as a finite float array of shape (nq,) whose (cos, sin) pairs are unit.

        A planar root joint and each continuous joint store an angle as ``(cos, sin)``; a pair
        whose norm is off 1 by more than :data:`UNIT_TOLERANCE` is no angle and is refused
        (integration keeps the pairs unit to about 1e-15).

        Raises:
            ShapeError: If the shape is not (nq,).
            NonFiniteValue: If an entry is NaN or infinite.
            GainError: If a (cos, sin) pair is not unit, naming ``q``.
        """
        q = as_array("q", q, (self.model.nq,))
        if not pin.isNormalized(self.model, q, UNIT_TOLERANCE):
            raise GainError(
                f"q: a (cos, sin) pair of {q.round(6).tolist()} is not unit (tolerance "
                f"{UNIT_TOLERANCE:g}); expected the angles of the planar and continuous joints "
                "as (cos, sin), e.g. from robot.neutral() or robot.with_arm_positions()",
                field="q",
            )
        return q

    def check_velocity(self, v: npt.ArrayLike, name: str = "v") -> np.ndarray:
        """Actuated velocity as a finite float array of shape (n,)."""
        return as_array(name, v, (self.n,))

    def integrate(self, q: npt.ArrayLike, v: npt.ArrayLike, dt: float) -> np.ndarray:
        """Configuration after moving with actuated velocity ``v`` for ``dt`` seconds.

        Args:
            q: Configuration. Shape (nq,).
            v: Actuated velocity. Shape (n,).
            dt: Duration [s].

        Returns:
            ``pin.integrate(q, S v dt)``. Shape (nq,).

        Raises:
            NonFiniteValue: If ``dt`` (or an entry of ``q`` or ``v``) is not finite.
        """
        q = self.check_configuration(q)
        v = self.check_velocity(v)
        as_array("dt", dt, ())
        return pin.integrate(self.model, q, self.selection @ (v * dt))

    def arm_positions(self, q: npt.ArrayLike) -> np.ndarray:
        """Arm joint angles [rad] (or positions [m]) from a configuration. Shape (n_arm,).

        Continuous joints (stored as cos/sin) give their angle.
        """
        q = as_array("q", q, (self.model.nq,))
        return arm_angles(q, self.arm_q_indices, self.arm_continuous)

    def with_arm_positions(self, q: npt.ArrayLike, arm: npt.ArrayLike) -> np.ndarray:
        """Copy of ``q`` with the arm joints set to ``arm`` [rad or m]. Shape (nq,).

        Raises:
            ShapeError: If ``q`` is not (nq,) or ``arm`` not (n_arm,).
            NonFiniteValue: If an entry is not finite.
        """
        q = as_array("q", q, (self.model.nq,))
        arm = as_array("arm", arm, (self.n_arm,))
        for name, value in zip(self.arm_joint_names, arm, strict=True):
            joint = self.model.joints[self.model.getJointId(name)]
            if joint.nq == 2:
                q[joint.idx_q : joint.idx_q + 2] = np.cos(value), np.sin(value)
            else:
                q[joint.idx_q] = value
        return q

    def arm_position_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper arm joint limits; ``-inf``/``inf`` for continuous joints."""
        lower, upper = [], []
        for name in self.arm_joint_names:
            joint = self.model.joints[self.model.getJointId(name)]
            if joint.nq == 2:
                lower.append(-np.inf)
                upper.append(np.inf)
            else:
                lower.append(self.model.lowerPositionLimit[joint.idx_q])
                upper.append(self.model.upperPositionLimit[joint.idx_q])
        return np.array(lower), np.array(upper)

    # ------------------------------------------------------------------ kinematics
    def frame_pose(self, q: npt.ArrayLike, frame: str) -> pin.SE3:
        """``world_T_frame`` for a named frame.

        Raises:
            FrameNotFound: If ``frame`` does not exist.
        """
        frame_id = self.frame_id(frame)
        pin.framesForwardKinematics(self.model, self.data, self.check_configuration(q))
        return pin.SE3(self.data.oMf[frame_id])

    def frame_id(self, frame: str) -> int:
        """Index of a named frame, or FrameNotFound listing the valid names (WrongType: no text)."""
        if not isinstance(frame, str):
            raise WrongType("frame", "a frame name (text)", frame)
        if not self.model.existFrame(frame):
            raise FrameNotFound(frame, [f.name for f in self.model.frames], self.source)
        return self.model.getFrameId(frame)

    def camera_pose(self, q: npt.ArrayLike) -> pin.SE3:
        """``world_T_camera``: pose of the optical frame in the world."""
        pin.framesForwardKinematics(self.model, self.data, self.check_configuration(q))
        return pin.SE3(self.data.oMf[self.camera_frame_id])

    def camera_placement(self, q: np.ndarray) -> pin.SE3:
        """:meth:`camera_pose` for a ``q`` known to be valid (the control loop's hot path).

        Only the joints' placements and the camera frame's are computed; the result refers to
        ``self.data.oMf``: valid until the next Pinocchio call on ``self.data``.
        """
        pin.forwardKinematics(self.model, self.data, q)
        return pin.updateFramePlacement(self.model, self.data, self.camera_frame_id)

    def camera_jacobian(self, q: npt.ArrayLike) -> np.ndarray:
        """Camera twist in the camera frame from the actuated velocities.

        ``J_cam(q) S`` with ``J_cam`` the optical frame's Jacobian in ``pin.LOCAL``.

        Returns:
            Shape (6, n): rows ``[v; w]`` [m/s, rad/s] of the camera in its own frame.
        """
        return self.camera_jacobian_unchecked(self.check_configuration(q))

    def camera_jacobian_unchecked(self, q: np.ndarray) -> np.ndarray:
        """:meth:`camera_jacobian` for a ``q`` known to be valid (the control loop's hot path).

        Also leaves the camera placement ``world_T_camera`` in ``self.data.oMf``.
        """
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacement(self.model, self.data, self.camera_frame_id)
        jacobian = pin.getFrameJacobian(self.model, self.data, self.camera_frame_id, pin.LOCAL)
        return jacobian @ self.selection

    def base_pose(self, q: npt.ArrayLike) -> pin.SE3:
        """``world_T_base``: pose of the root joint's frame (the drive footprint)."""
        pin.forwardKinematics(self.model, self.data, self.check_configuration(q))
        return pin.SE3(self.data.oMi[1] if self.model.njoints > 1 else pin.SE3.Identity())


def _lock_off_chain(
    model: pin.Model, visual_model: pin.GeometryModel, camera_frame: str, names: tuple[str, ...]
) -> tuple[pin.Model, pin.GeometryModel]:
    """Lock, at neutral, every joint not between the root and the camera frame, and ``names``."""
    parent = model.frames[model.getFrameId(camera_frame)].parentJoint
    chain = set(model.supports[parent])
    locked = [j for j in range(1, model.njoints) if j not in chain or model.names[j] in names]
    if not locked:
        return model, visual_model
    return pin.buildReducedModel(model, visual_model, locked, pin.neutral(model))
