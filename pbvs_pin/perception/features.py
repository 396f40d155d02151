r"""Image feature sets and the Jacobians of eq. (3).

A feature set turns the image points of the target into the feature vector ``xi`` (r entries,
pixels) and gives the two Jacobians of eq. (3),

.. math:: \dot\xi = J(q, \xi, z)\, v + J_o(q, \xi, z)\, \dot p,

where ``v`` are the robot's actuated velocities and ``p`` the target's world position. Both
are assembled from the point interaction matrix of :mod:`pbvs_pin.model.camera`, the camera frame
Jacobian in Pinocchio's ``LOCAL`` convention and the base's selection matrix ``S``.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from numba import njit

from pbvs_pin.exceptions import GainError, PointBehindCamera, ShapeError
from pbvs_pin.linalg import matmul
from pbvs_pin.model.camera import MIN_DEPTH, CameraIntrinsics, point_jacobians
from pbvs_pin.validation import (
    as_array,
    as_instance,
    as_matrix,
    as_numbers,
    as_rows,
    convert_fields,
)

if TYPE_CHECKING:
    from pbvs_pin.model.robot import MobileManipulator


def _checked_already(points: object, depths: object) -> bool:
    """Whether ``points`` and ``depths`` are float64 arrays of shapes (k, 2) and (k,)."""
    return (
        isinstance(points, np.ndarray)
        and isinstance(depths, np.ndarray)
        and points.dtype == np.float64
        and depths.dtype == np.float64
        and points.ndim == 2
        and points.shape[1] == 2
        and depths.shape == (points.shape[0],)
    )


@dataclass(frozen=True)
class ImageMeasurement:
    """What one camera frame gives about the target.

    Attributes:
        points: Image coordinates ``[u, v]`` of each target point [px]. Shape (k, 2).
        depths: Depth of each point along the optical axis [m]. Shape (k,).
    """

    points: np.ndarray
    depths: np.ndarray

    def __post_init__(self) -> None:
        """Convert both to float arrays, ``(k, 2)`` and ``(k,)`` (NaN kept: a lost point).

        Raises:
            WrongType: If either is not numbers.
            ShapeError: If the shapes differ from ``(k, 2)`` and ``(k,)``.
        """
        if _checked_already(self.points, self.depths):
            return  # float arrays of (k, 2) and (k,): the control loop's own measurements
        points = as_rows("points", self.points, 2, finite=False)
        rows = len(points)
        depths = as_numbers("depths", self.depths)
        if depths.shape != (rows,):
            raise ShapeError("depths", (rows,), depths.shape)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "depths", depths)


@njit(cache=True, inline="always")
def feature_jacobians(
    points: np.ndarray,
    depths: np.ndarray,
    rows: np.ndarray,
    focal: float,
    camera_jacobian: np.ndarray,
    rotation_world_to_camera: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""Features and both Jacobians of eq. (3) from image points.

    .. math:: J = L\, J_{cam} S,\qquad J_o = \frac{\partial \xi}{\partial p_c}\, {}^c R_w

    Args:
        points: ``[u, v]`` of each point [px]. Shape (k, 2).
        depths: Depths [m]. Shape (k,).
        rows: Indices into ``[u1, v1, u2, v2, ...]`` forming ``xi``. Shape (r,).
        focal: Focal length [px].
        camera_jacobian: ``J_cam S``, camera twist (LOCAL) per actuated velocity. Shape (6, n).
        rotation_world_to_camera: ``cRw``. Shape (3, 3).

    Returns:
        ``xi`` (r,) [px], ``J`` (r, n), ``J_o`` (r, 3).
    """
    interaction, position = point_jacobians(points, depths, focal)
    flat = points.ravel()
    r = rows.shape[0]
    xi = np.empty(r)
    selected_l = np.empty((r, 6))
    selected_p = np.empty((r, 3))
    for a in range(r):
        xi[a] = flat[rows[a]]
        selected_l[a] = interaction[rows[a]]
        selected_p[a] = position[rows[a]]
    return xi, matmul(selected_l, camera_jacobian), matmul(selected_p, rotation_world_to_camera)


