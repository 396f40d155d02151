"""Run logs: what a closed-loop run recorded, saved as ``log.npz`` plus ``summary.json``.

Every channel is an array whose first axis is time (the log rate). Features and errors are in
pixels; the passivity quantities (``storage``, ``nu``, ``gamma``, ``lambda_min``) are in the
controller's feature units (``meta["feature_scale"]`` pixels each), as in the paper's proofs.

Two sets of passivity signals are logged. The controller's own (``nu``, ``storage``,
``passivity_input``) come from its last camera measurement: stale between frames, noisy, and
with the controller's (possibly wrong) kinematic model. The true-state set (``nu_true``,
``storage_true``, ``passivity_input_true``) is derived after the run from the true
configuration, the true target and the true robot's ``J`` and ``J_o``: one consistent set, in
which the identity behind eq. (9) holds up to sampling.

What the controller read of the robot (:mod:`pbvs_pin.sim.sensing`) is logged beside the
truth: ``v_measured`` beside ``v``, ``platform_pose_measured`` (odometry, or the true pose
with perfect localisation) beside ``platform_pose`` (``[x, y, heading]`` [m, m, rad]). The
platform's slip is logged as ``body_velocity``, its true ``[forward, lateral, yaw rate]``
[m/s, m/s, rad/s] over each log interval (from the true poses, in the platform frame at the
interval's mid heading), beside ``wheel_velocity``, the ``[u, omega]`` its wheels' rotation
implies over the same interval (from the true ``wheel_angles``); a platform that does not slip
has zero lateral speed and equal yaw rates. ``meta["odometry_drift"]`` and ``meta["slip"]``
summarise them (:func:`sensing_meta`).
"""

from __future__ import annotations

import json
import os
import tempfile
import time
import zipfile
import zlib
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO

import numpy as np

from pbvs_pin.exceptions import LogError, OutputError
from pbvs_pin.model.base import DifferentialDrive
from pbvs_pin.model.camera import MIN_DEPTH
from pbvs_pin.model.joint_angles import arm_angles
from pbvs_pin.model.manipulability import arm_jacobian, manipulability
from pbvs_pin.outputs import Output, check_output
from pbvs_pin.perception.features import ImageMeasurement
from pbvs_pin.sim.obstacles import clearance
from pbvs_pin.sim.passivity_signals import feedback_terms, passivity_terms, true_passivity_terms
from pbvs_pin.sim.scenario import obstacle_table
from pbvs_pin.sim.sensing import planar_of, planar_pose
from pbvs_pin.validation import as_path

if TYPE_CHECKING:
    from pbvs_pin.control.kinematic import ControlOutput
    from pbvs_pin.control.tracking import TargetTracker
    from pbvs_pin.sim.sensing import Sensing
    from pbvs_pin.sim.setup import Setup

AT_LIMIT = 1.0 - 1e-6
"""A velocity counts as at its limit from this fraction of the limit on."""


def command_limited(scaled: bool, v_ref: np.ndarray, limits: np.ndarray) -> bool:
    """Whether the velocity limits cut the command (the ``saturated`` channel).

    They cut it when the law scaled ``u`` down, or when a component of ``v_ref`` sits at its
    limit (the compensator clips ``v_ref`` to the limits, eq. 20): a law whose ``u`` stays
    inside the limits (the classic IBVS baseline) can still drive ``v_ref`` onto them
    through the compensation.

    Args:
        scaled: The law scaled ``u`` down (``ControlOutput.saturated``).
        v_ref: Velocity reference sent to the robot [m/s, rad/s]. Shape (n,).
        limits: Velocity limits of the controller's model [m/s, rad/s]. Shape (n,).
    """
    return bool(scaled) or bool(np.any(np.abs(v_ref) >= AT_LIMIT * limits))


