"""The controller hands its law the same J and J_o as the model layer; its compiled step agrees
with the modular reference (seen, lost beside an obstacle, and the IBVS baseline)."""

import numpy as np
import pytest
from conftest import REPO_ROOT
from simhelpers import controller_with_first_frame, past_the_margin

from pbvs_pin import CameraFrame
from pbvs_pin.control import layout
from pbvs_pin.control.secondary import ObstacleAvoidance, secondary_input
from pbvs_pin.control.support import KeepSupported
from pbvs_pin.model.support import COM_MARGIN, SupportRows, at_origin
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.setup import build
from pbvs_pin.study.experiments import with_robot

NO_LATENCY = {"camera.latency": 0.0, "estimator.predict": False}
"""Frames servoed on as they are (the shipped experiments predict each one forward to the
configuration now), so that the measurement is the frame's."""


def test_loop_jacobians_match_the_feature_set_at_the_current_configuration():
    setup, control = controller_with_first_frame(
        load_scenario("experiment1").with_values(**NO_LATENCY)
    )
    # A configuration other than the one the frame was captured at, so a stale camera
    # placement in pin.Data would give a different J_o.
    q = setup.model.integrate(setup.plant.q, np.array([0.2, 0.5, 0.4, -0.3, 0.2]), 1.0)
    control.step(1.0, q, np.zeros(5), target_velocity=np.zeros(3))
    _, (jacobian, object_jacobian) = control.diagnostics()
    measurement = control.tracker.measurement
    rotation = setup.model.camera_pose(q).rotation
    expected_j = setup.features.interaction_matrix(setup.model.camera, measurement) @ (
        setup.model.camera_jacobian(q)
    )
    expected_jo = setup.features.object_jacobian(setup.model.camera, measurement, rotation.T)
    np.testing.assert_allclose(jacobian, expected_j, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(object_jacobian, expected_jo, rtol=1e-12, atol=1e-9)


def _paths_agree(scenario, laser, predict, start=None, prepare=None):
    """Step the modular classes and the compiled step side by side; both give the same.

    ``start``: the configuration the steps wander from (None: the plant's); ``prepare(modular,
    fused)`` is called before the steps.
    """
    modular_setup, modular = controller_with_first_frame(scenario, modular=True)
    _, fused = controller_with_first_frame(scenario)
    assert getattr(modular, "reference", False) and not hasattr(fused, "reference")
    if prepare is not None:
        prepare(modular, fused)
    rng = np.random.default_rng(3)
    q = modular_setup.plant.q if start is None else start
    for step in range(1, 4):  # several steps: the command derivative and impedance have memory
        q = modular.model.integrate(q, rng.uniform(-0.05, 0.05, modular.model.n), 1.0)
        v = rng.uniform(-0.2, 0.2, modular.model.n)
        target_velocity = rng.uniform(-0.1, 0.1, 3)
        commands = [
            c.step(0.1 * step, q, v, laser=laser, target_velocity=target_velocity)
            for c in (modular, fused)
        ]
        (output, (jacobian, object_jacobian)), (fused_output, (jacobian_f, object_jacobian_f)) = (
            modular.diagnostics(),
            fused.diagnostics(),
        )
        np.testing.assert_allclose(commands[1].u, commands[0].u, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(commands[1].v_ref, commands[0].v_ref, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(commands[1].error, commands[0].error, rtol=1e-12, atol=1e-9)
        assert commands[1].v2 == pytest.approx(commands[0].v2, rel=1e-10)
        np.testing.assert_allclose(jacobian_f, jacobian, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(object_jacobian_f, object_jacobian, rtol=1e-12, atol=1e-9)
        assert fused_output.storage == pytest.approx(output.storage, rel=1e-10)
        np.testing.assert_allclose(fused_output.null_space, output.null_space, atol=1e-12)
        assert commands[0].predicting == predict
    assert np.linalg.norm(output.null_space) > 1e-3  # the objectives really acted
    return modular


@pytest.mark.parametrize("predict", [False, True])
def test_fused_step_equals_the_modular_blocks(predict):
    """The compiled step gives what the modular classes give, prediction on or off."""
    # posture, joint limits and obstacle avoidance on; an obstacle inside d0, to the right
    scenario = load_scenario("experiment2").with_values(
        **{**NO_LATENCY, "estimator.predict": predict}
    )
    _paths_agree(scenario, (0.6, 0.3), predict)


def test_fused_step_equals_the_modular_blocks_on_a_holonomic_base_near_dead_ahead():
    """TIAGo Pro's holonomic base, an obstacle 0.05 rad right of dead ahead: inside the turn's
    ramp (``TURN_RAMP``), where a flag lost on either path would show."""
    scenario = with_robot(
        load_scenario("experiment2"), REPO_ROOT / "robots" / "tiago_pro.toml"
    ).with_values(**NO_LATENCY)
    modular = _paths_agree(scenario, (0.6, 0.05), False)
    assert modular.model.n_base == 3
    # The turn the modular avoidance took is the ramp's half, not the paper's whole.
    avoidance = next(o for o in modular.objectives if isinstance(o, ObstacleAvoidance))
    ramp, paper = avoidance.force(0.6, 0.05, holonomic=True), avoidance.force(0.6, 0.05)
    assert ramp[1] == pytest.approx(0.5 * paper[1])


def test_the_support_objective_in_the_compiled_step_equals_its_reference_at_the_edge():
    """The UR5 on the Pioneer reaching 0.06 m past the support's margin, with a posture target
    whose way back runs over the edge and an obstacle between d0 and 1.5 d0: the support
    objective's push and its platform turn (both acting, checked on the reference) come out of
    the compiled step as out of ``KeepSupported.contribution`` with its own ``pin.Data``."""
    scenario = load_scenario("experiment2").with_values(
        **{**NO_LATENCY, "robot.name": "pioneer_ur5"}
    )
    robot = build(scenario).model
    start = past_the_margin(robot, COM_MARGIN, 0.06)
    rows = SupportRows(robot, robot.support, COM_MARGIN)
    slack, gradient = rows.slack(at_origin(start))
    over = gradient[slack.argmin()]
    target = robot.arm_positions(start) - 0.3 * over / np.linalg.norm(over)  # (19) pulls over
    acted = []

    def prepare(modular, fused) -> None:
        support = next(o for o in modular.objectives if isinstance(o, KeepSupported))
        assert support.turns(robot.n_base)
        support.target = target
        layout.parameter_views(fused.fused.params, fused.fused.indices).support_target[:] = target
        acted.append(support)

    d0 = next(o for o in build(scenario).control.objectives if isinstance(o, KeepSupported)).d0
    assert d0 > 0.0
    laser = (1.25 * d0, 0.4)
    modular = _paths_agree(scenario, laser, False, start=start, prepare=prepare)
    assert acted[0].barrier(start, robot.n)[0] > 0.0  # past the kept distance: it must act
    state = secondary_input(robot, start, np.array(laser), 1e-3, robot.camera_pose(start).rotation)
    push = acted[0].contribution(state, robot.n_base, robot.n)
    assert np.linalg.norm(push[robot.n_base :]) > 0.1  # the arm is pushed back
    assert abs(push[robot.n_base - 1]) > 1e-3  # and the platform turns
    assert modular.model.n_base == 2


def test_the_ibvs_baseline_runs_in_the_compiled_step_as_its_modular_reference():
    """``controller.law = "ibvs"``: the compiled step's feedback ``lambda J# e`` with the same
    objectives, upright row and stops as the reference (``ClassicIbvs``, that is
    ``PassivityController.step`` with the IBVS code; ``test_control.py`` checks the law itself
    by hand)."""
    scenario = load_scenario("experiment2").with_values(
        **{**NO_LATENCY, "controller.law": "ibvs", "controller.ibvs_gain": 0.4}
    )
    modular = _paths_agree(scenario, (0.6, 0.3), False)
    assert type(modular.law).__name__ == "ClassicIbvs"


def test_a_target_loss_next_to_an_obstacle_keeps_one_state():
    """Seen, then lost for 0.3 s beside an obstacle inside d0, then seen again: the compiled
    step's obstacle impedance goes on stepping through the loss exactly as the modular
    objective's own state does, the lost steps brake a zero command, and the command after the
    loss (its derivative restarted) equals the reference's."""
    scenario = load_scenario("experiment2").with_values(**{**NO_LATENCY, "estimator.hold": 0.0})
    setup, modular = controller_with_first_frame(scenario, modular=True)
    _, fused = controller_with_first_frame(scenario)
    avoidance = next(o for o in modular.objectives if isinstance(o, ObstacleAvoidance))
    camera, rng, q = setup.model.camera, np.random.default_rng(11), setup.plant.q
    impedance_at_loss = None
    for step in range(1, 13):
        t = 0.1 * step
        q = setup.model.integrate(q, rng.uniform(-0.02, 0.02, setup.model.n), 1.0)
        v = rng.uniform(-0.2, 0.2, setup.model.n)
        lost = 4 <= step <= 6
        frame = (
            CameraFrame.not_visible(t)
            if lost
            else CameraFrame.seen(
                t, *camera.project_world(setup.model.camera_pose(q), setup.target.centres(t))
            )
        )
        laser = (0.5 + 0.02 * step, 0.3)  # inside d0 throughout, moving
        commands = [
            c.step(t, q, v, frame, laser=laser, target_velocity=np.zeros(3))
            for c in (modular, fused)
        ]
        assert commands[0].seen == commands[1].seen == (not lost)
        np.testing.assert_allclose(commands[1].v_ref, commands[0].v_ref, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(commands[1].u, commands[0].u, rtol=1e-10, atol=1e-12)
        impedance = fused.fused.views.impedance_velocity
        np.testing.assert_allclose(impedance, avoidance.velocity, rtol=1e-12, atol=1e-15)
        if lost:
            np.testing.assert_array_equal(commands[1].u, 0.0)
            assert np.isnan(commands[1].error).all()
            commands[1].error[:] = 0.0  # a caller's write reaches no later command
            assert fused.diagnostics()[1] is None and not fused.diagnostics()[0].valid
            if impedance_at_loss is None:
                impedance_at_loss = impedance.copy()
    assert not np.allclose(impedance, impedance_at_loss)  # it stepped through the loss
    assert np.linalg.norm(commands[1].u) > 1e-3
