r"""The balanced feedback: every direction of ``J J^T`` at one stated gain per camera frame.

The paper's feedback ``nu = J^T K_c e`` (``controller.feedback = "transpose"``) makes the
error decay in each direction of ``J J^T`` at a rate proportional to that direction's
eigenvalue, so one gain ``k`` serves every direction. On robots whose eigenvalues spread far
apart it cannot: Vega-1's largest direction made the loop-gain net cut every gain to a third
(Experiment 4 ended 3.92 px off), and Stretch's depth direction, 600 times slower than its
telescoping arm, left the depth error to a time constant of minutes. ``balanced`` sets the
feedback per direction from the robot's model and the camera period (an extension, and the
default since this round: with it Vega-1 holds Experiment 4 at 0.05 px, and 18 of the zoo's 20
robots hold all four experiments on the Pinocchio plant and 15 on MuJoCo, against 15 and 12
with the paper's law; the docs' *Feedback per direction* page compares them):

.. math:: u_{fb} = -g\, M J^T (J M J^T + \mu^2 I)^{-1} K_c \tilde\xi,\qquad
          M = \mathrm{diag}(h_j \bar u_j^2),\qquad g = \frac{\rho}{T k_{max}}

With ``J M J^T = U diag(lambda) U^T`` the error along ``U_i`` then shrinks by
``rho lambda_i / (lambda_i + mu^2)`` per camera period ``T`` (``K_c <= k``): every direction at
the stated gain ``rho`` (:data:`BALANCED_SHARE` of the loop-gain margin: 0.5 per frame when the
estimator predicts, 0.25 with one frame of latency not predicted), except the directions
damped by ``mu^2`` (:data:`DIRECTION_FLOOR`), as the pseudo-inverse damps singular ones.

- **Units.** ``M`` counts each velocity in its own limit ``bar u_j``: a prismatic joint's m/s
  and a revolute joint's rad/s both as fractions of what the joint can do, so that a joint
  counted in mm/s gets the same motion.
- **Joint stops.** ``h_j`` is the joint's room towards the limit it would move to
  (:func:`joint_room`, squared): a first pass with ``h = 1`` finds each joint's direction, the
  second leaves out the joints at their stops, and the other joints take their share.
- **Knobs.** ``k``'s scale drops out: its ratios weight the features, and ``V1`` (eq. 7) keeps
  it. ``loop_gain_margin`` sets ``rho``. The loop-gain net has nothing to cut.

**What it does to the passivity argument.** The vision system's passivity (9) is a property of
the plant and does not change; the analysis evaluates it on every run. The paper closes the
loop with unit gain on the passive output, ``u = -nu``; for ``J`` of full row rank the balanced
law is ``u_fb = -H nu`` with

.. math:: H = g\, M J^T (A + \mu^2 I)^{-1} A^{-1} J M,\qquad A = J M J^T,

symmetric and positive definite on the range of ``J^T``, where ``nu`` lives. That unit gain is
the assumption that changes: (13)-(14) and (27) hold with the power the controller draws,
``nu^T H nu = -nu^T u_fb``, in place of ``|nu|^2``, and ``V1`` still decreases along the loop
when the feed-forward is exact (``dV1/dt = -nu^T H nu``). The analysis evaluates them so
(:mod:`pbvs_pin.study.analysis.passivity`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from pbvs_pin.linalg import cholesky_solve, matmul, matvec

BALANCED_SHARE = 0.5
"""The balanced law's gain per camera sample in every direction, as a share of the loop-gain
margin [1]. The margin bounds the fastest direction of the transpose law; the balanced law puts
every direction there, also those that move the platform, whose servos lag: at the full margin
Baxter's arm and the KUKA iiwa oscillated at 3.3 and 3.0 px RMS above 0.5 Hz in Experiment 2
(1.7 and 1.6 px at half)."""

DIRECTION_FLOOR = 1e-2
"""Tikhonov floor ``mu^2`` of the balanced feedback, as a share of the largest diagonal entry of
``J M J^T`` (between ``lambda_max / r`` and ``lambda_max``): directions about 10 times weaker in
singular value than the strongest are damped rather than driven at the full rate [1]. A weak
direction turns pixel noise into large velocities, mostly the platform's. With 1e-4 (directions
100 times weaker driven) the reference robot's Experiment 2 on MuJoCo oscillated at 3.37 px RMS
above 0.5 Hz and 4 of the zoo's 20 robots held all four experiments there; with 1e-2, 0.87 px
and 15 of 20, and on the Pinocchio plant 18 of 20 either way (``docs/feedback_laws.rst``)."""


@njit(cache=True, inline="always")
def balanced_gain(margin: float, period: float, k_max: float) -> float:
    """``g = rho / (T k_max)`` with ``rho = BALANCED_SHARE * margin`` [1]."""
    return BALANCED_SHARE * margin / (period * k_max)


@njit(cache=True, inline="always")
def joint_room(
    theta: np.ndarray, lower: np.ndarray, upper: np.ndarray, n_base: int, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """How far each velocity may still move up and down, as a fraction in [0, 1].

    A base velocity has no limit (1 both ways). An arm joint's room towards a limit is its
    distance to that limit over the zone of :data:`LIMIT_ZONE` of its range, clipped to [0, 1];
    a continuous joint (infinite limits) has room 1.

    Args:
        theta: Arm joint positions [q]. Shape (n_arm,).
        lower: Lower limits [q]. Shape (n_arm,).
        upper: Upper limits [q]. Shape (n_arm,).
        n_base: Base velocities (first in ``v``).
        n: Actuated velocities.

    Returns:
        Room upwards and downwards. Shapes (n,), (n,).
    """
    up = np.ones(n)
    down = np.ones(n)
    for a in range(theta.shape[0]):
        span = upper[a] - lower[a]
        if not np.isfinite(span):
            continue
        zone = LIMIT_ZONE * span
        up[n_base + a] = min(max((upper[a] - theta[a]) / zone, 0.0), 1.0)
        down[n_base + a] = min(max((theta[a] - lower[a]) / zone, 0.0), 1.0)
    return up, down


LIMIT_ZONE = 0.1
"""Fraction of a joint's range next to each limit in which the balanced feedback stops asking
that joint to move further towards the limit [1]."""


@njit(cache=True, inline="always")
def _metric_feedback(
    kc_error: np.ndarray, jacobian: np.ndarray, metric: np.ndarray, gain: float
) -> np.ndarray:
    r"""``gain M J^T (J M J^T + mu^2 I)^{-1} K_c e`` for a diagonal metric ``M``. Shape (n,)."""
    r, n = jacobian.shape
    weighted = np.empty((n, r))
    for j in range(n):
        for i in range(r):
            weighted[j, i] = metric[j] * jacobian[i, j]
    gram = matmul(jacobian, weighted)
    largest = 0.0
    for i in range(r):
        largest = max(largest, gram[i, i])
    floor = DIRECTION_FLOOR * largest + 1e-300
    for i in range(r):
        gram[i, i] += floor
    solved = np.empty((r, 1))
    solved[:, 0] = kc_error
    cholesky_solve(gram, solved)
    return gain * matvec(weighted, solved[:, 0])


@njit(cache=True, inline="always")
def balanced_feedback(
    kc_error: np.ndarray,
    jacobian: np.ndarray,
    limits: np.ndarray,
    room_up: np.ndarray,
    room_down: np.ndarray,
    gain: float,
) -> np.ndarray:
    r"""The feedback of the balanced law: every direction of ``J M J^T`` at one rate.

    .. math:: \nu_b = g\, M J^T (J M J^T + \mu^2 I)^{-1} K_c \tilde\xi,\qquad
              M = \mathrm{diag}(h_j \bar u_j^2)

    ``bar u_j`` the velocity limits (so that metres and radians count alike, as fractions of
    what each joint can do) and ``h_j`` the joint's room towards the limit it would move to
    (:func:`joint_room`, squared): a first pass with ``h = 1`` finds the direction each joint
    is asked to move in, the second removes the joints at their stops.

    Args:
        kc_error: ``K_c e`` (controller units per second). Shape (r,).
        jacobian: ``J`` (controller units). Shape (r, n).
        limits: Velocity limits [u]. Shape (n,).
        room_up: Room upwards. Shape (n,).
        room_down: Room downwards. Shape (n,).
        gain: ``g = rho / (T k_max)`` [1].

    Returns:
        ``nu_b``, to be subtracted from the command. Shape (n,).
    """
    n = limits.shape[0]
    metric = np.empty(n)
    for j in range(n):
        metric[j] = limits[j] * limits[j]
    first = _metric_feedback(kc_error, jacobian, metric, gain)
    for j in range(n):
        room = room_down[j] if first[j] > 0.0 else room_up[j]  # u_j = -first_j
        metric[j] *= room * room
    return _metric_feedback(kc_error, jacobian, metric, gain)
