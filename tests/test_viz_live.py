"""The live Meshcat view of a run, the robot viewer, and what happens when no viewer can start.

A headless Chromium connects to the live server's URL *before* the run, so the checks see what a
user's browser receives over the websocket while ``simulate`` calls ``LiveView.show``.
References are independent of the viewer code: Pinocchio's placements of the last snapshot's
configuration and the snapshot itself.
"""

from __future__ import annotations

import sys
import time
import types

import cv2
import numpy as np
import pinocchio as pin
import pytest
from browser import JS_DESCRIBE, JS_NODE, JS_SET_VISIBLE, Page, chromium, geometry_placements

import pbvs_pin.viz.live as live_module
import pbvs_pin.viz.server as server
from pbvs_pin.cli import main
from pbvs_pin.exceptions import PbvsError, ViewerUnavailable
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario, scenario_dir
from pbvs_pin.viz.live import LiveView, view_robot
from pbvs_pin.viz.run_scene import IMAGE_PLANE_DEPTH

# meshcat 0.3.2 imports a pyzmq module that pyzmq itself deprecates.
pytestmark = pytest.mark.filterwarnings(
    "ignore:zmq.eventloop.ioloop is deprecated:DeprecationWarning"
)

POSE_TOL = 1e-5  # float32 transforms in the page
SPHERES = ["meshcat/pbvs/targets/sphere_0", "meshcat/pbvs/targets/sphere_1"]
CAMERA = "meshcat/pbvs/camera"
CURRENT = ["meshcat/pbvs/camera/image/current/0", "meshcat/pbvs/camera/image/current/1"]
TRAILS = ["meshcat/pbvs/trail_platform", "meshcat/pbvs/trail_target"]
SPEED = 1.0  # simulated seconds per wall-clock second in the live run
EYE = "Cameras/default/rotated/<object>/pbvs_eye_view"  # the eye-view panel, on the view camera

# The eye-view panel's corners projected by the page's own viewing camera: its rectangle on
# the screen [px], (left, top, right, bottom), and the uuid of the mesh shown.
JS_PANEL = (
    "(path) => {"
    + JS_NODE
    + """
    const o = pbvsNode(path).children['<object>'].object;
    const camera = window.viewer.camera, canvas = window.viewer.renderer.domElement;
    window.viewer.scene.updateMatrixWorld(true);
    o.geometry.computeBoundingBox();
    const b = o.geometry.boundingBox, cols = [], rows = [];
    for (const x of [b.min.x, b.max.x]) for (const y of [b.min.y, b.max.y]) {
        const p = new o.position.constructor(x, y, 0).applyMatrix4(o.matrixWorld).project(camera);
        cols.push((p.x + 1) / 2 * canvas.clientWidth);
        rows.push((1 - p.y) / 2 * canvas.clientHeight);
    }
    return {rect: [Math.min(...cols), Math.min(...rows), Math.max(...cols), Math.max(...rows)],
            uuid: o.uuid, loaded: o.material.map !== null && o.material.map.image !== undefined};
}"""
)


JS_WATCH_CAMERA = """() => {
    window.pbvsCameraSeen = [];
    const watch = () => {
        const x = window.viewer.scene_tree.children.meshcat.children.pbvs.children.camera
            .object.position.x;
        const seen = window.pbvsCameraSeen;
        if (seen.length === 0 || seen[seen.length - 1] !== x) seen.push(x);
        requestAnimationFrame(watch);
    };
    watch();
}"""


@pytest.fixture(scope="module")
def browser():
    with chromium() as b:
        yield b


def _geometry_paths(robot) -> dict[str, str]:
    model = robot.model
    return {
        g.name: f"meshcat/pbvs/robot/{model.names[g.parentJoint]}/{g.name}"
        for g in robot.visual_model.geometryObjects
    }


def _camera_pose(robot, q) -> pin.SE3:
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    return pin.SE3(data.oMf[robot.model.getFrameId(robot.camera_frame)])


