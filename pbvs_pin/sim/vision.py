"""The simulated camera: frames at a rate, pixel noise, latency, image bounds, faults.

A frame holds the image coordinates and apparent diameters of both spheres, measured on the
true robot and target, and the encoder configuration at its timestamp. The controller only
ever sees frames (after their latency) and encoders.

The faults a real camera brings, each off by default and drawn from a generator of
its own (seeded from the scenario's seed) so that the pixel noise of a run without faults is
unchanged:

- **frame drops**: each frame is lost with probability ``drop_probability``; nothing is
  delivered for it, the controller keeps its previous frame;
- **occlusion**: during an episode the frame arrives without the target (``visible`` false);
  episodes start at given times, and/or at random (a Poisson process of ``occlusion_rate``
  episodes per second), each lasting ``occlusion_duration``;
- **latency jitter**: each frame's transport delay is ``latency`` plus a uniform draw in
  ``[0, latency_jitter]``; a frame overtaken by a newer delivered one is discarded;
- **exposure delay**: the image shows the scene ``exposure_delay`` before its timestamp and
  encoder reading (the camera stamps the end of readout); unlike the latency, this delay is
  invisible in the timestamps.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pbvs_pin.exceptions import GainError
from pbvs_pin.model.camera import MIN_DEPTH, CameraIntrinsics
from pbvs_pin.perception.features import ImageMeasurement

if TYPE_CHECKING:
    from pbvs_pin.sim.rendered_camera import RenderedCamera

FAULT_STREAM = 13
"""Second entry of the fault generator's seed ``[seed, FAULT_STREAM]``."""


@dataclass(frozen=True)
class Frame:
    """One camera frame.

    Attributes:
        time: Timestamp [s] (capture time plus the exposure delay).
        points: ``[u, v]`` of each sphere [px]; NaN when not visible. Shape (2, 2).
        diameters: Apparent diameters [px]; NaN when not visible. Shape (2,).
        q: Encoder configuration at the timestamp. Shape (nq,).
        visible: Both spheres are in front of the camera, inside the image and not occluded.
    """

    time: float
    points: np.ndarray
    diameters: np.ndarray
    q: np.ndarray
    visible: bool

    def measurement(self, camera: CameraIntrinsics, diameter: float) -> ImageMeasurement:
        """Image points and depths from the apparent diameters, ``z = f D / d``."""
        return ImageMeasurement(self.points, camera.focal_px * diameter / self.diameters)


@dataclass(frozen=True)
class CameraFaults:
    """The faults of a camera (see the module docstring); the defaults are a perfect camera.

    Attributes:
        drop_probability: Probability that a frame is lost, in [0, 1).
        occlusion_starts: Start times of occlusion episodes [s].
        occlusion_rate: Random occlusion episodes per second [1/s].
        occlusion_duration: Length of every occlusion episode [s].
        latency_jitter: Largest extra transport delay (uniform) [s].
        exposure_delay: Delay from the exposure to the timestamp and encoders [s].
    """

    drop_probability: float = 0.0
    occlusion_starts: tuple[float, ...] = ()
    occlusion_rate: float = 0.0
    occlusion_duration: float = 0.0
    latency_jitter: float = 0.0
    exposure_delay: float = 0.0


