"""The controller's view of the target: the newest delivered camera frame and the estimate.

**Prediction** (an extension of the paper, issue 13). Between the newest frame showing the
target (timestamp ``t_k``, encoders ``q_k``) and now ``(t, q)``, the features move by eq. (3),
``xi_dot = J(q) q_dot + J_o(q) phat_dot``. With the velocity estimate held constant over the
interval, its integral along the measured joint path has a closed form: back-project the
frame's points with their depths (eq. 2 inverted), place them in the world with the model's
camera pose at ``q_k``, move them by ``phat_dot (t - t_k)``, and project them (eq. 2) from
the model's camera pose at ``q``. It needs no integration step and only the delay the
timestamps give (an exposure delay, invisible in them, is not compensated).

- ``estimator.predict``: every control step servoes on the newest frame brought up to now
  (latency compensation, which also removes the staleness between frames);
- ``estimator.hold`` [s]: when a frame arrives without the target, the loop keeps servoing on
  the prediction until ``hold`` seconds after the newest frame that showed it; then the
  command is zero and the dynamic compensation brakes the robot to a stop (as without
  ``hold``). The same holds when no frame arrives at all: with a ``hold``, a frame older than
  it is not used. When the target reappears the measurement replaces the prediction; the two
  differ only by the prediction's error, so the command does not jump.
- ``estimator.smoothing`` ``w`` in (0, 1] (noise handling): a new frame updates the previous
  estimate brought up to the frame's stamp, ``x = x_pred + w (z - x_pred)``, on the image
  points and the depths (the estimate also feeds the velocity filter). The camera's and the
  target's motion are predicted, so they pass without lag; only what the prediction misses is
  low-passed, by a first-order filter with pole ``1 - w`` at the frame rate ``f_s``: a
  bandwidth of ``-ln(1 - w) f_s / (2 pi)`` (0.2 at 30 Hz: 1.07 Hz) and a white-noise standard
  deviation reduced by ``sqrt(w / (2 - w))`` (0.2: a third). ``w = 1`` is no filter.
"""

from __future__ import annotations

import numpy as np

from pbvs_pin.features import ImageMeasurement
from pbvs_pin.sim.setup import Setup
from pbvs_pin.sim.vision import Frame


class Perception:
    """The controller's view of the target: the newest delivered frame, and the estimate.

    Attributes:
        measurement: The newest measurement of the target (None before the first).
        lost: The newest delivered frame did not show the target.
        used: What the controller servoes on now (set by :meth:`current`; None: nothing).
        predicting: ``used`` is a prediction rather than the newest measurement.
    """

    def __init__(self, setup: Setup) -> None:
        self.setup = setup
        spec = setup.scenario.estimator
        self.exact = spec.kind == "exact"
        self.predict, self.hold, self.smoothing = spec.predict, spec.hold, spec.smoothing
        self.filter = setup.estimator
        self.measurement: ImageMeasurement | None = None
        self.frame: Frame | None = None
        self.lost = False
        self.used: ImageMeasurement | None = None
        self.predicting = False
        self._world = np.zeros((0, 3))
        """The newest measurement's points in the world, where its frame saw them [m]."""

    def take(self, frame: Frame) -> None:
        """Use a delivered frame: keep its measurement and update the filter."""
        if not frame.visible:
            self.lost = True
            return
        self.lost = False
        setup = self.setup
        measurement = frame.measurement(setup.model.camera, setup.target.diameter)
        if self.smoothing < 1 and self.frame is not None:
            prior = self.predicted(frame.time, frame.q)
            measurement = ImageMeasurement(
                prior.points + self.smoothing * (measurement.points - prior.points),
                prior.depths + self.smoothing * (measurement.depths - prior.depths),
            )
        self.frame, self.measurement = frame, measurement
        pose = setup.model.camera_pose(frame.q)
        in_camera = setup.model.camera.back_project(measurement.points, measurement.depths)
        self._world = in_camera @ pose.rotation.T + pose.translation
        self.filter.update(pose.act(in_camera.mean(axis=0)), frame.time)

    def velocity(self, t: float) -> np.ndarray:
        """``phat_dot``: the filter's estimate, or the truth for an "exact" estimator."""
        if self.exact:
            return self.setup.target.motion.velocity(t)
        return self.filter.velocity

    def current(self, t: float, q: np.ndarray) -> ImageMeasurement | None:
        """What the controller servoes on at ``t``: the measurement, its prediction, or None.

        Args:
            t: Time [s].
            q: Encoder configuration now. Shape (nq,).
        """
        age = np.inf if self.frame is None else t - self.frame.time
        # with a hold, a frame older than it is no longer used, even if none arrived since
        expired = self.hold > 0 and age > self.hold
        held = self.lost and self.hold > 0 and not expired
        fresh = not self.lost and not expired
        self.predicting = self.frame is not None and (held or (self.predict and fresh))
        if self.predicting:
            self.used = self.predicted(t, q)
        else:
            self.used = self.measurement if fresh else None
        return self.used

    def predicted(self, t: float, q: np.ndarray) -> ImageMeasurement:
        """The newest measurement brought up to ``(t, q)`` along eq. (3) (module docstring)."""
        model, frame = self.setup.model, self.frame
        world = self._world + self.velocity(t) * (t - frame.time)
        image, depths = model.camera.project_world(model.camera_placement(q), world)
        return ImageMeasurement(image, depths)
