"""Generated bad input (issue 24 item 3): every door, fuzzed with hypothesis, seeded.

Doors: the command line (``run`` on mutated scenarios with ``--set`` and ``--duration``, the run
itself replaced by a trap), scenario files (a shipped scenario mutated key by key: types, signs, lengths, NaN and
infinity, huge and tiny values, unknown keys and tables, several keys at once), URDF files
(the reference robot's, with tags removed, trees broken, masses and inertias zero, negative
or NaN, limits reversed, unknown joint types), run logs (truncated, bit-flipped, foreign
archives, random channels), sweep folders (damaged ``results.csv``, ``timings.csv`` and
``sweep.json``) and robot files (mutated ``[robot]`` tables, foreign bytes).

Property: the project's own error, in one line, or an accepted input that is sound (a robot
whose mass matrix is symmetric positive definite; a scenario that runs 0.1 s without a
non-finite number in its log); never a raw Python error or a hang (each case runs under
:data:`CASE_SECONDS`, enforced by a timer signal).

Every test is derandomised (the same cases on every run). ``PBVS_FUZZ_EXAMPLES`` multiplies
the number of cases (1 in CI, 2 212 cases; e.g. 20 for a nightly run);
``PBVS_FUZZ_SEED`` replaces the fixed derandomisation by that seed, so that nightly runs
explore new cases. ``PBVS_FUZZ_SURVEY=1`` records the class of every outcome instead of
failing on the first raw error, and prints the count per class at the end (how the numbers of
docs/bad_input.rst were measured).
"""

from __future__ import annotations

import collections
import contextlib
import io
import json
import math
import os
import signal
import tomllib
import warnings
import zipfile
from xml.etree import ElementTree

import numpy as np
import pinocchio as pin
import pytest
from conftest import URDF_DIR
from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st

from pbvs_pin import MobileManipulator
from pbvs_pin.cli import main
from pbvs_pin.exceptions import PbvsError, PbvsWarning
from pbvs_pin.sim.log import RunLog
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import SCHEMA, load_scenario, scenario_dir
from pbvs_pin.study.experiments import with_robot
from pbvs_pin.study.sweep.spec import load_sweep
from pbvs_pin.study.sweep.table import TABLE, TIMINGS, ResultTable, check_folder, read_table

SCALE = max(1, int(os.environ.get("PBVS_FUZZ_EXAMPLES", "1")))
"""Multiplier of every test's number of cases."""

SURVEY = os.environ.get("PBVS_FUZZ_SURVEY") == "1"
"""Count outcome classes instead of failing (see the module docstring)."""

CASE_SECONDS = 10.0
"""Longest a generated case may take (a hang fails the test)."""

OUTCOMES: collections.Counter = collections.Counter()
"""``door: outcome class`` -> cases, filled by every case."""


def _settings(examples: int):
    """Seeded settings: derandomised, or ``PBVS_FUZZ_SEED``; no example database."""
    chosen = os.environ.get("PBVS_FUZZ_SEED")
    configured = settings(
        max_examples=examples * SCALE,
        derandomize=chosen is None,
        database=None,
        deadline=None,  # the timer below bounds each case; hypothesis's deadline only reports
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                               HealthCheck.filter_too_much, HealthCheck.data_too_large],
    )  # fmt: skip

    def decorate(test):
        test = configured(test)
        return seed(int(chosen))(test) if chosen is not None else test

    return decorate


class CaseTimeout(Exception):
    """A generated case ran longer than :data:`CASE_SECONDS`."""


