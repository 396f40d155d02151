"""Running a configuration once and finding its figure in the docs' prose.

The generated blocks (the README's results table, the gallery's MuJoCo table) are checked by
``test_experiments.py`` and ``test_mujoco_acceptance.py``. The figures in the prose of the docs
pages are checked by the tests using this module: each runs the configuration its sentence
names, formats the figure as the page writes it and looks for the sentence on its page. When
one fails, the behaviour changed: measure again and update the sentence (or the conclusion
drawn from it).

A figure found on its page only shows that the page was updated. Each test also bounds its
figures by what the sentence concludes from them, independently of the page: the report's
3 px oscillation flag (:data:`OSCILLATION_FLAG_PX`), the loop-gain margin, one run against
another ("prediction lowers it", "the home does better").

The tests are in ``test_readme_numbers*.py``, split in three files, each run on one parallel
worker (pytest-xdist ``--dist loadfile``): the runs a file shares are made once.
"""

from __future__ import annotations

import functools

import numpy as np
from conftest import REPO_ROOT

from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.metrics import summarize
from pbvs_pin.sim.scenario import load_scenario


def page_text(name: str) -> str:
    """``docs/NAME.md`` with every run of whitespace (line breaks included) made one space."""
    return " ".join((REPO_ROOT / "docs" / f"{name}.md").read_text().split())


NET_OFF = 1e6
"""A loop-gain margin the net never reaches: the net switched off."""

IDEALISED = {
    "sensing.exact": True, "camera.latency": 0.0, "laser.range_noise": 0.0,
    "laser.range_resolution": 0.0, "estimator.predict": False,
}  # fmt: skip
"""The old idealisation: exact state, no latency, an exact laser, no prediction."""

PAPERS_LAW = {"controller.feedback": "transpose"}
"""The paper's feedback ``-J^T K_c e`` (the default is the balanced law): for the figures about
its loop gain and the net that caps it."""

EXPERIMENTS = ("experiment1", "experiment2", "experiment3", "experiment4")

OSCILLATION_FLAG_PX = 3.0
"""The report flags an oscillation above 0.5 Hz of more than 3 px RMS."""


@functools.cache
def _run(experiment: str, values: tuple) -> tuple[dict, dict[str, np.ndarray]]:
    log = simulate(load_scenario(experiment).with_values(**dict(values)))
    t = log["t"]
    final = t >= t[-1] - 5.0
    n_arm = len(log.meta["posture_target"])
    figures = {
        "arm_speed_final_window": float(np.max(np.abs(log["v"][final][:, -n_arm:]))),
        "upright_min_deg": float(np.degrees(np.nanmin(log["upright_angle"]))),
        "gain_limited": float(np.mean(log["gain_limited"])),
        "largest_gain": float(np.nanmax(log["loop_gain"])),
    }
    return summarize(log), figures


def run(experiment: str, **values: object) -> tuple[dict, dict[str, float]]:
    """The run's summary and a few figures of its log, computed once per configuration."""
    hashable = {key: tuple(v) if isinstance(v, list) else v for key, v in values.items()}
    return _run(experiment, tuple(sorted(hashable.items())))


def stated(sentence: str, page: str = "departures") -> None:
    assert sentence in page_text(page), f"docs/{page}.md no longer says {sentence!r}: measure again"
