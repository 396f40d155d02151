"""The ``pbvs-pin`` command.

Every subcommand prints a package error (:class:`pbvs_pin.exceptions.PbvsError`) as one line
on stderr, without a traceback, and exits with status 2. Every file or folder a subcommand
writes is declared with :func:`pbvs_pin.outputs.output_option` and checked
(:func:`pbvs_pin.outputs.check_output`) before the subcommand starts. Ctrl-C prints one line
and exits with status 130; during a simulation it is held until the next logged instant
(:mod:`pbvs_pin.interrupts`), so that it never lands inside compiled code, and the run so far
is saved first (:class:`RunInterrupted`).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tomllib
from collections.abc import Callable, Sequence
from contextlib import nullcontext
from pathlib import Path
from typing import TYPE_CHECKING

from pbvs_pin import __version__
from pbvs_pin.bringup.catalogue import OTHER_ROBOTS, ROBOT_NAMES
from pbvs_pin.exceptions import (
    GainError,
    PbvsError,
    RobotNotFound,
    UsageError,
    ViewerUnavailable,
)
from pbvs_pin.interrupts import (
    INTERRUPTED,
    finished,
    held_interrupts,
    interrupted_in_compiled_code,
    interrupted_line,
    loaded,
    stage,
)
from pbvs_pin.model.shipped import scenario_file
from pbvs_pin.outputs import Output, check_outputs, output_option, replace_run_folder
from pbvs_pin.ros.commands import add_arguments as ros_arguments
from pbvs_pin.study.report import ENGINE_ROBOTS
from pbvs_pin.study.zoo import add_arguments as zoo_arguments
from pbvs_pin.study.zoo import command as zoo_command
from pbvs_pin.validation import positive_number

if TYPE_CHECKING:
    from pbvs_pin.model.robot import MobileManipulator
    from pbvs_pin.sim.scenario import Scenario


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
    from pbvs_pin.bringup.catalogue import build_robot

    if Path(argument).suffix.lower() != ".toml":
        return build_robot(argument)
    from pbvs_pin.study.experiments import robot_file

    scenario = robot_file(argument)
    return scenario.robot.build(scenario.camera.intrinsics())


def _info(args: argparse.Namespace) -> None:
    """Print a robot's dof, joints, limits, camera and manipulability."""
    robot = load_robot_argument(args.robot)
    from pbvs_pin.model.manipulability import arm_manipulability, whole_body_manipulability

    q = robot.home()
    lower, upper = robot.arm_position_limits()
    label, source = _normalised(args.robot), _normalised(robot.source)
    print(f"robot: {label}" + (f"  ({source})" if source != label else ""))
    print(f"base: {robot.base}")
    print(f"actuated dof n = {robot.n} (base {robot.n_base}, arm {robot.n_arm})")
    print(f"{'joint':<28}{'position limits':>26}{'velocity limit':>18}")
    for i, name in enumerate(robot.velocity_names):
        if i < robot.n_base:
            limits = "-"
        else:
            limits = f"[{lower[i - robot.n_base]:+.3f}, {upper[i - robot.n_base]:+.3f}]"
        print(f"{name:<28}{limits:>26}{robot.velocity_limits[i]:>18.3f}")
    camera = robot.camera
    position = ", ".join(f"{round(x, 3) + 0.0:+.3f}" for x in robot.camera_pose(q).translation)
    print(f"camera frame: {robot.camera_frame}")
    print(f"intrinsics: f = {camera.focal_px:g} px, image {camera.width} x {camera.height} px")
    print(f"camera position at home [m]: [{position}]")
    print(f"arm manipulability at home: {arm_manipulability(robot, q):.3g}")
    if robot.n < 6:  # sqrt(det(J J^T)) of a 6 x n Jacobian is zero
        print(f"whole-body manipulability at home: n/a (n = {robot.n} < 6)")
    else:
        print(f"whole-body manipulability at home: {whole_body_manipulability(robot, q):.3g}")


def _normalised(text: str) -> str:
    """An existing file's path without ``..`` and symbolic links; other text as it is."""
    return str(Path(text).resolve()) if Path(text).is_file() else text


