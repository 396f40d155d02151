r"""Mutation testing of the control law, the estimator, the upright row, the prediction, the servo.

Runs `cosmic-ray <https://cosmic-ray.readthedocs.io>`_ (``pip install -e '.[mutation]'``) on
one module at a time, each with the focused unit tests that exercise it, and prints the counts
and the surviving mutants (docs/mutation.md has the measured run and what became of each
survivor)::

    python tools/mutation.py                       # every module, the documented sample
    python tools/mutation.py estimation upright    # some modules only
    python tools/mutation.py --list                # count the mutants, run nothing
    python tools/mutation.py --report              # counts and survivors of the last run

The mutants are cosmic-ray's operators restricted to the functions of :data:`MODULES` (their
bodies, docstrings and decorators excluded) with the operators of :data:`EXCLUDED_OPERATORS`
left out. A module with a ``sample`` runs that many mutants drawn with ``random.Random(SEED)``
from the sorted list of its mutants; the others run every mutant. Tests run with
``NUMBA_DISABLE_JIT=1``: each mutant would otherwise recompile the kernels for about a minute
(numba keys its cache on the sources), and the kernels run the same as Python. cosmic-ray
mutates the module's file on disk and restores it after each mutant; the sessions (SQLite)
are kept in ``results/mutation/`` (git-ignored).
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import random
import re
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "mutation"
COSMIC_RAY = str(Path(sys.executable).with_name("cosmic-ray"))
SEED = 24
"""Seed of the sample drawn from a module's mutants (issue 24)."""
TIMEOUT = 120.0
"""Seconds after which a mutant's tests count as killed by timeout (a clean run takes < 30)."""

EXCLUDED_OPERATORS = (
    # a float operand makes these a TypeError on the first call: killed by any test that
    # reaches the line, so they only inflate the score
    r"core/ReplaceBinaryOperator_.*_(FloorDiv|Mod|BitOr|BitAnd|BitXor|LShift|RShift)$",
    r"core/ReplaceComparisonOperator_.*_(In|NotIn)$",
    # the decorators are njit (a no-op with NUMBA_DISABLE_JIT) and dataclass/property
    r"core/RemoveDecorator",
    # draw random names: not reproducible
    r"core/VariableInserter",
    r"core/VariableReplacer",
)


@dataclass(frozen=True)
class Module:
    """One module under mutation: which functions, which tests, how many mutants."""

    path: str
    functions: tuple[str, ...]
    tests: tuple[str, ...]
    sample: int | None = None


_CONTROLLER = (
    "tests/test_controller.py",
    "--deselect",
    "tests/test_controller.py::test_a_built_controller_has_compiled_its_step",
)

MODULES = {
    "kinematic": Module(
        "pbvs_pin/control/kinematic.py",
        (
            "storage_function",
            "saturate",
            "damped_pseudo_inverse",
            "passivity_law",
            "law_output",
            "PassivityController.__init__",
            "PassivityController.step",
            "PassivityController._row",
            "PassivityController.feature_gains",
        ),
        ("tests/test_control.py", *_CONTROLLER),
        sample=50,
    ),
    "gains": Module(
        "pbvs_pin/control/gains.py",
        ("ServoGains.weight_inverse", "ServoGains.expand"),
        ("tests/test_control.py", *_CONTROLLER),
        sample=50,
    ),
    "estimation": Module(
        "pbvs_pin/perception/estimation.py",
        (
            "AlphaBetaFilter.__init__",
            "AlphaBetaFilter.reset",
            "AlphaBetaFilter.from_tracking_index",
            "AlphaBetaFilter.update",
        ),
        ("tests/test_estimation.py",),
        sample=100,
    ),
    "upright": Module(
        "pbvs_pin/control/upright.py",
        (
            "upright_angle",
            "upright_row",
            "upright_null_space",
            "loop_gain_factor",
            "delayed_margin",
        ),
        ("tests/test_upright.py", "-k", "not 1- and not fused"),
        sample=35,
    ),
    "tracking": Module(
        "pbvs_pin/control/tracking.py",
        (
            "TargetTracker.__init__",
            "TargetTracker.take",
            "TargetTracker.current",
            "TargetTracker.predicted",
            "TargetTracker.forget",
        ),
        (
            *_CONTROLLER,
            "tests/test_prediction.py::test_latency_compensation_brings_the_frame_up_to_now",
            "tests/test_prediction.py::test_with_a_hold_a_frame_older_than_it_is_not_used",
            "tests/test_prediction.py::test_tracker_smoothing_is_the_first_order_filter_of_its_definition",
            "tests/test_prediction.py::test_tracker_uses_a_frame_until_the_hold_then_nothing",
        ),
        sample=30,
    ),
    "servo": Module(
        "pbvs_pin/model/servo.py",
        (
            "scheduled_stiffness",
            "ServoModel.from_robot",
            "ServoModel.gravity_weight",
            "ServoModel.loop_gain_coefficients",
            "ServoModel.reference_model",
            "pack_servos",
            "servo_constants",
            "packed_servo_step",
            "servo_step",
        ),
        ("tests/test_servo.py", "-k", "not tiago and not requested_platform"),
        sample=40,
    ),
}
"""The modules, the functions mutated in each, the tests run on each mutant."""


