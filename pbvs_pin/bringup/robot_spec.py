"""A robot described by a ``[robot]`` table: its three forms, their rules, and building it.

A ``[robot]`` table (:class:`pbvs_pin.sim.sections.RobotSection`, in a scenario or in a robot
file of its own) gives exactly one form:

- ``name``: a shipped robot (:data:`pbvs_pin.bringup.catalogue.ROBOT_NAMES`);
- ``urdf`` + ``camera_frame``: one URDF holding platform, arm and camera optical frame
  (:meth:`MobileManipulator.from_urdf`);
- ``base``, ``arm``, ``mount``, ``camera_link``, ``camera_pose``: an arm mounted on a
  platform (:meth:`MobileManipulator.assemble`); ``arm`` and ``mount`` are absent when the
  base carries its arm.

``arm_root`` and ``arm_tip`` (URDF and assembly forms) make the arm the chain between the two
links: with ``arm``, only that chain of the arm's URDF is mounted; without (a URDF or base that
carries its arm), every movable joint off the chain is locked at neutral. ``repair_inertia``
(URDF and assembly forms) repairs inertias that break the triangle inequality
(:func:`pbvs_pin.model.urdf_checks.balance_inertia`).
``home`` (the arm's home posture) applies to every form. The drive parameters
``wheel_radius``, ``track`` and ``wheel_speed_limit`` (all three or none, URDF and assembly
forms) replace the drive axle found in the platform's URDF by a
:class:`~pbvs_pin.model.base.DifferentialDrive` with those values, whose planar root joint then sits
at the platform's root link (:func:`drive_of`). ``base_joints`` and ``forward_axis`` (URDF and
assembly forms) say which joints model the platform's motion and which way it drives
(:class:`~pbvs_pin.model.platform_frame.PlatformFrame`). Every error names the file and the dotted
field at fault, and what to add.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from pbvs_pin.bringup.catalogue import build_robot, floor_support
from pbvs_pin.bringup.holding import warn_overloaded
from pbvs_pin.bringup.home import compute_home
from pbvs_pin.bringup.placement import warn_placement
from pbvs_pin.exceptions import (
    BaseJointsError,
    ChainError,
    DriveAxleNotFound,
    FrameNotFound,
    GainError,
    HomeNotFound,
    NoMovableJoint,
    PbvsError,
    RobotNotFound,
    ScenarioError,
    UrdfError,
)
from pbvs_pin.model.assembly import PACKAGE_PREFIX
from pbvs_pin.model.base import BaseAdapter, DifferentialDrive, Omnidirectional
from pbvs_pin.model.camera import CameraIntrinsics
from pbvs_pin.model.platform_frame import PlatformFrame
from pbvs_pin.model.robot import MobileManipulator


class RobotTable(Protocol):
    """What this module reads of a ``[robot]`` table (:class:`pbvs_pin.sim.sections.RobotSection`).

    Declared here, not imported, so that the table's module can use this one without a cycle.
    """

    source: str
    name: str
    urdf: str
    camera_frame: str
    base: str
    arm: str
    mount: tuple[float, ...] | None
    camera_link: str
    camera_pose: tuple[float, ...] | None
    wheel_radius: float | None
    track: float | None
    wheel_speed_limit: float | None
    drive: str
    speed_limit: float | None
    yaw_rate_limit: float | None
    base_joints: tuple[str, ...] | None
    forward_axis: str
    arm_root: str
    arm_tip: str
    repair_inertia: bool
    geometry_density: float | None
    home: tuple[float, ...] | None

    @property
    def form(self) -> str:
        """Which of :data:`ROBOT_FORMS` the table uses."""
        ...

ROBOT_FORMS: dict[str, tuple[str, ...]] = {
    "name": ("name",),
    "urdf": ("urdf", "camera_frame"),
    "assembly": ("base", "arm", "mount", "camera_link", "camera_pose"),
}
"""The ``[robot]`` forms and their keys."""

DRIVE_KEYS = ("wheel_radius", "track", "wheel_speed_limit")
"""The explicit differential-drive parameters (all or none)."""

OMNIDIRECTIONAL_KEYS = ("speed_limit", "yaw_rate_limit")
"""The limits of an omnidirectional drive (``drive = "omnidirectional"`` only)."""

DRIVE_WAYS_OUT = (
    "; or give the drive in [robot]: add wheel_radius, track and wheel_speed_limit (a drive "
    "axle for the Pinocchio plant only: the MuJoCo plant rolls the URDF's own wheels), or "
    'set drive = "omnidirectional" for a holonomic base (mecanum, omni or swerve wheels)'
)
"""What the error of a platform without a drive axle adds: every way out of a ``[robot]``."""

DEFAULT_OMNIDIRECTIONAL_LIMIT = 1.0
"""An omnidirectional drive's speed [m/s] and yaw-rate [rad/s] limit when not given."""

