"""A pytest plugin: at the end of a run, each test file's total time, slowest first.

Every test's setup, call and teardown durations (``report.duration``) are summed by the file of
its node id. Under pytest-xdist the workers' reports reach the controller, whose terminal
summary prints the sums; so the table is the CPU time each file took, whichever worker ran it.
``tests/conftest.py`` loads these hooks; ``pytest -p file_times`` loads them anywhere.
"""

from __future__ import annotations

from collections import defaultdict

import pytest

TITLE = "seconds per test file (setup + call + teardown, slowest first)"
"""The heading of the table."""

_SECONDS: defaultdict[str, float] = defaultdict(float)
"""Test file -> summed duration [s] of the reports seen so far."""


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """Add one phase of one test to its file's total."""
    _SECONDS[report.nodeid.partition("::")[0]] += report.duration


def pytest_terminal_summary(terminalreporter, exitstatus: int, config: pytest.Config) -> None:
    """Print the table (not on an xdist worker, whose output nobody sees)."""
    if hasattr(config, "workerinput") or not _SECONDS:
        return
    terminalreporter.write_sep("=", TITLE)
    total = sum(_SECONDS.values())
    for path, seconds in sorted(_SECONDS.items(), key=lambda item: (-item[1], item[0])):
        terminalreporter.write_line(f"{seconds:8.1f} s {100 * seconds / total:5.1f} %  {path}")
    terminalreporter.write_line(f"{total:8.1f} s in all, over {len(_SECONDS)} files")
