"""The support objective: the centre of mass's rows against Pinocchio by hand, and its rate.

References written here: the Pioneer's support is an axis-aligned rectangle, so each row is a
plain difference of coordinates (no normals); Pinocchio's ``centerOfMass`` at perturbed
postures gives the rows' Jacobian and the rate at which the objective's arm motion closes the
shortfall. The closed loop (the UR5 kept standing on MuJoCo) is in
``tests/test_mujoco_acceptance.py``.
"""

import numpy as np
import pinocchio as pin
import pytest
from simhelpers import past_the_margin

from pbvs_pin import load_robot
from pbvs_pin.control.secondary import SecondaryInput
from pbvs_pin.control.support import (
    BARRIER_RATE,
    EDGE_KEPT,
    EDGE_RAMP,
    EDGE_TURN,
    KeepSupported,
    keep_inside,
)
from pbvs_pin.exceptions import GainError
from pbvs_pin.model.support import COM_MARGIN, SupportRows, at_origin

STEP = 1e-6  # [rad] finite-difference step


@pytest.fixture(scope="module")
def ur5():
    return load_robot("pioneer_ur5")


def _centre(robot, q) -> np.ndarray:
    """Pinocchio's centre of mass, platform at the origin. Shape (2,)."""
    return pin.centerOfMass(robot.model, robot.model.createData(), at_origin(q))[:2].copy()


def _rows_by_hand(robot, q, margin) -> np.ndarray:
    """Distance to each side of the axis-aligned support rectangle, less the margin."""
    (x0, y0), (x1, y1) = robot.support.min(axis=0), robot.support.max(axis=0)
    cx, cy = _centre(robot, q)
    return np.sort([cx - x0, x1 - cx, cy - y0, y1 - cy]) - margin


def _reaching(robot, margin: float = COM_MARGIN, past: float = 0.02) -> np.ndarray:
    """The home with the shoulder lift turned until the centre of mass is ``past`` [m] past
    ``margin`` (with the default margin, inside the support)."""
    return past_the_margin(robot, margin, past)


def test_the_pioneers_support_is_a_rectangle_around_its_axles(ur5):
    xs, ys = np.unique(ur5.support[:, 0].round(9)), np.unique(ur5.support[:, 1].round(9))
    assert len(ur5.support) == 4 and len(xs) == 2 and len(ys) == 2
    np.testing.assert_allclose(xs, [-0.134, 0.134], atol=1e-3)  # the wheels' contact lines


def test_rows_are_the_distances_to_the_sides_by_hand(ur5):
    for q in (ur5.home(), _reaching(ur5)):
        slack, _ = SupportRows(ur5, ur5.support, COM_MARGIN).slack(at_origin(q))
        np.testing.assert_allclose(np.sort(slack), _rows_by_hand(ur5, q, COM_MARGIN), atol=1e-12)


def test_the_rows_jacobian_is_the_centre_of_mass_by_finite_differences(ur5):
    q = _reaching(ur5)
    rows = SupportRows(ur5, ur5.support, COM_MARGIN)
    slack, jacobian = rows.slack(at_origin(q))
    for column, index in enumerate(ur5.arm_q_indices):
        moved = q.copy()
        moved[index] += STEP
        expected = (rows.normals @ _centre(ur5, moved) - rows.offsets - slack) / STEP
        np.testing.assert_allclose(jacobian[:, column], expected, atol=1e-5)


def test_the_objective_closes_the_shortfall_at_its_rate(ur5):
    """``ds/dt = g . theta_dot = k_s (-s)`` along the arm motion it asks for."""
    q = _reaching(ur5)
    objective = KeepSupported(ur5, ur5.support, gain=10.0)
    state = SecondaryInput(ur5.home_arm, np.inf, 0.0, 0.01, None, q)
    rate = objective.contribution(state, ur5.n_base, ur5.n)
    assert np.all(rate[: ur5.n_base] == 0.0)
    shortfall = -_rows_by_hand(ur5, q, COM_MARGIN)[0]
    assert shortfall > 0.02
    moved = q.copy()
    moved[ur5.arm_q_indices] += STEP * rate[ur5.n_base :]
    closing = (_rows_by_hand(ur5, moved, COM_MARGIN)[0] + shortfall) / STEP
    assert closing == pytest.approx(10.0 * shortfall, rel=1e-3)


