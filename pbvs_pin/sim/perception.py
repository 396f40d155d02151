"""The controller's view of the target: the newest delivered camera frame and the estimate."""

from __future__ import annotations

import numpy as np

from pbvs_pin.features import ImageMeasurement
from pbvs_pin.sim.setup import Setup
from pbvs_pin.sim.vision import Frame


class Perception:
    """The controller's view of the target: the newest delivered frame, and the estimate."""

    def __init__(self, setup: Setup) -> None:
        self.setup = setup
        self.exact = setup.scenario.estimator.kind == "exact"
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
        in_camera = setup.model.camera.back_project(frame.points, self.measurement.depths)
        self.filter.update(pose.act(in_camera.mean(axis=0)), frame.time)

    def velocity(self, t: float) -> np.ndarray:
        """``phat_dot``: the filter's estimate, or the truth for an "exact" estimator."""
        if self.exact:
            return self.setup.target.motion.velocity(t)
        return self.filter.velocity
