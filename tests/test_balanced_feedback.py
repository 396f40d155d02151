"""The balanced feedback law: every direction of ``J M J^T`` at the stated gain per frame.

References are numpy's eigen-decomposition of ``J M J^T`` and the law's statement in
:mod:`pbvs_pin.control.kinematic` (rate per direction, units, joint stops, the feedback's
symmetric gain on ``nu``), never the kernels under test.
"""

from __future__ import annotations

import numpy as np
import pytest

from pbvs_pin.control.balanced import BALANCED_SHARE, DIRECTION_FLOOR, LIMIT_ZONE, joint_room
from pbvs_pin.control.gains import ServoGains
from pbvs_pin.control.kinematic import PassivityController
from pbvs_pin.exceptions import GainError

SCALE = 150.0
PERIOD = 1.0 / 30.0
MARGIN = 1.0
LIMITS = np.array([0.7, 3.5, 1.2, 0.3, 2.0, 0.8])
"""Velocity limits with a spread, one prismatic-like entry of 0.3 m/s [m/s, rad/s]."""


def _controller(k=(0.15, 0.15, 0.15), limits=LIMITS) -> PassivityController:
    gains = ServoGains(
        k=k, k1=(0.5,), k2=(1.0,), feature_scale=SCALE, feedback="balanced", upright=False,
        camera_period=PERIOD, loop_gain_margin=MARGIN,
    )  # fmt: skip
    return PassivityController(gains, limits)


def _problem(seed: int, n: int = 6):
    rng = np.random.default_rng(seed)
    jacobian = rng.standard_normal((3, n)) * rng.uniform(0.05, 3.0, n)  # columns far apart
    error_px = rng.uniform(-2.0, 2.0, 3)  # small: the command stays below the limits
    return jacobian, error_px


def _feedback(controller, jacobian, error_px, room=None):
    """The command of the feedback alone (no feed-forward, no null-space term)."""
    n = jacobian.shape[1]
    out = controller.step(
        error_px, jacobian * SCALE, np.zeros((3, 3)), np.zeros(3), np.zeros(n), room=room
    )
    assert out.valid and not out.saturated
    return out


@pytest.mark.parametrize("seed", range(4))
def test_every_direction_decays_at_the_stated_gain_per_frame(seed):
    """Along each eigenvector of ``A = J M J^T`` (numpy), ``M = diag(limits^2)``, the error's
    rate is ``rho / T lambda / (lambda + mu^2)`` times that direction's share of ``K_c e``,
    with ``rho = BALANCED_SHARE * margin`` and ``mu^2 = DIRECTION_FLOOR lambda_max``."""
    controller = _controller()
    jacobian, error_px = _problem(seed)
    out = _feedback(controller, jacobian, error_px)
    e = error_px / SCALE
    kc_e = 0.15 / (1.0 + np.abs(e)) * e
    eigenvalues, vectors = np.linalg.eigh(jacobian @ np.diag(LIMITS**2) @ jacobian.T)
    assert eigenvalues[-1] / eigenvalues[0] > 10.0  # directions far apart: the test sees them
    mu2 = DIRECTION_FLOOR * np.max(np.diag(jacobian @ np.diag(LIMITS**2) @ jacobian.T))
    rho = BALANCED_SHARE * MARGIN
    rate = vectors.T @ (jacobian @ out.u)  # d(e)/dt along each direction [units/s]
    expected = -(rho / PERIOD / 0.15) * eigenvalues / (eigenvalues + mu2) * (vectors.T @ kc_e)
    np.testing.assert_allclose(rate, expected, rtol=1e-7, atol=1e-12)
    assert out.loop_gain == pytest.approx(rho)
    assert not out.gain_limited


def test_the_transpose_law_spreads_the_directions_the_balanced_law_evens():
    """The contrast: per unit of ``K_c e`` along each eigenvector of ``J J^T`` (numpy, unit
    limits so that ``M = I``), ``J^T`` feedback decays at rates as far apart as the eigenvalues,
    the balanced law at one rate within the floor's damping."""
    jacobian = np.random.default_rng(5).standard_normal((3, 6))
    jacobian[2] *= 0.05  # one feature barely moves: its direction is slow under J^T
    ones = np.ones(6)
    eigenvalues, vectors = np.linalg.eigh(jacobian @ jacobian.T)
    assert eigenvalues[-1] / eigenvalues[0] > 100.0
    rates = {}
    for law in ("transpose", "balanced"):
        gains = ServoGains(
            k=(0.15,), k1=(0.5,), feature_scale=SCALE, feedback=law, upright=False,
            camera_period=PERIOD, loop_gain_margin=1e6 if law == "transpose" else MARGIN,
        )  # fmt: skip  (the net off for J^T)
        controller = PassivityController(gains, ones * 1e3 if law == "transpose" else ones)
        per_direction = []
        for i in range(3):  # an error along one eigenvector at a time, small enough to be linear
            error = 1e-4 * vectors[:, i] * SCALE
            out = controller.step(error, jacobian * SCALE, np.zeros((3, 3)), np.zeros(3),
                                  np.zeros(6))  # fmt: skip
            per_direction.append(-(vectors[:, i] @ (jacobian @ out.u)) / 1e-4)
        rates[law] = np.array(per_direction)
    spread = rates["transpose"].max() / rates["transpose"].min()
    assert spread == pytest.approx(eigenvalues[-1] / eigenvalues[0], rel=1e-3)
    assert rates["balanced"].max() / rates["balanced"].min() < 1.0 + 2 * DIRECTION_FLOOR * spread


