"""A user's own secondary objective plugs into the Controller and simulate(), in closed loop.

The objective below is written as a user would, from the public names only: it pulls the arm's
first joint (the Cyton's shoulder pan) to a chosen angle through ``Lambda`` (eq. 16), so the
null space of eq. (34) turns the joint while the image error stays bounded. The reference for
"it acted" is the same run without it, where the joint stays near its home.
"""

from __future__ import annotations

import numpy as np
import pytest

import pbvs_pin
from pbvs_pin.exceptions import WrongType

PAN_TARGET = 0.4
"""Where the objective pulls the shoulder pan [rad] (home 0; 0.13 at the end without it)."""


class PanTo(pbvs_pin.SecondaryObjective):
    """``Lambda_pan = gain (target - theta_pan)``; zero in every other velocity."""

    def __init__(self, target: float, gain: float = 5.0) -> None:
        self.target, self.gain = target, gain
        self.calls = 0

    def contribution(self, state: pbvs_pin.SecondaryInput, n_base: int, n: int) -> np.ndarray:
        self.calls += 1
        out = np.zeros(n)
        out[n_base] = self.gain * (self.target - state.arm_positions[0])
        return out


class WrongLength(pbvs_pin.SecondaryObjective):
    """Returns one entry too many."""

    def contribution(self, state: pbvs_pin.SecondaryInput, n_base: int, n: int) -> np.ndarray:
        return np.zeros(n + 1)


@pytest.fixture(scope="module")
def runs():
    """Experiment 1 (30 s) on the reference robot, without and with the objective."""
    scenario = pbvs_pin.load_scenario("experiment1")
    objective = PanTo(PAN_TARGET)
    plain = pbvs_pin.simulate(scenario)
    pulled = pbvs_pin.simulate(scenario, objectives=[objective])
    return plain, pulled, objective


def _final_window(log: pbvs_pin.RunLog, seconds: float = 5.0) -> np.ndarray:
    return log["t"] >= log["t"][-1] - seconds


def test_the_objective_turns_the_joint_in_closed_loop(runs):
    plain, pulled, objective = runs
    window = _final_window(pulled)
    assert objective.calls > 1000  # evaluated at the control rate, seen steps included
    assert abs(np.mean(pulled["arm"][window, 0]) - PAN_TARGET) < 0.05
    assert abs(np.mean(plain["arm"][_final_window(plain), 0]) - PAN_TARGET) > 0.2


def test_the_image_error_stays_within_experiment_1s_rule_with_it(runs):
    _, pulled, _ = runs
    error = np.abs(pulled["xi_true"] - pulled["xi_d"])[_final_window(pulled)]
    assert np.max(error) < 8.0  # the rule of Experiment 1 (report's claims)
    assert not np.any(pulled["target_lost"])


def test_the_controller_takes_it_and_keeps_it_through_reset():
    robot = pbvs_pin.load_robot("pioneer_cyton")
    objective = PanTo(PAN_TARGET)
    controller = pbvs_pin.Controller(robot, announce=False, objectives=[objective])
    assert controller.user_objectives == (objective,)
    assert controller.objectives[-1] is objective
    controller.reset()
    assert controller.objectives[-1] is objective


def test_a_wrong_shape_is_refused_naming_the_objective():
    robot = pbvs_pin.load_robot("pioneer_cyton")
    with pytest.raises(pbvs_pin.ShapeError, match=r"WrongLength\.contribution"):
        pbvs_pin.Controller(robot, announce=False, objectives=[WrongLength()])


@pytest.mark.parametrize(
    ("given", "named"),
    [(PanTo(0.0), "objectives"), ([PanTo(0.0), "posture"], r"objectives\[1\]")],
)
def test_what_is_not_a_list_of_objectives_is_refused(given, named):
    robot = pbvs_pin.load_robot("pioneer_cyton")
    with pytest.raises(WrongType, match=named):
        pbvs_pin.Controller(robot, announce=False, objectives=given)
