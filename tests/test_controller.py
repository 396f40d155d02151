"""pbvs_pin.Controller, the controller a robot runs, stepped as a robot's loop steps it.

Only public names are used. References are independent of the code under test: the pinhole of
eq. (2) written in conftest, the target's true motion, the identity ``J u = -J_o phat_dot`` of
eq. (34) at zero error, the delayed loop's margin ``sin(pi / (2 (2 d + 1)))``.
"""

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
from conftest import planar_pose, project_world

import pbvs_pin
from pbvs_pin import CameraFrame, Controller, ControllerSettings

FOCAL = 600.0  # [px], the scenarios' camera
SEPARATION = 0.1  # [m]
ZERO = np.zeros(3)


@pytest.fixture(scope="module")
def robot():
    return pbvs_pin.load_robot("pioneer_cyton")


def settings(**estimator) -> ControllerSettings:
    """Experiment 1's settings, the estimator's keys replaced."""
    base = ControllerSettings.from_scenario(pbvs_pin.load_scenario("experiment1"))
    return replace(base, estimator=replace(base.estimator, **estimator))


@pytest.fixture
def controller(robot):
    return Controller(robot, settings(), announce=False)


def target_ahead(robot, q, xi):
    """Sphere centres [m] that the camera at ``q`` sees at ``xi = [u1, v1, v2]`` [px]."""
    z = FOCAL * SEPARATION / (xi[1] - xi[2])
    pose = robot.camera_pose(q)
    return np.array([pose.act(np.array([-xi[0] * z / FOCAL, -v * z / FOCAL, z])) for v in xi[1:]])


def frame_of(robot, q, centres, t) -> CameraFrame:
    """The frame a perfect camera at ``q`` takes of ``centres`` at ``t`` (pinhole of eq. 2)."""
    pose = robot.camera_pose(q)
    points = np.array([project_world(FOCAL, pose, c) for c in centres])
    depths = np.array([(pose.rotation.T @ (c - pose.translation))[2] for c in centres])
    return CameraFrame.seen(t, points, depths)


def features_of(robot, q, centres):
    """``[u1, v1, v2]`` [px] of ``centres`` seen from ``q``."""
    pose = robot.camera_pose(q)
    (u1, v1), (_, v2) = (project_world(FOCAL, pose, c) for c in centres)
    return np.array([u1, v1, v2])


def turning(robot, t: float, rate: float = 0.5) -> np.ndarray:
    """Home, the platform turned by ``rate t`` [rad] about its axle midpoint."""
    return robot.integrate(robot.home(), np.r_[0.0, rate, np.zeros(robot.n_arm)], t)


# ---------------------------------------------------------------- what a step gives
def test_no_command_before_the_target_is_seen(controller, robot):
    command = controller.step(0.0, robot.home(), np.zeros(robot.n))
    assert not command.seen and not command.lost
    np.testing.assert_array_equal(command.u, np.zeros(robot.n))
    np.testing.assert_allclose(command.v_ref, 0.0, atol=1e-12)
    assert np.all(np.isnan(command.error)) and command.frame_age == np.inf


def test_zero_error_and_still_target_give_no_motion(controller, robot):
    q = robot.home()
    centres = target_ahead(robot, q, controller.xi_d)
    command = controller.step(0.0, q, np.zeros(robot.n), frame_of(robot, q, centres, 0.0))
    assert command.seen
    np.testing.assert_allclose(command.error, 0.0, atol=1e-9)
    np.testing.assert_allclose(command.u, 0.0, atol=1e-9)


def test_error_to_the_left_turns_the_platform_left(controller, robot):
    """A target to the left (u > 0 in the paper's image coordinates) makes omega > 0."""
    q = robot.home()
    centres = target_ahead(robot, q, controller.xi_d + np.array([80.0, 0.0, 0.0]))
    command = controller.step(0.0, q, np.zeros(robot.n), frame_of(robot, q, centres, 0.0))
    np.testing.assert_allclose(command.error, [80.0, 0.0, 0.0], atol=1e-9)
    assert command.u[1] > 0.0 or command.u[2] > 0.0  # platform yaw or arm yaw to the left


