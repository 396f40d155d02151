"""Shared fixtures of the model-layer tests.

Robots are loaded once per session (TIAGo and the example-robot-data arms take about a second
each). Helpers that the tests use as *independent references* (rotation matrices, the pinhole
projection, URDF parsing, the closed-form kinematics of the reference robot) are written here
from scratch, without the package under test.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before any MuJoCo import: headless rendering

import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from file_times import pytest_runtest_logreport, pytest_terminal_summary  # noqa: F401 (hooks)

import pbvs_pin

REPO_ROOT = Path(__file__).resolve().parents[1]
URDF_DIR = REPO_ROOT / "urdf"
DATA_DIR = Path(__file__).resolve().parent / "data"

ARM_ROBOTS = ("pioneer_ur5", "pioneer_panda", "pioneer_z1", "pioneer_kinova", "pioneer_xarm7")
"""The example-robot-data arms shipped on the reference platform."""


# ---------------------------------------------------------------- independent math helpers
def rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF convention: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def pinhole(focal: float, point_in_camera: np.ndarray) -> np.ndarray:
    """The paper's eq. (2), written independently: xi = -(f / z) [x, y]."""
    x, y, z = point_in_camera
    assert z > 0.0, "test setup error: point behind the camera"
    return np.array([-focal * x / z, -focal * y / z])


def project_world(focal: float, pose: pin.SE3, point_world: np.ndarray) -> np.ndarray:
    """Project a world point through a camera at ``pose`` (world_T_camera)."""
    in_camera = pose.rotation.T @ (np.asarray(point_world) - pose.translation)
    return pinhole(focal, in_camera)


def planar_pose(q: np.ndarray) -> pin.SE3:
    """world_T_base of a planar root joint q[:4] = [x, y, cos th, sin th]."""
    theta = np.arctan2(q[3], q[2])
    return pin.SE3(rot_z(theta), np.array([q[0], q[1], 0.0]))


def points_in_front(
    pose: pin.SE3, rng: np.random.Generator, count: int, near: float = 0.8, far: float = 2.0
) -> list[np.ndarray]:
    """Random world points 0.8-2 m in front of a camera, well inside its field of view."""
    points = []
    for _ in range(count):
        z = rng.uniform(near, far)
        in_camera = np.array([z * rng.uniform(-0.35, 0.35), z * rng.uniform(-0.35, 0.35), z])
        points.append(pose.rotation @ in_camera + pose.translation)
    return points


def random_configuration(robot: pbvs_pin.MobileManipulator, rng: np.random.Generator) -> np.ndarray:
    """A random configuration built from the Pinocchio model's joint list.

    Planar root: x, y in [-2, 2] m, heading in (-pi, pi]. Arm joints: uniform inside their
    limits (0.1 away from each limit, clipped to [-pi, pi]); continuous joints any angle.
    """
    model = robot.model
    q = pin.neutral(model)
    theta = rng.uniform(-np.pi, np.pi)
    q[:4] = [rng.uniform(-2, 2), rng.uniform(-2, 2), np.cos(theta), np.sin(theta)]
    for joint_id in range(2, model.njoints):
        joint = model.joints[joint_id]
        if joint.nq == 2:  # continuous joint: (cos, sin)
            angle = rng.uniform(-np.pi, np.pi)
            q[joint.idx_q : joint.idx_q + 2] = np.cos(angle), np.sin(angle)
        else:
            lower = max(model.lowerPositionLimit[joint.idx_q], -np.pi)
            upper = min(model.upperPositionLimit[joint.idx_q], np.pi)
            margin = min(0.1, 0.25 * (upper - lower))
            q[joint.idx_q] = rng.uniform(lower + margin, upper - margin)
    return q


