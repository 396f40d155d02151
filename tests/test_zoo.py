"""The robot zoo (issue 22, item 1): its robot files, and a short run of the sweep.

The short run is Experiment 1 cut to 1 s on the Pinocchio plant for two robots of the zoo
(the reference robot and Hello Robot's Stretch, five prismatic joints) and a robot file whose
camera link does not exist. Its figures are checked against the same run done here with
:func:`simulate` and measured from the log.
"""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from docs_figures import PAPERS_LAW

from pbvs_pin.bringup.catalogue import RECIPES
from pbvs_pin.cli import main
from pbvs_pin.exceptions import OutputError, PbvsWarning
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.sections import RobotSection
from pbvs_pin.study.zoo import (
    PAGE_BEGIN,
    PAGE_END,
    errors,
    load_zoo,
    run_robot,
    run_zoo,
    write_block,
    zoo_table,
)

ROBOTS = Path(__file__).resolve().parents[1] / "robots"
DURATION = 1.0  # [s]
BROKEN = """[robot]
base = "pioneer3at"
arm = "ur5"
mount = [0.10, 0.0, 0.27, 0.0, 0.0, 0.0]
camera_link = "no_such_link"
camera_pose = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
"""


def test_the_zoo_has_twenty_robots_from_eight_packages():
    """Issue 32: at least 20 robots from 8 PyPI packages, 3 holonomic bases, 1 URDF whose base
    is modelled as joints (read from the files, as a user wrote them)."""
    zoo = load_zoo(ROBOTS)
    for robot in zoo:
        RobotSection.from_toml(robot.table, str(robot.path))  # every file is a valid table
    packages = {robot.name: robot.package for robot in zoo}
    assert len(zoo) >= 20
    others = [name for name, package in packages.items() if "example-robot-data" not in package]
    assert len(others) >= 10, packages
    distributions = {part for package in packages.values() for part in package.split(" + ")}
    assert len(distributions - {"pbvs_pin"}) >= 8, distributions
    assert packages["stretch_re1"] == "hello-robot-stretch-urdf"
    assert packages["pioneer_iiwa14"] == "pbvs_pin + rtb-data"
    assert packages["fetch"] == "fetch-planning"  # the distribution calls itself fetch_planning
    holonomic = [r.name for r in zoo if r.table.get("drive") == "omnidirectional"]
    assert len(holonomic) >= 3, holonomic
    assert [r.name for r in zoo if r.table.get("base_joints")] == ["fetch_whole_body"]


@pytest.fixture(scope="module")
def short_zoo(tmp_path_factory):
    folder = tmp_path_factory.mktemp("robots")
    for name in ("pioneer_cyton", "stretch_re1"):
        shutil.copy(ROBOTS / f"{name}.toml", folder)
    (folder / "broken.toml").write_text(BROKEN)
    out = folder / "results"
    rows = run_zoo(folder, out, ("experiment1",), ("pinocchio",), duration=DURATION)
    return folder, out, rows


def test_short_zoo_rows_are_the_runs_measured_from_their_logs(short_zoo):
    folder, _, rows = short_zoo
    by_robot = {row["robot"]: row for row in rows}
    assert sorted(by_robot) == ["broken", "pioneer_cyton", "stretch_re1"]
    stretch = by_robot["stretch_re1"]
    assert (stretch["dof"], stretch["joint_types"]) == (8, "5 P + 1 R")  # u, omega; lift, 4 arm, yaw
    robot = RobotSection.from_toml(load_zoo(folder)[2].table, "stretch_re1.toml").build()
    log = simulate(load_scenario("experiment1").with_values(duration=DURATION), robot=robot)
    error = np.abs(log["xi_true"] - log["xi_d"])
    assert stretch["max_error_last_5s_px"] == pytest.approx(error.max(), rel=1e-9)
    assert stretch["target_lost_samples"] == int(np.sum(log["target_lost"]))
    assert stretch["net_share"] == pytest.approx(np.mean(log["gain_limited"]))
    assert "no_such_link" in by_robot["broken"]["error"]


def test_short_zoo_table_and_errors(short_zoo, tmp_path):
    _, out, rows = short_zoo
    table = zoo_table(rows, ("pinocchio",))
    lines = [line for line in table.splitlines() if line.startswith("   * - ")]
    assert len(lines) == 1 + 3  # header, one robot and experiment per line
    assert "hello-robot-stretch-urdf" in table and "5 P + 1 R" in table
    assert table.count("     - not judged\n") == 2  # 1 s runs: shorter than the rule's window
    assert "broken" in errors(rows) and "robot.camera_link" in errors(rows)
    assert (out / "stretch_re1" / "experiment1_pinocchio.json").is_file()
    page = tmp_path / "zoo.rst"
    page.write_text(f"Zoo\n===\n\n{PAGE_BEGIN}\nold\n{PAGE_END}\n\nafter\n")
    write_block(page, table)
    text = page.read_text()
    assert "old" not in text and "hello-robot-stretch-urdf" in text and text.endswith("after\n")
    page.write_text("no markers\n")
    with pytest.raises(OutputError, match="zoo table"):
        write_block(page, table)