@pytest.mark.parametrize("seed", range(3))
def test_a_prismatic_joint_in_millimetres_gets_the_same_motion(seed):
    """Units: a joint's velocity counted in mm/s (its column of ``J`` / 1000, its limit * 1000)
    gives the same physical motion: its command * 1000, every other command unchanged."""
    jacobian, error_px = _problem(10 + seed)
    metres = _feedback(_controller(), jacobian, error_px).u
    scaled_jacobian, scaled_limits = jacobian.copy(), LIMITS.copy()
    scaled_jacobian[:, 3] /= 1000.0
    scaled_limits[3] *= 1000.0
    millimetres = _feedback(_controller(limits=scaled_limits), scaled_jacobian, error_px).u
    expected = metres.copy()
    expected[3] *= 1000.0
    np.testing.assert_allclose(millimetres, expected, rtol=1e-9, atol=1e-15)


def test_a_joint_at_its_stop_is_not_asked_to_go_further():
    """With no room upwards, a joint the law would move up gets 0, and the others take its
    share: the error still decreases (``(K_c e)^T J u < 0``)."""
    controller = _controller()
    jacobian, error_px = _problem(3)
    free = _feedback(controller, jacobian, error_px).u
    joint = int(np.argmax(np.abs(free[2:]))) + 2
    up, down = np.ones(6), np.ones(6)
    if free[joint] > 0.0:
        up[joint] = 0.0
    else:
        down[joint] = 0.0
    blocked = _feedback(controller, jacobian, error_px, room=(up, down)).u
    assert blocked[joint] == 0.0
    assert np.max(np.abs(np.delete(blocked - free, joint))) > 1e-6  # the others moved
    e = error_px / SCALE
    kc_e = 0.15 / (1.0 + np.abs(e)) * e
    assert kc_e @ (jacobian @ blocked) < 0.0
    # the other way the joint is free: room upwards only matters when it moves up
    up[joint], down[joint] = down[joint], up[joint]
    np.testing.assert_allclose(
        _feedback(controller, jacobian, error_px, room=(up, down)).u, free, rtol=1e-12
    )


@pytest.mark.parametrize("seed", range(3))
def test_the_feedback_is_a_symmetric_positive_gain_on_nu(seed):
    """The passivity structure: ``u_fb = -H nu`` with ``H = g M J^T (A + mu^2)^-1 A^-1 J M``
    (numpy), symmetric, and ``-nu^T u_fb = nu^T H nu > 0``."""
    controller = _controller()
    jacobian, error_px = _problem(20 + seed)
    out = _feedback(controller, jacobian, error_px)
    metric = np.diag(LIMITS**2)
    a = jacobian @ metric @ jacobian.T
    mu2 = DIRECTION_FLOOR * np.max(np.diag(a))
    g = BALANCED_SHARE * MARGIN / (PERIOD * 0.15)
    h = g * metric @ jacobian.T @ np.linalg.inv(a + mu2 * np.eye(3)) @ np.linalg.inv(a)
    h = h @ jacobian @ metric
    np.testing.assert_allclose(h, h.T, rtol=1e-9, atol=1e-12 * np.max(np.abs(h)))
    np.testing.assert_allclose(out.u, -h @ out.nu, rtol=1e-7, atol=1e-14)
    assert -out.nu @ out.u > 0.0


def test_joint_room_by_hand():
    """Room is the distance to the limit over a tenth of the range, clipped to [0, 1]; base
    velocities and continuous joints (infinite limits) have room 1."""
    theta = np.array([0.0, 0.95, 0.02, 5.0])
    lower = np.array([-1.0, -1.0, 0.0, -np.inf])
    upper = np.array([1.0, 1.0, 0.13, np.inf])
    up, down = joint_room(theta, lower, upper, 2, 6)
    assert LIMIT_ZONE == 0.1
    np.testing.assert_allclose(up, [1, 1, 1, 0.05 / 0.2, 1, 1])
    np.testing.assert_allclose(down, np.ones(6))  # 0.02 above 0 is beyond the 0.013 zone
    beyond = joint_room(np.array([1.2, -1.5, 0.2, 0.0]), lower, upper, 2, 6)
    np.testing.assert_allclose(beyond[0][2:5], [0.0, 1.0, 0.0])
    np.testing.assert_allclose(beyond[1][3], 0.0)


def test_an_unknown_feedback_law_is_refused_by_name():
    with pytest.raises(GainError, match="feedback: expected one of transpose, pseudoinverse"):
        ServoGains(feedback="adaptive")
