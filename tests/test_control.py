"""The controllers: eq. (10)/(34), the secondary objectives (16)-(19), eq. (20).

References are written in the tests from the paper (numpy's own inverse for the weighted
pseudo-inverse, quadrature for eq. (7), the closed-form first-order impedance response), and
the dynamic compensator is checked in closed loop with the plant against eqs. (21)-(22).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import quad
from simhelpers import random_spd, storage_reference, weighted_pinv

from pbvs_pin.control.compensation import Compensation, DynamicCompensator
from pbvs_pin.control.gains import ServoGains
from pbvs_pin.control.ibvs import ClassicIbvs
from pbvs_pin.control.kinematic import PassivityController, saturate, storage_function
from pbvs_pin.control.secondary import (
    ArmPosture,
    JointLimitAvoidance,
    ObstacleAvoidance,
    SecondaryInput,
    secondary_vector,
)
from pbvs_pin.exceptions import GainError, ShapeError
from pbvs_pin.model.servo import ServoModel
from pbvs_pin.plant.pinocchio_plant import Plant

SCALE = 150.0
"""Pixels per controller unit used throughout (the package default)."""

NO_LIMITS = np.full(5, 1e9)
"""Velocity limits that never bind, to see the raw law."""

REFERENCE_LIMITS = np.array([0.7, 3.5, 1.2, 1.2, 1.2])
"""Pioneer + Cyton-like limits [m/s, rad/s]."""


def _gains(n: int, rng: np.random.Generator, weights=(1.0,), **extra) -> ServoGains:
    """Random gains of the paper's law (``feedback`` given in ``extra`` replaces it)."""
    extra = {"feedback": "transpose", **extra}
    return ServoGains(
        k=tuple(rng.uniform(0.1, 0.5, 3)),
        k1=tuple(rng.uniform(0.1, 1.0, n)),
        k2=tuple(rng.uniform(0.1, 2.0, n)),
        feature_scale=SCALE,
        weights=weights,
        **extra,
    )


def _weights(kind: str, n: int, rng: np.random.Generator) -> tuple[tuple, np.ndarray]:
    """``W`` as the controller takes it, and as a matrix for the reference."""
    if kind == "diagonal":
        diagonal = rng.uniform(0.5, 4.0, n)
        return tuple(diagonal), np.diag(diagonal)
    full = random_spd(rng, n)
    return tuple(tuple(row) for row in full), full


def _random_problem(rng: np.random.Generator, n: int):
    """A full-row-rank J (controller units, entries ~1), J_o, a target velocity and Lambda."""
    jacobian = rng.standard_normal((3, n))
    assert np.linalg.svd(jacobian, compute_uv=False)[-1] > 0.2  # well away from singular
    return (
        jacobian,
        rng.standard_normal((3, 3)),
        rng.uniform(-0.3, 0.3, 3),
        rng.uniform(-2.0, 2.0, n),
    )


