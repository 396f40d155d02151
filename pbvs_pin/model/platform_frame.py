"""The platform in a URDF: the joints that already model its motion, and its forward axis.

Two things a URDF can say about its platform that the base adapters (:mod:`pbvs_pin.model.base`) do
not expect, handled here before the Pinocchio model is built (:class:`PlatformFrame`):

- **Base joints.** Planning URDFs often model the base's motion as joints in a chain from the
  root link: prismatic x, prismatic y and a revolute or continuous yaw (in any order), one
  ``planar`` joint (axis z), or one ``floating`` joint. The base adapter adds its own planar
  root joint, so these joints would count the base twice, as arm joints.
  :func:`fix_base_joints` makes them fixed at zero: the platform is then rigid with the root
  link, on which the drive's planar root joint sits (the drive axle's footprint below it for a
  differential drive). A root link named ``world`` (MuJoCo's fixed world) is renamed
  :data:`pbvs_pin.model.frames.BASE_JOINTS_ROOT`, since it now moves.
- **Forward axis.** A platform whose root link's x axis is not the way it drives (a
  differential base whose wheel axles lie along x, driving along -y) gets a new root link
  :data:`pbvs_pin.model.frames.PLATFORM_FRAME` at the same origin, x along the forward axis
  (:func:`turn_platform`); :func:`warn_wheel_axles` names the wheel joints that turn about it.
"""

from __future__ import annotations

import warnings
from collections import defaultdict
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import yourdfpy

from pbvs_pin.exceptions import BaseJointsError, GainError, PbvsWarning, UrdfError
from pbvs_pin.model import frames
from pbvs_pin.model.assembly import _AXIS_TOLERANCE, UrdfSource, _fixed_chain_poses, _origin

FORWARD_AXES: dict[str, float] = {"x": 0.0, "y": np.pi / 2, "-x": np.pi, "-y": -np.pi / 2}
"""Forward axis (an axis of the platform URDF's root link) -> yaw [rad] of the platform frame
in that link."""

BASE_MOTIONS = ({"x", "y", "yaw"}, {"planar"}, {"floating"})
"""The joint sets that model a base (:func:`joint_motion` of each joint)."""

WORLD_MASS_FRACTION = 0.01
"""Largest share of the robot's mass on the links the base joints move relative to (the root
and the links between the joints) for the joints to be recognised automatically."""


@dataclass(frozen=True)
class PlatformFrame:
    """Where the platform is in a URDF: the joints modelling its motion, and its forward axis.

    Attributes:
        base_joints: Names of the URDF's joints that model the base's motion (x, y and yaw
            joints, a planar or a floating joint), fixed at zero (:func:`fix_base_joints`);
            None: recognised automatically; empty: none (every joint stays an arm joint).
        forward_axis: The root link's axis the platform drives along, one of
            :data:`FORWARD_AXES`.
    """

    base_joints: tuple[str, ...] | None = None
    forward_axis: str = "x"

    def __post_init__(self) -> None:
        """Check the forward axis and the joint names.

        Raises:
            GainError: Naming ``forward_axis`` or ``base_joints``.
        """
        if not isinstance(self.forward_axis, str) or self.forward_axis not in FORWARD_AXES:
            raise GainError(
                f"expected one of {tuple(FORWARD_AXES)} (the root link's axis the platform "
                f"drives along), got {self.forward_axis!r}", "forward_axis",
            )  # fmt: skip
        if self.base_joints is not None:
            if isinstance(self.base_joints, str) or not all(
                isinstance(name, str) for name in self.base_joints
            ):
                raise GainError(
                    f"expected a list of joint names, got {self.base_joints!r}", "base_joints"
                )
            object.__setattr__(self, "base_joints", tuple(self.base_joints))


def joint_motion(joint: yourdfpy.Joint, rotation: np.ndarray) -> str | None:
    """What a joint does to the platform, if it models a base's motion.

    Args:
        joint: The joint.
        rotation: Orientation of the joint frame in the root link at zero. Shape (3, 3).

    Returns:
        ``"x"`` or ``"y"`` (prismatic along the root's x or y), ``"yaw"`` (revolute or
        continuous about its z), ``"planar"`` (planar, normal z), ``"floating"``, else None.
    """
    if joint.type == "floating":
        return "floating"
    axis = rotation @ np.asarray(joint.axis if joint.axis is not None else [1.0, 0.0, 0.0])
    if not np.linalg.norm(axis) > 0.0:
        return None
    axis = axis / np.linalg.norm(axis)
    along = [abs(axis[i]) >= _AXIS_TOLERANCE for i in range(3)]
    if joint.type == "prismatic" and (along[0] or along[1]):
        return "x" if along[0] else "y"
    if joint.type in ("revolute", "continuous") and along[2]:
        return "yaw"
    if joint.type == "planar" and along[2]:
        return "planar"
    return None


