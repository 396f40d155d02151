"""The closed loop of the paper's Fig. 3, simulated.

Data flows one way at every control step: camera frames (after latency) and the robot's
sensors (encoders, wheel odometry, laser: :mod:`pbvs_pin.sim.sensing`) -> feature error,
``J`` and ``J_o`` from the *controller's* model -> target velocity estimate -> secondary
objectives -> kinematic controller (eq. 34) -> dynamic compensation (eq. 20) -> plant (eq. 1
with the *true* model), integrated at its own step. The camera sees the true scene from the
true camera pose; the controller only ever gets the frames and the sensors' readings.
"""

from __future__ import annotations

import time as wallclock
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pbvs_pin.compile_cache import compile_notice
from pbvs_pin.control.secondary import SecondaryInput, secondary_vector
from pbvs_pin.control.step import FusedControlStep
from pbvs_pin.control.upright import upright_row
from pbvs_pin.exceptions import RunInterrupted
from pbvs_pin.plant import Plant
from pbvs_pin.robot import MobileManipulator
from pbvs_pin.sim.log import RunLog, RunRecorder
from pbvs_pin.sim.obstacles import footprint_points
from pbvs_pin.sim.perception import Perception
from pbvs_pin.sim.scenario import Scenario
from pbvs_pin.sim.sensing import Sensing
from pbvs_pin.sim.setup import Setup, build


@dataclass(frozen=True)
class Snapshot:
    """What a live viewer needs at one logged instant.

    Attributes:
        t: Time [s].
        q: True configuration. Shape (nq,).
        centres: True sphere centres [m]. Shape (2, 3).
        xi: Measured features [px] (NaN when the target is not seen). Shape (r,).
        xi_d: Desired features [px]. Shape (r,).
        points: Measured image points ``[u, v]`` of both spheres [px] (NaN when unseen).
            Shape (2, 2).
    """

    t: float
    q: np.ndarray
    centres: np.ndarray
    xi: np.ndarray
    xi_d: np.ndarray
    points: np.ndarray


def simulate(
    scenario: Scenario,
    progress: bool = False,
    observer: Callable[[Snapshot], None] | None = None,
    robot: MobileManipulator | None = None,
) -> RunLog:
    """Run one scenario and return its log.

    With ``progress``, a bar labelled with the scenario, robot and law goes to stderr, preceded
    by one line (:func:`pbvs_pin.compile_cache.compile_notice`) when the control kernels are not
    compiled yet.

    Args:
        scenario: A validated scenario.
        progress: Show a progress bar (tqdm) on stderr.
        observer: Called with a :class:`Snapshot` at every logged instant (a live view).
        robot: A built robot that replaces the scenario's ``[robot]`` table; see
            :func:`pbvs_pin.sim.setup.build`.

    Returns:
        The run's log (arrays at the log rate) with its setup's key facts.

    Raises:
        RunInterrupted: On Ctrl-C; it carries the run so far, its ``meta["interrupted"]``
            true (None when nothing was recorded yet).
    """
    setup = build(scenario, robot)
    plant_dt = scenario.simulation.plant_dt
    substeps = max(1, round(1.0 / (scenario.controller.rate * plant_dt)))
    control_dt = substeps * plant_dt
    steps = round(scenario.duration / control_dt)
    log_every = max(1, round(1.0 / (scenario.simulation.log_rate * control_dt)))
    laser_every = max(1, round(1.0 / (scenario.laser.rate * control_dt)))
    footprint = footprint_points(scenario.platform.length, scenario.platform.width)
    sensing = Sensing(setup)
    recorder = RunRecorder(setup, footprint, sensing)
    perception = Perception(setup)
    laser_reading = (float("inf"), 0.0)
    laser_array = np.array(laser_reading)
    fused = None
    if FusedControlStep.supports(setup.controller, setup.objectives):
        fused = FusedControlStep(
            setup.model, setup.features, setup.xi_d, setup.controller, setup.compensator,
            setup.objectives,
        )  # fmt: skip
    shared = fused is not None and shares_dynamics(setup)
    if progress:
        compile_notice()
    started = wallclock.perf_counter()
    bar = _progress(steps, progress, progress_label(setup))
    try:
        for step in range(steps):
            t = step * control_dt
            plant = setup.plant
            sensing.read(t)
            q, v = sensing.q, sensing.v  # what the controller knows of the robot
            if setup.sensor.capture_due(t):  # the true camera sees the true target
                setup.sensor.capture(
                    t, setup.robot.camera_pose(plant.q), setup.target.centres(t), q
                )
            setup.sensor.stamp(t, q)  # frames whose exposure delay has elapsed
            frame = setup.sensor.deliver(t)
            if frame is not None:
                perception.take(frame)
            if setup.obstacles and step % laser_every == 0:
                laser_reading = sensing.laser_reading()
                laser_array = np.array(laser_reading)
            measurement = perception.current(t, q)
            seen = measurement is not None
            if fused is not None and seen:
                _, v_ref, v2 = fused.step(
                    q, v, measurement, perception.velocity(t), laser_array, control_dt
                )
            else:
                if fused is not None:
                    fused.restart_derivative()  # the command derivative restarts after a loss
                output, jacobians = _control_step(
                    setup, perception, q, laser_reading, t, control_dt
                )
                v_ref, v2 = setup.compensator.step(q, v, output.u, control_dt)
            if step % log_every == 0:
                if fused is not None and seen:
                    output, jacobians = fused.output()
                recorder.record(
                    t=t,
                    output=output,
                    jacobians=jacobians,
                    perception=perception,
                    v_ref=v_ref,
                    v2=v2,
                    laser=laser_reading,
                )
                if observer is not None:
                    observer(_snapshot(setup, perception, t))  # fmt: skip
            terms = fused.terms_at(plant.q, plant.v) if shared and seen else None
            if terms is not None:
                plant.step(v_ref, terms)  # on the controller's Pinocchio terms: the same numbers
            for _ in range(substeps - (terms is not None)):
                plant.step(v_ref)
            if bar is not None:
                bar.update(1)
    except KeyboardInterrupt as interrupt:
        if bar is not None:
            bar.close()
        log = recorder.finish(started, interrupted=True) if recorder.rows["t"] else None
        raise RunInterrupted(log) from interrupt
    if bar is not None:
        bar.close()
    return recorder.finish(started)


