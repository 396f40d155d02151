"""Every scenario key moves the run: changing it, where it can act, changes the log.

A key whose change leaves the log bit-identical is a knob connected to nothing. Each case
gives a short run in which the key can act (its context: e.g. obstacle keys with avoidance on
and the obstacle within reach) and a new value; the log's arrays or its metadata must differ.
The ``[robot]`` forms are covered by ``tests/test_robot_spec.py``.

A log that changed does not show that it changed the intended way (a sign error moves it
too), so the keys of :data:`EFFECTS` also check the direction of their effect on the same two
runs, against references written here: the target's closed-form paths, the loop gain
``k T lambda_max(J J^T)`` scaling with ``k`` and ``1 / feature_scale^2``, the pixel noise's
standard deviation, the filters' trade of speed against noise.
"""

import json

import numpy as np
import pytest
from docs_figures import PAPERS_LAW  # the paper's law: its loop gain k T lambda_max

from pbvs_pin.perception.detection import ColourDetector, register_detector
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import Scenario, load_scenario
from pbvs_pin.toml_keys import keys_of

BASE = {"duration": 2.0}
OBSTACLE = {"secondary.obstacle_avoidance": True, "secondary.d0": 3.0}
NEAR_LIMIT = {"robot.initial_arm": [0.0, 0.0, 0.55]}  # 0.05 rad below the elbow's upper limit
ROLLING = {"robot.name": "pioneer_panda"}
HEAVY_ARM = {"robot.name": "pioneer_ur5"}  # its home's centre of mass at the support's margin
STRETCH = {  # an arm that cannot move the camera along its optical axis: the heading term acts
    "robot.name": "",
    "robot.base": "package://stretch_urdf/RE1V0/stretch_description_RE1V0_tool_none.urdf",
    "robot.camera_link": "link_wrist_yaw",
    "robot.camera_pose": [0.0, 0.0, 0.0, 1.5707963, 0.0, 1.5707963],
    "robot.wheel_radius": 0.0508,
    "robot.track": 0.3407,
    "robot.wheel_speed_limit": 5.9,
}
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
    "estimator.process_noise": ({}, 0.0),  # the default is 0.03: 0 keeps the fixed gains
    "controller.law": ({}, "ibvs"),
    "controller.k": (PAPERS_LAW, [0.3]),
    "controller.k1": ({}, [0.5, 0.8, 0.2, 0.2, 0.2]),
    "controller.k2": ({}, [0.5]),
    "controller.feature_scale": (PAPERS_LAW, 120.0),
    "controller.weights": ({}, [2.0]),
    "controller.feedback": ({}, "pseudoinverse"),
    "controller.ibvs_gain": ({"controller.law": "ibvs"}, 2.0),
    "controller.rate": ({}, 200.0),
    "controller.upright": (ROLLING, False),
    "controller.upright_rate": ({**ROLLING, "robot.initial_arm": None}, 1.0),
    "controller.loop_gain_margin": (PAPERS_LAW, 0.5),
    "compensation.mode": ({}, "all"),
    "compensation.k_d": ({}, [2.0]),
    "compensation.derivative_time_constant": ({}, 0.1),
    "secondary.obstacle_avoidance": (OBSTACLE, False),
    "secondary.posture": ({}, False),
    "secondary.posture_target": ({}, "max_manipulability"),
    "secondary.joint_limits": (NEAR_LIMIT, False),
    "secondary.support": (HEAVY_ARM, False),
    "secondary.k_support": (HEAVY_ARM, 2.0),
    "secondary.k_uobs": (OBSTACLE, 1.0),
    "secondary.k_wobs": (OBSTACLE, 1.5),
    "secondary.d0": (OBSTACLE, 2.5),
    "secondary.impedance_mass": (OBSTACLE, 1.0),
    "secondary.impedance_damping": (OBSTACLE, 2.0),
    "secondary.k_lambda": ({}, 2.0),
    "secondary.k_heading": (STRETCH, 0.0),
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
    "robot.geometry_density", "robot.drive", "robot.speed_limit", "robot.yaw_rate_limit",
    "robot.base_joints", "robot.forward_axis",
}  # fmt: skip
"""Keys that say what the robot is; each form's effect is tested where the form is built
(test_assembly, test_robot_spec; the chain keys and the inertia repair in test_zoo and
test_inertia_repair, the inertia from geometry in test_link_inertia, the drive and its limits
in test_robot_spec and test_holonomic, the base joints and the forward axis in
test_platform_frame)."""


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


def _run(changes: dict):
    scenario = load_scenario("experiment2").with_values(**{**BASE, **changes})
    return simulate(scenario)


def _error(log) -> np.ndarray:
    """``|xi_true - xi_d|`` per sample [px]."""
    return np.linalg.norm(log["xi_true"] - log["xi_d"], axis=1)


def _first_gain(log) -> float:
    """The loop gain ``k T lambda_max(J J^T)`` of the first valid step."""
    gains = log["loop_gain"]
    return float(gains[np.flatnonzero(np.isfinite(gains))[0]])


