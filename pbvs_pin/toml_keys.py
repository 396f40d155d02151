"""Scenario keys: a key's default, documentation and check, and the section they form.

Every key of a scenario table is a dataclass field made by :func:`key`, which keeps the key's
default, its documentation (with its unit) and its check side by side; :class:`Section`
applies the checks in ``__post_init__`` (type, choices, length, sign), and a section's
:meth:`Section.validate` adds what the package's own blocks refuse. A constructor raises
:class:`~pbvs_pin.exceptions.GainError` naming the key; :meth:`Section.from_toml` turns it
into a :class:`~pbvs_pin.exceptions.ScenarioError` that names the file and the dotted field.
The tables themselves are in :mod:`pbvs_pin.control.tables` (the controller's) and
:mod:`pbvs_pin.sim.sections` (the simulator's).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import Field, field, fields
from enum import Enum
from typing import Any, ClassVar, Self

from pbvs_pin.exceptions import GainError, ScenarioError


class Sign(Enum):
    """What every number of a key must satisfy (NaN never does)."""

    ANY = "any"
    POSITIVE = "positive"
    NON_NEGATIVE = "non-negative"


def key(
    default: Any,
    doc: str,
    *,
    sign: Sign = Sign.ANY,
    choices: tuple[str, ...] = (),
    length: int | None = None,
    optional: type | None = None,
    matrix: bool = False,
    names: bool = False,
) -> Any:
    """A scenario key: a dataclass field with its default, documentation and check.

    The default also fixes the key's type: a string, a boolean, a float (an integer is
    accepted and converted), an integer (a float with an integral value is converted, 1.5 is
    refused), or a tuple of numbers (a TOML array; of arrays only when ``matrix``; ``None`` as
    default means "array or absent", or "``optional`` or absent" when ``optional`` gives a
    scalar type). Every number must be finite.

    Args:
        default: Value when the file does not give the key.
        doc: What the key means, with its unit.
        sign: Sign every number in the value must have.
        choices: The allowed strings, if the key is a choice.
        length: Required number of entries of an array.
        optional: With a ``None`` default, the type of the value when given (``float``,
            ``str``); arrays when not given.
        matrix: Whether the array may also be an array of arrays (a matrix).
        names: Whether the array holds strings (names) instead of numbers.
    """
    metadata = {
        "doc": doc, "sign": sign, "choices": choices, "length": length, "optional": optional,
        "matrix": matrix, "names": names,
    }  # fmt: skip
    return field(default=default, metadata=metadata)


def keys_of(cls: type) -> list[Field]:
    """The fields of ``cls`` made by :func:`key`, in declaration order."""
    return [spec for spec in fields(cls) if "doc" in spec.metadata]


class Section:
    """Base of every table: checks each :func:`key` field, then :meth:`validate`.

    Attributes:
        TABLE: The TOML table's name (``""`` for the file's root keys).
    """

    TABLE: ClassVar[str] = ""

    def __post_init__(self) -> None:
        """Check and normalise each key (arrays become tuples), then :meth:`validate`.

        Raises:
            GainError: If a value is invalid; ``field`` names the key.
        """
        for spec in keys_of(type(self)):
            object.__setattr__(self, spec.name, _checked(spec, getattr(self, spec.name)))
        self.validate()

    def validate(self) -> None:
        """Checks across keys; raise GainError naming the key (or none for the table)."""

    @classmethod
    def from_toml(cls, table: Mapping[str, Any], source: str) -> Self:
        """Build the section from its TOML table.

        Args:
            table: Key -> value as read from the file.
            source: The file (or name), for error messages.

        Raises:
            ScenarioError: On an unknown key or an invalid value, naming the dotted field.
        """
        known = [spec.name for spec in keys_of(cls)]
        for name in table:
            if name not in known:
                raise ScenarioError(
                    source,
                    cls.dotted(name),
                    f"unknown key; expected one of {', '.join(sorted(known))}",
                )
        try:
            return cls(**table)
        except GainError as err:
            raise ScenarioError(
                source, cls.dotted(err.field) if err.field else cls.TABLE, str(err)
            ) from err

    @classmethod
    def dotted(cls, name: str) -> str:
        """The dotted field name of key ``name`` in this table."""
        return f"{cls.TABLE}.{name}" if cls.TABLE else name

    def to_toml(self) -> dict[str, Any]:
        """Key -> value as a TOML table (tuples as lists)."""
        return {spec.name: _plain(getattr(self, spec.name)) for spec in keys_of(type(self))}


def _plain(value: Any) -> Any:
    return [_plain(x) for x in value] if isinstance(value, tuple) else value


def is_number(x: Any) -> bool:
    """A finite real number, not a boolean (NaN and infinity are not)."""
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def _numbers(value: Any) -> list:
    """Every number of a scalar, an array or an array of arrays."""
    rows = value if isinstance(value, tuple) else ((value,),)
    return [y for x in rows for y in (x if isinstance(x, tuple) else (x,))]


def _checked(spec: Field, value: Any) -> Any:
    """``value`` converted to the key's type and checked, or a GainError naming the key."""
    meta = spec.metadata
    default = spec.default
    if default is None and value is not None and meta["optional"] is not None:
        default = meta["optional"]()
    if meta.get("names") and value is not None:
        if not isinstance(value, list | tuple) or not all(isinstance(x, str) for x in value):
            raise GainError(f"expected a list of names (strings), got {value!r}", spec.name)
        return tuple(value)
    value = _typed(spec.name, value, default, meta.get("matrix", False))
    if value is None:
        return value
    if meta["choices"] and value not in meta["choices"]:
        raise GainError(f"expected one of {meta['choices']}, got {value!r}", spec.name)
    if meta["length"] is not None and len(value) != meta["length"]:
        shown = _plain(value)
        raise GainError(f"expected {meta['length']} values, got {len(value)}: {shown}", spec.name)
    numbers = _numbers(value)
    if meta["sign"] is Sign.POSITIVE and not all(is_number(x) and x > 0 for x in numbers):
        raise GainError(f"expected positive values, got {_plain(value)}", spec.name)
    if meta["sign"] is Sign.NON_NEGATIVE and not all(is_number(x) and x >= 0 for x in numbers):
        raise GainError(f"expected values >= 0, got {_plain(value)}", spec.name)
    return value