def test_feedforward_cancels_the_target_motion_in_the_image(controller, robot):
    """At zero error eq. (34) gives J u = -J_o phat_dot: the camera follows the target."""
    q = robot.home()
    centres = target_ahead(robot, q, controller.xi_d)
    velocity = np.array([0.05, 0.08, 0.0])  # [m/s]
    frame = frame_of(robot, q, centres, 0.0)
    command = controller.step(0.0, q, np.zeros(robot.n), frame, None, velocity)
    output, (jacobian, object_jacobian) = controller.diagnostics()
    image_rate = object_jacobian @ velocity  # [px/s], the target's motion in the image
    assert np.linalg.norm(image_rate) > 10.0 and not output.saturated
    np.testing.assert_allclose(jacobian @ command.u, -image_rate, atol=0.02 * np.linalg.norm(image_rate))


def test_compensation_changes_the_command_on_its_rows(robot):
    """Eq. (20) acts on the rows it compensates: off passes u through; all reshapes it.

    With the robot still (v = 0) and no command history, ``v_ref = M K_D u / K_e + g / K_e``
    row by row: about ``k_d T_i`` times ``u`` (4 x 0.05 on the arm), far from ``u``.
    """
    q = robot.home()
    references = {}
    for mode in ("off", "platform", "all"):
        base = settings()
        mode_settings = replace(base, compensation=replace(base.compensation, mode=mode))
        control = Controller(robot, mode_settings, announce=False)
        centres = target_ahead(robot, q, control.xi_d + np.array([60.0, 20.0, 0.0]))
        frame = frame_of(robot, q, centres, 0.0)
        references[mode] = control.step(0.0, q, np.zeros(robot.n), frame, None, ZERO)
    np.testing.assert_allclose(references["off"].v_ref, references["off"].u, atol=1e-12)
    platform = references["platform"]
    np.testing.assert_allclose(platform.v_ref[2:], platform.u[2:], atol=1e-12)
    assert np.abs(platform.v_ref[:2] - platform.u[:2]).max() > 0.01
    full = references["all"]
    assert np.all(np.abs(full.v_ref[2:] - full.u[2:]) > 0.3 * np.abs(full.u[2:]))


# ---------------------------------------------------------------- frames, latency, prediction
@pytest.mark.parametrize("predict", [True, False])
def test_a_late_frame_is_placed_at_its_capture_configuration(robot, predict):
    """The platform turns; a frame taken at 0.10 s arrives at 0.20 s.

    With prediction the error is the true error now (still target, exact odometry); without,
    it is the true error at the capture configuration, never the frame's points at ``q`` now.
    """
    control = Controller(robot, settings(predict=predict), announce=False)
    centres = target_ahead(robot, robot.home(), control.xi_d + np.array([30.0, 0.0, 0.0]))
    for step in range(21):
        t = 0.01 * step
        frame = frame_of(robot, turning(robot, 0.10), centres, 0.10) if step == 20 else None
        command = control.step(t, turning(robot, t), np.zeros(robot.n), frame, None, ZERO)
    expected_at = 0.20 if predict else 0.10
    expected = features_of(robot, turning(robot, expected_at), centres) - control.xi_d
    np.testing.assert_allclose(command.error, expected, atol=1e-6)
    assert command.predicting == predict
    assert command.frame_age == pytest.approx(0.10) and command.latency == pytest.approx(0.10)


def test_the_filter_gets_capture_times_and_capture_encoders(robot):
    """A still target seen from a turning platform, frames 0.1 s late with jitter: ~0 m/s.

    Placed with the encoders on arrival, the target would seem to orbit the platform at
    0.2 rad/s x 0.75 m = 0.15 m/s.
    """
    control = Controller(robot, settings(), announce=False)
    centres = target_ahead(robot, robot.home(), control.xi_d)
    rng = np.random.default_rng(4)
    in_flight = []
    for step in range(150):
        t = 0.01 * step
        if step % 3 == 0:
            arrival = t + 0.1 + rng.uniform(0.0, 0.03)
            in_flight.append((arrival, frame_of(robot, turning(robot, t, 0.2), centres, t)))
        due = [f for a, f in in_flight if a <= t + 1e-9]
        in_flight = [(a, f) for a, f in in_flight if a > t + 1e-9]
        command = control.step(t, turning(robot, t, 0.2), np.zeros(robot.n), due[-1] if due else None)
    assert np.linalg.norm(command.target_velocity) < 2e-3


