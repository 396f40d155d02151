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
from numba import njit

from pbvs_pin.exceptions import GainError
from pbvs_pin.validation import as_array, as_number, convert_fields


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

    def per_velocity(self, linear: float, yaw: float) -> tuple[float, ...]:
        """A value written for a unicycle (forward speed, yaw rate), one per base velocity.

        Gains and time constants written for the paper's platform fit any base: the linear
        value goes to every linear velocity (``u``; ``vx`` and ``vy`` of a holonomic base), the
        yaw value to ``omega``.
        """
        linear, yaw = as_number("linear", linear), as_number("yaw", yaw)
        return tuple(yaw if name == "omega" else linear for name in self.velocity_names)


@dataclass(frozen=True)
class DifferentialDrive(BaseAdapter):
    r"""A platform driven by a left and a right wheel (or wheel set), no side slip.

    Actuated velocities: forward speed ``u`` [m/s] and yaw rate ``omega`` [rad/s] of the
    drive-axle midpoint. Wheel speeds: ``w_right = (u + omega * chi * track / 2) / r`` and
    ``w_left = (u - omega * chi * track / 2) / r``, with the *effective track* ``chi * track``.

    A skid-steer platform (more than one wheel per side, all fixed) slips sideways whenever it
    turns: its wheels' instantaneous centres of rotation lie outside the wheels, so that it
    turns as if its track were ``chi`` times wider (the ICR expansion factor; Mandow et al.,
    "Experimental kinematics for wheeled skid-steer mobile robots", IROS 2007, on a Pioneer
    3-AT; ``wheel_separation_multiplier`` of ROS's ``diff_drive_controller``). With one wheel
    per side, ``chi = 1``. For wheels at ``+-a`` from the axle midpoint along x and ``+-b``
    along y, equal loads and Coulomb friction, the moment balance of a spin in place gives
    ``chi = (a^2 + b^2) / b^2`` (:func:`skid_steer_factor`).

    Attributes:
        wheel_radius: Wheel radius r [m].
        track: Distance between the left and right wheel contact lines [m].
        max_wheel_speed: Largest wheel angular speed [rad/s].
        track_factor: ICR expansion factor ``chi >= 1`` [-]: the wheel-speed mapping, the yaw
            rate limit and wheel odometry use the effective track ``chi * track``.
    """

    wheel_radius: float
    track: float
    max_wheel_speed: float
    track_factor: float = 1.0

    def __post_init__(self) -> None:
        """Reject non-positive dimensions and an expansion factor below 1."""
        convert_fields(self, ("wheel_radius", "track", "max_wheel_speed", "track_factor"))
        if not (np.isfinite(self.track_factor) and self.track_factor >= 1.0):
            raise GainError(
                f"DifferentialDrive.track_factor: expected >= 1, got {self.track_factor}"
            )
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

    @property
    def effective_track(self) -> float:
        """``chi * track`` [m]: the track of the unicycle the platform turns as."""
        return self.track_factor * self.track

    def velocity_limits(self) -> np.ndarray:
        """``[r w_max, 2 r w_max / (chi track)]``: speed [m/s] and yaw rate [rad/s] limits."""
        u_max = self.wheel_radius * self.max_wheel_speed
        return np.array([u_max, 2.0 * u_max / self.effective_track])

    def wheel_speeds(self, u: float, omega: float) -> tuple[float, float]:
        """Left and right wheel angular speeds [rad/s] for a command (:meth:`wheel_map`)."""
        u, omega = as_number("u", u), as_number("omega", omega)
        left, right = self.wheel_map() @ np.array([u, 0.0, omega])
        return float(left), float(right)

    def wheel_map(self) -> np.ndarray:
        r"""Left and right wheel speeds [rad/s] from the planar joint's ``[vx, vy, wz]``.

        .. math:: w_l = (v_x - \omega_z b / 2) / r,\quad w_r = (v_x + \omega_z b / 2) / r

        with ``b`` the effective track (the platform moving as the unicycle its wheel speeds
        command, :meth:`wheel_speeds`).

        Returns:
            Shape (2, 3).
        """
        half = 0.5 * self.effective_track
        return np.array([[1.0, 0.0, -half], [1.0, 0.0, half]]) / self.wheel_radius

    def platform_velocity(self, wheel_speeds: np.ndarray) -> np.ndarray:
        r"""``[u, omega]`` [m/s, rad/s] from left and right wheel speeds [rad/s], shape (2,).

        .. math:: u = r (w_l + w_r) / 2,\quad \omega = r (w_r - w_l) / b

        with ``b`` the effective track, the inverse of :meth:`wheel_speeds`.

        Returns:
            Shape (2,).
        """
        left, right = as_array("wheel_speeds", wheel_speeds, (2,))
        return np.array(unicycle_twist(self.wheel_radius, self.effective_track, left, right))


