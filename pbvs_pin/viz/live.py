"""Live Meshcat views: a running simulation (:class:`LiveView`) and a robot (:func:`view_robot`).

Both draw with the scene modules of :mod:`pbvs_pin.viz`; a run is drawn by the same
:class:`~pbvs_pin.viz.run_scene.RunScene` as the standalone replay of
:mod:`pbvs_pin.viz.html_replay`.

A live view must never cost the run its results, and little of its time. :meth:`LiveView.show`
is called at the log rate; it records trail points and sends the scene at most
:data:`MAX_RATE` times a second of wall-clock time, one meshcat command per moving node (the
robot has one node per joint). Commands wait at most :data:`SEND_TIMEOUT` for the server; if
it stops answering, the view prints one warning on stderr and does nothing from then on,
while the simulation goes on. With a ``speed``, :meth:`LiveView.show` also holds the
simulation back so that the browser plays the run at that many simulated seconds per second
(``pbvs-pin run --meshcat`` plays in real time); without one the run goes as fast as it can.

The robot's-eye view (:class:`~pbvs_pin.viz.eye_panel.EyePanel`) is a panel in the lower left
of the browser's view: the rendered camera's newest frame with its detections and ``xi_d``
marked, or, with the points camera, the measured points drawn as discs with the same marks.
It is sent at most :data:`EYE_VIEW_RATE` times a second of wall-clock time, and only when
there is something new to show (a new frame, or moved points).
"""

from __future__ import annotations

import contextlib
import sys
import time
import webbrowser
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pbvs_pin.bringup.catalogue import build_robot
from pbvs_pin.exceptions import PbvsError, ViewerUnavailable
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.perception.features import TwoSphereFeatures
from pbvs_pin.sim.loop import Snapshot
from pbvs_pin.sim.scenario import Scenario, load_scenario, obstacle_table
from pbvs_pin.sim.setup import solve_target_start
from pbvs_pin.validation import positive_number
from pbvs_pin.viz import server
from pbvs_pin.viz.eye_panel import EyePanel
from pbvs_pin.viz.frustum import add_camera_frustum, add_camera_triad
from pbvs_pin.viz.primitives import set_camera_view
from pbvs_pin.viz.recorder import offline_visualizer
from pbvs_pin.viz.robot_scene import RobotScene
from pbvs_pin.viz.run_scene import (
    FRUSTUM_DEPTH,
    TRIAD_SCALE,
    RunFacts,
    RunScene,
    two_sphere_points,
)

if TYPE_CHECKING:  # pragma: no cover - typing only
    import meshcat

SEND_TIMEOUT = 5.0
"""Longest wait for the meshcat server to take one command [s]; longer means it is gone."""

TRAIL_EVERY = 10
"""Snapshots between two redraws of the trails."""

TRAIL_STEP = 0.002
"""Smallest distance between two trail points [m]: a still platform or target adds none."""

MAX_RATE = 30.0
"""Most scene updates sent per second of wall-clock time [Hz]."""

EYE_VIEW_RATE = 5.0
"""Most robot's-eye view images sent per second of wall-clock time [Hz]."""

LIVE_ADVICE = (
    "run without --meshcat and add `--html FILE` to write a standalone replay next to the "
    "results (`pbvs-pin run SCENARIO --html FILE`), then open that file in a browser"
)
"""What to do when the live view cannot start."""

VIEW_ADVICE = (
    "write a standalone file with `pbvs-pin view {name} --html FILE` (no server needed) "
    "and open it in a browser"
)
"""What to do when :func:`view_robot` cannot serve (``{name}``: the robot asked for)."""

ROBOT_VIEW = (1.3, -1.5, 1.1)
"""Initial position of the browser's viewing camera for :func:`view_robot` [m]."""


@dataclass(frozen=True)
class LiveStats:
    """What a live view did, for measuring its cost to the run.

    Attributes:
        snapshots: Calls of :meth:`LiveView.show`.
        frames: Scene updates sent to the server (at most :data:`MAX_RATE` a second).
        show_seconds: Mean wall time of one :meth:`LiveView.show` call [s].
        frame_seconds: Mean wall time of the calls that sent a scene update (and with it,
            at most :data:`EYE_VIEW_RATE` times a second, a robot's-eye view image) [s].
        total_seconds: Wall time the run spent in :meth:`LiveView.show` [s].
        eye_frames: Robot's-eye view images sent (at most :data:`EYE_VIEW_RATE` a second).
        eye_seconds: Mean wall time of marking, encoding and sending one of them [s].
    """

    snapshots: int
    frames: int
    show_seconds: float
    frame_seconds: float
    total_seconds: float
    eye_frames: int = 0
    eye_seconds: float = 0.0


