"""Sensing as a real robot has it (issue 9): odometry, encoders, camera latency, laser noise.

References are independent of the code under test: the true pose and velocity of the plant,
the quantisation bounds (one count) and the noise standard deviations that were set.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import rot_z

from pbvs_pin.model.base import DifferentialDrive
from pbvs_pin.plant.odometry import WheelOdometry
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.obstacles import BoxObstacle, Laser
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.sensing import (
    ENCODER_STREAM,
    GYRO_STREAM,
    NOISE_BLOCK,
    Sensing,
    planar_pose,
)
from pbvs_pin.sim.setup import build

CONTROL_DT = 0.01
"""Period [s] at which the open-loop drives below read the sensors (the control rate)."""


def _wrap(angle):
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def _drive(engine: str, command, seconds: float, **values):
    """Drive a plant open loop under ``command(t)`` (shape (n,)), reading its sensors at 100 Hz.

    Returns the setup, the sensing and, per reading, the true and the measured pose and the
    true configuration and velocity.
    """
    scenario = load_scenario("experiment1").with_values(
        **{"plant.engine": engine, "duration": 2 * seconds, **values}
    )
    setup = build(scenario)
    sensing = Sensing(setup)
    plant = setup.plant
    substeps = round(CONTROL_DT / plant.dt)
    rows = {"true": [], "measured": [], "q": [], "v": [], "v_measured": []}
    for step in range(round(seconds / CONTROL_DT)):
        t = step * CONTROL_DT
        sensing.read(t)
        rows["true"].append(planar_pose(setup.robot, plant.q))
        rows["measured"].append(planar_pose(setup.robot, sensing.q))
        rows["q"].append(plant.q.copy())
        rows["v"].append(plant.v.copy())
        rows["v_measured"].append(sensing.v.copy())
        for _ in range(substeps):
            plant.step(command(t))
    return setup, sensing, {name: np.array(values) for name, values in rows.items()}


def _turning(n: int):
    """Forward 0.3 m/s and a 0.6 rad/s turn, the arm's first joint at 0.2 rad/s."""
    command = np.zeros(n)
    command[:3] = 0.3, 0.6, 0.2
    return lambda t: command


def test_odometry_follows_the_true_pose_within_quantisation_on_the_pinocchio_plant():
    """No slip: the counts measure the platform's motion; only the counts' resolution errs.

    One count of a wheel is ``r delta`` of travel: the heading errs by at most
    ``2 r delta / b`` (both wheels a count off), the position by ``2 r delta`` plus the path
    length times that heading bound.
    """
    setup, _, rows = _drive("pinocchio", _turning(5), 4.0, **{"sensing.heading": "wheels"})
    drive, counts = setup.model.base, setup.scenario.sensing.wheel_encoder_counts
    travel = drive.wheel_radius * 2 * np.pi / counts
    heading_bound = 2 * travel / drive.effective_track
    path = np.sum(np.linalg.norm(np.diff(rows["true"][:, :2], axis=0), axis=1))
    assert path > 1.0 and abs(rows["true"][-1, 2] - rows["true"][0, 2]) > 2.0  # it turned
    heading_error = np.abs(_wrap(rows["measured"][:, 2] - rows["true"][:, 2]))
    position_error = np.linalg.norm(rows["measured"][:, :2] - rows["true"][:, :2], axis=1)
    assert heading_error.max() <= heading_bound
    assert position_error.max() <= 2 * travel + path * heading_bound
    assert heading_error.max() > 0  # quantised, not the truth