@pytest.fixture(scope="module")
def live_run(browser):
    """Two seconds of experiment 1 played in real time, a browser watching from the start."""
    scenario = load_scenario("experiment1").with_values(duration=2.0)
    snapshots = []
    with LiveView(scenario, speed=SPEED) as live:
        assert live.url.startswith("http://")
        paths = _geometry_paths(live.robot)
        page = Page(browser, live.url)
        page.wait_ready([*paths.values(), *SPHERES, *CURRENT], n_actions=0)
        start = page.world_poses(list(paths.values()))
        # record every distinct camera position the page shows while the run goes on
        page.page.evaluate(JS_WATCH_CAMERA)

        def observer(snapshot):
            snapshots.append(snapshot)
            live.show(snapshot)

        wall = time.monotonic()
        log = simulate(scenario, observer=observer)
        wall = time.monotonic() - wall
        assert live.flush()
        stats = live.stats()
        static_html = live.static_html()
        # the websocket delivers asynchronously: wait for the last pose to arrive
        last = geometry_placements(live.robot.model, live.robot.visual_model, snapshots[-1].q)
        deadline = time.monotonic() + 15.0
        while True:
            now = page.world_poses(list(paths.values()))
            error = max(np.abs(now[p] - last[n]).max() for n, p in paths.items())
            if error < POSE_TOL or time.monotonic() > deadline:
                break
            time.sleep(0.1)
        seen = page.page.evaluate("() => window.pbvsCameraSeen")
        yield {
            "seen": seen,
            "live": live,
            "log": log,
            "snapshots": snapshots,
            "paths": paths,
            "page": page,
            "start": start,
            "stats": stats,
            "static_html": static_html,
            "wall": wall,
        }
        page.page.close()


def test_live_page_shows_the_last_snapshot(live_run):
    live, page, snapshots = live_run["live"], live_run["page"], live_run["snapshots"]
    robot, paths = live.robot, live_run["paths"]
    assert len(snapshots) == len(live_run["log"]["t"]) == 100
    q = snapshots[-1].q
    expected = geometry_placements(robot.model, robot.visual_model, q)
    now = page.world_poses([*paths.values(), *SPHERES, CAMERA, *CURRENT])
    moved = max(np.abs(now[p] - live_run["start"][p]).max() for p in paths.values())
    assert moved > 0.01, "the robot must have moved during the run"
    for name, path in paths.items():
        np.testing.assert_allclose(now[path], expected[name], atol=POSE_TOL, err_msg=name)
    for path, centre in zip(SPHERES, snapshots[-1].centres, strict=True):
        np.testing.assert_allclose(now[path][:3, 3], centre, atol=POSE_TOL, err_msg=path)
    camera = _camera_pose(robot, q)
    np.testing.assert_allclose(now[CAMERA], camera.homogeneous, atol=POSE_TOL)
    # current points: the measured [u, v] on the image plane (pixel col = cx - u, row = cy - v)
    f, depth = robot.camera.focal_px, IMAGE_PLANE_DEPTH
    assert np.all(np.isfinite(snapshots[-1].points))
    for path, (u, v) in zip(CURRENT, snapshots[-1].points, strict=True):
        want = camera.act(np.array([-u / f * depth, -v / f * depth, depth]))
        np.testing.assert_allclose(now[path][:3, 3], want, atol=POSE_TOL, err_msg=path)
    assert page.errors == []


def test_live_trails_follow_the_run(live_run):
    page = live_run["page"]
    desc = page.page.evaluate(JS_DESCRIBE, TRAILS)
    for path in TRAILS:
        assert desc[path]["type"] == "Line", desc
        assert desc[path]["vertices"] >= 10, desc
    # the target moves at 0.1 m/s; its trail reaches the last snapshot's midpoint
    last = page.page.evaluate(
        """(path) => {
            let n = window.viewer.scene_tree;
            for (const s of path.split('/')) n = n.children[s];
            const a = n.children['<object>'].object.geometry.attributes.position;
            return [a.getX(a.count - 1), a.getY(a.count - 1), a.getZ(a.count - 1)];
        }""",
        TRAILS[1],
    )
    np.testing.assert_allclose(last, live_run["snapshots"][-1].centres.mean(axis=0), atol=1e-5)


