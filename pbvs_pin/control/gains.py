"""The gains of the kinematic controller, eqs. (10) and (34), checked when they are built.

:class:`ServoGains` holds them with the paper's defaults (§5); :class:`pbvs_pin.control.
kinematic.PassivityController` fits them to a robot's velocities and features.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pbvs_pin.control.upright import LOOP_GAIN_MARGIN, RESTORING_RATE
from pbvs_pin.exceptions import GainError

FEEDBACK_LAWS = ("transpose", "pseudoinverse", "balanced")
"""The feedback laws' names (the ``controller.feedback`` key), in the order of their codes in
the compiled step (:data:`pbvs_pin.control.kinematic.TRANSPOSE`, ...)."""


def positive_vector(name: str, value: npt.ArrayLike) -> np.ndarray:
    """A 1-D array of finite positive entries, or a GainError naming ``name``."""
    array = np.atleast_1d(np.asarray(value, dtype=float))
    if array.ndim != 1 or not np.all(np.isfinite(array)) or np.any(array <= 0):
        raise GainError(
            f"{name}: expected positive finite values, got {value!r}", name.rpartition(".")[2]
        )
    return array


@dataclass(frozen=True)
class ServoGains:
    """Gains of eq. (10)/(34), defaults from the paper's experiments (§5).

    Attributes:
        k: ``k_i`` of ``K_c`` [1/s], one per feature or a scalar for all.
        k1: Diagonal of ``k_1``, null-space velocity amplitude [m/s or rad/s]; length n or 1.
        k2: Diagonal of ``k_2``, null-space slope [1 / unit of Lambda]; length n or 1.
        feature_scale: Pixels per controller unit of feature [px].
        weights: ``W``: its diagonal (length n or 1), or the full symmetric positive
            definite matrix (n rows of n).
        feedback: ``transpose`` (the paper's ``-J^T K_c e``), ``pseudoinverse``
            (``-J# K_c e``) or ``balanced`` (:func:`~pbvs_pin.control.balanced.balanced_feedback`).
        damping_threshold: Smallest singular value of ``J W^-1/2`` (controller units) below
            which the pseudo-inverse is damped.
        max_damping: Damping factor at a singular ``J``.
        upright: Keep the null-space term from rolling the image (:mod:`~pbvs_pin.control.upright`).
        upright_rate: ``k_phi``, decay rate of the upright angle in the null space [1/s].
        camera_period: Camera sample period ``T`` of the loop-gain net [s].
        loop_gain_margin: Largest gain per camera sample ``k T lambda_max(J J^T)``.
    """

    k: tuple[float, ...] = (0.15,)
    k1: tuple[float, ...] = (0.7, 1.0, 0.1, 0.1, 0.1)
    k2: tuple[float, ...] = (0.2,)
    feature_scale: float = 150.0
    weights: tuple = (1.0,)
    feedback: str = "balanced"
    damping_threshold: float = 0.05
    max_damping: float = 0.05
    upright: bool = True
    upright_rate: float = RESTORING_RATE
    camera_period: float = 1.0 / 30.0
    loop_gain_margin: float = LOOP_GAIN_MARGIN

    def __post_init__(self) -> None:
        """Validate every gain (GainError names the field)."""
        for name in ("k", "k1", "k2"):
            positive_vector(f"ServoGains.{name}", getattr(self, name))
        if self.feedback not in FEEDBACK_LAWS:
            raise GainError(
                f"ServoGains.feedback: expected one of {', '.join(FEEDBACK_LAWS)}, got "
                f"{self.feedback!r}",
                "feedback",
            )
        weights = np.asarray(self.weights, dtype=float)
        if weights.ndim == 2:
            symmetric = weights.shape[0] == weights.shape[1] and np.allclose(weights, weights.T)
            if not symmetric or np.any(np.linalg.eigvalsh(weights) <= 0):
                raise GainError(
                    f"ServoGains.weights: expected a symmetric positive definite matrix, got "
                    f"{weights.tolist()}",
                    "weights",
                )
        else:
            positive_vector("ServoGains.weights", weights)
        for name in (
            "feature_scale", "damping_threshold", "max_damping", "camera_period",
            "loop_gain_margin",
        ):  # fmt: skip
            positive_vector(f"ServoGains.{name}", getattr(self, name))
        if not np.isfinite(self.upright_rate) or self.upright_rate < 0:
            raise GainError(
                f"ServoGains.upright_rate: expected >= 0 [1/s], got {self.upright_rate!r}",
                "upright_rate",
            )

    @property
    def feedback_law(self) -> int:
        """The feedback law's code in the compiled step (``kinematic.TRANSPOSE``, ...)."""
        return FEEDBACK_LAWS.index(self.feedback)

    def weight_inverse(self, size: int) -> np.ndarray:
        """``W^-1``, shape (size, size).

        Raises:
            GainError: If ``W`` does not have ``size`` rows.
        """
        weights = np.asarray(self.weights, dtype=float)
        if weights.ndim == 2:
            if weights.shape != (size, size):
                raise GainError(
                    f"ServoGains.weights: expected a ({size}, {size}) matrix, got {weights.shape}",
                    "weights",
                )
            return np.linalg.inv(weights)
        return np.diag(1.0 / self.expand("weights", size))

    def expand(self, name: str, size: int) -> np.ndarray:
        """Gain ``name`` as a vector of ``size`` entries (a scalar is repeated).

        Raises:
            GainError: If the gain has neither 1 nor ``size`` entries.
        """
        values = np.asarray(getattr(self, name), dtype=float)
        if values.size == 1:
            return np.full(size, float(values[0]))
        if values.size != size:
            raise GainError(
                f"ServoGains.{name}: expected 1 or {size} values, got {values.size}", name
            )
        return values
