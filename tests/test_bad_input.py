"""Every bad input of the model layer raises its own PbvsError naming what is at fault."""

import numpy as np
import pytest

import pbvs_pin
from pbvs_pin.cli import main

ARM_ONLY_FIXED = """<robot name="stick">
  <link name="base_link"/>
  <link name="tip"/>
  <joint name="weld" type="fixed"><parent link="base_link"/><child link="tip"/></joint>
  <link name="camera_optical_frame"/>
  <joint name="cam" type="fixed"><parent link="tip"/><child link="camera_optical_frame"/></joint>
</robot>"""

WHEELS_ONE_SIDE = """<robot name="lopsided">
  <link name="base_link"/>
  <link name="wheel"><visual><geometry><cylinder radius="0.1" length="0.05"/></geometry></visual></link>
  <joint name="wheel_joint" type="continuous"><parent link="base_link"/><child link="wheel"/>
    <origin xyz="0 0.2 0.1"/><axis xyz="0 1 0"/><limit effort="1" velocity="5"/></joint>
</robot>"""


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_all_errors_share_the_package_base_class():
    for error in (
        pbvs_pin.UrdfError, pbvs_pin.FrameNotFound, pbvs_pin.NoMovableJoint,
        pbvs_pin.DriveAxleNotFound, pbvs_pin.PointBehindCamera, pbvs_pin.NonFiniteValue,
        pbvs_pin.ShapeError, pbvs_pin.RobotNotFound, pbvs_pin.ScenarioError,
    ):  # fmt: skip
        assert issubclass(error, pbvs_pin.PbvsError)


def test_malformed_urdf_names_the_file(tmp_path):
    path = write(tmp_path, "broken.urdf", "<robot name='x'><link name='a'>")
    with pytest.raises(pbvs_pin.UrdfError, match=r"broken\.urdf"):
        pbvs_pin.MobileManipulator.from_urdf(str(path))


def test_missing_camera_link_lists_valid_names():
    with pytest.raises(pbvs_pin.FrameNotFound) as info:
        pbvs_pin.MobileManipulator.assemble(base="pioneer3at", arm="ur5", camera_link="nose")
    assert "'nose'" in str(info.value) and "tool0" in str(info.value)


def test_missing_camera_frame_in_one_urdf():
    with pytest.raises(pbvs_pin.FrameNotFound, match="wrist_link"):
        pbvs_pin.MobileManipulator.from_urdf("pioneer_cyton", camera_frame="eye")


def test_arm_without_movable_joint(tmp_path):
    path = write(tmp_path, "stick.urdf", ARM_ONLY_FIXED)
    with pytest.raises(pbvs_pin.NoMovableJoint, match=r"stick\.urdf"):
        pbvs_pin.MobileManipulator.from_urdf(str(path), base="fixed")


def test_platform_without_drive_axle(tmp_path):
    path = write(tmp_path, "lopsided.urdf", WHEELS_ONE_SIDE)
    with pytest.raises(pbvs_pin.DriveAxleNotFound) as info:
        pbvs_pin.MobileManipulator.assemble(base=str(path), arm="ur5", camera_link="tool0")
    assert "lopsided.urdf" in str(info.value) and "wheel_joint" in str(info.value)


def test_point_behind_camera(cyton):
    with pytest.raises(pbvs_pin.PointBehindCamera, match=r"-0\.5"):
        cyton.camera.project([0.0, 0.0, -0.5])


def test_non_finite_and_wrong_shapes(cyton):
    q = cyton.neutral()
    q[0] = np.nan
    with pytest.raises(pbvs_pin.NonFiniteValue, match="q"):
        cyton.camera_pose(q)
    with pytest.raises(pbvs_pin.ShapeError, match=r"expected shape \(7,\), got \(3,\)"):
        cyton.camera_pose(np.zeros(3))
    features = pbvs_pin.TwoSphereFeatures(diameter=0.05)
    with pytest.raises(pbvs_pin.ShapeError, match="points_world"):
        features.jacobians(cyton, cyton.neutral(), [1.0, 0.0, 0.4])


def test_unknown_robot_lists_shipped_names():
    with pytest.raises(pbvs_pin.RobotNotFound, match="pioneer_cyton"):
        pbvs_pin.load_robot("r2d2")


def test_cli_prints_one_line_without_traceback(tmp_path, capsys):
    path = write(tmp_path, "broken.urdf", "<robot")
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("pbvs-pin: error:") and "broken.urdf" in err
    assert "Traceback" not in err and err.count("\n") == 1


def test_cli_info_describes_the_robot(capsys):
    assert main(["info", "pioneer_cyton"]) == 0
    out = capsys.readouterr().out
    for expected in ("n = 5", "shoulder_pitch_joint", "camera_optical_frame", "628 x 582"):
        assert expected in out
