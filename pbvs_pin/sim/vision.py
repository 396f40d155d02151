"""The simulated camera: frames at a rate, pixel noise, latency, image bounds.

A frame holds the image coordinates and apparent diameters of both spheres, measured on the
true robot and target, and the encoder configuration at capture time. The controller only
ever sees frames (after their latency) and encoders.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from pbvs_pin.camera import MIN_DEPTH, CameraIntrinsics
from pbvs_pin.exceptions import GainError
from pbvs_pin.features import ImageMeasurement


@dataclass(frozen=True)
class Frame:
    """One camera frame.

    Attributes:
        time: Capture time [s].
        points: ``[u, v]`` of each sphere [px]; NaN when not visible. Shape (2, 2).
        diameters: Apparent diameters [px]; NaN when not visible. Shape (2,).
        q: Encoder configuration at capture time. Shape (nq,).
        visible: Both spheres are in front of the camera and inside the image.
    """

    time: float
    points: np.ndarray
    diameters: np.ndarray
    q: np.ndarray
    visible: bool

    def measurement(self, camera: CameraIntrinsics, diameter: float) -> ImageMeasurement:
        """Image points and depths from the apparent diameters, ``z = f D / d``."""
        return ImageMeasurement(self.points, camera.focal_px * diameter / self.diameters)


class CameraSensor:
    """Produces frames at ``rate`` and delivers them ``latency`` seconds later.

    Args:
        camera: Intrinsics.
        diameter: Sphere diameter D [m].
        rate: Frame rate [Hz].
        latency: Delay between capture and delivery [s].
        noise_px: Standard deviation of the pixel noise on coordinates and diameters [px].
        rng: Seeded random generator.
    """

    def __init__(
        self,
        camera: CameraIntrinsics,
        diameter: float,
        rate: float,
        latency: float,
        noise_px: float,
        rng: np.random.Generator,
    ) -> None:
        if not rate > 0:
            raise GainError(f"camera rate: expected > 0 Hz, got {rate}")
        if not (latency >= 0 and noise_px >= 0):
            raise GainError(f"camera latency/noise: expected >= 0, got {latency}, {noise_px}")
        self.camera, self.diameter = camera, diameter
        self.period, self.latency, self.noise = 1.0 / rate, latency, noise_px
        self.rng = rng
        self.next_capture = 0.0
        self.pending: deque[Frame] = deque()

    def capture_due(self, t: float) -> bool:
        """Whether a frame is to be captured at time ``t``."""
        return t + 1e-9 >= self.next_capture

    def capture(self, t: float, camera_pose: object, centres: np.ndarray, q: np.ndarray) -> None:
        """Capture a frame of the true target seen from the true camera pose.

        Args:
            t: Time [s].
            camera_pose: True ``world_T_camera`` (``pin.SE3``).
            centres: True sphere centres [m]. Shape (2, 3).
            q: Encoder configuration. Shape (nq,).
        """
        self.next_capture += self.period
        image, depths = self.camera.project_world(camera_pose, centres)
        visible = bool(np.all(depths > MIN_DEPTH))
        points = np.full((2, 2), np.nan)
        diameters = np.full(2, np.nan)
        if visible:
            points = image
            diameters = self.camera.focal_px * self.diameter / depths
            points = points + self.noise * self.rng.standard_normal((2, 2))
            diameters = np.maximum(diameters + self.noise * self.rng.standard_normal(2), 1.0)
            visible = self.camera.in_image(points)
        self.pending.append(Frame(t, points, diameters, q.copy(), visible))

    def deliver(self, t: float) -> Frame | None:
        """The newest frame whose latency has elapsed by ``t`` (older ones are dropped)."""
        latest = None
        while self.pending and self.pending[0].time + self.latency <= t + 1e-9:
            latest = self.pending.popleft()
        return latest
