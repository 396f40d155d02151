"""Checks across the tables of a scenario: what each value allows alone, the run may not.

Each table checks its own keys (:mod:`pbvs_pin.sim.sections`); these checks need two tables
at once and refuse what a user could not have meant, before any robot is built:

- **Features**: ``target.xi0`` and ``target.xi_d`` inside the image (coordinates centred on
  the principal point, ``|u| <= width / 2``, ``|v| <= height / 2``) and ordered: sphere 1 is
  the upper one and ``v`` grows upwards (design notes §2), so ``v1 > v2``.
- **Rates**: the plant step is shorter than the run, the control period and the camera
  period; the control period is a whole number of plant steps (within
  :data:`RATE_TOLERANCE`); the log and laser rates do not exceed the control rate. The loop
  logs and scans at whole numbers of control steps: a log or laser rate that does not divide
  the control rate is rounded to the nearest one, with a :class:`PbvsWarning`. Camera frames
  are captured at the first control step at or after their due time (the camera is not
  synchronised with the controller), so the camera rate need not divide the control rate.
- **Time**: the run lasts at least :data:`MIN_LOG_SAMPLES` log periods; the latency is
  shorter than the run and a second frame is delivered before the run ends (the latency
  defaults to one frame period: :attr:`~pbvs_pin.control.tables.CameraSection.delivery_latency`).
- **Obstacles**: none overlaps the platform's footprint (``[platform]``) at the start, where
  the base stands at the origin with heading 0.

Every refusal is a :class:`~pbvs_pin.exceptions.GainError` whose ``field`` is the dotted key
at fault, which the scenario's parser turns into a ScenarioError naming the file.
"""

from __future__ import annotations

import warnings
from typing import Protocol

import numpy as np

from pbvs_pin.control.tables import CameraSection, ControllerSection, TargetSection
from pbvs_pin.exceptions import GainError, PbvsWarning
from pbvs_pin.sim.obstacles import BoxObstacle, CircleObstacle, footprint_points
from pbvs_pin.sim.sections import LaserSection, PlatformSection, SimulationSection


class ScenarioView(Protocol):
    """What these checks read of a :class:`pbvs_pin.sim.scenario.Scenario`.

    Declared here, not imported, because the scenario's own validation calls these checks.
    """

    source: str
    duration: float
    camera: CameraSection
    target: TargetSection
    controller: ControllerSection
    laser: LaserSection
    platform: PlatformSection
    simulation: SimulationSection
    obstacles: tuple[CircleObstacle | BoxObstacle, ...]


RATE_TOLERANCE = 1e-6
"""Relative distance to a whole number of steps below which a period counts as a multiple."""

MIN_LOG_SAMPLES = 2
"""Fewest log samples a run must produce (the analysis needs a start and an end)."""


def check_consistency(scenario: ScenarioView) -> None:
    """Refuse values that contradict each other (see the module doc).

    Raises:
        GainError: Naming the dotted field at fault in ``field``.
    """
    camera = scenario.camera
    for name in ("xi0", "xi_d"):
        _check_features(f"target.{name}", getattr(scenario.target, name), camera)
    _check_rates(scenario)
    _check_obstacles(scenario)


def _check_features(field: str, xi: tuple[float, ...], camera: CameraSection) -> None:
    """``xi = [u1, v1, v2]`` [px] inside a ``width x height`` image and ``v1 > v2``."""
    width, height = camera.width, camera.height
    u1, v1, v2 = xi
    if abs(u1) > width / 2 or abs(v1) > height / 2 or abs(v2) > height / 2:
        raise GainError(
            f"{list(xi)} px is not visible: outside the {width} x {height} px image (expected "
            f"|u| <= {width / 2:g} and |v| <= {height / 2:g}, centred on the principal point)",
            field,
        )
    if not v1 > v2:
        raise GainError(
            f"expected v1 > v2 (sphere 1 is the upper one and v grows upwards), got v1 = {v1:g}"
            f", v2 = {v2:g}",
            field,
        )


