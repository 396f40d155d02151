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

from pbvs_pin.sim.scenario import OBSTACLE_KINDS, Scenario
from pbvs_pin.sim.sections import SECTIONS
from pbvs_pin.study.sweep.spec import SWEEP_DEFAULTS, SWEEP_KEY_DOCS
from pbvs_pin.toml_keys import keys_of

REPO_ROOT = Path(__file__).resolve().parents[1]

BUILD_OUTPUT: dict[str, str] = {}
"""What the build of the ``site`` fixture printed."""


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
    BUILD_OUTPUT["stdout"] = result.stdout
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
        "pbvs_pin.model.robot.MobileManipulator",
    ):
        assert f'id="{name}"' in raw, name
    text = page_text(site, "api.html")
    assert "Returns" in text and "Raises" in text  # napoleon turned Google sections into fields


def test_the_api_reference_puts_the_public_names_first_and_internals_apart(site):
    import pbvs_pin

    api, internals = (site / "api.html").read_text(), (site / "internals.html").read_text()
    for name in pbvs_pin.__all__:
        obj = getattr(pbvs_pin, name)
        if isinstance(obj, type) or callable(obj):
            target = f"{obj.__module__}.{obj.__qualname__}"
            assert f'id="{target}"' in api, target
            assert f'id="{target}"' not in internals, target  # documented once, publicly
    assert 'id="pbvs_pin.toml_keys.keys_of"' in internals


def test_the_index_leads_to_every_section():
    index = (REPO_ROOT / "docs" / "index.rst").read_text()
    for caption in ("Start", "Guides", "Theory and design", "Reference"):
        assert f":caption: {caption}" in index
    for page in (
        "getting_started", "gallery", "own_robot", "controller", "scenarios", "faults",
        "analysis", "sweeps", "theory", "design", "style", "api", "internals",
        "bad_input", "zoo", "rendered_camera", "mutation", "ros2",
    ):  # fmt: skip
        assert re.search(rf"^   {page}$", index, re.M), page


def test_the_mutation_page_names_tests_that_exist():
    """Each survivor's killing test on docs/mutation.md is a test of that file."""
    text = (REPO_ROOT / "docs" / "mutation.md").read_text()
    tests = set(re.findall(r"`tests/(\w+\.py)::(\w+)`", text))
    assert len(tests) >= 5
    for file, test in sorted(tests):
        source = (REPO_ROOT / "tests" / file).read_text()
        assert re.search(rf"^def {test}\(", source, re.M), f"tests/{file}::{test}"


def test_the_theory_map_names_code_and_tests_that_exist():
    """Every importable name and every ``tests/FILE::TEST`` on the theory map exists."""
    import importlib

    text = (REPO_ROOT / "docs" / "theory.md").read_text()
    names = set(re.findall(r"`(pbvs_pin(?:\.\w+)+)`", text))
    tests = set(re.findall(r"`tests/(\w+\.py)::(\w+)`", text))
    assert len(names) >= 20 and len(tests) >= 25
    for dotted in sorted(names):
        parts = dotted.split(".")
        for cut in range(len(parts), 0, -1):  # the longest importable module, then attributes
            try:
                obj = importlib.import_module(".".join(parts[:cut]))
            except ImportError:
                continue
            for attribute in parts[cut:]:
                obj = getattr(obj, attribute)
            break
    for file, test in sorted(tests):
        source = (REPO_ROOT / "tests" / file).read_text()
        assert re.search(rf"^def {test}\(", source, re.M), f"tests/{file}::{test}"
    for equation in ("(1)", "(2)", "(3)", "(7)", "(9)", "(10)", "(14)", "(16)", "(17)", "(19)",
                     "(20)", "(27)", "(30)", "(31)", "(39)"):  # fmt: skip
        assert f"**{equation}" in text or f", {equation}**" in text, equation


JS_BROKEN = """() => {
    const images = [...document.images].filter(i => !i.complete || i.naturalWidth === 0)
        .map(i => i.getAttribute('src'));
    const links = [...document.querySelectorAll('a[href]')].map(a => a.href)
        .filter(h => h.startsWith('file://'));
    return {images, links, title: document.title,
            text: document.body.innerText.length};
}"""


