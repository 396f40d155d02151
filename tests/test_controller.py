"""pbvs_pin.Controller: the controller stepped by a loop of one's own."""

import numpy as np
import pytest

import pbvs_pin


@pytest.fixture(scope="module")
def robot():
    return pbvs_pin.load_robot("pioneer_cyton")


@pytest.fixture
def controller(robot):
    return pbvs_pin.Controller.from_scenario(pbvs_pin.load_scenario("experiment1"), robot)


def sphere_image(robot, q, xi):
    """Image points [px] and depths [m] of two spheres whose features are ``xi`` (D = 0.05 m).

    With xi = [u1, v1, v2] and both spheres at one depth z, the separation 0.1 m fixes
    z = f * 0.1 / (v1 - v2) (independent reference: the pinhole model of eq. (2)).
    """
    f = robot.camera.focal_px
    z = f * 0.1 / (xi[1] - xi[2])
    return np.array([[xi[0], xi[1]], [xi[0], xi[2]]]), np.array([z, z])


def test_no_command_before_the_target_is_seen(controller, robot):
    command = controller.step(robot.home(), np.zeros(robot.n), None, None, 0.0)
    assert not command.seen
    np.testing.assert_array_equal(command.u, np.zeros(robot.n))
    np.testing.assert_allclose(command.v_ref, 0.0, atol=1e-12)
    assert np.all(np.isnan(command.error))


def test_zero_error_and_still_target_give_no_motion(controller, robot):
    q = robot.home()
    points, depths = sphere_image(robot, q, controller.xi_d)
    command = controller.step(q, np.zeros(robot.n), points, depths, 0.0, target_velocity=[0, 0, 0])
    assert command.seen
    np.testing.assert_allclose(command.error, 0.0, atol=1e-9)
    np.testing.assert_allclose(command.u, 0.0, atol=1e-9)


def test_error_to_the_left_turns_the_platform_left(controller, robot):
    """A target to the left (u > 0 in the paper's image coordinates) makes omega > 0."""
    q = robot.home()
    xi = controller.xi_d + np.array([80.0, 0.0, 0.0])
    points, depths = sphere_image(robot, q, xi)
    command = controller.step(q, np.zeros(robot.n), points, depths, 0.0, target_velocity=[0, 0, 0])
    np.testing.assert_allclose(command.error, [80.0, 0.0, 0.0], atol=1e-9)
    assert command.u[1] > 0.0 or command.u[2] > 0.0  # platform yaw or arm yaw to the left


def test_wrong_point_shape_is_a_shape_error(controller, robot):
    with pytest.raises(pbvs_pin.ShapeError):
        controller.step(robot.home(), np.zeros(robot.n), np.zeros((3, 2)), np.ones(3), 0.0)
