"""Dynamics in actuated coordinates (the servos and eq. (1): ``tests/test_servo.py``).

References: Pinocchio's recursive Newton-Euler algorithm and kinetic energy (independent of
the projection ``S^T (.) S`` under test), link masses parsed from the URDF, central finite
differences of ``M_v`` along the motion.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import random_configuration, urdf_link_masses

from pbvs_pin import rigid_body_terms

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
