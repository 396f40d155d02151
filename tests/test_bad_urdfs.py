"""Catalogue of bad URDF files (issue 12): each is refused before Pinocchio builds a model.

Every case is a small text edit of the shipped ``pioneer_cyton.urdf`` written to ``tmp_path``.
Loading it must raise the exact :class:`UrdfError` subclass, on one line naming the file and
the link or joint at fault; none may crash the interpreter (a link with two parents used to
segfault Pinocchio) or be accepted.
"""

from __future__ import annotations

import pytest
from conftest import URDF_DIR

from pbvs_pin import MobileManipulator
from pbvs_pin.exceptions import DriveAxleNotFound, UrdfError

CYTON = (URDF_DIR / "pioneer_cyton.urdf").read_text()

LOOP_JOINT = (
    '<joint name="loop_joint" type="fixed"><parent link="{parent}"/><child link="{child}"/>'
    "</joint>\n</robot>"
)
"""An extra joint, added before ``</robot>``."""

SHOULDER_LIMIT = '<limit effort="5.0" velocity="1.2" lower="-2.6" upper="2.6"/>'
WHEEL_AXIS = '<axis xyz="0.0 1.0 0.0"/>\n    <limit effort="20.0" velocity="6.5"/>'
WHEEL_MASS = '<mass value="0.6"/>'
WHEEL_INERTIA = (
    '<inertia ixx="0.00218469" ixy="0.0" ixz="0.0" iyy="0.00346687" iyz="0.0" izz="0.00218469"/>'
)


def edit(old: str, new: str) -> str:
    """The URDF with the first ``old`` replaced."""
    assert old in CYTON, old
    return CYTON.replace(old, new, 1)


def extra_joint(parent: str, child: str) -> str:
    return edit("</robot>", LOOP_JOINT.format(parent=parent, child=child))


def inertia(ixx: float, iyy: float, izz: float, ixy: float = 0.0) -> str:
    return edit(
        WHEEL_INERTIA,
        f'<inertia ixx="{ixx}" ixy="{ixy}" ixz="0.0" iyy="{iyy}" iyz="0.0" izz="{izz}"/>',
    )


# (id, text, exception class, what the message must name)
CASES = [
    # tree
    ("link-two-parents", extra_joint("upper_arm_link", "chassis_link"), UrdfError,
     "'chassis_link' has two parents"),
    ("loop-without-root", extra_joint("chassis_link", "base_link"), UrdfError, "root link"),
    ("joint-to-unknown-link", extra_joint("base_link", "ghost_link"), UrdfError, "'ghost_link'"),
    ("joint-from-unknown-link", extra_joint("ghost_link", "base_link"), UrdfError, "'ghost_link'"),
    ("duplicate-link", edit('<link name="laser_link">', '<link name="chassis_link">'), UrdfError,
     "'chassis_link'"),
    ("duplicate-joint", edit('<joint name="top_plate_joint"', '<joint name="chassis_joint"'),
     UrdfError, "'chassis_joint'"),
    ("two-roots", edit('<link name="arm_mount_link"/>',
                       '<link name="arm_mount_link"/>\n  <link name="floating_link"/>'),
     UrdfError, "floating_link"),
    # masses
    ("mass-negative", edit(WHEEL_MASS, '<mass value="-0.6"/>'), UrdfError,
     "'front_left_wheel_link'"),
    ("mass-absurd", edit(WHEEL_MASS, '<mass value="1e30"/>'), UrdfError, "'front_left_wheel_link'"),
    ("mass-nan", edit(WHEEL_MASS, '<mass value="nan"/>'), UrdfError, "'front_left_wheel_link'"),
    ("mass-inf", edit(WHEEL_MASS, '<mass value="inf"/>'), UrdfError, "'front_left_wheel_link'"),
    # inertias
    ("inertia-negative", inertia(-0.002, 0.003, 0.002), UrdfError, "'front_left_wheel_link'"),
    ("inertia-all-negative", inertia(-0.002, -0.003, -0.002), UrdfError,
     "'front_left_wheel_link'"),
    ("inertia-not-definite", inertia(0.01, 0.01, 0.01, ixy=0.02), UrdfError,
     "'front_left_wheel_link'"),
    ("inertia-triangle", inertia(0.001, 0.001, 0.01), UrdfError, "triangle inequality"),
    ("inertia-nan", inertia(float("nan"), 0.003, 0.002), UrdfError, "'front_left_wheel_link'"),
    # joints
    ("lower-above-upper", edit(SHOULDER_LIMIT, SHOULDER_LIMIT.replace('"-2.6"', '"2.7"')),
     UrdfError, "'shoulder_yaw_joint'"),
    ("velocity-zero", edit(SHOULDER_LIMIT, SHOULDER_LIMIT.replace('"1.2"', '"0"')), UrdfError,
     "'shoulder_yaw_joint'"),
    ("velocity-negative", edit(SHOULDER_LIMIT, SHOULDER_LIMIT.replace('"1.2"', '"-1.2"')),
     UrdfError, "'shoulder_yaw_joint'"),
    ("limit-nan", edit(SHOULDER_LIMIT, SHOULDER_LIMIT.replace('"2.6"', '"nan"')), UrdfError,
     "'shoulder_yaw_joint'"),
    ("wheel-velocity-zero", edit(WHEEL_AXIS, WHEEL_AXIS.replace('"6.5"', '"0.0"')), UrdfError,
     "'front_left_wheel_joint'"),
    ("origin-nan", edit('<joint name="arm_mount_joint" type="fixed">',
                        '<joint name="arm_mount_joint" type="fixed">\n    <origin xyz="nan 0 0"/>'),
     UrdfError, "'arm_mount_joint'"),
    # drive and meshes
    ("wheel-without-axis", edit(WHEEL_AXIS, '<limit effort="20.0" velocity="6.5"/>'),
     DriveAxleNotFound, "'front_left_wheel_joint'"),
    ("missing-relative-mesh", edit('<link name="chassis_link">',
                                   '<link name="chassis_link">\n    <visual><geometry>'
                                   '<mesh filename="meshes/none.stl"/></geometry></visual>'),
     UrdfError, "meshes/none.stl"),
    # files
    ("not-xml", "binary \x00\x01 garbage", UrdfError, "not well-formed XML"),
    ("truncated", CYTON[: len(CYTON) // 2], UrdfError, "not well-formed XML"),
]  # fmt: skip


@pytest.mark.parametrize(("text", "error", "named"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])  # fmt: skip
def test_bad_urdf_is_refused_before_pinocchio(tmp_path, text, error, named):
    path = tmp_path / "bad_robot.urdf"
    path.write_text(text)
    with pytest.raises(UrdfError) as err:
        MobileManipulator.from_urdf(str(path))
    message = str(err.value)
    assert type(err.value) is error
    assert str(path) in message
    assert named in message
    assert "\n" not in message
