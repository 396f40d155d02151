"""The alpha-beta filter of §4 (eq. (30)), against the textbook formulas written out here.

References: the filter's error dynamics on a constant-velocity target (characteristic
polynomial ``z^2 - (2 - alpha - beta) z + (1 - alpha)``), the steady-state noise variances of
an alpha-beta tracker, and Kalata's tracking-index relations (Kalata 1984,
"The tracking index: a generalized parameter for alpha-beta and alpha-beta-gamma target
trackers", IEEE TAES 20(2)):

    Lambda^2 = beta^2 / (1 - alpha),      beta = 2 (2 - alpha) - 4 sqrt(1 - alpha).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from pbvs_pin.exceptions import GainError
from pbvs_pin.perception.estimation import AlphaBetaFilter

PERIOD = 1.0 / 30.0
"""The paper's camera rate [s]."""

VELOCITY = np.array([0.10, 0.04, -0.02])
"""Experiment 1's target velocity, plus a small vertical part [m/s]."""

START = np.array([0.8, -0.1, 0.4])


def _track(filt: AlphaBetaFilter, count: int, noise: float, rng: np.random.Generator):
    """Feed ``count`` noisy positions of the constant-velocity target; velocity errors."""
    errors = []
    for k in range(count):
        t = k * PERIOD
        filt.update(START + VELOCITY * t + noise * rng.standard_normal(3), t)
        errors.append(filt.velocity - VELOCITY)
    return np.array(errors)


def _velocity_variance(alpha: float, beta: float, noise: float) -> float:
    """Steady-state variance of an alpha-beta tracker's velocity estimate, per axis.

    ``sigma_v^2 = sigma_n^2 / T^2 * 2 beta^2 / (alpha (4 - 2 alpha - beta))``.
    """
    return noise**2 / PERIOD**2 * 2 * beta**2 / (alpha * (4 - 2 * alpha - beta))


def test_noise_free_convergence_rate():
    """Error contracts like |z|^N with |z| = sqrt(1 - alpha) (complex roots for 0.5, 0.1)."""
    alpha, beta = 0.5, 0.1
    assert (2 - alpha - beta) ** 2 < 4 * (1 - alpha)  # complex pair: modulus sqrt(1 - alpha)
    errors = _track(AlphaBetaFilter(alpha, beta), 61, 0.0, np.random.default_rng(0))
    initial = np.linalg.norm(VELOCITY)  # the filter starts with zero velocity
    bound = 10.0 * initial * np.sqrt(1 - alpha) ** 60  # ~1e-8 m/s
    assert np.linalg.norm(errors[-1]) < bound
    assert np.linalg.norm(errors[-1]) < 1e-6


def test_converges_with_seeded_noise():
    """2 mm position noise at 30 Hz (the default alpha = 0.5, beta = 0.1 of the scenarios).

    Stated tolerance: after 90 updates (3 s) every velocity error stays below 5 sigma_v per
    axis, sigma_v = 7.0 mm/s from the steady-state formula; the measured variance is within
    20 % of the formula and the mean error (bias) below sigma_v / 5.
    """
    alpha, beta, noise = 0.5, 0.1, 2e-3
    sigma_v = np.sqrt(_velocity_variance(alpha, beta, noise))
    assert sigma_v == pytest.approx(7.05e-3, rel=0.01)
    errors = _track(AlphaBetaFilter(alpha, beta), 6000, noise, np.random.default_rng(42))
    settled = errors[90:]
    assert np.max(np.abs(settled)) < 5 * sigma_v
    assert np.var(settled) == pytest.approx(sigma_v**2, rel=0.20)
    assert np.max(np.abs(settled.mean(axis=0))) < sigma_v / 5


def test_position_estimate_tracks_with_seeded_noise():
    """Position variance ratio (2 beta - 3 alpha beta + 2 alpha^2) / (alpha (4 - 2 alpha - beta))."""
    alpha, beta, noise = 0.5, 0.1, 2e-3
    filt = AlphaBetaFilter(alpha, beta)
    rng = np.random.default_rng(43)
    errors = []
    for k in range(6000):
        t = k * PERIOD
        filt.update(START + VELOCITY * t + noise * rng.standard_normal(3), t)
        errors.append(filt.position - (START + VELOCITY * t))
    ratio = (2 * beta - 3 * alpha * beta + 2 * alpha**2) / (alpha * (4 - 2 * alpha - beta))
    assert np.var(np.array(errors)[90:]) == pytest.approx(noise**2 * ratio, rel=0.2)


