"""The results folder: ``results.csv`` and ``timings.csv``, its lock and its ``sweep.json``.

**Table.** The primary output is ``results.csv``, one row per run: ``run_id``, ``status``
(``ok`` or ``failed``), ``reason`` (exception text, ``diverged: ...`` or ``timeout: ...``),
``seed``, the parameters (vectors as JSON), ``target_speed_m_s``, the analysis figures of
:mod:`pbvs_pin.study.analysis` and the figures of :func:`pbvs_pin.sim.metrics.summarize` (lists
flattened to ``name_0, name_1, ...``). CSV is primary because it can be appended one line at
a time (each line is flushed and fsync'ed as its run finishes), so an interrupted sweep loses
nothing; it needs no extra package and any tool reads it. Floats are written with ``repr``
(exact round trip). When the sweep ends, the table is rewritten sorted by run id with a fixed
column order, so the same spec gives the same file on any executor; wall-clock figures, which
are not reproducible, go to ``timings.csv`` instead. ``results.parquet`` (typed columns) is
written from it when pyarrow is installed, with two summary plots.

**Resume.** Running the same spec into the same folder skips every run already in the table
(ok or failed) and appends the rest; a half-written last line (a killed writer) is dropped.
``sweep.json`` holds a fingerprint of what every run shares (base scenario, fixed values,
seed, epsilon); a spec that changes it is refused for that folder, while adding grid values
or random draws is allowed. Rows are keyed by parameters, not by the version of the code:
after changing the simulation, sweep into a new folder (or pass ``retry_failed`` to run the
failed runs again).
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from pbvs_pin.exceptions import OutputError, PbvsError, ScenarioError
from pbvs_pin.study.sweep.runner import ANALYSIS_COLUMNS, TIMING_KEYS
from pbvs_pin.study.sweep.spec import SweepSpec

LEADING_COLUMNS = ("run_id", "status", "reason", "seed")
"""First columns of the table; the parameters follow, then ``target_speed_m_s``."""

TABLE = "results.csv"
TIMINGS = "timings.csv"


def format_cell(value: Any) -> str:
    """A CSV cell: '' for None or non-finite, ``repr`` for floats, JSON for lists."""
    if value is None:
        return ""
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, float | np.floating):
        return repr(float(value)) if math.isfinite(value) else ""
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, list | tuple | dict):
        return json.dumps(value)
    return " ".join(str(value).split())[:500]


class ResultTable:
    """``results.csv``: one row per run, appended line by line, keyed by run id.

    Args:
        path: The CSV file (created on the first row).
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.columns: list[str] = []
        self.rows: dict[str, dict[str, str]] = {}
        if path.exists():
            self._read()

    def _read(self) -> None:
        """Load the rows; drop a half-written last line or malformed rows, then rewrite.

        Raises:
            OutputError: If the table is not a readable UTF-8 file (a folder, binary data).
        """
        try:
            text = self.path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as err:
            raise OutputError(
                str(self.path),
                f"is not a readable results table ({getattr(err, 'strerror', None) or err}); "
                "move it away or use another output folder",
            ) from err
        repaired = bool(text) and not text.endswith("\n")
        if repaired:
            text = text[: text.rfind("\n") + 1]
        reader = csv.reader(io.StringIO(text))
        header = next(reader, None) or []
        self.columns = list(header)
        count = 0
        for fields in reader:
            count += 1
            if len(fields) != len(header) or "run_id" not in header:
                repaired = True
                continue
            row = dict(zip(header, fields, strict=True))
            self.rows[row["run_id"]] = row
        if repaired or count != len(self.rows):
            self._rewrite(self.columns)

    def append(self, row: dict[str, Any]) -> None:
        """Add one run's row and make it durable (flush and fsync)."""
        cells = {key: format_cell(value) for key, value in row.items()}
        self.rows[cells["run_id"]] = cells
        new = [key for key in cells if key not in self.columns]
        if new or not self.path.exists():
            self._rewrite(self.columns + new)
            return
        with self.path.open("a", newline="") as handle:
            csv.writer(handle, lineterminator="\n").writerow(
                [cells.get(c, "") for c in self.columns]
            )
            handle.flush()
            os.fsync(handle.fileno())

    def remove(self, run_ids: set[str]) -> None:
        """Drop rows (e.g. failed runs to retry)."""
        for run_id in run_ids:
            self.rows.pop(run_id, None)
        self._rewrite(self.columns)

    def _rewrite(self, columns: list[str]) -> None:
        """Write the whole table atomically (temporary file, then rename), rows by run id."""
        self.columns = columns
        temporary = self.path.with_suffix(".csv.tmp")
        with temporary.open("w", newline="") as handle:
            writer = csv.writer(handle, lineterminator="\n")
            writer.writerow(columns)
            for run_id in sorted(self.rows):
                writer.writerow([self.rows[run_id].get(c, "") for c in columns])
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, self.path)

    def finalize(self, params: tuple[str, ...]) -> None:
        """Rewrite sorted by run id, columns in the canonical order (see the module doc)."""
        first = [*LEADING_COLUMNS, *params, "target_speed_m_s", *ANALYSIS_COLUMNS]
        present = set(self.columns) | {c for row in self.rows.values() for c in row}
        rest = sorted(present - set(first))
        self._rewrite([c for c in first if c in present] + rest)


