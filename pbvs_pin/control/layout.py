"""Named layout of the fused control step's three packed buffers (:mod:`pbvs_pin.control.step`).

Calling a compiled function from Python costs about 0.1 us per argument and 0.7 us per array
it returns, so the 1 kHz step takes its constants in one float array ``params`` and one integer
array ``indices``, and keeps its memory and outputs in one float array ``state``. This module is
the only place that knows where a quantity sits in them: its compiled functions cut the buffers
into named tuples of views and values, which the step reads by name, and
:class:`~pbvs_pin.control.step.FusedControlStep` fills the buffers through the same views.
Numba builds the named tuples in nopython mode, with no Python work per call; the compiled
functions are inlined into the step (``inline="always"``), so that cutting the buffers costs no
more than the positional slicing it replaced.

Units: ``[u]`` stands for the unit of each actuated velocity (m/s or rad/s), ``[q]`` for that
of an arm joint position (rad or m).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from pbvs_pin.linalg import cut


class Sizes(NamedTuple):
    """The sizes, first in ``indices``."""

    n: int
    """Actuated velocities."""
    r: int
    """Features."""
    nv: int
    """Pinocchio velocities."""
    n_arm: int
    """Arm joints."""
    n_support: int
    """Rows of the support objective (edges of the support polygon); 0: off."""


class Indices(NamedTuple):
    """The constant integers, after the :class:`Sizes` in ``indices``."""

    rows: np.ndarray
    """Indices into ``[u1, v1, u2, v2, ...]`` forming ``xi``. Shape (r,)."""
    arm_q_indices: np.ndarray
    """Index of each arm joint in ``q``. Shape (n_arm,)."""
    arm_continuous: np.ndarray
    """1 where the joint is stored as (cos, sin) in ``q``. Shape (n_arm,)."""


class Parameters(NamedTuple):
    """Views of the constant floats in ``params``, in this order."""

    xi_d: np.ndarray
    """Desired features [px]. Shape (r,)."""
    k: np.ndarray
    """``k_i`` of ``K_c``, eq. (10) [1/s]. Shape (r,)."""
    k1: np.ndarray
    """Diagonal of ``k_1``, null-space amplitude [u]. Shape (n,)."""
    k2: np.ndarray
    """Diagonal of ``k_2``, null-space slope [1 / unit of Lambda]. Shape (n,)."""
    velocity_limits: np.ndarray
    """Largest magnitude of each command and velocity reference [u]. Shape (n,)."""
    pseudo_inverse_damping: np.ndarray
    """``[sigma_0, mu_max]`` of the damped pseudo-inverse (controller units). Shape (2,)."""
    gain_per_mass: np.ndarray
    """``a`` of the servos' loop gain ``K_e,i = a_i sum_j |M_v,ij| + b_i``, eq. (1) [1/s].
    Shape (n,)."""
    gain_constant: np.ndarray
    """``b`` of that loop gain [N s/m or N m s/rad]. Shape (n,)."""
    gravity_weight: np.ndarray
    """Diagonal of ``I - G`` (0 where the servo cancels gravity) [1]. Shape (n,)."""
    compensated: np.ndarray
    """1 on the rows eq. (20) compensates, 0 on those that pass ``u`` through. Shape (n,)."""
    k_d: np.ndarray
    """Diagonal of ``K_D``, eq. (20) [1/s]. Shape (n,)."""
    weight_inverse: np.ndarray
    """``W^-1`` of the pseudo-inverse. Shape (n, n)."""
    posture_target: np.ndarray
    """``theta_d`` of eq. (19) [q]. Shape (n_arm,)."""
    lower: np.ndarray
    """Lower arm joint limits of the joint-limit objective [q]. Shape (n_arm,)."""
    upper: np.ndarray
    """Upper arm joint limits [q]. Shape (n_arm,)."""
    support_normals: np.ndarray
    """Inward unit normals of the support's edges (:class:`~pbvs_pin.model.support.SupportRows`).
    Shape (n_support, 2)."""
    support_offsets: np.ndarray
    """``n_i^T v_i + margin`` of each edge [m]. Shape (n_support,)."""
    support_barrier_offsets: np.ndarray
    """``n_i^T v_i + d_min,i`` [m] of the support's barrier. Shape (n_support,)."""
    support_target: np.ndarray
    """``theta_d`` of the support objective's turn at the edge [q]. Shape (n_arm,)."""
    selection: np.ndarray
    """``S``, actuated to Pinocchio velocities. Shape (nv, n)."""
    settings: np.ndarray
    """The scalar settings, read by :func:`settings`. Shape (len(Settings._fields),)."""


