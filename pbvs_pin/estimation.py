r"""Target velocity estimation with an alpha-beta filter (paper §4, eq. (30), refs. [32, 33]).

The filter tracks the target's world position ``p`` reconstructed from each camera frame:
the features and depths give the point in the camera frame, and the camera pose from the
joint encoders maps it to the world.

.. math:: \hat p^- = \hat p + T \hat{\dot p},\quad r = p_{meas} - \hat p^-,\quad
          \hat p = \hat p^- + \alpha r,\quad \hat{\dot p} = \hat{\dot p} + \frac{\beta}{T} r

The gains can be given directly or from Kalata's tracking index
``Lambda = sigma_w T^2 / sigma_n`` (ref. [33]).

The estimated speed is clamped to ``max_speed`` (:data:`MAX_TARGET_SPEED` by default): a
measurement that slipped past the controller's gate, or two frames a microsecond apart, move
the estimate by ``beta / T`` times their residual, without bound otherwise.
"""

from __future__ import annotations

import abc

import numpy as np
import numpy.typing as npt

from pbvs_pin.exceptions import GainError

MAX_TARGET_SPEED = 10.0
"""Largest target speed [m/s]: the filter's estimate is clamped to it, and a target velocity
given to the controller beyond it is refused (:mod:`pbvs_pin.control.bounds`)."""


class VelocityEstimator(abc.ABC):
    """Estimates the target's world velocity from its measured world positions."""

    @abc.abstractmethod
    def update(self, position: np.ndarray, time: float) -> None:
        """Take a new position measurement [m] (shape (3,)) taken at ``time`` [s]."""

    @abc.abstractmethod
    def reset(self) -> None:
        """Forget every measurement: the next one starts the estimate afresh."""

    @property
    @abc.abstractmethod
    def position(self) -> np.ndarray:
        """Estimated position [m]. Shape (3,)."""

    @property
    @abc.abstractmethod
    def velocity(self) -> np.ndarray:
        """Estimated velocity [m/s]. Shape (3,)."""


class AlphaBetaFilter(VelocityEstimator):
    """Alpha-beta tracker on a 3-D position.

    Args:
        alpha: Position gain, ``0 < alpha <= 1``.
        beta: Velocity gain, ``0 < beta < 4 - 2 alpha`` (stability).
        max_speed: The estimated speed is clamped to this [m/s].
    """

    def __init__(
        self, alpha: float = 0.5, beta: float = 0.1, max_speed: float = MAX_TARGET_SPEED
    ) -> None:
        if not 0.0 < alpha <= 1.0:
            raise GainError(f"AlphaBetaFilter.alpha: expected 0 < alpha <= 1, got {alpha}", "alpha")
        if not 0.0 < beta < 4.0 - 2.0 * alpha:
            raise GainError(
                f"AlphaBetaFilter.beta: expected 0 < beta < 4 - 2 alpha = {4 - 2 * alpha:g}, "
                f"got {beta}",
                "beta",
            )
        self.alpha, self.beta, self.max_speed = alpha, beta, max_speed
        self.reset()

    def reset(self) -> None:
        """Forget every measurement: zero estimates, the next measurement starts the track."""
        self._position = np.zeros(3)
        self._velocity = np.zeros(3)
        self._time: float | None = None

    @classmethod
    def from_tracking_index(cls, tracking_index: float) -> AlphaBetaFilter:
        """Optimal steady-state gains for Kalata's tracking index (ref. [33]).

        ``r = (4 + L - sqrt(8 L + L^2)) / 4``, ``alpha = 1 - r^2``, ``beta = 2 (2 - alpha) -
        4 sqrt(1 - alpha)``.
        """
        if not tracking_index > 0:
            raise GainError(f"tracking index: expected > 0, got {tracking_index}")
        lam = tracking_index
        r = (4.0 + lam - np.sqrt(8.0 * lam + lam * lam)) / 4.0
        alpha = 1.0 - r * r
        beta = 2.0 * (2.0 - alpha) - 4.0 * np.sqrt(1.0 - alpha)
        return cls(alpha, beta)

    def update(self, position: npt.ArrayLike, time: float) -> None:
        """Predict to ``time`` and correct with the measured position; clamp the speed."""
        measured = np.asarray(position, dtype=float)
        if not np.all(np.isfinite(measured)):
            return
        if self._time is None:
            self._position, self._time = measured.copy(), time
            return
        period = time - self._time
        if period <= 0.0:
            return
        predicted = self._position + period * self._velocity
        residual = measured - predicted
        self._position = predicted + self.alpha * residual
        velocity = self._velocity + self.beta / period * residual
        speed = float(np.sqrt(velocity @ velocity))
        if speed > self.max_speed:  # also catches an overflow to inf (NaN fails both tests)
            velocity *= self.max_speed / speed
        if np.isfinite(velocity).all():
            self._velocity = velocity
        self._time = time

    @property
    def position(self) -> np.ndarray:
        """Estimated position [m]."""
        return self._position.copy()

    @property
    def velocity(self) -> np.ndarray:
        """Estimated velocity [m/s]."""
        return self._velocity.copy()
