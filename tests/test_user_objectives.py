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
from pbvs_pin.control.secondary import ArmPosture
from pbvs_pin.exceptions import WrongType

CONTROL_STEPS = 3000
"""Control steps of Experiment 1: 30 s at the default 100 Hz."""

PAN_TARGET = 0.6
"""Where the objective pulls the shoulder pan [rad] (home 0; 0.24 at the end without it)."""


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


class ArmPostureProbe(ArmPosture):
    """The built-in posture objective (a frozen dataclass), counting its calls."""

    calls = 0

    def contribution(self, state: pbvs_pin.SecondaryInput, n_base: int, n: int) -> np.ndarray:
        object.__setattr__(self, "calls", self.calls + 1)
        return super().contribution(state, n_base, n)


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
    assert objective.calls == CONTROL_STEPS  # once a step, seen or not; never at the build
    assert abs(np.mean(pulled["arm"][window, 0]) - PAN_TARGET) < 0.05
    assert abs(np.mean(plain["arm"][_final_window(plain), 0]) - PAN_TARGET) > 0.2
    assert pulled.meta["user_objectives"] == ["PanTo"] and plain.meta["user_objectives"] == []


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


class NotANumber(pbvs_pin.SecondaryObjective):
    """Returns NaN in every velocity."""

    def contribution(self, state: pbvs_pin.SecondaryInput, n_base: int, n: int) -> np.ndarray:
        return np.full(n, np.nan)


def _first_step(controller: pbvs_pin.Controller) -> pbvs_pin.ServoCommand:
    """One step at home with the target seen straight ahead."""
    robot = controller.model
    frame = pbvs_pin.CameraFrame.seen(0.0, np.array([[0.0, 30.0], [0.0, -30.0]]), np.ones(2))
    return controller.step(0.0, robot.home(), np.zeros(robot.n), frame, laser=(1.0, 0.0),
                           target_velocity=np.zeros(3))  # fmt: skip


@pytest.mark.parametrize(
    ("objective", "error", "named"),
    [(WrongLength(), pbvs_pin.ShapeError, r"WrongLength\.contribution"),
     (NotANumber(), pbvs_pin.NonFiniteValue, r"NotANumber\.contribution")],
)  # fmt: skip
def test_a_wrong_contribution_is_refused_naming_the_objective(objective, error, named):
    robot = pbvs_pin.load_robot("pioneer_cyton")
    controller = pbvs_pin.Controller(robot, announce=False, objectives=[objective])
    with pytest.raises(error, match=named):
        _first_step(controller)


def test_building_the_controller_does_not_call_them():
    objective = PanTo(PAN_TARGET)
    pbvs_pin.Controller(pbvs_pin.load_robot("pioneer_cyton"), announce=False,
                        objectives=[objective])  # fmt: skip
    assert objective.calls == 0


def test_one_of_a_built_in_kind_given_by_the_user_is_evaluated_as_the_users():
    """An ArmPosture given as a user objective: the compiled step stays, and evaluates it in
    Python once a step."""
    robot = pbvs_pin.load_robot("pioneer_cyton")
    target = robot.home_arm + 0.2
    users = ArmPostureProbe(target, gain=1.0)
    controller = pbvs_pin.Controller(robot, announce=False, objectives=[users])
    assert controller.fused is not None and controller.fused.user_objectives[-1:] == (users,)
    command = _first_step(controller)
    assert users.calls == 1
    assert np.all(np.isfinite(command.v_ref))


@pytest.mark.parametrize(
    ("given", "named"),
    [(PanTo(0.0), "objectives"), ([PanTo(0.0), "posture"], r"objectives\[1\]")],
)
def test_what_is_not_a_list_of_objectives_is_refused(given, named):
    robot = pbvs_pin.load_robot("pioneer_cyton")
    with pytest.raises(WrongType, match=named):
        pbvs_pin.Controller(robot, announce=False, objectives=given)
