"""URDF side of a mobile manipulator: load, mount an arm on a platform, add the camera frame.

Everything here edits URDF descriptions with yourdfpy and returns one URDF string that
:class:`pbvs_pin.model.robot.MobileManipulator` hands to Pinocchio. A URDF source is a file path or
an example-robot-data name (``"ur5"``, ``"panda"``, ``"tiago"``, ...).

For a differential-drive platform the drive axle is found from the URDF: the continuous or
revolute joints hanging from the platform's root through fixed joints only, with their axis
along the platform's y axis, at least one on each side. A link ``drive_footprint`` is added on
the floor below the axle midpoint and becomes the root, so that Pinocchio's planar root joint
sits exactly where the no-side-slip constraint holds.
"""

from __future__ import annotations

import copy
import importlib.util
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
import yourdfpy
from lxml import etree

from pbvs_pin.exceptions import (
    DriveAxleNotFound,
    FrameNotFound,
    RobotNotFound,
    UrdfError,
    WrongType,
)
from pbvs_pin.model import frames
from pbvs_pin.model.base import DifferentialDrive, skid_steer_factor
from pbvs_pin.model.link_inertia import checked_density, fill_missing_inertias
from pbvs_pin.model.shipped import shipped_urdf
from pbvs_pin.model.urdf_checks import axisless_joints, check_physics, check_tree
from pbvs_pin.validation import as_path

DRIVE_ADVICE = (
    "The drive needs wheel_radius [m], track [m] (distance between the left and right wheels) "
    "and wheel_speed_limit [rad/s]: add them to the URDF (wheel joints with <limit "
    "velocity=...>, wheel links with cylinder or sphere geometry), or give them explicitly "
    "with base=DifferentialDrive(wheel_radius=..., track=..., max_wheel_speed=...), whose "
    "planar joint then sits at the platform's root link; a holonomic base needs none: "
    'pass the base kind "omnidirectional"'
)
"""What every DriveAxleNotFound message ends with: the drive parameters and where they go."""

_AXIS_TOLERANCE = 0.99
"""|cos| between a wheel axis and the platform's y axis above which it counts as a wheel."""


@dataclass
class UrdfSource:
    """A loaded URDF and what is needed to find its meshes.

    Attributes:
        robot: The yourdfpy description (edited in place by the assembly functions).
        label: File path or name it was loaded from, used in error messages.
        package_dirs: Folders against which ``package://`` mesh URIs resolve.
        axisless: Joints written without ``<axis>`` (yourdfpy fills in URDF's default x).
        repaired_inertias: Links whose inertia was repaired on loading
            (:func:`pbvs_pin.model.urdf_checks.balance_inertia`).
        filled_inertias: Links given the inertia of their geometry on loading
            (:func:`pbvs_pin.model.link_inertia.fill_missing_inertias`).
        locked: Movable joints held at their neutral position although they may carry the
            camera: those outside the arm's chain of a URDF carrying its own arm
            (:func:`pbvs_pin.model.arm_chain.lock_outside_chain`).
    """

    robot: yourdfpy.Robot
    label: str
    package_dirs: tuple[str, ...]
    axisless: frozenset[str] = frozenset()
    repaired_inertias: tuple[str, ...] = ()
    filled_inertias: tuple[str, ...] = ()
    locked: tuple[str, ...] = ()

    def link_names(self) -> list[str]:
        """Names of all links."""
        return [link.name for link in self.robot.links]

    def root_link(self) -> str:
        """The single link that is no joint's child.

        Raises:
            UrdfError: If there is not exactly one such link.
        """
        children = {joint.child for joint in self.robot.joints}
        roots = [name for name in self.link_names() if name not in children]
        if len(roots) != 1:
            raise UrdfError(self.label, f"expected one root link, found {roots}")
        return roots[0]

    def require_link(self, name: str) -> None:
        """Raise :class:`FrameNotFound` unless ``name`` is a link of this description."""
        if name not in self.link_names():
            raise FrameNotFound(name, self.link_names(), self.label)


