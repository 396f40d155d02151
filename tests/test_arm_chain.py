"""Part of a URDF as the arm (issue 22, item 4): Baxter's left arm on the reference platform.

Mounted whole, example-robot-data's Baxter brings its torso and pedestal: the pedestal (with
its casters) reaches below the floor and both sit inside the platform, which the placement
check must name. With ``arm_root``/``arm_tip`` only the left arm's chain is mounted: nothing
of the rest is in the model, the views or the URDF handed to the MuJoCo plant.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import REPO_ROOT

from pbvs_pin import MobileManipulator, UrdfError
from pbvs_pin.bringup.catalogue import PIONEER_MOUNT
from pbvs_pin.bringup.home import compute_home
from pbvs_pin.bringup.placement import (
    FLOOR_TOLERANCE,
    Placement,
    placement_problems,
    warn_placement,
    world_boxes,
)
from pbvs_pin.exceptions import PbvsWarning, ScenarioError
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.sections import RobotSection

CAMERA = "left_hand_camera_link"
LEFT_ARM = ("left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2")
PLATFORM_ROOT = "base_link"  # pioneer3at.urdf's root link, where mount is given
DROPPED = ("torso", "pedestal", "head", "right_upper_shoulder", "right_wrist", "screen")


def baxter(**chain):
    return MobileManipulator.assemble("pioneer3at", "baxter", PIONEER_MOUNT, CAMERA, (0,) * 6,
                                      **chain)  # fmt: skip


@pytest.fixture(scope="module")
def whole():
    return baxter()


@pytest.fixture(scope="module")
def left_arm():
    robot = baxter(arm_root="left_arm_mount", arm_tip=CAMERA)
    robot.home_arm = compute_home(robot)
    return robot


def test_whole_urdf_warns_naming_the_links_below_the_floor_and_inside_the_platform(whole):
    boxes = world_boxes(whole, whole.home())
    assert boxes["pedestal"][0, 2] < -0.5  # the pedestal's foot is ~0.9 m below the mount
    with pytest.warns(PbvsWarning, match="arm_root and arm_tip") as caught:
        found = warn_placement(whole, "baxter.toml")
    assert found.below_floor == ("pedestal",)
    assert {"torso", "pedestal"} <= set(found.inside_platform)
    message = str(caught[0].message)
    assert "baxter.toml" in message and "below the floor: pedestal" in message


def test_chain_mounts_only_the_left_arm(left_arm):
    assert left_arm.arm_joint_names == LEFT_ARM
    frames = {frame.name for frame in left_arm.model.frames}
    shown = {
        left_arm.model.frames[g.parentFrame].name for g in left_arm.visual_model.geometryObjects
    }
    for link in DROPPED:
        assert link not in frames and link not in shown
        assert f'"{link}"'.encode() not in left_arm.urdf_xml  # the MuJoCo plant's description
    assert {"left_upper_shoulder", "left_wrist", "chassis_link"} <= shown
    boxes = world_boxes(left_arm, left_arm.home())
    assert min(box[0, 2] for box in boxes.values()) > -FLOOR_TOLERANCE
    assert placement_problems(left_arm, left_arm.home()) == Placement((), ())


def test_chain_root_sits_at_the_mount(left_arm):
    q = left_arm.home()
    platform = left_arm.frame_pose(q, PLATFORM_ROOT)
    mount = left_arm.frame_pose(q, "left_arm_mount")
    expected = platform * pin.XYZQUATToSE3(np.r_[PIONEER_MOUNT[:3], 0.0, 0.0, 0.0, 1.0])
    assert np.allclose(mount.homogeneous, expected.homogeneous, atol=1e-12)


def test_tip_not_below_root_is_refused():
    with pytest.raises(UrdfError, match="does not hang below"):
        baxter(arm_root="right_arm_mount", arm_tip=CAMERA)


def test_scenario_names_the_chain_keys():
    table = {"robot.name": "", "robot.base": "pioneer3at", "robot.arm": "baxter",
             "robot.mount": list(PIONEER_MOUNT), "robot.camera_link": CAMERA,
             "robot.camera_pose": [0.0] * 6}  # fmt: skip
    with pytest.raises(ScenarioError, match=r"robot\.arm_root: .*does not hang below"):
        load_scenario("experiment1").with_values(
            **table, **{"robot.arm_root": "right_arm_mount"}
        ).robot.build()
    with pytest.raises(ScenarioError, match=r"robot\.arm_tip: .*does not hang below"):
        load_scenario("experiment1").with_values(
            **table, **{"robot.arm_root": "left_arm_mount", "robot.arm_tip": "right_wrist"}
        ).robot.build()
    with pytest.raises(ScenarioError, match=r"robot\.arm_root.*no_such_link"):
        load_scenario("experiment1").with_values(
            **table, **{"robot.arm_root": "no_such_link"}
        ).robot.build()
    with pytest.raises(ScenarioError, match=r"robot\.arm_root.*shipped robot's arm is known"):
        load_scenario("experiment1").with_values(**{"robot.arm_root": "left_arm_mount"})


def test_left_arm_holds_the_target(left_arm):
    log = simulate(load_scenario("experiment1").with_values(duration=6.0), robot=left_arm)
    t, error = log["t"], log["xi_true"] - log["xi_d"]
    assert not np.any(log["target_lost"])
    assert np.max(np.abs(error[t >= 4.0])) < 8.0


# ---------------------------------------------------------------- a URDF that carries its arm
CYTON_ARM = ("shoulder_yaw_joint", "shoulder_pitch_joint", "elbow_pitch_joint")
TIAGO_ARM = tuple(f"arm_{i}_joint" for i in range(1, 8))


def _robot_file(tmp_path, keys: str) -> Path:
    """A robot file whose `base` is a copy of the reference robot's URDF (platform and arm)."""
    shutil.copy(REPO_ROOT / "urdf" / "pioneer_cyton.urdf", tmp_path / "robot.urdf")
    path = tmp_path / "robot.toml"
    path.write_text(
        '[robot]\nbase = "robot.urdf"\ncamera_link = "camera_optical_frame"\n'
        "camera_pose = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\nhome = [0.0, 0.0]\n" + keys
    )
    return path


