"""Obstacles on the floor, the platform's 2D laser rangefinder, and clearance.

Obstacles are vertical prisms (circles and boxes in the floor plane). The laser casts rays in
the plane of its frame; the nearest return gives ``d`` and the incidence angle ``alpha`` of
eqs. (17)-(18), measured clockwise from the platform's forward axis (positive to the right).
"""

from __future__ import annotations

import abc
from dataclasses import dataclass

import numpy as np

from pbvs_pin.exceptions import GainError


class Obstacle(abc.ABC):
    """A vertical prism standing on the floor."""

    @abc.abstractmethod
    def ray_distances(self, origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Distance along each ray to the first hit, ``inf`` for a miss.

        Args:
            origin: Ray origin in the floor plane [m]. Shape (2,).
            directions: Unit ray directions. Shape (k, 2).

        Returns:
            Shape (k,) [m].
        """

    @abc.abstractmethod
    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """Distance from each floor point to the obstacle, negative inside. Shape (k,)."""


@dataclass(frozen=True)
class CircleObstacle(Obstacle):
    """A vertical cylinder.

    Attributes:
        x: Centre x [m].
        y: Centre y [m].
        radius: [m].
        height: [m] (for display).
    """

    x: float
    y: float
    radius: float
    height: float = 0.4

    def __post_init__(self) -> None:
        """Reject a non-positive radius."""
        if not self.radius > 0:
            raise GainError(f"CircleObstacle.radius: expected > 0 m, got {self.radius}")

    def ray_distances(self, origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Smallest non-negative root of ``|o + s d - c| = r``."""
        offset = origin - np.array([self.x, self.y])
        b = directions @ offset
        c = offset @ offset - self.radius**2
        disc = b * b - c
        hit = disc >= 0
        root = np.sqrt(np.where(hit, disc, 0.0))
        near, far = -b - root, -b + root
        s = np.where(near >= 0, near, np.where(far >= 0, 0.0, np.inf))
        return np.where(hit, s, np.inf)

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """``|p - c| - r``."""
        return np.linalg.norm(points - [self.x, self.y], axis=1) - self.radius


@dataclass(frozen=True)
class BoxObstacle(Obstacle):
    """A vertical box.

    Attributes:
        x: Centre x [m].
        y: Centre y [m].
        size_x: Extent along the box's own x [m].
        size_y: Extent along the box's own y [m].
        yaw: Heading of the box's x axis [rad].
        height: [m] (for display).
    """

    x: float
    y: float
    size_x: float
    size_y: float
    yaw: float = 0.0
    height: float = 0.4

    def __post_init__(self) -> None:
        """Reject non-positive sizes."""
        if not (self.size_x > 0 and self.size_y > 0):
            raise GainError(f"BoxObstacle size: expected > 0 m, got {self.size_x, self.size_y}")

    def _to_box(self, vectors: np.ndarray) -> np.ndarray:
        """Rotate floor vectors into the box frame."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return vectors @ np.array([[c, -s], [s, c]])

    def ray_distances(self, origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Slab method in the box frame."""
        o = self._to_box(origin - np.array([self.x, self.y]))
        d = self._to_box(directions)
        half = np.array([self.size_x, self.size_y]) / 2
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (-half - o) / d
            t2 = (half - o) / d
        t1 = np.where(np.isnan(t1), -np.inf, t1)
        t2 = np.where(np.isnan(t2), np.inf, t2)
        enter = np.max(np.minimum(t1, t2), axis=1)
        leave = np.min(np.maximum(t1, t2), axis=1)
        hit = (leave >= np.maximum(enter, 0.0)) & np.all((d != 0) | (np.abs(o) <= half), axis=1)
        return np.where(hit, np.maximum(enter, 0.0), np.inf)

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """Exact signed distance to the rectangle."""
        local = np.abs(self._to_box(points - [self.x, self.y])) - [self.size_x / 2, self.size_y / 2]
        outside = np.linalg.norm(np.maximum(local, 0.0), axis=1)
        inside = np.minimum(np.max(local, axis=1), 0.0)
        return outside + inside


@dataclass(frozen=True)
class Laser:
    """A planar laser rangefinder.

    A scan's range ``d_i`` to the first hit becomes ``round((d_i + sigma n_i) / delta) delta``
    with ``n_i`` standard normal (:meth:`scan` with a generator), clipped at 0; a range beyond
    ``max_range`` (before the noise) is no return (``inf``).

    Attributes:
        field_of_view: Angular span, centred on the forward axis [rad].
        beams: Number of rays.
        max_range: Longest range reported [m].
        range_noise: Standard deviation ``sigma`` of the range noise [m].
        range_resolution: Resolution ``delta`` of the reported ranges [m] (0: exact).
    """

    field_of_view: float = np.pi
    beams: int = 181
    max_range: float = 8.0
    range_noise: float = 0.0
    range_resolution: float = 0.0

    def __post_init__(self) -> None:
        """Reject a negative noise or resolution."""
        if not (self.range_noise >= 0 and self.range_resolution >= 0):
            raise GainError(
                f"Laser range noise/resolution: expected >= 0 m, got {self.range_noise}, "
                f"{self.range_resolution}"
            )

    def angles(self) -> np.ndarray:
        """Beam angles, counter-clockwise from forward [rad]. Shape (beams,)."""
        half = self.field_of_view / 2
        return np.linspace(-half, half, self.beams)

    def scan(
        self,
        obstacles: list[Obstacle],
        x: float,
        y: float,
        yaw: float,
        rng: np.random.Generator | None = None,
    ) -> np.ndarray:
        """Ranges [m] from a laser at ``(x, y)`` facing ``yaw``; ``inf`` beyond range.

        Args:
            obstacles: What the rays may hit.
            x: Laser x in the world [m].
            y: Laser y in the world [m].
            yaw: Laser heading [rad].
            rng: Generator of the range noise; None: exact ranges (no noise, no rounding).

        Returns:
            Shape (beams,) [m].
        """
        angles = self.angles() + yaw
        directions = np.stack([np.cos(angles), np.sin(angles)], axis=1)
        origin = np.array([x, y])
        ranges = np.full(self.beams, np.inf)
        for obstacle in obstacles:
            ranges = np.minimum(ranges, obstacle.ray_distances(origin, directions))
        hit = ranges <= self.max_range
        if rng is not None:
            ranges = ranges + self.range_noise * rng.standard_normal(self.beams)
            if self.range_resolution > 0:
                ranges = np.round(ranges / self.range_resolution) * self.range_resolution
            ranges = np.maximum(ranges, 0.0)
        return np.where(hit, ranges, np.inf)

    def nearest(self, ranges: np.ndarray) -> tuple[float, float]:
        """``(d, alpha)``: shortest range and its angle, clockwise-positive [m, rad]."""
        index = int(np.argmin(ranges))
        return float(ranges[index]), float(-self.angles()[index])


def footprint_points(length: float, width: float, per_side: int = 12) -> np.ndarray:
    """Points on the boundary of a rectangular platform footprint, in its own frame.

    Returns:
        Shape (4 * per_side, 2) [m].
    """
    s = np.linspace(-0.5, 0.5, per_side, endpoint=False)
    edges = [
        np.stack([s * length, np.full_like(s, width / 2)], axis=1),
        np.stack([np.full_like(s, length / 2), -s * width], axis=1),
        np.stack([-s * length, np.full_like(s, -width / 2)], axis=1),
        np.stack([np.full_like(s, -length / 2), s * width], axis=1),
    ]
    return np.vstack(edges)


def clearance(
    obstacles: list[Obstacle], footprint: np.ndarray, x: float, y: float, yaw: float
) -> float:
    """Smallest distance [m] between a placed footprint boundary and any obstacle (<0: contact).

    Args:
        obstacles: The obstacles.
        footprint: Boundary points in the platform frame. Shape (k, 2).
        x: Platform x [m].
        y: Platform y [m].
        yaw: Platform heading [rad].
    """
    if not obstacles:
        return float("inf")
    c, s = np.cos(yaw), np.sin(yaw)
    world = footprint @ np.array([[c, s], [-s, c]]) + [x, y]
    return float(min(np.min(obstacle.signed_distance(world)) for obstacle in obstacles))