class CameraSensor:
    """Produces frames at ``rate`` and delivers them ``latency`` seconds after their stamp.

    Args:
        camera: Intrinsics.
        diameter: Sphere diameter D [m].
        rate: Frame rate [Hz].
        latency: Delay between the timestamp and delivery [s].
        noise_px: Standard deviation of the pixel noise on coordinates and diameters [px].
        rng: Seeded random generator of the pixel noise.
        faults: The camera's faults (none by default).
        fault_rng: Seeded random generator of the faults (drops, random occlusions, jitter).
        renderer: The rendered camera (``camera.model = "rendered"``): each frame's points,
            diameters and visibility come from its image instead of the projection of the
            centres, and ``noise_px`` does not apply (:mod:`pbvs_pin.sim.rendered_camera`).
    """

    def __init__(
        self,
        camera: CameraIntrinsics,
        diameter: float,
        rate: float,
        latency: float,
        noise_px: float,
        rng: np.random.Generator,
        faults: CameraFaults | None = None,
        fault_rng: np.random.Generator | None = None,
        renderer: RenderedCamera | None = None,
    ) -> None:
        if not rate > 0:
            raise GainError(f"camera rate: expected > 0 Hz, got {rate}")
        if not (latency >= 0 and noise_px >= 0):
            raise GainError(f"camera latency/noise: expected >= 0, got {latency}, {noise_px}")
        faults = faults if faults is not None else CameraFaults()
        if not 0 <= faults.drop_probability < 1:
            raise GainError(f"drop probability: expected in [0, 1), got {faults.drop_probability}")
        self.camera, self.diameter = camera, diameter
        self.period, self.latency, self.noise = 1.0 / rate, latency, noise_px
        self.rng, self.faults = rng, faults
        self.fault_rng = fault_rng if fault_rng is not None else np.random.default_rng(0)
        self.renderer = renderer
        self.next_capture = 0.0
        self.occluded_until = -np.inf
        self.exposed: list[tuple[float, Frame]] = []  # (exposure time, frame before its stamp)
        self.pending: list[tuple[float, Frame]] = []  # (delivery time, frame)
        self.next_arrival = np.inf  # the earliest delivery time in ``pending``

    def capture_due(self, t: float) -> bool:
        """Whether a frame is to be captured at time ``t``."""
        return t + 1e-9 >= self.next_capture

    def capture(self, t: float, camera_pose: object, centres: np.ndarray, q: np.ndarray) -> None:
        """Capture a frame of the true target seen from the true camera pose.

        Without an exposure delay the frame is stamped at once with ``t`` and ``q``; otherwise
        :meth:`stamp` stamps it later.

        Args:
            t: Time [s].
            camera_pose: True ``world_T_camera`` (``pin.SE3``).
            centres: True sphere centres [m]. Shape (2, 3).
            q: Encoder configuration. Shape (nq,).
        """
        self.next_capture += self.period
        faults = self.faults
        if faults.drop_probability > 0 and self.fault_rng.random() < faults.drop_probability:
            return
        if self.renderer is not None:
            points, diameters, visible = self.renderer.capture(t, camera_pose, centres)
        else:
            points, diameters, visible = self._project(camera_pose, centres)
        if visible and self._occluded(t):
            points, diameters, visible = np.full((2, 2), np.nan), np.full(2, np.nan), False
        self.exposed.append((t, Frame(t, points, diameters, q, visible)))
        self.stamp(t, q)

    def _project(
        self, camera_pose: object, centres: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, bool]:
        """Points [px], diameters [px] and visibility of the point camera: eq. (2) plus noise."""
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
        return points, diameters, visible

    def _occluded(self, t: float) -> bool:
        """Whether an occlusion episode covers ``t`` (random episodes start here)."""
        faults = self.faults
        if faults.occlusion_rate > 0:
            if self.fault_rng.random() < 1.0 - np.exp(-faults.occlusion_rate * self.period):
                self.occluded_until = max(self.occluded_until, t + faults.occlusion_duration)
        if t < self.occluded_until:
            return True
        return any(s <= t < s + faults.occlusion_duration for s in faults.occlusion_starts)

    def stamp(self, t: float, q: np.ndarray) -> None:
        """Stamp the exposed frames whose exposure delay has elapsed by ``t`` with ``t``, ``q``.

        The frame is then due ``latency`` (plus its jitter draw) after ``t``. A rendered
        camera remembers the instant for a blurred exposure (called at every control step).
        """
        if self.renderer is not None:
            self.renderer.observe(t)
        while self.exposed and self.exposed[0][0] + self.faults.exposure_delay <= t + 1e-9:
            _, frame = self.exposed.pop(0)
            delay = self.latency
            if self.faults.latency_jitter > 0:
                delay += self.faults.latency_jitter * self.fault_rng.random()
            stamped = Frame(t, frame.points, frame.diameters, q.copy(), frame.visible)
            self.pending.append((t + delay, stamped))
            self.next_arrival = min(self.next_arrival, t + delay)

    def deliver(self, t: float) -> Frame | None:
        """The newest frame due by ``t``; it and every older pending frame leave the queue."""
        if self.next_arrival > t + 1e-9:  # nothing due: the 1 kHz loop's usual case
            return None
        due = [frame for arrival, frame in self.pending if arrival <= t + 1e-9]
        latest = max(due, key=lambda frame: frame.time)
        self.pending = [(a, f) for a, f in self.pending if f.time > latest.time]
        self.next_arrival = min((a for a, _ in self.pending), default=np.inf)
        return latest
