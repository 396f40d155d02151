"""Catalogue of bad scenario files (issue 12): each is refused before any simulation.

Every case is a small text edit of a valid scenario, written to ``tmp_path``; it must raise a
:class:`ScenarioError` (never a raw Python error) whose one-line message names the file and
the dotted field at fault, and whose ``field`` attribute is that field.
"""

from __future__ import annotations

import pytest

from pbvs_pin.exceptions import PbvsWarning, ScenarioError
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.setup import build

BASE = """
name = "bad"
duration = 5.0

[robot]
name = "pioneer_cyton"

[target]
xi0 = [-150.0, 20.0, -100.0]
xi_d = [0.0, 60.0, -60.0]
"""
"""A valid scenario; each case appends a table or replaces a line."""

XI0 = "xi0 = [-150.0, 20.0, -100.0]"
XI_D = "xi_d = [0.0, 60.0, -60.0]"
DURATION = "duration = 5.0"


def appended(extra: str) -> str:
    return BASE + "\n" + extra + "\n"


def replaced(old: str, new: str) -> str:
    assert old in BASE
    return BASE.replace(old, new)


# (id, file text, dotted field) -- refused when the file is read
READ_CASES = [
    # numbers that are not finite
    ("duration-inf", replaced(DURATION, "duration = inf"), "duration"),
    ("duration-nan", replaced(DURATION, "duration = nan"), "duration"),
    ("duration-negative", replaced(DURATION, "duration = -1.0"), "duration"),
    ("duration-zero", replaced(DURATION, "duration = 0.0"), "duration"),
    ("duration-text", replaced(DURATION, 'duration = "long"'), "duration"),
    ("duration-too-short", replaced(DURATION, "duration = 0.004"), "duration"),
    ("xi0-inf", replaced(XI0, "xi0 = [inf, 20.0, -100.0]"), "target.xi0"),
    ("xi0-nan", replaced(XI0, "xi0 = [nan, 20.0, -100.0]"), "target.xi0"),
    ("xi0-nested", replaced(XI0, "xi0 = [[-150.0], [20.0], [-100.0]]"), "target.xi0"),
    ("xi0-short", replaced(XI0, "xi0 = [-150.0, 20.0]"), "target.xi0"),
    ("xi0-strings", replaced(XI0, 'xi0 = ["a", "b", "c"]'), "target.xi0"),
    ("xi0-scalar", replaced(XI0, "xi0 = 3.0"), "target.xi0"),
    ("xi0-booleans", replaced(XI0, "xi0 = [true, false, true]"), "target.xi0"),
    ("spheres-overlap", appended("diameter = 0.12\nseparation = 0.10"), "target.diameter"),
    ("spheres-touch", replaced(XI_D, XI_D + "\ndiameter = 0.1\nseparation = 0.1"),
     "target.diameter"),
    ("velocity-nested", appended("[motion]\nvelocity = [[0.1, 0.0], [0.0]]"), "motion.velocity"),
    ("amplitude-inf", appended("[motion]\namplitude = [inf, 0.0, 0.0]"), "motion.amplitude"),
    # integers
    ("seed-negative", appended("[simulation]\nseed = -1"), "simulation.seed"),
    ("seed-fraction", appended("[simulation]\nseed = 1.5"), "simulation.seed"),
    ("seed-text", appended('[simulation]\nseed = "one"'), "simulation.seed"),
    ("beams-fraction", appended("[laser]\nbeams = 0.5"), "laser.beams"),
    ("beams-zero", appended("[laser]\nbeams = 0"), "laser.beams"),
    ("width-fraction", appended("[camera]\nwidth = 0.5"), "camera.width"),
    ("height-fraction", appended("[camera]\nheight = 480.5"), "camera.height"),
    ("width-huge", appended("[camera]\nwidth = 10000000"), "camera.width"),
    # camera
    ("focal-huge", appended("[camera]\nfocal_px = 1e30"), "camera.focal_px"),
    ("focal-zero", appended("[camera]\nfocal_px = 0.0"), "camera.focal_px"),
    ("focal-inf", appended("[camera]\nfocal_px = inf"), "camera.focal_px"),
    ("camera-rate-tiny", appended("[camera]\nrate = 1e-6"), "camera.rate"),
    ("camera-rate-negative", appended("[camera]\nrate = -30.0"), "camera.rate"),
    ("latency-beyond-run", appended("[camera]\nlatency = 100.0"), "camera.latency"),
    ("latency-equals-run", appended("[camera]\nlatency = 5.0"), "camera.latency"),
    ("latency-one-frame", appended("[camera]\nlatency = 4.99\nrate = 30.0"), "camera.rate"),
    ("latency-negative", appended("[camera]\nlatency = -0.1"), "camera.latency"),
    ("noise-negative", appended("[camera]\nnoise_px = -1.0"), "camera.noise_px"),
    # sensing and laser (issue 9)
    ("localisation-gps", appended('[sensing]\nlocalisation = "gps"'), "sensing.localisation"),
    ("heading-compass", appended('[sensing]\nheading = "compass"'), "sensing.heading"),
    ("gyro-noise-negative", appended("[sensing]\ngyro_noise = -0.1"), "sensing.gyro_noise"),
    ("gyro-bias-text", appended('[sensing]\ngyro_bias = "small"'), "sensing.gyro_bias"),
    ("encoder-bits-50", appended("[sensing]\narm_encoder_bits = 50"), "sensing.arm_encoder_bits"),
    ("encoder-bits-zero", appended("[sensing]\narm_encoder_bits = 0"), "sensing.arm_encoder_bits"),
    ("wheel-counts-fraction", appended("[sensing]\nwheel_encoder_counts = 0.5"),
     "sensing.wheel_encoder_counts"),
    ("linear-resolution-zero", appended("[sensing]\narm_linear_resolution = 0.0"),
     "sensing.arm_linear_resolution"),
    ("joint-noise-negative", appended("[sensing]\njoint_velocity_noise = -0.1"),
     "sensing.joint_velocity_noise"),
    ("wheel-noise-nan", appended("[sensing]\nwheel_velocity_noise = nan"),
     "sensing.wheel_velocity_noise"),
    ("velocity-filter-negative", appended("[sensing]\nvelocity_filter = -0.01"),
     "sensing.velocity_filter"),
    ("exact-text", appended('[sensing]\nexact = "yes"'), "sensing.exact"),
    ("range-noise-negative", appended("[laser]\nrange_noise = -0.01"), "laser.range_noise"),
    ("range-resolution-inf", appended("[laser]\nrange_resolution = inf"),
     "laser.range_resolution"),
    ("default-latency-too-long", replaced(DURATION, "duration = 0.06"), "camera.rate"),
    # features: visible and ordered
    ("xi_d-outside-v", replaced(XI_D, "xi_d = [0.0, 600.0, -60.0]"), "target.xi_d"),
    ("xi_d-outside-u", replaced(XI_D, "xi_d = [400.0, 60.0, -60.0]"), "target.xi_d"),
    ("xi_d-swapped", replaced(XI_D, "xi_d = [0.0, -60.0, 60.0]"), "target.xi_d"),
    ("xi_d-equal", replaced(XI_D, "xi_d = [0.0, 60.0, 60.0]"), "target.xi_d"),
    ("xi0-outside", replaced(XI0, "xi0 = [500.0, 20.0, -100.0]"), "target.xi0"),
    ("xi0-swapped", replaced(XI0, "xi0 = [-150.0, -100.0, 20.0]"), "target.xi0"),
    ("xi_d-outside-small-image", appended("[camera]\nheight = 100"), "target.xi0"),
    # rates
    ("controller-33Hz", appended("[controller]\nrate = 33.0"), "controller.rate"),
    ("controller-3000Hz", appended("[controller]\nrate = 3000.0"), "controller.rate"),
    ("controller-zero", appended("[controller]\nrate = 0.0"), "controller.rate"),
    ("plant-dt-50ms", appended("[simulation]\nplant_dt = 0.05"), "simulation.plant_dt"),
    ("plant-dt-10s", appended("[simulation]\nplant_dt = 10.0"), "simulation.plant_dt"),
    ("plant-dt-negative", appended("[simulation]\nplant_dt = -0.001"), "simulation.plant_dt"),
    ("plant-dt-camera", appended("[simulation]\nplant_dt = 0.04"), "simulation.plant_dt"),
    ("log-faster-than-control", appended("[simulation]\nlog_rate = 500.0"), "simulation.log_rate"),
    ("laser-faster-than-control", appended("[laser]\nrate = 400.0"), "laser.rate"),
    # obstacles
    ("obstacle-over-start", appended('[[obstacles]]\nkind = "circle"\nx = 0.0\ny = 0.0\n'
                                     "radius = 0.3"), "obstacles[0]"),
    ("obstacle-touching", appended('[[obstacles]]\nkind = "circle"\nx = 0.4\ny = 0.0\n'
                                   "radius = 0.2"), "obstacles[0]"),
    ("obstacle-inside-footprint", appended('[[obstacles]]\nkind = "circle"\nx = 0.1\ny = 0.1\n'
                                           "radius = 0.01"), "obstacles[0]"),
    ("box-over-start", appended('[[obstacles]]\nkind = "box"\nx = 0.0\ny = 0.5\nsize_x = 1.0\n'
                                "size_y = 1.0"), "obstacles[0]"),
    ("obstacle-no-radius", appended('[[obstacles]]\nkind = "circle"\nx = 3.0\ny = 0.0'),
     "obstacles[0].radius"),
    ("obstacle-bad-kind", appended('[[obstacles]]\nkind = "cone"\nx = 3.0\ny = 0.0'),
     "obstacles[0].kind"),
    ("obstacle-kind-list", appended('[[obstacles]]\nkind = []\nx = 3.0\ny = 0.0'),
     "obstacles[0].kind"),
    ("obstacle-inf", appended('[[obstacles]]\nkind = "circle"\nx = inf\ny = 0.0\nradius = 0.2'),
     "obstacles[0].x"),
    ("obstacle-text", appended('[[obstacles]]\nkind = "circle"\nx = "far"\ny = 0.0\n'
                               "radius = 0.2"), "obstacles[0].x"),
    ("obstacles-not-tables", BASE.replace('name = "bad"', 'name = "bad"\nobstacles = 3'),
     "obstacles"),
    # keys and tables
    ("unknown-key", appended("[camera]\nfocal = 600.0"), "camera.focal"),
    ("unknown-table", appended("[cameras]\nrate = 30.0"), "cameras"),
    ("unknown-root-key", replaced(DURATION, "duration = 5.0\nlength = 3"), "length"),
    ("motion-kind", appended('[motion]\nkind = "spiral"'), "motion.kind"),
    ("estimator-alpha", appended("[estimator]\nalpha = 1.5"), "estimator.alpha"),
    ("k-negative", appended("[controller]\nk = [-0.1]"), "controller.k"),
    ("weights-ragged", appended("[controller]\nweights = [[1.0, 2.0], [3.0]]"),
     "controller.weights"),
    ("robot-two-forms", BASE.replace('name = "pioneer_cyton"', 'name = "pioneer_cyton"\n'
                                     'urdf = "x.urdf"'), "robot.urdf"),
    ("mount-short", BASE.replace('name = "pioneer_cyton"', 'base = "pioneer3at"\n'
                                 'arm = "cyton_alpha3"\nmount = [0.0, 0.0]'), "robot.mount"),
]  # fmt: skip

