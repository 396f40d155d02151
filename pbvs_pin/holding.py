"""Whether a robot's joints can hold its home posture against gravity.

A joint's servo clips its torque (force) to the URDF's ``effort`` limit (:mod:`pbvs_pin.servo`).
When the gravity load at home is above that limit, the joint cannot hold the robot still: from
the first step it sags at a growing speed, and the controller refuses the measured velocity
once it is ten times the joint's limit (:mod:`pbvs_pin.control.bounds`), a message that names
neither the joint nor the cause. Link masses the user chose (``geometry_density`` fills a
mesh solid) or an arm on a joint made for a lighter one both lead there.
:func:`overloaded_joints` finds those joints from the gravity torque ``g(q)`` (Pinocchio's
``computeGeneralizedGravity``) at home, and :func:`warn_overloaded` warns, naming them.
"""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin

from pbvs_pin.exceptions import PbvsWarning
from pbvs_pin.robot import MobileManipulator


def overloaded_joints(robot: MobileManipulator, q: np.ndarray) -> list[tuple[str, float, float]]:
    """Arm joints whose gravity load at ``q`` exceeds their effort limit.

    Args:
        robot: The robot.
        q: Configuration. Shape (nq,).

    Returns:
        Per such joint: its name, the load ``|g_i(q)|`` [N m or N] and the limit [N m or N].
    """
    model = robot.model
    gravity = pin.computeGeneralizedGravity(model, model.createData(), q)
    found = []
    for name in robot.arm_joint_names:
        index = model.joints[model.getJointId(name)].idx_v
        limit = float(model.effortLimit[index])
        load = abs(float(gravity[index]))
        if np.isfinite(limit) and 0.0 < limit < load:
            found.append((name, load, limit))
    return found


def warn_overloaded(robot: MobileManipulator, where: str) -> list[tuple[str, float, float]]:
    """Warn (:class:`PbvsWarning`) about the joints that cannot hold the robot at home.

    Args:
        robot: The robot, with its ``home_arm`` set.
        where: The file or robot named in the warning.

    Returns:
        What :func:`overloaded_joints` found at home.
    """
    found = overloaded_joints(robot, robot.home())
    if found:
        loads = ", ".join(f"{name} {load:.4g} > {limit:.4g}" for name, load, limit in found)
        warnings.warn(
            f"{where}: at home, gravity loads joints past their URDF effort limit [N m or N]: "
            f"{loads}; they cannot hold the robot and will sag. Check the links' masses "
            "(geometry_density fills each mesh solid) and the arm's home",
            PbvsWarning,
            stacklevel=2,
        )
    return found