CHANNELS = (
    "t", "xi", "xi_true", "xi_d", "u", "v_ref", "v", "q", "arm", "target", "target_estimate",
    "target_velocity", "target_velocity_estimate", "obstacle_distance", "obstacle_angle",
    "clearance", "manipulability", "storage", "storage_v2", "nu", "passivity_input",
    "lambda_min", "gamma", "saturated", "damped", "target_lost", "valid", "loop_gain",
    "gain_limited", "upright_angle", "nu_true", "storage_true", "passivity_input_true",
    "feedback", "feedback_true", "xi_measured", "predicted", "v_measured", "platform_pose",
    "platform_pose_measured", "wheel_angles", "body_velocity", "wheel_velocity",
)  # fmt: skip
"""Names of the arrays in a log."""

RECORDED = (
    "t", "xi", "u", "v_ref", "v", "q", "target_estimate", "target_velocity_estimate",
    "obstacle_distance", "obstacle_angle", "storage", "storage_v2", "nu", "saturated", "damped",
    "target_lost", "valid", "loop_gain", "gain_limited", "upright_angle", "xi_measured",
    "predicted", "v_measured", "platform_pose_measured", "wheel_angles",
)  # fmt: skip
"""Channels copied in the loop; :meth:`RunRecorder.finish` derives the others."""


@dataclass
class RunLog:
    """A run's channels and facts.

    Attributes:
        channels: Name -> array, first axis time.
        meta: Scenario name, robot, gains, posture target, timings (JSON-serialisable).
    """

    channels: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        """One channel."""
        return self.channels[name]

    @property
    def interrupted(self) -> bool:
        """Whether the run was stopped (Ctrl-C) before its end: a partial log."""
        return bool(self.meta.get("interrupted", False))

    def save(self, folder: str | Path) -> Path:
        """Write ``log.npz`` (channels and meta) into ``folder``, atomically; return its path.

        The file is written under a temporary name in the same folder, then renamed: a
        ``log.npz`` is always whole, and a failed write (a full disk) leaves none behind.

        Raises:
            OutputError: If the folder or the file cannot be written.
        """
        folder = as_path("folder", folder)
        path = folder / "log.npz"
        with atomic_file(path) as handle:
            np.savez_compressed(handle, meta=json.dumps(self.meta), **self.channels)
        return path

    @classmethod
    def load(cls, path: str | Path) -> RunLog:
        """Read a log written by :meth:`save` (a file or the folder holding ``log.npz``).

        Raises:
            LogError: If the file is missing, truncated or not a ``.npz`` archive, holds
                objects (pickles are never read), has no JSON ``meta`` or no time channel
                ``t``, or channels of another length than ``t``.
        """
        path = as_path("path", path)
        if path.is_dir():
            path = path / "log.npz"
        try:
            data = np.load(path, allow_pickle=False)
            if not isinstance(data, np.lib.npyio.NpzFile):  # a .npy file: one array
                raise LogError(str(path), "one NumPy array (.npy), not a run log (expected the "
                               ".npz archive that pbvs-pin run writes)")  # fmt: skip
            with data:
                meta = json.loads(str(data["meta"]))
                channels = {name: data[name] for name in data.files if name != "meta"}
        except FileNotFoundError as err:
            raise LogError(str(path), "no such file (expected a run's log.npz)") from err
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error,
                TypeError, UnicodeDecodeError, NotImplementedError) as err:  # fmt: skip
            raise LogError(str(path), f"not a readable run log ({type(err).__name__})") from err
        if not isinstance(meta, dict) or "t" not in channels or channels["t"].ndim != 1:
            raise LogError(str(path), "not a run log: no meta table or no time channel t")
        length = len(channels["t"])
        short = sorted(name for name, a in channels.items() if a.ndim == 0 or len(a) != length)
        if short:
            raise LogError(
                str(path), f"channels {short} do not have the {length} samples of t (damaged)"
            )
        return cls(channels, meta)


