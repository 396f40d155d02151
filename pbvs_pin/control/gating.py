r"""The innovation gate: a frame far from the prediction is an outlier, not the target.

Each new frame showing the target is compared with the newest accepted frame brought up to
the new frame's capture time (:meth:`pbvs_pin.control.tracking.TargetTracker.predicted`: the
points moved by the velocity estimate and seen from the camera's pose at capture). Per target
point ``i`` the innovation has three pixel components: the image point ``(u, v)`` and the
apparent diameter ``f D / z`` of a sphere of the target's diameter ``D`` at the point's depth
``z`` (the depths are measured through that diameter, with the same pixel noise). The test is
a chi-square gate on the innovation normalised by its expected spread:

.. math:: \epsilon = \sum_i \Big(\frac{|\xi_i - \hat\xi_i|^2}{\sigma^2}
          + \frac{f^2 D^2}{\sigma_d^2} \big(\tfrac{1}{z_i} - \tfrac{1}{\hat z_i}\big)^2\Big),
          \qquad \epsilon > \chi^2_{3k}(1 - P_{FA}) \;\Rightarrow\; \text{rejected}

with :math:`\sigma^2 = 2 \sigma_n^2 + \sigma_p^2` and
:math:`\sigma_d^2 = 2 \sigma_n^2 + \sigma_{pd}^2`: the pixel noise of the new frame and of the
frame the prediction started from (``sigma_n``: the camera's stated ``noise_px``, at least
:data:`NOISE_FLOOR_PX`), and the prediction's own uncertainty over the age ``tau`` of the
accepted frame at the new capture, across the image and in the apparent diameter,

.. math:: \sigma_p = \sigma_0 + \frac{f}{\bar z}\,\delta(\tau), \quad
          \sigma_{pd} = \sigma_{0d} + \frac{f D}{\bar z^2}\,\delta(\tau), \quad
          \delta(\tau) = \Delta v\,\tau + \tfrac12 a\,\tau^2

(``sigma_0`` = :data:`PREDICTION_PX` and ``sigma_0d`` = :data:`DIAMETER_PX`: the model's
kinematic error and the latency jitter; ``Delta v`` = :data:`SPEED_UNCERTAINTY`: the velocity
estimate's error; ``a`` = :data:`ACCELERATION`: the target's unmodelled acceleration;
``delta`` the distance the target may stray from its prediction [m]; ``z_bar`` the predicted
mean depth). ``P_FA`` = :data:`FALSE_ALARM`: with Gaussian noise within these spreads, one
good frame in a million is rejected. The gate widens as the accepted frame ages: after an
occlusion of a second it no longer rejects anything on the image. At 30 Hz, 0.5 m away and
4 px of noise, one point 95 px from its prediction is still accepted (both points 70 px off,
or both depths doubled, are not); at 0.5 px, 89 px.

A rejected frame is not used (the tracker keeps what it had) and is counted. After
:data:`RESTART_AFTER` rejections in a row, the target really moved where the frames say: the
last of them restarts the estimate (the velocity filter is reset and the frame is taken as
the first).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

NOISE_FLOOR_PX = 0.5
"""Smallest pixel noise the gate assumes [px] (a detector's sub-pixel accuracy), also for a
camera stated noiseless."""
PREDICTION_PX = 5.0
"""``sigma_0``: the prediction's error across the image with no time to grow [px]."""
DIAMETER_PX = 1.0
"""``sigma_0d``: the prediction's error in the apparent diameter with no time to grow [px]."""
SPEED_UNCERTAINTY = 0.2
"""``Delta v``: error of the velocity estimate the prediction assumes [m/s]."""
ACCELERATION = 2.0
"""``a``: largest unmodelled target acceleration [m/s^2]."""
FALSE_ALARM = 1e-6
"""``P_FA``: the chance that a good frame fails the gate under the stated spreads."""
RESTART_AFTER = 3
"""Rejections in a row after which the last rejected frame restarts the estimate (0.1 s at
30 Hz)."""


@dataclass(slots=True)
class FaultCounts:
    """What the controller dropped or changed since it was built or reset (counts).

    Attributes:
        frames_gated: Frames rejected by the innovation gate (module docstring).
        restarts: Estimates restarted after :data:`RESTART_AFTER` rejections in a row.
        frames_out_of_bounds: Frames dropped for finite values beyond the physical bounds
            (:mod:`pbvs_pin.control.bounds`).
        laser_dropped: Laser readings dropped (range below 0 or beyond the bound, bearing
            outside ``[-pi, pi]``); the previous reading is kept.
        clock_jitter: Frames stamped after ``t`` by at most
            :data:`~pbvs_pin.control.bounds.CLOCK_JITTER`, used as captured at ``t``.
    """

    frames_gated: int = 0
    restarts: int = 0
    frames_out_of_bounds: int = 0
    laser_dropped: int = 0
    clock_jitter: int = 0

    def as_dict(self) -> dict[str, int]:
        """The counts by name."""
        return {field.name: getattr(self, field.name) for field in fields(self)}


def gate_threshold(dof: int) -> float:
    """``chi^2_dof(1 - FALSE_ALARM)``: the statistic's bound for ``dof`` components."""
    from scipy.special import gammainccinv  # the chi-square quantile, only when built

    return 2.0 * float(gammainccinv(0.5 * dof, FALSE_ALARM))


class InnovationGate:
    """The chi-square gate of the module docstring, with its count of rejections in a row.

    Args:
        noise_px: The camera's stated pixel noise (standard deviation) [px].
        focal: Focal length ``f`` [px].
        diameter: The target spheres' diameter ``D`` [m].
        points: Target points per frame ``k``.
        counts: Where rejections and restarts are counted.
    """

    def __init__(
        self, noise_px: float, focal: float, diameter: float, points: int, counts: FaultCounts
    ) -> None:
        self.noise_variance = 2.0 * max(noise_px, NOISE_FLOOR_PX) ** 2
        self.focal, self.size = focal, focal * diameter
        self.threshold = gate_threshold(3 * points)
        self.counts = counts
        self.in_a_row = 0

    def spreads(self, age: float, depth: float) -> tuple[float, float]:
        """``sigma`` and ``sigma_d`` [px]: the innovation's spreads ``age`` [s] on, at ``depth``.

        ``age`` is the time since the accepted frame the prediction starts from, ``depth`` the
        predicted mean depth [m].
        """
        stray = SPEED_UNCERTAINTY * age + 0.5 * ACCELERATION * age * age  # delta [m]
        across = PREDICTION_PX + self.focal / depth * stray
        diameter = DIAMETER_PX + self.size / (depth * depth) * stray
        noise = self.noise_variance
        return math.sqrt(noise + across * across), math.sqrt(noise + diameter * diameter)

    def statistic(
        self,
        points: np.ndarray,
        depths: np.ndarray,
        predicted_points: np.ndarray,
        predicted_depths: np.ndarray,
        age: float,
    ) -> float:
        """``epsilon`` of the module docstring (dimensionless).

        Args:
            points: The new frame's points [px]. Shape (k, 2).
            depths: Their depths [m]. Shape (k,).
            predicted_points: The prediction's points [px]. Shape (k, 2).
            predicted_depths: Their depths [m], positive. Shape (k,).
            age: The new capture minus the accepted frame's [s].
        """
        image = points - predicted_points
        size = self.size * (1.0 / depths - 1.0 / predicted_depths)
        sigma, sigma_d = self.spreads(age, float(predicted_depths.mean()))
        return float((image * image).sum()) / sigma**2 + float(size @ size) / sigma_d**2

    def verdict(self, statistic: float) -> tuple[bool, bool]:
        """Whether a frame of this statistic is used, and whether it restarts the estimate.

        Counts the rejection or the restart; a frame that passes ends a run of rejections.
        """
        if statistic <= self.threshold:
            self.in_a_row = 0
            return True, False
        self.in_a_row += 1
        if self.in_a_row >= RESTART_AFTER:
            self.in_a_row = 0
            self.counts.restarts += 1
            return True, True
        self.counts.frames_gated += 1
        return False, False

    def clear(self) -> None:
        """Forget the run of rejections (the estimate was restarted or forgotten)."""
        self.in_a_row = 0
