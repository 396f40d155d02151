"""Mounting example-robot-data arms on the reference platform.

Reference: each arm's own forward kinematics from a separate Pinocchio model loaded with
``example_robot_data.load``, composed by hand with the platform pose, the drive footprint
(parsed from pioneer3at.urdf), the mount and the camera pose.
"""

from __future__ import annotations

import example_robot_data
import numpy as np
import pinocchio as pin
import pytest
from conftest import DATA_DIR, URDF_DIR, planar_pose, random_configuration, rpy_matrix, urdf_wheels

import pbvs_pin
from pbvs_pin import MobileManipulator

CAMERA_LINKS = {
    "ur5": "tool0",
    "panda": "panda_hand_tcp",
    "z1": "link06",
    "kinova": "j2s6s200_end_effector",
    "xarm7": "link_eef",
}
MOUNT = (0.12, -0.03, 0.27, 0.05, -0.08, 0.4)  # x, y, z [m], roll, pitch, yaw [rad]
CAMERA_POSE = (0.01, 0.02, 0.05, -1.4, 0.1, -1.6)


def _se3(xyz_rpy) -> pin.SE3:
    """URDF-style (x, y, z, roll, pitch, yaw) as SE3, with our own rpy matrix."""
    return pin.SE3(rpy_matrix(*xyz_rpy[3:]), np.array(xyz_rpy[:3], dtype=float))


def _footprint_to_base() -> pin.SE3:
    """footprint_T_base_link for pioneer3at: floor point under the mean wheel centre."""
    wheels = urdf_wheels(URDF_DIR / "pioneer3at.urdf")
    centre = np.mean([c for c, _, _ in wheels], axis=0)
    radius = np.mean([r for _, r, _ in wheels])
    footprint_in_base = np.array([centre[0], centre[1], centre[2] - radius])
    return pin.SE3(np.eye(3), -footprint_in_base)


@pytest.fixture(scope="module")
def arm_model():
    cache = {}

    def _arm(name):
        if name not in cache:
            cache[name] = example_robot_data.load(name).model
        return cache[name]

    return _arm


@pytest.fixture(scope="module")
def assembled():
    cache = {}

    def _assembled(name, mount_kind):
        key = (name, mount_kind)
        if key not in cache:
            if mount_kind == "vector":
                mount, camera_pose = MOUNT, CAMERA_POSE
            else:
                mount, camera_pose = _se3(MOUNT), _se3(CAMERA_POSE)
            cache[key] = MobileManipulator.assemble(
                base="pioneer3at",
                arm=name,
                mount=mount,
                camera_link=CAMERA_LINKS[name],
                camera_pose=camera_pose,
            )
        return cache[key]

    return _assembled


def _chain_joints(model: pin.Model, link: str) -> list[int]:
    """Joints (ids) between the model's root and a link."""
    parent = model.frames[model.getFrameId(link)].parentJoint
    return [j for j in model.supports[parent] if j > 0]


def _robot_joint_name(robot, arm_name: str) -> str:
    """A joint's name in the assembled robot (an ``arm_`` prefix resolves clashes)."""
    if robot.model.existJointName(arm_name):
        return arm_name
    assert robot.model.existJointName(f"arm_{arm_name}"), arm_name
    return f"arm_{arm_name}"


def _expected_camera_pose(robot, arm, link, q, mount, camera_pose) -> pin.SE3:
    """world_T_camera = world_T_footprint * footprint_T_base * mount * arm FK * camera_pose."""
    q_arm = pin.neutral(arm)
    for joint_id in _chain_joints(arm, link):
        src = robot.model.joints[
            robot.model.getJointId(_robot_joint_name(robot, arm.names[joint_id]))
        ]
        dst = arm.joints[joint_id]
        assert src.nq == dst.nq
        q_arm[dst.idx_q : dst.idx_q + dst.nq] = q[src.idx_q : src.idx_q + src.nq]
    data = arm.createData()
    pin.framesForwardKinematics(arm, data, q_arm)
    arm_fk = data.oMf[arm.getFrameId(link)]
    return planar_pose(q) * _footprint_to_base() * mount * arm_fk * camera_pose


