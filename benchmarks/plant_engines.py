"""Benchmark: the closed loop's speed on the Pinocchio plant and on the MuJoCo plant.

Run: ``python benchmarks/plant_engines.py``. Prints, for the reference robot on Experiment 1
with a 1 kHz controller and a 1 kHz plant (``plant_dt`` 1 ms), the real-time factor
(simulated seconds per wall-clock second of :func:`pbvs_pin.sim.loop.simulate`; the setup is
not counted) of each ``[plant] engine``, medians over repeats run alternately so that both
engines share the load of this shared machine, and the median ratio of the two. Then the
median time of one MuJoCo plant step and of the MuJoCo calls it makes (``mj_step1``,
``mj_fullM``, ``mj_step2``), measured in the same run.
"""

from __future__ import annotations

import statistics

import mujoco
import numpy as np
from control_step import mean_time

from pbvs_pin.bringup.catalogue import REFERENCE_ROBOT
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.setup import build

DURATION_S = 10.0
"""Simulated time of one closed-loop run [s]."""

REPEATS = 5
"""Closed-loop runs per engine."""

STEP_CALLS = 2000
"""Plant steps per timing of the step."""


def _scenario(engine: str):
    """Experiment 1 on the reference robot, 1 kHz controller, for ``DURATION_S``."""
    return load_scenario("experiment1").with_values(
        duration=DURATION_S,
        **{"controller.rate": 1000.0, "plant.engine": engine, "robot.name": REFERENCE_ROBOT},
    )


def real_time_factors(repeats: int = REPEATS) -> dict[str, list[float]]:
    """Real-time factor of each engine's closed loop, ``repeats`` runs each, alternated."""
    factors: dict[str, list[float]] = {"pinocchio": [], "mujoco": []}
    scenarios = {engine: _scenario(engine) for engine in factors}
    for engine in factors:  # compile the kernels and warm the caches first
        simulate(scenarios[engine].with_values(duration=0.1))
    for _ in range(repeats):
        for engine, scenario in scenarios.items():
            factors[engine].append(DURATION_S / simulate(scenario).meta["wall_time"])
    return factors


def plant_step_times(repeats: int = 9) -> tuple[float, float]:
    """Median time of one MuJoCo plant step and of its MuJoCo calls [s], turning."""
    plant = build(_scenario("mujoco")).plant
    model, data = plant.model, plant.data
    v_ref = np.zeros(plant.robot.n)
    v_ref[:2] = 0.2, 0.3
    v_ref[2:] = 0.1
    mass = np.zeros((model.nv, model.nv))

    def calls() -> None:
        mujoco.mj_step1(model, data)
        mujoco.mj_fullM(model, data, mass)
        mujoco.mj_step2(model, data)

    def step() -> None:
        plant.step(v_ref)

    pairs = [(mean_time(step, STEP_CALLS), mean_time(calls, STEP_CALLS)) for _ in range(repeats)]
    return statistics.median(a for a, _ in pairs), statistics.median(b for _, b in pairs)


def main() -> None:
    """Print the measurements."""
    factors = real_time_factors()
    ratios = [m / p for m, p in zip(factors["mujoco"], factors["pinocchio"], strict=True)]
    print(
        f"closed loop, {REFERENCE_ROBOT}, Experiment 1, 1 kHz controller and plant, "
        f"{DURATION_S:g} s x {REPEATS} runs per engine (medians)"
    )
    for engine, values in factors.items():
        spread = ", ".join(f"{value:.1f}" for value in values)
        print(f"  {engine:<10} {statistics.median(values):6.1f}x real time   ({spread})")
    print(f"  mujoco / pinocchio: {statistics.median(ratios):.2f}")
    step, calls = plant_step_times()
    print(
        f"MuJoCo plant step: {step * 1e6:.1f} us, of which mj_step1 + mj_fullM + mj_step2 "
        f"{calls * 1e6:.1f} us"
    )


if __name__ == "__main__":
    main()
