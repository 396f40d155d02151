"""The measured numbers in the docs' prose, each recomputed from a fresh run: other arms.

How each test checks its figure: :mod:`docs_figures`.
"""

from __future__ import annotations

from docs_figures import (
    EXPERIMENTS,
    PAPERS_LAW,
    run,
    stated,
)

from pbvs_pin import load_robot
from pbvs_pin.bringup.catalogue import ROBOT_NAMES


def test_the_image_rolls_without_the_upright_constraint():
    paper_posture = {"controller.upright": False, "secondary.posture_target": "max_manipulability"}
    _, panda_figures = run("experiment4", **{"robot.name": "pioneer_panda"}, **paper_posture)
    stated(f"rolled the Panda's image by {abs(panda_figures['upright_min_deg']):.0f} deg;")
    tiago, tiago_figures = run("experiment4", **{"robot.name": "tiago"}, **paper_posture)
    upright, upright_figures = run(
        "experiment4", **{"robot.name": "tiago", "secondary.posture_target": "max_manipulability"}
    )
    assert tiago["target_lost_samples"] == 0
    error = "max_abs_error_final_window_px"
    stated(
        f"TIAGo's rolled by {abs(tiago_figures['upright_min_deg']):.0f} deg and ended "
        f"{tiago[error]:.1f} px off; with it, by {abs(upright_figures['upright_min_deg']):.0f} "
        f"deg and {upright[error]:.1f} px off"
    )
    assert panda_figures["upright_min_deg"] < -20.0 and tiago_figures["upright_min_deg"] < -5.0
    # the constraint holds the image upright; it does not lower TIAGo's error (the sentence
    # says so: this posture target misses Experiment 4's rule either way)
    assert abs(upright_figures["upright_min_deg"]) < 2.0


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


def test_the_net_on_six_and_seven_joint_arms():
    arms = [name for name in ROBOT_NAMES if load_robot(name).n_arm in (6, 7)]
    assert len(arms) >= 4
    acting = {
        name: [
            run(experiment, **{"robot.name": robot, **PAPERS_LAW})[1]["gain_limited"]
            for robot in arms
        ]
        for name, experiment in zip("1234", EXPERIMENTS, strict=True)
    }
    first_three = acting["1"] + acting["2"] + acting["3"]
    stated(
        f"it acts in {min(first_three) * 100:.0f}-{max(first_three) * 100:.0f} % of the samples "
        f"of Experiments 1-3 ({min(acting['4']) * 100:.0f}-{max(acting['4']) * 100:.0f} % in "
        "Experiment 4)"
    )
    # most samples, but where the support's barrier holds a heavy arm back at the edge the
    # gain per sample is lower (32 % at the least since the barrier, 82 % before)
    assert min(first_three) > 0.25 and max(first_three + acting["4"]) <= 1.0
