"""The robot zoo: the paper's four experiments on every robot file of a folder, on both plants.

Each robot is a TOML file with a ``[robot]`` table, written as a user would write it (the
repository's ``robots/`` folder holds robots from several PyPI packages of robot descriptions).
:func:`run_zoo` runs each robot through Experiments 1-4 on the Pinocchio and the MuJoCo plants with
the shipped gains, in a process pool, and keeps each run's summary in
``<out>/<robot>/<experiment>_<engine>.json`` (a summary already there is not run again).
:func:`zoo_table` writes them as the reStructuredText page ``docs/zoo.rst``: per robot its package,
degrees of freedom and joint types, and per experiment and plant the max error over the last 5 s,
the target-lost samples, the largest excursion past a joint limit, the oscillation RMS, the share
of samples where the loop-gain net cut the gains, and whether the run meets the paper's claim by
its experiment's rule (:data:`pbvs_pin.study.claims.CLAIMS`): ``yes``, ``**no**`` with the failed
clauses' names, or ``not judged`` for a run too short for the rule (``--duration`` under 7 s). Each
run's verdict is printed as its robot finishes (:func:`progress_line`).

Run it with ``pbvs-pin zoo robots --out zoo_results --page docs/zoo.rst``.
"""

from __future__ import annotations

import argparse
import json
import re
import site
import sysconfig
import time
import warnings
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from importlib.metadata import packages_distributions
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pbvs_pin.exceptions import PbvsError, PbvsWarning
from pbvs_pin.model.shipped import urdf_dir
from pbvs_pin.outputs import Output
from pbvs_pin.study.claims import failed, judge, verdict_text
from pbvs_pin.study.report import rst_row
from pbvs_pin.validation import read_toml

if TYPE_CHECKING:  # the command's arguments load without Pinocchio (pbvs-pin --help)
    from pbvs_pin.model.robot import MobileManipulator

EXPERIMENTS = ("experiment1", "experiment2", "experiment3", "experiment4")
"""The paper's experiments, as shipped scenarios."""

ENGINES = ("pinocchio", "mujoco")
"""The plants every robot runs on."""

SHIPPED_PACKAGE = "pbvs_pin"
"""Package named for a robot the project ships its URDF of."""


@dataclass(frozen=True)
class ZooRobot:
    """One robot file of the zoo.

    Attributes:
        name: The file's stem.
        path: The TOML file.
        table: Its ``[robot]`` table.
    """

    name: str
    path: Path
    table: dict[str, Any]

    @property
    def package(self) -> str:
        """The PyPI package that ships the robot's URDFs (each distinct one, joined by +)."""
        sources = [self.table.get(key, "") for key in ("urdf", "base", "arm", "name")]
        return " + ".join(dict.fromkeys(_package_of(s) for s in sources if s))

    @property
    def scenario_values(self) -> dict[str, Any]:
        """The robot as scenario keys (``robot.<key>``), replacing a scenario's own robot."""
        values = {f"robot.{key}": value for key, value in self.table.items()}
        return {"robot.name": "", **values}


def _package_of(source: str) -> str:
    """The distribution a ``[robot]`` URDF source (or shipped robot name) comes from."""
    from pbvs_pin.bringup.catalogue import RECIPES, REFERENCE_ROBOT
    from pbvs_pin.model.assembly import PACKAGE_PREFIX

    if source.startswith(PACKAGE_PREFIX):
        module = source[len(PACKAGE_PREFIX) :].split("/", 1)[0]
        name = packages_distributions().get(module, [module])[0]
        return re.sub(r"[-_.]+", "-", name).lower()  # as pip names it (PEP 503): fetch-planning
    if source == REFERENCE_ROBOT:
        return SHIPPED_PACKAGE
    if source in RECIPES:
        return _file_package(RECIPES[source].arm or RECIPES[source].base)
    return _file_package(source)


def _file_package(source: str) -> str:
    """The distribution of a URDF name: shipped, a file of the user's, or example-robot-data."""
    from pbvs_pin.model.shipped import shipped_urdf

    if shipped_urdf(source) is not None:
        return SHIPPED_PACKAGE
    return "file" if source.lower().endswith(".urdf") else "example-robot-data"