def test_nothing_while_the_centre_of_mass_keeps_its_margin():
    robot = load_robot("pioneer_cyton")  # a light arm: far inside at home
    assert _rows_by_hand(robot, robot.home(), COM_MARGIN)[0] > 0.0
    objective = KeepSupported(robot, robot.support)
    state = SecondaryInput(robot.home_arm, np.inf, 0.0, 0.01, None, robot.home())
    assert np.all(objective.contribution(state, robot.n_base, robot.n) == 0.0)


def test_a_holonomic_base_has_no_support_and_no_objective():
    from pbvs_pin.control.settings import ControllerSettings, secondary_objectives
    from pbvs_pin.sim.scenario import load_scenario

    scenario = load_scenario("experiment1")
    robot = load_robot("pioneer_ur5")
    kinds = {type(o) for o in secondary_objectives(
        ControllerSettings.from_scenario(scenario), robot, robot.home_arm)}  # fmt: skip
    assert KeepSupported in kinds
    robot.support = None
    kinds = {type(o) for o in secondary_objectives(
        ControllerSettings.from_scenario(scenario), robot, robot.home_arm)}  # fmt: skip
    assert KeepSupported not in kinds


def test_a_non_positive_gain_is_refused_by_name(ur5):
    with pytest.raises(GainError, match=r"KeepSupported\.gain"):
        KeepSupported(ur5, ur5.support, gain=0.0)


def _looking(yaw: float) -> np.ndarray:
    """``wRc`` of a camera whose optical axis lies level at ``yaw`` [rad] in the world."""
    axis = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    across = np.array([np.sin(yaw), -np.cos(yaw), 0.0])
    return np.column_stack([across, np.cross(axis, across), axis])


def _worst_row_gradient_by_hand(robot, q) -> np.ndarray:
    """d(least row)/d(arm joints) by central differences of the rectangle's rows. Shape (n_arm,)."""
    gradient = []
    for index in robot.arm_q_indices:
        up, down = q.copy(), q.copy()
        up[index] += STEP
        down[index] -= STEP
        rows = _rows_by_hand(robot, up, 0.0)[0], _rows_by_hand(robot, down, 0.0)[0]
        gradient.append((rows[0] - rows[1]) / (2 * STEP))
    return np.array(gradient)


def test_the_platform_turns_at_the_edge_only_while_the_posture_pushes_over_it(ur5):
    """The turn ``min(1, -s / delta) blocked s_d (psi - psi_d)``, all by hand: ``psi`` is the
    camera's yaw (the platform faces +x, the camera looks level), ``blocked`` the cosine between
    the posture's pull and the way over the edge, ``s_d`` the obstacle's share. ``theta_d``
    lies further out than the arm, past the edge, so the objective's margin is 0 (the
    target's) and the arm 1 cm past the edge: half-way up the ramp."""
    q = _reaching(ur5, margin=0.0, past=0.01)
    theta = q[ur5.arm_q_indices]
    pull = np.zeros(ur5.n_arm)  # theta_d - theta: the shoulder further forward
    pull[1] = theta[1] - ur5.home_arm[1]
    yaw, offset = 0.4, 0.1
    state = SecondaryInput(theta, np.inf, 0.0, 0.01, _looking(yaw), q)
    shortfall = -_rows_by_hand(ur5, q, 0.0)[0]
    assert 0.01 < shortfall < EDGE_RAMP
    g = _worst_row_gradient_by_hand(ur5, q)
    blocked = -(g @ pull) / (np.linalg.norm(g) * np.linalg.norm(pull))
    assert 0.0 < blocked <= 1.0
    expected = min(1.0, shortfall / EDGE_RAMP) * blocked * (yaw - offset)
    heading = {"heading_gain": 1.0, "heading_offset": offset, "d0": 1.0}
    turning = KeepSupported(ur5, ur5.support, target=theta + pull, **heading)
    rate = turning.contribution(state, ur5.n_base, ur5.n)
    assert rate[ur5.n_base - 1] == pytest.approx(expected, rel=1e-4)
    assert rate[0] == 0.0
    # an obstacle halfway between d0 and 1.5 d0, at any angle: half the turn
    for angle in (0.0, np.pi / 2):
        half = SecondaryInput(theta, 1.25, angle, 0.01, _looking(yaw), q)
        turn = turning.contribution(half, ur5.n_base, ur5.n)[ur5.n_base - 1]
        assert turn == pytest.approx(expected / 2, rel=1e-4)
    # within d0 at any angle, even abeam: the yaw is left to obstacle avoidance
    for angle in (0.0, np.pi / 2, -np.pi / 2):
        near = SecondaryInput(theta, 0.9, angle, 0.01, _looking(yaw), q)
        assert turning.contribution(near, ur5.n_base, ur5.n)[ur5.n_base - 1] == 0.0
    # a continuous pan whose theta_d is a turn away: the same pull, the same turn
    wrapped = KeepSupported(ur5, ur5.support, target=theta + pull, **heading)
    wrapped.continuous = np.array([True] + [False] * (ur5.n_arm - 1))
    wrapped.target = wrapped.target + np.array([2 * np.pi] + [0.0] * (ur5.n_arm - 1))
    turn = wrapped.contribution(state, ur5.n_base, ur5.n)[ur5.n_base - 1]
    assert turn == pytest.approx(expected, rel=1e-4)
    # the posture pulls back inside: the arm can carry it, no turn
    inside = KeepSupported(ur5, ur5.support, target=theta - pull, **heading)
    assert inside.contribution(state, ur5.n_base, ur5.n)[ur5.n_base - 1] == 0.0
    # no heading gain (the default): no turn
    plain = KeepSupported(ur5, ur5.support, target=theta + pull)
    assert plain.contribution(state, ur5.n_base, ur5.n)[ur5.n_base - 1] == 0.0


