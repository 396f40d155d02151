"""Tests of pbvs_pin.study.analysis: the paper's §4 figures and the passivity inequalities of a log.

Synthetic logs check every number against a re-computation written here from the paper's
equations (lambda from singular values, V1 by quadrature, integrals in closed form, t1 by brute
force). Short simulated runs check the claims: with exact models and condition (31) satisfied,
the measured error stays within the bound (39) after t1, and inequality (9) holds.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.integrate import quad

from pbvs_pin.cli import main
from pbvs_pin.exceptions import GainError, NonFiniteValue, PbvsError
from pbvs_pin.sim.log import RunLog
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.study.analysis import analyze_log, analyze_run, choose_t1, min_eigenvalue_jjt

SCALE = 100.0  # px per controller unit
K = np.array([0.15, 0.2, 0.3])
XI_D = np.array([0.0, 60.0, -60.0])


def synthetic_log(gamma_spike: float = 5.0, gamma_level: float = 0.004, nan_at=(7, 40)):
    """A log with known signals: e(t) = e0 exp(-2t) px, gamma = a spike then a constant level.

    J is random (seeded) at every sample; lambda_min is filled from it (NaN at ``nan_at``).
    True-state set: nu = n0 exp(-t), passivity_input = -nu, storage from its closed form;
    v - u = 0.1 nu. The controller's set differs from it in every channel (stale and scaled),
    so any mixture of the two sets gives other integrals than the true set alone.
    """
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 4.0, 201)
    e0 = np.array([-150.0, 40.0, 25.0])
    error_px = e0 * np.exp(-2.0 * t)[:, None]
    base = np.hstack([np.eye(3), np.zeros((3, 2))])
    jacobians = base + 0.1 * rng.normal(size=(t.size, 3, 5))
    lambda_min = np.array([min_eigenvalue_jjt(j) for j in jacobians])
    lambda_min[list(nan_at)] = np.nan
    gamma_dir = np.array([0.6, -0.8, 0.0])
    gamma = np.where((t < 0.5)[:, None], gamma_spike * gamma_dir, gamma_level * gamma_dir)
    n0 = np.array([0.3, -0.2, 0.1, 0.05, 0.0])
    nu = n0 * np.exp(-t)[:, None]
    e_units = error_px / SCALE
    storage = np.sum(K * (np.abs(e_units) - np.log1p(np.abs(e_units))), axis=1)
    channels = {
        "t": t,
        "xi_true": XI_D + error_px,
        "xi_d": np.tile(XI_D, (t.size, 1)),
        "lambda_min": lambda_min,
        "gamma": gamma,
        "nu_true": nu,
        "passivity_input_true": -nu,
        "storage_true": storage,
        "nu": 1.3 * np.roll(nu, 3, axis=0),
        "passivity_input": -0.5 * nu,
        "storage": 1.1 * storage,
        "u": np.zeros_like(nu),
        "v": 0.1 * nu,
    }
    meta = {"scenario": "synthetic", "robot": "none", "feature_scale": SCALE, "k": K.tolist()}
    return RunLog(channels, meta), jacobians, e0


def v1_by_quadrature(error_units: np.ndarray, gains: np.ndarray = K) -> float:
    """Eq. (7) integrated numerically along the straight path from 0 to e."""
    return sum(
        quad(lambda eta, k=k: k * eta / (1.0 + abs(eta)), 0.0, e)[0]
        for k, e in zip(gains, error_units, strict=True)
    )


def test_figures_match_an_independent_recomputation():
    log, jacobians, e0 = synthetic_log()
    result = analyze_log(log, epsilon=0.5)

    # lambda from the singular values of J (not eigvalsh), NaN samples skipped
    sigma_min_sq = np.array([np.linalg.svd(j, compute_uv=False)[-1] ** 2 for j in jacobians])
    sigma_min_sq[[7, 40]] = np.inf
    lam = sigma_min_sq.min()
    assert result["lambda"] == pytest.approx(lam, rel=1e-10)
    assert result["lambda_missing_samples"] == 2
    lambda_prime = 0.5 * lam
    assert result["lambda_prime"] == pytest.approx(lambda_prime, rel=1e-10)
    assert result["k_min"] == pytest.approx(0.15)

    # t1 by brute force: the first sample from which (31) holds and (38) holds to the end
    t = log["t"]
    e = (log["xi_true"] - log["xi_d"]) / SCALE
    kc_e = np.linalg.norm(K * e / (1 + np.abs(e)), axis=1)
    g = np.linalg.norm(log["gamma"], axis=1)
    first = next(
        i
        for i in range(t.size)
        if g[i:].max() < lambda_prime * 0.15 and np.all(kc_e[i:] <= g[i:].max() / lambda_prime)
    )
    assert first > 0, "test setup: the spike must push t1 past the start"
    assert result["t1_s"] == pytest.approx(t[first])

    gamma_inf = g[first:].max()
    assert result["gamma_inf"] == pytest.approx(gamma_inf)
    assert result["condition_31"]["holds"] is True
    margin = lambda_prime * 0.15 - gamma_inf
    assert result["bound_39"]["predicted_units"] == pytest.approx(gamma_inf / margin)
    assert result["bound_39"]["predicted_px"] == pytest.approx(SCALE * gamma_inf / margin)
    measured = np.linalg.norm(e0) * math.exp(-2.0 * t[first])
    assert result["bound_39"]["measured_sup_px"] == pytest.approx(measured)
    assert result["bound_39"]["holds"] is bool(measured <= SCALE * gamma_inf / margin)

    # (42): varsigma, zeta with V1(t1) by quadrature, integrals in closed form
    l2 = result["l2_gain_42"]
    varsigma = 1.0 / margin
    assert l2["varsigma"] == pytest.approx(varsigma)
    v1_t1 = v1_by_quadrature(e[first])
    assert l2["V1_t1"] == pytest.approx(v1_t1, rel=1e-8)
    assert l2["zeta"] == pytest.approx(lambda_prime * varsigma**2 * v1_t1, rel=1e-8)
    t1, end = t[first], t[-1]
    error_sq = (np.linalg.norm(e0) / SCALE) ** 2 * (math.exp(-4 * t1) - math.exp(-4 * end)) / 4
    gamma_sq = 0.004**2 * (end - t1)
    assert l2["integral_error_sq"] == pytest.approx(error_sq, rel=2e-3)
    assert l2["integral_gamma_sq"] == pytest.approx(gamma_sq, rel=1e-9)
    assert l2["measured_ratio"] == pytest.approx(error_sq / gamma_sq, rel=2e-3)

    # (9) and (14): nu^T input = -||nu||^2, so beta_1 = 0 and beta = V1(0)
    n0_sq = 0.3**2 + 0.2**2 + 0.1**2 + 0.05**2
    nu_sq = n0_sq * (1 - math.exp(-2 * end)) / 2
    v1_0 = v1_by_quadrature(e[0])
    p9, p14 = result["passivity_9"], result["passivity_14"]
    assert p9["lhs_integral_nu_input"] == pytest.approx(-nu_sq, rel=1e-3)
    assert p9["rhs_minus_V1_0"] == pytest.approx(-v1_0, rel=1e-8)
    assert p9["holds"] is bool(-nu_sq >= -v1_0)
    assert p14["beta_1"] == 0.0
    assert p14["rhs_beta"] == pytest.approx(v1_0, rel=1e-8)
    assert p14["holds"] is bool(nu_sq <= v1_0)
    # (27): int ||nu||^2 <= V1(0) + int nu^T (v - u), with v - u = 0.1 nu
    p27 = result["passivity_27"]
    assert p27["integral_nu_velocity_error"] == pytest.approx(0.1 * nu_sq, rel=1e-3)
    assert p27["rhs"] == pytest.approx(v1_0 + 0.1 * nu_sq, rel=1e-3)
    assert p27["holds"] is bool(nu_sq <= v1_0 + 0.1 * nu_sq)
    assert result["passivity_signals"].startswith("true state")
    json.dumps(result, allow_nan=False)


def test_passivity_uses_one_signal_set_never_a_mixture():
    """(9) from the true-state channels only; the controller's channels only as a diagnostic."""
    log, _, _ = synthetic_log()
    result = analyze_log(log)
    t = log["t"]

    def supply(nu_name, input_name):
        return np.trapezoid(np.sum(log[nu_name] * log[input_name], axis=1), t)

    true_supply = supply("nu_true", "passivity_input_true")
    assert result["passivity_9"]["lhs_integral_nu_input"] == pytest.approx(true_supply)
    assert result["passivity_9"]["rhs_minus_V1_0"] == pytest.approx(-log["storage_true"][0])
    for mixed in (supply("nu", "passivity_input_true"), supply("nu_true", "passivity_input")):
        assert abs(mixed - true_supply) > 1e-3 * abs(true_supply)
    diagnostic = result["passivity_controller_signals"]
    assert diagnostic["signals"].startswith("diagnostic")
    assert diagnostic["passivity_9"]["lhs_integral_nu_input"] == pytest.approx(
        supply("nu", "passivity_input")
    )
    assert diagnostic["passivity_9"]["rhs_minus_V1_0"] == pytest.approx(-log["storage"][0])


