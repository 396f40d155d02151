"""Acceptance on the MuJoCo plant: the four experiments hold the target on real wheels.

Issue 9's bounds, on each robot of :data:`pbvs_pin.study.report.ENGINE_ROBOTS` with the full
shipped scenarios and the default sensing (wheel odometry, encoder velocities, one frame of
camera latency): max |feature error| over the last 5 s below 5 px (Experiment 4: 1 px), and
the target never lost. The report's two-plant table is built from these runs.

``pioneer_ur5`` carries 21 kg of UR5 on 13.2 kg of Pioneer whose axles are 0.268 m apart. Its
home keeps the centre of mass 0.05 m inside the wheels' support; following the target, the arm
carries it forward. Without the support objective (``secondary.support = false``) the Pioneer
tips over in all four experiments (the target lost from 4.5 s in Experiment 4); with it (the
default, :mod:`pbvs_pin.control.support`) the centre of mass stays inside and every run holds.
"""

from __future__ import annotations

import numpy as np
import pytest
from docs_figures import OSCILLATION_FLAG_PX, run, stated

from pbvs_pin.bringup.catalogue import build_robot
from pbvs_pin.bringup.home import HomeCriteria
from pbvs_pin.plant.mujoco_support import centre_of_mass_margins, support_polygon
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.metrics import summarize
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.study.experiments import PAPER_CLAIMS
from pbvs_pin.study.report import (
    ENGINE_ROBOTS,
    ENGINES_BEGIN,
    ENGINES_END,
    engines_table,
    readme_block,
    readme_engines,
)

HOLD_PX = 5.0
"""Largest feature error over the last 5 s [px] that counts as holding the target."""

CONVERGE_PX = 1.0
"""The same for Experiment 4 (perfect knowledge of the target's velocity)."""


SUPPORTED = "pioneer_ur5"
"""The engine robot the support objective keeps standing."""


@pytest.fixture(scope="module")
def runs() -> dict[tuple[str, str], tuple[dict, np.ndarray]]:
    """Each engine robot's four experiments on the MuJoCo plant: summary, log's ``t`` and the
    centre of mass's margin [m] inside the support over the run (platform robots; else empty).
    """
    out = {}
    for robot in ENGINE_ROBOTS:
        model = build_robot(robot)
        support = support_polygon(model)
        for name in PAPER_CLAIMS:
            log = simulate(
                load_scenario(name).with_values(**{"robot.name": robot, "plant.engine": "mujoco"})
            )
            margins = (
                np.zeros(0)
                if support is None
                else centre_of_mass_margins(model, log["arm"], support)
            )
            out[(robot, name)] = (summarize(log), np.stack([log["t"][: len(margins)], margins]))
    return out


@pytest.fixture(scope="module")
def summaries(runs) -> dict[tuple[str, str], dict]:
    """Each engine robot's four experiments' summaries."""
    return {key: summary for key, (summary, _) in runs.items()}


HELD = [(r, n) for r in ENGINE_ROBOTS for n in PAPER_CLAIMS]


@pytest.mark.parametrize(("robot", "name"), HELD)
def test_the_mujoco_plant_holds_the_target(summaries, robot, name):
    s = summaries[(robot, name)]
    bound = CONVERGE_PX if name == "experiment4" else HOLD_PX
    assert s["engine"] == "mujoco"
    assert s["target_lost_samples"] == 0
    assert s["max_abs_error_final_window_px"] < bound, s["max_abs_error_final_window_px"]


def test_the_support_objective_keeps_the_heavy_arm_standing(runs):
    """With it the centre of mass never leaves the support (the plant's own measure of the
    margin, :func:`centre_of_mass_margins`, from the run's arm); without it the same Experiment
    4 tips the Pioneer in its transient."""
    for name in PAPER_CLAIMS:
        _, (_, margin) = runs[(SUPPORTED, name)]
        assert margin[0] >= HomeCriteria().com_margin - 1e-3, margin[0]
        assert margin.min() > 0.0, (name, margin.min())
    scenario = load_scenario("experiment4").with_values(
        **{"robot.name": SUPPORTED, "plant.engine": "mujoco", "secondary.support": False}
    )
    tipped = summarize(simulate(scenario))
    assert tipped["target_lost_samples"] > 0
    assert not tipped["max_abs_error_final_window_px"] <= HOLD_PX  # NaN: fallen, no finite error


def test_the_report_shows_odometry_drift_and_slip_on_mujoco(summaries):
    table = engines_table(list(summaries.values()))
    assert table.count("| mujoco |") == len(summaries)
    # the skid-steer Pioneer slips when it turns: some lateral slip is measured
    pioneer = [s for (robot, _), s in summaries.items() if robot.startswith("pioneer")]
    assert max(s["lateral_slip_rms_mps"] for s in pioneer) > 1e-4
    assert all(s["odometry_drift_m"] >= 0 for s in summaries.values())


def test_readme_mujoco_results_match_fresh_runs(summaries):
    """The gallery's MuJoCo table is the one generated from these fresh runs' summaries."""
    from conftest import REPO_ROOT

    page = (REPO_ROOT / "docs" / "gallery.md").read_text()
    assert readme_block(page, ENGINES_BEGIN, ENGINES_END) == readme_engines(
        list(summaries.values())
    ), (
        "docs/gallery.md's MuJoCo results differ from fresh runs: regenerate with pbvs-pin "
        "reproduce --out results && python -m pbvs_pin.study.report README.md docs/gallery.md results"
    )


def test_prediction_on_the_mujoco_plant(summaries):
    """The prediction's gain on MuJoCo: the shipped runs (which predict) against the same runs
    without it."""

    def summary(robot: str, experiment: str, predict: bool) -> dict:
        if predict:  # the shipped scenarios predict: this module's runs
            assert load_scenario(experiment).estimator.predict
            return summaries[(robot, experiment)]
        values = {"robot.name": robot, "plant.engine": "mujoco", "estimator.predict": False}
        return run(experiment, **values)[0]

    cyton, tiago = (
        [summary(robot, "experiment2", p)["oscillation_rms_px"] for p in (False, True)]
        for robot in ("pioneer_cyton", "tiago")
    )
    ur5 = [
        summary("pioneer_ur5", "experiment4", p)["max_abs_error_final_window_px"]
        for p in (False, True)
    ]
    stated(
        f"Experiment 2's oscillation above 0.5 Hz {cyton[0]:.2f} and {cyton[1]:.2f} px RMS "
        f"(the report flags 3 px), TIAGo's {tiago[0]:.2f} and {tiago[1]:.2f} px; `pioneer_ur5` "
        f"Experiment 4 ended up to {ur5[0]:.2f} and {ur5[1]:.2f} px off over the last 5 s"
    )
    for without, with_prediction in (cyton, tiago, ur5):  # prediction lowers each
        assert with_prediction < without
    assert max(cyton[1], tiago[1]) < OSCILLATION_FLAG_PX and ur5[1] < 0.5  # the claim: 0.5 px