def _typed(name: str, value: Any, default: Any, matrix: bool = False) -> Any:
    """Coerce ``value`` to the default's type (int -> float allowed), or a GainError."""
    if default is None or isinstance(default, tuple):
        if default is None and value is None:
            return None
        if not isinstance(value, list | tuple) or not all(
            is_number(x)
            or (matrix and isinstance(x, list | tuple) and all(is_number(y) for y in x))
            for x in value
        ):
            kind = "list of finite numbers" + (" (or a list of such lists)" if matrix else "")
            raise GainError(f"expected a {kind}, got {value!r}", name)
        rows = {len(x) if isinstance(x, list | tuple) else None for x in value}
        if len(rows) > 1:
            raise GainError(f"expected numbers or rows of equal length, got {value!r}", name)
        return tuple(tuple(x) if isinstance(x, list | tuple) else x for x in value)
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise GainError(f"expected true or false, got {value!r}", name)
        return value
    if isinstance(default, int | float):
        if not is_number(value):
            raise GainError(f"expected a finite number, got {value!r}", name)
        if isinstance(default, float):
            return float(value)
        if isinstance(value, float) and not value.is_integer():
            raise GainError(f"expected an integer, got {value!r}", name)
        return int(value)
    if not isinstance(value, str):
        raise GainError(f"expected a string, got {value!r}", name)
    return value


POSITIVE, NON_NEGATIVE = Sign.POSITIVE, Sign.NON_NEGATIVE