def load_zoo(folder: str | Path) -> list[ZooRobot]:
    """Every ``*.toml`` robot file of ``folder``, sorted by name.

    Raises:
        ScenarioError: Naming a file without a ``[robot]`` table, or that is not UTF-8 text
            or not valid TOML.
    """
    from pbvs_pin.exceptions import ScenarioError

    robots = []
    for path in sorted(Path(folder).glob("*.toml")):
        table = read_toml(path, "a robot file")
        if "robot" not in table:
            raise ScenarioError(str(path), "robot", "missing; a robot file has a [robot] table")
        robots.append(ZooRobot(path.stem, path, table["robot"]))
    return robots


def joint_types(robot: MobileManipulator) -> str:
    """The arm's joints by type, e.g. ``"5 P + 1 R"`` (prismatic, revolute, continuous)."""
    kinds = []
    for name in robot.arm_joint_names:
        joint = robot.model.joints[robot.model.getJointId(name)]
        prismatic = joint.shortname().startswith("JointModelP")
        kinds.append("P" if prismatic else "C" if joint.nq == 2 else "R")
    counts = {kind: kinds.count(kind) for kind in ("P", "R", "C") if kind in kinds}
    return " + ".join(f"{count} {kind}" for kind, count in counts.items())


def run_robot(
    robot_file: ZooRobot, out: Path, experiments: tuple[str, ...], engines: tuple[str, ...],
    duration: float | None, changes: dict[str, Any] | None = None,
) -> list[dict[str, Any]]:  # fmt: skip
    """Run one robot through ``experiments`` on ``engines``; each run's row, saved as JSON.

    ``changes`` are scenario keys set in every run (``pbvs-pin zoo --set``), after the robot's.

    A robot that cannot be built gives one row per run with its ``error``; so does a run
    that raises (a project error's message, or the exception's type and message).
    """
    from pbvs_pin.sim.loop import simulate
    from pbvs_pin.sim.metrics import summarize
    from pbvs_pin.sim.scenario import load_scenario
    from pbvs_pin.sim.sections import RobotSection

    folder = out / robot_file.name
    folder.mkdir(parents=True, exist_ok=True)
    values = robot_file.scenario_values
    rows, robot, info = [], None, {}
    for experiment in experiments:
        for engine in engines:
            path = folder / f"{experiment}_{engine}.json"
            if path.exists():
                rows.append(json.loads(path.read_text()))
                continue
            row = {"robot": robot_file.name, "package": robot_file.package,
                   "experiment": experiment, "engine": engine}  # fmt: skip
            started = time.perf_counter()
            try:
                scenario = load_scenario(experiment).with_values(
                    **values, **(changes or {}), **{"plant.engine": engine},
                    **({} if duration is None else {"duration": duration}),
                )  # fmt: skip
                if robot is None:  # built from its file: messages name it, paths are its own
                    spec = RobotSection.from_toml(robot_file.table, str(robot_file.path))
                    robot = spec.build(scenario.camera.intrinsics())
                    info = {"dof": robot.n, "base_dof": robot.n_base,
                            "joint_types": joint_types(robot)}  # fmt: skip
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always", PbvsWarning)
                    log = simulate(scenario, robot=robot)
                for other in caught:  # only the project's warnings go into the row
                    if not issubclass(other.category, PbvsWarning):
                        warnings.showwarning(
                            other.message, other.category, other.filename, other.lineno
                        )
                row |= info | _figures(log, summarize(log)) | _warning(caught)
            except Exception as err:  # a failing run is a row of the table; the zoo goes on
                message = str(err) if isinstance(err, PbvsError) else f"{type(err).__name__}: {err}"
                row |= info | {"error": message}
            row["wall_time_s"] = time.perf_counter() - started
            path.write_text(json.dumps(row, indent=1))
            rows.append(row)
    return rows


def _warning(caught: list[warnings.WarningMessage]) -> dict[str, str]:
    """The run's project warnings as ``{"warning": ...}`` (each once), or nothing."""
    messages = dict.fromkeys(str(w.message) for w in caught if issubclass(w.category, PbvsWarning))
    return {"warning": "; ".join(messages)} if messages else {}


def _figures(log: Any, summary: dict[str, Any]) -> dict[str, Any]:
    """A run's figures for the table (pixels, metres or radians, fractions)."""
    summary = summary | {"scenario": log.meta["scenario"]}
    judgement = judge(summary)
    return {
        "max_error_last_5s_px": summary["max_abs_error_final_window_px"],
        "target_lost_samples": summary["target_lost_samples"],
        "joint_limit_violation": summary["joint_limit_violation"] or 0.0,
        "oscillation_rms_px": summary["oscillation_rms_px"],
        "net_share": float(np.mean(log["gain_limited"])),
        "claim_met": judgement["met"],
        "not_judged": judgement["not_judged"],
        "clauses": judgement["clauses"],
        "min_clearance_m": summary["min_clearance_m"],
        "duration_s": summary["duration_s"],
    }


