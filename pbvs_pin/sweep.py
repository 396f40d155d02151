"""Robustness sweeps: many runs of one scenario with some fields varied, one table of results.

A sweep spec is a TOML file::

    [sweep]
    name = "target_speed"        # optional, default: the file stem
    scenario = "experiment1"     # shipped name, or a path (relative to the spec's folder)
    seed = 1                     # per-run seeds derive from it (default 0)
    epsilon = 0.5                # eps of eq. (31) for the analysis columns
    timeout = 600.0              # wall-clock limit of one run [s]
    save_logs = false            # also write logs/<run_id>/log.npz (needs a shared disk on Dask)

    [fixed]                      # dotted scenario fields set for every run
    duration = 12.0

    [grid]                       # every combination of these values (in this order) ...
    "motion.velocity" = [[0.05, 0.02, 0.0], [0.10, 0.04, 0.0]]
    "estimator.alpha" = [0.3, 0.6]

    # ... or, instead of [grid], a random sample:
    [random]
    n = 20
    seed = 3                     # the sample's seed (default: [sweep] seed)
    "camera.noise_px" = { range = [0.0, 2.0] }               # uniform (ints: integers)
    "estimator.beta" = { range = [0.01, 0.5], log = true }   # log-uniform
    "motion.velocity" = { range = [[0.0, 0.0, 0.0], [0.2, 0.1, 0.0]] }  # per component
    "estimator.kind" = { choices = ["alpha_beta", "exact"] }

Field names are checked against the scenario schema when the spec is read (a
:class:`~pbvs_pin.exceptions.ScenarioError` names the spec file and the field); field *values*
are checked per run, so an invalid value is a failed run in the table, not a failed sweep.

**Runs and ids.** A run is its swept parameters. Its id is the first 16 hex digits of the
SHA-256 of the parameters as canonical JSON (sorted keys), so it does not depend on the
executor, on the order of completion or on other runs. Its seed (``simulation.seed``, unless
that field is swept) is derived from the spec seed and the run id, also by SHA-256. The random
sample is drawn run by run in field order, so a larger ``n`` keeps the earlier runs; a repeated
draw is one run.

**Table.** The primary output is ``results.csv``, one row per run: ``run_id``, ``status``
(``ok`` or ``failed``), ``reason`` (exception text, ``diverged: ...`` or ``timeout: ...``),
``seed``, the parameters (vectors as JSON), ``target_speed_m_s``, the analysis figures of
:mod:`pbvs_pin.analysis` and the figures of :func:`pbvs_pin.sim.metrics.summarize` (lists
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

**Executors.** A local process pool (``concurrent.futures.ProcessPoolExecutor``, workers
forked from a clean fork server that has the simulation imported, one BLAS thread each) by
default, or a Dask distributed cluster when a scheduler address is given
(``dask[distributed]`` needed). Runs are submitted a few at a time per worker
and recorded as they complete. A run's failure (exception, divergence, timeout) is recorded in
its row and the sweep goes on; a worker process that dies is replaced and its runs are retried
once, then recorded as failed. The timeout is checked by the run itself at every logged
instant, so it works on every executor.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import itertools
import json
import math
import os
import socket
import time
import tomllib
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Executor, Future, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pbvs_pin.exceptions import PbvsError, ScenarioError
from pbvs_pin.sim.scenario import SCHEMA, Scenario, load_scenario

SWEEP_DEFAULTS: dict[str, Any] = {
    "name": "",
    "scenario": None,
    "seed": 0,
    "epsilon": 0.5,
    "timeout": 600.0,
    "save_logs": False,
}
"""Keys of the ``[sweep]`` table and their defaults (``scenario`` is required)."""

LEADING_COLUMNS = ("run_id", "status", "reason", "seed")
"""First columns of the table; the parameters follow, then ``target_speed_m_s``."""

ANALYSIS_COLUMNS = (
    "lambda",
    "lambda_prime",
    "k_min",
    "t1_s",
    "gamma_inf",
    "condition_31",
    "bound39_predicted_px",
    "bound39_measured_sup_px",
    "bound39_holds",
    "l2_varsigma",
    "l2_zeta",
    "l2_measured_ratio",
    "l2_varsigma_squared",
    "l2_holds",
    "passivity9_lhs",
    "passivity9_rhs",
    "passivity9_holds",
    "passivity14_lhs",
    "passivity14_rhs",
    "passivity14_holds",
)
"""Analysis figures in the table (see :func:`pbvs_pin.analysis.analyze_log`)."""

TIMING_KEYS = ("wall_time_s", "real_time_factor")
"""Figures of ``summarize`` that depend on the machine; written to ``timings.csv``."""

TABLE = "results.csv"
TIMINGS = "timings.csv"
RETRIES_AFTER_CRASH = 1
"""How many times a run in flight when its worker process died is run again."""


def sweep_dir() -> Path:
    """Folder of the shipped sweep specs."""
    return Path(__file__).resolve().parent / "sweeps"


# ----------------------------------------------------------------------------- the spec
@dataclass(frozen=True)
class RunTask:
    """One run of a sweep, as sent to a worker.

    Attributes:
        run_id: Stable id (hash of ``params``).
        params: Swept dotted field -> value.
        seed: Simulation seed of the run.
        scenario: Base scenario with the spec's fixed values applied.
        epsilon: ``eps`` of eq. (31).
        timeout: Wall-clock limit [s].
        log_dir: Where to save the run's log (None: not saved).
    """

    run_id: str
    params: dict[str, Any]
    seed: int
    scenario: Scenario
    epsilon: float
    timeout: float
    log_dir: str | None = None


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep spec.

    Attributes:
        source: Path of the spec file.
        name: The sweep's name.
        scenario: Base scenario with the fixed values applied.
        seed: Spec seed.
        epsilon: ``eps`` of eq. (31).
        timeout: Wall-clock limit of one run [s].
        save_logs: Whether runs save their logs.
        fields: Swept fields, in spec order.
        runs: Parameters of every run, in spec order, duplicates removed.
        fingerprint: Hash of what every run shares (base, fixed values, seed, epsilon).
    """

    source: str
    name: str
    scenario: Scenario
    seed: int
    epsilon: float
    timeout: float
    save_logs: bool
    fields: tuple[str, ...]
    runs: tuple[dict[str, Any], ...]
    fingerprint: str

    def tasks(self, log_root: Path | None = None) -> list[RunTask]:
        """Every run as a task, in spec order."""
        tasks = []
        for params in self.runs:
            run_id = run_id_of(params)
            seed = params.get("simulation.seed", derive_seed(self.seed, run_id))
            log_dir = str(log_root / run_id) if log_root is not None else None
            tasks.append(
                RunTask(
                    run_id, params, int(seed), self.scenario, self.epsilon, self.timeout, log_dir
                )
            )
        return tasks