def function_lines(path: Path, names: tuple[str, ...]) -> list[tuple[int, int]]:
    """Line ranges of the named functions' bodies, without their docstrings."""
    tree = ast.parse(path.read_text())
    found: dict[str, tuple[int, int]] = {}

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            elif isinstance(child, ast.FunctionDef):
                body = child.body
                if isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                    body = body[1:]
                if not body:
                    continue
                found[prefix + child.name] = (body[0].lineno, child.end_lineno or body[0].lineno)

    visit(tree, "")
    missing = [name for name in names if name not in found]
    if missing:
        raise SystemExit(f"{path}: no function {missing}")
    return [found[name] for name in names]


def test_command(module: Module) -> str:
    """The command cosmic-ray runs on each mutant."""
    tests = (f"'{test}'" if " " in test else test for test in module.tests)
    pytest = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider"]
    return " ".join([*pytest, *tests])


def write_config(name: str, module: Module) -> Path:
    """The module's cosmic-ray configuration, written to results/mutation/NAME.toml."""
    OUT.mkdir(parents=True, exist_ok=True)
    config = OUT / f"{name}.toml"
    config.write_text(
        "[cosmic-ray]\n"
        f'module-path = "{module.path}"\n'
        f"timeout = {TIMEOUT}\n"
        "excluded-modules = []\n"
        f'test-command = "{test_command(module)}"\n'
        "[cosmic-ray.distributor]\n"
        'name = "local"\n'
    )
    return config


def init(name: str, module: Module, session: Path) -> None:
    """A fresh session at ``session`` of the module's mutants in scope, sampled."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import WorkerOutcome, WorkResult

    config = write_config(name, module)
    session.unlink(missing_ok=True)
    subprocess.run([COSMIC_RAY, "init", str(config), str(session)], cwd=ROOT, check=True)
    excluded = [re.compile(pattern) for pattern in EXCLUDED_OPERATORS]
    ranges = function_lines(ROOT / module.path, module.functions)
    with use_db(str(session), WorkDB.Mode.open) as db:
        keep, skip = [], []
        for item in db.pending_work_items:
            mutation = item.mutations[0]
            line = mutation.start_pos[0]
            inside = any(start <= line <= end for start, end in ranges)
            operator_ok = not any(p.search(mutation.operator_name) for p in excluded)
            (keep if inside and operator_ok else skip).append(item)
        print(f"{name}: {len(keep)} mutants in scope, sample {module.sample}", flush=True)
        if module.sample is not None and len(keep) > module.sample:
            keep.sort(key=lambda item: _key(item))
            chosen = set(id(item) for item in random.Random(SEED).sample(keep, module.sample))
            skip += [item for item in keep if id(item) not in chosen]
        if skip:
            db.set_multiple_results(
                [item.job_id for item in skip],
                WorkResult(output="out of scope or sample", worker_outcome=WorkerOutcome.SKIPPED),
            )


def _key(item) -> tuple:
    """A mutant's identity independent of cosmic-ray's random job ids."""
    mutation = item.mutations[0]
    return (mutation.start_pos, mutation.operator_name, mutation.occurrence)


def report(module: Module) -> dict:
    """Counts and survivors of a module's session."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome

    name = next(key for key, value in MODULES.items() if value == module)
    session = OUT / f"{name}.sqlite"
    counts = {"mutants": 0, "killed": 0, "survived": 0, "timeout": 0, "pending": 0}
    survivors, survived_jobs = [], []
    # the committed source: during a run the file on disk holds the current mutant
    source = subprocess.run(["git", "show", f"HEAD:{module.path}"], cwd=ROOT, capture_output=True)
    lines = source.stdout.decode().splitlines()
    with use_db(str(session), WorkDB.Mode.open) as db:
        results = dict(db.results)
        for item in sorted(db.work_items, key=_key):
            result = results.get(item.job_id)
            if result is not None and result.worker_outcome == WorkerOutcome.SKIPPED:
                continue
            counts["mutants"] += 1
            if result is None:
                counts["pending"] += 1
            elif result.output == "timeout":
                counts["timeout"] += 1
            elif result.test_outcome == TestOutcome.KILLED or result.is_killed:
                counts["killed"] += 1
            else:
                counts["survived"] += 1
                survived_jobs.append(item.job_id)
                mutation = item.mutations[0]
                line = mutation.start_pos[0]
                survivors.append(
                    f"{module.path}:{line} {mutation.operator_name} #{mutation.occurrence}"
                    f"  | {lines[line - 1].strip()}"
                )
    return {"counts": counts, "survivors": survivors, "survived_jobs": survived_jobs}


