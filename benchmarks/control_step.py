"""Benchmark: the control step against the Pinocchio calls it makes, and closed-loop speed.

The control step timed is the compiled step the public controller makes every step, as the
simulation loop runs it: :class:`FusedControlStep` (secondary objectives, eq. 3, the
prediction, eq. 34 and eq. 20 in one compiled call after its Pinocchio calls).

Run: ``python benchmarks/control_step.py``. Prints, per robot, the median time of one full control
step (kinematic controller, eq. 34, plus dynamic compensation, eq. 20) and of the Pinocchio calls
that step makes (joint Jacobians, camera frame placement and Jacobian, CRBA, nonlinear effects,
gravity, and the centre of mass's Jacobian when the support objective is on), both measured in this
run, and their ratio; where the step's time goes (Pinocchio, Python glue, passing the 22 arguments
to compiled code, the compiled arithmetic) and the ratio it would have with no arithmetic at all
(its floor); then the real-time factor of a closed-loop simulation with a 1 kHz controller on the
reference robot, its cost per simulated second against the number of arm joints (a Panda on the
reference platform with the camera on its link 3 ... 7: 3 ... 7 arm joints), and where the loop's
time goes on the reference robot: the Pinocchio calls per simulated millisecond that no speed-up
removes (the floor), the rest of the compiled step, the rest of the public controller's step (its
checks, encoder history, tracker and command), the plant step, the sensors' reading
(:class:`~pbvs_pin.sim.sensing.Sensing`), and everything else in the loop. Medians over repeats: the
machine is shared. ``benchmarks/compiled_floor.py`` measures what the step and the loop would cost
with the Pinocchio calls made from compiled code.
"""

from __future__ import annotations

import statistics
import time

import numpy as np
import pinocchio as pin
from numba import njit

from pbvs_pin.control.step import FusedControlStep, fused_control_step, split_objectives
from pbvs_pin.perception.camera_frame import CameraFrame
from pbvs_pin.perception.features import ImageMeasurement
from pbvs_pin.plant.pinocchio_plant import Plant
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.sensing import Sensing
from pbvs_pin.sim.setup import build

REPEATS = 15
CALLS = 500


def mean_time(function, calls: int = CALLS) -> float:
    """Mean time of one call over ``calls`` calls [s]."""
    start = time.perf_counter()
    for _ in range(calls):
        function()
    return (time.perf_counter() - start) / calls


def _interleaved(*functions, repeats: int = REPEATS) -> tuple[float, ...]:
    """Medians of the functions' times, and of the first's over the second's, timed alternately.

    Alternating keeps all under the same load of this shared machine.
    """
    for function in functions:
        function()
    rows = [[mean_time(function) for function in functions] for _ in range(repeats)]
    medians = [statistics.median(row[i] for row in rows) for i in range(len(functions))]
    return (*medians, statistics.median(row[0] / row[1] for row in rows))


@njit
def _no_op(
    a, b, c, d, e, f, g, h, i, j, k, m, n, o, centre, centre_jacobian, p, seen, dt, params,
    indices, state,
) -> None:  # fmt: skip
    """A compiled call that does nothing with the fused step's 22 arguments."""


def control_step_calls(
    model: pin.Model,
    data: pin.Data,
    frame: int,
    q: np.ndarray,
    v_pin: np.ndarray,
    support: tuple[pin.Data, np.ndarray] | None = None,
) -> None:
    """The Pinocchio calls of :meth:`FusedControlStep.step`, made from Python.

    ``support``: :attr:`FusedControlStep.support` (the centre of mass's Jacobian, platform at
    the origin); None: the support objective is off.
    """
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacement(model, data, frame)
    pin.getFrameJacobian(model, data, frame, pin.LOCAL)
    pin.crba(model, data, q)
    pin.nonLinearEffects(model, data, q, v_pin)
    pin.computeGeneralizedGravity(model, data, q)
    if support is not None:
        support_data, at_origin_q = support
        at_origin_q[4:] = q[4:]
        pin.jacobianCenterOfMass(model, support_data, at_origin_q)


def plant_step_calls(
    model: pin.Model, data: pin.Data, q: np.ndarray, v_pin: np.ndarray, displacement: np.ndarray
) -> None:
    """The Pinocchio calls of :meth:`pbvs_pin.plant.pinocchio_plant.Plant.step`, from Python."""
    pin.crba(model, data, q)
    pin.nonLinearEffects(model, data, q, v_pin)
    pin.computeGeneralizedGravity(model, data, q)
    pin.integrate(model, q, displacement)


