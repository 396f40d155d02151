r"""Wheel odometry: the platform pose from the counts of its wheel encoders.

A differential drive's left and right wheel encoders count ``c_l``, ``c_r`` edges
(``N`` counts a wheel revolution, resolution ``delta = 2 pi / N`` [rad]). Between two readings
the wheels rolled ``s_l = r delta Delta c_l`` and ``s_r = r delta Delta c_r`` [m], so that the
platform advanced ``Delta s = (s_l + s_r) / 2`` and turned ``Delta theta = (s_r - s_l) / b``
(radius ``r``, effective track ``b = chi * track`` of
:class:`pbvs_pin.model.base.DifferentialDrive`). Over the interval the motion is taken as one arc of
constant curvature (the exact integral for constant wheel speeds, which is also what
``pin.integrate`` of the planar joint gives for a constant twist):

.. math::
    \begin{bmatrix} x \\ y \end{bmatrix}_{k+1} = \begin{bmatrix} x \\ y \end{bmatrix}_k
    + R(\theta_k) \begin{bmatrix} \Delta s\, \mathrm{sinc}(\Delta\theta) \\
      \Delta s\, (1 - \cos \Delta\theta) / \Delta\theta \end{bmatrix},\qquad
    \theta_{k+1} = \theta_k + \Delta\theta,

with ``sinc(x) = sin(x) / x``. With a gyro, ``Delta theta`` is the gyro's integrated yaw rate
instead (gyro-corrected odometry, as a skid-steer platform needs: its wheel counts over-count
its turns). Counts are cumulative, so the quantisation does not
accumulate in the distance travelled; what accumulates is the pose error of wheels that slip
(the counts then measure the wheels' rotation, not the platform's motion), and, through the
heading, the quantisation of ``Delta theta``.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

from pbvs_pin.exceptions import GainError
from pbvs_pin.model.base import DifferentialDrive


class WheelOdometry:
    """Dead reckoning of a differential drive from its wheel encoders.

    The pose and the counts live in one array, :attr:`state`, which the compiled
    :func:`odometry_update` advances (also from :func:`pbvs_pin.sim.sensing.sensing_step`).

    Args:
        drive: The controller's model of the drive (wheel radius, track).
        counts_per_revolution: Encoder counts per wheel revolution ``N``.
        pose: Starting pose ``[x, y, theta]`` [m, m, rad] (the odometry frame's origin).
        wheel_angles: Left and right wheel angles at the start [rad], where the counts are
            zero. Shape (2,).

    Attributes:
        state: ``[x, y, theta, c_l, c_r, a_0l, a_0r, delta, r delta, b]``: the pose [m, m,
            rad], the counts, the wheel angles where they are zero [rad], the resolution
            ``delta`` [rad], the distance one count rolls [m] and the effective track [m].
            Shape (10,).
    """

    def __init__(
        self,
        drive: DifferentialDrive,
        counts_per_revolution: int,
        pose: npt.ArrayLike,
        wheel_angles: npt.ArrayLike,
    ) -> None:
        if not counts_per_revolution > 0:
            raise GainError(
                f"odometry: expected counts per revolution > 0, got {counts_per_revolution}"
            )
        self.drive = drive
        resolution = 2.0 * np.pi / counts_per_revolution
        self.state = np.zeros(10)
        self.state[:3] = np.array(pose, dtype=float)
        self.state[5:7] = np.array(wheel_angles, dtype=float)
        self.state[7:] = resolution, drive.wheel_radius * resolution, drive.effective_track

    @property
    def resolution(self) -> float:
        """Encoder resolution ``delta = 2 pi / N`` [rad]."""
        return float(self.state[7])

    @property
    def pose(self) -> np.ndarray:
        """Current estimate ``[x, y, theta]`` [m, m, rad]. Shape (3,)."""
        return self.state[:3].copy()

    @property
    def counts(self) -> np.ndarray:
        """Current left and right counts. Shape (2,)."""
        return self.state[3:5].copy()

    def read_counts(self, wheel_angles: npt.ArrayLike) -> np.ndarray:
        """The encoders' counts at wheel angles [rad] (shape (2,)): ``floor((a - a_0) / delta)``."""
        counts = np.empty(2)
        read_counts(np.asarray(wheel_angles, dtype=float), self.state, counts)
        return counts

    def update(self, counts: np.ndarray, turn: float | None = None) -> np.ndarray:
        """Advance the pose to new counts; return the count increments.

        Args:
            counts: Left and right counts now. Shape (2,).
            turn: The heading change [rad] since the last update from another sensor (a
                gyro: gyro-corrected odometry); None takes it from the counts.

        Returns:
            The count increments. Shape (2,).
        """
        increments = np.empty(2)
        given = turn is not None
        odometry_update(self.state, np.asarray(counts, dtype=float), turn if given else 0.0,
                        given, increments)  # fmt: skip
        return increments


@njit(cache=True)
def read_counts(wheel_angles: np.ndarray, state: np.ndarray, counts: np.ndarray) -> None:
    """Write ``floor((a - a_0) / delta)`` of wheel angles ``a`` [rad] into ``counts``.

    Args:
        wheel_angles: Left and right wheel angles [rad]. Shape (2,).
        state: :attr:`WheelOdometry.state`. Shape (10,).
        counts: Output. Shape (2,).
    """
    for side in range(2):
        counts[side] = np.floor((wheel_angles[side] - state[5 + side]) / state[7])


@njit(cache=True)
def odometry_update(
    state: np.ndarray, counts: np.ndarray, turn: float, given: bool, increments: np.ndarray
) -> None:
    """Advance :attr:`WheelOdometry.state` to new counts along one arc (module docstring).

    Args:
        state: The odometry's state, updated in place. Shape (10,).
        counts: Left and right counts now. Shape (2,).
        turn: The heading change [rad] from another sensor, used if ``given``.
        given: Whether ``turn`` holds; otherwise ``Delta theta = (s_r - s_l) / b``.
        increments: Output: the count increments. Shape (2,).
    """
    for side in range(2):
        increments[side] = counts[side] - state[3 + side]
        state[3 + side] = counts[side]
    step = state[8]
    left, right = increments[0] * step, increments[1] * step
    distance = 0.5 * (left + right)
    if not given:
        turn = (right - left) / state[9]
    if turn == 0.0:
        forward, sideways = distance, 0.0
    else:
        forward = distance * math.sin(turn) / turn
        sideways = distance * (1.0 - math.cos(turn)) / turn
    x, y, theta = state[0], state[1], state[2]
    c, s = math.cos(theta), math.sin(theta)
    state[0] = x + c * forward - s * sideways
    state[1] = y + s * forward + c * sideways
    state[2] = theta + turn