def test_every_page_renders_with_no_broken_image_or_link(site):
    """Each page opens in Chromium; every image loads, every local link reaches a file and,
    with a fragment, an element of that id."""
    from urllib.parse import unquote, urlparse

    from browser import chromium

    pages = sorted(p for p in site.rglob("*.html") if "_static" not in p.parts)
    assert len(pages) >= 20
    anchors: dict[Path, set[str]] = {}

    def ids(path: Path) -> set[str]:
        if path not in anchors:
            anchors[path] = set(re.findall(r'id="([^"]+)"', path.read_text()))
        return anchors[path]

    with chromium() as browser:
        tab = browser.new_page()
        errors: list[str] = []
        tab.on("pageerror", lambda e: errors.append(str(e)))
        for page in pages:
            tab.goto(page.as_uri())
            found = tab.evaluate(JS_BROKEN)
            assert not found["images"], (page.name, found["images"])
            assert found["text"] > 50, page.name  # the page has content
            for link in found["links"]:
                parsed = urlparse(link)
                target = Path(unquote(parsed.path))
                assert target.exists(), (page.name, link)
                if parsed.fragment and target.suffix == ".html":
                    assert unquote(parsed.fragment) in ids(target), (page.name, link)
        assert not errors, errors


JS_MATH = """() => MathJax.startup.promise.then(() => ({
    math: document.querySelectorAll('.math').length,
    typeset: document.querySelectorAll('.math mjx-container').length,
    glyphs: document.querySelectorAll('mjx-container mjx-c').length,
    width: Math.min(...[...document.querySelectorAll('mjx-container')]
        .map(e => e.getBoundingClientRect().width)),
    text: document.body.innerText,
}))"""


def test_equations_are_typeset_offline(site):
    """The docstrings' equations are typeset by the MathJax copied into the site: every script
    is local, a page opened with all network refused shows MathJax's output for each equation
    and no raw TeX."""
    from browser import chromium

    for page in sorted(p for p in site.rglob("*.html") if "_static" not in p.parts):
        scripts = re.findall(r'<script[^>]*\bsrc="([^"]+)"', page.read_text())
        assert not [s for s in scripts if "://" in s or s.startswith("//")], (page.name, scripts)
    assert (site / "_static" / "mathjax" / "tex-chtml.js").is_file()
    with chromium() as browser:
        context = browser.new_context()
        remote: list[str] = []

        def local_only(route):
            if route.request.url.startswith("file://"):
                route.continue_()
            else:
                remote.append(route.request.url)
                route.abort()

        context.route("**/*", local_only)
        tab = context.new_page()
        errors: list[str] = []
        tab.on("pageerror", lambda e: errors.append(str(e)))
        tab.on("console", lambda m: m.type == "error" and errors.append(m.text))
        tab.goto((site / "api.html").as_uri())
        tab.wait_for_function("() => window.MathJax && MathJax.startup", timeout=30_000)
        found = tab.evaluate(JS_MATH)
    assert found["math"] >= 5 and found["typeset"] == found["math"], found["math"]
    assert found["glyphs"] >= 3 * found["math"] and found["width"] > 0  # glyphs drawn
    for tex in ("\\(", "\\[", "\\frac", "\\begin"):
        assert tex not in found["text"], tex
    assert not remote and not errors, (remote, errors)


QUICK_START = (
    "pip install -c constraints.txt . && pbvs-pin reproduce --out results\n"
    "pip install -c constraints.txt '.[test,ros]' && ruff check pbvs_pin tests examples && python -m pytest -q -n auto --dist loadfile\n"
)


def test_the_readme_is_a_front_door():
    """At most 200 lines; the two quick-start commands; a picture; every local link resolves."""
    readme = (REPO_ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 200
    assert f"```bash\n{QUICK_START}```" in readme
    ci = (REPO_ROOT / ".ci" / "run").read_text().replace("pip install -q ", "pip install ")
    assert QUICK_START.splitlines()[1] in ci  # CI runs the README's test command
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", readme)
    local = [link for link in links if "://" not in link]
    assert any(link.endswith(".png") for link in local)
    assert len(local) >= 10
    for link in local:
        assert (REPO_ROOT / link).exists(), link


def test_array_arguments_show_as_arraylike_not_its_expansion(site):
    text = page_text(site, "api.html")
    assert "points ( numpy.typing.ArrayLike )" in " ".join(text.split())
    assert "_SupportsArray" not in text and "_NestedSequence" not in text


def test_the_build_says_what_it_did(site):
    """What it built, where, and that it built without a warning (the fixture's own run)."""
    printed = BUILD_OUTPUT["stdout"].splitlines()
    assert printed[0].startswith("building ") and f"into {site}" in printed[0]
    assert "4 generated: api.rst, internals.rst, scenario_keys.rst, sweep_keys.rst" in printed[0]
    pages = len(list(site.glob("*.html")))
    assert printed[-1] == (
        f"documentation built: {pages} HTML pages, no warning; open {site / 'index.html'}"
    )
