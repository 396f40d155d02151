"""The controller on ROS 2 across processes: ``pbvs-pin ros control`` and ``pbvs-pin ros sim``.

Needs the ``ros`` extra (``pip install '.[ros]'``): without it the module fails to import,
it is not skipped. Deselect it only by choice: ``-m 'not ros'``.

One node process serves the whole module (its start, imports and kernels from the cache,
takes about 15 s): Experiment 1 against the simulated robot first, then the stop cases
against a stand-in robot played by this process, then SIGINT. Every process runs on a
``ROS_DOMAIN_ID`` chosen for this test run, with discovery kept to this machine.
"""

import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import rclpy  # without the ros extra this fails: the module errors, it is not skipped
from conftest import REPO_ROOT
from std_msgs.msg import Bool

import pbvs_pin
from pbvs_pin.ros.stand_in import StandInRobot

pytestmark = pytest.mark.ros

PERIOD = 0.01  # [s] the controller's period (Experiment 1: 100 Hz)
SENSOR_TIMEOUT = 0.05  # [s] the node's default sensor_timeout
DURATION = 6.0  # [s] simulated
WINDOW_START = 3.0  # [s] the error is judged over [3, 6] s
ERROR_BOUND = 8.0  # [px] Experiment 1's rule; see test_experiment1_holds_the_target_...
STAND_IN_START = 100.0  # [s] the stand-in robot's clock starts after the simulation's


def _environment() -> dict:
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(10 + os.getpid() % 80)  # one per test run
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["MUJOCO_GL"] = env.get("MUJOCO_GL", "egl")
    return env


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "pbvs_pin.cli", "ros", *args]


