"""The rendered camera: a frame is an image of the true scene, and the spheres are found in it.

With ``camera.model = "rendered"`` the :class:`~pbvs_pin.sim.vision.CameraSensor` asks a
:class:`RenderedCamera` for each frame's points, diameters and visibility instead of
projecting the sphere centres. The rendered camera reads the true configuration from the
plant itself (the robot's links hide the target when they are in the way), draws the scene
with :class:`~pbvs_pin.sim.render.SceneRenderer` from the camera pose it is given, applies the
image effects, and runs the detector (:mod:`pbvs_pin.perception.detection`). The frame's latency,
drops and occlusion episodes then act as for the point camera; the ``noise_px`` key does not
apply (the pixel noise is the image's own, :attr:`ImageEffects.noise`).

Image effects (:class:`ImageEffects`), each off by default:

- **sensor noise**: Gaussian noise of ``noise`` grey levels on every pixel and channel;
- **motion blur**: the image is the mean of the scene drawn at every control step of the
  exposure ``[t - exposure_time, t]`` (the sub-frame poses the sensor saw, :meth:`observe`);
- **lighting change**: from ``light_change_time`` on, the lights' intensity is multiplied by
  ``light_change_scale``.

Every frame's detection error (detected minus projected, eq. (2), points and diameters) is
kept (:meth:`RenderedCamera.detection_meta`), for the log and ``summary.json``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import pinocchio as pin

from pbvs_pin.exceptions import GainError
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.perception.detection import CameraImage, Detector
from pbvs_pin.sim.render import SceneRenderer

RENDER_STREAM = 21
"""Second entry of the image-noise generator's seed ``[seed, RENDER_STREAM]``."""


class TruePlant(Protocol):
    """What the rendered camera reads of a plant: its true configuration."""

    @property
    def q(self) -> np.ndarray:
        """True configuration. Shape (nq,)."""


class TrueTarget(Protocol):
    """What the rendered camera reads of the target: its true sphere centres."""

    def centres(self, t: float) -> np.ndarray:
        """Sphere centres [m] at time ``t`` [s]. Shape (2, 3)."""


