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

from pbvs_pin import load_robot
from pbvs_pin.control.secondary import SecondaryInput
from pbvs_pin.control.support import KeepSupported
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


def _reaching(robot) -> np.ndarray:
    """The home with the shoulder lift turned forward until the centre of mass is past the
    margin by 2 cm (but inside the support)."""
    q = robot.home()
    joint = robot.arm_q_indices[1]
    rows = SupportRows(robot, robot.support, COM_MARGIN)
    for _ in range(400):
        if rows.slack(at_origin(q))[0].min() < -0.02:
            return q
        q[joint] += 0.005 * np.sign(robot.home()[joint] or -1.0)
    raise AssertionError("no posture past the margin")


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
