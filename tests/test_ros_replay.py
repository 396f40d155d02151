"""``pbvs-pin ros replay-bag``: a bag's readings stepped through the controller offline.

Needs the ``ros`` extra (messages are serialised by ROS itself); no ROS process is started.
"""

import numpy as np
import pytest
from rosgraph_msgs.msg import Clock

from pbvs_pin.controller import Controller
from pbvs_pin.exceptions import LogError
from pbvs_pin.ros import messages
from pbvs_pin.ros.bag import BagRecorder
from pbvs_pin.ros.bag_replay import replay_bag
from pbvs_pin.sim.scenario import load_scenario

pytestmark = pytest.mark.ros

PERIOD = 0.01  # [s] Experiment 1's control period
STEPS = 40
BASE = np.array([0.1, 0.05])  # [m/s, rad/s] the platform's reading, constant
ARM_RATE = 0.1  # [rad/s] every arm joint's reading, constant


def _record(path, scenario) -> np.ndarray:
    """A bag as the simulated robot writes it, the commands from a controller stepped here on
    the same readings (no frame: the braking command of eq. (20), not zero). Returns them."""
    controller = Controller.from_scenario(scenario)
    robot = controller.model
    rates = np.full(robot.n_arm, ARM_RATE)
    recorder = BagRecorder(path)
    commands = []
    for k in range(1, STEPS + 1):
        t = k * PERIOD
        arm = robot.home_arm + rates * t
        planar = np.array([0.2 * t, 0.0, BASE[1] * t])
        q = robot.home()
        q[:4] = planar[0], planar[1], np.cos(planar[2]), np.sin(planar[2])
        q = robot.with_arm_positions(q, arm)
        v_ref = controller.step(t, q, np.concatenate([BASE, rates]), None, None).v_ref
        commands.append(v_ref)
        names = robot.arm_joint_names
        recorder.write("/joint_states", messages.joint_state(t, names, arm, rates), t)
        recorder.write("/odom", messages.odometry(t, planar, BASE, "odom", "drive_footprint"), t)
        recorder.write("/clock", Clock(clock=messages.stamp(t)), t)
        recorder.write("/cmd_vel", messages.twist(v_ref[:2]), t)
        recorder.write("/arm_controller/commands", messages.arm_command(v_ref[2:]), t)
    recorder.close()
    return np.array(commands)


def test_replay_reproduces_the_commands_of_its_own_bag(tmp_path):
    """Every command identical with the readings of the step; not with those of the step
    before (the replay tells them apart)."""
    scenario = load_scenario("experiment1")
    commands = _record(tmp_path / "bag", scenario)
    assert np.abs(commands).max() > 1e-3  # the controller did command something
    same = replay_bag(tmp_path / "bag", scenario)
    assert (same["steps"], same["identical"]) == (STEPS, STEPS), same
    lagged = replay_bag(tmp_path / "bag", scenario, lag=1)
    assert lagged["steps"] == STEPS - 1
    assert lagged["identical"] < lagged["steps"], lagged
    assert lagged["first_difference_s"] == pytest.approx(2 * PERIOD)


def test_replay_of_a_folder_that_is_not_a_bag_is_a_log_error(tmp_path):
    with pytest.raises(LogError, match="rosbag2"):
        replay_bag(tmp_path, load_scenario("experiment1"))