# (id, file text, dotted field) -- refused when the robot is built, before the run
BUILD_CASES = [
    ("initial-arm-short", BASE.replace('"pioneer_cyton"', '"pioneer_cyton"\ninitial_arm = [0.0]'),
     "robot.initial_arm"),
    ("initial-arm-beyond-limit", BASE.replace('"pioneer_cyton"', '"pioneer_cyton"\n'
                                              "initial_arm = [0.0, 3.0, 0.0]"),
     "robot.initial_arm"),
    ("home-beyond-limit", BASE.replace('"pioneer_cyton"', '"pioneer_cyton"\n'
                                       "home = [0.0, 0.0, 2.0]"), "robot.home"),
    ("unknown-robot", BASE.replace('"pioneer_cyton"', '"no_such_robot"'), "robot.name"),
    ("k1-length", appended("[controller]\nk1 = [0.1, 0.2, 0.3]"), "controller.k1"),
    ("weights-size", appended("[controller]\nweights = [[1.0, 0.0], [0.0, 1.0]]"),
     "controller.weights"),
    ("k_d-length", appended("[compensation]\nk_d = [1.0, 2.0]"), "compensation.k_d"),
]  # fmt: skip


def _expect(err: pytest.ExceptionInfo, path, field: str) -> None:
    message = str(err.value)
    assert type(err.value) is ScenarioError
    assert str(path) in message
    assert field in message
    assert err.value.field == field
    assert "\n" not in message


