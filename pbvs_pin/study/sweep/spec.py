"""The sweep spec: a TOML file read and validated into a :class:`SweepSpec` of run tasks.

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

The run parameters of ``[grid]`` and ``[random]`` are drawn by :mod:`pbvs_pin.study.sweep.sampling`.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pbvs_pin.exceptions import ScenarioError
from pbvs_pin.sim.scenario import Scenario, load_scenario
from pbvs_pin.study.sweep.sampling import check_field, flatten, grid_runs, random_runs
from pbvs_pin.validation import as_path, read_toml

SWEEP_DEFAULTS: dict[str, Any] = {
    "name": "",
    "scenario": None,
    "seed": 0,
    "epsilon": 0.5,
    "timeout": 600.0,
    "save_logs": False,
}
"""Keys of the ``[sweep]`` table and their defaults (``scenario`` is required)."""

SWEEP_KEY_DOCS: dict[str, str] = {
    "name": "The sweep's name; the file's stem when empty.",
    "scenario": "Base scenario: a shipped name, or a path relative to the spec's folder.",
    "seed": "Spec seed (integer >= 0); each run's simulation seed derives from it.",
    "epsilon": "eps of eq. (31), in (0, 1), for the analysis columns.",
    "timeout": "Wall-clock limit of one run [s]; a run over it is a failed row.",
    "save_logs": "Also write logs/<run_id>/log.npz (needs a shared disk on Dask).",
}
"""What each key of the ``[sweep]`` table means (for the key reference)."""

SWEEP_TABLE_DOCS: dict[str, str] = {
    "fixed": "Dotted scenario fields set for every run, e.g. ``duration = 12.0``.",
    "grid": "Dotted scenario field -> list of values; every combination is a run.",
    "random": (
        "``n`` runs (``seed``: the sample's seed, the spec seed by default) drawing each "
        "dotted scenario field from ``{ range = [low, high] }`` (uniform; integers for "
        "integer bounds; per component for arrays), ``{ range = [low, high], log = true }`` "
        "(log-uniform) or ``{ choices = [...] }``."
    ),
}
"""What the ``[fixed]``, ``[grid]`` and ``[random]`` tables hold (exactly one of the last two)."""


def sweep_dir() -> Path:
    """Folder of the shipped sweep specs."""
    return Path(__file__).resolve().parent / "specs"


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
    path = as_path("name_or_path", name_or_path)
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
    raw = read_toml(path, "a sweep spec")
    unknown = set(raw) - {"sweep", "fixed", "grid", "random"}
    if unknown:
        raise ScenarioError(
            source, sorted(unknown)[0], "unknown section; expected sweep, fixed, grid or random"
        )
    settings = _settings(source, raw.get("sweep", {}))
    base = _base_scenario(source, path.parent, settings["scenario"])
    fixed = flatten(raw.get("fixed", {}))
    for field in fixed:
        check_field(source, f"fixed.{field}", field)
    try:
        scenario = base.with_values(**fixed) if fixed else base
    except ScenarioError as err:
        raise ScenarioError(source, f"fixed.{err.field}", str(err)) from err
    if ("grid" in raw) == ("random" in raw):
        raise ScenarioError(source, "", "expected exactly one of the sections [grid], [random]")
    if "grid" in raw:
        fields, runs = grid_runs(source, raw["grid"])
    else:
        fields, runs = random_runs(source, raw["random"], settings["seed"])
    unique = list({run_id_of(p): p for p in runs}.values())
    fingerprint = hashlib.sha256(
        _canonical(
            {
                "scenario": scenario.to_toml(),
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
