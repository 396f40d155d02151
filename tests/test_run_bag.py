"""``pbvs-pin run ... --bag DIR``: a simulated run as a ROS 2 bag (issue 29, item 5).

Read back three ways that do not share the writer's code: ``rosbags`` (its own CDR decoder),
Foxglove's MCAP libraries (``mcap`` with ``mcap-ros2-support``, decoding every message from the
schemas the file carries, as Foxglove does), and OpenCV for the images. The references are the
run's log (its arrays, written by the simulation) and Pinocchio's camera pose.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pinocchio as pin
import pytest
from conftest import REPO_ROOT
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

import pbvs_pin.ros  # noqa: F401  (the middleware, before rclpy's messages)
from pbvs_pin.exceptions import LogError
from pbvs_pin.ros.bag_replay import replay_bag
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.study.experiments import run_scenario
from pbvs_pin.viz.eye_view import eye_views
from pbvs_pin.viz.run_scene import log_robot

DURATION = 0.6
"""Simulated seconds: 30 logged instants at 50 Hz, 6 images at 10 Hz."""


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Experiment 2 (the obstacle, the target moving) for 0.6 s, with its bag."""
    folder = tmp_path_factory.mktemp("run_bag")
    scenario = load_scenario("experiment2").with_values(duration=DURATION)
    log, _ = run_scenario(scenario, folder / "out", progress=False, figures=False,
                          bag=folder / "bag")  # fmt: skip
    messages: dict[str, list] = {}
    with AnyReader([folder / "bag"], default_typestore=get_typestore(Stores.ROS2_KILTED)) as bag:
        for connection, stamp, raw in bag.messages():
            message = bag.deserialize(raw, connection.msgtype)
            messages.setdefault(connection.topic, []).append((stamp * 1e-9, message))
    return log, messages, folder / "bag"


def test_every_topic_holds_every_logged_instant(recorded):
    log, messages, _ = recorded
    samples = len(log["t"])
    assert samples == 30
    counts = {topic: len(found) for topic, found in messages.items()}
    assert counts == {
        "/pbvs_pin/run": 1, "/clock": samples, "/tf": samples, "/joint_states": samples,
        "/odom": samples, "/cmd_vel": samples, "/arm_controller/commands": samples,
        "/diagnostics": samples, "/camera/camera_info": 6, "/camera/image_raw/compressed": 6,
    }  # fmt: skip
    stamps = [stamp for stamp, _ in messages["/clock"]]
    np.testing.assert_allclose(stamps, log["t"], atol=1e-9)


def test_the_messages_carry_the_log(recorded):
    log, messages, _ = recorded
    joints = np.array([m.position for _, m in messages["/joint_states"]])
    np.testing.assert_allclose(joints, log["arm"], atol=1e-12)
    cmd_vel = np.array([[m.linear.x, m.angular.z] for _, m in messages["/cmd_vel"]])
    np.testing.assert_allclose(cmd_vel, log["v_ref"][:, :2], atol=1e-12)
    arm = np.array([m.data for _, m in messages["/arm_controller/commands"]])
    np.testing.assert_allclose(arm, log["v_ref"][:, 2:], atol=1e-12)
    odom = messages["/odom"][-1][1].pose.pose
    x, y, yaw = log["platform_pose"][-1]
    assert (odom.position.x, odom.position.y) == pytest.approx((x, y), abs=1e-12)
    assert 2 * np.arctan2(odom.orientation.z, odom.orientation.w) == pytest.approx(yaw)
    values = {kv.key: kv.value for kv in messages["/diagnostics"][-1][1].status[0].values}
    error = log["xi"][-1] - log["xi_d"][-1]
    assert float(values["max_abs_error_px"]) == pytest.approx(np.max(np.abs(error)), abs=1e-3)
    assert messages["/pbvs_pin/run"][0][1].data.startswith("{")


def test_tf_holds_the_camera_and_the_target_where_the_log_has_them(recorded):
    log, messages, _ = recorded
    robot = log_robot(log)
    for i in (0, len(log["t"]) - 1):
        tf = {t.child_frame_id: t for t in messages["/tf"][i][1].transforms}
        assert all(t.header.frame_id == "odom" for t in tf.values())
        assert {"base_link", "drive_footprint", "camera_optical_frame", "target"} <= tf.keys()
        camera = tf["camera_optical_frame"].transform
        rotation = camera.rotation
        quaternion = pin.Quaternion(rotation.w, rotation.x, rotation.y, rotation.z)
        expected = robot.camera_pose(log["q"][i])
        np.testing.assert_allclose(quaternion.toRotationMatrix(), expected.rotation, atol=1e-9)
        translation = camera.translation
        position = [translation.x, translation.y, translation.z]
        np.testing.assert_allclose(position, expected.translation, atol=1e-12)
        target = tf["target"].transform.translation
        np.testing.assert_allclose([target.x, target.y, target.z], log["target"][i], atol=1e-12)