def _canonical(value: Any) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"))


def run_id_of(params: dict[str, Any]) -> str:
    """Stable id of a run: 16 hex digits of the SHA-256 of its parameters (canonical JSON)."""
    return hashlib.sha256(_canonical(params).encode()).hexdigest()[:16]


def derive_seed(spec_seed: int, run_id: str) -> int:
    """Simulation seed of a run, from the spec seed and the run id (32 bits)."""
    digest = hashlib.sha256(f"{spec_seed}/{run_id}".encode()).digest()
    return int.from_bytes(digest[:4], "little")


def load_sweep(name_or_path: str | Path) -> SweepSpec:
    """Read and validate a sweep spec (a TOML path, or a shipped spec's name).

    Raises:
        ScenarioError: Missing file, malformed TOML, unknown section, key or scenario field,
            or an invalid value; the message names the spec file and the field.
    """
    path = Path(name_or_path)
    if not path.is_file():
        shipped = sweep_dir() / f"{name_or_path}.toml"
        if not shipped.is_file():
            names = ", ".join(sorted(p.stem for p in sweep_dir().glob("*.toml")))
            raise ScenarioError(
                str(name_or_path),
                "",
                f"no such sweep spec file, and not a shipped sweep; shipped: {names}",
            )
        path = shipped
    source = str(path)
    try:
        raw = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise ScenarioError(source, "", f"not valid TOML: {err}") from err
    unknown = set(raw) - {"sweep", "fixed", "grid", "random"}
    if unknown:
        raise ScenarioError(
            source, sorted(unknown)[0], "unknown section; expected sweep, fixed, grid or random"
        )
    settings = _settings(source, raw.get("sweep", {}))
    base = _base_scenario(source, path.parent, settings["scenario"])
    fixed = _flatten(raw.get("fixed", {}))
    for field in fixed:
        _check_field(source, f"fixed.{field}", field)
    try:
        scenario = base.with_values(**fixed) if fixed else base
    except ScenarioError as err:
        raise ScenarioError(source, f"fixed.{err.field}", str(err)) from err
    if ("grid" in raw) == ("random" in raw):
        raise ScenarioError(source, "", "expected exactly one of the sections [grid], [random]")
    if "grid" in raw:
        fields, runs = _grid(source, raw["grid"])
    else:
        fields, runs = _random(source, raw["random"], settings["seed"])
    unique = list({run_id_of(p): p for p in runs}.values())
    fingerprint = hashlib.sha256(
        _canonical(
            {
                "scenario": scenario.values,
                "obstacles": list(scenario.obstacles),
                "seed": settings["seed"],
                "epsilon": settings["epsilon"],
            }
        ).encode()
    ).hexdigest()[:16]
    return SweepSpec(
        source,
        settings["name"] or path.stem,
        scenario,
        settings["seed"],
        settings["epsilon"],
        settings["timeout"],
        settings["save_logs"],
        tuple(fields),
        tuple(unique),
        fingerprint,
    )


