r"""A computed home posture: the camera looks horizontally forward, image upright.

For any robot, :func:`compute_home` finds arm joint positions ``theta_h`` in which, with the
platform at the origin,

* the optical frame (z forward, x right, y down) has the orientation
  :math:`R_d = [-y_p, -z_p, x_p]` (columns x, y, z of the camera in the platform frame): the
  optical axis along the platform's x axis, horizontal, and no roll, so the image is upright;
* the camera is at a height in ``[min_height, max_height]`` above the floor, at least
  ``min_ahead`` in front of the platform origin and within ``max_lateral`` of its centreline;
* every joint with limits keeps ``limit_margin`` of its range from each limit;
* among such postures, the arm's manipulability
  (:func:`pbvs_pin.model.manipulability.arm_manipulability`) is as large as possible.

It solves two problems with SciPy, from several seeded starts, with Pinocchio's frame placement
and frame Jacobian (never re-derived):

1. bounded nonlinear least squares (``least_squares``, trust-region reflective) of the
   orientation error and the placement-band violations,

   .. math:: r(\theta) = \left[\log_3\!\left(R_d^\top R(\theta)\right),\;
             w\,[h_{min} - z]_+,\; w\,[z - h_{max}]_+,\; w\,[x_{min} - x]_+,\;
             w\,[x - x_{max}]_+,\; w\,[|y| - y_{max}]_+\right],
             \quad w = 0.01\ \mathrm{rad/m},

   (``dogbox``), with the analytic Jacobian :math:`J_{log_3}\,J_\omega^{LOCAL}` of the
   orientation rows; the small ``w`` puts the orientation first;
2. from the best solutions of 1, ``minimize(method="SLSQP")`` of

   .. math:: -\log m(\theta) + c \sum_i \left(\frac{\theta_i - \bar\theta_i}
             {\theta_i^{max} - \theta_i^{min}}\right)^2

   (m the manipulability, :math:`\bar\theta` the middle of the bounds, c =
   ``posture_weight``, which picks, among equally well-conditioned postures, the one nearest
   the middle of the joint ranges) subject to inequalities that keep the orientation error and
   the band violation within 1e-5 of the best step 1 reached (zero for an arm that reaches
   exactly).

An arm that cannot reach ``R_d`` with its camera in the band (too few joints, too short)
gets the best feasible posture of step 1; :func:`assess_home` reports its residuals. If even
the optical axis cannot be brought within ``max_forward_error`` of the platform's x axis,
:class:`~pbvs_pin.exceptions.HomeNotFound` is raised.

A platform that stands on wheels must not tip over at home (the MuJoCo plant's robot can;
the Pinocchio plant's planar base cannot). If the posture found puts the whole robot's centre
of mass (Pinocchio's, ``pin.centerOfMass``) outside the platform's support polygon (the convex
hull of its floor contacts on the MuJoCo plant,
:func:`pbvs_pin.plant.mujoco_support.support_polygon`), steps 1 and 2 run again with the rows
:math:`s_i = n_i^\top (c_{xy} - v_i) - \text{com\_margin} \ge 0` (``n_i`` the inward
normals of the polygon's edges through its vertices ``v_i``): a residual
:math:`[-s_i]_+` (weight 1 rad/m) in step 1, an inequality in step 2. A posture that does not
tip is returned as found.

Likewise a joint must hold the home against gravity: the simulated servos clip each torque to
the URDF's effort limit (:mod:`pbvs_pin.model.servo`). If the posture found loads an arm joint past
its limit (a PR2's shoulder, whose spring counterbalance the URDF does not model), steps 1 and
2 run again with the rows :math:`h_i = 1 - \text{effort\_margin} - |g_i(\theta)| /
\tau_i^{max} \ge 0` (:func:`pbvs_pin.bringup.holding.holding_rows`; ``g`` Pinocchio's gravity
torque), kept like the support rows. A posture that holds is returned as found.

The result is deterministic and depends on the model only: the starts are the zero posture
(clipped to the bounds), the middle of the bounds, and ``starts`` postures drawn with
``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from scipy.optimize import least_squares, minimize

from pbvs_pin.bringup.home_conditions import Condition, conditions
from pbvs_pin.exceptions import GainError, HomeNotFound
from pbvs_pin.model.joint_angles import arm_difference
from pbvs_pin.model.manipulability import arm_manipulability
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.model.support import COM_MARGIN
from pbvs_pin.validation import as_count, as_instance, as_rows, convert_fields

CAMERA_FORWARD = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
"""``R_d``: optical frame in the platform frame when looking forward, image upright."""

_BAND_WEIGHT = 0.01
"""``w`` [rad/m]: a band violation of 1 cm costs as much as an orientation error of 1e-4 rad."""

_ANGLE_SLACK = 1e-3
"""Orientation error [rad] step 2 may add to step 1's before step 1 polishes it away."""

