"""Target motions: the world trajectory of the two-sphere target.

The target is two spheres of diameter ``D`` whose centres are ``separation`` apart on a
vertical line; its *position* is the upper sphere's centre. Each motion gives the position
offset from the start and its exact velocity, so runs can compare the estimate with the truth.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pbvs_pin.exceptions import GainError
from pbvs_pin.validation import as_array

TARGET_POINTS = 2
"""The simulated target's image points: the two sphere centres, the upper one first."""


class TargetMotion(abc.ABC):
    """Displacement of the target from its start, as a function of time."""

    @abc.abstractmethod
    def offset(self, t: float) -> np.ndarray:
        """Displacement from the start position at time ``t`` [m]. Shape (3,)."""

    @abc.abstractmethod
    def velocity(self, t: float) -> np.ndarray:
        """World velocity at time ``t`` [m/s]. Shape (3,)."""


@dataclass(frozen=True)
class Still(TargetMotion):
    """A target that does not move."""

    def offset(self, t: float) -> np.ndarray:
        """Zero."""
        return np.zeros(3)

    def velocity(self, t: float) -> np.ndarray:
        """Zero."""
        return np.zeros(3)


@dataclass(frozen=True)
class LineThenStop(TargetMotion):
    """Constant velocity until ``stop_time``, then an abrupt stop (Experiments 1 and 3).

    Attributes:
        velocity_world: Velocity while moving [m/s]. Shape (3,).
        stop_time: Time of the stop [s].
    """

    velocity_world: tuple[float, float, float]
    stop_time: float

    def offset(self, t: float) -> np.ndarray:
        """``v min(t, t_stop)``."""
        return np.asarray(self.velocity_world) * min(max(t, 0.0), self.stop_time)

    def velocity(self, t: float) -> np.ndarray:
        """``v`` before the stop, zero after."""
        moving = 0.0 <= t < self.stop_time
        return np.asarray(self.velocity_world, dtype=float) * float(moving)


@dataclass(frozen=True)
class Weave(TargetMotion):
    """Forward at constant speed plus sinusoids, then a stop (Experiments 2 and 4).

    ``offset(t) = v t + A * (1 - cos(2 pi f t))`` per axis until ``stop_time``; with a
    vertical amplitude the path is three-dimensional.

    Attributes:
        velocity_world: Mean velocity [m/s]. Shape (3,).
        amplitude: Half peak-to-peak of the sinusoid per axis [m]. Shape (3,).
        frequency: Sinusoid frequency [Hz].
        stop_time: Time of the stop [s].
    """

    velocity_world: tuple[float, float, float]
    amplitude: tuple[float, float, float]
    frequency: float
    stop_time: float

    def __post_init__(self) -> None:
        """Reject a negative frequency."""
        if not self.frequency >= 0:
            raise GainError(f"Weave.frequency: expected >= 0 Hz, got {self.frequency}")

    def offset(self, t: float) -> np.ndarray:
        """Mean drift plus the sinusoid, frozen after the stop."""
        t = min(max(t, 0.0), self.stop_time)
        phase = 2.0 * np.pi * self.frequency * t
        return np.asarray(self.velocity_world) * t + np.asarray(self.amplitude) * (
            1.0 - np.cos(phase)
        )

    def velocity(self, t: float) -> np.ndarray:
        """Exact derivative of :meth:`offset`."""
        if not 0.0 <= t < self.stop_time:
            return np.zeros(3)
        omega = 2.0 * np.pi * self.frequency
        return np.asarray(self.velocity_world) + np.asarray(self.amplitude) * omega * np.sin(
            omega * t
        )


@dataclass(frozen=True)
class TwoSphereTarget:
    """Geometry and start of the target.

    Attributes:
        start: Upper sphere centre at t = 0 [m]. Shape (3,).
        diameter: Sphere diameter D [m].
        separation: Distance between the two centres [m].
        motion: How it moves.
    """

    start: np.ndarray
    diameter: float
    separation: float
    motion: TargetMotion

    def __post_init__(self) -> None:
        """Refuse a start that is not a finite 3-vector (ShapeError, NonFiniteValue)."""
        object.__setattr__(self, "start", as_array("start", self.start, (3,)))

    def centres(self, t: float) -> np.ndarray:
        """Upper and lower sphere centres [m]. Shape (2, 3)."""
        return centres_from(np.asarray(self.start) + self.motion.offset(t), self.separation)

    def midpoint(self, t: float) -> np.ndarray:
        """Midpoint of the two centres [m]. Shape (3,)."""
        return self.centres(t).mean(axis=0)


def centres_from(top: npt.ArrayLike, separation: float) -> np.ndarray:
    """Both sphere centres from the upper one [m]. Shape (2, 3)."""
    top = np.asarray(top, dtype=float)
    return np.array([top, top - [0.0, 0.0, separation]])
