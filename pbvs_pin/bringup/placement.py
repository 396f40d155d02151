"""Where a robot's links are at home: below the floor, or inside the platform.

A URDF mounted as it comes can bring parts the robot does not have on this platform: Baxter's
pedestal and casters end below the floor, its other arm hangs through the platform. Nothing
breaks (the model only moves the camera chain), but the views and the MuJoCo plant show them.
:func:`placement_problems` finds them from the visual geometry's bounding boxes at a
configuration, and :func:`warn_placement` warns, naming the links and the keys that drop them
(``arm_root``, ``arm_tip``).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pbvs_pin.exceptions import PbvsWarning
from pbvs_pin.model.robot import MobileManipulator

FLOOR_TOLERANCE = 0.02
"""Depth [m] below the floor (z = 0) that a link's geometry may reach: a wheel's flattening."""

OVERLAP_MARGIN = 0.03
"""Depth [m] by which an arm link's box must enter a platform link's box to count: arm links
resting on the platform's top plate touch it by design."""


@dataclass(frozen=True)
class Placement:
    """Links badly placed at one configuration.

    Attributes:
        below_floor: Links whose geometry goes more than :data:`FLOOR_TOLERANCE` below z = 0.
        inside_platform: Mounted arm links whose geometry enters a platform link's by more
            than :data:`OVERLAP_MARGIN` (empty for a robot with no mounted arm).
    """

    below_floor: tuple[str, ...]
    inside_platform: tuple[str, ...]


def world_boxes(robot: MobileManipulator, q: np.ndarray) -> dict[str, np.ndarray]:
    """Axis-aligned bounding box in the world of each link's visual geometry at ``q``.

    Args:
        robot: The robot.
        q: Configuration. Shape (nq,).

    Returns:
        Link name to ``[min, max]`` corners [m], shape (2, 3); links without geometry absent.
    """
    model, visual = robot.model, robot.visual_model
    data = visual.createData()
    pin.updateGeometryPlacements(model, robot.data, visual, data, robot.check_configuration(q))
    boxes: dict[str, np.ndarray] = {}
    for index, geometry in enumerate(visual.geometryObjects):
        shape = geometry.geometry
        shape.computeLocalAABB()
        low, high = np.asarray(shape.aabb_local.min_), np.asarray(shape.aabb_local.max_)
        corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1])
                            for z in (low[2], high[2])])  # fmt: skip
        pose = data.oMg[index]
        world = corners @ pose.rotation.T + pose.translation
        box = np.array([world.min(axis=0), world.max(axis=0)])
        link = model.frames[geometry.parentFrame].name
        if link in boxes:
            box = np.array([np.minimum(boxes[link][0], box[0]), np.maximum(boxes[link][1], box[1])])
        boxes[link] = box
    return boxes


def placement_problems(robot: MobileManipulator, q: np.ndarray) -> Placement:
    """Links below the floor, and mounted arm links inside the platform, at ``q``.

    Args:
        robot: The robot; its ``mounted_links`` tell arm from platform.
        q: Configuration. Shape (nq,).
    """
    boxes = world_boxes(robot, q)
    below = tuple(link for link, box in boxes.items() if box[0, 2] < -FLOOR_TOLERANCE)
    arm = set(robot.mounted_links)
    platform = [box for link, box in boxes.items() if link not in arm]
    inside = tuple(
        link
        for link, box in boxes.items()
        if link in arm and any(_overlap(box, other) > OVERLAP_MARGIN for other in platform)
    )
    return Placement(below, inside)


def _overlap(box: np.ndarray, other: np.ndarray) -> float:
    """Depth [m] of the overlap of two boxes (``[min, max]``, shape (2, 3)); < 0 if apart."""
    return float(np.min(np.minimum(box[1], other[1]) - np.maximum(box[0], other[0])))


def warn_placement(robot: MobileManipulator, where: str) -> Placement:
    """Warn (:class:`PbvsWarning`) about the links :func:`placement_problems` finds at home.

    Args:
        robot: The robot, with its ``home_arm`` set.
        where: The file or robot named in the warning.

    Returns:
        What was found.
    """
    found = placement_problems(robot, robot.home())
    parts = []
    if found.below_floor:
        parts.append(f"links below the floor: {', '.join(found.below_floor)}")
    if found.inside_platform:
        parts.append(f"arm links inside the platform: {', '.join(found.inside_platform)}")
    if parts:
        warnings.warn(
            f"{where}: at home, {'; '.join(parts)}. If they are not part of the robot on this "
            "platform, mount only the arm's chain with arm_root and arm_tip (the links from "
            "the arm's mount down to the camera link); else raise the mount",
            PbvsWarning,
            stacklevel=2,
        )
    return found
