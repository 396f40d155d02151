"""Everything a run is built from: the true robot, the controller's model and every block.

:func:`build` turns a parsed :class:`~pbvs_pin.sim.scenario.Scenario` into a :class:`Setup`.
The scenario's sections have checked every value on their own; what only the robot can reveal
(the robot itself, per-dof vector lengths, the size of ``W``, the arm's start, the target's
visibility at the start) is checked here and reported as a ScenarioError naming the field.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.optimize import least_squares

from pbvs_pin.bringup.robot_spec import arm_posture
from pbvs_pin.control.kinematic import PassivityController
from pbvs_pin.control.secondary import SecondaryObjective
from pbvs_pin.control.settings import ControllerSettings
from pbvs_pin.controller import Controller
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.model.servo import ServoModel
from pbvs_pin.perception.estimation import VelocityEstimator
from pbvs_pin.perception.features import FeatureSet, TwoSphereFeatures
from pbvs_pin.plant.pinocchio_plant import Plant
from pbvs_pin.sim.obstacles import Laser, Obstacle
from pbvs_pin.sim.scenario import Scenario
from pbvs_pin.sim.sections import MotionSection
from pbvs_pin.sim.targets import LineThenStop, Still, TargetMotion, TwoSphereTarget, Weave
from pbvs_pin.sim.vision import FAULT_STREAM, CameraFaults, CameraSensor

if TYPE_CHECKING:
    from pbvs_pin.plant.mujoco_plant import MujocoPlant
    from pbvs_pin.sim.rendered_camera import RenderedCamera

SETTLE_TIME = 0.5
"""Time [s] a MuJoCo plant stands still before ``t = 0``, its wheels settling on the floor."""


def _motion(spec: MotionSection) -> TargetMotion:
    velocity = tuple(spec.velocity)
    if spec.kind == "line_then_stop":
        return LineThenStop(velocity, spec.stop_time)
    if spec.kind == "weave":
        return Weave(velocity, tuple(spec.amplitude), spec.frequency, spec.stop_time)
    return Still()


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
    """Everything a run is built from: the true robot and world, and the controller.

    Attributes:
        control: The public controller the loop steps (:class:`pbvs_pin.Controller`).
    """

    scenario: Scenario
    robot: MobileManipulator
    model: MobileManipulator
    plant: Plant | MujocoPlant
    target: TwoSphereTarget
    sensor: CameraSensor
    control: Controller
    obstacles: list[Obstacle]
    laser: Laser
    robot_given: bool = False

    @property
    def features(self) -> TwoSphereFeatures:
        """The controller's feature set."""
        return self.control.features

    @property
    def xi_d(self) -> np.ndarray:
        """Desired features [px]. Shape (r,)."""
        return self.control.xi_d

    @property
    def posture_target(self) -> np.ndarray:
        """``theta_d`` of eq. (19). Shape (n_arm,)."""
        return self.control.posture_target

    @property
    def law(self) -> PassivityController:
        """The kinematic controller (eq. 34 or the IBVS baseline)."""
        return self.control.law

    @property
    def objectives(self) -> list[SecondaryObjective]:
        """The controller's secondary objectives."""
        return self.control.objectives

    @property
    def estimator(self) -> VelocityEstimator:
        """The controller's target-velocity filter."""
        return self.control.tracker.estimator

    def robot_meta(self) -> dict[str, Any]:
        """The robot in a log's meta: its label, table and the inertias changed on loading.

        ``robot`` is a label; ``robot_table`` is the ``[robot]`` table the robot was built
        from (None for a robot given from Python, whose label is its source), and
        ``robot_source`` the file it was read from (a robot file, or the scenario);
        ``inertia_repaired`` lists the links whose inertia ``repair_inertia`` changed,
        ``inertia_from_geometry`` those that ``geometry_density`` gave an inertia.
        """
        repaired = {
            "inertia_repaired": list(self.robot.repaired_inertias),
            "inertia_from_geometry": list(self.robot.filled_inertias),
        }
        if self.robot_given:
            return {"robot": self.robot.source, "robot_table": None, **repaired}
        return {
            "robot": self.scenario.robot.label,
            "robot_table": self.scenario.robot.to_toml(),
            "robot_source": self.scenario.robot.source,
            **repaired,
        }