def _list(args: argparse.Namespace) -> None:
    """Print the shipped robots, example-robot-data arms, scenarios and sweeps.

    With ``--keys``: every scenario key instead
    (:func:`pbvs_pin.sim.scenario.key_lines`).
    """
    if args.keys:  # what --set changes
        from pbvs_pin.sim.scenario import key_lines

        print("scenario keys (pbvs-pin run SCENARIO --set KEY=VALUE; VALUE is read as TOML):")
        print("\n".join(f"  {line}" for line in key_lines()))
        return
    from pbvs_pin.bringup.catalogue import example_robot_data_arms
    from pbvs_pin.model.shipped import shipped_scenarios
    from pbvs_pin.study.sweep.spec import sweep_dir

    sections = (
        ("shipped robots (pbvs-pin info NAME; [robot] name = NAME)", ROBOT_NAMES),
        (
            "example-robot-data arms (one chain of at least 3 joints; [robot] arm = NAME with "
            "base, camera_link, camera_pose: see the README)",
            example_robot_data_arms(),
        ),
        ("scenarios (pbvs-pin run NAME)", shipped_scenarios()),
        ("sweeps (pbvs-pin sweep NAME)", sorted(p.stem for p in sweep_dir().glob("*.toml"))),
    )
    for title, names in sections:
        print(f"{title}:")
        print("\n".join(f"  {name}" for name in names))


def _run_scenario(args: argparse.Namespace) -> Scenario:
    """The scenario of ``run`` with its ``--robot``, ``--engine``, ``--duration`` and ``--set``.

    Raises:
        ScenarioError: If the scenario, the robot or a changed value is invalid.
    """
    scenario_file(args.scenario)  # an unknown name is refused before the simulation loads
    from pbvs_pin.sim.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    if args.robot is not None:
        from pbvs_pin.study.experiments import with_robot

        scenario = with_robot(scenario, args.robot)
    changes = dict(_setting(text) for text in args.set)
    if args.engine is not None:
        changes["plant.engine"] = args.engine
    if args.duration is not None:
        changes["duration"] = args.duration
    return scenario.with_values(**changes) if changes else scenario


def _setting(text: str) -> tuple[str, object]:
    """``key=value`` of ``--set``, its value read as TOML, or as text where it is not TOML.

    ``1.5``, ``[0, 1]`` and ``true`` are TOML; ``controller.law=ibvs`` gives the text ``ibvs``.

    Raises:
        UsageError: If there is no ``=`` or no key.
    """
    key, equals, value = text.partition("=")
    if not equals or not key.strip():
        raise UsageError("--set", f"expected key=value (e.g. camera.rate=60), got {text!r}")
    try:
        parsed: object = tomllib.loads(f"value = {value.strip()}")["value"]
    except tomllib.TOMLDecodeError:
        parsed = value.strip()
    return key.strip(), parsed


def _run(args: argparse.Namespace) -> None:
    """Run one scenario, optionally with a live Meshcat view (the run goes on without one)."""
    if args.speed is not None and not args.meshcat:
        raise UsageError("--speed", "only applies to the live view; add --meshcat or drop it")
    speed = 1.0 if args.speed is None else args.speed
    out = Path(args.out)
    html = Path(args.html) if args.html else None
    scenario = _run_scenario(args)
    from pbvs_pin.study.experiments import run_scenario

    if args.force:
        replace_run_folder(out)
    live = None
    if args.meshcat:
        from pbvs_pin.viz.live import LiveView

        try:
            live = LiveView(scenario, speed=speed)
        except ViewerUnavailable as err:
            watch = f"the replay will be in {html}" if html else "add --html FILE to watch a replay"
            print(
                f"pbvs-pin: no live view ({err.reason}); running without it; {watch}",
                file=sys.stderr,
            )
    eye = args.eye_view
    bag = Path(args.bag) if args.bag else None
    if bag is not None:  # the ros extra is checked before the run, not after it
        from pbvs_pin.ros.commands import ros_module

        ros_module("run_bag")
    if live is None:
        summary = run_scenario(scenario, out, html, eye_view=eye, bag=bag)[1]
    else:
        with live:
            print(f"live view: {live.url} (playing at {speed:g}x real time)")
            summary = run_scenario(
                scenario, out, html, observer=live.show, eye_view=eye, bag=bag
            )[1]
    from pbvs_pin.study.claims import verdict_lines

    verdict = verdict_lines(summary)
    if verdict is not None:
        print(verdict)
    if args.json:
        from pbvs_pin.sim.log import json_safe

        print(json.dumps(json_safe(summary), indent=2))
    suffix = "mp4" if eye == "video" else "png"
    eye_file = f"; robot's-eye view: {out / f'eye_view.{suffix}'}" if eye else ""
    print(
        f"log, summary (summary.json{'' if args.json else '; --json prints it'}) and figures "
        f"written to {out}" + (f"; replay: {html}" if html else "") + eye_file
        + (f"; ROS 2 bag: {bag}" if bag else "")
    )


