"""Mobile-base adapters: how the platform's actuated velocities enter Pinocchio's model.

A base adapter chooses the root joint of the Pinocchio model and the constant selection matrix
``S`` that maps the actuated velocities ``v`` (``n`` of them) to Pinocchio's velocity ``v_pin``
(``nv`` of them): ``v_pin = S v``. The arm's joints map one to one, so an adapter only
describes the block of ``S`` that belongs to the root joint.

The differential drive puts a ``pin.JointModelPlanar`` at the drive-axle midpoint. Its velocity
``[vx, vy, wz]`` is expressed in the platform frame, so the no-side-slip constraint is
``vy = 0`` and ``S`` is constant.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pbvs_pin.exceptions import GainError


class BaseAdapter(abc.ABC):
    """Root joint and velocity selection of a mobile base."""

    @abc.abstractmethod
    def root_joint(self) -> pin.JointModel | None:
        """The Pinocchio root joint, or None for a base fixed to the world."""

    @property
    @abc.abstractmethod
    def velocity_names(self) -> tuple[str, ...]:
        """Names of the base's actuated velocities, in order."""

    @abc.abstractmethod
    def selection(self) -> np.ndarray:
        """Block of ``S`` for the root joint.

        Returns:
            Shape (nv_root, n_root): root-joint velocity from actuated base velocity.
        """

    @abc.abstractmethod
    def velocity_limits(self) -> np.ndarray:
        """Largest magnitude of each actuated base velocity, SI units. Shape (n_root,)."""


@dataclass(frozen=True)
class DifferentialDrive(BaseAdapter):
    """A platform driven by a left and a right wheel (or wheel set), no side slip.

    Actuated velocities: forward speed ``u`` [m/s] and yaw rate ``omega`` [rad/s] of the
    drive-axle midpoint. Wheel speeds: ``w_right = (u + omega * track / 2) / r`` and
    ``w_left = (u - omega * track / 2) / r``.

    Attributes:
        wheel_radius: Wheel radius r [m].
        track: Distance between the left and right wheel contact lines [m].
        max_wheel_speed: Largest wheel angular speed [rad/s].
    """

    wheel_radius: float
    track: float
    max_wheel_speed: float

    def __post_init__(self) -> None:
        """Reject non-positive dimensions."""
        for name in ("wheel_radius", "track", "max_wheel_speed"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0.0:
                raise GainError(f"DifferentialDrive.{name}: expected > 0, got {value}")

    def root_joint(self) -> pin.JointModel:
        """A planar joint, velocity ``[vx, vy, wz]`` in the platform frame."""
        return pin.JointModelPlanar()

    @property
    def velocity_names(self) -> tuple[str, ...]:
        """``("u", "omega")``."""
        return ("u", "omega")

    def selection(self) -> np.ndarray:
        r"""No side slip: ``vx = u``, ``vy = 0``, ``wz = omega``.

        .. math:: \begin{bmatrix} v_x \\ v_y \\ \omega_z \end{bmatrix}
                  = \begin{bmatrix} 1 & 0 \\ 0 & 0 \\ 0 & 1 \end{bmatrix}
                    \begin{bmatrix} u \\ \omega \end{bmatrix}

        Returns:
            Shape (3, 2).
        """
        return np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])

    def velocity_limits(self) -> np.ndarray:
        """``[r w_max, 2 r w_max / track]``: speed [m/s] and yaw rate [rad/s] limits."""
        u_max = self.wheel_radius * self.max_wheel_speed
        return np.array([u_max, 2.0 * u_max / self.track])

    def wheel_speeds(self, u: float, omega: float) -> tuple[float, float]:
        """Left and right wheel angular speeds [rad/s] for a platform command."""
        half = 0.5 * omega * self.track
        return (u - half) / self.wheel_radius, (u + half) / self.wheel_radius

    def wheel_map(self) -> np.ndarray:
        r"""Left and right wheel speeds [rad/s] from the planar joint's ``[vx, vy, wz]``.

        .. math:: w_l = (v_x - \omega_z b / 2) / r,\quad w_r = (v_x + \omega_z b / 2) / r

        Returns:
            Shape (2, 3).
        """
        half = 0.5 * self.track
        return np.array([[1.0, 0.0, -half], [1.0, 0.0, half]]) / self.wheel_radius

    def platform_velocity(self, wheel_speeds: np.ndarray) -> np.ndarray:
        r"""``[u, omega]`` [m/s, rad/s] from left and right wheel speeds [rad/s], shape (2,).

        .. math:: u = r (w_l + w_r) / 2,\quad \omega = r (w_r - w_l) / b

        Returns:
            Shape (2,).
        """
        left, right = wheel_speeds
        r = self.wheel_radius
        return np.array([0.5 * r * (left + right), r * (right - left) / self.track])


@dataclass(frozen=True)
class Omnidirectional(BaseAdapter):
    """A holonomic platform: ``[vx, vy, wz]`` in the platform frame are all actuated.

    Attributes:
        max_speed: Largest linear speed along each platform axis [m/s].
        max_yaw_rate: Largest yaw rate [rad/s].
    """

    max_speed: float = 1.0
    max_yaw_rate: float = 1.0

    def root_joint(self) -> pin.JointModel:
        """A planar joint, velocity ``[vx, vy, wz]`` in the platform frame."""
        return pin.JointModelPlanar()

    @property
    def velocity_names(self) -> tuple[str, ...]:
        """``("vx", "vy", "omega")``."""
        return ("vx", "vy", "omega")

    def selection(self) -> np.ndarray:
        """Identity, shape (3, 3)."""
        return np.eye(3)

    def velocity_limits(self) -> np.ndarray:
        """``[max_speed, max_speed, max_yaw_rate]``."""
        return np.array([self.max_speed, self.max_speed, self.max_yaw_rate])


@dataclass(frozen=True)
class FixedBase(BaseAdapter):
    """No platform motion: the arm's root is fixed in the world."""

    def root_joint(self) -> None:
        """No root joint."""
        return None

    @property
    def velocity_names(self) -> tuple[str, ...]:
        """No base velocity."""
        return ()

    def selection(self) -> np.ndarray:
        """Empty, shape (0, 0)."""
        return np.zeros((0, 0))

    def velocity_limits(self) -> np.ndarray:
        """Empty, shape (0,)."""
        return np.zeros(0)