class Settings(NamedTuple):
    """The constant scalars, stored as floats in ``Parameters.settings``, in this order.

    The objective fields default to "off": the step adds only the objectives switched on.
    """

    focal: float
    """Focal length [px]."""
    feature_scale: float
    """Pixels per controller unit of feature [px]."""
    feedback_law: int
    """The feedback law (:data:`~pbvs_pin.control.kinematic.TRANSPOSE`, ...)."""
    derivative_time_constant: float
    """Low-pass time constant of the command derivative ``u_dot`` [s]."""
    n_base: int
    """Base velocities (the first entries of ``v``)."""
    posture: bool = False
    """The arm posture objective of eq. (19) is on."""
    posture_gain: float = 0.0
    """Its ``k_Lambda`` [1/s]."""
    joint_limits: bool = False
    """The joint-limit objective is on."""
    limit_margin: float = 0.0
    """Width of its active zone [q]."""
    limit_gain: float = 0.0
    """Its gain [1/s]."""
    obstacle: bool = False
    """The obstacle avoidance of eqs. (17)-(18) is on."""
    k_u: float = 0.0
    """``k_uobs`` [1/(rad s)]."""
    k_w: float = 0.0
    """``k_wobs`` [1/s]."""
    d0: float = 0.0
    """Distance at which avoidance starts [m]."""
    impedance_mass: float = 0.0
    """Impedance inertia ``m`` [s]."""
    impedance_damping: float = 0.0
    """Impedance damping ``b`` [1]."""
    upright: bool = False
    """Keep the null-space term from rolling the image (:mod:`pbvs_pin.control.upright`)."""
    upright_rate: float = 0.0
    """``k_phi``, decay rate of the upright angle in the null space [1/s]."""
    camera_period: float = 0.0
    """Camera sample period ``T`` of the loop-gain net [s]; 0 turns the net off."""
    loop_gain_margin: float = 1.0
    """Largest gain per camera sample ``k T lambda_max(J J^T)`` [1]."""
    heading_gain: float = 0.0
    """``k_psi`` of the base-heading objective [1/s] (:func:`~.secondary.heading_term`); 0: off."""
    heading_offset: float = 0.0
    """Its ``psi_d``, the camera's heading at ``theta_d`` [rad]."""
    support_gain: float = 0.0
    """``k_s`` of the support objective [1/s] (:mod:`~pbvs_pin.control.support`); 0: off."""
    support_turn_gain: float = 0.0
    """Its turn at the edge: ``k_psi`` [1/s]; 0: no turn."""
    support_turn_offset: float = 0.0
    """That turn's ``psi_d`` [rad]."""
    support_d0: float = 0.0
    """That turn's ``d_0`` [m]; 0: obstacle avoidance off."""


class State(NamedTuple):
    """Views of the memory and outputs in ``state``, in this order."""

    u_previous: np.ndarray
    """The previous step's command [u]. Shape (n,)."""
    u_dot: np.ndarray
    """Low-pass filtered command derivative [u/s]. Shape (n,)."""
    impedance_velocity: np.ndarray
    """``[u_obs, omega_obs, vy_obs]``, the obstacle impedance's output [m/s, rad/s, m/s].
    Shape (3,)."""
    u: np.ndarray
    """Command of eq. (34) [u]. Shape (n,)."""
    v_ref: np.ndarray
    """Velocity reference of eq. (20) [u]. Shape (n,)."""
    nu: np.ndarray
    """``J^T K_c e`` in controller units. Shape (n,)."""
    feedforward: np.ndarray
    """``J# J_o phat_dot`` [u]. Shape (n,)."""
    null_space: np.ndarray
    """``(I - J# J) k1 tanh(k2 Lambda)`` [u]. Shape (n,)."""
    xi: np.ndarray
    """Measured features [px]. Shape (r,)."""
    jacobian: np.ndarray
    """``J`` of eq. (3) [px per u]. Shape (r, n)."""
    object_jacobian: np.ndarray
    """``J_o`` of eq. (3) [px/m]. Shape (r, 3)."""
    scalars: np.ndarray
    """The scalar state, read by :func:`step_scalars`. Shape (len(StepScalars._fields),)."""


