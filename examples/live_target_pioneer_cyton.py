# /// script
# requires-python = ">=3.11"
# dependencies = ["pbvs_pin"]  # from this repository: pip install .
# ///
"""Interactive Meshcat: the target flies a scripted figure-eight while the robot servos.

The target's path is yours: edit :func:`target_path` (or feed it from a keyboard or a
joystick), and the robot follows it live in the browser. The loop is the one of
``own_loop_pioneer_cyton.py``: :class:`pbvs_pin.Controller` turns camera frames (stamped with
their capture time) and encoders into velocity references; a first-order lag stands in for the
robot's velocity loops.
:class:`pbvs_pin.viz.live.LiveView` draws the robot, the target, the camera frustum with the
desired (green) and current feature points, and the trails.

    python examples/live_target_pioneer_cyton.py               # opens Meshcat, 40 s in real time
    python examples/live_target_pioneer_cyton.py --speed 2     # twice as fast
    python examples/live_target_pioneer_cyton.py --no-viz      # headless, 5 s
"""

import argparse
import webbrowser

import numpy as np

import pbvs_pin
from pbvs_pin.sim.loop import Snapshot

CONTROL_RATE = 100.0  # [Hz]
CAMERA_EVERY = 3  # a camera frame every 3 control periods: 33 Hz
SHOW_EVERY = 2  # a view update every 2 control periods: 50 Hz
LOOP_TIME_CONSTANT = 0.05  # the robot's velocity loops [s]
PERIOD = 20.0  # of the figure-eight [s]


def target_path(t: float) -> np.ndarray:
    """Displacement of the target from its start in the world frame [m]. Shape (3,).

    A figure-eight 0.8 m long and 0.5 m wide that rises and falls by 0.1 m; at most
    0.13 m/s.
    """
    w = 2.0 * np.pi / PERIOD  # [rad/s]
    return np.array([0.4 * np.sin(w * t), 0.25 * np.sin(2.0 * w * t), 0.1 * np.sin(w * t)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=40.0, help="[s]")
    parser.add_argument("--speed", type=float, default=1.0, help="simulated s per wall s")
    parser.add_argument("--no-viz", action="store_true", help="headless, 5 s")
    args = parser.parse_args()
    duration = 5.0 if args.no_viz else args.duration

    scenario = pbvs_pin.load_scenario("experiment1")  # gains, xi_d, robot, drawing
    robot = pbvs_pin.load_robot("pioneer_cyton")
    controller = pbvs_pin.Controller.from_scenario(scenario, robot)
    features = pbvs_pin.TwoSphereFeatures(scenario.target.diameter)
    live = None
    if not args.no_viz:
        from pbvs_pin.viz.live import LiveView

        live = LiveView(scenario, speed=args.speed)
        print(f"Meshcat at {live.url}")
        webbrowser.open(live.url)

    q, v = robot.home(), np.zeros(robot.n)
    pose = robot.camera_pose(q)  # world_T_camera
    # the two sphere centres 0.6 m ahead of the camera, 0.1 m apart (optical frame: y down)
    start = np.array([pose.act(np.array([0.10, y, 0.6])) for y in (-0.05, 0.05)])  # [m]
    dt = 1.0 / CONTROL_RATE  # [s]
    errors = []
    try:
        for step in range(round(duration * CONTROL_RATE)):
            t = step * dt
            centres = start + target_path(t)  # [m], shape (2, 3)
            frame = None
            if step % CAMERA_EVERY == 0:
                image = features.measure(robot, q, centres)  # points [px], depths [m]
                frame = pbvs_pin.CameraFrame.seen(t, image.points, image.depths)
            command = controller.step(t, q, v, frame)
            errors.append(np.abs(command.error).max())
            if live is not None and step % SHOW_EVERY == 0:
                seen = controller.tracker.measurement
                live.show(
                    Snapshot(
                        t, q.copy(), centres, command.error + controller.xi_d,
                        controller.xi_d, seen.points,
                    )
                )  # fmt: skip
            v = v + dt / LOOP_TIME_CONSTANT * (command.v_ref - v)  # the velocity loops
            q = robot.integrate(q, v, dt)
    finally:
        if live is not None:
            live.close()
    errors = np.array(errors)  # [px]
    tail = errors[-round(CONTROL_RATE) :]  # the last second
    print(f"max feature error over the last second: {tail.max():.2f} px (start {errors[0]:.0f} px)")


if __name__ == "__main__":
    main()
