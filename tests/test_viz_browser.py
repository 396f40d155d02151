"""End-to-end check of the standalone HTML replay in a real headless browser.

The replay written by ``pbvs_pin.viz.write_replay_html`` is opened from a
``file://`` URL in Debian's Chromium (software WebGL through SwiftShader),
driven by Playwright.  Nothing is skipped: if Chromium or Playwright is
missing the tests fail and say how to install them.

Requirements (no browser download, ever -- do NOT run ``playwright install``)::

    apt-get update && apt-get install -y chromium     # /usr/bin/chromium
    pip install playwright

The Chromium binary can be overridden with ``PBVS_CHROMIUM=/path/to/chromium``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from browser import JS_DESCRIBE, JS_SET_VISIBLE, Page, chromium
from browser import geometry_placements as _geometry_placements
from browser import threejs_to_meshcat as _threejs_to_meshcat

# meshcat 0.3.2 imports a pyzmq module that pyzmq itself deprecates.
pytestmark = pytest.mark.filterwarnings(
    "ignore:zmq.eventloop.ioloop is deprecated:DeprecationWarning"
)

REPO_ROOT = Path(__file__).resolve().parents[1]
try:
    import pbvs_pin.viz as viz
except ImportError:  # running pytest without the repo on sys.path
    sys.path.insert(0, str(REPO_ROOT))
    import pbvs_pin.viz as viz

FPS = 30.0
DURATION = 2.0
SEEK_TIMES = (0.8, 1.6)  # keyframes (k = 24, 48 at 30 fps)
POSE_TOL = 1e-3


# --------------------------------------------------------------------------
# fixtures
# --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def browser():
    with chromium() as b:
        yield b


@pytest.fixture(scope="module")
def ur5_replay(tmp_path_factory):
    """UR5 on a seeded random smooth joint trajectory + two target spheres."""
    import example_robot_data

    robot = example_robot_data.load("ur5")
    model, visual_model = robot.model, robot.visual_model
    rng = np.random.default_rng(20240601)
    times = np.arange(round(DURATION * FPS) + 1) / FPS  # 61 keys, 0..2 s
    amp = rng.uniform(0.3, 0.9, size=(3, model.nq))
    freq = rng.uniform(0.5, 2.0, size=(3, model.nq))
    phase = rng.uniform(-np.pi, np.pi, size=(3, model.nq))
    q_mean = rng.uniform(-1.0, 1.0, size=model.nq)
    qs = np.array(
        [q_mean + (amp * np.sin(2 * np.pi * freq * t + phase)).sum(axis=0) for t in times]
    )

    html = tmp_path_factory.mktemp("replay") / "ur5_replay.html"
    with viz.open_visualizer() as vis:
        robot_scene = viz.RobotScene(vis, model, visual_model)
        spheres = viz.add_target_spheres(
            vis,
            [[0.45, 0.25, 0.35], [0.45, -0.25, 0.35]],
            diameter=0.08,
            color=[(1.0, 0.0, 0.0), (0.0, 0.0, 1.0)],
        )
        viz.set_camera_view(vis, [1.1, 0.8, 0.8])
        poses = robot_scene.trajectory_poses(qs)
        viz.write_replay_html(html, vis, times, poses, fps=FPS)

    assert robot_scene.failed == []
    return {
        "html": html,
        "model": model,
        "visual_model": visual_model,
        "times": times,
        "qs": qs,
        "robot_paths": dict(robot_scene.paths),
        "sphere_paths": spheres,
    }


@pytest.fixture(scope="module")
def ur5_page(browser, ur5_replay):
    page = Page(browser, ur5_replay["html"])
    robot_paths = list(ur5_replay["robot_paths"].values())
    page.wait_ready(
        ["meshcat/" + p for p in robot_paths + ur5_replay["sphere_paths"]],
        n_actions=len(robot_paths),
    )
    yield page
    page.page.close()


# --------------------------------------------------------------------------
# tests: UR5 replay
# --------------------------------------------------------------------------
def test_html_is_standalone(ur5_replay):
    # The meshcat server is already stopped here (open_visualizer() exited):
    # the page below loads from file:// with nothing to talk to.
    html = ur5_replay["html"].read_text(encoding="utf-8")
    assert "new MeshCat.Viewer(" in html
    commands = html.split("new MeshCat.Viewer(", 1)[1]
    assert "viewer.connect(" not in commands
    n_fetch = commands.count("fetch(")
    assert n_fetch > 0 and n_fetch == commands.count('fetch("data:'), "non-embedded resource"


def test_all_geometries_and_spheres_in_scene_tree(ur5_replay, ur5_page):
    model_names = [g.name for g in ur5_replay["visual_model"].geometryObjects]
    assert sorted(ur5_replay["robot_paths"]) == sorted(model_names)
    paths = ["meshcat/" + p for p in ur5_replay["robot_paths"].values()]
    spheres = ["meshcat/" + p for p in ur5_replay["sphere_paths"]]
    assert len(spheres) == 2
    desc = ur5_page.page.evaluate(JS_DESCRIBE, paths + spheres)
    for p in paths + spheres:
        assert desc[p]["found"], f"{p} not in viewer.scene_tree"
        assert desc[p]["type"] == "Mesh", f"{p}: {desc[p]}"
        assert desc[p]["vertices"] > 0, f"{p}: empty geometry"
    n_actions = ur5_page.page.evaluate("() => window.viewer.animator.actions.length")
    assert n_actions == len(paths)
    assert ur5_page.errors == []


@pytest.mark.parametrize("t_seek", SEEK_TIMES)
def test_seek_matches_pinocchio(ur5_replay, ur5_page, t_seek):
    times, qs = ur5_replay["times"], ur5_replay["qs"]
    k = int(np.argmin(np.abs(times - t_seek)))
    assert abs(times[k] - t_seek) < 1e-9, "seek time must be a keyframe"
    names = list(ur5_replay["robot_paths"])
    paths = ["meshcat/" + ur5_replay["robot_paths"][n] for n in names]

    res = ur5_page.seek(paths, float(t_seek))
    assert all(abs(t - t_seek) < 1e-9 for t in res["action_times"]), res["action_times"]
    S = np.array(res["scene"]).reshape(4, 4, order="F")
    np.testing.assert_allclose(S, viz.MESHCAT_TO_THREEJS, atol=1e-12)

    expected = _geometry_placements(ur5_replay["model"], ur5_replay["visual_model"], qs[k])
    initial = _geometry_placements(ur5_replay["model"], ur5_replay["visual_model"], qs[0])
    # the end link really moved: a no-op seek could not pass
    assert np.abs(expected["wrist_3_link_0"] - initial["wrist_3_link_0"]).max() > 0.05
    for name, path in zip(names, paths, strict=True):
        got = _threejs_to_meshcat(res["nodes"][path], res["scene"])
        err = np.abs(got - expected[name]).max()
        assert err < POSE_TOL, (
            f"{name} at t={t_seek}: max |dT| = {err:.2e}\n{got}\n{expected[name]}"
        )


def test_robot_really_renders(ur5_replay, ur5_page):
    paths = ["meshcat/" + p for p in ur5_replay["robot_paths"].values()]
    ur5_page.seek(paths, 1.0)
    shown = ur5_page.screenshot()
    assert ur5_page.page.evaluate(JS_SET_VISIBLE, ["meshcat/pbvs/robot", False]) is False
    hidden = ur5_page.screenshot()
    assert ur5_page.page.evaluate(JS_SET_VISIBLE, ["meshcat/pbvs/robot", True]) is True
    shown_again = ur5_page.screenshot()

    changed = (np.abs(shown - hidden).max(axis=2) > 40).mean()
    noise = (np.abs(shown - shown_again).max(axis=2) > 40).mean()
    assert changed > 0.005, f"only {changed:.2%} of the pixels change when hiding the robot"
    assert noise < 0.001, f"rendering not reproducible: {noise:.2%} pixels differ"
    assert ur5_page.errors == []


# --------------------------------------------------------------------------
# tests: primitive URDF robot + every scene helper
# --------------------------------------------------------------------------
PRIMITIVE_URDF = """<?xml version="1.0"?>
<robot name="prims">
  <link name="base">
    <visual><origin xyz="0 0 0.075"/><geometry><box size="0.4 0.3 0.15"/></geometry>
      <material name="grey"><color rgba="0.6 0.6 0.6 1"/></material></visual>
  </link>
  <link name="column">
    <visual><origin xyz="0 0 0.2"/><geometry><cylinder radius="0.04" length="0.4"/></geometry>
      <material name="blue"><color rgba="0.2 0.3 0.8 1"/></material></visual>
  </link>
  <link name="head">
    <visual><geometry><sphere radius="0.06"/></geometry>
      <material name="white"><color rgba="1 1 1 1"/></material></visual>
  </link>
  <joint name="x" type="prismatic"><parent link="world_dummy"/><child link="base"/>
    <axis xyz="1 0 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <link name="world_dummy"/>
  <joint name="yaw" type="revolute"><parent link="base"/><child link="column"/>
    <origin xyz="0.1 0 0.15"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="tilt" type="revolute"><parent link="column"/><child link="head"/>
    <origin xyz="0 0 0.4"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>
