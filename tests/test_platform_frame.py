"""A URDF's own base joints and the platform's forward axis (``base_joints``, ``forward_axis``).

Each URDF is the reference robot (``urdf/pioneer_cyton.urdf``) with a few links and joints
added above its root link ``base_link``, written into ``tmp_path``: a planning URDF's base
modelled as prismatic x, prismatic y and continuous yaw joints, as one planar joint, as one
floating joint, and a platform whose root link is turned so that it drives along -y. The
reference is the unchanged file: with the base joints fixed (or the platform frame turned
back), every robot must be the reference robot, joint for joint and pose for pose.
"""

from __future__ import annotations

import tomllib
import warnings

import numpy as np
import pytest
from conftest import REPO_ROOT

from pbvs_pin.bringup.catalogue import PIONEER_MOUNT, RECIPES
from pbvs_pin.exceptions import BaseJointsError, GainError, PbvsWarning, ScenarioError
from pbvs_pin.model.assembly import load_urdf
from pbvs_pin.model.base import Omnidirectional
from pbvs_pin.model.platform_frame import PlatformFrame, fix_base_joints, warn_wheel_axles
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.sections import RobotSection

REFERENCE = REPO_ROOT / "urdf" / "pioneer_cyton.urdf"
CYTON = ("shoulder_yaw_joint", "shoulder_pitch_joint", "elbow_pitch_joint")
"""The reference arm's three joints."""

LIMIT = '<limit lower="-10" upper="10" effort="100" velocity="1"/>'
BASES = {  # the links and joints that model the base, above the reference's base_link
    "xyz_joints": f"""
        <link name="world"/><link name="x_link"/><link name="y_link"/>
        <joint name="x_joint" type="prismatic"><parent link="world"/><child link="x_link"/>
          <axis xyz="1 0 0"/>{LIMIT}</joint>
        <joint name="y_joint" type="prismatic"><parent link="x_link"/><child link="y_link"/>
          <axis xyz="0 1 0"/>{LIMIT}</joint>
        <joint name="theta_joint" type="continuous"><parent link="y_link"/>
          <child link="base_link"/><axis xyz="0 0 1"/></joint>""",
    "planar": """
        <link name="odom"/>
        <joint name="base_planar" type="planar"><parent link="odom"/><child link="base_link"/>
          <axis xyz="0 0 1"/></joint>""",
    "floating": """
        <link name="odom"/>
        <joint name="base_float" type="floating"><parent link="odom"/>
          <child link="base_link"/></joint>""",
}
JOINTS = {
    "xyz_joints": ["x_joint", "y_joint", "theta_joint"],
    "planar": ["base_planar"],
    "floating": ["base_float"],
}
NV = {"xyz_joints": 3, "planar": 3, "floating": 6}
"""Pinocchio velocities of each base model (x, y, yaw; a planar joint; a free flyer)."""

DRIVES_ALONG_MINUS_Y = """
    <link name="body"/>
    <joint name="body_joint" type="fixed"><parent link="body"/><child link="base_link"/>
      <origin rpy="0 0 -1.5707963267948966"/></joint>"""
"""A root link whose x axis lies along the wheel axles: the platform drives along its -y."""

WHEELS = [f"{a}_{b}_wheel_joint" for a in ("front", "rear") for b in ("left", "right")]


def _urdf(tmp_path, extra: str, name: str = "robot") -> str:
    """The reference robot with ``extra`` links and joints, written to ``tmp_path``."""
    path = tmp_path / f"{name}.urdf"
    path.write_text(REFERENCE.read_text().replace("</robot>", f"{extra}\n</robot>"))
    return str(path)


def _build(path: str, **options) -> tuple[MobileManipulator, list[str]]:
    """The robot of a URDF and the PbvsWarnings raised while building it."""
    base = options.pop("base", "differential")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        robot = MobileManipulator.from_urdf(
            path, base=base, platform_frame=PlatformFrame(**options)
        )
    return robot, [str(w.message) for w in caught if issubclass(w.category, PbvsWarning)]


@pytest.fixture(scope="module")
def reference():
    return MobileManipulator.from_urdf(str(REFERENCE))