def test_live_server_scene_and_cost(live_run):
    html = live_run["static_html"]
    assert "new MeshCat.Viewer(" in html and html.count("fetch(") > 20
    stats = live_run["stats"]
    print(
        f"LiveView.show: {stats.snapshots} calls, {stats.frames} sent, "
        f"mean {1e6 * stats.show_seconds:.0f} us/call, {1e3 * stats.frame_seconds:.2f} ms/sent"
    )
    assert stats.snapshots == 100 and 2 <= stats.frames <= stats.snapshots
    assert stats.show_seconds < stats.frame_seconds


def test_live_page_is_updated_during_the_run(live_run):
    """The run is paced, and the browser saw the camera at many intermediate places."""
    duration = 2.0
    # paced: the last snapshot (t = 1.98 s) is shown no earlier than 1.98 / SPEED after the first
    assert live_run["wall"] >= (duration - 0.02) / SPEED - 0.02, live_run["wall"]
    # MAX_RATE updates per second for two seconds: a browser rendering in software (a few
    # frames per second at worst) still sees the camera at several places
    seen = live_run["seen"]
    assert len(seen) >= 5, seen
    assert live_run["stats"].frames >= 20, live_run["stats"]


# ---------------------------------------------------------------------- robot's-eye view
def _panel(page, expected: np.ndarray, timeout: float = 15.0) -> tuple[np.ndarray, float]:
    """The screenshot inside the eye-view panel once it shows ``expected`` (RGB, any size),
    and its mean absolute difference from it [grey levels]."""
    deadline = time.monotonic() + timeout
    while True:
        left, top, right, bottom = page.page.evaluate(JS_PANEL, EYE)["rect"]
        inner = (slice(round(top) + 2, round(bottom) - 2), slice(round(left) + 2, round(right) - 2))
        size = (round(right) - round(left), round(bottom) - round(top))
        want = cv2.resize(expected, size, interpolation=cv2.INTER_AREA).astype(float)
        want = want[2:-2, 2:-2]
        shot = page.screenshot()[inner]
        error = float(np.abs(shot - want).mean())
        if error < 4.0 or time.monotonic() > deadline:
            return shot, error
        time.sleep(0.2)


def _sphere_pixels(rgb: np.ndarray) -> list[int]:
    """Pixels of the upper (green) and lower (yellow) sphere's colour in an RGB image."""
    hsv = cv2.cvtColor(np.ascontiguousarray(rgb, dtype=np.uint8), cv2.COLOR_RGB2HSV)
    hue, vivid = hsv[..., 0].astype(int), (hsv[..., 1] > 128) & (hsv[..., 2] > 100)
    return [int(np.sum(vivid & (np.abs(hue - h) < 8))) for h in (60, 30)]  # OpenCV: deg / 2


