"""Replay a recorded bag through the controller offline, and compare its commands.

:func:`replay_bag` reads a bag written by ``pbvs-pin ros sim --bag`` (rosbag2, MCAP, read
with ``rosbags``, deserialised by ROS itself), steps a fresh :class:`pbvs_pin.Controller` at
every recorded ``/clock`` time ``t`` as the node does (:func:`pbvs_pin.ros.node.step_inputs`:
the newest ``joint_states`` and ``odom``, the newest frame captured by ``t``, the scan that
came since the last step) and compares its platform and arm commands with the recorded
``cmd_vel`` and ``arm_controller/commands`` of that step.

The readings it steps on are those published at ``t - lag * T`` (``lag`` = 0: the readings of
the step itself, as ``simulate()`` does; 1: those of the period before, what a node gets when
``/clock`` overtakes the readings on their way). Which lag reproduces the recorded commands
tells which readings the node stepped on.
"""

from __future__ import annotations

import importlib
from collections import defaultdict
from pathlib import Path

import numpy as np
from rclpy.serialization import deserialize_message
from rosbags.rosbag2 import Reader

from pbvs_pin.controller import Controller
from pbvs_pin.exceptions import LogError
from pbvs_pin.perception.detection import detector_from
from pbvs_pin.ros import messages
from pbvs_pin.ros.node import frame_of, step_inputs
from pbvs_pin.ros.run_bag import RUN_TOPIC
from pbvs_pin.sim.scenario import Scenario

TOPICS = (
    "/joint_states", "/odom", "/scan", "/camera/image_raw", "/clock", "/cmd_vel",
    "/arm_controller/commands",
)  # fmt: skip
"""The topics the replay reads."""

MATCH = 1e-9
"""Largest difference [m/s, rad/s] of two commands counted as the same."""


def _message_class(type_name: str) -> type:
    """The ROS message class of ``package/msg/Name``."""
    package, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def read_steps(path: str | Path) -> dict[int, dict[str, list]]:
    """The bag's messages by control step (recorded time in ns) and topic, in bag order.

    Raises:
        LogError: If ``path`` is not a rosbag2 bag or lacks ``/clock`` or ``/cmd_vel``.
    """
    try:
        reader = Reader(path)
        reader.open()
    except Exception as err:  # rosbags raises its own types for a missing or bad bag
        raise LogError(str(path), f"expected a rosbag2 bag ({err})") from err
    try:
        if any(c.topic == RUN_TOPIC for c in reader.connections):
            raise LogError(
                str(path),
                "is a bag of `pbvs-pin run --bag`, written from the run's log at its 50 Hz, not "
                "the readings of every control step; replay a bag of `pbvs-pin ros sim --bag`",
            )
        connections = [c for c in reader.connections if c.topic in TOPICS]
        missing = {"/clock", "/cmd_vel"} - {c.topic for c in connections}
        if missing:
            raise LogError(str(path), f"no {sorted(missing)} in the bag; expected a run's bag")
        classes = {c.topic: _message_class(c.msgtype) for c in connections}
        steps: dict[int, dict[str, list]] = defaultdict(lambda: defaultdict(list))
        for connection, time_ns, raw in reader.messages(connections=connections):
            topic = connection.topic
            steps[time_ns][topic].append(deserialize_message(raw, classes[topic]))
    finally:
        reader.close()
    return steps


def replay_bag(path: str | Path, scenario: Scenario, lag: int = 0) -> dict:
    """Step the controller on the bag's readings and compare with its recorded commands.

    Args:
        path: The bag's folder.
        scenario: The node's scenario (the robot, the controller's settings, the detector).
        lag: The readings stepped on are those of ``lag`` periods before the step.

    Returns:
        ``steps`` compared (those with a recorded command and readings), ``identical``
        (within :data:`MATCH`), ``max_abs_difference`` [m/s or rad/s], and the time [s] of
        the first differing step (None).
    """
    controller = Controller.from_scenario(scenario)
    model = controller.model
    detector = detector_from(scenario.camera.detector, model.camera)
    names, n_base = tuple(model.arm_joint_names), model.n_base
    steps = read_steps(path)
    times = sorted(steps)
    frames, laser = [], None
    compared = identical = 0
    worst, first = 0.0, None
    for index, time_ns in enumerate(times):
        here = steps[time_ns]
        if index < lag:
            continue
        source = steps[times[index - lag]]
        for image in source["/camera/image_raw"]:
            frames.append(frame_of(image, detector, model.camera, scenario.target.diameter))
        if source["/scan"]:
            laser = messages.nearest_return(source["/scan"][-1])
        if not (here["/clock"] and here["/cmd_vel"] and source["/joint_states"]):
            continue
        t = time_ns * 1e-9
        joints = messages.arm_reading(source["/joint_states"][-1], names)
        odom = messages.platform_reading(source["/odom"][-1], n_base)
        q, v, frame, frames = step_inputs(model, joints, odom, frames, t)
        v_ref = controller.step(t, q, v, frame, laser).v_ref
        laser = None
        recorded = messages.twist_velocity(here["/cmd_vel"][-1], n_base)
        if here["/arm_controller/commands"]:
            arm = np.asarray(here["/arm_controller/commands"][-1].data, dtype=float)
            recorded = np.concatenate([recorded, arm])
        difference = float(np.max(np.abs(v_ref[: recorded.size] - recorded)))
        compared += 1
        identical += difference <= MATCH
        worst = max(worst, difference)
        if difference > MATCH and first is None:
            first = round(t, 6)
    return {
        "lag": lag,
        "steps": compared,
        "identical": identical,
        "max_abs_difference": worst,
        "first_difference_s": first,
    }