def example_robot_data_alias(name: str) -> str | None:
    """The example-robot-data name whose robot ``name`` really loads, if another's; else None.

    example-robot-data's loader table maps some names to another robot's loader (``"ur3"`` to
    the UR5's): ``name`` shares its loader with a name its URDF file is named after
    (``ur5_robot.urdf``).
    """
    from example_robot_data.robots_loader import ROBOTS

    loader = ROBOTS.get(name)
    stem = Path(loader.urdf_filename or "").stem if loader is not None else ""
    owners = [n for n, other in ROBOTS.items() if other is loader and stem.startswith(n)]
    return None if not owners or stem.startswith(name) else owners[0]


def _example_robot_data(name: str) -> tuple[Path, tuple[str, ...]] | None:
    """URDF path and package folders of an example-robot-data robot, or None if unknown.

    Raises:
        UrdfError: If example-robot-data maps ``name`` to another robot
            (:func:`example_robot_data_alias`), saying which and what to write instead.
    """
    from example_robot_data.robots_loader import ROBOTS

    if name not in ROBOTS:
        return None
    loader = ROBOTS[name]()
    alias = example_robot_data_alias(name)
    if alias is not None:
        alternatives = [n for n in ROBOTS if n != name and n.startswith(name)]
        raise UrdfError(
            name,
            f"example-robot-data maps {name!r} to the {alias!r} robot "
            f"({Path(loader.df_path).name}), not to a robot of its own name: write "
            f"{alias!r} for that robot"
            + (f", or one of {', '.join(map(repr, alternatives))}" if alternatives else "")
            + " (or a path to the .urdf file you mean)",
        )
    robots_dir = Path(loader.model_path)
    return Path(loader.df_path), (str(robots_dir), str(robots_dir.parents[1]))


PACKAGE_PREFIX = "package://"
"""Prefix of a URDF source inside an installed Python package: ``package://pkg/path.urdf``."""


def _python_package(source: str) -> tuple[Path, tuple[str, ...]]:
    """File path and package folders of ``package://<python package>/<path in it>``.

    Raises:
        UrdfError: If the package is not installed or the file is not in it.
    """
    name, _, relative = source[len(PACKAGE_PREFIX) :].partition("/")
    spec = importlib.util.find_spec(name) if name.isidentifier() else None
    if spec is None or not spec.submodule_search_locations:
        raise UrdfError(
            source,
            f"no installed Python package {name!r} (expected package://<importable package>/"
            "<path to the .urdf in it>; pip install the package that ships the robot)",
        )
    folder = Path(next(iter(spec.submodule_search_locations)))
    path = folder / relative
    if not path.is_file():
        raise UrdfError(source, f"file not found: {path} (expected a .urdf file in {folder})")
    return path, (str(path.parent), str(folder), str(folder.parent))


def _resolve(source: str | Path) -> tuple[Path, tuple[str, ...]]:
    """File path and package folders of a URDF source (path, ``package://``, shipped or ERD)."""
    if str(source).startswith(PACKAGE_PREFIX):
        return _python_package(str(source))
    path = Path(source)
    if path.suffix.lower() == ".urdf" or path.exists():
        if not path.is_file():
            raise UrdfError(str(source), "file not found (expected a path to a .urdf file)")
        return path, (str(path.resolve().parent),)
    shipped = shipped_urdf(str(source))
    if shipped is not None:
        return shipped, (str(shipped.parent),)
    erd = _example_robot_data(str(source))
    if erd is None:
        from example_robot_data.robots_loader import ROBOTS

        from pbvs_pin.model.shipped import SHIPPED_URDFS

        truthful = [name for name in ROBOTS if example_robot_data_alias(name) is None]
        raise RobotNotFound(str(source), SHIPPED_URDFS, truthful)
    return erd


def _absolute_mesh_paths(robot: yourdfpy.Robot, folder: Path) -> None:
    """Rewrite relative mesh file names as absolute paths, so the URDF can move."""
    for link in robot.links:
        for element in [*link.visuals, *link.collisions]:
            mesh = element.geometry.mesh if element.geometry is not None else None
            if mesh is None or mesh.filename is None:
                continue
            if "://" in mesh.filename or Path(mesh.filename).is_absolute():
                continue
            mesh.filename = str((folder / mesh.filename).resolve())


