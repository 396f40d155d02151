"""``[plant] engine`` and ``[model_error]``: the true robot is not the controller's model.

Every key that describes the true robot or the controller's knowledge of it must move the
log; a key that leaves it bit-identical is a knob that does nothing (``mass_scale`` once did:
the servo gains were recomputed from the erroneous model and cancelled it).
"""

from __future__ import annotations

import numpy as np
import pytest

from pbvs_pin.plant.mujoco_plant import MujocoPlant
from pbvs_pin.plant.pinocchio_plant import Plant
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.metrics import summarize
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.setup import build

SHORT_S = 1.0
"""Duration [s] of the runs compared sample by sample."""

HOLD_S = 6.0
"""Duration [s] of the MuJoCo run of Experiment 1 (its transient settles in ~2 s)."""

HOLD_PX = 5.0
"""Largest feature error [px] over the last second that counts as holding the target."""


def _run(**changes):
    scenario = load_scenario("experiment1").with_values(duration=SHORT_S, **changes)
    return simulate(scenario)


@pytest.fixture(scope="module")
def default_log():
    return _run()


def test_the_default_engine_is_the_pinocchio_plant():
    scenario = load_scenario("experiment1")
    assert scenario.plant.engine == "pinocchio"
    assert isinstance(build(scenario).plant, Plant)
    mujoco = build(scenario.with_values(**{"plant.engine": "mujoco"}))
    assert isinstance(mujoco.plant, MujocoPlant)


@pytest.mark.parametrize(
    "changes",
    [
        {"plant.engine": "mujoco"},
        {"model_error.kinematic_scale": 1.2},
        {"model_error.mass_scale": 2.0},
        {"model_error.mass_scale": 2.0, "plant.engine": "mujoco"},
        {"model_error.payload": 0.5},
        {"model_error.payload": 0.5, "plant.engine": "mujoco"},
    ],
    ids=[
        "engine",
        "kinematic_scale",
        "mass_scale",
        "mass_scale-mujoco",
        "payload",
        "payload-mujoco",
    ],
)
def test_a_plant_or_model_error_key_moves_the_log(default_log, changes):
    log = _run(**changes)
    reference = default_log
    if "plant.engine" in changes and len(changes) > 1:
        reference = _run(**{"plant.engine": changes["plant.engine"]})
    moved = np.abs(log["q"] - reference["q"]).max()
    assert moved > 1e-6, f"{changes} left the configuration unchanged"
    assert not np.array_equal(log["v"], reference["v"])


def test_mass_scale_makes_the_plant_heavier_not_the_model():
    scenario = load_scenario("experiment1").with_values(**{"model_error.mass_scale": 2.0})
    setup = build(scenario)
    nominal = sum(inertia.mass for inertia in setup.model.model.inertias)
    true = sum(inertia.mass for inertia in setup.plant.robot.model.inertias)
    assert true == pytest.approx(2.0 * nominal)
    # servos tuned on the nominal robot: twice the inertia doubles their time constants
    assert np.allclose(setup.plant.loop.time_constants[:2], [0.52, 0.46])


def test_experiment1_on_the_mujoco_plant_holds_the_target():
    scenario = load_scenario("experiment1").with_values(
        duration=HOLD_S, **{"plant.engine": "mujoco"}
    )
    log = simulate(scenario)
    assert not np.any(log["target_lost"])
    last = log["t"] >= HOLD_S - 1.0
    error = np.abs(log["xi"][last] - np.asarray(scenario.target.xi_d))
    assert np.nanmax(error) < HOLD_PX


def test_experiment3_on_the_mujoco_plant_holds_the_target_on_the_skid_steer_pioneer():
    """The skid-steer Pioneer turns at the commanded rate (its gyro loop) and holds the target
    within 5 px over the last 5 s of Experiment 3; without the loop it turned at a third of
    the rate and ended 18 px off."""
    scenario = load_scenario("experiment3").with_values(**{"plant.engine": "mujoco"})
    summary = summarize(simulate(scenario))
    assert summary["target_lost_samples"] == 0
    assert summary["max_abs_error_final_window_px"] < HOLD_PX
