"""Wheels built from the drive keys: Stretch RE1 on the MuJoCo plant.

Stretch's URDF has mesh wheels and no ``<limit velocity>``, so its robot file gives the drive
(``wheel_radius``, ``track``, ``wheel_speed_limit``) and the MuJoCo plant builds the wheels.
References written here: the keys' values in ``robots/stretch_re1.toml`` (0.0508 m, 0.3407 m),
its caster 0.245 m behind the axle (the URDF's ``caster_joint``), and Pinocchio's total mass of
the controller's model.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from pbvs_pin.plant.mujoco_spec import build_spec
from pbvs_pin.plant.mujoco_stability import contact_polygon
from pbvs_pin.plant.mujoco_wheels import KEY_WHEELS
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.sections import RobotSection
from pbvs_pin.study.zoo import load_zoo

ROBOTS = Path(__file__).resolve().parents[1] / "robots"
RADIUS, TRACK = 0.0508, 0.3407
"""Stretch RE1's drive keys [m]."""


@pytest.fixture(scope="module")
def stretch():
    robot_file = next(robot for robot in load_zoo(ROBOTS) if robot.name == "stretch_re1")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # placement warnings
        return RobotSection.from_toml(robot_file.table, str(robot_file.path)).build()


def test_the_wheels_are_cylinders_of_the_keys_on_the_platforms_root(stretch):
    spec, axle = build_spec(stretch)
    model = spec.compile()
    assert axle.wheel_joints == KEY_WHEELS
    for name, side in zip(KEY_WHEELS, (1.0, -1.0), strict=True):
        body = model.body(name)
        assert model.body_parentid[body.id] == 1  # the platform's root
        np.testing.assert_allclose(model.body_pos[body.id], [0.0, side * TRACK / 2, RADIUS])
        geom = model.geom_bodyid.tolist().index(body.id)
        assert model.geom_type[geom] == mujoco.mjtGeom.mjGEOM_CYLINDER
        assert model.geom_size[geom][0] == pytest.approx(RADIUS)
        joint = model.joint(name)
        np.testing.assert_allclose(model.jnt_axis[joint.id], [0.0, 1.0, 0.0])
    # the wheels' mass comes off the root link: the total is the URDF's
    assert model.body_subtreemass[1] == pytest.approx(pin.computeTotalMass(stretch.model))
    # it stands on both wheels and its own caster sphere
    data = mujoco.MjData(model)
    data.qpos[:7] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]
    mujoco.mj_forward(model, data)
    polygon = contact_polygon(data)
    assert polygon[:, 0].min() == pytest.approx(-0.245, abs=1e-3)
    assert polygon[:, 1].max() >= TRACK / 2 and polygon[:, 1].min() <= -TRACK / 2


def test_stretch_runs_experiment1_on_mujoco_and_keeps_the_target(stretch):
    scenario = load_scenario("experiment1").with_values(
        **{"plant.engine": "mujoco", "duration": 3.0}
    )
    log = simulate(scenario, robot=stretch)
    error = np.abs(log["xi_true"] - log["xi_d"])
    assert not np.any(log["target_lost"])
    assert np.all(np.isfinite(error))
    assert error[len(error) // 2 :].max() < 8.0  # the claim's bound, on the last 1.5 s


def test_wheels_without_an_effort_limit_keep_their_integral_action(stretch):
    """The keys' wheels have no effort limit: their integral is clamped at the torque the
    floor takes from a wheel (friction 1 x its share of the weight x radius), not at zero. A
    small forward command (2 mm/s) is then reached within 2 % after 2 s; with the clamp at
    zero (proportional action alone) the platform ran at 2.46 mm/s."""
    from pbvs_pin.model.servo import ServoModel
    from pbvs_pin.plant.mujoco_plant import MujocoPlant

    plant = MujocoPlant(stretch, ServoModel.from_robot(stretch), stretch.home(), settle=0.3)
    weight = pin.computeTotalMass(stretch.model) * 9.81
    share = weight * RADIUS / len(KEY_WHEELS)  # [N m] friction coefficient 1
    limits = plant._integral_limit * plant.model.actuator_gainprm[: len(KEY_WHEELS), 0]
    np.testing.assert_allclose(limits / plant.wheel_integral_time, share, rtol=1e-3)
    v_ref = np.zeros(stretch.n)
    v_ref[0] = 0.002
    speeds = []
    for step in range(4000):
        plant.step(v_ref)
        if step >= 2000:
            speeds.append(plant.v[0])
    assert np.mean(speeds) == pytest.approx(0.002, rel=0.02)


def test_a_platforms_shapes_below_the_keys_floor_are_left_out_so_that_it_drives():
    """Fetch whole-body's planning URDF approximates its base with bounding spheres, three of
    which reach 0.058-0.060 m below the floor its drive keys give (the wheels touch it at the
    root link's z = 0). They held the built wheels 5.9 cm in the air and the platform never
    moved. They are left out with a warning naming the file; the platform then stands on its
    wheels and the key supports, and a 0.2 m/s command moves it at 0.2 m/s."""
    from pbvs_pin.exceptions import PbvsWarning
    from pbvs_pin.model.servo import ServoModel
    from pbvs_pin.plant.mujoco_plant import MujocoPlant
    from pbvs_pin.plant.mujoco_wheels import KEY_SUPPORTS

    robot_file = next(robot for robot in load_zoo(ROBOTS) if robot.name == "fetch_whole_body")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fetch = RobotSection.from_toml(robot_file.table, str(robot_file.path)).build()
    with pytest.warns(PbvsWarning, match=r"fetch_whole_body\.urdf: 3 collision shapes") as caught:
        spec, _ = build_spec(fetch)
    assert "0.060 m below the floor" in str(caught[0].message)
    assert {geom.name for geom in spec.geoms} >= set(KEY_SUPPORTS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plant = MujocoPlant(fetch, ServoModel.from_robot(fetch), fetch.home(), settle=0.3)
    v_ref = np.zeros(fetch.n)
    v_ref[0] = 0.2
    for _ in range(2000):
        plant.step(v_ref)
    assert plant.v[0] == pytest.approx(0.2, rel=0.03)


def test_a_platform_on_key_supports_stands_on_both_wheels_and_one_support():
    """Fetch: no collision geometry of its own, so two support spheres are added, their
    lowest point 2 mm above the floor (``KEY_SUPPORT_GAP``). Standing at home, both wheels
    touch the floor and one support does (three points). With the supports on the floor all
    four touched, and a reaching arm rolled the platform onto one wheel."""
    from pbvs_pin.model.servo import ServoModel
    from pbvs_pin.plant.mujoco_plant import MujocoPlant
    from pbvs_pin.plant.mujoco_wheels import KEY_SUPPORTS

    robot_file = next(robot for robot in load_zoo(ROBOTS) if robot.name == "fetch")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fetch = RobotSection.from_toml(robot_file.table, str(robot_file.path)).build()
        plant = MujocoPlant(fetch, ServoModel.from_robot(fetch), fetch.home(), settle=0.5)
    model, data = plant.model, plant.data
    touches = [c for c in data.contact[: data.ncon] if c.dist <= 1e-4]  # not the listed gaps
    touching = {
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, model.geom_bodyid[geom])
        for contact in touches
        for geom in (contact.geom1, contact.geom2)
    } | {
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
        for contact in touches
        for geom in (contact.geom1, contact.geom2)
    }
    assert set(KEY_WHEELS) <= touching, touching
    assert len(set(KEY_SUPPORTS) & touching) == 1, touching
