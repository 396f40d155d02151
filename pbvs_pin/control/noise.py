r"""The fed-back features' pixel noise, measured online, and the loop gain it allows (issue 31).

**Measurement.** Each frame that passes the gate is compared with the previous *raw* frame
brought up to its capture along eq. (3) (:meth:`pbvs_pin.control.tracking.TargetTracker.
predicted`): the innovation ``d_k = z_k - P(z_{k-1}) = n_k - n_{k-1} + b_k``, where ``n`` is
the detector's white noise (``sigma`` px per image coordinate) and ``b`` the prediction's
slow error (the velocity estimate's, the model's). Its second difference cancels ``b``:

.. math:: e_k = d_k - d_{k-1} = n_k - 2 n_{k-1} + n_{k-2},\qquad E[e_k^2] = 6 \sigma^2,

averaged over every image coordinate and over :data:`NOISE_WINDOW` frames (an exponential
window).

**Loop gain.** A loop of gain ``g`` per camera sample on a noisy error,
``e_{k+1} = (1 - g) e_k - g n_k``, holds the error's variance at ``g / (2 - g)`` times the
noise's. The largest per-sample gain (the ``loop_gain_margin``) that keeps the noise in the
motion, ``sigma sqrt(g / (2 - g))``, within :data:`NOISE_BUDGET_PX` is

.. math:: g_{max} = \frac{2 b^2}{\sigma^2 + b^2}

(:func:`noise_margin`), for ``sigma > b`` only: 1 at ``sigma = b``, 0.25 at 4 px. Below the
budget (the experiments' 0.5 px) there is no cap at all, so a ``loop_gain_margin`` raised
above 1 (the net switched off) stays as it was. The net's other margins
(:func:`pbvs_pin.control.upright.delayed_margin`) still apply; the smaller one wins.
Lowering the margin scales the feature gains by a positive factor, as the existing cap does,
so the passivity argument (docs ``theory``) is unchanged: the storage function's decrease
needs positive-definite gains, not their size.
"""

from __future__ import annotations

import numpy as np

NOISE_BUDGET_PX = 1.5
"""Largest standard deviation of the feature noise passed into the motion [px]."""

NOISE_WINDOW = 60
"""Frames the pixel-noise estimate averages over (an exponential window; 2 s at 30 Hz)."""

WARM_UP = 10
"""Second differences needed before the estimate is used (0 is reported before)."""

MAX_NOISE_PX = 100.0
"""Largest noise one second difference can report [px]: one glitch moves the estimate a bounded
amount (the gate already refuses frames far from their prediction)."""


def noise_margin(noise_px: float, budget_px: float = NOISE_BUDGET_PX) -> float:
    """The per-sample loop gain that passes ``budget_px`` of ``noise_px`` into the motion.

    ``2 b^2 / (sigma^2 + b^2)`` (module docstring); ``inf`` (no cap) for ``sigma <= b``, and
    for no noise measured (0).
    """
    if not noise_px > budget_px:
        return float("inf")
    return 2.0 * budget_px**2 / (noise_px**2 + budget_px**2)


class PixelNoise:
    """Online estimate of the detector's pixel noise from the innovation's second difference.

    Attributes:
        count: Second differences averaged so far.
    """

    def __init__(self) -> None:
        self._variance = 0.0
        self.count = 0
        self._previous: np.ndarray | None = None

    def restart(self) -> None:
        """The track restarted: the next innovation starts a new difference (keeps the noise)."""
        self._previous = None

    def update(self, innovation: np.ndarray) -> None:
        """Take one frame's innovation ``z_k - P(z_{k-1})`` [px], any shape (e.g. (k, 2))."""
        innovation = np.asarray(innovation, dtype=float)
        previous, self._previous = self._previous, innovation.copy()
        if previous is None or previous.shape != innovation.shape:
            return
        sample = float(np.mean((innovation - previous) ** 2)) / 6.0
        if not np.isfinite(sample):
            self._previous = None
            return
        self.count += 1
        weight = max(1.0 / self.count, 1.0 / NOISE_WINDOW)
        self._variance += weight * (min(sample, MAX_NOISE_PX**2) - self._variance)

    @property
    def noise_px(self) -> float:
        """The estimated noise per image coordinate [px]; 0 until :data:`WARM_UP` differences."""
        return float(np.sqrt(self._variance)) if self.count >= WARM_UP else 0.0
