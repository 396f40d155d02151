"""The closed loop of the paper's Fig. 3, simulated.

Data flows one way at every control step: camera frames (after latency) and encoders ->
feature error, ``J`` and ``J_o`` from the *controller's* model -> target velocity estimate ->
secondary objectives -> kinematic controller (eq. 34) -> dynamic compensation (eq. 20) ->
plant (eq. 1 with the *true* model), integrated at its own step.
"""

from __future__ import annotations

import time as wallclock
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from pbvs_pin.camera import CameraIntrinsics
from pbvs_pin.catalogue import build_robot
from pbvs_pin.control.compensation import Compensation, DynamicCompensator
from pbvs_pin.control.ibvs import ClassicIbvs
from pbvs_pin.control.kinematic import PassivityController, ServoGains
from pbvs_pin.control.secondary import (
    ArmPosture,
    JointLimitAvoidance,
    ObstacleAvoidance,
    SecondaryInput,
    SecondaryObjective,
    secondary_vector,
)
from pbvs_pin.control.step import FusedControlStep
from pbvs_pin.dynamics import VelocityLoop
from pbvs_pin.estimation import AlphaBetaFilter
from pbvs_pin.features import ImageMeasurement, TwoSphereFeatures
from pbvs_pin.manipulability import max_manipulability_posture
from pbvs_pin.plant import Plant
from pbvs_pin.robot import MobileManipulator
from pbvs_pin.sim.log import RunLog, RunRecorder
from pbvs_pin.sim.obstacles import (
    BoxObstacle,
    CircleObstacle,
    Laser,
    Obstacle,
    footprint_points,
)
from pbvs_pin.sim.scenario import Scenario, check
from pbvs_pin.sim.targets import LineThenStop, Still, TargetMotion, TwoSphereTarget, Weave
from pbvs_pin.sim.vision import CameraSensor, Frame


def _motion(scenario: Scenario) -> TargetMotion:
    spec = scenario["motion"]
    velocity = tuple(spec["velocity"])
    if spec["kind"] == "line_then_stop":
        return LineThenStop(velocity, spec["stop_time"])
    if spec["kind"] == "weave":
        return Weave(velocity, tuple(spec["amplitude"]), spec["frequency"], spec["stop_time"])
    return Still()


def _obstacles(scenario: Scenario) -> list[Obstacle]:
    built: list[Obstacle] = []
    for i, table in enumerate(scenario.obstacles):
        fields = {k: v for k, v in table.items() if k != "kind"}
        kind = CircleObstacle if table["kind"] == "circle" else BoxObstacle
        built.append(check(scenario, f"obstacles[{i}]", lambda k=kind, f=fields: k(**f)))
    return built


def solve_target_start(
    robot: MobileManipulator,
    q: np.ndarray,
    features: TwoSphereFeatures,
    separation: float,
    xi0: np.ndarray,
) -> np.ndarray:
    """Upper sphere centre [m] whose features at ``q`` equal ``xi0`` [px].

    Least squares from a point 1 m ahead of the camera; the image of two vertically aligned
    spheres fixes all three coordinates once their separation is known.
    """
    pose = robot.camera_pose(q)
    guess = pose.act(np.array([0.0, 0.0, 1.0]))

    def residual(top: np.ndarray) -> np.ndarray:
        centres = np.array([top, top - [0.0, 0.0, separation]])
        image, _ = robot.camera.project_world(pose, centres, min_depth=1e-3)
        return image.reshape(-1)[features.rows] - xi0

    return least_squares(residual, guess, xtol=1e-12, ftol=1e-12).x


@dataclass
class Setup:
    """Everything a run is built from (true and controller-side objects)."""

    scenario: Scenario
    robot: MobileManipulator
    model: MobileManipulator
    plant: Plant
    target: TwoSphereTarget
    features: TwoSphereFeatures
    sensor: CameraSensor
    controller: PassivityController
    compensator: DynamicCompensator
    objectives: list[SecondaryObjective]
    obstacles: list[Obstacle]
    laser: Laser
    posture_target: np.ndarray
    xi_d: np.ndarray
    estimator: AlphaBetaFilter


