"""Run the four experiments with the rendered camera on both plants; rewrite the docs' table.

Run: ``python tools/rendered_results.py [docs/rendered_camera.rst]`` (about 5 minutes of
simulation; ``MUJOCO_GL=egl`` is set when not given). The reference robot's four shipped
experiments with ``camera.model = "rendered"``, each on the Pinocchio and the MuJoCo plant;
the table between :data:`pbvs_pin.study.report.RENDERED_BEGIN` and ``RENDERED_END`` is replaced by
:func:`pbvs_pin.study.report.rendered_results` of their summaries. ``tests/test_render.py`` checks
Experiment 1's rows against fresh runs.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before MuJoCo is imported

import sys
from pathlib import Path

from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.metrics import summarize
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.study.report import RENDERED_BEGIN, RENDERED_END, readme_block, rendered_results
from pbvs_pin.study.zoo import ENGINES, EXPERIMENTS


def rendered_summary(experiment: str, engine: str) -> dict:
    """The summary of ``experiment`` with the rendered camera on plant ``engine``."""
    keys = {"camera.model": "rendered", "plant.engine": engine}
    return summarize(simulate(load_scenario(experiment).with_values(**keys)))


def main() -> None:
    """Run the experiments and rewrite the page's generated table."""
    page = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/rendered_camera.rst")
    summaries = []
    for experiment in EXPERIMENTS:
        for engine in ENGINES:
            print(f"{experiment} on the {engine} plant ...", flush=True)
            summaries.append(rendered_summary(experiment, engine))
    text = page.read_text()
    block = readme_block(text, RENDERED_BEGIN, RENDERED_END)
    page.write_text(text.replace(block, rendered_results(summaries)))


if __name__ == "__main__":
    main()
