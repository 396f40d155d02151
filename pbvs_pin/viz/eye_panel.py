"""The robot's-eye view in a live Meshcat scene: a panel fixed in the browser's view.

:class:`EyePanel` draws a textured plane as a child of the browser's viewing camera
(``/Cameras/default/rotated/<object>``, meshcat's orbit-controlled camera), so it stays in the
lower left of the view whatever the user does with the mouse, and scene objects never hide it
(its material has no depth test). Its texture is a PNG of the camera image at
:data:`PANEL_SCALE` of its size, marked by :func:`pbvs_pin.viz.eye_view.mark` as the saved
eye view is: white circles where the detector found the spheres (centre and apparent
diameter), cyan crosses at the desired features ``xi_d``.

- **Rendered camera** (``camera.model = "rendered"``): the image is the run's own newest frame
  (:class:`~pbvs_pin.perception.detection.CameraImage`), circled where the run's detector found the
  spheres; nothing is drawn again.
- **Points camera**: there is no image, so :meth:`EyePanel.show_points` draws one: the two
  spheres as discs of their colours (:data:`pbvs_pin.perception.detection.SPHERE_HUES`) at the
  measured points, of the diameter given, on a plain grey background; the same marks on top.

The panel is placed for meshcat's default viewing camera (vertical field of view
:data:`VIEW_FOV`); its left edge is within the view of any window at least as wide as it is
tall. It can be hidden with its checkbox under ``Cameras`` in meshcat's controls.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from pbvs_pin.model.camera import CameraIntrinsics
from pbvs_pin.perception.detection import SPHERE_HUES, sphere_rgba
from pbvs_pin.viz.eye_view import mark

if TYPE_CHECKING:  # pragma: no cover - typing only
    import meshcat

PANEL_PATH = "/Cameras/default/rotated/<object>/pbvs_eye_view"
"""Meshcat path of the panel: a child of the browser's viewing camera."""

VIEW_FOV = 75.0
"""Vertical field of view of meshcat's default viewing camera [deg]."""

PANEL_DEPTH = 0.05
"""Distance of the panel in front of the viewing camera [m] (beyond its 0.01 m near plane)."""

PANEL_HEIGHT = 0.4
"""Height of the panel as a fraction of the view's height."""

PANEL_MARGIN = 0.03
"""Gap between the panel and the view's left and bottom edges, a fraction of its height."""

PANEL_SCALE = 0.5
"""Size of the panel's image relative to the camera image (PNG encoding time goes with it)."""

MARK_THICKNESS = 2
"""Line width of the marks [px of the camera image]: 1 px on the half-size panel image."""

BACKGROUND_RGB = (96, 96, 96)
"""Background of the points camera's drawn image (the floor's grey, darker)."""

PNG_COMPRESSION = 1
"""zlib level of the panel's PNG: the fastest; the image is only sent to a local server."""


def panel_rectangle(aspect: float) -> tuple[float, float, float, float]:
    """The panel's left, bottom, right and top edges in the viewing camera's frame [m].

    The frame is three.js's (x right, y up, looking along ``-z``); the panel lies at
    ``z = -PANEL_DEPTH``, where the view's half-height is ``PANEL_DEPTH tan(VIEW_FOV / 2)``.

    Args:
        aspect: The image's width over its height.
    """
    half = PANEL_DEPTH * np.tan(np.radians(VIEW_FOV) / 2)
    left = bottom = -half + PANEL_MARGIN * 2 * half
    height = PANEL_HEIGHT * 2 * half
    return left, bottom, left + aspect * height, bottom + height


def _plane_geometry(width: float, height: float) -> Any:
    """three.js's ``PlaneGeometry`` of ``width`` x ``height`` [m] (meshcat 0.3 has none)."""
    import meshcat.geometry as g

    class PlaneGeometry(g.Geometry):
        def lower(self, object_data: Any) -> dict[str, Any]:
            return {
                "uuid": self.uuid, "type": "PlaneGeometry", "width": width, "height": height,
                "widthSegments": 1, "heightSegments": 1,
            }  # fmt: skip

    return PlaneGeometry()


class EyePanel:
    """The robot's-eye view panel of a live meshcat scene (module docstring).

    Args:
        vis: The served visualizer.
        camera: The robot's camera intrinsics (image size, pixel positions).
        desired: Desired ``[u, v]`` of both spheres [px], crossed on every image. Shape (2, 2).
    """

    def __init__(
        self, vis: meshcat.Visualizer, camera: CameraIntrinsics, desired: np.ndarray
    ) -> None:
        import meshcat.transformations as tf

        self.vis, self.camera = vis, camera
        self.desired = np.asarray(desired, dtype=float).reshape(2, 2)
        left, bottom, right, top = panel_rectangle(camera.width / camera.height)
        self._plane = _plane_geometry(right - left, top - bottom)
        size = (camera.height, camera.width, 3)
        self._background = np.broadcast_to(np.array(BACKGROUND_RGB, np.uint8), size).copy()
        centre = [(left + right) / 2, (bottom + top) / 2, -PANEL_DEPTH]
        self.vis[PANEL_PATH].set_transform(tf.translation_matrix(centre))
        self.show_points(np.full((2, 2), np.nan), np.full(2, np.nan))

    def show_image(
        self, image: np.ndarray, points: np.ndarray | None, diameters: np.ndarray
    ) -> None:
        """Show a camera image with its detections and ``xi_d`` marked.

        Args:
            image: RGB ``uint8``. Shape (H, W, 3).
            points: Found ``[u, v]`` of both spheres [px]; None: not found. Shape (2, 2).
            diameters: Their apparent diameters [px]. Shape (2,).
        """
        import meshcat.geometry as g

        marked = mark(image, self.camera, points, diameters, self.desired, MARK_THICKNESS)
        scale = PANEL_SCALE
        small = cv2.resize(marked, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        bgr = cv2.cvtColor(small, cv2.COLOR_RGB2BGR)
        _, png = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, PNG_COMPRESSION])
        texture = g.ImageTexture(g.PngImage(png.tobytes()))
        material = g.MeshBasicMaterial(map=texture, depthTest=False)
        self.vis[PANEL_PATH].set_object(g.Mesh(self._plane, material))

    def show_points(self, points: np.ndarray, diameters: np.ndarray) -> None:
        """Show the points camera's view: the spheres drawn as discs, then marked.

        Args:
            points: Measured ``[u, v]`` of both spheres [px] (NaN: not seen). Shape (2, 2).
            diameters: Their apparent diameters [px] (NaN: not drawn). Shape (2,).
        """
        camera = self.camera
        image = self._background.copy()
        points = np.asarray(points, dtype=float).reshape(2, 2)
        diameters = np.asarray(diameters, dtype=float).reshape(2)
        seen = bool(np.all(np.isfinite(points)) and np.all(np.isfinite(diameters)))
        if seen:
            pixels = camera.to_pixel(points)
            for (col, row), diameter, hue in zip(pixels, diameters, SPHERE_HUES, strict=True):
                if max(abs(col), abs(row), diameter) < 1e6:
                    colour = tuple(round(255 * c) for c in sphere_rgba(hue)[:3])
                    centre = (round(col - 0.5), round(row - 0.5))
                    cv2.circle(image, centre, round(diameter / 2), colour, -1, cv2.LINE_AA)
        self.show_image(image, points if seen else None, diameters)