def run_zoo(
    folder: str | Path, out: str | Path, experiments: tuple[str, ...] = EXPERIMENTS,
    engines: tuple[str, ...] = ENGINES, duration: float | None = None, workers: int = 1,
    echo: Callable[[str], None] = print, changes: dict[str, Any] | None = None,
) -> list[dict[str, Any]]:  # fmt: skip
    """Run every robot of ``folder`` (one task per robot) in a pool of ``workers`` processes.

    Args:
        folder: Folder of robot TOML files.
        out: Folder of the per-run JSON rows (created; existing rows are kept, not rerun).
        experiments: Shipped scenario names.
        engines: Plant engines.
        duration: Cut every run to this length [s]; each experiment's own when None.
        workers: Processes; 1 on a shared machine.
        echo: Told each run's :func:`progress_line` as its robot finishes (rows kept from an
            earlier sweep included).
        changes: Scenario keys set in every run (e.g. ``{"controller.feedback": "balanced"}``).

    Returns:
        Every run's row, by robot then experiment then engine.
    """
    out = Path(out)
    robots = load_zoo(folder)
    with ProcessPoolExecutor(max_workers=workers) as pool:
        tasks = [
            pool.submit(
                run_robot, robot, out, tuple(experiments), tuple(engines), duration, changes
            )
            for robot in robots
        ]
        rows = []
        for task in tasks:
            rows += task.result()
            for row in task.result():
                echo(progress_line(row))
        return rows


def _cell(row: dict[str, Any]) -> list[str]:
    """One run's five figures and claim, as table cells."""
    if "error" in row:
        return ["error", "", "", "", "", ""]
    return [
        f"{row['max_error_last_5s_px']:.2f}",
        str(row["target_lost_samples"]),
        f"{row['joint_limit_violation']:.3g}",
        f"{row['oscillation_rms_px']:.2f}",
        f"{row['net_share']:.2f}",
        _met_cell(row),
    ]


def _judgement(row: dict[str, Any]) -> dict[str, Any]:
    """A zoo row's verdict as :func:`pbvs_pin.study.claims.judge` gives it (old rows: none)."""
    return {"met": row["claim_met"], "not_judged": row.get("not_judged"),
            "clauses": row.get("clauses", [])}  # fmt: skip


def _met_cell(row: dict[str, Any]) -> str:
    """``yes``, ``**no**`` with the failed clauses' names, ``not judged`` or ``-``."""
    met = row["claim_met"]
    if met is None:
        return "not judged" if row.get("not_judged") else "-"
    names = ", ".join(clause["name"] for clause in failed(_judgement(row)))
    return "yes" if met else "**no**" + (f" ({names})" if names else "")


def progress_line(row: dict[str, Any]) -> str:
    """One run's line as the zoo goes: robot, experiment, plant, and its verdict or error.

    ``stretch_re1 experiment2 pinocchio: NOT met: last 5 s: 47.6 px >= 8 px; ...``
    """
    head = f"{row['robot']} {row['experiment']} {row['engine']}"
    if "error" in row:
        return f"{head}: error: {_portable(row['error'])}"
    return f"{head}: {verdict_text(_judgement(row))}"


BASE_KINDS = {0: "fixed", 2: "differential", 3: "omnidirectional"}
"""The table's name of a base by its number of velocities."""

FIGURES = ("max err last 5 s [px]", "lost", "past limits [rad or m]", "osc. [px]", "net share",
           "claim met")  # fmt: skip
"""Column heads of one run's figures."""


def zoo_table(rows: list[dict[str, Any]], engines: tuple[str, ...] = ENGINES) -> str:
    """The zoo's rows as an RST list-table: one line per robot and experiment."""
    heads = ["robot", "package", "dof", "base", "arm joints", "experiment"] + [
        f"{engine}: {figure}" for engine in engines for figure in FIGURES
    ]
    by_run = {(r["robot"], r["experiment"], r["engine"]): r for r in rows}
    lines = [".. list-table::", "   :header-rows: 1", ""]
    lines += rst_row(heads)
    for robot, experiment in dict.fromkeys((r["robot"], r["experiment"]) for r in rows):
        first = next(r for r in rows if r["robot"] == robot)
        cells = [robot, first["package"], str(first.get("dof", "")),
                 BASE_KINDS.get(first.get("base_dof"), ""), first.get("joint_types", ""),
                 experiment]  # fmt: skip
        for engine in engines:
            row = by_run.get((robot, experiment, engine))
            cells += _cell(row) if row is not None else ["not run", "", "", "", "", ""]
        lines += rst_row(cells)
    return "\n".join(lines) + "\n"


