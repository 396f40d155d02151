"""Headless-browser helpers shared by the visualisation tests.

Pages (a standalone replay from a ``file://`` URL, or a live meshcat server's ``http://`` URL)
are opened in Debian's Chromium (software WebGL through SwiftShader), driven by Playwright.
Nothing is skipped: if Chromium or Playwright is missing the tests fail and say how to install
them.

Requirements (no browser download, ever -- do NOT run ``playwright install``)::

    apt-get update && apt-get install -y chromium     # /usr/bin/chromium
    pip install playwright

The Chromium binary can be overridden with ``PBVS_CHROMIUM=/path/to/chromium``.
"""

from __future__ import annotations

import contextlib
import io
import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

CHROMIUM = os.environ.get("PBVS_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
INSTALL_HINT = (
    "Install the browser-test requirements with: `apt-get update && apt-get install -y chromium` "
    "(provides /usr/bin/chromium) and `pip install playwright`. "
    "Do NOT run `playwright install`: the test drives Debian's Chromium."
)
VIEWPORT = {"width": 800, "height": 600}

# --------------------------------------------------------------------------
# JavaScript run in the page
# --------------------------------------------------------------------------
# Look a node up WITHOUT creating it (SceneNode.find() creates missing nodes).
JS_NODE = """
function pbvsNode(path) {
    let node = window.viewer.scene_tree;
    for (const name of path.split('/').filter(s => s.length > 0)) {
        node = node.children[name];
        if (node === undefined) return null;
    }
    return node;
}
"""

# Every path must carry a loaded three.js object in its "<object>" child and
# the animation must have one action per animated path.
JS_READY = (
    "([paths, nActions]) => {"
    + JS_NODE
    + """
    if (!window.viewer || !window.viewer.animator) return false;
    if (window.viewer.animator.actions.length < nActions) return false;
    return paths.every(p => {
        const n = pbvsNode(p);
        return n !== null && n.children['<object>'] !== undefined
            && n.children['<object>'].object.type !== 'Group';
    });
}"""
)

JS_DESCRIBE = (
    "(paths) => {"
    + JS_NODE
    + """
    const out = {};
    for (const p of paths) {
        const n = pbvsNode(p);
        const o = n && n.children['<object>'] ? n.children['<object>'].object : null;
        let nvert = 0;
        if (o && o.geometry && o.geometry.attributes && o.geometry.attributes.position)
            nvert = o.geometry.attributes.position.count;
        out[p] = {found: n !== null, type: o ? o.type : null, vertices: nvert,
                  visible: o ? o.visible : null};
    }
    return out;
}"""
)

# Pause the animation, seek it to time t (seconds) and return world matrices
# (three.js Matrix4.elements, column-major) of the scene root and of each path's
# node (and of its "<object>" child).
JS_SEEK = (
    "([paths, t]) => {"
    + JS_NODE
    + """
    const a = window.viewer.animator;
    a.pause();
    a.seek(t);
    window.viewer.scene.updateMatrixWorld(true);
    const out = {scene: window.viewer.scene.matrixWorld.toArray(),
                 action_times: a.actions.map(x => x.time), nodes: {}, objects: {}};
    for (const p of paths) {
        const n = pbvsNode(p);
        out.nodes[p] = n.object.matrixWorld.toArray();
        const o = n.children['<object>'];
        out.objects[p] = o ? o.object.matrixWorld.toArray() : null;
    }
    return out;
}"""
)

# World matrices of the nodes of ``paths`` as they are now (no animation involved).
JS_MATRICES = (
    "(paths) => {"
    + JS_NODE
    + """
    window.viewer.scene.updateMatrixWorld(true);
    const out = {scene: window.viewer.scene.matrixWorld.toArray(), nodes: {}};
    for (const p of paths) {
        const n = pbvsNode(p);
        out.nodes[p] = n === null ? null : n.object.matrixWorld.toArray();
    }
    return out;
}"""
)

JS_SET_VISIBLE = (
    "([path, visible]) => {"
    + JS_NODE
    + """
    const n = pbvsNode(path);
    n.set_property('visible', visible);
    window.viewer.set_dirty();
    return n.object.visible;
}"""
)

JS_TWO_FRAMES = (
    "() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(() => r(true))))"
)


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------
def threejs_to_meshcat(page_matrix, scene_matrix) -> np.ndarray:
    """World matrix read in the page -> meshcat/Pinocchio world (Z-up)."""
    M = np.array(page_matrix, dtype=float).reshape(4, 4, order="F")
    S = np.array(scene_matrix, dtype=float).reshape(4, 4, order="F")
    return np.linalg.solve(S, M)


def launch(playwright):
    """Debian's Chromium, headless, or a test failure that says how to install it."""
    if not Path(CHROMIUM).exists():
        pytest.fail(f"Chromium not found at {CHROMIUM}. {INSTALL_HINT}")
    try:
        return playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
    except Exception as exc:  # pragma: no cover - environment problem
        pytest.fail(f"could not launch Chromium at {CHROMIUM}: {exc}\n{INSTALL_HINT}")


class Page:
    """An opened meshcat page (a file or a URL) plus the errors it reported."""

    def __init__(self, browser, where: Path | str):
        self.page = browser.new_page(viewport=VIEWPORT)
        self.errors: list[str] = []
        self.page.on("pageerror", lambda e: self.errors.append(f"pageerror: {e}"))
        self.page.on("console", self._console)
        url = where if isinstance(where, str) else where.resolve().as_uri()
        self.page.goto(url)

    def _console(self, message) -> None:
        # A served page (meshcat's server has no favicon) logs the browser's own favicon 404.
        if message.type == "error" and not message.location.get("url", "").endswith("/favicon.ico"):
            self.errors.append(f"console.error: {message.text}")

    def wait_ready(self, paths: list[str], n_actions: int) -> None:
        try:
            self.page.wait_for_function(JS_READY, arg=[paths, n_actions], timeout=30_000)
        except Exception as exc:
            desc = self.page.evaluate(JS_DESCRIBE, paths)
            missing = {p: d for p, d in desc.items() if d["type"] in (None, "Group")}
            raise AssertionError(
                f"scene never became ready: {exc}\nmissing objects: {missing}\n"
                f"page errors: {self.errors}"
            ) from exc

    def seek(self, paths: list[str], t: float) -> dict:
        return self.page.evaluate(JS_SEEK, [paths, t])

    def world_poses(self, paths: list[str]) -> dict[str, np.ndarray | None]:
        """Current world pose (meshcat/Pinocchio frame) of each path's node."""
        res = self.page.evaluate(JS_MATRICES, paths)
        return {
            p: None if m is None else threejs_to_meshcat(m, res["scene"])
            for p, m in res["nodes"].items()
        }

    def screenshot(self) -> np.ndarray:
        from PIL import Image

        self.page.evaluate(JS_TWO_FRAMES)
        png = self.page.screenshot()
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(np.int16)

    def robot_pixel_change(self, robot_path: str = "meshcat/pbvs/robot") -> tuple[float, float]:
        """Fractions of pixels that change when the robot is hidden, and when redrawn."""
        shown = self.screenshot()
        assert self.page.evaluate(JS_SET_VISIBLE, [robot_path, False]) is False
        hidden = self.screenshot()
        assert self.page.evaluate(JS_SET_VISIBLE, [robot_path, True]) is True
        shown_again = self.screenshot()
        changed = float((np.abs(shown - hidden).max(axis=2) > 40).mean())
        noise = float((np.abs(shown - shown_again).max(axis=2) > 40).mean())
        return changed, noise


def geometry_placements(model, visual_model, q) -> dict[str, np.ndarray]:
    """Pinocchio oMg (with meshScale) per geometry name, computed directly."""
    data, gdata = model.createData(), visual_model.createData()
    pin.forwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, visual_model, gdata)
    out = {}
    for gid, g in enumerate(visual_model.geometryObjects):
        T = np.array(gdata.oMg[gid].homogeneous)
        T[:3, :3] *= np.asarray(g.meshScale)[None, :]
        out[g.name] = T
    return out


# --------------------------------------------------------------------------
# browser session (wrap it in a module-scoped fixture)
# --------------------------------------------------------------------------
@contextlib.contextmanager
def chromium() -> Iterator:
    """A headless Chromium for one test module, closed on exit."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.fail(f"the Python package `playwright` is not installed. {INSTALL_HINT}")
    with sync_playwright() as p:
        b = launch(p)
        try:
            yield b
        finally:
            b.close()