def _whole_steps(period: float, step: float) -> bool:
    """Whether ``period`` is a whole number of ``step`` within :data:`RATE_TOLERANCE`."""
    ratio = period / step
    return abs(ratio - round(ratio)) <= RATE_TOLERANCE * ratio


def _check_rates(scenario: ScenarioView) -> None:
    """Plant step, control, camera, log and laser rates, duration and latency."""
    duration = scenario.duration
    plant_dt = scenario.simulation.plant_dt
    control_rate = scenario.controller.rate
    control_dt = 1.0 / control_rate
    camera = scenario.camera
    latency = camera.delivery_latency
    if plant_dt >= duration:
        raise GainError(
            f"expected a plant step shorter than the run (duration = {duration:g} s), got "
            f"{plant_dt:g} s",
            "simulation.plant_dt",
        )
    if plant_dt >= 1.0 / camera.rate:
        raise GainError(
            f"expected a plant step shorter than the camera period (1/camera.rate = "
            f"{1.0 / camera.rate:g} s), got {plant_dt:g} s",
            "simulation.plant_dt",
        )
    if control_dt < plant_dt * (1 - RATE_TOLERANCE):
        raise GainError(
            f"expected at most 1/plant_dt = {1.0 / plant_dt:g} Hz (one plant step per control "
            f"step), got {control_rate:g} Hz",
            "controller.rate",
        )
    if not _whole_steps(control_dt, plant_dt):
        steps = max(1, round(control_dt / plant_dt))
        raise GainError(
            f"{control_rate:g} Hz is not a whole number of plant steps (plant_dt = {plant_dt:g}"
            f" s gives {control_dt / plant_dt:.4g}); expected e.g. "
            f"{1.0 / (steps * plant_dt):g} Hz",
            "controller.rate",
        )
    for field, rate in (
        ("simulation.log_rate", scenario.simulation.log_rate),
        ("laser.rate", scenario.laser.rate),
    ):
        if rate > control_rate * (1 + RATE_TOLERANCE):
            raise GainError(
                f"expected at most the control rate ({control_rate:g} Hz), got {rate:g} Hz",
                field,
            )
        if not _whole_steps(1.0 / rate, control_dt):
            used = control_rate / round(control_rate / rate)
            warnings.warn(
                f"{scenario.source}: {field} = {rate:g} Hz is not a whole number of control "
                f"steps; rounded to {used:g} Hz",
                PbvsWarning,
                stacklevel=2,
            )
    log_dt = 1.0 / scenario.simulation.log_rate
    if duration < MIN_LOG_SAMPLES * log_dt:
        raise GainError(
            f"expected at least {MIN_LOG_SAMPLES} log periods ({MIN_LOG_SAMPLES * log_dt:g} s "
            f"at simulation.log_rate = {1.0 / log_dt:g} Hz), got {duration:g} s",
            "duration",
        )
    if camera.latency is not None and latency >= duration:  # the default is the rate's fault
        raise GainError(
            f"expected a latency shorter than the run (duration = {duration:g} s), got "
            f"{latency:g} s: no frame would arrive",
            "camera.latency",
        )
    if latency + 1.0 / camera.rate >= duration:
        raise GainError(
            f"{camera.rate:g} Hz delivers at most one frame in {duration:g} s (latency "
            f"{latency:g} s); expected more than {1.0 / (duration - latency):.4g} Hz",
            "camera.rate",
        )


def _check_obstacles(scenario: ScenarioView) -> None:
    """No obstacle overlaps the platform's footprint at the start (base at the origin)."""
    platform = scenario.platform
    boundary = footprint_points(platform.length, platform.width)
    for index, obstacle in enumerate(scenario.obstacles):
        distance = float(np.min(obstacle.signed_distance(boundary)))
        inside = abs(obstacle.x) <= platform.length / 2 and abs(obstacle.y) <= platform.width / 2
        if distance <= 0.0 or inside:
            raise GainError(
                f"overlaps the platform's {platform.length:g} x {platform.width:g} m footprint "
                f"at the start (clearance {distance:.3g} m; the base starts at the origin, "
                "heading +x); expected a positive clearance",
                f"obstacles[{index}]",
            )
