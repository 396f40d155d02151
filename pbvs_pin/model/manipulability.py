"""Manipulability of the arm and of the whole robot, and the posture that maximises it.

Manipulability (Yoshikawa) is the product of a Jacobian's singular values,
``sqrt(det(J J^T))`` for a wide Jacobian and ``sqrt(det(J^T J))`` for a tall one. For the arm
it uses the camera frame's Jacobian restricted to the arm's columns, in ``LOCAL_WORLD_ALIGNED``:
only its translational rows for an arm of three joints or fewer (the paper's robot), all six
rows otherwise.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from scipy.optimize import minimize

from pbvs_pin.exceptions import WrongType
from pbvs_pin.model.joint_angles import arm_difference
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.validation import as_count, as_instance, as_numbers

LIMIT_MARGIN = 0.05
"""Distance [rad or m] the maximising posture keeps from each joint limit."""

TIE_TOLERANCE = 1e-4
"""Relative manipulability difference below which two postures count as equally good."""


def manipulability(jacobian: npt.ArrayLike) -> float | np.ndarray:
    """Product of the singular values of a Jacobian; 0 when singular.

    Args:
        jacobian: Shape (r, n), or a stack of them, shape (..., r, n).

    Returns:
        A float for one Jacobian, else an array of shape (...).
    """
    jacobian = as_numbers("jacobian", jacobian)
    if jacobian.ndim < 2:
        raise WrongType("jacobian", "a matrix, shape (r, n), or a stack of them", jacobian)
    values = np.prod(np.linalg.svd(jacobian, compute_uv=False), axis=-1)
    return float(values) if jacobian.ndim == 2 else values


def arm_jacobian(robot: MobileManipulator, q: npt.ArrayLike) -> np.ndarray:
    """Camera frame Jacobian of the arm joints, ``LOCAL_WORLD_ALIGNED``.

    Returns:
        Shape (3, n_arm) for an arm of three joints or fewer, else (6, n_arm).
    """
    robot = as_instance("robot", robot, MobileManipulator)
    jacobian = pin.computeFrameJacobian(
        robot.model,
        robot.data,
        robot.check_configuration(q),
        robot.camera_frame_id,
        pin.LOCAL_WORLD_ALIGNED,
    )
    arm = (jacobian @ robot.selection)[:, robot.n_base :]
    return arm[:3] if robot.n_arm <= 3 else arm


def arm_manipulability(robot: MobileManipulator, q: npt.ArrayLike) -> float:
    """Manipulability of the arm alone at ``q``."""
    return manipulability(arm_jacobian(robot, q))


def whole_body_manipulability(robot: MobileManipulator, q: npt.ArrayLike) -> float:
    """Manipulability of the camera's twist over all actuated velocities at ``q``."""
    robot = as_instance("robot", robot, MobileManipulator)
    return manipulability(robot.camera_jacobian(q))


def max_manipulability_posture(
    robot: MobileManipulator, starts: int = 8, seed: int = 0
) -> np.ndarray:
    """Arm posture ``theta_d`` that maximises :func:`arm_manipulability` (paper §3.3, [31]).

    Bounded quasi-Newton (L-BFGS-B) from the home posture and from ``starts`` seeded random
    postures within the joint limits (``[-pi, pi]`` for a continuous joint, which is not
    bounded), each kept ``LIMIT_MARGIN`` inside them; the best result wins. Among postures
    within ``TIE_TOLERANCE`` of the best (manipulability does not depend on a first yaw joint,
    for example) the one closest to home wins, a continuous joint's distance taken the
    shortest way round and its angle given in ``[-pi, pi)``. Manipulability does not depend
    on the base pose, so the base stays at the origin.

    Args:
        robot: The robot.
        starts: Number of random starting postures besides home.
        seed: Seed of the random starting postures.

    Returns:
        ``theta_d`` [rad or m]. Shape (n_arm,).
    """
    robot = as_instance("robot", robot, MobileManipulator)
    starts, seed = as_count("starts", starts), as_count("seed", seed)
    lower, upper = robot.arm_position_limits()
    limited = np.isfinite(lower) & np.isfinite(upper)
    lower = np.where(limited, lower, -np.pi) + LIMIT_MARGIN
    upper = np.where(limited, upper, np.pi) - LIMIT_MARGIN
    base_q = robot.neutral()
    continuous = robot.arm_continuous

    def cost(arm: np.ndarray) -> float:
        return -arm_manipulability(robot, robot.with_arm_positions(base_q, arm))

    rng = np.random.default_rng(seed)
    guesses = [np.where(limited, np.clip(robot.home_arm, lower, upper), robot.home_arm)]
    guesses += [rng.uniform(lower, upper) for _ in range(starts)]
    bounds = [(low, high) if bounded else (None, None)
              for low, high, bounded in zip(lower, upper, limited, strict=True)]  # fmt: skip
    results = [minimize(cost, guess, method="L-BFGS-B", bounds=bounds) for guess in guesses]
    best = min(result.fun for result in results)
    ties = [
        arm_difference(r.x, np.zeros_like(r.x), continuous)
        for r in results if r.fun <= best + TIE_TOLERANCE * abs(best)
    ]  # fmt: skip
    home = guesses[0]
    return min(ties, key=lambda arm: np.linalg.norm(arm_difference(arm, home, continuous)))
