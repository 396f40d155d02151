"""One run of a scenario: simulate it, write its log, summary, figures, replay and bag.

The paper's reproduction over the robots, and its report, is :mod:`pbvs_pin.study.reproduction`.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import replace
from pathlib import Path
from typing import Any

from pbvs_pin.bringup.catalogue import ROBOT_NAMES
from pbvs_pin.exceptions import (
    GainError,
    OutputError,
    OutputsInterrupted,
    RobotNotFound,
    RunInterrupted,
    ScenarioError,
)
from pbvs_pin.interrupts import (
    interrupt_point,
    interrupts_held,
    simulating,
    stage,
    with_interrupt_point,
)
from pbvs_pin.sim.log import (
    RunLog,
    check_writable,
    write_json_atomically,
)
from pbvs_pin.sim.loop import Snapshot, simulate
from pbvs_pin.sim.metrics import summarize
from pbvs_pin.sim.scenario import Scenario, load_scenario, parse_scenario
from pbvs_pin.study.claims import judge
from pbvs_pin.study.report import CLAIMS
from pbvs_pin.validation import as_path, read_toml

PAPER_CLAIMS = {name: claim.text for name, claim in CLAIMS.items()}
"""The paper's claim for each experiment (§5); the rules: :data:`pbvs_pin.study.claims.CLAIMS`."""


