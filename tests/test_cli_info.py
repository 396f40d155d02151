"""``pbvs-pin info``: describes a robot; a package error is one line on stderr, status 2."""

from __future__ import annotations

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
