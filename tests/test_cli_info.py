"""``pbvs-pin info``: describes a robot; a package error is one line on stderr, status 2."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest
from conftest import DATA_DIR, REPO_ROOT

from pbvs_pin.cli import main


def test_info_reference_robot(capsys):
    status = main(["info", "pioneer_cyton"])
    out, err = capsys.readouterr()
    assert status == 0
    assert err == ""
    assert "actuated dof n = 5 (base 2, arm 3)" in out
    for joint in ("shoulder_yaw_joint", "shoulder_pitch_joint", "elbow_pitch_joint"):
        assert joint in out
    assert "camera frame: camera_optical_frame" in out
    assert "f = 600 px, image 628 x 582 px" in out
    # Platform speed limit r * w_max = 0.1075 m * 6.5 rad/s = 0.699 m/s (pioneer3at.urdf).
    u_line = next(line for line in out.splitlines() if line.startswith("u "))
    assert u_line.split()[-1] == "0.699"
    elbow_line = next(line for line in out.splitlines() if line.startswith("elbow_pitch_joint"))
    assert "[-2.200, +0.600]" in elbow_line


def test_info_urdf_path(capsys):
    status = main(["info", str(REPO_ROOT / "urdf" / "pioneer_cyton.urdf")])
    out, _ = capsys.readouterr()
    assert status == 0
    assert "actuated dof n = 5" in out


def _assert_one_error_line(err: str, *fragments: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("pbvs-pin: error: ")
    assert "Traceback" not in err
    for fragment in fragments:
        assert fragment in lines[0]


@pytest.mark.parametrize(
    "content",
    ["this is not xml", '<robot name="x"><link name="a"></robot'],
    ids=["garbage", "unclosed"],
)
def test_info_bad_urdf(tmp_path, capsys, content):
    path = tmp_path / "broken.urdf"
    path.write_text(content)
    status = main(["info", str(path)])
    out, err = capsys.readouterr()
    assert status != 0
    assert out == ""
    _assert_one_error_line(err, str(path))


@pytest.mark.parametrize(
    ("argument", "fragment"),
    [
        ("no_such_robot", "'no_such_robot'"),
        ("missing_robot.urdf", "missing_robot.urdf"),
        (str(DATA_DIR / "no_wheels.urdf"), "drive axle"),
        (str(DATA_DIR / "fixed_chain.urdf"), "no movable joint"),
    ],
)
def test_info_bad_robot(capsys, argument, fragment):
    status = main(["info", argument])
    _, err = capsys.readouterr()
    assert status == 2
    _assert_one_error_line(err, fragment)


def test_info_bad_urdf_in_a_real_process(tmp_path):
    """Outside pytest's log capture: nothing but the one error line reaches stderr."""
    path = tmp_path / "broken.urdf"
    path.write_text('<robot name="x"><link name="a"></robot')
    result = subprocess.run(
        [sys.executable, "-m", "pbvs_pin.cli", "info", str(path)],
        capture_output=True,
        text=True,
        cwd=REPO_ROOT,
        timeout=120,
        check=False,
    )
    assert result.returncode == 2
    assert result.stdout == ""
    _assert_one_error_line(result.stderr, str(path))


def test_info_figures_are_meaningful_and_rounded(capsys):
    """Three arm joints, n = 5 < 6: no whole-body manipulability (sqrt(det(J J^T)) = 0)."""
    assert main(["info", "pioneer_cyton"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[3].split()[0] == "joint"
    assert "whole-body manipulability at home: n/a (n = 5 < 6)" in out
    position = next(line for line in out.splitlines() if line.startswith("camera position"))
    assert "e-" not in position
    values = position.split("[m]: ")[1].strip("[]").split(", ")
    assert len(values) == 3
    assert all(re.fullmatch(r"[+-]\d+\.\d{3}", value) for value in values)
    assert values[1] == "+0.000"  # the camera sits on the platform's mid-plane
    arm = next(line for line in out.splitlines() if line.startswith("arm manipulability"))
    assert len(arm.split(": ")[1]) <= 7


def test_info_normalises_paths(capsys):
    argument = str(REPO_ROOT / "urdf" / ".." / "urdf" / "pioneer_cyton.urdf")
    assert main(["info", argument]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert ".." not in first
    assert first == f"robot: {(REPO_ROOT / 'urdf' / 'pioneer_cyton.urdf').resolve()}"


def test_unknown_robot_separates_shipped_from_example_robot_data():
    import pbvs_pin
    from pbvs_pin.exceptions import RobotNotFound

    with pytest.raises(RobotNotFound) as error:
        pbvs_pin.MobileManipulator.assemble(base="pioneer3at", arm="iiwa", camera_link="tool0")
    message = str(error.value)
    shipped, erd = message.split("; example-robot-data: ")
    assert "shipped: cyton_alpha3, pioneer3at, pioneer_cyton" in shipped
    assert "ur5" not in shipped and "ur5" in erd.split(", ")
    with pytest.raises(RobotNotFound) as error:
        pbvs_pin.load_robot("iiwa")
    assert "example-robot-data" in str(error.value) and ", ur5," not in str(error.value)