CHAIN_KEYS = ("arm_root", "arm_tip")
"""The keys that make the arm a chain of a URDF (URDF and assembly forms)."""

REQUIRED: dict[str, tuple[tuple[str, tuple[str, ...]], ...]] = {
    "name": (),
    "urdf": (("urdf", ()), ("camera_frame", ())),
    "assembly": (("base", ()), ("arm", ("mount",)), ("mount", ("arm",)), ("camera_link", ()),
                 ("camera_pose", ())),
}  # fmt: skip
"""Per form: each required key, when the keys listed with it are all given."""

HINTS = {
    "urdf": '"path/to/robot.urdf"',
    "camera_frame": '"camera_optical_frame" (the URDF\'s optical frame: z forward, x right, '
    "y down)",
    "base": '"pioneer3at" (a shipped URDF name, a URDF path or an example-robot-data name)',
    "arm": '"ur5" (the arm that mount places)',
    "mount": "[x, y, z, roll, pitch, yaw] (the arm's root link in the platform's root link)",
    "camera_link": '"tool0" (the link the camera is fixed to)',
    "camera_pose": "[x, y, z, roll, pitch, yaw] (the optical frame in camera_link; all zeros "
    "if camera_link is the optical frame)",
}
"""What to write for each required key, in the error that says it is missing."""


def given(spec: RobotTable, name: str) -> bool:
    """Whether key ``name`` of the table is given (not empty, not absent)."""
    return getattr(spec, name) not in ("", None)


def forms_given(spec: RobotTable) -> list[str]:
    """The forms (:data:`ROBOT_FORMS`) of which the table gives at least one key, in order."""
    return [form for form, names in ROBOT_FORMS.items() if any(given(spec, n) for n in names)]


def check_forms(spec: RobotTable) -> None:
    """Exactly one form (:data:`ROBOT_FORMS`), with every key it needs and no key it refuses.

    Raises:
        GainError: Naming the key at fault.
    """
    forms = forms_given(spec)
    if len(forms) > 1:
        first, second = (next(n for n in ROBOT_FORMS[f] if given(spec, n)) for f in forms[:2])
        raise GainError(
            f"cannot be combined with robot.{first}: give one form, a shipped name, a urdf "
            "with its camera_frame, or an assembly (base, arm, mount, camera_link, "
            "camera_pose)",
            second,
        )
    for name, needed in REQUIRED[forms[0]]:
        if not given(spec, name) and all(given(spec, n) for n in needed):
            raise GainError(f"missing; add {name} = {HINTS[name]}", name)
    chain = [name for name in CHAIN_KEYS if given(spec, name)]
    if forms[0] == "name" and chain:
        raise GainError("a shipped robot's arm is known: remove it", chain[0])
    drive = [given(spec, name) for name in DRIVE_KEYS]
    if forms[0] == "name" and spec.repair_inertia:
        raise GainError("a shipped robot's inertias are valid: remove it", "repair_inertia")
    if forms[0] == "name" and spec.geometry_density is not None:
        raise GainError("a shipped robot has its inertias: remove it", "geometry_density")
    if forms[0] == "name" and (spec.base_joints is not None or spec.forward_axis != "x"):
        name = "base_joints" if spec.base_joints is not None else "forward_axis"
        raise GainError("a shipped robot's platform is known: remove it", name)
    if forms[0] == "name" and any(drive):
        name = DRIVE_KEYS[drive.index(True)]
        raise GainError("a shipped robot's drive is known: remove the drive keys", name)
    if any(drive) and not all(drive):
        name = DRIVE_KEYS[drive.index(False)]
        raise GainError(f"missing; the drive keys go together: add {name}", name)
    _check_drive_kind(spec, forms[0], any(drive))


