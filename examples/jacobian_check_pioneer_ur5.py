# /// script
# requires-python = ">=3.11"
# dependencies = ["pbvs_pin"]  # from this repository: pip install .
# ///
"""Check the feature Jacobians of eq. (3) against finite differences, for your own robot.

``xi_dot = J v + J_o p_dot``: ``J`` [px per unit of v] maps the actuated velocities
``v = [u [m/s], omega [rad/s], arm rates [rad/s]]`` to the feature rates, ``J_o`` [px/m] the
target's velocity in the world. Central differences on the configuration manifold
(``robot.integrate``, i.e. ``pin.integrate(q, S v dt)``) and on the target position give both
columns one by one, at seeded random arm postures with the target 0.6 m ahead of the camera.

    python examples/jacobian_check_pioneer_ur5.py                       # UR5 on the Pioneer
    python examples/jacobian_check_pioneer_ur5.py --robot my_robot.urdf  # any URDF with a
                                                                        # camera_optical_frame
    python examples/jacobian_check_pioneer_ur5.py --no-viz              # no plot
"""

import argparse

import numpy as np

import pbvs_pin

STEP = 1e-6  # finite-difference step [m, rad]
POSTURES = 5  # random arm postures checked
DIAMETER = 0.05  # sphere diameter [m]


def features_at(features, robot, q, centres) -> np.ndarray:
    """Features ``xi`` [px] of world sphere centres (shape (2, 3)) seen at ``q``. Shape (3,)."""
    return features.features(features.measure(robot, q, centres))


def check(robot, q, centres) -> tuple[float, float, np.ndarray]:
    """Largest errors of ``J`` and ``J_o`` [px per unit] and ``|J - J_fd|``, shape (3, n)."""
    features = pbvs_pin.TwoSphereFeatures(DIAMETER)
    _, jacobian, object_jacobian = features.jacobians(robot, q, *centres)
    numeric = np.zeros_like(jacobian)
    for i in range(robot.n):
        dv = np.zeros(robot.n)
        dv[i] = STEP
        plus = features_at(features, robot, robot.integrate(q, dv, 1.0), centres)
        minus = features_at(features, robot, robot.integrate(q, -dv, 1.0), centres)
        numeric[:, i] = (plus - minus) / (2 * STEP)
    numeric_o = np.zeros_like(object_jacobian)
    for j in range(3):
        dp = np.zeros(3)
        dp[j] = STEP  # both spheres move together
        plus = features_at(features, robot, q, centres + dp)
        minus = features_at(features, robot, q, centres - dp)
        numeric_o[:, j] = (plus - minus) / (2 * STEP)
    difference = np.abs(jacobian - numeric)
    return difference.max(), np.abs(object_jacobian - numeric_o).max(), difference


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="pioneer_ur5", help="shipped name or URDF path")
    parser.add_argument("--no-viz", action="store_true", help="no plot")
    args = parser.parse_args()

    robot = pbvs_pin.load_robot(args.robot)
    rng = np.random.default_rng(0)
    lower, upper = robot.arm_position_limits()  # [rad or m]
    lower, upper = np.maximum(lower, -np.pi), np.minimum(upper, np.pi)  # continuous joints
    worst, worst_o, worst_map = 0.0, 0.0, None
    for _ in range(POSTURES):
        q = robot.with_arm_positions(robot.neutral(), rng.uniform(lower, upper))
        q[:2] = rng.uniform(-1.0, 1.0, 2)  # platform position [m]
        yaw = rng.uniform(-np.pi, np.pi)  # [rad]
        q[2:4] = np.cos(yaw), np.sin(yaw)
        pose = robot.camera_pose(q)  # world_T_camera
        # sphere centres 0.6 m ahead of the camera, 0.1 m apart (optical frame: y down)
        centres = np.array([pose.act(np.array([0.05, y, 0.6])) for y in (-0.05, 0.05)])
        error, error_o, difference = check(robot, q, centres)
        if error > worst:
            worst, worst_map = error, difference
        worst_o = max(worst_o, error_o)
    print(f"{args.robot}: n = {robot.n}, {POSTURES} random postures, step {STEP:g}")
    print(f"max |J - J_fd| = {worst:.2e} px per unit of v")
    print(f"max |J_o - J_o_fd| = {worst_o:.2e} px/m")
    print(f"max error: {max(worst, worst_o):.2e}")
    if not args.no_viz:
        import matplotlib.pyplot as plt

        plt.imshow(worst_map, cmap="viridis")
        plt.colorbar(label="|J - J_fd| [px per unit of v]")
        plt.xlabel("actuated velocity index")
        plt.ylabel("feature [u1, v1, v2]")
        plt.show()


if __name__ == "__main__":
    main()
