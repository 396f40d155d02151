"""A joint whose effort limit cannot carry the robot's weight at home is named, not left to sag,
and the home solver finds a home every joint holds.

References, by hand: the load of a vertical prismatic lift is the weight it carries, m g; the
load of a pitch joint holding a point mass m at l along a link at angle theta above the
horizontal is m g l cos(theta).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pbvs_pin import MobileManipulator
from pbvs_pin.bringup.holding import holding_rows, overloaded_joints, warn_overloaded
from pbvs_pin.bringup.home import HomeCriteria, compute_home
from pbvs_pin.exceptions import PbvsWarning
from pbvs_pin.sim.scenario import load_scenario

GRAVITY = 9.81  # [m/s^2], Pinocchio's default model.gravity
CARRIED = 5.0 + 1.0  # [kg]: the lift's carriage and the pan link above it

LIFT_ARM = """<?xml version="1.0"?>
<robot name="lift_arm">
  <link name="lift_base"/>
  <link name="carriage">
    <inertial><mass value="5.0"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <link name="pan_link">
    <inertial><mass value="1.0"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
  </link>
  <link name="tool_link"/>
  <joint name="lift_joint" type="prismatic">
    <parent link="lift_base"/><child link="carriage"/><axis xyz="0 0 1"/>
    <limit effort="EFFORT" velocity="0.2" lower="0.0" upper="0.4"/>
  </joint>
  <joint name="pan_joint" type="revolute">
    <parent link="carriage"/><child link="pan_link"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit effort="5" velocity="1.0" lower="-2.0" upper="2.0"/>
  </joint>
  <joint name="tool_joint" type="fixed">
    <parent link="pan_link"/><child link="tool_link"/><origin xyz="0.1 0 0"/>
  </joint>
</robot>
"""


def _mounted(path: Path, text: str) -> MobileManipulator:
    """The arm URDF ``text``, written to ``path``, on the reference platform's top plate."""
    path.write_text(text)
    return MobileManipulator.assemble(
        base="pioneer3at", arm=str(path), mount=(0.0, 0.0, 0.27, 0.0, 0.0, 0.0),
        camera_link="tool_link",
    )  # fmt: skip


def _robot(tmp_path, effort: float) -> MobileManipulator:
    robot = _mounted(tmp_path / "lift_arm.urdf", LIFT_ARM.replace("EFFORT", str(effort)))
    robot.home_arm = np.array([0.2, 0.0])
    return robot


def test_a_lift_too_weak_for_its_load_is_named_with_load_and_limit(tmp_path):
    robot = _robot(tmp_path, effort=10.0)
    [(name, load, limit)] = overloaded_joints(robot, robot.home())
    assert name == "lift_joint"
    assert load == pytest.approx(CARRIED * GRAVITY, rel=1e-9)
    assert limit == 10.0
    with pytest.warns(PbvsWarning, match=r"my_robot\.toml: .*lift_joint 58\.86 > 10; "):
        warn_overloaded(robot, "my_robot.toml")


def test_a_lift_strong_enough_raises_no_warning(tmp_path):
    robot = _robot(tmp_path, effort=CARRIED * GRAVITY * 1.01)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert warn_overloaded(robot, "my_robot.toml") == []


PITCH_MASS, PITCH_LENGTH, PITCH_LIMIT = 2.0, 0.5, 20.0  # [kg], [m], [N m]

PITCH_ARM = f"""<?xml version="1.0"?>
<robot name="pitch_arm">
  <link name="arm_base"/>
  <link name="boom">
    <inertial><origin xyz="{PITCH_LENGTH} 0 0"/><mass value="{PITCH_MASS}"/>
      <inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/></inertial>
  </link>
  <link name="tool_link"/>
  <joint name="pitch_joint" type="revolute">
    <parent link="arm_base"/><child link="boom"/><axis xyz="0 1 0"/>
    <limit effort="{PITCH_LIMIT}" velocity="1.0" lower="-2.0" upper="2.0"/>
  </joint>
  <joint name="tool_joint" type="fixed">
    <parent link="boom"/><child link="tool_link"/><origin xyz="{PITCH_LENGTH} 0 0"/>
  </joint>
</robot>
"""


@pytest.mark.parametrize("theta", [-1.2, -0.3, 0.0, 0.7, 1.5])
def test_holding_rows_are_the_share_of_the_limit_left_after_gravity(tmp_path, theta):
    """h = 1 - margin - m g l |cos(theta)| / limit; dh/dtheta = sign(cos) m g l sin / limit.

    theta is the rotation about y, which lowers the boom's tip below the joint for theta > 0.
    """
    robot = _mounted(tmp_path / "pitch_arm.urdf", PITCH_ARM)
    q = robot.with_arm_positions(robot.neutral(), [theta])
    rows, slope = holding_rows(robot, q, margin=0.2)
    moment = PITCH_MASS * GRAVITY * PITCH_LENGTH
    assert rows == pytest.approx([0.8 - moment * abs(np.cos(theta)) / PITCH_LIMIT], abs=1e-9)
    expected = np.sign(np.cos(theta)) * moment * np.sin(theta) / PITCH_LIMIT
    assert slope.shape == (1, 1)
    assert slope[0, 0] == pytest.approx(expected, abs=1e-9)


def test_a_robot_without_effort_limits_has_no_rows(tmp_path):
    robot = _robot(tmp_path, effort=0.0)  # effort 0 in a URDF: not given
    assert robot.model.effortLimit[robot.model.nv - 1] > 0.0  # the pan joint keeps its 5 N m
    rows, slope = holding_rows(robot, robot.home(), margin=0.2)
    assert rows.shape == (1,) and slope.shape == (1, 2)  # the pan joint only


def test_the_pr2_home_is_one_its_shoulder_holds(load):
    """The PR2's URDF leaves out its shoulder's spring counterbalance: the home found without
    the effort rows loads the right shoulder lift with 35.2 N m against its 30 N m limit; the
    home solver then keeps every joint's load within 80 % of its limit, with no warning."""
    path = Path(__file__).parents[1] / "robots" / "pr2.toml"
    with warnings.catch_warnings():
        warnings.simplefilter("error", PbvsWarning)
        robot = load_scenario(path).robot.build()
    model = robot.model
    for name in robot.arm_joint_names:
        index = model.joints[model.getJointId(name)].idx_v
        limit = model.effortLimit[index]
        load = abs(pin.computeGeneralizedGravity(model, model.createData(), robot.home())[index])
        assert load <= 0.8 * limit + 1e-6, name
    sagging = compute_home(robot, HomeCriteria(effort_margin=None))
    robot.home_arm = sagging
    [(name, load, limit)] = overloaded_joints(robot, robot.home())
    assert (name, round(load, 1), limit) == ("r_shoulder_lift_joint", 35.2, 30.0)


def test_a_home_every_joint_holds_is_kept_as_found(load):
    """The effort rows are added only when the home found without them overloads a joint."""
    robot = load("pioneer_cyton")
    assert np.array_equal(
        compute_home(robot), compute_home(robot, HomeCriteria(effort_margin=None))
    )
