"""The ``[robot]`` table: its three forms build and run, and every mistake names its key.

Each form is written into a real TOML file under ``tmp_path`` and loaded as a user would. The
assembly is the UR5 on the reference platform exactly as ``pioneer_ur5`` is mounted in
``catalogue.py``; the README's examples are read from README.md and run here.
"""

from __future__ import annotations

import re
import shutil

import numpy as np
import pytest
from conftest import DATA_DIR, REPO_ROOT

from pbvs_pin.bringup.catalogue import PIONEER_MOUNT, RECIPES, build_robot
from pbvs_pin.cli import main
from pbvs_pin.exceptions import PbvsWarning, ScenarioError
from pbvs_pin.model.base import Omnidirectional
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.sections import RobotSection
from pbvs_pin.study.experiments import with_robot

UR5 = RECIPES["pioneer_ur5"]
UR5_JOINTS = (
    "shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
    "wrist_1_joint", "wrist_2_joint", "wrist_3_joint",
)  # fmt: skip
"""The UR5's six joints (example-robot-data's ur5.urdf)."""

ASSEMBLY = f"""
[robot]
base = "pioneer3at"
arm = "ur5"
mount = {list(PIONEER_MOUNT)}
camera_link = "tool0"
camera_pose = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
home = {list(UR5.home)}
"""

URDF = """
[robot]
urdf = "robots/pioneer_cyton.urdf"
camera_frame = "camera_optical_frame"
"""

FORMS = {"name": '\n[robot]\nname = "pioneer_ur5"\n', "urdf": URDF, "assembly": ASSEMBLY}


def _scenario_file(tmp_path, robot_table: str, name: str = "user.toml"):
    """experiment1 with ``robot_table`` in place of its ``[robot]``, in ``tmp_path/scen``.

    A copy of the reference robot's URDF sits in ``scen/robots/`` for relative paths.
    """
    folder = tmp_path / "scen"
    (folder / "robots").mkdir(parents=True, exist_ok=True)
    shutil.copy(REPO_ROOT / "urdf" / "pioneer_cyton.urdf", folder / "robots")
    text = (REPO_ROOT / "pbvs_pin" / "scenarios" / "experiment1.toml").read_text()
    text = text.replace('[robot]\nname = "pioneer_cyton"\n', robot_table)
    assert robot_table in text
    path = folder / name
    path.write_text(text)
    return path


def _robot_error(tmp_path, robot_table: str) -> tuple[ScenarioError, str]:
    """The ScenarioError of loading and building a scenario with ``robot_table``."""
    path = _scenario_file(tmp_path, robot_table)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path).robot.build()
    assert type(info.value) is ScenarioError
    assert str(path) in str(info.value)
    return info.value, str(path)


# ---------------------------------------------------------------- the forms
@pytest.mark.parametrize("form", FORMS)
def test_each_form_parses_builds_and_runs(tmp_path, monkeypatch, form):
    monkeypatch.chdir(tmp_path)  # relative paths must not depend on the working folder
    path = _scenario_file(tmp_path, FORMS[form])
    scenario = load_scenario(path).with_values(duration=0.5)
    assert scenario.robot.form == form
    robot = scenario.robot.build(scenario.camera.intrinsics())
    expected_arm = UR5_JOINTS if form != "urdf" else (
        "shoulder_yaw_joint", "shoulder_pitch_joint", "elbow_pitch_joint"
    )  # fmt: skip
    assert robot.arm_joint_names == expected_arm
    assert robot.n == 2 + len(expected_arm)
    log = simulate(scenario)
    assert log["t"][-1] == pytest.approx(0.5, abs=0.03)
    delivered = log["t"] >= scenario.camera.delivery_latency  # the first frame's arrival
    assert np.all(np.isfinite(log["xi"][delivered][0]))
    assert log.meta["velocity_names"] == ["u", "omega", *expected_arm]
    assert log.meta["robot_table"] == scenario.robot.to_toml()


def test_assembly_equals_the_shipped_recipe(tmp_path):
    scenario = load_scenario(_scenario_file(tmp_path, ASSEMBLY))
    assembled = scenario.robot.build()
    shipped = build_robot("pioneer_ur5")
    np.testing.assert_array_equal(assembled.home(), shipped.home())
    pose_a, pose_s = assembled.camera_pose(shipped.home()), shipped.camera_pose(shipped.home())
    np.testing.assert_allclose(pose_a.homogeneous, pose_s.homogeneous, atol=1e-12)


def test_relative_urdf_path_is_read_from_the_file_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = _scenario_file(tmp_path, URDF)
    scenario = load_scenario(path)
    assert scenario.robot.urdf == str(path.parent / "robots" / "pioneer_cyton.urdf")
    # A copy with another value keeps the folder; an absolute path stays as it is.
    again = scenario.with_values(**{"simulation.seed": 3})
    assert again.robot.urdf == scenario.robot.urdf


