r"""What a home posture must keep besides looking forward: standing, and holding against gravity.

:mod:`pbvs_pin.bringup.home` searches a home again with these rows kept non-negative when the home
it found first breaks one: :class:`Balance` keeps the whole robot's centre of mass inside the
platform's support polygon (else the MuJoCo plant's robot tips over), :class:`Holding` keeps
every arm joint's gravity load below its URDF effort limit (else the simulated servos, which
clip their torque there, let the arm sag: :mod:`pbvs_pin.bringup.holding`). Each gives its rows and
their Jacobian in the arm joints from Pinocchio (``centerOfMass``, ``jacobianCenterOfMass``,
``computeGeneralizedGravity`` and its derivatives), never re-derived.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from pbvs_pin.bringup.holding import holding_rows
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.model.support import SupportRows


class Balance(SupportRows):
    r"""The centre of mass kept ``margin`` inside a convex support polygon, platform at the origin.

    The rows of :class:`pbvs_pin.model.support.SupportRows`, kept non-negative.
    """

    def shortfall(self, q: np.ndarray) -> float:
        """How far [m] the centre of mass lacks the margin (0 when it keeps it)."""
        return shortfall_of(self.slack(q)[0])


class Holding:
    """Every effort-limited arm joint holding gravity with ``margin`` of its limit spare.

    Rows :func:`pbvs_pin.bringup.holding.holding_rows` (a share of each limit), with their Jacobian.
    """

    def __init__(self, robot: MobileManipulator, margin: float) -> None:
        self.robot, self.margin = robot, margin

    def slack(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows ``h``, shape (k,), and their Jacobian in the arm joints, shape (k, n_arm)."""
        return holding_rows(self.robot, q, self.margin)

    def shortfall(self, q: np.ndarray) -> float:
        """How far (a share of its limit) the most loaded joint lacks the margin (0: none)."""
        return shortfall_of(self.slack(q)[0])


def shortfall_of(rows: np.ndarray) -> float:
    """How far the lowest row is below 0 (0 when none is)."""
    return max(0.0, -float(np.min(rows))) if rows.size else 0.0


Condition = Balance | Holding
"""Rows a home keeps non-negative."""


def conditions(
    robot: MobileManipulator,
    com_margin: float | None,
    effort_margin: float | None,
    support: np.ndarray | None,
) -> list[tuple[Callable[[np.ndarray], float], Condition]]:
    """Per condition a home must meet: its shortfall at zero margin, and the rows to keep.

    Tipping needs ``com_margin`` [m] and a support of at least three vertices (``support``
    given, shape (m, 2), or the MuJoCo plant's floor contacts); sagging needs
    ``effort_margin`` (a share of each limit). None leaves a condition out.
    """
    checks: list[tuple[Callable[[np.ndarray], float], Condition]] = []
    if com_margin is not None:
        from pbvs_pin.plant.mujoco_stability import convex_hull
        from pbvs_pin.plant.mujoco_support import support_polygon

        support = support_polygon(robot) if support is None else convex_hull(support)
        if support is not None and len(support) >= 3:  # something to stand on, with an inside
            test = Balance(robot, support, 0.0).shortfall
            checks.append((test, Balance(robot, support, com_margin)))
    if effort_margin is not None:
        test = Holding(robot, 0.0).shortfall
        checks.append((test, Holding(robot, effort_margin)))
    return checks