def test_the_filter_estimates_a_moving_target(robot):
    """A target moving at 0.1 m/s, frames at 30 Hz, 0.1 s late: the estimate converges."""
    control = Controller(robot, settings(), announce=False)
    q = robot.home()
    start = target_ahead(robot, q, control.xi_d)
    velocity = np.array([0.1, 0.0, 0.0])
    pending = []
    for step in range(400):
        t = 0.01 * step
        if step % 3 == 0:
            pending.append((t + 0.1, frame_of(robot, q, start + velocity * t, t)))
        frame = pending.pop(0)[1] if pending and pending[0][0] <= t + 1e-9 else None
        command = control.step(t, q, np.zeros(robot.n), frame)
    np.testing.assert_allclose(command.target_velocity, velocity, atol=5e-3)


def test_no_new_frame_is_not_a_lost_target_and_the_hold_expires(robot):
    """None keeps servoing; a frame without the target is a loss, held 0.3 s, then braking."""
    control = Controller(robot, settings(hold=0.3), announce=False)
    q = robot.home()
    centres = target_ahead(robot, q, control.xi_d + np.array([40.0, 0.0, 0.0]))
    control.step(0.0, q, np.zeros(robot.n), frame_of(robot, q, centres, 0.0), None, ZERO)
    assert control.step(0.1, q, np.zeros(robot.n), None, None, ZERO).seen  # no new frame
    held = control.step(0.2, q, np.zeros(robot.n), CameraFrame.not_visible(0.15), None, ZERO)
    assert held.lost and held.seen and held.predicting
    assert np.abs(held.u).max() > 1e-3
    expired = control.step(0.31, q, np.zeros(robot.n), None, None, ZERO)
    assert expired.lost and not expired.seen
    np.testing.assert_array_equal(expired.u, 0.0)
    back = control.step(0.4, q, np.zeros(robot.n), frame_of(robot, q, centres, 0.35), None, ZERO)
    assert back.seen and not back.lost


def test_without_hold_a_lost_target_stops_the_command(robot):
    control = Controller(robot, settings(hold=0.0), announce=False)
    q = robot.home()
    centres = target_ahead(robot, q, control.xi_d + np.array([40.0, 0.0, 0.0]))
    control.step(0.0, q, np.zeros(robot.n), frame_of(robot, q, centres, 0.0), None, ZERO)
    lost = control.step(0.1, q, np.zeros(robot.n), CameraFrame.not_visible(0.05), None, ZERO)
    assert lost.lost and not lost.seen
    np.testing.assert_array_equal(lost.u, 0.0)


def test_the_margin_follows_the_latency_seen(robot):
    """Without prediction, frames 0.1 s late at 30 Hz: margin sin(pi / (2 (2 d + 1))), d = 3."""
    control = Controller(robot, settings(predict=False), announce=False)
    q = robot.home()
    centres = target_ahead(robot, q, control.xi_d)
    control.step(0.0, q, np.zeros(robot.n))
    control.step(0.1, q, np.zeros(robot.n), frame_of(robot, q, centres, 0.0))
    assert control.law.gains.loop_gain_margin == pytest.approx(np.sin(np.pi / 14), rel=1e-9)
    predicting = Controller(robot, settings(predict=True), announce=False)
    predicting.step(0.0, q, np.zeros(robot.n))
    predicting.step(0.1, q, np.zeros(robot.n), frame_of(robot, q, centres, 0.0))
    assert predicting.law.gains.loop_gain_margin == pytest.approx(1.0)


