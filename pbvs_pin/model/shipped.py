"""Where the URDF files and the scenarios shipped with pbvs_pin live.

In a source checkout the URDF files are in the top-level ``urdf/`` folder; an installed wheel
carries the same files as the package data ``pbvs_pin.urdf``. The scenarios are the package
data ``pbvs_pin/scenarios/*.toml``. This module loads nothing heavy: the command line resolves
a scenario's name here, and refuses an unknown one, before it loads the simulation.
"""

from __future__ import annotations

from pathlib import Path

from pbvs_pin.exceptions import ScenarioError
from pbvs_pin.validation import as_path

PACKAGE = Path(__file__).resolve().parents[1]
"""The ``pbvs_pin`` package folder (this module is in its ``model`` package)."""

SHIPPED_URDFS = ("pioneer3at", "cyton_alpha3", "pioneer_cyton")
"""Names of the shipped URDF files (without ``.urdf``)."""


def urdf_dir() -> Path:
    """Folder holding the shipped URDF files."""
    checkout = PACKAGE.parent / "urdf"
    if checkout.is_dir():
        return checkout
    return PACKAGE / "urdf"


def shipped_urdf(name: str) -> Path | None:
    """Path of a shipped URDF file by name (``"pioneer3at"``), or None if not shipped."""
    if name not in SHIPPED_URDFS:
        return None
    return urdf_dir() / f"{name}.urdf"


def scenario_dir() -> Path:
    """Folder of the shipped scenarios."""
    return PACKAGE / "scenarios"


def shipped_scenarios() -> list[str]:
    """Names of the shipped scenarios."""
    return sorted(path.stem for path in scenario_dir().glob("*.toml"))


def scenario_file(name_or_path: str | Path) -> Path:
    """The file of a scenario: a TOML path, or a shipped scenario's name (``"experiment1"``).

    Raises:
        WrongType: If ``name_or_path`` is not text or a path.
        ScenarioError: If it is neither an existing file nor a shipped scenario's name.
    """
    path = as_path("name_or_path", name_or_path)
    if path.is_file():
        return path
    shipped = scenario_dir() / f"{name_or_path}.toml"
    if not shipped.is_file():
        raise ScenarioError(
            str(name_or_path),
            "",
            "no such scenario file, and not a shipped scenario; shipped: "
            + ", ".join(shipped_scenarios()),
        )
    return shipped
