r"""Classic image-based visual servoing baseline, as ViSP does it, in the same compiled step.

.. math:: u = -\lambda\, J^\# \tilde\xi - J^\# J_o \hat{\dot p}
              + (I - J^\# J)\, k_1 \tanh(k_2 \Lambda)

It is :func:`~pbvs_pin.control.kinematic.passivity_law` with the feedback
:data:`~pbvs_pin.control.kinematic.IBVS`: ``lambda J# e`` in place of ``J^T K_c e``. Everything
else is the passivity controller's: the same (weighted, damped) pseudo-inverse, secondary
objectives, upright row, joint stops, loop-gain net (``lambda T`` per camera sample, as for the
pseudo-inverse feedback) and velocity saturation, so that the comparison is about the feedback
law only. ``J`` and ``e`` are taken in controller units (``J# e`` does not depend on the unit;
the damping threshold does). The storage the step reports is ``V1`` of eq. (7) with
``k_i = lambda``, a measure of the error, not a storage function of this law. How ``lambda`` is
chosen: :func:`pbvs_pin.study.baseline.matched_ibvs_gain`.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from pbvs_pin.control.gains import ServoGains
from pbvs_pin.control.kinematic import IBVS, PassivityController
from pbvs_pin.exceptions import GainError


class ClassicIbvs(PassivityController):
    """``u = -lambda J# e - J# J_o phat_dot + (I - J# J) k1 tanh(k2 Lambda)``.

    Args:
        gain: ``lambda`` [1/s].
        velocity_limits: Largest magnitude of each command. Shape (n,).
        gains: ``k1``, ``k2``, ``W``, feature scale, damping, upright and net settings
            (``k`` and ``feedback`` are unused).
    """

    def __init__(
        self, gain: float, velocity_limits: npt.ArrayLike, gains: ServoGains | None = None
    ) -> None:
        if not np.isfinite(gain) or gain <= 0:
            raise GainError(f"ClassicIbvs.gain: expected > 0 [1/s], got {gain}")
        super().__init__(gains or ServoGains(), velocity_limits)
        self.gain = gain
        self.feedback_law = IBVS

    def feature_gains(self, r: int) -> np.ndarray:
        """``lambda`` for each of ``r`` features [1/s]. Shape (r,)."""
        if self._k is None or self._k.size != r:
            self._k = np.full(r, float(self.gain))
        return self._k