def control_step_ratio(robot_name: str) -> tuple[float, float, float, float, float]:
    """Median times [s] of the control step and its parts, and its ratio to its Pinocchio calls.

    Returns the step, its Pinocchio calls, their median ratio, the compiled call alone and a
    compiled call that does nothing with the same arguments. The difference step - Pinocchio
    calls - compiled call is the Python glue; compiled call - no-op is the compiled arithmetic;
    the no-op is the price of calling compiled code with the step's 22 arguments.
    """
    scenario = load_scenario("experiment1").with_values(**{"robot.name": robot_name})
    setup = build(scenario)
    q = setup.plant.q
    measurement = ImageMeasurement(
        *setup.model.camera.project_world(setup.model.camera_pose(q), setup.target.centres(0.0))
    )
    v = np.full(setup.robot.n, 0.05)
    dt = 1e-3
    control = setup.control
    fused = FusedControlStep(
        setup.model, setup.features, setup.xi_d, setup.law, control.compensator,
        *split_objectives(setup.objectives, ()),
    )  # fmt: skip
    laser, target_velocity = np.array([np.inf, 0.0]), np.zeros(3)

    def step() -> None:
        fused.step(q, v, measurement, target_velocity, laser, dt)

    model, data = setup.model.model, setup.model.data
    frame = setup.model.camera_frame_id
    v_pin = setup.model.selection @ v

    def pinocchio_calls() -> None:
        control_step_calls(model, data, frame, q, v_pin, fused.support)

    step()
    arguments = (
        pin.getFrameJacobian(model, data, frame, pin.LOCAL).copy(),
        data.oMf[frame].rotation.copy(), data.oMf[frame].translation.copy(), data.M.copy(),
        data.nle.copy(), data.g.copy(), q, v, measurement.points, measurement.depths,
        np.zeros((0, 3)), float("nan"), target_velocity, laser, *fused.centre_of_mass(q),
        np.zeros(fused.model.n), True, dt, fused.params, fused.indices, fused.state,
    )  # fmt: skip

    def compiled() -> None:
        fused_control_step(*arguments)

    def no_op() -> None:
        _no_op(*arguments)

    step_time, calls, compiled_time, no_op_time, ratio = _interleaved(
        step, pinocchio_calls, compiled, no_op
    )
    return step_time, calls, ratio, compiled_time, no_op_time


def closed_loop_real_time_factor(
    duration: float = 10.0, repeats: int = 3, **values: object
) -> tuple[float, float]:
    """Median simulated seconds per wall-clock second of the loop, 1 kHz controller.

    On the reference robot (or the robot ``values`` give), over ``repeats`` runs. The setup
    (loading the robot, maximising manipulability) is not counted.

    Returns:
        The factor, and the fraction of logged steps with a valid command.
    """
    scenario = load_scenario("experiment1").with_values(
        **{"controller.rate": 1000.0, "duration": duration, **values}
    )
    logs = [simulate(scenario) for _ in range(repeats)]
    factor = statistics.median(duration / log.meta["wall_time"] for log in logs)
    return factor, float(np.mean(logs[0]["valid"]))


def panda_truncated(joints: int) -> dict[str, object]:
    """Scenario values: a Panda on the reference platform, camera on link ``joints``."""
    return {
        "robot.name": "", "robot.base": "pioneer3at", "robot.arm": "panda",
        "robot.camera_link": f"panda_link{joints}", "robot.camera_pose": (0.0,) * 6,
        "robot.mount": (0.10, 0.0, 0.27, 0.0, 0.0, 0.0),
    }  # fmt: skip


def plant_step_times(robot_name: str) -> tuple[float, float]:
    """Median plant step and its Pinocchio calls [s], interleaved."""
    setup = build(load_scenario("experiment1").with_values(**{"robot.name": robot_name}))
    plant = setup.plant
    assert isinstance(plant, Plant)
    model, data, q0 = plant.robot.model, plant.robot.data, plant.q.copy()
    v_ref = np.zeros(setup.robot.n)
    displacement = np.zeros(model.nv)

    def step() -> None:
        plant.q = q0
        plant.step(v_ref)

    def pinocchio_calls() -> None:
        plant_step_calls(model, data, q0, displacement, displacement)

    step_time, calls, _ = _interleaved(step, pinocchio_calls)
    return step_time, calls


