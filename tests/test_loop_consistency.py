"""The control loop hands the controller the same J and J_o as the model layer computes."""

import numpy as np
import pinocchio as pin
import pytest

from pbvs_pin.sim.loop import _control_step
from pbvs_pin.sim.perception import Perception
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.setup import build

NO_LATENCY = {"camera.latency": 0.0, "estimator.predict": False}
"""A frame captured at 0 s is delivered at 0 s (the default latency is one frame) and servoed
on as it is (the shipped experiments predict it forward to the configuration now)."""


def test_loop_jacobians_match_the_feature_set_at_the_current_configuration():
    setup = build(load_scenario("experiment1").with_values(**NO_LATENCY))
    perception = Perception(setup)
    q0 = setup.plant.q
    setup.sensor.capture(0.0, setup.robot.camera_pose(q0), setup.target.centres(0.0), q0)
    perception.take(setup.sensor.deliver(0.0))
    # A configuration other than the one the frame was captured at, so a stale camera
    # placement in pin.Data would give a different J_o.
    q = setup.model.integrate(q0, np.array([0.2, 0.5, 0.4, -0.3, 0.2]), 1.0)
    _, (jacobian, object_jacobian) = _control_step(setup, perception, q, (np.inf, 0.0), 0.0, 0.01)
    measurement = perception.measurement
    rotation = setup.model.camera_pose(q).rotation
    expected_j = setup.features.interaction_matrix(setup.model.camera, measurement) @ (
        setup.model.camera_jacobian(q)
    )
    expected_jo = setup.features.object_jacobian(setup.model.camera, measurement, rotation.T)
    np.testing.assert_allclose(jacobian, expected_j, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(object_jacobian, expected_jo, rtol=1e-12, atol=1e-9)


def test_fused_step_equals_the_modular_blocks():
    """The 1 kHz loop's single compiled call gives what the modular classes give."""
    from pbvs_pin.control.step import FusedControlStep

    # posture, joint limits and obstacle avoidance on
    scenario = load_scenario("experiment2").with_values(**NO_LATENCY)
    modular, fused_setup = build(scenario), build(scenario)
    fused = FusedControlStep(
        fused_setup.model, fused_setup.features, fused_setup.xi_d, fused_setup.controller,
        fused_setup.compensator, fused_setup.objectives,
    )  # fmt: skip
    rng = np.random.default_rng(3)
    perception = Perception(modular)
    q = modular.plant.q
    modular.sensor.capture(0.0, modular.robot.camera_pose(q), modular.target.centres(0.0), q)
    perception.take(modular.sensor.deliver(0.0))
    laser = (0.6, 0.3)  # an obstacle inside d0, to the right
    dt = 0.01
    for step in range(3):  # several steps: the command derivative and impedance have memory
        q = modular.model.integrate(q, rng.uniform(-0.2, 0.2, modular.model.n), 1.0)
        v = rng.uniform(-0.2, 0.2, modular.model.n)
        target_velocity = rng.uniform(-0.1, 0.1, 3)
        perception.velocity = lambda t, w=target_velocity: w
        output, (jacobian, object_jacobian) = _control_step(modular, perception, q, laser, 0.0, dt)
        v_ref, v2 = modular.compensator.step(q, v, output.u, dt)
        u_f, v_ref_f, v2_f = fused.step(
            q, v, perception.measurement, target_velocity, np.array(laser), dt
        )
        fused_output, (jacobian_f, object_jacobian_f) = fused.output()
        np.testing.assert_allclose(u_f, output.u, rtol=1e-10, atol=1e-12, err_msg=f"u {step}")
        np.testing.assert_allclose(v_ref_f, v_ref, rtol=1e-10, atol=1e-12)
        assert v2_f == pytest.approx(v2, rel=1e-10)
        np.testing.assert_allclose(jacobian_f, jacobian, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(object_jacobian_f, object_jacobian, rtol=1e-12, atol=1e-9)
        assert fused_output.storage == pytest.approx(output.storage, rel=1e-10)
        np.testing.assert_allclose(fused_output.null_space, output.null_space, atol=1e-12)
    assert np.linalg.norm(output.null_space) > 1e-3  # the objectives really acted


# ------------------------------------------------- the plant on the controller's Pinocchio terms
def test_the_plant_shares_the_controllers_terms_only_when_the_models_are_equal():
    """Equal models share; any model error (or another engine) does not."""
    from pbvs_pin.sim.loop import shares_dynamics

    scenario = load_scenario("experiment1")
    assert shares_dynamics(build(scenario))
    for key in ("model_error.kinematic_scale", "model_error.mass_scale"):
        assert not shares_dynamics(build(scenario.with_values(**{key: 1.1})))


def test_sharing_the_terms_leaves_the_run_bit_identical(monkeypatch):
    """A run with the plant on the controller's terms equals one that computes its own."""
    import pbvs_pin.sim.loop as loop

    scenario = load_scenario("experiment2").with_values(duration=1.0)
    shared = loop.simulate(scenario)
    monkeypatch.setattr(loop, "shares_dynamics", lambda setup: False)
    own = loop.simulate(scenario)
    for name in ("q", "v", "v_ref", "u", "xi"):
        np.testing.assert_array_equal(shared[name], own[name])


def test_terms_are_given_only_for_the_very_arrays_the_step_ran_on():
    """A measured copy of q (a sensing layer's) never gets the controller's terms."""
    from pbvs_pin.control.step import FusedControlStep

    setup = build(load_scenario("experiment1").with_values(**NO_LATENCY))
    perception = Perception(setup)
    q, v = setup.plant.q, setup.plant.v
    setup.sensor.capture(0.0, setup.robot.camera_pose(q), setup.target.centres(0.0), q)
    perception.take(setup.sensor.deliver(0.0))
    fused = FusedControlStep(
        setup.model, setup.features, setup.xi_d, setup.controller, setup.compensator,
        setup.objectives,
    )  # fmt: skip
    assert fused.terms_at(q, v) is None
    fused.step(q, v, perception.measurement, np.zeros(3), np.array([np.inf, 0.0]), 1e-3)
    assert fused.terms_at(q.copy(), v) is None and fused.terms_at(q, v.copy()) is None
    mass, _, _ = fused.terms_at(q, v)
    np.testing.assert_array_equal(mass, pin.crba(setup.model.model, setup.model.data, q))
    fused.restart_derivative()
    assert fused.terms_at(q, v) is None
