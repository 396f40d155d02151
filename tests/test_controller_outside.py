"""The public controller holds the experiments in a loop that is not the simulator's.

The loop is ``examples/own_loop_pioneer_cyton.py``: public names only, its own plant (velocity
loops with first-order lags integrated at 1 kHz), its own pinhole camera whose frames arrive
late, stamped with their capture time, its own laser. The rules are the report's
(:data:`pbvs_pin.study.claims.CLAIMS`), evaluated here on the true image error with their own
arithmetic; ``docs/controller.rst``'s latency table is checked against fresh runs.
"""

import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
HALF_IMAGE_HEIGHT = 291.0  # [px], the paper's 582 px image
WINDOW = 5.0  # [s]
OSCILLATION_PX = 3.0  # [px] RMS of the error's fast part over any 5 s window
SMOOTHING = 0.5  # [s] the moving average that the fast part is taken from


def _loop():
    spec = importlib.util.spec_from_file_location(
        "own_loop", REPO / "examples" / "own_loop_pioneer_cyton.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


OWN_LOOP = _loop()
_RUNS: dict[tuple, dict] = {}


def run(experiment: str, robot: str = "pioneer_cyton", late: int = 1, **values) -> dict:
    """One run of the outside loop, kept for the module's other tests."""
    key = (experiment, robot, late, tuple(sorted(values.items())))
    if key not in _RUNS:
        _RUNS[key] = OWN_LOOP.run(experiment, robot, late, values=values)
    return _RUNS[key]


def final_window_max(log: dict) -> float:
    """Max |xi - xi_d| over the last 5 s [px]."""
    return float(np.abs(log["error"][log["t"] > log["t"][-1] - WINDOW]).max())


def fastest_oscillation(log: dict) -> float:
    """Largest RMS over 5 s windows of the error minus its 0.5 s moving average [px]."""
    dt = log["t"][1] - log["t"][0]
    width = round(SMOOTHING / dt)
    kernel = np.ones(width) / width
    error = log["error"]
    fast = np.column_stack(
        [e - np.convolve(e, kernel, mode="same") for e in error.T]
    )[width:-width]  # fmt: skip
    per_window = round(WINDOW / dt)
    return max(
        float(np.sqrt(np.mean(fast[i : i + per_window] ** 2)))
        for i in range(0, len(fast) - per_window, per_window // 2)
    )


def test_experiment_1_holds_with_frames_one_period_late():
    log = run("experiment1")
    assert final_window_max(log) < 8.0
    assert fastest_oscillation(log) < OSCILLATION_PX
    assert np.isfinite(log["v_ref"]).all()


def test_experiment_2_holds_with_frames_one_period_late():
    log = run("experiment2")
    after = log["t"] > 2.0
    final = log["t"] > log["t"][-1] - WINDOW
    assert np.abs(log["error"][after]).max() < HALF_IMAGE_HEIGHT
    assert log["clearance"].min() > 0.0
    assert log["posture"][final].max() < 0.1  # [rad] arm back at theta_d
    assert final_window_max(log) < 8.0
    assert fastest_oscillation(log) < OSCILLATION_PX


def test_an_arm_that_can_roll_its_camera_keeps_the_image_upright():
    """TIAGo, Experiment 4 (exact target velocity, no noise), frames one period late."""
    log = run("experiment4", "tiago")
    assert np.degrees(np.abs(log["roll"]).max()) < 5.0
    assert final_window_max(log) < 0.5  # Experiment 4's rule: convergence


def test_the_upright_row_keeps_the_image_upright_against_the_papers_posture_target():
    """The Panda pulled to its most manipulable posture (the paper's theta_d) rolls its camera
    unless the null space is kept from rolling the image (75 degrees and lost without it). The
    support objective is off: that posture puts the centre of mass past the support's margin,
    and held back from it the camera rolled by up to 6.1 degrees."""
    log = run(
        "experiment4",
        "pioneer_panda",
        **{"secondary.posture_target": "max_manipulability", "secondary.support": False},
    )
    assert np.degrees(np.abs(log["roll"]).max()) < 5.0
    assert final_window_max(log) < 0.5


def test_the_oscillation_measure_sees_an_oscillation():
    """The measure flags a 2 px, 3 Hz oscillation and passes a slow drift."""
    t = np.arange(0.0, 20.0, 0.01)
    oscillating = {"t": t, "error": np.column_stack([5 * np.sin(2 * np.pi * 3 * t)] * 3)}
    drifting = {"t": t, "error": np.column_stack([5 * np.sin(2 * np.pi * 0.05 * t)] * 3)}
    assert fastest_oscillation(oscillating) > OSCILLATION_PX
    assert fastest_oscillation(drifting) < 0.5


def docs_table() -> dict[tuple[str, int], float]:
    """``docs/controller.rst``'s latency table: (experiment, periods late) -> px."""
    text = (REPO / "docs" / "controller.rst").read_text()
    rows = re.findall(r"^\s*(experiment\d)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s*$", text, re.M)
    assert len(rows) == 2, "the latency table of docs/controller.rst"
    return {
        (name, late): float(value)
        for name, *values in rows
        for late, value in zip((0, 1, 3), values, strict=True)
    }


@pytest.mark.parametrize("experiment", ["experiment1", "experiment2"])
def test_the_docs_latency_table_is_measured(experiment):
    table = docs_table()
    for late in (0, 1, 3):
        measured = final_window_max(run(experiment, late=late))
        assert table[(experiment, late)] == pytest.approx(measured, abs=0.006), late
