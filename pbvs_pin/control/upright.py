r"""Keep the image upright and the sampled loop's gain bounded (departures from the paper).

**Upright image.** The features ``[u1, v1, v2]`` fix three of the camera's six degrees of
freedom, not its roll about the optical axis. On an arm that can roll its camera the secondary
objectives move it there through ``(I - J# J)``; rolling shrinks ``v1 - v2``, the loop closes the
distance to compensate, ``J`` grows like ``1/z`` and the target is lost (TIAGo, Experiment 4:
roll 0 -> -71 deg, depth 0.86 -> 0.18 m). The paper's arm (yaw, pitch, pitch) cannot roll its
camera and never meets this. The image's upright angle, from gravity:

.. math:: c_{up} = {}^wR_c^T e_z,\qquad \varphi = \operatorname{atan2}(c_{up,x}, -c_{up,y})

(0 when world up points to the image's top, ``-y`` of the optical frame). With the camera
twist's angular part ``omega_c = J_cam,ang S v`` (``pin.LOCAL``), ``dc_up/dt = c_up x omega_c``
and

.. math:: \dot\varphi = j_\varphi v,\qquad j_\varphi = w^T J_{cam,ang} S,\qquad
          w = \left(\frac{c_x c_z}{c_x^2 + c_y^2}, \frac{c_y c_z}{c_x^2 + c_y^2}, -1\right)

The null-space velocity ``eta_0 = (I - J# J) k1 tanh(k2 Lambda)`` is then also projected,
W-orthogonally, out of ``j_phi``'s direction inside the null space of ``J``:

.. math:: b = (I - J^\# J) W^{-1} j_\varphi^T,\qquad \sigma_\varphi^2 = j_\varphi b,\qquad
          \eta = \eta_0 - \beta(\sigma_\varphi)\, b\,
                 \frac{j_\varphi \eta_0 + k_\varphi \varphi}{\sigma_\varphi^2}

so that ``j_phi eta = (1 - beta) j_phi eta_0 - beta k_phi phi``: with ``beta = 1`` the secondary
objectives no longer roll the image, and a roll present at the start decays with the rate
``k_phi`` (:data:`RESTORING_RATE`). ``sigma_phi`` is the part of ``j_phi`` outside the row space
of ``J`` (W-metric), i.e. the roll the null space can produce per unit of velocity [rad]. With
one radian of roll counted as one controller unit (it moves a point ``feature_scale`` pixels
from the image centre by ``feature_scale`` pixels), ``sigma_phi`` is compared with the
pseudo-inverse's damping threshold ``sigma_0``: ``beta = clip(sigma_phi / sigma_0 - 1, 0, 1)``,
zero below ``sigma_0`` (the roll direction is as ill-conditioned as a direction ``J#`` damps),
one above ``2 sigma_0``, linear between so that ``eta`` is continuous in the posture. A robot
that cannot roll its camera has ``sigma_phi`` at round-off level and gets exactly ``eta_0``.

**Loop-gain safety net.** Between two camera samples (period ``T``) the feature error of the
law ``u = -J^T K_c e`` evolves as ``e+ = (I - T J J^T K_c) e``: with ``g = k T lambda_max(J J^T)``
(controller units, ``K_c <= k``) this first-order sampled loop is stable for ``g < 2``, and for
``g <= 1`` the correction of one sample never exceeds the error (no sign change from sample to
sample). Above 1 the slowest-decaying mode alternates in sign at half the camera rate, where the
servos' lag adds phase, so :data:`LOOP_GAIN_MARGIN` = 1, half the stability limit (a gain margin
of 2). The feature gains are scaled by ``min(1, margin / g)``. With ``-J# K_c e`` feedback
``J J# = I`` and ``g = k T``. Measured on the reference robot with the paper's gains: ``g`` up to
0.71, 0.84, 0.90 and 0.71 in Experiments 1-4, so the net does not act there; on TIAGo without
the upright projection ``g`` grew to 9.2 before the target was lost.

A frame that reaches the controller ``d`` camera periods after it was taken (the camera's
latency, one frame by default) delays the feedback: ``e_{k+1} = e_k - g e_{k-d}``, whose
characteristic polynomial ``z^{d+1} - z^d + g`` has its roots inside the unit circle for
``g < 2 sin(pi / (2 (2 d + 1)))`` (2 without delay, 1 with one period). The net keeps the same
fraction of that limit (:func:`delayed_margin`): with one frame of latency the margin is half
the one set, unless the estimator predicts each frame up to now (``estimator.predict``), which
removes the delay from the loop. The reference robot exceeds the halved margin in the
experiments (``g`` up to 0.9 against 0.5); without it Experiment 2 oscillates at 2.7 Hz.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

RESTORING_RATE = 0.2
"""``k_phi`` [1/s]: the upright angle's decay rate inside the null space, the posture
objective's own rate in Experiments 2-4 (``k1 k2 = 0.1 rad/s * 2 /rad``, a 5 s time constant)."""