# ---------------------------------------------------------------- eq. (10): null space
@pytest.mark.parametrize("weight_kind", ["diagonal", "full"])
@pytest.mark.parametrize("n", [5, 7])
@pytest.mark.parametrize("seed", range(4))
def test_null_space_motion_leaves_features_still(weight_kind, n, seed):
    """Zero error and zero target velocity: u = (I - J#J) k1 tanh(k2 Lambda), and J u = 0."""
    rng = np.random.default_rng(seed)
    weights, w_matrix = _weights(weight_kind, n, rng)
    gains = _gains(n, rng, weights)
    controller = PassivityController(gains, np.full(n, 1e9))
    jacobian, object_jacobian, _, secondary = _random_problem(rng, n)

    out = controller.step(
        np.zeros(3), jacobian * SCALE, object_jacobian * SCALE, np.zeros(3), secondary
    )

    assert out.valid and not out.damped and not out.saturated
    pinv = weighted_pinv(jacobian, w_matrix)
    expected = (np.eye(n) - pinv @ jacobian) @ (
        np.asarray(gains.k1) * np.tanh(np.asarray(gains.k2) * secondary)
    )
    assert np.linalg.norm(expected) > 0.05  # the test sees a real self-motion
    np.testing.assert_allclose(out.null_space, expected, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(out.u, expected, rtol=1e-9, atol=1e-12)
    feature_rate = (jacobian * SCALE) @ out.u  # px/s, computed here
    assert np.linalg.norm(feature_rate) < 1e-9 * SCALE * np.linalg.norm(out.u)


@pytest.mark.parametrize("weight_kind", ["diagonal", "full"])
@pytest.mark.parametrize("feedback", ["transpose", "pseudoinverse"])
@pytest.mark.parametrize("seed", range(3))
def test_command_matches_eq34_written_out(weight_kind, feedback, seed):
    """u = -J^T Kc(e) e - J# J_o phat_dot + (I - J#J) k1 tanh(k2 Lambda), controller units."""
    n = 5
    rng = np.random.default_rng(100 + seed)
    weights, w_matrix = _weights(weight_kind, n, rng)
    gains = _gains(n, rng, weights, feedback=feedback)
    controller = PassivityController(gains, NO_LIMITS)
    jacobian, object_jacobian, target_velocity, secondary = _random_problem(rng, n)
    error_px = rng.uniform(-200.0, 200.0, 3)

    out = controller.step(
        error_px, jacobian * SCALE, object_jacobian * SCALE, target_velocity, secondary
    )

    e = error_px / SCALE
    k = np.asarray(gains.k)
    kc_e = k / (1.0 + np.abs(e)) * e  # K_c(e) e, eq. (8)
    pinv = weighted_pinv(jacobian, w_matrix)
    nu = jacobian.T @ kc_e
    feedback_term = pinv @ kc_e if feedback == "pseudoinverse" else nu
    null = (np.eye(n) - pinv @ jacobian) @ (
        np.asarray(gains.k1) * np.tanh(np.asarray(gains.k2) * secondary)
    )
    expected = -feedback_term - pinv @ object_jacobian @ target_velocity + null
    np.testing.assert_allclose(out.nu, nu, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(out.feedforward, pinv @ object_jacobian @ target_velocity,
                               rtol=1e-9, atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(out.u, expected, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(out.error, error_px)
    # Eq. (12): the self-motion does no work on the passivity output nu.
    assert abs(out.nu @ out.null_space) < 1e-10 * np.linalg.norm(nu) * np.linalg.norm(null)
    # With v = u and the exact target velocity, J u + J_o pdot = -J J^T Kc e: V1 decreases.
    if feedback == "transpose":
        v1_rate = kc_e @ (jacobian @ out.u + object_jacobian @ target_velocity)
        np.testing.assert_allclose(v1_rate, -nu @ nu, rtol=1e-9)
        assert v1_rate < 0


def test_storage_function_is_eq7_integral():
    """V1 = int_0^e eta^T Kc(eta) d eta (quadrature), and the controller reports it."""
    rng = np.random.default_rng(7)
    k = np.array([0.15, 0.3, 0.05])
    for _ in range(5):
        e = rng.uniform(-3.0, 3.0, 3)
        by_quadrature = sum(
            quad(lambda eta, ki=ki: ki * eta / (1.0 + abs(eta)), 0.0, ei)[0]
            for ki, ei in zip(k, e, strict=True)
        )
        assert storage_function(e, k) == pytest.approx(by_quadrature, rel=1e-10)
        assert storage_reference(e, k)[0] == pytest.approx(by_quadrature, rel=1e-10)
    assert storage_function(np.zeros(3), k) == 0.0
    gains = ServoGains(k=tuple(k))
    controller = PassivityController(gains, NO_LIMITS)
    rng_problem = np.random.default_rng(8)
    jacobian, object_jacobian, velocity, secondary = _random_problem(rng_problem, 5)
    error_px = np.array([-150.0, 40.0, 90.0])
    out = controller.step(error_px, jacobian * 150.0, object_jacobian * 150.0, velocity, secondary)
    assert out.storage == pytest.approx(storage_reference(error_px / 150.0, k)[0], rel=1e-12)


# ---------------------------------------------------------------- safety
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize(
    "which", ["error", "jacobian", "object_jacobian", "target_velocity", "secondary"]
)
def test_non_finite_input_gives_zero_command(which, bad):
    rng = np.random.default_rng(3)
    controller = PassivityController(ServoGains(), REFERENCE_LIMITS)
    jacobian, object_jacobian, velocity, secondary = _random_problem(rng, 5)
    inputs = {
        "error": rng.uniform(-50, 50, 3),
        "jacobian": jacobian * SCALE,
        "object_jacobian": object_jacobian * SCALE,
        "target_velocity": velocity,
        "secondary": secondary,
    }
    assert controller.step(*inputs.values()).valid  # the clean inputs are fine
    inputs[which] = np.array(inputs[which], dtype=float)
    inputs[which].flat[1] = bad

    out = controller.step(*inputs.values())

    assert not out.valid
    np.testing.assert_array_equal(out.u, np.zeros(5))
    assert np.all(np.isfinite(out.u))
    assert not out.saturated


@pytest.mark.parametrize("law", ["passivity", "ibvs"])
def test_non_finite_input_gives_zero_command_for_both_laws(law):
    controller = (
        ClassicIbvs(0.5, REFERENCE_LIMITS)
        if law == "ibvs"
        else PassivityController(ServoGains(), REFERENCE_LIMITS)
    )
    out = controller.step(
        np.array([np.nan, 0.0, 0.0]), np.ones((3, 5)), np.ones((3, 3)), np.zeros(3), np.zeros(5)
    )
    assert not out.valid
    np.testing.assert_array_equal(out.u, np.zeros(5))


@pytest.mark.parametrize("seed", range(6))
def test_saturation_scales_uniformly_and_keeps_direction(seed):
    rng = np.random.default_rng(200 + seed)
    gains = _gains(5, rng)
    jacobian, object_jacobian, _, secondary = _random_problem(rng, 5)
    # A fast target (6 m/s) and a large error: the raw command exceeds the limits.
    direction = rng.standard_normal(3)
    args = (rng.uniform(-300, 300, 3), jacobian * SCALE, object_jacobian * SCALE,
            6.0 * direction / np.linalg.norm(direction), secondary)  # fmt: skip
    raw = PassivityController(gains, NO_LIMITS).step(*args).u
    assert np.any(np.abs(raw) > REFERENCE_LIMITS)  # test setup: saturation is needed

    out = PassivityController(gains, REFERENCE_LIMITS).step(*args)

    expected_scale = 1.0 / np.max(np.abs(raw) / REFERENCE_LIMITS)
    assert out.saturated and out.valid
    assert out.scale == pytest.approx(expected_scale, rel=1e-12)
    assert np.all(np.abs(out.u) <= REFERENCE_LIMITS * (1 + 1e-12))
    assert np.max(np.abs(out.u) / REFERENCE_LIMITS) == pytest.approx(1.0, rel=1e-12)
    ratio = out.u[raw != 0] / raw[raw != 0]
    np.testing.assert_allclose(ratio, expected_scale, rtol=1e-10)  # one factor for all


def test_saturate_leaves_small_commands_alone():
    u = np.array([0.1, -0.2, 0.3])
    limits = np.array([0.5, 0.5, 0.5])
    out, factor = saturate(u, limits)
    np.testing.assert_array_equal(out, u)
    assert factor == 1.0
    out, factor = saturate(np.array([1.0, -0.25, 0.0]), limits)
    np.testing.assert_allclose(out, [0.5, -0.125, 0.0])
    assert factor == 0.5


@pytest.mark.parametrize("gap", [1e-1, 1e-3, 1e-6, 1e-10, 0.0])
def test_near_singular_jacobian_is_damped_and_bounded(gap):
    """Two feature rows nearly parallel: J# stays below 1 / sigma_0 and u stays finite.

    With ``max_damping == damping_threshold == sigma_0`` the damped pseudo-inverse's
    singular values are ``s / (s^2 + mu^2)`` with ``mu^2 = sigma_0^2 (1 - s_min^2/sigma_0^2)``,
    which is at most ``1 / sigma_0`` for every ``s`` (derived in this docstring's terms:
    ``s^2 + mu^2 >= sigma_0^2`` when ``s >= s_min``).
    """
    rng = np.random.default_rng(11)
    sigma_0 = 0.05
    gains = ServoGains(damping_threshold=sigma_0, max_damping=sigma_0)
    a, b, c = rng.standard_normal((3, 5))
    jacobian = np.array([a, b, a + gap * c])  # controller units
    controller = PassivityController(gains, NO_LIMITS)
    pinv, sigma_min, damped = controller.pseudo_inverse(jacobian)
    reference_sigma = np.linalg.svd(jacobian, compute_uv=False)[-1]
    assert sigma_min == pytest.approx(reference_sigma, abs=1e-6)
    assert damped == (reference_sigma < sigma_0)
    assert np.all(np.isfinite(pinv))
    assert np.linalg.norm(pinv, 2) <= (1.0 / sigma_0) * (1 + 1e-9)

    args = (np.array([-150.0, 60.0, -40.0]), jacobian * SCALE, rng.standard_normal((3, 3))
            * SCALE, np.array([0.1, 0.05, 0.0]), rng.uniform(-1, 1, 5))  # fmt: skip
    out = PassivityController(gains, REFERENCE_LIMITS).step(*args)
    assert out.valid
    assert out.damped == (reference_sigma < sigma_0)
    assert np.all(np.isfinite(out.u))
    assert np.all(np.abs(out.u) <= REFERENCE_LIMITS * (1 + 1e-12))
    unlimited = PassivityController(gains, NO_LIMITS).step(*args)
    # |u| <= |nu| + |J#| |J_o pdot| + |k1| (projector norm <= |J#||J| + 1)
    bound = (
        np.linalg.norm(unlimited.nu)
        + np.linalg.norm(args[2] / SCALE @ args[3]) / sigma_0
        + (1 + np.linalg.norm(jacobian, 2) / sigma_0) * np.linalg.norm(gains.k1)
    )
    assert np.linalg.norm(unlimited.u) <= bound


@pytest.mark.parametrize("rows", [1, 2, 3, 4, 6])
def test_smallest_singular_value_matches_svd_for_every_feature_count(rows):
    """sigma_min of J W^-1/2 (closed form up to r = 3, LAPACK above) against NumPy's SVD.

    Random weights W, scales over five decades, and exactly or nearly rank-deficient J.
    """
    rng = np.random.default_rng(100 + rows)
    n = 7
    for trial in range(200):
        jacobian = rng.standard_normal((rows, n)) * 10.0 ** rng.uniform(-2, 3)
        if rows > 1 and trial % 3 == 0:
            jacobian[-1] = jacobian[0] * (1.0 + [0.0, 1e-9, 1e-4][trial % 9 // 3])
        weights, weight = _weights("full", n, rng)
        gains = _gains(n, rng, weights, damping_threshold=1e-12)
        controller = PassivityController(gains, np.full(n, 1e9))
        pinv, sigma_min, _ = controller.pseudo_inverse(jacobian)
        assert np.all(np.isfinite(pinv)), trial  # even when J is singular to round-off
        root = np.linalg.cholesky(np.linalg.inv(weight))  # W^-1 = L L^T
        singular = np.linalg.svd(jacobian @ root, compute_uv=False)
        # lambda_min(J W^-1 J^T) is exact to ~1e-15 |J W^-1 J^T|; its square root then has
        # an absolute error of at most sqrt(1e-14 |.|) near zero
        tolerance = 1e-9 * singular[0] + np.sqrt(1e-14) * singular[0]
        assert sigma_min == pytest.approx(singular[-1], abs=tolerance), trial


def test_well_conditioned_jacobian_is_not_damped():
    controller = PassivityController(ServoGains(), NO_LIMITS)
    jacobian = np.hstack([np.eye(3), np.zeros((3, 2))])
    pinv, sigma_min, damped = controller.pseudo_inverse(jacobian)
    assert not damped and sigma_min == pytest.approx(1.0)
    np.testing.assert_allclose(pinv, jacobian.T, atol=1e-14)


@pytest.mark.parametrize("feedback", ["transpose", "pseudoinverse"])
@pytest.mark.parametrize("period", [0.002, 5.0])
def test_loop_gain_is_k_T_lambda_max_and_the_net_scales_k(feedback, period):
    """``g = k_max T lambda_max(J J^T)`` (``J J# = I``: 1 with ``J#`` feedback), by numpy; above
    the margin 1 the law is eq. (34) with ``k`` times ``1 / g``; ``T = 0`` turns the net off."""
    n = 5
    rng = np.random.default_rng(9)
    gains = _gains(n, rng, feedback=feedback, camera_period=period)
    controller = PassivityController(gains, NO_LIMITS)
    jacobian, object_jacobian, target_velocity, secondary = _random_problem(rng, n)
    error_px = rng.uniform(-200.0, 200.0, 3)
    arguments = (error_px, jacobian * SCALE, object_jacobian * SCALE, target_velocity, secondary)
    out = controller.step(*arguments)
    largest = 1.0 if feedback == "pseudoinverse" else np.linalg.eigvalsh(jacobian @ jacobian.T)[-1]
    gain = max(gains.k) * period * largest
    assert out.loop_gain == pytest.approx(gain, rel=1e-10)
    assert out.gain_limited == (gain > 1.0) == (period > 1.0)
    scaled = PassivityController(
        replace(gains, k=tuple(np.asarray(gains.k) * min(1.0, 1.0 / gain))), NO_LIMITS
    )
    scaled.safety = scaled.safety._replace(camera_period=0.0)  # the net off
    reference = scaled.step(*arguments)
    assert np.isnan(reference.loop_gain) and not reference.gain_limited
    np.testing.assert_allclose(out.u, reference.u, rtol=1e-12, atol=1e-15)
    assert out.storage == pytest.approx(reference.storage, rel=1e-12)


@pytest.mark.parametrize("gap", [0.3, 1e-3])
def test_damped_pseudo_inverse_is_the_nakamura_hanafusa_formula(gap):
    """``J# = W^-1 J^T (J W^-1 J^T + mu^2 I)^-1``, ``mu^2 = mu_max^2 (1 - (s_min / s_0)^2)``,
    with ``s_min`` from numpy's SVD of ``J W^-1/2`` and numpy's inverse."""
    rng = np.random.default_rng(12)
    n = 5
    weights, weight = _weights("full", n, rng)
    gains = _gains(n, rng, weights, damping_threshold=0.5, max_damping=0.3)
    a, b, c = rng.standard_normal((3, n))
    jacobian = np.array([a, b, a + gap * c])
    pinv, _, damped = PassivityController(gains, NO_LIMITS).pseudo_inverse(jacobian)
    inverse = np.linalg.inv(weight)
    smallest = np.linalg.svd(jacobian @ np.linalg.cholesky(inverse), compute_uv=False)[-1]
    assert damped == (smallest < 0.5)
    mu2 = 0.3**2 * (1.0 - (smallest / 0.5) ** 2) if smallest < 0.5 else 0.0
    gram = jacobian @ inverse @ jacobian.T + mu2 * np.eye(3)
    reference = inverse @ jacobian.T @ np.linalg.inv(gram)
    np.testing.assert_allclose(pinv, reference, rtol=1e-8)
    # the law damps with the same sigma_0 and mu_max: its feed-forward is J# J_o phat_dot
    object_jacobian, target_velocity = rng.standard_normal((3, 3)), rng.uniform(-0.3, 0.3, 3)
    out = PassivityController(gains, NO_LIMITS).step(
        np.zeros(3), jacobian * SCALE, object_jacobian * SCALE, target_velocity, np.zeros(n)
    )
    assert out.damped == damped and out.min_singular_value == pytest.approx(smallest, rel=1e-6)
    np.testing.assert_allclose(
        out.feedforward, reference @ object_jacobian @ target_velocity, rtol=1e-8, atol=1e-12
    )


def test_damping_starts_strictly_below_the_threshold():
    """``s_min = s_0`` exactly (``J = [I 0]``): not damped, ``J#`` is ``J^T``."""
    gains = ServoGains(damping_threshold=1.0, max_damping=0.5)
    pinv, sigma_min, damped = PassivityController(gains, NO_LIMITS).pseudo_inverse(
        np.hstack([np.eye(3), np.zeros((3, 2))])
    )
    assert sigma_min == 1.0 and not damped
    np.testing.assert_array_equal(pinv, np.hstack([np.eye(3), np.zeros((3, 2))]).T)


def test_a_jacobian_singular_to_round_off_gets_the_smallest_regularisation():
    """Two equal rows and ``mu_max^2`` below the round-off floor: ``mu^2`` is raised to the
    floor, ``1e-12 tr(J W^-1 J^T)``, no more; ``J J#`` is then the projector onto the range of
    ``J`` (numpy's SVD) but for the round-off of the singular direction (~1e-5)."""
    rng = np.random.default_rng(13)
    a, b = rng.standard_normal((2, 5))
    jacobian = np.array([a, b, a])
    gains = ServoGains(damping_threshold=0.05, max_damping=1e-9)
    pinv, _, damped = PassivityController(gains, NO_LIMITS).pseudo_inverse(jacobian)
    assert damped and np.all(np.isfinite(pinv))
    basis = np.linalg.svd(jacobian)[0][:, :2]
    np.testing.assert_allclose(jacobian @ pinv, basis @ basis.T, atol=1e-3)


def test_upright_row_of_the_wrong_length_is_refused():
    """``[phi, j_phi]`` has ``n + 1`` entries; with a ``j_phi`` the null space changes."""
    rng = np.random.default_rng(14)
    controller = PassivityController(_gains(5, rng), NO_LIMITS)
    jacobian, object_jacobian, target_velocity, secondary = _random_problem(rng, 5)
    arguments = (np.zeros(3), jacobian * SCALE, object_jacobian * SCALE, target_velocity, secondary)
    for length in (5, 7):
        with pytest.raises(ShapeError, match="upright"):
            controller.step(*arguments, upright=np.zeros(length))
    plain = controller.step(*arguments, upright=np.zeros(6))
    np.testing.assert_array_equal(plain.u, controller.step(*arguments).u)
    rolled = controller.step(*arguments, upright=np.array([0.3, 1.0, 0.0, 0.0, 0.0, 0.0]))
    assert not np.allclose(rolled.null_space, plain.null_space)


def test_classic_ibvs_law():
    """u = -lambda J# e - J# J_o phat_dot + (I - J# J) k1 tanh(k2 Lambda) (Moore-Penrose)."""
    rng = np.random.default_rng(12)
    jacobian, object_jacobian, velocity, secondary = _random_problem(rng, 5)
    jacobian_px, object_px = jacobian * SCALE, object_jacobian * SCALE
    error_px = np.array([30.0, -20.0, 10.0])
    gains = ServoGains()
    out = ClassicIbvs(0.5, NO_LIMITS, gains).step(
        error_px, jacobian_px, object_px, velocity, secondary
    )
    pinv = np.linalg.pinv(jacobian_px)
    shaped = np.array(gains.k1) * np.tanh(np.array(gains.k2) * secondary)
    null_space = (np.eye(5) - pinv @ jacobian_px) @ shaped
    np.testing.assert_allclose(out.null_space, null_space, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(
        out.u, -0.5 * pinv @ error_px - pinv @ object_px @ velocity + null_space,
        rtol=1e-8, atol=1e-12,
    )  # fmt: skip
    assert np.linalg.norm(null_space) > 1e-3  # the objectives do act
    np.testing.assert_allclose(jacobian_px @ out.null_space, 0.0, atol=1e-9)


def test_classic_ibvs_differs_from_the_pseudoinverse_feedback_only_by_its_constant_gain():
    """With the upright row acting, the IBVS baseline and the passivity law's pseudo-inverse
    feedback at ``k_i = lambda`` share the null space (kept upright) and the feed-forward; their
    commands differ by ``J# (lambda e - K_c e)`` alone, ``K_c e = lambda e / (1 + |e|)``."""
    rng = np.random.default_rng(21)
    jacobian, object_jacobian, velocity, secondary = _random_problem(rng, 5)
    gains = replace(_gains(5, rng, feedback="pseudoinverse"), k=(0.5,))
    error = np.array([0.4, -0.2, 0.1])  # controller units
    upright = np.array([0.3, 1.0, -0.5, 0.2, 0.0, 0.4])
    arguments = (error * SCALE, jacobian * SCALE, object_jacobian * SCALE, velocity, secondary)
    ibvs = ClassicIbvs(0.5, NO_LIMITS, gains).step(*arguments, upright=upright)
    shaped = PassivityController(gains, NO_LIMITS).step(*arguments, upright=upright)
    assert ibvs.upright_weight > 0.0 and not ibvs.gain_limited and not shaped.gain_limited
    np.testing.assert_allclose(ibvs.null_space, shaped.null_space, atol=1e-12)
    np.testing.assert_allclose(ibvs.feedforward, shaped.feedforward, atol=1e-12)
    pinv = PassivityController(gains, NO_LIMITS).pseudo_inverse(jacobian)[0]
    difference = pinv @ (0.5 * error - 0.5 * error / (1.0 + np.abs(error)))
    np.testing.assert_allclose(ibvs.u - shaped.u, -difference, rtol=1e-9, atol=1e-12)
    assert np.linalg.norm(difference) > 1e-3


# ---------------------------------------------------------------- gains and shapes
@pytest.mark.parametrize(
    "field, value",
    [
        ("k", (-0.15,)),
        ("k", (0.0,)),
        ("k1", (0.7, 1.0, float("nan"), 0.1, 0.1)),
        ("k2", (-0.2,)),
        ("feature_scale", 0.0),
        ("weights", (1.0, -1.0, 1.0, 1.0, 1.0)),
        ("weights", ((1.0, 2.0), (2.0, 1.0))),  # symmetric, eigenvalues 3 and -1
        ("weights", ((1.0, 0.5), (0.0, 1.0))),  # not symmetric
        ("damping_threshold", -1.0),
        ("max_damping", 0.0),
    ],
)
def test_invalid_gain_raises_gain_error_naming_it(field, value):
    with pytest.raises(GainError, match=rf"ServoGains\.{field}"):
        ServoGains(**{field: value})


def test_gain_vector_of_wrong_length_is_rejected():
    with pytest.raises(GainError, match=r"k1: expected 1 or 7 values, got 5"):
        PassivityController(ServoGains(), np.ones(7))
    with pytest.raises(GainError, match=r"weights: expected a \(5, 5\) matrix"):
        PassivityController(ServoGains(weights=((2.0, 0.0), (0.0, 2.0))), np.ones(5))
    with pytest.raises(GainError, match="velocity_limits"):
        PassivityController(ServoGains(), [1.0, 1.0, -1.0, 1.0, 1.0])


def test_feature_gains_follow_the_feature_count():
    """One ``k_i`` per feature: three gains serve three features and are refused for two, also
    after a step with three (the gains are kept between steps)."""
    controller = PassivityController(ServoGains(k=(0.1, 0.2, 0.3)), NO_LIMITS)
    np.testing.assert_array_equal(controller.feature_gains(3), [0.1, 0.2, 0.3])
    with pytest.raises(GainError, match=r"k: expected 1 or 2 values, got 3"):
        controller.feature_gains(2)


@pytest.mark.parametrize(
    "argument, shape",
    [("jacobian", (3, 4)), ("object_jacobian", (3, 2)), ("target_velocity", (2,)),
     ("secondary", (4,))],
)  # fmt: skip
def test_inconsistent_shape_raises_shape_error(argument, shape):
    controller = PassivityController(ServoGains(), REFERENCE_LIMITS)
    args = {
        "error_px": np.zeros(3),
        "jacobian_px": np.ones((3, 5)),
        "object_jacobian_px": np.ones((3, 3)),
        "target_velocity": np.zeros(3),
        "secondary": np.zeros(5),
    }
    key = {"jacobian": "jacobian_px", "object_jacobian": "object_jacobian_px"}.get(
        argument, argument
    )
    args[key] = np.zeros(shape)
    with pytest.raises(ShapeError, match=argument):
        controller.step(**args)


# ---------------------------------------------------------------- secondary objectives
def _eq17_18(k_u, k_w, d0, d, alpha):
    """Fictitious force of eqs. (17)-(18) before the impedance, written from the paper."""
    if d >= d0:
        return np.zeros(2)
    return np.array(
        [k_u * (d0 - d) * (np.pi / 2 - abs(alpha)),
         k_w * (d0 - d) * np.sign(alpha) * (np.pi / 2 - abs(alpha))]
    )  # fmt: skip


@pytest.mark.parametrize(
    "d, alpha",
    [(0.4, 0.3), (0.4, -0.3), (0.9, 0.0), (0.05, 1.2), (0.7, -np.pi / 2), (1.0, 0.2),
     (1.5, 0.2), (np.inf, 0.0)],
)  # fmt: skip
def test_obstacle_force_is_eqs_17_18(d, alpha):
    avoidance = ObstacleAvoidance(k_u=0.5, k_w=0.9, d0=1.0)
    np.testing.assert_allclose(avoidance.force(d, alpha)[:2], _eq17_18(0.5, 0.9, 1.0, d, alpha))


def test_obstacle_force_by_hand():
    """d = 0.5 m, d0 = 1 m, alpha = pi/4 to the right: (d0-d)(pi/2-|alpha|) = pi/8."""
    force = ObstacleAvoidance(k_u=0.5, k_w=0.9, d0=1.0).force(0.5, np.pi / 4)
    np.testing.assert_allclose(force[:2], [0.5 * np.pi / 8, 0.9 * np.pi / 8])
    # Obstacle on the left: the turn is the other way, the braking the same.
    left = ObstacleAvoidance(k_u=0.5, k_w=0.9, d0=1.0).force(0.5, -np.pi / 4)
    np.testing.assert_allclose(left[:2], [0.5 * np.pi / 8, -0.9 * np.pi / 8])


@pytest.mark.parametrize(
    "alpha, lateral",  # (d0 - d) = 0.5, k_u = 0.5; the triangle of sin(alpha), peak at pi/2
    [(0.0, 0.0), (np.pi / 4, 0.25 * np.pi / 4), (np.pi / 2, 0.25 * np.pi / 2),
     (-np.pi / 3, -0.25 * np.pi / 3), (3 * np.pi / 4, 0.25 * np.pi / 4)],
)  # fmt: skip
def test_obstacle_lateral_force_pushes_a_holonomic_base_away(alpha, lateral):
    """Obstacle on the right (alpha > 0): push left (+y), the most for one abeam. Lambda gets
    ``[-u_obs, vy_obs, omega_obs, 0...]`` on a holonomic base, the paper's ``[-u_obs, omega_obs,
    0...]`` on a unicycle."""
    avoidance = ObstacleAvoidance(k_u=0.5, k_w=0.9, d0=1.0)
    force = avoidance.force(0.5, alpha)
    assert force[2] == pytest.approx(lateral)
    assert avoidance.force(1.5, alpha)[2] == 0.0  # beyond d0
    state = SecondaryInput(np.zeros(3), 0.5, alpha, 1.0)
    decay = 1.0 - np.exp(-1.0 * 1.0 / 0.5)  # the impedance's step from rest: (1 - e^(-b dt/m)) F/b
    u_obs, omega_obs, vy_obs = decay * force
    holonomic = ObstacleAvoidance(k_u=0.5, k_w=0.9, d0=1.0).contribution(state, 3, 6)
    np.testing.assert_allclose(holonomic, [-u_obs, vy_obs, omega_obs, 0, 0, 0], atol=1e-15)
    unicycle = ObstacleAvoidance(k_u=0.5, k_w=0.9, d0=1.0).contribution(state, 2, 5)
    np.testing.assert_allclose(unicycle, [-u_obs, omega_obs, 0, 0, 0], atol=1e-15)


@pytest.mark.parametrize(
    "alpha, side",  # TURN_RAMP = 0.1 rad: the ramp's share of the paper's full turn
    [(0.0, 0.0), (0.05, 0.5), (-0.02, -0.2), (0.1, 1.0), (0.4, 1.0), (-1.0, -1.0)],
)  # fmt: skip
def test_holonomic_avoidance_turn_ramps_through_dead_ahead(alpha, side):
    """A holonomic base's F_w: the paper's sign(alpha) replaced by a ramp over +-0.1 rad, so
    an obstacle sweeping through its forward axis does not reverse the turn at full strength;
    a unicycle keeps the paper's sign (eq. 18)."""
    avoidance = ObstacleAvoidance(k_u=0.5, k_w=0.9, d0=1.0)
    paper = 0.9 * 0.5 * (np.pi / 2 - abs(alpha))  # k_w (d0 - d)(pi/2 - |alpha|), d = 0.5
    assert avoidance.force(0.5, alpha, holonomic=True)[1] == pytest.approx(side * paper)
    assert avoidance.force(0.5, alpha)[1] == pytest.approx(np.sign(alpha) * paper)
    # Braking and the lateral push are the same on both.
    np.testing.assert_array_equal(
        avoidance.force(0.5, alpha, holonomic=True)[[0, 2]], avoidance.force(0.5, alpha)[[0, 2]]
    )
    # The contribution a holonomic base gets takes the ramp: [-u_obs, vy_obs, omega_obs, ...].
    state = SecondaryInput(np.zeros(3), 0.5, alpha, 1.0)
    decay = 1.0 - np.exp(-1.0 * 1.0 / 0.5)
    lam = ObstacleAvoidance(k_u=0.5, k_w=0.9, d0=1.0).contribution(state, 3, 6)
    assert lam[2] == pytest.approx(decay * side * paper)


def test_obstacle_impedance_is_first_order_mass_damper():
    """Constant force F through Z(s) = m s + b: velocity = F/b (1 - exp(-b t / m))."""
    mass, damping, dt = 0.5, 2.0, 0.01
    avoidance = ObstacleAvoidance(k_u=0.5, k_w=0.9, d0=1.0, mass=mass, damping=damping)
    state = SecondaryInput(np.zeros(3), 0.4, 0.3, dt)
    force = _eq17_18(0.5, 0.9, 1.0, 0.4, 0.3)
    for step in range(1, 151):
        lam = avoidance.contribution(state, n_base=2, n=5)
        t = step * dt
        expected = force / damping * (1.0 - np.exp(-damping * t / mass))
        np.testing.assert_allclose([-lam[0], lam[1]], expected, rtol=1e-9)
        np.testing.assert_array_equal(lam[2:], 0.0)
    # Obstacle to the right (alpha > 0): brake (Lambda_u < 0) and turn left (omega > 0).
    assert lam[0] < 0 and lam[1] > 0
    # Once the obstacle is gone the velocity relaxes with the same time constant m / b.
    clear = SecondaryInput(np.zeros(3), np.inf, 0.0, 0.1)
    before = avoidance.velocity.copy()
    avoidance.contribution(clear, 2, 5)
    np.testing.assert_allclose(avoidance.velocity, before * np.exp(-damping * 0.1 / mass))


def test_arm_posture_is_eq19():
    target = np.array([0.0, 0.6065, 1.2346])  # the paper's theta_d, §5
    posture = ArmPosture(target, gain=1.5)
    state = SecondaryInput(np.array([0.2, 0.1, 1.5]), np.inf, 0.0, 0.01)
    np.testing.assert_allclose(
        posture.contribution(state, 2, 5), [0, 0, -0.3, 1.5 * 0.5065, 1.5 * (1.2346 - 1.5)]
    )


def test_joint_limit_avoidance_by_hand():
    limits = JointLimitAvoidance(np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0]),
                                 margin=0.2, gain=2.0)  # fmt: skip
    state = SecondaryInput(np.array([0.9, 0.0, -0.95]), np.inf, 0.0, 0.01)
    np.testing.assert_allclose(limits.contribution(state, 2, 5), [0, 0, -0.2, 0.0, 0.3])


def test_secondary_vector_sums_objectives():
    posture = ArmPosture(np.array([0.0, 0.5, 1.0]), gain=1.0)
    limits = JointLimitAvoidance(np.full(3, -1.0), np.full(3, 1.0), margin=0.2, gain=2.0)
    state = SecondaryInput(np.array([0.9, 0.5, 1.0]), np.inf, 0.0, 0.01)
    # posture: [-0.9, 0, 0]; limits: joint 1 at 0.9 > 0.8 -> -0.2, joint 3 at 1.0 -> -0.4
    np.testing.assert_allclose(
        secondary_vector([posture, limits], state, 2, 5), [0, 0, -0.9 - 0.2, 0, -0.4]
    )


@pytest.mark.parametrize(
    "make",
    [
        lambda: ObstacleAvoidance(k_u=-0.5),
        lambda: ObstacleAvoidance(d0=0.0),
        lambda: ObstacleAvoidance(mass=float("nan")),
        lambda: ArmPosture(np.zeros(3), gain=0.0),
        lambda: JointLimitAvoidance(np.zeros(3), np.ones(3), margin=-0.1),
    ],
)
def test_invalid_secondary_gain_raises(make):
    with pytest.raises(GainError):
        make()


# ---------------------------------------------------------------- eq. (20): compensation
def _smooth_command(t: float) -> np.ndarray:
    """A smooth known u(t) [m/s, rad/s], nonzero at t = 0 (the plant starts at rest)."""
    return np.array([
        0.2 + 0.1 * np.sin(t), 0.3 * np.cos(0.7 * t), 0.2 * np.cos(t),
        -0.15 + 0.05 * np.cos(t), 0.1 * np.cos(1.3 * t),
    ])  # fmt: skip


def _compensated_run(robot, loop, k_d: float, duration: float, dt: float = 1e-3):
    """Plant and DynamicCompensator (same robot and servos, all rows) under u(t); V2(t)."""
    q0 = robot.with_arm_positions(robot.home(), [0.3, 0.6, -1.2])
    plant = Plant(robot, loop, q0, dt)
    compensator = DynamicCompensator(robot, loop, Compensation.ALL, k_d, 1e-6)
    times, storage, errors = [], [], []
    for step in range(round(duration / dt)):
        t = step * dt
        u = _smooth_command(t)
        v_ref, v2 = compensator.step(plant.q, plant.v, u, dt)
        assert v2 == pytest.approx(0.5 * np.sum((plant.v - u) ** 2), rel=1e-12)
        times.append(t)
        storage.append(v2)
        errors.append(plant.v - u)
        plant.step(v_ref)
    return np.array(times), np.array(storage), np.array(errors)


def _proportional(loop: ServoModel) -> ServoModel:
    """The servos without their integral action: eq. (1), which eq. (20) inverts, has none (the
    plant's arm servos have it, a model error the experiments carry)."""
    return replace(loop, integral_rates=np.zeros_like(loop.integral_rates))


def test_compensated_velocity_error_decays_at_kd(cyton):
    """Eqs. (21)-(22): with exact M, C, g, V2 = |v - u|^2 / 2 never increases and decays as
    exp(-2 K_D t).

    Servos: ``ServoModel.from_robot(cyton, revolute=0.25)`` for both the plant and the
    compensator, so an arm joint's own lag ``M_ii / K_i`` (0.2-0.4 T with the row-sum
    stiffness on this arm) is well above the 1 ms plant step; the sampled law then differs from
    (21) by ``O(h K_i / M_ii)``. See ``test_compensated_velocity_error_with_default_stiff_arm_loops``
    for the default servos.
    """
    k_d = 1.5  # [1/s]
    loop = _proportional(ServoModel.from_robot(cyton, revolute=0.25))
    t, v2, errors = _compensated_run(cyton, loop, k_d, duration=1.5)
    assert v2[0] > 0.05  # v(0) = 0 != u(0)
    increases = np.diff(v2)
    assert np.max(increases) <= 1e-9 * v2[0], "V2 increased"
    fit = t >= 0.05
    rate = -np.polyfit(t[fit], np.log(v2[fit]), 1)[0]
    assert rate == pytest.approx(2 * k_d, rel=0.10)
    # Eq. (21) is decoupled: each component follows vtilde_j(0) exp(-K_D t) on its own (the
    # O(h / tau) coupling of the sampled plant through M_v stays below 2 % of |vtilde(0)|).
    assert np.all(np.abs(errors[0]) > 0.05)
    expected = errors[0] * np.exp(-k_d * t[-1])
    assert np.max(np.abs(errors[-1] - expected)) < 0.02 * np.linalg.norm(errors[0])


def test_compensated_velocity_error_with_default_stiff_arm_loops(cyton):
    """The default arm servos (``T = 0.02 s``) lag by only 3-8 ms (``M_ii / K_i`` with the
    row-sum stiffness), a few 1 ms plant steps: the sampled law departs from eq. (21) by
    ``O(h K_i / M_ii)``, so the decay rate is checked to 15 %."""
    k_d = 1.5
    loop = _proportional(ServoModel.from_robot(cyton))
    t, v2, _ = _compensated_run(cyton, loop, k_d, duration=1.5)
    fit = t >= 0.05
    rate = -np.polyfit(t[fit], np.log(v2[fit]), 1)[0]
    assert rate == pytest.approx(2 * k_d, rel=0.15)


def test_compensation_reference_is_eq20(cyton):
    """v_ref = M (udot - K_D (v - u)) + C v + g with M, C, g built here from Pinocchio.

    The servos' loop gain is written here from its definition, ``K_e,i = sum_j |M_v,ij| / T_i
    + D_i`` (URDF damping fed forward, so it leaves ``C``). The arm servos cancel their own
    gravity load (``loop.gravity_compensated``), so ``g`` only has the base rows' gravity (zero
    on flat ground).
    """
    robot = cyton
    loop = ServoModel.from_robot(robot)
    k_d = np.array([0.3, 0.3, 1.0, 2.0, 3.0])
    dt, tau = 0.01, 0.05
    compensator = DynamicCompensator(robot, loop, Compensation.ALL, k_d, tau)
    rng = np.random.default_rng(5)
    q = robot.with_arm_positions(robot.home(), [0.2, 0.5, 1.1])
    v = rng.uniform(-0.3, 0.3, 5)
    u0, u1 = rng.uniform(-0.3, 0.3, 5), rng.uniform(-0.3, 0.3, 5)
    compensator.step(q, v, u0, dt)  # first call: udot starts at zero
    v_ref, v2 = compensator.step(q, v, u1, dt)

    udot = dt / (tau + dt) * (u1 - u0) / dt  # one step of the first-order filter from 0
    model, data, s = robot.model, robot.data, robot.selection
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    coriolis = pin.computeCoriolisMatrix(model, data, q, s @ v)
    gravity = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv))
    mass_v = s.T @ mass @ s
    kv = np.abs(mass_v).sum(axis=1) / loop.time_constants + loop.damping
    expected = (
        mass_v @ (udot - k_d * (v - u1))
        + (s.T @ coriolis @ s) @ v
        + (1.0 - loop.gravity_compensated) * (s.T @ gravity)
    ) / kv + v
    # The low-level loops accept references within the velocity limits only.
    limits = robot.velocity_limits
    inside = np.abs(expected) < limits
    assert inside.sum() >= 3, "too few unclipped entries to check eq. (20)"
    expected = np.clip(expected, -limits, limits)
    np.testing.assert_allclose(v_ref, expected, rtol=1e-9, atol=1e-12)
    assert v2 == pytest.approx(0.5 * np.sum((v - u1) ** 2))

    platform = DynamicCompensator(robot, loop, Compensation.PLATFORM, k_d, tau)
    platform.step(q, v, u0, dt)
    v_ref_platform, _ = platform.step(q, v, u1, dt)
    np.testing.assert_allclose(v_ref_platform[:2], expected[:2], rtol=1e-9)
    np.testing.assert_array_equal(v_ref_platform[2:], u1[2:])
    off = DynamicCompensator(robot, loop, Compensation.OFF, k_d, tau)
    np.testing.assert_array_equal(off.step(q, v, u1, dt)[0], u1)


@pytest.mark.parametrize(
    "kwargs", [{"k_d": 0.0}, {"k_d": [0.3, 0.3, -1.0, 1.0, 1.0]}, {"derivative_time_constant": 0}]
)
def test_invalid_compensation_gain_raises(cyton, kwargs):
    loop = ServoModel.from_robot(cyton)
    with pytest.raises(GainError):
        DynamicCompensator(cyton, loop, Compensation.PLATFORM, **kwargs)