def movable_motions(chain: list[yourdfpy.Joint]) -> list[tuple[yourdfpy.Joint, str | None]]:
    """The movable joints of a chain from the root, each with its :func:`joint_motion`."""
    pose, found = np.eye(4), []
    for joint in chain:
        pose = pose @ _origin(joint)
        if joint.type != "fixed":
            found.append((joint, joint_motion(joint, pose[:3, :3])))
    return found


def describe(chain: list[yourdfpy.Joint]) -> list[str]:
    """``"name (type, motion)"`` for each movable joint of a chain from the root."""
    words = {"x": " along x", "y": " along y", "yaw": " about z", "planar": "", "floating": ""}
    return [
        f"{j.name} ({j.type}{words[m] if m else ', no base motion'})"
        for j, m in movable_motions(chain)
    ]


def _partial(motions: list[str | None]) -> bool:
    """Whether the motions can still grow into one of :data:`BASE_MOTIONS`."""
    return len(set(motions)) == len(motions) and any(set(motions) <= s for s in BASE_MOTIONS)


def _chains(source: UrdfSource) -> list[tuple[list[yourdfpy.Joint], list[str]]]:
    """Every chain from the root whose movable joints make one of :data:`BASE_MOTIONS`.

    Returns:
        Per chain: its joints from the root (fixed ones included) and the motions of its
        movable ones.
    """
    children = defaultdict(list)
    for joint in source.robot.joints:
        children[joint.parent].append(joint)
    found, stack = [], [(source.root_link(), np.eye(4), [], [])]
    while stack:
        link, pose, path, motions = stack.pop()
        for joint in children[link]:
            placed = pose @ _origin(joint)
            moves = joint.type != "fixed"
            grown = [*motions, joint_motion(joint, placed[:3, :3])] if moves else motions
            if not _partial(grown):
                continue
            if grown and set(grown) in BASE_MOTIONS:
                found.append(([*path, joint], grown))
            else:
                stack.append((joint.child, placed, [*path, joint], grown))
    return found


def _world_side(source: UrdfSource, last: yourdfpy.Joint) -> set[str]:
    """The links not carried by ``last``: those the base joints move relative to."""
    carried, frontier = set(), [last.child]
    while frontier:
        link = frontier.pop()
        carried.add(link)
        frontier += [j.child for j in source.robot.joints if j.parent == link]
    return set(source.link_names()) - carried


def _is_world_side(source: UrdfSource, chain: list[yourdfpy.Joint]) -> bool:
    """Whether the chain's root side is a bare world: no other movable joint, almost no mass."""
    world = _world_side(source, chain[-1])
    others = [
        j for j in source.robot.joints if j.parent in world and j.type != "fixed" and j not in chain
    ]
    mass = {
        link.name: link.inertial.mass if link.inertial is not None and link.inertial.mass else 0.0
        for link in source.robot.links
    }
    return not others and sum(mass[n] for n in world) <= WORLD_MASS_FRACTION * sum(mass.values())


def _named_chain(source: UrdfSource, names: tuple[str, ...]) -> list[yourdfpy.Joint]:
    """The chain from the root to the deepest named joint, checked to model a base.

    Raises:
        BaseJointsError: If a name is not a joint, the joints are not in one chain from the
            root with no other movable joint, or do not make one of :data:`BASE_MOTIONS`.
    """
    joints = {joint.name: joint for joint in source.robot.joints}
    movable = [name for name, joint in joints.items() if joint.type != "fixed"]
    for name in names:
        if name not in joints:
            raise BaseJointsError(
                source.label, f"base_joints: no joint {name!r}; movable joints: {movable}"
            )
    parent_joint = {joint.child: joint for joint in source.robot.joints}
    chains = []
    for name in names:
        chain, link = [], joints[name].child
        while link in parent_joint:
            chain.insert(0, parent_joint[link])
            link = chain[0].parent
        chains.append(chain)
    chain = max(chains, key=len)
    motions = [motion for _, motion in movable_motions(chain)]
    described = describe(chain)
    if sorted(j.name for j, _ in movable_motions(chain)) != sorted(names) or not (
        _partial(motions) and set(motions) in BASE_MOTIONS
    ):
        raise BaseJointsError(
            source.label,
            f"base_joints: {list(names)} do not model a base; expected, in one chain from the "
            "root link with no other movable joint, prismatic x, prismatic y and a revolute or "
            "continuous yaw (any order), one planar joint (axis z) or one floating joint; the "
            f"chain to them holds {described}",
        )
    return chain


