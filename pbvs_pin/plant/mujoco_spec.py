"""The MuJoCo model of a robot's assembled URDF, on a ground plane, without actuators.

:func:`build_spec` reads the URDF the controller's model was built from
(:attr:`pbvs_pin.model.robot.MobileManipulator.urdf_xml`) with MuJoCo's own importer: visual and
mesh collision geometry stripped, inertias from ``<inertial>`` only (a full inertia MuJoCo
refuses replaced by its diagonal), every joint the controller's model locks welded, and either a
free joint on the drive footprint with wheels that touch the ground (the URDF's, or built from
the drive keys by :mod:`pbvs_pin.plant.mujoco_wheels`) or a holonomic base's planar joints.
:class:`pbvs_pin.plant.mujoco_plant.MujocoPlant` adds the servos and steps it.
"""

from __future__ import annotations

import io
import warnings
from typing import TYPE_CHECKING

import mujoco
import numpy as np
import yourdfpy
from lxml import etree

from pbvs_pin.exceptions import DriveAxleNotFound, GainError, PbvsWarning, UrdfError
from pbvs_pin.model import frames
from pbvs_pin.model.assembly import DriveAxle, UrdfSource, find_drive_axle
from pbvs_pin.model.base import DifferentialDrive, Omnidirectional
from pbvs_pin.plant.mujoco_wheels import add_key_wheels

if TYPE_CHECKING:
    from pbvs_pin.model.robot import MobileManipulator

WHEEL_FRICTION = 1.0
"""Sliding friction coefficient of a drive wheel on the floor (rubber on concrete)."""

GROUND = "ground"
"""Name of the ground plane geom."""

_CONTACT_AFFINITY = 1
"""Robot geoms have ``conaffinity`` 1 and ``contype`` 0, the ground the reverse: robot geoms
meet the ground but never each other."""


FLOOR_TOLERANCE = 0.005
"""Depth [m] below the drive keys' floor that a platform's collision shape may reach and still
count as a support (Stretch's caster sphere touches it at 0)."""

WORLD_LINK = "world_link"
"""What a link named ``world`` (an arm's root in example-robot-data's UR URDFs) is renamed."""


def _strip_geometry(xml: str | bytes) -> bytes:
    """The URDF without ``<visual>`` elements and mesh ``<collision>`` elements.

    A link named ``world`` is renamed :data:`WORLD_LINK`: MuJoCo's URDF importer would merge
    it, and the arm hanging from it, into its fixed world body.
    """
    root = etree.fromstring(xml.encode() if isinstance(xml, str) else xml)
    for element in root.findall("link/visual"):
        element.getparent().remove(element)
    for element in root.findall("link/collision"):
        if element.find("geometry/mesh") is not None:
            element.getparent().remove(element)
    for path, key in (("link", "name"), ("joint/parent", "link"), ("joint/child", "link")):
        for element in root.findall(path):
            if element.get(key) == "world":
                element.set(key, WORLD_LINK)
    return etree.tostring(root)


def _drive_axle(xml: bytes, label: str) -> DriveAxle:
    """The drive axle of an assembled URDF (whose root is the drive footprint)."""
    urdf = yourdfpy.URDF.load(
        io.BytesIO(xml),
        build_scene_graph=False,
        load_meshes=False,
        load_collision_meshes=False,
        filename_handler=yourdfpy.filename_handler_null,
    )
    return find_drive_axle(UrdfSource(urdf.robot, label, ()))


def _rotation(quat: np.ndarray) -> np.ndarray:
    """The rotation matrix of a MuJoCo quaternion ``[w, x, y, z]``. Shape (3, 3)."""
    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, np.asarray(quat, dtype=float))
    return matrix.reshape(3, 3)


def _welded_frames(root: mujoco.MjsBody) -> list[tuple[mujoco.MjsBody, np.ndarray, np.ndarray]]:
    """``root`` and every body welded to it (reached without crossing a joint), with frames.

    Each body comes with its position [m] and rotation in ``root``'s frame.
    """
    found, frontier = [], [(root, np.zeros(3), np.eye(3))]
    while frontier:
        body, position, rotation = frontier.pop()
        found.append((body, position, rotation))
        for child in body.bodies:
            if not child.joints:
                offset = position + rotation @ np.asarray(child.pos, dtype=float)
                frontier.append((child, offset, rotation @ _rotation(child.quat)))
    return found


def _static_descendants(body: mujoco.MjsBody) -> list[mujoco.MjsBody]:
    """``body`` and every body welded to it (reached without crossing a joint)."""
    return [welded for welded, _, _ in _welded_frames(body)]