"""
FOCAL, WIDTH, HEIGHT = 400.0, 640, 480


def _camera_pose(model, data, q) -> np.ndarray:
    """Camera on the head, optical axis (z) along the head's x axis."""
    pin.forwardKinematics(model, data, q)
    R = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    return (data.oMi[model.getJointId("tilt")] * pin.SE3(R, np.array([0.07, 0, 0]))).homogeneous


def test_primitive_robot_and_helpers(browser, tmp_path):
    model = pin.buildModelFromXML(PRIMITIVE_URDF)
    visual_model = pin.buildGeomFromUrdfString(model, PRIMITIVE_URDF, pin.GeometryType.VISUAL)
    # a non-uniformly scaled primitive exercises the animated "scale" track
    import coal

    marker = pin.GeometryObject(
        "scaled_marker",
        model.getJointId("tilt"),
        pin.SE3(np.eye(3), np.array([0.0, 0.1, 0.0])),
        coal.Box(0.05, 0.05, 0.05),
    )
    marker.meshScale = np.array([2.0, 1.0, 0.5])
    marker.meshColor = np.array([1.0, 0.5, 0.0, 1.0])
    visual_model.addGeometryObject(marker)
    data = model.createData()
    times = np.arange(31) / FPS
    qs = np.array([[0.3 * t, 0.6 * np.sin(2 * t), 0.3 * t] for t in times])
    world_pts = np.array([[1.5, 0.15, 0.5], [1.5, -0.15, 0.5], [1.5, -0.15, 0.8], [1.5, 0.15, 0.8]])
    desired_uv = np.array([[220.0, 140.0], [420.0, 140.0], [420.0, 340.0], [220.0, 340.0]])

    def project(oMc, pts):
        cMo = np.linalg.inv(oMc)
        pc = (cMo[:3, :3] @ pts.T).T + cMo[:3, 3]
        return np.column_stack(
            [FOCAL * pc[:, 0] / pc[:, 2] + WIDTH / 2, FOCAL * pc[:, 1] / pc[:, 2] + HEIGHT / 2]
        )

    cam_poses = [_camera_pose(model, data, q) for q in qs]
    html = tmp_path / "prims.html"
    with viz.open_visualizer() as vis:
        robot = viz.RobotScene(vis, model, visual_model)
        obstacles = [
            viz.add_cylinder_obstacle(vis, "pillar", [0.8, 0.6], radius=0.1, height=1.0),
            viz.add_box_obstacle(vis, "crate", [0.8, -0.6], [0.3, 0.4, 0.5], yaw=0.3),
        ]
        spheres = viz.add_target_spheres(vis, world_pts[:2], 0.05, 0xFF00FF)
        frustum = viz.add_camera_frustum(vis, FOCAL, WIDTH, HEIGHT, depth=0.2, pose=cam_poses[0])
        img = viz.add_image_plane(
            vis,
            FOCAL,
            WIDTH,
            HEIGHT,
            desired_uv,
            current_uv=project(cam_poses[0], world_pts),
            depth=0.15,
        )
        trail = viz.add_trail(vis, np.array([T[:3, 3] for T in cam_poses]))
        robot_poses = robot.trajectory_poses(qs)

        def frame(k, t):
            out = {p: T[k] for p, T in robot_poses.items()}
            out[viz.CAMERA_PREFIX] = pin.SE3(cam_poses[k])
            out.update(
                viz.feature_point_poses(
                    project(cam_poses[k], world_pts), FOCAL, WIDTH, HEIGHT, depth=0.15
                )
            )
            return out

        viz.write_replay_html(html, vis, times, frame, fps=FPS)

    assert robot.failed == [] and len(robot.paths) == 4
    n_animated = len(robot.paths) + 1 + len(img["current"])
    static = obstacles + spheres + [frustum, trail] + img["plane"] + img["desired"]
    every = ["meshcat/" + p for p in list(robot.paths.values()) + static + img["current"]]
    page = Page(browser, html)
    try:
        page.wait_ready(every, n_actions=n_animated)
        desc = page.page.evaluate(JS_DESCRIBE, every)
        kinds = {p: d["type"] for p, d in desc.items()}
        assert kinds["meshcat/" + frustum] == "LineSegments"
        assert kinds["meshcat/" + trail] == "Line"
        assert all(d["vertices"] > 0 for d in desc.values()), desc

        k = 21
        res = page.seek(every, float(times[k]))
        expected = _geometry_placements(model, visual_model, qs[k])
        for name, path in robot.paths.items():
            got = _threejs_to_meshcat(res["nodes"]["meshcat/" + path], res["scene"])
            np.testing.assert_allclose(got, expected[name], atol=POSE_TOL, err_msg=name)
        # feature spheres compose camera pose (world) and image-plane offset (camera)
        uv = project(cam_poses[k], world_pts)
        pts_c = viz.pixels_to_image_plane(uv, FOCAL, WIDTH, HEIGHT, 0.15)
        for i, path in enumerate(img["current"]):
            got = _threejs_to_meshcat(res["nodes"]["meshcat/" + path], res["scene"])
            want = cam_poses[k] @ viz.translation_pose(pts_c[i])
            np.testing.assert_allclose(got, want, atol=POSE_TOL, err_msg=path)
        # the cylinder obstacle stands upright (three.js cylinders are Y-up)
        pillar = _threejs_to_meshcat(res["objects"]["meshcat/" + obstacles[0]], res["scene"])
        np.testing.assert_allclose(pillar[:3, 1], [0, 0, 1], atol=1e-9)
        np.testing.assert_allclose(pillar[:3, 3], [0.8, 0.6, 0.5], atol=1e-9)
        assert page.errors == []
    finally:
        page.page.close()


def test_viz_does_not_import_meshcat_eagerly():
    code = (
        "import sys, pbvs_pin.viz; "
        "assert 'meshcat' not in sys.modules, 'pbvs_pin.viz imported meshcat'"
    )
    env = dict(
        os.environ, PYTHONPATH=str(REPO_ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        cwd=REPO_ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
