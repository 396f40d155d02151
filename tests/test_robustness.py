"""The robustness map (issue 13, item 6): the breaking-point rule and the map's rows."""

from __future__ import annotations

import math

import pytest

from pbvs_pin.study.robustness import (
    VARIANTS,
    breaking_point,
    load_map,
    map_path,
    map_section,
    plot_map,
    run_map,
)


def _row(size, variant, error, lost=False):
    return {"fault": "noise", "unit": "px", "field": "camera.noise_px", "size": size,
            "variant": variant, "error_px": error, "lost": lost,
            "broken": lost or error > 10.0}  # fmt: skip


SYNTHETIC = [
    _row(1.0, "without", 2.0), _row(2.0, "without", 12.0), _row(4.0, "without", 9.0),
    _row(1.0, "with", 1.0), _row(2.0, "with", 3.0), _row(4.0, "with", 5.0, lost=True),
]  # fmt: skip
"""Hand-made table: without breaks first at 2 px (12 px > 10, even though 4 px is back under),
with only at 4 px, by losing the target at 5 px."""


def test_breaking_point_is_the_first_size_above_the_threshold_or_lost():
    assert breaking_point(SYNTHETIC, "noise", "without") == 2.0
    assert breaking_point(SYNTHETIC, "noise", "with") == 4.0
    assert breaking_point(SYNTHETIC[:1] + SYNTHETIC[3:5], "noise", "with") is None
    table = map_section(SYNTHETIC)
    assert "| noise | 1, 2, 4 px | 2 px | 4 px |" in table


def test_the_shipped_spec_covers_the_four_faults():
    spec = load_map()
    fields = [fault["field"] for fault in spec["fault"]]
    assert fields == [
        "camera.latency",
        "camera.noise_px",
        "camera.drop_probability",
        "camera.occlusion_duration",
    ]
    assert spec["map"]["compensation"]["estimator.predict"] is True
    assert all(fault["sizes"] == sorted(fault["sizes"]) for fault in spec["fault"])


@pytest.fixture(scope="module")
def small_map():
    """Latency 0 and 0.2 s on 6 s of Experiment 1 (the last 5 s window then starts at 1 s)."""
    spec = load_map()
    spec["fault"] = [dict(spec["fault"][0], sizes=[0.0, 0.2])]
    return run_map(spec, duration=6.0)


def test_the_map_runs_each_size_without_and_with_compensation(small_map, tmp_path):
    assert [(r["size"], r["variant"]) for r in small_map] == [
        (0.0, "without"), (0.0, "with"), (0.2, "without"), (0.2, "with"),
    ]  # fmt: skip
    assert all(math.isfinite(r["error_px"]) and r["error_px"] > 0 for r in small_map)
    for r in small_map:
        assert r["broken"] == (r["lost"] or r["error_px"] > 10.0)
    late = {r["variant"]: r["error_px"] for r in small_map if r["size"] == 0.2}
    assert late["with"] < late["without"]  # the prediction removes most of the delay's effect
    path = plot_map(small_map, tmp_path / "robustness.png")
    assert path.stat().st_size > 10_000
    assert set(VARIANTS) == {r["variant"] for r in small_map}


def test_sweep_names_the_shipped_map_but_not_an_ordinary_spec(tmp_path):
    assert map_path("robustness") is not None
    assert map_path("target_speed") is None
    assert map_path(tmp_path / "missing.toml") is None
