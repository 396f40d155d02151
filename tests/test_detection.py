"""The default detector on images drawn by OpenCV with spheres at known positions."""

from __future__ import annotations

import colorsys

import cv2
import numpy as np
import pytest

from pbvs_pin.exceptions import GainError, ShapeError
from pbvs_pin.model.camera import CameraIntrinsics
from pbvs_pin.perception.detection import (
    SPHERE_HUES,
    ColourDetector,
    Detector,
    detector_from,
    detector_names,
    register_detector,
)

CAMERA = CameraIntrinsics(600.0, 628, 582)
SHIFT = 8  # cv2.circle's fractional bits: centres and radii at 1/256 px
BACKGROUND = (110, 110, 110)


def rgb(hue: float, value: float = 0.9) -> tuple[int, int, int]:
    return tuple(round(255 * c) for c in colorsys.hsv_to_rgb(hue / 360, 1.0, value))


def draw(centres, radii, value: float = 0.9, size=(582, 628)) -> np.ndarray:
    """Grey image with a filled disc per sphere; centres in pixel [col, row] (centre at +0.5)."""
    image = np.full((*size, 3), BACKGROUND, dtype=np.uint8)
    for (col, row), radius, hue in zip(centres, radii, SPHERE_HUES, strict=True):
        # OpenCV's pixel (i, j) has its centre at (i, j): shift our +0.5 convention
        centre = tuple(round((c - 0.5) * 2**SHIFT) for c in (col, row))
        cv2.circle(image, centre, round(radius * 2**SHIFT), rgb(hue, value), -1,
                   cv2.LINE_8, SHIFT)  # fmt: skip
    return image


def to_image_coordinates(col: float, row: float) -> np.ndarray:
    """The paper's [u, v] of a pixel position, written out: u = W/2 - col, v = H/2 - row."""
    return np.array([314.0 - col, 291.0 - row])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_centroids_and_diameters_of_drawn_discs(seed):
    rng = np.random.default_rng(seed)
    centres = rng.uniform([80, 80], [548, 502], size=(2, 2))
    radii = rng.uniform(8.0, 40.0, size=2)
    if np.linalg.norm(centres[0] - centres[1]) < radii.sum() + 2:
        centres[1] = 628 - centres[0]  # keep the discs apart
    points, diameters, visible = ColourDetector(CAMERA).detect(draw(centres, radii))
    assert visible
    for k in range(2):
        np.testing.assert_allclose(points[k], to_image_coordinates(*centres[k]), atol=0.3)
    # cv2.circle fills the pixels within r + 1/2 of the centre: a disc of diameter 2 r + 1
    np.testing.assert_allclose(diameters, 2 * radii + 1.0, atol=0.3)


def test_darker_lighting_still_found():
    centres, radii = np.array([[200.3, 150.7], [420.1, 400.2]]), np.array([20.0, 25.0])
    points, _, visible = ColourDetector(CAMERA).detect(draw(centres, radii, value=0.3))
    assert visible
    np.testing.assert_allclose(points[1], to_image_coordinates(*centres[1]), atol=0.3)


@pytest.mark.parametrize(
    ("centres", "radii", "why"),
    [
        ([[5.0, 150.0], [400.0, 300.0]], [20.0, 20.0], "cut by the left border"),
        ([[300.0, 300.0], [400.0, 578.0]], [20.0, 20.0], "cut by the bottom border"),
        ([[300.0, 150.0], [400.0, 300.0]], [1.0, 20.0], "too small"),
        ([[300.0, 290.0], [600.0, 300.0]], [200.0, 10.0], "too large"),
    ],
)
def test_refused_blobs_are_not_visible(centres, radii, why):
    points, diameters, visible = ColourDetector(CAMERA).detect(
        draw(np.array(centres), np.array(radii))
    )
    assert not visible, why
    assert np.isnan(points).all() and np.isnan(diameters).all()


def test_half_hidden_sphere_is_not_visible():
    """A bar over half of a disc (the arm in front of the sphere) leaves a blob that is not round."""
    image = draw(np.array([[200.0, 200.0], [400.0, 300.0]]), np.array([25.0, 25.0]))
    cv2.rectangle(image, (200, 150), (260, 250), (60, 60, 60), -1)
    assert not ColourDetector(CAMERA).detect(image)[2]


def test_missing_sphere_is_not_visible():
    image = draw(np.array([[200.0, 200.0], [400.0, 300.0]]), np.array([25.0, 25.0]))
    image[250:350, 350:450] = BACKGROUND
    assert not ColourDetector(CAMERA).detect(image)[2]


def test_wrong_image_shape():
    with pytest.raises(
        ShapeError, match=r"image: expected shape \(582, 628, 3\), got \(10, 10, 3\)"
    ):
        ColourDetector(CAMERA).detect(np.zeros((10, 10, 3), dtype=np.uint8))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"min_fill": 0.0}, "min_fill"),
        ({"hue_tolerance": 120.0}, "hue_tolerance"),
        ({"min_diameter": 50.0, "max_diameter": 10.0}, "min_diameter < max_diameter"),
    ],
)
def test_bad_detector_values(kwargs, match):
    with pytest.raises(GainError, match=match):
        ColourDetector(CAMERA, **kwargs)


class FixedDetector(Detector):
    def __init__(self, camera):
        self.camera = camera

    def detect(self, image):
        return np.array([[1.0, 2.0], [3.0, 4.0]]), np.array([5.0, 6.0]), True


def test_detector_by_name_and_by_object():
    register_detector("fixed_for_test", FixedDetector)
    assert "fixed_for_test" in detector_names()
    named = detector_from("fixed_for_test", CAMERA)
    assert isinstance(named, FixedDetector) and named.camera is CAMERA
    given = FixedDetector(CAMERA)
    assert detector_from(given, CAMERA) is given
    assert isinstance(detector_from("colour", CAMERA), ColourDetector)


def test_unknown_detector_names_the_registered_ones():
    with pytest.raises(GainError, match=r"unknown detector 'nope': expected one of \[.*'colour'"):
        detector_from("nope", CAMERA)
    with pytest.raises(GainError, match="detect"):
        detector_from(object(), CAMERA)
