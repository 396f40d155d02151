"""One camera frame as a robot's driver hands it to :class:`pbvs_pin.Controller`.

A frame carries when its image was taken and what it shows: the target's image points and
their depths, or that the target is not visible. Conventions:

- **Time**: ``capture_time`` is on the controller's clock, the clock of the ``t`` given to
  :meth:`pbvs_pin.Controller.step`, at the instant the image shows (for a camera that stamps
  the end of readout, subtract the exposure and readout time). The controller places the
  frame at the encoder reading of that instant (:class:`~pbvs_pin.control.encoders.EncoderHistory`).
- **Image points**: the paper's image coordinates ``xi = [u, v]`` [px], origin at the image
  centre ``(W/2, H/2)``, ``u`` to the left and ``v`` upwards (eq. 2). In pixel coordinates
  (``col`` to the right, ``row`` down, the pixel of index ``(i, j)`` centred at
  ``(i + 0.5, j + 0.5)``) that is ``u = W/2 - col``, ``v = H/2 - row``:
  :meth:`pbvs_pin.CameraIntrinsics.from_pixel` and :meth:`~pbvs_pin.CameraIntrinsics.to_pixel`.
- **Depths**: along the optical axis [m]; from a sphere's apparent diameter ``d`` [px] and
  true diameter ``D`` [m], ``z = f D / d`` (:meth:`CameraFrame.from_diameters`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pbvs_pin.exceptions import ShapeError
from pbvs_pin.model.camera import CameraIntrinsics
from pbvs_pin.validation import as_number, as_numbers, as_rows


@dataclass(frozen=True)
class CameraFrame:
    """What one camera frame shows of the target, and when.

    Attributes:
        capture_time: When the image was taken, on the controller's clock [s].
        points: Image points ``[u, v]`` of the target's points [px] (module docstring).
            Shape (k, 2); None when the target is not visible.
        depths: Their depths along the optical axis [m]. Shape (k,); None when not visible.
    """

    capture_time: float
    points: np.ndarray | None = None
    depths: np.ndarray | None = None

    def __post_init__(self) -> None:
        """Convert the time to a float and the points and depths to float arrays.

        NaN points or depths are kept: the controller counts such a frame as not visible.

        Raises:
            WrongType: If a value is not numbers.
            NonFiniteValue: If the capture time is not finite.
            ShapeError: If the points are not (k, 2) or the depths not (k,).
        """
        object.__setattr__(self, "capture_time", as_number("capture_time", self.capture_time))
        if self.points is None and self.depths is None:
            return
        points = as_rows("points", self.points, 2, finite=False)
        depths = as_numbers("depths", self.depths)
        if depths.shape != (len(points),):
            raise ShapeError("depths", (len(points),), depths.shape)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "depths", depths)

    @property
    def visible(self) -> bool:
        """Whether the frame shows the target (it has points)."""
        return self.points is not None

    @classmethod
    def seen(
        cls, capture_time: float, points: npt.ArrayLike, depths: npt.ArrayLike
    ) -> CameraFrame:
        """A frame showing the target at ``points`` [px] (k, 2) and ``depths`` [m] (k,)."""
        return cls(capture_time, points, depths)

    @classmethod
    def not_visible(cls, capture_time: float) -> CameraFrame:
        """A frame taken at ``capture_time`` [s] in which the target is not visible."""
        return cls(capture_time)

    @classmethod
    def from_diameters(
        cls,
        capture_time: float,
        points: npt.ArrayLike,
        diameters_px: npt.ArrayLike,
        camera: CameraIntrinsics,
        sphere_diameter: float,
    ) -> CameraFrame:
        """A frame of spheres, their depths from their apparent diameters, ``z = f D / d``.

        Args:
            capture_time: When the image was taken [s].
            points: Image points of the sphere centres [px]. Shape (k, 2).
            diameters_px: Apparent diameters ``d`` [px]. Shape (k,).
            camera: The camera's intrinsics (its focal length ``f`` [px]).
            sphere_diameter: The spheres' true diameter ``D`` [m].
        """
        diameters = as_numbers("diameters_px", diameters_px)
        sphere_diameter = as_number("sphere_diameter", sphere_diameter)
        return cls.seen(capture_time, points, camera.focal_px * sphere_diameter / diameters)