def test_the_turn_at_the_edge_is_given_where_the_heading_objective_is_off(ur5):
    """A two-wheel base whose arm moves the camera along its axis has no heading objective
    (``heading_factor`` 0): its support objective turns the platform with a share of ``k_psi``,
    from the heading at ``theta_d``; none with ``k_psi = 0`` or without eq. (19)."""
    from dataclasses import replace

    from pbvs_pin.control.secondary import BaseHeading, heading_at
    from pbvs_pin.control.settings import ControllerSettings, secondary_objectives

    def support_of(settings):
        objectives = secondary_objectives(settings, ur5, ur5.home_arm)
        assert not [o for o in objectives if isinstance(o, BaseHeading)]
        [support] = [o for o in objectives if isinstance(o, KeepSupported)]
        return support

    defaults = ControllerSettings()  # the scenarios switch eq. (19) and avoidance on
    on = {"posture": True, "obstacle_avoidance": True}
    settings = replace(defaults, secondary=replace(defaults.secondary, **on))
    assert settings.secondary.k_heading == 1.0 and EDGE_TURN == 0.3
    support = support_of(settings)
    assert support.heading_gain == EDGE_TURN * settings.secondary.k_heading
    assert support.heading_offset == heading_at(ur5, ur5.home_arm)
    assert support.d0 == settings.secondary.d0 > 0.0
    for change in ({"k_heading": 0.0}, {"posture": False}):
        quiet = replace(settings, secondary=replace(settings.secondary, **change))
        assert support_of(quiet).heading_gain == 0.0, change


@pytest.mark.parametrize(
    "values", [{"heading_gain": -1.0}, {"d0": np.nan}, {"heading_offset": np.inf}]
)
def test_a_bad_turn_setting_is_refused_by_name(ur5, values):
    [name] = values
    with pytest.raises(GainError, match=rf"KeepSupported\.{name}"):
        KeepSupported(ur5, ur5.support, **values)


def test_the_barrier_row_is_the_edge_distance_and_gradient_by_hand(ur5):
    """``b = -gamma (d - d_min)`` with ``d`` the rectangle's least distance by hand (at home
    and reaching), and ``g`` by central differences; with a posture target nearer the edge
    than ``d_min``, the target's distance is kept instead."""
    objective = KeepSupported(ur5, ur5.support)
    for q in (ur5.home(), _reaching(ur5, past=0.02)):
        distance = _rows_by_hand(ur5, q, 0.0)[0]
        row = objective.barrier(q, ur5.n)
        assert row[0] == pytest.approx(-BARRIER_RATE * (distance - EDGE_KEPT), abs=1e-10)
    assert 0.0 < distance < COM_MARGIN - 0.02 + 1e-9
    near = _reaching(ur5, past=COM_MARGIN - 0.004)  # 0.004 m inside the edge
    kept = _rows_by_hand(ur5, near, 0.0)[0]
    assert 0.0 < kept < EDGE_KEPT
    targeted = KeepSupported(ur5, ur5.support, target=ur5.arm_positions(near))
    assert targeted.barrier(near, ur5.n)[0] == pytest.approx(0.0, abs=1e-10)
    assert np.all(row[1 : 1 + ur5.n_base] == 0.0)  # the platform does not move the centre
    np.testing.assert_allclose(
        row[1 + ur5.n_base :], _worst_row_gradient_by_hand(ur5, q), atol=1e-6
    )


