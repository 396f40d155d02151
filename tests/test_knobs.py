"""Every scenario key moves the run: changing it, where it can act, changes the log.

A key whose change leaves the log bit-identical is a knob connected to nothing. Each case
gives a short run in which the key can act (its context: e.g. obstacle keys with avoidance on
and the obstacle within reach) and a new value; the log's arrays or its metadata must differ.
The ``[robot]`` forms are covered by ``tests/test_robot_spec.py``.
"""

import json

import numpy as np
import pytest

from pbvs_pin.sim.detection import ColourDetector, register_detector
from pbvs_pin.sim.keys import keys_of
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import Scenario, load_scenario

BASE = {"duration": 2.0}
OBSTACLE = {"secondary.obstacle_avoidance": True, "secondary.d0": 3.0}
NEAR_LIMIT = {"robot.initial_arm": [0.0, 0.0, 0.55]}  # 0.05 rad below the elbow's upper limit
ROLLING = {"robot.name": "pioneer_panda"}
OCCLUDED = {"camera.occlusion_starts": [0.5], "camera.occlusion_duration": 0.5}
RENDERED = {"camera.model": "rendered"}
DARK = {**RENDERED, "camera.light_change_scale": 0.05}  # spheres darker than the detector's floor
register_detector("round_only", lambda camera: ColourDetector(camera, min_fill=0.99))

CASES = {  # key: (context, new value)
    "name": ({}, "renamed"),
    "description": ({}, "another description"),
    "duration": ({}, 1.5),
    "robot.initial_arm": ({}, [0.1, 0.1, -0.1]),
    "robot.home": ({}, [0.1, 0.0, 0.0]),
    "model_error.kinematic_scale": ({}, 1.2),
    "model_error.mass_scale": ({}, 2.0),
    "model_error.payload": ({}, 0.5),
    "camera.focal_px": ({}, 650.0),
    "camera.width": ({}, 640),
    "camera.height": ({}, 600),
    "camera.rate": ({}, 25.0),
    "camera.latency": ({}, 0.05),
    "camera.noise_px": ({}, 2.0),
    "camera.drop_probability": ({}, 0.3),
    "camera.occlusion_starts": ({"camera.occlusion_duration": 0.5}, [0.5]),
    "camera.occlusion_rate": ({"camera.occlusion_duration": 0.5}, 2.0),
    "camera.occlusion_duration": ({"camera.occlusion_starts": [0.5]}, 0.5),
    "camera.latency_jitter": ({}, 0.05),
    "camera.exposure_delay": ({}, 0.05),
    "camera.model": ({}, "rendered"),
    "camera.detector": (RENDERED, "round_only"),
    "camera.image_noise": (RENDERED, 20.0),
    "camera.exposure_time": (RENDERED, 0.03),
    "camera.light_change_time": (DARK, 1.0),
    "camera.light_change_scale": (RENDERED, 0.05),
    "target.diameter": ({}, 0.06),
    "target.separation": ({}, 0.12),
    "target.xi0": ({}, [-100.0, 10.0, -90.0]),
    "target.xi_d": ({}, [10.0, 50.0, -50.0]),
    "motion.kind": ({}, "still"),
    "motion.velocity": ({}, [0.2, 0.0, 0.0]),
    "motion.amplitude": ({}, [0.0, 0.3, 0.0]),
    "motion.frequency": ({}, 0.2),
    "motion.stop_time": ({"motion.kind": "line_then_stop"}, 1.0),
    "estimator.kind": ({}, "exact"),
    "estimator.alpha": ({}, 0.3),
    "estimator.beta": ({}, 0.2),
    "estimator.predict": ({"camera.latency": 0.1}, False),  # the experiments predict
    "estimator.hold": (OCCLUDED, 1.0),
    "estimator.smoothing": ({}, 0.5),
    "controller.law": ({}, "ibvs"),
    "controller.k": ({}, [0.3]),
    "controller.k1": ({}, [0.5, 0.8, 0.2, 0.2, 0.2]),
    "controller.k2": ({}, [0.5]),
    "controller.feature_scale": ({}, 120.0),
    "controller.weights": ({}, [2.0]),
    "controller.feedback": ({}, "pseudoinverse"),
    "controller.ibvs_gain": ({"controller.law": "ibvs"}, 2.0),
    "controller.rate": ({}, 200.0),
    "controller.upright": (ROLLING, False),
    "controller.upright_rate": ({**ROLLING, "robot.initial_arm": None}, 1.0),
    "controller.loop_gain_margin": ({}, 0.5),
    "compensation.mode": ({}, "all"),
    "compensation.k_d": ({}, [2.0]),
    "compensation.derivative_time_constant": ({}, 0.1),
    "secondary.obstacle_avoidance": (OBSTACLE, False),
    "secondary.posture": ({}, False),
    "secondary.posture_target": ({}, "max_manipulability"),
    "secondary.joint_limits": (NEAR_LIMIT, False),
    "secondary.k_uobs": (OBSTACLE, 1.0),
    "secondary.k_wobs": (OBSTACLE, 1.5),
    "secondary.d0": (OBSTACLE, 2.5),
    "secondary.impedance_mass": (OBSTACLE, 1.0),
    "secondary.impedance_damping": (OBSTACLE, 2.0),
    "secondary.k_lambda": ({}, 2.0),
    "laser.rate": (OBSTACLE, 10.0),
    "laser.beams": (OBSTACLE, 91),
    "laser.field_of_view": (OBSTACLE, 1.0),
    "laser.max_range": (OBSTACLE, 1.0),
    "laser.range_noise": (OBSTACLE, 0.05),
    "laser.range_resolution": (OBSTACLE, 0.01),
    "sensing.exact": ({}, True),
    "sensing.localisation": ({}, "perfect"),
    "sensing.heading": ({}, "wheels"),
    "sensing.gyro_noise": ({}, 0.05),
    "sensing.gyro_bias": ({}, 0.01),
    "sensing.wheel_encoder_counts": ({}, 1000),
    "sensing.arm_encoder_bits": ({}, 12),
    "sensing.arm_linear_resolution": ({"robot.name": "tiago"}, 1e-3),
    "sensing.joint_velocity_noise": ({}, 0.05),
    "sensing.wheel_velocity_noise": ({}, 0.2),
    "sensing.velocity_filter": ({}, 0.05),
    "platform.length": ({}, 0.6),
    "platform.width": ({}, 0.55),
    "simulation.plant_dt": ({}, 0.0005),
    "simulation.log_rate": ({}, 25.0),
    "simulation.seed": ({}, 7),
    "plant.engine": ({"duration": 0.5}, "mujoco"),
}
"""Each key with the context in which it acts and a value that differs from the context's."""