WHEELLESS_ASSEMBLY = f"""
[robot]
base = "{DATA_DIR / "box_platform.urdf"}"
arm = "{DATA_DIR / "one_joint_arm.urdf"}"
mount = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
camera_link = "tool_link"
camera_pose = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
"""
"""A one-joint arm on a platform without wheel joints, whose camera cannot look forward."""


def test_drive_keys_give_a_platform_without_wheels_a_drive(tmp_path):
    table = WHEELLESS_ASSEMBLY
    error, _ = _robot_error(tmp_path, table)
    assert error.field == "robot.base"
    # every way out: the URDF's wheels, the explicit (Pinocchio-only) keys, a holonomic drive
    for way in ("<limit velocity=...>", "add wheel_radius, track and wheel_speed_limit",
                "Pinocchio plant only", 'set drive = "omnidirectional"'):  # fmt: skip
        assert way in str(error), way
    # the toy arm cannot point its camera forward, so its home is given
    drive = "wheel_radius = 0.1\ntrack = 0.4\nwheel_speed_limit = 5.0\nhome = [0.0]\n"
    robot = load_scenario(_scenario_file(tmp_path, table + drive)).robot.build()
    # Platform limits r w_max = 0.5 m/s and 2 r w_max / track = 2.5 rad/s.
    np.testing.assert_allclose(robot.velocity_limits[:2], [0.5, 2.5])


def test_an_omnidirectional_drive_gets_its_limits(tmp_path):
    """The same platform without wheels, holonomic: vx, vy and omega with the limits given."""
    drive = 'drive = "omnidirectional"\nspeed_limit = 0.5\nyaw_rate_limit = 0.8\nhome = [0.0]\n'
    robot = load_scenario(_scenario_file(tmp_path, WHEELLESS_ASSEMBLY + drive)).robot.build()
    assert robot.base == Omnidirectional(0.5, 0.8)
    assert robot.velocity_names[:3] == ("vx", "vy", "omega")
    np.testing.assert_allclose(robot.velocity_limits[:3], [0.5, 0.5, 0.8])


def test_home_overrides_the_arm_posture(tmp_path):
    home = [0.3, -0.4, 0.2]
    table = f'\n[robot]\nname = "pioneer_cyton"\nhome = {home}\n'
    robot = load_scenario(_scenario_file(tmp_path, table)).robot.build()
    np.testing.assert_array_equal(robot.arm_positions(robot.home()), home)


def test_no_form_is_the_reference_robot():
    assert RobotSection().name == "pioneer_cyton"
    assert RobotSection.from_toml({"initial_arm": [0.0, 0.1, 0.2]}, "x.toml").form == "name"


def test_simulate_uses_the_given_robot():
    scenario = load_scenario("experiment1").with_values(duration=0.5)
    assert scenario.robot.name == "pioneer_cyton"
    robot = build_robot("pioneer_ur5")
    log = simulate(scenario, robot=robot)
    assert log.meta["velocity_names"] == ["u", "omega", *UR5_JOINTS]
    assert log["arm"].shape[1] == 6
    assert log.meta["robot"] == robot.source and log.meta["robot_table"] is None
    np.testing.assert_allclose(log["arm"][0], UR5.home, atol=1e-9)


