"""The ``pbvs-pin`` command.

Every subcommand prints a package error (:class:`pbvs_pin.exceptions.PbvsError`) as one line
on stderr, without a traceback, and exits with status 2.
"""

from __future__ import annotations

import argparse
import json
import sys
import tomllib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pbvs_pin.exceptions import GainError, PbvsError, ScenarioError
from pbvs_pin.validation import positive_number

if TYPE_CHECKING:
    from pbvs_pin.robot import MobileManipulator


def load_robot_argument(argument: str) -> MobileManipulator:
    """The robot of ``info`` and ``view``: a shipped name, a URDF path, or a TOML file.

    A TOML file (``.toml``) holds a ``[robot]`` table: a robot file, or a whole scenario
    (whose ``[camera]`` then gives the intrinsics).

    Raises:
        RobotNotFound: If a name is neither shipped nor a file.
        UrdfError: If a URDF path is missing or malformed.
        ScenarioError: If the TOML file is missing, malformed, has no ``[robot]`` table, or
            its robot cannot be built (naming the dotted field).
    """
    from pbvs_pin.catalogue import build_robot
    from pbvs_pin.sim.scenario import load_scenario

    if Path(argument).suffix.lower() != ".toml":
        return build_robot(argument)
    if not Path(argument).is_file():
        raise ScenarioError(argument, "", "no such robot or scenario file")
    scenario = load_scenario(argument)
    if "robot" not in tomllib.loads(Path(argument).read_text()):
        raise ScenarioError(
            argument, "robot", 'no [robot] table; add one, e.g. [robot] name = "pioneer_cyton"'
        )
    return scenario.robot.build(scenario.camera.intrinsics())


def _info(args: argparse.Namespace) -> None:
    """Print a robot's dof, joints, limits, camera and manipulability."""
    from pbvs_pin.manipulability import arm_manipulability, whole_body_manipulability

    robot = load_robot_argument(args.robot)
    q = robot.home()
    lower, upper = robot.arm_position_limits()
    print(f"robot: {args.robot}  ({robot.source})")
    print(f"base: {robot.base}")
    print(f"actuated dof n = {robot.n} (base {robot.n_base}, arm {robot.n_arm})")
    print(f"{'velocity':<28}{'position limits':>26}{'velocity limit':>18}")
    for i, name in enumerate(robot.velocity_names):
        if i < robot.n_base:
            limits = "-"
        else:
            limits = f"[{lower[i - robot.n_base]:+.3f}, {upper[i - robot.n_base]:+.3f}]"
        print(f"{name:<28}{limits:>26}{robot.velocity_limits[i]:>18.3f}")
    camera = robot.camera
    pose = robot.camera_pose(q)
    print(f"camera frame: {robot.camera_frame}")
    print(f"intrinsics: f = {camera.focal_px:g} px, image {camera.width} x {camera.height} px")
    print(f"camera position at home [m]: {np.array2string(pose.translation, precision=3)}")
    print(f"arm manipulability at home: {arm_manipulability(robot, q):.5g}")
    print(f"whole-body manipulability at home: {whole_body_manipulability(robot, q):.5g}")


def _run(args: argparse.Namespace) -> None:
    """Run one scenario, optionally with a live Meshcat view."""
    from pbvs_pin.experiments import run_scenario

    out = Path(args.out)
    html = Path(args.html) if args.html else None
    if args.meshcat:
        from pbvs_pin.viz.live import LiveView

        with LiveView(args.scenario, speed=args.speed) as live:
            print(f"live view: {live.url} (playing at {args.speed:g}x real time)")
            summary = run_scenario(args.scenario, out, html, observer=live.show)[1]
    else:
        summary = run_scenario(args.scenario, out, html)[1]
    print(json.dumps(summary, indent=2))
    print(f"log, summary and figures written to {out}")


def _reproduce(args: argparse.Namespace) -> None:
    """Run the paper's four experiments and write the report."""
    from pbvs_pin.experiments import reproduce

    report = reproduce(Path(args.out), compensation=not args.no_compensation)
    print(f"report written to {report}")


def _view(args: argparse.Namespace) -> None:
    """Show a robot at home with its camera frame and frustum."""
    from pbvs_pin.viz.live import view_robot

    view_robot(load_robot_argument(args.robot), Path(args.html) if args.html else None)


