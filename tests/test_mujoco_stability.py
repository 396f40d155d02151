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


@pytest.mark.parametrize("name", ["pioneer_panda", "pioneer_ur5e"])
def test_an_arm_that_carries_the_centre_of_mass_past_the_wheels_tips_the_robot(name):
    robot = _zoo_robot(name)
    q = robot.home()
    centre = pin.centerOfMass(robot.model, robot.data, q)  # the drive axle at the origin
    with pytest.warns(PbvsWarning, match="tips over on the MuJoCo plant"):
        plant = MujocoPlant(robot, ServoModel.from_robot(robot), q)
    assert centre[0] > PIONEER_HALF_WHEELBASE
    assert support_margin(plant.model, plant.data) == pytest.approx(
        PIONEER_HALF_WHEELBASE - centre[0], abs=0.005
    )
    assert _tilt_after(plant, 1.0) > 20.0


def test_the_reference_robot_stands():
    robot = load_robot("pioneer_cyton")
    with warnings.catch_warnings():
        warnings.simplefilter("error", PbvsWarning)
        plant = MujocoPlant(robot, ServoModel.from_robot(robot), robot.home())
    centre = pin.centerOfMass(robot.model, robot.data, robot.home())
    assert support_margin(plant.model, plant.data) == pytest.approx(
        PIONEER_HALF_WHEELBASE - abs(centre[0]), abs=0.005
    )
    assert _tilt_after(plant, 1.0) < 0.5