def _geometry_bottoms(root: mujoco.MjsBody) -> list[tuple[mujoco.MjsGeom, float]]:
    """Each primitive geom welded to ``root``, with its lowest point's height [m].

    Heights in ``root``'s frame: a sphere's centre minus its radius; a box's, capsule's or
    cylinder's lowest corner or rim as turned.
    """
    found = []
    for body, position, rotation in _welded_frames(root):
        for geom in body.geoms:
            up = np.abs((rotation @ _rotation(geom.quat))[2])  # |z| of the geom's axes
            centre = position + rotation @ np.asarray(geom.pos, dtype=float)
            size = np.asarray(geom.size, dtype=float)
            depth = {
                mujoco.mjtGeom.mjGEOM_SPHERE: size[0],
                mujoco.mjtGeom.mjGEOM_CAPSULE: size[0] + size[1] * up[2],
                mujoco.mjtGeom.mjGEOM_CYLINDER: size[0] * np.sqrt(max(1.0 - up[2] ** 2, 0.0))
                + size[1] * up[2],
                mujoco.mjtGeom.mjGEOM_BOX: float(up @ size),
            }.get(geom.type)
            if depth is not None:
                found.append((geom, float(centre[2] - depth)))
    return found


def _drop_geometry_below_the_floor(
    spec: mujoco.MjSpec, root: mujoco.MjsBody, label: str
) -> list[float]:
    """Remove the platform's primitive geoms that reach below the floor of the drive keys.

    Returns the lowest points [m] of those kept (:func:`_geometry_bottoms`).

    Wheels built from the keys touch the floor at the root's ``z = 0``. Geometry that reaches
    lower (a planning URDF's bounding spheres: Fetch whole-body's reach 0.06 m below) would
    hold them in the air, and the platform would never move; it is not a support, and is
    removed with a warning (:class:`~pbvs_pin.exceptions.PbvsWarning`) naming the file.
    """
    bottoms = _geometry_bottoms(root)
    below = [(geom, bottom) for geom, bottom in bottoms if bottom < -FLOOR_TOLERANCE]
    for geom, _ in below:
        spec.delete(geom)
    if below:
        warnings.warn(
            f"{label}: {len(below)} collision shapes of the platform reach up to "
            f"{-min(b for _, b in below):.3f} m below the floor its drive keys give (wheel_radius: "
            "the wheels touch the floor at the root link's z = 0); the MuJoCo plant leaves them "
            "out so that the wheels touch the floor",
            PbvsWarning,
            stacklevel=4,
        )
    return [bottom for _, bottom in bottoms if bottom >= -FLOOR_TOLERANCE]


def _repair_inertia(body: mujoco.MjsBody) -> None:
    """Replace a full inertia that is not positive definite by its diagonal's magnitudes.

    MuJoCo refuses such an inertia, Pinocchio does not: TIAGo's antenna links (1e-6 kg) have
    products of inertia larger than their moments. The change is far below the arm's and the
    platform's inertias (the cross-engine test holds to 1e-6).
    """
    full = np.asarray(body.fullinertia, dtype=float)
    if np.isnan(full[0]):
        return
    xx, yy, zz, xy, xz, yz = full
    matrix = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    if np.linalg.eigvalsh(matrix)[0] <= 0.0:
        body.fullinertia = [abs(xx), abs(yy), abs(zz), 0.0, 0.0, 0.0]


