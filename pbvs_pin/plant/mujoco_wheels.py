r"""Drive wheels built from the drive keys, for a URDF that does not describe its drive axle.

The MuJoCo plant rolls a platform on its URDF's drive axle
(:func:`pbvs_pin.model.assembly.find_drive_axle`). A robot whose drive is given by keys instead
(``wheel_radius``, ``track``, ``wheel_speed_limit``:
:class:`pbvs_pin.model.base.DifferentialDrive`), as Stretch's mesh wheels need, has no such axle:
:func:`add_key_wheels` builds it. Two wheel bodies hang from the platform's root link (where the
controller's planar joint sits, on the floor), at ``(0, +-track / 2, wheel_radius)``, each a
cylinder of ``wheel_radius`` and
:data:`KEY_WHEEL_WIDTH` on a hinge about the root's y axis. Each wheel's mass is
:data:`KEY_WHEEL_MASS_SHARE` of the robot's, taken from the root link's own so that the total
stays the URDF's (its centre of mass moves by that share times the distance from the root's
centre of mass to the axle: about 1 mm on Stretch); its inertia is a solid cylinder's,

.. math:: I_{yy} = m r^2 / 2, \qquad I_{xx} = I_{zz} = m (3 r^2 + w^2) / 12 .

The URDF's own wheel joints are welded (the plant welds every joint the controller's model
locks). A platform with no primitive collision geometry of its own (its caster a mesh, or
none) gets two frictionless spheres of radius ``wheel_radius / 2`` on its centreline,
``track / 2`` ahead of and behind the axle, :data:`KEY_SUPPORT_GAP` above the floor, so that
it stands; Stretch keeps its own caster sphere.
"""

from __future__ import annotations

import mujoco
import numpy as np

from pbvs_pin.model.assembly import DriveAxle
from pbvs_pin.model.base import DifferentialDrive

KEY_WHEEL_WIDTH = 0.04
"""Width [m] of a wheel built from the drive keys."""

KEY_WHEEL_MASS_SHARE = 0.01
"""Mass of each wheel built from the drive keys, as a share of the robot's."""

KEY_WHEELS = ("key_wheel_left", "key_wheel_right")
"""Names of the built wheels' bodies and hinges: left (y > 0), right."""

KEY_SUPPORTS = ("key_support_front", "key_support_rear")
"""Names of the frictionless support spheres added to a platform with no collision geometry."""

KEY_SUPPORT_GAP = 0.002
"""Height [m] of the support spheres' lowest point above the floor. Both wheels then carry the
platform, and one support catches it as it pitches (three points). With both supports on the
floor, four rigid points on a line and two wheels, a reaching arm rolled the platform onto
one wheel: Fetch drove backward at 7-11 mm/s against a forward command of 10-15 mm/s and
missed Experiments 2 and 3 on MuJoCo (22.9 and 28.8 px)."""

_AXIS_Y = [np.sqrt(0.5), -np.sqrt(0.5), 0.0, 0.0]
"""Quaternion turning a geom's z axis (a cylinder's) onto its body's y axis."""


def add_key_wheels(
    spec: mujoco.MjSpec, root: mujoco.MjsBody, drive: DifferentialDrive, supported: bool
) -> DriveAxle:
    """Add the drive's two wheels to the platform's root body (in place).

    Args:
        spec: The robot's spec, geometry stripped (:func:`pbvs_pin.plant.mujoco_spec.build_spec`).
        root: The platform's root body, whose frame lies on the floor at the axle's middle.
        drive: The drive the keys give (its ``wheel_radius`` and ``track`` [m]).
        supported: Whether the platform has collision geometry of its own to stand on; if
            not, :data:`KEY_SUPPORTS` are added.

    Returns:
        The axle: the drive, the identity as footprint, the wheel hinges' names.
    """
    radius, width = drive.wheel_radius, KEY_WHEEL_WIDTH
    mass = KEY_WHEEL_MASS_SHARE * sum(body.mass for body in spec.bodies)
    root.mass = max(root.mass - 2.0 * mass, 0.0)
    across = mass * (3.0 * radius**2 + width**2) / 12.0
    for side, name in zip((1.0, -1.0), KEY_WHEELS, strict=True):
        wheel = root.add_body(name=name, pos=[0.0, side * drive.track / 2, radius])
        wheel.mass, wheel.inertia = mass, [across, mass * radius**2 / 2, across]
        wheel.explicitinertial = True
        wheel.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0.0, 1.0, 0.0])
        wheel.add_geom(
            type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[radius, width / 2, 0.0], quat=_AXIS_Y
        )
    if not supported:
        for sign, name in zip((1.0, -1.0), KEY_SUPPORTS, strict=True):
            root.add_geom(
                name=name,
                type=mujoco.mjtGeom.mjGEOM_SPHERE,
                size=[radius / 2, 0.0, 0.0],
                pos=[sign * drive.track / 2, 0.0, radius / 2 + KEY_SUPPORT_GAP],
            )
    return DriveAxle(drive, np.eye(4), KEY_WHEELS)