def test_live_eye_view_panel_is_fixed_in_the_view_and_shows_the_points(live_run):
    """Points camera: a panel in the lower left of the view, over the scene, that shows the
    last measured points as discs of the spheres' colours."""
    page, snapshot = live_run["page"], live_run["snapshots"][-1]
    assert snapshot.image is None  # no image: the panel draws one
    camera = live_run["live"].robot.camera
    panel = page.page.evaluate(JS_PANEL, EYE)
    left, top, right, bottom = panel["rect"]
    height, width = page.screenshot().shape[:2]
    assert 0 < left < width / 4 and right < width and height / 2 < top < bottom < height, panel
    np.testing.assert_allclose(bottom - top, 0.4 * height, rtol=0.02)
    np.testing.assert_allclose((right - left) / (bottom - top), camera.width / camera.height, 1e-3)
    # the last points, drawn as discs: the green disc's centre where the upper point is
    deadline, found, want = time.monotonic() + 15.0, None, None
    col, row = camera.to_pixel(snapshot.points[0])
    want = (left + col / camera.width * (right - left), top + row / camera.height * (bottom - top))
    while found is None or np.hypot(*np.subtract(found, want)) > 3.0:
        if time.monotonic() > deadline:
            break
        shot = page.screenshot()
        hsv = cv2.cvtColor(shot.astype(np.uint8), cv2.COLOR_RGB2HSV)
        green = (hsv[..., 1] > 128) & (np.abs(hsv[..., 0].astype(int) - 60) < 8)
        green[: round(top)] = green[:, round(right) :] = False  # the scene's triad is green too
        rows, cols = np.nonzero(green)
        found = (cols.mean() + 0.5, rows.mean() + 0.5) if len(rows) else (np.nan, np.nan)
        time.sleep(0.2)
    assert np.hypot(*np.subtract(found, want)) < 3.0, (found, want)
    inner = (slice(round(top) + 2, round(bottom) - 2), slice(round(left) + 2, round(right) - 2))
    assert min(_sphere_pixels(shot[inner])) > 20
    # over the scene: hiding it changes the pixels inside its rectangle, and only those
    assert page.page.evaluate(JS_SET_VISIBLE, [EYE, False]) is False
    hidden = page.screenshot()
    assert page.page.evaluate(JS_SET_VISIBLE, [EYE, True]) is True
    changed = np.abs(page.screenshot() - hidden).max(axis=2) > 40
    outside = np.ones_like(changed)
    outside[round(top) - 2 : round(bottom) + 2, round(left) - 2 : round(right) + 2] = False
    assert changed[inner].mean() > 0.8 and changed[outside].mean() < 0.001
    stats = live_run["stats"]
    assert 3 <= stats.eye_frames <= 5 * live_run["wall"] + 2, stats  # 5 a second, start, flush
    print(f"eye view (points): {stats.eye_frames} sent, {1e3 * stats.eye_seconds:.1f} ms each")
    assert page.errors == []


@pytest.fixture(scope="module")
def rendered_run(browser):
    """Experiment 1 with the rendered camera for 0.6 s, as fast as it goes, a browser watching."""
    scenario = load_scenario("experiment1").with_values(
        **{"camera.model": "rendered", "duration": 0.6}
    )
    snapshots = []
    with LiveView(scenario) as live:
        page = Page(browser, live.url)
        page.wait_ready(SPHERES, n_actions=0)

        def observer(snapshot):
            snapshots.append(snapshot)
            live.show(snapshot)

        wall = time.monotonic()
        simulate(scenario, observer=observer)
        wall = time.monotonic() - wall
        assert live.flush()
        yield {"live": live, "page": page, "snapshots": snapshots, "wall": wall}
        page.page.close()


def test_live_eye_view_shows_the_rendered_frames(rendered_run):
    """Rendered camera: the panel shows the run's last frame (both spheres in their colours)
    with the desired points crossed in cyan, at a small cost per image."""
    live, page = rendered_run["live"], rendered_run["page"]
    frames = {s.image.time: s.image for s in rendered_run["snapshots"] if s.image is not None}
    assert len(frames) == 18  # 30 Hz for 0.6 s
    last = frames[max(frames)]
    assert last.visible
    shot, error = _panel(page, last.image)
    print(f"eye view (rendered): panel differs from the last frame by {error:.1f} grey levels")
    assert error < 4.0, error  # the marks and the texture's filtering; the first frame: 14
    assert min(_sphere_pixels(shot)) > 20
    hsv = cv2.cvtColor(shot.astype(np.uint8), cv2.COLOR_RGB2HSV)
    cyan = (hsv[..., 1] > 128) & (np.abs(hsv[..., 0].astype(int) - 90) < 8)
    assert cyan.sum() > 10  # the crosses at xi_d
    stats = live.stats()
    print(
        f"eye view (rendered): {stats.eye_frames} sent in {rendered_run['wall']:.1f} s, "
        f"{1e3 * stats.eye_seconds:.1f} ms each (mark, PNG, send)"
    )
    assert 2 <= stats.eye_frames <= 5 * rendered_run["wall"] + 2, stats
    assert page.errors == []


