"""Small dense linear algebra for the compiled kernels (Numba).

At the control step's sizes (``r <= 8`` features, ``n <= 12`` actuated velocities) plain loops
beat a BLAS/LAPACK call and its temporaries. Every kernel of the equations
(:mod:`pbvs_pin.model.camera`, :mod:`pbvs_pin.perception.features`,
:mod:`pbvs_pin.model.dynamics`, :mod:`pbvs_pin.control`) uses these.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` for small matrices."""
    out = np.zeros((a.shape[0], b.shape[1]))
    for i in range(a.shape[0]):
        for k in range(a.shape[1]):
            aik = a[i, k]
            if aik != 0.0:
                for j in range(b.shape[1]):
                    out[i, j] += aik * b[k, j]
    return out


@njit(cache=True)
def matvec(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``a @ x`` for a small matrix."""
    out = np.zeros(a.shape[0])
    for i in range(a.shape[0]):
        total = 0.0
        for k in range(a.shape[1]):
            total += a[i, k] * x[k]
        out[i] = total
    return out


@njit(cache=True)
def cholesky_solve(a: np.ndarray, x: np.ndarray) -> None:
    """Overwrite ``x`` with the solution of ``a x = b`` (``x`` holds ``b`` on entry).

    Args:
        a: Symmetric positive definite. Shape (r, r).
        x: ``b`` on entry, the solution on return (a transposed view is fine). Shape (r, m).
    """
    r = a.shape[0]
    low = np.zeros((r, r))
    for j in range(r):
        total = a[j, j]
        for k in range(j):
            total -= low[j, k] * low[j, k]
        low[j, j] = np.sqrt(total)
        for i in range(j + 1, r):
            total = a[i, j]
            for k in range(j):
                total -= low[i, k] * low[j, k]
            low[i, j] = total / low[j, j]
    for col in range(x.shape[1]):
        for i in range(r):
            total = x[i, col]
            for k in range(i):
                total -= low[i, k] * x[k, col]
            x[i, col] = total / low[i, i]
        for i in range(r - 1, -1, -1):
            total = x[i, col]
            for k in range(i + 1, r):
                total -= low[k, i] * x[k, col]
            x[i, col] = total / low[i, i]


@njit(cache=True)
def smallest_eigenvalue(a: np.ndarray) -> float:
    """Smallest eigenvalue of a symmetric matrix; closed form up to 3 x 3 (Smith 1961).

    For 3 x 3, the eigenvalues are ``q + 2 p cos(phi + 2 pi j / 3)`` with ``q = tr(a) / 3``,
    ``p = |a - q I|_F / sqrt(6)`` and ``cos(3 phi) = det((a - q I) / p) / 2``. Larger
    matrices go to LAPACK.
    """
    r = a.shape[0]
    if r == 1:
        return a[0, 0]
    if r == 2:
        half_gap = 0.5 * (a[0, 0] - a[1, 1])
        return 0.5 * (a[0, 0] + a[1, 1]) - np.sqrt(half_gap * half_gap + a[0, 1] * a[0, 1])
    if r > 3:
        return np.linalg.eigvalsh(a)[0]
    off = a[0, 1] * a[0, 1] + a[0, 2] * a[0, 2] + a[1, 2] * a[1, 2]
    q = (a[0, 0] + a[1, 1] + a[2, 2]) / 3.0
    d0, d1, d2 = a[0, 0] - q, a[1, 1] - q, a[2, 2] - q
    p = np.sqrt((d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * off) / 6.0)
    if p == 0.0:
        return q
    b01, b02, b12 = a[0, 1] / p, a[0, 2] / p, a[1, 2] / p
    b0, b1, b2 = d0 / p, d1 / p, d2 / p
    det = b0 * (b1 * b2 - b12 * b12) - b01 * (b01 * b2 - b12 * b02) + b02 * (b01 * b12 - b1 * b02)
    phi = np.arccos(min(max(0.5 * det, -1.0), 1.0)) / 3.0
    return q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)


@njit(cache=True)
def all_finite(a: np.ndarray) -> bool:
    """Whether every entry of ``a`` is finite (no temporary arrays)."""
    for x in a.flat:
        if not np.isfinite(x):
            return False
    return True


@njit(cache=True, inline="always")
def cut(buffer: np.ndarray, start: int, count: int) -> tuple[np.ndarray, int]:
    """The ``count`` entries of ``buffer`` from ``start``, and the offset after them.

    Names the slots of a packed buffer in turn (:mod:`pbvs_pin.control.layout`,
    :func:`pbvs_pin.model.servo.servo_constants`).
    """
    return buffer[start : start + count], start + count
