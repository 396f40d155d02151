"""Pinhole camera of eq. (2) and the point interaction matrix.

References: the projection written out in the test, and central finite differences of that
projection under a camera body twist, ``pose * exp6(twist h)`` (the camera moves, the point
is fixed in the world).
"""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
import pytest
from conftest import pinhole, project_world

from pbvs_pin import CameraIntrinsics, point_interaction_matrix


def _random_pose(rng: np.random.Generator) -> pin.SE3:
    return pin.SE3(pin.exp3(rng.uniform(-np.pi, np.pi, 3) / np.sqrt(3)), rng.uniform(-2, 2, 3))


def _point_in_front(pose: pin.SE3, rng: np.random.Generator) -> np.ndarray:
    z = rng.uniform(0.8, 2.0)
    in_camera = np.array([z * rng.uniform(-0.4, 0.4), z * rng.uniform(-0.4, 0.4), z])
    return pose.act(in_camera)


@pytest.mark.parametrize("focal", [420.0, 600.0, 955.5])
@pytest.mark.parametrize("seed", range(4))
def test_interaction_matrix_matches_body_twist_finite_differences(focal, seed):
    rng = np.random.default_rng([21, seed, int(focal)])
    pose = _random_pose(rng)
    point = _point_in_front(pose, rng)
    xi = project_world(focal, pose, point)
    depth = (pose.rotation.T @ (point - pose.translation))[2]

    h = 1e-6
    fd = np.zeros((2, 6))
    for k in range(6):
        twist = np.zeros(6)
        twist[k] = h
        plus = project_world(focal, pose * pin.exp6(twist), point)
        minus = project_world(focal, pose * pin.exp6(-twist), point)
        fd[:, k] = (plus - minus) / (2 * h)

    matrix = point_interaction_matrix(focal, xi, depth)
    assert matrix.shape == (2, 6)
    np.testing.assert_allclose(matrix, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_interaction_matrix_at_principal_point_by_hand():
    # Point on the optical axis at depth 2 m, f = 500 px: xi = 0, xn = yn = 0.
    # Moving the camera +x (right) moves the point left in the camera, x/z decreases, so
    # u = -f x / z increases by f/z per m: +250 px/m. Rotating about the camera y axis by
    # +w turns the optical axis towards +x: x/z of the point decreases by w, u grows by f.
    matrix = point_interaction_matrix(500.0, [0.0, 0.0], 2.0)
    expected = np.array(
        [
            [250.0, 0.0, 0.0, 0.0, 500.0, 0.0],
            [0.0, 250.0, 0.0, -500.0, 0.0, 0.0],
        ]
    )
    np.testing.assert_allclose(matrix, expected, atol=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_project_matches_paper_sign(seed):
    rng = np.random.default_rng([22, seed])
    camera = CameraIntrinsics(focal_px=rng.uniform(300, 900))
    point = np.array([*rng.uniform(-0.5, 0.5, 2), rng.uniform(0.5, 3)])
    np.testing.assert_allclose(camera.project(point), pinhole(camera.focal_px, point), rtol=1e-14)


def test_project_sign_convention_by_hand():
    # A point to the right (x > 0) and below (y > 0, optical y is down) of the axis has,
    # with eq. (2), u < 0 and v < 0.
    camera = CameraIntrinsics(focal_px=400.0, width=640, height=480)
    np.testing.assert_allclose(camera.project([0.1, 0.2, 2.0]), [-20.0, -40.0])
    # Pixel columns grow to the right, rows downwards: col = cx - u, row = cy - v.
    np.testing.assert_allclose(camera.to_pixel([-20.0, -40.0]), [340.0, 280.0])
    assert camera.in_image([[-20.0, -40.0]])
    assert not camera.in_image([[330.0, 0.0]])  # col = -10
    assert not camera.in_image([[0.0, 0.0]], margin=250.0)  # 240 px from top and bottom


@pytest.mark.parametrize("seed", range(3))
def test_project_jacobian_matches_finite_differences(seed):
    rng = np.random.default_rng([23, seed])
    camera = CameraIntrinsics(focal_px=rng.uniform(300, 900))
    point = np.array([*rng.uniform(-0.5, 0.5, 2), rng.uniform(0.8, 2)])
    h = 1e-6
    fd = np.column_stack(
        [
            (pinhole(camera.focal_px, point + h * e) - pinhole(camera.focal_px, point - h * e))
            / (2 * h)
            for e in np.eye(3)
        ]
    )
    np.testing.assert_allclose(camera.project_jacobian(point), fd, rtol=1e-6, atol=1e-4)


@pytest.mark.parametrize("seed", range(3))
def test_project_world_matches_the_pinhole_of_each_point(seed):
    """Many points at once, against the reference's point-by-point projection."""
    rng = np.random.default_rng([24, seed])
    camera = CameraIntrinsics(focal_px=rng.uniform(300, 900))
    pose = _random_pose(rng)
    points = np.array([_point_in_front(pose, rng) for _ in range(4)])
    image, depths = camera.project_world(pose, points)
    expected = np.array([project_world(camera.focal_px, pose, p) for p in points])
    np.testing.assert_allclose(image, expected, rtol=1e-12)
    np.testing.assert_allclose(depths, [pose.actInv(p)[2] for p in points], rtol=1e-12)


def test_project_world_divides_by_the_smallest_depth_given_and_never_warns():
    """``min_depth`` replaces a smaller depth as divisor (the depth itself is returned); a
    point in the camera's plane gives infinite coordinates and a NaN depth NaN, silently."""
    camera = CameraIntrinsics(focal_px=500.0)
    in_camera = np.array([[0.1, -0.2, 0.5], [0.1, -0.2, 1e-4], [0.1, 0.0, 0.0], [0.1, 0.1, np.nan]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        image, depths = camera.project_world(pin.SE3.Identity(), in_camera, min_depth=1e-3)
        plain, _ = camera.project_world(pin.SE3.Identity(), in_camera)
    np.testing.assert_array_equal(depths, in_camera[:, 2])
    np.testing.assert_allclose(image[0], pinhole(500.0, in_camera[0]), rtol=1e-14)
    np.testing.assert_allclose(image[1], [-500.0 * 0.1 / 1e-3, 500.0 * 0.2 / 1e-3], rtol=1e-14)
    np.testing.assert_allclose(plain[1], [-500.0 * 0.1 / 1e-4, 500.0 * 0.2 / 1e-4], rtol=1e-14)
    assert plain[2, 0] == -np.inf and np.isnan(plain[2, 1])  # -f x / 0 and -f 0 / 0
    assert np.isnan(image[3]).all() and np.isnan(plain[3]).all()


def test_depth_from_apparent_diameter():
    # Similar triangles: a 0.2 m sphere 2.5 m away spans f * 0.2 / 2.5 px.
    camera = CameraIntrinsics(focal_px=640.0)
    assert camera.apparent_diameter(2.5, 0.2) == pytest.approx(51.2)
    assert camera.depth_from_diameter(51.2, 0.2) == pytest.approx(2.5)


def test_default_intrinsics_are_the_papers_image_size():
    camera = CameraIntrinsics()
    assert (camera.width, camera.height) == (628, 582)
    assert camera.principal_point == (314.0, 291.0)
