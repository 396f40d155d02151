"""The one conversion of user arguments, with errors that name the argument at fault.

Every public function and constructor converts its numbers (:func:`as_number`,
:func:`as_count`), vectors and matrices (:func:`as_array`), poses (:func:`as_se3`) and paths
(:func:`as_path`) here, once, at the door: a wrong kind of value (text, a bool, an object, a
ragged list) raises :class:`~pbvs_pin.exceptions.WrongType`, a wrong shape
:class:`~pbvs_pin.exceptions.ShapeError`, NaN or infinity
:class:`~pbvs_pin.exceptions.NonFiniteValue`, each naming the argument.
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from pbvs_pin.exceptions import GainError, NonFiniteValue, ScenarioError, ShapeError, WrongType


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
    array = as_numbers(name, value)
    if array.shape != shape:
        raise ShapeError(name, shape, array.shape)
    if not np.isfinite(array).all():
        raise NonFiniteValue(name)
    return array


NUMERIC_KINDS = "iuf"
"""NumPy dtype kinds accepted as numbers: integers and floats (not bools, text, objects)."""


def as_numbers(name: str, value: npt.ArrayLike) -> np.ndarray:
    """Convert ``value`` (a number, or nested sequences of numbers) to a float array.

    Raises:
        WrongType: If ``value`` is text, a bool, an object, complex or ragged.
    """
    if isinstance(value, str | bytes):
        raise WrongType(name, "numbers", value)
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError) as err:  # ragged sequences, objects that refuse
        raise WrongType(name, "numbers", value) from err
    if raw.dtype.kind not in NUMERIC_KINDS:
        raise WrongType(name, "numbers", value)
    return raw.astype(float, copy=False)


def as_rows(name: str, value: npt.ArrayLike, width: int, finite: bool = True) -> np.ndarray:
    """Convert ``value`` to a float array of shape ``(k, width)``, any ``k``.

    Args:
        name: Name of the argument, used in error messages.
        value: The rows.
        width: Entries per row.
        finite: Refuse NaN and infinity (False: the caller decides what they mean).

    Raises:
        WrongType: If ``value`` is not numbers.
        ShapeError: If it is not ``k`` rows of ``width``.
        NonFiniteValue: If an entry is NaN or infinite and ``finite``.
    """
    array = as_numbers(name, value)
    shape = (len(array) if array.ndim == 2 else 1, width)
    if array.shape != shape:
        raise ShapeError(name, shape, array.shape)
    if finite and not np.isfinite(array).all():
        raise NonFiniteValue(name)
    return array


def as_matrix(name: str, value: npt.ArrayLike, rows: int) -> np.ndarray:
    """Convert ``value`` to a finite float array of shape ``(rows, n)``, any ``n``.

    Raises:
        WrongType: If ``value`` is not numbers.
        ShapeError: If it is not a matrix of ``rows`` rows.
        NonFiniteValue: If an entry is NaN or infinite.
    """
    array = as_numbers(name, value)
    return as_array(name, array, (rows, array.shape[1] if array.ndim == 2 else 1))


def as_number(name: str, value: object, finite: bool = True) -> float:
    """Convert ``value`` (an int or a float, not text or a bool) to a float.

    Args:
        name: Name of the argument, used in error messages.
        value: The number.
        finite: Refuse NaN and infinity (False: the caller decides what they mean).

    Raises:
        WrongType: If ``value`` is not a single real number.
        NonFiniteValue: If it is NaN or infinite and ``finite``.
    """
    number = as_numbers(name, value)
    if number.shape != ():
        raise WrongType(name, "a number", value)
    if finite and not np.isfinite(number):
        raise NonFiniteValue(name)
    return float(number)


def as_pose_object(name: str, pose: object) -> pin.SE3:
    """``pose`` itself if it is a ``pinocchio.SE3`` (no other check: for inner loops).

    Raises:
        WrongType: If it is not.
    """
    if not isinstance(pose, pin.SE3):
        raise WrongType(name, "a pinocchio.SE3", pose)
    return pose


def as_count(name: str, value: object, minimum: int = 0) -> int:
    """Convert ``value`` (an integer, or a float with no fraction) to an int ``>= minimum``.

    Raises:
        WrongType: If ``value`` is not a whole number.
        NonFiniteValue: If it is NaN or infinite.
        GainError: If it is below ``minimum``.
    """
    number = as_number(name, value)
    if not number.is_integer():
        raise WrongType(name, "a whole number", value)
    if number < minimum:
        raise GainError(f"{name}: expected a whole number >= {minimum}, got {value!r}", name)
    return int(number)


def as_instance(name: str, value: object, kind: type) -> Any:
    """``value`` itself, if it is a ``kind`` (e.g. a ``MobileManipulator``).

    Raises:
        WrongType: If it is not (a dict, a name or a list where an object is expected).
    """
    if not isinstance(value, kind):
        raise WrongType(name, f"a {kind.__name__}", value)
    return value


NAME_MAX = 255
"""Longest file or folder name [bytes] of the usual file systems (ext4, APFS, NTFS)."""


def as_path(name: str, value: object) -> Path:
    """Convert ``value`` (a ``str`` or ``os.PathLike``) to a :class:`~pathlib.Path`.

    Raises:
        WrongType: If ``value`` is not a path, is empty, or has a name of more than
            :data:`NAME_MAX` bytes (which the system refuses with "File name too long").
    """
    if not isinstance(value, str | os.PathLike) or str(value) == "":
        raise WrongType(name, "a file or folder path (str or pathlib.Path)", value)
    path = Path(value)
    if any(len(os.fsencode(part)) > NAME_MAX for part in path.parts):
        raise WrongType(name, f"a path whose names have at most {NAME_MAX} bytes", value)
    return path


def read_toml(path: Path, kind: str) -> dict:
    """Read a TOML file the user named.

    Args:
        path: The file.
        kind: What it should be, for the message (e.g. ``"a sweep spec"``).

    Raises:
        ScenarioError: Naming the file, if it cannot be read, is not UTF-8 text or not TOML.
    """
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as err:
        problem = f"not UTF-8 text (expected {kind}, a TOML file): {err}"
    except OSError as err:
        problem = f"cannot be read (expected {kind}, a TOML file): {err.strerror}"
    except tomllib.TOMLDecodeError as err:
        problem = f"not valid TOML (expected {kind}): {err}"
    raise ScenarioError(str(path), "", problem)


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


def convert_fields(
    instance: object, numbers: tuple[str, ...] = (), counts: tuple[str, ...] = ()
) -> None:
    """Convert a frozen dataclass's number and count fields in place (for ``__post_init__``).

    Each error names the field as ``ClassName.field``.

    Args:
        instance: The dataclass instance.
        numbers: Fields converted by :func:`as_number`.
        counts: Fields converted by :func:`as_count`.

    Raises:
        WrongType: If a field is not a number (or not a whole one, for ``counts``).
        NonFiniteValue: If a count is NaN or infinite.
    """
    owner = type(instance).__name__
    for name in numbers:  # NaN and infinity are left to the class's own range checks
        value = as_number(f"{owner}.{name}", getattr(instance, name), finite=False)
        object.__setattr__(instance, name, value)
    for name in counts:
        value = as_count(f"{owner}.{name}", getattr(instance, name), minimum=-(2**62))
        object.__setattr__(instance, name, value)