def _analyze(args: argparse.Namespace) -> None:
    """Passivity and L2-gain figures of a run."""
    from pbvs_pin.analysis import analyze_run

    result = analyze_run(
        Path(args.log), args.epsilon, Path(args.out) if args.out else None, t1=args.t1
    )
    print(json.dumps(result, indent=2))


def _sweep(args: argparse.Namespace) -> None:
    """Run a grid or random sample of scenarios."""
    from pbvs_pin.sweep import run_sweep

    table = run_sweep(
        Path(args.spec),
        Path(args.out),
        args.scheduler,
        args.workers,
        max_runs=args.max_runs,
        retry_failed=args.retry_failed,
        force=args.force,
    )
    print(f"results table written to {table}")


def _positive_float(text: str) -> float:
    """An argparse type: a positive finite number."""
    try:
        return positive_number("value", text)
    except GainError as err:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from err


ROBOT_HELP = (
    "shipped robot name (e.g. pioneer_cyton), URDF path with a camera_optical_frame, or a "
    "TOML file with a [robot] table (a robot file or a scenario)"
)
"""Help of the robot argument of ``info`` and ``view``."""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every subcommand."""
    parser = argparse.ArgumentParser(
        prog="pbvs-pin",
        description="Passivity-based visual servoing of mobile manipulators (Pinocchio).",
    )
    commands = parser.add_subparsers(dest="command", required=True)
    info = commands.add_parser("info", help="describe a robot (name, URDF or TOML [robot])")
    info.add_argument("robot", help=ROBOT_HELP)
    info.set_defaults(handler=_info)
    run = commands.add_parser("run", help="simulate one scenario (shipped name or TOML path)")
    run.add_argument("scenario")
    run.add_argument("--out", default="results/run", help="output folder")
    run.add_argument("--html", help="also write a standalone HTML replay to this file")
    run.add_argument("--meshcat", action="store_true", help="open a live Meshcat view")
    run.add_argument(
        "--speed",
        type=_positive_float,
        default=1.0,
        help="with --meshcat: simulated seconds shown per second (default 1: real time)",
    )
    run.set_defaults(handler=_run)
    reproduce = commands.add_parser("reproduce", help="run the paper's four experiments")
    reproduce.add_argument("--out", default="results", help="output folder")
    reproduce.add_argument(
        "--no-compensation",
        action="store_true",
        help="skip the comparison of the compensation modes (8 runs)",
    )
    reproduce.set_defaults(handler=_reproduce)
    view = commands.add_parser("view", help="show a robot, its camera frame and frustum")
    view.add_argument("robot", help=ROBOT_HELP)
    view.add_argument("--html", help="write a standalone HTML file instead of serving")
    view.set_defaults(handler=_view)
    analyze = commands.add_parser("analyze", help="passivity and L2-gain analysis of a run")
    analyze.add_argument("log", help="a run's log.npz (or its folder)")
    analyze.add_argument("--epsilon", type=float, default=0.5, help="epsilon of eq. (31)")
    analyze.add_argument("--out", help="folder for the analysis report and plots")
    analyze.add_argument("--t1", type=float, help="start [s] of the ultimate-bound window")
    analyze.set_defaults(handler=_analyze)
    sweep = commands.add_parser("sweep", help="run a grid or random sample of scenarios")
    sweep.add_argument("spec", help="sweep specification (TOML)")
    sweep.add_argument("--out", default="results/sweep", help="output folder")
    sweep.add_argument("--scheduler", help="Dask scheduler address (default: local processes)")
    sweep.add_argument("--workers", type=int, help="local worker processes")
    sweep.add_argument("--max-runs", type=int, help="stop after this many new runs")
    sweep.add_argument("--retry-failed", action="store_true", help="run failed rows again")
    sweep.add_argument(
        "--force",
        action="store_true",
        help="adopt a folder with results whose sweep.json is missing or unreadable",
    )
    sweep.set_defaults(handler=_sweep)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args = build_parser().parse_args(argv)
    handler: Callable[[argparse.Namespace], None] = args.handler
    try:
        handler(args)
    except PbvsError as err:
        print(f"pbvs-pin: error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
