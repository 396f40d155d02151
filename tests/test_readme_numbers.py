"""The measured numbers in the docs' prose, each recomputed from a fresh run.

The generated blocks (the README's results table, the gallery's MuJoCo table) are checked by
``test_experiments.py`` and ``test_mujoco_acceptance.py``. The figures in the prose of the docs
pages are checked here: each test runs the configuration its sentence names, formats the figure
as the page writes it and looks for the sentence on its page. When one fails, the behaviour
changed: measure again and update the sentence (or the conclusion drawn from it).

A figure found on its page only shows that the page was updated. Each test also bounds its
figures by what the sentence concludes from them, independently of the page: the report's
3 px oscillation flag (:data:`OSCILLATION_FLAG_PX`), the loop-gain margin, one run against
another ("prediction lowers it", "the home does better").
"""

from __future__ import annotations

import functools

import numpy as np
from conftest import REPO_ROOT
from test_any_robot import TIAGO_PRO, robot_values, unshipped_arm
from test_mujoco_plant import _mean_body_velocity, _plant
from test_prediction import ALL_FAULTS

from pbvs_pin import load_robot
from pbvs_pin.catalogue import ROBOT_NAMES
from pbvs_pin.control.upright import LOOP_GAIN_MARGIN
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.metrics import summarize
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.setup import SETTLE_TIME, build


def page_text(name: str) -> str:
    """``docs/NAME.md`` with every run of whitespace (line breaks included) made one space."""
    return " ".join((REPO_ROOT / "docs" / f"{name}.md").read_text().split())


NET_OFF = 1e6
"""A loop-gain margin the net never reaches: the net switched off."""

IDEALISED = {
    "sensing.exact": True, "camera.latency": 0.0, "laser.range_noise": 0.0,
    "laser.range_resolution": 0.0, "estimator.predict": False,
}  # fmt: skip
"""The old idealisation: exact state, no latency, an exact laser, no prediction."""

EXPERIMENTS = ("experiment1", "experiment2", "experiment3", "experiment4")

OSCILLATION_FLAG_PX = 3.0
"""The report flags an oscillation above 0.5 Hz of more than 3 px RMS."""


@functools.cache
def _run(experiment: str, values: tuple) -> tuple[dict, dict[str, np.ndarray]]:
    log = simulate(load_scenario(experiment).with_values(**dict(values)))
    t = log["t"]
    final = t >= t[-1] - 5.0
    n_arm = len(log.meta["posture_target"])
    figures = {
        "arm_speed_final_window": float(np.max(np.abs(log["v"][final][:, -n_arm:]))),
        "upright_min_deg": float(np.degrees(np.nanmin(log["upright_angle"]))),
        "gain_limited": float(np.mean(log["gain_limited"])),
        "largest_gain": float(np.nanmax(log["loop_gain"])),
    }
    return summarize(log), figures


def run(experiment: str, **values: object) -> tuple[dict, dict[str, float]]:
    """The run's summary and a few figures of its log, computed once per configuration."""
    hashable = {key: tuple(v) if isinstance(v, list) else v for key, v in values.items()}
    return _run(experiment, tuple(sorted(hashable.items())))


def stated(sentence: str, page: str = "departures") -> None:
    assert sentence in page_text(page), f"docs/{page}.md no longer says {sentence!r}: measure again"


def test_the_reference_cameras_home_height():
    setup = build(load_scenario("experiment1"))
    height = setup.robot.camera_pose(setup.plant.q).translation[2]
    assert height < 0.5  # below the band: the sentence's point
    stated(f"the Cyton's camera gets to {height:.2f} m high", "own_robot")


def test_the_four_faults_are_the_tested_ones():
    stated(
        f"four faults together: {ALL_FAULTS['camera.latency'] * 1e3:.0f} ms latency, "
        f"{ALL_FAULTS['camera.noise_px']:.0f} px noise, "
        f"{ALL_FAULTS['camera.drop_probability'] * 100:.0f} % of the frames dropped and a "
        f"{ALL_FAULTS['camera.occlusion_duration']:.0f} s occlusion",
        "faults",
    )