@contextlib.contextmanager
def _bounded(seconds: float = CASE_SECONDS):
    """Raise :class:`CaseTimeout` in the case if it runs longer than ``seconds``."""

    def expire(signum, frame):
        raise CaseTimeout(f"case ran longer than {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _outcome(door: str, call, allowed=(PbvsError,)):
    """Run one case: its result, or None after an allowed error (one line, recorded).

    A raw error fails the test (or, in survey mode, is recorded by class).
    """
    try:
        with _bounded(), warnings.catch_warnings():
            warnings.simplefilter("ignore", PbvsWarning)
            result = call()
    except allowed as err:
        assert "\n" not in str(err), str(err)
        OUTCOMES[f"{door}: {type(err).__name__}"] += 1
        return None
    except Exception as err:
        if not SURVEY:
            raise
        OUTCOMES[f"{door}: raw {type(err).__name__}"] += 1
        return None
    OUTCOMES[f"{door}: accepted"] += 1
    return result


@pytest.fixture(scope="module", autouse=True)
def _report_outcomes():
    yield
    if SURVEY:
        print("\nfuzz outcomes:")
        for key, count in sorted(OUTCOMES.items()):
            print(f"  {key}: {count}")


# ---------------------------------------------------------------- TOML text
def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return "nan" if math.isnan(value) else repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + "}"
    raise AssertionError(f"test setup: no TOML for {value!r}")


def toml_text(raw: dict) -> str:
    """A TOML file for ``raw``: root keys, then tables, then arrays of tables."""
    lines = [f"{k} = {_toml_value(v)}" for k, v in raw.items() if not _is_table(v)
             and not _is_table_array(v)]  # fmt: skip
    for name, table in raw.items():
        if _is_table(table):
            lines += ["", f"[{name}]", *(f"{k} = {_toml_value(v)}" for k, v in table.items())]
    for name, tables in raw.items():
        if _is_table_array(tables):
            for table in tables:
                lines += ["", f"[[{name}]]",
                          *(f"{k} = {_toml_value(v)}" for k, v in table.items())]  # fmt: skip
    return "\n".join(lines) + "\n"


def _is_table(value) -> bool:
    return isinstance(value, dict) and all(not isinstance(v, dict) for v in value.values())


def _is_table_array(value) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def test_toml_text_round_trips():
    raw = tomllib.loads((scenario_dir() / "experiment2.toml").read_text())
    assert tomllib.loads(toml_text(raw)) == raw


# ---------------------------------------------------------------- scenario files
SPECIAL_FLOATS = [0.0, -0.0, -1.0, 1e-300, 5e-324, 1e300, -1e300, math.inf, -math.inf, math.nan]
WRONG = st.one_of(
    st.sampled_from(SPECIAL_FLOATS),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(2**63), 2**63 - 1),
    st.booleans(),
    st.text(max_size=6),
    st.lists(st.floats(-1e3, 1e3), max_size=5),
    st.lists(st.sampled_from(SPECIAL_FLOATS), min_size=1, max_size=4),
    st.lists(st.lists(st.integers(-5, 5), max_size=3), max_size=3),
    st.lists(st.text(max_size=2), min_size=1, max_size=3),
    st.dictionaries(st.sampled_from(["a", "kind", "x"]), st.integers(-3, 3), max_size=2),
)
"""Values of every TOML type, signs, sizes and lengths."""

SCENARIOS = sorted(p.stem for p in scenario_dir().glob("*.toml"))
TABLES = sorted(SCHEMA)
UNKNOWN = st.sampled_from(["speed", "Rate", "k_p", "unknown", "x"])


def _scaled(original, factor: float):
    """A numeric value (or list) scaled: same type, another size or sign."""
    if isinstance(original, bool) or not isinstance(original, int | float | list | tuple):
        return original
    if isinstance(original, list | tuple):
        return [_scaled(v, factor) for v in original]
    return type(original)(original * factor) if math.isfinite(original * factor) else original


@st.composite
def mutated_scenarios(draw) -> dict:
    """A shipped scenario with one to three keys changed, added or removed."""
    raw = tomllib.loads((scenario_dir() / f"{draw(st.sampled_from(SCENARIOS))}.toml").read_text())
    for _ in range(draw(st.integers(1, 3))):
        table = draw(st.sampled_from([*TABLES, "obstacles", "nosuchtable"]))
        if table == "obstacles":
            obstacles = raw.setdefault("obstacles", [{"kind": "circle", "x": 2.0, "y": 0.5,
                                                      "radius": 0.2}])  # fmt: skip
            if not _is_table_array(obstacles):
                continue
            target = draw(st.sampled_from(obstacles))
            keys = ["kind", "x", "y", "radius", "width", "length", "yaw"]
        else:
            target = raw if table == "" else raw.setdefault(table, {})
            if not isinstance(target, dict):
                continue
            keys = sorted(SCHEMA.get(table, {}))
        key = draw(st.one_of(st.sampled_from(keys), UNKNOWN) if keys else UNKNOWN)
        action = draw(st.sampled_from(["wrong", "scale", "remove"]))
        if action == "remove":
            target.pop(key, None)
        elif action == "scale":
            original = target.get(key, SCHEMA.get(table, {}).get(key))
            factor = draw(st.sampled_from([-1.0, 0.0, 1e-9, 1e-3, 0.5, 2.0, 10.0, 1e3, 1e9]))
            target[key] = _scaled(original, factor) if original is not None else factor
        else:
            target[key] = draw(WRONG)
    return raw


