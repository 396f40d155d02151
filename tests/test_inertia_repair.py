"""Opt-in repair of inertias that break the triangle inequality (issue 22, item 3).

The bad inertia is the reference robot's front-left wheel replaced by principal moments
(1, 2, 10) g m^2, which break I1 + I2 >= I3, turned by a known rotation so that the file holds
off-diagonal terms. MuJoCo's ``balanceinertia`` sets the three principal moments to their
mean: the repaired inertia must be (1 + 2 + 10) / 3 g m^2 times the identity, whatever the
rotation.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import URDF_DIR, rot_x, rot_z

from pbvs_pin import MobileManipulator, UrdfError
from pbvs_pin.exceptions import ScenarioError
from pbvs_pin.model.assembly import load_urdf
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario

WHEEL = "front_left_wheel_link"
WHEEL_INERTIA = (
    '<inertia ixx="0.00218469" ixy="0.0" ixz="0.0" iyy="0.00346687" iyz="0.0" izz="0.00218469"/>'
)
MOMENTS = np.array([0.001, 0.002, 0.010])  # [kg m^2], 0.001 + 0.002 < 0.010
ROTATION = rot_z(0.3) @ rot_x(0.5)
REPAIRED = MOMENTS.sum() / 3.0 * np.eye(3)  # [kg m^2], MuJoCo's balanceinertia


@pytest.fixture
def bad_urdf(tmp_path):
    """The reference robot with the wheel's inertia replaced by the bad one."""
    inertia = ROTATION @ np.diag(MOMENTS) @ ROTATION.T
    names = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    values = (inertia[0, 0], inertia[0, 1], inertia[0, 2], inertia[1, 1], inertia[1, 2],
              inertia[2, 2])  # fmt: skip
    element = "<inertia " + " ".join(
        f'{n}="{float(v)!r}"' for n, v in zip(names, values, strict=True)
    )
    text = (URDF_DIR / "pioneer_cyton.urdf").read_text()
    assert WHEEL_INERTIA in text
    path = tmp_path / "bad_inertia.urdf"
    path.write_text(text.replace(WHEEL_INERTIA, element + "/>", 1))
    return path


def test_refusal_names_the_repair_key(bad_urdf):
    with pytest.raises(UrdfError, match="triangle inequality") as err:
        MobileManipulator.from_urdf(str(bad_urdf))
    assert "repair_inertia = true" in str(err.value)
    assert WHEEL in str(err.value)


def test_repair_sets_every_principal_moment_to_their_mean(bad_urdf):
    source = load_urdf(bad_urdf, repair_inertia=True)
    wheel = next(link for link in source.robot.links if link.name == WHEEL)
    assert np.allclose(wheel.inertial.inertia, REPAIRED, rtol=1e-12, atol=1e-15)
    assert source.repaired_inertias == (WHEEL,)
    others = [link for link in source.robot.links if link.name != WHEEL and link.inertial]
    original = {link.name: link.inertial.inertia for link in load_urdf(URDF_DIR /
                "pioneer_cyton.urdf").robot.links if link.inertial}  # fmt: skip
    assert all(np.array_equal(link.inertial.inertia, original[link.name]) for link in others)


def test_a_valid_urdf_is_not_repaired():
    robot = MobileManipulator.from_urdf(str(URDF_DIR / "pioneer_cyton.urdf"), repair_inertia=True)
    assert robot.repaired_inertias == ()


def test_scenario_key_repairs_and_the_run_meta_names_the_links(bad_urdf):
    values = {"robot.name": "", "robot.urdf": str(bad_urdf),
              "robot.camera_frame": "camera_optical_frame", "duration": 0.2}  # fmt: skip
    with pytest.raises(ScenarioError, match="repair_inertia"):
        load_scenario("experiment1").with_values(**values).robot.build()
    log = simulate(load_scenario("experiment1").with_values(**values, **{"robot.repair_inertia":
                                                                          True}))  # fmt: skip
    assert log.meta["inertia_repaired"] == [WHEEL]