def build(
    scenario: Scenario,
    robot: MobileManipulator | None = None,
    objectives: Sequence[SecondaryObjective] = (),
    features: FeatureSet | None = None,
    xi_d: np.ndarray | None = None,
) -> Setup:
    """Build the true robot, the controller's model and every block of the loop.

    Args:
        scenario: A validated scenario.
        robot: A built robot that replaces the scenario's whole ``[robot]`` table (its
            ``home_arm`` is the start; ``initial_arm`` and ``home`` are not applied). The
            plant and the controller's model derive from it as from the table's robot. The
            camera is the scenario's ``[camera]``: a robot with other intrinsics is used
            through a shallow copy that carries them; the robot itself is not modified.
        objectives: The user's own secondary objectives, added to the scenario's in the
            controller (:class:`~pbvs_pin.controller.Controller`).
        features: The controller's feature set, on the two sphere centres, and ``xi_d`` its
            desired features [px] (shape (r,)), checked by :func:`pbvs_pin.simulate`; None:
            the paper's ``[u1, v1, v2]`` and the scenario's ``target.xi_d``.
        xi_d: See ``features``.

    Raises:
        ScenarioError: If a value is invalid for this robot, or the target is not visible
            at the start.
    """
    camera = scenario.camera.intrinsics()
    robot_given = robot is not None
    if robot is None:
        robot = scenario.robot.build(camera)
        q0 = _start(scenario, robot)
    else:
        if robot.camera != camera:
            robot = copy.copy(robot)
            robot.camera = camera
        q0 = robot.home()
    model = robot.with_model_error(scenario.model_error.kinematic_scale)
    if scenario.camera.model == "rendered":
        import pbvs_pin.sim.render  # noqa: F401  (sets MUJOCO_GL before a MuJoCo plant loads MuJoCo)
    plant = _plant(scenario, robot, q0)
    target_spec = scenario.target
    placing = TwoSphereFeatures(target_spec.diameter)  # target.xi0 is the paper's features
    xi0 = np.asarray(target_spec.xi0, dtype=float)
    top = solve_target_start(robot, q0, placing, target_spec.separation, xi0)
    target = TwoSphereTarget(
        top, target_spec.diameter, target_spec.separation, _motion(scenario.motion)
    )
    _check_start_visible(scenario, robot, q0, target, placing, xi0)
    rng = np.random.default_rng(scenario.simulation.seed)
    spec = scenario.camera
    faults = CameraFaults(
        spec.drop_probability, spec.occlusion_starts, spec.occlusion_rate,
        spec.occlusion_duration, spec.latency_jitter, spec.exposure_delay,
    )  # fmt: skip
    fault_rng = np.random.default_rng([scenario.simulation.seed, FAULT_STREAM])
    latency = spec.delivery_latency
    renderer = None
    if spec.model == "rendered":
        renderer = _rendered_camera(scenario, robot, plant, target)
    sensor = CameraSensor(
        camera, target.diameter, spec.rate, latency, spec.noise_px, rng, faults, fault_rng,
        renderer,
    )  # fmt: skip
    control = Controller(
        model, ControllerSettings.from_scenario(scenario), announce=False, objectives=objectives,
        features=features, xi_d=xi_d,
    )  # fmt: skip
    laser_spec = scenario.laser
    laser = Laser(
        laser_spec.field_of_view, int(laser_spec.beams), laser_spec.max_range,
        laser_spec.range_noise, laser_spec.range_resolution,
    )  # fmt: skip
    return Setup(
        scenario, robot, model, plant, target, sensor, control, list(scenario.obstacles), laser,
        robot_given,
    )  # fmt: skip


def _plant(scenario: Scenario, robot: MobileManipulator, q0: np.ndarray) -> Plant | MujocoPlant:
    """The true robot's physics (``plant.engine``), as ``[model_error]`` makes it.

    The servos were tuned on the nominal robot (the URDF's masses, the controller's model):
    their stiffness ``K = sum |M_v,nominal| / T`` is ``sum |M_v,true| / (s T)`` on a robot whose
    masses are ``mass_scale = s`` times the nominal, so the true plant's servos have time
    constants ``s T``. A ``payload`` at the camera frame is unknown to them: their stiffness
    and gravity cancellation stay those of the robot without it.
    """
    errors = scenario.model_error
    servo = ServoModel.from_robot(robot)
    if errors.mass_scale != 1.0:
        servo = replace(servo, time_constants=errors.mass_scale * servo.time_constants)
    dt = scenario.simulation.plant_dt
    if scenario.plant.engine == "mujoco":
        from pbvs_pin.plant.mujoco_plant import MujocoPlant  # MuJoCo is loaded only when asked for

        return MujocoPlant(
            robot, servo, q0, dt, mass_scale=errors.mass_scale, payload=errors.payload,
            settle=SETTLE_TIME,
        )  # fmt: skip
    tuned = robot if errors.mass_scale == 1.0 else robot.with_model_error(1.0, errors.mass_scale)
    if errors.payload == 0:
        return Plant(tuned, servo, q0, dt)
    return Plant(tuned.with_payload(errors.payload), servo, q0, dt, tuned=tuned)


def _rendered_camera(
    scenario: Scenario,
    robot: MobileManipulator,
    plant: Plant | MujocoPlant,
    target: TwoSphereTarget,
) -> RenderedCamera:
    """The rendered camera of ``camera.model = "rendered"``, reading the true plant."""
    from pbvs_pin.perception.detection import detector_from  # OpenCV and MuJoCo only when rendering
    from pbvs_pin.sim.render import SceneRenderer, warn_self_view
    from pbvs_pin.sim.rendered_camera import RENDER_STREAM, ImageEffects, RenderedCamera

    spec = scenario.camera
    camera = robot.camera
    effects = ImageEffects(
        spec.image_noise, spec.exposure_time, spec.light_change_time, spec.light_change_scale
    )
    scene = SceneRenderer(robot, camera, target.diameter, list(scenario.obstacles))
    q = plant.q
    shares = scene.robot_in_view(q, robot.camera_pose(q), target.centres(0.0))
    warn_self_view(shares, robot.source)
    rng = np.random.default_rng([scenario.simulation.seed, RENDER_STREAM])
    return RenderedCamera(
        robot, scene, plant, target, detector_from(spec.detector, camera), effects, rng
    )


def _start(scenario: Scenario, robot: MobileManipulator) -> np.ndarray:
    """Initial configuration: home, with the scenario's arm positions if it gives them."""
    q0 = robot.home()
    arm = scenario.robot.initial_arm
    if arm is None:
        return q0
    return robot.with_arm_positions(
        q0, arm_posture(scenario.source, "robot.initial_arm", robot, arm)
    )


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