def test_a_single_urdfs_chain_is_the_arm_and_the_rest_is_locked(tmp_path, cyton):
    """base = "robot.urdf" without arm: the shoulder yaw above arm_root is held at zero."""
    robot = load_scenario(_robot_file(tmp_path, 'arm_root = "shoulder_link"\n')).robot.build()
    assert robot.arm_joint_names == CYTON_ARM[1:]
    assert robot.velocity_names == ("u", "omega", *CYTON_ARM[1:])
    # independent reference: the whole robot's camera with its yaw at zero
    rng = np.random.default_rng(7)
    for pitches in rng.uniform(-0.8, 0.8, (3, 2)):
        cut = robot.camera_pose(robot.with_arm_positions(robot.neutral(), pitches))
        whole = cyton.camera_pose(cyton.with_arm_positions(cyton.neutral(), [0.0, *pitches]))
        assert np.allclose(cut.homogeneous, whole.homogeneous, atol=1e-12)
    # the URDF form takes the keys too
    urdf = RobotSection.from_toml(
        {"urdf": str(tmp_path / "robot.urdf"), "camera_frame": "camera_optical_frame",
         "arm_tip": "upper_arm_link", "home": [0.0, 0.0]}, str(tmp_path / "u.toml"),
    ).build()  # fmt: skip
    assert urdf.arm_joint_names == CYTON_ARM[:2]  # the elbow below arm_tip is locked


def test_a_robot_carrying_its_arm_locks_its_torso():
    """TIAGo from torso_lift_link: its seven arm joints move, the torso lift stays at zero."""
    whole = MobileManipulator.assemble("tiago", None, (0,) * 6, "arm_tool_link", (0,) * 6)
    arm = MobileManipulator.assemble("tiago", None, (0,) * 6, "arm_tool_link", (0,) * 6,
                                     arm_root="torso_lift_link")  # fmt: skip
    assert whole.arm_joint_names == ("torso_lift_joint", *TIAGO_ARM)
    assert arm.arm_joint_names == TIAGO_ARM
    posture = np.random.default_rng(3).uniform(-0.5, 0.5, 7)
    cut = arm.camera_pose(arm.with_arm_positions(arm.neutral(), posture))
    full = whole.camera_pose(whole.with_arm_positions(whole.neutral(), [0.0, *posture]))
    assert np.allclose(cut.homogeneous, full.homogeneous, atol=1e-12)


@pytest.mark.parametrize(
    ("keys", "field", "fragment"),
    [
        ('arm_root = "no_such_link"\n', "robot.arm_root", "'no_such_link'"),
        ('arm_root = "forearm_link"\narm_tip = "shoulder_link"\n', "robot.arm_tip",
         "'shoulder_link' does not hang below link 'forearm_link'"),
        ('arm_tip = "front_left_wheel_link"\n', "robot.arm_tip",
         "expected camera_link at or below arm_tip"),
    ],
    ids=["unknown-root", "tip-above-root", "camera-off-the-chain"],
)  # fmt: skip
def test_a_single_urdfs_bad_chain_names_the_key(tmp_path, keys, field, fragment):
    path = _robot_file(tmp_path, keys)
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path).robot.build()
    assert caught.value.field == field
    assert str(caught.value).startswith(f"{path}: {field}: ")
    assert fragment in str(caught.value)