def append_timing(path: Path, timing: dict[str, Any]) -> None:
    """Append one run's wall-clock row to ``timings.csv`` (header first if the file is new)."""
    columns = ["run_id", "worker", "run_wall_time_s", *TIMING_KEYS]
    new = not path.exists() or path.stat().st_size == 0
    torn = not new and path.read_bytes()[-1:] != b"\n"
    with path.open("a", newline="") as handle:
        if torn:  # a line cut by a killed writer: end it, so that this row stays whole
            handle.write("\n")
        writer = csv.writer(handle, lineterminator="\n")
        if new:
            writer.writerow(columns)
        writer.writerow([format_cell(timing.get(c)) for c in columns])


@contextlib.contextmanager
def exclusive(folder: Path) -> Iterator[None]:
    """Hold ``folder/.lock`` so that two sweeps never write the same table (POSIX only)."""
    try:
        import fcntl
    except ImportError:  # no advisory locks on this platform
        yield
        return
    with (folder / ".lock").open("w") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            raise PbvsError(f"{folder}: another sweep is writing into this folder") from err
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def check_folder(spec: SweepSpec, out: Path, force: bool = False) -> None:
    """Write ``sweep.json``, or refuse a folder that holds another sweep's results.

    A folder with results (``results.csv`` or ``timings.csv``) whose ``sweep.json`` is
    missing or unreadable cannot be told apart from another sweep's: it is refused unless
    ``force``, which adopts it for ``spec``.

    Raises:
        ScenarioError: Naming the spec and the folder.
        OutputError: If ``sweep.json`` cannot be written (e.g. a folder of that name).
    """
    meta_path = out / "sweep.json"
    has_results = any((out / name).exists() for name in (TABLE, TIMINGS))
    previous = None
    if meta_path.exists():
        try:
            previous = json.loads(meta_path.read_text()).get("fingerprint")
        except (OSError, UnicodeDecodeError, json.JSONDecodeError, AttributeError):
            previous = None
        if previous is None and not force:
            raise ScenarioError(
                spec.source,
                "",
                f"{meta_path} is unreadable or holds no fingerprint, so the results in {out} "
                "cannot be matched to this spec; use another output folder, or --force "
                "(force=True) to adopt them",
            )
    elif has_results and not force:
        raise ScenarioError(
            spec.source,
            "",
            f"{out} holds results but no sweep.json, so they cannot be matched to this spec; "
            "use another output folder, or --force (force=True) to adopt them",
        )
    if previous is not None and previous != spec.fingerprint:
        raise ScenarioError(
            spec.source,
            "",
            f"{out} holds results of a sweep with another "
            "base scenario, fixed values, seed or epsilon; use another "
            "output folder",
        )
    meta = {
        "name": spec.name,
        "spec": spec.source,
        "fingerprint": spec.fingerprint,
        "scenario": spec.scenario.source,
        "seed": spec.seed,
        "epsilon": spec.epsilon,
        "fields": list(spec.fields),
        "runs": len(spec.runs),
    }
    try:
        meta_path.write_text(json.dumps(meta, indent=2))
    except OSError as err:
        raise OutputError(str(meta_path), f"cannot be written ({err.strerror or err})") from err


def write_parquet(csv_path: Path, path: Path) -> Path | None:
    """Typed copy of the table (if pyarrow is installed); return its path."""
    try:
        import pyarrow.csv
        import pyarrow.parquet
    except ImportError:
        return None
    options = pyarrow.csv.ConvertOptions(strings_can_be_null=True)
    pyarrow.parquet.write_table(pyarrow.csv.read_csv(csv_path, convert_options=options), path)
    return path


def read_table(path: Path) -> list[dict[str, Any]]:
    """Rows of a results table, numbers parsed (empty cells become None)."""

    def parse(cell: str) -> Any:
        if cell == "":
            return None
        if cell in ("true", "false"):
            return cell == "true"
        try:
            return json.loads(cell)
        except json.JSONDecodeError:
            return cell

    with Path(path).open(newline="") as handle:
        return [{k: parse(v) for k, v in row.items()} for row in csv.DictReader(handle)]
