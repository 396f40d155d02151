"""The closed loop of the paper's Fig. 3, simulated around the public controller.

The loop holds the true world (the plant, the target, the obstacles) and the robot's sensors;
:class:`pbvs_pin.Controller` is the control. At every control step the loop hands the
controller what a robot's driver would: the encoder and odometry readings with the time
(:mod:`pbvs_pin.sim.sensing`), the camera frame that arrived (after its latency, with its
capture time, or "target not visible"; :mod:`pbvs_pin.sim.vision`) and the laser reading
when a scan arrived, and applies the velocity references it returns to the plant (eq. 1 with
the *true* model), integrated at its own step. The camera sees the true scene from the true
camera pose; the controller only ever gets the frames and the sensors' readings.
"""

from __future__ import annotations

import time as wallclock
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from pbvs_pin.compile_cache import announce_compiles
from pbvs_pin.control.secondary import SecondaryObjective, user_objectives
from pbvs_pin.control.tracking import TargetTracker
from pbvs_pin.exceptions import RunInterrupted, ShapeError
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.perception.camera_frame import CameraFrame
from pbvs_pin.perception.features import FeatureSet, checked_feature_set
from pbvs_pin.sim.log import RunLog, RunRecorder
from pbvs_pin.sim.obstacles import footprint_points
from pbvs_pin.sim.scenario import Scenario
from pbvs_pin.sim.sensing import Sensing
from pbvs_pin.sim.setup import Setup, build
from pbvs_pin.sim.targets import TARGET_POINTS
from pbvs_pin.sim.vision import Frame
from pbvs_pin.validation import as_instance