def test_condition_31_fails_when_gamma_is_large():
    log, _, _ = synthetic_log(gamma_level=1e3)
    result = analyze_log(log, epsilon=0.5)
    assert result["condition_31"]["holds"] is False
    assert "condition (31) fails" in result["bound_39"]["reason"]
    assert "predicted_px" not in result["bound_39"]
    assert "varsigma" not in result["l2_gain_42"]


def test_no_t1_when_gamma_is_zero():
    """Exact estimator: gamma = 0, the theory promises only asymptotic convergence."""
    log, _, _ = synthetic_log(gamma_spike=0.0, gamma_level=0.0)
    result = analyze_log(log, epsilon=0.5)
    assert result["t1_s"] is None
    assert "gamma = 0" in result["bound_39"]["reason"]


def test_choose_t1_treats_missing_error_as_above_the_bound():
    kc = np.array([3.0, 1.0, 0.5, np.nan, 0.1, 0.1])
    gamma = np.array([10.0, 1.0, 0.4, np.nan, 0.2, 0.2])
    # lambda' = 1, k_min large so (31) holds from index 2; the NaN at 3 blocks t1 before 4
    assert choose_t1(kc, gamma, 1.0, 1.0) == 4
    assert choose_t1(np.array([1.0, 2.0]), np.array([0.0, 0.0]), 1.0, 1.0) is None


