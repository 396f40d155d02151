"""Scenarios: TOML files that describe one closed-loop run.

A scenario names the robot, the camera, the target and its motion, the estimator, the
controller gains, the secondary objectives, the obstacles, the rates and the model errors.
A file is parsed once into a frozen :class:`Scenario` of typed sections
(:mod:`pbvs_pin.control.tables`, :mod:`pbvs_pin.sim.sections`), whose constructors check every
key: an unknown key, a wrong type, a vector of the wrong length or a non-positive gain is a
:class:`ScenarioError` that names the file and the dotted field. Shipped scenarios live in
``pbvs_pin/scenarios/`` and are found by name.

The raw TOML data (a dict of tables) stays the input format: :meth:`Scenario.with_values`
overrides dotted fields of :meth:`Scenario.to_toml` and parses again.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import MISSING, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, ClassVar

from pbvs_pin.control.tables import (
    CameraSection,
    CompensationSection,
    ControllerSection,
    EstimatorSection,
    SecondarySection,
    TargetSection,
)
from pbvs_pin.exceptions import GainError, ScenarioError
from pbvs_pin.model.shipped import scenario_dir as scenario_dir  # where it was, for its users
from pbvs_pin.model.shipped import scenario_file, shipped_scenarios
from pbvs_pin.sim.consistency import check_consistency
from pbvs_pin.sim.obstacles import BoxObstacle, CircleObstacle
from pbvs_pin.sim.sections import (
    SECTIONS,
    LaserSection,
    ModelErrorSection,
    MotionSection,
    PlantSection,
    PlatformSection,
    RobotSection,
    SensingSection,
    SimulationSection,
)
from pbvs_pin.toml_keys import Section, Sign, is_number, key, keys_of
from pbvs_pin.validation import read_toml

OBSTACLE_KINDS: dict[str, type[CircleObstacle | BoxObstacle]] = {
    "circle": CircleObstacle,
    "box": BoxObstacle,
}
"""``kind`` of an ``[[obstacles]]`` table -> its class (whose fields are the table's keys)."""


@dataclass(frozen=True)
class Scenario(Section):
    """A validated scenario: the file's root keys, one typed section per table, the obstacles.

    Attributes:
        source: File it came from (or its name), for error messages.
        name: The scenario's name; the file's stem when the file gives none.
        description: One line on what the run shows.
        duration: Simulated time [s].
        robot, model_error, plant, camera, target, motion, estimator, controller,
            compensation, secondary, laser, platform, simulation, sensing: The tables, see
            :mod:`pbvs_pin.control.tables` and :mod:`pbvs_pin.sim.sections`.
        obstacles: The ``[[obstacles]]`` tables as obstacles.
    """

    TABLE: ClassVar[str] = ""
    source: str = ""
    name: str = key("", "The scenario's name; the file's stem when empty.")
    description: str = key("", "One line on what the run shows.")
    duration: float = key(30.0, "Simulated time [s].", sign=Sign.POSITIVE)
    robot: RobotSection = field(default_factory=RobotSection)
    model_error: ModelErrorSection = field(default_factory=ModelErrorSection)
    plant: PlantSection = field(default_factory=PlantSection)
    camera: CameraSection = field(default_factory=CameraSection)
    target: TargetSection = field(default_factory=TargetSection)
    motion: MotionSection = field(default_factory=MotionSection)
    estimator: EstimatorSection = field(default_factory=EstimatorSection)
    controller: ControllerSection = field(default_factory=ControllerSection)
    compensation: CompensationSection = field(default_factory=CompensationSection)
    secondary: SecondarySection = field(default_factory=SecondarySection)
    laser: LaserSection = field(default_factory=LaserSection)
    platform: PlatformSection = field(default_factory=PlatformSection)
    simulation: SimulationSection = field(default_factory=SimulationSection)
    sensing: SensingSection = field(default_factory=SensingSection)
    obstacles: tuple[CircleObstacle | BoxObstacle, ...] = ()

    @classmethod
    def from_toml(cls, table: Mapping[str, Any], source: str) -> Scenario:
        """The whole file's data: see :func:`parse_scenario`."""
        return parse_scenario(dict(table), source)

    def validate(self) -> None:
        """Name the scenario after its file when it has no name; check across tables.

        Raises:
            GainError: If values of different tables contradict each other
                (:func:`pbvs_pin.sim.consistency.check_consistency`), naming the dotted field.
        """
        if not self.name:
            object.__setattr__(self, "name", Path(self.source).stem)
        check_consistency(self)

    def error(self, field: str, problem: str) -> ScenarioError:
        """A ScenarioError for this file."""
        return ScenarioError(self.source, field, problem)

    def to_toml(self) -> dict[str, Any]:
        """The scenario as TOML data (every key, defaults included); parses back to itself."""
        data = super().to_toml()
        for section in SECTIONS:
            data[section.TABLE] = getattr(self, section.TABLE).to_toml()
        data["obstacles"] = [obstacle_table(o) for o in self.obstacles]
        return data

    def with_values(self, **changes: Any) -> Scenario:
        """Copy with dotted fields replaced, e.g. ``with_values(**{"robot.name": "tiago"})``.

        A ``[robot]`` read from a robot file of its own (``run --robot FILE``) keeps naming
        that file in its messages unless a ``robot.`` key changes.

        Raises:
            ScenarioError: If a field is unknown or its value is invalid.
        """
        raw = self.to_toml()
        for dotted, value in changes.items():
            section, _, name = dotted.rpartition(".")
            table = raw.get(section) if section else raw
            if not isinstance(table, dict) or section == "obstacles":
                raise self.error(section, f"unknown section; expected one of {_sections()}")
            table[name] = value
        changed = parse_scenario(raw, self.source)
        if self.robot.source == self.source or any(d.startswith("robot.") for d in changes):
            return changed
        return replace(changed, robot=self.robot)


SCHEMA: dict[str, dict[str, Any]] = {
    "": {spec.name: spec.default for spec in keys_of(Scenario)},
    **{s.TABLE: {spec.name: spec.default for spec in keys_of(s)} for s in SECTIONS},
}
"""Every section and key with its default (from the sections' fields). The root is ``""``."""


def key_lines() -> list[str]:
    """Every scenario key as ``dotted.name = default  # meaning`` (default as JSON)."""
    lines = []
    for section in (Scenario, *SECTIONS):
        for spec in keys_of(section):
            name = f"{section.TABLE}.{spec.name}" if section.TABLE else spec.name
            default = list(spec.default) if isinstance(spec.default, tuple) else spec.default
            lines.append(f"{name} = {json.dumps(default)}  # {spec.metadata['doc']}")
    return lines


def obstacle_table(obstacle: CircleObstacle | BoxObstacle) -> dict[str, Any]:
    """An obstacle as its ``[[obstacles]]`` table: ``kind`` and every field."""
    kind = next(name for name, cls in OBSTACLE_KINDS.items() if isinstance(obstacle, cls))
    return {"kind": kind, **{spec.name: getattr(obstacle, spec.name) for spec in fields(obstacle)}}


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Read and validate a scenario file, or a shipped scenario by name.

    Raises:
        ScenarioError: Unknown scenario, malformed TOML, or an invalid field.
    """
    path = scenario_file(name_or_path)
    raw = read_toml(path, "a scenario")
    if not raw:
        raise ScenarioError(
            str(path),
            "",
            "empty scenario (no key, no table); expected at least a [robot] or [target] table, "
            "or name a shipped scenario: " + ", ".join(shipped_scenarios()),
        )
    return parse_scenario(raw, str(path))


def parse_scenario(raw: dict[str, Any], source: str) -> Scenario:
    """Build a :class:`Scenario` from parsed TOML data; absent keys take their defaults.

    Raises:
        ScenarioError: On any unknown key or invalid value, naming the field.
    """
    tables = {section.TABLE: section for section in SECTIONS}
    sections: dict[str, Section] = {}
    root: dict[str, Any] = {}
    known = [spec.name for spec in keys_of(Scenario)]
    for name, value in raw.items():
        if name == "obstacles":
            continue
        if isinstance(value, dict):
            if name not in tables:
                raise ScenarioError(source, name, f"unknown section; expected one of {_sections()}")
            sections[name] = tables[name].from_toml(value, source)
        elif name in known:
            root[name] = value
        else:
            raise ScenarioError(
                source, name, f"unknown key; expected one of {', '.join(sorted(known))}"
            )
    obstacles = raw.get("obstacles", [])
    if not isinstance(obstacles, list):
        raise ScenarioError(source, "obstacles", "expected an array of tables [[obstacles]]")
    built = tuple(_obstacle(source, i, table) for i, table in enumerate(obstacles))
    try:
        return Scenario(source=source, **root, **sections, obstacles=built)
    except GainError as err:
        raise ScenarioError(source, err.field, str(err)) from err


def _sections() -> str:
    return ", ".join(section.TABLE for section in SECTIONS)


def _obstacle(source: str, index: int, table: Any) -> CircleObstacle | BoxObstacle:
    """Build one ``[[obstacles]]`` table."""
    where = f"obstacles[{index}]"
    kind = table.get("kind") if isinstance(table, dict) else None
    if not isinstance(kind, str) or kind not in OBSTACLE_KINDS:
        raise ScenarioError(source, f"{where}.kind", f"expected one of {tuple(OBSTACLE_KINDS)}")
    cls = OBSTACLE_KINDS[table["kind"]]
    allowed = {spec.name for spec in fields(cls)}
    for name, value in table.items():
        if name == "kind":
            continue
        if name not in allowed:
            raise ScenarioError(
                source,
                f"{where}.{name}",
                f"unknown key; expected one of {sorted(allowed | {'kind'})}",
            )
        if not is_number(value):
            raise ScenarioError(source, f"{where}.{name}", f"expected a number, got {value!r}")
    missing = [spec.name for spec in fields(cls) if spec.name not in table
               and spec.default is MISSING and spec.default_factory is MISSING]  # fmt: skip
    if missing:
        raise ScenarioError(source, f"{where}.{missing[0]}", "missing; this kind needs it")
    try:
        return cls(**{name: value for name, value in table.items() if name != "kind"})
    except GainError as err:
        raise ScenarioError(source, where, str(err)) from err