@pytest.mark.parametrize("name", list(CAMERA_LINKS))
def test_assembled_dof_and_camera_pose(assembled, arm_model, name):
    robot = assembled(name, "vector")
    arm = arm_model(name)
    link = CAMERA_LINKS[name]
    chain = _chain_joints(arm, link)
    assert robot.n == 2 + sum(arm.joints[j].nv for j in chain)
    assert robot.arm_joint_names == tuple(_robot_joint_name(robot, arm.names[j]) for j in chain)

    mount, camera_pose = _se3(MOUNT), _se3(CAMERA_POSE)
    q0 = robot.neutral()
    expected = _expected_camera_pose(robot, arm, link, q0, mount, camera_pose)
    actual = robot.camera_pose(q0)
    np.testing.assert_allclose(actual.translation, expected.translation, atol=1e-9)
    np.testing.assert_allclose(actual.rotation, expected.rotation, atol=1e-9)

    rng = np.random.default_rng([61, len(name)])
    for _ in range(3):
        q = random_configuration(robot, rng)
        expected = _expected_camera_pose(robot, arm, link, q, mount, camera_pose)
        actual = robot.camera_pose(q)
        np.testing.assert_allclose(actual.translation, expected.translation, atol=1e-9)
        np.testing.assert_allclose(actual.rotation, expected.rotation, atol=1e-9)


@pytest.mark.parametrize("name", ["ur5", "xarm7"])  # the two fastest to build
def test_mount_as_vector_or_se3_gives_same_model(assembled, name):
    a = assembled(name, "vector")
    b = assembled(name, "se3")
    assert (a.model.nq, a.model.nv, a.n) == (b.model.nq, b.model.nv, b.n)
    assert list(a.model.names) == list(b.model.names)
    for pa, pb in zip(a.model.jointPlacements, b.model.jointPlacements, strict=True):
        np.testing.assert_allclose(pa.homogeneous, pb.homogeneous, atol=1e-12)
    for ia, ib in zip(a.model.inertias, b.model.inertias, strict=True):
        assert ia.mass == pytest.approx(ib.mass, rel=1e-12)
        np.testing.assert_allclose(ia.lever, ib.lever, atol=1e-12)
        np.testing.assert_allclose(ia.inertia, ib.inertia, atol=1e-12)
    rng = np.random.default_rng([62, len(name)])
    q = random_configuration(a, rng)
    np.testing.assert_allclose(
        a.camera_pose(q).homogeneous, b.camera_pose(q).homogeneous, atol=1e-12
    )
    np.testing.assert_allclose(a.camera_jacobian(q), b.camera_jacobian(q), atol=1e-12)


def test_reference_robot_chain(cyton):
    assert cyton.n == 5
    assert cyton.arm_joint_names == (
        "shoulder_yaw_joint",
        "shoulder_pitch_joint",
        "elbow_pitch_joint",
    )
    # Wheels are locked: they are not on the camera chain.
    assert not any("wheel" in name for name in cyton.model.names)
    np.testing.assert_array_equal(cyton.home_arm, np.zeros(3))


def test_arm_with_its_own_optical_frame_matches_the_shipped_assembly():
    mount = pin.SE3(np.eye(3), np.array([0.10, 0.0, 0.27]))
    assembled = pbvs_pin.MobileManipulator.assemble(
        base="pioneer3at", arm="cyton_alpha3", mount=mount, camera_link="camera_optical_frame"
    )
    shipped = pbvs_pin.load_robot("pioneer_cyton")
    q = shipped.with_arm_positions(shipped.neutral(), [0.3, -0.4, 0.5])
    expected = shipped.camera_pose(q)
    got = assembled.camera_pose(q)
    np.testing.assert_allclose(got.homogeneous, expected.homogeneous, atol=1e-12)
    with pytest.raises(pbvs_pin.UrdfError, match="identity camera_pose"):
        pbvs_pin.MobileManipulator.assemble(
            base="pioneer3at", arm="cyton_alpha3", mount=mount,
            camera_link="camera_optical_frame", camera_pose=(0, 0, 0.1, 0, 0, 0),
        )  # fmt: skip