def test_live_view_rejects_a_bad_speed():
    for speed in (0.0, -1.0, float("nan"), "fast"):
        with pytest.raises(PbvsError, match="speed: expected a positive number"):
            LiveView("experiment1", speed=speed)


def test_live_view_survives_a_dead_server(capsys):
    """The run finishes and one warning says the view stopped. zmq may queue a request to a
    dead server without error, so the death shows at the first send that waits for a reply:
    during the run or at the final flush."""
    scenario = load_scenario("experiment1").with_values(duration=0.5)
    with LiveView(scenario, timeout=0.3) as live:
        live.vis.window.server_proc.kill()
        live.vis.window.server_proc.wait()
        log = simulate(scenario, observer=live.show)
    assert not live.alive
    assert len(log["t"]) == 25  # the run finished
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("pbvs-pin: warning: live view stopped")


def test_run_meshcat_keeps_results_when_the_viewer_dies(tmp_path, monkeypatch, capsys):
    toml = (scenario_dir() / "experiment1.toml").read_text().replace("30.0", "0.5", 1)
    (tmp_path / "short.toml").write_text(toml)
    monkeypatch.setattr(live_module, "SEND_TIMEOUT", 0.3)
    enter = LiveView.__enter__

    def enter_then_kill_server(self):
        self.vis.window.server_proc.kill()
        return enter(self)

    monkeypatch.setattr(LiveView, "__enter__", enter_then_kill_server)
    out = tmp_path / "out"
    status = main(["run", str(tmp_path / "short.toml"), "--meshcat", "--out", str(out)])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    assert (out / "log.npz").is_file() and (out / "summary.json").is_file()
    assert "live view: http://" in captured.out
    warnings = [line for line in captured.err.splitlines() if "warning" in line]
    assert len(warnings) == 1 and "live view stopped" in warnings[0], captured.err
    assert "Traceback" not in captured.err


def test_run_meshcat_rejects_a_bad_speed_without_a_traceback(tmp_path, capsys):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exit_info:
        main(["run", "experiment1", "--meshcat", "--speed", "0", "--out", str(out)])
    err = capsys.readouterr().err
    assert exit_info.value.code != 0
    assert "--speed: expected a positive number, got '0'" in err, err
    assert "Traceback" not in err and not out.exists()


# ---------------------------------------------------------------------- view_robot
@pytest.mark.parametrize("name", ["pioneer_ur5", "urdf"])
def test_view_robot_html_has_every_link_and_the_frustum(browser, tmp_path, capsys, name):
    from conftest import URDF_DIR

    from pbvs_pin.bringup.catalogue import build_robot

    name = str(URDF_DIR / "pioneer_cyton.urdf") if name == "urdf" else name
    html = tmp_path / "robot.html"
    assert view_robot(name, html) == html
    assert str(html) in capsys.readouterr().out
    robot = build_robot(name)
    model, visual = robot.model, robot.visual_model
    paths = {g.name: f"meshcat/pbvs/robot/{g.name}" for g in visual.geometryObjects}
    parts = [CAMERA + "/frustum", CAMERA + "/triad"]
    page = Page(browser, html)
    try:
        page.wait_ready([*paths.values(), *parts], n_actions=0)
        desc = page.page.evaluate(JS_DESCRIBE, [*paths.values(), *parts])
        assert all(d["vertices"] > 0 for d in desc.values()), desc
        assert desc[parts[0]]["type"] == "LineSegments"
        now = page.world_poses([*paths.values(), CAMERA])
        q = robot.home()
        expected = geometry_placements(model, visual, q)
        for geometry, path in paths.items():
            np.testing.assert_allclose(now[path], expected[geometry], atol=POSE_TOL)
        np.testing.assert_allclose(now[CAMERA], _camera_pose(robot, q).homogeneous, atol=POSE_TOL)
        changed, _ = page.robot_pixel_change()
        assert changed > 0.005
        assert page.errors == []
    finally:
        page.page.close()