UNDECLARED_PREFIX = "NS_ERR_UNDEFINED_NAMESPACE"
"""libxml2's error for a namespace prefix used without a declaration."""


def _parse_strictly(path: Path) -> etree._Element:
    """The file's XML root; refuses broken XML, which yourdfpy would silently recover from.

    An undeclared namespace prefix is not a fault: simulators' URDF extensions
    (``drake:acceleration``, ...) are often written without declaring it, and URDF ignores them.

    Raises:
        UrdfError: If the file cannot be read or is not well-formed XML.
    """
    parser = etree.XMLParser(recover=True)  # its own error log: this file's errors only
    try:
        root = etree.parse(str(path), parser).getroot()
    except etree.XMLSyntaxError as err:
        raise UrdfError(str(path), f"not well-formed XML ({err})") from err
    except OSError as err:
        raise UrdfError(str(path), f"cannot be read ({err})") from err
    faults = [
        entry for entry in parser.error_log
        if entry.level >= etree.ErrorLevels.ERROR and entry.type_name != UNDECLARED_PREFIX
    ]  # fmt: skip
    if root is None or faults:
        first = faults[0] if faults else "no root element"
        raise UrdfError(str(path), f"not well-formed XML ({first})")
    return root


def load_urdf(
    source: str | Path, repair_inertia: bool = False, geometry_density: float | None = None
) -> UrdfSource:
    """Load a URDF file or an example-robot-data robot with yourdfpy.

    Args:
        source: A path to a ``.urdf`` file, ``package://<python package>/<path>.urdf`` (a file
            inside an installed Python package), a shipped file name (``"pioneer3at"``), or
            an example-robot-data name (``"ur5"``).
        repair_inertia: Repair inertias that break the triangle inequality instead of
            refusing them (:func:`pbvs_pin.model.urdf_checks.balance_inertia`); the links changed
            are in the result's ``repaired_inertias``.
        geometry_density: Give each link without ``<inertial>`` the inertia of its geometry
            at this density [kg/m^3] (:mod:`pbvs_pin.model.link_inertia`); the links are in the
            result's ``filled_inertias``. None: leave them massless.

    Returns:
        The description with mesh paths made absolute.

    Raises:
        UrdfError: If the file is missing, is not well-formed XML, is not a URDF, its links
            do not form a tree, or its masses, inertias or limits are impossible
            (:mod:`pbvs_pin.model.urdf_checks`).
        RobotNotFound: If the name is neither a file nor a known robot.
        WrongType: If ``source`` is not a path or a name.
    """
    if not isinstance(source, str | os.PathLike) or str(source) == "":
        raise WrongType("source", "a URDF path or a robot name (str or pathlib.Path)", source)
    as_path("source", source)  # refuses a name the system cannot open ("File name too long")
    if geometry_density is not None:
        geometry_density = checked_density(geometry_density)
    path, package_dirs = _resolve(source)
    tree = _parse_strictly(path)
    if tree.tag == "robot":
        check_tree(tree, str(path))
    try:
        urdf = yourdfpy.URDF.load(
            str(path),
            build_scene_graph=False,
            load_meshes=False,
            load_collision_meshes=False,
            filename_handler=yourdfpy.filename_handler_null,
        )
    except Exception as err:  # yourdfpy raises lxml, ValueError, AttributeError...
        raise UrdfError(str(path), f"not a valid URDF ({type(err).__name__}: {err})") from err
    if urdf.robot is None or not urdf.robot.links:
        raise UrdfError(str(path), "not a valid URDF (expected <robot> with at least one <link>)")
    robot = copy.deepcopy(urdf.robot)
    repaired = check_physics(robot, str(path), repair_inertia)
    _absolute_mesh_paths(robot, path.resolve().parent)
    _resolve_package_uris(robot, package_dirs, path.resolve().parents[:RENAMED_PACKAGE_DEPTH])
    label = str(path) if path.exists() else str(source)
    filled = []
    if geometry_density is not None:
        filled = fill_missing_inertias(robot, geometry_density, label)
    return UrdfSource(
        robot, label, package_dirs, axisless_joints(tree), tuple(repaired), tuple(filled)
    )