def _start(scenario: Scenario, robot: MobileManipulator) -> tuple[np.ndarray, np.ndarray]:
    """The run's start: configuration and sphere centres (as :func:`simulate` sets them)."""
    q0 = robot.home()
    arm = scenario.robot.initial_arm
    if arm is not None:
        with contextlib.suppress(PbvsError):  # the run itself reports a bad value
            q0 = robot.with_arm_positions(q0, arm)
    target = scenario.target
    features = TwoSphereFeatures(target.diameter)
    top = solve_target_start(
        robot, q0, features, target.separation, np.asarray(target.xi0, dtype=float)
    )
    return q0, np.array([top, top - [0.0, 0.0, target.separation]])


class LiveView:
    """A meshcat server showing a run as it is simulated.

    Use it as a context manager and pass :meth:`show` as the simulation's observer::

        with LiveView("experiment1") as live:
            print(live.url)
            log = simulate(load_scenario("experiment1"), observer=live.show)

    Every snapshot extends the trails; the scene itself is sent at most :data:`MAX_RATE`
    times a second of wall-clock time (a browser shows no more), the trails every
    ``trail_every`` snapshots, and :meth:`flush` or leaving the context sends the newest
    snapshot. Nothing here raises once the view is up: if the server stops answering, one
    warning goes to stderr and the view does nothing from then on.

    Attributes:
        scenario: The scenario shown.
        robot: The robot drawn (its own instance, not the simulation's).
        vis: The served visualizer.
        url: Address of the viewer page.
        scene: The drawn :class:`~pbvs_pin.viz.run_scene.RunScene`.
        eye: The robot's-eye view panel (None when ``eye_view`` is off).
    """

    def __init__(
        self,
        scenario: str | Path | Scenario,
        timeout: float | None = None,
        trail_every: int = TRAIL_EVERY,
        speed: float | None = None,
        eye_view: bool = True,
    ) -> None:
        """Start a meshcat server and draw the run's scene at its start.

        Args:
            scenario: A shipped scenario name, a TOML path, or a loaded scenario.
            timeout: Longest wait for the server to take one command [s];
                :data:`SEND_TIMEOUT` by default.
            trail_every: Snapshots between two redraws of the trails.
            speed: Simulated seconds shown per wall-clock second: 1.0 plays the run in real
                time, 2.0 twice as fast; ``None`` lets the simulation run as fast as it can.
            eye_view: Show the robot's-eye view panel (module docstring).

        Raises:
            GainError: If ``speed`` is not a positive number.
            ScenarioError: If the scenario cannot be loaded or its robot cannot be built.
            ViewerUnavailable: If the meshcat server cannot be started or stops answering
                while the scene is drawn.
        """
        self.scenario = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
        self.robot = self.scenario.robot.build(self.scenario.camera.intrinsics())
        target = self.scenario.target
        facts = RunFacts(
            target_diameter=target.diameter,
            target_separation=target.separation,
            desired_points=two_sphere_points(target.xi_d),
            obstacles=tuple(obstacle_table(o) for o in self.scenario.obstacles),
        )
        q0, centres0 = _start(self.scenario, self.robot)
        timeout = SEND_TIMEOUT if timeout is None else float(timeout)
        self._speed = None if speed is None else positive_number("speed", speed)
        self._wall_start: float | None = None
        self._trail_every = max(1, int(trail_every))
        self.vis: meshcat.Visualizer = server.start_visualizer(timeout=timeout, advice=LIVE_ADVICE)
        try:
            self.url: str = self.vis.url()
            self.scene = RunScene(self.vis, self.robot, facts)
            self.scene.apply(self.scene.poses(q0, centres0, facts.desired_points))
            self.eye = (
                EyePanel(self.vis, self.robot.camera, facts.desired_points) if eye_view else None
            )
        except Exception as err:  # zmq errors: the server died while drawing
            server.stop_visualizer(self.vis)
            raise ViewerUnavailable(
                f"the meshcat server stopped answering ({type(err).__name__}: {err})",
                LIVE_ADVICE,
            ) from err
        self._platform: list[np.ndarray] = []
        self._target: list[np.ndarray] = []
        self._since_trail = 0
        self._latest: Snapshot | None = None
        self._latest_sent = True
        self._last_frame = -float("inf")
        self._dead = False
        self._closed = False
        self._snapshots = 0
        self._frames = 0
        self._show_time = 0.0
        self._frame_time = 0.0
        self._last_eye = -float("inf")
        self._eye_shown: float | np.ndarray | None = None  # frame time, or points, shown
        self._eye_frames = 0
        self._eye_time = 0.0

    # ------------------------------------------------------------------ context manager
    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # ------------------------------------------------------------------ observer
    def show(self, snapshot: Snapshot) -> None:
        """Show one instant of the run (the simulation's observer); never raises.

        Args:
            snapshot: The instant: time, configuration, sphere centres, measured points.
        """
        if not self.alive:
            return
        started = time.perf_counter()
        sent = False
        try:
            _extend(self._platform, self.scene.platform_point(snapshot.q))
            _extend(self._target, np.asarray(snapshot.centres, dtype=float).mean(axis=0))
            self._since_trail += 1
            self._latest, self._latest_sent = snapshot, False
            if started - self._last_frame >= 1.0 / MAX_RATE:
                self._send(self._since_trail >= self._trail_every)
                self._last_frame = started
                sent = True
                eye_due = started - self._last_eye >= 1.0 / EYE_VIEW_RATE
                if self.eye is not None and eye_due and self._show_eye(self.eye, snapshot):
                    self._last_eye = started
        except Exception as err:  # zmq errors, a dead server: a live view must not stop the run
            self._die(err)
        elapsed = time.perf_counter() - started
        self._snapshots += 1
        self._show_time += elapsed
        if sent:
            self._frames += 1
            self._frame_time += elapsed
        self._keep_pace(snapshot.t, started)

    def _keep_pace(self, t: float, now: float) -> None:
        """Sleep until the wall clock reaches simulated time ``t`` at the chosen speed."""
        if self._speed is None:
            return
        if self._wall_start is None:
            self._wall_start = now - t / self._speed
        wait = self._wall_start + t / self._speed - time.perf_counter()
        if wait > 0.0:
            time.sleep(wait)

    def flush(self) -> bool:
        """Send the newest snapshot and the trails if they are not on the server yet.

        Returns:
            Whether the view is still alive (False after a server failure or :meth:`close`).
        """
        if not self.alive:
            return False
        try:
            if not self._latest_sent:
                self._send(trails=True)
            elif self._since_trail:
                self._draw_trails()
            if self.eye is not None and self._latest is not None:
                self._show_eye(self.eye, self._latest)
        except Exception as err:  # a live view must not stop the run
            self._die(err)
        return self.alive

    def close(self) -> None:
        """Flush, then stop the server; never raises."""
        if self._closed:
            return
        self.flush()
        self._closed = True
        server.stop_visualizer(self.vis)

    def static_html(self) -> str:
        """The served scene as a standalone page (asks the server).

        Raises:
            ViewerUnavailable: If the server does not answer.
        """
        try:
            return self.vis.static_html()
        except Exception as err:
            raise ViewerUnavailable(
                f"the meshcat server did not answer ({type(err).__name__}: {err})", LIVE_ADVICE
            ) from err

    def stats(self) -> LiveStats:
        """Counts and costs of :meth:`show`."""
        return LiveStats(
            snapshots=self._snapshots,
            frames=self._frames,
            show_seconds=self._show_time / max(1, self._snapshots),
            frame_seconds=self._frame_time / max(1, self._frames),
            total_seconds=self._show_time,
            eye_frames=self._eye_frames,
            eye_seconds=self._eye_time / max(1, self._eye_frames),
        )

    @property
    def alive(self) -> bool:
        """Whether the view still sends updates (False after a server failure or close)."""
        return not (self._dead or self._closed)

    # ------------------------------------------------------------------ sending
    def _send(self, trails: bool) -> None:
        """Pose the scene at the newest snapshot, and redraw the trails if asked."""
        snapshot = self._latest
        if snapshot is not None:
            self.scene.apply(self.scene.poses(snapshot.q, snapshot.centres, snapshot.points))
            self._latest_sent = True
        if trails:
            self._draw_trails()

    def _show_eye(self, eye: EyePanel, snapshot: Snapshot) -> bool:
        """Send the robot's-eye view of ``snapshot`` unless it is the one shown.

        Returns:
            Whether an image was sent.
        """
        started = time.perf_counter()
        frame, shown = snapshot.image, self._eye_shown
        if frame is not None:  # the rendered camera's own frame and detections
            if isinstance(shown, float) and shown == frame.time:
                return False
            points = frame.points if frame.visible else None
            eye.show_image(frame.image, points, frame.diameters)
            self._eye_shown = frame.time
        else:  # the points camera: the measured points, drawn
            points = np.asarray(snapshot.points, dtype=float)
            if isinstance(shown, np.ndarray) and np.array_equal(shown, points, equal_nan=True):
                return False
            eye.show_points(points, self._apparent_diameters(snapshot))
            self._eye_shown = points
        self._eye_frames += 1
        self._eye_time += time.perf_counter() - started
        return True

    def _apparent_diameters(self, snapshot: Snapshot) -> np.ndarray:
        """The spheres' apparent diameters ``f D / z`` at their true depths [px]. Shape (2,)."""
        camera = self.robot.camera
        _, depths = camera.project_world(self.robot.camera_pose(snapshot.q), snapshot.centres)
        diameter = self.scenario.target.diameter
        return np.where(depths > 0, camera.focal_px * diameter / np.maximum(depths, 1e-9), np.nan)

    def _draw_trails(self) -> None:
        self.scene.draw_trails(self._platform, self._target)
        self._since_trail = 0

    def _die(self, err: Exception) -> None:
        """Become a no-op after one warning on stderr."""
        self._dead = True
        print(
            f"pbvs-pin: warning: live view stopped ({type(err).__name__}: {err}); "
            "the run continues and its results are still written",
            file=sys.stderr,
        )


