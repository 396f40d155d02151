"""The MuJoCo plant's tip-over warning: the zoo's MuJoCo losses on the Pioneer, diagnosed.

References written here: the centre of mass from Pinocchio (``pin.centerOfMass`` of the
controller's model, not MuJoCo's), the Pioneer 3-AT's wheel contacts at +-0.134 m, and the
platform's tilt after 1 s of zero commands.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pbvs_pin import load_robot
from pbvs_pin.exceptions import PbvsWarning
from pbvs_pin.mujoco_plant import MujocoPlant
from pbvs_pin.mujoco_stability import support_margin
from pbvs_pin.servo import ServoModel
from pbvs_pin.sim.sections import RobotSection
from pbvs_pin.zoo import load_zoo

ROBOTS = Path(__file__).resolve().parents[1] / "robots"
PIONEER_HALF_WHEELBASE = 0.134
"""Wheel contacts of the Pioneer 3-AT ahead of and behind its drive axle [m]."""


def _zoo_robot(name: str):
    robot_file = next(robot for robot in load_zoo(ROBOTS) if robot.name == name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # placement warnings
        return RobotSection.from_toml(robot_file.table, str(robot_file.path)).build()


def _tilt_after(plant: MujocoPlant, seconds: float) -> float:
    """The platform's tilt [deg] after ``seconds`` of zero commands."""
    for _ in range(round(seconds / plant.dt)):
        plant.step(np.zeros(plant.robot.n))
    return float(np.degrees(np.arccos(np.clip(plant.data.xmat[1][8], -1.0, 1.0))))


TIPPING = ("pioneer_panda", "baxter_left_pioneer", "pioneer_ur5e", "pioneer_iiwa14")
"""The zoo's robots that tip the Pioneer over on MuJoCo, in docs/zoo.rst's order."""


@pytest.fixture(scope="module")
def tipping():
    """Per robot: Pinocchio's centre of mass at home, the warnings, the margin, the tilt."""
    found = {}
    for name in TIPPING:
        robot = _zoo_robot(name)
        q = robot.home()
        centre = pin.centerOfMass(robot.model, robot.data, q)  # the drive axle at the origin
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", PbvsWarning)
            plant = MujocoPlant(robot, ServoModel.from_robot(robot), q)
        margin = support_margin(plant.data)
        found[name] = (centre, [str(w.message) for w in caught], margin, _tilt_after(plant, 1.0))
    return found


@pytest.mark.parametrize("name", TIPPING)
def test_an_arm_that_carries_the_centre_of_mass_past_the_wheels_tips_the_robot(tipping, name):
    centre, messages, margin, tilt = tipping[name]
    assert any("tips over on the MuJoCo plant" in message for message in messages)
    assert centre[0] > PIONEER_HALF_WHEELBASE
    assert margin == pytest.approx(PIONEER_HALF_WHEELBASE - centre[0], abs=0.005)
    assert tilt > 20.0


def test_the_zoo_page_states_the_tipping_figures(tipping):
    margins = ", ".join(f"{-tipping[name][2]:.3f}" for name in TIPPING[:3])
    tilts = ", ".join(f"{tipping[name][3]:.0f}" for name in TIPPING[:3])
    sentence = (
        f"carry the robot's centre of mass {margins} and {-tipping[TIPPING[3]][2]:.3f} m beyond "
        f"the Pioneer's front wheels (which touch the floor 0.134 m ahead of the axle), and with "
        f"zero commands the platform has tilted by {tilts} and {tipping[TIPPING[3]][3]:.0f} "
        "degrees after 1 s"
    )
    page = " ".join((ROBOTS.parent / "docs" / "zoo.rst").read_text().split())
    assert sentence in page, f"docs/zoo.rst no longer says {sentence!r}: measure again"


def test_the_reference_robot_stands():
    robot = load_robot("pioneer_cyton")
    with warnings.catch_warnings():
        warnings.simplefilter("error", PbvsWarning)
        plant = MujocoPlant(robot, ServoModel.from_robot(robot), robot.home())
    centre = pin.centerOfMass(robot.model, robot.data, robot.home())
    assert support_margin(plant.data) == pytest.approx(
        PIONEER_HALF_WHEELBASE - abs(centre[0]), abs=0.005
    )
    assert _tilt_after(plant, 1.0) < 0.5