@contextmanager
def atomic_file(path: Path) -> Iterator[BinaryIO]:
    """A binary file handle whose content replaces ``path`` only once all of it is written.

    Writes to a temporary file in ``path``'s folder (created if missing), then
    :func:`os.replace` s it onto ``path``. On any failure, Ctrl-C included, the temporary
    file is removed and ``path`` is left as it was.

    Raises:
        OutputError: If the folder cannot be created or the file cannot be written (an
            ``OSError`` such as a full disk or a read-only folder).
    """
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        descriptor, temporary = tempfile.mkstemp(
            prefix=f".{path.name}.", suffix=".tmp", dir=path.parent
        )
    except OSError as err:
        raise OutputError(str(path), f"cannot write ({err.strerror or err})") from err
    mask = os.umask(0)  # mkstemp makes the file private: give it the usual permissions
    os.umask(mask)
    try:
        os.fchmod(descriptor, 0o666 & ~mask)
        with os.fdopen(descriptor, "wb") as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, path)
    except BaseException as err:
        with suppress(OSError):
            os.unlink(temporary)
        if isinstance(err, OSError):
            raise OutputError(
                str(path), f"cannot write ({err.strerror or err}); nothing was written"
            ) from err
        raise


def check_writable(folder: Path, *files: Path) -> None:
    """Make sure a run's outputs can be written, before the run: fail fast, not after it.

    The paths are first checked by the command line's guard
    (:func:`pbvs_pin.outputs.check_output`); then ``folder`` and each file's folder are
    created (as the run would) and a temporary file is written and removed in each.

    Args:
        folder: Output folder of the run.
        files: Other files the run will write (e.g. an HTML replay).

    Raises:
        OutputError: If a folder cannot be created or written, or a file is a folder.
    """
    check_output(folder, Output.FOLDER)
    for path in files:
        check_output(path, Output.FILE)
    for place in dict.fromkeys([folder, *(path.parent for path in files)]):
        try:
            place.mkdir(parents=True, exist_ok=True)
            descriptor, probe = tempfile.mkstemp(prefix=".pbvs-pin-check.", dir=place)
            os.close(descriptor)
            os.unlink(probe)
        except OSError as err:
            raise OutputError(
                str(place), f"cannot be written ({err.strerror or err}); nothing was run"
            ) from err