def _extend(trail: list[np.ndarray], point: np.ndarray) -> None:
    """Append ``point`` unless it is within :data:`TRAIL_STEP` of the last one."""
    point = np.asarray(point, dtype=float)
    if not trail or float(np.linalg.norm(point - trail[-1])) >= TRAIL_STEP:
        trail.append(point)


# ---------------------------------------------------------------------- robot viewer
def _draw_robot(vis: meshcat.Visualizer, robot: MobileManipulator, q: np.ndarray) -> None:
    """The robot at ``q`` with its camera optical frame (triad) and frustum."""
    robot_scene = RobotScene(vis, robot.model, robot.visual_model, strict=False)
    if robot_scene.failed:
        print(
            f"pbvs-pin: warning: {len(robot_scene.failed)} geometries could not be drawn: "
            + ", ".join(robot_scene.failed),
            file=sys.stderr,
        )
    robot_scene.display(q)
    camera = robot.camera
    add_camera_frustum(
        vis, camera.focal_px, camera.width, camera.height, FRUSTUM_DEPTH,
        pose=robot.camera_pose(q), principal_point=camera.principal_point,
    )  # fmt: skip
    add_camera_triad(vis, TRIAD_SCALE)
    set_camera_view(vis, ROBOT_VIEW)


def _open_browser(url: str) -> bool:
    """``webbrowser.open``, False where no browser can be opened."""
    try:
        return bool(webbrowser.open(url, new=2))
    except webbrowser.Error:
        return False