def errors(rows: list[dict[str, Any]], field: str = "error") -> str:
    """The runs that raised, one bullet per robot, plant and error, naming the experiments.

    With ``field = "warning"``: the runs that warned (a robot that tips over on MuJoCo).
    """
    failed: dict[tuple[str, str, str], list[str]] = {}
    for row in rows:
        if field in row:
            key = (row["robot"], row["engine"], row[field])
            failed.setdefault(key, []).append(row["experiment"])
    return "".join(
        f"- ``{robot}`` on {engine} ({', '.join(experiments)}): {_portable(error)}\n"
        for (robot, engine, error), experiments in failed.items()
    )


def _portable(message: str) -> str:
    """``message`` without this machine's folders.

    An installed package's file is named from the package's folder on (``rtbdata/xacro/...``),
    a shipped URDF by its file name.
    """
    folders = {*site.getsitepackages(), sysconfig.get_paths()["purelib"], str(urdf_dir())}
    for folder in sorted(folders, key=len, reverse=True):
        message = message.replace(folder.rstrip("/") + "/", "")
    return message


def add_arguments(parser: argparse.ArgumentParser, output: Callable) -> None:
    """The zoo's command-line arguments (the ``pbvs-pin zoo`` subcommand).

    Args:
        parser: The subcommand's parser.
        output: Declares an argument naming what the command writes
            (:func:`pbvs_pin.outputs.output_option`: checked before the command runs).
    """
    parser.add_argument("folder", help="folder of robot TOML files")
    output(
        parser, "--out", Output.FOLDER, default="zoo_results",
        help="folder of the per-run results",
    )  # fmt: skip
    output(
        parser, "--page", Output.FILE,
        help="write the table into this RST page's generated block",
    )  # fmt: skip
    parser.add_argument("--duration", type=float, help="cut every run to this length [s]")
    parser.add_argument(
        "--engines", default=",".join(ENGINES), help="plants to run, comma-separated"
    )
    parser.add_argument(
        "--experiments", default=",".join(EXPERIMENTS), help="experiments, comma-separated"
    )
    parser.add_argument("--workers", type=int, default=1, help="local worker processes")
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE",
        help="change a scenario key in every run, e.g. --set controller.feedback=balanced "
        "(repeatable; keep a separate --out per setting: existing rows are not rerun)",
    )  # fmt: skip


def command(args: argparse.Namespace) -> None:
    """Run the zoo as ``args`` say; print the wall time, write or print the table."""
    engines = tuple(args.engines.split(","))
    started = time.perf_counter()
    rows = run_zoo(args.folder, args.out, tuple(args.experiments.split(",")), engines,
                   args.duration, args.workers, changes=getattr(args, "changes", None))  # fmt: skip
    print(f"{len(rows)} runs in {time.perf_counter() - started:.0f} s")
    table = zoo_table(rows, engines)
    for field, title in (("error", "Runs that raised"), ("warning", "Runs that warned")):
        if errors(rows, field):
            table += f"\n{title}:\n\n{errors(rows, field)}"
    if args.page:
        write_block(Path(args.page), table)
    else:
        print(table)


PAGE_BEGIN = ".. zoo table: generated by pbvs-pin zoo"
PAGE_END = ".. end of the generated zoo table"


def write_block(page: Path, table: str) -> None:
    """Replace the text between :data:`PAGE_BEGIN` and :data:`PAGE_END` of ``page``.

    Raises:
        OutputError: If the page lacks the markers.
    """
    from pbvs_pin.exceptions import OutputError

    text = page.read_text()
    if PAGE_BEGIN not in text or PAGE_END not in text:
        raise OutputError(str(page), f"expected the lines {PAGE_BEGIN!r} and {PAGE_END!r}")
    head, rest = text.split(PAGE_BEGIN, 1)
    tail = rest.split(PAGE_END, 1)[1]
    page.write_text(f"{head}{PAGE_BEGIN}\n\n{table}\n{PAGE_END}{tail}")