_MAX_EVALUATIONS = 100
"""Evaluation cap of step 1 per start (converging starts need fewer than 30)."""

_MAX_ITERATIONS = 60
"""Iteration cap of step 2 (a start that has not converged by then is rarely the best)."""

LOCKED_WIDTH = 1e-9
"""Width [rad or m] of the search interval of a locked joint (lower = upper limit), which
``least_squares`` needs open; the result holds the joint exactly at its value."""

_KEEP = 1e-5
"""How much [rad or m] step 2 may lose on step 1's orientation error and band violation."""

_KEPT_WEIGHT = 1.0
"""Weight of a kept row's shortfall in step 1: 1 rad per m of the centre of mass's
(:class:`~pbvs_pin.bringup.home_conditions.Balance`) and 1 rad per effort limit of a joint's load
(:class:`~pbvs_pin.bringup.home_conditions.Holding`), as much as
the orientation, since a home that tips the platform or sags is no home."""


@dataclass(frozen=True)
class HomeCriteria:
    """What a home posture must satisfy.

    Attributes:
        min_height: Lowest camera height above the floor (the platform frame's z = 0) [m].
        max_height: Highest camera height [m].
        min_ahead: Least distance of the camera in front of the platform origin [m].
        max_ahead: Largest distance of the camera in front of the platform origin [m]; with
            ``max_height`` it keeps the arm from stretching far out.
        max_lateral: Largest distance of the camera from the platform's centreline [m].
        limit_margin: Fraction of each joint's range kept from both of its limits. A joint
            without limits (continuous) is searched without bounds, from starts in
            ``[-pi, pi]``, and its home is given in ``[-pi, pi)``.
        posture_weight: Weight ``c`` of the distance from the middle of the joint ranges in
            step 2's cost, against ``-log`` of the manipulability.
        max_forward_error: Largest angle [rad] between the optical axis and the platform's x
            axis before :func:`compute_home` gives up (10 deg).
        com_margin: Least distance [m] the centre of mass keeps inside the platform's support
            polygon when the home found without it would tip the platform (a home that does
            not tip is kept as found); None: tipping is not considered.
        effort_margin: Share of each arm joint's effort limit its gravity load keeps spare
            when the home found without it loads a joint past its limit (a home every joint
            holds is kept as found); None: the loads are not considered.
    """

    min_height: float = 0.5
    max_height: float = 1.0
    min_ahead: float = 0.3
    max_ahead: float = 0.7
    max_lateral: float = 0.01
    limit_margin: float = 0.1
    posture_weight: float = 0.2
    max_forward_error: float = np.radians(10.0)
    com_margin: float | None = COM_MARGIN
    effort_margin: float | None = 0.2

    def __post_init__(self) -> None:
        """Reject an empty band, a non-positive tolerance, a margin outside [0, 0.5) or < 0."""
        given = (field.name for field in fields(self))
        convert_fields(self, tuple(name for name in given if getattr(self, name) is not None))
        if self.com_margin is not None:
            if not (np.isfinite(self.com_margin) and self.com_margin >= 0.0):
                raise GainError(
                    f"HomeCriteria.com_margin: expected >= 0 m or None, got {self.com_margin}",
                    "com_margin",
                )
        if self.effort_margin is not None and not 0.0 <= self.effort_margin < 1.0:
            raise GainError(
                f"HomeCriteria.effort_margin: expected in [0, 1) or None, got "
                f"{self.effort_margin}",
                "effort_margin",
            )
        for low, high in (("min_height", "max_height"), ("min_ahead", "max_ahead")):
            if not getattr(self, high) > getattr(self, low):
                raise GainError(
                    f"HomeCriteria: expected {high} > {low}, got {getattr(self, high)} <= "
                    f"{getattr(self, low)}",
                    high,
                )
        for name in ("max_lateral", "max_forward_error"):
            if not getattr(self, name) > 0.0:
                raise GainError(
                    f"HomeCriteria.{name}: expected > 0, got {getattr(self, name)}", name
                )
        if not 0.0 <= self.limit_margin < 0.5:
            raise GainError(
                f"HomeCriteria.limit_margin: expected in [0, 0.5), got {self.limit_margin}",
                "limit_margin",
            )


