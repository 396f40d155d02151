"""Checks of a URDF before Pinocchio sees it: its tree and its physics.

Pinocchio trusts its input: a link with two parents (a kinematic loop) crashes the process,
and a negative mass or a lower limit above the upper one gives a model that runs and lies. So
every URDF is checked when it is loaded (:func:`pbvs_pin.model.assembly.load_urdf`), and each fault
is a :class:`~pbvs_pin.exceptions.UrdfError` that names the file, the link or joint, the value
and what was expected:

- **Tree** (on the XML): unique link and joint names, every joint's parent and child exist,
  no link has two parents, exactly one root, every link reachable from it (no loop).
- **Links**: a finite mass with ``0 <= m <=`` :data:`MAX_LINK_MASS`; a finite symmetric
  inertia with non-negative diagonal, positive semidefinite (a zero inertia, a point mass, is
  allowed) and whose principal moments satisfy the triangle inequality ``I1 + I2 >= I3``,
  which every rigid body does; the last two within :data:`INERTIA_TOLERANCE` of the trace
  plus :data:`INERTIA_ABSOLUTE_TOLERANCE` (published URDFs hold tiny links a few 1e-8 kg m^2
  off, e.g. TIAGo's antennas, which do not matter).
  A URDF whose inertias break the triangle inequality can be loaded with ``repair_inertia``
  (the ``[robot]`` key of that name): each such inertia is replaced by
  :func:`balance_inertia`, as MuJoCo's ``balanceinertia`` compiler option does.
- **Joints**: finite origins; ``lower <= upper``; a velocity limit that, when given for a
  movable joint, is positive; mesh files that exist (``package://`` URIs are resolved later).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt
import yourdfpy
from lxml import etree

from pbvs_pin.exceptions import UrdfError

MAX_LINK_MASS = 1.0e4
"""Largest mass [kg] of one link: a mobile manipulator's link is never ten tonnes."""

INERTIA_TOLERANCE = 1.0e-6
"""Relative tolerance (of the inertia's trace) of the positivity and triangle checks."""

INERTIA_ABSOLUTE_TOLERANCE = 1.0e-6
"""Absolute tolerance [kg m^2] of the positivity and triangle checks."""

MOVABLE = ("revolute", "continuous", "prismatic")
"""Joint types with one degree of freedom and a velocity limit."""


def check_tree(root: etree._Element, label: str) -> None:
    """Refuse a URDF whose links do not form one tree (see the module doc).

    Args:
        root: The parsed ``<robot>`` element.
        label: File the URDF came from, for messages.

    Raises:
        UrdfError: Naming the link or joint at fault.
    """
    links = [link.get("name") for link in root.findall("link")]
    _unique(links, "link", label)
    joints = root.findall("joint")
    _unique([joint.get("name") for joint in joints], "joint", label)
    parent_of: dict[str, str] = {}
    for joint in joints:
        name = joint.get("name")
        ends = {}
        for end in ("parent", "child"):
            element = joint.find(end)
            ends[end] = element.get("link") if element is not None else None
            if ends[end] not in links:
                raise UrdfError(
                    label,
                    f"joint {name!r}: {end} link {ends[end]!r} is not a link of the file "
                    f'(expected <{end} link="..."/> naming one of its links)',
                )
        child = ends["child"]
        if child in parent_of:
            raise UrdfError(
                label,
                f"link {child!r} has two parents ({parent_of[child]!r} and {ends['parent']!r}, "
                f"through joint {name!r}): a kinematic loop; expected a tree, one parent per link",
            )
        parent_of[child] = ends["parent"]
    roots = [link for link in links if link not in parent_of]
    if len(roots) != 1:
        raise UrdfError(label, f"expected one root link (no parent), found {roots}")
    for link in links:
        seen = {link}
        while link in parent_of:
            link = parent_of[link]
            if link in seen:
                raise UrdfError(
                    label, f"links {sorted(seen)} form a loop; expected a tree from {roots[0]!r}"
                )
            seen.add(link)


def _unique(names: list[str | None], kind: str, label: str) -> None:
    """Every ``kind`` (link or joint) has a name, and no name is used twice."""
    seen: set[str] = set()
    for name in names:
        if not name:
            raise UrdfError(label, f'a <{kind}> has no name; expected name="..."')
        if name in seen:
            raise UrdfError(label, f"two {kind}s are named {name!r}; expected unique names")
        seen.add(name)


def axisless_joints(root: etree._Element) -> frozenset[str]:
    """Names of the joints without an ``<axis>`` element (URDF then defaults to x)."""
    return frozenset(j.get("name") for j in root.findall("joint") if j.find("axis") is None)


REPAIR_KEY = "repair_inertia"
"""The ``[robot]`` key (and API argument) that repairs inertias breaking the triangle rule."""


def balance_inertia(inertia: npt.ArrayLike) -> npt.NDArray[np.float64]:
    r"""An inertia with every principal moment set to their mean, as MuJoCo's ``balanceinertia``.

    MuJoCo's compiler option ``balanceinertia`` sets the three principal moments to their
    average when they break the triangle inequality. The average keeps the trace (the sum of
    the moments, hence the link's polar moment of mass), and three equal moments satisfy the
    inequality. The result is isotropic, so it is the same in every frame:

    .. math::

        I' = \frac{\operatorname{tr} I}{3} \, \mathbb{1}_3

    Args:
        inertia: Rotational inertia about the centre of mass [kg m^2]. Shape (3, 3).

    Returns:
        The repaired inertia [kg m^2]. Shape (3, 3).
    """
    matrix = np.asarray(inertia, dtype=float)
    return np.trace(matrix) / 3.0 * np.eye(3)


