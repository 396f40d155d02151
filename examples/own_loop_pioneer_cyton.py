# /// script
# requires-python = ">=3.11"
# dependencies = ["pbvs_pin"]  # from this repository: pip install .
# ///
"""Run the controller in your own loop, as on a real robot: no simulator.

Every control period your loop gives :meth:`pbvs_pin.Controller.step` what a robot has, and
sends the returned ``v_ref`` to the robot's velocity loops. Each place where a real robot's
driver plugs in is marked ``# ROBOT:``. Here a few stand-ins play the robot, written with
public names only and none of the simulator:

- the velocity loops follow ``v_ref`` with first-order lags (0.25 s platform, 0.05 s arm),
  integrated at 1 kHz; the controller is told these lags (``servo_time_constants``);
- the camera projects the two sphere centres (a pinhole, with the scenario's pixel noise) at
  30 Hz and its frames arrive one frame period (33 ms) after their capture, stamped with the
  capture time;
- the laser gives the range and bearing of the nearest obstacle in its 180-degree field of
  view.

Idealised here: the odometry and the encoders are exact, the camera has no distortion.

    python examples/own_loop_pioneer_cyton.py                 # Experiment 1, 30 s, a plot
    python examples/own_loop_pioneer_cyton.py --no-viz --experiment experiment2 --frames-late 3
"""

import argparse
from collections import deque
from dataclasses import replace

import numpy as np

import pbvs_pin

CONTROL_RATE = 100.0  # [Hz]
PLANT_RATE = 1000.0  # [Hz] the stand-in robot's integration
PLATFORM_LAG = 0.25  # [s] the stand-in platform's velocity loop
ARM_LAG = 0.05  # [s] the stand-in arm's velocity loops
FINAL_WINDOW = 5.0  # [s] the window the report's rules judge


def target_offset(motion, t: float) -> np.ndarray:
    """The target's displacement [m] since t = 0, as the scenario's ``[motion]`` describes."""
    t = min(max(t, 0.0), motion.stop_time) if motion.kind != "still" else 0.0
    drift = np.array(motion.velocity) * t  # [m]
    if motion.kind != "weave":
        return drift
    return drift + np.array(motion.amplitude) * (1.0 - np.cos(2 * np.pi * motion.frequency * t))


def target_velocity(motion, t: float) -> np.ndarray:
    """The target's velocity [m/s] (central difference of :func:`target_offset`)."""
    h = 1e-6  # [s]
    return (target_offset(motion, t + h) - target_offset(motion, t - h)) / (2 * h)


def pinhole(robot, q, centres):
    """Image points [px] (origin at the image centre, u left, v up) and depths [m] of points."""
    in_camera = np.array([robot.camera_pose(q).actInv(c) for c in centres])  # optical frame
    depths = in_camera[:, 2]  # [m]
    points = -robot.camera.focal_px * in_camera[:, :2] / depths[:, None]  # [px]
    return points, depths


class StandInCamera:
    """Frames at ``rate``, each delivered ``frames_late`` frame periods after its capture."""

    def __init__(self, robot, rate: float, noise: float, frames_late: int, rng) -> None:
        self.robot, self.period, self.noise, self.rng = robot, 1.0 / rate, noise, rng
        self.late = frames_late * self.period  # [s]
        self.next_capture = 0.0  # [s]
        self.in_flight = deque()  # (arrival time [s], frame)

    def capture(self, t: float, q: np.ndarray, centres: np.ndarray) -> None:
        """Take an image if one is due (the true camera pose, the true target)."""
        if t + 1e-9 < self.next_capture:
            return
        self.next_capture += self.period
        points, depths = pinhole(self.robot, q, centres)
        half = np.array([self.robot.camera.width, self.robot.camera.height]) / 2  # [px]
        if np.all(depths > 0.05) and np.all(np.abs(points) < half):
            points = points + self.noise * self.rng.standard_normal(points.shape)
            frame = pbvs_pin.CameraFrame.seen(t, points, depths)  # stamped with its capture time
        else:
            frame = pbvs_pin.CameraFrame.not_visible(t)
        self.in_flight.append((t + self.late, frame))

    def arrived(self, t: float):
        """The newest frame that arrived by ``t``, or None."""
        frame = None
        while self.in_flight and self.in_flight[0][0] <= t + 1e-9:
            frame = self.in_flight.popleft()[1]
        return frame


class StandInRobot:
    """Velocity loops with first-order lags; the configuration integrated at 1 kHz."""

    def __init__(self, robot) -> None:
        self.robot = robot
        self.q, self.v = robot.home(), np.zeros(robot.n)
        self.lags = np.array([PLATFORM_LAG] * robot.n_base + [ARM_LAG] * robot.n_arm)  # [s]

    def follow(self, v_ref: np.ndarray, duration: float) -> None:
        """Track ``v_ref`` for ``duration`` [s]."""
        dt = 1.0 / PLANT_RATE  # [s]
        for _ in range(round(duration * PLANT_RATE)):
            self.v = self.v + dt / self.lags * (v_ref - self.v)
            self.q = self.robot.integrate(self.q, self.v, dt)


def laser(robot, q, obstacles) -> tuple[float, float]:
    """Range [m] to the nearest cylinder ahead (its surface) and its bearing [rad], clockwise."""
    pose = robot.base_pose(q)
    best = (np.inf, 0.0)
    for obstacle in obstacles:
        local = pose.actInv(np.array([obstacle.x, obstacle.y, 0.0]))  # [m]
        distance = np.hypot(local[0], local[1]) - obstacle.radius
        bearing = -np.arctan2(local[1], local[0])  # [rad]
        if distance < best[0] and abs(bearing) <= np.pi / 2:
            best = (distance, bearing)
    return best


