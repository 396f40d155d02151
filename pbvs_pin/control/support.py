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
a robot whose centre of mass stays inside runs bit for bit as without it.

An arm held at the edge cannot carry eq. (19)'s return to ``theta_d`` either, when the way
back runs over the edge: the pushes of (19) and of this objective cancel (measured: the UR10
on the Pioneer 1.25 rad from ``theta_d`` at the end of Experiment 2, its pan turned 1.25 rad to
where the camera looks, its straight way back 0.019 m past the front edge). Only the platform
can then carry the return, by turning to where the camera looks. So, on a two-wheel platform
whose heading objective is off (:func:`~pbvs_pin.control.secondary.heading_factor`), while a
row is below its margin the objective also adds a share of the heading objective's turn
(:func:`~pbvs_pin.control.secondary.heading_term`, ``psi - psi_d``) with the share

.. math:: w = \min\!\left(1, \frac{-s_i}{\delta}\right)
          \frac{\max(0,\ -g^\top \tilde\theta)}{\|g\|\,\|\tilde\theta\|}\, s_d,\qquad
          s_d = \mathrm{clip}\!\left(\frac{d - d_0}{d_0 / 2}, 0, 1\right)

with ``theta~ = theta_d - theta`` (the posture's pull), ``delta`` :data:`EDGE_RAMP` (the
turn is in full 0.02 m below the row's margin), and ``s_d`` 0 within
``d_0``, rising to 1 at ``1.5 d_0`` (and 1 with nothing seen); its gain is :data:`EDGE_TURN`
``k_psi``. The
middle factor is how squarely (19) pulls the arm over the edge: 0 when the way home leads back
inside, as it does for an arm that reached out after the target (without it the iiwa's and
the Panda's Experiments 2-3 oscillated at 3.4-13 px RMS on MuJoCo, rule 3). ``s_d`` leaves
the yaw to obstacle avoidance near an obstacle at any angle (with the
heading objective's own share, which gives an obstacle abeam the full turn, the UR10 hit
Experiment 2's obstacle: clearance -0.12 m).

**The barrier, above the image task.** Working in the image task's null space, the objective
cannot refuse a reach the task asks for: on the MuJoCo plant the UR10 tipped the Pioneer in
Experiments 2 and 3, reaching after the target until its centre of mass stood 0.014 m past the
front edge. So the command itself is kept on

.. math:: g^\top \dot\theta \ge b = -\gamma\,(d - d_{min}),\qquad d = n_i^\top c - n_i^\top v_i

(``d`` the centre's distance from the edge whose row is least past its kept distance, ``g`` its
gradient): the centre of mass approaches ``d_min`` no faster than ``exp(-gamma t)`` (``gamma``:
:data:`BARRIER_RATE`), and past it is driven back at that rate. ``d_min`` is :data:`EDGE_KEPT`,
or the posture target's own distance from that edge where it is less (the controller's model
may put the target past the edge: with the model error of the experiments, the UR3e's home
stands 0.0045 m past it in the model and 0.019 m inside on the plant; a ``d_min`` the target
does not keep would hold the arm against eq. (19)).
:func:`keep_inside` projects the command onto that half-space in ``W``'s metric, along
``W^-1 g`` (the arm's joints with the default diagonal ``W``), after eq. (34) and before the
velocity limits. It acts whenever the centre of mass would approach ``d_min`` faster than
``gamma (d - d_min)``, which can happen while every row still keeps its margin (a fast arm at
its home's margin: ``b = -0.2`` m/s where the UR5's arm can move it at 0.5 m/s); the reference
robot's arm cannot approach that fast, and its runs are bit for bit those without the
barrier. It holds ``d`` in the controller's model, one row at a time, and the velocity limits
scale the result afterwards. This puts standing above the image task, where the paper has no
such row: where the barrier acts, ``u`` is not eq. (34)'s, and the image error is left to the
platform (the feedback drives it where the arm may not reach). Eq. (9) is evaluated in every
run, so a run where that costs the image error shows it.

:func:`support_term` is the objective's arithmetic, compiled: the control step
(:mod:`pbvs_pin.control.step`) calls it with the centre of mass and its Jacobian from one
Pinocchio call, and :meth:`KeepSupported.contribution`, the reference, with its own.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from pbvs_pin.control.secondary import (
    SecondaryInput,
    SecondaryObjective,
    check_positive,
    heading_share,
    heading_term,
)
from pbvs_pin.exceptions import GainError
from pbvs_pin.linalg import matmul, matvec
from pbvs_pin.model.joint_angles import arm_difference
from pbvs_pin.model.support import COM_MARGIN, SupportRows, at_origin

if TYPE_CHECKING:  # pragma: no cover - typing only
    from pbvs_pin.model.robot import MobileManipulator

GRADIENT_FLOOR = 1e-6
"""``epsilon`` [m^2/rad^2]: below it the arm cannot move the centre of mass, and the
objective asks for at most ``k_s (-s_i) g / epsilon``."""

EDGE_RAMP = 0.02
"""``delta`` [m]: the deficit below a row's margin at which the platform's turn at the edge is
in full. Chosen by measurement: with 0.05 an unshipped UR5 with limited joints
(example-robot-data's ``ur5_limited``) on the Pioneer ended Experiment 2 1.19 rad from
``theta_d``, held 0.01 m below the margin where the turn was a fifth of its gain (0.045 rad
with 0.02)."""

EDGE_KEPT = 0.01
"""``d_min`` [m]: the distance inside the support's edge that the command never takes the
centre of mass past (the barrier)."""

BARRIER_RATE = 5.0
"""``gamma`` [1/s]: the rate at which the barrier lets the centre of mass approach ``d_min``."""

EDGE_TURN = 0.3
"""The platform's turn at the edge as a share of ``k_psi`` (``secondary.k_heading``). Chosen by
measurement: the full ``k_psi`` made the UR5's Experiment 3 on MuJoCo oscillate at 9.35 px RMS
(rule 3; with 0.3, 2.58 and 1.32 with ramps of 0.02 and 0.05 m), and with 0.3 the UR10's
Experiment 2 posture holds (0.055 rad)."""


@njit(cache=True, inline="always")
def worst_row(centre: np.ndarray, normals: np.ndarray, offsets: np.ndarray) -> tuple[int, float]:
    """The least row ``s_i = n_i^T c - offset_i`` [m] and its index (the first of equals).

    Args:
        centre: The centre of mass, platform at the origin [m]. Shape (3,) or (2,).
        normals: Inward unit normals of the support's edges. Shape (m, 2).
        offsets: ``n_i^T v_i + margin_i`` [m]. Shape (m,).
    """
    worst, least = 0, np.inf
    for i in range(normals.shape[0]):
        row = normals[i, 0] * centre[0] + normals[i, 1] * centre[1] - offsets[i]
        if row < least or i == 0:
            worst, least = i, row
    return worst, least


@njit(cache=True, inline="always")
def row_gradient(
    centre_jacobian: np.ndarray, arm_columns: np.ndarray, normals: np.ndarray, row: int
) -> np.ndarray:
    """``g = ds_row / d theta`` [m/rad or m/m]. Shape (n_arm,).

    Args:
        centre_jacobian: The centre of mass's Jacobian, Pinocchio velocities. Shape (3, nv).
        arm_columns: The selection's arm columns. Shape (nv, n_arm).
        normals: Inward unit normals of the support's edges. Shape (m, 2).
        row: The row.
    """
    along = matmul(centre_jacobian[:2], arm_columns)  # the centre's floor velocity per joint
    return normals[row, 0] * along[0] + normals[row, 1] * along[1]


@njit(cache=True, inline="always")
def support_term(
    centre: np.ndarray,
    centre_jacobian: np.ndarray,
    arm_columns: np.ndarray,
    normals: np.ndarray,
    offsets: np.ndarray,
    gain: float,
    theta: np.ndarray,
    target: np.ndarray,
    continuous: np.ndarray,
    turn: float,
    share_distance: float,
    out: np.ndarray,
) -> None:
    r"""Add the objective's ``Lambda`` (module docstring) to ``out``: nothing unless a row is short.

    Args:
        centre: The centre of mass, platform at the origin [m]. Shape (3,).
        centre_jacobian: Its Jacobian, Pinocchio velocities (``pin.jacobianCenterOfMass``).
            Shape (3, nv).
        arm_columns: The selection's arm columns. Shape (nv, n_arm).
        normals: Inward unit normals of the support's edges. Shape (m, 2).
        offsets: ``n_i^T v_i + margin`` [m]. Shape (m,).
        gain: ``k_s`` [1/s].
        theta: The arm's positions [rad or m]. Shape (n_arm,).
        target: ``theta_d`` [rad or m]. Shape (n_arm,).
        continuous: 1 where an arm joint is continuous. Shape (n_arm,).
        turn: The heading objective's turn ``k_psi (psi - psi_d)`` at the edge's gain
            (:func:`~pbvs_pin.control.secondary.heading_term`); 0: no turn.
        share_distance: ``s_d``, the obstacle's share (:func:`heading_share` at any angle).
        out: ``Lambda`` (n,): the arm's part is its last n_arm entries, the turn goes to the
            entry before them.
    """
    worst, least = worst_row(centre, normals, offsets)
    if not least < 0.0:
        return
    n_arm = arm_columns.shape[1]
    n_base = out.shape[0] - n_arm
    g = row_gradient(centre_jacobian, arm_columns, normals, worst)  # most steps stand clear
    norm_squared = 0.0
    for j in range(n_arm):
        norm_squared += g[j] * g[j]
    push = gain * -least
    for j in range(n_arm):
        out[n_base + j] += push * g[j] / max(norm_squared, GRADIENT_FLOOR)
    if turn == 0.0:
        return
    home = arm_difference(target, theta, continuous)
    pull, along_home, home_squared = 0.0, 0.0, 0.0
    for j in range(n_arm):
        along_home += g[j] * home[j]
        home_squared += home[j] * home[j]
    size = np.sqrt(norm_squared) * np.sqrt(home_squared)
    if size > 0.0:
        pull = max(0.0, -along_home) / size
    share = pull * min(1.0, -least / EDGE_RAMP) * share_distance
    out[n_base - 1] += share * turn


@njit(cache=True, inline="always")
def support_barrier(
    centre: np.ndarray,
    centre_jacobian: np.ndarray,
    arm_columns: np.ndarray,
    normals: np.ndarray,
    barrier_offsets: np.ndarray,
    barrier: np.ndarray,
) -> None:
    r"""The barrier's row ``[b, g]`` into ``barrier`` (module docstring): ``g u >= b``.

    ``b = -gamma h`` with ``h = n_i^T c - (n_i^T v_i + d_min,i)`` the least row's distance
    past its kept distance from the edge, and ``g = dh / d theta``.

    Args:
        centre: The centre of mass, platform at the origin [m]. Shape (3,).
        centre_jacobian: Its Jacobian, Pinocchio velocities. Shape (3, nv).
        arm_columns: The selection's arm columns. Shape (nv, n_arm).
        normals: Inward unit normals of the support's edges. Shape (m, 2).
        barrier_offsets: ``n_i^T v_i + d_min,i`` [m] (:attr:`KeepSupported.barrier_offsets`).
            Shape (m,).
        barrier: ``[b, g]`` with ``g`` over the actuated velocities (zero on the platform's).
            Shape (n + 1,); overwritten.
    """
    worst, least = worst_row(centre, normals, barrier_offsets)
    g = row_gradient(centre_jacobian, arm_columns, normals, worst)
    n_base = barrier.shape[0] - 1 - g.shape[0]
    barrier[:] = 0.0
    barrier[0] = -BARRIER_RATE * least
    barrier[1 + n_base :] = g


@njit(cache=True, inline="always")
def keep_inside(command: np.ndarray, weight_inverse: np.ndarray, barrier: np.ndarray) -> bool:
    r"""Project ``command`` onto ``g u >= b`` in ``W``'s metric (in place); True if it acted.

    .. math:: u \leftarrow u + W^{-1} g\, \frac{b - g u}{g^\top W^{-1} g}
              \quad\text{where } g u < b

    the smallest change of ``u`` in ``W``'s metric that meets the row, with ``g W^-1 g^T`` taken
    at least :data:`GRADIENT_FLOOR` (an arm that can barely move the centre of mass is asked for
    at most ``(b - g u) W^-1 g / epsilon``, as the objective is). It changes the feature
    velocity too: the image task gives what the row takes (a correction kept inside the null
    space of ``J``, so that the platform takes over, was tried: :doc:`departures`).

    Args:
        command: ``u`` [u]. Shape (n,).
        weight_inverse: ``W^-1`` (the pseudo-inverse's, joints at their stops weighted out).
            Shape (n, n).
        barrier: ``[b, g]`` (:func:`support_barrier`); ``b = -inf``: nothing to do.
            Shape (n + 1,).
    """
    bound = barrier[0]
    if not bound > -np.inf:
        return False
    n = command.shape[0]
    rate = 0.0
    for j in range(n):
        rate += barrier[1 + j] * command[j]
    if rate >= bound:
        return False
    along = matvec(weight_inverse, barrier[1:])  # W^-1 g
    size = 0.0
    for j in range(n):
        size += barrier[1 + j] * along[j]
    if not size > 0.0:
        return False
    step = (bound - rate) / max(size, GRADIENT_FLOOR)  # an arm that barely moves the centre
    for j in range(n):
        command[j] += step * along[j]
    return True


class KeepSupported(SecondaryObjective):
    """Push the arm back when the centre of mass comes within ``margin`` of the support's edge.

    There, when eq. (19) pulls the arm over the edge, it also turns the platform to where the
    camera looks (module docstring).

    Attributes:
        rows: The support rows (:class:`~pbvs_pin.model.support.SupportRows`).
        gain: ``k_s`` [1/s].
        target: ``theta_d`` of eq. (19) [rad or m], shape (n_arm,); None: no turn.
        continuous: Which arm joints are continuous (wrapped in ``theta_d - theta``).
            Shape (n_arm,).
        heading_gain: ``k_psi`` of the platform's turn at the edge [1/s]; 0: no turn.
        heading_offset: ``psi_d``, the camera's heading at ``theta_d`` [rad].
        d0: Distance at which obstacle avoidance starts [m]; 0: avoidance off.
        data: Scratch ``pin.Data`` of the robot's model, for the centre of mass.
    """

    def __init__(
        self,
        model: MobileManipulator,
        support: np.ndarray,
        gain: float = 10.0,
        margin: float = COM_MARGIN,
        target: np.ndarray | None = None,
        heading_gain: float = 0.0,
        heading_offset: float = 0.0,
        d0: float = 0.0,
    ) -> None:
        """Rows of ``model`` on ``support`` (shape (m, 2), m >= 3, counter-clockwise) [m].

        Each edge keeps ``margin`` [m], or less where the posture target ``target`` (``theta_d``
        of eq. (19), shape (n_arm,)) keeps less: a shipped recipe's home (the Z1's, the Kinova's)
        stands closer to an edge than the computed homes' 0.05 m, and a margin the target does
        not keep would hold the arm away from it for good (measured: the Z1 and Kinova arms
        0.73 and 0.46 rad from ``theta_d`` at the end of Experiment 2). ``heading_gain``
        (``k_psi`` [1/s]), ``heading_offset`` (``psi_d`` [rad]) and ``d0`` (``d_0`` [m]) are
        the platform's turn at the edge (module docstring); ``heading_gain = 0`` or no
        ``target`` leaves it out.

        Raises:
            GainError: If ``gain`` is not positive and finite, or ``heading_gain``, ``d0``
                negative or not finite, or ``heading_offset`` not finite.
        """
        check_positive("KeepSupported", gain=gain)
        for name, value in (("heading_gain", heading_gain), ("d0", d0)):
            if not np.isfinite(value) or value < 0.0:
                raise GainError(f"KeepSupported.{name}: expected >= 0, got {value}")
        if not np.isfinite(heading_offset):
            raise GainError(f"KeepSupported.heading_offset: expected finite, got {heading_offset}")
        self.heading_gain, self.heading_offset, self.d0 = heading_gain, heading_offset, d0
        support = np.asarray(support, dtype=float)
        self.data = model.model.createData()
        margins = np.full(len(support), float(margin))
        kept = np.full(len(support), EDGE_KEPT)
        if target is not None:
            q = model.with_arm_positions(model.neutral(), target)  # platform at the origin
            at_target = SupportRows(model, support, 0.0).slack(q, self.data)[0]
            margins = np.minimum(margins, np.maximum(at_target, 0.0))
            kept = np.minimum(kept, at_target)
        self.rows = SupportRows(model, support, margins)
        self.barrier_offsets = self.rows.offsets - self.rows.margins + kept
        """``n_i^T v_i + d_min,i`` [m]: the barrier keeps ``n_i^T c`` above each; ``d_min,i``
        is :data:`EDGE_KEPT`, or the target's own distance from the edge where it is less."""
        self.gain = gain
        self.target = None if target is None else np.asarray(target, dtype=float)
        self.continuous = model.arm_continuous

    def contribution(self, state: SecondaryInput, n_base: int, n: int) -> np.ndarray:
        """``[0, .., w Lambda_omega, Lambda_arm]``: zero unless a row is below its margin.

        Shape (n,). The compiled step computes the same (:func:`support_term`).
        """
        out = np.zeros(n)
        if state.q is None:
            return out
        _, centre_jacobian = self.rows.rows(at_origin(state.q), self.data)  # sets data.com
        turn, share = 0.0, 0.0
        if self.turns(n_base) and state.camera_rotation is not None:
            rotation = np.asarray(state.camera_rotation, dtype=float)
            q = np.asarray(state.q, dtype=float)
            turn = heading_term(rotation, q, self.heading_gain, self.heading_offset)
            share = heading_share(state.obstacle_distance, 0.0, self.d0)  # at any angle
        support_term(
            self.data.com[0], centre_jacobian, self.rows.arm_columns, self.rows.normals,
            self.rows.offsets, self.gain, np.asarray(state.arm_positions, dtype=float),
            self.target_or_zero, self.continuous.astype(np.int64), turn, share, out,
        )  # fmt: skip
        return out

    def barrier(self, q: np.ndarray, n: int) -> np.ndarray:
        """``[b, g]`` of the barrier at ``q`` (:func:`support_barrier`), the reference's.

        Shape (n + 1,).
        """
        row = np.empty(n + 1)
        _, centre_jacobian = self.rows.rows(at_origin(q), self.data)  # sets data.com
        support_barrier(
            self.data.com[0], centre_jacobian, self.rows.arm_columns, self.rows.normals,
            self.barrier_offsets, row,
        )  # fmt: skip
        return row

    def turns(self, n_base: int) -> bool:
        """The platform turns at the edge: a turn gain, a posture target, two or more wheels."""
        return self.heading_gain > 0.0 and self.target is not None and n_base >= 2

    @property
    def target_or_zero(self) -> np.ndarray:
        """``theta_d`` [rad or m], zeros without one (then nothing reads it). Shape (n_arm,)."""
        if self.target is None:
            return np.zeros(self.rows.arm_columns.shape[1])
        return self.target