# ---------------------------------------------------------------- the errors
@pytest.mark.parametrize(
    ("table", "field", "fragment"),
    [
        ('name = "pioneer_ur5"\nurdf = "x.urdf"\n', "robot.urdf", "robot.name"),
        ('name = "pioneer_ur5"\nbase = "pioneer3at"\n', "robot.base", "robot.name"),
        ('urdf = "x.urdf"\ncamera_link = "tool0"\n', "robot.camera_link", "robot.urdf"),
        ('urdf = "robots/pioneer_cyton.urdf"\n', "robot.camera_frame", "add camera_frame"),
        ('camera_frame = "camera_optical_frame"\n', "robot.urdf", "add urdf"),
        (ASSEMBLY.replace('camera_link = "tool0"\n', "").replace("[robot]\n", ""),
         "robot.camera_link", "add camera_link"),
        (ASSEMBLY.replace("camera_pose", "# ").replace("[robot]\n", ""),
         "robot.camera_pose", "add camera_pose"),
        (ASSEMBLY.replace("mount", "# ").replace("[robot]\n", ""), "robot.mount", "add mount"),
        ('base = "pioneer3at"\nmount = [0, 0, 0.27, 0, 0, 0]\ncamera_link = "tool0"\n'
         "camera_pose = [0, 0, 0, 0, 0, 0]\n", "robot.arm", "add arm"),
        (ASSEMBLY.replace(str(list(PIONEER_MOUNT)), "[0.1, 0.0, 0.27]").replace("[robot]\n", ""),
         "robot.mount", "expected 6 values"),
        ('name = "pioneer_cyton"\ntrack = 0.4\n', "robot.track", "drive"),
        ('urdf = "x.urdf"\ncamera_frame = "c"\nwheel_radius = 0.1\n', "robot.track",
         "add track"),
        ('urdf = "x.urdf"\ncamera_frame = "c"\nwheel_radius = -0.1\ntrack = 0.4\n'
         "wheel_speed_limit = 5.0\n", "robot.wheel_radius", "positive"),
        ('name = "pioneer_cyton"\narm_name = "ur5"\n', "robot.arm_name", "unknown key"),
        ('name = "pioneer_cyton"\ndrive = "omnidirectional"\n', "robot.drive", "known"),
        ('urdf = "x.urdf"\ncamera_frame = "c"\ndrive = "omnidirectional"\nwheel_radius = 0.1\n'
         "track = 0.4\nwheel_speed_limit = 5.0\n", "robot.drive", "no drive axle"),
        ('urdf = "x.urdf"\ncamera_frame = "c"\nspeed_limit = 0.5\n', "robot.speed_limit",
         'add drive = "omnidirectional"'),
        ('urdf = "x.urdf"\ncamera_frame = "c"\ndrive = "mecanum"\n', "robot.drive",
         "omnidirectional"),
        ('name = "tiago"\nyaw_rate_limit = 0.5\n', "robot.yaw_rate_limit", "limits are known"),
    ],
    ids=[
        "name-and-urdf", "name-and-assembly", "urdf-and-assembly", "missing-camera-frame",
        "missing-urdf", "missing-camera-link", "missing-camera-pose", "missing-mount",
        "missing-arm", "bad-mount-length", "drive-on-shipped", "partial-drive", "bad-drive",
        "unknown-key", "drive-on-shipped-name", "omnidirectional-with-wheels",
        "omnidirectional-limit-alone", "unknown-drive", "limit-on-shipped-name",
    ],
)  # fmt: skip
def test_bad_table_names_file_and_field(tmp_path, table, field, fragment):
    path = _scenario_file(tmp_path, "\n[robot]\n" + table)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert type(info.value) is ScenarioError
    assert info.value.field == field
    message = str(info.value)
    assert message.startswith(f"{path}: {field}: ")
    assert fragment in message
    assert "\n" not in message


@pytest.mark.parametrize(
    ("table", "field", "fragment"),
    [
        (ASSEMBLY.replace('"ur5"', '"no_such_arm"'), "robot.arm", "'no_such_arm'"),
        (ASSEMBLY.replace('"pioneer3at"', '"no_such_base"'), "robot.base", "'no_such_base'"),
        (ASSEMBLY.replace('"tool0"', '"no_such_link"'), "robot.camera_link", "'no_such_link'"),
        (ASSEMBLY.replace('"ur5"', '"arms/missing.urdf"'), "robot.arm", "file not found"),
        (URDF.replace("robots/", "elsewhere/"), "robot.urdf", "file not found"),
        (URDF.replace('"camera_optical_frame"', '"no_such_frame"'), "robot.camera_frame",
         "'no_such_frame'"),
        ('\n[robot]\nname = "pioneer_cyton_mk2"\n', "robot.name", "'pioneer_cyton_mk2'"),
        ('\n[robot]\nname = "pioneer_cyton"\nhome = [0.1, 0.2]\n', "robot.home",
         "expected 3 values"),
        ('\n[robot]\nname = "pioneer_cyton"\nhome = [0.0, 0.0, 3.0]\n', "robot.home",
         "elbow_pitch_joint"),
        (ASSEMBLY.replace('"ur5"', '"ur3"'), "robot.arm",
         "maps 'ur3' to the 'ur5' robot (ur5_robot.urdf)"),
    ],
    ids=[
        "unknown-arm", "unknown-base", "unknown-camera-link", "missing-arm-file",
        "missing-urdf-file", "unknown-camera-frame", "unknown-name", "home-length",
        "home-off-limits", "ur3-is-a-ur5",
    ],
)  # fmt: skip
def test_robot_that_cannot_be_built_names_file_and_field(tmp_path, table, field, fragment):
    error, path = _robot_error(tmp_path, table)
    assert error.field == field
    assert str(error).startswith(f"{path}: {field}: ")
    assert fragment in str(error)


