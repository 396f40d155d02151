"""The per-file times that CI prints (tests/file_times.py), with and without pytest-xdist.

Two throw-away test files run in a child pytest: one waits 0.3 s, one does nothing; the table
lists both, the waiting one first and with at least its wait. The child loads no other plugin
(``PYTEST_DISABLE_PLUGIN_AUTOLOAD``), so that it starts in about a second.
"""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from file_times import TITLE

TESTS = Path(__file__).resolve().parent


def _table(tmp_path: Path, *options: str) -> dict[str, float]:
    (tmp_path / "test_slow_one.py").write_text("import time\n\ndef test_wait():\n    time.sleep(0.3)\n")
    (tmp_path / "test_quick_one.py").write_text("def test_a():\n    pass\n\ndef test_b():\n    pass\n")
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "file_times", "-q", "-p", "no:cacheprovider",
         *options, str(tmp_path)],
        capture_output=True, text=True, cwd=tmp_path, timeout=300,
        env={**os.environ, "PYTHONPATH": str(TESTS), "PYTEST_DISABLE_PLUGIN_AUTOLOAD": "1"},
    )  # fmt: skip
    assert done.returncode == 0, done.stdout + done.stderr
    text = done.stdout
    assert TITLE in text, text
    rows = re.findall(r"^\s*([0-9.]+) s\s+[0-9.]+ %\s+(\S+)$", text.split(TITLE, 1)[1], re.M)
    return {Path(path).name: float(seconds) for seconds, path in rows}


@pytest.mark.parametrize("options", [(), ("-p", "xdist.plugin", "-n", "2")], ids=["one", "xdist"])
def test_each_file_is_listed_once_slowest_first(tmp_path, options):
    table = _table(tmp_path, *options)
    assert list(table) == ["test_slow_one.py", "test_quick_one.py"], table
    assert table["test_slow_one.py"] >= 0.3


def test_every_slow_file_exists(request):
    """The quick subset's list names real files (a renamed file would silently turn quick)."""
    from conftest import SLOW_FILES

    assert SLOW_FILES
    assert sorted(name for name in SLOW_FILES if not (TESTS / name).is_file()) == []
    assert "slow" not in request.node.keywords  # this file is in the quick subset
