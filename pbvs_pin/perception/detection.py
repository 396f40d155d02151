"""Finding the two spheres in a camera image: the replaceable detector of the rendered camera.

A detector turns an RGB image into what a :class:`~pbvs_pin.sim.vision.Frame` carries: the
image points ``[u, v]`` of both spheres [px] (the paper's coordinates, eq. (2): from the
image centre, ``u`` to the left, ``v`` upwards), their apparent diameters [px] and whether
both were found. Any object with a ``detect(image)`` method of that signature is a detector
(:class:`Detector`); :func:`detector_from` takes such an object or the name it was
registered under (:func:`register_detector`).

The default, :class:`ColourDetector`, segments each sphere by its colour with OpenCV (hue,
saturation and value thresholds, so that a change of lighting moves only the value), keeps
the largest blob per colour, and reports its centroid from the mask's image moments
(sub-pixel) and the diameter of the disc of the same area. It says "not visible" rather than
guess when a blob is too small, too large, touches the image border (a sphere cut by the
border has a centroid pulled inward) or is not round (a sphere partly hidden by the arm or an
obstacle).

Pixel convention (as MuJoCo and OpenCV draw): pixel ``(col, row)`` covers
``[col, col + 1) x [row, row + 1)``, so its centre is at ``col + 0.5``, and the image centre is
``(W / 2, H / 2)``; :meth:`pbvs_pin.model.camera.CameraIntrinsics.to_pixel` maps ``[u, v]`` to it.
"""

from __future__ import annotations

import abc
import colorsys
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from pbvs_pin.exceptions import GainError, ShapeError, WrongType
from pbvs_pin.model.camera import CameraIntrinsics
from pbvs_pin.validation import as_instance

SPHERE_HUES = (120.0, 60.0)
"""Hue [deg] of the upper and of the lower sphere (green and yellow): far from the reference
robot's red chassis, grey arm and dark blue laser, and from the grey floor."""


def sphere_rgba(hue: float) -> list[float]:
    """A saturated colour [0-1] of ``hue`` [deg] for a sphere (RGBA)."""
    return [*colorsys.hsv_to_rgb(hue / 360.0, 1.0, 0.9), 1.0]


@dataclass(frozen=True)
class CameraImage:
    """The newest image of a rendered camera and what its detector found in it.

    Attributes:
        time: Capture time [s].
        image: RGB ``uint8``, as the detector saw it (image effects included).
            Shape (H, W, 3).
        points: ``[u, v]`` of each sphere [px]; NaN when not found. Shape (2, 2).
        diameters: Apparent diameters [px]; NaN when not found. Shape (2,).
        visible: The detector found both spheres (before the camera's faults act).
    """

    time: float
    image: np.ndarray
    points: np.ndarray
    diameters: np.ndarray
    visible: bool