# ---------------------------------------------------------------- built without a scenario
def test_built_from_public_settings_and_the_robots_lags(robot):
    """Typed settings, no scenario file; the velocity loops' lags move the compensation."""
    typed = ControllerSettings(
        target=pbvs_pin.TargetSection(xi_d=(0.0, 50.0, -50.0)),
        estimator=pbvs_pin.EstimatorSection(predict=True, hold=0.5),
        compensation=pbvs_pin.CompensationSection(mode="all"),
    )
    q = robot.home()
    commands = []
    for lags in (None, (0.25, 0.25, 0.05, 0.05, 0.05)):
        control = Controller(robot, replace(typed, servo_time_constants=lags), announce=False)
        np.testing.assert_array_equal(control.xi_d, [0.0, 50.0, -50.0])
        centres = target_ahead(robot, q, control.xi_d + np.array([50.0, 0.0, 0.0]))
        control.step(0.0, q, np.full(robot.n, 0.05), frame_of(robot, q, centres, 0.0))
        commands.append(control.step(0.01, q, np.full(robot.n, 0.05)).v_ref)
    assert np.abs(commands[0] - commands[1]).max() > 1e-4
    with pytest.raises(pbvs_pin.ScenarioError, match="servo_time_constants"):
        Controller(robot, replace(typed, servo_time_constants=(0.1, 0.2)), announce=False)


def test_pixels_and_image_coordinates_are_inverse(robot):
    camera = robot.camera
    pixel = np.array([[0.5, 0.5], [camera.width / 2, camera.height / 2]])
    xi = camera.from_pixel(pixel)
    np.testing.assert_allclose(xi[1], [0.0, 0.0])
    np.testing.assert_allclose(xi[0], [camera.width / 2 - 0.5, camera.height / 2 - 0.5])
    np.testing.assert_allclose(camera.to_pixel(xi), pixel)


# ---------------------------------------------------------------- bad input at run time
def test_bad_input_raises_and_leaves_the_controller_usable(controller, robot):
    q, v = robot.home(), np.zeros(robot.n)
    centres = target_ahead(robot, q, controller.xi_d)
    controller.step(1.0, q, v, frame_of(robot, q, centres, 1.0))
    bad_q = q.copy()
    bad_q[4] = np.nan
    for call, error in (
        (lambda: controller.step(1.1, bad_q, v), pbvs_pin.NonFiniteValue),
        (lambda: controller.step(1.1, q, np.zeros(robot.n + 1)), pbvs_pin.ShapeError),
        (lambda: controller.step(0.9, q, v), pbvs_pin.ControlInputError),  # time went back
        (lambda: controller.step(1.0, q, v), pbvs_pin.ControlInputError),  # time stood still
        (lambda: controller.step(float("nan"), q, v), pbvs_pin.NonFiniteValue),
        (lambda: controller.step(1.1, q, v, frame_of(robot, q, centres, 1.5)), pbvs_pin.ControlInputError),
        (lambda: controller.step(1.1, q, v, CameraFrame.seen(1.05, np.zeros((3, 2)), np.ones(3))), pbvs_pin.ShapeError),
        (lambda: controller.step(1.1, q, v, laser=(np.nan, 0.0)), pbvs_pin.NonFiniteValue),
        (lambda: controller.step(1.1, q, v, target_velocity=[0.0, 1.0]), pbvs_pin.ShapeError),
        (lambda: controller.step(1.1, q, v, frame=(1.0, None)), pbvs_pin.ControlInputError),
    ):
        with pytest.raises(error):
            call()
    command = controller.step(1.1, q, v)
    assert command.seen and np.isfinite(command.v_ref).all()


@pytest.mark.parametrize(
    "points, depths, reason",
    [
        ([[np.nan, 0.0], [0.0, -60.0]], [1.0, 1.0], "non-finite"),
        ([[0.0, 60.0], [0.0, -60.0]], [np.inf, 1.0], "non-finite"),
        ([[0.0, 60.0], [0.0, -60.0]], [-1.0, 1.0], "not above"),
    ],
)
def test_unusable_frames_count_as_not_visible(controller, robot, points, depths, reason):
    q, v = robot.home(), np.zeros(robot.n)
    controller.step(0.0, q, v, frame_of(robot, q, target_ahead(robot, q, controller.xi_d), 0.0))
    command = controller.step(0.1, q, v, CameraFrame.seen(0.05, points, depths))
    assert reason in command.rejected and command.lost and not command.seen
    assert np.isfinite(command.v_ref).all()


