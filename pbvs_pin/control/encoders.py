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
        return self.times[self._oldest_slot()]

    def _oldest_slot(self) -> int:
        """The slot of the oldest reading held (with at least one recorded)."""
        return self.count % self.times.size if self.count > self.times.size else 0

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
        slot = self._slot_at_or_after(t - TIME_TOLERANCE)
        if slot is None:
            return None
        times = self.times
        if abs(times[slot] - t) <= TIME_TOLERANCE:
            return self.configurations[slot].copy()
        if slot == self._oldest_slot():
            return None
        before = (slot - 1) % times.size
        fraction = (t - times[before]) / (times[slot] - times[before])
        return pin.interpolate(
            self.model, self.configurations[before], self.configurations[slot], fraction
        )

    def _slot_at_or_after(self, t: float) -> int | None:
        """The slot of the oldest reading at or after ``t``; None if all are before.

        The ring holds two time-ordered runs: slots ``newest + 1 ... size - 1`` (older, once
        the ring has wrapped) then ``0 ... newest``.
        """
        times, size = self.times, self.times.size
        newest = (self.count - 1) % size
        if times[newest] < t:
            return None
        wrapped = self.count > size and newest < size - 1
        if wrapped and t <= times[size - 1]:  # in the older run
            return newest + 1 + int(np.searchsorted(times[newest + 1 :], t))
        return int(np.searchsorted(times[: newest + 1], t))
