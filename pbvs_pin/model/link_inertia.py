"""Mass and inertia of links from their geometry, for URDFs that give none.

Many published URDFs are made for viewing and carry no ``<inertial>``: their joints then move
no mass, and the simulated servos and the dynamic compensation have nothing to act on
(:mod:`pbvs_pin.model.servo` refuses such an arm, naming the joints). With ``geometry_density``
[kg/m^3] (the ``[robot]`` key, or the argument of :meth:`MobileManipulator.from_urdf
<pbvs_pin.model.robot.MobileManipulator.from_urdf>` and ``assemble``), each link without
``<inertial>`` gets the mass, centre of mass and inertia of its collision geometry (of its
visual geometry when it has no collision geometry) filled with that uniform density, as
MuJoCo's ``inertiafromgeom`` compiler option does. Boxes, cylinders and spheres are exact
(trimesh's primitives); a mesh is taken as the solid it encloses when it is closed, else as
its convex hull. The parts of a link add up about their common centre of mass (the
parallel-axis theorem). A link without geometry stays massless.

A uniform density is an assumption, stated by the user: 1000 kg/m^3 gives 24.0 kg for the
KUKA iiwa 14's base and seven links from their collision meshes (rtb-data's URDF, which has no
``<inertial>``). Nothing checks that the geometry is the robot's own, at its size.
"""

from __future__ import annotations

import numpy as np
import trimesh
import yourdfpy

from pbvs_pin.exceptions import GainError, UrdfError
from pbvs_pin.validation import as_number

GEOMETRY_KEY = "geometry_density"
"""The ``[robot]`` key (and API argument) that fills missing inertias from geometry."""


def checked_density(value: object) -> float:
    """``geometry_density`` as a positive finite float [kg/m^3].

    Raises:
        WrongType: If it is not a single real number (text and booleans are not).
        GainError: If it is not finite and above zero.
    """
    density = as_number(GEOMETRY_KEY, value, finite=False)
    if not (np.isfinite(density) and density > 0.0):
        raise GainError(
            f"{GEOMETRY_KEY}: expected a density > 0 [kg/m^3], got {value!r}", GEOMETRY_KEY
        )
    return density


def fill_missing_inertias(robot: yourdfpy.Robot, density: float, label: str) -> list[str]:
    """Give each link without ``<inertial>`` the inertia of its geometry at ``density``.

    Args:
        robot: The description, with mesh file names resolved; edited in place.
        density: Uniform density [kg/m^3], > 0.
        label: File the URDF came from, for messages.

    Returns:
        The names of the links that got an inertia.

    Raises:
        UrdfError: If a mesh of such a link cannot be read.
    """
    filled = []
    for link in robot.links:
        if link.inertial is not None:
            continue
        parts = [_solid(element, link.name, label) for element in link.collisions or link.visuals]
        parts = [part for part in parts if part is not None]
        if parts:
            link.inertial = combined_inertial(parts, density)
            filled.append(link.name)
    return filled


def combined_inertial(parts: list[trimesh.Trimesh], density: float) -> yourdfpy.Inertial:
    """The inertial of rigidly joined solids of one density, about their centre of mass.

    Args:
        parts: Solids in the link's frame [m].
        density: Uniform density [kg/m^3].

    Returns:
        Mass [kg], centre of mass as the origin's translation [m], inertia [kg m^2] in axes
        parallel to the link's.
    """
    masses = np.array([density * part.volume for part in parts])
    centres = np.array([part.center_mass for part in parts])
    mass = float(masses.sum())
    centre = masses @ centres / mass
    inertia = np.zeros((3, 3))
    for part, part_mass, part_centre in zip(parts, masses, centres, strict=True):
        offset = part_centre - centre
        # trimesh's moment_inertia is for unit density, about the part's centre of mass
        inertia += density * np.asarray(part.moment_inertia) + part_mass * (
            offset @ offset * np.eye(3) - np.outer(offset, offset)
        )
    origin = np.eye(4)
    origin[:3, 3] = centre
    return yourdfpy.Inertial(mass=mass, origin=origin, inertia=inertia)


def _solid(element: yourdfpy.Collision | yourdfpy.Visual, link: str, label: str):
    """The element's geometry as a solid in the link's frame; None for an empty geometry."""
    geometry = element.geometry
    if geometry.box is not None:
        solid = trimesh.primitives.Box(extents=geometry.box.size)
    elif geometry.cylinder is not None:
        solid = trimesh.primitives.Cylinder(
            radius=geometry.cylinder.radius, height=geometry.cylinder.length
        )
    elif geometry.sphere is not None:
        solid = trimesh.primitives.Sphere(radius=geometry.sphere.radius)
    elif geometry.mesh is not None:
        solid = _mesh_solid(geometry.mesh, link, label)
    else:
        return None
    if element.origin is not None:
        solid = solid.copy()
        solid.apply_transform(np.asarray(element.origin, dtype=float))
    return solid


def _mesh_solid(mesh: yourdfpy.Mesh, link: str, label: str) -> trimesh.Trimesh:
    """A mesh file's solid: the mesh when closed, else its convex hull; scaled as the URDF says."""
    try:
        solid = trimesh.load(mesh.filename, force="mesh")
        if solid.is_empty:
            raise ValueError("no triangles")
        if mesh.scale is not None:
            scale = np.broadcast_to(np.asarray(mesh.scale, dtype=float), (3,))
            solid.apply_transform(np.diag([*scale, 1.0]))
        return solid if solid.is_watertight else solid.convex_hull
    except Exception as err:  # trimesh and scipy raise many types for unreadable meshes
        raise UrdfError(
            label,
            f"link {link!r}: cannot read the mesh {mesh.filename!r} to compute its inertia "
            f"({GEOMETRY_KEY}): {type(err).__name__}: {err}",
        ) from err