def test_the_barrier_projects_the_command_onto_its_half_space():
    """Where ``g u < b``, the command moves along ``W^-1 g`` to ``g u = b`` (the smallest move
    in ``W``'s metric: any other move reaching the plane is longer); elsewhere it is kept."""
    rng = np.random.default_rng(5)
    n = 6
    root = rng.normal(size=(n, n))
    weight = root @ root.T + n * np.eye(n)
    weight_inverse = np.linalg.inv(weight)
    g = np.r_[0.0, 0.0, rng.normal(size=n - 2)]
    bound = -0.05
    barrier = np.r_[bound, g]
    command = rng.normal(size=n)
    command -= g * (g @ command - bound + 0.3) / (g @ g)  # 0.3 below the bound
    kept = command.copy()
    assert keep_inside(kept, weight_inverse, barrier)
    assert g @ kept == pytest.approx(bound, abs=1e-12)
    move = kept - command
    for _ in range(20):  # other moves onto the plane are longer in W's metric
        other = move + rng.normal(size=n) * 0.1
        other -= weight_inverse @ g * (g @ other - g @ move) / (g @ weight_inverse @ g)
        assert g @ (command + other) == pytest.approx(bound, abs=1e-12)
        assert other @ weight @ other >= move @ weight @ move - 1e-12
    inside = kept + weight_inverse @ g  # g u > b: nothing to do
    before = inside.copy()
    assert not keep_inside(inside, weight_inverse, barrier)
    np.testing.assert_array_equal(inside, before)
    assert not keep_inside(inside, weight_inverse, np.r_[-np.inf, g])


def test_the_ur10_keeps_its_centre_of_mass_inside_the_kept_distance():
    """The UR10 on the Pioneer, Experiment 2 to 16 s (on MuJoCo it tipped at 12.4 s before the
    barrier; on the Pinocchio plant its centre of mass went 0.020 m past the front edge at
    12.9 s): measured by hand from the log's configurations, the centre of mass stays
    ``d_min`` inside the support, and comes to it (the barrier held it there), with the target
    in view throughout."""
    from conftest import REPO_ROOT

    import pbvs_pin
    from pbvs_pin.study.experiments import with_robot

    scenario = with_robot(
        pbvs_pin.load_scenario("experiment2"), REPO_ROOT / "robots" / "pioneer_ur10.toml"
    ).with_values(duration=16.0)
    log = pbvs_pin.simulate(scenario, progress=False)
    robot = load_robot_of(scenario)
    distances = np.array([_rows_by_hand(robot, q, 0.0)[0] for q in log["q"]])
    assert distances.min() >= EDGE_KEPT - 2e-3
    assert distances.min() <= EDGE_KEPT + 5e-3
    assert np.isfinite(log["xi"][log["t"] > 0.1]).all()  # in view from the first frame on


def load_robot_of(scenario):
    """The scenario's robot model (the plant's, without model error)."""
    from pbvs_pin.sim.setup import build

    return build(scenario).robot


def test_two_support_objectives_and_a_barrier_of_the_wrong_shape_are_refused():
    """The compiled step takes one objective of each kind (GainError naming them); the law's
    reference takes a barrier row of n + 1 entries (ShapeError naming it)."""
    from simhelpers import controller_with_first_frame

    from pbvs_pin.control.step import FusedControlStep
    from pbvs_pin.exceptions import ShapeError
    from pbvs_pin.sim.scenario import load_scenario

    scenario = load_scenario("experiment1").with_values(**{"robot.name": "pioneer_ur5"})
    _, control = controller_with_first_frame(scenario)
    support = next(o for o in control.objectives if isinstance(o, KeepSupported))
    with pytest.raises(GainError, match="KeepSupported, KeepSupported"):
        FusedControlStep(
            control.model, control.features, control.xi_d, control.law, control.compensator,
            [support, support],
        )  # fmt: skip
    n, r = control.model.n, control.features.size
    with pytest.raises(ShapeError, match="barrier"):
        control.law.step(np.zeros(r), np.ones((r, n)), np.zeros((r, 3)), np.zeros(3),
                         np.zeros(n), barrier=np.zeros(n))  # fmt: skip
