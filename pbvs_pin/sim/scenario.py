"""Scenarios: TOML files that describe one closed-loop run.

A scenario names the robot, the camera, the target and its motion, the estimator, the
controller gains, the secondary objectives, the obstacles, the rates and the model errors.
Every key is checked against the schema below: an unknown key, a wrong type, a vector of the
wrong length or a non-positive gain is a :class:`ScenarioError` that names the file and the
dotted field. Shipped scenarios live in ``pbvs_pin/scenarios/`` and are found by name.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pbvs_pin.exceptions import GainError, PbvsError, ScenarioError

SCHEMA: dict[str, dict[str, Any]] = {
    "": {"name": "", "description": "", "duration": 30.0},
    "robot": {"name": "pioneer_cyton", "initial_arm": None},
    "model_error": {"kinematic_scale": 1.0, "mass_scale": 1.0},
    "camera": {
        "focal_px": 600.0,
        "width": 628,
        "height": 582,
        "rate": 30.0,
        "latency": 0.0,
        "noise_px": 0.0,
    },
    "target": {
        "diameter": 0.05,
        "separation": 0.10,
        "xi0": [-150.0, 20.0, -100.0],
        "xi_d": [0.0, 60.0, -60.0],
    },
    "motion": {
        "kind": "still",
        "velocity": [0.0, 0.0, 0.0],
        "amplitude": [0.0, 0.0, 0.0],
        "frequency": 0.0,
        "stop_time": 0.0,
    },
    "estimator": {"kind": "alpha_beta", "alpha": 0.5, "beta": 0.1},
    "controller": {
        "law": "passivity",
        "k": [0.15],
        "k1": [0.7, 1.0, 0.1, 0.1, 0.1],
        "k2": [0.2],
        "feature_scale": 150.0,
        "weights": [1.0],
        "feedback": "transpose",
        "ibvs_gain": 0.5,
        "rate": 100.0,
    },
    "compensation": {"mode": "platform", "k_d": [4.0], "derivative_time_constant": 0.05},
    "secondary": {
        "obstacle_avoidance": False,
        "posture": False,
        "joint_limits": True,
        "k_uobs": 0.5,
        "k_wobs": 0.9,
        "d0": 1.0,
        "impedance_mass": 0.5,
        "impedance_damping": 1.0,
        "k_lambda": 1.0,
    },
    "laser": {"rate": 20.0, "beams": 181, "field_of_view": 3.14159, "max_range": 8.0},
    "platform": {"length": 0.50, "width": 0.49},
    "simulation": {"plant_dt": 0.001, "log_rate": 50.0, "seed": 0},
}
"""Every section and key with its default. The root section is ``""``."""

CHOICES = {
    "motion.kind": ("still", "line_then_stop", "weave"),
    "estimator.kind": ("alpha_beta", "exact"),
    "controller.law": ("passivity", "ibvs"),
    "controller.feedback": ("transpose", "pseudoinverse"),
    "compensation.mode": ("off", "platform", "all"),
}

POSITIVE = {
    "duration", "camera.focal_px", "camera.width", "camera.height", "camera.rate",
    "target.diameter", "target.separation", "controller.k", "controller.k1", "controller.k2",
    "controller.feature_scale", "controller.ibvs_gain", "controller.rate", "compensation.k_d",
    "compensation.derivative_time_constant", "secondary.k_uobs", "secondary.k_wobs",
    "secondary.d0", "secondary.impedance_mass", "secondary.impedance_damping",
    "secondary.k_lambda", "laser.rate", "laser.beams", "laser.field_of_view",
    "laser.max_range", "platform.length", "platform.width", "simulation.plant_dt",
    "simulation.log_rate", "model_error.kinematic_scale", "model_error.mass_scale",
}  # fmt: skip
"""Fields whose every value must be > 0."""

NON_NEGATIVE = {"camera.latency", "camera.noise_px", "motion.frequency", "motion.stop_time"}

LENGTHS = {
    "target.xi0": 3,
    "target.xi_d": 3,
    "motion.velocity": 3,
    "motion.amplitude": 3,
}

OBSTACLE_KEYS = {
    "circle": {"x", "y", "radius", "height"},
    "box": {"x", "y", "size_x", "size_y", "yaw", "height"},
}


@dataclass(frozen=True)
class Scenario:
    """A validated scenario.

    Attributes:
        source: File it came from (or its name), for error messages.
        values: Section -> key -> value, every key present (defaults filled in).
        obstacles: Obstacle tables, each with a ``kind``.
    """

    source: str
    values: dict[str, dict[str, Any]]
    obstacles: tuple[dict[str, Any], ...]

    def __getitem__(self, section: str) -> dict[str, Any]:
        """One section's values."""
        return self.values[section]

    @property
    def name(self) -> str:
        """The scenario's name (the file stem when not given)."""
        return self.values[""]["name"] or Path(self.source).stem

    def error(self, field: str, problem: str) -> ScenarioError:
        """A ScenarioError for this file."""
        return ScenarioError(self.source, field, problem)

    def with_values(self, **changes: Any) -> Scenario:
        """Copy with dotted fields replaced, e.g. ``with_values(**{"robot.name": "tiago"})``.

        Raises:
            ScenarioError: If a field is unknown or its value is invalid.
        """
        raw = {section: dict(keys) for section, keys in self.values.items()}
        root = raw.pop("")
        for dotted, value in changes.items():
            section, _, key = dotted.rpartition(".")
            (raw.setdefault(section, {}) if section else root)[key] = value
        raw.update(root)
        raw["obstacles"] = [dict(o) for o in self.obstacles]
        return parse_scenario(raw, self.source)


