"""The replay page reads on its own: title, play/pause, time slider, readout, camera-image inset.

A short run of Experiment 2 is written as a replay and opened in headless Chromium. The
expectations come from the log and the pinhole model, not from the page's code: the page title
names the robot and the experiment; the readout shows the time and the largest feature error
the log holds at that time; the inset's red dots sit where the spheres project from the logged
configuration and its green rings at ``xi_d``; the screenshot shows the bar's controls and text
in their boxes, and sky (not grid lines) above the horizon.
"""

from __future__ import annotations

import re

import numpy as np
import pinocchio as pin
import pytest
from browser import Page, chromium
from conftest import project_world

from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.viz.html_replay import log_robot, write_run_replay

pytestmark = pytest.mark.filterwarnings(
    "ignore:zmq.eventloop.ioloop is deprecated:DeprecationWarning"
)

DURATION = 4.0
SEEK = 2.0  # a key time of the 10 Hz replay [s]
INSET_WIDTH = 220  # [CSS px], the page's documented inset width
JS_SEEK = """(t) => { const a = viewer.animator; a.pause(); a.seek(t); viewer.set_dirty();
    return new Promise(r => requestAnimationFrame(() => requestAnimationFrame(() => r(true)))); }"""


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    log = simulate(load_scenario("experiment2").with_values(duration=DURATION), progress=False)
    html = write_run_replay(log, tmp_path_factory.mktemp("page") / "replay.html")
    return log, html


@pytest.fixture(scope="module")
def page(run):
    with chromium() as browser:
        page = Page(browser, run[1])
        page.page.wait_for_function(
            "() => window.viewer && viewer.animator.actions.length > 0", timeout=60_000
        )
        yield page
        assert not page.errors, page.errors


def box(page: Page, element: str) -> dict:
    found = page.page.locator(f"#{element}").bounding_box()
    assert found is not None, f"#{element} is not displayed"
    return found


def crop(image: np.ndarray, where: dict) -> np.ndarray:
    x, y = round(where["x"]), round(where["y"])
    return image[y : y + int(where["height"]), x : x + int(where["width"])]


def inside_viewport(where: dict) -> bool:
    return (
        where["x"] >= 0 and where["y"] >= 0 and where["width"] > 0 and where["height"] > 0
        and where["x"] + where["width"] <= 800 and where["y"] + where["height"] <= 600
    )  # fmt: skip


def test_the_title_names_the_robot_and_the_experiment(page):
    assert page.page.title() == "pioneer_cyton · experiment2"
    heading = box(page, "pbvs-title")
    assert inside_viewport(heading) and heading["y"] < 40
    assert page.page.inner_text("#pbvs-title") == "pioneer_cyton · experiment2"


def test_play_pause_and_slider_are_visible_and_drive_the_animation(page):
    play, slider = box(page, "pbvs-play"), box(page, "pbvs-slider")
    for where in (play, slider):
        assert inside_viewport(where) and where["y"] > 540  # on the bar along the bottom
    assert slider["width"] > 200
    playing = page.page.evaluate("() => viewer.animator.playing")
    page.page.click("#pbvs-play")
    page.page.wait_for_function(  # the click acts through the page's event loop
        "(expected) => viewer.animator.playing === expected", arg=not playing, timeout=5000
    )
    assert page.page.evaluate("() => viewer.animator.playing") is (not playing)
    assert page.page.inner_text("#pbvs-play") == ("Play" if playing else "Pause")
    if not playing:
        page.page.click("#pbvs-play")  # pause again, and wait until the page has paused
        page.page.wait_for_function("() => !viewer.animator.playing", timeout=5000)
    page.page.evaluate(
        "(t) => { const s = document.getElementById('pbvs-slider'); s.value = t;"
        " s.dispatchEvent(new Event('input')); s.dispatchEvent(new Event('change')); }",
        SEEK,
    )
    times = page.page.evaluate("() => viewer.animator.actions.map(a => a.time)")
    np.testing.assert_allclose(times, SEEK, atol=1e-6)