def build(scenario: Scenario) -> Setup:
    """Build the true robot, the controller's model and every block of the loop.

    Raises:
        ScenarioError: If a value is invalid for this robot, or the target is not visible
            at the start.
    """
    spec = scenario["camera"]
    camera = check(
        scenario,
        "camera",
        lambda: CameraIntrinsics(spec["focal_px"], spec["width"], spec["height"]),
    )
    robot = check(scenario, "robot.name", lambda: build_robot(scenario["robot"]["name"], camera))
    errors = scenario["model_error"]
    model = robot.with_model_error(errors["kinematic_scale"], errors["mass_scale"])
    q0 = robot.home()
    if scenario["robot"]["initial_arm"] is not None:
        q0 = check(
            scenario,
            "robot.initial_arm",
            lambda: robot.with_arm_positions(q0, scenario["robot"]["initial_arm"]),
        )
    plant = Plant(
        robot, VelocityLoop.from_time_constants(robot), q0, scenario["simulation"]["plant_dt"]
    )
    target_spec = scenario["target"]
    features = TwoSphereFeatures(target_spec["diameter"])
    xi0 = np.asarray(target_spec["xi0"], dtype=float)
    top = solve_target_start(robot, q0, features, target_spec["separation"], xi0)
    target = TwoSphereTarget(
        top, target_spec["diameter"], target_spec["separation"], _motion(scenario)
    )
    _check_start_visible(scenario, robot, q0, target, features, xi0)
    rng = np.random.default_rng(scenario["simulation"]["seed"])
    sensor = CameraSensor(
        camera, target.diameter, spec["rate"], spec["latency"], spec["noise_px"], rng
    )
    controller = _controller(scenario, model)
    comp = scenario["compensation"]
    compensator = check(
        scenario,
        "compensation",
        lambda: DynamicCompensator(
            model,
            VelocityLoop.from_time_constants(model),
            Compensation(comp["mode"]),
            _vector(scenario, "compensation.k_d", comp["k_d"], model.n),
            comp["derivative_time_constant"],
        ),
    )
    posture_target = max_manipulability_posture(model)
    objectives = _objectives(scenario, model, posture_target)
    gains = scenario["estimator"]
    estimator = check(scenario, "estimator", lambda: AlphaBetaFilter(gains["alpha"], gains["beta"]))
    laser_spec = scenario["laser"]
    laser = Laser(laser_spec["field_of_view"], int(laser_spec["beams"]), laser_spec["max_range"])
    return Setup(
        scenario, robot, model, plant, target, features, sensor, controller, compensator,
        objectives, _obstacles(scenario), laser, posture_target,
        np.asarray(target_spec["xi_d"], dtype=float),
        estimator,
    )  # fmt: skip


def _vector(scenario: Scenario, field: str, values: list, n: int) -> np.ndarray:
    """A per-dof vector given as 1 or n values, or a ScenarioError."""
    array = np.asarray(values, dtype=float)
    if array.size == 1:
        return np.full(n, float(array[0]))
    if array.size != n:
        raise scenario.error(field, f"expected 1 or {n} values for this robot, got {array.size}")
    return array


def _controller(scenario: Scenario, model: MobileManipulator) -> PassivityController:
    spec = scenario["controller"]
    n = model.n
    gains = check(
        scenario,
        "controller",
        lambda: ServoGains(
            k=tuple(_vector(scenario, "controller.k", spec["k"], 3)),
            k1=tuple(_vector(scenario, "controller.k1", _per_dof(spec["k1"], model), n)),
            k2=tuple(_vector(scenario, "controller.k2", _per_dof(spec["k2"], model), n)),
            feature_scale=spec["feature_scale"],
            weights=_weights(scenario, spec["weights"], n),
            use_pseudoinverse_feedback=spec["feedback"] == "pseudoinverse",
        ),
    )
    if spec["law"] == "ibvs":
        return ClassicIbvs(spec["ibvs_gain"], model.velocity_limits, gains)
    return PassivityController(gains, model.velocity_limits)