def _check_drive_kind(spec: RobotTable, form: str, wheels_given: bool) -> None:
    """``drive`` and its limits: not for a shipped robot, not with the wheel keys."""
    omnidirectional = spec.drive == "omnidirectional"
    if form == "name" and omnidirectional:
        raise GainError("a shipped robot's drive is known: remove it", "drive")
    if omnidirectional and wheels_given:
        raise GainError(
            "an omnidirectional drive has no drive axle: remove wheel_radius, track and "
            "wheel_speed_limit, or set drive = \"differential\"", "drive",
        )  # fmt: skip
    for name in (name for name in OMNIDIRECTIONAL_KEYS if given(spec, name)):
        if form == "name":
            raise GainError("a shipped robot's limits are known: remove it", name)
        if not omnidirectional:
            raise GainError('limits an omnidirectional drive: add drive = "omnidirectional"', name)


def is_path(name: str, value: str) -> bool:
    """Whether a ``[robot]`` value is a file path: urdf; name, base or arm ending in .urdf.

    A ``package://`` source (a URDF inside an installed Python package) is not a path.
    """
    urdf_name = name in ("name", "base", "arm") and value.lower().endswith(".urdf")
    return bool(value) and not value.startswith(PACKAGE_PREFIX) and (name == "urdf" or urdf_name)


def drive_of(spec: RobotTable) -> BaseAdapter | str:
    """The drive: omnidirectional, explicit from the drive keys, else ``"differential"``.

    ``"differential"`` is the drive axle found in the URDF; an omnidirectional drive's planar
    root joint sits at the platform's root link, with the limits given (1 m/s and 1 rad/s if
    absent).

    This is the one place where the drive keys reach the robot builders, as the ``base``
    adapter of :meth:`MobileManipulator.from_urdf` and :meth:`MobileManipulator.assemble`.
    """
    if spec.drive == "omnidirectional":
        return Omnidirectional(
            *(getattr(spec, name) or DEFAULT_OMNIDIRECTIONAL_LIMIT for name in OMNIDIRECTIONAL_KEYS)
        )
    if spec.wheel_radius is None:
        return "differential"
    return DifferentialDrive(spec.wheel_radius, spec.track, spec.wheel_speed_limit)


def build_robot_from(
    spec: RobotTable, camera: CameraIntrinsics | None = None
) -> MobileManipulator:
    """Build the robot a ``[robot]`` table describes, with its ``home`` if given.

    Args:
        spec: The validated table.
        camera: Intrinsics; the paper's camera by default.

    Warns:
        PbvsWarning: If links are below the floor or arm links inside the platform at home
            (:func:`pbvs_pin.bringup.placement.warn_placement`), or gravity loads a joint past its
            effort limit there (:func:`pbvs_pin.bringup.holding.warn_overloaded`).

    Raises:
        ScenarioError: Naming ``spec.source`` and the dotted field: an unknown name, a
            missing or malformed URDF, a missing frame, a platform whose drive cannot be
            found (saying which keys to add), a ``home`` of the wrong length or off limits.
    """
    try:
        robot = _build(spec, camera)
    except PbvsError as err:
        field = _field_at_fault(spec, err)
        problem = str(err)
        if isinstance(err, DriveAxleNotFound):
            problem += DRIVE_WAYS_OUT
        raise ScenarioError(spec.source, f"robot.{field}", problem) from err
    if spec.form != "name":
        robot.support = floor_support(robot)
    if spec.home is not None:
        robot.home_arm = arm_posture(spec.source, "robot.home", robot, spec.home)
    elif spec.form != "name":
        try:
            robot.home_arm = compute_home(robot, support=robot.support)
        except HomeNotFound as err:
            raise ScenarioError(spec.source, "robot.home", str(err)) from err
    if spec.form != "name":
        warn_placement(robot, spec.source or robot.source)
        warn_overloaded(robot, spec.source or robot.source)
    return robot