# ---------------------------------------------------------------- URDF parsing (xml.etree)
def urdf_joints(path: Path) -> dict[str, dict]:
    """Joints of a URDF file: name -> type, parent, child, xyz, rpy, axis, velocity limit."""
    joints = {}
    for element in ET.parse(path).getroot().findall("joint"):
        origin = element.find("origin")
        axis = element.find("axis")
        limit = element.find("limit")
        joints[element.get("name")] = {
            "type": element.get("type"),
            "parent": element.find("parent").get("link"),
            "child": element.find("child").get("link"),
            "xyz": np.array(
                [
                    float(v)
                    for v in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()
                ]
            ),
            "rpy": np.array(
                [
                    float(v)
                    for v in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()
                ]
            ),
            "axis": np.array([float(v) for v in axis.get("xyz").split()])
            if axis is not None
            else None,
            "velocity": float(limit.get("velocity")) if limit is not None else None,
        }
    return joints


def urdf_link_masses(path: Path) -> dict[str, float]:
    """Link name -> mass [kg] (0 for a link without <inertial>)."""
    masses = {}
    for link in ET.parse(path).getroot().findall("link"):
        mass = link.find("inertial/mass")
        masses[link.get("name")] = float(mass.get("value")) if mass is not None else 0.0
    return masses


def urdf_wheels(path: Path) -> list[tuple[np.ndarray, float, float]]:
    """Drive wheels (continuous joints with a y axis on the root link): (centre, radius, speed)."""
    root = ET.parse(path).getroot()
    radii = {}
    for link in root.findall("link"):
        cylinder = link.find("collision/geometry/cylinder")
        if cylinder is not None:
            radii[link.get("name")] = float(cylinder.get("radius"))
    wheels = []
    for joint in urdf_joints(path).values():
        if (
            joint["type"] == "continuous"
            and joint["axis"] is not None
            and abs(joint["axis"][1]) == 1
        ):
            wheels.append((joint["xyz"], radii[joint["child"]], joint["velocity"]))
    return wheels


