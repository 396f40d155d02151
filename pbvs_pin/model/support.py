r"""How far the robot's centre of mass lies inside its platform's support, and how the arm moves it.

A platform stands on the convex polygon of its floor contacts (the *support*, vertices ``v_i``
counter-clockwise in the platform frame, x forward). With its centre of mass ``c`` outside, a
robot standing still tips over. Each edge gives one row

.. math:: s_i(\theta) = n_i^\top (c_{xy}(\theta) - v_i) - m \ge 0

with ``n_i`` the edge's inward unit normal and ``m`` a margin [m]; the rows and their Jacobian
in the arm joints come from Pinocchio's ``centerOfMass`` and ``jacobianCenterOfMass`` of the
whole robot, with the platform at the origin (its pose moves ``c`` and the support together).
The home search (:mod:`pbvs_pin.bringup.home`) keeps them non-negative;
:class:`pbvs_pin.control.support.KeepSupported` keeps them so while the robot moves.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

if TYPE_CHECKING:  # pragma: no cover - typing only
    from pbvs_pin.model.robot import MobileManipulator


COM_MARGIN = 0.05
"""The margin [m] the centre of mass keeps inside the support: at the home
(``HomeCriteria.com_margin``) and, while the robot moves, by
:class:`pbvs_pin.control.support.KeepSupported` (one value, so that at the posture target the
objective does not pull against eq. (19)). A larger one for the objective alone (0.075-0.1 m)
kept the UR10 standing in Experiment 2 on MuJoCo but held its arm 0.13 rad from ``theta_d``."""


class SupportRows:
    """The rows ``s_i`` of one robot, support and margin.

    Attributes:
        normals: Inward unit normal of each edge. Shape (m, 2).
        offsets: ``n_i^T v_i + margin`` [m]. Shape (m,).
        margins: Each edge's margin [m]. Shape (m,).
        arm_columns: The selection's arm columns, Pinocchio velocities to arm joints.
            Shape (nv, n_arm).
    """

    def __init__(
        self, robot: MobileManipulator, vertices: np.ndarray, margin: float | np.ndarray
    ) -> None:
        """Rows for ``vertices`` (shape (m, 2), m >= 3, counter-clockwise) and ``margin``.

        ``margin`` [m]: one for every edge, or one per edge (shape (m,)).
        """
        self.robot = robot
        edges = np.roll(vertices, -1, axis=0) - vertices
        normals = np.stack([-edges[:, 1], edges[:, 0]], axis=1)
        self.normals = normals / np.linalg.norm(normals, axis=1)[:, None]
        self.margins = np.broadcast_to(np.asarray(margin, dtype=float), (len(vertices),)).copy()
        self.offsets = np.sum(self.normals * vertices, axis=1) + self.margins
        self.arm_columns = robot.selection[:, robot.n_base :]

    def slack(
        self, q: np.ndarray, data: pin.Data | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Rows ``s`` [m] and their Jacobian in the arm joints, platform at the origin.

        Returns ``s``, shape (m,), and ``ds / d theta`` [m/rad or m/m], shape (m, n_arm).

        Args:
            q: Configuration; its platform pose must be the origin (:func:`at_origin`).
                Shape (nq,).
            data: Scratch ``pin.Data`` of the robot's model; None: the robot's own.
        """
        rows, centre_jacobian = self.rows(q, data)
        return rows, self.gradient(centre_jacobian)

    def rows(self, q: np.ndarray, data: pin.Data | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Rows ``s`` [m], shape (m,), and the centre of mass's Jacobian, shape (3, nv).

        :meth:`slack` without the gradient, which :meth:`gradient` gives from the Jacobian
        when it is needed (arguments as :meth:`slack`'s).
        """
        robot = self.robot
        data = robot.data if data is None else data
        jacobian = pin.jacobianCenterOfMass(robot.model, data, q)
        return self.normals @ data.com[0][:2] - self.offsets, jacobian

    def gradient(self, centre_jacobian: np.ndarray) -> np.ndarray:
        """``ds / d theta`` [m/rad or m/m] from the centre of mass's Jacobian. Shape (m, n_arm)."""
        return self.normals @ (centre_jacobian[:2] @ self.arm_columns)


def at_origin(q: np.ndarray) -> np.ndarray:
    """A copy of ``q`` with a planar root joint's pose (``x, y, cos, sin``) at the origin.

    Args:
        q: Configuration, the planar root joint first. Shape (nq,).
    """
    local = np.array(q, dtype=float)
    local[:4] = (0.0, 0.0, 1.0, 0.0)
    return local
