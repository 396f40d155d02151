"""URDFs as PyPI packages ship them (issue 22): ``package://`` sources, extensions, meshes.

- ``package://<python package>/<path>`` names a URDF inside an installed Python package;
- an undeclared namespace prefix (airo-models' ``drake:acceleration``) is not broken XML;
- a mesh URI whose ROS package folder was renamed in the wheel (rtb-data's
  ``package://kuka_lbr_iiwa_support/...`` under ``kuka_lbr_iiwa/``) is found above the URDF.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import URDF_DIR

from pbvs_pin import MobileManipulator, UrdfError
from pbvs_pin.model.assembly import load_urdf

STRETCH = "package://stretch_urdf/RE1V0/stretch_description_RE1V0_tool_none.urdf"
IIWA = "package://rtbdata/xacro/kuka_description/kuka_lbr_iiwa/urdf/lbr_iiwa_14_r820.urdf"
SHOULDER_LIMIT = '<limit effort="5.0" velocity="1.2" lower="-2.6" upper="2.6"/>'


def test_a_urdf_inside_an_installed_package_loads():
    source = load_urdf(STRETCH)
    assert Path(source.label).is_file() and source.label.endswith("tool_none.urdf")
    assert "joint_lift" in {joint.name for joint in source.robot.joints}


@pytest.mark.parametrize(
    ("uri", "named"),
    [("package://no_such_package/robot.urdf", "no installed Python package 'no_such_package'"),
     ("package://stretch_urdf/RE1V0/missing.urdf", "file not found")],
)  # fmt: skip
def test_a_missing_package_or_file_is_named(uri, named):
    with pytest.raises(UrdfError, match=named) as err:
        load_urdf(uri)
    assert uri in str(err.value)


def test_an_undeclared_namespace_prefix_is_not_broken_xml(tmp_path):
    text = (URDF_DIR / "pioneer_cyton.urdf").read_text()
    assert SHOULDER_LIMIT in text
    path = tmp_path / "drake.urdf"
    path.write_text(text.replace(SHOULDER_LIMIT, SHOULDER_LIMIT.replace(
        "<limit ", '<limit drake:acceleration="2.5" '), 1))  # fmt: skip
    robot = MobileManipulator.from_urdf(str(path))
    assert robot.arm_joint_names == ("shoulder_yaw_joint", "shoulder_pitch_joint",
                                     "elbow_pitch_joint")  # fmt: skip
    path.write_text(text.replace("</robot>", "<link name='x'></robot>"))
    with pytest.raises(UrdfError, match="not well-formed XML"):
        load_urdf(path)


def test_meshes_of_a_renamed_ros_package_are_found():
    source = load_urdf(IIWA)
    meshes = [element.geometry.mesh.filename for link in source.robot.links
              for element in [*link.visuals, *link.collisions] if element.geometry.mesh]  # fmt: skip
    assert meshes and all(Path(mesh).is_file() for mesh in meshes)
    assert any("kuka_lbr_iiwa/meshes/" in mesh for mesh in meshes)
