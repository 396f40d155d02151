"""A run's passivity signals, derived after the run: eqs. (9), (13)-(14), (27) and (31).

The controller's set (its own ``J``, ``J_o``) and the true-state set (the true robot's, the true
target's) of :mod:`pbvs_pin.study.analysis.passivity`, in controller units, for every sample at
once.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from pbvs_pin.control.balanced import balanced_feedback, balanced_gain, joint_room
from pbvs_pin.control.kinematic import IBVS, PSEUDOINVERSE, TRANSPOSE

if TYPE_CHECKING:
    from pbvs_pin.control.kinematic import PassivityController
    from pbvs_pin.sim.setup import Setup


def passivity_terms(
    setup: Setup,
    jacobians: np.ndarray,
    object_jacobians: np.ndarray,
    v: np.ndarray,
    target_velocity: np.ndarray,
    estimated_velocity: np.ndarray,
) -> dict[str, np.ndarray]:
    """``v + J# J_o pdot`` (input of eq. 9), ``lambda_min(J J^T)`` and ``gamma`` (eq. 31).

    All in controller units, for every sample at once; NaN where there was no measurement.

    Args:
        setup: The run's blocks.
        jacobians: ``J`` [px]. Shape (N, r, n).
        object_jacobians: ``J_o`` [px/m]. Shape (N, r, 3).
        v: Actuated velocities. Shape (N, n).
        target_velocity: True target velocities [m/s]. Shape (N, 3).
        estimated_velocity: Estimated target velocities [m/s]. Shape (N, 3).
    """
    scale = setup.law.gains.feature_scale
    jacobian, object_jacobian = jacobians / scale, object_jacobians / scale
    seen = np.isfinite(jacobian).all(axis=(1, 2)) & np.isfinite(object_jacobian).all(axis=(1, 2))
    samples, _, n = jacobian.shape
    passivity_input = np.full((samples, n), np.nan)
    lambda_min = np.full(samples, np.nan)
    for i in np.flatnonzero(seen):
        pinv = setup.law.pseudo_inverse(jacobian[i])[0]
        passivity_input[i] = v[i] + pinv @ (object_jacobian[i] @ target_velocity[i])
    if seen.any():
        gram = jacobian[seen] @ jacobian[seen].transpose(0, 2, 1)
        lambda_min[seen] = np.linalg.eigvalsh(gram)[:, 0]
    gamma = np.einsum("sij,sj->si", object_jacobian, target_velocity - estimated_velocity)
    return {"passivity_input": passivity_input, "lambda_min": lambda_min, "gamma": gamma}


def true_passivity_terms(
    setup: Setup, derived: dict[str, np.ndarray], v: np.ndarray
) -> dict[str, np.ndarray]:
    r"""The true-state passivity set: ``nu``, ``V1`` and the input of eq. (9) from the truth.

    With ``e = (xi_true - xi_d) / feature_scale`` and the true robot's ``J``, ``J_o``:

    .. math::
        \nu = J^T K_c(e)\, e \ (9),\qquad V_1 = \sum_i k_i (|e_i| - \ln(1 + |e_i|)) \ (7),
        \qquad \text{input} = v + J^\# J_o \dot p

    with the true ``v`` and ``pdot`` and the controller's weighted pseudo-inverse of the true
    ``J`` (``K_c(e) e`` is ``k e`` for the IBVS baseline, as in its logged ``nu``). NaN where
    the target is behind the camera. Pops ``object_jacobian_true`` from ``derived`` (it is not
    logged; ``jacobian_true`` goes once :func:`feedback_terms` used it).

    Args:
        setup: The run's blocks.
        derived: Channels derived from the true state (:mod:`pbvs_pin.sim.log`).
        v: Actuated velocities. Shape (N, n).
    """
    scale = setup.law.gains.feature_scale
    jacobian = derived["jacobian_true"] / scale
    object_jacobian = derived.pop("object_jacobian_true") / scale
    k = setup.law.feature_gains(setup.features.size)
    error = (derived["xi_true"] - setup.xi_d) / scale
    magnitude = np.abs(error)
    nu = np.einsum("sij,si->sj", jacobian, shaped_error(setup.law, error))
    storage = np.sum(k * (magnitude - np.log1p(magnitude)), axis=1)
    inputs = np.full_like(v, np.nan, dtype=float)
    for i in np.flatnonzero(np.isfinite(jacobian).all(axis=(1, 2))):
        pinv = setup.law.pseudo_inverse(jacobian[i])[0]
        inputs[i] = v[i] + pinv @ (object_jacobian[i] @ derived["target_velocity"][i])
    return {"nu_true": nu, "storage_true": storage, "passivity_input_true": inputs}


def shaped_error(law: PassivityController, error: np.ndarray) -> np.ndarray:
    """``K_c(e) e`` of eq. (10) (``k e`` for the IBVS baseline's constant gain), per sample.

    Args:
        law: The run's kinematic law.
        error: ``xi - xi_d`` in controller units. Shape (..., r).
    """
    k = law.feature_gains(error.shape[-1])
    if law.feedback_law == IBVS:
        return k * error
    return k / (1.0 + np.abs(error)) * error


def feedback_terms(
    setup: Setup, error_px: np.ndarray, jacobians: np.ndarray, nu: np.ndarray, arm: np.ndarray
) -> np.ndarray:
    """The law's feedback ``nu_fb`` at every sample, for (13)-(27) (:mod:`.analysis.passivity`).

    ``nu`` itself for the paper's law; else the law's own term on the same error and ``J``, with
    the joints' room from the true arm positions. NaN where there was no measurement.

    Args:
        setup: The run's blocks.
        error_px: ``xi - xi_d`` [px]. Shape (N, r).
        jacobians: ``J`` [px]. Shape (N, r, n).
        nu: ``nu`` of the same set. Shape (N, n).
        arm: Arm joint positions [q]. Shape (N, n_arm).
    """
    law = setup.law
    if law.feedback_law == TRANSPOSE:
        return nu
    scale = law.gains.feature_scale
    model = setup.model
    lower, upper = model.arm_position_limits()
    out = np.full_like(nu, np.nan, dtype=float)
    seen = np.isfinite(error_px).all(axis=1) & np.isfinite(jacobians).all(axis=(1, 2))
    for i in np.flatnonzero(seen):
        room = joint_room(arm[i], lower, upper, model.n_base, model.n)
        out[i] = law_feedback(law, error_px[i] / scale, jacobians[i] / scale, room)
    return out


def law_feedback(
    law: PassivityController,
    error: np.ndarray,
    jacobian: np.ndarray,
    room: tuple[np.ndarray, np.ndarray],
) -> np.ndarray:
    """The law's feedback ``nu_fb`` (``u = -nu_fb - J# J_o phat_dot + ...``) at one sample.

    ``nu`` for the paper's law, ``J# K_c e``, the balanced feedback
    (:func:`pbvs_pin.control.balanced.balanced_feedback`) or the IBVS baseline's
    ``lambda J# e``; before the loop-gain net and the saturation.

    Args:
        law: The run's kinematic law.
        error: ``xi - xi_d`` in controller units. Shape (r,).
        jacobian: ``J`` in controller units. Shape (r, n).
        room: Room towards the upper and lower limits (:func:`joint_room`).

    Returns:
        ``nu_fb`` [u]. Shape (n,).
    """
    k = law.feature_gains(error.shape[0])
    kc_error = shaped_error(law, error)
    if law.feedback_law == TRANSPOSE:
        return jacobian.T @ kc_error
    if law.feedback_law in (PSEUDOINVERSE, IBVS):
        return law.pseudo_inverse(jacobian)[0] @ kc_error
    gain = balanced_gain(law.safety.loop_gain_margin, law.safety.camera_period, k.max())
    jacobian = np.ascontiguousarray(jacobian, dtype=float)
    return balanced_feedback(kc_error, jacobian, law.velocity_limits, *room, gain)