@dataclass(frozen=True)
class ImageEffects:
    """Image effects of the rendered camera (module docstring); the defaults are none.

    Attributes:
        noise: Standard deviation of the per-pixel Gaussian noise [grey levels of 255].
        exposure_time: Exposure over which the image is averaged (motion blur) [s].
        light_change_time: Time from which the lighting changes [s].
        light_change_scale: Factor on the lights' intensity from then on [1].
    """

    noise: float = 0.0
    exposure_time: float = 0.0
    light_change_time: float = 0.0
    light_change_scale: float = 1.0

    def __post_init__(self) -> None:
        """Reject negative values, naming the field."""
        for name in ("noise", "exposure_time", "light_change_time", "light_change_scale"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise GainError(f"ImageEffects.{name}: expected >= 0, got {value}", name)

    def light(self, t: float) -> float:
        """Factor on the lights at time ``t`` [s]."""
        return self.light_change_scale if t >= self.light_change_time else 1.0


class RenderedCamera:
    """Frames drawn by MuJoCo and measured by a detector (module docstring).

    Args:
        robot: The true robot (its camera pose for the sub-frames of a blurred exposure).
        scene: The scene renderer.
        plant: The true plant, read for the robot's configuration.
        target: The true target, read for the sub-frames' sphere centres.
        detector: Finds the spheres in the image.
        effects: Image effects.
        rng: Seeded generator of the image noise.
    """

    def __init__(
        self,
        robot: MobileManipulator,
        scene: SceneRenderer,
        plant: TruePlant,
        target: TrueTarget,
        detector: Detector,
        effects: ImageEffects,
        rng: np.random.Generator,
    ) -> None:
        self.robot, self.scene, self.plant, self.target = robot, scene, plant, target
        self.detector, self.effects, self.rng = detector, effects, rng
        self.camera = scene.camera
        self.history: list[tuple[float, np.ndarray]] = []  # (t, q) of the exposure so far
        self.times: list[float] = []
        self.errors: list[np.ndarray] = []  # detected minus projected [u1, v1, u2, v2, d1, d2]
        self.detected: list[bool] = []
        self.projected_inside: list[bool] = []
        self.latest: CameraImage | None = None  # the newest frame, for a live view

    def observe(self, t: float) -> None:
        """Remember the plant's configuration at ``t`` for a blurred exposure (none without)."""
        exposure = self.effects.exposure_time
        if exposure <= 0 or (self.history and self.history[-1][0] >= t - 1e-9):
            return
        self.history.append((t, self.plant.q.copy()))
        while self.history and self.history[0][0] < t - exposure - 1e-9:
            self.history.pop(0)

    def capture(
        self, t: float, camera_pose: pin.SE3, centres: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, bool]:
        """Draw the frame at ``t``, detect the spheres and record the detection error.

        Args:
            t: Time [s].
            camera_pose: True ``world_T_camera`` (of the plant's configuration).
            centres: True sphere centres [m]. Shape (2, 3).

        Returns:
            Points ``[u, v]`` [px] (shape (2, 2)), apparent diameters [px] (shape (2,)) and
            visibility, as the detector gives them; the frame itself is kept as
            :attr:`latest` (a :class:`~pbvs_pin.perception.detection.CameraImage`).
        """
        image = self.draw(t, camera_pose, centres)
        points, diameters, visible = self.detector.detect(image)
        points = np.asarray(points, dtype=float).reshape(2, 2)
        diameters = np.asarray(diameters, dtype=float).reshape(2)
        self._record(t, camera_pose, centres, points, diameters, bool(visible))
        self.latest = CameraImage(t, image, points, diameters, bool(visible))
        return points, diameters, bool(visible)

    def draw(self, t: float, camera_pose: pin.SE3, centres: np.ndarray) -> np.ndarray:
        """The image at ``t`` with the effects: RGB ``uint8``, shape (H, W, 3)."""
        effects, light = self.effects, self.effects.light(t)
        q = self.plant.q
        image = self.scene.render(q, camera_pose, centres, light)
        if effects.exposure_time <= 0 and effects.noise <= 0:
            return image
        total = image.astype(float)
        earlier = [(s, p) for s, p in self.history if s < t - 1e-9]
        for s, p in earlier:
            pose = self.robot.camera_pose(p)
            total += self.scene.render(p, pose, self.target.centres(s), effects.light(s))
        total /= 1 + len(earlier)
        if effects.noise > 0:
            total += effects.noise * self.rng.standard_normal(total.shape)
        return np.clip(np.rint(total), 0, 255).astype(np.uint8)

    def _record(
        self,
        t: float,
        camera_pose: pin.SE3,
        centres: np.ndarray,
        points: np.ndarray,
        diameters: np.ndarray,
        visible: bool,
    ) -> None:
        """Keep the frame's detection error against eq. (2)'s projection and ``f D / z``."""
        projected, depths = self.camera.project_world(camera_pose, centres)
        inside = bool(np.all(depths > 0) and self.camera.in_image(projected))
        expected = self.camera.focal_px * self.scene.diameter / depths
        self.times.append(t)
        self.errors.append(np.concatenate([(points - projected).reshape(-1), diameters - expected]))
        self.detected.append(visible)
        self.projected_inside.append(inside)

    def detection_meta(self) -> dict[str, Any]:
        """Every frame's detection, JSON-serialisable (NaN as None).

        Keys: ``time`` [s]; ``error_px``, detected minus projected ``[du1, dv1, du2, dv2,
        dd1, dd2]`` [px] (None when not detected); ``detected``; ``projected_inside`` (both
        centres in front of the camera and inside the image).
        """
        return {
            "time": list(self.times),
            "error_px": [
                [None if not np.isfinite(x) else round(float(x), 4) for x in row]
                for row in self.errors
            ],
            "detected": list(self.detected),
            "projected_inside": list(self.projected_inside),
        }