def _fixed_chain_poses(robot: yourdfpy.Robot, root: str) -> dict[str, np.ndarray]:
    """Pose in ``root`` of every link reached from ``root`` through fixed joints only.

    Returns:
        Link name to homogeneous transform, shape (4, 4).
    """
    poses = {root: np.eye(4)}
    frontier = [root]
    while frontier:
        parent = frontier.pop()
        for joint in robot.joints:
            if joint.parent == parent and joint.type == "fixed":
                poses[joint.child] = poses[parent] @ _origin(joint)
                frontier.append(joint.child)
    return poses


def _origin(joint: yourdfpy.Joint) -> np.ndarray:
    """Joint origin as a (4, 4) transform (identity when absent)."""
    return np.eye(4) if joint.origin is None else np.asarray(joint.origin, dtype=float)


def _joint_carriers(robot: yourdfpy.URDF) -> set[str]:
    """Links with a movable (non-fixed) joint somewhere below them: never a wheel's link."""
    carriers: set[str] = set()
    parents = {joint.child: joint.parent for joint in robot.joints}
    for joint in robot.joints:
        if joint.type != "fixed":
            link = joint.parent
            while link is not None and link not in carriers:
                carriers.add(link)
                link = parents.get(link)
    return carriers


def _wheel_radius(link: yourdfpy.Link) -> float | None:
    """Radius of a wheel link's first cylinder or sphere (collision first), if any."""
    for element in [*link.collisions, *link.visuals]:
        geometry = element.geometry
        if geometry is None:
            continue
        if geometry.cylinder is not None:
            return float(geometry.cylinder.radius)
        if geometry.sphere is not None:
            return float(geometry.sphere.radius)
    return None


@dataclass(frozen=True)
class DriveAxle:
    """The drive axle found in a platform URDF.

    Attributes:
        drive: The differential-drive adapter (wheel radius, track, wheel speed limit).
        footprint: Pose in the platform's root link of the floor point below the axle
            midpoint, x forward. Shape (4, 4).
        wheel_joints: Names of the drive-wheel joints.
    """

    drive: DifferentialDrive
    footprint: np.ndarray
    wheel_joints: tuple[str, ...]