def test_given_t1_and_epsilon_are_checked():
    log, _, _ = synthetic_log()
    assert analyze_log(log, 0.5, t1=1.0)["t1_s"] == pytest.approx(1.0)
    with pytest.raises(GainError, match="epsilon"):
        analyze_log(log, 1.0)
    with pytest.raises(GainError, match="t1"):
        analyze_log(log, 0.5, t1=99.0)


def test_log_without_measurements_is_an_error():
    log, _, _ = synthetic_log()
    log.channels["lambda_min"] = np.full_like(log["lambda_min"], np.nan)
    with pytest.raises(NonFiniteValue, match="lambda_min"):
        analyze_log(log)
    del log.channels["gamma"]
    with pytest.raises(PbvsError, match="gamma"):
        analyze_log(log)


def test_missing_log_file(tmp_path, capsys):
    with pytest.raises(PbvsError, match="no run log"):
        analyze_run(tmp_path / "nowhere")
    assert main(["analyze", str(tmp_path / "nowhere")]) == 2
    assert "no run log" in capsys.readouterr().err


# ------------------------------------------------------------------------ simulated runs
@pytest.fixture(scope="module")
def weave_log():
    """Exact models, no camera noise, a slowly weaving target tracked by the alpha-beta filter.

    The filter lags the weave, so gamma stays non-zero and (31) holds after the transient.
    """
    scenario = load_scenario("experiment1").with_values(
        **{
            "duration": 6.0,
            "camera.noise_px": 0.0,
            "motion.kind": "weave",
            "motion.velocity": [0.03, 0.0, 0.0],
            "motion.amplitude": [0.0, 0.05, 0.02],
            "motion.frequency": 0.1,
            "motion.stop_time": 100.0,
        }
    )
    return simulate(scenario)