# ---------------------------------------------------------------- base joints
@pytest.mark.parametrize("model", BASES)
@pytest.mark.parametrize("drive", ["differential", "omnidirectional"])
def test_base_joints_are_recognised_as_the_base(tmp_path, reference, model, drive):
    base = Omnidirectional() if drive == "omnidirectional" else "differential"
    robot, caught = _build(_urdf(tmp_path, BASES[model]), base=base)
    assert robot.arm_joint_names == CYTON
    assert robot.n == (3 if drive == "omnidirectional" else 2) + 3
    assert len(caught) == 1
    assert "robot.urdf" in caught[0] and str(JOINTS[model]) in caught[0]
    assert "fixed at zero" in caught[0]
    if drive == "differential":
        assert robot.base == reference.base  # the wheels under base_link give the drive
    # The same robot as the reference, at rest and after driving (the chain is identity at 0).
    command = np.array([0.3, 0.2, *(0.1,) * 3]) if drive == "differential" else None
    if command is not None:
        q, q_ref = robot.integrate(robot.neutral(), command, 1.0), reference.integrate(
            reference.neutral(), command, 1.0
        )
        np.testing.assert_allclose(
            robot.camera_pose(q).homogeneous, reference.camera_pose(q_ref).homogeneous,
            atol=1e-12,
        )  # fmt: skip


@pytest.mark.parametrize("model", BASES)
def test_named_base_joints_need_no_warning_and_none_keeps_them_as_arm_joints(tmp_path, model):
    path = _urdf(tmp_path, BASES[model])
    named, caught = _build(path, base=Omnidirectional(), base_joints=JOINTS[model])
    assert named.arm_joint_names == CYTON and caught == []
    # Detection off: the base counted twice, its joints taken as arm joints (issue 32's trial).
    doubled, caught = _build(path, base=Omnidirectional(), base_joints=[])
    assert doubled.model.nv == 3 + NV[model] + 3
    assert set(JOINTS[model]) <= set(doubled.arm_joint_names)


def test_base_joints_on_a_heavy_root_or_beside_wheels_are_not_recognised(tmp_path):
    heavy = BASES["xyz_joints"].replace(
        '<link name="world"/>',
        '<link name="world"><inertial><mass value="40"/>'
        '<inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>',
    )
    source = load_urdf(_urdf(tmp_path, heavy, "heavy"))
    assert fix_base_joints(source) == ()  # a 40 kg root is a platform, not a world
    beside = BASES["xyz_joints"] + (
        '<link name="roller"/><joint name="roller_joint" type="continuous">'
        '<parent link="world"/><child link="roller"/><axis xyz="0 1 0"/></joint>'
    )
    source = load_urdf(_urdf(tmp_path, beside, "beside"))
    assert fix_base_joints(source) == ()  # a movable joint on the root: not a bare world
    assert fix_base_joints(source, ("x_joint", "y_joint", "theta_joint")) == (
        "x_joint", "y_joint", "theta_joint",
    )  # fmt: skip
    assert {j.type for j in source.robot.joints if j.name.endswith("_joint")} >= {"fixed"}


@pytest.mark.parametrize(
    ("names", "words"),
    [
        (["x_joint", "nope"], "no joint 'nope'"),
        (["x_joint", "y_joint"], "do not model a base"),
        (["x_joint", "y_joint", "shoulder_yaw_joint"], "shoulder_yaw_joint"),
    ],
)
def test_named_joints_that_are_no_base_are_refused(tmp_path, names, words):
    source = load_urdf(_urdf(tmp_path, BASES["xyz_joints"]))
    with pytest.raises(BaseJointsError, match=words):
        fix_base_joints(source, tuple(names))


def test_the_shipped_robots_name_their_base_joints_and_drive_along_their_forward_axis():
    tables = {}
    for path in sorted((REPO_ROOT / "robots").glob("*.toml")):
        tables[path.stem] = RobotSection.from_toml(tomllib.loads(path.read_text())["robot"],
                                                   str(path))  # fmt: skip
    assert len(tables) == 20
    # Only the planning URDF models its base as joints, and its file names them.
    assert {name for name, table in tables.items() if table.base_joints} == {"fetch_whole_body"}
    for name, table in tables.items():
        recipe = RECIPES.get(table.name)  # a robot by name: a recipe's platform
        urdf = table.urdf or table.base or (recipe.base if recipe else str(REFERENCE))
        source = load_urdf(urdf, table.repair_inertia, table.geometry_density)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert fix_base_joints(source, table.base_joints) == (table.base_joints or ()), name
            assert warn_wheel_axles(source, table.forward_axis, source.root_link()) == [], name
    # The named joints are the ones the loader would have recognised by itself, with a warning.
    fetch = tables["fetch_whole_body"]
    source = load_urdf(fetch.base, fetch.repair_inertia, fetch.geometry_density)
    with pytest.warns(PbvsWarning, match="base_x_joint"):
        assert fix_base_joints(source) == fetch.base_joints