def write_text_atomically(path: Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` through :func:`atomic_file`.

    Raises:
        OutputError: If the file cannot be written.
    """
    with atomic_file(path) as handle:
        handle.write(text.encode())


def json_safe(value: Any) -> Any:
    """``value`` with every NaN or infinite float replaced by None (JSON ``null``).

    JSON has no NaN; Python writes a bare ``NaN`` that other readers refuse.
    """
    if isinstance(value, dict):
        return {key: json_safe(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(item) for item in value]
    if isinstance(value, float | np.floating) and not np.isfinite(value):
        return None
    return value


def write_json_atomically(path: Path, data: Any) -> None:
    """Write ``data`` as strict JSON (non-finite numbers as ``null``), atomically.

    Raises:
        OutputError: If the file cannot be written.
    """
    write_text_atomically(path, json.dumps(json_safe(data), indent=2, allow_nan=False))


class RunRecorder:
    """Collects a run's samples; derives the costly channels once, at the end.

    In the loop, :meth:`record` copies what only exists at that instant (commands, velocities,
    configuration, estimates, the controller's Jacobians). :meth:`finish` then derives the rest
    from the recorded configurations and times in one pass: true features, arm angles, the
    target's true motion, clearance, manipulability, and the passivity terms (batched linear
    algebra instead of a dozen small NumPy calls per sample).
    """

    def __init__(self, setup: Setup, footprint: np.ndarray, sensing: Sensing) -> None:
        """Prepare empty channels.

        Args:
            setup: The run's blocks.
            footprint: Platform boundary points in its own frame [m], for the clearance.
                Shape (k, 2).
            sensing: What the controller reads of the robot.
        """
        self.setup = setup
        self.footprint = footprint
        self.sensing = sensing
        self.rows: dict[str, list] = {name: [] for name in RECORDED}
        self._jacobians: list[np.ndarray] = []
        self._object_jacobians: list[np.ndarray] = []

    def record(
        self,
        *,
        t: float,
        output: ControlOutput,
        jacobians: tuple[np.ndarray, np.ndarray] | None,
        tracker: TargetTracker,
        target_velocity: np.ndarray,
        v_ref: np.ndarray,
        v2: float,
        laser: tuple[float, float],
    ) -> None:
        """Append one sample of what exists only at this instant."""
        setup = self.setup
        plant = setup.plant
        measurement = tracker.measurement
        seen = measurement is not None and not tracker.lost
        rows = self.rows
        for name, value in (
            ("t", t), ("u", output.u), ("v_ref", v_ref), ("v", plant.v), ("q", plant.q),
            ("target_estimate", tracker.estimator.position),
            ("target_velocity_estimate", target_velocity),
            ("obstacle_distance", laser[0]), ("obstacle_angle", laser[1]),
            ("storage", output.storage), ("storage_v2", v2), ("nu", output.nu),
            ("saturated", command_limited(output.saturated, v_ref, setup.model.velocity_limits)),
            ("damped", output.damped), ("target_lost", tracker.lost), ("valid", output.valid),
            ("loop_gain", output.loop_gain), ("gain_limited", output.gain_limited),
            ("upright_angle", output.upright_angle), ("predicted", tracker.predicting),
            ("v_measured", self.sensing.v),
            ("platform_pose_measured", planar_pose(setup.robot, self.sensing.q)),
            ("wheel_angles", plant.wheel_angles),
        ):  # fmt: skip
            rows[name].append(np.array(value, copy=True))
        unseen = np.full(setup.features.size, np.nan)
        used = tracker.used
        rows["xi"].append(setup.features.features(used) if used is not None else unseen)
        rows["xi_measured"].append(setup.features.features(measurement) if seen else unseen)
        r, n = setup.features.size, setup.model.n
        self._jacobians.append(np.array(jacobians[0]) if jacobians else np.full((r, n), np.nan))
        self._object_jacobians.append(
            np.array(jacobians[1]) if jacobians else np.full((r, 3), np.nan)
        )

    def finish(self, started: float, interrupted: bool = False) -> RunLog:
        """Derive the remaining channels and stack everything into a :class:`RunLog`.

        Args:
            started: ``time.perf_counter()`` when the run started; ``meta["wall_time"]`` is
                the time from then until the log is complete.
            interrupted: The run was stopped early: keep the samples recorded whole (a
                sample cut by the interruption is dropped) and set ``meta["interrupted"]``.
        """
        setup = self.setup
        samples = min(
            min(len(values) for values in self.rows.values()),
            len(self._jacobians),
            len(self._object_jacobians),
        )
        self._jacobians = self._jacobians[:samples]
        self._object_jacobians = self._object_jacobians[:samples]
        recorded = {name: np.array(values[:samples]) for name, values in self.rows.items()}
        derived = _derived_in_one_pass(setup, self.footprint, recorded["t"], recorded["q"])
        jacobians = np.array(self._jacobians)
        derived.update(
            passivity_terms(
                setup,
                jacobians,
                np.array(self._object_jacobians),
                recorded["v"],
                derived["target_velocity"],
                recorded["target_velocity_estimate"],
            )
        )
        derived.update(true_passivity_terms(setup, derived, recorded["v"]))
        derived["feedback"] = feedback_terms(
            setup, recorded["xi"] - setup.xi_d, jacobians, recorded["nu"], derived["arm"],
        )  # fmt: skip
        derived["feedback_true"] = feedback_terms(
            setup, derived["xi_true"] - setup.xi_d, derived.pop("jacobian_true"),
            derived["nu_true"], derived["arm"],
        )  # fmt: skip
        derived["xi_d"] = np.broadcast_to(setup.xi_d, recorded["xi"].shape).copy()
        derived.update(
            _slip(setup, recorded["t"], derived["platform_pose"], recorded["wheel_angles"])
        )
        every = {**recorded, **derived}
        channels = {name: every[name] for name in CHANNELS}
        wall_time = time.perf_counter() - started
        scenario = setup.scenario
        gains = setup.law.gains
        meta = {
            "scenario": scenario.name,
            "description": scenario.description,
            "source": scenario.source,
            **setup.robot_meta(),
            "law": scenario.controller.law,
            "feedback": scenario.controller.feedback,
            "user_objectives": [type(o).__name__ for o in setup.control.user_objectives],
            "features": type(setup.features).__name__,
            "feature_rows": np.asarray(setup.features.rows).tolist(),
            "engine": scenario.plant.engine,
            "feature_scale": gains.feature_scale,
            "k": list(np.broadcast_to(np.asarray(gains.k, dtype=float), (setup.features.size,))),
            "posture_target": setup.posture_target.tolist(),
            "velocity_names": list(setup.robot.velocity_names),
            "velocity_limits": setup.robot.velocity_limits.tolist(),
            "arm_position_limits": [
                [None if not np.isfinite(x) else float(x) for x in side]
                for side in setup.robot.arm_position_limits()
            ],
            "arm_continuous": setup.robot.arm_continuous.tolist(),
            "compensation": scenario.compensation.mode,
            "duration": float(scenario.duration),
            "interrupted": interrupted,
            "wall_time": wall_time,
            "obstacles": [obstacle_table(o) for o in scenario.obstacles],
            "target_diameter": setup.target.diameter,
            "target_separation": setup.target.separation,
            "camera": {
                "focal_px": setup.robot.camera.focal_px,
                "width": setup.robot.camera.width,
                "height": setup.robot.camera.height,
            },
            **sensing_meta(every),
            "detection": (
                setup.sensor.renderer.detection_meta() if setup.sensor.renderer else None
            ),
            "controller_counts": setup.control.counts.as_dict(),
        }
        return RunLog(channels, meta)


def _derived_in_one_pass(
    setup: Setup, footprint: np.ndarray, times: np.ndarray, configurations: np.ndarray
) -> dict[str, np.ndarray]:
    """Channels that follow from each sample's time and true configuration."""
    robot, model, target = setup.robot, setup.model, setup.target
    samples = len(times)
    r = setup.features.size
    out = {
        "xi_true": np.full((samples, r), np.nan),
        "arm": np.empty((samples, model.n_arm)),
        "target": np.empty((samples, 3)),
        "target_velocity": np.empty((samples, 3)),
        "clearance": np.empty(samples),
        "platform_pose": np.empty((samples, 3)),
        "jacobian_true": np.full((samples, r, model.n), np.nan),
        "object_jacobian_true": np.full((samples, r, 3), np.nan),
    }
    arm_jacobians = []
    data, camera_frame = robot.data, robot.camera_frame_id
    for i, (t, q) in enumerate(zip(times, configurations, strict=True)):
        centres = target.centres(t)
        # the plant's own configurations: one pass of joint placements and Jacobians serves the
        # camera's pose and Jacobian and the platform's pose (no check, no frame left behind)
        camera_jacobian = robot.camera_jacobian_unchecked(q)
        pose = data.oMf[camera_frame]
        image, depths = robot.camera.project_world(pose, centres)
        if np.all(depths > MIN_DEPTH):  # FeatureSet.jacobians of the same image, posed once
            out["xi_true"][i] = image.reshape(-1)[setup.features.rows]
            _, out["jacobian_true"][i], out["object_jacobian_true"][i] = (
                setup.features.jacobians_from_measurement(
                    robot.camera, ImageMeasurement(image, depths), camera_jacobian,
                    pose.rotation.T,
                )
            )  # fmt: skip
        out["platform_pose"][i] = planar_of(data.oMi[1])
        out["clearance"][i] = clearance(setup.obstacles, footprint, *out["platform_pose"][i])
        out["arm"][i] = arm_angles(q, model.arm_q_indices, model.arm_continuous)
        out["target"][i] = centres.mean(axis=0)
        out["target_velocity"][i] = target.motion.velocity(t)
        arm_jacobians.append(arm_jacobian(model, q))
    out["manipulability"] = manipulability(np.array(arm_jacobians))
    return out


def _slip(
    setup: Setup, times: np.ndarray, poses: np.ndarray, wheel_angles: np.ndarray
) -> dict[str, np.ndarray]:
    r"""``body_velocity`` and ``wheel_velocity`` over each log interval (module docstring).

    Over ``[t_{i-1}, t_i]``, with ``d`` the true displacement and ``theta_m`` the mid heading,

    .. math:: [v_f, v_l] = R(\theta_m)^T d / \Delta t,\quad
              \dot\theta = \Delta\theta / \Delta t,\quad
              [u, \omega] = P\, \Delta a / \Delta t

    (``P``: :meth:`pbvs_pin.model.base.DifferentialDrive.platform_velocity`, ``a`` the wheel
    angles). The chord of an arc of constant curvature points along its mid heading, so that a
    platform that does not slip has ``v_l`` near zero (zero on such an arc). The first sample
    (no interval) is zero; a platform without a differential drive has no ``wheel_velocity``
    (NaN).
    """
    samples = len(times)
    body = np.zeros((samples, 3))
    wheel = np.zeros((samples, 2))
    if samples < 2:
        return {"body_velocity": body, "wheel_velocity": wheel}
    dt = np.diff(times)[:, None]
    theta = np.unwrap(poses[:, 2])
    mid = 0.5 * (theta[1:] + theta[:-1])
    step = np.diff(poses[:, :2], axis=0)
    c, s = np.cos(mid), np.sin(mid)
    body[1:, 0] = (c * step[:, 0] + s * step[:, 1]) / dt[:, 0]
    body[1:, 1] = (-s * step[:, 0] + c * step[:, 1]) / dt[:, 0]
    body[1:, 2] = np.diff(theta) / dt[:, 0]
    drive = setup.model.base
    if isinstance(drive, DifferentialDrive):
        wheel[1:] = np.array([drive.platform_velocity(w) for w in np.diff(wheel_angles, axis=0)])
        wheel[1:] /= dt
    else:
        wheel[:] = np.nan
    return {"body_velocity": body, "wheel_velocity": wheel}


def sensing_meta(channels: dict[str, np.ndarray]) -> dict[str, Any]:
    """The run's odometry drift at the end and the platform's measured slip.

    Returns:
        ``odometry_drift``: ``position`` [m] and ``heading`` [rad] (wrapped to
        ``(-pi, pi]``, absolute) between the measured and the true platform pose at the last
        sample. ``slip``: ``lateral_speed_rms`` [m/s], the RMS of the true lateral speed, and
        ``yaw_rate_ratio``, the least-squares slope of the true yaw rate on the yaw rate the
        wheels imply (1: no slip; None when the wheels never turn the platform or the
        platform has no wheels).
    """
    true, measured = channels["platform_pose"][-1], channels["platform_pose_measured"][-1]
    heading = float(np.angle(np.exp(1j * (measured[2] - true[2]))))
    body, wheel = channels["body_velocity"], channels["wheel_velocity"]
    implied = wheel[:, 1]
    energy = float(np.sum(implied * implied)) if np.all(np.isfinite(implied)) else 0.0
    ratio = float(np.sum(body[:, 2] * implied) / energy) if energy > 1e-12 else None
    return {
        "odometry_drift": {
            "position": float(np.hypot(*(measured[:2] - true[:2]))),
            "heading": abs(heading),
        },
        "slip": {
            "lateral_speed_rms": float(np.sqrt(np.mean(body[:, 1] ** 2))),
            "yaw_rate_ratio": ratio,
        },
    }
