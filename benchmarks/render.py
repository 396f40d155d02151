"""Benchmark: the rendered camera's cost per frame, and a rendered Experiment 1.

Run: ``python benchmarks/render.py`` (``MUJOCO_GL=egl`` is set when not given). Prints the
median time of drawing one 628 x 582 frame with MuJoCo (:class:`SceneRenderer`, Experiment 1's
start, the robot and the spheres in view) and of finding the spheres in it
(:class:`ColourDetector`), medians over repeats (the machine is shared); then the wall time of
Experiment 1 (30 s simulated) on the Pinocchio plant with ``camera.model = "points"`` and
``"rendered"``, and on the MuJoCo plant rendered, with each rendered run's detection figures
from its summary.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before MuJoCo is imported

import statistics
import time

from control_step import mean_time

from pbvs_pin.perception.detection import ColourDetector
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.metrics import summarize
from pbvs_pin.sim.render import SceneRenderer
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.setup import build

REPEATS = 7
FRAMES = 10
RUNS = (("points", "pinocchio"), ("rendered", "pinocchio"), ("rendered", "mujoco"))
"""``(camera.model, plant.engine)`` of the timed runs of Experiment 1."""


def frame_costs() -> tuple[float, float]:
    """Median time [s] of rendering one frame and of detecting the spheres in it."""
    setup = build(load_scenario("experiment1"))
    robot, camera, q = setup.robot, setup.robot.camera, setup.plant.q
    scene = SceneRenderer(robot, camera, setup.target.diameter, setup.obstacles)
    pose, centres = robot.camera_pose(q), setup.target.centres(0.0)
    detector = ColourDetector(camera)
    image = scene.render(q, pose, centres)
    render = [mean_time(lambda: scene.render(q, pose, centres), FRAMES) for _ in range(REPEATS)]
    detect = [mean_time(lambda: detector.detect(image), FRAMES) for _ in range(REPEATS)]
    scene.close()
    return statistics.median(render), statistics.median(detect)


def run_wall_time(model: str, engine: str) -> tuple[float, dict]:
    """Wall time [s] of Experiment 1 with camera ``model`` on plant ``engine``; its summary."""
    keys = {"camera.model": model, "plant.engine": engine}
    scenario = load_scenario("experiment1").with_values(**keys)
    start = time.perf_counter()
    log = simulate(scenario)
    return time.perf_counter() - start, summarize(log)


def main() -> None:
    """Print the per-frame costs and the wall times."""
    render, detect = frame_costs()
    print(f"render one 628 x 582 frame: {1e3 * render:.1f} ms (median of {REPEATS})")
    print(f"detect the spheres in it:   {1e3 * detect:.1f} ms")
    for model, engine in RUNS:
        wall, summary = run_wall_time(model, engine)
        print(f"Experiment 1 (30 s), camera.model = {model}, {engine} plant: {wall:.1f} s wall")
        if model == "rendered":
            print_detection(summary)


def print_detection(summary: dict) -> None:
    """A rendered run's detection figures and final-window error."""
    print(
        f"  {summary['detection_frames']} frames, "
        f"{summary['detection_missed_frames']} missed, detection error "
        f"{summary['detection_error_rms_px']:.3f} px RMS, "
        f"{summary['detection_error_max_px']:.3f} px max; final-window error "
        f"{summary['max_abs_error_final_window_px']:.3f} px"
    )


if __name__ == "__main__":
    main()
