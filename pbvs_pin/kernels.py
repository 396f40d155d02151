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

ROUNDOFF_FLOOR = 1e-12
"""Smallest eigenvalue of the regularised ``J W^-1 J^T``, relative to its trace."""

# Small dense helpers: at these sizes (r <= 8, n <= 12) plain loops beat a BLAS/LAPACK call.


@njit(cache=True)
def _matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` for small matrices."""
    out = np.zeros((a.shape[0], b.shape[1]))
    for i in range(a.shape[0]):
        for k in range(a.shape[1]):
            aik = a[i, k]
            if aik != 0.0:
                for j in range(b.shape[1]):
                    out[i, j] += aik * b[k, j]
    return out


@njit(cache=True)
def _matvec(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``a @ x`` for a small matrix."""
    out = np.zeros(a.shape[0])
    for i in range(a.shape[0]):
        total = 0.0
        for k in range(a.shape[1]):
            total += a[i, k] * x[k]
        out[i] = total
    return out


@njit(cache=True)
def _actuated_terms(
    mass_upper: np.ndarray,
    bias: np.ndarray,
    gravity: np.ndarray,
    selection: np.ndarray,
    gravity_weight: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    r"""Rigid-body terms in actuated coordinates, for eq. (1).

    .. math:: M_v = S^T M_{rb} S,\qquad C_v v + (I - G) g_v = S^T b - G\, S^T g_{rb}

    with ``b = C_rb(q, S v) S v + g_rb`` from ``pin.nonLinearEffects``.

    Args:
        mass_upper: CRBA mass matrix, upper triangle filled (``pin.crba``). Shape (nv, nv).
        bias: ``b``. Shape (nv,).
        gravity: ``g_rb``. Shape (nv,).
        selection: ``S``; mostly zeros, which are skipped. Shape (nv, n).
        gravity_weight: Diagonal of ``I - G``. Shape (n,).

    Returns:
        ``M_v`` (n, n) and ``C_v v + (I - G) g_v`` (n,).
    """
    nv, n = selection.shape
    mass_v = np.zeros((n, n))
    bias_v = np.zeros(n)
    for a in range(nv):
        for i in range(n):
            s_ai = selection[a, i]
            if s_ai == 0.0:
                continue
            bias_v[i] += s_ai * (bias[a] - (1.0 - gravity_weight[i]) * gravity[a])
            for b in range(nv):
                m_ab = mass_upper[a, b] if a <= b else mass_upper[b, a]
                for j in range(n):
                    mass_v[i, j] += s_ai * m_ab * selection[b, j]
    return mass_v, bias_v


@njit(cache=True)
def _cholesky_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``a x = b`` for a symmetric positive definite ``a`` (shape (r, r), b (r, m))."""
    r = a.shape[0]
    low = np.zeros((r, r))
    for j in range(r):
        total = a[j, j]
        for k in range(j):
            total -= low[j, k] * low[j, k]
        low[j, j] = np.sqrt(total)
        for i in range(j + 1, r):
            total = a[i, j]
            for k in range(j):
                total -= low[i, k] * low[j, k]
            low[i, j] = total / low[j, j]
    x = b.copy()
    for col in range(x.shape[1]):
        for i in range(r):
            total = x[i, col]
            for k in range(i):
                total -= low[i, k] * x[k, col]
            x[i, col] = total / low[i, i]
        for i in range(r - 1, -1, -1):
            total = x[i, col]
            for k in range(i + 1, r):
                total -= low[k, i] * x[k, col]
            x[i, col] = total / low[i, i]
    return x


@njit(cache=True)
def _smallest_eigenvalue(a: np.ndarray) -> float:
    """Smallest eigenvalue of a symmetric matrix; closed form up to 3 x 3 (Smith 1961).

    For 3 x 3, the eigenvalues are ``q + 2 p cos(phi + 2 pi j / 3)`` with ``q = tr(a) / 3``,
    ``p = |a - q I|_F / sqrt(6)`` and ``cos(3 phi) = det((a - q I) / p) / 2``. Larger
    matrices go to LAPACK.
    """
    r = a.shape[0]
    if r == 1:
        return a[0, 0]
    if r == 2:
        half_gap = 0.5 * (a[0, 0] - a[1, 1])
        return 0.5 * (a[0, 0] + a[1, 1]) - np.sqrt(half_gap * half_gap + a[0, 1] * a[0, 1])
    if r > 3:
        return np.linalg.eigvalsh(a)[0]
    off = a[0, 1] * a[0, 1] + a[0, 2] * a[0, 2] + a[1, 2] * a[1, 2]
    q = (a[0, 0] + a[1, 1] + a[2, 2]) / 3.0
    d0, d1, d2 = a[0, 0] - q, a[1, 1] - q, a[2, 2] - q
    p = np.sqrt((d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * off) / 6.0)
    if p == 0.0:
        return q
    b01, b02, b12 = a[0, 1] / p, a[0, 2] / p, a[1, 2] / p
    b0, b1, b2 = d0 / p, d1 / p, d2 / p
    det = b0 * (b1 * b2 - b12 * b12) - b01 * (b01 * b2 - b12 * b02) + b02 * (b01 * b12 - b1 * b02)
    phi = np.arccos(min(max(0.5 * det, -1.0), 1.0)) / 3.0
    return q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)


@njit(cache=True)
def _all_finite(a: np.ndarray) -> bool:
    """Whether every entry of ``a`` is finite (no temporary arrays)."""
    for x in a.flat:
        if not np.isfinite(x):
            return False
    return True


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
    return xi, _matmul(selected_l, camera_jacobian), _matmul(selected_p, rotation_world_to_camera)


@njit(cache=True)
def storage_function(error_units: np.ndarray, k: np.ndarray) -> float:
    r"""``V1`` of eq. (7) in closed form.

    .. math:: V_1 = \int_0^{\tilde\xi} \eta^T K_c(\eta)\, d\eta
              = \sum_i k_i \left(|\tilde\xi_i| - \ln(1 + |\tilde\xi_i|)\right)

    Args:
        error_units: Feature error in controller units. Shape (r,).
        k: ``k_i``. Shape (r,).
    """
    total = 0.0
    for i in range(error_units.shape[0]):
        magnitude = abs(error_units[i])
        total += k[i] * (magnitude - np.log1p(magnitude))
    return total


@njit(cache=True)
def saturate(u: np.ndarray, limits: np.ndarray) -> tuple[np.ndarray, float]:
    """Scale ``u`` uniformly so that ``|u_i| <= limits_i``; return it and the factor."""
    ratio = 0.0
    for i in range(u.shape[0]):
        ratio = max(ratio, abs(u[i]) / limits[i])
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

    If that leaves ``J W^-1 J^T + mu^2 I`` with an eigenvalue below :data:`ROUNDOFF_FLOOR`
    times its trace (``J`` singular to round-off and a tiny ``sigma_0``), ``mu^2`` is raised
    to that floor, so that no division by zero can happen.

    Args:
        jacobian: ``J``. Shape (r, n).
        weight_inverse: ``W^-1``. Shape (n, n).
        threshold: ``sigma_0``.
        max_damping: ``mu_max``.

    Returns:
        ``J#`` (n, r), ``sigma_min`` of ``J W^-1/2``, whether it was damped.
    """
    right = _matmul(weight_inverse, jacobian.T)
    gram = _matmul(jacobian, right)
    smallest = _smallest_eigenvalue(gram)
    sigma_min = np.sqrt(max(smallest, 0.0))
    damped = sigma_min < threshold
    mu2 = max_damping * max_damping * (1.0 - (sigma_min / threshold) ** 2) if damped else 0.0
    # a J singular to round-off with a tiny threshold: keep the Cholesky factor real
    floor = ROUNDOFF_FLOOR * np.trace(gram)
    if smallest + mu2 < floor:
        mu2 = floor - min(smallest, 0.0)
    if mu2 > 0.0:
        gram = gram + mu2 * np.eye(gram.shape[0])
    return _cholesky_solve(gram, right.T.copy()).T.copy(), sigma_min, damped


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
        _all_finite(error)
        and _all_finite(jacobian)
        and _all_finite(object_jacobian)
        and _all_finite(target_velocity)
        and _all_finite(secondary)
    )
    if not finite:
        return False, zero, zero, zero, zero, np.nan, np.nan, False, 1.0
    r = error.shape[0]
    kc_error = np.empty(r)
    for i in range(r):
        kc_error[i] = k[i] / (1.0 + abs(error[i])) * error[i]
    shaped = np.empty(n)
    for j in range(n):
        shaped[j] = k1[j] * np.tanh(k2[j] * secondary[j])
    nu = _matvec(jacobian.T, kc_error)
    pinv, sigma_min, damped = damped_pseudo_inverse(
        jacobian, weight_inverse, damping[0], damping[1]
    )
    feedforward = _matvec(pinv, _matvec(object_jacobian, target_velocity))
    null_space = shaped - _matvec(pinv, _matvec(jacobian, shaped))
    feedback = _matvec(pinv, kc_error) if pseudoinverse_feedback else nu
    u, factor = saturate(null_space - feedback - feedforward, limits)
    if not _all_finite(u):
        return False, zero, zero, zero, zero, np.nan, np.nan, False, 1.0
    storage = storage_function(error, k)
    return True, u, nu, feedforward, null_space, storage, sigma_min, damped, factor


@njit(cache=True)
def compensation_law(
    mass_upper: np.ndarray,
    bias: np.ndarray,
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
    limits: np.ndarray,
) -> tuple[np.ndarray, float]:
    r"""Eq. (20) on the velocity-reference model of eq. (1), from Pinocchio's terms.

    .. math:: M = K_v^{-1} S^T M_{rb} S,\quad C = K_v^{-1}(S^T C_{rb} S + D) + I,\quad
              g = K_v^{-1} (I - G) S^T g_{rb},

    .. math:: v_{ref} = M(\dot u - K_D (v - u)) + C v + g

    Args:
        mass_upper: CRBA mass matrix, upper triangle filled (``pin.crba``). Shape (nv, nv).
        bias: ``C_rb(q, S v) S v + g_rb`` (``pin.nonLinearEffects``). Shape (nv,).
        gravity: Generalised gravity ``g_rb``. Shape (nv,).
        selection: ``S``. Shape (nv, n).
        gain_inverse: ``1 / K_v``. Shape (n,).
        damping: ``D``. Shape (n,).
        gravity_weight: Diagonal of ``I - G`` (0 where the servo cancels gravity). Shape (n,).
        rows: Which rows are compensated (the others pass ``u`` through). Shape (n,).
        k_d: Diagonal of ``K_D`` [1/s]. Shape (n,).
        v: Measured actuated velocity. Shape (n,).
        u: Kinematic command. Shape (n,).
        u_dot: Command derivative. Shape (n,).
        limits: Velocity limits the low-level loops accept; ``v_ref`` is clipped to them.
            Shape (n,).

    Returns:
        ``v_ref`` (n,) and ``V2 = |v - u|^2 / 2`` (eq. 22).
    """
    n = v.shape[0]
    mass_v, bias_v = _actuated_terms(mass_upper, bias, gravity, selection, gravity_weight)
    acceleration = np.empty(n)
    storage = 0.0
    for j in range(n):
        error = v[j] - u[j]
        storage += 0.5 * error * error
        acceleration[j] = u_dot[j] - k_d[j] * error
    v_ref = np.empty(n)
    for i in range(n):
        value = u[i]
        if rows[i]:
            inertial = bias_v[i] + damping[i] * v[i]
            for j in range(n):
                inertial += mass_v[i, j] * acceleration[j]
            value = gain_inverse[i] * inertial + v[i]
        v_ref[i] = min(max(value, -limits[i]), limits[i])
    return v_ref, storage


@njit(cache=True)
def velocity_loop_step(
    mass_upper: np.ndarray,
    bias: np.ndarray,
    gravity: np.ndarray,
    selection: np.ndarray,
    gains: np.ndarray,
    damping: np.ndarray,
    gravity_weight: np.ndarray,
    v: np.ndarray,
    v_ref: np.ndarray,
    h: float,
    v_pin_out: np.ndarray,
    displacement_out: np.ndarray,
) -> np.ndarray:
    r"""One semi-implicit step of eq. (1) times ``K_v``: the plant's velocity update.

    .. math:: (M_v + h (K_v + D))\, v_{k+1} = M_v v_k + h (K_v v_{ref} - C_v v_k - (I - G) g_v)

    Args:
        mass_upper: CRBA mass matrix, upper triangle filled. Shape (nv, nv).
        bias: ``C_rb(q, S v) S v + g_rb`` (``pin.nonLinearEffects``). Shape (nv,).
        gravity: Generalised gravity ``g_rb``. Shape (nv,).
        selection: ``S``. Shape (nv, n).
        gains: ``K_v``. Shape (n,).
        damping: ``D``. Shape (n,).
        gravity_weight: Diagonal of ``I - G`` (0 where the servo cancels gravity). Shape (n,).
        v: Actuated velocity. Shape (n,).
        v_ref: Velocity reference. Shape (n,).
        h: Step [s].
        v_pin_out: Written: ``S v_{k+1}``. Shape (nv,).
        displacement_out: Written: ``S v_{k+1} h`` for ``pin.integrate``. Shape (nv,).

    Returns:
        ``v_{k+1}``. Shape (n,).
    """
    mass_v, bias_v = _actuated_terms(mass_upper, bias, gravity, selection, gravity_weight)
    lhs = mass_v + h * np.diag(gains + damping)
    rhs = _matvec(mass_v, v) + h * (gains * v_ref - bias_v)
    v_next = _cholesky_solve(lhs, rhs.reshape(-1, 1))[:, 0]
    v_pin_out[:] = _matvec(selection, v_next)
    displacement_out[:] = h * v_pin_out
    return v_next


@njit(cache=True)
def arm_angles(q: np.ndarray, idx_q: np.ndarray, continuous: np.ndarray) -> np.ndarray:
    """Arm joint positions from a configuration; continuous joints (cos, sin) give an angle.

    Args:
        q: Configuration. Shape (nq,).
        idx_q: Index of each arm joint in ``q``. Shape (n_arm,).
        continuous: Whether each joint is stored as (cos, sin). Shape (n_arm,).

    Returns:
        Shape (n_arm,) [rad or m].
    """
    angles = np.empty(idx_q.shape[0])
    for i in range(idx_q.shape[0]):
        j = idx_q[i]
        angles[i] = np.arctan2(q[j + 1], q[j]) if continuous[i] else q[j]
    return angles


@njit(cache=True)
def posture_term(arm: np.ndarray, target: np.ndarray, gain: float) -> np.ndarray:
    r"""Eq. (19): ``f_i = k_Lambda (theta_id - theta_i)``. Shape (n_arm,)."""
    return gain * (target - arm)


@njit(cache=True)
def joint_limit_term(
    arm: np.ndarray, lower: np.ndarray, upper: np.ndarray, margin: float, gain: float
) -> np.ndarray:
    """Restoring rates within ``margin`` of a limit; infinite limits give 0. Shape (n_arm,)."""
    above = np.maximum(arm - (upper - margin), 0.0)
    below = np.minimum(arm - (lower + margin), 0.0)
    return -gain * (above + below)


@njit(cache=True)
def obstacle_force(distance: float, angle: float, k_u: float, k_w: float, d0: float) -> np.ndarray:
    r"""Fictitious force of eqs. (17)-(18) before the impedance, ``[F_u, F_w]``.

    .. math:: F_u = k_{uobs} (d_0 - d)(\tfrac{\pi}{2} - |\alpha|),\quad
              F_\omega = k_{\omega obs} (d_0 - d)\, \mathrm{sign}(\alpha)(\tfrac{\pi}{2} - |\alpha|)

    zero when ``d >= d_0`` or nothing is seen (``d`` infinite).
    """
    force = np.zeros(2)
    if np.isfinite(distance) and distance < d0:
        reach = (d0 - distance) * (0.5 * np.pi - abs(angle))
        force[0] = k_u * reach
        force[1] = k_w * np.sign(angle) * reach
    return force


@njit(cache=True)
def impedance_step(
    velocity: np.ndarray, force: np.ndarray, mass: float, damping: float, dt: float
) -> np.ndarray:
    """Exact step of ``m du/dt + b u = F`` over ``dt`` with ``F`` held (the ``Z^-1`` of (17))."""
    decay = np.exp(-damping / mass * dt)
    return decay * velocity + (1.0 - decay) * force / damping


# The fused step's packed arguments. Calling a compiled function from Python costs about
# 0.1 us per argument and about 0.7 us per array returned, so the 1 kHz step passes its constant
# data in one float and one integer array and writes its results into one preallocated buffer.
# The layouts are defined here only; ``FusedControlStep`` fills them through these views.

SIZE_FIELDS = 4
"""``indices`` starts with ``n, r, nv, n_arm``; then ``rows, arm_idx_q, arm_continuous``."""


@njit(cache=True)
def _sizes(indices: np.ndarray) -> tuple[int, int, int, int]:
    return indices[0], indices[1], indices[2], indices[3]


@njit(cache=True)
def parameter_size(indices: np.ndarray) -> int:
    """Length of the float parameter array of :func:`fused_control_step`."""
    n, r, nv, n_arm = _sizes(indices)
    return 2 * r + 8 * n + n * n + 3 * n_arm + SCALARS + nv * n


@njit(cache=True)
def state_size(indices: np.ndarray) -> int:
    """Length of the state-and-output buffer of :func:`fused_control_step`."""
    n, r, _, _ = _sizes(indices)
    return 3 * max(n, 3) + 7 * max(n, r, 6) + r * n + r * 3


SCALARS = 18
"""Entries of the ``scalars`` parameter block (see :func:`_control_step`)."""


@njit(cache=True)
def parameter_views(params: np.ndarray, indices: np.ndarray) -> tuple:
    """Views of the constant floats in ``params``.

    In this order:

    - ``xi_d``: desired features [px], (r,);
    - ``k``: ``k_i``, (r,);
    - ``dof``: rows ``k1, k2, limits, 1/K_v, D, I - G, compensated, K_D``, (8, n);
    - ``weight_inverse``: ``W^-1``, (n, n);
    - ``arm``: rows ``theta_d, lower, upper``, (3, n_arm);
    - ``scalars``: ``focal, feature_scale, sigma_0, mu_max, pinv_feedback, tau_udot, n_base,
      posture_on, k_Lambda, limits_on, limit_margin, limit_gain, obstacle_on, k_uobs, k_wobs,
      d0, impedance_mass, impedance_damping``, (18,);
    - ``selection``: ``S``, (nv, n).
    """
    n, r, nv, n_arm = _sizes(indices)
    a = 0
    xi_d = params[a : a + r]
    a += r
    k = params[a : a + r]
    a += r
    dof = params[a : a + 8 * n].reshape((8, n))
    a += 8 * n
    weight_inverse = params[a : a + n * n].reshape((n, n))
    a += n * n
    arm = params[a : a + 3 * n_arm].reshape((3, n_arm))
    a += 3 * n_arm
    scalars = params[a : a + SCALARS]
    a += SCALARS
    selection = params[a : a + nv * n].reshape((nv, n))
    return xi_d, k, dof, weight_inverse, arm, scalars, selection


@njit(cache=True)
def index_views(indices: np.ndarray) -> tuple:
    """Views of the constant integers in ``indices``.

    Feature ``rows`` (r,), the arm joints' indices in ``q`` (n_arm,), and whether each is
    continuous (n_arm,).
    """
    _, r, _, n_arm = _sizes(indices)
    a = SIZE_FIELDS
    return indices[a : a + r], indices[a + r : a + r + n_arm], indices[a + r + n_arm :]


@njit(cache=True)
def state_views(state: np.ndarray, indices: np.ndarray) -> tuple:
    """Views of the memory and outputs in ``state``.

    In this order:

    - ``memory``: rows ``u_prev``, ``u_dot``, ``[has_prev, F_u state, F_w state, ...]``,
      (3, max(n, 3));
    - ``out``: rows ``u, v_ref, nu, feedforward, null_space`` (first n entries),
      ``[valid, storage, sigma_min, damped, factor, V2]``, ``xi`` (first r entries),
      (7, max(n, r, 6));
    - ``J`` [px], (r, n), and ``J_o`` [px/m], (r, 3).
    """
    n, r, _, _ = _sizes(indices)
    m, w = max(n, 3), max(n, r, 6)
    memory = state[: 3 * m].reshape((3, m))
    out = state[3 * m : 3 * m + 7 * w].reshape((7, w))
    a = 3 * m + 7 * w
    jacobian = state[a : a + r * n].reshape((r, n))
    object_jacobian = state[a + r * n : a + r * n + 3 * r].reshape((r, 3))
    return memory, out, jacobian, object_jacobian


@njit(cache=True)
def fused_control_step(
    frame_jacobian: np.ndarray,
    rotation: np.ndarray,
    mass_upper: np.ndarray,
    bias: np.ndarray,
    gravity: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
    points: np.ndarray,
    depths: np.ndarray,
    target_velocity: np.ndarray,
    laser: np.ndarray,
    dt: float,
    params: np.ndarray,
    indices: np.ndarray,
    state: np.ndarray,
) -> None:
    """One whole control step in one call: eqs. (16)-(19), (3), (34) and (20).

    It chains the kernels above exactly as the modular classes do (secondary objectives,
    :func:`feature_jacobians`, :func:`passivity_law`, :func:`compensation_law`);
    :class:`pbvs_pin.control.fused.FusedControlStep` packs the arguments.

    Args:
        frame_jacobian: Camera frame Jacobian, ``pin.LOCAL``. Shape (6, nv).
        rotation: ``wRc``. Shape (3, 3).
        mass_upper: ``pin.crba``. Shape (nv, nv).
        bias: ``pin.nonLinearEffects`` at ``S v``. Shape (nv,).
        gravity: ``pin.computeGeneralizedGravity``. Shape (nv,).
        q: Configuration. Shape (nq,).
        v: Actuated velocity. Shape (n,).
        points: Measured image points [px]. Shape (k, 2).
        depths: Their depths [m]. Shape (k,).
        target_velocity: ``phat_dot`` [m/s]. Shape (3,).
        laser: ``[d, alpha]`` of the nearest return. Shape (2,).
        dt: Control period [s].
        params: Constant floats, laid out by :func:`parameter_views`.
        indices: Sizes and constant integers, laid out by :func:`index_views`.
        state: Memory and outputs, laid out by :func:`state_views`; updated in place.
    """
    xi_d, k, dof, weight_inverse, arm, scalars, selection = parameter_views(params, indices)
    rows, arm_idx_q, arm_continuous = index_views(indices)
    memory, out, jacobian_out, object_jacobian_out = state_views(state, indices)
    n = selection.shape[1]
    n_base = int(scalars[6])
    theta = arm_angles(q, arm_idx_q, arm_continuous)
    secondary = np.zeros(n)
    if scalars[7] > 0.0:
        secondary[n_base:] += posture_term(theta, arm[0], scalars[8])
    if scalars[9] > 0.0:
        secondary[n_base:] += joint_limit_term(theta, arm[1], arm[2], scalars[10], scalars[11])
    if scalars[12] > 0.0:
        force = obstacle_force(laser[0], laser[1], scalars[13], scalars[14], scalars[15])
        impedance = impedance_step(memory[2, 1:3], force, scalars[16], scalars[17], dt)
        memory[2, 1:3] = impedance
        if n_base >= 2:
            secondary[0] -= impedance[0]
            secondary[n_base - 1] += impedance[1]
    xi, jacobian, object_jacobian = feature_jacobians(
        points, depths, rows, scalars[0], _matmul(frame_jacobian, selection), rotation.T
    )
    r = xi.shape[0]
    out[6, :r] = xi
    jacobian_out[:, :] = jacobian
    object_jacobian_out[:, :] = object_jacobian
    # controller units (eq. 34 works in feature_scale px)
    scale = scalars[1]
    error = (xi - xi_d) / scale
    jacobian /= scale
    object_jacobian /= scale
    valid, u, nu, feedforward, null_space, storage, sigma_min, damped, factor = passivity_law(
        error, jacobian, object_jacobian, target_velocity, secondary, k, dof[0], dof[1],
        weight_inverse, scalars[2:4], dof[2], scalars[4] > 0.0,
    )  # fmt: skip
    u_prev, u_dot = memory[0], memory[1]
    if memory[2, 0] > 0.0 and dt > 0.0:
        blend = dt / (scalars[5] + dt)
        for j in range(n):
            u_dot[j] += blend * ((u[j] - u_prev[j]) / dt - u_dot[j])
    u_prev[:n] = u
    memory[2, 0] = 1.0
    v_ref, v2 = compensation_law(
        mass_upper, bias, gravity, selection, dof[3], dof[4], dof[5], dof[6], dof[7], v, u,
        u_dot[:n], dof[2],
    )  # fmt: skip
    out[0, :n] = u
    out[1, :n] = v_ref
    out[2, :n] = nu
    out[3, :n] = feedforward
    out[4, :n] = null_space
    out[5, 0] = 1.0 if valid else 0.0
    out[5, 1] = storage
    out[5, 2] = sigma_min
    out[5, 3] = 1.0 if damped else 0.0
    out[5, 4] = factor
    out[5, 5] = v2
