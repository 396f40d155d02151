r"""Classic image-based visual servoing baseline, as ViSP does it, with the same null space.

.. math:: u = -\lambda\, J^\# \tilde\xi - J^\# J_o \hat{\dot p}
              + (I - J^\# J)\, k_1 \tanh(k_2 \Lambda)

with ``J#`` the same (weighted, damped) pseudo-inverse, the same secondary-objective term as
eq. (34) and the same velocity saturation as the passivity controller, so that the comparison
is about the feedback law only. ``J`` and ``e`` are taken in controller units (``J# e`` does
not depend on the unit; the damping threshold does). How ``lambda`` is chosen:
:func:`pbvs_pin.study.baseline.matched_ibvs_gain`.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from pbvs_pin.control.kinematic import ControlOutput, PassivityController, ServoGains, saturate
from pbvs_pin.exceptions import GainError


class ClassicIbvs(PassivityController):
    """``u = -lambda J# e - J# J_o phat_dot + (I - J# J) k1 tanh(k2 Lambda)``.

    Args:
        gain: ``lambda`` [1/s].
        velocity_limits: Largest magnitude of each command. Shape (n,).
        gains: ``k1``, ``k2``, ``W``, feature scale and damping settings (``k`` is unused).
    """

    def __init__(
        self, gain: float, velocity_limits: npt.ArrayLike, gains: ServoGains | None = None
    ) -> None:
        if not np.isfinite(gain) or gain <= 0:
            raise GainError(f"ClassicIbvs.gain: expected > 0 [1/s], got {gain}")
        super().__init__(gains or ServoGains(), velocity_limits)
        self.gain = gain

    def step(
        self,
        error_px: npt.ArrayLike,
        jacobian_px: npt.ArrayLike,
        object_jacobian_px: npt.ArrayLike,
        target_velocity: npt.ArrayLike,
        secondary: npt.ArrayLike,
        upright: np.ndarray | None = None,
        room: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> ControlOutput:
        """The classic law with the null-space term. Same diagnostics as the passivity law.

        Args: as :meth:`PassivityController.step` (``secondary`` is ``Lambda`` of eq. 16);
        ``upright`` and ``room`` are ignored (the baseline keeps the paper's null space and its
        own pseudo-inverse feedback).
        """
        error_px, jacobian_px, object_jacobian_px, target_velocity, secondary = self._inputs(
            error_px, jacobian_px, object_jacobian_px, target_velocity, secondary
        )
        r = error_px.shape[0]
        inputs = (error_px, jacobian_px, object_jacobian_px, target_velocity, secondary)
        if not all(np.all(np.isfinite(x)) for x in inputs):
            return self.zero_output(r)
        scale = self.gains.feature_scale
        jacobian = jacobian_px / scale
        pinv, sigma_min, damped = self.pseudo_inverse(jacobian)
        feedback = self.gain * (pinv @ (error_px / scale))
        feedforward = pinv @ (object_jacobian_px / scale) @ target_velocity
        shaped = self.k1 * np.tanh(self.k2 * secondary)
        null_space = shaped - pinv @ (jacobian @ shaped)
        u, factor = saturate(null_space - feedback - feedforward, self.velocity_limits)
        return ControlOutput(
            u=u,
            error=error_px,
            storage=0.5 * float(error_px @ error_px),
            nu=np.zeros(self.n),
            feedforward=feedforward,
            null_space=null_space,
            min_singular_value=sigma_min,
            damped=damped,
            saturated=factor < 1.0,
            scale=factor,
        )
