"""The Python code of the README and of the docs pages runs verbatim, each block in a fresh
process from an empty folder."""

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
PAGES = [REPO_ROOT / "README.md", *sorted((REPO_ROOT / "docs").glob("*.md"))]
"""The README and the Markdown pages of the documentation."""
BLOCKS = [
    block for page in PAGES for block in re.findall(r"```python\n(.*?)```", page.read_text(), re.S)
]


def run_block(code: str, folder: Path) -> str:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO_ROOT), env.get("PYTHONPATH", "")])
    result = subprocess.run(
        [sys.executable, "-c", code],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    return result.stdout


def test_getting_started_has_the_python_blocks():
    page = (REPO_ROOT / "docs" / "getting_started.md").read_text()
    found = re.findall(r"```python\n(.*?)```", page, re.S)
    assert any("features.jacobians" in block for block in found)
    assert any("pbvs_pin.simulate" in block for block in found)


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_readme_block_runs_verbatim(index, tmp_path):
    out = run_block(BLOCKS[index], tmp_path)
    if "features.jacobians" in BLOCKS[index]:
        # spheres 1 m ahead, 0.05 m above and below the optical axis, f = 600 px:
        # xi = -(f/z) [x, y] = [0, 30, -30] px
        printed = re.search(r"\[\s*(-?[0-9.]+)\s+(-?[0-9.]+)\s+(-?[0-9.]+)\s*\]", out)
        assert printed, out
        np.testing.assert_allclose([float(g) for g in printed.groups()], [0, 30, -30], atol=0.05)
    if "pbvs_pin.simulate" in BLOCKS[index]:
        assert (tmp_path / "results" / "exp1_ur5" / "log.npz").is_file()
