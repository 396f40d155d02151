"""Manipulability and the posture that maximises it (theta_d of the paper's eq. (19)).

References: manipulability recomputed here from Pinocchio's frame Jacobian (Yoshikawa,
sqrt(det(J J^T))), the hand-written Jacobian of the reference robot, a brute-force grid
search over its two pitch joints, and perturbations of the returned posture.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import random_configuration

from pbvs_pin import (
    arm_manipulability,
    manipulability,
    max_manipulability_posture,
    whole_body_manipulability,
)

OPTIMISED_ROBOTS = (
    "pioneer_cyton",
    "pioneer_ur5",
    "pioneer_panda",
    "pioneer_kinova",
    "pioneer_xarm7",
)


def yoshikawa(robot, arm_angles) -> float:
    """sqrt(det(J J^T)) of the camera's arm Jacobian, LOCAL_WORLD_ALIGNED, base at origin.

    Translational rows only for an arm of <= 3 joints, all six rows otherwise.
    """
    q = pin.neutral(robot.model)
    for name, angle in zip(robot.arm_joint_names, arm_angles, strict=True):
        joint = robot.model.joints[robot.model.getJointId(name)]
        if joint.nq == 2:
            q[joint.idx_q : joint.idx_q + 2] = np.cos(angle), np.sin(angle)
        else:
            q[joint.idx_q] = angle
    data = robot.model.createData()
    full = pin.computeFrameJacobian(
        robot.model, data, q, robot.model.getFrameId(robot.camera_frame), pin.LOCAL_WORLD_ALIGNED
    )
    arm_columns = [
        robot.model.joints[robot.model.getJointId(n)].idx_v for n in robot.arm_joint_names
    ]
    jac = full[:, arm_columns]
    if len(arm_columns) <= 3:
        jac = jac[:3]
    return float(np.sqrt(max(np.linalg.det(jac @ jac.T), 0.0)))


@pytest.fixture(scope="module")
def optimum(load):
    cache = {}

    def _optimum(name):
        if name not in cache:
            robot = load(name)
            cache[name] = max_manipulability_posture(robot)
        return cache[name]

    return _optimum


@pytest.mark.parametrize(
    "name",
    [*OPTIMISED_ROBOTS, "tiago"],
)
def test_no_better_neighbour(load, optimum, name):
    robot = load(name)
    theta = optimum(name)
    lower, upper = robot.arm_position_limits()
    assert theta.shape == (robot.n_arm,)
    assert np.all(theta >= lower) and np.all(theta <= upper)
    best = yoshikawa(robot, theta)
    assert best > 0
    assert arm_manipulability(robot, robot.with_arm_positions(robot.neutral(), theta)) == (
        pytest.approx(best, rel=1e-9)
    )

    neighbours = []
    for i in range(robot.n_arm):
        for sign in (-1, 1):
            step = np.zeros(robot.n_arm)
            step[i] = sign * 1e-3
            neighbours.append(theta + step)
    rng = np.random.default_rng([51, len(name)])
    for scale in (1e-3, 1e-2, 5e-2):
        neighbours += [theta + rng.normal(0, scale, robot.n_arm) for _ in range(20)]
    for candidate in neighbours:
        if np.all(candidate >= lower) and np.all(candidate <= upper):
            assert yoshikawa(robot, candidate) <= best * (1 + 1e-6), candidate - theta


def test_reference_robot_optimum_against_grid_search(cyton, optimum, closed_form):
    """Brute force over both pitch joints inside their limits, hand-written Jacobian."""
    theta = optimum("pioneer_cyton")

    def hand_manipulability(q2, q3):
        linear, _ = closed_form.world_jacobian(0.0, 0.0, 0.0, 0.0, q2, q3)
        return abs(np.linalg.det(linear[:, 2:]))  # square 3 x 3: |det| = product of sigmas

    lower, upper = cyton.arm_position_limits()
    pitch = np.linspace(lower[1], upper[1], 151)
    elbow = np.linspace(lower[2], upper[2], 141)
    grid = np.array([[hand_manipulability(a, b) for b in elbow] for a in pitch])
    i, j = np.unravel_index(grid.argmax(), grid.shape)
    # Refine the best cell with a finer local grid.
    fine_pitch = np.linspace(pitch[max(i - 1, 0)], pitch[min(i + 1, 150)], 41)
    fine_elbow = np.linspace(elbow[max(j - 1, 0)], elbow[min(j + 1, 140)], 41)
    fine = np.array([[hand_manipulability(a, b) for b in fine_elbow] for a in fine_pitch])
    k, m = np.unravel_index(fine.argmax(), fine.shape)
    grid_best = fine[k, m]

    found = hand_manipulability(theta[1], theta[2])
    assert found >= grid_best * (1 - 1e-6)
    assert found <= grid_best * (1 + 1e-4)  # the grid is fine enough to be close
    np.testing.assert_allclose(theta[1:], [fine_pitch[k], fine_elbow[m]], atol=5e-3)
    # Manipulability does not depend on the yaw; ties go to the posture nearest home (0).
    assert abs(theta[0]) < 1e-3
    assert yoshikawa(cyton, theta) == pytest.approx(found, rel=1e-9)


def test_optimum_is_reproducible(cyton, optimum):
    np.testing.assert_array_equal(
        max_manipulability_posture(cyton, seed=0), optimum("pioneer_cyton")
    )


@pytest.mark.parametrize("seed", range(3))
def test_manipulability_is_product_of_singular_values(seed):
    rng = np.random.default_rng([52, seed])
    wide = rng.normal(size=(3, 5))
    tall = rng.normal(size=(6, 4))
    assert manipulability(wide) == pytest.approx(np.sqrt(np.linalg.det(wide @ wide.T)), rel=1e-10)
    assert manipulability(tall) == pytest.approx(np.sqrt(np.linalg.det(tall.T @ tall)), rel=1e-10)
    singular = wide.copy()
    singular[2] = 2 * singular[0] - singular[1]
    assert manipulability(singular) == pytest.approx(0.0, abs=1e-12)


def test_manipulability_does_not_depend_on_base_pose(cyton):
    rng = np.random.default_rng(53)
    q = random_configuration(cyton, rng)
    moved = q.copy()
    theta = rng.uniform(-np.pi, np.pi)
    moved[:4] = [*rng.uniform(-3, 3, 2), np.cos(theta), np.sin(theta)]
    assert arm_manipulability(cyton, moved) == pytest.approx(
        arm_manipulability(cyton, q), rel=1e-10
    )
    assert whole_body_manipulability(cyton, moved) == pytest.approx(
        whole_body_manipulability(cyton, q), rel=1e-10
    )


def test_reference_robot_arm_manipulability_by_hand(cyton, closed_form):
    rng = np.random.default_rng(54)
    q = random_configuration(cyton, rng)
    x, y, th = q[0], q[1], np.arctan2(q[3], q[2])
    linear, angular = closed_form.world_jacobian(x, y, th, *q[4:7])
    assert arm_manipulability(cyton, q) == pytest.approx(
        abs(np.linalg.det(linear[:, 2:])), rel=1e-9
    )
    _, rotation = closed_form.pose(x, y, th, *q[4:7])
    local = np.vstack([rotation.T @ linear, rotation.T @ angular])
    assert local.shape == (6, 5)  # tall: sqrt(det(J^T J))
    assert whole_body_manipulability(cyton, q) == pytest.approx(
        np.sqrt(np.linalg.det(local.T @ local)), rel=1e-8
    )
