"""The controller on its own: image points and encoders in, velocity references out.

:class:`Controller` is the paper's control chain of Fig. 3 without a simulator, for a loop of
your own (a real robot's, or a simulator other than :func:`pbvs_pin.simulate`):

1. image points and depths of the target -> features ``xi`` [px] and ``J``, ``J_o`` of
   eq. (3) from the controller's model at the measured configuration;
2. the target's position in the world -> its velocity estimate ``phat_dot`` (alpha-beta
   filter);
3. secondary objectives (obstacle avoidance, arm posture, joint limits) -> ``Lambda`` of
   eq. (16);
4. the kinematic controller of eq. (34) -> command ``u``;
5. dynamic compensation of eq. (20) -> velocity references ``v_ref`` for the low-level loops.

Build it from a scenario, which gives the gains, ``xi_d`` and the objectives::

    controller = Controller.from_scenario(load_scenario("experiment1"), robot)
    command = controller.step(q, v, points, depths, t)   # command.v_ref, shape (n,)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pbvs_pin.control.compensation import DynamicCompensator
from pbvs_pin.control.kinematic import ControlOutput, PassivityController
from pbvs_pin.control.secondary import SecondaryInput, SecondaryObjective, secondary_vector
from pbvs_pin.estimation import VelocityEstimator
from pbvs_pin.features import FeatureSet, ImageMeasurement
from pbvs_pin.robot import MobileManipulator
from pbvs_pin.sim.scenario import Scenario
from pbvs_pin.sim.setup import build
from pbvs_pin.validation import as_array


@dataclass(frozen=True)
class ServoCommand:
    """What one control step gives.

    Attributes:
        v_ref: Velocity references for the low-level loops: platform ``[u [m/s], omega
            [rad/s]]`` then arm joint rates [rad/s or m/s], clipped to the velocity limits.
            Shape (n,). Zero until the target has been seen.
        u: Kinematic command of eq. (34), same units. Shape (n,).
        error: Feature error ``xi - xi_d`` [px]. Shape (r,); NaN until the target is seen.
        target_velocity: Estimated target velocity ``phat_dot`` in the world [m/s]. Shape (3,).
        seen: Whether a measurement of the target was available.
        output: The kinematic controller's output with its diagnostics (storage, damping,
            saturation).
    """

    v_ref: np.ndarray
    u: np.ndarray
    error: np.ndarray
    target_velocity: np.ndarray
    seen: bool
    output: ControlOutput


class Controller:
    """The passivity-based visual servo controller, stepped by your own loop.

    Args:
        robot: The controller's model of the robot.
        features: Feature set (which image coordinates form ``xi``).
        xi_d: Desired features [px]. Shape (r,).
        controller: Kinematic controller (eq. 34).
        compensator: Dynamic compensation (eq. 20).
        objectives: Secondary objectives summed into ``Lambda``.
        estimator: Target velocity estimator fed with the target's position in the world.
    """

    def __init__(
        self,
        robot: MobileManipulator,
        features: FeatureSet,
        xi_d: npt.ArrayLike,
        controller: PassivityController,
        compensator: DynamicCompensator,
        objectives: list[SecondaryObjective],
        estimator: VelocityEstimator,
    ) -> None:
        self.robot = robot
        self.features = features
        self.xi_d = as_array("xi_d", xi_d, (features.size,))
        self.controller = controller
        self.compensator = compensator
        self.objectives = list(objectives)
        self.estimator = estimator
        self.measurement: ImageMeasurement | None = None
        self._previous_t: float | None = None

    @classmethod
    def from_scenario(
        cls, scenario: Scenario, robot: MobileManipulator | None = None
    ) -> Controller:
        """The controller a simulation of ``scenario`` would run.

        Args:
            scenario: Gives ``xi_d``, the gains, the compensation, the secondary objectives,
                the estimator and the model errors of the controller's model.
            robot: The robot, replacing the scenario's ``[robot]`` table (as in
                :func:`pbvs_pin.simulate`).

        Raises:
            ScenarioError: If a value does not fit the robot.
        """
        setup = build(scenario, robot)
        return cls(
            setup.model, setup.features, setup.xi_d, setup.controller, setup.compensator,
            setup.objectives, setup.estimator,
        )  # fmt: skip

    def step(
        self,
        q: npt.ArrayLike,
        v: npt.ArrayLike,
        points: npt.ArrayLike | None,
        depths: npt.ArrayLike | None,
        t: float,
        obstacle: tuple[float, float] = (float("inf"), 0.0),
        target_velocity: npt.ArrayLike | None = None,
    ) -> ServoCommand:
        """One control step.

        Args:
            q: Measured Pinocchio configuration (odometry and encoders). Shape (nq,).
            v: Measured actuated velocity ``[u, omega, arm rates]``. Shape (n,).
            points: Image points ``[u, v]`` of the target points [px] in the paper's
                image coordinates (origin at the image centre, ``u`` to the left, ``v``
                upwards), shape (k, 2); None when no new camera frame arrived, in which case
                the newest measurement is used again.
            depths: Depth of each point along the optical axis [m], shape (k,), e.g. from
                an apparent diameter with :meth:`CameraIntrinsics.depth_from_diameter`;
                None with ``points``.
            t: Time [s]; increasing from call to call.
            obstacle: Shortest laser range ``d`` [m] and its angle ``alpha`` [rad] (clockwise
                from the platform's forward axis) for obstacle avoidance; ``inf``: none.
            target_velocity: The target's velocity in the world [m/s], shape (3,), when you
                know it; the estimator's otherwise.

        Returns:
            The velocity references and the step's diagnostics.

        Raises:
            ShapeError: If an array has the wrong shape.
            NonFiniteValue: If an input is NaN or infinite.
        """
        q = self.robot.check_configuration(q)
        v = self.robot.check_velocity(v)
        t = float(t)
        dt = 0.0 if self._previous_t is None else max(t - self._previous_t, 0.0)
        self._previous_t = t
        if points is not None:
            self._observe(q, points, depths, t)
        if target_velocity is not None:
            velocity = as_array("target_velocity", target_velocity, (3,))
        else:
            velocity = np.asarray(self.estimator.velocity, dtype=float)
        robot = self.robot
        state = SecondaryInput(robot.arm_positions(q), float(obstacle[0]), float(obstacle[1]), dt)
        secondary = secondary_vector(self.objectives, state, robot.n_base, robot.n)
        size = self.features.size
        if self.measurement is None:
            output = self.controller.zero_output(size)
            error = np.full(size, np.nan)
        else:
            rotation = robot.camera_pose(q).rotation
            xi, jacobian, object_jacobian = self.features.jacobians_from_measurement(
                robot.camera, self.measurement, robot.camera_jacobian(q), rotation.T
            )
            error = xi - self.xi_d
            output = self.controller.step(error, jacobian, object_jacobian, velocity, secondary)
        v_ref, _ = self.compensator.step(q, v, output.u, dt)
        return ServoCommand(v_ref, output.u, error, velocity, self.measurement is not None, output)

    def _observe(
        self, q: np.ndarray, points: npt.ArrayLike, depths: npt.ArrayLike | None, t: float
    ) -> None:
        """Keep a new measurement and feed the target's midpoint in the world to the filter."""
        k = self.features.n_points
        points = as_array("points", points, (k, 2))
        depths = as_array("depths", depths, (k,))
        self.measurement = ImageMeasurement(points, depths)
        in_camera = self.robot.camera.back_project(points, depths)
        self.estimator.update(self.robot.camera_pose(q).act(in_camera.mean(axis=0)), t)