@_settings(800)
@given(raw=mutated_scenarios())
def test_a_mutated_scenario_is_refused_in_one_line_or_accepted(tmp_path_factory, raw):
    path = tmp_path_factory.mktemp("scenario") / "mutated.toml"
    try:
        path.write_text(toml_text(raw))
    except AssertionError:
        return  # a value TOML cannot hold
    _outcome("scenario", lambda: load_scenario(path))


SOUND_CHANNELS = ("q", "v", "u", "v_ref")
"""Channels that must stay finite in a run of an accepted scenario."""

GENTLE = st.sampled_from([0.5, 0.8, 1.25, 2.0])


@st.composite
def perturbed_scenarios(draw) -> dict:
    """A shipped scenario with gains, rates, noise and target values scaled by 0.5-2."""
    raw = tomllib.loads((scenario_dir() / f"{draw(st.sampled_from(SCENARIOS))}.toml").read_text())
    for table, key in draw(st.lists(st.sampled_from([
        ("controller", "k"), ("controller", "k1"), ("controller", "k2"), ("camera", "rate"),
        ("camera", "noise_px"), ("estimator", "alpha"), ("target", "diameter"),
        ("motion", "velocity"), ("model_error", "kinematic_scale"), ("camera", "focal_px"),
    ]), min_size=1, max_size=3, unique=True)):  # fmt: skip
        section = raw.setdefault(table, {})
        original = section.get(key, SCHEMA[table][key])
        section[key] = _scaled(original, draw(GENTLE)) if original else draw(GENTLE) * 0.1
    raw["duration"] = 0.1
    raw.pop("plant", None)  # the Pinocchio plant: MuJoCo is fuzzed by its own tests
    return raw


@_settings(12)
@given(raw=perturbed_scenarios())
def test_an_accepted_scenario_runs_without_a_non_finite_number(tmp_path_factory, raw):
    path = tmp_path_factory.mktemp("scenario") / "perturbed.toml"
    path.write_text(toml_text(raw))
    scenario = _outcome("perturbed scenario", lambda: load_scenario(path))
    if scenario is None:
        return
    log = _outcome("perturbed run", lambda: simulate(scenario))
    if log is None:
        return
    for name in SOUND_CHANNELS:
        assert np.isfinite(log[name]).all(), name


# ---------------------------------------------------------------- URDF files
CYTON = (URDF_DIR / "pioneer_cyton.urdf").read_text()
JOINT_TYPES = ["revolute", "continuous", "prismatic", "fixed", "floating", "planar",
               "spherical", "bogus", ""]  # fmt: skip
BAD_NUMBERS = ["0", "-1", "nan", "inf", "-inf", "1e300", "1e-300", "abc", "", "1 2"]


@st.composite
def mutated_urdfs(draw) -> str:
    """The reference robot's URDF with one to three elements or attributes damaged."""
    root = ElementTree.fromstring(CYTON)
    for _ in range(draw(st.integers(1, 3))):
        elements = list(root.iter())
        kind = draw(st.sampled_from(["remove", "attribute", "joint_type", "limits", "parent",
                                     "mass", "inertia", "duplicate"]))  # fmt: skip
        if kind == "remove":
            element = draw(st.sampled_from(elements[1:]))
            parent = next(p for p in root.iter() if element in list(p))
            parent.remove(element)
        elif kind == "attribute":
            element = draw(st.sampled_from([e for e in elements if e.attrib] or [root]))
            name = draw(st.sampled_from(sorted(element.attrib) or ["name"]))
            element.set(name, draw(st.sampled_from(BAD_NUMBERS)))
        elif kind == "joint_type":
            joint = draw(st.sampled_from(root.findall("joint")))
            joint.set("type", draw(st.sampled_from(JOINT_TYPES)))
        elif kind == "limits":
            limits = root.findall("joint/limit")
            if limits:
                limit = draw(st.sampled_from(limits))
                lower, upper = limit.get("lower", "0"), limit.get("upper", "0")
                limit.set("lower", upper)
                limit.set("upper", lower)
        elif kind == "parent":
            parent = draw(st.sampled_from(root.findall("joint/parent")))
            links = [link.get("name") for link in root.findall("link")]
            parent.set("link", draw(st.sampled_from([*links, "no_such_link"])))
        elif kind == "mass":
            masses = root.findall("link/inertial/mass")
            if masses:
                draw(st.sampled_from(masses)).set("value", draw(st.sampled_from(BAD_NUMBERS)))
        elif kind == "inertia":
            inertias = root.findall("link/inertial/inertia")
            if inertias:
                inertia = draw(st.sampled_from(inertias))
                axis = draw(st.sampled_from(["ixx", "iyy", "izz", "ixy", "ixz", "iyz"]))
                inertia.set(axis, draw(st.sampled_from(BAD_NUMBERS)))
        else:
            root.append(draw(st.sampled_from(elements[1:])))
    return ElementTree.tostring(root, encoding="unicode")


