"""The documentation builds with every Sphinx warning an error, offline, and is complete.

The key references are generated from the schema, so each key of every scenario table and of
the sweep spec must appear on its page; the API reference must carry the public façade.
"""

import html
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from pbvs_pin.sim.keys import keys_of
from pbvs_pin.sim.scenario import OBSTACLE_KINDS, Scenario
from pbvs_pin.sim.sections import SECTIONS
from pbvs_pin.sweep.spec import SWEEP_DEFAULTS, SWEEP_KEY_DOCS

REPO_ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("html")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO_ROOT), env.get("PYTHONPATH", "")])
    result = subprocess.run(
        [sys.executable, str(REPO_ROOT / "docs" / "build.py"), str(out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert result.returncode == 0, (result.stdout + result.stderr)[-5000:]
    assert "WARNING" not in result.stderr
    return out


def page_text(site: Path, name: str) -> str:
    return html.unescape(re.sub(r"<[^>]+>", " ", (site / name).read_text()))


def test_every_scenario_key_is_documented(site):
    text = page_text(site, "scenario_keys.html")
    for cls in (Scenario, *SECTIONS):
        if cls.TABLE:
            assert f"[{cls.TABLE}]" in text
        for spec in keys_of(cls):
            assert re.search(rf"\b{spec.name}\b", text), f"{cls.TABLE}.{spec.name}"
            assert spec.metadata["doc"].split("[")[0].strip()[:30] in text
    for kind in OBSTACLE_KINDS:
        assert f'kind = "{kind}"' in text


def test_every_sweep_key_is_documented(site):
    text = page_text(site, "sweep_keys.html")
    assert set(SWEEP_KEY_DOCS) == set(SWEEP_DEFAULTS)
    for name in SWEEP_DEFAULTS:
        assert re.search(rf"\b{name}\b", text)
    for table in ("[sweep]", "[fixed]", "[grid]", "[random]"):
        assert table in text


def test_the_api_reference_documents_the_public_api(site):
    raw = (site / "api.html").read_text()
    for name in (
        "pbvs_pin.controller.Controller",
        "pbvs_pin.controller.Controller.step",
        "pbvs_pin.sim.loop.simulate",
        "pbvs_pin.sim.scenario.load_scenario",
        "pbvs_pin.robot.MobileManipulator",
    ):
        assert f'id="{name}"' in raw, name
    text = page_text(site, "api.html")
    assert "Returns" in text and "Raises" in text  # napoleon turned Google sections into fields
