"""The control loop hands the controller the same J and J_o as the model layer computes."""

import numpy as np

from pbvs_pin.sim.loop import Perception, _control_step, build
from pbvs_pin.sim.scenario import load_scenario


def test_loop_jacobians_match_the_feature_set_at_the_current_configuration():
    setup = build(load_scenario("experiment1"))
    perception = Perception(setup)
    q0 = setup.plant.q
    setup.sensor.capture(0.0, setup.robot.camera_pose(q0), setup.target.centres(0.0), q0)
    perception.take(setup.sensor.deliver(0.0))
    # A configuration other than the one the frame was captured at, so a stale camera
    # placement in pin.Data would give a different J_o.
    q = setup.model.integrate(q0, np.array([0.2, 0.5, 0.4, -0.3, 0.2]), 1.0)
    _, (jacobian, object_jacobian) = _control_step(
        setup, perception, q, (np.inf, 0.0), 0.0, 0.01
    )
    measurement = perception.measurement
    rotation = setup.model.camera_pose(q).rotation
    expected_j = setup.features.interaction_matrix(setup.model.camera, measurement) @ (
        setup.model.camera_jacobian(q)
    )
    expected_jo = setup.features.object_jacobian(setup.model.camera, measurement, rotation.T)
    np.testing.assert_allclose(jacobian, expected_j, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(object_jacobian, expected_jo, rtol=1e-12, atol=1e-9)