@njit(cache=True)
def unicycle_twist(radius: float, track: float, left: float, right: float) -> tuple[float, float]:
    r"""``(u, omega)`` [m/s, rad/s] of wheel speeds ``left``, ``right`` [rad/s].

    .. math:: u = r (w_l + w_r) / 2,\quad \omega = r (w_r - w_l) / b

    Args:
        radius: Wheel radius ``r`` [m].
        track: Effective track ``b`` [m].
        left: Left wheel speed [rad/s].
        right: Right wheel speed [rad/s].
    """
    return 0.5 * radius * (left + right), radius * (right - left) / track


def skid_steer_factor(wheel_positions: np.ndarray) -> float:
    r"""ICR expansion factor ``chi`` of fixed wheels at ``wheel_positions``.

    For wheel contact points at ``(x_i, y_i)`` around their centroid, half-wheelbase
    ``a = sqrt(mean (x_i - mean x)^2)`` and half-track ``b = mean |y_i - mean y|``, a spin in
    place under Coulomb friction and equal wheel loads is balanced (zero net yaw moment of the
    friction forces ``-mu N s_i / |s_i|`` against the slip velocities ``s_i``) at
    ``omega = omega_c b^2 / (a^2 + b^2)``, where ``omega_c = r (w_r - w_l) / (2 b)``:

    .. math:: \chi = \frac{a^2 + b^2}{b^2}.

    One wheel per side (``a = 0``) gives ``chi = 1``; the Pioneer 3-AT (``a = 0.134`` m,
    ``b = 0.197`` m) gives 1.46, within the 1.3-2 measured on such platforms.

    Args:
        wheel_positions: Wheel centres in the platform frame [m], x forward, y left.
            Shape (n_wheels, 2) or (n_wheels, 3).

    Returns:
        ``chi >= 1``.
    """
    positions = np.asarray(wheel_positions, dtype=float)[:, :2]
    centred = positions - positions.mean(axis=0)
    half_wheelbase_sq = float(np.mean(centred[:, 0] ** 2))
    half_track = float(np.mean(np.abs(centred[:, 1])))
    return (half_wheelbase_sq + half_track**2) / half_track**2


@dataclass(frozen=True)
class Omnidirectional(BaseAdapter):
    """A holonomic platform: ``[vx, vy, wz]`` in the platform frame are all actuated.

    Attributes:
        max_speed: Largest linear speed along each platform axis [m/s].
        max_yaw_rate: Largest yaw rate [rad/s].
    """

    max_speed: float = 1.0
    max_yaw_rate: float = 1.0

    def __post_init__(self) -> None:
        """Convert both limits to numbers; reject a limit that is not above zero."""
        convert_fields(self, ("max_speed", "max_yaw_rate"))
        for name in ("max_speed", "max_yaw_rate"):
            if getattr(self, name) <= 0.0:
                raise GainError(
                    f"Omnidirectional.{name}: expected > 0, got {getattr(self, name)}", name
                )

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