ROBOT_FORM_KEYS = {
    "robot.name", "robot.urdf", "robot.camera_frame", "robot.base", "robot.arm", "robot.mount",
    "robot.camera_link", "robot.camera_pose", "robot.wheel_radius", "robot.track",
    "robot.wheel_speed_limit", "robot.arm_root", "robot.arm_tip", "robot.repair_inertia",
}  # fmt: skip
"""Keys that say what the robot is; each form's effect is tested where the form is built
(test_assembly, test_robot_spec; the chain keys and the inertia repair in test_zoo and
test_inertia_repair)."""


def _all_keys() -> set[str]:
    from pbvs_pin.sim.scenario import SECTIONS

    keys = {spec.name for spec in keys_of(Scenario)}
    for section in SECTIONS:
        keys |= {f"{section.TABLE}.{spec.name}" for spec in keys_of(section)}
    return keys


def test_every_key_has_a_case():
    assert _all_keys() - ROBOT_FORM_KEYS == set(CASES)


def _fingerprint(log) -> tuple:
    meta = dict(log.meta)
    meta.pop("wall_time", None)
    return json.dumps(meta, sort_keys=True, default=str), dict(log.channels)


def _run(changes: dict) -> tuple:
    scenario = load_scenario("experiment2").with_values(**{**BASE, **changes})
    return _fingerprint(simulate(scenario))


_BASES: dict[str, tuple] = {}


DISCONNECTED: dict[str, str] = {}
"""Keys known to move nothing yet, each with the open issue that connects it. Strict: the
test fails as soon as such a key starts to act, so that it leaves this list."""


@pytest.mark.parametrize(
    "key",
    [
        pytest.param(key, marks=pytest.mark.xfail(reason=DISCONNECTED[key], strict=True))
        if key in DISCONNECTED
        else key
        for key in sorted(CASES)
    ],
)
def test_the_key_moves_the_log(key):
    context, value = CASES[key]
    label = json.dumps(context, sort_keys=True)
    if label not in _BASES:
        _BASES[label] = _run(context)
    meta, arrays = _BASES[label]
    changed_meta, changed_arrays = _run({**context, key: value})
    same_arrays = arrays.keys() == changed_arrays.keys() and all(
        arrays[k].shape == changed_arrays[k].shape
        and np.array_equal(arrays[k], changed_arrays[k], equal_nan=True)
        for k in arrays
    )
    assert not (same_arrays and meta == changed_meta), f"{key} = {value!r} changed nothing"
