r"""Wheel odometry: the platform pose from the counts of its wheel encoders.

A differential drive's left and right wheel encoders count ``c_l``, ``c_r`` edges
(``N`` counts a wheel revolution, resolution ``delta = 2 pi / N`` [rad]). Between two readings
the wheels rolled ``s_l = r delta Delta c_l`` and ``s_r = r delta Delta c_r`` [m], so that the
platform advanced ``Delta s = (s_l + s_r) / 2`` and turned ``Delta theta = (s_r - s_l) / b``
(radius ``r``, effective track ``b = chi * track`` of
:class:`pbvs_pin.base.DifferentialDrive`). Over the interval the motion is taken as one arc of
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

from pbvs_pin.base import DifferentialDrive
from pbvs_pin.exceptions import GainError


class WheelOdometry:
    """Dead reckoning of a differential drive from its wheel encoders.

    Args:
        drive: The controller's model of the drive (wheel radius, track).
        counts_per_revolution: Encoder counts per wheel revolution ``N``.
        pose: Starting pose ``[x, y, theta]`` [m, m, rad] (the odometry frame's origin).
        wheel_angles: Left and right wheel angles at the start [rad], where the counts are
            zero. Shape (2,).

    Attributes:
        pose: Current estimate ``[x, y, theta]`` [m, m, rad]. Shape (3,).
        counts: Current left and right counts. Shape (2,).
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
        self.resolution = 2.0 * np.pi / counts_per_revolution
        self.pose = np.array(pose, dtype=float)
        self._origin = np.array(wheel_angles, dtype=float)
        self.counts = np.zeros(2)

    def read_counts(self, wheel_angles: npt.ArrayLike) -> np.ndarray:
        """The encoders' counts at wheel angles [rad] (shape (2,)): ``floor((a - a_0) / delta)``."""
        return np.floor((np.asarray(wheel_angles, dtype=float) - self._origin) / self.resolution)

    def update(self, counts: np.ndarray, turn: float | None = None) -> np.ndarray:
        """Advance the pose to new counts; return the count increments.

        Args:
            counts: Left and right counts now. Shape (2,).
            turn: The heading change [rad] since the last update from another sensor (a
                gyro: gyro-corrected odometry); None takes it from the counts.

        Returns:
            The count increments. Shape (2,).
        """
        increments = counts - self.counts
        self.counts = counts
        step = self.drive.wheel_radius * self.resolution
        left, right = float(increments[0]) * step, float(increments[1]) * step
        distance = 0.5 * (left + right)
        if turn is None:
            turn = (right - left) / self.drive.effective_track
        if turn == 0.0:
            forward, sideways = distance, 0.0
        else:
            forward = distance * math.sin(turn) / turn
            sideways = distance * (1.0 - math.cos(turn)) / turn
        x, y, theta = self.pose
        c, s = math.cos(theta), math.sin(theta)
        self.pose = np.array([x + c * forward - s * sideways, y + s * forward + c * sideways,
                              theta + turn])  # fmt: skip
        return increments