def test_gyro_heading_drifts_by_its_bias_and_noise_only():
    """Gyro-corrected odometry on the Pinocchio plant: the heading's error is the integrated
    bias ``b t`` plus the noise's random walk (``sigma T sqrt(N)``, bounded at 5 sigma); a
    bias ten times larger drifts ten times further."""
    errors = {}
    for bias in (0.001, 0.01):
        setup, _, rows = _drive(
            "pinocchio", _turning(5), 4.0, **{"sensing.gyro_bias": bias, "sensing.heading": "gyro"}
        )
        noise = setup.scenario.sensing.gyro_noise
        steps = len(rows["true"]) - 1
        heading_error = _wrap(rows["measured"][-1, 2] - rows["true"][-1, 2])
        walk = 5 * noise * CONTROL_DT * np.sqrt(steps)
        assert abs(heading_error - bias * steps * CONTROL_DT) <= walk + 2e-3  # + rate sampling
        errors[bias] = heading_error
    assert errors[0.01] > 5 * errors[0.001] > 0


def test_odometry_drifts_on_the_skid_steer_mujoco_plant_when_it_turns():
    """The Pioneer 3-AT's wheels slip in a turn: the counts overstate the rotation (by far
    more than the gyro's drift), and even with the gyro's heading the position drifts."""
    drift = {}
    for heading in ("wheels", "gyro"):
        _, _, rows = _drive("mujoco", _turning(5), 3.0, **{"sensing.heading": heading})
        heading_error = abs(_wrap(rows["measured"][-1, 2] - rows["true"][-1, 2]))
        position_error = np.linalg.norm(rows["measured"][-1, :2] - rows["true"][-1, :2])
        drift[heading] = heading_error, position_error
    assert drift["wheels"][0] > 0.1 > 10 * drift["gyro"][0]
    assert drift["wheels"][1] > 0.02 and drift["gyro"][1] > 0.005


@pytest.mark.parametrize("engine", ["pinocchio", "mujoco"])
def test_both_engines_are_read_by_the_same_sensors(engine):
    """Driving straight (no slip on either engine), the measured platform velocity equals the
    true one within the wheel encoders' bound; the arm's within its encoder's bound."""
    command = np.zeros(5)
    command[0], command[2] = 0.3, 0.2
    values = {"sensing.velocity_filter": 0.0, "sensing.joint_velocity_noise": 0.0,
              "sensing.wheel_velocity_noise": 0.0}  # fmt: skip
    setup, sensing, rows = _drive(engine, lambda t: command, 2.0, **values)
    assert type(sensing.plant).__name__ == {"pinocchio": "Plant", "mujoco": "MujocoPlant"}[engine]
    steady = slice(100, None)  # after the servos' transient
    drive, spec = setup.model.base, setup.scenario.sensing
    wheel_bound = 2 * np.pi / spec.wheel_encoder_counts / CONTROL_DT  # one count per period
    forward_error = rows["v_measured"][steady, 0] - rows["v"][steady, 0]
    assert np.abs(forward_error).max() <= drive.wheel_radius * wheel_bound + 2e-3
    assert np.abs(rows["v_measured"][steady, 2] - 0.2).max() < 0.01


def test_encoder_velocity_error_is_bounded_by_one_count_per_period():
    """Without noise and filter, a velocity reading is an encoder difference over the period:
    it differs from the true mean velocity over the period by less than one count."""
    values = {"sensing.velocity_filter": 0.0, "sensing.joint_velocity_noise": 0.0,
              "sensing.wheel_velocity_noise": 0.0, "sensing.arm_encoder_bits": 12}  # fmt: skip
    setup, _, rows = _drive("pinocchio", _turning(5), 2.0, **values)
    model = setup.model
    arm = np.array([model.arm_positions(q) for q in rows["q"]])
    mean_velocity = np.diff(arm, axis=0) / CONTROL_DT
    error = rows["v_measured"][1:, 2:] - mean_velocity
    bound = 2 * np.pi / 2**12 / CONTROL_DT
    assert np.abs(error).max() <= bound * (1 + 1e-9)
    assert np.abs(error).max() > 0.3 * bound  # the quantisation is there