def test_the_images_are_the_camera_view_in_jpeg(recorded):
    log, messages, _ = recorded
    info = messages["/camera/camera_info"][0][1]
    stamp, first = messages["/camera/image_raw/compressed"][0]
    assert first.format == "jpeg" and stamp == pytest.approx(0.0)
    bgr = cv2.imdecode(np.frombuffer(bytes(first.data), np.uint8), cv2.IMREAD_COLOR)
    assert bgr.shape == (info.height, info.width, 3)
    drawn = eye_views(log, np.array([0]), marked=False)[0]
    difference = np.abs(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(float) - drawn)
    assert difference.mean() < 3.0  # JPEG at quality 90 (a wrong frame differs by tens)
    later = [stamp for stamp, _ in messages["/camera/image_raw/compressed"]]
    np.testing.assert_allclose(np.diff(later), 0.1, atol=1e-9)


def test_foxglove_reads_every_message_from_the_schemas_in_the_file(recorded):
    """Foxglove's own MCAP reader and ROS 2 decoder, with no ROS and no type store."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    _, messages, bag = recorded
    (mcap_file,) = Path(bag).glob("*.mcap")
    counts: dict[str, int] = {}
    with mcap_file.open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for schema, channel, _, decoded in reader.iter_decoded_messages():
            assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/tf":
                assert decoded.transforms[-2].child_frame_id == "camera_optical_frame"
    assert counts == {topic: len(found) for topic, found in messages.items()}


def test_replay_refuses_a_run_bag_in_one_line(recorded):
    with pytest.raises(LogError, match="pbvs-pin run --bag"):
        replay_bag(recorded[2], load_scenario("experiment2"))


def test_the_command_refuses_a_bag_folder_that_exists_before_running(tmp_path):
    (tmp_path / "bag").mkdir()
    done = subprocess.run(
        [sys.executable, "-m", "pbvs_pin.cli", "run", "experiment1", "--duration", "0.1",
         "--out", str(tmp_path / "out"), "--bag", str(tmp_path / "bag")],
        capture_output=True, text=True, timeout=300,
        env={**os.environ, "PYTHONPATH": str(REPO_ROOT)},
    )  # fmt: skip
    assert done.returncode == 2
    assert done.stderr.strip() == (
        f"pbvs-pin: error: {tmp_path / 'bag'}: exists; expected a new folder; nothing was run"
    )
    assert not (tmp_path / "out").exists()


def test_each_message_kind_reads_back_the_same_in_ros_and_rosbags():
    """The bags' bytes are rosbags' CDR: ROS deserialises them to the message it built.

    ROS's own serialiser pads an empty sequence of doubles (a JointState without efforts) by
    4 bytes that rosbags refuses; this is why the bags are not serialised by ROS.
    """
    from rclpy.serialization import deserialize_message, serialize_message
    from rosgraph_msgs.msg import Clock

    from pbvs_pin.model.camera import CameraIntrinsics
    from pbvs_pin.ros import messages
    from pbvs_pin.ros.bag import message_type, store_message

    store = get_typestore(Stores.ROS2_KILTED)
    built = [
        messages.joint_state(0.1, ("a", "b"), [1.0, 2.0], [3.0, 4.0]),
        messages.odometry(0.2, [1.0, 2.0, 0.3], [0.1, 0.2], "odom", "base"),
        messages.twist(np.array([0.1, 0.2, 0.3])),
        messages.arm_command(np.array([1.0, -2.0])),
        messages.diagnostics(0.3, "node", {"seen": True, "error_px": [1.5, 2.0]}, False),
        messages.laser_scan(0.1, [1.0, 2.0, 3.0], 1.0, 5.0, "laser"),
        messages.image(0.1, np.full((4, 5, 3), 7, np.uint8), "camera"),
        messages.camera_info(0.1, CameraIntrinsics(600.0, 640, 480), "camera"),
        Clock(clock=messages.stamp(1.5)),
    ]
    for message in built:
        kind = message_type(message)
        raw = bytes(store.serialize_cdr(store_message(message, store), kind))
        assert deserialize_message(raw, type(message)) == message, kind
        assert store.serialize_cdr(store.deserialize_cdr(raw, kind), kind) == raw, kind
    with pytest.raises(Exception, match="size mismatch"):  # what the bags avoid
        store.deserialize_cdr(serialize_message(built[0]), "sensor_msgs/msg/JointState")
