"""The robustness map: each camera fault raised alone until the loop breaks.

The map is read from the shipped spec ``pbvs_pin/study/sweep/specs/robustness.toml``: a base
scenario, the compensation (``[map.compensation]``: prediction along eq. (3), a hold through lost
frames, feature smoothing), the values without it (``[map.without]``: the paper's estimator) and
one ``[[fault]]`` block per fault with its field and sizes. Each size is run twice, without and
with the compensation. A run is *broken* when the max ``|xi_true - xi_d|`` over the last
``window_s`` seconds is above ``threshold_px``, or the target is lost in that window.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.study.sweep.spec import sweep_dir

VARIANTS = ("without", "with")
"""The two variants of every size: without and with the compensation of the spec."""


def map_path(name_or_path: str | Path) -> Path | None:
    """The robustness spec a ``pbvs-pin sweep`` argument names (shipped name or path).

    None when it names no readable TOML file with a ``[map]`` table (an ordinary sweep spec,
    whose errors :func:`pbvs_pin.study.sweep.spec.load_sweep` then reports).
    """
    try:
        shipped = sweep_dir() / f"{name_or_path}.toml"
        path = shipped if shipped.is_file() else Path(name_or_path)
        with open(path, "rb") as file:
            return path if "map" in tomllib.load(file) else None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):  # a name too long, too
        return None


def load_map(path: Path | None = None) -> dict[str, Any]:
    """The robustness spec (default: the shipped ``sweep/specs/robustness.toml``) as a dict."""
    with open(path or sweep_dir() / "robustness.toml", "rb") as file:
        return tomllib.load(file)


def write_map(
    out: Path, path: Path | None = None, echo: Callable[[str], None] | None = None
) -> tuple[Path, str]:
    """Run the map of ``path`` (default: the shipped one); write ``out/robustness.png``.

    Returns:
        The figure's path and the markdown section (:func:`map_section`).
    """
    spec = load_map(path)
    rows = run_map(spec, echo=echo)
    out.mkdir(parents=True, exist_ok=True)
    if echo is not None:
        echo(f"  writing {out / 'robustness.png'}")
    figure = plot_map(rows, out / "robustness.png", spec["map"]["threshold_px"])
    return figure, map_section(rows)


def final_error(log: Any, window_s: float) -> tuple[float, bool]:
    """Max ``|xi_true - xi_d|`` over the last ``window_s`` s [px]; whether the target was lost.

    A window whose errors are all NaN counts as ``inf``; ``lost`` is any lost sample in it.
    """
    t = np.asarray(log["t"])
    final = t >= t[-1] - window_s
    error = np.abs(np.asarray(log["xi_true"])[final] - np.asarray(log["xi_d"])[final])
    worst = float(np.nanmax(error)) if np.isfinite(error).any() else math.inf
    return worst, bool(np.any(np.asarray(log["target_lost"], dtype=bool)[final]))


def run_map(
    spec: dict[str, Any] | None = None,
    duration: float | None = None,
    echo: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """Run every fault size without and with the compensation.

    Args:
        spec: The map (see :func:`load_map`); the shipped one by default.
        duration: Run length [s]; the base scenario's when None.
        echo: Told one line per run.

    Returns:
        One row per run: ``fault``, ``unit``, ``size``, ``variant`` (``"without"``/``"with"``),
        ``field``, ``error_px`` (max over the last window), ``lost`` and ``broken``.
    """
    spec = spec or load_map()
    setup = spec["map"]
    base = load_scenario(setup["scenario"])
    if duration is not None:
        base = base.with_values(duration=duration)
    rows = []
    for fault in spec["fault"]:
        for size in fault["sizes"]:
            for variant in VARIANTS:
                values = dict(fault.get("fixed", {}), **{fault["field"]: size})
                values.update(setup["compensation" if variant == "with" else "without"])
                log = simulate(base.with_values(**values), progress=False)
                error, lost = final_error(log, setup["window_s"])
                broken = lost or not error <= setup["threshold_px"]
                rows.append(
                    {"fault": fault["name"], "unit": fault["unit"], "field": fault["field"],
                     "size": size,
                     "variant": variant, "error_px": error, "lost": lost, "broken": broken}
                )  # fmt: skip
                if echo is not None:
                    echo(
                        f"  {fault['name']} {size:g} {fault['unit']}, {variant} fault handling: "
                        f"{error:.3g} px{' (target lost)' if lost else ''}"
                    )
    return rows


def breaking_point(rows: list[dict[str, Any]], fault: str, variant: str) -> float | None:
    """The smallest size of ``fault`` at which the ``variant`` run is broken (None: never)."""
    broken = [r["size"] for r in rows if r["fault"] == fault and r["variant"] == variant
              and r["broken"]]  # fmt: skip
    return min(broken) if broken else None


def _faults(rows: list[dict[str, Any]]) -> list[str]:
    return list(dict.fromkeys(r["fault"] for r in rows))


def _break_label(rows: list[dict[str, Any]], fault: str, variant: str) -> str:
    """Where ``variant`` breaks under ``fault``: ``"4 px"``, or ``"not up to 8 px"``."""
    unit = next(r["unit"] for r in rows if r["fault"] == fault)
    first = breaking_point(rows, fault, variant)
    if first is None:
        top = max(r["size"] for r in rows if r["fault"] == fault)
        return f"not up to {top:g} {unit}".rstrip()
    return f"{first:g} {unit}".rstrip()


MAP_STYLES = {
    "without": ("tab:red", "o", "without fault handling"),
    "with": ("tab:blue", "s", "with fault handling (predict, hold, smooth)"),
}
"""Colour, marker and label of each variant in :func:`plot_map`."""


def plot_map(rows: list[dict[str, Any]], path: Path, threshold_px: float = 10.0) -> Path:
    """Draw the map to ``path``: one panel per fault, error [px] against the fault's size.

    Both variants per panel, the threshold drawn, each variant's breaking point marked by a
    dotted line and named in the panel's title, lost-target runs by a cross; log-y; one legend
    for the figure.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import LogFormatter

    faults = _faults(rows)
    columns = min(2, len(faults))
    grid = (math.ceil(len(faults) / columns), columns)
    fig, axes = plt.subplots(*grid, figsize=(6.0 * columns, 4.6 * grid[0]), squeeze=False)
    for ax in axes.flat[len(faults) :]:
        ax.set_visible(False)
    for ax, fault in zip(axes.flat, faults, strict=False):
        unit, field = next((r["unit"], r["field"]) for r in rows if r["fault"] == fault)
        breaks = []
        for variant in VARIANTS:
            color, marker, label = MAP_STYLES[variant]
            mine = [r for r in rows if r["fault"] == fault and r["variant"] == variant]
            errors = [min(r["error_px"], 1e4) for r in mine]
            ax.plot([r["size"] for r in mine], errors, marker=marker, color=color, label=label)
            lost = [(r["size"], min(r["error_px"], 1e4)) for r in mine if r["lost"]]
            if lost:
                ax.scatter(*zip(*lost, strict=True), marker="x", s=80, color="k", zorder=3,
                           label="target lost in the last 5 s")  # fmt: skip
            first = breaking_point(rows, fault, variant)
            if first is not None:
                ax.axvline(first, color=color, linestyle=":", linewidth=1.5)
            breaks.append(f"{variant}: {_break_label(rows, fault, variant)}")
        ax.axhline(threshold_px, color="gray", linestyle="--", label=f"{threshold_px:g} px limit")
        ax.set_yscale("log")
        # plain numbers (2, 30, 500) rather than 2x10^0 on the log axis
        ax.yaxis.set_major_formatter(LogFormatter(labelOnlyBase=False))
        ax.yaxis.set_minor_formatter(LogFormatter(labelOnlyBase=False, minor_thresholds=(2, 0.4)))
        ax.set_title(f"{fault}\nbreaks (dotted) {'; '.join(breaks)}")
        ax.set_xlabel(f"{field} [{unit or '-'}]")
        ax.set_ylabel("max |error| over the last 5 s [px]")
        ax.grid(True, which="both", alpha=0.3)
    legend = {}
    for ax in axes.flat[: len(faults)]:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            legend.setdefault(label, handle)
    fig.legend(legend.values(), legend.keys(), loc="lower center", ncol=2, fontsize=9)
    fig.suptitle("Robustness map, Experiment 1")
    fig.tight_layout(h_pad=2.0, rect=(0.0, 0.07, 1.0, 1.0))
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def map_section(rows: list[dict[str, Any]], figure: str = "robustness.png") -> str:
    """The report's section: the figure and a table of breaking points per fault."""
    lines = [
        "",
        "## Robustness map: each camera fault alone, Experiment 1",
        "",
        "Each fault raised alone (sizes in `pbvs_pin/study/sweep/specs/robustness.toml`), "
        "without and with the estimator's fault handling (prediction along eq. (3), 1.5 s hold, "
        "smoothing 0.2, "
        "noise-adaptive velocity filter; "
        "not the dynamic compensation of eq. (20)). Broken: max "
        "|error| over the last 5 s above 10 px, or the target lost then.",
        "",
        f"![robustness map]({figure})",
        "",
        "| fault | sizes | breaks without fault handling | breaks with fault handling |",
        "|---|---|---|---|",
    ]
    for fault in _faults(rows):
        unit = next(r["unit"] for r in rows if r["fault"] == fault)
        sizes = sorted({r["size"] for r in rows if r["fault"] == fault})
        cells = [_break_label(rows, fault, variant) for variant in VARIANTS]
        lines.append(
            f"| {fault} | {(', '.join(f'{s:g}' for s in sizes) + ' ' + unit).rstrip()} | "
            + " | ".join(cells)
            + " |"
        )
    return "\n".join(lines) + "\n"