@dataclass(frozen=True)
class HomeAssessment:
    """How well an arm posture meets :class:`HomeCriteria`.

    Attributes:
        forward_error: Angle between the optical axis and the platform's x axis [rad].
        roll: Rotation of the image about the optical axis away from upright [rad]; positive
            when the camera's x axis turns from ``-y_p`` towards ``-z_p``.
        orientation_error: ``|log3(R_d^T R)|``, the whole rotation away from ``R_d`` [rad].
        position: Camera position in the platform frame [m]. Shape (3,).
        limit_margin: Smallest distance to a joint limit as a fraction of that joint's range
            (``inf`` when no joint has limits).
        manipulability: :func:`pbvs_pin.model.manipulability.arm_manipulability` at the posture.
    """

    forward_error: float
    roll: float
    orientation_error: float
    position: np.ndarray
    limit_margin: float
    manipulability: float

    def band_violation(self, criteria: HomeCriteria) -> float:
        """Largest distance [m] by which the camera is outside the placement band (0 inside)."""
        x, y, z = self.position
        return max(
            0.0,
            criteria.min_height - z,
            z - criteria.max_height,
            criteria.min_ahead - x,
            x - criteria.max_ahead,
            abs(y) - criteria.max_lateral,
        )


def _limits(robot: MobileManipulator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Arm joint limits and which joints have them (continuous joints: ``[-pi, pi]``).

    A continuous joint's ``[-pi, pi]`` is the box of the starting postures and of the posture
    weight, not a bound.
    """
    lower, upper = robot.arm_position_limits()
    limited = np.isfinite(lower) & np.isfinite(upper)
    return np.where(limited, lower, -np.pi), np.where(limited, upper, np.pi), limited


def assess_home(robot: MobileManipulator, arm: npt.ArrayLike) -> HomeAssessment:
    """Measure an arm posture against the home criteria, platform at the origin.

    Args:
        robot: The robot.
        arm: Arm joint positions [rad or m]. Shape (n_arm,).

    Returns:
        The assessment.
    """
    robot = as_instance("robot", robot, MobileManipulator)
    arm = np.asarray(arm, dtype=float)
    q = robot.with_arm_positions(robot.neutral(), arm)
    pose = robot.camera_pose(q)
    rotation = pose.rotation
    lower, upper, limited = _limits(robot)
    ranged = limited & (upper > lower)  # a locked joint (lower = upper) has no fraction
    fractions = np.minimum(arm - lower, upper - arm)[ranged] / (upper - lower)[ranged]
    return HomeAssessment(
        forward_error=float(np.arccos(np.clip(rotation[0, 2], -1.0, 1.0))),
        roll=float(np.arctan2(-rotation[2, 0], -rotation[1, 0])),
        orientation_error=float(np.linalg.norm(pin.log3(CAMERA_FORWARD.T @ rotation))),
        position=np.array(pose.translation),
        limit_margin=float(fractions.min()) if fractions.size else float("inf"),
        manipulability=arm_manipulability(robot, q),
    )


class _Kinematics:
    """Camera pose and arm Jacobian at an arm posture, platform at the origin (cached).

    Attributes:
        kept: The rows both steps keep non-negative (:mod:`pbvs_pin.bringup.home_conditions`).
    """

    def __init__(self, robot: MobileManipulator) -> None:
        self.robot = robot
        self.base_q = robot.neutral()
        self._arm: np.ndarray | None = None
        self.kept: list[Condition] = []

    def shortfall(self, arm: np.ndarray) -> float:
        """The largest ``shortfall`` of the kept rows at ``arm`` (0 without any)."""
        q = self.robot.with_arm_positions(self.base_q, arm)
        return max((rows.shortfall(q) for rows in self.kept), default=0.0)

    def kept_rows(self, arm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The kept rows at ``arm`` and their Jacobian; shapes (k,) and (k, n_arm)."""
        q = self.robot.with_arm_positions(self.base_q, arm)
        parts = [rows.slack(q) for rows in self.kept]
        return (
            np.concatenate([np.zeros(0), *(value for value, _ in parts)]),
            np.vstack([np.zeros((0, len(arm))), *(slope for _, slope in parts)]),
        )

    def at(self, arm: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Rotation (3, 3), position (3,), ``dp/dtheta`` (3, n_arm), ``J_w`` LOCAL (3, n_arm)."""
        if self._arm is None or not np.array_equal(arm, self._arm):
            robot = self.robot
            q = robot.with_arm_positions(self.base_q, arm)
            jacobian = robot.camera_jacobian_unchecked(q)[:, robot.n_base :]
            pose = robot.data.oMf[robot.camera_frame_id]
            rotation = np.array(pose.rotation)
            self._arm = np.array(arm)
            self._value = (
                rotation,
                np.array(pose.translation),
                rotation @ jacobian[:3],
                jacobian[3:],
            )
        return self._value


def _band(criteria: HomeCriteria, slack: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Placement band as rows ``g(p) = A p + b - [0, 0, 0, 0, |y|] >= 0``.

    Rows: above ``min_height``, below ``max_height``, beyond ``min_ahead``, within
    ``max_ahead``, within ``max_lateral`` of the centreline; each relaxed by ``slack`` [m].

    Returns:
        ``A`` shape (5, 3), ``b`` shape (5,), and the lateral row's mask, shape (5,).
    """
    a = np.array([[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0], [-1.0, 0, 0], [0, 0, 0]])
    b = np.array(
        [
            -criteria.min_height,
            criteria.max_height,
            -criteria.min_ahead,
            criteria.max_ahead,
            criteria.max_lateral,
        ]
    )
    return a, b + slack, np.array([False, False, False, False, True])


def _stage_one(
    kinematics: _Kinematics, criteria: HomeCriteria, start: np.ndarray, bounds: tuple
) -> np.ndarray:
    """Least squares of orientation error and band violation from one start (step 1)."""
    a, b, lateral = _band(criteria, 0.0)

    def parts(arm: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        rotation, position, jp, jw = kinematics.at(arm)
        error = CAMERA_FORWARD.T @ rotation
        sign = np.where(lateral, np.sign(position[1]), 1.0)
        slack = a @ position + b - np.where(lateral, np.abs(position[1]), 0.0)
        d_slack = a @ jp - np.where(lateral[:, None], sign[:, None] * jp[1], 0.0)
        return error, slack, d_slack, jw

    def residual(arm: np.ndarray) -> np.ndarray:
        error, slack, _, _ = parts(arm)
        kept = kinematics.kept_rows(arm)[0]
        return np.concatenate(
            [
                pin.log3(error),
                _BAND_WEIGHT * np.maximum(0.0, -slack),
                _KEPT_WEIGHT * np.maximum(0.0, -kept),
            ]
        )

    def jacobian(arm: np.ndarray) -> np.ndarray:
        error, slack, d_slack, jw = parts(arm)
        d_band = np.where((slack < 0.0)[:, None], -_BAND_WEIGHT * d_slack, 0.0)
        kept, d_kept = kinematics.kept_rows(arm)
        d_kept = np.where((kept < 0.0)[:, None], -_KEPT_WEIGHT * d_kept, 0.0)
        return np.vstack([pin.Jlog3(error) @ jw, d_band, d_kept])

    return least_squares(
        residual, start, jac=jacobian, bounds=bounds, method="dogbox", max_nfev=_MAX_EVALUATIONS
    ).x


def _stage_two(
    kinematics: _Kinematics,
    criteria: HomeCriteria,
    start: np.ndarray,
    bounds: tuple[np.ndarray, np.ndarray],
    box: tuple[np.ndarray, np.ndarray],
    reached: HomeAssessment,
    shortfall: float = 0.0,
) -> tuple[np.ndarray, float]:
    """Step 2 from a step-1 posture: best-conditioned posture keeping what step 1 reached.

    Args:
        kinematics: The robot's cached kinematics.
        criteria: The criteria.
        start: A step-1 posture. Shape (n_arm,).
        bounds: Lower and upper bounds of the arm joints (infinite for a continuous joint).
            Shapes (n_arm,).
        box: ``bounds`` with ``[-pi, pi]`` for a continuous joint: its middle and span
            scale the posture weight. Shapes (n_arm,).
        reached: Assessment of the best step-1 posture: its orientation error and band
            violation (plus ``_KEEP``) bound those of the result.
        shortfall: The best step-1 posture's shortfall from the kept rows
            (:meth:`_Kinematics.shortfall`; plus ``_KEEP``, it bounds the result's).

    Returns:
        The posture, shape (n_arm,), and its cost; cost ``inf`` if it breaks the constraints.
    """
    robot = kinematics.robot
    a, b, lateral = _band(criteria, reached.band_violation(criteria) + _KEEP)
    angle_limit = reached.orientation_error + _ANGLE_SLACK
    middle, span = 0.5 * (box[0] + box[1]), box[1] - box[0]
    span = np.where(span > 0.0, span, 1.0)  # a locked joint sits at its middle: no weight

    def orientation(arm: np.ndarray) -> np.ndarray:
        error = pin.log3(CAMERA_FORWARD.T @ kinematics.at(arm)[0])
        return np.array([angle_limit**2 - error @ error])

    def orientation_jacobian(arm: np.ndarray) -> np.ndarray:
        rotation, _, _, jw = kinematics.at(arm)
        matrix = CAMERA_FORWARD.T @ rotation
        return -2.0 * pin.log3(matrix) @ pin.Jlog3(matrix) @ jw[None]

    def band(arm: np.ndarray) -> np.ndarray:
        position = kinematics.at(arm)[1]
        return a @ position + b - np.where(lateral, np.abs(position[1]), 0.0)

    def band_jacobian(arm: np.ndarray) -> np.ndarray:
        _, position, jp, _ = kinematics.at(arm)
        return a @ jp - np.where(lateral[:, None], np.sign(position[1]) * jp[1], 0.0)

    def cost(arm: np.ndarray) -> float:
        q = robot.with_arm_positions(kinematics.base_q, arm)
        posture = criteria.posture_weight * np.sum(((arm - middle) / span) ** 2)
        return posture - np.log(arm_manipulability(robot, q) + 1e-12)

    constraints = [
        {"type": "ineq", "fun": orientation, "jac": orientation_jacobian},
        {"type": "ineq", "fun": band, "jac": band_jacobian},
    ]
    if kinematics.kept:
        constraints.append(
            {
                "type": "ineq",
                "fun": lambda arm: kinematics.kept_rows(arm)[0] + shortfall + _KEEP,
                "jac": lambda arm: kinematics.kept_rows(arm)[1],
            }
        )
    result = minimize(
        cost,
        start,
        method="SLSQP",
        bounds=list(zip(*bounds, strict=True)),
        constraints=constraints,
        options={"maxiter": _MAX_ITERATIONS, "ftol": 1e-10},
    )
    arm = _stage_one(kinematics, criteria, np.clip(result.x, *bounds), bounds)
    found = assess_home(robot, arm)
    kept = (
        found.orientation_error <= reached.orientation_error + _KEEP
        and found.band_violation(criteria) <= reached.band_violation(criteria) + _KEEP
        and kinematics.shortfall(arm) <= shortfall + _KEEP
    )
    return arm, (cost(arm) if kept else np.inf)


def compute_home(
    robot: MobileManipulator,
    criteria: HomeCriteria | None = None,
    starts: int = 8,
    refine: int = 3,
    seed: int = 0,
    support: npt.ArrayLike | None = None,
) -> np.ndarray:
    """Arm posture in which the camera looks horizontally forward, image upright.

    See the module docstring for the criteria and the two optimisation steps.

    Args:
        robot: The robot (its ``home_arm`` is not used: the result depends on the model only).
        criteria: Placement band, joint-limit margin and weights; defaults otherwise.
        starts: Number of seeded random starting postures besides the zero posture (clipped
            to the bounds) and the middle of the bounds.
        refine: Number of the best step-1 postures from which step 2 starts.
        seed: Seed of the random starting postures.
        support: Points [m] in the platform frame whose convex hull is the platform's
            support, shape (m, 2); None: the MuJoCo plant's floor contacts
            (:func:`pbvs_pin.plant.mujoco_support.support_polygon`). A hull of fewer than three
            vertices, or ``criteria.com_margin`` None: tipping is not considered. If the
            camera cannot look forward with the centre of mass kept inside, the home found
            without it is returned (the MuJoCo plant warns that it tips). Likewise, with
            ``criteria.effort_margin``, for a joint whose gravity load passes its effort
            limit (the robot's loader warns).

    Returns:
        ``theta_h`` [rad or m], at least ``limit_margin`` of its range from each limit; a
        continuous joint's in ``[-pi, pi)``. Shape (n_arm,).

    Raises:
        HomeNotFound: If no posture brings the optical axis within
            ``criteria.max_forward_error`` of the platform's x axis.
    """
    robot = as_instance("robot", robot, MobileManipulator)
    criteria = criteria or HomeCriteria()
    starts, seed = as_count("starts", starts), as_count("seed", seed)
    refine = as_count("refine", refine, minimum=1)
    support = None if support is None else as_rows("support", support, 2)
    lower, upper, limited = _limits(robot)
    margin = np.where(limited, criteria.limit_margin * (upper - lower), 0.0)
    box = (lower + margin, upper - margin)
    # a continuous joint is unbounded: a bound at +-pi would stop the search at the wrap
    bounds = (np.where(limited, box[0], -np.inf), np.where(limited, box[1], np.inf))
    # a locked joint (lower = upper) is held within LOCKED_WIDTH of its value, and set to it
    # at the end: least_squares needs lower < upper
    locked = limited & (upper <= lower)
    bounds = (bounds[0] - np.where(locked, LOCKED_WIDTH, 0.0), bounds[1])
    kinematics = _Kinematics(robot)
    rng = np.random.default_rng(seed)
    guesses = [np.clip(np.zeros(robot.n_arm), *box), 0.5 * (box[0] + box[1])]
    guesses += [rng.uniform(*box) for _ in range(starts)]
    solve = (kinematics, criteria, guesses, (bounds, box), refine)
    arm = _solve(*solve)
    # (test at zero margin, row kept with the criteria's margin) for tipping and sagging
    checks = conditions(robot, criteria.com_margin, criteria.effort_margin, support)
    for _ in checks:  # a row added can make a home break another: each is added once
        q = robot.with_arm_positions(kinematics.base_q, arm)
        added = [kept for test, kept in checks if kept not in kinematics.kept and test(q) > 0.0]
        if not added:  # it neither tips nor sags: kept as found
            break
        kinematics.kept += added
        try:
            arm = _solve(*solve)
        except HomeNotFound:  # kept, the camera cannot look forward: the plants will warn
            break
    return _finish(robot, arm, locked, lower)


def _finish(
    robot: MobileManipulator, arm: np.ndarray, locked: np.ndarray, lower: np.ndarray
) -> np.ndarray:
    """A solved posture with its locked joints at their value, continuous ones in [-pi, pi)."""
    arm = np.where(locked, lower, arm)
    return arm_difference(arm, np.zeros(robot.n_arm), robot.arm_continuous)


def _solve(
    kinematics: _Kinematics,
    criteria: HomeCriteria,
    guesses: list[np.ndarray],
    limits: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    refine: int,
) -> np.ndarray:
    """Steps 1 and 2 from every guess: the best posture (see :func:`compute_home`).

    ``limits`` is ``(bounds, box)`` as :func:`_stage_two` takes them.
    """
    robot = kinematics.robot
    bounds, box = limits
    candidates = [_stage_one(kinematics, criteria, g, bounds) for g in guesses]
    assessed = [assess_home(robot, arm) for arm in candidates]
    shortfalls = [kinematics.shortfall(arm) for arm in candidates]
    ranks = sorted(
        range(len(candidates)),
        key=lambda i: (
            assessed[i].orientation_error
            + _BAND_WEIGHT * assessed[i].band_violation(criteria)
            + _KEPT_WEIGHT * shortfalls[i]
        ),
    )
    best, least = assessed[ranks[0]], shortfalls[ranks[0]]
    if best.forward_error > criteria.max_forward_error:
        raise HomeNotFound(robot.source, np.degrees(best.forward_error), criteria)
    feasible = [
        i
        for i in ranks
        if assessed[i].orientation_error <= best.orientation_error + _KEEP
        and assessed[i].band_violation(criteria) <= best.band_violation(criteria) + _KEEP
        and shortfalls[i] <= least + _KEEP
    ]
    refined = [
        _stage_two(kinematics, criteria, candidates[i], bounds, box, best, least)
        for i in feasible[:refine]
    ]
    arm, value = min(refined, key=lambda pair: pair[1])
    return np.asarray(arm if np.isfinite(value) else candidates[ranks[0]], dtype=float)