class StepScalars(NamedTuple):
    """The scalars in ``State.scalars``, in this order; flags are 1.0 (true) or 0.0."""

    has_previous: float
    """``u_previous`` holds a command, so the next step differentiates it."""
    valid: float
    """The inputs were finite (else ``u`` is zero)."""
    storage: float
    """``V1`` of eq. (7) in controller units [1/s]."""
    sigma_min: float
    """Smallest singular value of ``J W^-1/2`` (controller units)."""
    damped: float
    """The pseudo-inverse was damped."""
    factor: float
    """Factor the command was scaled by to respect the velocity limits (1: unsaturated)."""
    v2: float
    """``V2 = |v - u|^2 / 2`` of eq. (22) [u^2]."""
    loop_gain: float
    """Gain per camera sample ``k T lambda_max(J J^T)`` before the loop-gain net [1]."""
    gain_factor: float
    """Factor the net scaled the feature gains by (1: it did not act)."""
    sigma_phi: float
    """Roll the null space can produce per unit of velocity (controller units)."""
    upright_weight: float
    """``beta``, how much of the roll was removed from the null space [1]."""
    upright_angle: float
    """The image's upright angle ``phi`` [rad]."""
    seen: float
    """The step servoed on a measurement (else ``u`` is zero and the rest is NaN or neutral)."""


SIZES = len(Sizes._fields)
SETTINGS = len(Settings._fields)
STEP_SCALARS = len(StepScalars._fields)
V2_SLOT = StepScalars._fields.index("v2")
"""Position of ``v2`` in ``State.scalars`` (written once eq. (20) has run)."""


def pack_indices(
    sizes: Sizes, rows: np.ndarray, arm_q_indices: np.ndarray, arm_continuous: np.ndarray
) -> np.ndarray:
    """``indices``: the sizes, then the fields of :class:`Indices`. Shape (SIZES + r + 2 n_arm,)."""
    return np.concatenate([sizes, rows, arm_q_indices, arm_continuous]).astype(np.int64)


@njit(cache=True, inline="always")
def sizes(indices: np.ndarray) -> Sizes:
    """The :class:`Sizes` at the start of ``indices``."""
    return Sizes(n=indices[0], r=indices[1], nv=indices[2], n_arm=indices[3], n_support=indices[4])


@njit(cache=True, inline="always")
def index_views(indices: np.ndarray) -> Indices:
    """Views of the constant integers in ``indices``."""
    size = sizes(indices)
    rows, a = cut(indices, SIZES, size.r)
    arm_q_indices, a = cut(indices, a, size.n_arm)
    arm_continuous, a = cut(indices, a, size.n_arm)
    return Indices(rows=rows, arm_q_indices=arm_q_indices, arm_continuous=arm_continuous)


@njit(cache=True, inline="always")
def parameter_size(indices: np.ndarray) -> int:
    """Length of ``params``: the sum of the :class:`Parameters` fields' sizes."""
    n, r, nv, n_arm, n_support = sizes(indices)
    return 2 * r + 8 * n + 2 + n * n + 4 * n_arm + nv * n + 4 * n_support + SETTINGS


@njit(cache=True, inline="always")
def parameter_views(params: np.ndarray, indices: np.ndarray) -> Parameters:
    """Views of the constant floats in ``params`` (shape (parameter_size(indices),))."""
    n, r, nv, n_arm, n_support = sizes(indices)
    xi_d, a = cut(params, 0, r)
    k, a = cut(params, a, r)
    k1, a = cut(params, a, n)
    k2, a = cut(params, a, n)
    velocity_limits, a = cut(params, a, n)
    pseudo_inverse_damping, a = cut(params, a, 2)
    gain_per_mass, a = cut(params, a, n)
    gain_constant, a = cut(params, a, n)
    gravity_weight, a = cut(params, a, n)
    compensated, a = cut(params, a, n)
    k_d, a = cut(params, a, n)
    weight_inverse, a = cut(params, a, n * n)
    posture_target, a = cut(params, a, n_arm)
    lower, a = cut(params, a, n_arm)
    upper, a = cut(params, a, n_arm)
    support_normals, a = cut(params, a, 2 * n_support)
    support_offsets, a = cut(params, a, n_support)
    support_barrier_offsets, a = cut(params, a, n_support)
    support_target, a = cut(params, a, n_arm)
    selection, a = cut(params, a, nv * n)
    settings_block, a = cut(params, a, SETTINGS)
    return Parameters(
        xi_d=xi_d,
        k=k,
        k1=k1,
        k2=k2,
        velocity_limits=velocity_limits,
        pseudo_inverse_damping=pseudo_inverse_damping,
        gain_per_mass=gain_per_mass,
        gain_constant=gain_constant,
        gravity_weight=gravity_weight,
        compensated=compensated,
        k_d=k_d,
        weight_inverse=weight_inverse.reshape((n, n)),
        posture_target=posture_target,
        lower=lower,
        upper=upper,
        support_normals=support_normals.reshape((n_support, 2)),
        support_offsets=support_offsets,
        support_barrier_offsets=support_barrier_offsets,
        support_target=support_target,
        selection=selection.reshape((nv, n)),
        settings=settings_block,
    )


