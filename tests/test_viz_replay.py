"""The HTML replay of a simulated run, checked in headless Chromium against Pinocchio and the log.

A 3 s run of experiment 2 (moving target, one obstacle) is simulated, written with
``write_run_replay`` and opened from ``file://`` (no server). The references are independent
of the viewer code: geometry placements from Pinocchio (``browser.geometry_placements``), the
sphere centres from the log, and the image points from the pinhole of ``conftest``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from browser import JS_DESCRIBE, Page, chromium, geometry_placements, threejs_to_meshcat
from conftest import project_world

from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.viz.html_replay import log_robot, write_run_replay
from pbvs_pin.viz.primitives import MESHCAT_TO_THREEJS
from pbvs_pin.viz.recorder import offline_visualizer
from pbvs_pin.viz.run_scene import IMAGE_PLANE_DEPTH, RunFacts, RunScene
from pbvs_pin.viz.server import open_visualizer

# meshcat 0.3.2 imports a pyzmq module that pyzmq itself deprecates.
pytestmark = pytest.mark.filterwarnings(
    "ignore:zmq.eventloop.ioloop is deprecated:DeprecationWarning"
)

DURATION = 3.0
KEY_TIME = 1.2  # a key of the 10 Hz replay
BETWEEN_TIME = 0.73  # between the keys 0.7 and 0.8, and between log samples 0.72 and 0.74
POSE_TOL = 1e-4  # [m] and rotation-matrix entries: float32 in the page
# three.js interpolates poses between keys 0.1 s apart (lerp, slerp); at BETWEEN_TIME that
# differs from Pinocchio on the interpolated log by < 1e-4 m and < 3e-4 rad.
POSITION_TOL = 5e-4  # [m]
ROTATION_TOL = 2e-3  # rotation-matrix entries


@pytest.fixture(scope="module")
def browser():
    with chromium() as b:
        yield b


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    log = simulate(load_scenario("experiment2").with_values(duration=DURATION))
    html = write_run_replay(log, tmp_path_factory.mktemp("replay") / "run.html")
    robot = log_robot(log)
    model, visual = robot.model, robot.visual_model
    # one node per geometry, under its joint's node
    geometry_paths = {
        g.name: f"meshcat/pbvs/robot/{model.names[g.parentJoint]}/{g.name}"
        for g in visual.geometryObjects
    }
    moving_joints = {g.parentJoint for g in visual.geometryObjects if g.parentJoint > 0}
    return {
        "log": log,
        "html": html,
        "robot": robot,
        "geometry_paths": geometry_paths,
        # joint nodes, 2 spheres, the camera node, 2 current image points, the follow node
        "n_tracks": len(moving_joints) + 2 + 1 + 2 + 1,
    }


@pytest.fixture(scope="module")
def page(browser, run):
    page = Page(browser, run["html"])
    page.wait_ready(
        [*run["geometry_paths"].values(), *SPHERES, FRUSTUM, *CURRENT], n_actions=run["n_tracks"]
    )
    yield page
    page.page.close()


SPHERES = ["meshcat/pbvs/targets/sphere_0", "meshcat/pbvs/targets/sphere_1"]
CAMERA = "meshcat/pbvs/camera"
FRUSTUM = "meshcat/pbvs/camera/frustum"
CURRENT = ["meshcat/pbvs/camera/image/current/0", "meshcat/pbvs/camera/image/current/1"]
DESIRED = ["meshcat/pbvs/camera/image/desired/0", "meshcat/pbvs/camera/image/desired/1"]
STATIC = [
    "meshcat/pbvs/obstacles/obstacle_0",
    "meshcat/pbvs/camera/image/plane",
    "meshcat/pbvs/camera/triad",
    "meshcat/pbvs/trail_platform",
    "meshcat/pbvs/trail_target",
]


def _sample(log, model: pin.Model, t: float):
    """Configuration and upper sphere centre at time t, interpolated between log samples."""
    times = log["t"]
    k = int(np.searchsorted(times, t)) - 1
    a = (t - times[k]) / (times[k + 1] - times[k])
    q = pin.interpolate(model, log["q"][k], log["q"][k + 1], a)
    target = (1 - a) * log["target"][k] + a * log["target"][k + 1]
    return q, target + np.array([0.0, 0.0, log.meta["target_separation"] / 2])


def _camera_pose(robot, q) -> pin.SE3:
    """Pose of the camera optical frame, straight from Pinocchio."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    return pin.SE3(data.oMf[robot.model.getFrameId(robot.camera_frame)])


