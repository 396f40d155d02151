"""Numba's cache is keyed on every kernel's source: an edited kernel never runs stale code.

The fused control step compiles kernels of other modules into itself; Numba alone checks a
cached function against its own file only. These tests edit a kernel in a copy of the package,
and check the notice a cold cache prints (one cold compile of the simulator's kernels, one of
the controller's after the edit).
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from pbvs_pin import compile_cache
from pbvs_pin.compile_cache import cache_key, kernel_modules

REPO_ROOT = Path(__file__).resolve().parents[1]
CLAMP = "v_ref[i] = min(max(value, -limits[i]), limits[i])"
"""A line of eq. (20)'s kernel, which the fused step inlines from another module."""

NOTICE = """
import sys
from pbvs_pin.compile_cache import announce_compiles, kernels_cached
announcing = announce_compiles(stream=sys.stdout)  # kept: it listens to the end
announcing.__enter__()
"""
SIMULATE = """
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
simulate(load_scenario("experiment1").with_values(duration=0.1))
print("warm after run:", kernels_cached())
"""
STEP = """
import numpy as np, pbvs_pin
robot = pbvs_pin.load_robot("pioneer_cyton")
control = pbvs_pin.Controller(robot, pbvs_pin.ControllerSettings(), announce=False)
q = robot.home()
points = np.array([[40.0, 80.0], [40.0, -40.0]])
command = control.step(0.0, q, np.zeros(robot.n), pbvs_pin.CameraFrame.seen(0.0, points, [0.5, 0.5]))
print(" ".join(repr(float(x)) for x in command.v_ref))
"""


def copy_package(tmp_path: Path) -> Path:
    """The package copied (with its URDF folder) under ``tmp_path``; its folder."""
    package = tmp_path / "pbvs_pin"
    shutil.copytree(REPO_ROOT / "pbvs_pin", package, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(REPO_ROOT / "urdf", package / "urdf")
    return package


def test_the_key_covers_every_kernel_module_and_nothing_else(tmp_path):
    package = copy_package(tmp_path)
    key = cache_key(package)
    assert key == cache_key(Path(compile_cache.__file__).parent)
    assert package / "control" / "compensation.py" in kernel_modules(package)
    assert package / "control" / "step.py" in kernel_modules(package)
    cli = package / "cli.py"
    cli.write_text(cli.read_text() + "\n# an edit outside the kernels\n")
    assert cache_key(package) == key
    kernel = package / "control" / "compensation.py"
    kernel.write_text(kernel.read_text() + "\n# any edit of a kernel module\n")
    assert cache_key(package) != key


def test_a_cold_cache_is_announced_warmed_and_an_edited_kernel_recompiled(tmp_path):
    """One compile notice with a cold cache and none once the run warmed it; then eq. (20)'s
    clamp broken in the copy: the notice again, and the next process runs the edit."""
    package = copy_package(tmp_path)
    env = {**os.environ, "PYTHONPATH": str(tmp_path), "NUMBA_CACHE_DIR": str(tmp_path / "cache")}

    def run(script: str) -> tuple[list[str], np.ndarray]:
        """The script's output lines, and ``v_ref`` from its last line."""
        result = subprocess.run(
            [sys.executable, "-c", NOTICE + script], env=env, cwd=tmp_path,
            capture_output=True, text=True, timeout=600, check=False,
        )  # fmt: skip
        assert result.returncode == 0, result.stderr[-3000:]
        lines = result.stdout.splitlines()
        return lines, np.array([float(x) for x in lines[-1].split()])

    cold, before = run(SIMULATE + STEP)
    assert cold[0].startswith("compiling the control kernels (once, about ")
    assert "warm after run: True" in cold
    assert np.abs(before).max() > 1e-3
    warm, again = run(SIMULATE + STEP)
    assert not any("compiling" in line for line in warm)
    np.testing.assert_array_equal(again, before)
    kernel = package / "control" / "compensation.py"
    text = kernel.read_text()
    assert CLAMP in text
    kernel.write_text(text.replace(CLAMP, "v_ref[i] = 0.0"))
    edited, after = run(STEP)
    assert edited[0].startswith("compiling the control kernels")
    np.testing.assert_array_equal(after, 0.0)
    assert len(list((tmp_path / "cache").iterdir())) == 2  # one keyed cache per source