if TYPE_CHECKING:  # pragma: no cover - typing only
    from pbvs_pin.perception.detection import CameraImage


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
        image: The rendered camera's newest image with its detections (the robot's-eye
            view); None with the points camera.
    """

    t: float
    q: np.ndarray
    centres: np.ndarray
    xi: np.ndarray
    xi_d: np.ndarray
    points: np.ndarray
    image: CameraImage | None = None


def simulate(
    scenario: Scenario,
    progress: bool = False,
    observer: Callable[[Snapshot], None] | None = None,
    robot: MobileManipulator | None = None,
    objectives: Sequence[SecondaryObjective] = (),
    features: FeatureSet | None = None,
    xi_d: npt.ArrayLike | None = None,
) -> RunLog:
    """Run one scenario and return its log.

    With ``progress``, a bar labelled with the scenario, robot and law goes to stderr, with one
    line (:func:`pbvs_pin.compile_cache.announce_compiles`) when a control kernel compiles.

    Args:
        scenario: A validated scenario.
        progress: Show a progress bar (tqdm) on stderr.
        observer: Called with a :class:`Snapshot` at every logged instant (a live view).
        robot: A built robot that replaces the scenario's ``[robot]`` table; see
            :func:`pbvs_pin.sim.setup.build`.
        objectives: The user's own secondary objectives
            (:class:`~pbvs_pin.control.secondary.SecondaryObjective` subclasses), added to the
            scenario's in ``Lambda`` (eq. 16); see :class:`pbvs_pin.Controller`.
        features: Your own feature set, built on the target's two sphere centres (upper one
            first, ``n_points = 2``), in place of the paper's ``[u1, v1, v2]``; see
            :class:`pbvs_pin.Controller`. The log's ``xi``, ``xi_true`` and ``xi_d`` are its
            features, and the rules of :mod:`pbvs_pin.study.claims` judge them.
        xi_d: Its desired features [px], shape (r,); required with ``features``.

    Returns:
        The run's log (arrays at the log rate) with its setup's key facts.

    Raises:
        WrongType: If ``scenario`` is not a Scenario (e.g. a name: use ``load_scenario``),
            ``robot`` not a MobileManipulator, or ``objectives`` not a list of
            SecondaryObjective, or ``features`` not a FeatureSet.
        GainError: If ``features`` has no valid rows, or comes without ``xi_d``.
        ShapeError: If ``features`` is not built on two points, or ``xi_d`` has not one
            entry per feature.
        RunInterrupted: On Ctrl-C; it carries the run so far, its ``meta["interrupted"]``
            true (None when nothing was recorded yet).
    """
    scenario = as_instance("scenario", scenario, Scenario)
    robot = None if robot is None else as_instance("robot", robot, MobileManipulator)
    objectives = user_objectives(objectives)
    if features is not None:
        features, xi_d = checked_feature_set(features, xi_d)
        if features.n_points != TARGET_POINTS:
            raise ShapeError("features.n_points", (TARGET_POINTS,), (features.n_points,))
    with announce_compiles(progress):
        return _simulate(scenario, progress, observer, robot, objectives, features, xi_d)


def _simulate(
    scenario: Scenario,
    progress: bool,
    observer: Callable[[Snapshot], None] | None,
    robot: MobileManipulator | None,
    objectives: tuple[SecondaryObjective, ...],
    features: FeatureSet | None,
    xi_d: np.ndarray | None,
) -> RunLog:
    """:func:`simulate`'s run (the same arguments)."""
    setup = build(scenario, robot, objectives, features, xi_d)
    plant_dt = scenario.simulation.plant_dt
    substeps = max(1, round(1.0 / (scenario.controller.rate * plant_dt)))
    control_dt = substeps * plant_dt
    steps = round(scenario.duration / control_dt)
    log_every = max(1, round(1.0 / (scenario.simulation.log_rate * control_dt)))
    laser_every = max(1, round(1.0 / (scenario.laser.rate * control_dt)))
    footprint = footprint_points(scenario.platform.length, scenario.platform.width)
    sensing = Sensing(setup)
    recorder = RunRecorder(setup, footprint, sensing)
    control, sensor = setup.control, setup.sensor
    exact_velocity = scenario.estimator.kind == "exact"
    laser_reading = (float("inf"), 0.0)
    started = wallclock.perf_counter()
    bar = _progress(steps, progress, progress_label(setup))
    try:
        for step in range(steps):
            t = step * control_dt
            plant = setup.plant
            sensing.read(t)
            q, v = sensing.q, sensing.v  # what the controller knows of the robot
            if sensor.capture_due(t):  # the true camera sees the true target
                sensor.capture(t, setup.robot.camera_pose(plant.q), setup.target.centres(t), q)
            sensor.stamp(t, q)  # frames whose exposure delay has elapsed
            frame = sensor.deliver(t)
            scan = None
            if setup.obstacles and step % laser_every == 0:
                laser_reading = sensing.laser_reading()
                scan = laser_reading
            velocity = setup.target.motion.velocity(t) if exact_velocity else None
            command = control.step(t, q, v, _handed_over(setup, frame), scan, velocity)
            if step % log_every == 0:
                output, jacobians = control.diagnostics()
                recorder.record(
                    t=t, output=output, jacobians=jacobians, tracker=control.tracker,
                    target_velocity=command.target_velocity, v_ref=command.v_ref,
                    v2=command.v2, laser=laser_reading,
                )  # fmt: skip
                if observer is not None:
                    observer(_snapshot(setup, control.tracker, t))
            for _ in range(substeps):
                plant.step(command.v_ref)
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


def _handed_over(setup: Setup, frame: Frame | None) -> CameraFrame | None:
    """The simulated camera's frame as a driver hands it over (points, depths or not visible).

    The depths come from the apparent diameters, ``z = f D / d``.
    """
    if frame is None:
        return None
    if not frame.visible:
        return CameraFrame.not_visible(frame.time)
    return CameraFrame.from_diameters(
        frame.time, frame.points, frame.diameters, setup.model.camera, setup.target.diameter
    )


def _snapshot(setup: Setup, tracker: TargetTracker, t: float) -> Snapshot:
    """The instant's true state and what the camera saw."""
    seen = tracker.measurement is not None and not tracker.lost
    points = tracker.measurement.points if seen else np.full((TARGET_POINTS, 2), np.nan)
    xi = setup.features.features(tracker.measurement) if seen else np.full_like(setup.xi_d, np.nan)
    renderer = setup.sensor.renderer
    image = renderer.latest if renderer is not None else None
    return Snapshot(t, setup.plant.q.copy(), setup.target.centres(t), xi, setup.xi_d, points, image)


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