def _sound_robot(robot: MobileManipulator) -> None:
    """An accepted robot's mass matrix at a neutral posture is finite, symmetric, positive."""
    q = robot.neutral()
    mass = pin.crba(robot.model, robot.data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    assert np.isfinite(mass).all()
    assert np.linalg.eigvalsh(mass).min() > 0.0
    limits = robot.velocity_limits
    assert np.isfinite(limits).all() and (limits > 0).all()


@_settings(200)
@given(text=mutated_urdfs())
def test_a_mutated_urdf_is_refused_in_one_line_or_sound(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("urdf") / "mutated.urdf"
    path.write_text(text)
    robot = _outcome("urdf", lambda: MobileManipulator.from_urdf(str(path)))
    if robot is not None:
        _sound_robot(robot)


# ---------------------------------------------------------------- run logs
def _valid_log_bytes() -> bytes:
    buffer = io.BytesIO()
    channels = {"t": np.arange(20) * 0.1, "xi": np.zeros((20, 3)), "q": np.zeros((20, 7))}
    np.savez_compressed(buffer, meta=json.dumps({"scenario": "x", "duration": 2.0}), **channels)
    return buffer.getvalue()


VALID_LOG = _valid_log_bytes()
ARRAYS = st.one_of(
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=6).map(np.array),
    st.integers(0, 4).map(lambda n: np.zeros((n, 2))),
    st.text(max_size=5).map(np.array),
    st.just(np.array(3.0)),
)


@st.composite
def damaged_logs(draw) -> bytes:
    """A log cut, bit-flipped, replaced by random bytes, or a foreign archive."""
    kind = draw(st.sampled_from(["cut", "flip", "random", "foreign", "channels"]))
    if kind == "cut":
        return VALID_LOG[: draw(st.integers(0, len(VALID_LOG) - 1))]
    if kind == "flip":
        data = bytearray(VALID_LOG)
        for index in draw(st.lists(st.integers(0, len(data) - 1), min_size=1, max_size=4)):
            data[index] ^= 1 << draw(st.integers(0, 7))
        return bytes(data)
    if kind == "random":
        return draw(st.binary(max_size=300))
    buffer = io.BytesIO()
    if kind == "foreign":
        with zipfile.ZipFile(buffer, "w") as archive:
            archive.writestr(draw(st.sampled_from(["readme.txt", "t.npy", "meta.npy"])),
                             draw(st.binary(max_size=40)))  # fmt: skip
        return buffer.getvalue()
    channels = draw(st.dictionaries(st.sampled_from(["t", "xi", "q", "storage", "saturated"]),
                                    ARRAYS, max_size=4))  # fmt: skip
    meta = draw(st.one_of(st.just(json.dumps({"scenario": "x"})), st.text(max_size=8)))
    np.savez(buffer, meta=meta, **channels)
    return buffer.getvalue()


@_settings(500)
@given(data=damaged_logs())
def test_a_damaged_log_is_refused_in_one_line(tmp_path_factory, data):
    folder = tmp_path_factory.mktemp("log")
    (folder / "log.npz").write_bytes(data)
    _outcome("log", lambda: RunLog.load(folder))
    stderr = io.StringIO()
    with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(io.StringIO()):
        status = _outcome("analyze (main)", lambda: main(["analyze", str(folder)]))
    if status is None:  # a raw error, recorded in survey mode
        return
    OUTCOMES[f"analyze: exit {status}"] += 1
    assert status in (0, 2), stderr.getvalue()
    assert "Traceback" not in stderr.getvalue()
    if status == 2:
        assert stderr.getvalue().count("\n") == 1


# ---------------------------------------------------------------- sweep folders
SPEC = load_sweep("target_speed")
FILE_CONTENTS = st.one_of(
    st.none(),
    st.binary(max_size=200),
    st.text(max_size=200),
    st.just(b"run_id,status\nabc,ok\n"),
    st.just(b'{"fingerprint": 3}'),
    st.just(b"[1, 2]"),
    st.just(json.dumps({"fingerprint": SPEC.fingerprint}).encode()),
    st.just("folder"),
)


def _write(path, content) -> None:
    if content is None:
        return
    if content == "folder":
        path.mkdir()
    elif isinstance(content, str):
        path.write_text(content, encoding="utf-8", errors="surrogatepass")
    else:
        path.write_bytes(content)


@_settings(250)
@given(table=FILE_CONTENTS, timings=FILE_CONTENTS, meta=FILE_CONTENTS, force=st.booleans())
def test_a_damaged_sweep_folder_is_refused_in_one_line_or_resumed(tmp_path_factory, table,
                                                                  timings, meta, force):
    out = tmp_path_factory.mktemp("sweep")
    for name, content in ((TABLE, table), (TIMINGS, timings), ("sweep.json", meta)):
        _write(out / name, content)

    def resume() -> list:
        check_folder(SPEC, out, force)
        ResultTable(out / TABLE)
        return read_table(out / TABLE) if (out / TABLE).is_file() else []

    _outcome("sweep folder", resume)


# ---------------------------------------------------------------- robot files
ROBOT_KEYS = sorted(SCHEMA["robot"])
EXPERIMENT = load_scenario("experiment1")


@st.composite
def robot_files(draw) -> bytes:
    """A ``[robot]`` table with wrong keys and values, or foreign bytes."""
    kind = draw(st.sampled_from(["table", "table", "random", "urdf", "no_table"]))
    if kind == "random":
        return draw(st.binary(max_size=200))
    if kind == "urdf":
        return CYTON[: draw(st.integers(0, 400))].encode()
    table = {draw(st.one_of(st.sampled_from(ROBOT_KEYS), UNKNOWN)): draw(
        st.one_of(WRONG, st.sampled_from(["pioneer_ur5", "tiago", "no_such", "ur5",
                                          "pioneer3at", "missing.urdf"])))
             for _ in range(draw(st.integers(0, 4)))}  # fmt: skip
    raw = {"camera": {"rate": 30.0}} if kind == "no_table" else {"robot": table}
    return toml_text(raw).encode()


@_settings(300)
@given(data=robot_files())
def test_a_bad_robot_file_is_refused_in_one_line(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("robot") / "my_robot.toml"
    path.write_bytes(data)
    _outcome("robot file", lambda: with_robot(EXPERIMENT, str(path)))


# ---------------------------------------------------------------- the command line
class _Trapped(Exception):
    """Raised instead of simulating: the command line accepted its input."""


SET_KEYS = [f"{table}.{key}" if table else key for table in TABLES for key in SCHEMA[table]]
SET_TEXT = st.one_of(
    st.tuples(st.sampled_from(SET_KEYS), st.sampled_from(["=", "", "=="]),
              st.one_of(WRONG.map(lambda v: _toml_value(v)), st.text(max_size=8)))
    .map("".join),
    st.text(max_size=12),
)  # fmt: skip
"""``--set`` arguments: known keys with values of every kind, and arbitrary text."""


@_settings(150)
@given(raw=mutated_scenarios(), settings_=st.lists(SET_TEXT, max_size=2),
       duration=st.sampled_from([None, "0", "-1", "nan", "1e-9", "2.5", "1e300", "x"]))
def test_the_command_line_refuses_in_one_line_or_starts_the_run(tmp_path_factory, monkeypatch,
                                                                raw, settings_, duration):
    """``run`` on a mutated scenario with ``--set`` and ``--duration``; the run is trapped."""
    folder = tmp_path_factory.mktemp("cli")
    try:
        (folder / "s.toml").write_text(toml_text(raw))
    except AssertionError:
        return
    argv = ["run", str(folder / "s.toml"), "--out", str(folder / "out")]
    argv += [x for text in settings_ for x in ("--set", text)]
    argv += ["--duration", duration] if duration is not None else []

    def trap(*args, **kwargs):
        raise _Trapped

    monkeypatch.setattr("pbvs_pin.study.experiments.run_scenario", trap)
    stderr = io.StringIO()
    with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(io.StringIO()):
        status = _outcome("command line", lambda: main(argv), allowed=(_Trapped, SystemExit))
    if status is not None:
        OUTCOMES[f"command line: exit {status}"] += 1
        assert status == 2
        assert stderr.getvalue().count("\n") == 1 and "Traceback" not in stderr.getvalue()
