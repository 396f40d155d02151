"""``pbvs-pin ros control`` and ``pbvs-pin ros sim``: their arguments and what they run.

This module imports no ROS: :func:`add_arguments` only declares the arguments, and each
command imports :mod:`pbvs_pin.ros.node` or :mod:`pbvs_pin.ros.sim_robot` when it runs, raising
:class:`~pbvs_pin.exceptions.RosUnavailable` (one line on the command line) when the ``ros``
extra is not installed.
"""

from __future__ import annotations

import argparse
import importlib
import json
from collections.abc import Callable
from functools import partial
from types import ModuleType

import numpy as np

from pbvs_pin.exceptions import GainError, RosUnavailable
from pbvs_pin.outputs import Output

DEFAULT_SCENARIO = "experiment1"
"""The scenario whose settings the node takes when it is given a robot, not a scenario."""


def ros_module(name: str) -> ModuleType:
    """``pbvs_pin.ros.<name>``, which imports ``rclpy``.

    Raises:
        RosUnavailable: If ROS 2 cannot be imported (the ``ros`` extra is not installed).
    """
    try:
        return importlib.import_module(f"pbvs_pin.ros.{name}")
    except ImportError as err:
        raise RosUnavailable(str(err)) from err


def add_arguments(parser: argparse.ArgumentParser, output: Callable, scenario_of: Callable) -> None:
    """The ``ros`` subcommands' arguments.

    Args:
        parser: The ``ros`` subcommand's parser.
        output: Declares an argument naming a file the command writes
            (:func:`pbvs_pin.outputs.output_option`).
        scenario_of: The scenario of a namespace with ``scenario``, ``robot``, ``set``,
            ``engine`` and ``duration`` (:func:`pbvs_pin.cli._run_scenario`).
    """
    commands = parser.add_subparsers(dest="ros_command", required=True)
    setting = {
        "action": "append",
        "default": [],
        "metavar": "KEY=VALUE",
        "help": "change a scenario key, as pbvs-pin run --set",
    }
    ros_args = {
        "nargs": argparse.REMAINDER,
        "default": [],
        "help": "the rest goes to ROS (remaps, parameters: -r cmd_vel:=/base/cmd_vel)",
    }
    control = commands.add_parser("control", help="run the controller as a ROS 2 node")
    control.add_argument(
        "robot",
        help="a scenario (shipped name or TOML file) or a robot (shipped name, URDF or robot "
        f"file), then with {DEFAULT_SCENARIO}'s settings",
    )
    control.add_argument("--set", **setting)
    control.add_argument("--use-sim-time", action="store_true", help="follow /clock")
    control.add_argument("--ros-args", **ros_args)
    control.set_defaults(handler=partial(_control, scenario_of=scenario_of))
    sim = commands.add_parser("sim", help="a simulated robot behind the same ROS 2 topics")
    sim.add_argument("scenario", help="shipped scenario name or scenario TOML file")
    sim.add_argument("--robot", help="robot instead of the scenario's")
    sim.add_argument("--set", **setting)
    sim.add_argument(
        "--engine",
        choices=("pinocchio", "mujoco"),
        default="mujoco",
        help="physics of the plant",
    )
    sim.add_argument("--duration", type=float, help="simulated time [s]")
    sim.add_argument(
        "--rate-factor",
        type=float,
        default=1.0,
        help="simulated seconds per wall-clock second, at most",
    )
    sim.add_argument(
        "--command-timeout",
        type=float,
        default=0.1,
        help="age [s] past which a command is replaced by zero",
    )
    sim.add_argument(
        "--lockstep",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="each step waits up to this long for the controller's answer",
    )
    sim.add_argument(
        "--wait",
        type=float,
        default=0.0,
        help="wait up to this long [s] for a controller node before starting",
    )
    output(
        sim, "--bag", Output.NEW_FOLDER,
        help="record every topic, and TF, into this new folder: a rosbag2 bag, MCAP storage",
    )  # fmt: skip
    output(sim, "--summary", Output.FILE, help="write the true feature error here (JSON)")
    sim.add_argument("--ros-args", **ros_args)
    sim.set_defaults(handler=partial(_sim, scenario_of=scenario_of))
    replay = commands.add_parser(
        "replay-bag", help="step the controller on a recorded bag; compare with its commands"
    )
    replay.add_argument("bag", help="a bag written by pbvs-pin ros sim --bag")
    replay.add_argument("robot", help="the node's scenario or robot, as for ros control")
    replay.add_argument("--set", **setting)
    replay.add_argument(
        "--lag", type=int, default=0, help="step on the readings of LAG periods before (0)"
    )
    replay.set_defaults(handler=partial(_replay, scenario_of=scenario_of))