def _settings(source: str, table: Any) -> dict[str, Any]:
    """The ``[sweep]`` table, checked and with defaults."""
    if not isinstance(table, dict):
        raise ScenarioError(source, "sweep", "expected a table")
    settings = dict(SWEEP_DEFAULTS)
    for key, value in table.items():
        if key not in SWEEP_DEFAULTS:
            raise ScenarioError(
                source, f"sweep.{key}", f"unknown key; expected one of {', '.join(SWEEP_DEFAULTS)}"
            )
        settings[key] = value
    checks: dict[str, tuple[Callable[[Any], bool], str]] = {
        "name": (lambda v: isinstance(v, str), "a string"),
        "scenario": (lambda v: isinstance(v, str) and v != "", "a scenario name or path"),
        "seed": (
            lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= 0,
            "an integer >= 0",
        ),
        "epsilon": (lambda v: _is_number(v) and 0 < v < 1, "a number in (0, 1)"),
        "timeout": (lambda v: _is_number(v) and v > 0, "a positive number of seconds"),
        "save_logs": (lambda v: isinstance(v, bool), "true or false"),
    }
    for key, (valid, expected) in checks.items():
        if not valid(settings[key]):
            raise ScenarioError(
                source, f"sweep.{key}", f"expected {expected}, got {settings[key]!r}"
            )
    settings["epsilon"] = float(settings["epsilon"])
    settings["timeout"] = float(settings["timeout"])
    return settings


def _base_scenario(source: str, folder: Path, name: str) -> Scenario:
    """The base scenario: a path relative to the spec's folder, or a shipped name."""
    relative = folder / name
    try:
        return load_scenario(relative if relative.is_file() else name)
    except ScenarioError as err:
        raise ScenarioError(source, "sweep.scenario", str(err)) from err


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


LEAF_KEYS = {"range", "choices", "log"}


