"""The report of ``pbvs-pin reproduce``: claims with their rules, flagged rows, README figures.

Every figure comes from a run's ``summary.json`` (:func:`pbvs_pin.sim.metrics.summarize`) or
its analysis (:func:`pbvs_pin.analysis.analyze_log`); nothing is typed in by hand. A paper's
claim is marked met only when the figures named by its rule (:data:`CLAIMS`) meet it. Every
run's row carries the flags of :mod:`pbvs_pin.sim.metrics` (target lost, joints past limits,
collision, sustained oscillation) and its saturation fractions, so no row hides a failure.

The README's results table is :func:`readme_results` of the reference runs, between
:data:`README_BEGIN` and :data:`README_END`, and the gallery's MuJoCo table
:func:`readme_engines`; ``python -m pbvs_pin.report README.md docs/gallery.md RESULTS`` rewrites
them from the ``summary.json`` files of a ``reproduce`` output folder, and tests check them
against fresh runs. The report opens with its findings (:mod:`pbvs_pin.findings`).
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pbvs_pin.exceptions import PbvsError
from pbvs_pin.sim.metrics import OSCILLATION_CUTOFF_HZ, OSCILLATION_FLAG_PX


@dataclass(frozen=True)
class Claim:
    """One of the paper's claims (§5) and the rule that decides whether a run meets it.

    Attributes:
        text: The paper's claim.
        rule: The rule, in words, as the report prints it.
        check: The rule on a run's summary.
    """

    text: str
    rule: str
    check: Callable[[dict[str, Any]], bool]


SUSTAINED_OSCILLATION_PX = 3.0
"""Largest RMS of the error's part above the oscillation cut-off, over any 5 s window [px]."""

JOINT_LIMIT_TOLERANCE = 0.01
"""Largest excursion of an arm joint past its position limit [rad or m]."""

SOUND_RULE = (
    "target never lost; no joint more than "
    f"{JOINT_LIMIT_TOLERANCE:g} past its limits; no sustained oscillation (the error's part "
    f"above {OSCILLATION_CUTOFF_HZ:g} Hz < {SUSTAINED_OSCILLATION_PX:g} px RMS over every 5 s "
    "window)"
)
"""What every claim requires besides its own figures: a run that holds only through an
artefact (a lost target, a joint past its stop, an oscillation inside a loose bound) is not
a pass."""


def _sound(s: dict[str, Any]) -> bool:
    """:data:`SOUND_RULE` on a run's summary."""
    violation = s["joint_limit_violation"] or 0.0
    return (
        s["target_lost_samples"] == 0
        and violation <= JOINT_LIMIT_TOLERANCE
        and s["oscillation_rms_px"] < SUSTAINED_OSCILLATION_PX
    )


def _bounded(s: dict[str, Any]) -> bool:
    """Max |error| after the transient below half the image height; clearance > 0."""
    clearance = s["min_clearance_m"]
    return (
        s["max_abs_error_after_transient_px"] < s["image_height_px"] / 2
        and (clearance is None or clearance > 0)
    )


CLAIMS = {
    "experiment1": Claim(
        "errors ultimately bounded, final max |error| < 8 px",
        f"max abs(e) over the last 5 s < 8 px; {SOUND_RULE}",
        lambda s: _sound(s) and s["max_abs_error_final_window_px"] < 8.0,
    ),
    "experiment2": Claim(
        "errors bounded while avoiding the obstacle; arm returns to max manipulability",
        "max abs(e) after 2 s < half the image height; min clearance > 0; arm within 0.1 rad of "
        f"theta_d over the last 5 s; last 5 s < 8 px; {SOUND_RULE}",
        lambda s: _sound(s)
        and _bounded(s)
        and s["posture_error_final_window_rad"] < 0.1
        and s["max_abs_error_final_window_px"] < 8.0,
    ),
    "experiment3": Claim(
        "errors bounded with a 20% kinematic model error (degraded but acceptable)",
        "max abs(e) after 2 s < half the image height; min clearance > 0; last 5 s < 12 px "
        f"(1.5 times Exp. 1's 8 px); {SOUND_RULE}",
        lambda s: _sound(s) and _bounded(s) and s["max_abs_error_final_window_px"] < 12.0,
    ),
    "experiment4": Claim(
        "errors converge to zero (perfect knowledge)",
        f"max abs(e) over the last 5 s < 0.5 px; {SOUND_RULE}",
        lambda s: _sound(s) and s["max_abs_error_final_window_px"] < 0.5,
    ),
}
"""The paper's claim for each experiment (§5) and its rule (the design notes, §4)."""