def _per_dof(values: list, model: MobileManipulator) -> list:
    """Gains written for the paper's robot (2 base + 3 arm values) fit any robot.

    The base values are kept and the last arm value is repeated for every arm joint.
    """
    if len(values) == 5 and model.n != 5 and model.n_base == 2:
        return [*values[:2], *([values[-1]] * model.n_arm)]
    return values


def _weights(scenario: Scenario, weights: list, n: int) -> tuple:
    """``W`` as a diagonal or a full matrix, checked for size and definiteness."""
    if weights and isinstance(weights[0], list):
        if len(weights) != n or any(len(row) != n for row in weights):
            raise scenario.error("controller.weights", f"expected a {n} x {n} matrix")
        return tuple(tuple(row) for row in weights)
    return tuple(_vector(scenario, "controller.weights", weights, n))


def _objectives(
    scenario: Scenario, model: MobileManipulator, posture_target: np.ndarray
) -> list[SecondaryObjective]:
    spec = scenario["secondary"]
    objectives: list[SecondaryObjective] = []
    if spec["obstacle_avoidance"]:
        objectives.append(
            ObstacleAvoidance(
                spec["k_uobs"],
                spec["k_wobs"],
                spec["d0"],
                spec["impedance_mass"],
                spec["impedance_damping"],
            )
        )
    if spec["posture"]:
        objectives.append(ArmPosture(posture_target, spec["k_lambda"]))
    if spec["joint_limits"]:
        lower, upper = model.arm_position_limits()
        objectives.append(JointLimitAvoidance(lower, upper))
    return objectives


def _check_start_visible(
    scenario: Scenario,
    robot: MobileManipulator,
    q0: np.ndarray,
    target: TwoSphereTarget,
    features: TwoSphereFeatures,
    xi0: np.ndarray,
) -> None:
    """ScenarioError unless both spheres are in front of the camera, in the image, at xi0."""
    image, depths = robot.camera.project_world(robot.camera_pose(q0), target.centres(0.0))
    if np.any(depths <= 0.05):
        raise scenario.error("target.xi0", "the target would be behind the camera at the start")
    if not robot.camera.in_image(image) or not np.allclose(
        image.reshape(-1)[features.rows], xi0, atol=0.5
    ):
        raise scenario.error(
            "target.xi0",
            f"{xi0.tolist()} px is not visible in a {robot.camera.width} x "
            f"{robot.camera.height} px image from the initial configuration",
        )


