"""The physical bounds of a control step's inputs: a finite value beyond them is a fault.

A value can be finite and still impossible: a pixel a million image widths off, a laser range
of ``-1e308`` m, a wheel speed of ``1e155`` m/s. Such a value, taken as it is, overflows the
features, the filters and the laws downstream (a target speed of ``1e297`` m/s, all-NaN
commands). :class:`pbvs_pin.Controller` therefore checks every input against the bounds below
and, by where the value comes from:

- **refuses** (raises :class:`~pbvs_pin.exceptions.ControlInputError`, naming the argument,
  the entry, the value and the bound, and leaves the controller as it was) what the robot's
  own loop computes or reads from its joints: ``t``, ``q``, ``v``, ``target_velocity``. There is
  no earlier reading to fall back on that the caller would not know about;
- **drops with a count** (:class:`~pbvs_pin.control.gating.FaultCounts`) what a sensor
  delivers now and again, a camera frame or a laser scan: the step goes on with the previous
  one, as when nothing arrived.

The bounds are far beyond any real reading, so that they never refuse a good one.
"""

from __future__ import annotations

import math

import numpy as np

from pbvs_pin.exceptions import ControlInputError
from pbvs_pin.perception.estimation import MAX_TARGET_SPEED

MAX_COORDINATE = 1e6
"""Largest ``|q_i|`` [m or rad]: odometry a thousand kilometres from its origin."""
VELOCITY_BOUND = 10.0
"""Largest ``|v_i|``, in multiples of the robot's velocity limit for that entry."""
MAX_STEP_GAP = 60.0
"""Largest ``t`` minus the previous step's ``t`` [s]; after a longer pause call ``reset()``."""
CLOCK_JITTER = 0.005
"""A frame stamped at most this long after ``t`` [s] is used as captured at ``t`` (counted);
later, the frame's clock is not the controller's and the step raises."""
MAX_DEPTH = 100.0
"""Largest depth of a target point [m]."""
IMAGE_REACH = 1.0
"""Image points lie within ``IMAGE_REACH`` image widths (heights) of the centre, ``|u| <= W``
and ``|v| <= H``: half an image beyond each edge."""
MAX_LASER_RANGE = 1000.0
"""Largest finite laser range [m] (``inf``: nothing in range); the bearing lies in
``[-pi, pi]``."""


def check_configuration_bounds(q: np.ndarray) -> None:
    """Refuse a configuration entry beyond :data:`MAX_COORDINATE`.

    Raises:
        ControlInputError: Naming the entry and its value.
    """
    values = q.tolist()  # Python floats: faster than NumPy on a few entries
    if max(map(abs, values), default=0.0) > MAX_COORDINATE:
        entry = max(range(len(values)), key=lambda i: abs(values[i]))
        raise ControlInputError(
            f"q[{entry}] = {values[entry]:g}: expected |q| <= {MAX_COORDINATE:g} (m or rad)"
        )


def check_velocity_bounds(v: np.ndarray, bound: tuple[float, ...]) -> None:
    """Refuse a measured velocity entry beyond ``bound`` (``VELOCITY_BOUND`` times its limit).

    Args:
        v: Measured actuated velocity. Shape (n,).
        bound: Largest ``|v_i|`` [m/s or rad/s], one per entry.

    Raises:
        ControlInputError: Naming the entry, its value and its bound.
    """
    for entry, (value, largest) in enumerate(zip(v.tolist(), bound, strict=True)):
        if abs(value) > largest:
            raise ControlInputError(
                f"v[{entry}] = {value:g}: expected |v| <= {largest:g} ({VELOCITY_BOUND:g} "
                "times the velocity limit)"
            )


def check_target_speed(velocity: np.ndarray) -> None:
    """Refuse a given target velocity faster than :data:`MAX_TARGET_SPEED`.

    Raises:
        ControlInputError: Naming the speed.
    """
    speed = math.hypot(*velocity.tolist())  # no overflow
    if speed > MAX_TARGET_SPEED:
        raise ControlInputError(
            f"target_velocity: speed {speed:g} m/s, expected at most {MAX_TARGET_SPEED:g} m/s"
        )


def check_time_gap(t: float, previous: float) -> None:
    """Refuse a step more than :data:`MAX_STEP_GAP` after the previous one (-inf: none yet).

    Raises:
        ControlInputError: Naming both times.
    """
    if previous > -math.inf and t - previous > MAX_STEP_GAP:
        raise ControlInputError(
            f"t = {t:g} s is more than {MAX_STEP_GAP:g} s after the previous step's "
            f"({previous:g} s); after a pause, call controller.reset()"
        )


def frame_fault(points: np.ndarray, depths: np.ndarray, width: float, height: float) -> str:
    """Why a frame's finite points or depths are impossible; empty when they are within bounds.

    Args:
        points: Image points [px]. Shape (k, 2).
        depths: Depths [m]. Shape (k,).
        width: Image width [px].
        height: Image height [px].
    """
    reach = np.array([IMAGE_REACH * width, IMAGE_REACH * height])
    if (np.abs(points) > reach).any():
        return (
            f"points {points.round(1).tolist()} beyond |u| <= {reach[0]:g}, |v| <= {reach[1]:g} "
            "px: dropped"
        )
    if (depths > MAX_DEPTH).any():
        return f"depths {depths.tolist()} beyond {MAX_DEPTH:g} m: dropped"
    return ""


def laser_fault(distance: float, bearing: float) -> str:
    """Why a laser reading is impossible; empty when it is within bounds.

    Args:
        distance: Range [m]; ``inf`` when nothing is in range.
        bearing: Bearing [rad].
    """
    if not 0.0 <= distance <= MAX_LASER_RANGE and distance != math.inf:
        return f"laser range {distance:g} m outside [0, {MAX_LASER_RANGE:g}] m (or inf): dropped"
    if abs(bearing) > math.pi:
        return f"laser bearing {bearing:g} rad outside [-pi, pi]: dropped"
    return ""
