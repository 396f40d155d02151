"""Static stability on the MuJoCo plant: the robot's centre of mass over its wheels' support.

The Pinocchio plant's platform is a planar joint: it cannot tip. On the MuJoCo plant the
platform stands on its wheels (and casters), so an arm whose home posture carries the centre
of mass beyond them tips the robot over before the run starts: the zoo's Panda, UR5e, Baxter
arm and KUKA iiwa on the Pioneer 3-AT do (``docs/zoo.rst``). :func:`support_margin` measures
it at the configuration MuJoCo's data holds, :func:`warn_if_tipping` says so.
"""

from __future__ import annotations

import warnings

import mujoco
import numpy as np

from pbvs_pin.exceptions import PbvsWarning


def support_margin(data: mujoco.MjData) -> float:
    """How far [m] the centre of mass lies inside the support (negative: outside).

    The support is the rectangle of the floor contacts' extent in the platform's frame
    (body 1, the root), the centre of mass the whole robot's (``data.subtree_com`` of the
    root), both from the last ``mj_forward``. Without contacts: ``-inf``.
    """
    if data.ncon == 0:
        return -np.inf
    rotation = data.xmat[1].reshape(3, 3)
    origin = data.xpos[1]
    contacts = np.array([data.contact[i].pos for i in range(data.ncon)])
    local = (contacts - origin) @ rotation  # rows: R^T (p - o)
    centre = (data.subtree_com[1] - origin) @ rotation
    low, high = local[:, :2].min(axis=0), local[:, :2].max(axis=0)
    return float(np.min(np.concatenate([centre[:2] - low, high - centre[:2]])))


def warn_if_tipping(data: mujoco.MjData, label: str) -> None:
    """Warn (:class:`PbvsWarning`) when the centre of mass lies outside the wheels' support.

    The support's rectangle is larger than the triangle of two wheels and a caster, so a robot
    that tips over such a triangle's edge may go unwarned.
    """
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
            "keeps the centre of mass over the wheels (robot.home)",
            PbvsWarning,
            stacklevel=3,
        )
