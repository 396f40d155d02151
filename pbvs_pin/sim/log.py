"""Run logs: what a closed-loop run recorded, saved as ``log.npz`` plus ``summary.json``.

Every channel is an array whose first axis is time (the log rate). Features and errors are in
pixels; the passivity quantities (``storage``, ``nu``, ``gamma``, ``lambda_min``) are in the
controller's feature units (``meta["feature_scale"]`` pixels each), as in the paper's proofs.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from pbvs_pin.control.kinematic import ControlOutput
    from pbvs_pin.sim.loop import Perception, Setup

CHANNELS = (
    "t", "xi", "xi_true", "xi_d", "u", "v_ref", "v", "q", "arm", "target", "target_estimate",
    "target_velocity", "target_velocity_estimate", "obstacle_distance", "obstacle_angle",
    "clearance", "manipulability", "storage", "storage_v2", "nu", "passivity_input",
    "lambda_min", "gamma", "saturated", "damped", "target_lost", "valid",
)  # fmt: skip
"""Names of the arrays in a log."""


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

    def save(self, folder: str | Path) -> Path:
        """Write ``log.npz`` (channels and meta) into ``folder``; return its path."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / "log.npz"
        np.savez_compressed(path, meta=json.dumps(self.meta), **self.channels)
        return path

    @classmethod
    def load(cls, path: str | Path) -> RunLog:
        """Read a log written by :meth:`save` (a file or the folder holding ``log.npz``)."""
        path = Path(path)
        if path.is_dir():
            path = path / "log.npz"
        with np.load(path) as data:
            meta = json.loads(str(data["meta"]))
            channels = {name: data[name] for name in data.files if name != "meta"}
        return cls(channels, meta)


class RunRecorder:
    """Collects channels during a run into preallocated lists."""

    def __init__(self, setup: Setup, expected: int) -> None:
        self.setup = setup
        self.rows: dict[str, list] = {name: [] for name in CHANNELS}
        self.expected = expected

    def record(
        self,
        *,
        t: float,
        output: ControlOutput,
        jacobians: tuple[np.ndarray, np.ndarray] | None,
        perception: Perception,
        v_ref: np.ndarray,
        v2: float,
        laser: tuple[float, float],
        clearance: float,
        manipulability: float,
    ) -> None:
        """Append one sample."""
        setup = self.setup
        plant = setup.plant
        target_velocity = setup.target.motion.velocity(t)
        measurement = perception.measurement
        xi = (
            setup.features.features(measurement)
            if measurement is not None and not perception.lost
            else np.full(setup.features.size, np.nan)
        )
        xi_true = _true_features(setup, t)
        passivity_input, lambda_min, gamma = _passivity_terms(
            setup, jacobians, plant.v, target_velocity, perception.velocity(t)
        )
        sample = {
            "t": t, "xi": xi, "xi_true": xi_true, "xi_d": setup.xi_d, "u": output.u,
            "v_ref": v_ref, "v": plant.v, "q": plant.q, "arm": setup.model.arm_positions(plant.q),
            "target": setup.target.midpoint(t), "target_estimate": perception.filter.position,
            "target_velocity": target_velocity,
            "target_velocity_estimate": perception.velocity(t),
            "obstacle_distance": laser[0], "obstacle_angle": laser[1], "clearance": clearance,
            "manipulability": manipulability, "storage": output.storage, "storage_v2": v2,
            "nu": output.nu, "passivity_input": passivity_input, "lambda_min": lambda_min,
            "gamma": gamma, "saturated": output.saturated, "damped": output.damped,
            "target_lost": perception.lost, "valid": output.valid,
        }  # fmt: skip
        for name, value in sample.items():
            self.rows[name].append(np.array(value, copy=True))

    def finish(self, wall_time: float) -> RunLog:
        """Stack the samples into a :class:`RunLog`."""
        channels = {name: np.array(values) for name, values in self.rows.items()}
        setup = self.setup
        scenario = setup.scenario
        gains = setup.controller.gains
        meta = {
            "scenario": scenario.name,
            "source": scenario.source,
            "robot": scenario["robot"]["name"],
            "law": scenario["controller"]["law"],
            "feature_scale": gains.feature_scale,
            "k": list(np.broadcast_to(np.asarray(gains.k, dtype=float), (3,))),
            "posture_target": setup.posture_target.tolist(),
            "velocity_names": list(setup.robot.velocity_names),
            "velocity_limits": setup.robot.velocity_limits.tolist(),
            "duration": float(scenario[""]["duration"]),
            "wall_time": wall_time,
            "obstacles": [dict(o) for o in scenario.obstacles],
            "target_diameter": setup.target.diameter,
            "target_separation": setup.target.separation,
            "camera": {
                "focal_px": setup.robot.camera.focal_px,
                "width": setup.robot.camera.width,
                "height": setup.robot.camera.height,
            },
        }
        return RunLog(channels, meta)


def _true_features(setup: Setup, t: float) -> np.ndarray:
    """Features of the true target seen from the true robot (NaN when behind the camera)."""
    camera = setup.robot.camera
    image, depths = camera.project_world(
        setup.robot.camera_pose(setup.plant.q), setup.target.centres(t)
    )
    if np.any(depths <= 1e-3):
        return np.full(setup.features.size, np.nan)
    return image.reshape(-1)[setup.features.rows]


def _passivity_terms(
    setup: Setup,
    jacobians: tuple[np.ndarray, np.ndarray] | None,
    v: np.ndarray,
    target_velocity: np.ndarray,
    estimated_velocity: np.ndarray,
) -> tuple[np.ndarray, float, np.ndarray]:
    """``v + J# J_o pdot`` (input of eq. 9), ``lambda_min(J J^T)`` and ``gamma`` (eq. 31).

    All in controller units; NaN when there is no measurement.
    """
    n, r = setup.model.n, setup.features.size
    if jacobians is None:
        return np.full(n, np.nan), float("nan"), np.full(r, np.nan)
    scale = setup.controller.gains.feature_scale
    jacobian, object_jacobian = jacobians[0] / scale, jacobians[1] / scale
    pinv, _, _ = setup.controller.pseudo_inverse(jacobian)
    passivity_input = v + pinv @ object_jacobian @ target_velocity
    lambda_min = float(np.linalg.eigvalsh(jacobian @ jacobian.T)[0])
    gamma = object_jacobian @ (target_velocity - estimated_velocity)
    return passivity_input, lambda_min, gamma
