"""Numba's cache is keyed on every kernel's source: an edited kernel never runs stale code.

The fused control step compiles kernels of other modules into itself; Numba alone checks a
cached function against its own file only. These tests edit a kernel in a copy of the package.
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


def test_an_edited_inlined_kernel_is_recompiled_not_served_from_the_cache(tmp_path):
    """Warm the cache, break eq. (20)'s clamp in the copy: the next process sees the edit."""
    package = copy_package(tmp_path)
    env = {**os.environ, "PYTHONPATH": str(tmp_path), "NUMBA_CACHE_DIR": str(tmp_path / "cache")}

    def v_ref() -> np.ndarray:
        result = subprocess.run(
            [sys.executable, "-c", STEP], env=env, cwd=tmp_path, capture_output=True,
            text=True, timeout=600, check=False,
        )  # fmt: skip
        assert result.returncode == 0, result.stderr[-3000:]
        return np.array([float(x) for x in result.stdout.split()])

    before = v_ref()
    assert np.abs(before).max() > 1e-3
    kernel = package / "control" / "compensation.py"
    text = kernel.read_text()
    assert CLAMP in text
    kernel.write_text(text.replace(CLAMP, "v_ref[i] = 0.0"))
    np.testing.assert_array_equal(v_ref(), 0.0)
    assert len(list((tmp_path / "cache").iterdir())) == 2  # one keyed cache per source