def fix_base_joints(source: UrdfSource, names: tuple[str, ...] | None = None) -> tuple[str, ...]:
    """Fix at zero the joints that model the base's motion (in place).

    Args:
        source: The platform's (or whole robot's) description.
        names: The joints, checked to model a base; None: recognised automatically (a single
            chain from the root whose root side has no other movable joint and at most
            :data:`WORLD_MASS_FRACTION` of the mass), with a warning naming them; empty: none.

    Returns:
        The names of the joints fixed.

    Warns:
        PbvsWarning: Naming the file and the joints recognised automatically.

    Raises:
        BaseJointsError: If named joints do not model a base (:func:`_named_chain`).
        UrdfError: If the root link is ``world`` and :data:`frames.BASE_JOINTS_ROOT` is taken.
    """
    if names is not None and not names:
        return ()
    if names is None:
        chains = [chain for chain, _ in _chains(source) if _is_world_side(source, chain)]
        if len(chains) != 1:
            return ()
        chain = chains[0]
    else:
        chain = _named_chain(source, names)
    fixed = tuple(joint.name for joint in chain if joint.type != "fixed")
    if names is None:
        warnings.warn(
            f"{source.label}: joints {', '.join(describe(chain))} model the platform's motion from "
            f"the root link {source.root_link()!r}: they are fixed at zero, not arm joints, and "
            "the drive's planar root joint moves the platform (name them with base_joints = "
            f"{list(fixed)} to silence this, or base_joints = [] to keep them as arm joints)",
            PbvsWarning,
            stacklevel=3,
        )
    for joint in chain:
        if joint.type != "fixed":
            joint.type, joint.axis, joint.limit, joint.dynamics, joint.mimic = (
                "fixed", None, None, None, None,
            )  # fmt: skip
    if source.root_link() == frames.WORLD:
        _rename_link(source, frames.WORLD, frames.BASE_JOINTS_ROOT)
    return fixed


def _rename_link(source: UrdfSource, old: str, new: str) -> None:
    """Rename a link and the joints' references to it (in place)."""
    if new in source.link_names():
        raise UrdfError(source.label, f"link name {new!r} is reserved")
    next(link for link in source.robot.links if link.name == old).name = new
    for joint in source.robot.joints:
        joint.parent = new if joint.parent == old else joint.parent
        joint.child = new if joint.child == old else joint.child


def turn_platform(source: UrdfSource, forward_axis: str) -> None:
    """Add a root link :data:`frames.PLATFORM_FRAME`, x along ``forward_axis`` (in place).

    Nothing changes for ``"x"``. Then warn about wheel axles along the forward axis.

    Raises:
        UrdfError: If :data:`frames.PLATFORM_FRAME` is already a link.
    """
    root = source.root_link()
    if forward_axis != "x":
        if frames.PLATFORM_FRAME in source.link_names():
            raise UrdfError(source.label, f"link name {frames.PLATFORM_FRAME!r} is reserved")
        source.robot.links.insert(0, yourdfpy.Link(name=frames.PLATFORM_FRAME))
        turn = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, -FORWARD_AXES[forward_axis]), np.zeros(3))
        source.robot.joints.insert(
            0,
            yourdfpy.Joint(
                name=f"{frames.PLATFORM_FRAME}_joint", type="fixed",
                parent=frames.PLATFORM_FRAME, child=root, origin=turn.homogeneous,
            ),
        )  # fmt: skip
    warn_wheel_axles(source, forward_axis, root)


def warn_wheel_axles(source: UrdfSource, forward_axis: str, root: str) -> list[str]:
    """Warn if wheel joints turn about the platform's forward axis (its root link's x).

    A wheel joint is a continuous or revolute joint named (or whose child link is named) with
    ``wheel``, hanging from the root link through fixed joints, with an ``<axis>``.

    Args:
        source: The description, its root link x along the forward axis.
        forward_axis: The forward axis given, for the message.
        root: The platform URDF's own root link, for the message.

    Returns:
        The names of those wheel joints.

    Warns:
        PbvsWarning: Naming the file, the joints, and the ``forward_axis`` to try.
    """
    poses = _fixed_chain_poses(source.robot, source.root_link())
    along = []
    for joint in source.robot.joints:
        wheel = "wheel" in f"{joint.name} {joint.child}".lower()
        if not wheel or joint.type not in ("continuous", "revolute") or joint.parent not in poses:
            continue
        if joint.name in source.axisless:  # no <axis>: the drive axle's finder says so
            continue
        axis = (poses[joint.parent] @ _origin(joint))[:3, :3] @ np.asarray(
            joint.axis if joint.axis is not None else [1.0, 0.0, 0.0]
        )
        if abs(axis[0]) / np.linalg.norm(axis) >= _AXIS_TOLERANCE:
            along.append(joint.name)
    if along:
        across = '"y" or "-y"' if forward_axis in ("x", "-x") else '"x" or "-x"'
        warnings.warn(
            f"{source.label}: wheel joints {along} turn about the platform's forward axis "
            f"(forward_axis = {forward_axis!r}, an axis of the root link {root!r}): the "
            "platform would drive along its wheel axles; set forward_axis to the way it drives "
            f"(here {across})",
            PbvsWarning,
            stacklevel=5,
        )
    return along
