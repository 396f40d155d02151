"""Whether a robot's joints can hold its home posture against gravity.

A joint's servo clips its torque (force) to the URDF's ``effort`` limit
(:mod:`pbvs_pin.model.servo`). When the gravity load at home is above that limit, the joint cannot
hold the robot still: from the first step it sags at a growing speed, and the controller refuses the
measured velocity once it is ten times the joint's limit (:mod:`pbvs_pin.control.bounds`), a message
that names neither the joint nor the cause. Link masses the user chose (``geometry_density`` fills a
mesh solid) or an arm on a joint made for a lighter one both lead there.
:func:`overloaded_joints` finds those joints from the gravity torque ``g(q)`` (Pinocchio's
``computeGeneralizedGravity``) at home, and :func:`warn_overloaded` warns, naming them.
:func:`holding_rows` states the same as rows the home solver keeps non-negative
(:mod:`pbvs_pin.bringup.home`), so that a home that overloads a joint is searched again with every
joint's load a stated share below its limit.
"""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin

from pbvs_pin.exceptions import PbvsWarning
from pbvs_pin.model.robot import MobileManipulator


def overloaded_joints(robot: MobileManipulator, q: np.ndarray) -> list[tuple[str, float, float]]:
    """Arm joints whose gravity load at ``q`` exceeds their effort limit.

    Args:
        robot: The robot.
        q: Configuration. Shape (nq,).

    Returns:
        Per such joint: its name, the load ``|g_i(q)|`` [N m or N] and the limit [N m or N].
    """
    model = robot.model
    names, index, limit = _limited(robot)
    load = np.abs(pin.computeGeneralizedGravity(model, model.createData(), q)[index])
    return [
        (name, float(carried), float(most))
        for name, carried, most in zip(names, load, limit, strict=True)
        if most < carried
    ]


def _limited(robot: MobileManipulator) -> tuple[list[str], np.ndarray, np.ndarray]:
    """The arm joints with an effort limit: names, velocity indices (k,) and limits (k,)."""
    model = robot.model
    index = np.array(
        [model.joints[model.getJointId(name)].idx_v for name in robot.arm_joint_names], dtype=int
    )
    limit = np.asarray(model.effortLimit, dtype=float)[index]
    given = np.isfinite(limit) & (limit > 0.0)  # effort <= 0 in a URDF: not given
    names = [name for name, kept in zip(robot.arm_joint_names, given, strict=True) if kept]
    return names, index[given], limit[given]


def holding_rows(
    robot: MobileManipulator, q: np.ndarray, margin: float
) -> tuple[np.ndarray, np.ndarray]:
    r"""Rows that are non-negative when every limited arm joint holds ``q`` with ``margin`` spare.

    .. math:: h_i(q) = 1 - \text{margin} - \frac{|g_i(q)|}{\tau_i^{max}}

    for each arm joint ``i`` with an effort limit ``tau_max`` (``g`` from Pinocchio's
    ``computeGeneralizedGravity``, its derivative from ``computeGeneralizedGravityDerivatives``).

    Args:
        robot: The robot.
        q: Configuration. Shape (nq,).
        margin: Share of each limit kept spare (for the motion), in [0, 1).

    Returns:
        ``h`` (dimensionless), shape (k,), and ``dh/dtheta`` in the arm joints, shape
        (k, n_arm); k = 0 for a robot without effort limits.
    """
    model = robot.model
    _, index, limit = _limited(robot)
    data = model.createData()
    gravity = pin.computeGeneralizedGravity(model, data, q)[index]
    slope = pin.computeGeneralizedGravityDerivatives(model, data, q)[index]
    arm_columns = robot.selection[:, robot.n_base :]
    rows = 1.0 - margin - np.abs(gravity) / limit
    return rows, -(np.sign(gravity) / limit)[:, None] * (slope @ arm_columns)


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