@njit(cache=True, inline="always")
def settings(block: np.ndarray) -> Settings:
    """The :class:`Settings` stored in ``block`` (``Parameters.settings``)."""
    return Settings(
        focal=block[0],
        feature_scale=block[1],
        feedback_law=int(block[2]),
        derivative_time_constant=block[3],
        n_base=int(block[4]),
        posture=block[5] > 0.0,
        posture_gain=block[6],
        joint_limits=block[7] > 0.0,
        limit_margin=block[8],
        limit_gain=block[9],
        obstacle=block[10] > 0.0,
        k_u=block[11],
        k_w=block[12],
        d0=block[13],
        impedance_mass=block[14],
        impedance_damping=block[15],
        upright=block[16] > 0.0,
        upright_rate=block[17],
        camera_period=block[18],
        loop_gain_margin=block[19],
        heading_gain=block[20],
        heading_offset=block[21],
        support_gain=block[22],
        support_turn_gain=block[23],
        support_turn_offset=block[24],
        support_d0=block[25],
    )


@njit(cache=True, inline="always")
def state_size(indices: np.ndarray) -> int:
    """Length of ``state``: the sum of the :class:`State` fields' sizes."""
    size = sizes(indices)
    n, r = size.n, size.r
    return 7 * n + 3 + r + r * n + 3 * r + STEP_SCALARS


@njit(cache=True, inline="always")
def state_views(state: np.ndarray, indices: np.ndarray) -> State:
    """Views of the memory and outputs in ``state`` (shape (state_size(indices),))."""
    size = sizes(indices)
    n, r = size.n, size.r
    u_previous, a = cut(state, 0, n)
    u_dot, a = cut(state, a, n)
    impedance_velocity, a = cut(state, a, 3)
    u, a = cut(state, a, n)
    v_ref, a = cut(state, a, n)
    nu, a = cut(state, a, n)
    feedforward, a = cut(state, a, n)
    null_space, a = cut(state, a, n)
    xi, a = cut(state, a, r)
    jacobian, a = cut(state, a, r * n)
    object_jacobian, a = cut(state, a, r * 3)
    scalars, a = cut(state, a, STEP_SCALARS)
    return State(
        u_previous=u_previous,
        u_dot=u_dot,
        impedance_velocity=impedance_velocity,
        u=u,
        v_ref=v_ref,
        nu=nu,
        feedforward=feedforward,
        null_space=null_space,
        xi=xi,
        jacobian=jacobian.reshape((r, n)),
        object_jacobian=object_jacobian.reshape((r, 3)),
        scalars=scalars,
    )


@njit(cache=True, inline="always")
def step_scalars(block: np.ndarray) -> StepScalars:
    """The :class:`StepScalars` stored in ``block`` (``State.scalars``)."""
    return StepScalars(
        has_previous=block[0],
        valid=block[1],
        storage=block[2],
        sigma_min=block[3],
        damped=block[4],
        factor=block[5],
        v2=block[6],
        loop_gain=block[7],
        gain_factor=block[8],
        sigma_phi=block[9],
        upright_weight=block[10],
        upright_angle=block[11],
        seen=block[12],
    )


@njit(cache=True, inline="always")
def store(block: np.ndarray, values: StepScalars) -> None:
    """Write ``values`` into ``block`` (``State.scalars``) in their field order."""
    for i in range(len(values)):
        block[i] = values[i]


def slot(record: type[NamedTuple], name: str) -> int:
    """Position of field ``name`` of a scalar block (:class:`Settings`, :class:`StepScalars`)."""
    return record._fields.index(name)