def test_command_line_reuses_the_runs_and_writes_the_page(short_zoo, tmp_path, capsys):
    folder, out, _ = short_zoo
    page = tmp_path / "zoo.rst"
    page.write_text(f"{PAGE_BEGIN}\n{PAGE_END}\n")
    status = main(["zoo", str(folder), "--out", str(out), "--page", str(page), "--engines",
                   "pinocchio", "--experiments", "experiment1", "--duration", str(DURATION)])  # fmt: skip
    assert status == 0
    out = capsys.readouterr().out
    assert "3 runs in" in out
    assert (  # each run's verdict as its robot finishes; 1 s runs are too short to judge
        "stretch_re1 experiment1 pinocchio: not judged: run logged to 0.98 s, shorter than the "
        "rule's 5 s window\n"
    ) in out
    assert "broken experiment1 pinocchio: error: " in out
    assert "stretch_re1" in page.read_text() and "no_such_link" in page.read_text()


def _asked_loop_gain(name: str) -> tuple[float, float]:
    """Median loop gain the paper's law asks for over Experiment 4's first 10 s, and the net's
    share."""
    robot_file = next(robot for robot in load_zoo(ROBOTS) if robot.name == name)
    values = {**robot_file.scenario_values, **PAPERS_LAW}
    scenario = load_scenario("experiment4").with_values(**values, duration=10.0)
    spec = RobotSection.from_toml(robot_file.table, str(robot_file.path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # placement warnings (Vega's wheels, UR10's shoulder)
        robot = spec.build(scenario.camera.intrinsics())
    log = simulate(scenario, robot=robot)
    asked = log["loop_gain"][np.isfinite(log["loop_gain"])]
    return float(np.median(asked)), float(np.mean(log["gain_limited"]))


def test_vega_asks_for_a_loop_gain_the_net_must_cut_in_experiment4():
    """docs/zoo.rst's diagnosis of Vega-1's Experiment 4 under the paper's law: the loop
    gain ``g = k T lambda_max(J J^T)`` its Jacobian asks for is above 2, the sampled loop's
    stability limit, in almost every sample, so the net cuts every feature gain (to at most
    half); UR10, which holds the experiment, asks for less than the margin (1) at its home
    that keeps the Pioneer standing, the reference robot for less still."""
    asked, share = _asked_loop_gain("vega_1")
    ur10, ur10_share = _asked_loop_gain("pioneer_ur10")
    reference, reference_share = _asked_loop_gain("pioneer_cyton")
    assert asked > 2.0 and share > 0.95
    assert 0.5 < ur10 < 1.0 and ur10_share == 0.0
    assert reference < ur10 and reference_share == 0.0
    page = " ".join((ROBOTS.parent / "docs" / "zoo.rst").read_text().split())
    for sentence in (
        f"asks for a loop gain of {asked:.1f} (median over its first 10 s; the net cut the "
        f"gains in {100 * share:.1f} % of them)",
        f"asks for {ur10:.1f} (no cut; 1.0 and a cut of a few percent",
        f"the reference robot asks for {reference:.1f} (no cut)",
    ):
        assert sentence in page, f"docs/zoo.rst no longer says {sentence!r}: measure again"


def test_errors_name_files_without_this_machines_folders():
    import sysconfig

    from pbvs_pin.model.shipped import shipped_urdf

    installed = Path(sysconfig.get_paths()["purelib"]) / "rtbdata" / "xacro" / "irb140.urdf"
    row = {"robot": "r", "engine": "pinocchio", "experiment": "experiment1",
           "error": f"{shipped_urdf('pioneer3at')} + {installed}: arm joints move no mass"}  # fmt: skip
    assert errors([row]) == (
        "- ``r`` on pinocchio (experiment1): pioneer3at.urdf + rtbdata/xacro/irb140.urdf: "
        "arm joints move no mass\n"
    )


OLD_PANDA_HOME = (-1.9003, -1.4102, 0.8454, -1.9898, 2.2748, 2.0776, 1.4413)
"""Panda's home on the Pioneer before the home solver knew the wheels' support: it tips."""


def test_a_robot_that_tips_over_on_mujoco_is_listed_with_its_warning(tmp_path):
    """Panda on the Pioneer with its old home tips over on the MuJoCo plant
    (tests/test_mujoco_stability.py): its row keeps the plant's warning, and the page lists it
    under the runs that warned."""
    folder = tmp_path / "robots"
    folder.mkdir()
    text = (ROBOTS / "pioneer_panda.toml").read_text()
    (folder / "pioneer_panda.toml").write_text(text + f"home = {list(OLD_PANDA_HOME)}\n")
    rows = run_zoo(folder, tmp_path / "out", ("experiment1",), ("mujoco",), duration=0.2)
    assert "tips over on the MuJoCo plant" in rows[0]["warning"]
    assert errors(rows, "warning").startswith("- ``pioneer_panda`` on mujoco (experiment1): ")
    assert errors(rows) == ""


def test_a_robot_files_warnings_name_the_file(tmp_path):
    """The UR5 mounted on the floor: the placement warning names its robot file."""
    folder = tmp_path / "robots"
    folder.mkdir()
    low = BROKEN.replace('"no_such_link"', '"tool0"').replace("0.27", "0.0")
    (folder / "low_ur5.toml").write_text(low + f"home = {list(RECIPES['pioneer_ur5'].home)}\n")
    robot = load_zoo(folder)[0]  # run in this process (run_zoo's pool keeps its warnings)
    with pytest.warns(PbvsWarning) as caught:
        rows = run_robot(robot, tmp_path / "out", ("experiment1",), ("pinocchio",), 0.1)
    assert errors(rows) == ""
    placement = [str(w.message) for w in caught if "at home" in str(w.message)]
    assert placement[0].startswith(f"{folder / 'low_ur5.toml'}: at home, arm links inside")