def find_drive_axle(source: UrdfSource) -> DriveAxle:
    """Find the drive wheels of a differential-drive platform.

    A wheel is a continuous or revolute joint about the platform's y axis, hanging from the
    root link through fixed joints, with no movable joint below it (a mounted arm whose first
    joint pitches about y is not a wheel), off the platform's centreline (a one-joint arm
    pitching about y is not either).

    Args:
        source: The platform's (or whole robot's) description.

    Returns:
        The drive axle.

    Raises:
        DriveAxleNotFound: If there is no wheel on one side, a wheel has no cylinder or sphere
            geometry to give its radius, or no velocity limit.
    """
    robot = source.robot
    root = source.root_link()
    poses = _fixed_chain_poses(robot, root)
    links = {link.name: link for link in robot.links}
    carriers = _joint_carriers(robot)
    wheels = []
    for joint in robot.joints:
        if joint.type not in ("continuous", "revolute") or joint.parent not in poses:
            continue
        if joint.child in carriers:  # an arm's first joint, not a wheel: a chain hangs below
            continue
        pose = poses[joint.parent] @ _origin(joint)
        if joint.name in source.axisless and "wheel" in f"{joint.name} {joint.child}".lower():
            raise DriveAxleNotFound(
                source.label,
                f"wheel joint {joint.name!r} has no <axis>: URDF's default x axis would make "
                'the wheel roll sideways; expected e.g. <axis xyz="0 1 0"/>',
            )
        axis = pose[:3, :3] @ np.asarray(joint.axis if joint.axis is not None else [1, 0, 0])
        if abs(axis[1]) / np.linalg.norm(axis) >= _AXIS_TOLERANCE:
            wheels.append((joint, pose[:3, 3]))
    left = [w for w in wheels if w[1][1] > 0.0]
    right = [w for w in wheels if w[1][1] < 0.0]
    if not left or not right:
        found = [joint.name for joint, _ in wheels]
        raise DriveAxleNotFound(
            source.label,
            "no usable drive axle: expected continuous or revolute wheel joints with their "
            "axis along the platform's y axis, hanging from the root link "
            f"{root!r} through fixed joints, on both sides (y > 0 and y < 0); found {found}. "
            f"{DRIVE_ADVICE}",
        )
    wheels = left + right  # a joint on the centreline (an arm's pitch joint) drives no axle
    radii, speeds = [], []
    for joint, _ in wheels:
        radius = _wheel_radius(links[joint.child])
        if radius is None:
            raise DriveAxleNotFound(
                source.label,
                f"wheel link {joint.child!r} has no cylinder or sphere geometry giving its "
                f"radius (wheel_radius). {DRIVE_ADVICE}",
            )
        if joint.limit is None or not joint.limit.velocity:
            raise DriveAxleNotFound(
                source.label,
                f"wheel joint {joint.name!r} has no <limit velocity=...> giving the wheel speed "
                f"limit (wheel_speed_limit). {DRIVE_ADVICE}",
            )
        radii.append(radius)
        speeds.append(float(joint.limit.velocity))
    centres = np.array([position for _, position in wheels])
    track = float(np.mean([p[1] for _, p in left]) - np.mean([p[1] for _, p in right]))
    footprint = np.eye(4)
    footprint[:3, 3] = [*centres[:, :2].mean(axis=0), centres[:, 2].mean() - np.mean(radii)]
    drive = DifferentialDrive(
        float(np.mean(radii)), track, float(min(speeds)), skid_steer_factor(centres)
    )
    return DriveAxle(drive, footprint, tuple(joint.name for joint, _ in wheels))


def add_drive_footprint(source: UrdfSource, axle: DriveAxle) -> None:
    """Make a new root link ``drive_footprint`` at the axle's floor point (in place)."""
    root = source.root_link()
    if frames.DRIVE_FOOTPRINT in source.link_names():
        raise UrdfError(source.label, f"link name {frames.DRIVE_FOOTPRINT!r} is reserved")
    source.robot.links.insert(0, yourdfpy.Link(name=frames.DRIVE_FOOTPRINT))
    source.robot.joints.insert(
        0,
        yourdfpy.Joint(
            name=f"{frames.DRIVE_FOOTPRINT}_joint",
            type="fixed",
            parent=frames.DRIVE_FOOTPRINT,
            child=root,
            origin=np.linalg.inv(axle.footprint),
        ),
    )


def add_fixed_frame(source: UrdfSource, parent: str, name: str, pose: pin.SE3) -> None:
    """Attach a massless link ``name`` to ``parent`` at ``pose`` (in place).

    Raises:
        FrameNotFound: If ``parent`` is not a link.
        UrdfError: If ``name`` is already taken.
    """
    source.require_link(parent)
    if name in source.link_names():
        raise UrdfError(source.label, f"cannot add frame {name!r}: a link of that name exists")
    source.robot.links.append(yourdfpy.Link(name=name))
    source.robot.joints.append(
        yourdfpy.Joint(
            name=f"{name}_joint", type="fixed", parent=parent, child=name, origin=pose.homogeneous
        )
    )


def _rename_clashes(arm: UrdfSource, taken_links: set[str], taken_joints: set[str]) -> dict:
    """Prefix ``arm_`` to the arm's link and joint names that clash (in place).

    Returns:
        Map from the arm's original link names to their names after renaming.
    """
    links = {}
    for link in arm.robot.links:
        new = f"arm_{link.name}" if link.name in taken_links else link.name
        links[link.name] = new
        link.name = new
    for joint in arm.robot.joints:
        joint.parent, joint.child = links[joint.parent], links[joint.child]
        if joint.name in taken_joints:
            joint.name = f"arm_{joint.name}"
    return links