# ---------------------------------------------------------------- forward axis
def test_a_platform_driving_along_minus_y_is_warned_and_turned(tmp_path, reference):
    path = _urdf(tmp_path, DRIVES_ALONG_MINUS_Y)
    with pytest.warns(PbvsWarning) as caught, pytest.raises(Exception, match="no usable drive"):
        MobileManipulator.from_urdf(path)
    message = str(caught[0].message)
    assert "robot.urdf" in message and str(WHEELS) in message and '"y" or "-y"' in message
    robot, caught = _build(path, forward_axis="-y")
    assert caught == [] and robot.base == reference.base and robot.n == 5
    # The turned platform frame is the reference's base_link: driving moves both alike.
    command = np.array([0.4, -0.3, 0.2, 0.1, -0.1])
    q, q_ref = robot.integrate(robot.neutral(), command, 1.5), reference.integrate(
        reference.neutral(), command, 1.5
    )
    np.testing.assert_allclose(
        robot.camera_pose(q).homogeneous, reference.camera_pose(q_ref).homogeneous, atol=1e-12
    )
    # The robot as built, written and read back with the defaults, is the same robot.
    again, caught = _build(str(robot.write_urdf(tmp_path / "written.urdf")))
    assert caught == [] and vars(again.base) == pytest.approx(vars(robot.base), rel=1e-12)
    np.testing.assert_allclose(  # the file holds the turn as rpy: rounded to ~1e-16
        again.camera_pose(q).homogeneous, robot.camera_pose(q).homogeneous, atol=1e-12
    )


def test_forward_axis_is_checked():
    with pytest.raises(GainError, match="expected one of") as info:
        PlatformFrame(forward_axis="z")
    assert info.value.field == "forward_axis"
    with pytest.raises(GainError, match="list of joint names") as info:
        PlatformFrame(base_joints="x_joint")
    assert info.value.field == "base_joints"


# ---------------------------------------------------------------- the [robot] keys
def _table(path: str, **keys) -> dict:
    return {"robot.name": "", "robot.urdf": path,
            "robot.camera_frame": "camera_optical_frame", **keys}  # fmt: skip


@pytest.mark.parametrize(
    ("keys", "field", "words"),
    [
        ({"robot.forward_axis": "z"}, "robot.forward_axis", "expected one of"),
        ({"robot.base_joints": "x_joint"}, "robot.base_joints", "list of names"),
        ({"robot.base_joints": ["x_joint", "y_joint"]}, "robot.base_joints", "not model a base"),
    ],
)
def test_a_bad_key_names_itself(tmp_path, keys, field, words):
    path = _urdf(tmp_path, BASES["xyz_joints"])
    with pytest.raises(ScenarioError, match=words) as info:
        load_scenario("experiment1").with_values(**_table(path, **keys)).robot.build()
    assert info.value.field == field


def test_a_shipped_robot_refuses_the_platform_keys():
    for name, value in (("forward_axis", "-y"), ("base_joints", [])):
        with pytest.raises(ScenarioError, match="platform is known") as info:
            load_scenario("experiment1").with_values(**{f"robot.{name}": value})
        assert info.value.field == f"robot.{name}"


@pytest.mark.parametrize(
    ("extra", "keys", "velocities"),
    [
        (BASES["xyz_joints"], {"robot.drive": "omnidirectional"}, ["vx", "vy", "omega"]),
        (DRIVES_ALONG_MINUS_Y, {"robot.forward_axis": "-y"}, ["u", "omega"]),
    ],
)
def test_the_closed_loop_keeps_the_target(tmp_path, extra, keys, velocities):
    path = _urdf(tmp_path, extra)
    scenario = load_scenario("experiment1").with_values(duration=5.0, **_table(path, **keys))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PbvsWarning)  # the recognised base joints
        log = simulate(scenario)
    assert log.meta["velocity_names"] == [*velocities, *CYTON]
    assert not np.any(log["target_lost"])
    late = log["t"] >= 3.0
    error = np.abs(log["xi_true"] - log["xi_d"])[late]
    assert np.max(error) < 8.0, np.max(error)  # [px], Experiment 1's settled claim


def test_an_assembly_platform_with_base_joints_carries_the_arm(tmp_path):
    pioneer = REPO_ROOT / "urdf" / "pioneer3at.urdf"
    platform = tmp_path / "platform.urdf"
    platform.write_text(pioneer.read_text().replace("</robot>", BASES["planar"] + "</robot>"))
    arm = ("ur5", PIONEER_MOUNT, "tool0", (0.0,) * 6)
    with pytest.warns(PbvsWarning, match="base_planar"):
        robot = MobileManipulator.assemble(str(platform), *arm)
    reference = MobileManipulator.assemble(str(pioneer), *arm)
    assert robot.velocity_names == reference.velocity_names and robot.n == 2 + 6
    # mount is in the platform's root link odom, which is base_link at zero: the same robot
    q = robot.integrate(robot.neutral(), np.linspace(0.1, 0.8, 8), 1.0)
    np.testing.assert_allclose(
        robot.camera_pose(q).homogeneous, reference.camera_pose(q).homogeneous, atol=1e-12
    )
