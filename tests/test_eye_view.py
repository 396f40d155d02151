"""The robot's-eye view drawn again from a logged run: a strip and a video."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from pbvs_pin.exceptions import GainError
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.study.experiments import run_scenario
from pbvs_pin.viz.eye_view import STRIP_PANELS, write_eye_view

pytestmark = pytest.mark.filterwarnings(
    "ignore:zmq.eventloop.ioloop is deprecated:DeprecationWarning"
)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("eye")
    scenario = load_scenario("experiment1").with_values(
        **{"camera.model": "rendered", "duration": 0.4}
    )
    log, _ = run_scenario(scenario, out, progress=False, figures=False, eye_view="strip")
    return log, out


def test_strip_shows_both_spheres_in_every_panel(run):
    _, out = run
    strip = cv2.imread(str(out / "eye_view.png"))
    width, height = 628 // 2, 582 // 2
    assert strip.shape == (height, STRIP_PANELS * width, 3)
    hsv = cv2.cvtColor(strip, cv2.COLOR_BGR2HSV)
    for k in range(STRIP_PANELS):
        panel = hsv[:, k * width : (k + 1) * width]
        saturated = panel[..., 1] > 128
        for hue in (60, 30):  # OpenCV's hue of green and yellow (degrees / 2)
            assert np.sum(saturated & (np.abs(panel[..., 0].astype(int) - hue) < 8)) > 100


def test_video_has_a_frame_per_logged_instant(run, tmp_path):
    log, _ = run
    path = write_eye_view(log, tmp_path / "view.mp4", "video")
    video = cv2.VideoCapture(str(path))
    frames = 0
    while video.read()[0]:
        frames += 1
    video.release()
    assert frames == len(log["t"])


def test_unknown_eye_view_refused_before_the_run(tmp_path):
    with pytest.raises(GainError, match="eye view: expected 'strip' or 'video', got 'gif'"):
        run_scenario("experiment1", tmp_path, progress=False, figures=False, eye_view="gif")


JS_EYE = """(t) => {
    const a = window.viewer.animator; a.pause(); a.seek(t);
    window.viewer.set_dirty(); window.viewer.render();
    const image = document.getElementById("eye-view");
    return {key: Number(image.dataset.key), width: image.naturalWidth, src: image.src.length};
}"""


JS_BOXES = """() => Object.fromEntries(["eye-view", "pbvs-readout", "pbvs-slider", "pbvs-play"]
    .map((id) => [id, document.getElementById(id).getBoundingClientRect().toJSON()]))"""


def test_replay_shows_the_eye_view_at_the_animation_time(run, tmp_path):
    """The image of the key at the animation's time, clear of the time and error readout."""
    from browser import Page, chromium

    from pbvs_pin.viz.html_replay import write_run_replay

    log, _ = run
    html = write_run_replay(log, tmp_path / "replay.html", rate=10.0, eye_view=True)
    spheres = ["meshcat/pbvs/targets/sphere_0", "meshcat/pbvs/targets/sphere_1"]
    with chromium() as browser:
        page = Page(browser, html)
        page.wait_ready(spheres, 1)
        early = page.page.evaluate(JS_EYE, 0.0)
        late = page.page.evaluate(JS_EYE, 0.21)
        page.page.wait_for_function("() => document.getElementById('eye-view').complete")
        shown = page.page.evaluate(JS_EYE, 0.3)
        boxes = page.page.evaluate(JS_BOXES)
        assert not page.errors, page.errors
    eye = boxes["eye-view"]
    for covered in ("pbvs-readout", "pbvs-slider", "pbvs-play"):  # the time and error readout
        box = boxes[covered]
        apart = eye["left"] >= box["right"] or eye["right"] <= box["left"] or (
            eye["top"] >= box["bottom"] or eye["bottom"] <= box["top"])  # fmt: skip
        assert apart, (covered, eye, box)
    # a 50 Hz log of 0.4 s keyed at 10 Hz: keys at 0, 0.1, 0.2, 0.3 and 0.38 s
    assert early["key"] == 0 and late["key"] == 2 and shown["key"] == 3
    assert shown["width"] == 628 // 2 and shown["src"] > 1000


def test_a_logged_robot_from_a_robot_file_names_that_file_when_rebuilt():
    """The eye view, the replay and the bag rebuild the robot from the log: its warnings named
    the scenario's file (experiment1.toml), not the robot file the table came from."""
    import warnings

    from conftest import REPO_ROOT

    from pbvs_pin.exceptions import PbvsWarning
    from pbvs_pin.sim.loop import simulate
    from pbvs_pin.study.experiments import with_robot
    from pbvs_pin.viz.run_scene import log_robot

    path = REPO_ROOT / "robots" / "vega_1.toml"  # warns: wheel links below the floor
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scenario = with_robot(load_scenario("experiment1"), str(path))
        log = simulate(scenario.with_values(duration=0.2), progress=False)
    assert log.meta["robot_source"] == str(path)
    with pytest.warns(PbvsWarning) as caught:
        log_robot(log)
    said = [str(w.message) for w in caught if "below the floor" in str(w.message)]
    assert said and all(message.startswith(f"{path}: ") for message in said)