LOOP_GAIN_MARGIN = 1.0
"""Largest gain per camera sample ``k T lambda_max(J J^T)`` (controller units); see above."""

VERTICAL_VIEW = 1e-6
"""``c_x^2 + c_y^2`` below which the camera looks straight up or down and ``phi`` is undefined
(``j_phi`` is then zero: nothing is removed)."""


class Safety(NamedTuple):
    """The settings of both departures, as the passivity law takes them."""

    upright: bool
    """Keep the null-space term from rolling the image."""
    upright_rate: float
    """``k_phi`` [1/s]."""
    camera_period: float
    """Camera sample period ``T`` [s]; 0 turns the loop-gain net off."""
    loop_gain_margin: float
    """Largest gain per camera sample [1]."""


class SafetyOutput(NamedTuple):
    """What both departures did at one step."""

    loop_gain: float
    """``g = k T lambda_max(J J^T)`` before the net (NaN when the net is off) [1]."""
    gain_factor: float
    """``min(1, margin / g)``, the factor on the feature gains [1]."""
    sigma_phi: float
    """Roll the null space can produce per unit of velocity (controller units)."""
    upright_weight: float
    """``beta``, how much of the roll was removed from the null space [1]."""


@njit(cache=True, inline="always")
def upright_angle(rotation: np.ndarray) -> float:
    r"""The image's upright angle ``phi = atan2(c_x, -c_y)``, ``c = wRc^T e_z`` [rad].

    Args:
        rotation: ``wRc``, camera optical frame (x right, y down, z forward). Shape (3, 3).

    Returns:
        ``phi`` in (-pi, pi]; 0 when the image is upright, pi when it is upside down.
    """
    return np.arctan2(rotation[2, 0], -rotation[2, 1])


@njit(cache=True, inline="always")
def upright_row(rotation: np.ndarray, camera_jacobian: np.ndarray) -> np.ndarray:
    r"""``[phi, j_phi]``: the upright angle and its rate per actuated velocity.

    .. math:: j_\varphi = w^T J_{cam,ang} S,\quad
              w = \left(\frac{c_x c_z}{c_x^2 + c_y^2}, \frac{c_y c_z}{c_x^2 + c_y^2}, -1\right)

    Args:
        rotation: ``wRc``. Shape (3, 3).
        camera_jacobian: ``J_cam S``, camera twist (``pin.LOCAL``, linear then angular) per
            actuated velocity. Shape (6, n).

    Returns:
        ``phi`` [rad] then ``j_phi`` [rad per m or rad of v], zero when the camera looks
        vertically (:data:`VERTICAL_VIEW`). Shape (n + 1,).
    """
    n = camera_jacobian.shape[1]
    out = np.zeros(n + 1)
    cx, cy, cz = rotation[2, 0], rotation[2, 1], rotation[2, 2]
    out[0] = upright_angle(rotation)
    horizontal = cx * cx + cy * cy
    if horizontal < VERTICAL_VIEW:
        return out
    w0, w1 = cx * cz / horizontal, cy * cz / horizontal
    for j in range(n):
        out[j + 1] = w0 * camera_jacobian[3, j] + w1 * camera_jacobian[4, j] - camera_jacobian[5, j]
    return out


