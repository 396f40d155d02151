"""A simulated run as a ROS 2 bag: ``pbvs-pin run ... --bag DIR``.

The bag (rosbag2, MCAP storage) is written after the run from its log, one message per topic
at every logged instant (the log's rate, 50 Hz by default; the controller ran at 1 kHz):

- ``/clock`` (``rosgraph_msgs/Clock``): the run's time;
- ``/tf`` (``tf2_msgs/TFMessage``): every link, the camera's optical frame and the target's
  midpoint (``target``) in ``odom`` (:mod:`pbvs_pin.ros.tf`);
- ``/joint_states`` (arm joints, true positions and rates), ``/odom`` (the platform's true pose
  and velocities);
- ``/cmd_vel`` and ``/arm_controller/commands``: the controller's command ``v_ref``, as the
  node publishes it;
- ``/diagnostics``: the feature error, seen, lost, saturated, as the node publishes them;
- ``/camera/image_raw/compressed`` (``sensor_msgs/CompressedImage``, JPEG) with
  ``/camera/camera_info``: the camera's view drawn again from the log by the rendered camera's
  scene (:func:`pbvs_pin.viz.eye_view.eye_views`), at :data:`IMAGE_RATE`; compressed: the
  60 s of Experiment 2 make a 21 MB bag, where raw frames would take 0.66 GB;
- ``/pbvs_pin/run``: the log's meta (``std_msgs/String``, JSON), which marks the bag as a
  run's.

It is a record to look at (Foxglove, ``ros2 bag``, ``rosbags``), not a recording of what a
controller stepped on: ``pbvs-pin ros replay-bag`` needs every control step's readings, which
a bag of ``pbvs-pin ros sim --bag`` holds, and refuses this one.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CompressedImage
from std_msgs.msg import String

from pbvs_pin.model import frames
from pbvs_pin.ros import messages
from pbvs_pin.ros.bag import BagRecorder
from pbvs_pin.ros.tf import TF_TYPE, tf_message
from pbvs_pin.sim.log import RunLog, json_safe
from pbvs_pin.viz.run_scene import log_robot

RUN_TOPIC = "/pbvs_pin/run"
"""The topic of the log's meta, which marks a bag of ``pbvs-pin run --bag``."""

IMAGE_RATE = 10.0
"""Camera images per second of the run in the bag [Hz] (drawing one took 16 ms here)."""

JPEG_QUALITY = 90
"""JPEG quality of the bag's images (0-100)."""


def _image_samples(t: np.ndarray) -> np.ndarray:
    """The logged instants that get an image: the first, then one per ``1 / IMAGE_RATE``."""
    slots = np.floor(t * IMAGE_RATE + 1e-9)
    return np.flatnonzero(np.diff(slots, prepend=-1.0) > 0)


def compressed_image(t: float, rgb: np.ndarray) -> CompressedImage:
    """A JPEG ``sensor_msgs/CompressedImage`` of an RGB ``uint8`` image, stamped ``t`` [s]."""
    ok, encoded = cv2.imencode(
        ".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY]
    )
    if not ok:  # OpenCV's JPEG encoder refuses no RGB uint8 image
        raise RuntimeError("cv2.imencode could not encode the image")
    message = CompressedImage(format="jpeg", data=encoded.tobytes())
    message.header.stamp, message.header.frame_id = messages.stamp(t), frames.CAMERA_OPTICAL
    return message


def write_run_bag(log: RunLog, path: str | Path, images: bool = True) -> Path:
    """Write a run's log as a rosbag2 bag (MCAP) into the new folder ``path``.

    Args:
        log: The run's log.
        path: The bag's folder; must not exist.
        images: Also draw the camera's images (MuJoCo's renderer).

    Returns:
        ``path``.

    Raises:
        OutputError: If ``path`` exists.
    """
    robot = log_robot(log)
    n_base, names = robot.n_base, robot.arm_joint_names
    t, q, v, v_ref = log["t"], log["q"], log["v"], log["v_ref"]
    error = log["xi"] - log["xi_d"]
    drawn = _image_samples(t) if images else np.zeros(0, dtype=int)
    pictures = dict(zip(drawn, _views(log, drawn), strict=True))
    bag = BagRecorder(path)
    try:
        meta = json.dumps(json_safe(dict(log.meta)))
        bag.write(RUN_TOPIC, String(data=meta), float(t[0]))
        for i, now in enumerate(map(float, t)):
            bag.write("/clock", Clock(clock=messages.stamp(now)), now)
            tf = tf_message(now, robot, q[i], log["target"][i])
            bag.write_serialised("/tf", TF_TYPE, tf, now)
            arm = robot.arm_positions(q[i])
            bag.write("/joint_states", messages.joint_state(now, names, arm, v[i, n_base:]), now)
            planar = log["platform_pose"][i]
            odom = messages.odometry(now, planar, v[i, :n_base], frames.ODOM,
                                     frames.DRIVE_FOOTPRINT)  # fmt: skip
            bag.write("/odom", odom, now)
            bag.write("/cmd_vel", messages.twist(v_ref[i, :n_base]), now)
            bag.write("/arm_controller/commands", messages.arm_command(v_ref[i, n_base:]), now)
            bag.write("/diagnostics", _diagnostics(log, i, error[i]), now)
            if i in pictures:
                info = messages.camera_info(now, robot.camera, frames.CAMERA_OPTICAL)
                bag.write("/camera/camera_info", info, now)
                bag.write("/camera/image_raw/compressed", compressed_image(now, pictures[i]), now)
    finally:
        bag.close()
    return Path(path)


def _views(log: RunLog, samples: np.ndarray) -> list[np.ndarray]:
    """The camera's view at the logged ``samples``, unmarked (none: nothing is drawn)."""
    if not len(samples):
        return []
    from pbvs_pin.viz.eye_view import eye_views

    return eye_views(log, samples, marked=False)


def _diagnostics(log: RunLog, i: int, error: np.ndarray):
    """The node's diagnostics of logged instant ``i``."""
    seen = not bool(log["target_lost"][i]) and bool(np.all(np.isfinite(error)))
    values = {
        "t": round(float(log["t"][i]), 6),
        "error_px": [round(float(e), 3) for e in error],
        "max_abs_error_px": round(float(np.max(np.abs(error))), 3) if seen else "nan",
        "seen": seen,
        "lost": bool(log["target_lost"][i]),
        "saturated": bool(log["saturated"][i]),
    }
    return messages.diagnostics(float(log["t"][i]), "pbvs_pin_run", values, True)
