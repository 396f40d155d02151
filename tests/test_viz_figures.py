"""The stroboscopic plot draws the robot at a few instants, with honest axes and titles."""

from __future__ import annotations

import numpy as np
import pytest

from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.viz.figures import plot_run
from pbvs_pin.viz.html_replay import log_robot
from pbvs_pin.viz.stroboscope import instants, plot_stroboscope


@pytest.fixture(scope="module")
def log():
    return simulate(load_scenario("experiment2").with_values(duration=4.0), progress=False)


def test_stroboscope_draws_robot_and_target_at_each_instant(log, tmp_path):
    count = 6
    path, top, side = plot_stroboscope(log, log_robot(log), tmp_path / "s.png", count=count)
    assert path.stat().st_size > 10_000
    footprints = [p for p in top.patches if p.get_gid() == "footprint"]
    assert len(footprints) == count == len(instants(count, len(log["t"])))
    assert len([p for p in top.patches if p.get_gid() == "target"]) == 2 * count
    assert len([line for line in side.lines if line.get_gid() == "camera"]) == count
    # footprint rectangle centred on the logged base position at the first instant
    corners = footprints[0].get_xy()[:4]
    np.testing.assert_allclose(corners.mean(axis=0), log["q"][0, :2], atol=1e-9)
    assert top.get_aspect() == 1.0 and side.get_aspect() == 1.0
    low, high = side.get_ylim()
    camera_z = log_robot(log).camera_pose(log["q"][0]).translation[2]
    assert low <= 0.0 and high >= max(camera_z, log["target"][:, 2].max())
    assert high - low > 0.3  # not a flat line on a 3 cm axis
    assert "pioneer_cyton, experiment2, passivity law" in top.figure._suptitle.get_text()


def test_plot_run_writes_every_figure(log, tmp_path):
    paths = plot_run(log, tmp_path)
    assert [p.name for p in paths][-1] == "motion_xyz.png"
    assert all(p.stat().st_size > 5_000 for p in paths)
