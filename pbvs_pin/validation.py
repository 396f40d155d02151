"""Conversion of user arrays, with errors that name the argument at fault."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from pbvs_pin.exceptions import GainError, NonFiniteValue, ShapeError


def as_array(name: str, value: npt.ArrayLike, shape: tuple[int, ...]) -> np.ndarray:
    """Convert ``value`` to a finite float array of the given shape.

    Args:
        name: Name of the argument, used in error messages.
        value: Anything ``np.asarray`` accepts.
        shape: The expected shape.

    Returns:
        A float64 array of shape ``shape``.

    Raises:
        ShapeError: If the shape differs.
        NonFiniteValue: If an entry is NaN or infinite.
    """
    array = np.asarray(value, dtype=float)
    if array.shape != shape:
        raise ShapeError(name, shape, array.shape)
    if not np.isfinite(array).all():
        raise NonFiniteValue(name)
    return array


def positive_number(name: str, value: object) -> float:
    """Convert ``value`` (a number or its text) to a positive finite float.

    Args:
        name: Name of the parameter, used in the error message and as its ``field``.
        value: Anything ``float`` accepts.

    Raises:
        GainError: If ``value`` is not a number, not finite, or not above zero.
    """
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = float("nan")
    if not (np.isfinite(number) and number > 0.0):
        raise GainError(f"{name}: expected a positive number, got {value!r}", field=name)
    return number


ROTATION_TOLERANCE = 1e-6
"""Largest entry of ``|R^T R - I|`` of a rotation given as a matrix."""


def as_se3(name: str, pose: pin.SE3 | npt.ArrayLike) -> pin.SE3:
    """Convert a pose to ``pinocchio.SE3``.

    Args:
        name: Name of the argument, used in error messages.
        pose: A ``pinocchio.SE3``, or a 6-vector ``(x, y, z, roll, pitch, yaw)`` in m and rad
            (rotation ``Rz(yaw) Ry(pitch) Rx(roll)``, as in URDF).

    Returns:
        The pose.

    Raises:
        ShapeError: If a vector is not of length 6.
        NonFiniteValue: If an entry is NaN or infinite.
        GainError: If an SE3's rotation is not orthonormal with determinant +1 (within
            :data:`ROTATION_TOLERANCE`); it is refused, never silently altered.
    """
    if isinstance(pose, pin.SE3):
        rotation = as_array(f"{name}.rotation", pose.rotation, (3, 3))
        as_array(f"{name}.translation", pose.translation, (3,))
        error = np.abs(rotation.T @ rotation - np.eye(3)).max()
        if error > ROTATION_TOLERANCE or np.linalg.det(rotation) < 0:
            raise GainError(
                f"{name}: the rotation is not a rotation matrix (|R^T R - I| = {error:.3g}, "
                f"det R = {np.linalg.det(rotation):.3g}); expected R^T R = I and det R = +1",
                field=name,
            )
        return pin.SE3(pose)
    xyz_rpy = as_array(name, pose, (6,))
    return pin.SE3(pin.rpy.rpyToMatrix(xyz_rpy[3:]), xyz_rpy[:3])