def test_view_robot_serves_until_ctrl_c(monkeypatch, capsys):
    opened, stopped = [], []
    monkeypatch.setattr(live_module.webbrowser, "open", lambda url, new=0: opened.append(url))

    def ctrl_c(seconds):
        raise KeyboardInterrupt

    # only the viewer's own clock: Ctrl-C arrives while it serves
    clock = types.SimpleNamespace(sleep=ctrl_c, perf_counter=time.perf_counter)
    monkeypatch.setattr(live_module, "time", clock)
    stop = server.stop_visualizer

    def record_stop(vis):
        stopped.append(vis)
        stop(vis)

    monkeypatch.setattr(server, "stop_visualizer", record_stop)
    assert view_robot("pioneer_cyton") is None
    out = capsys.readouterr().out
    assert opened and opened[0].startswith("http://") and opened[0] in out
    # webbrowser.open returned a false value: the URL to open is printed
    assert f"open {opened[0]} in one" in out
    assert "stopped" in out
    assert len(stopped) == 1 and stopped[0].window.server_proc.poll() is not None


# ---------------------------------------------------------------------- no viewer at all
def _server_dies(*args, **kwargs):
    raise RuntimeError("the meshcat server process exited prematurely with exit code 1")


@pytest.fixture(params=["server process", "Visualizer"])
def no_meshcat_server(request, monkeypatch):
    """No served viewer: the server subprocess dies, or ``meshcat.Visualizer`` itself raises."""
    import meshcat
    import meshcat.visualizer

    if request.param == "Visualizer":
        monkeypatch.setattr(meshcat, "Visualizer", _server_dies)
    else:
        monkeypatch.setattr(meshcat.visualizer, "start_zmq_server_as_subprocess", _server_dies)


def test_unavailable_viewer_says_what_to_do_instead(no_meshcat_server):
    with pytest.raises(ViewerUnavailable) as error:
        view_robot("pioneer_cyton")
    message = str(error.value)
    assert isinstance(error.value, PbvsError)
    assert "exited prematurely" in message
    assert "pbvs-pin view pioneer_cyton --html FILE" in message
    with pytest.raises(ViewerUnavailable, match="--html FILE") as error:
        LiveView("experiment1")
    assert "without --meshcat" in str(error.value)


def test_cli_view_without_server_is_one_line_and_status_2(no_meshcat_server, capsys):
    status = main(["view", "pioneer_cyton"])
    err = capsys.readouterr().err
    assert status == 2
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith("pbvs-pin: error: Meshcat viewer unavailable")
    assert "--html FILE" in err and "Traceback" not in err


def test_cli_view_html_needs_no_server(monkeypatch, tmp_path, capsys):
    import meshcat.visualizer

    monkeypatch.setattr(meshcat.visualizer, "start_zmq_server_as_subprocess", _server_dies)
    status = main(["view", "pioneer_cyton", "--html", str(tmp_path / "v.html")])
    assert status == 0, capsys.readouterr().err
    assert (tmp_path / "v.html").stat().st_size > 100_000


def test_missing_server_program_is_a_viewer_error(monkeypatch):
    """A real failure: the server subprocess cannot even be executed."""
    monkeypatch.setattr(sys, "executable", "/nonexistent/python3")
    with pytest.raises(ViewerUnavailable, match="could not start the meshcat server"):
        server.start_visualizer()