@pytest.mark.parametrize("tau", [0.0, 0.02])
def test_encoder_velocity_noise_has_the_standard_deviation_set(tau):
    """At rest, the velocity readings are the noise alone, low-passed: standard deviation
    ``sigma sqrt((1 - p) / (1 + p))``, ``p = exp(-T / tau)`` (``sigma`` without the filter)."""
    sigma_arm, sigma_wheel = 0.05, 0.2
    values = {"sensing.velocity_filter": tau, "sensing.joint_velocity_noise": sigma_arm,
              "sensing.wheel_velocity_noise": sigma_wheel}  # fmt: skip
    setup, _, rows = _drive("pinocchio", lambda t: np.zeros(5), 20.0, **values)
    pole = np.exp(-CONTROL_DT / tau) if tau else 0.0
    shrink = np.sqrt((1 - pole) / (1 + pole))
    readings = rows["v_measured"][50:]
    assert np.std(readings[:, 2:]) == pytest.approx(sigma_arm * shrink, rel=0.05)
    drive = setup.model.base
    # u = r (w_l + w_r) / 2 of two independent wheel readings
    u_std = drive.wheel_radius * sigma_wheel * shrink / np.sqrt(2)
    assert np.std(readings[:, 0]) == pytest.approx(u_std, rel=0.05)


def test_noise_follows_its_streams_draw_by_draw_across_blocks():
    """Drawn in blocks, the noise is still each stream's draws in order, one set per reading:
    at rest without a filter, an arm reading is ``sigma`` times the encoder stream's draw, the
    platform's ``u`` that of the two wheels' draws, and its yaw rate the gyro's bias plus
    ``sigma`` times the gyro stream's draw."""
    sigma_arm, sigma_wheel = 0.05, 0.2
    values = {"sensing.velocity_filter": 0.0, "sensing.joint_velocity_noise": sigma_arm,
              "sensing.wheel_velocity_noise": sigma_wheel}  # fmt: skip
    steps = NOISE_BLOCK + 50
    setup, _, rows = _drive("pinocchio", lambda t: np.zeros(5), steps * CONTROL_DT, **values)
    spec, n_arm = setup.scenario.sensing, setup.model.n_arm
    seed = setup.scenario.simulation.seed
    encoders = np.random.default_rng([seed, ENCODER_STREAM]).standard_normal((steps - 1, n_arm + 2))
    gyro = np.random.default_rng([seed, GYRO_STREAM]).standard_normal(steps - 1)
    readings = rows["v_measured"][1:]
    np.testing.assert_allclose(readings[:, 2:], sigma_arm * encoders[:, :n_arm], rtol=1e-12)
    radius = setup.model.base.wheel_radius
    u = 0.5 * radius * sigma_wheel * (encoders[:, n_arm] + encoders[:, n_arm + 1])
    np.testing.assert_allclose(readings[:, 0], u, rtol=1e-12)
    np.testing.assert_allclose(
        readings[:, 1], spec.gyro_bias + spec.gyro_noise * gyro, rtol=1e-9, atol=1e-12
    )


@pytest.mark.parametrize("gyro", [False, True])
def test_odometry_moves_along_the_arc_pinocchio_integrates(gyro):
    """Counts for a constant-curvature step (or a turn from a gyro) move the pose by the
    exponential of the planar twist ``[s, 0, 0, 0, 0, dtheta]`` (Pinocchio's ``exp6``)."""
    drive = DifferentialDrive(wheel_radius=0.11, track=0.4, max_wheel_speed=5.0, track_factor=1.5)
    start = np.array([0.3, -0.2, 0.7])
    odometry = WheelOdometry(drive, 4096, start, [0.5, -1.0])
    counts = odometry.read_counts([0.5 + 2.0, -1.0 + 3.0])  # 2 rad left, 3 rad right
    np.testing.assert_array_equal(counts, np.floor(np.array([2.0, 3.0]) / odometry.resolution))
    left, right = drive.wheel_radius * odometry.resolution * counts
    distance = 0.5 * (left + right)
    turn = 0.3 if gyro else (right - left) / drive.effective_track
    increments = odometry.update(counts, turn if gyro else None)
    np.testing.assert_array_equal(increments, counts)
    np.testing.assert_array_equal(odometry.counts, counts)
    moved = pin.SE3(rot_z(start[2]), np.array([*start[:2], 0.0])) * pin.exp6(
        pin.Motion(np.array([distance, 0.0, 0.0]), np.array([0.0, 0.0, turn]))
    )
    x, y, theta = odometry.pose
    np.testing.assert_allclose([x, y], moved.translation[:2], atol=1e-12)
    assert theta == pytest.approx(start[2] + turn, abs=1e-12)
    np.testing.assert_allclose(moved.rotation, rot_z(theta), atol=1e-12)


