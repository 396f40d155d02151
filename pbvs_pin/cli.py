"""The ``pbvs-pin`` command.

Every subcommand prints a package error (:class:`pbvs_pin.exceptions.PbvsError`) as one line
on stderr, without a traceback, and exits with status 2.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

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