class Detector(abc.ABC):
    """Finds the two spheres in an image."""

    @abc.abstractmethod
    def detect(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
        """Image points, apparent diameters and visibility of the two spheres.

        Args:
            image: RGB image, ``uint8``. Shape (H, W, 3).

        Returns:
            ``[u, v]`` of the upper then the lower sphere [px], shape (2, 2); their apparent
            diameters [px], shape (2,); and whether both were found (when not, the points and
            diameters are NaN).
        """


def not_visible() -> tuple[np.ndarray, np.ndarray, bool]:
    """What a detector returns when it does not see both spheres: NaN points and diameters."""
    return np.full((2, 2), np.nan), np.full(2, np.nan), False


@dataclass(frozen=True)
class Blob:
    """One connected region of a colour mask.

    Attributes:
        centroid: ``[col, row]`` of the region's centre of area [px], pixel centres at
            ``index + 0.5``. Shape (2,).
        area: Pixel count [px^2].
        bounds: ``(col, row, width, height)`` of its bounding box [px].
        fill: Area over the area of its smallest enclosing circle (1 for a disc).
    """

    centroid: np.ndarray
    area: float
    bounds: tuple[int, int, int, int]
    fill: float


class ColourDetector(Detector):
    r"""Two spheres of known hues, found by colour thresholds with OpenCV.

    Per sphere: a mask of the pixels whose hue is within ``hue_tolerance`` of the sphere's,
    with saturation and value above their floors (``cv2.inRange`` on ``cv2.COLOR_RGB2HSV``);
    the largest region (outer contour, ``cv2.findContours``, filled); its centroid from the
    image moments ``(m10 / m00, m01 / m00)`` (``cv2.moments``) and its apparent diameter

    .. math:: d = 2 \sqrt{A / \pi}

    from its area ``A`` [px^2]. The region is refused (not visible) when ``d`` is outside
    ``[min_diameter, max_diameter]``, when it touches the image border, or when its ``fill``
    (area over that of its smallest enclosing circle) is below ``min_fill``.

    Args:
        camera: Intrinsics (image size and principal point).
        hues: Hue [deg] of the upper and of the lower sphere.
        hue_tolerance: Half-width of each hue window [deg].
        min_saturation: Smallest saturation of a sphere pixel, in [0, 1].
        min_value: Smallest value (brightness) of a sphere pixel, in [0, 1].
        min_diameter: Smallest apparent diameter accepted [px].
        max_diameter: Largest apparent diameter accepted [px]; a quarter of the image's
            smaller side by default.
        min_fill: Smallest ratio of a blob's area to its enclosing circle's, in (0, 1].

    Raises:
        GainError: On a value outside its range, naming it.
    """

    def __init__(
        self,
        camera: CameraIntrinsics,
        hues: tuple[float, float] = SPHERE_HUES,
        hue_tolerance: float = 20.0,
        min_saturation: float = 0.5,
        min_value: float = 0.1,
        min_diameter: float = 4.0,
        max_diameter: float | None = None,
        min_fill: float = 0.8,
    ) -> None:
        camera = as_instance("camera", camera, CameraIntrinsics)
        if max_diameter is None:
            max_diameter = 0.25 * min(camera.width, camera.height)
        for name, value, low, high in (
            ("hue_tolerance", hue_tolerance, 0.0, 90.0),
            ("min_saturation", min_saturation, 0.0, 1.0),
            ("min_value", min_value, 0.0, 1.0),
            ("min_fill", min_fill, 0.0, 1.0),
        ):
            if not low < value <= high:
                raise GainError(f"ColourDetector.{name}: expected in ({low}, {high}], got {value}")
        if not 0 < min_diameter < max_diameter:
            raise GainError(
                f"ColourDetector diameters: expected 0 < min_diameter < max_diameter, got "
                f"{min_diameter}, {max_diameter} px"
            )
        self.camera = camera
        self.hues, self.hue_tolerance = tuple(float(h) for h in hues), float(hue_tolerance)
        self.floors = (255.0 * min_saturation, 255.0 * min_value)
        self.min_diameter, self.max_diameter, self.min_fill = min_diameter, max_diameter, min_fill

    def detect(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
        """The two spheres in ``image`` (see :meth:`Detector.detect`).

        Raises:
            ShapeError: If the image is not ``(height, width, 3)`` of the camera.
        """
        camera = self.camera
        expected = (camera.height, camera.width, 3)
        if image.shape != expected:
            raise ShapeError("image", expected, image.shape)
        hsv = cv2.cvtColor(np.ascontiguousarray(image, dtype=np.uint8), cv2.COLOR_RGB2HSV)
        blobs = [self.largest_blob(hsv, hue) for hue in self.hues]
        if any(blob is None or not self.accepts(blob) for blob in blobs):
            return not_visible()
        centroids = np.array([blob.centroid for blob in blobs])
        cx, cy = camera.principal_point
        points = np.column_stack([cx - centroids[:, 0], cy - centroids[:, 1]])
        diameters = np.array([2.0 * np.sqrt(blob.area / np.pi) for blob in blobs])
        return points, diameters, True

    def mask(self, hsv: np.ndarray, hue: float) -> np.ndarray:
        """Pixels of ``hue`` (``uint8`` 0/255, shape (H, W)) in an OpenCV HSV image."""
        saturation, value = self.floors
        # OpenCV's 8-bit hue is degrees / 2; a window crossing 0 deg is two windows
        low, high = (hue - self.hue_tolerance) / 2.0, (hue + self.hue_tolerance) / 2.0
        mask = np.zeros(hsv.shape[:2], dtype=np.uint8)
        for start, stop in ((low, high), (low + 180.0, high + 180.0), (low - 180.0, high - 180.0)):
            lower = np.array([max(start, 0.0), saturation, value])
            upper = np.array([min(stop, 179.0), 255.0, 255.0])
            if lower[0] <= upper[0]:
                mask |= cv2.inRange(hsv, lower, upper)
        return mask

    def largest_blob(self, hsv: np.ndarray, hue: float) -> Blob | None:
        """The largest connected region of ``hue`` in an HSV image; None when there is none.

        The region is the largest outer contour (``cv2.findContours``) filled, intersected
        with the mask inside its bounding box; its moments are those of its pixels.
        """
        mask = self.mask(hsv, hue)
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        if not contours:
            return None
        contour = max(contours, key=cv2.contourArea)
        col, row, width, height = cv2.boundingRect(contour)
        region = np.zeros((height, width), dtype=np.uint8)
        cv2.drawContours(region, [contour], -1, 1, thickness=cv2.FILLED, offset=(-col, -row))
        region &= mask[row : row + height, col : col + width] > 0
        moments = cv2.moments(region, binaryImage=True)
        area = moments["m00"]
        centroid = np.array([col + moments["m10"] / area + 0.5, row + moments["m01"] / area + 0.5])
        _, radius = cv2.minEnclosingCircle(contour)
        fill = area / (np.pi * (radius + 0.5) ** 2)
        return Blob(centroid, float(area), (col, row, width, height), float(fill))

    def accepts(self, blob: Blob) -> bool:
        """Whether a blob is a whole sphere: size in range, inside the border, round."""
        diameter = 2.0 * np.sqrt(blob.area / np.pi)
        col, row, width, height = blob.bounds
        inside = (
            col > 0 and row > 0
            and col + width < self.camera.width and row + height < self.camera.height
        )  # fmt: skip
        return (
            self.min_diameter <= diameter <= self.max_diameter
            and inside
            and blob.fill >= self.min_fill
        )


DetectorFactory = Callable[[CameraIntrinsics], Detector]
"""Builds a detector for a camera's intrinsics."""

_DETECTORS: dict[str, DetectorFactory] = {"colour": ColourDetector}


def register_detector(name: str, factory: DetectorFactory) -> None:
    """Make a detector available to scenarios as ``camera.detector = name``.

    Args:
        name: The key's value.
        factory: Called with the camera's intrinsics, returns the detector.

    Raises:
        WrongType: If ``name`` is not text or ``factory`` cannot be called.
    """
    if not isinstance(name, str) or not name:
        raise WrongType("name", "a detector name (text)", name)
    if not callable(factory):
        raise WrongType("factory", "a callable (intrinsics -> detector)", factory)
    _DETECTORS[name] = factory


def detector_names() -> list[str]:
    """The registered detector names."""
    return sorted(_DETECTORS)


def detector_from(spec: str | Detector, camera: CameraIntrinsics) -> Detector:
    """A detector given by name (:func:`register_detector`) or as an object.

    Args:
        spec: A registered name, or any object with a ``detect(image)`` method.
        camera: The intrinsics a named detector is built for.

    Raises:
        GainError: If a name is not registered (the message lists the registered ones), or
            an object has no ``detect`` method.
    """
    if isinstance(spec, str):
        if spec not in _DETECTORS:
            raise GainError(
                f"unknown detector {spec!r}: expected one of {detector_names()}", "detector"
            )
        return _DETECTORS[spec](camera)
    if not callable(getattr(spec, "detect", None)):
        raise GainError(f"detector: expected a name or an object with detect(image), got {spec!r}")
    return spec