@njit(cache=True, inline="always")
def upright_null_space(
    null_space: np.ndarray,
    pinv: np.ndarray,
    jacobian: np.ndarray,
    weight_inverse: np.ndarray,
    row: np.ndarray,
    threshold: float,
    restoring_rate: float,
) -> tuple[np.ndarray, float, float]:
    r"""Remove from the null-space velocity its component that changes ``phi``.

    .. math:: \eta = \eta_0 - \beta\, b\, (j_\varphi \eta_0 + k_\varphi \varphi) / \sigma_\varphi^2,
              \quad b = W^{-1} j_\varphi^T - J^\# J W^{-1} j_\varphi^T,
              \quad \beta = \mathrm{clip}(\sigma_\varphi / \sigma_0 - 1, 0, 1)

    Args:
        null_space: ``eta_0 = (I - J# J) k1 tanh(k2 Lambda)``. Shape (n,).
        pinv: ``J#`` as used for ``eta_0`` (controller units). Shape (n, r).
        jacobian: ``J`` (controller units). Shape (r, n).
        weight_inverse: ``W^-1``. Shape (n, n).
        row: ``[phi, j_phi]`` from :func:`upright_row`. Shape (n + 1,).
        threshold: ``sigma_0``, the pseudo-inverse's damping threshold.
        restoring_rate: ``k_phi`` [1/s].

    Returns:
        ``eta`` (the input array itself when ``beta = 0``, so the result is bit-identical),
        ``sigma_phi`` [rad per unit of v], ``beta``.
    """
    r, n = jacobian.shape
    wj = np.zeros(n)
    for i in range(n):
        for j in range(n):
            wj[i] += weight_inverse[i, j] * row[j + 1]
    jwj = np.zeros(r)
    for a in range(r):
        for j in range(n):
            jwj[a] += jacobian[a, j] * wj[j]
    b = wj.copy()
    sigma2 = 0.0
    for i in range(n):
        for a in range(r):
            b[i] -= pinv[i, a] * jwj[a]
        sigma2 += row[i + 1] * b[i]
    sigma = np.sqrt(max(sigma2, 0.0))
    weight = min(max(sigma / threshold - 1.0, 0.0), 1.0)
    if weight == 0.0:
        return null_space, sigma, 0.0
    rate = restoring_rate * row[0]
    for j in range(n):
        rate += row[j + 1] * null_space[j]
    return null_space - (weight * rate / sigma2) * b, sigma, weight


@njit(cache=True, inline="always")
def loop_gain_factor(
    largest_eigenvalue: float, k_max: float, period: float, margin: float
) -> tuple[float, float]:
    r"""Factor on the feature gains that keeps ``g = k T lambda_max`` at most ``margin``.

    Args:
        largest_eigenvalue: ``lambda_max(J J^T)`` in controller units (1 for ``J#`` feedback).
        k_max: Largest ``k_i`` [1/s].
        period: Camera sample period ``T`` [s].
        margin: Largest allowed ``g`` (:data:`LOOP_GAIN_MARGIN`).

    Returns:
        ``min(1, margin / g)`` and ``g`` before limiting.
    """
    gain = k_max * period * largest_eigenvalue
    if gain > margin:
        return margin / gain, gain
    return 1.0, gain


def delayed_margin(margin: float, delay: float) -> float:
    r"""The loop-gain margin of a loop whose samples arrive ``d`` sample periods late.

    The stability limit of ``e_{k+1} = e_k - g e_{k-d}`` relative to the undelayed limit 2:

    .. math:: \text{margin}_d = \text{margin}\, \sin\frac{\pi}{2 (2 d + 1)}

    exact for a whole ``d`` (1 at ``d = 0``, 1/2 at ``d = 1``) and interpolating between.

    Args:
        margin: The margin without delay (:data:`LOOP_GAIN_MARGIN`).
        delay: ``d``, the latency in sample periods, >= 0.

    Returns:
        The margin for the delayed loop.
    """
    return margin * float(np.sin(np.pi / (2.0 * (2.0 * delay + 1.0))))
