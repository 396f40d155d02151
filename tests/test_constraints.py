"""The library versions the published figures were measured with (``constraints.txt``).

The figure tests (``test_readme_numbers*.py``, the results tables) compare fresh runs with the
docs to the printed digit, and a new Pinocchio or MuJoCo moves the figures by a few per cent
(Pinocchio 4.1 and MuJoCo 4.0 did, by up to 3 %). The README's commands install with
``-c constraints.txt``; this test names the package at fault when an environment differs,
instead of leaving a dozen figure tests to fail on their own.
"""

from __future__ import annotations

from importlib.metadata import version

import pytest
from conftest import REPO_ROOT

NUMERIC_STACK = ("pin", "mujoco", "numpy", "scipy", "numba", "eigenpy", "coal")
"""The packages whose version moves a figure: kinematics, dynamics, the plant, the arithmetic."""


def pinned() -> dict[str, str]:
    """``constraints.txt`` as {distribution: version}."""
    pins = {}
    for line in (REPO_ROOT / "constraints.txt").read_text().splitlines():
        if line and not line.startswith("#"):
            name, _, exact = line.partition("==")
            assert exact, f"constraints.txt: {line!r} is not NAME==VERSION"
            pins[name.lower().replace("_", "-")] = exact
    return pins


def test_the_constraints_pin_the_numeric_stack_and_every_runtime_dependency():
    pins = pinned()
    runtime = ("example-robot-data-loaders", "yourdfpy", "opencv-python-headless")
    for name in (*NUMERIC_STACK, *runtime):
        assert name in pins, f"constraints.txt does not pin {name}"


@pytest.mark.parametrize("name", NUMERIC_STACK)
def test_the_installed_version_is_the_one_the_figures_were_measured_with(name):
    assert version(name) == pinned()[name], (
        f"{name} {version(name)} is installed; the docs' figures were measured with "
        f"{pinned()[name]}: install with `pip install -c constraints.txt ...` (README)"
    )
