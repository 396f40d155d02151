r"""Compiled kernels of the control step (Numba), the single implementation of its equations.

The classes in :mod:`pbvs_pin.control.kinematic`, :mod:`pbvs_pin.control.compensation` and
:mod:`pbvs_pin.features` validate their inputs and call these functions; Pinocchio computes
every Jacobian and dynamic term beforehand. Numba compiles each kernel on first use and caches
the machine code next to this file, so that a 1 kHz control step costs a small multiple of
the Pinocchio calls it makes (``benchmarks/control_step.py``) instead of the tens of small
NumPy calls a plain implementation needs.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
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


@njit(cache=True)
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
    return xi, selected_l @ camera_jacobian, selected_p @ rotation_world_to_camera


@njit(cache=True)
def storage_function(error_units: np.ndarray, k: np.ndarray) -> float:
    r"""``V1`` of eq. (7) in closed form.

    .. math:: V_1 = \int_0^{\tilde\xi} \eta^T K_c(\eta)\, d\eta
              = \sum_i k_i \left(|\tilde\xi_i| - \ln(1 + |\tilde\xi_i|)\right)

    Args:
        error_units: Feature error in controller units. Shape (r,).
        k: ``k_i``. Shape (r,).
    """
    magnitude = np.abs(error_units)
    return np.sum(k * (magnitude - np.log1p(magnitude)))


@njit(cache=True)
def saturate(u: np.ndarray, limits: np.ndarray) -> tuple[np.ndarray, float]:
    """Scale ``u`` uniformly so that ``|u_i| <= limits_i``; return it and the factor."""
    ratio = np.max(np.abs(u) / limits)
    if ratio <= 1.0:
        return u, 1.0
    return u / ratio, 1.0 / ratio


@njit(cache=True)
def damped_pseudo_inverse(
    jacobian: np.ndarray, weight_inverse: np.ndarray, threshold: float, max_damping: float
) -> tuple[np.ndarray, float, bool]:
    r"""Weighted right pseudo-inverse, damped near singularities (Nakamura & Hanafusa 1986).

    .. math:: J^\# = W^{-1} J^T (J W^{-1} J^T + \mu^2 I)^{-1},\quad
              \mu^2 = \mu_{max}^2 \left(1 - (\sigma_{min}/\sigma_0)^2\right)
              \text{ if } \sigma_{min} < \sigma_0 \text{ else } 0

    Args:
        jacobian: ``J``. Shape (r, n).
        weight_inverse: ``W^-1``. Shape (n, n).
        threshold: ``sigma_0``.
        max_damping: ``mu_max``.

    Returns:
        ``J#`` (n, r), ``sigma_min`` of ``J W^-1/2``, whether it was damped.
    """
    right = weight_inverse @ jacobian.T
    gram = jacobian @ right
    sigma_min = np.sqrt(max(np.linalg.eigvalsh(gram)[0], 0.0))
    damped = sigma_min < threshold
    if damped:
        mu2 = max_damping * max_damping * (1.0 - (sigma_min / threshold) ** 2)
        gram = gram + mu2 * np.eye(gram.shape[0])
    return np.linalg.solve(gram, right.T).T, sigma_min, damped


@njit(cache=True)
def passivity_law(
    error: np.ndarray,
    jacobian: np.ndarray,
    object_jacobian: np.ndarray,
    target_velocity: np.ndarray,
    secondary: np.ndarray,
    k: np.ndarray,
    k1: np.ndarray,
    k2: np.ndarray,
    weight_inverse: np.ndarray,
    damping: np.ndarray,
    limits: np.ndarray,
    pseudoinverse_feedback: bool,
) -> tuple:
    r"""Eq. (10)/(34) in controller units, saturated uniformly to the velocity limits.

    .. math:: \nu = J^T K_c(\tilde\xi)\tilde\xi,\quad
              K_c = \mathrm{diag}\!\left(\frac{k_i}{1 + |\tilde\xi_i|}\right),\quad
              u = -\nu - J^\# J_o \hat{\dot p} + (I - J^\# J)\, k_1 \tanh(k_2 \Lambda)

    and ``V1 = sum_i k_i (|e_i| - ln(1 + |e_i|))`` (eq. 7 in closed form).

    Args:
        error: ``xi - xi_d`` in controller units. Shape (r,).
        jacobian: ``J`` in controller units. Shape (r, n).
        object_jacobian: ``J_o`` in controller units. Shape (r, 3).
        target_velocity: ``phat_dot`` [m/s]. Shape (3,).
        secondary: ``Lambda``. Shape (n,).
        k: ``k_i`` [1/s]. Shape (r,).
        k1: Diagonal of ``k_1``. Shape (n,).
        k2: Diagonal of ``k_2``. Shape (n,).
        weight_inverse: ``W^-1``. Shape (n, n).
        damping: ``[sigma_0, mu_max]`` of the pseudo-inverse. Shape (2,).
        limits: Velocity limits. Shape (n,).
        pseudoinverse_feedback: Use ``J# K_c e`` instead of ``nu`` as feedback.

    Returns:
        ``(valid, u, nu, feedforward, null_space, storage, sigma_min, damped, factor)``;
        ``valid`` is False (and ``u`` zero) when an input is not finite.
    """
    n = secondary.shape[0]
    zero = np.zeros(n)
    finite = (
        np.all(np.isfinite(error))
        and np.all(np.isfinite(jacobian))
        and np.all(np.isfinite(object_jacobian))
        and np.all(np.isfinite(target_velocity))
        and np.all(np.isfinite(secondary))
    )
    if not finite:
        return False, zero, zero, zero, zero, np.nan, np.nan, False, 1.0
    kc_error = k / (1.0 + np.abs(error)) * error
    nu = jacobian.T @ kc_error
    pinv, sigma_min, damped = damped_pseudo_inverse(
        jacobian, weight_inverse, damping[0], damping[1]
    )
    feedforward = pinv @ (object_jacobian @ target_velocity)
    shaped = k1 * np.tanh(k2 * secondary)
    null_space = shaped - pinv @ (jacobian @ shaped)
    feedback = pinv @ kc_error if pseudoinverse_feedback else nu
    u, factor = saturate(-feedback - feedforward + null_space, limits)
    if not np.all(np.isfinite(u)):
        return False, zero, zero, zero, zero, np.nan, np.nan, False, 1.0
    storage = storage_function(error, k)
    return True, u, nu, feedforward, null_space, storage, sigma_min, damped, factor


@njit(cache=True)
def compensation_law(
    mass_upper: np.ndarray,
    coriolis: np.ndarray,
    gravity: np.ndarray,
    selection: np.ndarray,
    gain_inverse: np.ndarray,
    damping: np.ndarray,
    gravity_weight: np.ndarray,
    rows: np.ndarray,
    k_d: np.ndarray,
    v: np.ndarray,
    u: np.ndarray,
    u_dot: np.ndarray,
) -> tuple[np.ndarray, float]:
    r"""Eq. (20) on the velocity-reference model of eq. (1), from Pinocchio's terms.

    .. math:: M = K_v^{-1} S^T M_{rb} S,\quad C = K_v^{-1}(S^T C_{rb} S + D) + I,\quad
              g = K_v^{-1} (I - G) S^T g_{rb},

    .. math:: v_{ref} = M(\dot u - K_D (v - u)) + C v + g

    Args:
        mass_upper: CRBA mass matrix, upper triangle filled (``pin.crba``). Shape (nv, nv).
        coriolis: Coriolis matrix at ``S v``. Shape (nv, nv).
        gravity: Generalised gravity. Shape (nv,).
        selection: ``S``. Shape (nv, n).
        gain_inverse: ``1 / K_v``. Shape (n,).
        damping: ``D``. Shape (n,).
        gravity_weight: Diagonal of ``I - G`` (0 where the servo cancels gravity). Shape (n,).
        rows: Which rows are compensated (the others pass ``u`` through). Shape (n,).
        k_d: Diagonal of ``K_D`` [1/s]. Shape (n,).
        v: Measured actuated velocity. Shape (n,).
        u: Kinematic command. Shape (n,).
        u_dot: Command derivative. Shape (n,).

    Returns:
        ``v_ref`` (n,) and ``V2 = |v - u|^2 / 2`` (eq. 22).
    """
    error = v - u
    storage = 0.5 * np.sum(error * error)
    mass = np.triu(mass_upper) + np.triu(mass_upper, 1).T
    mass_v = selection.T @ mass @ selection
    coriolis_v = selection.T @ coriolis @ selection
    gravity_v = gravity_weight * (selection.T @ gravity)
    acceleration = u_dot - k_d * error
    inertial = mass_v @ acceleration + coriolis_v @ v + gravity_v + damping * v
    reference = gain_inverse * inertial + v
    return np.where(rows, reference, u), storage


@njit(cache=True)
def velocity_loop_step(
    mass_upper: np.ndarray,
    coriolis: np.ndarray,
    gravity: np.ndarray,
    selection: np.ndarray,
    gains: np.ndarray,
    damping: np.ndarray,
    gravity_weight: np.ndarray,
    v: np.ndarray,
    v_ref: np.ndarray,
    h: float,
) -> np.ndarray:
    r"""One semi-implicit step of eq. (1) times ``K_v``: the plant's velocity update.

    .. math:: (M_v + h (K_v + D))\, v_{k+1} = M_v v_k + h (K_v v_{ref} - C_v v_k - (I - G) g_v)

    Args:
        mass_upper: CRBA mass matrix, upper triangle filled. Shape (nv, nv).
        coriolis: Coriolis matrix at ``S v``. Shape (nv, nv).
        gravity: Generalised gravity. Shape (nv,).
        selection: ``S``. Shape (nv, n).
        gains: ``K_v``. Shape (n,).
        damping: ``D``. Shape (n,).
        gravity_weight: Diagonal of ``I - G`` (0 where the servo cancels gravity). Shape (n,).
        v: Actuated velocity. Shape (n,).
        v_ref: Velocity reference. Shape (n,).
        h: Step [s].

    Returns:
        ``v_{k+1}``. Shape (n,).
    """
    mass = np.triu(mass_upper) + np.triu(mass_upper, 1).T
    mass_v = selection.T @ mass @ selection
    lhs = mass_v + h * np.diag(gains + damping)
    rhs = mass_v @ v + h * (gains * v_ref - selection.T @ (coriolis @ (selection @ v)))
    rhs -= h * gravity_weight * (selection.T @ gravity)
    return np.linalg.solve(lhs, rhs)
