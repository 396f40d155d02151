"""Differential-drive base adapter against the closed-form unicycle.

Parameters are deliberately not 1 (u, omega, track, radius, heading), so that a factor of
omega * track or omega / track in the wrong place cannot hide.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import URDF_DIR, urdf_wheels

from pbvs_pin import DifferentialDrive, FixedBase, GainError, Omnidirectional
from pbvs_pin.model.base import skid_steer_factor


def unicycle_arc(x0, y0, th0, u, w, t):
    """Exact pose after driving at constant forward speed u and yaw rate w for t seconds."""
    th = th0 + w * t
    if w == 0.0:
        return x0 + u * t * np.cos(th0), y0 + u * t * np.sin(th0), th0
    return (
        x0 + (u / w) * (np.sin(th) - np.sin(th0)),
        y0 - (u / w) * (np.cos(th) - np.cos(th0)),
        th,
    )


def _start(robot, rng, th0):
    q0 = robot.neutral()
    q0[:4] = [0.42, -1.3, np.cos(th0), np.sin(th0)]
    # Arm somewhere off zero, to check it stays put.
    for name in robot.arm_joint_names[:2]:
        joint = robot.model.joints[robot.model.getJointId(name)]
        if joint.nq == 1:
            lo = robot.model.lowerPositionLimit[joint.idx_q]
            hi = robot.model.upperPositionLimit[joint.idx_q]
            q0[joint.idx_q] = rng.uniform(max(lo, -1.0), min(hi, 1.0))
    return q0


def _pose_from_q(q):
    return q[0], q[1], np.arctan2(q[3], q[2])


def _angle_difference(a, b):
    return np.angle(np.exp(1j * (a - b)))


@pytest.mark.parametrize("name", ["pioneer_cyton", "tiago"])
@pytest.mark.parametrize(
    ("u", "w", "th0", "t"),
    [(0.37, -0.83, 0.6, 2.3), (-0.21, 1.7, -2.4, 1.1), (0.55, 0.0, 1.2, 1.9)],
)
def test_integrate_follows_unicycle_arc(load, name, u, w, th0, t):
    robot = load(name)
    rng = np.random.default_rng(31)
    q0 = _start(robot, rng, th0)
    v = np.zeros(robot.n)
    v[:2] = u, w
    expected = unicycle_arc(0.42, -1.3, th0, u, w, t)

    one_step = robot.integrate(q0, v, t)
    many = q0.copy()
    for _ in range(500):
        many = robot.integrate(many, v, t / 500)

    for q in (one_step, many):
        x, y, th = _pose_from_q(q)
        np.testing.assert_allclose([x, y], expected[:2], atol=1e-9)
        assert abs(_angle_difference(th, expected[2])) < 1e-9
        assert np.hypot(q[2], q[3]) == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(q[4:], q0[4:], atol=0)  # the arm does not move
        pose = robot.base_pose(q)
        np.testing.assert_allclose(pose.translation, [*expected[:2], 0.0], atol=1e-9)
        np.testing.assert_allclose(
            pose.rotation[:2, 0], [np.cos(expected[2]), np.sin(expected[2])], atol=1e-9
        )


def test_selection_matrix_layout(load):
    for name in ("pioneer_cyton", "pioneer_panda"):
        robot = load(name)
        n_arm = robot.n - 2
        expected = np.zeros((3 + n_arm, 2 + n_arm))
        expected[:3, :2] = [[1, 0], [0, 0], [0, 1]]
        expected[3:, 2:] = np.eye(n_arm)
        np.testing.assert_array_equal(robot.selection, expected)
        assert robot.velocity_names[:2] == ("u", "omega")


@pytest.mark.parametrize(("u", "w"), [(0.4, 0.0), (0.0, 1.3), (-0.25, -0.7), (0.6, 2.2)])
def test_wheel_speeds_from_contact_point_velocity(u, w):
    radius, track = 0.085, 0.47
    drive = DifferentialDrive(wheel_radius=radius, track=track, max_wheel_speed=8.0)
    # Contact points at y = +track/2 (left) and -track/2 (right); rigid planar motion gives
    # their forward speed u + (w e_z x r)_x = u - w y.
    left_contact = u - w * (+track / 2)
    right_contact = u - w * (-track / 2)
    left, right = drive.wheel_speeds(u, w)
    assert left == pytest.approx(left_contact / radius, rel=1e-14, abs=1e-14)
    assert right == pytest.approx(right_contact / radius, rel=1e-14, abs=1e-14)


def test_velocity_limits_saturate_the_wheels():
    radius, track, w_max = 0.085, 0.47, 8.0
    drive = DifferentialDrive(wheel_radius=radius, track=track, max_wheel_speed=w_max)
    u_max, omega_max = drive.velocity_limits()
    assert u_max == pytest.approx(radius * w_max)  # both wheels at +w_max
    assert omega_max == pytest.approx(2 * radius * w_max / track)  # wheels at -w_max, +w_max
    np.testing.assert_allclose(drive.wheel_speeds(u_max, 0.0), [w_max, w_max])
    np.testing.assert_allclose(drive.wheel_speeds(0.0, omega_max), [-w_max, w_max])


@pytest.mark.parametrize("name", ["pioneer_cyton", "pioneer_ur5"])
def test_pioneer_drive_read_from_urdf(load, name):
    """Wheel radius, track and speed limits against the platform URDF parsed by hand."""
    robot = load(name)
    path = URDF_DIR / ("pioneer_cyton.urdf" if name == "pioneer_cyton" else "pioneer3at.urdf")
    wheels = urdf_wheels(path)
    ys = np.array([centre[1] for centre, _, _ in wheels])
    track = ys[ys > 0].mean() - ys[ys < 0].mean()
    radius = np.mean([r for _, r, _ in wheels])
    w_max = min(speed for _, _, speed in wheels)
    assert (track, radius, w_max) == pytest.approx((0.394, 0.1075, 6.5))
    assert isinstance(robot.base, DifferentialDrive)
    assert robot.base.track == pytest.approx(track)
    assert robot.base.wheel_radius == pytest.approx(radius)
    # four wheels at x = +-0.134 m: skid-steer, chi = (a^2 + b^2) / b^2
    xs = np.array([centre[0] for centre, _, _ in wheels])
    half_wheelbase, half_track = np.abs(xs - xs.mean()).mean(), track / 2
    assert half_wheelbase == pytest.approx(0.134)
    chi = (half_wheelbase**2 + half_track**2) / half_track**2
    assert robot.base.track_factor == pytest.approx(chi, rel=1e-12)
    np.testing.assert_allclose(
        robot.velocity_limits[:2], [radius * w_max, 2 * radius * w_max / (chi * track)], rtol=1e-12
    )


def _coulomb_spin_ratio(wheels: np.ndarray) -> float:
    """Yaw rate over ``r (w_r - w_l) / track`` of a spin in place, rigid Coulomb friction.

    Wheels at ``wheels`` (x, y) spin at ``+-omega_c * b``; the platform's yaw rate is the root
    of the net yaw moment of the friction forces ``-N s_i / |s_i|`` (equal loads), found by
    bisection.
    """
    half_track = np.abs(wheels[:, 1]).mean()

    def moment(omega: float) -> float:
        rolling = np.sign(wheels[:, 1]) * half_track  # wheel surface speed, omega_c = 1
        slip = np.column_stack([-omega * wheels[:, 1] + rolling, omega * wheels[:, 0]])
        force = -slip / np.maximum(np.linalg.norm(slip, axis=1, keepdims=True), 1e-300)
        return float(np.sum(wheels[:, 0] * force[:, 1] - wheels[:, 1] * force[:, 0]))

    low, high = 0.0, 1.0
    for _ in range(60):
        middle = 0.5 * (low + high)
        low, high = (low, middle) if moment(middle) < 0 else (middle, high)
    return 0.5 * (low + high)


@pytest.mark.parametrize(
    ("wheels", "chi"),
    [
        ([[0.0, 0.2], [0.0, -0.2]], 1.0),
        ([[0.134, 0.197], [0.134, -0.197], [-0.134, 0.197], [-0.134, -0.197]], None),
        ([[0.3, 0.25], [0.3, -0.25], [-0.3, 0.25], [-0.3, -0.25]], None),
    ],
    ids=["two-wheel", "pioneer-3at", "long"],
)
def test_skid_steer_factor_is_the_coulomb_spin_balance(wheels, chi):
    """chi from the formula against the root of the moment balance, found numerically."""
    wheels = np.asarray(wheels)
    factor = skid_steer_factor(wheels)
    assert factor == pytest.approx(1.0 / _coulomb_spin_ratio(wheels), rel=1e-9)
    if chi is not None:
        assert factor == chi


def test_effective_track_sets_wheel_speeds_and_yaw_limit():
    drive = DifferentialDrive(wheel_radius=0.1, track=0.4, max_wheel_speed=5.0, track_factor=1.5)
    assert drive.effective_track == pytest.approx(0.6)
    left, right = drive.wheel_speeds(0.0, 1.0)
    assert (left, right) == pytest.approx((-0.3 / 0.1, 0.3 / 0.1))
    assert drive.velocity_limits()[1] == pytest.approx(2 * 0.1 * 5.0 / 0.6)


@pytest.mark.parametrize("value", [0.9, float("nan")])
def test_track_factor_below_one_is_refused(value):
    with pytest.raises(GainError, match="track_factor"):
        DifferentialDrive(wheel_radius=0.1, track=0.4, max_wheel_speed=5.0, track_factor=value)


@pytest.mark.parametrize("field", ["wheel_radius", "track", "max_wheel_speed"])
@pytest.mark.parametrize("value", [0.0, -0.3, float("nan")])
def test_differential_drive_rejects_bad_dimensions(field, value):
    values = {"wheel_radius": 0.1, "track": 0.4, "max_wheel_speed": 5.0, field: value}
    with pytest.raises(GainError, match=field):
        DifferentialDrive(**values)


def test_other_adapters_selection():
    np.testing.assert_array_equal(Omnidirectional().selection(), np.eye(3))
    assert Omnidirectional(max_speed=0.3, max_yaw_rate=0.9).velocity_limits().tolist() == [
        0.3,
        0.3,
        0.9,
    ]
    assert FixedBase().selection().shape == (0, 0)
    assert FixedBase().root_joint() is None
    assert FixedBase().velocity_names == ()
