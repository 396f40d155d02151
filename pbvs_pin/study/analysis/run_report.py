"""The analysis of a saved run, written to ``analysis.json`` and ``analysis.md`` (and the plots).

:func:`analyze_run` loads a run's ``log.npz``, computes :func:`~pbvs_pin.study.analysis.analyze_log`
and writes the report; :func:`report_markdown` sets both sides of every inequality ((9),
(13)/(14), (31), (38), (39), (42)) in a markdown table; the plots come from
:mod:`~pbvs_pin.study.analysis.bound_plots`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pbvs_pin.exceptions import LogError, OutputError, PbvsError
from pbvs_pin.sim.log import CHANNELS, RunLog, write_json_atomically, write_text_atomically
from pbvs_pin.study.analysis.analyze import analyze_log
from pbvs_pin.study.analysis.bound_plots import plot_analysis
from pbvs_pin.validation import as_path


def analyze_run(
    path: Path, epsilon: float = 0.5, out: Path | None = None, t1: float | None = None
) -> dict[str, Any]:
    """Analyse a saved run; with ``out``, also write the report and the plots.

    Args:
        path: A run's ``log.npz`` or the folder holding it.
        epsilon: ``eps`` of eq. (31), ``0 < eps < 1``.
        out: Folder for ``analysis.json``, ``analysis.md`` and the PNG plots (created); None
            to write nothing.
        t1: Start [s] of the ultimate-bound phase; None for the default rule.

    Returns:
        The figures of :func:`analyze_log`, plus ``files`` (paths written) when ``out`` is given.

    Raises:
        PbvsError: If there is no readable log at ``path``.
        GainError: If ``epsilon`` or ``t1`` is out of range.
        NonFiniteValue: If the run never measured the target.
    """
    path = as_path("path", path)
    log_file = path / "log.npz" if path.is_dir() else path
    if not log_file.is_file():
        raise PbvsError(
            f"{path}: no run log here (expected a log.npz of pbvs-pin run, or its folder)"
        )
    log = RunLog.load(log_file)
    missing = [name for name in CHANNELS if name not in log.channels]
    if missing:
        raise LogError(str(log_file), f"not a whole run log: no channel {', '.join(missing)}")
    result = analyze_log(log, epsilon, t1, str(log_file))
    if out is not None:
        out = Path(out)
        files = [out / "analysis.json", out / "analysis.md"]
        write_text_atomically(files[1], report_markdown(result))
        try:
            files += plot_analysis(log, result, out)
        except OSError as err:
            raise OutputError(str(out), f"cannot write ({err.strerror or err})") from err
        result["files"] = [str(f) for f in files]
        write_json_atomically(files[0], result)
    return result


def _fmt(value: Any, digits: int = 4) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def report_markdown(result: dict[str, Any]) -> str:
    """The analysis as a markdown page (both sides of every inequality).

    Norms are written ``‖x‖`` so that their bars do not split the table's cells.
    """
    r = result
    b39, l2 = r["bound_39"], r["l2_gain_42"]
    c31 = r["condition_31"]
    rows = [
        (
            "lambda = min_t lambda_min(J J^T) (controller units)",
            f"{_fmt(r['lambda'])} (at t = {_fmt(r['lambda_at_s'])} s)",
        ),
        ("lambda' = eps lambda", _fmt(r["lambda_prime"])),
        ("k_min [1/s]", _fmt(r["k_min"])),
        ("lambda' k_min", _fmt(r["lambda_prime_k_min"])),
        ("t1 [s]", _fmt(r["t1_s"])),
        ("sup ||gamma|| over the whole run", _fmt(r["gamma_inf_whole_run"])),
        ("||gamma||_inf over [t1, T]", _fmt(r["gamma_inf"])),
        ("condition (31): ||gamma||_inf < lambda' k_min", _fmt(c31.get("holds"))),
        ("why (31) holds or fails", c31.get("explanation", "-")),
    ]
    if "predicted_px" in b39:
        rows += [
            (
                "(39) predicted bound on ||e||",
                f"{_fmt(b39['predicted_px'])} px ({_fmt(b39['predicted_units'])} units)",
            ),
            (
                "measured sup ||e|| after t1",
                f"{_fmt(b39['measured_sup_px'])} px ({_fmt(b39['measured_sup_units'])} units)",
            ),
            ("(39) holds", _fmt(b39["holds"])),
        ]
    if "varsigma" in l2:
        rows += [
            ("varsigma, zeta of (42)", f"{_fmt(l2['varsigma'])}, {_fmt(l2['zeta'])}"),
            (
                "measured int ||e||^2 / int ||gamma||^2 vs varsigma^2",
                f"{_fmt(l2['measured_ratio'])} vs {_fmt(l2['varsigma_squared'])}",
            ),
            (
                "(42): int ||e||^2 <= varsigma^2 int ||gamma||^2 + zeta",
                f"{_fmt(l2['integral_error_sq'])} <= {_fmt(l2['rhs'])}: {_fmt(l2['holds'])}",
            ),
        ]
    rows += _passivity_rows(r, "true state")
    rows += _passivity_rows(r["passivity_controller_signals"], "controller's signals, diagnostic")
    lines = [
        f"# Robustness and L2-gain analysis: {r['scenario']} ({r['robot']})",
        "",
        f"Log: `{r['log']}`. Controller unit: {r['feature_scale_px']:g} px; "
        f"epsilon = {r['epsilon']:g}; t1 rule: {r['t1_rule']}.".replace("||", "‖"),
        "",
        "| quantity | value |",
        "|---|---|",
        *(f"| {q} | {v} |".replace("||", "‖") for q, v in rows),
    ]
    for part in (c31, b39, l2):
        if part and "reason" in part:
            lines += ["", f"Note: {part['reason']}."]
            break
    lines += [
        "",
        "gamma = J_o (pdot - phat_dot) covers the target-velocity estimation error only; the "
        "velocity-tracking error, camera sampling, latency and noise are further disturbances "
        "that the paper's bound does not include.",
        "",
        f"(9), (13)/(14) and (27) are evaluated on one consistent set of signals, the "
        f"{r['passivity_signals']}. The margin of (9) is V1(T), near zero once the error has "
        "converged; sampling and the integration at the log rate then decide its sign (see the "
        "identity residual). (14) with the smallest beta_1 of (13) is equivalent to (9); with "
        "beta_1 = 0 it assumes perfect velocity tracking, and (27) adds the velocity error's "
        "term. The rows marked diagnostic use the "
        f"{r['passivity_controller_signals']['signals']}: they mix signals of different "
        "instants and models, so the identity behind (9) does not hold for them.",
    ]
    return "\n".join(lines) + "\n"


def _passivity_rows(p: dict[str, Any], label: str) -> list[tuple[str, str]]:
    """Both sides of (9), (13)/(14) and (27) from one signal set."""
    p9, p14, p27 = p["passivity_9"], p["passivity_14"], p["passivity_27"]
    return [
        (f"(9), {label}: int nu^T (v + J# J_o pdot) dt >= -V1(0)",
         f"{_fmt(p9['lhs_integral_nu_input'])} >= {_fmt(p9['rhs_minus_V1_0'])}: "
         f"{_fmt(p9['holds'])}"),
        (f"V1(T) - V1(0); identity residual, {label}",
         f"{_fmt(p9['V1_T_minus_V1_0'])}; {_fmt(p9['identity_residual'])}"),
        (f"(13)/(14), {label}: int ||nu||^2 dt <= beta = V1(0) + beta_1",
         f"{_fmt(p14['lhs_integral_nu_feedback'])} <= {_fmt(p14['rhs_beta'])} "
         f"(beta_1 = {_fmt(p14['beta_1'])}): {_fmt(p14['holds'])}"),
        (f"(14) with beta_1 = 0, {label}: int ||nu||^2 dt <= V1(0)",
         f"{_fmt(p14['lhs_integral_nu_feedback'])} <= {_fmt(p14['perfect_tracking_rhs_V1_0'])}: "
         f"{_fmt(p14['holds_with_beta_1_zero'])}"),
        (f"(27), {label}: int ||nu||^2 dt <= V1(0) + int nu^T (v - u) dt",
         f"{_fmt(p27['lhs_integral_nu_feedback'])} <= {_fmt(p27['rhs'])}: {_fmt(p27['holds'])}"),
    ]  # fmt: skip
