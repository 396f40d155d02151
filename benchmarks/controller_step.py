"""Benchmark: the public controller's step, as a robot's 1 kHz loop calls it.

Run: ``python benchmarks/controller_step.py [--previous PATH]``. For the reference robot and the
xArm7 on the reference platform it times :meth:`pbvs_pin.Controller.step` call by call over 10 000
calls of a 1 kHz loop (the configuration moving every call, a frame every 33 ms arriving one frame
period after its capture, so that every step predicts), and the Pinocchio calls one step makes
(joint Jacobians, camera placement and Jacobian, CRBA, nonlinear effects, gravity; the centre of
mass's Jacobian with the support objective on), timed the same way in the same run; it prints the
medians, the 99th percentiles and the median ratio. Then the median of the controller's compiled
step alone (:meth:`FusedControlStep.step`: those Pinocchio calls and one compiled call predicting
the frame, without the input checks, the encoder history, the tracker or the command object): the
floor of this structure, Pinocchio called from Python. Last, the time a freshly built controller
took to build (compiling or loading its kernels) and its first step.

With ``--previous PATH`` (a checkout of another version of the package), it also runs the
closed loop (Experiment 1 on the reference robot, 10 s at a 1 kHz controller, setup not
counted) alternately with this checkout and that one, in fresh processes, and prints each
one's median real-time factor.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from control_step import control_step_calls

CALLS = 10_000
WARM_UP = 200
RATE = 1000.0  # [Hz]
CAMERA_PERIOD = 0.033  # [s]
CLOSED_LOOP = (
    "import pbvs_pin; s = pbvs_pin.load_scenario('experiment1').with_values("
    "**{'controller.rate': 1000.0, 'duration': 10.0}); log = pbvs_pin.simulate(s); "
    "print(10.0 / log.meta['wall_time'])"
)


def centres_of(robot) -> np.ndarray:
    """Two sphere centres [m] 0.5 m ahead of the camera at home, seen at v = +-60 px."""
    pose = robot.camera_pose(robot.home())
    depth = 0.5  # [m]
    return np.array([pose.act(np.array([0.0, -v * depth / 600, depth])) for v in (60, -60)])


def loop_inputs(robot, calls: int) -> tuple[list, dict]:
    """Configurations of a moving robot at 1 kHz and the frames that arrive, by call index."""
    from pbvs_pin import CameraFrame

    q0 = robot.home()
    velocity = np.r_[0.05, 0.02, np.full(robot.n_arm, 0.01)]
    configurations = [robot.integrate(q0, velocity, k / RATE) for k in range(calls)]
    centres = centres_of(robot)
    every = round(CAMERA_PERIOD * RATE)
    frames = {0: None}
    for k in range(0, calls - every, every):
        points, depths = robot.camera.project_world(robot.camera_pose(configurations[k]), centres)
        frames[k + every] = CameraFrame.seen(k / RATE, points, depths)  # one period late
    return configurations, frames


def per_call(function, calls: int) -> np.ndarray:
    """Each call's time [us]; ``function(k)`` is called for k = 0 ... calls - 1."""
    times = np.empty(calls)
    clock = time.perf_counter_ns
    for k in range(calls):
        start = clock()
        function(k)
        times[k] = clock() - start
    return times / 1e3


def step_and_calls(robot_name: str) -> dict[str, float]:
    """Median and 99th percentile [us] of the step and of its Pinocchio calls; build times."""
    import pbvs_pin

    scenario = pbvs_pin.load_scenario("experiment1").with_values(**{"robot.name": robot_name})
    robot = pbvs_pin.load_robot(robot_name)
    started = time.perf_counter()
    controller = pbvs_pin.Controller.from_scenario(scenario, robot, announce=False)
    built = time.perf_counter() - started
    model = controller.model
    total = WARM_UP + CALLS
    configurations, frames = loop_inputs(model, total)
    v = np.zeros(model.n)
    start = model.camera_pose(configurations[0])
    points, depths = model.camera.project_world(start, centres_of(model))
    frames[0] = pbvs_pin.CameraFrame.seen(0.0, points, depths)
    first = per_call(lambda k: controller.step(0.0, configurations[0], v, frames[0]), 1)[0]
    controller.reset()
    steps = per_call(
        lambda k: controller.step(k / RATE, configurations[k], v, frames.get(k)), total
    )[WARM_UP:]
    pin_model, data, frame = model.model, model.data, model.camera_frame_id
    v_pin = model.selection @ v
    support = controller.fused.support
    calls = per_call(
        lambda k: control_step_calls(pin_model, data, frame, configurations[k], v_pin, support),
        total,
    )[WARM_UP:]
    fused, tracker, laser = controller.fused, controller.tracker, controller.laser
    velocity, measurement = tracker.estimator.velocity, tracker.measurement
    floor = per_call(
        lambda k: fused.step(
            configurations[k], v, measurement, velocity, laser, 1 / RATE, (tracker.world, 0.033)
        ),
        total,
    )[WARM_UP:]
    return {
        "step_median": float(np.median(steps)), "step_p99": float(np.percentile(steps, 99)),
        "calls_median": float(np.median(calls)), "calls_p99": float(np.percentile(calls, 99)),
        "ratio": float(np.median(steps) / np.median(calls)), "built": built, "first": first,
        "floor_median": float(np.median(floor)),
    }  # fmt: skip


def closed_loop(previous: Path, repeats: int = 5) -> tuple[float, float]:
    """Median real-time factors of this checkout's and ``previous``'s loop, run alternately."""
    here = Path(__file__).resolve().parents[1]
    factors: dict[Path, list[float]] = {here: [], previous: []}
    for _ in range(repeats):
        for checkout in factors:
            env = {**os.environ, "PYTHONPATH": str(checkout)}
            result = subprocess.run(
                [sys.executable, "-c", CLOSED_LOOP], env=env, cwd=checkout, capture_output=True,
                text=True, check=True,
            )  # fmt: skip
            factors[checkout].append(float(result.stdout.split()[-1]))
    return statistics.median(factors[here]), statistics.median(factors[previous])


def main() -> None:
    """Print the measurements."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--previous", type=Path, help="another checkout, for the closed loop")
    args = parser.parse_args()
    print(f"Controller.step over {CALLS} calls at 1 kHz (frames one period late) [us]:")
    print(f"{'robot':<16}{'step median':>12}{'step p99':>10}{'pinocchio median':>18}"
          f"{'pinocchio p99':>15}{'ratio':>7}{'compiled step alone':>21}{'build [s]':>11}"
          f"{'first step':>12}")  # fmt: skip
    for name in ("pioneer_cyton", "pioneer_xarm7"):
        r = step_and_calls(name)
        print(f"{name:<16}{r['step_median']:>12.1f}{r['step_p99']:>10.1f}"
              f"{r['calls_median']:>18.1f}{r['calls_p99']:>15.1f}{r['ratio']:>7.2f}"
              f"{r['floor_median']:>21.1f}{r['built']:>11.2f}{r['first']:>12.1f}")  # fmt: skip
    if args.previous is not None:
        now, before = closed_loop(args.previous.resolve())
        print(f"closed loop, 1 kHz controller: {now:.1f}x real time; previous {before:.1f}x")


if __name__ == "__main__":
    main()
