# /// script
# requires-python = ">=3.11"
# dependencies = ["pbvs_pin"]  # from this repository: pip install .
# ///
"""Run the controller in your own loop, as on a real robot: no simulator.

Each control period you give :meth:`pbvs_pin.Controller.step` what a real robot has:
- the configuration ``q`` from odometry and joint encoders (Pinocchio layout: x, y, cos yaw,
  sin yaw of the platform, then the arm joints);
- the measured velocities ``v = [u [m/s], omega [rad/s], arm joint rates [rad/s]]``;
- when a new camera frame arrived, the image points ``[u, v]`` of both sphere centres [px]
  (origin at the image centre, u to the left, v upwards) and their depths [m], here from the
  spheres' apparent diameters, ``z = f D / d``;
and send the returned ``v_ref`` to the robot's velocity loops.

Here a few lines stand in for the robot: the image comes from projecting a moving target,
the velocity loops follow ``v_ref`` with a first-order lag, and ``q`` is integrated.

    python examples/own_loop_pioneer_cyton.py           # 15 s, then a plot of the error
    python examples/own_loop_pioneer_cyton.py --no-viz  # 5 s, no plot
"""

import argparse

import numpy as np

import pbvs_pin

CONTROL_RATE = 100.0  # [Hz]
CAMERA_EVERY = 3  # a camera frame every 3 control periods: 33 Hz
LOOP_TIME_CONSTANT = 0.05  # the robot's velocity loops [s]
TARGET_VELOCITY = np.array([0.10, 0.03, 0.0])  # in the world frame [m/s]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=15.0, help="[s]")
    parser.add_argument("--no-viz", action="store_true", help="5 s, no plot")
    args = parser.parse_args()
    duration = 5.0 if args.no_viz else args.duration

    robot = pbvs_pin.load_robot("pioneer_cyton")
    # the scenario gives xi_d, the gains, the compensation and the secondary objectives
    scenario = pbvs_pin.load_scenario("experiment1")
    controller = pbvs_pin.Controller.from_scenario(scenario, robot)
    diameter = scenario.target.diameter  # [m]
    camera = robot.camera  # focal length [px], image size [px]

    # stand-in for the robot and the target
    q, v = robot.home(), np.zeros(robot.n)
    pose = robot.camera_pose(q)  # world_T_camera
    # the two sphere centres 0.6 m ahead of the camera, 0.1 m apart (optical frame: y down)
    start = np.array([pose.act(np.array([0.10, y, 0.6])) for y in (-0.05, 0.05)])  # [m]
    dt = 1.0 / CONTROL_RATE  # [s]
    times, errors = [], []
    for step in range(round(duration * CONTROL_RATE)):
        t = step * dt
        points = depths = None
        if step % CAMERA_EVERY == 0:  # a new frame: image points [px] and apparent diameters
            centres = start + TARGET_VELOCITY * t  # [m], shape (2, 3)
            image = pbvs_pin.TwoSphereFeatures(diameter).measure(robot, q, centres)
            apparent = [camera.apparent_diameter(z, diameter) for z in image.depths]  # [px]
            points = image.points
            depths = [camera.depth_from_diameter(d, diameter) for d in apparent]  # [m]

        command = controller.step(q, v, points, depths, t)  # your robot's control step

        v = v + dt / LOOP_TIME_CONSTANT * (command.v_ref - v)  # the velocity loops
        q = robot.integrate(q, v, dt)  # odometry and encoders
        times.append(t)
        errors.append(command.error)

    errors = np.array(errors)  # [px], shape (steps, 3)
    print(f"initial feature error: {np.abs(errors[0]).max():.1f} px")
    print(f"final feature error: {np.abs(errors[-1]).max():.2f} px after {times[-1]:.2f} s")
    print(f"estimated target velocity: {np.round(command.target_velocity, 3)} m/s")
    if not args.no_viz:
        import matplotlib.pyplot as plt

        plt.plot(times, errors, label=["u1", "v1", "v2"])
        plt.xlabel("t [s]")
        plt.ylabel("xi - xi_d [px]")
        plt.legend()
        plt.show()


if __name__ == "__main__":
    main()