def shares_dynamics(setup: Setup) -> bool:
    """Whether the plant may step on the controller's Pinocchio terms.

    Only a Pinocchio plant whose model equals the controller's, value for value (no
    ``model_error``), and with the same ``S``: then ``crba``, ``nonLinearEffects`` and the
    gravity at the same ``(q, v)`` are the same numbers, computed once per control step.
    """
    plant = setup.plant
    return (
        isinstance(plant, Plant)
        and setup.model.model == plant.robot.model
        and np.array_equal(setup.model.selection, plant.robot.selection)
    )


def _snapshot(setup: Setup, perception: Perception, t: float) -> Snapshot:
    """The instant's true state and what the camera saw."""
    seen = perception.measurement is not None and not perception.lost
    points = perception.measurement.points if seen else np.full((2, 2), np.nan)
    xi = setup.features.features(perception.measurement) if seen else np.full(3, np.nan)
    return Snapshot(t, setup.plant.q.copy(), setup.target.centres(t), xi, setup.xi_d, points)


def progress_label(setup: Setup) -> str:
    """A run's progress label: scenario, robot (a file by its name) and law."""
    robot = setup.robot_meta()["robot"]
    if "/" in robot or "\\" in robot:
        robot = Path(robot).name
    return f"{setup.scenario.name} {robot} {setup.scenario.controller.law}"


def _progress(steps: int, enabled: bool, name: str):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=steps, desc=name, unit="step", leave=False, mininterval=0.5)


def _control_step(
    setup: Setup,
    perception: Perception,
    q: np.ndarray,
    laser: tuple[float, float],
    t: float,
    dt: float,
):
    """Kinematic controller on the current measurement; zero command when there is none."""
    model = setup.model
    secondary_state = SecondaryInput(model.arm_positions(q), laser[0], laser[1], dt)
    secondary = secondary_vector(setup.objectives, secondary_state, model.n_base, model.n)
    measurement = perception.current(t, q)
    if measurement is None:
        return setup.controller.zero_output(setup.features.size), None
    camera_jacobian = model.camera_jacobian_unchecked(q)
    rotation = model.data.oMf[model.camera_frame_id].rotation
    xi, jacobian, object_jacobian = setup.features.jacobians_from_measurement(
        model.camera, measurement, camera_jacobian, rotation.T
    )
    output = setup.controller.step(
        xi - setup.xi_d, jacobian, object_jacobian, perception.velocity(t), secondary,
        upright_row(rotation, camera_jacobian),
    )  # fmt: skip
    return output, (jacobian, object_jacobian)