def _noise(log) -> np.ndarray:
    """Standard deviation of the servoed features about the true ones, per feature [px]."""
    return np.nanstd(log["xi"] - log["xi_true"], axis=0)


def _frames(log) -> int:
    """Frames the controller received: changes of the newest measurement's features."""
    return int(np.sum(np.diff(log["xi_measured"][:, 0]) != 0))


def _velocity_error(log) -> np.ndarray:
    """``|phat_dot - p_dot|`` per sample [m/s]."""
    return np.linalg.norm(log["target_velocity_estimate"] - log["target_velocity"], axis=1)


def _offset(log) -> np.ndarray:
    """The target's displacement since the start [m]. Shape (samples, 3)."""
    return log["target"] - log["target"][0]


def _effect_k(base, changed, value):
    # g is linear in k at the same first posture; the doubled gain converges faster
    assert _first_gain(changed) == pytest.approx(_first_gain(base) * value[0] / 0.15, rel=1e-12)
    assert np.all(_error(changed)[5:] < _error(base)[5:])


def _effect_feature_scale(base, changed, value):
    # J in controller units is J_px / scale: g scales with 1 / scale^2
    assert _first_gain(changed) == pytest.approx(
        _first_gain(base) * (150.0 / value) ** 2, rel=1e-12
    )
    assert np.all(_error(changed)[5:] < _error(base)[5:])


def _effect_feedback(base, changed, value):
    # J J# = I: the gain per sample is k T, whatever J
    gains = changed["loop_gain"][np.isfinite(changed["loop_gain"])]
    np.testing.assert_allclose(gains, 0.15 / 30.0, rtol=1e-12)
    assert _first_gain(base) > 10 * gains[0]


def _effect_margin(base, changed, value):
    for log, margin in ((base, 1.0), (changed, value)):  # experiment2 predicts: full margin
        valid = np.isfinite(log["loop_gain"])
        np.testing.assert_array_equal(log["gain_limited"][valid], log["loop_gain"][valid] > margin)
    assert changed["gain_limited"].any()


def _effect_noise(base, changed, value):
    # same seed: the noise is the base's scaled by 2 / 0.5; the prediction error adds a little
    ratio = _noise(changed) / _noise(base)
    assert np.all((ratio > 3.0) & (ratio < 4.5)), ratio
    assert np.all(np.abs(_noise(changed) - value) < 0.5), _noise(changed)


def _effect_smoothing(base, changed, value):
    # a first-order filter with pole 1 - w: white noise times sqrt(w / (2 - w)) = 0.58
    ratio = _noise(changed) / _noise(base)
    assert np.all(ratio < 0.9) and np.mean(ratio) < 0.8, ratio


def _effect_beta(base, changed, value):
    # a larger beta: the velocity estimate converges sooner and is noisier afterwards
    settle = [log["t"][np.argmax(_velocity_error(log) < 0.02)] for log in (base, changed)]
    assert settle[1] < settle[0]
    assert np.std(_velocity_error(changed)[50:]) > np.std(_velocity_error(base)[50:])


def _effect_exact_estimator(base, changed, value):
    np.testing.assert_array_equal(changed["target_velocity_estimate"], changed["target_velocity"])
    assert np.abs(base["target_velocity_estimate"] - base["target_velocity"]).max() > 0.01


def _effect_predict(base, changed, value):
    assert base["predicted"].mean() > 0.9 and not changed["predicted"].any()


def _effect_hold(base, changed, value):
    # occluded over [0.5, 1.0) s: without a hold the command is zero, with one it servoes on
    # the prediction
    hidden = (base["t"] > 0.6) & (base["t"] < 1.0)
    assert base["target_lost"][hidden].all() and changed["target_lost"][hidden].all()
    assert not base["u"][hidden].any()
    assert changed["predicted"][hidden].all()
    assert np.all(np.linalg.norm(changed["u"][hidden], axis=1) > 0)


def _effect_occlusion(base, changed, value):
    t, lost = changed["t"], changed["target_lost"]
    assert not base["target_lost"].any()
    assert lost[(t > 0.55) & (t < 1.0)].all()  # the first frame after 0.5 s, one frame late
    assert not lost[(t < 0.5) | (t > 1.1)].any()


def _effect_drop(base, changed, value):
    # 2 s at 30 Hz: 60 frames, each lost with probability 0.3 (binomial, 3 sigma)
    assert abs(_frames(base) - 60) <= 1
    expected, sigma = 60 * (1 - value), np.sqrt(60 * value * (1 - value))
    assert abs(_frames(changed) - expected) < 3 * sigma


def _effect_camera_rate(base, changed, value):
    assert abs(_frames(base) - 60) <= 1 and abs(_frames(changed) - 2 * value) <= 1


def _effect_velocity(base, changed, value):
    # weave: offset(t) = v t + A (1 - cos(2 pi f t)), A along y only
    t = changed["t"]
    np.testing.assert_allclose(_offset(changed)[:, 0], value[0] * t, atol=1e-12)
    np.testing.assert_allclose(_offset(changed)[:, 1:], _offset(base)[:, 1:], atol=1e-12)