def view_robot(name: str | MobileManipulator, html: str | Path | None = None) -> Path | None:
    """Show a robot at its home configuration with its camera optical frame and frustum.

    With ``html``, the scene is written to a standalone HTML file (no server involved) and
    its path is printed. Otherwise a meshcat server is started, its URL printed and opened
    in a web browser (or, where none can be opened, the URL to open is printed), and it is
    served until Ctrl-C.

    Args:
        name: A shipped robot name (e.g. ``pioneer_cyton``, ``pioneer_ur5``, ``tiago``), a
            URDF path with a ``camera_optical_frame``, or a built robot.
        html: Output file; ``None`` serves instead.

    Returns:
        The written file, or None after serving.

    Raises:
        RobotNotFound: If ``name`` is not a robot.
        ViewerUnavailable: If the meshcat server cannot be started (serving only).
    """
    robot = name if isinstance(name, MobileManipulator) else build_robot(name)
    q = robot.home()
    if html is not None:
        vis = offline_visualizer()
        _draw_robot(vis, robot, q)
        path = Path(html)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(vis.static_html(), encoding="utf-8")
        print(f"robot view written to {path}")
        return path
    advice = VIEW_ADVICE.format(name=name if isinstance(name, str) else robot.source)
    vis = server.start_visualizer(timeout=SEND_TIMEOUT, advice=advice)
    try:
        try:
            _draw_robot(vis, robot, q)
        except Exception as err:  # zmq errors: the server died while drawing
            raise ViewerUnavailable(
                f"the meshcat server stopped answering ({type(err).__name__}: {err})", advice
            ) from err
        url = vis.url()
        print(f"robot view: {url}")
        if not _open_browser(url):
            print(f"could not open a web browser; open {url} in one")
        print("serving; press Ctrl-C to stop")
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        print("stopped")
    finally:
        server.stop_visualizer(vis)
    return None