def test_the_old_idealisation():
    errors = [run(name, **IDEALISED)[0]["max_abs_error_final_window_px"] for name in EXPERIMENTS]
    stated(
        f"the reference robot's largest feature errors over the last 5 s are {errors[0]:.2f}, "
        f"{errors[1]:.2f}, {errors[2]:.2f} and {errors[3]:.3f} px in Experiments 1-4",
        "idealisations",
    )
    assert max(errors) < 3.0  # every experiment converges


def test_feature_scale_80():
    unprotected, figures = run(
        "experiment1",
        **{
            "controller.feature_scale": 80.0, "controller.loop_gain_margin": NET_OFF,
            "estimator.predict": False,
        },
    )  # fmt: skip
    stated(
        f"{unprotected['max_abs_error_final_window_px']:.0f} px over the last 5 s, "
        f"{unprotected['oscillation_rms_px']:.0f} px RMS above 0.5 Hz, arm joints at up to "
        f"{figures['arm_speed_final_window']:.2f} rad/s"
    )
    held, held_figures = run("experiment1", **{"controller.feature_scale": 80.0})
    stated(
        f"80 px holds ({held['max_abs_error_final_window_px']:.2f} px), but the net cuts the "
        f"gain in {held_figures['gain_limited'] * 100:.1f} % of the samples"
    )
    assert run("experiment1")[1]["gain_limited"] == 0.0  # "with 150 px it never acts"
    assert unprotected["oscillation_rms_px"] > OSCILLATION_FLAG_PX  # "limit-cycles"
    unprotected_error = unprotected["max_abs_error_final_window_px"]
    assert unprotected_error > 10 * held["max_abs_error_final_window_px"]
    assert held["max_abs_error_final_window_px"] < 3.0 and held_figures["gain_limited"] > 0.5


def test_the_image_rolls_without_the_upright_constraint():
    paper_posture = {"controller.upright": False, "secondary.posture_target": "max_manipulability"}
    panda, panda_figures = run("experiment4", **{"robot.name": "pioneer_panda"}, **paper_posture)
    assert panda["target_lost_samples"] > 0
    stated(
        f"rolled the Panda's image by {abs(panda_figures['upright_min_deg']):.0f} deg, and the "
        "target was lost"
    )
    tiago, tiago_figures = run("experiment4", **{"robot.name": "tiago"}, **paper_posture)
    upright = run(
        "experiment4", **{"robot.name": "tiago", "secondary.posture_target": "max_manipulability"}
    )[0]
    assert tiago["target_lost_samples"] == 0
    stated(
        f"TIAGo's rolled by {abs(tiago_figures['upright_min_deg']):.0f} deg and ended "
        f"{tiago['max_abs_error_final_window_px']:.1f} px off "
        f"({upright['max_abs_error_final_window_px']:.1f} px with it)"
    )
    assert panda_figures["upright_min_deg"] < -45.0 and tiago_figures["upright_min_deg"] < -5.0
    error = "max_abs_error_final_window_px"
    assert upright[error] < tiago[error]  # the upright constraint does better


def test_the_loop_gain_net():
    largest = [run(name)[1]["largest_gain"] for name in EXPERIMENTS]
    stated(
        f"largest gain per sample {largest[0]:.2f}, {largest[1]:.2f}, {largest[2]:.2f} and "
        f"{largest[3]:.2f} in Experiments 1-4"
    )
    acting = [run(name, **{"estimator.predict": False})[1]["gain_limited"] for name in EXPERIMENTS]
    assert len({f"{fraction * 100:.1f}" for fraction in acting[:3]}) == 1
    stated(
        f"it acted in {acting[0] * 100:.1f} % of the samples of Experiments 1-3 and "
        f"{acting[3] * 100:.0f} % of Experiment 4's"
    )
    without = run(
        "experiment2", **{"controller.loop_gain_margin": NET_OFF, "estimator.predict": False}
    )[0]
    stated(f"oscillated at {without['oscillation_rms_px']:.1f} px RMS above 0.5 Hz")
    assert max(largest) < LOOP_GAIN_MARGIN  # with prediction the net never acts
    assert all(0.0 < fraction <= 1.0 for fraction in acting)
    assert without["oscillation_rms_px"] > OSCILLATION_FLAG_PX


