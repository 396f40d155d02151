"""Odometry jumps: a platform pose that the velocity limits cannot reach in one step.

A driver's odometry can jump (a reset, a relocalisation, a wrapped counter). A frame is placed
at the configuration of its capture instant (:mod:`pbvs_pin.control.encoders`), so after a
jump the readings before it no longer describe where the camera was. The controller checks
each step's planar root pose against the previous one and, on a jump, forgets the encoder
history and the measurement placed with the old odometry.
"""

from __future__ import annotations

import math

import pinocchio as pin

JUMP_SLACK = (0.05, 0.1)
"""Platform motion in one step [m, rad] beyond the velocity limits' reach that counts as an
odometry jump."""


def planar_root_slice(model: pin.Model) -> slice | None:
    """Where a planar root joint's ``[x, y, cos, sin]`` lie in ``q``; None without one."""
    if model.njoints < 2 or model.joints[1].shortname() != "JointModelPlanar":
        return None
    start = model.joints[1].idx_q
    return slice(start, start + 4)


class OdometryJumps:
    """Each step's platform pose against the previous step's.

    Args:
        model: The robot's Pinocchio model (a planar root joint, or none: never a jump).
        speed_limits: Twice the platform's forward and yaw speed limits [m/s, rad/s]: a move
            beyond them (and :data:`JUMP_SLACK`) in one step is a jump.
    """

    def __init__(self, model: pin.Model, speed_limits: tuple[float, float]) -> None:
        self.root = planar_root_slice(model)
        self.speed_limits = speed_limits
        self.previous: tuple[float, float, float, float] | None = None
        """The previous step's ``[x, y, cos, sin]``; None before the first."""

    def jumped(self, q: object, dt: float) -> bool:
        """Whether the planar root moved further than the limits allow in ``dt`` [s]."""
        if self.root is None:
            return False
        x, y, c, s = q[self.root].tolist()
        previous, self.previous = self.previous, (x, y, c, s)
        if previous is None:
            return False
        x0, y0, c0, s0 = previous
        limits = self.speed_limits
        moved = math.hypot(x - x0, y - y0)
        turned = abs(math.atan2(c0 * s - s0 * c, c0 * c + s0 * s))
        return moved > limits[0] * dt + JUMP_SLACK[0] or turned > limits[1] * dt + JUMP_SLACK[1]