def test_a_robot_files_warnings_name_it_not_the_scenario(tmp_path):
    """`run --robot FILE` (with --duration): the placement warning names FILE."""
    robot_file = tmp_path / "low_ur5.toml"  # mounted on the floor: the arm is in the platform
    robot_file.write_text(ASSEMBLY.replace(str(list(PIONEER_MOUNT)), "[0.1, 0.0, 0.0, 0, 0, 0]"))
    scenario = with_robot(load_scenario("experiment1"), str(robot_file))
    scenario = scenario.with_values(duration=0.1)
    with pytest.warns(PbvsWarning) as caught:
        scenario.robot.build()
    message = str(caught[0].message)
    assert message.startswith(f"{robot_file}: at home, arm links inside the platform")
    assert "experiment1" not in message
    # a changed robot key makes the table the scenario's again
    assert scenario.with_values(**{"robot.home": list(UR5.home)}).robot.source == scenario.source


def test_relative_paths_resolve_in_the_error(tmp_path):
    error, _ = _robot_error(tmp_path, URDF.replace("robots/", "elsewhere/"))
    assert str(tmp_path / "scen" / "elsewhere" / "pioneer_cyton.urdf") in str(error)


def test_simulate_reports_a_bad_robot_table(tmp_path):
    path = _scenario_file(tmp_path, ASSEMBLY.replace('"ur5"', '"no_such_arm"'))
    with pytest.raises(ScenarioError) as info:
        simulate(load_scenario(path).with_values(duration=0.1))
    assert info.value.field == "robot.arm"


# ---------------------------------------------------------------- command line and README
def test_info_and_view_take_a_robot_file(tmp_path, capsys):
    robot_file = tmp_path / "my_robot.toml"
    robot_file.write_text(ASSEMBLY)
    assert main(["info", str(robot_file)]) == 0
    out = capsys.readouterr().out
    assert "actuated dof n = 8 (base 2, arm 6)" in out
    assert all(joint in out for joint in UR5_JOINTS)
    html = tmp_path / "view.html"
    assert main(["view", str(robot_file), "--html", str(html)]) == 0
    assert html.stat().st_size > 0


def test_info_takes_a_scenario_and_reports_errors_in_one_line(tmp_path, capsys):
    assert main(["info", str(_scenario_file(tmp_path, URDF))]) == 0
    assert "actuated dof n = 5" in capsys.readouterr().out
    no_table = tmp_path / "no_robot.toml"
    no_table.write_text('name = "x"\n')
    bad = _scenario_file(tmp_path, ASSEMBLY.replace('"tool0"', '"no_such_link"'), "bad.toml")
    for path, field in ((no_table, "robot"), (bad, "robot.camera_link")):
        assert main(["info", str(path)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"pbvs-pin: error: {path}: {field}: ")


def _readme_robot_tables() -> list[str]:
    """The TOML blocks of the "Describing a robot" section of docs/own_robot.md."""
    page = (REPO_ROOT / "docs" / "own_robot.md").read_text()
    section = page.split("## Describing a robot\n", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```toml\n(.*?)```", section, flags=re.DOTALL)


def test_readme_examples_run(tmp_path):
    tables = _readme_robot_tables()
    assert len(tables) == 3
    for i, (table, form) in enumerate(zip(tables, ("assembly", "urdf", "assembly"), strict=True)):
        folder = tmp_path / f"{form}{i}"
        (folder / "urdf").mkdir(parents=True)
        shutil.copy(REPO_ROOT / "urdf" / "pioneer_cyton.urdf", folder / "urdf")
        path = folder / "user.toml"
        text = (REPO_ROOT / "pbvs_pin" / "scenarios" / "experiment1.toml").read_text()
        path.write_text(text.replace('[robot]\nname = "pioneer_cyton"\n', table))
        scenario = load_scenario(path).with_values(duration=0.3)
        assert scenario.robot.form == form
        log = simulate(scenario)
        assert np.all(np.isfinite(log["xi"][-1]))
        if "arm_root" in table:  # TIAGo from its torso: the torso lift is locked
            assert log.meta["velocity_names"] == ["u", "omega", *(f"arm_{j}_joint" for j in
                                                  range(1, 8))]  # fmt: skip


def test_a_robot_whose_camera_cannot_look_forward_needs_its_home(tmp_path):
    """Without `home`, the home is computed; an arm that cannot point its camera forward is
    refused on robot.home, naming what to give."""
    table = WHEELLESS_ASSEMBLY + "wheel_radius = 0.1\ntrack = 0.4\nwheel_speed_limit = 5.0\n"
    with pytest.raises(ScenarioError) as caught:
        load_scenario(_scenario_file(tmp_path, table)).robot.build()
    assert caught.value.field == "robot.home"
    assert "give the home posture explicitly" in str(caught.value)
