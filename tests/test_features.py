"""Feature Jacobians of eq. (3) and the camera Jacobian they are built on.

References, none taken from the code under test:

* a closed-form forward kinematics and hand-differentiated Jacobian of the reference robot
  ``pioneer_cyton`` (unicycle platform + yaw/pitch/pitch arm), with its link offsets parsed
  from the shipped URDF with ``xml.etree``, and the textbook point interaction matrix
  (Chaumette & Hutchinson 2006) written out here;
* central finite differences of the whole pipeline q -> camera pose -> own pinhole projection,
  moving on the configuration manifold with ``robot.integrate``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import (
    ARM_ROBOTS,
    pinhole,
    points_in_front,
    project_world,
    random_configuration,
)

from pbvs_pin import ImagePointFeatures, TwoSphereFeatures

FD_ROBOTS = ("pioneer_cyton", *ARM_ROBOTS, "tiago")
TWO_SPHERE_ROWS = [0, 1, 3]  # [u1, v1, v2] out of [u1, v1, u2, v2]


# ================================================================ closed-form reference robot
def cyton_state(rng: np.random.Generator, robot):
    """Random (x, y, th, q1, q2, q3) inside the joint limits, and the Pinocchio q."""
    x, y = rng.uniform(-3, 3, 2)
    th = rng.uniform(-np.pi, np.pi)
    q1, q2, q3 = rng.uniform([-2.5, -1.4, -2.1], [2.5, 1.4, 0.5])
    q = np.array([x, y, np.cos(th), np.sin(th), q1, q2, q3])
    assert q.shape == (robot.model.nq,)
    return (x, y, th, q1, q2, q3), q


@pytest.mark.parametrize("seed", range(5))
def test_cyton_camera_pose_closed_form(cyton, closed_form, seed):
    rng = np.random.default_rng(seed)
    state, q = cyton_state(rng, cyton)
    position, rotation = closed_form.pose(*state)
    pose = cyton.camera_pose(q)
    np.testing.assert_allclose(pose.translation, position, atol=1e-12)
    np.testing.assert_allclose(pose.rotation, rotation, atol=1e-12)


def test_cyton_home_camera_looks_forward(cyton, closed_form):
    # The paper's initial configuration is all zeros; the hand FK gives the optical axis.
    position, rotation = closed_form.pose(0, 0, 0, 0, 0, 0)
    np.testing.assert_allclose(rotation[:, 2], [1, 0, 0], atol=1e-4)  # z forward
    np.testing.assert_allclose(rotation[:, 1], [0, 0, -1], atol=1e-4)  # y down
    np.testing.assert_allclose(cyton.camera_pose(cyton.home()).translation, position, atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_cyton_camera_jacobian_closed_form(cyton, closed_form, seed):
    rng = np.random.default_rng(100 + seed)
    state, q = cyton_state(rng, cyton)
    _, rotation = closed_form.pose(*state)
    linear, angular = closed_form.world_jacobian(*state)
    expected_local = np.vstack([rotation.T @ linear, rotation.T @ angular])

    jacobian = cyton.camera_jacobian(q)
    assert jacobian.shape == (6, 5)
    np.testing.assert_allclose(jacobian, expected_local, atol=1e-9)


def textbook_interaction(focal: float, point_in_camera: np.ndarray) -> np.ndarray:
    """d xi / d [v_c; w_c] for xi = -f [x/z, y/z], point fixed in the world.

    Normalised coordinates s = (x/z, y/z) have the classic interaction matrix
    L_s = [[-1/Z, 0, x/Z, x y, -(1 + x^2), y], [0, -1/Z, y/Z, 1 + y^2, -x y, -x]]
    (Chaumette & Hutchinson 2006), and xi = -f s.
    """
    big_x, big_y, z = point_in_camera
    x, y = big_x / z, big_y / z
    normalised = np.array(
        [
            [-1 / z, 0, x / z, x * y, -(1 + x * x), y],
            [0, -1 / z, y / z, 1 + y * y, -x * y, -x],
        ]
    )
    return -focal * normalised


@pytest.mark.parametrize("seed", range(5))
def test_cyton_feature_jacobian_closed_form(cyton, closed_form, seed):
    rng = np.random.default_rng(200 + seed)
    state, q = cyton_state(rng, cyton)
    position, rotation = closed_form.pose(*state)
    linear, angular = closed_form.world_jacobian(*state)
    camera_local = np.vstack([rotation.T @ linear, rotation.T @ angular])
    focal = cyton.camera.focal_px

    p_top, p_bottom = points_in_front(pin.SE3(rotation, position), rng, 2)
    in_camera = [rotation.T @ (p - position) for p in (p_top, p_bottom)]
    expected_xi = np.concatenate([pinhole(focal, p) for p in in_camera])[TWO_SPHERE_ROWS]
    interaction = np.vstack([textbook_interaction(focal, p) for p in in_camera])
    expected_j = (interaction @ camera_local)[TWO_SPHERE_ROWS]
    # d xi / d p_world: the point moves, the camera does not.
    object_blocks = [
        -focal / z * np.array([[1, 0, -x / z], [0, 1, -y / z]]) @ rotation.T
        for x, y, z in in_camera
    ]
    expected_jo = np.vstack(object_blocks)[TWO_SPHERE_ROWS]

    xi, jac, jac_o = TwoSphereFeatures(diameter=0.1).jacobians(cyton, q, p_top, p_bottom)
    assert xi.shape == (3,) and jac.shape == (3, 5) and jac_o.shape == (3, 3)
    np.testing.assert_allclose(xi, expected_xi, rtol=1e-11, atol=1e-9)
    np.testing.assert_allclose(jac, expected_j, rtol=1e-9, atol=1e-9 * np.abs(expected_j).max())
    np.testing.assert_allclose(jac_o, expected_jo, rtol=1e-9, atol=1e-9 * np.abs(expected_jo).max())


# ================================================================ finite differences, all robots
def _features(robot, q, points, rows):
    pose = robot.camera_pose(q)
    focal = robot.camera.focal_px
    return np.concatenate([project_world(focal, pose, p) for p in points])[rows]


def _fd_jacobians(robot, q, points, rows, h=1e-6):
    """Central differences of xi w.r.t. actuated velocity directions and target motion."""
    jac = np.zeros((len(rows), robot.n))
    for i in range(robot.n):
        step = np.zeros(robot.n)
        step[i] = h
        plus = _features(robot, robot.integrate(q, step, 1.0), points, rows)
        minus = _features(robot, robot.integrate(q, -step, 1.0), points, rows)
        jac[:, i] = (plus - minus) / (2 * h)
    jac_o = np.zeros((len(rows), 3))
    for k in range(3):
        delta = np.zeros(3)
        delta[k] = h
        plus = _features(robot, q, [p + delta for p in points], rows)
        minus = _features(robot, q, [p - delta for p in points], rows)
        jac_o[:, k] = (plus - minus) / (2 * h)
    return jac, jac_o


def _assert_close_relative(actual, expected, rtol):
    scale = np.abs(expected).max()
    np.testing.assert_allclose(actual, expected, rtol=rtol, atol=rtol * scale)


@pytest.mark.parametrize("name", FD_ROBOTS)
def test_two_sphere_jacobians_match_finite_differences(load, name):
    robot = load(name)
    rng = np.random.default_rng([11, FD_ROBOTS.index(name)])
    features = TwoSphereFeatures(diameter=0.12)
    for _ in range(3):
        q = random_configuration(robot, rng)
        points = points_in_front(robot.camera_pose(q), rng, 2)
        xi, jac, jac_o = features.jacobians(robot, q, *points)
        assert jac.shape == (3, robot.n) and jac_o.shape == (3, 3)
        np.testing.assert_allclose(xi, _features(robot, q, points, TWO_SPHERE_ROWS), atol=1e-9)
        fd_jac, fd_jac_o = _fd_jacobians(robot, q, points, TWO_SPHERE_ROWS)
        _assert_close_relative(jac, fd_jac, 1e-5)
        _assert_close_relative(jac_o, fd_jac_o, 1e-5)


@pytest.mark.parametrize("name", ["pioneer_cyton", "pioneer_panda", "tiago"])
def test_image_point_jacobians_match_finite_differences(load, name):
    robot = load(name)
    rng = np.random.default_rng([12, len(name)])
    features = ImagePointFeatures(3)
    rows = list(range(6))
    for _ in range(2):
        q = random_configuration(robot, rng)
        points = points_in_front(robot.camera_pose(q), rng, 3)
        xi, jac, jac_o = features.jacobians(robot, q, *points)
        assert xi.shape == (6,) and jac.shape == (6, robot.n) and jac_o.shape == (6, 3)
        fd_jac, fd_jac_o = _fd_jacobians(robot, q, points, rows)
        _assert_close_relative(jac, fd_jac, 1e-5)
        _assert_close_relative(jac_o, fd_jac_o, 1e-5)


@pytest.mark.parametrize("name", FD_ROBOTS)
def test_camera_jacobian_is_local_twist(load, name):
    """Columns of camera_jacobian against the body-frame twist of the camera pose, by FD."""
    robot = load(name)
    rng = np.random.default_rng([13, FD_ROBOTS.index(name)])
    q = random_configuration(robot, rng)
    pose = robot.camera_pose(q)
    h = 1e-6
    fd = np.zeros((6, robot.n))
    for i in range(robot.n):
        step = np.zeros(robot.n)
        step[i] = h
        plus = pose.actInv(robot.camera_pose(robot.integrate(q, step, 1.0)))
        minus = pose.actInv(robot.camera_pose(robot.integrate(q, -step, 1.0)))
        fd[:, i] = (pin.log6(plus).vector - pin.log6(minus).vector) / (2 * h)
    _assert_close_relative(robot.camera_jacobian(q), fd, 1e-6)


def test_features_do_not_depend_on_diameter(cyton):
    """Depth is the true depth in ``jacobians``; the diameter only serves the image model."""
    rng = np.random.default_rng(14)
    q = random_configuration(cyton, rng)
    points = points_in_front(cyton.camera_pose(q), rng, 2)
    a = TwoSphereFeatures(diameter=0.05).jacobians(cyton, q, *points)
    b = TwoSphereFeatures(diameter=0.3).jacobians(cyton, q, *points)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


def test_measure_depths_are_optical_z(cyton):
    rng = np.random.default_rng(15)
    q = random_configuration(cyton, rng)
    pose = cyton.camera_pose(q)
    points = np.array(points_in_front(pose, rng, 2))
    measurement = TwoSphereFeatures(diameter=0.1).measure(cyton, q, points)
    expected_depths = [(pose.rotation.T @ (p - pose.translation))[2] for p in points]
    np.testing.assert_allclose(measurement.depths, expected_depths, rtol=1e-12)
    assert measurement.points.shape == (2, 2)