@pytest.fixture(scope="module")
def ros_env():
    env = _environment()
    saved = {key: os.environ.get(key) for key in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")}
    os.environ.update({key: env[key] for key in saved})
    yield env
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


@pytest.fixture(scope="module")
def node(ros_env):
    """The controller node, following /clock."""
    process = subprocess.Popen(
        _cli("control", "experiment1", "--use-sim-time"),
        env=ros_env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    line = process.stdout.readline()  # printed once the node is built
    assert "running experiment1" in line, process.stderr.read()
    yield process
    if process.poll() is None:
        process.send_signal(signal.SIGKILL)
        process.wait(10)


def test_experiment1_holds_the_target_across_processes(node, ros_env, tmp_path):
    """Experiment 1, node and simulated robot in two processes over DDS, 6 s in lockstep.

    The bound: over [3, 6] s, max |xi - xi_d| (true projection, in the simulator) < 8 px,
    Experiment 1's rule (the report's, on the last 5 s). ``simulate()`` on the same scenario
    (rendered camera, Pinocchio plant, 6 s) gives 0.87 px there; across processes 1.20 px in
    each of six runs (docs/ros2.md). A lost target or an oscillation breaks the bound.

    Every step but the first is answered in lockstep (599 of 600 in every run since the
    transport of ``pbvs_pin/ros/fastdds.xml``). With Fast DDS's defaults, messages lost beside
    the images were held until resent, and 93-96 % of the steps were answered: this count
    fails when that comes back.
    """
    summary_path = tmp_path / "summary.json"
    started = time.perf_counter()
    sim = subprocess.run(
        _cli("sim", "experiment1", "--engine", "pinocchio", "--duration", str(DURATION),
             "--lockstep", "1", "--wait", "60", "--summary", str(summary_path),
             "--bag", str(tmp_path / "bag")),
        env=ros_env, capture_output=True, text=True, timeout=150,
    )  # fmt: skip
    assert sim.returncode == 0, sim.stderr[-2000:]
    summary = json.loads(summary_path.read_text())
    t, error = np.array(summary["t"]), np.abs(np.array(summary["error"]))
    steps = round(DURATION / PERIOD)
    assert summary["fresh_commands"] >= 0.99 * steps, summary["fresh_commands"]
    assert error[0].max() > 100.0  # the target starts far from xi_d (150 px): it was servoed
    held = error[t >= WINDOW_START].max()
    assert held < ERROR_BOUND, f"max |e| over [3, 6] s: {held:.2f} px"
    print(f"ROS Experiment 1: {held:.2f} px over [3, 6] s; {time.perf_counter() - started:.0f} s")
    _check_bag(tmp_path / "bag", summary, steps)


def _check_bag(bag, summary: dict, steps: int) -> None:
    """rosbags reads the bag back: every topic with its standard type, one reading per step,
    and the platform commands it holds are those the plant applied (the summary's)."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    expected = {
        "/joint_states": "sensor_msgs/msg/JointState", "/odom": "nav_msgs/msg/Odometry",
        "/clock": "rosgraph_msgs/msg/Clock", "/cmd_vel": "geometry_msgs/msg/Twist",
        "/arm_controller/commands": "std_msgs/msg/Float64MultiArray",
        "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
        "/camera/image_raw": "sensor_msgs/msg/Image",
        "/camera/camera_info": "sensor_msgs/msg/CameraInfo",
        "/tf": "tf2_msgs/msg/TFMessage",
    }  # fmt: skip
    try:
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_KILTED)) as reader:
            found = {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
            assert {topic: kind for topic, (kind, _) in found.items()} == expected
            assert found["/joint_states"][1] == steps
            assert found["/cmd_vel"][1] == summary["commands_received"]
            assert found["/tf"][1] == steps  # ROS from pip cannot publish it; the bag has it
            tf = [c for c in reader.connections if c.topic == "/tf"]
            first = reader.deserialize(next(reader.messages(connections=tf))[2], tf[0].msgtype)
            children = {transform.child_frame_id for transform in first.transforms}
            assert {"camera_optical_frame", "target", "base_link"} <= children
            commands = {}
            cmd_vel = [c for c in reader.connections if c.topic == "/cmd_vel"]
            for connection, stamp, raw in reader.messages(connections=cmd_vel):
                message = reader.deserialize(raw, connection.msgtype)
                commands[round(stamp * 1e-9, 6)] = [message.linear.x, message.angular.z]
        for t, v_ref in zip(summary["t"][1:], summary["v_ref"][1:], strict=True):
            assert np.allclose(commands[t], v_ref[:2], atol=1e-6), t
    finally:
        shutil.rmtree(bag, ignore_errors=True)  # 30 images a second: 200 MB


def _own_node_run(env: dict, node_for: str, sim: tuple[str, ...], duration: float,
                  summary_path, rate_factor: float = 1.0) -> dict:  # fmt: skip
    """A node of its own for ``node_for`` (a scenario or robot), waiting for readings stamped
    with its step's time, and the simulated robot (``ros sim`` with ``sim``), both on ``env``'s
    domain, for ``duration`` simulated seconds; the sim's summary."""
    node = subprocess.Popen(
        _cli("control", node_for, "--use-sim-time", "--ros-args", "-p", "wait_for_readings:=true"),
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert "running" in node.stdout.readline(), node.stderr.read()
        sim = subprocess.run(
            _cli("sim", *sim, "--engine", "pinocchio", "--duration", str(duration),
                 "--lockstep", "1", "--wait", "60", "--rate-factor", str(rate_factor),
                 "--summary", str(summary_path)),
            env=env, capture_output=True, text=True, timeout=300,
        )  # fmt: skip
        assert sim.returncode == 0, sim.stderr[-2000:]
    finally:
        node.send_signal(signal.SIGINT)
        node.wait(30)
    return json.loads(summary_path.read_text())


def _domain(ros_env: dict, offset: int) -> dict:
    """``ros_env`` on a domain apart from the module's node (whose commands would mix in)."""
    return {**ros_env, "ROS_DOMAIN_ID": str(int(ros_env["ROS_DOMAIN_ID"]) + offset)}


def test_a_holonomic_robot_holds_experiment1_across_processes(ros_env, tmp_path):
    """Dexmate Vega-1 (a swerve base: ``cmd_vel`` carries vx, vy and wz) on the Pinocchio plant,
    rendered camera, node and simulated robot as two processes, Experiment 1's rule over
    [3, 6] s (the report's window shortened as above).

    The node waits for readings stamped with its step's time (``wait_for_readings``): 3.33 px
    in each of three runs, 3.03 px for ``simulate()`` on the same scenario; without the wait,
    3.33 px too now that the transport loses nothing (docs/ros2.md).
    """
    robot = str(REPO_ROOT / "robots" / "vega_1.toml")
    summary = _own_node_run(_domain(ros_env, 100), robot, ("experiment1", "--robot", robot),
                            DURATION, tmp_path / "summary.json")  # fmt: skip
    t, error = np.array(summary["t"]), np.abs(np.array(summary["error"]))
    assert summary["fresh_commands"] >= 0.99 * round(DURATION / PERIOD)
    assert error[0].max() > 100.0
    held = error[t >= WINDOW_START].max()
    assert held < ERROR_BOUND, f"max |e| over [3, 6] s: {held:.2f} px"
    sideways = np.abs(np.array(summary["v_ref"])[:, 1])
    assert sideways.max() > 1e-3  # the base was driven sideways, through cmd_vel's linear.y
    print(f"ROS Experiment 1, Vega-1: {held:.2f} px over [3, 6] s")


def test_experiment2_holds_the_target_past_the_obstacle_across_processes(ros_env, tmp_path):
    """Experiment 2 (the obstacle: the ``scan`` path too) on the reference robot, its whole
    60 s, simulated at up to three times the wall clock (lockstep keeps every step answered):
    Experiment 2's rule across processes, clause by clause: the error over [7, 60] s (past the
    transient) under 8 px, the clearance above 0, and the arm within 0.1 rad of ``theta_d``
    over the last 5 s (eq. 19's posture clause).

    Measured: 2.16 px over [7, 60] s, 0.37 px over the last 5 s, clearance 0.065 m, posture
    0.037 rad, 5 999 of 6 000 steps answered, 32 s of wall-clock time. Over the first 20 s
    (the test's earlier length, before the transport fix made 60 s affordable): 1.39 px over
    [7, 20] s in each of six runs; ``simulate()`` on the same 20 s (rendered camera): 1.17 px
    and 0.0647 m.
    """
    duration, window = 60.0, 7.0
    summary = _own_node_run(_domain(ros_env, 110), "experiment2", ("experiment2",), duration,
                            tmp_path / "summary.json", rate_factor=3.0)  # fmt: skip
    t, error = np.array(summary["t"]), np.abs(np.array(summary["error"]))
    assert summary["fresh_commands"] >= 0.99 * round(duration / PERIOD)
    held = error[t >= window].max()
    assert held < ERROR_BOUND, f"max |e| over [7, 60] s: {held:.2f} px"
    clearance = np.array([np.inf if c is None else c for c in summary["clearance"]], dtype=float)
    closest = t[np.argmin(clearance)]
    assert 15.0 < closest < 25.0  # the closest approach (18.7 s in simulate()) is inside the run
    assert clearance.min() > 0.0, f"clearance {clearance.min():.4f} m at {closest:.2f} s"
    last = t >= t[-1] - 5.0 + 1e-9
    arm, target = np.array(summary["arm"]), np.array(summary["posture_target"])
    posture = np.abs(arm[last] - target).max()
    assert posture < 0.1, f"arm {posture:.3f} rad from theta_d over the last 5 s"
    print(f"ROS Experiment 2: {held:.2f} px over [7, 60] s, clearance {clearance.min():.4f} m, "
          f"posture {posture:.3f} rad")


@pytest.fixture(scope="module")
def stand_in(node, ros_env):
    rclpy.init()
    robot = StandInRobot(pbvs_pin.load_scenario("experiment1"), STAND_IN_START, PERIOD)
    deadline = time.perf_counter() + 30
    while not robot.commands and time.perf_counter() < deadline:  # discovery
        robot.tick()
    yield robot
    robot.node.destroy_node()
    rclpy.try_shutdown()


def _running(robot: StandInRobot) -> None:
    """Ten normal periods; the commands at their end are not zero (a stop can be seen)."""
    start = robot.t
    for _ in range(10):
        robot.tick()
    recent = robot.since(start + 5 * PERIOD)
    assert recent and all(np.abs(c).max() > 1e-4 for c in recent), recent


def _zero_within_three_periods(robot: StandInRobot, trigger: float, ticks: int, **kwargs) -> None:
    for _ in range(ticks):
        robot.tick(**kwargs)
    after = robot.since(trigger + 3 * PERIOD)
    assert len(after) >= ticks // 2, "too few commands came"
    assert all(np.all(c == 0.0) for c in after), after


def test_stale_odometry_stops_the_commands(stand_in):
    _running(stand_in)
    last_odom = stand_in.t
    _zero_within_three_periods(stand_in, last_odom + SENSOR_TIMEOUT, 15, odom=False)


def test_stale_joint_states_stop_the_commands(stand_in):
    _running(stand_in)
    last = stand_in.t
    _zero_within_three_periods(stand_in, last + SENSOR_TIMEOUT, 15, joints=False)


def test_bad_input_stops_the_commands_and_the_node_goes_on(stand_in, node):
    _running(stand_in)
    _zero_within_three_periods(stand_in, stand_in.t, 10, bad=True)
    assert node.poll() is None
    _running(stand_in)  # the next good reading clears it


def test_estop_stops_the_commands_until_released(stand_in):
    _running(stand_in)
    stand_in.estop.publish(Bool(data=True))
    stand_in.spin(0.1)
    _zero_within_three_periods(stand_in, stand_in.t, 10)
    stand_in.estop.publish(Bool(data=False))
    stand_in.spin(0.1)
    _running(stand_in)


def test_scenario_keys_are_ros_parameters(stand_in):
    """``-p estimator.hold:=0.7`` changes the controller's settings; an unknown key is refused."""
    from rclpy.parameter import Parameter

    from pbvs_pin.exceptions import ScenarioError
    from pbvs_pin.ros.node import ControlNode

    scenario = pbvs_pin.load_scenario("experiment1")
    assert scenario.estimator.hold != 0.7
    given = [Parameter("estimator.hold", value=0.7), Parameter("sensor_timeout", value=0.08)]
    control = ControlNode(scenario, given)
    try:
        assert control.controller.settings.estimator.hold == 0.7
        assert control.sensor_timeout == 0.08
    finally:
        control.destroy_node()
    with pytest.raises(ScenarioError, match=r"estimator\.nonsense"):
        ControlNode(scenario, [Parameter("estimator.nonsense", value=1.0)])


def test_sigint_publishes_zero_and_exits(stand_in, node):
    _running(stand_in)
    count = len(stand_in.commands)
    node.send_signal(signal.SIGINT)
    stand_in.spin(2.0)
    assert node.wait(15) == 0
    last = stand_in.commands[count:]
    assert last and np.all(last[-1][1] == 0.0), last


def test_without_ros_the_command_says_how_to_install(monkeypatch, capsys):
    from pbvs_pin import cli
    from pbvs_pin.ros import commands

    real = commands.importlib.import_module

    def missing(name, *args):
        if name.startswith("pbvs_pin.ros."):
            raise ImportError("No module named 'rclpy'")
        return real(name, *args)

    monkeypatch.setattr(commands.importlib, "import_module", missing)
    assert cli.main(["ros", "sim", "experiment1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install 'pbvs_pin[ros]'" in err, err


def test_message_conventions():
    """Stamps, the laser's clockwise angle, odometry's yaw, bgr8 images, CameraInfo's K."""
    from sensor_msgs.msg import CameraInfo, Image, LaserScan

    from pbvs_pin.exceptions import ControlInputError, NonFiniteValue
    from pbvs_pin.ros import messages

    assert messages.seconds(messages.stamp(12.345678901)) == pytest.approx(12.345678901, abs=1e-9)
    scan = LaserScan(angle_min=-1.0, angle_increment=0.5, range_min=0.1, range_max=5.0)
    scan.ranges = [3.0, 9.0, 2.0, float("nan"), 0.05]  # angles -1, -0.5, 0, 0.5, 1 rad
    assert messages.nearest_return(scan) == (2.0, -0.0)
    scan.ranges = [3.0, 9.0, 4.0, 1.5, 8.0]  # nearest at +0.5 rad (left): alpha = -0.5 rad
    assert messages.nearest_return(scan) == (1.5, -0.5)
    odom = messages.Odometry()
    odom.pose.pose.orientation.z, odom.pose.pose.orientation.w = np.sin(0.15), np.cos(0.15)
    odom.twist.twist.linear.x, odom.twist.twist.angular.z = 0.2, -0.1
    planar, velocity = messages.platform_reading(odom, 2)
    assert planar[2] == pytest.approx(0.3) and velocity.tolist() == [0.2, -0.1]
    odom.twist.twist.linear.x = float("nan")
    with pytest.raises(NonFiniteValue):
        messages.platform_reading(odom, 2)
    pixel = np.array([[[10, 20, 30], [40, 50, 60]]], dtype=np.uint8)  # one row, two pixels
    bgr = Image(height=1, width=2, encoding="bgr8", step=6, data=pixel[:, :, ::-1].tobytes())
    assert np.array_equal(messages.image_array(bgr), pixel)
    with pytest.raises(ControlInputError, match="encoding"):
        messages.image_array(Image(height=1, width=2, encoding="mono8", step=2, data=bytes(2)))
    camera = pbvs_pin.CameraIntrinsics()
    info = messages.camera_info(0.0, camera, "camera_optical_frame")
    messages.check_camera_info(info, camera)  # its own intrinsics pass
    info = CameraInfo(height=582, width=628, k=[610.0, 0, 314, 0, 610.0, 291, 0, 0, 1])
    with pytest.raises(ControlInputError, match=r"camera_info\.k"):
        messages.check_camera_info(info, camera)


def test_the_simulated_robot_stops_when_commands_stop_coming():
    """A controller killed with SIGKILL sends nothing: past the timeout the robot gets zero."""
    from pbvs_pin.ros.sim_robot import applied_command

    base, arm = (1.0, np.array([0.2, -0.1])), (1.0, np.array([0.3, 0.0, -0.3]))
    assert applied_command(1.05, base, arm, 0.1, 2, 5).tolist() == [0.2, -0.1, 0.3, 0.0, -0.3]
    assert applied_command(1.11, base, arm, 0.1, 2, 5).tolist() == [0.0] * 5
    assert applied_command(1.05, None, arm, 0.1, 2, 5).tolist() == [0.0, 0.0, 0.3, 0.0, -0.3]
    bad = (1.0, np.array([np.nan, 0.1]))
    assert applied_command(1.05, bad, None, 0.1, 2, 5).tolist() == [0.0] * 5


def test_a_step_waits_for_readings_stamped_with_its_time(stand_in, monkeypatch):
    """``wait_for_readings``: a step whose joint_states and odom are not yet those of its
    time runs when both come (at 1.15 and 1.16 s a stamp summed from sec and nanosec is below
    the clock's time, summed from nanoseconds, in its last bit: the tolerance covers it)."""
    from rclpy.parameter import Parameter

    from pbvs_pin.ros import messages
    from pbvs_pin.ros.node import ControlNode

    control = ControlNode(
        pbvs_pin.load_scenario("experiment1"), [Parameter("wait_for_readings", value=True)]
    )
    first, second = 115 * PERIOD, 116 * PERIOD  # as the node's clock has them
    sent, clock = [], [first]
    monkeypatch.setattr(control, "now", lambda: clock[0])
    monkeypatch.setattr(control, "_publish", lambda v_ref: sent.append((clock[0], v_ref)))
    names, arm = control.arm_joints, control.model.home_arm
    rates, base = np.full(len(names), 0.1), np.array([0.1, 0.05])

    def reading(topic: str, t: float) -> None:
        if topic == "joint_states":
            control._on_joints(messages.joint_state(t, names, arm + rates * t, rates))
        else:
            control._on_odom(messages.odometry(t, [0.1 * t, 0.0, 0.0], base, "odom", "base"))

    try:
        reading("joint_states", first)
        reading("odom", first)
        control.step()
        assert [t for t, _ in sent] == [first]
        clock[0] = second
        control.step()  # its readings have not come
        reading("joint_states", second)
        assert len(sent) == 1
        reading("odom", second)  # now both have: the step runs
        assert [t for t, _ in sent] == [first, second]
        assert not control._bad and control._t == second
    finally:
        control.destroy_node()
