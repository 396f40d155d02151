"""A joint whose effort limit cannot carry the robot's weight at home is named, not left to sag.

Reference: the load of a vertical prismatic lift is the weight it carries, m g, by hand.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from pbvs_pin import MobileManipulator
from pbvs_pin.exceptions import PbvsWarning
from pbvs_pin.holding import overloaded_joints, warn_overloaded

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


def _robot(tmp_path, effort: float) -> MobileManipulator:
    path = tmp_path / "lift_arm.urdf"
    path.write_text(LIFT_ARM.replace("EFFORT", str(effort)))
    robot = MobileManipulator.assemble(
        base="pioneer3at", arm=str(path), mount=(0.0, 0.0, 0.27, 0.0, 0.0, 0.0),
        camera_link="tool_link",
    )  # fmt: skip
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
