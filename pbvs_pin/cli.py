"""The ``pbvs-pin`` command.

Every subcommand prints a package error (:class:`pbvs_pin.exceptions.PbvsError`) as one line
on stderr, without a traceback, and exits with status 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from pbvs_pin.exceptions import PbvsError


def _info(args: argparse.Namespace) -> None:
    """Print a robot's dof, joints, limits, camera and manipulability."""
    from pbvs_pin.catalogue import build_robot
    from pbvs_pin.manipulability import arm_manipulability, whole_body_manipulability

    robot = build_robot(args.robot)
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


PAPER_CLAIMS = {
    "experiment1": "errors ultimately bounded, final max |error| < 8 px",
    "experiment2": "errors bounded while avoiding the obstacle; arm returns to max manipulability",
    "experiment3": "errors bounded with a 20% kinematic model error (degraded but acceptable)",
    "experiment4": "errors converge to zero (perfect knowledge)",
}
"""The paper's claim for each experiment (§5), for the report."""


def run_scenario(name: str, out: Path, html: Path | None = None, progress: bool = True):
    """Simulate one scenario; write its log, summary, figures (and HTML replay) into ``out``."""
    from pbvs_pin.sim.loop import simulate
    from pbvs_pin.sim.metrics import summarize
    from pbvs_pin.sim.scenario import load_scenario
    from pbvs_pin.viz.figures import plot_run

    scenario = load_scenario(name)
    log = simulate(scenario, progress=progress)
    out.mkdir(parents=True, exist_ok=True)
    log.save(out)
    summary = summarize(log)
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    plot_run(log, out)
    if html is not None:
        from pbvs_pin.viz.replay import write_run_replay

        write_run_replay(log, html)
    return log, summary


def _run(args: argparse.Namespace) -> None:
    """Run one scenario."""
    out = Path(args.out)
    _, summary = run_scenario(args.scenario, out, Path(args.html) if args.html else None)
    print(json.dumps(summary, indent=2))
    print(f"log, summary and figures written to {out}")


def _reproduce(args: argparse.Namespace) -> None:
    """Run the paper's four experiments and write the report."""
    out = Path(args.out)
    rows = []
    for name in PAPER_CLAIMS:
        _, summary = run_scenario(name, out / name, out / name / "replay.html")
        rows.append(summary)
        print(f"{name}: max |error| over the last 5 s = "
              f"{summary['max_abs_error_final_window_px']:.2f} px")  # fmt: skip
    lines = [
        "# pbvs_pin: the paper's experiments reproduced in simulation",
        "",
        "| experiment | paper's claim | max abs error, last 5 s [px] | max abs error after 2 s "
        "[px] | min clearance [m] | arm to theta_d, last 5 s [rad] |",
        "|---|---|---|---|---|---|",
    ]
    for summary in rows:
        name = summary["scenario"]
        clearance = summary["min_clearance_m"]
        lines.append(
            f"| {name} | {PAPER_CLAIMS[name]} | {summary['max_abs_error_final_window_px']:.2f} | "
            f"{summary['max_abs_error_after_transient_px']:.1f} | "
            f"{'-' if clearance is None else f'{clearance:.3f}'} | "
            f"{summary['posture_error_final_window_rad']:.3f} |"
        )
    lines += ["", "Figures of each experiment are in its folder: " + ", ".join(
        f"[{name}]({name}/feature_errors.png)" for name in PAPER_CLAIMS)]  # fmt: skip
    (out / "report.md").write_text("\n".join(lines) + "\n")
    print(f"report written to {out / 'report.md'}")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every subcommand."""
    parser = argparse.ArgumentParser(
        prog="pbvs-pin",
        description="Passivity-based visual servoing of mobile manipulators (Pinocchio).",
    )
    commands = parser.add_subparsers(dest="command", required=True)
    info = commands.add_parser("info", help="describe a robot (shipped name or URDF path)")
    info.add_argument("robot", help="shipped robot name (e.g. pioneer_cyton) or URDF path")
    info.set_defaults(handler=_info)
    run = commands.add_parser("run", help="simulate one scenario (shipped name or TOML path)")
    run.add_argument("scenario")
    run.add_argument("--out", default="results/run", help="output folder")
    run.add_argument("--html", help="also write a standalone HTML replay to this file")
    run.set_defaults(handler=_run)
    reproduce = commands.add_parser("reproduce", help="run the paper's four experiments")
    reproduce.add_argument("--out", default="results", help="output folder")
    reproduce.set_defaults(handler=_reproduce)
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