def run_scenario(
    scenario: str | Path | Scenario,
    out: str | Path,
    html: str | Path | None = None,
    progress: bool = True,
    observer: Callable[[Snapshot], None] | None = None,
    figures: bool = True,
    status: Callable[[str], None] | None = None,
    eye_view: str | None = None,
    bag: str | Path | None = None,
) -> tuple[RunLog, dict[str, Any]]:
    """Simulate one scenario; write ``log.npz``, ``summary.json`` and figures into ``out``.

    The outputs are checked writable before the simulation starts; the log and summary are
    written atomically (whole or not at all). The summary holds the run's figures
    (:func:`pbvs_pin.sim.metrics.summarize`) and its verdict by its experiment's rule
    (:func:`pbvs_pin.study.claims.judge`: ``met``, ``not_judged``, ``rule``, ``clauses``).

    Args:
        scenario: A shipped name, a TOML path, or a loaded scenario.
        out: Output folder (created).
        html: Where to write a standalone HTML replay, if anywhere.
        progress: Show a progress bar.
        observer: Live-view callback, see :func:`pbvs_pin.sim.loop.simulate`.
        figures: Also draw the run's figures.
        status: Told what is being written after the simulation ("figures", "replay").
        eye_view: Also write the robot's-eye view (:func:`pbvs_pin.viz.eye_view.write_eye_view`):
            ``"strip"`` as ``out/eye_view.png``, ``"video"`` as ``out/eye_view.mp4``; the HTML
            replay then shows it beside the scene.
        bag: Also write the run as a ROS 2 bag into this new folder
            (:func:`pbvs_pin.ros.run_bag.write_run_bag`; the ``ros`` extra).

    Returns:
        The log and its summary.

    Raises:
        OutputError: If ``out`` or ``html`` cannot be written (before simulating), or a write
            fails (a full disk).
        RunInterrupted: On Ctrl-C during the simulation, after the run so far was saved as
            ``out/log.npz`` (``meta["interrupted"]`` true; no summary, figures or replay).
        OutputsInterrupted: On Ctrl-C while the finished run's outputs are written, naming
            those written whole and those not written.
        GainError: If ``eye_view`` is neither ``"strip"`` nor ``"video"`` (before simulating).
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    out = as_path("out", out)
    html = None if html is None else as_path("html", html)
    bag = None if bag is None else as_path("bag", bag)
    check_writable(out, *([html] if html is not None else []))
    if eye_view not in (None, "strip", "video"):
        raise GainError(f"eye view: expected 'strip' or 'video', got {eye_view!r}", "eye_view")
    held = interrupts_held()  # Ctrl-C taken at a logged instant, never inside compiled code
    suffix = "mp4" if eye_view == "video" else "png"
    outputs = [
        (f"the log {out / 'log.npz'}", "", True),
        (f"the summary {out / 'summary.json'}", "", True),
        (f"the figures in {out}", "figures", figures),
        (f"the replay {html}", "replay", html is not None),
        (f"the eye view {out / f'eye_view.{suffix}'}", "eye view", eye_view is not None),
        (f"the bag {bag}", "bag", bag is not None),
    ]
    outputs = [(name, what) for name, what, wanted in outputs if wanted]
    try:
        with simulating() if held else nullcontext():
            stage("simulation")
            observer = with_interrupt_point(observer) if held else observer
            log = simulate(scenario, progress=progress, observer=observer)
    except RunInterrupted as stop:
        stop.lost = tuple(name for name, _ in outputs[1:])
        if stop.log is not None:
            stop.saved = str(stop.log.save(out))
        raise
    kept: list[str] = []
    try:
        with simulating() if held else nullcontext():  # a Ctrl-C waits for log and summary
            stage("outputs")
            log.save(out)
            kept.append(outputs[0][0])
            summary = summarize(log)
            summary |= judge(summary)  # met, not_judged, rule, clauses
            write_json_atomically(out / "summary.json", summary)
            kept.append(outputs[1][0])
        interrupt_point()  # a Ctrl-C held after the last logged instant: the run is saved
        for name, what in outputs[2:]:
            if status is not None:
                status(what)
            _write_output(what, log, scenario, out, html, eye_view, bag)
            kept.append(name)
    except OSError as err:
        where = err.filename or out
        raise OutputError(str(where), f"cannot write ({err.strerror or err})") from err
    except KeyboardInterrupt as stop:
        lost = [name for name, _ in outputs if name not in kept]
        raise OutputsInterrupted(kept, lost) from stop
    stage("written")
    return log, summary


def _write_output(
    what: str, log: RunLog, scenario: Scenario, out: Path, html: Path | None, eye: str | None,
    bag: Path | None = None,
) -> None:
    """Write one output of a finished run: figures, replay, eye view or bag (``what``)."""
    if what == "figures":
        from pbvs_pin.viz.figures import plot_run

        plot_run(log, out, footprint=(scenario.platform.length, scenario.platform.width))
    elif what == "replay" and html is not None:
        from pbvs_pin.viz.html_replay import write_run_replay

        write_run_replay(log, html, eye_view=eye is not None)
    elif what == "eye view" and eye is not None:
        from pbvs_pin.viz.eye_view import write_eye_view

        write_eye_view(log, out / f"eye_view.{'mp4' if eye == 'video' else 'png'}", eye)
    elif what == "bag" and bag is not None:
        from pbvs_pin.ros.commands import ros_module

        ros_module("run_bag").write_run_bag(log, bag)


def robot_file(path: str) -> Scenario:
    """The scenario of a robot file (or a whole scenario file): a TOML file with ``[robot]``.

    Raises:
        ScenarioError: A missing, unreadable or invalid file, or one without ``[robot]``.
    """
    if not as_path("robot", path).is_file():
        raise ScenarioError(path, "", "no such robot or scenario file")
    scenario = load_scenario(path)
    if "robot" not in read_toml(Path(path), "a robot file"):
        raise ScenarioError(path, "robot", 'no [robot] table; add one: [robot] name = "..."')
    return scenario


def with_robot(scenario: Scenario, robot: str) -> Scenario:
    """``scenario`` on another robot: a shipped name, a URDF file, or a robot file.

    A robot file is a TOML file with a ``[robot]`` table (its relative paths are read against
    its folder, and the robot's errors and warnings name it); a URDF file needs a
    ``camera_optical_frame``.

    Raises:
        RobotNotFound: If ``robot`` is neither a file nor a shipped name.
        ScenarioError: If the robot file has no ``[robot]`` table or the table is invalid.
    """
    own = None  # a robot file's table, which names that file
    if as_path("robot", robot).suffix.lower() == ".toml":
        own = robot_file(robot).robot  # names the file and field of any bad value
        table = own.to_toml()
    elif Path(robot).suffix.lower() == ".urdf" or Path(robot).is_file():
        table = {"urdf": str(Path(robot).resolve()), "camera_frame": "camera_optical_frame"}
    elif robot in ROBOT_NAMES:
        table = {"name": robot}
    else:
        raise RobotNotFound(robot, ROBOT_NAMES)
    raw = scenario.to_toml()
    raw["robot"] = table
    changed = parse_scenario(raw, scenario.source)
    return changed if own is None else replace(changed, robot=own)
