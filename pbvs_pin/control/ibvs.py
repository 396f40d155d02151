r"""Classic image-based visual servoing baseline, as ViSP does it.

.. math:: u = -\lambda\, J^\# \tilde\xi - J^\# J_o \hat{\dot p}

with ``J#`` the (damped) Moore-Penrose pseudo-inverse, no null-space term, and the same
velocity saturation as the passivity controller, so that the comparison is about the law.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from pbvs_pin.control.kinematic import ControlOutput, PassivityController, ServoGains, saturate
from pbvs_pin.exceptions import GainError


class ClassicIbvs(PassivityController):
    """``u = -lambda J# e - J# J_o phat_dot``.

    Args:
        gain: ``lambda`` [1/s].
        velocity_limits: Largest magnitude of each command. Shape (n,).
        gains: Damping settings (only ``damping_threshold`` and ``max_damping`` are used).
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
    ) -> ControlOutput:
        """The classic law; ``secondary`` and ``upright`` are ignored.

        Same diagnostics as the passivity law.
        """
        error_px, jacobian_px, object_jacobian_px, target_velocity, secondary = self._inputs(
            error_px, jacobian_px, object_jacobian_px, target_velocity, secondary
        )
        r = error_px.shape[0]
        inputs = (error_px, jacobian_px, object_jacobian_px, target_velocity)
        if not all(np.all(np.isfinite(x)) for x in inputs):
            return self.zero_output(r)
        pinv, sigma_min, damped = self.pseudo_inverse(jacobian_px)
        feedback = self.gain * (pinv @ error_px)
        feedforward = pinv @ np.asarray(object_jacobian_px) @ target_velocity
        u, factor = saturate(-feedback - feedforward, self.velocity_limits)
        zero = np.zeros(self.n)
        return ControlOutput(
            u=u,
            error=error_px,
            storage=0.5 * float(error_px @ error_px),
            nu=zero,
            feedforward=feedforward,
            null_space=zero,
            min_singular_value=sigma_min,
            damped=damped,
            saturated=factor < 1.0,
            scale=factor,
        )
