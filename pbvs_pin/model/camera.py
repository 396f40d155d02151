"""Pinhole camera with the paper's sign convention, eq. (2).

Image coordinates ``xi = [u, v]`` are pixels measured from the principal point, with the sign
of eq. (2): ``xi = -(f / z) [x, y]`` for a point ``[x, y, z]`` in the camera optical frame
(z forward, x right, y down). So ``u`` grows to the left and ``v`` grows upwards in the image.
Pixel rows and columns, used for the image bounds, are ``col = cx - u`` and ``row = cy - v``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from numba import njit

from pbvs_pin.exceptions import GainError, PointBehindCamera, ShapeError
from pbvs_pin.validation import (
    as_array,
    as_number,
    as_numbers,
    as_pose_object,
    as_rows,
    convert_fields,
)

MIN_DEPTH = 1e-3
"""Smallest depth [m] at which a point counts as in front of the camera."""


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics.

    The defaults model the paper's camera: 628 x 582 px images and a 1/3" sensor; the focal
    length (600 px, a 4.6 mm lens on that sensor) is not given in the paper.

    Attributes:
        focal_px: Focal length f [px].
        width: Image width [px].
        height: Image height [px].
    """

    focal_px: float = 600.0
    width: int = 628
    height: int = 582

    def __post_init__(self) -> None:
        """Reject non-positive values."""
        convert_fields(self, numbers=("focal_px",), counts=("width", "height"))
        for name in ("focal_px", "width", "height"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise GainError(f"CameraIntrinsics.{name}: expected > 0, got {value}")

    @property
    def principal_point(self) -> tuple[float, float]:
        """``(cx, cy)``: the image centre in pixel columns and rows."""
        return 0.5 * self.width, 0.5 * self.height

    def project(self, point_in_camera: npt.ArrayLike) -> np.ndarray:
        r"""Project a point given in the optical frame, eq. (2).

        .. math:: \xi = -\frac{f}{z} \begin{bmatrix} x \\ y \end{bmatrix}

        Args:
            point_in_camera: ``[x, y, z]`` [m]. Shape (3,).

        Returns:
            ``[u, v]`` [px]. Shape (2,).

        Raises:
            PointBehindCamera: If ``z <= MIN_DEPTH``.
        """
        x, y, z = as_array("point_in_camera", point_in_camera, (3,))
        if z <= MIN_DEPTH:
            raise PointBehindCamera(float(z))
        return -self.focal_px / z * np.array([x, y])

    def project_world(
        self, camera_pose: pin.SE3, points_world: np.ndarray, min_depth: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray]:
        r"""Eq. (2) for world points seen from ``world_T_camera``, for many points at once.

        .. math:: p_c = {}^c R_w (p_w - {}^w t_c),\qquad \xi = -\frac{f}{z} [x, y]

        No depth check: the caller decides what a point behind the camera means.

        Args:
            camera_pose: ``world_T_camera``.
            points_world: Points in the world [m]. Shape (k, 3).
            min_depth: Smallest depth used as divisor [m] (0: none), to keep a solver finite.

        Returns:
            Image points ``[u, v]`` [px], shape (k, 2), and depths [m], shape (k,).
        """
        camera_pose = as_pose_object("camera_pose", camera_pose)
        points = as_rows("points_world", points_world, 3, finite=False)
        min_depth = as_number("min_depth", min_depth)
        return project_points(
            points, camera_pose.translation, camera_pose.rotation, self.focal_px, min_depth
        )

    def project_jacobian(self, point_in_camera: npt.ArrayLike) -> np.ndarray:
        r"""Derivative of :meth:`project` with respect to the point.

        .. math:: \frac{\partial \xi}{\partial p} =
                  \begin{bmatrix} -f/z & 0 & -u/z \\ 0 & -f/z & -v/z \end{bmatrix}

        Args:
            point_in_camera: ``[x, y, z]`` [m]. Shape (3,).

        Returns:
            Shape (2, 3) [px/m].
        """
        u, v = self.project(point_in_camera)
        z = float(np.asarray(point_in_camera, dtype=float)[2])
        f = self.focal_px
        return np.array([[-f / z, 0.0, -u / z], [0.0, -f / z, -v / z]])

    def back_project(self, xi: npt.ArrayLike, depths: npt.ArrayLike) -> np.ndarray:
        r"""Points in the optical frame from their image points and depths, eq. (2) inverted.

        .. math:: \begin{bmatrix} x \\ y \end{bmatrix} = -\frac{z}{f} \xi

        Args:
            xi: Image points ``[u, v]`` [px]. Shape (k, 2).
            depths: Depths ``z`` along the optical axis [m]. Shape (k,).

        Returns:
            ``[x, y, z]`` in the optical frame [m]. Shape (k, 3).
        """
        xi = as_rows("xi", xi, 2)
        depths = as_array("depths", depths, (len(xi),))
        return back_project_points(xi, depths, self.focal_px)

    def to_pixel(self, xi: npt.ArrayLike) -> np.ndarray:
        """Image coordinates ``[u, v]`` to pixel ``[col, row]``. Shape (..., 2).

        ``col`` runs right and ``row`` down from the image's top-left corner; the pixel of
        index ``(i, j)`` is centred at ``(i + 0.5, j + 0.5)``. ``u = W/2 - col``,
        ``v = H/2 - row``.
        """
        xi = as_numbers("xi", xi)
        if xi.ndim == 0 or xi.shape[-1] != 2:
            raise ShapeError("xi", (*xi.shape[:-1], 2), xi.shape)
        cx, cy = self.principal_point
        return np.stack([cx - xi[..., 0], cy - xi[..., 1]], axis=-1)

    def from_pixel(self, pixel: npt.ArrayLike) -> np.ndarray:
        """Pixel ``[col, row]`` to image coordinates ``[u, v]``, :meth:`to_pixel` inverted.

        Args:
            pixel: ``[col, row]`` [px], the pixel of index ``(i, j)`` centred at
                ``(i + 0.5, j + 0.5)``. Shape (..., 2).

        Returns:
            ``[u, v]`` [px], origin at the image centre, ``u`` left, ``v`` up. Shape (..., 2).
        """
        pixel = as_numbers("pixel", pixel)
        if pixel.ndim == 0 or pixel.shape[-1] != 2:
            raise ShapeError("pixel", (*pixel.shape[:-1], 2), pixel.shape)
        return self.to_pixel(pixel)  # (u, v) -> (W/2 - u, H/2 - v) is its own inverse

    def in_image(self, xi: npt.ArrayLike, margin: float = 0.0) -> bool:
        """Whether every image point ``[u, v]`` (shape (..., 2)) is inside the image.

        Args:
            xi: Image points [px].
            margin: Distance [px] the points must keep from the border.
        """
        margin = as_number("margin", margin)
        pixel = self.to_pixel(xi)
        cols, rows = pixel[..., 0], pixel[..., 1]
        return bool(
            np.all(cols >= margin)
            and np.all(cols <= self.width - margin)
            and np.all(rows >= margin)
            and np.all(rows <= self.height - margin)
        )

    def depth_from_diameter(self, diameter_px: float, diameter_m: float) -> float:
        r"""Depth of a sphere from its apparent diameter (paper §2.2).

        .. math:: z = \frac{f D}{d_{px}}

        Args:
            diameter_px: Apparent diameter d [px].
            diameter_m: True diameter D [m].

        Returns:
            Depth z [m].

        Raises:
            PointBehindCamera: If the apparent diameter is not positive.
        """
        diameter_px = as_number("diameter_px", diameter_px, finite=False)
        diameter_m = as_number("diameter_m", diameter_m)
        if not np.isfinite(diameter_px) or diameter_px <= 0.0:
            raise PointBehindCamera(float("inf") if diameter_px == 0 else -1.0)
        return self.focal_px * diameter_m / diameter_px

    def apparent_diameter(self, depth: float, diameter_m: float) -> float:
        """Apparent diameter [px] of a sphere of diameter ``diameter_m`` at ``depth`` [m]."""
        depth, diameter_m = as_number("depth", depth), as_number("diameter_m", diameter_m)
        return self.focal_px * diameter_m / depth


@njit(cache=True, inline="always")
def point_jacobians(
    points: np.ndarray, depths: np.ndarray, focal: float
) -> tuple[np.ndarray, np.ndarray]:
    r"""Interaction matrix and position Jacobian of each image point (paper's sign, eq. 2).

    With ``xn = -u / f`` and ``yn = -v / f`` (Chaumette & Hutchinson 2006, scaled by ``-f``):

    .. math:: L_i = -f \begin{bmatrix}
              -1/z & 0 & x_n/z & x_n y_n & -(1 + x_n^2) & y_n \\
              0 & -1/z & y_n/z & 1 + y_n^2 & -x_n y_n & -x_n \end{bmatrix},\quad
              \frac{\partial \xi_i}{\partial p_c} =
              \begin{bmatrix} -f/z & 0 & -u/z \\ 0 & -f/z & -v/z \end{bmatrix}

    Args:
        points: ``[u, v]`` of each point [px]. Shape (k, 2).
        depths: Depth of each point [m]. Shape (k,).
        focal: Focal length f [px].

    Returns:
        ``L`` stacked, shape (2k, 6) [px/m, px/rad], for the camera twist in the camera frame
        with the point fixed in the world; ``d xi / d p_c`` stacked, shape (2k, 3) [px/m].
    """
    k = points.shape[0]
    interaction = np.zeros((2 * k, 6))
    position = np.zeros((2 * k, 3))
    for i in range(k):
        u, v, z = points[i, 0], points[i, 1], depths[i]
        xn, yn = -u / focal, -v / focal
        a, b = 2 * i, 2 * i + 1
        interaction[a, 0] = focal / z
        interaction[a, 2] = -focal * xn / z
        interaction[a, 3] = -focal * xn * yn
        interaction[a, 4] = focal * (1.0 + xn * xn)
        interaction[a, 5] = -focal * yn
        interaction[b, 1] = focal / z
        interaction[b, 2] = -focal * yn / z
        interaction[b, 3] = -focal * (1.0 + yn * yn)
        interaction[b, 4] = focal * xn * yn
        interaction[b, 5] = focal * xn
        position[a, 0] = -focal / z
        position[a, 2] = -u / z
        position[b, 1] = -focal / z
        position[b, 2] = -v / z
    return interaction, position


def point_interaction_matrix(focal_px: float, xi: npt.ArrayLike, depth: float) -> np.ndarray:
    r"""Interaction matrix of one image point in the paper's sign convention.

    With normalised coordinates ``xn = -u / f`` and ``yn = -v / f``, the classic point
    interaction matrix (Chaumette & Hutchinson 2006) scaled by ``-f``:

    .. math:: \dot\xi = -f \begin{bmatrix}
              -1/z & 0 & x_n/z & x_n y_n & -(1 + x_n^2) & y_n \\
              0 & -1/z & y_n/z & 1 + y_n^2 & -x_n y_n & -x_n \end{bmatrix}
              \begin{bmatrix} v_c \\ \omega_c \end{bmatrix}

    where ``[v_c; w_c]`` is the camera's twist expressed in the camera frame (Pinocchio's
    ``LOCAL`` convention) and the point is fixed in the world. Computed by
    :func:`point_jacobians`.

    Args:
        focal_px: Focal length f [px].
        xi: ``[u, v]`` [px]. Shape (2,).
        depth: Depth z [m].

    Returns:
        Shape (2, 6) [px/m, px/rad].
    """
    points = as_array("xi", xi, (2,)).reshape(1, 2)
    depth, focal_px = as_number("depth", depth), as_number("focal_px", focal_px)
    return point_jacobians(points, np.array([depth]), focal_px)[0]


def back_project_points(xi: np.ndarray, depths: np.ndarray, focal: float) -> np.ndarray:
    """:meth:`CameraIntrinsics.back_project` for float arrays of shapes (k, 2) and (k,).

    Returns:
        ``[x, y, z]`` in the optical frame [m]. Shape (k, 3).
    """
    in_camera = np.empty((len(depths), 3))
    np.multiply(-xi, depths[:, None], out=in_camera[:, :2])
    in_camera[:, :2] /= focal
    in_camera[:, 2] = depths
    return in_camera


@njit(cache=True, error_model="numpy")
def project_points(
    points_world: np.ndarray,
    translation: np.ndarray,
    rotation: np.ndarray,
    focal: float,
    min_depth: float,
) -> tuple[np.ndarray, np.ndarray]:
    r"""Eq. (2) for world points seen from ``world_T_camera`` (:meth:`project_world`).

    .. math:: p_c = {}^c R_w (p_w - {}^w t_c),\qquad \xi = -\frac{f}{z} [x, y]

    The rotation is applied by ``np.dot`` (BLAS, as NumPy's ``@``: the same numbers).

    Args:
        points_world: Points in the world [m]. Shape (k, 3).
        translation: ``{}^w t_c`` [m]. Shape (3,).
        rotation: ``{}^w R_c``. Shape (3, 3).
        focal: Focal length ``f`` [px].
        min_depth: Smallest depth used as divisor [m] (0: none); a NaN depth stays NaN.

    Returns:
        Image points ``[u, v]`` [px], shape (k, 2) (infinite or NaN at a zero depth), and
        depths [m], shape (k,).
    """
    in_camera = np.dot(points_world - translation, rotation)
    k = in_camera.shape[0]
    image, depths = np.empty((k, 2)), np.empty(k)
    for i in range(k):
        z = in_camera[i, 2]
        depths[i] = z
        divisor = z if min_depth <= 0 or not z < min_depth else min_depth
        image[i, 0] = -focal * in_camera[i, 0] / divisor
        image[i, 1] = -focal * in_camera[i, 1] / divisor
    return image, depths
