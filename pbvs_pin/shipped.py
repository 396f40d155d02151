"""Where the URDF files shipped with pbvs_pin live.

In a source checkout they are in the top-level ``urdf/`` folder; an installed wheel carries the
same files as the package data ``pbvs_pin.urdf``.
"""

from __future__ import annotations

from pathlib import Path

SHIPPED_URDFS = ("pioneer3at", "cyton_alpha3", "pioneer_cyton")
"""Names of the shipped URDF files (without ``.urdf``)."""


def urdf_dir() -> Path:
    """Folder holding the shipped URDF files."""
    checkout = Path(__file__).resolve().parents[1] / "urdf"
    if checkout.is_dir():
        return checkout
    return Path(__file__).resolve().parent / "urdf"


def shipped_urdf(name: str) -> Path | None:
    """Path of a shipped URDF file by name (``"pioneer3at"``), or None if not shipped."""
    if name not in SHIPPED_URDFS:
        return None
    return urdf_dir() / f"{name}.urdf"
