r"""The controller's view of the target: the newest frame, its prediction, the hold, smoothing.

**Prediction** (an extension of the paper). Between the newest frame showing the target
(captured at ``t_k`` with the encoders at ``q_k``) and now ``(t, q)``, the features move by
eq. (3), ``xi_dot = J(q) q_dot + J_o(q) phat_dot``. With the velocity estimate held constant
over the interval, its integral along the measured joint path has a closed form:
back-project the frame's points with their depths (eq. 2 inverted), place them in the world
with the model's camera pose at ``q_k``, move them by ``phat_dot (t - t_k)``, and project them
(eq. 2) from the model's camera pose at ``q``. It needs no integration step, only the frame's
capture time and the encoders at that time.

- ``predict``: every control step servoes on the newest frame brought up to now (latency
  compensation, which also removes the staleness between frames);
- ``hold`` [s]: when a frame arrives without the target, the controller keeps servoing on
  the prediction until ``hold`` seconds after the capture of the newest frame that showed it;
  then the command is zero and the dynamic compensation brakes the robot to a stop (as
  without ``hold``). The same holds when no frame arrives at all: with a ``hold``, a frame
  older than it is not used. When the target reappears the measurement replaces the
  prediction; the two differ only by the prediction's error, so the command does not jump.
- ``smoothing`` ``w`` in (0, 1] (noise handling): a new frame updates the previous estimate
  brought up to the frame's capture time, ``x = x_pred + w (z - x_pred)``, on the image points
  and the depths (the estimate also feeds the velocity filter). The camera's and the target's
  motion are predicted, so they pass without lag; only what the prediction misses is
  low-passed, by a first-order filter with pole ``1 - w`` at the frame rate ``f_s``: a
  bandwidth of ``-ln(1 - w) f_s / (2 pi)`` (0.2 at 30 Hz: 1.07 Hz) and a white-noise standard
  deviation reduced by ``sqrt(w / (2 - w))`` (0.2: a third). ``w = 1`` is no filter.
- **noise** (:mod:`pbvs_pin.control.noise`): each frame used is compared with the previous raw
  frame brought up to its capture; the second difference of that innovation measures the
  detector's pixel noise online (:attr:`TargetTracker.noise`), which lowers the loop gain.
- **gate** (outliers): a new frame is first compared with the same prediction by the
  innovation gate of :mod:`pbvs_pin.control.gating`; a frame that fails it is not used, and
  the last of :data:`~pbvs_pin.control.gating.RESTART_AFTER` failures in a row restarts the
  estimate from itself.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from pbvs_pin.control.gating import InnovationGate
from pbvs_pin.control.noise import PixelNoise
from pbvs_pin.model.camera import MIN_DEPTH, back_project_points, project_points
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.perception.estimation import VelocityEstimator
from pbvs_pin.perception.features import ImageMeasurement


@njit(cache=True, inline="always")
def predict_points(
    world: np.ndarray,
    velocity: np.ndarray,
    age: float,
    translation: np.ndarray,
    rotation: np.ndarray,
    focal: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The newest frame's points brought up to now (module docstring).

    Moved in the world by ``phat_dot`` over their age, and projected (eq. 2) from the camera's
    pose now.

    Args:
        world: The frame's points in the world, where it saw them [m]. Shape (k, 3).
        velocity: ``phat_dot`` [m/s]. Shape (3,).
        age: Time since the frame's capture [s].
        translation: ``wtc`` now [m]. Shape (3,).
        rotation: ``wRc`` now. Shape (3, 3).
        focal: Focal length [px].

    Returns:
        Image points [px], shape (k, 2), and depths [m], shape (k,).
    """
    return project_points(world + velocity * age, translation, rotation, focal, 0.0)