# ---------------------------------------------------------------- closed-form reference robot
class CytonClosedForm:
    """Hand-written kinematics of pioneer_cyton, offsets read from its URDF.

    Configuration: platform (x, y, th), arm (q1 yaw about z, q2 pitch about y, q3 pitch
    about y). Velocity: (u, omega, q1dot, q2dot, q3dot).
    """

    def __init__(self, urdf_path) -> None:
        joints = urdf_joints(urdf_path)
        zero = np.zeros(3)

        def get(name, *, kind, parent=None, child=None):
            joint = joints[name]
            assert joint["type"] == kind, name
            if parent is not None:
                assert joint["parent"] == parent, name
            if child is not None:
                assert joint["child"] == child, name
            return joint

        # The structure the closed form below assumes; the values are the ones of the brief.
        mount = get("arm_mount_joint", kind="fixed", parent="base_link", child="arm_mount_link")
        np.testing.assert_allclose(mount["xyz"], [0.10, 0.0, 0.27])
        np.testing.assert_array_equal(mount["rpy"], zero)
        to_cyton = get("arm_mount_to_cyton", kind="fixed", parent="arm_mount_link")
        np.testing.assert_array_equal(to_cyton["xyz"], zero)
        np.testing.assert_array_equal(to_cyton["rpy"], zero)
        yaw = get("shoulder_yaw_joint", kind="revolute", parent="cyton_base_link")
        pitch = get("shoulder_pitch_joint", kind="revolute", parent=yaw["child"])
        elbow = get("elbow_pitch_joint", kind="revolute", parent=pitch["child"])
        wrist = get("wrist_joint", kind="fixed", parent=elbow["child"])
        camera = get("camera_joint", kind="fixed", parent=wrist["child"])
        optical = get(
            "camera_optical_joint",
            kind="fixed",
            parent=camera["child"],
            child="camera_optical_frame",
        )
        np.testing.assert_array_equal(yaw["axis"], [0, 0, 1])
        np.testing.assert_array_equal(pitch["axis"], [0, 1, 0])
        np.testing.assert_array_equal(elbow["axis"], [0, 1, 0])
        for joint in (yaw, pitch, elbow, wrist, camera):  # offsets along the link's z only
            np.testing.assert_array_equal(joint["xyz"][:2], [0, 0])
        for joint in (yaw, pitch, wrist):
            np.testing.assert_array_equal(joint["rpy"], zero)
        for joint in (elbow, camera):  # a pure pitch
            assert joint["rpy"][0] == 0 and joint["rpy"][2] == 0
        np.testing.assert_array_equal(optical["xyz"][1:], [0, 0])
        assert optical["rpy"][1] == 0
        np.testing.assert_allclose(
            [yaw["xyz"][2], pitch["xyz"][2], elbow["xyz"][2], elbow["rpy"][1], wrist["xyz"][2]],
            [0.06, 0.05, 0.20, 2.1863, 0.20],
        )

        # Drive footprint: floor point below the mean of the wheel centres.
        wheels = urdf_wheels(urdf_path)
        assert len(wheels) == 4
        centre = np.mean([c for c, _, _ in wheels], axis=0)
        radius = np.mean([r for _, r, _ in wheels])
        footprint = np.array([centre[0], centre[1], centre[2] - radius])
        np.testing.assert_allclose(footprint, zero, atol=1e-12)  # identical to base_link

        self.mx, self.my = mount["xyz"][:2] - footprint[:2]
        self.h0 = mount["xyz"][2] - footprint[2] + yaw["xyz"][2] + pitch["xyz"][2]
        self.l1 = elbow["xyz"][2]
        self.l2 = wrist["xyz"][2] + camera["xyz"][2]
        self.beta = elbow["rpy"][1]
        self.gamma = camera["rpy"][1]
        self.dx = optical["xyz"][0]
        self.optical_rotation = rpy_matrix(*optical["rpy"])

    def _angles(self, q2, q3):
        a1 = q2
        a2 = q2 + self.beta + q3
        a3 = a2 + self.gamma
        return a1, a2, a3

    def _arm_plane(self, q2, q3):
        """Radial distance r and height h of the camera point, and their partials."""
        a1, a2, a3 = self._angles(q2, q3)
        l1, l2, dx = self.l1, self.l2, self.dx
        r = l1 * np.sin(a1) + l2 * np.sin(a2) + dx * np.cos(a3)
        h = self.h0 + l1 * np.cos(a1) + l2 * np.cos(a2) - dx * np.sin(a3)
        dr_dq2 = l1 * np.cos(a1) + l2 * np.cos(a2) - dx * np.sin(a3)
        dh_dq2 = -l1 * np.sin(a1) - l2 * np.sin(a2) - dx * np.cos(a3)
        dr_dq3 = l2 * np.cos(a2) - dx * np.sin(a3)
        dh_dq3 = -l2 * np.sin(a2) - dx * np.cos(a3)
        return r, h, (dr_dq2, dh_dq2), (dr_dq3, dh_dq3)

    def pose(self, x, y, th, q1, q2, q3):
        """world_T_camera: position (3,) and rotation (3, 3)."""
        r, h, _, _ = self._arm_plane(q2, q3)
        in_base = np.array([self.mx + r * np.cos(q1), self.my + r * np.sin(q1), h])
        position = np.array([x, y, 0.0]) + rot_z(th) @ in_base
        _, _, a3 = self._angles(q2, q3)
        rotation = rot_z(th + q1) @ rot_y(a3) @ self.optical_rotation
        return position, rotation

    def world_jacobian(self, x, y, th, q1, q2, q3):
        """Linear velocity of the camera origin and angular velocity, world frame. (3, 5) each."""
        r, h, (dr2, dh2), (dr3, dh3) = self._arm_plane(q2, q3)
        in_base = np.array([self.mx + r * np.cos(q1), self.my + r * np.sin(q1), h])
        c1, s1 = np.cos(q1), np.sin(q1)
        linear_in_base = np.column_stack(
            [
                [1.0, 0.0, 0.0],  # u: the axle midpoint moves along the platform's x
                [-in_base[1], in_base[0], 0.0],  # omega: e_z x p
                [-r * s1, r * c1, 0.0],  # q1
                [dr2 * c1, dr2 * s1, dh2],  # q2
                [dr3 * c1, dr3 * s1, dh3],  # q3
            ]
        )
        pitch_axis = [-np.sin(th + q1), np.cos(th + q1), 0.0]
        angular = np.column_stack([[0, 0, 0], [0, 0, 1], [0, 0, 1], pitch_axis, pitch_axis])
        return rot_z(th) @ linear_in_base, angular.astype(float)