def _image_point_in_camera(focal: float, camera_pose: pin.SE3, centre: np.ndarray) -> np.ndarray:
    """Where the image plane shows a sphere centre, in the camera frame (independent pinhole)."""
    u, v = project_world(focal, camera_pose, centre)
    depth = IMAGE_PLANE_DEPTH
    # paper's [u, v] -> pixel col = cx - u, row = cy - v -> ray ((col - cx)/f, (row - cy)/f, 1)
    return np.array([-u / focal * depth, -v / focal * depth, depth])


def test_every_geometry_sphere_and_camera_part_is_in_the_scene(run, page):
    robot = run["robot"]
    assert len(run["geometry_paths"]) == len(robot.visual_model.geometryObjects) > 5
    paths = [*run["geometry_paths"].values(), *SPHERES, *CURRENT, *DESIRED, FRUSTUM, *STATIC]
    desc = page.page.evaluate(JS_DESCRIBE, paths)
    for path in paths:
        assert desc[path]["found"], f"{path} not in viewer.scene_tree"
        assert desc[path]["vertices"] > 0, f"{path}: {desc[path]}"
    for path in [*run["geometry_paths"].values(), *SPHERES]:
        assert desc[path]["type"] == "Mesh", f"{path}: {desc[path]}"
    assert desc[FRUSTUM]["type"] == "LineSegments"
    assert desc["meshcat/pbvs/trail_platform"]["type"] == "Line"
    n_actions = page.page.evaluate("() => window.viewer.animator.actions.length")
    assert n_actions == run["n_tracks"]
    duration = page.page.evaluate("() => window.viewer.animator.duration")
    assert abs(duration - run["log"]["t"][-1]) < 1e-3, duration  # the whole run, to its last sample
    assert page.errors == []


def test_seek_to_a_key_matches_pinocchio_and_the_log(run, page):
    log, robot = run["log"], run["robot"]
    k = int(np.argmin(np.abs(log["t"] - KEY_TIME)))
    assert abs(log["t"][k] - KEY_TIME) < 1e-9
    q = log["q"][k]
    names = list(run["geometry_paths"])
    paths = [run["geometry_paths"][n] for n in names]
    res = page.seek([*paths, *SPHERES, CAMERA, *CURRENT], KEY_TIME)
    np.testing.assert_allclose(
        np.array(res["scene"]).reshape(4, 4, order="F"), MESHCAT_TO_THREEJS, atol=1e-12
    )
    expected = geometry_placements(robot.model, robot.visual_model, q)
    initial = geometry_placements(robot.model, robot.visual_model, log["q"][0])
    moved = max(np.abs(expected[n] - initial[n]).max() for n in names)
    assert moved > 0.05, "the robot must have moved, or a no-op seek would pass"
    for name, path in zip(names, paths, strict=True):
        got = threejs_to_meshcat(res["nodes"][path], res["scene"])
        np.testing.assert_allclose(got, expected[name], atol=POSE_TOL, err_msg=name)

    top = log["target"][k] + [0.0, 0.0, log.meta["target_separation"] / 2]
    centres = [top, top - [0.0, 0.0, log.meta["target_separation"]]]
    for path, centre in zip(SPHERES, centres, strict=True):
        got = threejs_to_meshcat(res["nodes"][path], res["scene"])
        np.testing.assert_allclose(got[:3, 3], centre, atol=POSE_TOL, err_msg=path)

    camera_pose = _camera_pose(robot, q)
    got_camera = threejs_to_meshcat(res["nodes"][CAMERA], res["scene"])
    np.testing.assert_allclose(got_camera, camera_pose.homogeneous, atol=POSE_TOL)
    for path, centre in zip(CURRENT, centres, strict=True):
        want = camera_pose.act(_image_point_in_camera(robot.camera.focal_px, camera_pose, centre))
        got = threejs_to_meshcat(res["nodes"][path], res["scene"])
        np.testing.assert_allclose(got[:3, 3], want, atol=POSE_TOL, err_msg=path)