@pytest.mark.parametrize("name", ["pioneer_ur5", "tiago"])
def test_written_urdf_loads_as_the_same_robot(load, tmp_path, name):
    """write_urdf then from_urdf: same joints, masses, drive, camera pose and Jacobian."""
    robot = load(name)
    path = robot.write_urdf(tmp_path / f"{name}.urdf")
    again = MobileManipulator.from_urdf(str(path), camera_frame=robot.camera_frame)
    assert (again.model.nq, again.model.nv, again.n) == (robot.model.nq, robot.model.nv, robot.n)
    assert again.arm_joint_names == robot.arm_joint_names
    assert again.base == robot.base  # same wheel radius, track and wheel speed limit
    np.testing.assert_allclose(again.velocity_limits, robot.velocity_limits, rtol=1e-12)
    for a, b in zip(again.model.inertias, robot.model.inertias, strict=True):
        assert a.mass == pytest.approx(b.mass, rel=1e-12)
        np.testing.assert_allclose(a.lever, b.lever, atol=1e-9)
        np.testing.assert_allclose(a.inertia, b.inertia, atol=1e-9)
    assert again.visual_model.ngeoms == robot.visual_model.ngeoms
    rng = np.random.default_rng([63, len(name)])
    for _ in range(3):
        q = random_configuration(robot, rng)
        np.testing.assert_allclose(
            again.camera_pose(q).homogeneous, robot.camera_pose(q).homogeneous, atol=1e-9
        )
        np.testing.assert_allclose(again.camera_jacobian(q), robot.camera_jacobian(q), atol=1e-9)
    # The file stands alone: no package:// URI is left, every mesh path is absolute.
    text = path.read_text()
    assert "package://" not in text


DRIVE_KEYS = ("wheel_radius", "track", "wheel_speed_limit", "DifferentialDrive(")


@pytest.mark.parametrize(
    ("edit", "problem"),
    [
        (lambda text: text, "no usable drive axle"),  # no_wheels.urdf as is
        (
            lambda text: text.replace('<limit effort="10" velocity="5.0"/>', ""),
            "no <limit velocity=...>",
        ),
        (
            lambda text: text.replace(
                '<cylinder radius="0.08" length="0.04"/>', '<mesh filename="wheel.stl"/>'
            ),
            "no cylinder or sphere geometry",
        ),
    ],
    ids=["no-wheels", "no-velocity-limit", "mesh-wheels"],
)
def test_drive_errors_name_the_parameters_to_add(tmp_path, edit, problem):
    source = DATA_DIR / (
        "no_wheels.urdf" if problem.startswith("no usable") else "fixed_chain.urdf"
    )
    path = tmp_path / source.name
    path.write_text(edit(source.read_text()))
    with pytest.raises(pbvs_pin.DriveAxleNotFound) as info:
        MobileManipulator.from_urdf(str(path))
    message = str(info.value)
    assert problem in message
    for key in DRIVE_KEYS:
        assert key in message


def test_explicit_drive_parameters_replace_the_missing_wheels():
    """The advice of the errors above works: a differential drive given explicitly."""
    drive = pbvs_pin.DifferentialDrive(wheel_radius=0.1, track=0.4, max_wheel_speed=5.0)
    robot = MobileManipulator.from_urdf(str(DATA_DIR / "no_wheels.urdf"), base=drive)
    assert robot.n == 3
    np.testing.assert_allclose(robot.velocity_limits[:2], [0.5, 2.5])  # r w, 2 r w / track


def test_an_arm_whose_first_joint_pitches_about_y_is_not_a_wheel():
    """An arm mounted rolled by pi/2 turns its pan axis onto the platform's -y, beside the
    wheels: it carries a chain, so the drive axle stays the Pioneer's four wheels (its URDF:
    r 0.1075 m, 6.5 rad/s)."""
    robot = MobileManipulator.assemble(
        base="pioneer3at",
        arm=str(DATA_DIR / "continuous_arm.urdf"),
        mount=(0.10, 0.15, 0.27, np.pi / 2, 0.0, 0.0),
        camera_link="tool_link",
    )
    assert robot.base.wheel_radius == pytest.approx(0.1075)
    assert robot.base.max_wheel_speed == pytest.approx(6.5)
    assert robot.velocity_names[2:] == ("pan_joint", "shoulder_joint", "elbow_joint")