def _effect_amplitude(base, changed, value):
    t = changed["t"]
    expected = value[1] * (1 - np.cos(2 * np.pi * 0.03 * t))
    np.testing.assert_allclose(_offset(changed)[:, 1], expected, atol=1e-12)


def _effect_frequency(base, changed, value):
    t = changed["t"]
    expected = 0.25 * (1 - np.cos(2 * np.pi * value * t))
    np.testing.assert_allclose(_offset(changed)[:, 1], expected, atol=1e-12)


def _effect_stop_time(base, changed, value):
    t, velocity = changed["t"], changed["target_velocity"]
    np.testing.assert_array_equal(
        velocity[t < value], np.tile([0.08, 0.0, 0.0], ((t < value).sum(), 1))
    )
    assert not velocity[t >= value].any()
    assert not np.ptp(changed["target"][t >= value], axis=0).any()


def _effect_still(base, changed, value):
    assert not changed["target_velocity"].any() and not np.ptp(changed["target"], axis=0).any()


def _effect_log_rate(base, changed, value):
    np.testing.assert_allclose(np.diff(changed["t"]), 1.0 / value, rtol=1e-9)
    np.testing.assert_allclose(np.diff(base["t"]), 1.0 / 50.0, rtol=1e-9)


def _effect_duration(base, changed, value):
    assert value - 0.05 < changed["t"][-1] < value <= base["t"][-1]


def _effect_xi_d(base, changed, value):
    np.testing.assert_array_equal(changed["xi_d"], np.tile(value, (len(changed["t"]), 1)))
    assert _error(changed)[-1] < 0.1 * _error(changed)[0]  # and the features go there


def _effect_xi0(base, changed, value):
    np.testing.assert_allclose(changed["xi_true"][0], value, atol=1e-9)


def _effect_upright(base, changed, value):
    # without the projection the posture objectives roll the image further
    assert abs(changed["upright_angle"][-1]) > abs(base["upright_angle"][-1])


def _effect_upright_rate(base, changed, value):
    # phi decays at the restoring rate: 1 /s against 0.2 /s
    assert abs(changed["upright_angle"][-1]) < 0.5 * abs(base["upright_angle"][-1])


def _effect_exact_sensing(base, changed, value):
    np.testing.assert_array_equal(changed["platform_pose_measured"], changed["platform_pose"])
    np.testing.assert_array_equal(changed["v_measured"], changed["v"])
    assert np.abs(base["platform_pose_measured"] - base["platform_pose"]).max() > 0


def _effect_perfect_localisation(base, changed, value):
    np.testing.assert_array_equal(changed["platform_pose_measured"], changed["platform_pose"])
    assert np.abs(base["platform_pose_measured"] - base["platform_pose"]).max() > 0


EFFECTS = {
    "controller.k": _effect_k,
    "controller.feature_scale": _effect_feature_scale,
    "controller.feedback": _effect_feedback,
    "controller.loop_gain_margin": _effect_margin,
    "controller.upright": _effect_upright,
    "controller.upright_rate": _effect_upright_rate,
    "camera.noise_px": _effect_noise,
    "camera.drop_probability": _effect_drop,
    "camera.rate": _effect_camera_rate,
    "camera.occlusion_starts": _effect_occlusion,
    "estimator.smoothing": _effect_smoothing,
    "estimator.beta": _effect_beta,
    "estimator.kind": _effect_exact_estimator,
    "estimator.predict": _effect_predict,
    "estimator.hold": _effect_hold,
    "motion.velocity": _effect_velocity,
    "motion.amplitude": _effect_amplitude,
    "motion.frequency": _effect_frequency,
    "motion.stop_time": _effect_stop_time,
    "motion.kind": _effect_still,
    "simulation.log_rate": _effect_log_rate,
    "duration": _effect_duration,
    "target.xi_d": _effect_xi_d,
    "target.xi0": _effect_xi0,
    "sensing.exact": _effect_exact_sensing,
    "sensing.localisation": _effect_perfect_localisation,
}
"""Keys whose intended effect is checked too: ``check(base_log, changed_log, new_value)``."""


_BASES: dict = {}


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
    base, changed = _BASES[label], _run({**context, key: value})
    (meta, arrays), (changed_meta, changed_arrays) = _fingerprint(base), _fingerprint(changed)
    same_arrays = arrays.keys() == changed_arrays.keys() and all(
        arrays[k].shape == changed_arrays[k].shape
        and np.array_equal(arrays[k], changed_arrays[k], equal_nan=True)
        for k in arrays
    )
    assert not (same_arrays and meta == changed_meta), f"{key} = {value!r} changed nothing"
    if key in EFFECTS:
        EFFECTS[key](base, changed, value)


def test_the_effects_are_checked_on_keys_with_a_case():
    assert set(EFFECTS) <= set(CASES)
