"""Arm joint angles: read from a configuration, and compared.

A continuous joint (no limits) is stored in a configuration as ``(cos, sin)`` and read as an
angle in ``(-pi, pi]`` (:func:`arm_angles`); an angle and the same angle plus ``2 pi`` are
the same posture of it, so a difference of two of its angles goes the shortest way round
(:func:`arm_difference`). Compiled with numba: the control step calls both.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def arm_angles(q: np.ndarray, idx_q: np.ndarray, continuous: np.ndarray) -> np.ndarray:
    """Arm joint positions from a configuration; continuous joints (cos, sin) give an angle.

    Args:
        q: Configuration. Shape (nq,).
        idx_q: Index of each arm joint in ``q``. Shape (n_arm,).
        continuous: Whether each joint is stored as (cos, sin). Shape (n_arm,).

    Returns:
        Shape (n_arm,) [rad or m].
    """
    angles = np.empty(idx_q.shape[0])
    for i in range(idx_q.shape[0]):
        j = idx_q[i]
        angles[i] = np.arctan2(q[j + 1], q[j]) if continuous[i] else q[j]
    return angles


@njit(cache=True, inline="always")
def arm_difference(a: np.ndarray, b: np.ndarray, continuous: np.ndarray) -> np.ndarray:
    """Arm posture difference ``a - b``, a continuous joint's the shortest way round.

    A continuous joint has no limits, and an angle and the same angle plus ``2 pi`` are the
    same posture: its difference is wrapped into ``[-pi, pi)``. Other joints' differences
    are as they are (a revolute joint with limits wider than ``2 pi`` winds its cables).

    Args:
        a: Arm positions [rad or m]. Shape (n_arm,).
        b: Arm positions [rad or m]. Shape (n_arm,).
        continuous: Whether each joint is continuous (booleans or 0/1). Shape (n_arm,).

    Returns:
        Shape (n_arm,) [rad or m].
    """
    out = a - b
    for i in range(out.shape[0]):
        if continuous[i]:
            out[i] = (out[i] + np.pi) % (2.0 * np.pi) - np.pi
    return out
