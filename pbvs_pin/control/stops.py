r"""Joints at their stops leave the redundancy resolution: the weighted least norm near limits.

The feed-forward ``J# J_o phat_dot`` and the null-space term ``(I - J# J) k1 tanh(k2 Lambda)``
of eq. (34) share the motion between the joints through ``J#``, on the assumption that every
joint moves as commanded. A joint at its stop does not: the other joints then make the motion
that was to cancel the stopped joint's share, and the image moves. On Stretch RE1 the four
telescoping segments reach their stops about 14 s into Experiment 2; the null space kept
sharing the posture's pull between them and the wrist and platform yaw, which turned the
camera away, and the run ended 30-48 px off.

Each joint moving towards a limit is weighted by its room ``h_j`` in ``[0, 1]``
(:func:`~pbvs_pin.control.balanced.joint_room`: 1 farther than a tenth of its range from the
limit, 0 at it) in the direction the first pass commands it (the command of eq. (34) with
``h = 1``); the second pass resolves the redundancy on the joints that can still move:

.. math:: W_h^{-1} = H W^{-1} H,\qquad J_h^\# = W_h^{-1} J^T (J W_h^{-1} J^T)^{-1},\qquad
          u_{ff} = J_h^\# J_o \hat{\dot p},\qquad
          \eta = (I - J_h^\# J)\, H k_1 \tanh(k_2 \Lambda)

with ``H = diag(h)``: Chan and Dubey's weighted least norm (IEEE Trans. Robot. Autom. 11(2),
1995), whose weight grows without bound as a joint nears a limit it moves towards, here with
``W_h^{-1}`` going to zero. A joint at its stop gets neither a share of ``J_h#`` nor of the
posture's pull into the stop, and the other joints no longer compensate a motion that does not
happen. ``J J_h^# = I`` still holds while the joints left span the task (else ``J#`` is damped,
as near any singularity), and ``eta`` stays in the null space of ``J``.

The feedback is left as the law has it: the paper's ``-J^T K_c e`` acts column by column, so a
stopped joint's share of it moves nothing else and the passivity argument (9)-(14) is unchanged
(the balanced law leaves stopped joints out of its feedback itself). A robot whose joints keep
more than a tenth of their range from every limit gets the first pass unchanged, bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def stop_weights(command: np.ndarray, room_up: np.ndarray, room_down: np.ndarray) -> np.ndarray:
    """``h_j``: each velocity's room in the direction it is commanded, in [0, 1]. Shape (n,).

    Args:
        command: The first pass's command ``u`` [u]. Shape (n,).
        room_up: Room towards the upper limit (:func:`~.balanced.joint_room`). Shape (n,).
        room_down: Room towards the lower limit. Shape (n,).
    """
    n = command.shape[0]
    weights = np.ones(n)
    for j in range(n):
        if command[j] > 0.0:
            weights[j] = room_up[j]
        elif command[j] < 0.0:
            weights[j] = room_down[j]
    return weights


@njit(cache=True, inline="always")
def weighted_inverse(weight_inverse: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``W_h^-1 = H W^-1 H`` with ``H = diag(weights)``. Shape (n, n)."""
    n = weights.shape[0]
    out = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            out[i, j] = weights[i] * weight_inverse[i, j] * weights[j]
    return out