# ---------------------------------------------------------------- the quick subset
SLOW_FILES = (
    "test_ros.py",
    "test_readme_numbers_arms.py",
    "test_readme_numbers_mujoco.py",
    "test_compile_cache.py",
    "test_mujoco_acceptance.py",
    "test_readme_numbers.py",
    "test_render.py",
    "test_docs.py",
    "test_knobs.py",
    "test_viz_live.py",
    "test_controller_outside.py",
    "test_experiments.py",
    "test_upright.py",
    "test_zoo.py",
    "test_arm_chain.py",
    "test_any_robot.py",
    "test_prediction.py",
    "test_sweep.py",
    "test_mujoco_stability.py",
    "test_examples.py",
    "test_robot_spec.py",
    "test_assembly.py",
    "test_fuzz.py",
)
"""The 23 test files that took the longest in a fresh clone's full run, slowest first (the
per-file times the suite prints at its end; 9.6-101 s each, 2026-12-05).

Two uses:

- They are marked ``slow``: the quick subset (``python -m pytest -m "not slow"``, the
  README's) leaves them out. The other files took 160 of the run's 917 s of worker time.
- They run first, in this order. With ``--dist loadfile`` a file runs whole on one worker;
  handing out the longest files first lets the two workers finish together (a 100 s file
  dealt last kept one worker busy alone for up to 100 s). ``pyproject.toml`` asks
  pytest-xdist to keep this order (``--no-loadscope-reorder``; by default it deals the files
  with the most tests first)."""


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark every test of :data:`SLOW_FILES` ``slow`` and move those files to the front.

    The sort is stable: each file's tests keep their order, and the other files theirs.
    """
    rank = {name: i for i, name in enumerate(SLOW_FILES)}
    for item in items:
        if item.path.name in rank:
            item.add_marker(pytest.mark.slow)
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


# ---------------------------------------------------------------- fixtures
@pytest.fixture(scope="session")
def load() -> Callable[[str], pbvs_pin.MobileManipulator]:
    """``load(name)``: a shipped robot, loaded at most once per session."""
    cache: dict[str, pbvs_pin.MobileManipulator] = {}

    def _load(name: str) -> pbvs_pin.MobileManipulator:
        if name not in cache:
            cache[name] = pbvs_pin.load_robot(name)
        return cache[name]

    return _load


@pytest.fixture(scope="session")
def cyton(load) -> pbvs_pin.MobileManipulator:
    """The paper's reference robot."""
    return load("pioneer_cyton")


@pytest.fixture(scope="session")
def tiago_pro() -> pbvs_pin.MobileManipulator:
    """PAL TIAGo Pro on its mecanum base (the zoo's robot file), loaded once per session."""
    import warnings

    from pbvs_pin.sim.sections import RobotSection
    from pbvs_pin.study.zoo import load_zoo

    robot_file = next(r for r in load_zoo(REPO_ROOT / "robots") if r.name == "tiago_pro")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # placement warnings
        return RobotSection.from_toml(robot_file.table, str(robot_file.path)).build()


@pytest.fixture(scope="session")
def cyton_urdf() -> Path:
    return URDF_DIR / "pioneer_cyton.urdf"


@pytest.fixture(scope="session")
def closed_form(cyton_urdf) -> CytonClosedForm:
    """Hand-written kinematics of the reference robot, offsets parsed from its URDF."""
    return CytonClosedForm(cyton_urdf)