def reading_and_controller_times() -> tuple[float, float]:
    """Median time of one sensor reading and of one public controller step [s], reference robot.

    The reading (:meth:`Sensing.read`: encoders, velocity filter, odometry, gyro) on a moving
    plant; the step (:meth:`pbvs_pin.Controller.step`) without a new frame, predicting the
    newest one, as most of the loop's steps are.
    """
    setup = build(load_scenario("experiment1"))
    sensing, plant = Sensing(setup), setup.plant
    v_ref = np.full(setup.robot.n, 0.1)
    for _ in range(20):
        plant.step(v_ref)
    clock = iter(np.arange(1, 10**7) * 1e-3)
    sensing.read(0.0)
    reading = statistics.median(
        mean_time(lambda: sensing.read(next(clock))) for _ in range(REPEATS)
    )
    control, q, v = setup.control, plant.q.copy(), np.zeros(setup.robot.n)
    placement = setup.model.camera_pose(q)
    points, depths = setup.model.camera.project_world(placement, setup.target.centres(0.0))
    control.step(0.0, q, v, CameraFrame.seen(0.0, points, depths))
    clock = iter(np.arange(1, 10**7) * 1e-3)
    step = statistics.median(
        mean_time(lambda: control.step(next(clock), q, v)) for _ in range(REPEATS)
    )
    assert control.tracker.predicting
    return reading, step


def main() -> None:
    """Print the measurements."""
    print(f"{'robot':<16}{'n':>3}{'control step [us]':>20}{'pinocchio calls [us]':>23}{'ratio':>8}")
    steps = {}
    for name in ("pioneer_cyton", "pioneer_xarm7"):
        step, calls, ratio, compiled, no_op = control_step_ratio(name)
        steps[name] = (step, calls, compiled, no_op)
        n = build(load_scenario("experiment1").with_values(**{"robot.name": name})).robot.n
        print(f"{name:<16}{n:>3}{step * 1e6:>20.1f}{calls * 1e6:>23.1f}{ratio:>8.2f}")
    print("\nwhere the control step goes [us], and its ratio with no arithmetic at all:")
    print(f"{'robot':<16}{'pinocchio':>10}{'python glue':>13}{'arguments':>11}"
          f"{'arithmetic':>12}{'floor ratio':>13}")  # fmt: skip
    for name, (step, calls, compiled, no_op) in steps.items():
        glue = step - calls - compiled
        floor = (calls + glue + no_op) / calls
        print(f"{name:<16}{calls * 1e6:>10.2f}{glue * 1e6:>13.2f}{no_op * 1e6:>11.2f}"
              f"{(compiled - no_op) * 1e6:>12.2f}{floor:>12.2f}x")  # fmt: skip
    factor, _ = closed_loop_real_time_factor()
    print(f"closed loop, 1 kHz controller, pioneer_cyton: {factor:.1f}x real time")
    print("\ncost per simulated second against the arm's joints (Panda, camera on link 3 ... 7):")
    print(f"{'arm joints':>10}{'n':>4}{'cost [ms per s]':>17}{'real time':>11}{'valid':>7}")
    for joints in range(3, 8):
        values = panda_truncated(joints)
        n = build(load_scenario("experiment1").with_values(**values)).robot.n
        dof_factor, valid = closed_loop_real_time_factor(5.0, **values)
        print(f"{joints:>10}{n:>4}{1e3 / dof_factor:>17.1f}{dof_factor:>10.1f}x{valid:>7.2f}")
    plant_step, plant_calls = plant_step_times("pioneer_cyton")
    control_step, control_calls, _, _ = steps["pioneer_cyton"]
    reading, controller = reading_and_controller_times()
    plant_floor = plant_calls
    loop = 1e-3 / factor
    print("\nwhere a simulated millisecond goes, pioneer_cyton (one control and plant step) [us]:")
    rows = (
        ("controller step: its Pinocchio calls", control_calls),
        ("controller step: its compiled step's glue and kernel", control_step - control_calls),
        ("controller step: checks, encoder history, tracker, command", controller - control_step),
        ("plant step: its Pinocchio calls", plant_floor),
        ("plant step: the rest (glue, compiled servo kernel)", plant_step - plant_calls),
        ("sensing: encoders, velocity filter, odometry, gyro", reading),
        (
            "loop: the rest (camera, frames, log, Python, cache misses)",
            loop - controller - plant_step - reading,
        ),
        ("total (the closed loop above)", loop),
        ("floor: the Pinocchio calls alone", control_calls + plant_floor),
    )  # fmt: skip
    for label, value in rows:
        print(f"  {label:<66}{value * 1e6:>7.2f}")
    print(f"  the floor allows at most {1e-3 / (control_calls + plant_floor):.0f}x real time")


if __name__ == "__main__":
    main()
