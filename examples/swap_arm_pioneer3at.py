# /// script
# requires-python = ">=3.11"
# dependencies = ["pbvs_pin"]  # from this repository: pip install .
# ///
"""Mount other arms on the reference platform (Pioneer 3-AT) and run an experiment.

Two arms: UR5 from example-robot-data (by name) and the Cyton-like arm from a URDF file (any
URDF path works: pass ``--arm-urdf`` and ``--camera-link``). Each is mounted on the platform
with :meth:`pbvs_pin.MobileManipulator.assemble`, given a home posture in which the camera
looks forward (:func:`pbvs_pin.compute_home`), and runs a shipped scenario with
``pbvs_pin.simulate(scenario, robot=...)``.

    python examples/swap_arm_pioneer3at.py            # Experiment 1, 30 s per arm
    python examples/swap_arm_pioneer3at.py --no-viz   # 3 s per arm
    python examples/swap_arm_pioneer3at.py --arm-urdf my_arm.urdf --camera-link tool0
"""

import argparse
import time

import numpy as np

import pbvs_pin
from pbvs_pin.model.shipped import shipped_urdf

MOUNT = (0.10, 0.0, 0.27, 0.0, 0.0, 0.0)  # arm root in the platform's root link [m, rad]
SHORT_RUN = 3.0  # simulated time of a --no-viz run [s]


def arms(args: argparse.Namespace) -> dict[str, tuple[str, str, tuple]]:
    """Label -> (arm source, camera link, optical frame pose in that link [m, rad])."""
    if args.arm_urdf:
        return {args.arm_urdf: (args.arm_urdf, args.camera_link, (0.0,) * 6)}
    return {
        # example-robot-data name; the camera sits on the tool flange, z along the tool axis
        "ur5 (example-robot-data)": ("ur5", "tool0", (0.0,) * 6),
        # a URDF file that already holds an optical frame (z forward, x right, y down)
        "cyton_alpha3.urdf": (
            str(shipped_urdf("cyton_alpha3")),
            "camera_optical_frame",
            (0.0,) * 6,
        ),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="experiment1", help="shipped name or TOML path")
    parser.add_argument("--arm-urdf", help="your own arm's URDF file")
    parser.add_argument("--camera-link", default="tool0", help="link the camera is fixed to")
    parser.add_argument("--no-viz", action="store_true", help="short runs")
    args = parser.parse_args()

    scenario = pbvs_pin.load_scenario(args.scenario)
    if args.no_viz:
        scenario = scenario.with_values(duration=SHORT_RUN)
    for label, (arm, camera_link, camera_pose) in arms(args).items():
        started = time.perf_counter()
        robot = pbvs_pin.MobileManipulator.assemble(
            base="pioneer3at", arm=arm, mount=MOUNT,
            camera_link=camera_link, camera_pose=camera_pose,
        )  # fmt: skip
        robot.home_arm = pbvs_pin.compute_home(robot)  # [rad]: the camera looks forward
        log = pbvs_pin.simulate(scenario, robot=robot)
        error = np.abs(log["xi"] - log["xi_d"])  # [px], shape (samples, 3)
        print(
            f"{label}: n = {robot.n}, home {np.round(robot.home_arm, 3).tolist()} rad, "
            f"final error {np.nanmax(error[-1]):.2f} px after {log['t'][-1]:.1f} s "
            f"({time.perf_counter() - started:.1f} s wall)"
        )


if __name__ == "__main__":
    main()