def control_scenario(args: argparse.Namespace, scenario_of: Callable):
    """The node's scenario: the one named, or :data:`DEFAULT_SCENARIO` on the robot named."""
    from pbvs_pin.sim.scenario import shipped_scenarios

    target = args.robot
    given = target in shipped_scenarios() or target.lower().endswith(".toml")
    spec = argparse.Namespace(
        scenario=target if given else DEFAULT_SCENARIO,
        robot=None if given else target,
        set=args.set,
        engine=None,
        duration=None,
    )
    return scenario_of(spec)


def _init(ros_args: list[str]) -> ModuleType:
    """``rclpy``, initialised with the ROS arguments; Ctrl-C left to Python."""
    rclpy = ros_module("node").rclpy
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(
        args=["pbvs-pin", "--ros-args", *ros_args] if ros_args else None,
        signal_handler_options=SignalHandlerOptions.NO,
    )
    return rclpy


def _control(args: argparse.Namespace, scenario_of: Callable) -> None:
    """Run the node until Ctrl-C or SIGTERM."""
    node_module = ros_module("node")
    scenario = control_scenario(args, scenario_of)
    rclpy = _init(args.ros_args)
    from rclpy.parameter import Parameter

    overrides = [Parameter("use_sim_time", value=True)] if args.use_sim_time else []
    node = None
    try:
        node = node_module.ControlNode(scenario, overrides, announce=True)
        print(
            f"pbvs-pin ros control: {node.get_fully_qualified_name()} running "
            f"{scenario.name} at {1 / node.controller.period:g} Hz",
            flush=True,
        )
        node_module.spin(node)
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


def _sim(args: argparse.Namespace, scenario_of: Callable) -> None:
    """Run the simulated robot for the scenario's duration; print the final error."""
    sim_module = ros_module("sim_robot")
    scenario = scenario_of(args)
    rclpy = _init(args.ros_args)
    node = None
    try:
        node = sim_module.SimRobot(scenario, args.rate_factor, args.command_timeout, args.lockstep)
        print(
            f"pbvs-pin ros sim: {scenario.name} on {scenario.plant.engine}, "
            f"{scenario.duration:g} s",
            flush=True,
        )
        if args.bag:
            node.record(args.bag)
        if args.wait > 0 and not node.wait_for_controller(args.wait):
            node.get_logger().warning(f"no controller node after {args.wait:g} s; starting")
        summary = node.run(scenario.duration)
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    if args.summary:
        sim_module.write_summary(summary, args.summary)
    error = np.abs(np.array(summary["error"]))
    print(
        json.dumps(
            {
                "simulated_s": summary["simulated_s"],
                "wall_s": summary["wall_s"],
                "commands_received": summary["commands_received"],
                "fresh_commands": summary["fresh_commands"],
                "final_max_abs_error_px": round(float(error[-1].max()), 3),
            }
        )
    )


def _replay(args: argparse.Namespace, scenario_of: Callable) -> None:
    """Print the comparison of the replayed and recorded commands (JSON)."""
    replay_module = ros_module("bag_replay")
    if args.lag < 0:
        raise GainError(f"--lag: expected 0 or more periods, got {args.lag}", "lag")
    scenario = control_scenario(args, scenario_of)
    print(json.dumps(replay_module.replay_bag(args.bag, scenario, args.lag)))