def scenario_dir() -> Path:
    """Folder of the shipped scenarios."""
    return Path(__file__).resolve().parents[1] / "scenarios"


def shipped_scenarios() -> list[str]:
    """Names of the shipped scenarios."""
    return sorted(path.stem for path in scenario_dir().glob("*.toml"))


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Read and validate a scenario file, or a shipped scenario by name.

    Raises:
        ScenarioError: Unknown scenario, malformed TOML, or an invalid field.
    """
    path = Path(name_or_path)
    if not path.is_file():
        shipped = scenario_dir() / f"{name_or_path}.toml"
        if not shipped.is_file():
            raise ScenarioError(
                str(name_or_path),
                "",
                "no such scenario file, and not a shipped scenario; shipped: "
                + ", ".join(shipped_scenarios()),
            )
        path = shipped
    try:
        raw = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise ScenarioError(str(path), "", f"not valid TOML: {err}") from err
    return parse_scenario(raw, str(path))


def parse_scenario(raw: dict[str, Any], source: str) -> Scenario:
    """Validate a parsed TOML document and fill in defaults.

    Raises:
        ScenarioError: On any unknown key or invalid value, naming the field.
    """
    values: dict[str, dict[str, Any]] = {s: dict(keys) for s, keys in SCHEMA.items()}
    for key, value in raw.items():
        if key == "obstacles":
            continue
        if isinstance(value, dict):
            if key not in SCHEMA or key == "":
                raise ScenarioError(source, key, f"unknown section; expected one of {_sections()}")
            for inner, inner_value in value.items():
                _set(values, source, key, inner, inner_value)
        else:
            _set(values, source, "", key, value)
    obstacles = tuple(_obstacle(source, i, o) for i, o in enumerate(raw.get("obstacles", [])))
    return Scenario(source, values, obstacles)


def _sections() -> str:
    return ", ".join(s for s in SCHEMA if s)


def _set(values: dict, source: str, section: str, key: str, value: Any) -> None:
    """Check one field against the schema and store it."""
    field = f"{section}.{key}" if section else key
    if key not in SCHEMA[section]:
        raise ScenarioError(
            source, field, f"unknown key; expected one of {', '.join(sorted(SCHEMA[section]))}"
        )
    default = SCHEMA[section][key]
    value = _typed(source, field, value, default)
    if field in CHOICES and value not in CHOICES[field]:
        raise ScenarioError(source, field, f"expected one of {CHOICES[field]}, got {value!r}")
    if field in LENGTHS and len(value) != LENGTHS[field]:
        raise ScenarioError(
            source, field, f"expected {LENGTHS[field]} values, got {len(value)}: {value}"
        )
    numbers = value if isinstance(value, list) else [value]
    if field in POSITIVE and not all(_number(x) and x > 0 for x in _flat(numbers)):
        raise ScenarioError(source, field, f"expected positive values, got {value}")
    if field in NON_NEGATIVE and not all(_number(x) and x >= 0 for x in _flat(numbers)):
        raise ScenarioError(source, field, f"expected values >= 0, got {value}")
    values[section][key] = value


def _number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and x == x


def _flat(values: list) -> list:
    return [y for x in values for y in (x if isinstance(x, list) else [x])]


def _typed(source: str, field: str, value: Any, default: Any) -> Any:
    """Coerce ``value`` to the default's type (int -> float allowed), or raise."""
    if default is None or isinstance(default, list):
        if default is None and value is None:
            return None
        if not isinstance(value, list) or not all(_number(x) or isinstance(x, list) for x in value):
            raise ScenarioError(source, field, f"expected a list of numbers, got {value!r}")
        return value
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ScenarioError(source, field, f"expected true or false, got {value!r}")
        return value
    if isinstance(default, int | float):
        if not _number(value):
            raise ScenarioError(source, field, f"expected a number, got {value!r}")
        return type(default)(value) if isinstance(default, float) else value
    if not isinstance(value, str):
        raise ScenarioError(source, field, f"expected a string, got {value!r}")
    return value


def _obstacle(source: str, index: int, table: Any) -> dict[str, Any]:
    """Validate one ``[[obstacles]]`` table."""
    field = f"obstacles[{index}]"
    if not isinstance(table, dict) or table.get("kind") not in OBSTACLE_KEYS:
        raise ScenarioError(source, f"{field}.kind", f"expected one of {tuple(OBSTACLE_KEYS)}")
    allowed = OBSTACLE_KEYS[table["kind"]] | {"kind"}
    for key, value in table.items():
        if key not in allowed:
            raise ScenarioError(
                source, f"{field}.{key}", f"unknown key; expected one of {sorted(allowed)}"
            )
        if key != "kind" and not _number(value):
            raise ScenarioError(source, f"{field}.{key}", f"expected a number, got {value!r}")
    return dict(table)


def check(scenario: Scenario, field: str, action: Any) -> Any:
    """Run ``action()``; turn a package error into a ScenarioError naming ``field``.

    A :class:`GainError` that names its parameter is reported as ``field.parameter``.
    """
    try:
        return action()
    except ScenarioError:
        raise
    except GainError as err:
        raise scenario.error(f"{field}.{err.field}" if err.field else field, str(err)) from err
    except PbvsError as err:
        raise scenario.error(field, str(err)) from err