def test_stale_frames_are_not_used(controller, robot):
    q, v = robot.home(), np.zeros(robot.n)
    centres = target_ahead(robot, q, controller.xi_d)
    for step in range(300):
        controller.step(0.01 * step, q, v)
    newer = controller.step(3.0, q, v, frame_of(robot, q, centres, 2.9))
    assert newer.rejected == "" and newer.seen
    older = controller.step(3.01, q, v, frame_of(robot, q, centres + np.array([0.0, 0.1, 0.0]), 2.8))
    assert "not after the newest frame" in older.rejected
    np.testing.assert_allclose(older.error, newer.error, atol=1e-9)
    ancient = controller.step(3.02, q, v, frame_of(robot, q, centres, 0.5 - 2.0))
    assert "not after the newest frame" in ancient.rejected
    fresh = Controller(robot, settings(), announce=False)
    for step in range(300):
        fresh.step(0.01 * step, q, v)
    too_old = fresh.step(3.0, q, v, frame_of(robot, q, centres, 0.5))
    assert "before the encoder history" in too_old.rejected and not too_old.seen


def test_an_odometry_jump_drops_the_measurement(controller, robot):
    q, v = robot.home(), np.zeros(robot.n)
    centres = target_ahead(robot, q, controller.xi_d + np.array([30.0, 0.0, 0.0]))
    assert controller.step(0.0, q, v, frame_of(robot, q, centres, 0.0)).seen
    jumped = q.copy()
    jumped[:2] += [1.0, 0.5]  # the odometry was reset by 1.1 m
    command = controller.step(0.01, jumped, v)
    assert command.odometry_jumped and not command.seen
    np.testing.assert_array_equal(command.u, 0.0)
    later = controller.step(0.05, jumped, v, frame_of(robot, q, centres, 0.04))
    assert later.seen and not later.odometry_jumped


def test_v_ref_stays_finite_and_within_limits_under_random_input(robot):
    """Seeded random readings, frames and garbage: every command finite and within limits."""
    control = Controller(robot, settings(hold=0.2), announce=False)
    rng = np.random.default_rng(11)
    limits = robot.velocity_limits
    q = robot.home()
    centres = target_ahead(robot, q, control.xi_d)
    t = 0.0
    for _ in range(400):
        t += rng.uniform(0.001, 0.05)
        q = robot.integrate(q, rng.uniform(-1, 1, robot.n) * limits, 0.01)
        v = rng.uniform(-2, 2, robot.n) * limits
        kind = rng.integers(5)
        frame = None
        if kind == 1:
            in_camera = np.array([robot.camera_pose(q).actInv(c) for c in centres])
            in_camera += rng.normal(0, 0.3, (1, 3))  # anywhere, behind the camera too
            points = -FOCAL * in_camera[:, :2] / in_camera[:, 2:]
            frame = CameraFrame.seen(t - rng.uniform(0, 0.2), points, in_camera[:, 2])
        elif kind == 2:
            frame = CameraFrame.seen(t, rng.normal(0, 1e4, (2, 2)), rng.uniform(-1, 1e3, 2))
        elif kind == 3:
            frame = CameraFrame.not_visible(t)
        laser = (rng.uniform(0.01, 5.0), rng.uniform(-2, 2)) if rng.random() < 0.3 else None
        try:
            command = control.step(t, q, v, frame, laser)
        except pbvs_pin.PbvsError:
            continue
        assert np.isfinite(command.v_ref).all()
        assert np.all(np.abs(command.v_ref) <= limits + 1e-12)


def test_a_built_controller_has_compiled_its_step(robot):
    """The kernels are compiled (or loaded) when the controller is built, not at its first step."""
    from pbvs_pin.control.step import fused_control_step

    Controller(robot, settings(), announce=False)
    assert fused_control_step.signatures
    pose = planar_pose(robot.home())
    assert isinstance(pose, pin.SE3)


def test_a_scenario_sizes_the_encoder_history_for_its_camera():
    """Frames up to latency + jitter + exposure delay old can still be placed."""
    scenario = pbvs_pin.load_scenario("experiment1").with_values(
        **{"camera.latency": 2.5, "camera.latency_jitter": 0.2, "camera.exposure_delay": 0.1}
    )
    settings_of = ControllerSettings.from_scenario(scenario)
    assert settings_of.history >= 2 * (2.5 + 0.2 + 0.1)
    assert ControllerSettings.from_scenario(pbvs_pin.load_scenario("experiment1")).history == 2.0
