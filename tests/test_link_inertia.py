"""Links without ``<inertial>`` given the inertia of their geometry (``geometry_density``).

References are closed forms: a solid box's mass ``rho a b c`` and moments ``m (b^2 + c^2) / 12``
..., a solid sphere's ``2 m r^2 / 5``, and the parallel-axis theorem for parts away from their
common centre of mass. The KUKA iiwa 14 of rtb-data (no ``<inertial>`` anywhere) is the
third-party case: without the key its servos are refused with an error naming the key; with
it, it runs.
"""

from __future__ import annotations

import io
import warnings

import numpy as np
import pytest
import yourdfpy

from pbvs_pin import MobileManipulator, UrdfError
from pbvs_pin.model.link_inertia import fill_missing_inertias
from pbvs_pin.model.servo import ServoModel

DENSITY = 1000.0  # [kg/m^3]
BOX = (0.1, 0.2, 0.3)  # [m]
IIWA = "package://rtbdata/xacro/kuka_description/kuka_lbr_iiwa/urdf/lbr_iiwa_14_r820.urdf"


def _robot(geometry: str, inertial: str = "") -> yourdfpy.Robot:
    """A one-link URDF with the given collision geometry (and inertial)."""
    xml = f'<robot name="r"><link name="a">{inertial}{geometry}</link></robot>'
    return yourdfpy.URDF.load(io.StringIO(xml), build_scene_graph=False, load_meshes=False).robot


def _collision(shape: str, xyz: str = "0 0 0") -> str:
    return f'<collision><origin xyz="{xyz}"/><geometry>{shape}</geometry></collision>'


def test_a_box_gets_its_mass_centre_and_moments():
    robot = _robot(_collision(f'<box size="{" ".join(map(str, BOX))}"/>', "0.1 -0.2 0.3"))
    assert fill_missing_inertias(robot, DENSITY, "box.urdf") == ["a"]
    inertial = robot.links[0].inertial
    a, b, c = BOX
    mass = DENSITY * a * b * c
    assert inertial.mass == pytest.approx(mass, rel=1e-12)
    np.testing.assert_allclose(inertial.origin[:3, 3], [0.1, -0.2, 0.3], atol=1e-12)
    moments = mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    np.testing.assert_allclose(inertial.inertia, np.diag(moments), rtol=1e-9, atol=1e-15)


def test_two_parts_add_up_about_their_common_centre():
    """A box at the origin and a sphere 0.4 m along x: parallel-axis theorem by hand."""
    radius = 0.05
    geometry = _collision(f'<box size="{" ".join(map(str, BOX))}"/>') + _collision(
        f'<sphere radius="{radius}"/>', "0.4 0 0"
    )
    robot = _robot(geometry)
    fill_missing_inertias(robot, DENSITY, "two.urdf")
    inertial = robot.links[0].inertial
    a, b, c = BOX
    m_box, m_ball = DENSITY * a * b * c, DENSITY * 4 / 3 * np.pi * radius**3
    mass = m_box + m_ball
    centre = m_ball * 0.4 / mass  # along x
    assert inertial.mass == pytest.approx(mass, rel=1e-9)
    np.testing.assert_allclose(inertial.origin[:3, 3], [centre, 0, 0], atol=1e-12)
    ball = 2 / 5 * m_ball * radius**2
    box = m_box / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    shift = m_box * centre**2 + m_ball * (0.4 - centre) ** 2  # about y and z, not x
    expected = np.diag(box + ball + np.array([0.0, shift, shift]))
    np.testing.assert_allclose(inertial.inertia, expected, rtol=1e-9, atol=1e-15)


def test_a_link_with_its_own_inertial_or_without_geometry_is_left_alone():
    own = (
        '<inertial><mass value="2.0"/>'
        '<inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>'
    )
    robot = _robot(_collision('<box size="1 1 1"/>'), own)
    assert fill_missing_inertias(robot, DENSITY, "own.urdf") == []
    assert robot.links[0].inertial.mass == 2.0
    bare = _robot("")
    assert fill_missing_inertias(bare, DENSITY, "bare.urdf") == []
    assert bare.links[0].inertial is None


def test_an_unreadable_mesh_is_named(tmp_path):
    broken = tmp_path / "broken.stl"
    broken.write_text("not a mesh")
    robot = _robot(_collision(f'<mesh filename="{broken}"/>'))
    with pytest.raises(UrdfError, match=r"link 'a'.*broken\.stl.*geometry_density"):
        fill_missing_inertias(robot, DENSITY, "mesh.urdf")


def _iiwa(**keys: float) -> MobileManipulator:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the arm's base link inside the platform's box
        return MobileManipulator.assemble(
            "pioneer3at", IIWA, (0.10, 0.0, 0.27, 0.0, 0.0, 0.0), "tool0", **keys
        )


def test_an_arm_without_inertias_is_refused_naming_the_key_then_runs_with_it():
    with pytest.raises(UrdfError, match=r"move no mass.*geometry_density = 1000\.0"):
        ServoModel.from_robot(_iiwa())
    robot = _iiwa(geometry_density=DENSITY)
    assert robot.filled_inertias == (
        "arm_base_link", "link_1", "link_2", "link_3", "link_4", "link_5", "link_6", "link_7",
    )  # fmt: skip
    arm_mass = sum(robot.model.inertias[j].mass for j in range(2, robot.model.njoints))
    assert 15.0 < arm_mass < 20.0  # links 1-7 from their closed collision meshes: 17.7 kg
    ServoModel.from_robot(robot)  # every joint now moves mass


def test_the_zoo_page_states_the_iiwa_mass_its_file_gets():
    from conftest import REPO_ROOT

    from pbvs_pin.model.assembly import load_urdf

    source = load_urdf(IIWA, geometry_density=DENSITY)
    total = sum(link.inertial.mass for link in source.robot.links if link.inertial is not None)
    assert len(source.filled_inertias) == 8
    page = " ".join((REPO_ROOT / "docs" / "zoo.rst").read_text().split())
    assert f"({total:.1f} kg for the base and seven links)" in page
    assert "geometry_density = 1000.0" in (REPO_ROOT / "robots" / "pioneer_iiwa14.toml").read_text()


def test_a_run_lists_the_links_that_got_an_inertia_in_its_meta():
    from conftest import REPO_ROOT

    from pbvs_pin.sim.loop import simulate
    from pbvs_pin.sim.scenario import load_scenario
    from pbvs_pin.study.zoo import load_zoo

    iiwa = next(robot for robot in load_zoo(REPO_ROOT / "robots") if robot.name == "pioneer_iiwa14")
    values = iiwa.scenario_values
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the arm's base link inside the platform's box
        log = simulate(load_scenario("experiment1").with_values(**values, duration=0.2))
    assert log.meta["inertia_from_geometry"][1:] == [f"link_{i}" for i in range(1, 8)]
    assert log.meta["inertia_repaired"] == []
