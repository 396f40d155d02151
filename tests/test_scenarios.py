"""Scenario files: the shipped ones, and every kind of bad input a user can write.

Each defect is written into a real TOML file under ``tmp_path`` and loaded as a user would,
so that the error is checked to name that file and the dotted field at fault. Errors that only
the robot can reveal (vector lengths per dof, weights, visibility of the target) come from
:func:`pbvs_pin.sim.setup.build`; the rest from the sections' constructors.
"""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from pbvs_pin.cli import main
from pbvs_pin.control.tables import CameraSection, ControllerSection
from pbvs_pin.exceptions import GainError, ScenarioError
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.obstacles import BoxObstacle, CircleObstacle
from pbvs_pin.sim.scenario import (
    SCHEMA,
    load_scenario,
    parse_scenario,
    scenario_dir,
    shipped_scenarios,
)
from pbvs_pin.sim.sections import SECTIONS
from pbvs_pin.sim.setup import build
from pbvs_pin.toml_keys import keys_of

EXPERIMENTS = ("experiment1", "experiment2", "experiment3", "experiment4")


def _write(tmp_path, text: str, name: str = "user.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


BASE = """
name = "user"
duration = 5.0

[target]
xi0 = [-150.0, 20.0, -100.0]
xi_d = [0.0, 60.0, -60.0]
"""
"""A valid minimal scenario; each test appends or edits one thing."""


def _read(value):
    """A TOML value as a section holds it: arrays become tuples."""
    return tuple(_read(x) for x in value) if isinstance(value, list) else value


def _expect(err: pytest.ExceptionInfo, path, field: str) -> None:
    """The message names the file and the dotted field; the attributes agree."""
    message = str(err.value)
    assert str(path) in message
    assert field in message
    assert err.value.field == field
    assert "\n" not in message


# ---------------------------------------------------------------- shipped scenarios
def test_shipped_scenarios_are_the_four_experiments():
    assert set(EXPERIMENTS) <= set(shipped_scenarios())


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_shipped_scenario_values_come_from_its_file(name):
    scenario = load_scenario(name)
    raw = tomllib.loads((scenario_dir() / f"{name}.toml").read_text())
    assert scenario.name == name
    for section, keys in raw.items():
        if section == "obstacles":
            assert len(scenario.obstacles) == len(keys)
            for obstacle, table in zip(scenario.obstacles, keys, strict=True):
                kind = {"circle": CircleObstacle, "box": BoxObstacle}[table.pop("kind")]
                assert type(obstacle) is kind
                assert all(getattr(obstacle, k) == v for k, v in table.items()), table
        elif isinstance(keys, dict):
            for key, value in keys.items():
                assert getattr(getattr(scenario, section), key) == _read(value), f"{section}.{key}"
        else:
            assert getattr(scenario, section) == keys, section
    # Unspecified keys take the schema's defaults.
    assert "plant_dt" not in raw.get("simulation", {})
    assert scenario.simulation.plant_dt == SCHEMA["simulation"]["plant_dt"] == 0.001


def test_paper_table_values_in_shipped_scenarios():
    """DESIGN.md §4: xi(0), xi_d of each experiment; Exp. 3's 20 % kinematic error."""
    table = {
        "experiment1": ([-150, 20, -100], [0, 60, -60]),
        "experiment2": ([-150, 0, -115], [0, 60, -60]),
        "experiment3": ([-212, 11, -137], [0, 50, -50]),
        "experiment4": ([212, -50, -120], [0, 50, -50]),
    }
    for name, (xi0, xi_d) in table.items():
        scenario = load_scenario(name)
        assert scenario.target.xi0 == tuple(xi0) and scenario.target.xi_d == tuple(xi_d)
    assert load_scenario("experiment3").model_error.kinematic_scale == 1.2
    assert load_scenario("experiment4").estimator.kind == "exact"
    assert load_scenario("experiment2").secondary.obstacle_avoidance is True


def test_with_values_replaces_dotted_fields_and_validates():
    scenario = load_scenario("experiment1")
    changed = scenario.with_values(**{"duration": 3.0, "camera.rate": 60.0})
    assert changed.duration == 3.0 and changed.camera.rate == 60.0
    assert scenario.duration == 30.0 and scenario.camera.rate == 30.0  # the original is untouched
    assert changed.source == scenario.source
    with pytest.raises(ScenarioError) as err:
        scenario.with_values(**{"camera.rate": -1.0})
    _expect(err, scenario.source, "camera.rate")


def test_built_start_matches_xi0():
    """The target is placed so that the initial features equal xi(0) (DESIGN.md §4)."""
    setup = build(load_scenario("experiment3"))
    pose = setup.robot.camera_pose(setup.plant.q)
    centres = setup.target.centres(0.0)
    in_camera = (centres - pose.translation) @ pose.rotation
    image = -setup.robot.camera.focal_px * in_camera[:, :2] / in_camera[:, 2:]
    np.testing.assert_allclose([image[0, 0], image[0, 1], image[1, 1]], [-212, 11, -137],
                               atol=1e-6)  # fmt: skip
    assert np.linalg.norm(centres[0] - centres[1]) == pytest.approx(0.10)


# ---------------------------------------------------------------- file-level errors
def test_unknown_scenario_name():
    with pytest.raises(ScenarioError, match="nosuch") as err:
        load_scenario("nosuch")
    assert "experiment1" in str(err.value)  # lists the shipped ones


def test_invalid_toml_syntax(tmp_path):
    path = _write(tmp_path, BASE + "\n[camera\nrate = 30\n")
    with pytest.raises(ScenarioError, match="not valid TOML") as err:
        load_scenario(path)
    assert str(path) in str(err.value)


# ---------------------------------------------------------------- field errors (parse time)
@pytest.mark.parametrize(
    "extra, field",
    [
        ("\n[controller]\nk = [-0.15]\n", "controller.k"),
        ("\n[controller]\nk2 = [0.2, 0.2, -0.2, 0.2, 0.2]\n", "controller.k2"),
        ("\n[compensation]\nk_d = [0.0]\n", "compensation.k_d"),
        ("\n[camera]\nrate = 0\n", "camera.rate"),
        ("\n[camera]\nnoise_px = -1.0\n", "camera.noise_px"),
        ("\n[camera]\nrate = \"fast\"\n", "camera.rate"),
        ("\n[secondary]\nposture = 1\n", "secondary.posture"),
        ("\n[motion]\nkind = \"circle\"\n", "motion.kind"),
        ("\n[motion]\nvelocity = [0.1, 0.0]\n", "motion.velocity"),
        ("TOP:bogus = 1\n", "bogus"),  # a root key must come before the first table
        ("\n[controller]\ngain = 1.0\n", "controller.gain"),
        ("\n[nosection]\nx = 1\n", "nosection"),
        ("\n[[obstacles]]\nkind = \"circle\"\nx = 1.0\ny = 0.0\nradius = 0.2\ncolour = 3\n",
         "obstacles[0].colour"),
        ("\n[[obstacles]]\nkind = \"cone\"\nx = 1.0\n", "obstacles[0].kind"),
        ("\n[[obstacles]]\nkind = \"box\"\nx = 1.0\ny = 0.0\nsize_x = \"big\"\n",
         "obstacles[0].size_x"),
        ("\n[[obstacles]]\nkind = \"circle\"\nx = 1.0\ny = 0.0\nradius = -0.2\n",
         "obstacles[0]"),
        ("\n[[obstacles]]\nkind = \"circle\"\nx = 1.0\ny = 0.0\n", "obstacles[0].radius"),
        ("\n[estimator]\nalpha = 2.0\n", "estimator.alpha"),
        ("\n[estimator]\nbeta = 3.5\n", "estimator.beta"),
        ("\n[controller]\nweights = [-1.0]\n", "controller.weights"),
        ("\n[camera]\nfocal_px = inf\n", "camera.focal_px"),
    ],
)  # fmt: skip
def test_invalid_field_names_file_and_field(tmp_path, extra, field):
    text = extra.removeprefix("TOP:") + BASE if extra.startswith("TOP:") else BASE + extra
    path = _write(tmp_path, text)
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    _expect(err, path, field)


def test_xi0_with_two_values(tmp_path):
    path = _write(tmp_path, BASE.replace("[-150.0, 20.0, -100.0]", "[-150.0, 20.0]"))
    with pytest.raises(ScenarioError, match="expected 3 values") as err:
        load_scenario(path)
    _expect(err, path, "target.xi0")


# ---------------------------------------------------------------- field errors (build time)
@pytest.mark.parametrize(
    "extra, field",
    [
        ("\n[controller]\nk1 = [0.7, 1.0, 0.1, 0.1]\n", "controller.k1"),
        ("\n[controller]\nk = [0.1, 0.2]\n", "controller.k"),
        ("\n[compensation]\nk_d = [4.0, 4.0]\n", "compensation.k_d"),
        ("\n[controller]\nweights = [[1.0, 0.0], [0.0, 1.0]]\n", "controller.weights"),
        ("\n[robot]\nname = \"no_such_robot\"\n", "robot.name"),
        ("\n[robot]\ninitial_arm = [0.1, 0.2]\n", "robot.initial_arm"),  # the Cyton has 3
    ],
)  # fmt: skip
def test_invalid_for_the_robot_names_file_and_field(tmp_path, extra, field):
    path = _write(tmp_path, BASE + extra)
    scenario = load_scenario(path)
    with pytest.raises(ScenarioError) as err:
        build(scenario)
    _expect(err, path, field)


@pytest.mark.parametrize(
    "xi0", [[500.0, 20.0, -100.0], [0.0, 320.0, 250.0], [-150.0, -400.0, -450.0]]
)
def test_target_not_visible_at_start(tmp_path, xi0):
    """xi0 outside the 628 x 582 image (|u| > 314 or |v| > 291 px), refused when read."""
    path = _write(tmp_path, BASE.replace("[-150.0, 20.0, -100.0]", str(xi0)))
    with pytest.raises(ScenarioError, match="not visible") as err:
        load_scenario(path)
    _expect(err, path, "target.xi0")


NOT_POSITIVE_DEFINITE = np.diag([1.0, 1.0, 1.0, 1.0, 1.0])
NOT_POSITIVE_DEFINITE[0, 1] = NOT_POSITIVE_DEFINITE[1, 0] = 2.0  # eigenvalues include -1


def _weights_file(tmp_path):
    rows = ", ".join(str(row) for row in NOT_POSITIVE_DEFINITE.tolist())
    return _write(tmp_path, BASE + f"\n[controller]\nweights = [{rows}]\n")


def test_weights_not_positive_definite_are_rejected(tmp_path):
    """What works today: a ScenarioError naming the file and ``weights``."""
    assert np.linalg.eigvalsh(NOT_POSITIVE_DEFINITE)[0] < 0
    path = _weights_file(tmp_path)
    with pytest.raises(ScenarioError, match="positive definite") as err:
        build(load_scenario(path))
    assert str(path) in str(err.value) and "weights" in str(err.value)


@pytest.mark.parametrize("kind", ["not_positive_definite", "negative_diagonal"])
def test_weights_error_names_the_dotted_field(tmp_path, kind):
    path = (
        _weights_file(tmp_path)
        if kind == "not_positive_definite"
        else _write(tmp_path, BASE + "\n[controller]\nweights = [-1.0]\n")
    )
    with pytest.raises(ScenarioError) as err:
        build(load_scenario(path))
    _expect(err, path, "controller.weights")


def test_estimator_gain_error_names_the_dotted_field(tmp_path):
    path = _write(tmp_path, BASE + "\n[estimator]\nalpha = 2.0\n")
    with pytest.raises(ScenarioError) as err:
        build(load_scenario(path))
    _expect(err, path, "estimator.alpha")


def test_estimator_gain_error_is_a_scenario_error_at_run_time(tmp_path):
    """What works today: the run refuses to start, naming the file and alpha."""
    path = _write(tmp_path, BASE.replace("5.0", "0.1") + "\n[estimator]\nalpha = 2.0\n")
    with pytest.raises(ScenarioError, match="alpha") as err:
        simulate(load_scenario(path))
    assert str(path) in str(err.value)


def test_parse_scenario_names_its_source():
    with pytest.raises(ScenarioError) as err:
        parse_scenario({"camera": {"rate": -2.0}}, "in-memory")
    assert str(err.value).startswith("in-memory: camera.rate:")


# ---------------------------------------------------------------- typed sections
def test_sections_validate_when_built_directly():
    """A section refuses a bad value itself (GainError naming the key), not only from a file."""
    assert CameraSection(rate=60).rate == 60.0 and isinstance(CameraSection(rate=60).rate, float)
    with pytest.raises(GainError) as err:
        CameraSection(rate=-1.0)
    assert err.value.field == "rate"
    with pytest.raises(GainError) as err:
        ControllerSection(feedback="inverse")
    assert err.value.field == "feedback"
    assert ControllerSection(k1=[1.0, 2.0]).k1 == (1.0, 2.0)  # arrays are kept as tuples


def test_sections_are_frozen():
    scenario = load_scenario("experiment1")
    with pytest.raises(AttributeError):
        scenario.camera.rate = 60.0
    with pytest.raises(AttributeError):
        scenario.duration = 1.0


def test_every_key_is_documented_and_in_the_schema():
    for section in SECTIONS:
        for spec in keys_of(section):
            assert spec.metadata["doc"].strip(), f"{section.TABLE}.{spec.name}"
            assert SCHEMA[section.TABLE][spec.name] == spec.default
    assert set(SCHEMA) == {"", *(s.TABLE for s in SECTIONS)}
    assert set(SCHEMA[""]) == {"name", "description", "duration"}


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_to_toml_parses_back_to_the_same_scenario(name):
    scenario = load_scenario(name)
    assert parse_scenario(scenario.to_toml(), scenario.source) == scenario


def test_unnamed_scenario_takes_its_file_stem(tmp_path):
    path = _write(tmp_path, BASE.replace('name = "user"\n', ""), name="nameless.toml")
    assert load_scenario(path).name == "nameless"


def test_with_values_refuses_an_unknown_section():
    with pytest.raises(ScenarioError) as err:
        load_scenario("experiment1").with_values(**{"nosection.x": 1.0})
    assert err.value.field == "nosection"


# ---------------------------------------------------------------- command line
def test_cli_unknown_scenario_exits_2_with_one_line(tmp_path, capsys):
    status = main(["run", "nosuch", "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    assert status == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("pbvs-pin: error:") and "nosuch" in lines[0]
    assert "Traceback" not in captured.err
    assert not (tmp_path / "out").exists()


def test_cli_invalid_field_exits_2_naming_file_and_field(tmp_path, capsys):
    path = _write(tmp_path, BASE + "\n[controller]\nk = [-1.0]\n")
    status = main(["run", str(path), "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    assert status == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0] and "controller.k" in lines[0]
    assert "Traceback" not in captured.err