FLAG_RULES = (
    "Flags: *lost N from t s*: the target was out of view for N log samples, first at t; "
    "*joints +x*: an arm joint went x [rad or m] past its position limit; *collision c m*: "
    f"the platform's clearance went below 0; *oscillation a px*: the feature error's part "
    f"above {OSCILLATION_CUTOFF_HZ:g} Hz (4th-order zero-phase Butterworth high-pass after 2 s), "
    f"RMS over its worst 5 s window, is above {OSCILLATION_FLAG_PX:g} px. *u sat*: fraction of "
    "samples where the velocity limits cut the command (u scaled down, or v_ref clipped); "
    "*v_ref lim*: fraction "
    "where a component of the compensator's v_ref sits at its limit."
)
"""How each flag of a row is defined."""

README_BEGIN = "<!-- results: generated by pbvs_pin.report from a fresh reproduce -->"
README_END = "<!-- end of generated results -->"
ENGINES_BEGIN = "<!-- MuJoCo results: generated by pbvs_pin.report from a fresh reproduce -->"
ENGINES_END = "<!-- end of generated MuJoCo results -->"
RENDERED_BEGIN = (
    ".. rendered camera results: generated by tools/rendered_results.py from fresh runs"
)
RENDERED_END = ".. end of generated rendered camera results"
RENDERED_COLUMNS = (
    "experiment", "plant", "claim met", "max abs error, last 5 s [px]",
    "detection error RMS / max [px]", "frames missed", "flags",
)  # fmt: skip
"""Columns of :func:`rendered_results`."""


def claim_met(summary: dict[str, Any]) -> bool | None:
    """Whether a run meets its experiment's claim; None for a scenario without one."""
    claim = CLAIMS.get(summary["scenario"])
    return None if claim is None else bool(claim.check(summary))


def verdict(summary: dict[str, Any]) -> str:
    """``met (experiment1's rule)``, ``NOT met (...)``, or ``-`` for a scenario without a claim.

    The verdict names the rule it was judged by: a run on another robot, on another plant or
    with another law is judged by its experiment's rule (:data:`CLAIMS`).
    """
    met = claim_met(summary)
    if met is None:
        return "-"
    return f"{'met' if met else 'NOT met'} ({summary['scenario']}'s rule)"


def flags(summary: dict[str, Any]) -> list[str]:
    """What went wrong in a run (module docstring of :mod:`pbvs_pin.sim.metrics`)."""
    found = []
    if summary["target_lost_samples"]:
        found.append(
            f"lost {summary['target_lost_samples']} from {summary['target_lost_first_s']:.2f} s"
        )
    violation = summary.get("joint_limit_violation")
    if violation:
        found.append(f"joints +{violation:.3g}")
    clearance = summary["min_clearance_m"]
    if clearance is not None and clearance < 0:
        found.append(f"collision {clearance:.3f} m")
    if summary["oscillation_rms_px"] > OSCILLATION_FLAG_PX:
        found.append(
            f"oscillation {summary['oscillation_rms_px']:.1f} px from "
            f"{summary['oscillation_window_start_s']:.1f} s"
        )
    return found


RUN_HEADER = (
    "| robot | experiment | law | claim met | max abs error, last 5 s [px] | max abs error "
    "after 2 s [px] | RMS error after 2 s [px] | min clearance [m] | arm to theta_d, last 5 s "
    "[rad] | u sat | v_ref lim | flags |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|---|"
)
"""Header of :func:`run_row`'s table."""


def run_row(s: dict[str, Any]) -> str:
    """One run's row: its figures, whether it meets its claim, and every flag."""
    clearance = s["min_clearance_m"]
    return (
        f"| {s['robot']} | {s['scenario']} | {s['law']} | {verdict(s)} | "
        f"{s['max_abs_error_final_window_px']:.2f} | "
        f"{s['max_abs_error_after_transient_px']:.1f} | "
        f"{s['rms_error_after_transient_px']:.2f} | "
        f"{'-' if clearance is None else f'{clearance:.3f}'} | "
        f"{s['posture_error_final_window_rad']:.3f} | "
        f"{s['saturated_fraction']:.3f} | {s['v_ref_at_limit_fraction']:.3f} | "
        f"{'; '.join(flags(s)) or 'none'} |"
    )