def _compile(args: argparse.Namespace) -> None:
    """Compile and cache every kernel a run calls, announced, and say how long it took.

    Runs 0.1 s of Experiment 1: its first control step compiles the fused step and the plant's
    servo kernel, its log the rest.
    """
    import time

    from pbvs_pin.compile_cache import announce_compiles
    from pbvs_pin.sim.loop import simulate
    from pbvs_pin.sim.scenario import load_scenario

    started = time.perf_counter()
    with announce_compiles(stream=sys.stdout) as announcer:
        simulate(load_scenario("experiment1").with_values(duration=0.1))
    if not announcer.compiled:
        print("control kernels already compiled; checked them", flush=True)
    elapsed = time.perf_counter() - started
    print(f"done in {elapsed:.1f} s; runs start at once from now on", flush=True)


def _reproduce(args: argparse.Namespace) -> None:
    """Run the paper's four experiments and write the report."""
    for robot in args.engines:
        if robot not in ROBOT_NAMES:
            raise RobotNotFound(robot, ROBOT_NAMES)
    from pbvs_pin.sim.scenario import load_scenario
    from pbvs_pin.study.experiments import with_robot
    from pbvs_pin.study.reproduction import reproduce

    for robot in args.robots:  # a name, a URDF or a robot file: checked before any run
        with_robot(load_scenario("experiment1"), robot)
    if args.force:
        replace_run_folder(Path(args.out))
    report = reproduce(
        Path(args.out),
        robots=tuple(args.robots),
        engines=tuple(args.engines),
        baseline=not args.no_baseline,
        compensation=not args.no_compensation,
        replays=not args.no_replay,
    )
    print(f"report written to {report}")


def _view(args: argparse.Namespace) -> None:
    """Show a robot at home with its camera frame and frustum."""
    robot = load_robot_argument(args.robot)
    from pbvs_pin.viz.live import view_robot

    view_robot(robot, Path(args.html) if args.html else None)


def _zoo(args: argparse.Namespace) -> None:
    """``pbvs-pin zoo``: :func:`pbvs_pin.study.zoo.command`, its ``--set`` read as ``run``'s."""
    args.changes = dict(_setting(text) for text in args.set)
    zoo_command(args)


def _analyze(args: argparse.Namespace) -> None:
    """Passivity and L2-gain figures of a run."""
    from pbvs_pin.study.analysis import analyze_run

    result = analyze_run(
        Path(args.log), args.epsilon, Path(args.out) if args.out else None, t1=args.t1
    )
    from pbvs_pin.sim.log import json_safe

    print(json.dumps(json_safe(result), indent=2))


def _sweep(args: argparse.Namespace) -> None:
    """Run a grid or random sample of scenarios, or a robustness map."""
    from pbvs_pin.study.robustness import map_path, write_map
    from pbvs_pin.study.sweep import run_sweep

    robustness = map_path(args.spec)
    if robustness is not None:
        figure = write_map(Path(args.out), robustness, echo=print)[0]
        print(f"robustness map written to {figure}")
        return

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


FORCE_HELP = "replace all files of an earlier run in the output folder"
"""Help of ``--force`` of ``run`` and ``reproduce``."""


class _DefaultsFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Help that shows each option's default, unless it has none (None, False)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        if action.default is None or action.default is False:
            return action.help or ""
        if isinstance(action.default, list):  # an empty list is no default to show
            shown = " ".join(action.default)
            return f"{action.help} (default: {shown})" if shown else action.help or ""
        return super()._get_help_string(action) or ""