def clearance(robot, q, obstacles, length: float, width: float) -> float:
    """Distance [m] from the platform's footprint rectangle to the nearest cylinder."""
    pose = robot.base_pose(q)
    gaps = [np.inf]
    for obstacle in obstacles:
        local = pose.actInv(np.array([obstacle.x, obstacle.y, 0.0]))
        outside = np.maximum(np.abs(local[:2]) - [length / 2, width / 2], 0.0)
        gaps.append(np.hypot(*outside) - obstacle.radius)
    return min(gaps)


def upright_angle(robot, q) -> float:
    """The image's roll [rad]: world up seen in the optical frame (x right, y down)."""
    up = robot.camera_pose(q).rotation.T @ np.array([0.0, 0.0, 1.0])
    return float(np.arctan2(up[0], -up[1]))


def start_centres(robot, q, xi0, separation: float) -> np.ndarray:
    """Sphere centres [m] (upper, lower) that the camera sees at ``xi0 = [u1, v1, v2]`` [px]."""
    f = robot.camera.focal_px  # [px]
    z = f * separation / (xi0[1] - xi0[2])  # [m] both spheres at one depth
    x = -xi0[0] * z / f
    pose = robot.camera_pose(q)
    return np.array([pose.act(np.array([x, -v * z / f, z])) for v in xi0[1:]])


def run(experiment="experiment1", robot_name="pioneer_cyton", frames_late=1, duration=None,
        seed=0, values=None):  # fmt: skip
    """Run one experiment in this loop; return its time series (arrays, first axis time).

    ``values`` replaces scenario keys (dotted names, as ``Scenario.with_values`` takes them).
    """
    scenario = pbvs_pin.load_scenario(experiment).with_values(**(values or {}))
    robot = pbvs_pin.load_robot(robot_name)
    duration = scenario.duration if duration is None else duration  # [s]
    # the controller: the scenario's settings, the stand-in robot's loop lags, a 0.5 s hold
    settings = replace(
        pbvs_pin.ControllerSettings.from_scenario(scenario),
        servo_time_constants=(PLATFORM_LAG,) * robot.n_base + (ARM_LAG,) * robot.n_arm,
        estimator=replace(scenario.estimator, hold=0.5),
    )
    controller = pbvs_pin.Controller(robot, settings)  # compiles (or loads) its kernels now
    plant = StandInRobot(robot)
    rng = np.random.default_rng(seed)
    camera = StandInCamera(robot, scenario.camera.rate, scenario.camera.noise_px, frames_late, rng)
    target = scenario.target
    start = start_centres(robot, plant.q, target.xi0, target.separation)
    exact = scenario.estimator.kind == "exact"  # the scenario gives the target velocity
    rows = {name: [] for name in ("t", "error", "v_ref", "clearance", "posture", "roll")}
    period = 1.0 / CONTROL_RATE  # [s]
    for step in range(round(duration * CONTROL_RATE)):
        t = step * period  # [s] ROBOT: your clock, the one the camera's stamps use
        q, v = plant.q, plant.v  # ROBOT: odometry and joint encoders, Pinocchio layout
        centres = start + target_offset(scenario.motion, t)  # [m]
        camera.capture(t, plant.q, centres)
        frame = camera.arrived(t)  # ROBOT: your detector's newest frame, with its capture time
        scan = laser(robot, q, scenario.obstacles)  # ROBOT: your laser driver's nearest return
        velocity = target_velocity(scenario.motion, t) if exact else None
        command = controller.step(t, q, v, frame, scan, velocity)
        plant.follow(command.v_ref, period)  # ROBOT: send v_ref to the velocity loops
        points, _ = pinhole(robot, plant.q, centres)  # the truth, for the evaluation
        rows["t"].append(t + period)
        rows["error"].append(points.reshape(-1)[[0, 1, 3]] - controller.xi_d)
        rows["v_ref"].append(command.v_ref)
        rows["clearance"].append(clearance(robot, plant.q, scenario.obstacles, 0.5, 0.49))
        arm = robot.arm_positions(plant.q)
        rows["posture"].append(np.abs(arm - controller.posture_target).max())
        rows["roll"].append(upright_angle(robot, plant.q))
    return {name: np.array(values) for name, values in rows.items()}


def final_error(log) -> float:
    """Max |xi - xi_d| over the last 5 s [px]."""
    return float(np.abs(log["error"][log["t"] > log["t"][-1] - FINAL_WINDOW]).max())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiment", default="experiment1")
    parser.add_argument("--robot", default="pioneer_cyton")
    parser.add_argument("--frames-late", type=int, default=1, help="camera periods")
    parser.add_argument("--duration", type=float, help="[s]; the experiment's by default")
    parser.add_argument("--no-viz", action="store_true", help="no plot")
    args = parser.parse_args()
    log = run(args.experiment, args.robot, args.frames_late, args.duration)
    print(f"initial feature error: {np.abs(log['error'][0]).max():.1f} px")
    print(f"max |error| over the last 5 s: {final_error(log):.2f} px")
    print(f"largest image roll: {np.degrees(np.abs(log['roll']).max()):.2f} deg")
    if not args.no_viz:
        import matplotlib.pyplot as plt

        plt.plot(log["t"], log["error"], label=["u1", "v1", "v2"])
        plt.xlabel("t [s]")
        plt.ylabel("xi - xi_d [px]")
        plt.legend()
        plt.show()


if __name__ == "__main__":
    main()
