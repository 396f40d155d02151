"""Benchmark: the latency through DDS from a sensor message to the ``cmd_vel`` it causes.

Starts ``pbvs-pin ros control experiment1 --use-sim-time`` in its own process and plays the
robot in this one (:class:`pbvs_pin.ros.stand_in.StandInRobot`): every tick publishes
``joint_states`` and ``odom`` (and every third tick a camera image with the target's two
discs, so the node's detector runs), then ``/clock``, and times, on the wall clock, from the
readings' publication to the arrival of the ``cmd_vel`` the node's step computes from them:
two DDS hops, the node's callbacks (the detection on image ticks) and its control step.
Prints the median and the 99th percentile, with and without an image.

With the node on the wall clock instead of ``/clock``, a reading also waits for the node's
next timer tick: up to one control period more (10 ms at 100 Hz, 5 ms on average).

Run: ``python benchmarks/ros_latency.py [--ticks 1500]`` (needs the ``ros`` extra).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys

import numpy as np
import rclpy

import pbvs_pin
from pbvs_pin.ros.stand_in import StandInRobot

WARM_UP = 100
"""Ticks left out at the start (discovery, the first frames)."""


def main() -> None:
    """Run the benchmark; print the latencies."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=1500)
    args = parser.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", str(10 + os.getpid() % 80))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    node = subprocess.Popen(
        [sys.executable, "-m", "pbvs_pin.cli", "ros", "control", "experiment1", "--use-sim-time"],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        node.stdout.readline()  # the node is built
        rclpy.init()
        robot = StandInRobot(pbvs_pin.load_scenario("experiment1"))
        for tick in range(WARM_UP + args.ticks):
            robot.tick(image=tick % 3 == 0)
        latencies = robot.latencies[-args.ticks :]
        for label, image in (("with an image", True), ("without", False)):
            values = 1e3 * np.array([dt for dt, i in latencies if i == image])
            print(f"{label:>14}: {values.size} ticks, median {np.median(values):.2f} ms, "
                  f"p99 {np.percentile(values, 99):.2f} ms")  # fmt: skip
        print(f"commands answered: {len(latencies)} of {args.ticks} ticks")
        robot.node.destroy_node()
        rclpy.try_shutdown()
    finally:
        node.send_signal(signal.SIGINT)
        node.wait(15)


if __name__ == "__main__":
    main()