def test_the_readout_shows_time_and_feature_error_from_the_log(page, run):
    log, _ = run
    page.page.evaluate(JS_SEEK, SEEK)
    k = int(np.argmin(np.abs(log["t"] - log["t"][0] - SEEK)))
    expected = float(np.max(np.abs(log["xi"][k] - log["xi_d"][k])))
    text = page.page.inner_text("#pbvs-readout")
    match = re.fullmatch(r"t =\s+([0-9.]+) s\s+max \|xi - xi_d\| = ([0-9.]+) px", text.strip())
    assert match, text
    assert float(match.group(1)) == pytest.approx(SEEK, abs=0.05)
    assert float(match.group(2)) == pytest.approx(expected, abs=0.051)


def test_the_screenshot_shows_the_bar_text_and_controls(page):
    page.page.evaluate(JS_SEEK, SEEK)
    shot = page.screenshot()
    readout = crop(shot, box(page, "pbvs-readout"))
    light = (readout.min(axis=2) > 180).mean()  # white text
    dark = (readout.max(axis=2) < 60).mean()  # the bar behind it
    assert 0.03 < light < 0.5 and dark > 0.4, (light, dark)
    button = crop(shot, box(page, "pbvs-play"))
    blue = (button[..., 2] > 180) & (button[..., 0] < 90)
    assert blue.mean() > 0.5  # a filled, coloured button
    title = crop(shot, box(page, "pbvs-title"))
    assert (title.min(axis=2) > 180).mean() > 0.05


def _blobs(mask: np.ndarray) -> list[np.ndarray]:
    """Centroids (col, row) of the upper and lower half of a two-blob mask."""
    rows, cols = np.nonzero(mask)
    middle = (rows.min() + rows.max()) / 2
    return [
        np.array([cols[part].mean(), rows[part].mean()])
        for part in (rows < middle, rows >= middle)
    ]


def test_the_inset_shows_the_image_points_and_xi_d(page, run):
    log, _ = run
    robot = log_robot(log)
    camera = robot.camera
    page.page.evaluate(JS_SEEK, SEEK)
    where = box(page, "pbvs-image")
    assert inside_viewport(where)
    assert where["width"] == pytest.approx(INSET_WIDTH, abs=1)
    inset = crop(page.screenshot(), where)
    scale = INSET_WIDTH / camera.width
    red = (inset[..., 0] > 200) & (inset[..., 1] < 110) & (inset[..., 2] < 110)
    green = (inset[..., 1] > 200) & (inset[..., 0] < 110) & (inset[..., 2] < 110)
    # independent projection of both sphere centres from the logged configuration
    k = int(np.argmin(np.abs(log["t"] - log["t"][0] - SEEK)))
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, log["q"][k])
    pose = data.oMf[robot.model.getFrameId(robot.camera_frame)]
    half = log.meta["target_separation"] / 2
    centre = log["target"][k]
    cx, cy = camera.width / 2, camera.height / 2
    for found, point in zip(_blobs(red), (half, -half), strict=True):
        u, v = project_world(camera.focal_px, pose, centre + np.array([0.0, 0.0, point]))
        np.testing.assert_allclose(found, [(cx - u) * scale, (cy - v) * scale], atol=2.0)
    u1, v1, v2 = log["xi_d"][0]
    for found, v in zip(_blobs(green), (v1, v2), strict=True):
        np.testing.assert_allclose(found, [(cx - u1) * scale, (cy - v) * scale], atol=2.0)
    assert red.sum() > 2 * 40  # two dots of radius 5 px
    assert green.sum() > 2 * 30  # two rings of radius 8 px


def test_no_grid_in_the_sky(page):
    page.page.evaluate(JS_SEEK, SEEK)
    assert page.page.evaluate("() => viewer.scene_tree.children['Grid'].object.visible") is False
    shot = page.screenshot()
    band = shot[60:110, 560:780]  # above the horizon, clear of the title, inset and controls
    sky = band[..., 2] > band[..., 0] + 40  # meshcat's blue background
    assert sky.mean() > 0.97, sky.mean()