def test_the_posture_target():
    def final(robot: str, target: str) -> float:
        values = {"robot.name": robot, "secondary.posture_target": target}
        return run("experiment4", **values)[0]["max_abs_error_final_window_px"]

    stated(
        f"xArm7 Experiment 4 ended up to {final('pioneer_xarm7', 'max_manipulability'):.1f} px "
        f"off over the last 5 s and TIAGo's {final('tiago', 'max_manipulability'):.1f} px, "
        f"against {final('pioneer_xarm7', 'home'):.2f} and {final('tiago', 'home'):.2f} px "
        "with the home"
    )
    for robot in ("pioneer_xarm7", "tiago"):
        assert final(robot, "home") < final(robot, "max_manipulability")


def test_the_servos_leave_no_oscillation():
    second, third = (run(name)[0]["oscillation_rms_px"] for name in EXPERIMENTS[1:3])
    stated(f"now {second:.2f} and {third:.2f} px RMS")
    assert max(second, third) < OSCILLATION_FLAG_PX


def test_prediction_on_the_mujoco_plant():
    def summary(robot: str, experiment: str, predict: bool) -> dict:
        values = {"robot.name": robot, "plant.engine": "mujoco", "estimator.predict": predict}
        return run(experiment, **values)[0]

    cyton, tiago = (
        [summary(robot, "experiment2", p)["oscillation_rms_px"] for p in (False, True)]
        for robot in ("pioneer_cyton", "tiago")
    )
    ur5 = [
        summary("pioneer_ur5", "experiment4", p)["max_abs_error_final_window_px"]
        for p in (False, True)
    ]
    stated(
        f"Experiment 2's oscillation above 0.5 Hz {cyton[0]:.2f} and {cyton[1]:.2f} px RMS "
        f"(the report flags 3 px), TIAGo's {tiago[0]:.2f} and {tiago[1]:.2f} px; `pioneer_ur5` "
        f"Experiment 4 ended up to {ur5[0]:.2f} and {ur5[1]:.2f} px off over the last 5 s"
    )
    for without, with_prediction in (cyton, tiago, ur5):  # prediction lowers each
        assert with_prediction < without
    assert max(cyton[1], tiago[1]) < OSCILLATION_FLAG_PX and ur5[1] < 0.5  # the claim: 0.5 px


def test_payload_with_integral_servos():
    def final(engine: str, kg: float, experiment: str) -> float:
        values = {"plant.engine": engine, "model_error.payload": kg}
        return run(experiment, **values)[0]["max_abs_error_final_window_px"]

    def pair(engine: str, kg: float) -> str:
        return f"{final(engine, kg, 'experiment1'):.2f} and {final(engine, kg, 'experiment4'):.2f}"

    stated(
        f"with the integral {pair('pinocchio', 0.5)} px (MuJoCo: {pair('mujoco', 0.5)} px), "
        f"1 kg {pair('pinocchio', 1.0)} px ({pair('mujoco', 1.0)} px)"
    )
    for engine in ("pinocchio", "mujoco"):  # the integral takes the payload: within 3 px
        for kg in (0.5, 1.0):
            assert max(final(engine, kg, name) for name in ("experiment1", "experiment4")) < 3.0


def test_compensating_the_arm_too():
    platform = run("experiment4")[0]
    arm_too = [run(name, **{"compensation.mode": "all"})[0] for name in EXPERIMENTS]
    stated(
        f"the arm's |v - u| RMS rose from {platform['velocity_tracking_rms_arm']:.4f} "
        f"(`platform`) to {arm_too[3]['velocity_tracking_rms_arm']:.4f} and the error over the "
        f"last 5 s from {platform['max_abs_error_final_window_px']:.2f} to "
        f"{arm_too[3]['max_abs_error_final_window_px']:.2f} px",
        "limitations",
    )
    assert arm_too[3]["velocity_tracking_rms_arm"] > platform["velocity_tracking_rms_arm"]
    error = "max_abs_error_final_window_px"
    assert arm_too[3][error] > platform[error]  # "rose": compensating the arm does worse
    oscillation = [summary["oscillation_rms_px"] for summary in arm_too]
    assert 0.0 < min(oscillation) and max(oscillation) < OSCILLATION_FLAG_PX
    stated(
        f"oscillate by {min(oscillation):.1f}-{max(oscillation):.1f} px RMS above 0.5 Hz",
        "limitations",
    )