def test_one_update_by_hand():
    filt = AlphaBetaFilter(0.5, 0.1)
    filt.update([1.0, 2.0, 3.0], 0.0)  # the first measurement sets the position only
    np.testing.assert_array_equal(filt.position, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(filt.velocity, [0.0, 0.0, 0.0])
    filt.update([1.2, 2.0, 2.9], 0.1)
    # residual = [0.2, 0, -0.1]: p = p- + 0.5 r, v = 0 + 0.1 / 0.1 * r
    np.testing.assert_allclose(filt.position, [1.1, 2.0, 2.95])
    np.testing.assert_allclose(filt.velocity, [0.2, 0.0, -0.1])
    filt.update([1.3, 2.1, 2.9], 0.2)
    predicted = np.array([1.1, 2.0, 2.95]) + 0.1 * np.array([0.2, 0.0, -0.1])
    residual = np.array([1.3, 2.1, 2.9]) - predicted
    np.testing.assert_allclose(filt.position, predicted + 0.5 * residual)
    np.testing.assert_allclose(filt.velocity, np.array([0.2, 0.0, -0.1]) + 1.0 * residual)


def test_missing_and_out_of_order_measurements_are_ignored():
    filt = AlphaBetaFilter(0.5, 0.1)
    filt.update([0.0, 0.0, 0.0], 0.0)
    filt.update([0.1, 0.0, 0.0], 0.1)
    position, velocity = filt.position, filt.velocity
    filt.update([np.nan, 0.0, 0.0], 0.2)  # target not seen
    filt.update([np.inf, 0.0, 0.0], 0.2)
    filt.update([5.0, 5.0, 5.0], 0.1)  # same time again
    filt.update([5.0, 5.0, 5.0], 0.05)  # older
    np.testing.assert_array_equal(filt.position, position)
    np.testing.assert_array_equal(filt.velocity, velocity)
    assert np.all(np.isfinite(filt.velocity))
    # The next valid frame predicts over the whole gap since the last used one.
    filt.update([0.3, 0.0, 0.0], 0.3)
    predicted = position + 0.2 * velocity
    np.testing.assert_allclose(filt.position, predicted + 0.5 * ([0.3, 0, 0] - predicted))


def _kalata_alpha(tracking_index: float) -> float:
    """Solve Kalata's two relations for alpha numerically (independent of the closed form)."""

    def residual(alpha: float) -> float:
        beta = 2 * (2 - alpha) - 4 * np.sqrt(1 - alpha)
        return beta**2 / (1 - alpha) - tracking_index**2

    return brentq(residual, 1e-12, 1 - 1e-12, xtol=1e-15, rtol=1e-14)


@pytest.mark.parametrize("tracking_index", [0.01, 0.1, 0.5, 1.0, 3.0, 10.0])
def test_gains_from_tracking_index_follow_kalata(tracking_index):
    filt = AlphaBetaFilter.from_tracking_index(tracking_index)
    alpha, beta = filt.alpha, filt.beta
    assert beta**2 / (1 - alpha) == pytest.approx(tracking_index**2, rel=1e-9)
    assert beta == pytest.approx(2 * (2 - alpha) - 4 * np.sqrt(1 - alpha), rel=1e-9)
    assert alpha == pytest.approx(_kalata_alpha(tracking_index), rel=1e-8)
    assert 0 < alpha < 1 and 0 < beta < 4 - 2 * alpha


def test_tracking_index_limits():
    """Small index: light smoothing (alpha, beta -> 0); large index: alpha -> 1, beta -> 2."""
    slow = AlphaBetaFilter.from_tracking_index(1e-3)
    fast = AlphaBetaFilter.from_tracking_index(1e3)
    assert slow.alpha < 0.1 and slow.beta < 1e-3
    assert fast.alpha > 0.99 and fast.beta == pytest.approx(2.0, abs=0.1)


@pytest.mark.parametrize(
    "alpha, beta",
    [(0.0, 0.1), (-0.5, 0.1), (1.5, 0.1), (0.5, 0.0), (0.5, -0.1), (0.5, 3.0), (1.0, 2.0),
     (float("nan"), 0.1), (0.5, float("nan"))],
)  # fmt: skip
def test_invalid_gains_raise_gain_error(alpha, beta):
    with pytest.raises(GainError, match="AlphaBetaFilter"):
        AlphaBetaFilter(alpha, beta)


@pytest.mark.parametrize("tracking_index", [0.0, -1.0, float("nan")])
def test_invalid_tracking_index_raises_gain_error(tracking_index):
    with pytest.raises(GainError, match="tracking index"):
        AlphaBetaFilter.from_tracking_index(tracking_index)


def test_the_beta_error_states_the_stability_bound():
    """The message gives ``4 - 2 alpha`` for the alpha given (mutation testing, docs/mutation.md)."""
    with pytest.raises(GainError, match=r"4 - 2 alpha = 3, got 3\.5"):
        AlphaBetaFilter(0.5, 3.5)
    with pytest.raises(GainError, match=r"4 - 2 alpha = 2\.4, got 2\.5"):
        AlphaBetaFilter(0.8, 2.5)


@pytest.mark.parametrize("reset", [False, True])
def test_before_a_measurement_the_estimates_are_zero_3_vectors(reset):
    filt = AlphaBetaFilter(0.5, 0.1)
    if reset:
        filt.update([1.0, 2.0, 3.0], 0.0)
        filt.update([1.1, 2.0, 3.0], 0.1)
        filt.reset()
    for estimate in (filt.position, filt.velocity):
        assert estimate.shape == (3,)
        assert not estimate.any()
    filt.update([1.0, 2.0, 3.0], 5.0)  # after a reset the next measurement starts the track
    np.testing.assert_array_equal(filt.position, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(filt.velocity, [0.0, 0.0, 0.0])


@pytest.mark.parametrize("alpha", [0.01, 0.5, 1.0])
def test_the_accepted_gains_are_the_whole_stability_triangle(alpha):
    """``0 < alpha <= 1`` and ``0 < beta < 4 - 2 alpha`` (the roots of
    ``z^2 - (2 - alpha - beta) z + (1 - alpha)`` inside the unit circle), up to its edge."""
    beta = (4.0 - 2.0 * alpha) * (1.0 - 1e-9)
    roots = np.roots([1.0, -(2.0 - alpha - beta), 1.0 - alpha])
    assert np.max(np.abs(roots)) < 1.0  # numpy: inside the stability region
    AlphaBetaFilter(alpha, beta)
    with pytest.raises(GainError, match="beta"):
        AlphaBetaFilter(alpha, 4.0 - 2.0 * alpha)
