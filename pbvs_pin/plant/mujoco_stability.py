"""Static stability on the MuJoCo plant: the robot's centre of mass over its wheels' support.

The Pinocchio plant's platform is a planar joint: it cannot tip. On the MuJoCo plant the
platform stands on its wheels (and casters), so an arm whose home posture carries the centre
of mass beyond them tips the robot over before the run starts: with the homes they had before
the home solver knew the contacts, the zoo's Panda, UR5e, Baxter arm and KUKA iiwa on the
Pioneer 3-AT did (``docs/zoo.rst``). The support is the convex hull of the floor contacts in the
platform's frame (:func:`contact_polygon`); :func:`polygon_margin` measures how far a point
lies inside it, :func:`support_margin` does so for the centre of mass at the configuration
MuJoCo's data holds, :func:`warn_if_tipping` says when it lies outside.
:func:`pbvs_pin.bringup.home.compute_home` keeps the centre of mass inside the same polygon.
"""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import numpy.typing as npt

from pbvs_pin.exceptions import PbvsWarning
from pbvs_pin.plant.mujoco_wheels import KEY_SUPPORTS


def convex_hull(points: npt.ArrayLike) -> np.ndarray:
    """Vertices of the convex hull of planar points, counter-clockwise (Andrew's monotone chain).

    Args:
        points: Points [m]. Shape (k, 2).

    Returns:
        The hull's vertices, shape (m, 2), ``m <= k``: one or two for points on a point or a
        line, collinear points dropped.
    """
    unique = np.unique(np.asarray(points, dtype=float).reshape(-1, 2), axis=0)  # sorted by x, y
    if len(unique) < 3:
        return unique

    def turns_left(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> bool:
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) > 1e-12

    def chain(ordered: np.ndarray) -> list[np.ndarray]:
        kept: list[np.ndarray] = []
        for point in ordered:
            while len(kept) >= 2 and not turns_left(kept[-2], kept[-1], point):
                kept.pop()
            kept.append(point)
        return kept[:-1]

    return np.array(chain(unique) + chain(unique[::-1]))


def polygon_margin(vertices: npt.ArrayLike, point: npt.ArrayLike) -> float:
    """How far [m] ``point`` lies inside a convex polygon (negative: outside).

    Args:
        vertices: The polygon's vertices counter-clockwise (:func:`convex_hull`). Shape (m, 2).
        point: The point [m]; only its first two coordinates are read. Shape (2,) or (3,).

    Returns:
        The least distance from the point to an edge's line, positive on the inner side of
        every edge. A polygon of one or two vertices (a point, a segment) has no inside: minus
        the distance to it. No vertex: ``-inf``.
    """
    vertices = np.asarray(vertices, dtype=float).reshape(-1, 2)
    point = np.asarray(point, dtype=float)[:2]
    if len(vertices) == 0:
        return -np.inf
    if len(vertices) < 3:
        start, end = vertices[0], vertices[-1]
        length = float(np.dot(end - start, end - start))
        along = 0.0 if length == 0.0 else np.clip(np.dot(point - start, end - start) / length, 0, 1)
        return -float(np.linalg.norm(point - start - along * (end - start)))
    edges = np.roll(vertices, -1, axis=0) - vertices
    inward = np.stack([-edges[:, 1], edges[:, 0]], axis=1) / np.linalg.norm(edges, axis=1)[:, None]
    return float(np.min(np.sum((point - vertices) * inward, axis=1)))


def contact_polygon(data: mujoco.MjData) -> np.ndarray:
    """The support: convex hull of the floor contacts in the platform's frame (body 1, the root).

    From the last ``mj_forward``; with the lowest points of the support spheres built from the
    drive keys (:data:`~pbvs_pin.plant.mujoco_wheels.KEY_SUPPORTS`), which stand
    :data:`~pbvs_pin.plant.mujoco_wheels.KEY_SUPPORT_GAP` above the floor. A wheel placed
    exactly on the floor touches it at one point of its tread's edge, so the hull lies within
    the wheels' footprint: a margin measured against it errs on the safe side.

    Returns:
        The hull's vertices [m] counter-clockwise (:func:`convex_hull`), shape (m, 2); (0, 2)
        without contacts.
    """
    points = [data.contact[i].pos for i in range(data.ncon)]
    if points:  # the key supports, 2 mm above the floor, catch the platform as it pitches
        model = data.model
        for name in KEY_SUPPORTS:
            geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
            if geom >= 0:
                points.append(data.geom_xpos[geom] - [0.0, 0.0, model.geom_size[geom][0]])
    if not points:
        return np.zeros((0, 2))
    rotation = data.xmat[1].reshape(3, 3)
    contacts = np.array(points)
    return convex_hull(((contacts - data.xpos[1]) @ rotation)[:, :2])  # rows: R^T (p - o)


def support_margin(data: mujoco.MjData) -> float:
    """How far [m] the centre of mass lies inside the support (negative: outside).

    The support is :func:`contact_polygon`, the centre of mass the whole robot's
    (``data.subtree_com`` of the root), both from the last ``mj_forward``. Without contacts:
    ``-inf``.
    """
    centre = (data.subtree_com[1] - data.xpos[1]) @ data.xmat[1].reshape(3, 3)
    return polygon_margin(contact_polygon(data), centre)


def warn_if_tipping(data: mujoco.MjData, label: str) -> None:
    """Warn (:class:`PbvsWarning`) when the centre of mass lies outside the wheels' support."""
    margin = support_margin(data)
    if margin == -np.inf:
        warnings.warn(
            f"{label}: at the start nothing of it touches the MuJoCo plant's floor",
            PbvsWarning,
            stacklevel=3,
        )
    elif margin < 0.0:
        warnings.warn(
            f"{label}: at the start its centre of mass lies {-margin:.3f} m outside its wheels' "
            "support: it tips over on the MuJoCo plant (the Pinocchio plant's planar base "
            "cannot tip); mount the arm further back or lower, or give it a home posture that "
            "keeps the centre of mass over the wheels (robot.home; a computed home does)",
            PbvsWarning,
            stacklevel=3,
        )