def _flatten(table: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested TOML tables -> dotted keys (``motion.velocity = 1`` and ``"motion.velocity"``).

    A table holding ``range`` or ``choices`` is a leaf (a random field's distribution).
    """
    flat: dict[str, Any] = {}
    for key, value in table.items():
        dotted = f"{prefix}{key}"
        if isinstance(value, dict) and not (set(value) & LEAF_KEYS):
            flat.update(_flatten(value, f"{dotted}."))
        else:
            flat[dotted] = value
    return flat


def _check_field(source: str, where: str, field: str) -> None:
    """ScenarioError unless ``field`` is a dotted scenario field of the schema."""
    section, _, key = field.rpartition(".")
    if section not in SCHEMA or key not in SCHEMA[section]:
        fields = [f"{s}.{k}" if s else k for s, keys in SCHEMA.items() for k in keys]
        raise ScenarioError(
            source, where, f"unknown scenario field {field!r}; expected one of {', '.join(fields)}"
        )


def _grid(source: str, table: dict[str, Any]) -> tuple[list[str], list[dict[str, Any]]]:
    """Every combination of the grid's values, first field varying slowest."""
    grid = _flatten(table)
    if not grid:
        raise ScenarioError(source, "grid", "expected at least one field")
    for field, values in grid.items():
        _check_field(source, f"grid.{field}", field)
        if not isinstance(values, list) or not values:
            raise ScenarioError(
                source, f"grid.{field}", f"expected a non-empty list of values, got {values!r}"
            )
    fields = list(grid)
    runs = [dict(zip(fields, combo, strict=True)) for combo in itertools.product(*grid.values())]
    return fields, runs


def _random(
    source: str, table: dict[str, Any], spec_seed: int
) -> tuple[list[str], list[dict[str, Any]]]:
    """``n`` draws of every field, drawn run by run in field order."""
    table = dict(table)
    n = table.pop("n", None)
    seed = table.pop("seed", spec_seed)
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        raise ScenarioError(source, "random.n", f"expected a positive integer, got {n!r}")
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise ScenarioError(source, "random.seed", f"expected an integer >= 0, got {seed!r}")
    fields = _flatten(table)
    if not fields:
        raise ScenarioError(source, "random", "expected at least one field")
    samplers = {}
    for field, spec in fields.items():
        _check_field(source, f"random.{field}", field)
        samplers[field] = _sampler(source, f"random.{field}", spec)
    rng = np.random.default_rng(seed)
    runs = [{field: draw(rng) for field, draw in samplers.items()} for _ in range(n)]
    return list(fields), runs


def _sampler(source: str, where: str, spec: Any) -> Callable[[np.random.Generator], Any]:
    """A draw function for ``{range = [lo, hi], log = false}`` or ``{choices = [...]}``."""
    if not isinstance(spec, dict) or len(set(spec) & {"range", "choices"}) != 1:
        raise ScenarioError(
            source,
            where,
            f"expected a table with either range = [low, high] or choices = [...], got {spec!r}",
        )
    extra = set(spec) - LEAF_KEYS
    if extra:
        raise ScenarioError(
            source, f"{where}.{sorted(extra)[0]}", "unknown key; expected range, choices or log"
        )
    if "choices" in spec:
        choices = spec["choices"]
        if not isinstance(choices, list) or not choices:
            raise ScenarioError(source, f"{where}.choices", "expected a non-empty list")
        return lambda rng: choices[int(rng.integers(len(choices)))]
    bounds = spec["range"]
    log = spec.get("log", False)
    if not isinstance(log, bool):
        raise ScenarioError(source, f"{where}.log", f"expected true or false, got {log!r}")
    if not isinstance(bounds, list) or len(bounds) != 2:
        raise ScenarioError(source, f"{where}.range", f"expected [low, high], got {bounds!r}")
    low, high = (np.asarray(b) for b in bounds)
    if (
        low.shape != high.shape
        or low.dtype.kind not in "if"
        or high.dtype.kind not in "if"
        or not np.all(np.isfinite(low))
        or np.any(low > high)
        or (log and np.any(low <= 0))
    ):
        raise ScenarioError(
            source,
            f"{where}.range",
            f"expected [low, high] of numbers (or equal-length lists) with "
            f"low <= high{' and low > 0 (log)' if log else ''}, got {bounds!r}",
        )
    integer = low.dtype.kind == "i" and high.dtype.kind == "i" and not log

    def draw(rng: np.random.Generator) -> Any:
        if integer:
            return np.asarray(rng.integers(low, high, endpoint=True)).tolist()
        if log:
            return np.asarray(np.exp(rng.uniform(np.log(low), np.log(high)))).tolist()
        return np.asarray(rng.uniform(low, high)).tolist()

    return draw


# ----------------------------------------------------------------------------- one run
class _RunTimeout(Exception):
    """Raised inside a run (never escapes it) when it exceeds the sweep's timeout."""


class _RunDiverged(Exception):
    """Raised inside a run (never escapes it) when its configuration becomes non-finite."""


def run_one(task: RunTask) -> tuple[dict[str, Any], dict[str, Any]]:
    """Simulate and analyse one run; never raises for a failing run.

    Runs in a worker process. Its row holds ``status = "failed"`` and the reason when the
    scenario is invalid, the simulation raises, diverges, or exceeds the timeout.

    Returns:
        The table row (JSON-able scalars and lists) and the timing row.
    """
    from pbvs_pin.analysis import analyze_log
    from pbvs_pin.sim.loop import simulate
    from pbvs_pin.sim.metrics import summarize

    started = time.perf_counter()
    row: dict[str, Any] = {
        "run_id": task.run_id,
        "status": "ok",
        "reason": "",
        "seed": task.seed,
        **task.params,
    }
    timing: dict[str, Any] = {
        "run_id": task.run_id,
        "worker": f"{socket.gethostname()}:{os.getpid()}",
    }

    def watchdog(snapshot: Any) -> None:
        elapsed = time.perf_counter() - started
        if elapsed > task.timeout:
            raise _RunTimeout(
                f"timeout: {elapsed:.1f} s > {task.timeout:g} s at simulated t = {snapshot.t:.2f} s"
            )
        if not np.all(np.isfinite(snapshot.q)):
            raise _RunDiverged(f"diverged: non-finite configuration at t = {snapshot.t:.2f} s")

    try:
        changes = dict(task.params)
        changes.setdefault("simulation.seed", task.seed)
        scenario = task.scenario.with_values(**changes)
        motion = scenario["motion"]
        speed = 0.0 if motion["kind"] == "still" else float(np.linalg.norm(motion["velocity"]))
        row["target_speed_m_s"] = speed
        log = simulate(scenario, observer=watchdog)
    except (_RunTimeout, _RunDiverged) as err:
        row.update(status="failed", reason=str(err))
        log = None
    except Exception as err:  # the sweep goes on whatever a run raises
        row.update(status="failed", reason=f"{type(err).__name__}: {err}")
        log = None
    if log is not None:
        diverged = divergence(log)
        if diverged:
            row.update(status="failed", reason=f"diverged: {diverged}")
        try:
            if task.log_dir is not None:
                log.save(task.log_dir)
            row.update(_summary_columns(summarize(log), timing))
            row.update(analysis_columns(analyze_log(log, task.epsilon, source=task.run_id)))
        except Exception as err:  # the run finished: keep its row, say what is missing
            note = f"analysis: {type(err).__name__}: {err}"
            row["reason"] = "; ".join(filter(None, [row["reason"], note]))
    timing["run_wall_time_s"] = time.perf_counter() - started
    return row, timing


def divergence(log: Any) -> str | None:
    """Why a finished run counts as diverged, or None.

    Diverged: a non-finite configuration or velocity, or at the last sample the target
    behind the camera or outside the image (the feature error then exceeds the image).
    """
    for name in ("q", "v"):
        bad = ~np.all(np.isfinite(log[name]), axis=tuple(range(1, np.ndim(log[name]))))
        if np.any(bad):
            return f"non-finite {name} from t = {float(log['t'][np.argmax(bad)]):.2f} s"
    final = np.asarray(log["xi_true"][-1], dtype=float)
    if not np.all(np.isfinite(final)):
        return "target behind the camera at the end"
    camera = log.meta.get("camera", {})
    width, height = camera.get("width", math.inf), camera.get("height", math.inf)
    # xi = [u1, v1, v2], centred on the principal point
    if abs(final[0]) > width / 2 or np.any(np.abs(final[1:]) > height / 2):
        return f"target outside the image at the end (xi = {np.round(final, 1).tolist()} px)"
    return None


def _summary_columns(summary: dict[str, Any], timing: dict[str, Any]) -> dict[str, Any]:
    """``summarize`` figures as flat columns; wall-clock figures moved to ``timing``."""
    columns: dict[str, Any] = {}
    for key, value in summary.items():
        if key in TIMING_KEYS:
            timing[key] = value
        elif isinstance(value, list | tuple):
            columns.update({f"{key}_{i}": item for i, item in enumerate(value)})
        else:
            columns[key] = value
    return columns


def analysis_columns(result: dict[str, Any]) -> dict[str, Any]:
    """The table's analysis columns (:data:`ANALYSIS_COLUMNS`) from an analysis dict."""
    b39, l2 = result.get("bound_39") or {}, result.get("l2_gain_42") or {}
    p9, p14 = result["passivity_9"], result["passivity_14"]
    values = {
        "lambda": result["lambda"],
        "lambda_prime": result["lambda_prime"],
        "k_min": result["k_min"],
        "t1_s": result["t1_s"],
        "gamma_inf": result["gamma_inf"],
        "condition_31": (result.get("condition_31") or {}).get("holds"),
        "bound39_predicted_px": b39.get("predicted_px"),
        "bound39_measured_sup_px": b39.get("measured_sup_px"),
        "bound39_holds": b39.get("holds"),
        "l2_varsigma": l2.get("varsigma"),
        "l2_zeta": l2.get("zeta"),
        "l2_measured_ratio": l2.get("measured_ratio"),
        "l2_varsigma_squared": l2.get("varsigma_squared"),
        "l2_holds": l2.get("holds"),
        "passivity9_lhs": p9["lhs_integral_nu_input"],
        "passivity9_rhs": p9["rhs_minus_V1_0"],
        "passivity9_holds": p9["holds"],
        "passivity14_lhs": p14["lhs_integral_nu_sq"],
        "passivity14_rhs": p14["rhs_beta"],
        "passivity14_holds": p14["holds"],
    }
    return {column: values[column] for column in ANALYSIS_COLUMNS}


def _failed(task: RunTask, reason: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """Row of a run whose worker failed (not the run itself)."""
    row = {
        "run_id": task.run_id,
        "status": "failed",
        "reason": reason,
        "seed": task.seed,
        **task.params,
    }
    return row, {"run_id": task.run_id, "worker": "-"}


# ----------------------------------------------------------------------------- the table
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
        """Load the rows; drop a half-written last line or malformed rows, then rewrite."""
        text = self.path.read_text()
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


def _append_timing(path: Path, timing: dict[str, Any]) -> None:
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
def _exclusive(folder: Path) -> Iterator[None]:
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


def _check_folder(spec: SweepSpec, out: Path) -> None:
    """Write ``sweep.json``, or refuse a folder that holds another sweep's results."""
    meta_path = out / "sweep.json"
    if meta_path.exists():
        try:
            previous = json.loads(meta_path.read_text()).get("fingerprint")
        except (json.JSONDecodeError, AttributeError):
            previous = None
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
    meta_path.write_text(json.dumps(meta, indent=2))


# ----------------------------------------------------------------------------- executors
SINGLE_THREAD_ENVIRONMENT = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}
"""Environment of the worker processes: one BLAS thread each, as Dask's workers have. The
matrices of a run are tiny, and two processes each spinning several BLAS threads on a small
machine run twice as slowly per run (measured: 3.1 s instead of 0.8 s on 2 cores)."""


@contextlib.contextmanager
def _worker_environment() -> Iterator[None]:
    """Set :data:`SINGLE_THREAD_ENVIRONMENT` (unless the user set it) while workers spawn."""
    previous = {key: os.environ.get(key) for key in SINGLE_THREAD_ENVIRONMENT}
    for key, value in SINGLE_THREAD_ENVIRONMENT.items():
        os.environ.setdefault(key, value)
    try:
        yield
    finally:
        for key, old in previous.items():
            if old is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = old


WORKER_PRELOAD = ["pbvs_pin.sweep", "pbvs_pin.sim.loop", "pbvs_pin.analysis"]
"""Modules the fork server imports once, so that each worker starts with them loaded."""


def _process_pool(workers: int) -> Executor:
    """A pool of ``workers`` processes, forked from a clean fork server (spawned if none).

    The fork server is a fresh single-threaded interpreter (safe to fork, unlike this
    process, which may run threads) that has imported :data:`WORKER_PRELOAD`; it lives as
    long as this process, so later pools start at once.
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(WORKER_PRELOAD)
    return ProcessPoolExecutor(workers, mp_context=context)


@contextlib.contextmanager
def _dask_executor(address: str) -> Iterator[tuple[Callable[[], Executor], int]]:
    """A concurrent.futures view of a Dask cluster, and its number of worker threads."""
    try:
        from distributed import Client
    except ImportError as err:
        raise PbvsError("--scheduler needs Dask: pip install 'dask[distributed]'") from err
    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError) as err:
        raise PbvsError(f"cannot reach the Dask scheduler at {address}: {err}") from err
    try:
        threads = max(1, sum(client.nthreads().values()))
        yield (lambda: client.get_executor(pure=False)), threads
    finally:
        client.close()


def _execute(
    make_executor: Callable[[], Executor], tasks: list[RunTask], window: int
) -> Iterator[tuple[dict[str, Any], dict[str, Any]]]:
    """Run tasks with at most ``window`` in flight; yield each result as it completes.

    A broken process pool is replaced; its runs in flight are retried
    :data:`RETRIES_AFTER_CRASH` times, then recorded as failed.
    """
    queue = deque(tasks)
    crashes: dict[str, int] = {}
    executor = make_executor()
    in_flight: dict[Future, RunTask] = {}
    try:
        while queue or in_flight:
            while queue and len(in_flight) < window:
                task = queue.popleft()
                in_flight[executor.submit(run_one, task)] = task
            done, _ = wait(in_flight, return_when=FIRST_COMPLETED)
            broken = False
            for future in done:
                task = in_flight.pop(future)
                try:
                    yield future.result()
                except BrokenProcessPool:
                    broken = True
                    crashes[task.run_id] = crashes.get(task.run_id, 0) + 1
                    if crashes[task.run_id] > RETRIES_AFTER_CRASH:
                        yield _failed(task, "worker process died while running it")
                    else:
                        queue.appendleft(task)
                except Exception as err:  # infrastructure failure (e.g. Dask KilledWorker)
                    yield _failed(task, f"worker error: {type(err).__name__}: {err}")
            if broken:
                for future, task in in_flight.items():
                    future.cancel()
                    queue.appendleft(task)
                in_flight.clear()
                _shutdown(executor, wait=False)
                executor = make_executor()
    finally:
        for future in in_flight:
            future.cancel()
        _shutdown(executor, wait=not in_flight)


def _shutdown(executor: Executor, wait: bool) -> None:
    """Shut an executor down; without waiting, cancel what has not started."""
    if wait:
        executor.shutdown(wait=True)
        return
    try:
        executor.shutdown(wait=False, cancel_futures=True)
    except TypeError:  # Dask's ClientExecutor cancels without being asked
        executor.shutdown(wait=False)


# ----------------------------------------------------------------------------- the sweep
def run_sweep(
    spec: Path,
    out: Path,
    scheduler: str | None = None,
    workers: int | None = None,
    *,
    max_runs: int | None = None,
    retry_failed: bool = False,
    progress: bool = True,
) -> Path:
    """Run (or resume) a sweep; return the path of its results table (``results.csv``).

    Args:
        spec: Sweep spec (TOML path, or a shipped spec's name).
        out: Output folder (created): ``results.csv``, ``timings.csv``, ``sweep.json``,
            ``results.parquet`` (with pyarrow) and the summary plots.
        scheduler: Dask scheduler address (e.g. ``tcp://127.0.0.1:8786``); None for a local
            process pool.
        workers: Local worker processes (default: the CPU count); ignored with Dask.
        max_runs: Stop after this many new runs (the rest are left for a resume).
        retry_failed: Run again the runs recorded as failed.
        progress: Show a progress bar (tqdm) on stderr.

    Raises:
        ScenarioError: If the spec is invalid, or ``out`` holds another sweep's results.
        PbvsError: If ``workers`` is not positive, the Dask scheduler cannot be reached, or
            another sweep is writing into ``out``.
    """
    from tqdm import tqdm

    sweep = load_sweep(spec)
    if workers is not None and workers < 1:
        raise PbvsError(f"--workers: expected a positive number of processes, got {workers}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with _exclusive(out):
        _check_folder(sweep, out)
        table = ResultTable(out / TABLE)
        if retry_failed:
            table.remove({i for i, row in table.rows.items() if row.get("status") != "ok"})
        tasks = sweep.tasks(out / "logs" if sweep.save_logs else None)
        pending = [task for task in tasks if task.run_id not in table.rows]
        if max_runs is not None:
            pending = pending[: max(0, max_runs)]
        with contextlib.ExitStack() as stack:
            if scheduler:
                make_executor, threads = stack.enter_context(_dask_executor(scheduler))
                window = 2 * threads
            else:
                stack.enter_context(_worker_environment())
                count = workers or os.cpu_count() or 1
                make_executor, window = (lambda: _process_pool(count)), 2 * count
            done = sum(task.run_id in table.rows for task in tasks)
            bar = stack.enter_context(
                tqdm(
                    total=len(tasks),
                    initial=done,
                    desc=sweep.name,
                    unit="run",
                    disable=not progress,
                )
            )
            if pending:
                for row, timing in _execute(make_executor, pending, window):
                    table.append(row)
                    _append_timing(out / TIMINGS, timing)
                    bar.update(1)
                    if row["status"] != "ok":
                        bar.write(f"{row['run_id']} failed: {format_cell(row['reason'])[:200]}")
        table.finalize(sweep.fields)
        _write_parquet(table.path, out / "results.parquet")
        if table.rows:
            plot_sweep(table.path, out)
    return table.path


def _write_parquet(csv_path: Path, path: Path) -> Path | None:
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


def plot_sweep(table_path: Path, folder: Path) -> list[Path]:
    """Write the two summary plots of a sweep; return their paths.

    - ``final_error_vs_speed.png``: largest absolute feature error over the final window [px]
      against the target speed [m/s], failed runs marked.
    - ``bound_measured_vs_predicted.png``: measured sup ``||e||`` after t1 against the bound
      (39) [px], for the runs where (31) holds; the diagonal is ``measured = predicted``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = read_table(table_path)

    def numbers(rows: list[dict[str, Any]], x: str, y: str) -> tuple[list, list]:
        pairs = [(r.get(x), r.get(y)) for r in rows]
        pairs = [
            (a, b) for a, b in pairs if isinstance(a, int | float) and isinstance(b, int | float)
        ]
        return [a for a, _ in pairs], [b for _, b in pairs]

    paths = []
    fig, ax = plt.subplots(figsize=(6, 4))
    plotted = False
    for status, marker in (("ok", "o"), ("failed", "x")):
        x, y = numbers(
            [r for r in rows if r.get("status") == status],
            "target_speed_m_s",
            "max_abs_error_final_window_px",
        )
        if x:
            ax.scatter(x, y, marker=marker, label=f"{status} ({len(x)})")
            plotted = True
    if not plotted:
        ax.text(0.5, 0.5, "no run with a final error", ha="center", transform=ax.transAxes)
    ax.set_xlabel("target speed [m/s]")
    ax.set_ylabel("max |error|, final window [px]")
    ax.set_title("Final feature error vs target speed")
    ax.grid(alpha=0.3)
    if plotted:
        ax.legend(fontsize=8)
    fig.tight_layout()
    paths.append(folder / "final_error_vs_speed.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(5, 5))
    x, y = numbers(
        [r for r in rows if r.get("condition_31") is True],
        "bound39_predicted_px",
        "bound39_measured_sup_px",
    )
    if x:
        ax.loglog(x, y, "o", label=f"runs where (31) holds ({len(x)})")
        low = max(min(min(x), min(y)), 1e-6)
        high = max(max(x), max(y))
        ax.loglog([low, high], [low, high], "k--", linewidth=1, label="measured = predicted")
        ax.legend(fontsize=8)
    else:
        ax.text(0.5, 0.5, "no run where (31) holds", ha="center", transform=ax.transAxes)
    ax.set_xlabel("predicted bound (39) [px]")
    ax.set_ylabel("measured sup ||e|| after t1 [px]")
    ax.set_title("Ultimate bound: measured vs predicted")
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    paths.append(folder / "bound_measured_vs_predicted.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    return paths