class _Parser(argparse.ArgumentParser):
    """A parser whose help shows the defaults (:class:`_DefaultsFormatter`)."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", _DefaultsFormatter)
        super().__init__(*args, **kwargs)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every subcommand."""
    parser = _Parser(
        prog="pbvs-pin",
        description="Passivity-based visual servoing of mobile manipulators (Pinocchio).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.set_defaults(simulates=False)  # run, compile, reproduce: Ctrl-C held (interrupts)
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    info = commands.add_parser("info", help="describe a robot (name, URDF or TOML [robot])")
    info.add_argument("robot", help=ROBOT_HELP)
    info.set_defaults(handler=_info)
    listing = commands.add_parser(
        "list", help="name the shipped robots, example-robot-data arms, scenarios and sweeps"
    )
    listing.add_argument(
        "--keys",
        action="store_true",
        help="list every scenario key instead (what `run --set KEY=VALUE` changes), with its "
        "default and meaning",
    )
    listing.set_defaults(handler=_list)
    run = commands.add_parser("run", help="simulate one scenario (shipped name or TOML path)")
    run.add_argument(
        "scenario",
        help="shipped scenario name (experiment1 ... experiment4; see `pbvs-pin list`) or a "
        "scenario TOML file",
    )
    run.add_argument("--robot", help="robot instead of the scenario's: " + ROBOT_HELP)
    run.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="change one key of the scenario for this run: a dotted key (TABLE.KEY, or KEY "
        "at the top) and a TOML value, e.g. --set camera.rate=60 --set "
        "target.xi_d=[0,50,-50] --set controller.law=ibvs; repeatable; `pbvs-pin list "
        "--keys` lists every key with its default and meaning",
    )
    run.add_argument("--engine", choices=("pinocchio", "mujoco"), help="physics of the plant")
    run.add_argument("--duration", type=_positive_float, help="simulated time [s]")
    output_option(run, "--out", Output.RUN_FOLDER, default="results/run", help="output folder")
    output_option(run, "--html", Output.FILE, help="also write a standalone HTML replay here")
    run.add_argument("--force", action="store_true", help=FORCE_HELP)
    run.add_argument(
        "--eye-view",
        choices=("strip", "video"),
        help="also save the robot's-eye view (what the camera saw, marked) in OUT: strip as "
        "eye_view.png, video as eye_view.mp4; a --html replay then shows it",
    )
    output_option(
        run, "--bag", Output.NEW_FOLDER,
        help="also write the run as a ROS 2 bag (rosbag2, MCAP) into this new folder: TF, "
        "joint_states, odom, cmd_vel, arm commands, diagnostics and the camera's images at "
        "10 Hz, for Foxglove or ros2 bag (the ros extra)",
    )  # fmt: skip
    run.add_argument(
        "--json", action="store_true", help="also print the summary (OUT/summary.json) as JSON"
    )
    run.add_argument("--meshcat", action="store_true", help="open a live Meshcat view")
    run.add_argument(
        "--speed",
        type=_positive_float,
        help="with --meshcat: simulated seconds shown per second (default 1, real time)",
    )
    run.set_defaults(handler=_run, simulates=True)
    compiling = commands.add_parser(
        "compile",
        help="compile the control kernels now (once after installing; else the first run does)",
    )
    compiling.set_defaults(
        handler=_compile,
        simulates=True,
        interrupted=lambda args: "the kernels compiled before it stay cached, the others "
        "compile on the next run",
    )
    reproduce = commands.add_parser("reproduce", help="run the paper's four experiments")
    output_option(reproduce, "--out", Output.RUN_FOLDER, default="results", help="output folder")
    reproduce.add_argument("--force", action="store_true", help=FORCE_HELP)
    reproduce.add_argument(
        "--robots",
        nargs="*",
        default=list(OTHER_ROBOTS),
        metavar="ROBOT",
        help="robots to repeat the experiments on besides the reference robot: shipped names, "
        "URDF files or robot files (TOML with a [robot] table); none: give the option alone",
    )
    reproduce.add_argument(
        "--engines",
        nargs="*",
        default=list(ENGINE_ROBOTS),
        metavar="NAME",
        help="shipped robots whose experiments are also run on the MuJoCo plant and compared "
        "with the Pinocchio plant (none: give the option alone)",
    )
    reproduce.add_argument(
        "--no-replay", action="store_true", help="skip the HTML replays of the reference runs"
    )
    reproduce.add_argument(
        "--no-baseline", action="store_true", help="skip the classic IBVS baseline (4 runs)"
    )
    reproduce.add_argument(
        "--no-compensation",
        action="store_true",
        help="skip the comparison of the compensation modes (8 runs)",
    )
    reproduce.set_defaults(
        handler=_reproduce,
        simulates=True,
        interrupted=lambda args: f"the runs finished before it are kept in {args.out}; the "
        "report was not written",
    )
    view = commands.add_parser("view", help="show a robot, its camera frame and frustum")
    view.add_argument("robot", help=ROBOT_HELP)
    output_option(
        view, "--html", Output.FILE, help="write a standalone HTML file instead of serving"
    )
    view.set_defaults(handler=_view)
    analyze = commands.add_parser("analyze", help="passivity and L2-gain analysis of a run")
    analyze.add_argument("log", help="a run's log.npz (or its folder)")
    analyze.add_argument("--epsilon", type=float, default=0.5, help="epsilon of eq. (31)")
    output_option(analyze, "--out", Output.FOLDER, help="folder for the analysis report and plots")
    analyze.add_argument("--t1", type=float, help="start [s] of the ultimate-bound window")
    analyze.set_defaults(handler=_analyze)
    sweep = commands.add_parser("sweep", help="run a grid or random sample of scenarios")
    sweep.add_argument("spec", help="sweep specification (TOML)")
    output_option(sweep, "--out", Output.FOLDER, default="results/sweep", help="output folder")
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
    zoo = commands.add_parser("zoo", help="the four experiments on every robot file of a folder")
    zoo_arguments(zoo, output_option)
    zoo.set_defaults(handler=_zoo)
    ros = commands.add_parser("ros", help="the controller as a ROS 2 node; a simulated ROS robot")
    ros_arguments(ros, output_option, _run_scenario)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args = None
    try:
        loaded()  # from here on a Ctrl-C is a KeyboardInterrupt, told in one line below
        stage("start-up")
        args = build_parser().parse_args(argv)
        handler: Callable[[argparse.Namespace], None] = args.handler
        check_outputs(args)
        if not args.simulates:
            stage("command")
        with held_interrupts() if args.simulates else nullcontext():
            handler(args)
    except PbvsError as err:
        print(f"pbvs-pin: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as stop:
        print(f"pbvs-pin: {interrupted_line(stop, _interrupt_note(args))}", file=sys.stderr)
        return INTERRUPTED
    except SystemError as err:  # Ctrl-C outside a simulation, inside a compiled kernel
        if not interrupted_in_compiled_code(err):
            raise
        line = interrupted_line(KeyboardInterrupt(), _interrupt_note(args))
        print(f"pbvs-pin: {line}", file=sys.stderr)
        return INTERRUPTED
    except BrokenPipeError:  # e.g. `pbvs-pin list | head`: the reader left, nothing to say
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except OSError as err:  # a system error no file door caught: one line all the same
        print(f"pbvs-pin: error: {err.filename or ''}: {err.strerror or err}", file=sys.stderr)
        return 2
    finally:
        finished()
    return 0


def _interrupt_note(args: argparse.Namespace | None) -> str:
    """What a command adds to the line of an interruption.

    Its ``interrupted`` default, or, for a command that holds no Ctrl-C, what it may have
    written.
    """
    note = getattr(args, "interrupted", None)
    if note is not None:
        return note(args)
    if args is None or args.simulates:
        return ""
    paths = [getattr(args, dest) for dest, _ in getattr(args, "outputs", ())]
    paths = [str(path) for path in paths if path is not None]
    if not paths:
        return "nothing was written"
    return f"what it wrote to {', '.join(paths)} before it is kept; the rest was not written"


if __name__ == "__main__":
    sys.exit(main())