def test_the_net_on_six_and_seven_joint_arms():
    arms = [name for name in ROBOT_NAMES if load_robot(name).n_arm in (6, 7)]
    assert len(arms) >= 4
    acting = {
        name: [run(experiment, **{"robot.name": robot})[1]["gain_limited"] for robot in arms]
        for name, experiment in zip("1234", EXPERIMENTS, strict=True)
    }
    first_three = acting["1"] + acting["2"] + acting["3"]
    stated(
        f"it acts in {min(first_three) * 100:.0f}-{max(first_three) * 100:.0f} % of the samples "
        f"of Experiments 1-3 ({min(acting['4']) * 100:.0f}-{max(acting['4']) * 100:.0f} % in "
        "Experiment 4)"
    )
    assert min(first_three) > 0.5 and max(first_three + acting["4"]) <= 1.0


def test_the_skid_steer_spin():
    robot = load_robot("pioneer_cyton")
    chi = robot.base.track_factor
    stated(f"Coulomb friction expands its track by {chi:.2f}", "limitations")
    stated(f"it would turn at {1.0 / chi:.2f} of", "limitations")

    def yaw_rate(u: float, omega: float, loop: bool) -> float:
        options = {} if loop else {"yaw_integral_time": None}
        plant = _plant(robot, settle=SETTLE_TIME, **options)
        return _mean_body_velocity(plant, [u, omega, 0.0, 0.0, 0.0])[2]

    slow, fast = yaw_rate(0.0, 0.1, False), yaw_rate(0.0, 0.4, False)
    stated(
        f"commanded to spin at 0.4 rad/s it turns at {fast:.2f} rad/s ({fast / 0.4:.2f} of the "
        f"command; {slow / 0.1:.2f} at 0.1 rad/s)",
        "limitations",
    )
    commands = ((0.0, 0.1), (0.0, 0.4), (0.2, 0.2))
    worst = max(abs(yaw_rate(u, omega, True) / omega - 1.0) for u, omega in commands)
    stated(f"within {worst * 100:.1f} % spinning at 0.1 and 0.4 rad/s", "limitations")
    # friction widens the track (chi > 1); sticking wheels turn slower still; the loop fixes it
    assert chi > 1.0 and fast / 0.4 < 1.0 / chi and slow / 0.1 < 1.0 and worst < 0.05


def test_tiago_pro_on_the_mujoco_plant():
    tiago_pro = robot_values(TIAGO_PRO)
    robot = build(load_scenario("experiment1").with_values(**tiago_pro)).robot
    command = np.zeros(robot.n)
    command[1] = 0.4
    spin = _mean_body_velocity(_plant(robot, settle=SETTLE_TIME), command)[2]
    runs = [run(name, **tiago_pro, **{"plant.engine": "mujoco"})[0] for name in EXPERIMENTS[::3]]
    assert all(summary["target_lost_samples"] == 0 for summary in runs)
    stated(
        f"skid-steer platform with an expansion factor of {robot.base.track_factor:.1f}: "
        f"commanded to spin at 0.4 rad/s it turns at {spin:.3f} rad/s, and Experiments 1 and 4 "
        f"end {runs[0]['max_abs_error_final_window_px']:.1f} and "
        f"{runs[1]['max_abs_error_final_window_px']:.1f} px off (target never lost)",
        "limitations",
    )
    assert robot.base.track_factor > 1.0 and 0.0 < spin < 0.4 / robot.base.track_factor


def test_unshipped_arms_on_the_mujoco_plant():
    def finals(arm: str) -> str:
        values = robot_values(unshipped_arm(arm))
        errors = [
            run(name, **values, **{"plant.engine": "mujoco"})[0]["max_abs_error_final_window_px"]
            for name in EXPERIMENTS
        ]
        assert max(errors) < 5.0  # "hold"
        return f"{errors[0]:.2f}, {errors[1]:.2f}, {errors[2]:.2f} and {errors[3]:.2f} px"

    stated(f"the UR10 ends Experiments 1-4 at {finals('ur10')}, the Reach Bravo 7 at "
           f"{finals('bravo7_no_ee')}", "limitations")  # fmt: skip
