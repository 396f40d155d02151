"""One test per kind of user mistake: the right exception, with a message naming the culprit.

Small URDF files for the bad robots are in ``tests/data/``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import DATA_DIR, URDF_DIR

import pbvs_pin
from pbvs_pin import (
    CameraIntrinsics,
    DriveAxleNotFound,
    FrameNotFound,
    GainError,
    ImagePointFeatures,
    MobileManipulator,
    NoMovableJoint,
    NonFiniteValue,
    PbvsError,
    PointBehindCamera,
    RobotNotFound,
    ScenarioError,
    ShapeError,
    TwoSphereFeatures,
    UrdfError,
)

CYTON_URDF = URDF_DIR / "pioneer_cyton.urdf"


@pytest.mark.parametrize(
    "error",
    [
        UrdfError,
        FrameNotFound,
        NoMovableJoint,
        DriveAxleNotFound,
        ShapeError,
        NonFiniteValue,
        GainError,
        PointBehindCamera,
        RobotNotFound,
        ScenarioError,
    ],
)
def test_every_error_is_a_pbvs_error(error):
    assert issubclass(error, PbvsError)
    assert not issubclass(error, (ValueError, KeyError, RuntimeError))


# ---------------------------------------------------------------- URDF files
@pytest.mark.parametrize(
    "content",
    ["this is not xml at all", "", '<?xml version="1.0"?>\n<notrobot/>\n'],
    ids=["garbage", "empty", "not-a-robot"],
)
def test_unreadable_urdf_names_the_file(tmp_path, content):
    path = tmp_path / "broken_robot.urdf"
    path.write_text(content)
    with pytest.raises(UrdfError) as info:
        MobileManipulator.from_urdf(str(path))
    assert str(path) in str(info.value)


@pytest.mark.parametrize("damage", ["truncated", "mismatched-tag"])
def test_malformed_xml_urdf_names_the_file(tmp_path, damage):
    text = CYTON_URDF.read_text()
    if damage == "truncated":
        text = text[: len(text) - 40]  # cut inside the last <origin .../>
    else:
        text = text.replace(
            '</link>\n  <link name="camera_optical_frame"/>',
            '</lnk>\n  <link name="camera_optical_frame"/>',
        )
    path = tmp_path / f"{damage}.urdf"
    path.write_text(text)
    with pytest.raises(UrdfError) as info:
        MobileManipulator.from_urdf(str(path))
    assert str(path) in str(info.value)


def test_missing_urdf_file_names_the_file(tmp_path):
    path = tmp_path / "nowhere" / "robot.urdf"
    with pytest.raises(UrdfError, match=r"robot\.urdf") as info:
        pbvs_pin.load_robot(str(path))
    assert str(path) in str(info.value)


# ---------------------------------------------------------------- frames
def test_missing_camera_frame_lists_available_frames():
    with pytest.raises(FrameNotFound) as info:
        MobileManipulator.from_urdf(str(CYTON_URDF), camera_frame="kinect_rgb_optical")
    message = str(info.value)
    assert "kinect_rgb_optical" in message
    assert "camera_link" in message and "wrist_link" in message  # real names
    assert "pioneer_cyton.urdf" in message
    assert "camera_optical_frame" in info.value.available


def test_missing_camera_link_in_arm_lists_arm_links():
    with pytest.raises(FrameNotFound) as info:
        MobileManipulator.assemble(
            base="pioneer3at", arm=str(DATA_DIR / "one_joint_arm.urdf"), camera_link="flange"
        )
    message = str(info.value)
    assert "'flange'" in message
    assert "tool_link" in message and "pan_link" in message
    assert "one_joint_arm.urdf" in message


def test_unknown_frame_query_lists_frames(cyton):
    with pytest.raises(FrameNotFound, match="gripper_frame") as info:
        cyton.frame_pose(cyton.home(), "gripper_frame")
    assert "shoulder_yaw_joint" in str(info.value)


# ---------------------------------------------------------------- robot structure
@pytest.mark.parametrize("base", ["differential", "fixed"])
def test_camera_on_fixed_chain_has_no_movable_joint(base):
    path = DATA_DIR / "fixed_chain.urdf"
    with pytest.raises(NoMovableJoint) as info:
        MobileManipulator.from_urdf(str(path), base=base)
    assert "fixed_chain.urdf" in str(info.value)
    assert "camera_optical_frame" in str(info.value)


def test_rigid_arm_has_no_movable_joint():
    with pytest.raises(NoMovableJoint) as info:
        MobileManipulator.assemble(
            base="pioneer3at", arm=str(DATA_DIR / "fixed_arm.urdf"), camera_link="tool_link"
        )
    assert "fixed_arm.urdf" in str(info.value)


def test_smallest_valid_arm_assembles():
    # Control for the two tests above and below: the same files with one joint do work.
    robot = MobileManipulator.assemble(
        base="pioneer3at", arm=str(DATA_DIR / "one_joint_arm.urdf"), camera_link="tool_link"
    )
    assert robot.n == 3
    assert robot.arm_joint_names == ("pan_joint",)
    assert robot.velocity_limits[2] == pytest.approx(0.8)


def test_platform_without_wheels_has_no_drive_axle():
    with pytest.raises(DriveAxleNotFound) as info:
        MobileManipulator.from_urdf(str(DATA_DIR / "no_wheels.urdf"))
    assert "no_wheels.urdf" in str(info.value)
    assert "base_link" in str(info.value)
    # The same file is fine for a holonomic base: the axle is what is missing.
    assert (
        MobileManipulator.from_urdf(str(DATA_DIR / "no_wheels.urdf"), base="omnidirectional").n == 4
    )


def test_wheels_on_one_side_only_have_no_drive_axle():
    with pytest.raises(DriveAxleNotFound) as info:
        MobileManipulator.from_urdf(str(DATA_DIR / "one_side_wheels.urdf"))
    message = str(info.value)
    assert "one_side_wheels.urdf" in message
    assert "front_left_wheel_joint" in message and "rear_left_wheel_joint" in message


def test_box_platform_assembly_has_no_drive_axle():
    with pytest.raises(DriveAxleNotFound, match=r"box_platform\.urdf"):
        MobileManipulator.assemble(
            base=str(DATA_DIR / "box_platform.urdf"),
            arm=str(DATA_DIR / "one_joint_arm.urdf"),
            camera_link="tool_link",
        )


def test_unknown_robot_name_lists_shipped_robots():
    with pytest.raises(RobotNotFound) as info:
        pbvs_pin.load_robot("pioneer_cyton_mk2")
    assert "'pioneer_cyton_mk2'" in str(info.value)
    for name in pbvs_pin.ROBOT_NAMES:
        assert name in str(info.value)


def test_unknown_base_kind_is_a_gain_error():
    with pytest.raises(GainError, match="legged"):
        MobileManipulator.from_urdf(str(CYTON_URDF), base="legged")


# ---------------------------------------------------------------- values and shapes
def test_point_behind_camera_gives_its_depth(cyton):
    q = cyton.home()
    pose = cyton.camera_pose(q)
    in_front = pose.act(np.array([0.0, 0.1, 1.5]))
    behind = pose.act(np.array([0.05, 0.0, -1.3]))
    with pytest.raises(PointBehindCamera, match=r"-1\.3") as info:
        TwoSphereFeatures(diameter=0.1).jacobians(cyton, q, in_front, behind)
    assert info.value.depth == pytest.approx(-1.3)
    with pytest.raises(PointBehindCamera, match=r"-2\.5"):
        CameraIntrinsics().project([0.0, 0.0, -2.5])
    with pytest.raises(PointBehindCamera):
        CameraIntrinsics().project([0.1, 0.0, 0.0])  # on the image plane


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_configuration(cyton, bad):
    q = cyton.home()
    q[5] = bad
    for query in (cyton.camera_pose, cyton.camera_jacobian, cyton.base_pose):
        with pytest.raises(NonFiniteValue, match=r"^q: "):
            query(q)
    rng = np.random.default_rng(71)
    points = [rng.uniform(-1, 1, 3) for _ in range(2)]
    with pytest.raises(NonFiniteValue, match=r"^q: "):
        TwoSphereFeatures(diameter=0.1).jacobians(cyton, q, *points)


def test_non_finite_target_point(cyton):
    q = cyton.home()
    pose = cyton.camera_pose(q)
    good = pose.act(np.array([0.0, 0.0, 1.0]))
    with pytest.raises(NonFiniteValue, match="points_world"):
        TwoSphereFeatures(diameter=0.1).jacobians(cyton, q, good, np.array([np.nan, 0, 1]))


@pytest.mark.parametrize("length", [6, 8, 0])
def test_configuration_of_wrong_length(cyton, length):
    q = np.zeros(length)
    with pytest.raises(ShapeError) as info:
        cyton.camera_pose(q)
    assert str(info.value) == f"q: expected shape (7,), got ({length},)"
    with pytest.raises(ShapeError, match=r"\(7,\)"):
        cyton.camera_jacobian(q)


def test_target_points_of_wrong_shape(cyton):
    q = cyton.home()
    pose = cyton.camera_pose(q)
    point = pose.act(np.array([0.0, 0.0, 1.0]))
    features = TwoSphereFeatures(diameter=0.1)
    with pytest.raises(ShapeError, match=r"points_world.*\(2, 3\).*\(1, 3\)"):
        features.jacobians(cyton, q, point)  # one point, two needed
    with pytest.raises(ShapeError, match=r"points_world.*\(2, 3\).*\(2, 2\)"):
        features.jacobians(cyton, q, point[:2], point[:2])  # 2-D points
    with pytest.raises(ShapeError, match=r"points_world.*\(3, 3\).*\(2, 3\)"):
        ImagePointFeatures(3).measure(cyton, q, np.array([point, point]))


def test_mount_pose_of_wrong_length():
    with pytest.raises(ShapeError, match=r"mount: expected shape \(6,\), got \(3,\)"):
        MobileManipulator.assemble(
            base="pioneer3at",
            arm=str(DATA_DIR / "one_joint_arm.urdf"),
            camera_link="tool_link",
            mount=(0.1, 0.0, 0.27),
        )
    with pytest.raises(NonFiniteValue, match="camera_pose"):
        MobileManipulator.assemble(
            base="pioneer3at",
            arm=str(DATA_DIR / "one_joint_arm.urdf"),
            camera_link="tool_link",
            camera_pose=(0, 0, 0, np.nan, 0, 0),
        )


@pytest.mark.parametrize(
    ("build", "field"),
    [
        (lambda: CameraIntrinsics(focal_px=-600.0), "focal_px"),
        (lambda: CameraIntrinsics(width=0), "width"),
        (lambda: TwoSphereFeatures(diameter=0.0), "diameter"),
        (lambda: ImagePointFeatures(0), "count"),
    ],
)
def test_invalid_parameters_are_gain_errors(build, field):
    with pytest.raises(GainError, match=field):
        build()


# ---------------------------------------------------------------- integrate
def test_integrate_velocity_of_wrong_length(cyton):
    with pytest.raises(ShapeError):
        cyton.integrate(cyton.home(), np.ones(4), 0.1)


def test_integrate_non_finite_configuration(cyton):
    q = cyton.home()
    q[5] = np.nan
    with pytest.raises(NonFiniteValue):
        cyton.integrate(q, np.ones(5), 0.1)


def test_integrate_rejects_wrong_configuration_length(cyton):
    with pytest.raises(ShapeError):
        cyton.integrate(np.zeros(6), np.ones(5), 0.1)


def test_se3_mount_passes_through(cyton):
    # Control: a pin.SE3 mount is accepted as is (see test_assembly for equality).
    robot = MobileManipulator.assemble(
        base="pioneer3at",
        arm=str(DATA_DIR / "one_joint_arm.urdf"),
        camera_link="tool_link",
        mount=pin.SE3.Identity(),
    )
    assert robot.n == 3
