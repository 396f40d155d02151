"""The arm as a chain of a URDF: from ``arm_root`` down to ``arm_tip``.

An arm URDF that brings more than the arm (a second arm, a pedestal, a torso) is cut to the
chain before mounting (:func:`keep_chain`). A URDF that carries its own arm keeps everything,
and every movable joint off the chain is locked at neutral (:func:`lock_outside_chain`).
"""

from __future__ import annotations

import yourdfpy

from pbvs_pin.exceptions import ChainError
from pbvs_pin.model.assembly import UrdfSource


def keep_chain(source: UrdfSource, root: str | None, tip: str) -> None:
    """Keep only the chain from ``root`` down to ``tip`` (in place).

    Kept: the links on the path from ``root`` to ``tip``, and the links fixed to them through
    fixed joints only (covers, sensor frames, a rigid hand). Dropped: everything else (a
    second arm, a pedestal, a head, the movable fingers of a gripper), so it is in neither the
    model, the plant nor the views. ``root`` becomes the description's root link.

    Args:
        source: The arm's description.
        root: First link kept; the description's root link when None.
        tip: Last link kept.

    Raises:
        FrameNotFound: If ``root`` or ``tip`` is not a link.
        ChainError: If ``tip`` does not hang below ``root``.
    """
    root = root or source.root_link()
    joints = _chain(source, root, tip)
    robot = source.robot
    kept = {root, *(joint.child for joint in joints)}
    fixed = [joint for joint in robot.joints if joint.type == "fixed" and joint not in joints]
    grown = True
    while grown:
        attached = [j for j in fixed if j.parent in kept and j.child not in kept]
        kept.update(j.child for j in attached)
        joints.extend(attached)
        grown = bool(attached)
    robot.links = [link for link in robot.links if link.name in kept]
    robot.joints = [joint for joint in robot.joints if joint in joints]
    source.repaired_inertias = tuple(link for link in source.repaired_inertias if link in kept)
    source.filled_inertias = tuple(link for link in source.filled_inertias if link in kept)


def _chain(
    source: UrdfSource, root: str, tip: str, expected: str = "arm_tip below arm_root"
) -> list[yourdfpy.Joint]:
    """The joints from link ``root`` down to link ``tip``, in order.

    Raises:
        FrameNotFound: If ``root`` or ``tip`` is not a link.
        ChainError: If ``tip`` does not hang below ``root``, saying what was ``expected``.
    """
    for link in (root, tip):
        source.require_link(link)
    joint_to = {joint.child: joint for joint in source.robot.joints}
    path = [tip]
    while path[-1] != root:
        if path[-1] not in joint_to:
            raise ChainError(
                source.label,
                f"link {tip!r} does not hang below link {root!r}; expected {expected} (the "
                f"links above {tip!r}: {path[1:] or 'none'})",
            )
        path.append(joint_to[path[-1]].parent)
    return [joint_to[link] for link in reversed(path[:-1])]


def lock_outside_chain(source: UrdfSource, root: str | None, tip: str, camera_link: str) -> None:
    """Make the arm of a URDF that carries its own the chain from ``root`` to ``tip`` (in place).

    Every movable joint off that chain (a torso lift, a head, the other arm, the fingers, a
    wrist below ``tip``) goes into ``source.locked``: the robot holds it at its neutral
    position, as it holds every joint that does not carry the camera. Nothing is removed.

    Args:
        source: The whole robot's description.
        root: First link of the arm; the description's root link when None.
        tip: Last link of the arm.
        camera_link: The link the camera is fixed to: ``tip`` or a link below it.

    Raises:
        FrameNotFound: If ``root``, ``tip`` or ``camera_link`` is not a link.
        ChainError: If ``tip`` does not hang below ``root``, or ``camera_link`` below ``tip``.
    """
    chain = {joint.name for joint in _chain(source, root or source.root_link(), tip)}
    _chain(source, tip, camera_link, "camera_link at or below arm_tip, which carries the camera")
    moving = [joint.name for joint in source.robot.joints if joint.type != "fixed"]
    source.locked = tuple(name for name in moving if name not in chain)