def runs_table(summaries: list[dict[str, Any]]) -> str:
    """The table of :func:`run_row` for a list of runs."""
    return "\n".join([RUN_HEADER, *(run_row(s) for s in summaries)])


def claims_table() -> str:
    """Each experiment's claim beside the rule that decides it."""
    lines = [
        "| experiment | paper's claim | its rule: 'met' means all of this holds |",
        "|---|---|---|",
    ]
    lines += [
        f"| {name} | {c.text.replace('|', '&#124;')} | {c.rule} |" for name, c in CLAIMS.items()
    ]
    return "\n".join(lines)


COMPENSATION_MODES = ("off", "platform", "all")
"""Dynamic-compensation modes compared in the report (eq. 20)."""


def compensation_table(summaries: list[dict[str, Any]]) -> str:
    """Velocity-tracking and feature errors of each experiment under each compensation mode."""
    lines = [
        "| experiment | compensation | RMS of abs(v - u) | platform part | arm part | "
        "RMS error after 2 s [px] | max abs error, last 5 s [px] | flags |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for s in summaries:
        lines.append(
            f"| {s['scenario']} | {s['compensation']} | {s['velocity_tracking_rms']:.4f} | "
            f"{s['velocity_tracking_rms_platform']:.4f} | {s['velocity_tracking_rms_arm']:.4f} | "
            f"{s['rms_error_after_transient_px']:.2f} | "
            f"{s['max_abs_error_final_window_px']:.2f} | {'; '.join(flags(s)) or 'none'} |"
        )
    return "\n".join(lines)


ENGINE_ROBOTS = ("pioneer_cyton", "pioneer_ur5", "tiago")
"""Robots whose experiments ``reproduce`` also runs on the MuJoCo plant (wheels on a floor)."""

ENGINE_COLUMNS = (
    "robot", "experiment", "plant", "claim met", "max abs error, last 5 s [px]",
    "RMS error after 2 s [px]", "odometry drift at the end [m]",
    "heading drift at the end [deg]", "lateral slip RMS [m/s]", "yaw rate / wheels'",
    "real-time factor", "flags",
)  # fmt: skip
"""Columns of :func:`engines_table`."""


def engine_row(s: dict[str, Any], speed: bool = True) -> str:
    """One run's row of the two-plant comparison: error, odometry drift, slip, speed.

    Args:
        s: The run's summary.
        speed: Include the real-time factor (a wall-clock figure).
    """
    ratio = s["yaw_rate_ratio"]
    cells = [
        s["robot"], s["scenario"], s["engine"], verdict(s),
        f"{s['max_abs_error_final_window_px']:.2f}", f"{s['rms_error_after_transient_px']:.2f}",
        f"{s['odometry_drift_m']:.3f}", f"{math.degrees(s['odometry_drift_rad']):.2f}",
        f"{s['lateral_slip_rms_mps']:.4f}", "-" if ratio is None else f"{ratio:.2f}",
        *([f"{s['real_time_factor']:.0f}x"] if speed else []),
        "; ".join(flags(s)) or "none",
    ]  # fmt: skip
    return "| " + " | ".join(cells) + " |"


def engines_table(summaries: list[dict[str, Any]], speed: bool = True) -> str:
    """The runs of each robot and experiment on both plants, side by side.

    Args:
        summaries: The runs' summaries, in any order.
        speed: Include the real-time factor column.
    """
    columns = [c for c in ENGINE_COLUMNS if speed or c != "real-time factor"]
    order = {name: i for i, name in enumerate(CLAIMS)}
    rows = sorted(summaries, key=lambda s: (s["robot"], order.get(s["scenario"], 99), s["engine"]))
    return "\n".join(
        [
            "| " + " | ".join(columns) + " |",
            "|" + "---|" * len(columns),
            *(engine_row(s, speed) for s in rows),
        ]
    )


def readme_results(reference: list[dict[str, Any]]) -> str:
    """The README's results block (markers included) from the reference runs' summaries."""
    lines = [
        README_BEGIN,
        "| experiment | rule for the paper's claim | met | max abs error, last 5 s [px] | "
        "max abs error after 2 s [px] | min clearance [m] | arm to theta_d, last 5 s [rad] | "
        "V1 increase after 2 s | flags |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for s in reference:
        clearance = s["min_clearance_m"]
        lines.append(
            f"| {s['scenario']} | {CLAIMS[s['scenario']].rule} | "
            f"{'met' if claim_met(s) else 'NOT met'} | "
            f"{s['max_abs_error_final_window_px']:.2f} | "
            f"{s['max_abs_error_after_transient_px']:.1f} | "
            f"{'-' if clearance is None else f'{clearance:.3f}'} | "
            f"{s['posture_error_final_window_rad']:.3f} | "
            f"{s['storage_increase_after_transient']:.3g} | {'; '.join(flags(s)) or 'none'} |"
        )
    lines.append(README_END)
    return "\n".join(lines)


def readme_block(text: str, begin: str = README_BEGIN, end: str = README_END) -> str:
    """A generated block of a README's text (markers included).

    Raises:
        PbvsError: If the markers are missing.
    """
    start, stop = text.find(begin), text.find(end)
    if start < 0 or stop < start:
        raise PbvsError(f"README: expected the markers {begin!r} ... {end!r}")
    return text[start : stop + len(end)]


def readme_engines(mujoco: list[dict[str, Any]]) -> str:
    """The README's MuJoCo block (markers included) from the MuJoCo runs' summaries.

    The report's two-plant rows without the real-time factor (a wall-clock figure that no
    fresh run repeats), so that a test can compare the block with fresh runs.
    """
    return "\n".join([ENGINES_BEGIN, engines_table(mujoco, speed=False), ENGINES_END])


def rendered_results(summaries: list[dict[str, Any]]) -> str:
    """The rendered camera's results (markers included): an RST list-table of the runs.

    Args:
        summaries: Summaries of runs with ``camera.model = "rendered"``, in table order.
    """
    lines = [RENDERED_BEGIN, "", ".. list-table::", "   :header-rows: 1", ""]
    for cells in [RENDERED_COLUMNS, *map(_rendered_cells, summaries)]:
        lines += rst_row(cells)
    return "\n".join([*lines, "", RENDERED_END])


def rst_row(cells: Sequence[str]) -> list[str]:
    """One row of an RST list-table, as its lines."""
    return [f"   * - {cells[0]}"] + [f"     - {cell}" for cell in cells[1:]]


def _rendered_cells(s: dict[str, Any]) -> tuple[str, ...]:
    """One rendered run's cells of :func:`rendered_results`."""
    return (
        s["scenario"], s["engine"], verdict(s), f"{s['max_abs_error_final_window_px']:.3f}",
        f"{s['detection_error_rms_px']:.3f} / {s['detection_error_max_px']:.3f}",
        f"{s['detection_missed_frames']} of {s['detection_frames']}",
        "; ".join(flags(s)) or "none",
    )  # fmt: skip


def _summaries(paths: list[Path], results: Path) -> list[dict[str, Any]]:
    """The summaries at ``paths``, or a PbvsError naming the first one missing."""
    for path in paths:
        if not path.is_file():
            raise PbvsError(f"{path}: missing; run pbvs-pin reproduce --out {results} first")
    return [json.loads(path.read_text()) for path in paths]


def update_readme(readme: Path, results: Path) -> None:
    """Rewrite the generated blocks of a page from a ``reproduce`` folder's ``summary.json`` files.

    The results block from the reference runs; the MuJoCo block from the runs of
    :data:`ENGINE_ROBOTS` on the MuJoCo plant (``results/mujoco/ROBOT/EXPERIMENT``). A page
    holds either block or both (the README holds the results, ``docs/gallery.md`` both).

    Raises:
        PbvsError: If a summary is missing, or the page holds neither block.
    """
    text = readme.read_text()
    found = False
    if README_BEGIN in text:
        reference = _summaries([results / name / "summary.json" for name in CLAIMS], results)
        text = text.replace(readme_block(text), readme_results(reference))
        found = True
    if ENGINES_BEGIN in text:
        mujoco = _summaries(
            [results / "mujoco" / robot / name / "summary.json" for robot in ENGINE_ROBOTS
             for name in CLAIMS], results,
        )  # fmt: skip
        text = text.replace(readme_block(text, ENGINES_BEGIN, ENGINES_END), readme_engines(mujoco))
        found = True
    if not found:
        raise PbvsError(f"{readme}: expected the markers {README_BEGIN!r} or {ENGINES_BEGIN!r}")
    readme.write_text(text)


if __name__ == "__main__":  # python -m pbvs_pin.report README.md docs/gallery.md RESULTS
    for page in sys.argv[1:-1]:
        update_readme(Path(page), Path(sys.argv[-1]))