class FeatureSet(abc.ABC):
    """Which image quantities form the feature vector, and their Jacobians."""

    @property
    @abc.abstractmethod
    def n_points(self) -> int:
        """Number of target points k the features are built from."""

    @property
    @abc.abstractmethod
    def rows(self) -> np.ndarray:  # indices, dtype int64
        """Indices into the stacked ``[u1, v1, u2, v2, ...]`` that form ``xi``. Shape (r,)."""

    @property
    def size(self) -> int:
        """Number of features r."""
        return len(self.rows)

    def features(self, measurement: ImageMeasurement) -> np.ndarray:
        """Feature vector ``xi`` [px]. Shape (r,)."""
        return measurement.points.reshape(-1)[self.rows]

    def interaction_matrix(
        self, camera: CameraIntrinsics, measurement: ImageMeasurement
    ) -> np.ndarray:
        """Feature rate from the camera twist in the camera frame.

        Args:
            camera: Intrinsics.
            measurement: Image points and depths.

        Returns:
            Shape (r, 6) [px/m, px/rad].
        """
        stacked = point_jacobians(measurement.points, measurement.depths, camera.focal_px)[0]
        return stacked[self.rows]

    def object_jacobian(
        self,
        camera: CameraIntrinsics,
        measurement: ImageMeasurement,
        rotation_world_to_camera: np.ndarray,
    ) -> np.ndarray:
        r"""``J_o`` of eq. (3): feature rate from the target's world velocity.

        Every target point translates with the same world velocity ``pdot``:

        .. math:: J_o = \frac{\partial \xi}{\partial p_c}\, {}^c R_w,\qquad
                  \frac{\partial \xi_i}{\partial p_c} =
                  \begin{bmatrix} -f/z_i & 0 & -u_i/z_i \\ 0 & -f/z_i & -v_i/z_i \end{bmatrix}

        Args:
            camera: Intrinsics.
            measurement: Image points and depths.
            rotation_world_to_camera: ``cRw``, maps world vectors into the camera frame.
                Shape (3, 3).

        Returns:
            Shape (r, 3) [px/m].
        """
        stacked = point_jacobians(measurement.points, measurement.depths, camera.focal_px)[1]
        rotation = as_array("rotation_world_to_camera", rotation_world_to_camera, (3, 3))
        return (stacked @ rotation)[self.rows]

    def jacobians_from_measurement(
        self,
        camera: CameraIntrinsics,
        measurement: ImageMeasurement,
        camera_jacobian: np.ndarray,
        rotation_world_to_camera: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(xi, J, J_o)`` of eq. (3) from what the camera measured.

        Args:
            camera: Intrinsics.
            measurement: Image points and depths.
            camera_jacobian: ``J_cam S`` (LOCAL camera twist per actuated velocity).
                Shape (6, n).
            rotation_world_to_camera: ``cRw``. Shape (3, 3).

        Returns:
            ``xi`` [px] shape (r,), ``J`` shape (r, n), ``J_o`` shape (r, 3).
        """
        camera_jacobian = as_matrix("camera_jacobian", camera_jacobian, 6)
        rotation = as_array("rotation_world_to_camera", rotation_world_to_camera, (3, 3))
        return feature_jacobians(
            measurement.points,
            measurement.depths,
            self.rows,
            camera.focal_px,
            camera_jacobian,
            np.ascontiguousarray(rotation),
        )

    def measure(
        self, robot: MobileManipulator, q: npt.ArrayLike, points_world: npt.ArrayLike
    ) -> ImageMeasurement:
        """Exact image of target points for a robot configuration.

        Args:
            robot: The robot carrying the camera.
            q: Pinocchio configuration. Shape (nq,).
            points_world: Target points in the world [m]. Shape (k, 3).

        Returns:
            Image points and true depths.

        Raises:
            PointBehindCamera: If a point is not in front of the camera.
        """
        points = as_array("points_world", points_world, (self.n_points, 3))
        image, depths = robot.camera.project_world(robot.camera_pose(q), points)
        if np.any(depths <= MIN_DEPTH):
            raise PointBehindCamera(float(depths.min()))
        return ImageMeasurement(image, depths)

    def visible(
        self, robot: MobileManipulator, q: npt.ArrayLike, points_world: npt.ArrayLike
    ) -> bool:
        """Whether every target point is in front of the camera and inside the image.

        Args:
            robot: The robot carrying the camera.
            q: Pinocchio configuration. Shape (nq,).
            points_world: Target points in the world [m]. Shape (k, 3).
        """
        try:
            measurement = self.measure(robot, q, points_world)
        except PointBehindCamera:
            return False
        return robot.camera.in_image(measurement.points)

    def jacobians(
        self, robot: MobileManipulator, q: npt.ArrayLike, *points_world: npt.ArrayLike
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Features and both Jacobians of eq. (3) from world target points.

        Args:
            robot: The robot carrying the camera.
            q: Pinocchio configuration. Shape (nq,).
            *points_world: The k target points in the world [m], each shape (3,).

        Returns:
            ``(xi, J, J_o)``: features [px] shape (r,), total Jacobian shape (r, robot.n),
            object Jacobian shape (r, 3).
        """
        if len(points_world) != self.n_points:
            raise ShapeError("points_world", (self.n_points, 3), (len(points_world), 3))
        shapes = [np.shape(point) for point in points_world]
        if len(set(shapes)) > 1:  # ragged: name the first point that is not a 3-vector
            i = next(i for i, shape in enumerate(shapes) if shape != (3,))
            raise ShapeError(f"points_world[{i}]", (3,), shapes[i])
        measurement = self.measure(robot, q, np.array(points_world, dtype=float))
        pose = robot.camera_pose(q)
        return self.jacobians_from_measurement(
            robot.camera, measurement, robot.camera_jacobian(q), pose.rotation.T
        )


def checked_feature_set(
    features: object, xi_d: npt.ArrayLike | None
) -> tuple[FeatureSet, np.ndarray]:
    """A user's feature set and its desired features, checked once where they enter.

    The compiled step reads only :attr:`FeatureSet.n_points` and :attr:`FeatureSet.rows` (the
    features are coordinates of the frame's points, eq. (3)); these are checked here.

    Args:
        features: A :class:`FeatureSet`.
        xi_d: Its desired features [px]. Shape (r,).

    Returns:
        The feature set and ``xi_d`` as a float array.

    Raises:
        WrongType: If ``features`` is not a FeatureSet, or a value is not numbers.
        GainError: If ``n_points`` is not a positive integer, or ``rows`` is empty, not
            integers, repeats an index or has one outside ``[0, 2 n_points)``; if ``xi_d``
            is missing.
        ShapeError: If ``xi_d`` does not have one entry per feature.
        NonFiniteValue: If ``xi_d`` holds NaN or inf.
    """
    features = as_instance("features", features, FeatureSet)
    name = type(features).__name__
    points = features.n_points
    if isinstance(points, bool) or not isinstance(points, int | np.integer) or points < 1:
        raise GainError(f"{name}.n_points: expected a positive integer, got {points!r}")
    rows = np.asarray(features.rows)
    stacked = 2 * int(points)
    if (
        rows.ndim != 1
        or rows.size == 0
        or rows.dtype.kind not in "iu"
        or len(np.unique(rows)) != rows.size
        or rows.min() < 0
        or rows.max() >= stacked
    ):
        raise GainError(
            f"{name}.rows: expected distinct integer indices into the {stacked} stacked "
            f"coordinates [u1, v1, ...] of {points} points, got {rows.tolist()!r}"
        )
    if xi_d is None:
        raise GainError(
            f"xi_d: a feature set of your own ({name}) needs its desired features, "
            f"{rows.size} values [px]"
        )
    return features, as_array("xi_d", xi_d, (rows.size,))


@dataclass(frozen=True)
class TwoSphereFeatures(FeatureSet):
    """The paper's features: two vertically aligned spheres, ``xi = [u1, v1, v2]``.

    Sphere 1 is the upper one. Depth comes from each sphere's apparent diameter.

    Attributes:
        diameter: Sphere diameter D [m].
    """

    diameter: float

    def __post_init__(self) -> None:
        """Reject a non-positive diameter."""
        convert_fields(self, numbers=("diameter",))
        if not np.isfinite(self.diameter) or self.diameter <= 0.0:
            raise GainError(f"TwoSphereFeatures.diameter: expected > 0 m, got {self.diameter}")

    @property
    def n_points(self) -> int:
        """Two sphere centres."""
        return 2

    @property
    def rows(self) -> np.ndarray:
        """``[u1, v1, v2]``."""
        return np.array([0, 1, 3])


@dataclass(frozen=True)
class ImagePointFeatures(FeatureSet):
    """Generic features: both coordinates of k image points, ``xi = [u1, v1, ..., uk, vk]``.

    Attributes:
        count: Number of points k.
    """

    count: int

    def __post_init__(self) -> None:
        """Reject a non-positive count."""
        convert_fields(self, counts=("count",))
        if self.count < 1:
            raise GainError(f"ImagePointFeatures.count: expected >= 1, got {self.count}")

    @property
    def n_points(self) -> int:
        """K."""
        return self.count

    @property
    def rows(self) -> np.ndarray:
        """All coordinates."""
        return np.arange(2 * self.count)