def build_spec(
    robot: MobileManipulator, friction: float = WHEEL_FRICTION
) -> tuple[mujoco.MjSpec, DriveAxle | None]:
    """MuJoCo description of ``robot`` on a ground plane, without actuators.

    Args:
        robot: A differential-drive or omnidirectional robot built from a URDF
            (``robot.urdf_xml`` set).
        friction: Sliding friction coefficient of the drive wheels on the ground.

    Returns:
        The spec (free joint on the drive footprint, ground, contact geometry; or a holonomic
        base's planar joints, :func:`_holonomic_spec`) and the drive axle found in the URDF, or
        built from the drive keys if it has none (:mod:`pbvs_pin.plant.mujoco_wheels`; None:
        holonomic).

    Raises:
        UrdfError: If the robot has no URDF, has a fixed base, or MuJoCo rejects it.
        GainError: If ``friction`` is not positive.
    """
    if robot.urdf_xml is None or not isinstance(robot.base, DifferentialDrive | Omnidirectional):
        raise UrdfError(
            robot.source,
            "MuJoCo plant: expected a differential-drive or omnidirectional robot built from a "
            "URDF (MobileManipulator.from_urdf or assemble)",
        )
    if not (np.isfinite(friction) and friction > 0):
        raise GainError(f"MuJoCo plant: expected wheel friction > 0, got {friction}")
    xml = _strip_geometry(robot.urdf_xml)
    if isinstance(robot.base, Omnidirectional):
        return _holonomic_spec(robot, xml), None
    spec = _read_spec(xml, robot.source)
    try:
        axle = _drive_axle(xml, robot.source)
        root = spec.body(frames.DRIVE_FOOTPRINT)
    except DriveAxleNotFound:  # the drive keys gave the drive: wheels built from them
        root = spec.worldbody.first_body()
        kept = _drop_geometry_below_the_floor(spec, root, robot.source)
        supported = any(bottom <= FLOOR_TOLERANCE for bottom in kept)  # something stands on it
        axle = add_key_wheels(spec, root, robot.base, supported)
    root.add_freejoint(name=frames.DRIVE_FOOTPRINT)
    platform = {body.name for body in _static_descendants(root)}
    wheels = {spec.joint(name).parent.name for name in axle.wheel_joints}
    _lock_other_joints(spec, robot, (frames.DRIVE_FOOTPRINT, *axle.wheel_joints))
    for body in spec.bodies:
        for geom in body.geoms:
            if body.name in wheels or (
                body.name in platform and geom.type != mujoco.mjtGeom.mjGEOM_MESH
            ):
                geom.contype, geom.conaffinity = 0, _CONTACT_AFFINITY
                geom.condim = 3 if body.name in wheels else 1
                geom.friction = [friction, 0.0, 0.0] if body.name in wheels else [0, 0, 0]
            else:
                spec.delete(geom)
    for name in wheels:
        if not spec.body(name).geoms:
            raise UrdfError(robot.source, f"wheel link {name!r}: expected a cylinder or sphere")
    spec.worldbody.add_geom(
        name=GROUND,
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[0.0, 0.0, 1.0],
        contype=_CONTACT_AFFINITY,
        conaffinity=0,
        condim=1,
        friction=[0.0, 0.0, 0.0],
    )
    return spec, axle


PLANAR_JOINTS = (
    ("base_x", mujoco.mjtJoint.mjJNT_SLIDE, (1.0, 0.0, 0.0)),
    ("base_y", mujoco.mjtJoint.mjJNT_SLIDE, (0.0, 1.0, 0.0)),
    ("base_yaw", mujoco.mjtJoint.mjJNT_HINGE, (0.0, 0.0, 1.0)),
)
"""A holonomic base's joints in MuJoCo: name, type, axis (the world's, at the start)."""


def _read_spec(xml: bytes, label: str) -> mujoco.MjSpec:
    """MuJoCo's spec of a stripped URDF, inertias from ``<inertial>`` only (repaired)."""
    try:
        spec = mujoco.MjSpec.from_string(xml.decode())
    except ValueError as err:
        raise UrdfError(label, f"MuJoCo cannot read the URDF: {err}") from err
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.compiler.fusestatic = True
    for body in spec.bodies:
        _repair_inertia(body)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    return spec


def _lock_other_joints(spec: mujoco.MjSpec, robot: MobileManipulator, keep: tuple) -> None:
    """Weld every joint the controller's model locks: a head, fingers, another arm.

    Pinocchio's reduced model holds them at their neutral position (zero, the URDF's joint
    origin), which is where a joint removed from the URDF's body leaves its child.

    Args:
        spec: The spec, edited.
        robot: The controller's model, whose arm joints stay.
        keep: Other joints that stay (the root's, the drive wheels').
    """
    kept = {*robot.arm_joint_names, *keep}
    for joint in list(spec.joints):
        if joint.name not in kept:
            spec.delete(joint)


def _holonomic_spec(robot: MobileManipulator, xml: bytes) -> mujoco.MjSpec:
    """A holonomic base: the platform's root body on planar joints, no contact geometry.

    Mecanum, omni and swerve wheels are not simulated: the root body slides along the world's
    x and y and turns about z (:data:`PLANAR_JOINTS`), each joint driven by a velocity servo
    (:class:`~pbvs_pin.plant.mujoco_plant.MujocoPlant`). The arm and platform keep their
    masses, inertias and couplings.
    """
    spec = _read_spec(xml, robot.source)
    _lock_other_joints(spec, robot, ())
    root = spec.worldbody.first_body()
    for name, kind, axis in PLANAR_JOINTS:
        root.add_joint(name=name, type=kind, axis=list(axis))
    for body in spec.bodies:
        for geom in body.geoms:
            spec.delete(geom)
    return spec
