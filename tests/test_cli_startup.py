"""The command line answers at once: ``--help`` and a refused input load no heavy library.

The numerical libraries (Numba, Pinocchio, MuJoCo, Matplotlib, SciPy, trimesh) take seconds to
import; the package's ``__init__`` and the command's modules import them only where a
subcommand runs. Checked by the modules a fresh interpreter has loaded when the command
returns, never by a clock. Numba's cache is still keyed when Numba loads after the package.
"""

import json
import subprocess
import sys

import pytest

HEAVY = ("numba", "pinocchio", "mujoco", "matplotlib", "scipy", "trimesh", "yourdfpy")
"""Libraries that take a second or more to import on the reference machine."""

LOADED = """
import json, sys
from pbvs_pin.cli import main
try:
    status = main(sys.argv[1:])
except SystemExit as stop:
    status = stop.code
print(json.dumps({"status": status, "modules": sorted(sys.modules)}))
"""


def loaded_by(*args: str) -> tuple[int, set[str]]:
    """Exit status of ``pbvs-pin ARGS`` in a fresh interpreter, and its loaded modules' roots."""
    done = subprocess.run(
        [sys.executable, "-c", LOADED, *args], capture_output=True, text=True, timeout=120
    )
    result = json.loads(done.stdout.strip().splitlines()[-1])
    return result["status"], {name.partition(".")[0] for name in result["modules"]}


@pytest.mark.parametrize(
    ("args", "status"),
    [
        (("--help",), 0),
        (("run", "no_such_scenario"), 2),
        (("run", "experiment1", "--duration", "-1"), 2),
        (("info", "no_such_robot"), 2),
        (("reproduce", "--engines", "no_such_robot"), 2),
    ],
)
def test_help_and_refused_inputs_load_no_heavy_library(args, status):
    code, roots = loaded_by(*args)
    assert code == status
    assert not roots & set(HEAVY), f"pbvs-pin {' '.join(args)} loaded {sorted(roots & set(HEAVY))}"


def test_the_check_sees_a_heavy_import():
    """The check can fail: a command that runs a robot's model loads Pinocchio."""
    code, roots = loaded_by("info", "pioneer_cyton")
    assert code == 0
    assert "pinocchio" in roots and "numba" in roots


def test_numba_loaded_after_the_package_uses_the_keyed_cache():
    source = (
        "import pbvs_pin, sys; assert 'numba' not in sys.modules; import numba.core.config as c; "
        "print(c.CACHE_DIR == str(pbvs_pin.compile_cache.KEYED_CACHE), c.CACHE_DIR)"
    )
    done = subprocess.run([sys.executable, "-c", source], capture_output=True, text=True)
    assert done.stdout.startswith("True "), done.stdout + done.stderr