@pytest.mark.parametrize(("text", "field"), [c[1:] for c in READ_CASES],
                         ids=[c[0] for c in READ_CASES])  # fmt: skip
def test_bad_value_is_refused_when_read(tmp_path, text, field):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    _expect(err, path, field)


@pytest.mark.parametrize(("text", "field"), [c[1:] for c in BUILD_CASES],
                         ids=[c[0] for c in BUILD_CASES])  # fmt: skip
def test_bad_value_for_the_robot_is_refused_before_the_run(tmp_path, text, field):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    scenario = load_scenario(path)
    with pytest.raises(ScenarioError) as err:
        build(scenario)
    _expect(err, path, field)


@pytest.mark.parametrize(
    "content",
    [bytes(range(256)) * 4, b"", b"# only a comment\n", b"duration = \n", b"[[[\n"],
    ids=["binary", "empty", "comment-only", "truncated", "bad-toml"],
)
def test_unreadable_or_empty_file_is_refused(tmp_path, content):
    path = tmp_path / "garbage.toml"
    path.write_bytes(content)
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    assert type(err.value) is ScenarioError
    assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_a_folder_is_not_a_scenario(tmp_path):
    folder = tmp_path / "folder.toml"
    folder.mkdir()
    with pytest.raises(ScenarioError, match="no such scenario file"):
        load_scenario(folder)


def test_log_rate_that_does_not_divide_is_rounded_with_a_warning(tmp_path):
    path = tmp_path / "round.toml"
    path.write_text(appended("[simulation]\nlog_rate = 30.0"))
    with pytest.warns(PbvsWarning, match=r"simulation.log_rate = 30 Hz.*rounded to 33.3333 Hz"):
        load_scenario(path)
