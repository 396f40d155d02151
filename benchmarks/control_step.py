"""Benchmark: the control step against the Pinocchio calls it makes, and closed-loop speed.

The control step timed is the one the simulation loop runs: :class:`FusedControlStep`
(secondary objectives, eq. 3, eq. 34 and eq. 20 in one compiled call after its Pinocchio calls).

Run: ``python benchmarks/control_step.py``. Prints, per robot, the median time of one full
control step (kinematic controller, eq. 34, plus dynamic compensation, eq. 20) and of the
Pinocchio calls that step makes (joint Jacobians, camera frame placement and Jacobian,
CRBA, nonlinear effects, gravity), both
measured in this run, and their ratio; then the real-time factor of a closed-loop simulation
with a 1 kHz controller on the reference robot. Medians over repeats: the machine is shared.
"""

from __future__ import annotations

import statistics
import time

import numpy as np
import pinocchio as pin

from pbvs_pin.control.step import FusedControlStep
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.perception import Perception
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.setup import build

REPEATS = 15
CALLS = 500


def _mean_time(function, calls: int = CALLS) -> float:
    """Mean time of one call over ``calls`` calls [s]."""
    start = time.perf_counter()
    for _ in range(calls):
        function()
    return (time.perf_counter() - start) / calls


def _interleaved(first, second, repeats: int = REPEATS) -> tuple[float, float, float]:
    """Medians of both functions' times and of their ratio, timed alternately.

    Alternating keeps both under the same load of this shared machine.
    """
    first(), second()
    pairs = [(_mean_time(first), _mean_time(second)) for _ in range(repeats)]
    return (
        statistics.median(a for a, _ in pairs),
        statistics.median(b for _, b in pairs),
        statistics.median(a / b for a, b in pairs),
    )


def control_step_ratio(robot_name: str) -> tuple[float, float, float]:
    """Median control-step time, median time of its Pinocchio calls [s], median ratio."""
    scenario = load_scenario("experiment1").with_values(**{"robot.name": robot_name})
    setup = build(scenario)
    perception = Perception(setup)
    q = setup.plant.q
    setup.sensor.capture(0.0, setup.robot.camera_pose(q), setup.target.centres(0.0), q)
    perception.take(setup.sensor.deliver(0.0))
    v = np.full(setup.robot.n, 0.05)
    dt = 1e-3
    fused = FusedControlStep(
        setup.model, setup.features, setup.xi_d, setup.controller, setup.compensator,
        setup.objectives,
    )  # fmt: skip
    laser, target_velocity = np.array([np.inf, 0.0]), np.zeros(3)

    def step() -> None:
        fused.step(q, v, perception.measurement, target_velocity, laser, dt)

    model, data = setup.model.model, setup.model.data
    frame = setup.model.camera_frame_id
    v_pin = setup.model.selection @ v

    def pinocchio_calls() -> None:
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacement(model, data, frame)
        pin.getFrameJacobian(model, data, frame, pin.LOCAL)
        pin.crba(model, data, q)
        pin.nonLinearEffects(model, data, q, v_pin)
        pin.computeGeneralizedGravity(model, data, q)

    return _interleaved(step, pinocchio_calls)


def closed_loop_real_time_factor(duration: float = 10.0, repeats: int = 3) -> float:
    """Median simulated seconds per wall-clock second of the loop, 1 kHz controller.

    On the reference robot, over ``repeats`` runs. The setup (loading the robot, maximising
    manipulability) is not counted.
    """
    scenario = load_scenario("experiment1").with_values(
        **{"controller.rate": 1000.0, "duration": duration}
    )
    return statistics.median(
        duration / simulate(scenario).meta["wall_time"] for _ in range(repeats)
    )


def main() -> None:
    """Print the measurements."""
    print(f"{'robot':<16}{'n':>3}{'control step [us]':>20}{'pinocchio calls [us]':>23}{'ratio':>8}")
    for name in ("pioneer_cyton", "pioneer_xarm7"):
        step, calls, ratio = control_step_ratio(name)
        n = build(load_scenario("experiment1").with_values(**{"robot.name": name})).robot.n
        print(f"{name:<16}{n:>3}{step * 1e6:>20.1f}{calls * 1e6:>23.1f}{ratio:>8.2f}")
    factor = closed_loop_real_time_factor()
    print(f"closed loop, 1 kHz controller, pioneer_cyton: {factor:.1f}x real time")


if __name__ == "__main__":
    main()
