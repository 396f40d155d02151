"""Run parameters of a sweep spec: every combination of ``[grid]``, or ``n`` draws of ``[random]``.

Also the two helpers the spec's sections share: dotted keys from nested TOML tables, and the
check that a dotted key is a field of the scenario schema. Errors are
:class:`~pbvs_pin.exceptions.ScenarioError` naming the spec file and the field.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import Any

import numpy as np

from pbvs_pin.exceptions import ScenarioError
from pbvs_pin.sim.scenario import SCHEMA

LEAF_KEYS = {"range", "choices", "log"}


def flatten(table: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested TOML tables -> dotted keys (``motion.velocity = 1`` and ``"motion.velocity"``).

    A table holding ``range`` or ``choices`` is a leaf (a random field's distribution).
    """
    flat: dict[str, Any] = {}
    for key, value in table.items():
        dotted = f"{prefix}{key}"
        if isinstance(value, dict) and not (set(value) & LEAF_KEYS):
            flat.update(flatten(value, f"{dotted}."))
        else:
            flat[dotted] = value
    return flat


def check_field(source: str, where: str, field: str) -> None:
    """ScenarioError unless ``field`` is a dotted scenario field of the schema."""
    section, _, key = field.rpartition(".")
    if section not in SCHEMA or key not in SCHEMA[section]:
        fields = [f"{s}.{k}" if s else k for s, keys in SCHEMA.items() for k in keys]
        raise ScenarioError(
            source, where, f"unknown scenario field {field!r}; expected one of {', '.join(fields)}"
        )


def grid_runs(source: str, table: dict[str, Any]) -> tuple[list[str], list[dict[str, Any]]]:
    """Every combination of the grid's values, first field varying slowest."""
    grid = flatten(table)
    if not grid:
        raise ScenarioError(source, "grid", "expected at least one field")
    for field, values in grid.items():
        check_field(source, f"grid.{field}", field)
        if not isinstance(values, list) or not values:
            raise ScenarioError(
                source, f"grid.{field}", f"expected a non-empty list of values, got {values!r}"
            )
    fields = list(grid)
    runs = [dict(zip(fields, combo, strict=True)) for combo in itertools.product(*grid.values())]
    return fields, runs


def random_runs(
    source: str, table: dict[str, Any], spec_seed: int
) -> tuple[list[str], list[dict[str, Any]]]:
    """``n`` draws of every field, drawn run by run in field order."""
    table = dict(table)
    n = table.pop("n", None)
    seed = table.pop("seed", spec_seed)
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        raise ScenarioError(source, "random.n", f"expected a positive integer, got {n!r}")
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise ScenarioError(source, "random.seed", f"expected an integer >= 0, got {seed!r}")
    fields = flatten(table)
    if not fields:
        raise ScenarioError(source, "random", "expected at least one field")
    samplers = {}
    for field, spec in fields.items():
        check_field(source, f"random.{field}", field)
        samplers[field] = _sampler(source, f"random.{field}", spec)
    rng = np.random.default_rng(seed)
    runs = [{field: draw(rng) for field, draw in samplers.items()} for _ in range(n)]
    return list(fields), runs


def _sampler(source: str, where: str, spec: Any) -> Callable[[np.random.Generator], Any]:
    """A draw function for ``{range = [lo, hi], log = false}`` or ``{choices = [...]}``."""
    if not isinstance(spec, dict) or len(set(spec) & {"range", "choices"}) != 1:
        raise ScenarioError(
            source,
            where,
            f"expected a table with either range = [low, high] or choices = [...], got {spec!r}",
        )
    extra = set(spec) - LEAF_KEYS
    if extra:
        raise ScenarioError(
            source, f"{where}.{sorted(extra)[0]}", "unknown key; expected range, choices or log"
        )
    if "choices" in spec:
        choices = spec["choices"]
        if not isinstance(choices, list) or not choices:
            raise ScenarioError(source, f"{where}.choices", "expected a non-empty list")
        return lambda rng: choices[int(rng.integers(len(choices)))]
    bounds = spec["range"]
    log = spec.get("log", False)
    if not isinstance(log, bool):
        raise ScenarioError(source, f"{where}.log", f"expected true or false, got {log!r}")
    if not isinstance(bounds, list) or len(bounds) != 2:
        raise ScenarioError(source, f"{where}.range", f"expected [low, high], got {bounds!r}")
    low, high = (np.asarray(b) for b in bounds)
    if (
        low.shape != high.shape
        or low.dtype.kind not in "if"
        or high.dtype.kind not in "if"
        or not np.all(np.isfinite(low))
        or np.any(low > high)
        or (log and np.any(low <= 0))
    ):
        raise ScenarioError(
            source,
            f"{where}.range",
            f"expected [low, high] of numbers (or equal-length lists) with "
            f"low <= high{' and low > 0 (log)' if log else ''}, got {bounds!r}",
        )
    integer = low.dtype.kind == "i" and high.dtype.kind == "i" and not log

    def draw(rng: np.random.Generator) -> Any:
        if integer:
            return np.asarray(rng.integers(low, high, endpoint=True)).tolist()
        if log:
            return np.asarray(np.exp(rng.uniform(np.log(low), np.log(high)))).tolist()
        return np.asarray(rng.uniform(low, high)).tolist()

    return draw