def test_camera_placement_is_the_camera_pose():
    setup = build(load_scenario("experiment1"))
    q = setup.model.integrate(setup.plant.q, np.full(setup.model.n, 0.3), 1.0)
    expected = setup.model.camera_pose(q)
    placement = setup.model.camera_placement(q)
    np.testing.assert_array_equal(placement.homogeneous, expected.homogeneous)


def _short(**values):
    return load_scenario("experiment1").with_values(duration=3.0, **values)


def test_perfect_localisation_has_no_drift_and_odometry_some():
    perfect = simulate(_short(**{"sensing.localisation": "perfect"}))
    odometry = simulate(_short())
    assert perfect.meta["odometry_drift"] == {"position": 0.0, "heading": 0.0}
    np.testing.assert_array_equal(perfect["platform_pose_measured"], perfect["platform_pose"])
    assert odometry.meta["odometry_drift"]["position"] > 0.0


def test_exact_sensing_reads_the_plant():
    log = simulate(_short(**{"sensing.exact": True}))
    np.testing.assert_array_equal(log["v_measured"], log["v"])
    np.testing.assert_array_equal(log["platform_pose_measured"], log["platform_pose"])


def test_the_same_seed_gives_the_same_log_and_another_seed_another():
    first, second = simulate(_short()), simulate(_short())
    other = simulate(_short(**{"simulation.seed": 3}))
    for name in first.channels:
        np.testing.assert_array_equal(first[name], second[name])
    assert not np.array_equal(first["v_measured"], other["v_measured"])


def test_the_pinocchio_plant_does_not_slip():
    log = simulate(_short())
    assert log.meta["slip"]["lateral_speed_rms"] < 1e-5
    assert log.meta["slip"]["yaw_rate_ratio"] == pytest.approx(1.0, abs=1e-6)


def test_camera_latency_defaults_to_one_frame():
    scenario = load_scenario("experiment1")
    assert scenario.camera.latency is None
    assert scenario.camera.delivery_latency == pytest.approx(1 / scenario.camera.rate)
    assert build(scenario).sensor.latency == pytest.approx(1 / 30)
    slower = scenario.with_values(**{"camera.rate": 20.0})
    assert build(slower).sensor.latency == pytest.approx(1 / 20)
    assert build(scenario.with_values(**{"camera.latency": 0.0})).sensor.latency == 0.0


def test_laser_noise_and_resolution_are_as_set():
    """A wall 2 m ahead: ranges are multiples of the resolution, their spread the noise's
    with the rounding's ``delta^2 / 12`` added."""
    sigma, delta = 0.02, 0.005
    laser = Laser(field_of_view=0.2, beams=11, max_range=8.0, range_noise=sigma,
                  range_resolution=delta)  # fmt: skip
    wall = [BoxObstacle(2.5, 0.0, 1.0, 10.0)]
    exact = laser.scan(wall, 0.0, 0.0, 0.0)
    rng = np.random.default_rng(1)
    scans = np.array([laser.scan(wall, 0.0, 0.0, 0.0, rng) for _ in range(2000)])
    steps = scans / delta
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
    assert np.std(scans - exact) == pytest.approx(np.sqrt(sigma**2 + delta**2 / 12), rel=0.03)
    assert abs(np.mean(scans - exact)) < 1e-3
    np.testing.assert_allclose(exact, 2.0 / np.cos(laser.angles()))
