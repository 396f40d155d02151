r"""Robustness and L2-gain figures of a run: the paper's §4, eqs. (30)-(42), and §3.2, (9)-(14).

Everything is computed from a :class:`~pbvs_pin.sim.log.RunLog`, in the controller's feature
units (``meta["feature_scale"]`` px each, design notes §3), the units in which the proofs hold;
error bounds are also given in pixels. Notation (controller units):

- ``e = (xi_true - xi_d) / feature_scale``: the *true* feature error (the physical error, as in
  :func:`pbvs_pin.sim.metrics.summarize`), shape (T, r).
- ``K_c(e) e``, with ``K_c(e) = diag(k_i / (1 + |e_i|))`` (eq. 8), shape (T, r).
- ``gamma = J_o (pdot - phat_dot)`` (eq. 31), logged by the simulation, shape (T, r).

Where each equation lives:

=========================  =====================================================================
module                     contents
=========================  =====================================================================
:mod:`.signals`            ``K_c(e) e`` of eq. (8); trapezoidal integrals; the check tolerance
:mod:`.motion_bounds`      eqs. (31)-(42): ``lambda``, ``lambda'``, ``k_min``, condition (31),
                           the choice of t1, the ball (38), the ultimate bound (39), the L2
                           gain (42)
:mod:`.passivity`          eqs. (9) and (13)/(14): the passivity inequalities over the run
:mod:`.analyze`            :func:`analyze_log`: all of the above from one log, as a JSON dict
:mod:`.run_report`         :func:`analyze_run`: a saved run to ``analysis.json`` and
                           ``analysis.md``
:mod:`.bound_plots`        ``bound.png`` (39), ``gamma.png`` (31)/(38), ``storage.png`` (9)/(14)
=========================  =====================================================================
"""

from pbvs_pin.study.analysis.analyze import REQUIRED_CHANNELS, analyze_log
from pbvs_pin.study.analysis.bound_plots import plot_analysis
from pbvs_pin.study.analysis.motion_bounds import choose_t1, min_eigenvalue_jjt, ultimate_bound
from pbvs_pin.study.analysis.run_report import analyze_run, report_markdown
from pbvs_pin.study.analysis.signals import TOLERANCE, gain_times_error, integrate

__all__ = [
    "REQUIRED_CHANNELS",
    "TOLERANCE",
    "analyze_log",
    "analyze_run",
    "choose_t1",
    "gain_times_error",
    "integrate",
    "min_eigenvalue_jjt",
    "plot_analysis",
    "report_markdown",
    "ultimate_bound",
]