def mount_arm(platform: UrdfSource, arm: UrdfSource, mount: pin.SE3) -> dict[str, str]:
    """Fix ``arm``'s root link to ``platform``'s root link at ``mount`` (platform edited in place).

    Args:
        platform: The platform description; receives the arm's links and joints.
        arm: The arm description.
        mount: Pose of the arm's root link in the platform's root link.

    Returns:
        Map from the arm's original link names to their names in the assembled description
        (clashing names get an ``arm_`` prefix).
    """
    base_root = platform.root_link()
    arm_root = arm.root_link()
    taken_links = set(platform.link_names())
    taken_joints = {joint.name for joint in platform.robot.joints}
    names = _rename_clashes(arm, taken_links, taken_joints)
    robot = platform.robot
    robot.links.extend(arm.robot.links)
    robot.joints.append(
        yourdfpy.Joint(
            name="arm_mount_joint" if "arm_mount_joint" not in taken_joints else "pbvs_arm_mount",
            type="fixed",
            parent=base_root,
            child=names[arm_root],
            origin=mount.homogeneous,
        )
    )
    robot.joints.extend(arm.robot.joints)
    known = {material.name for material in robot.materials}
    robot.materials.extend(m for m in arm.robot.materials if m.name not in known)
    robot.name = f"{robot.name}_{arm.robot.name}"
    platform.package_dirs = tuple(dict.fromkeys(platform.package_dirs + arm.package_dirs))
    platform.repaired_inertias += tuple(names[link] for link in arm.repaired_inertias)
    platform.filled_inertias += tuple(names[link] for link in arm.filled_inertias)
    platform.label = f"{platform.label} + {arm.label}"
    return names


RENAMED_PACKAGE_DEPTH = 3
"""Folders above a URDF searched for ``package://PKG/<path>``'s ``<path>`` when no ``PKG``
folder holds it: a wheel that ships ROS packages under other folder names (rtb-data's
``kuka_lbr_iiwa`` for ``kuka_lbr_iiwa_support``)."""


def _resolve_package_uris(
    robot: yourdfpy.Robot, package_dirs: tuple[str, ...], ancestors: Sequence[Path] = ()
) -> None:
    """Rewrite ``package://`` mesh URIs as absolute paths where the file is found.

    ``package://PKG/path`` is looked for as ``<folder>/PKG/path`` for each of
    ``package_dirs``, then as ``<folder>/path`` for each of ``ancestors`` (a renamed package).
    """
    for link in robot.links:
        for element in [*link.visuals, *link.collisions]:
            mesh = element.geometry.mesh if element.geometry is not None else None
            uri = "" if mesh is None or mesh.filename is None else mesh.filename
            if not uri.startswith(PACKAGE_PREFIX):
                continue
            relative = uri[len(PACKAGE_PREFIX) :]
            inside = relative.partition("/")[2]
            candidates = [Path(folder) / relative for folder in package_dirs]
            candidates += [Path(folder) / inside for folder in ancestors]
            found = next((c for c in candidates if c.is_file()), None)
            if found is not None:
                mesh.filename = str(found.resolve())


def write_urdf(source: UrdfSource, path: str | Path) -> Path:
    """Write a description as one self-contained URDF file.

    Mesh file names are made absolute (``package://`` URIs resolved against the source's
    package folders), so the file loads from any folder.

    Args:
        source: The description (not modified).
        path: File to write.

    Returns:
        The path written.
    """
    robot = copy.deepcopy(source.robot)
    _resolve_package_uris(robot, source.package_dirs)
    path = Path(path)
    xml = to_xml(UrdfSource(robot, source.label, source.package_dirs))
    path.write_bytes(xml if isinstance(xml, bytes) else xml.encode())  # yourdfpy gives bytes
    return path


def to_xml(source: UrdfSource) -> str:
    """Serialise a description to a URDF string."""
    urdf = yourdfpy.URDF(
        robot=source.robot,
        build_scene_graph=False,
        load_meshes=False,
        filename_handler=yourdfpy.filename_handler_null,
    )
    return urdf.write_xml_string()