def _build(spec: RobotTable, camera: CameraIntrinsics | None) -> MobileManipulator:
    """The robot of the table's form (package errors pass through)."""
    if spec.form == "name":
        return build_robot(spec.name, camera)
    if spec.form == "urdf":
        return MobileManipulator.from_urdf(
            spec.urdf, spec.camera_frame, drive_of(spec), camera, spec.repair_inertia,
            spec.geometry_density, PlatformFrame(spec.base_joints, spec.forward_axis),
            spec.arm_root or None, spec.arm_tip or None,
        )  # fmt: skip
    return MobileManipulator.assemble(
        spec.base,
        spec.arm or None,
        spec.mount or (0.0,) * 6,
        spec.camera_link,
        spec.camera_pose,
        camera=camera,
        base_kind=drive_of(spec),
        repair_inertia=spec.repair_inertia,
        geometry_density=spec.geometry_density,
        arm_root=spec.arm_root or None,
        arm_tip=spec.arm_tip or None,
        platform_frame=PlatformFrame(spec.base_joints, spec.forward_axis),
    )


def _field_at_fault(spec: RobotTable, err: PbvsError) -> str:
    """The key of ``spec`` that an error while building the robot comes from."""
    form = spec.form
    if form == "name":
        return "name"
    if isinstance(err, DriveAxleNotFound):
        return "urdf" if form == "urdf" else "base"
    if isinstance(err, BaseJointsError):
        return "base_joints"
    chain = {getattr(spec, key): key for key in CHAIN_KEYS if getattr(spec, key)}
    if isinstance(err, FrameNotFound) and err.name in chain:
        return chain[err.name]
    if isinstance(err, ChainError):
        return "arm_tip" if spec.arm_tip else "arm_root"
    if isinstance(err, FrameNotFound | NoMovableJoint):
        return "camera_frame" if form == "urdf" else "camera_link"
    if form == "urdf":
        return "urdf"
    arm = bool(spec.arm) and (
        (isinstance(err, RobotNotFound) and err.name == spec.arm)
        or (isinstance(err, UrdfError) and err.source == spec.arm)
    )
    return "arm" if arm else "base"


def arm_posture(
    source: str, field: str, robot: MobileManipulator, values: tuple[float, ...]
) -> np.ndarray:
    """Arm joint positions [rad or m] given by a key, checked for length and joint limits.

    Args:
        source: File the key was read from.
        field: Dotted name of the key (``"robot.home"``, ``"robot.initial_arm"``).
        robot: The robot the posture is for.
        values: One position per arm joint.

    Raises:
        ScenarioError: If the length is not ``robot.n_arm`` or a value is off its limits.
    """
    posture = np.asarray(values, dtype=float)
    if posture.shape != (robot.n_arm,):
        raise ScenarioError(
            source,
            field,
            f"expected {robot.n_arm} values for this robot ({', '.join(robot.arm_joint_names)}),"
            f" got {posture.size}",
        )
    lower, upper = robot.arm_position_limits()
    outside = [
        f"{name} = {value:g} not in [{low:g}, {high:g}]"
        for name, value, low, high in zip(
            robot.arm_joint_names, posture, lower, upper, strict=True
        )
        if not low <= value <= high
    ]
    if outside:
        raise ScenarioError(source, field, f"outside the joint limits: {'; '.join(outside)}")
    return posture
