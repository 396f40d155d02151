r"""Keep standing: a secondary objective that keeps the centre of mass inside the support.

A heavy arm reaching after the target carries the robot's centre of mass towards the edge of
its platform's support; past it, the platform tips over (on the MuJoCo plant: the UR5 and UR10
on the 13.2 kg Pioneer, Baxter's arm, the UR5e). The home keeps the centre of mass
:data:`~pbvs_pin.model.support.COM_MARGIN` (0.05 m) inside (:mod:`pbvs_pin.bringup.home`);
nothing in the paper's objectives (eqs. 16-19) keeps it there while the robot moves. This
objective does, within the null space of the image task like the others (an extension, not in
the paper).

With the rows of :class:`pbvs_pin.model.support.SupportRows` (margin ``m``: the home's), the
least one ``s_i < 0`` and its gradient ``g = ds_i / d theta`` in the arm joints, the arm's part
of ``Lambda`` is

.. math:: \Lambda_{arm} = k_s\, (-s_i)\, \frac{g}{\max(g^\top g,\ \epsilon)}

so that, where the null space lets it act in full, ``ds_i/dt = k_s (-s_i)``: the deficit
closes at the rate ``k_s`` (``secondary.k_support``). Zero while every row keeps its margin, so
a robot whose centre of mass stays inside runs bit for bit as without it. Evaluated in Python
at each step (one ``pin.jacobianCenterOfMass``), beside the compiled step's objectives.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from pbvs_pin.control.secondary import SecondaryInput, SecondaryObjective, check_positive
from pbvs_pin.model.support import COM_MARGIN, SupportRows, at_origin

if TYPE_CHECKING:  # pragma: no cover - typing only
    from pbvs_pin.model.robot import MobileManipulator

GRADIENT_FLOOR = 1e-6
"""``epsilon`` [m^2/rad^2]: below it the arm cannot move the centre of mass, and the
objective asks for at most ``k_s (-s_i) g / epsilon``."""


class KeepSupported(SecondaryObjective):
    """Push the arm back when the centre of mass comes within ``margin`` of the support's edge.

    Attributes:
        rows: The support rows (:class:`~pbvs_pin.model.support.SupportRows`).
        gain: ``k_s`` [1/s].
    """

    def __init__(
        self,
        model: MobileManipulator,
        support: np.ndarray,
        gain: float = 10.0,
        margin: float = COM_MARGIN,
        target: np.ndarray | None = None,
    ) -> None:
        """Rows of ``model`` on ``support`` (shape (m, 2), m >= 3, counter-clockwise) [m].

        Each edge keeps ``margin`` [m], or less where the posture target ``target`` (``theta_d``
        of eq. (19), shape (n_arm,)) keeps less: a shipped recipe's home (the Z1's, the Kinova's)
        stands closer to an edge than the computed homes' 0.05 m, and a margin the target does
        not keep would hold the arm away from it for good (measured: the Z1 and Kinova arms
        0.73 and 0.46 rad from ``theta_d`` at the end of Experiment 2).

        Raises:
            GainError: If ``gain`` is not positive and finite.
        """
        check_positive("KeepSupported", gain=gain)
        support = np.asarray(support, dtype=float)
        self._data = model.model.createData()
        margins = np.full(len(support), float(margin))
        if target is not None:
            q = model.with_arm_positions(model.neutral(), target)  # platform at the origin
            at_target = SupportRows(model, support, 0.0).slack(q, self._data)[0]
            margins = np.minimum(margins, np.maximum(at_target, 0.0))
        self.rows = SupportRows(model, support, margins)
        self.gain = gain

    def contribution(self, state: SecondaryInput, n_base: int, n: int) -> np.ndarray:
        """``[0, ..., Lambda_arm]``: zero unless a row is below its margin. Shape (n,)."""
        out = np.zeros(n)
        if state.q is None:
            return out
        slack, gradient = self.rows.slack(at_origin(state.q), self._data)
        worst = int(np.argmin(slack))
        if slack[worst] >= 0.0:
            return out
        g = gradient[worst]
        out[n_base:] = self.gain * (-slack[worst]) * g / max(float(g @ g), GRADIENT_FLOOR)
        return out