class TargetTracker:
    """The newest measurement of the target, what to servo on now, and the velocity filter.

    Args:
        model: The controller's model of the robot (camera poses, intrinsics).
        estimator: The target-velocity filter, fed the target's midpoint in the world.
        predict: Bring each frame up to now (module docstring).
        hold: Servo on the prediction this long after a loss [s]; 0: no hold.
        smoothing: Weight ``w`` of a new frame against its prediction, in (0, 1].
        gate: The innovation gate new frames pass; None: every frame is used.

    Attributes:
        measurement: The newest measurement of the target (None before the first).
        capture_time: Its capture time [s] (-inf before the first).
        lost: The newest frame did not show the target.
        used: What the controller servoes on now (set by :meth:`choose`; None: nothing).
        predicting: ``used`` is :attr:`prediction` rather than the newest measurement.
        prediction: The buffer the prediction is written into, by :meth:`current` or by the
            compiled control step (:mod:`pbvs_pin.control.step`); None before the first
            measurement.
        world: The newest measurement's points in the world, where its frame saw them [m].
            Shape (k, 3).
        noise: The pixel noise measured on the frames used (:mod:`pbvs_pin.control.noise`).
    """

    def __init__(
        self,
        model: MobileManipulator,
        estimator: VelocityEstimator,
        predict: bool,
        hold: float,
        smoothing: float,
        gate: InnovationGate | None = None,
    ) -> None:
        self.model = model
        self.gate = gate
        self.estimator = estimator
        self.predict, self.hold, self.smoothing = predict, hold, smoothing
        self.measurement: ImageMeasurement | None = None
        self.capture_time = -np.inf
        self.lost = False
        self.used: ImageMeasurement | None = None
        self.predicting = False
        self.prediction: ImageMeasurement | None = None
        self.world = np.zeros((0, 3))
        self._raw_world = self.world
        """The newest raw (unsmoothed) frame's points in the world [m]. Shape (k, 3)."""
        self.noise = PixelNoise()
        self._focal = model.camera.focal_px

    def take(
        self,
        measurement: ImageMeasurement | None,
        capture_time: float,
        q_capture: np.ndarray,
        velocity: np.ndarray,
    ) -> str:
        """Use a new frame unless it fails the gate: keep its measurement, update the filter.

        Args:
            measurement: The frame's points and depths; None when it does not show the target.
            capture_time: When it was taken [s].
            q_capture: The encoders at that time. Shape (nq,).
            velocity: The target velocity to predict with [m/s]. Shape (3,).

        Returns:
            Why the frame was not used (it failed the gate); empty when it was.
        """
        if measurement is None:
            self.lost = True
            return ""
        prior = None
        if self.measurement is not None:
            prior = self.predicted(capture_time, q_capture, velocity)
            if not (prior.depths > MIN_DEPTH).all():  # predicted behind the camera: no gate
                prior = None
        if prior is not None and self.gate is not None:
            age = capture_time - self.capture_time
            statistic = self.gate.statistic(
                measurement.points, measurement.depths, prior.points, prior.depths, age
            )
            used, restart = self.gate.verdict(statistic)
            if not used:
                return (
                    f"innovation {statistic:.3g} beyond the gate's {self.gate.threshold:.3g} "
                    "(control.gating): an outlier, not used"
                )
            if restart:
                self.estimator.reset()
                prior = None
        self._measure_noise(measurement, prior, capture_time, q_capture, velocity)
        self.lost = False
        model = self.model
        raw = measurement
        if self.smoothing < 1 and prior is not None:
            measurement = ImageMeasurement(
                prior.points + self.smoothing * (measurement.points - prior.points),
                prior.depths + self.smoothing * (measurement.depths - prior.depths),
            )
        self.measurement, self.capture_time = measurement, capture_time
        if self.prediction is None:
            self.prediction = ImageMeasurement(
                np.zeros_like(measurement.points), np.ones_like(measurement.depths)
            )
        pose = model.camera_placement(q_capture)
        in_camera = back_project_points(measurement.points, measurement.depths, self._focal)
        self.world = in_camera @ pose.rotation.T + pose.translation
        self._raw_world = self.world
        if raw is not measurement:
            in_camera_raw = back_project_points(raw.points, raw.depths, self._focal)
            self._raw_world = in_camera_raw @ pose.rotation.T + pose.translation
        self.estimator.update(pose.act(in_camera.mean(axis=0)), capture_time)
        return ""

    def _measure_noise(
        self,
        measurement: ImageMeasurement,
        prior: ImageMeasurement | None,
        capture_time: float,
        q_capture: np.ndarray,
        velocity: np.ndarray,
    ) -> None:
        """Feed :attr:`noise` the innovation against the previous raw frame (module docstring)."""
        if prior is None:
            self.noise.restart()
            return
        if self.smoothing < 1:  # the prior is the smoothed estimate's: predict the raw frame
            prior = self.predicted(capture_time, q_capture, velocity, self._raw_world)
        self.noise.update(measurement.points - prior.points)

    def current(self, t: float, q: np.ndarray, velocity: np.ndarray) -> ImageMeasurement | None:
        """What the controller servoes on at ``t``: the measurement, its prediction, or None.

        The NumPy reference of what :meth:`choose` and the compiled step do together (the
        tests' modular reference calls it; the controller does not).

        Args:
            t: Time [s].
            q: Encoder configuration now. Shape (nq,).
            velocity: The target velocity to predict with [m/s]. Shape (3,).
        """
        used = self.choose(t)
        if self.predicting:
            predicted = self.predicted(t, q, velocity)
            used.points[:], used.depths[:] = predicted.points, predicted.depths
        return used

    def choose(self, t: float) -> ImageMeasurement | None:
        """What to servo on at ``t``, set as :attr:`used`.

        The newest measurement, or (with ``predicting``) :attr:`prediction`, which the caller
        fills (:meth:`current` does); None: nothing to servo on.
        """
        age = t - self.capture_time
        # with a hold, a frame older than it is no longer used, even if none arrived since
        expired = self.hold > 0 and age > self.hold
        held = self.lost and self.hold > 0 and not expired
        fresh = not self.lost and not expired
        self.predicting = self.measurement is not None and (held or (self.predict and fresh))
        self.used = self.prediction if self.predicting else (self.measurement if fresh else None)
        return self.used

    def predicted(
        self, t: float, q: np.ndarray, velocity: np.ndarray, world: np.ndarray | None = None
    ) -> ImageMeasurement:
        """The newest measurement brought up to ``(t, q)`` along eq. (3) (module docstring).

        ``world``: other points placed by the newest frame [m], shape (k, 3) (its raw points).
        """
        placement = self.model.camera_placement(q)
        world = self.world if world is None else world
        image, depths = predict_points(
            world, velocity, t - self.capture_time, placement.translation, placement.rotation,
            self._focal,
        )  # fmt: skip
        return ImageMeasurement(image, depths)

    def forget(self) -> None:
        """Drop the measurement and restart the filter, after a jump of the odometry.

        The world points and the filter's positions were placed with the old odometry.
        """
        self.measurement, self.capture_time, self.used = None, -np.inf, None
        self.lost = self.predicting = False
        self.estimator.reset()
        self.noise.restart()
        if self.gate is not None:
            self.gate.clear()
