"""The encoder readings of the last seconds, to place a camera frame at its capture instant.

A frame arrives after its latency; the features it shows belong to the configuration at its
capture time, not to the configuration when it arrives. :class:`EncoderHistory` keeps the
configurations the controller was given (a ring buffer of ``(t, q)``) and returns the one at
a past instant: the stored reading itself when the instant is a step's time (within
:data:`TIME_TOLERANCE`), else Pinocchio's interpolation (``pin.interpolate``, on the
configuration's Lie group: angles stored as ``(cos, sin)`` stay unit) between the two
readings around it.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

TIME_TOLERANCE = 1e-9
"""Two times closer than this [s] are the same instant."""


class EncoderHistory:
    """The configurations of the last ``duration`` seconds.

    Args:
        model: The robot's Pinocchio model (for ``nq`` and the interpolation).
        duration: How far back a frame can be placed [s].
        period: The control period [s]; the buffer holds ``duration / period`` readings.
    """

    def __init__(self, model: pin.Model, duration: float, period: float) -> None:
        self.model = model
        size = max(2, int(np.ceil(duration / period)) + 2)
        self.times = np.full(size, -np.inf)
        self.configurations = np.zeros((size, model.nq))
        self.count = 0
        """Readings recorded so far (the newest is at ``(count - 1) % size``)."""

    @property
    def newest_time(self) -> float:
        """Time of the newest reading [s]; -inf before the first."""
        return self.times[(self.count - 1) % self.times.size] if self.count else -np.inf

    @property
    def oldest_time(self) -> float:
        """Time of the oldest reading still held [s]; -inf before the first."""
        if self.count == 0:
            return -np.inf
        size = self.times.size
        return self.times[self.count % size] if self.count > size else self.times[0]

    def record(self, t: float, q: np.ndarray) -> None:
        """Append the reading ``q`` (shape (nq,)) taken at ``t`` [s], later than the newest."""
        slot = self.count % self.times.size
        self.times[slot] = t
        self.configurations[slot] = q
        self.count += 1

    def clear(self) -> None:
        """Forget every reading (after the odometry jumped: older readings no longer fit)."""
        self.count = 0
        self.times[:] = -np.inf

    def at(self, t: float) -> np.ndarray | None:
        """The configuration at ``t`` [s] (shape (nq,)); None if ``t`` is not covered.

        ``t`` is covered from the oldest reading held to the newest (both within
        :data:`TIME_TOLERANCE`).
        """
        if self.count == 0:
            return None
        size = self.times.size
        newest = (self.count - 1) % size
        # the readings in time order: slots newest+1 .. size-1, then 0 .. newest
        order = np.roll(np.arange(size), -(newest + 1)) if self.count > size else None
        times = self.times[order] if order is not None else self.times[: self.count]
        index = int(np.searchsorted(times, t - TIME_TOLERANCE))
        if index == times.size:
            return None
        slot = int(order[index]) if order is not None else index
        if abs(times[index] - t) <= TIME_TOLERANCE:
            return self.configurations[slot].copy()
        if index == 0:
            return None
        before = int(order[index - 1]) if order is not None else index - 1
        fraction = (t - times[index - 1]) / (times[index] - times[index - 1])
        return pin.interpolate(
            self.model, self.configurations[before], self.configurations[slot], fraction
        )