def check_physics(robot: yourdfpy.Robot, label: str, repair_inertia: bool = False) -> list[str]:
    """Refuse masses, inertias, limits and origins no robot has (see the module doc).

    Args:
        robot: The yourdfpy description; with ``repair_inertia``, edited in place.
        label: File the URDF came from, for messages.
        repair_inertia: Replace each inertia that breaks the triangle inequality by
            :func:`balance_inertia` instead of refusing it.

    Returns:
        The names of the links whose inertia was repaired (empty without ``repair_inertia``).

    Raises:
        UrdfError: Naming the link or joint, the value and what was expected.
    """
    repaired = []
    for link in robot.links:
        if link.inertial is not None and _check_inertial(
            link.name, link.inertial, label, repair_inertia
        ):
            link.inertial.inertia = balance_inertia(link.inertial.inertia)
            repaired.append(link.name)
    for joint in robot.joints:
        where = f"joint {joint.name!r}"
        if joint.origin is not None and not np.all(np.isfinite(joint.origin)):
            raise UrdfError(label, f"{where}: <origin> is not finite; expected numbers")
        axis = joint.axis
        if axis is not None and (np.shape(axis) != (3,) or not np.all(np.isfinite(axis))):
            shown = " ".join(f"{value:g}" for value in np.ravel(axis))
            raise UrdfError(label, f'{where}: <axis xyz="{shown}">: expected three finite numbers')
        limit = joint.limit
        if limit is None or joint.type not in MOVABLE:
            continue
        lower, upper = limit.lower, limit.upper
        for name, value in (("lower", lower), ("upper", upper), ("velocity", limit.velocity)):
            if value is not None and not np.isfinite(value):
                raise UrdfError(label, f"{where}: <limit {name}> = {value}; expected a number")
        bounded = joint.type != "continuous" and lower is not None and upper is not None
        if bounded and lower > upper:
            raise UrdfError(
                label, f"{where}: <limit lower={lower:g} upper={upper:g}>: expected lower <= upper"
            )
        if limit.velocity is not None and limit.velocity <= 0:
            raise UrdfError(
                label,
                f"{where}: <limit velocity={limit.velocity:g}>: expected a positive speed limit "
                "[rad/s or m/s]",
            )
    return repaired


def _check_inertial(
    link: str, inertial: yourdfpy.Inertial, label: str, repair_inertia: bool
) -> bool:
    """Mass and inertia of one link; whether its inertia is to be repaired."""
    where = f"link {link!r}"
    mass = inertial.mass
    if mass is not None and not (np.isfinite(mass) and 0.0 <= mass <= MAX_LINK_MASS):
        raise UrdfError(
            label, f"{where}: <mass value={mass:g}>: expected 0 <= mass <= {MAX_LINK_MASS:g} kg"
        )
    if inertial.inertia is None:
        return False
    inertia = np.asarray(inertial.inertia, dtype=float)
    if not np.all(np.isfinite(inertia)):
        raise UrdfError(label, f"{where}: <inertia> is not finite; expected numbers")
    moments = np.linalg.eigvalsh(inertia)
    tolerance = INERTIA_TOLERANCE * float(np.trace(np.abs(inertia))) + INERTIA_ABSOLUTE_TOLERANCE
    diagonal = np.diag(inertia).round(9).tolist()
    if np.any(np.diag(inertia) < 0) or moments[0] < -tolerance:
        raise UrdfError(
            label,
            f"{where}: <inertia> (diagonal {diagonal}) has a negative principal moment "
            f"{moments[0]:.3g} kg m^2; expected a positive (semi)definite inertia",
        )
    if moments[0] + moments[1] >= moments[2] - tolerance:
        return False
    if repair_inertia:
        return True
    raise UrdfError(
        label,
        f"{where}: <inertia> principal moments {np.round(moments, 9).tolist()} kg m^2 break "
        "the triangle inequality I1 + I2 >= I3 that every rigid body satisfies; fix the URDF, "
        f"or set {REPAIR_KEY} = true in [robot] ({REPAIR_KEY}=True in Python) to replace each "
        "such inertia by its mean principal moment times the identity, as MuJoCo's "
        "balanceinertia does",
    )


def check_meshes(robot: yourdfpy.Robot, label: str) -> None:
    """Every mesh given as a file path (not a ``package://`` URI) exists.

    Raises:
        UrdfError: Naming the link and the missing file.
    """
    for link in robot.links:
        for element in [*link.visuals, *link.collisions]:
            mesh = element.geometry.mesh if element.geometry is not None else None
            if mesh is None or mesh.filename is None or "://" in mesh.filename:
                continue
            if not Path(mesh.filename).is_file():
                raise UrdfError(
                    label,
                    f"link {link.name!r}: mesh file {mesh.filename} not found (relative paths "
                    "are read against the URDF's folder)",
                )