@pytest.mark.parametrize("t1", [None, 2.0])
def test_measured_error_stays_within_the_bound_39(weave_log, t1):
    result = analyze_log(weave_log, epsilon=0.5, t1=t1)
    assert result["condition_31"]["holds"] is True
    start = result["t1_s"]
    t = weave_log["t"]
    error_px = np.linalg.norm(weave_log["xi_true"] - weave_log["xi_d"], axis=1)[t >= start - 1e-9]
    assert result["bound_39"]["measured_sup_px"] == pytest.approx(error_px.max())
    assert np.all(error_px <= result["bound_39"]["predicted_px"])
    assert result["bound_39"]["holds"] is True
    assert result["l2_gain_42"]["holds"] is True
    assert result["l2_gain_42"]["measured_ratio"] < result["l2_gain_42"]["varsigma_squared"]


def test_passivity_inequality_9_holds_on_a_run():
    """A short run (the error has not converged, so (9) has a margin of V1(T) > 0)."""
    scenario = load_scenario("experiment1").with_values(
        **{"duration": 0.2, "camera.noise_px": 0.0, "estimator.kind": "exact"}
    )
    log = simulate(scenario)
    result = analyze_log(log)
    p9 = result["passivity_9"]
    supply = np.trapezoid(np.sum(log["nu_true"] * log["passivity_input_true"], axis=1), log["t"])
    assert p9["lhs_integral_nu_input"] == pytest.approx(supply)
    assert p9["rhs_minus_V1_0"] == pytest.approx(-log["storage_true"][0])
    assert supply >= -log["storage_true"][0]
    assert p9["holds"] is True
    # the supply matches the storage change to within the sampling effects
    assert abs(p9["identity_residual"]) < 0.1 * log["storage_true"][0]


def test_true_state_channels_match_an_independent_recomputation(weave_log):
    """nu_true = J^T K_c e with J by finite differences of the true features; V1 by quadrature."""
    from pbvs_pin.sim.setup import build

    log = weave_log
    setup = build(load_scenario("experiment1"))
    robot, features = setup.robot, setup.features
    scale = log.meta["feature_scale"]
    k = np.asarray(log.meta["k"])
    i = len(log["t"]) // 2
    q = log["q"][i]
    half = np.array([0.0, 0.0, log.meta["target_separation"] / 2])
    points = [log["target"][i] + half, log["target"][i] - half]
    error = (log["xi_true"][i] - log["xi_d"][i]) / scale
    assert log["storage_true"][i] == pytest.approx(v1_by_quadrature(error, k), rel=1e-6)
    jac = np.empty((3, robot.n))
    h = 1e-6
    for j in range(robot.n):
        dv = np.zeros(robot.n)
        dv[j] = 1.0
        plus = features.jacobians(robot, robot.integrate(q, dv, h), *points)[0]
        minus = features.jacobians(robot, robot.integrate(q, -dv, h), *points)[0]
        jac[:, j] = (plus - minus) / (2 * h) / scale
    kc_e = k * error / (1 + np.abs(error))
    np.testing.assert_allclose(log["nu_true"][i], jac.T @ kc_e, rtol=1e-4, atol=1e-8)


def test_analyze_run_writes_report_and_plots(weave_log, tmp_path, capsys):
    path = weave_log.save(tmp_path / "run")
    out = tmp_path / "analysis"
    result = analyze_run(path, 0.5, out)
    for name in ("analysis.json", "analysis.md", "bound.png", "gamma.png", "storage.png"):
        assert (out / name).stat().st_size > 0
    assert json.loads((out / "analysis.json").read_text()) == result
    assert "(39) predicted bound" in (out / "analysis.md").read_text()
    assert main(["analyze", str(path.parent), "--epsilon", "0.4"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["epsilon"] == 0.4
    assert printed["lambda"] == pytest.approx(result["lambda"])
