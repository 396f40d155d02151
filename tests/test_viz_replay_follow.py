"""The run replay in a headless browser: the camera follows the platform, the spheres show."""

from __future__ import annotations

import numpy as np
import pytest
from browser import Page, chromium

from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.viz.html_replay import follow_point, write_run_replay

pytestmark = pytest.mark.filterwarnings(
    "ignore:zmq.eventloop.ioloop is deprecated:DeprecationWarning"
)
SPHERES = ["meshcat/pbvs/targets/sphere_0", "meshcat/pbvs/targets/sphere_1"]
JS_VIEW = """(t) => {
    const a = window.viewer.animator; a.pause(); a.seek(t);
    window.viewer.set_dirty(); window.viewer.render();
    const c = window.viewer.camera.position, g = window.viewer.controls.target;
    return {camera: [c.x, c.y, c.z], target: [g.x, g.y, g.z]};
}"""


@pytest.fixture(scope="module")
def replay(tmp_path_factory):
    log = simulate(load_scenario("experiment2").with_values(duration=16.0), progress=False)
    path = write_run_replay(log, tmp_path_factory.mktemp("follow") / "replay.html")
    return log, path


def _sphere_pixels(page: Page) -> int:
    """Pixels that change when both target spheres are hidden."""
    shown = page.screenshot()
    for path in SPHERES:
        page.page.evaluate(
            "(p) => { let n = window.viewer.scene_tree; for (const s of p.split('/')) "
            "n = n.children[s]; n.set_property('visible', false); window.viewer.set_dirty(); }",
            path,
        )
    hidden = page.screenshot()
    for path in SPHERES:
        page.page.evaluate(
            "(p) => { let n = window.viewer.scene_tree; for (const s of p.split('/')) "
            "n = n.children[s]; n.set_property('visible', true); window.viewer.set_dirty(); }",
            path,
        )
    return int((np.abs(shown - hidden).max(axis=2) > 40).sum())


def test_camera_follows_platform_and_spheres_are_visible(replay):
    log, html = replay
    t = log["t"]
    with chromium() as browser:
        page = Page(browser, html)
        page.wait_ready(SPHERES, 1)
        offsets = []
        for when in (1.0, 15.0):
            view = page.page.evaluate(JS_VIEW, when)
            k = int(np.argmin(np.abs(t - when)))
            expected = follow_point(log["q"][k, :3], log["target"][k])
            # three.js Y-up coordinates of the camera's parent: world (x, y, z) -> (x, z, -y)
            target = np.array(view["target"])
            world = np.array([target[0], -target[2], target[1]])
            np.testing.assert_allclose(world, expected, atol=0.05)
            camera = np.array(view["camera"])
            offset = np.array([camera[0], -camera[2], camera[1]]) - world
            offsets.append(offset)
            assert _sphere_pixels(page) > 200, when  # both spheres, each over 10 px wide
            page.page.screenshot(path=str(html.parent / f"replay_t{when:.0f}.png"))
        assert not page.errors, page.errors
    # the viewing camera moved with the followed point, keeping its offset
    np.testing.assert_allclose(offsets[0], offsets[1], atol=0.02)
    assert 0.5 < np.linalg.norm(offsets[0]) < 2.0
    assert np.ptp(log["q"][:, 0]) > 0.5  # the platform did move: following was needed