def test_seek_between_keys_follows_the_interpolated_log(run, page):
    log, robot = run["log"], run["robot"]
    q, top = _sample(log, robot.model, BETWEEN_TIME)
    names = list(run["geometry_paths"])
    paths = [run["geometry_paths"][n] for n in names]
    res = page.seek([*paths, *SPHERES], BETWEEN_TIME)
    expected = geometry_placements(robot.model, robot.visual_model, q)
    # a pose off by one 0.1 s key would be off by far more than the tolerance
    key = geometry_placements(robot.model, robot.visual_model, _sample(log, robot.model, 0.8)[0])
    assert max(np.abs(key[n][:3, 3] - expected[n][:3, 3]).max() for n in names) > 10 * POSITION_TOL
    for name, path in zip(names, paths, strict=True):
        got = threejs_to_meshcat(res["nodes"][path], res["scene"])
        np.testing.assert_allclose(
            got[:3, 3], expected[name][:3, 3], atol=POSITION_TOL, err_msg=name
        )
        np.testing.assert_allclose(
            got[:3, :3], expected[name][:3, :3], atol=ROTATION_TOL, err_msg=name
        )
    upper = threejs_to_meshcat(res["nodes"][SPHERES[0]], res["scene"])
    np.testing.assert_allclose(upper[:3, 3], top, atol=POSE_TOL)


def test_desired_points_sit_at_the_desired_features(run, page):
    robot, log = run["robot"], run["log"]
    u1, v1, v2 = log["xi_d"][0]
    f, depth = robot.camera.focal_px, IMAGE_PLANE_DEPTH
    res = page.seek([CAMERA, *DESIRED], KEY_TIME)
    camera = threejs_to_meshcat(res["nodes"][CAMERA], res["scene"])
    for path, (u, v) in zip(DESIRED, [(u1, v1), (u1, v2)], strict=True):
        local = np.linalg.solve(camera, threejs_to_meshcat(res["nodes"][path], res["scene"]))
        np.testing.assert_allclose(local[:3, 3], [-u / f * depth, -v / f * depth, depth], atol=1e-6)


def test_robot_really_renders(run, page):
    page.seek([SPHERES[0]], KEY_TIME)
    changed, noise = page.robot_pixel_change()
    assert changed > 0.005, f"only {changed:.2%} of the pixels change when hiding the robot"
    assert noise < 0.001, f"rendering not reproducible: {noise:.2%} pixels differ"
    assert page.errors == []


def test_offline_scene_is_the_served_scene(run):
    """The server-free page is byte for byte what meshcat's server returns."""
    import meshcat

    recorder = offline_visualizer().window

    class Tee:
        def __init__(self, served):
            self.served = served

        def send(self, command):
            self.served.send(command)
            recorder.send(command)

    with open_visualizer() as served:
        both = meshcat.Visualizer(window=Tee(served.window))
        obstacle = {"kind": "circle", "x": 1.0, "y": 0.0, "radius": 0.1}
        facts = RunFacts(0.05, 0.1, np.array([[0.0, 60.0], [0.0, -60.0]]), (obstacle,))
        run_scene = RunScene(both, run["robot"], facts)
        points = [[5.0, 6.0], [7.0, 8.0]]
        run_scene.apply(run_scene.poses(run["log"]["q"][-1], np.eye(3)[:2], points))
        both["pbvs/targets"].set_property("visible", False)
        both["pbvs/obstacles/obstacle_0"].delete()
        served_html = served.static_html()
    assert served_html == recorder.get_scene()
    assert served_html.count("fetch(") > 20


def test_replay_needs_no_meshcat_server(run, tmp_path, monkeypatch):
    import meshcat.visualizer

    def no_server(*args, **kwargs):
        raise RuntimeError("the meshcat server process exited prematurely with exit code 1")

    monkeypatch.setattr(meshcat.visualizer, "start_zmq_server_as_subprocess", no_server)
    with pytest.raises(RuntimeError, match="exited prematurely"):
        meshcat.Visualizer()  # a served viewer is impossible now
    short = type(run["log"])({k: v[:20] for k, v in run["log"].channels.items()}, run["log"].meta)
    html = write_run_replay(short, tmp_path / "short.html").read_text(encoding="utf-8")
    assert "new MeshCat.Viewer(" in html and "viewer.connect(" not in html
    assert html.count("fetch(") > 20