def rerun_survivors(name: str) -> None:
    """Run the survivors of the module's last run again, with the tests as they are now."""
    import sqlite3

    session = OUT / f"{name}.sqlite"
    survived = report(MODULES[name])["survived_jobs"]
    with sqlite3.connect(session) as db:
        db.executemany("DELETE FROM work_results WHERE job_id = ?", [(j,) for j in survived])


def execute(name: str, module: Module) -> None:
    """Check that the tests pass unmutated, then run the session's pending mutants."""
    start = time.monotonic()
    clean = subprocess.run(shlex.split(test_command(module)), cwd=ROOT)
    if clean.returncode:
        raise SystemExit(f"{name}: the tests fail without a mutant")
    print(f"{name}: clean run {time.monotonic() - start:.1f} s", flush=True)
    config = write_config(name, module)
    subprocess.run([COSMIC_RAY, "exec", str(config), str(OUT / f"{name}.sqlite")], cwd=ROOT)
    if subprocess.run(["git", "diff", "--quiet", "--", module.path], cwd=ROOT).returncode:
        raise SystemExit(f"{module.path} left mutated: git checkout it")


def main() -> None:
    """Run (or list, or report) the modules named on the command line, all by default."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("modules", nargs="*", help=f"some of {', '.join(MODULES)}")
    parser.add_argument("--list", action="store_true", help="count the mutants, run nothing")
    parser.add_argument("--report", action="store_true", help="report the last run")
    parser.add_argument(
        "--rerun", action="store_true", help="run the last run's survivors again (new tests)"
    )
    args = parser.parse_args()
    names = args.modules or list(MODULES)
    unknown = set(names) - set(MODULES)
    if unknown:
        parser.error(f"unknown modules {sorted(unknown)}; expected some of {list(MODULES)}")
    os.environ["NUMBA_DISABLE_JIT"] = "1"
    os.environ["PYTHONPATH"] = str(ROOT)
    for name in names:
        module = MODULES[name]
        stage = "last"
        if args.rerun:
            (OUT / f"{name}.first.json").write_text(json.dumps(report(module), indent=1))
            rerun_survivors(name)
            execute(name, module)
            stage = "rerun"
        elif args.list:  # a scratch session: never the one a run may be using
            init(name, module, OUT / f"{name}.list.sqlite")
            continue
        elif not args.report:
            init(name, module, OUT / f"{name}.sqlite")
            execute(name, module)
            stage = "first"
        summary = report(module)
        if stage != "last":
            (OUT / f"{name}.{stage}.json").write_text(json.dumps(summary, indent=1))
        print(name, summary["counts"], flush=True)
        for line in summary["survivors"]:
            print("  ", line)


if __name__ == "__main__":
    main()
