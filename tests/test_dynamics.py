"""Dynamics in actuated coordinates and the velocity-reference model of eq. (1).

References: Pinocchio's recursive Newton-Euler algorithm and kinetic energy (independent of
the projection ``S^T (.) S`` under test), link masses parsed from the URDF, central finite
differences of ``M_v`` along the motion, and step responses simulated here with our own
linearly implicit Euler scheme.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest
from conftest import random_configuration, urdf_link_masses

from pbvs_pin import VelocityLoop, rigid_body_terms

DYNAMICS_ROBOTS = ("pioneer_cyton", "pioneer_panda", "tiago")


def _state(robot, rng):
    q = random_configuration(robot, rng)
    v = rng.uniform(-1, 1, robot.n) * np.concatenate([[0.5, 1.0], np.ones(robot.n_arm)])
    return q, v


@pytest.mark.parametrize("name", DYNAMICS_ROBOTS)
@pytest.mark.parametrize("seed", range(3))
def test_mass_matrix_symmetric_positive_definite(load, name, seed):
    robot = load(name)
    q, v = _state(robot, np.random.default_rng([41, seed]))
    mass = rigid_body_terms(robot, q, v).mass
    assert mass.shape == (robot.n, robot.n)
    np.testing.assert_allclose(mass, mass.T, atol=1e-12)
    assert np.linalg.eigvalsh(mass).min() > 1e-6
    # Kinetic energy 1/2 v^T M_v v equals Pinocchio's, computed from link twists.
    data = robot.model.createData()
    energy = pin.computeKineticEnergy(robot.model, data, q, robot.selection @ v)
    assert 0.5 * v @ mass @ v == pytest.approx(energy, rel=1e-10)


@pytest.mark.parametrize("name", DYNAMICS_ROBOTS)
@pytest.mark.parametrize("seed", range(3))
def test_rnea_identities(load, name, seed):
    robot = load(name)
    rng = np.random.default_rng([42, seed])
    q, v = _state(robot, rng)
    acc = rng.uniform(-1, 1, robot.n)
    model, data, s = robot.model, robot.model.createData(), robot.selection
    terms = rigid_body_terms(robot, q, v)
    zero = np.zeros(model.nv)

    bias = s.T @ pin.rnea(model, data, q, s @ v, zero)
    np.testing.assert_allclose(terms.coriolis @ v + terms.gravity, bias, atol=1e-9)
    np.testing.assert_allclose(
        terms.gravity, s.T @ pin.rnea(model, data, q, zero, zero), atol=1e-10
    )
    np.testing.assert_allclose(
        terms.gravity, s.T @ pin.computeGeneralizedGravity(model, data, q), atol=1e-10
    )
    full = s.T @ pin.rnea(model, data, q, s @ v, s @ acc)
    np.testing.assert_allclose(
        terms.mass @ acc + terms.coriolis @ v + terms.gravity, full, atol=1e-9
    )
    # A flat floor: gravity does no work on the platform's forward motion or yaw.
    np.testing.assert_allclose(terms.gravity[:2], 0.0, atol=1e-10)


@pytest.mark.parametrize("name", DYNAMICS_ROBOTS)
@pytest.mark.parametrize("seed", range(2))
def test_mass_derivative_and_skew_symmetry(load, name, seed):
    robot = load(name)
    q, v = _state(robot, np.random.default_rng([43, seed]))
    terms = rigid_body_terms(robot, q, v)
    h = 1e-6

    def mass_at(t):
        q_t = pin.integrate(robot.model, q, robot.selection @ v * t)
        return rigid_body_terms(robot, q_t, v).mass

    mass_dot = (mass_at(h) - mass_at(-h)) / (2 * h)
    scale = max(np.abs(mass_dot).max(), 1e-3)
    coriolis = terms.coriolis
    np.testing.assert_allclose(mass_dot, coriolis + coriolis.T, atol=1e-6 * scale)
    n_matrix = mass_dot - 2 * coriolis
    np.testing.assert_allclose(n_matrix + n_matrix.T, 0.0, atol=1e-6 * scale)


def test_reference_robot_mass_from_urdf(cyton, cyton_urdf):
    # Translating the whole robot forward at u moves every link at u: M_v[0, 0] is the
    # total mass, and the platform's own translation does not couple with its yaw.
    total = sum(urdf_link_masses(cyton_urdf).values())
    assert total == pytest.approx(14.65)
    mass = rigid_body_terms(cyton, cyton.home(), np.zeros(cyton.n)).mass
    assert mass[0, 0] == pytest.approx(total, rel=1e-12)
    # The yaw inertia about the axle midpoint is at least the chassis box's own
    # (10 kg, 0.5 x 0.38 m box: m (a^2 + b^2) / 12).
    assert mass[1, 1] > 10.0 * (0.5**2 + 0.38**2) / 12


# ================================================================ eq. (1)
def test_reference_model_is_the_closed_velocity_loop(load):
    """M vdot + C v + g = v_ref  <=>  rnea(q, v, vdot) = K_v (v_ref - v) - D v + G g_v."""
    robot = load("pioneer_panda")
    loop = VelocityLoop.from_time_constants(robot)
    rng = np.random.default_rng(44)
    q, v = _state(robot, rng)
    acc = rng.uniform(-1, 1, robot.n)
    model_terms = loop.reference_model(robot, q, v)
    v_ref = model_terms.mass @ acc + model_terms.coriolis @ v + model_terms.gravity
    s = robot.selection
    data = robot.model.createData()
    torque = s.T @ pin.rnea(robot.model, data, q, s @ v, s @ acc)
    gravity = s.T @ pin.computeGeneralizedGravity(robot.model, data, q)
    assert loop.gravity_compensated[robot.n_base :].all()
    assert not loop.gravity_compensated[: robot.n_base].any()
    servo = loop.gains * (v_ref - v) - loop.damping * v + loop.gravity_compensated * gravity
    np.testing.assert_allclose(servo, torque, rtol=1e-9, atol=1e-9)


def test_velocity_loop_damping_from_urdf(cyton, cyton_urdf):
    loop = VelocityLoop.from_time_constants(cyton)
    root = ET.parse(cyton_urdf).getroot()
    damping = {
        j.get("name"): float(j.find("dynamics").get("damping"))
        for j in root.findall("joint")
        if j.find("dynamics") is not None
    }
    expected = [0.0, 0.0, *[damping[name] for name in cyton.arm_joint_names]]
    np.testing.assert_allclose(loop.damping, expected)
    assert np.all(loop.gains > 0)


def _step_response(robot, loop, index, amplitude, duration=2.5, dt=2e-3):
    """Simulate eq. (1) from rest at home for v_ref = amplitude e_index.

    Linearly implicit Euler: (M + dt C) v+ = M v + dt (v_ref - g), then q+ = q (+) S v+ dt.
    """
    q = robot.home()
    v = np.zeros(robot.n)
    v_ref = np.zeros(robot.n)
    v_ref[index] = amplitude
    times, values = [0.0], [0.0]
    for k in range(round(duration / dt)):
        terms = loop.reference_model(robot, q, v)
        v = np.linalg.solve(
            terms.mass + dt * terms.coriolis, terms.mass @ v + dt * (v_ref - terms.gravity)
        )
        q = robot.integrate(q, v, dt)
        times.append((k + 1) * dt)
        values.append(v[index])
    return np.array(times), np.array(values)


def _rise_time(times, values, fraction=1 - np.exp(-1)):
    normalised = values / values[-1]
    k = int(np.argmax(normalised >= fraction))
    assert k > 0
    # Linear interpolation between the two samples around the crossing.
    a, b = normalised[k - 1], normalised[k]
    return times[k - 1] + (fraction - a) / (b - a) * (times[k] - times[k - 1])


@pytest.mark.parametrize("name", ["pioneer_cyton", "tiago"])
def test_platform_time_constants_are_pioneer_like(load, name):
    robot = load(name)
    loop = VelocityLoop.from_time_constants(robot)
    for index, amplitude in ((0, 0.3), (1, 0.5)):
        times, values = _step_response(robot, loop, index, amplitude)
        assert values[-1] == pytest.approx(amplitude, rel=0.05)  # reaches the reference
        assert np.all(np.abs(values) <= 1.05 * amplitude)  # no overshoot: a lag, not a spring
        tau = _rise_time(times, values)
        assert 0.1 < tau < 0.6, f"{robot.velocity_names[index]}: time constant {tau:.3f} s"


def test_requested_time_constants_are_obtained(cyton):
    requested = (0.45, 0.15)
    loop = VelocityLoop.from_time_constants(cyton, base=requested)
    for index, amplitude in ((0, 0.2), (1, -0.4)):
        times, values = _step_response(cyton, loop, index, amplitude, duration=3.0, dt=1e-3)
        tau = _rise_time(times, values)
        assert tau == pytest.approx(requested[index], rel=0.1)