class Perception:
    """The controller's view of the target: the newest delivered frame, and the estimate."""

    def __init__(self, setup: Setup) -> None:
        self.setup = setup
        spec = setup.scenario["estimator"]
        self.exact = spec["kind"] == "exact"
        self.filter = setup.estimator
        self.measurement: ImageMeasurement | None = None
        self.lost = False

    def take(self, frame: Frame) -> None:
        """Use a delivered frame: keep its measurement and update the filter."""
        if not frame.visible:
            self.lost = True
            return
        self.lost = False
        setup = self.setup
        self.measurement = frame.measurement(setup.model.camera, setup.target.diameter)
        pose = setup.model.camera_pose(frame.q)
        depths = self.measurement.depths
        f = setup.model.camera.focal_px
        in_camera = np.column_stack([-frame.points * depths[:, None] / f, depths])
        self.filter.update(pose.act(in_camera.mean(axis=0)), frame.time)

    def velocity(self, t: float) -> np.ndarray:
        """``phat_dot``: the filter's estimate, or the truth for an "exact" estimator."""
        if self.exact:
            return self.setup.target.motion.velocity(t)
        return self.filter.velocity


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
) -> RunLog:
    """Run one scenario and return its log.

    Args:
        scenario: A validated scenario.
        progress: Show a progress bar (tqdm) on stderr.
        observer: Called with a :class:`Snapshot` at every logged instant (a live view).

    Returns:
        The run's log (arrays at the log rate) with its setup's key facts.
    """
    setup = build(scenario)
    sim = scenario["simulation"]
    plant_dt = sim["plant_dt"]
    substeps = max(1, round(1.0 / (scenario["controller"]["rate"] * plant_dt)))
    control_dt = substeps * plant_dt
    steps = round(scenario[""]["duration"] / control_dt)
    log_every = max(1, round(1.0 / (sim["log_rate"] * control_dt)))
    laser_every = max(1, round(1.0 / (scenario["laser"]["rate"] * control_dt)))
    footprint = footprint_points(scenario["platform"]["length"], scenario["platform"]["width"])
    recorder = RunRecorder(setup, footprint)
    perception = Perception(setup)
    laser_reading = (float("inf"), 0.0)
    laser_array = np.array(laser_reading)
    fused = None
    if FusedControlStep.supports(setup.controller, setup.objectives):
        fused = FusedControlStep(
            setup.model, setup.features, setup.xi_d, setup.controller, setup.compensator,
            setup.objectives,
        )  # fmt: skip
    started = wallclock.perf_counter()
    bar = _progress(steps, progress, setup.scenario.name)
    for step in range(steps):
        t = step * control_dt
        plant = setup.plant
        if setup.sensor.capture_due(t):
            setup.sensor.capture(
                t, setup.robot.camera_pose(plant.q), setup.target.centres(t), plant.q
            )
        frame = setup.sensor.deliver(t)
        if frame is not None:
            perception.take(frame)
        if setup.obstacles and step % laser_every == 0:
            laser_reading = _laser(setup, plant.q)
            laser_array = np.array(laser_reading)
        seen = perception.measurement is not None and not perception.lost
        if fused is not None and seen:
            _, v_ref, v2 = fused.step(
                plant.q, plant.v, perception.measurement, perception.velocity(t), laser_array,
                control_dt,
            )  # fmt: skip
        else:
            if fused is not None:
                fused.restart_derivative()  # the command derivative restarts after a loss
            output, jacobians = _control_step(
                setup, perception, plant.q, laser_reading, t, control_dt
            )
            v_ref, v2 = setup.compensator.step(plant.q, plant.v, output.u, control_dt)
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
        for _ in range(substeps):
            plant.step(v_ref)
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return recorder.finish(started)


def _snapshot(setup: Setup, perception: Perception, t: float) -> Snapshot:
    """The instant's true state and what the camera saw."""
    seen = perception.measurement is not None and not perception.lost
    points = perception.measurement.points if seen else np.full((2, 2), np.nan)
    xi = setup.features.features(perception.measurement) if seen else np.full(3, np.nan)
    return Snapshot(t, setup.plant.q.copy(), setup.target.centres(t), xi, setup.xi_d, points)


def _progress(steps: int, enabled: bool, name: str):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=steps, desc=name, unit="step", leave=False, mininterval=0.5)


def _laser(setup: Setup, q: np.ndarray) -> tuple[float, float]:
    """``(d, alpha)`` from a scan taken at the laser frame (or the base)."""
    frame = "laser_link" if setup.robot.model.existFrame("laser_link") else None
    pose = setup.robot.frame_pose(q, frame) if frame else setup.robot.base_pose(q)
    yaw = float(np.arctan2(pose.rotation[1, 0], pose.rotation[0, 0]))
    ranges = setup.laser.scan(setup.obstacles, pose.translation[0], pose.translation[1], yaw)
    return setup.laser.nearest(ranges)


def _control_step(
    setup: Setup,
    perception: Perception,
    q: np.ndarray,
    laser: tuple[float, float],
    t: float,
    dt: float,
):
    """Kinematic controller on the newest measurement; zero command when the target is lost."""
    model = setup.model
    secondary_state = SecondaryInput(model.arm_positions(q), laser[0], laser[1], dt)
    secondary = secondary_vector(setup.objectives, secondary_state, model.n_base, model.n)
    measurement = perception.measurement
    if measurement is None or perception.lost:
        return setup.controller.zero_output(setup.features.size), None
    camera_jacobian = model.camera_jacobian_unchecked(q)
    rotation = model.data.oMf[model.camera_frame_id].rotation
    xi, jacobian, object_jacobian = setup.features.jacobians_from_measurement(
        model.camera, measurement, camera_jacobian, rotation.T
    )
    output = setup.controller.step(
        xi - setup.xi_d, jacobian, object_jacobian, perception.velocity(t), secondary
    )
    return output, (jacobian, object_jacobian)
