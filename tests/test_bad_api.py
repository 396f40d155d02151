"""Catalogue of bad Python API calls (issue 12): each raises a named PbvsError subclass.

A wrong shape, a non-finite number, a configuration whose (cos, sin) pairs are not unit or a
rotation that is not orthonormal must raise the exact package error naming the argument,
never a raw ValueError from NumPy or Pinocchio, and never be silently altered.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import pbvs_pin
from pbvs_pin import (
    CameraIntrinsics,
    DifferentialDrive,
    FrameNotFound,
    GainError,
    MobileManipulator,
    NonFiniteValue,
    RobotNotFound,
    ScenarioError,
    ShapeError,
    TwoSphereFeatures,
    rigid_body_terms,
)
from pbvs_pin.bringup.home import assess_home, compute_home
from pbvs_pin.exceptions import WrongType
from pbvs_pin.model.manipulability import (
    arm_manipulability,
    max_manipulability_posture,
    whole_body_manipulability,
)
from pbvs_pin.perception.detection import register_detector
from pbvs_pin.perception.estimation import AlphaBetaFilter
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.targets import Still, TwoSphereTarget
from pbvs_pin.validation import as_se3

NAN, INF = float("nan"), float("inf")


@pytest.fixture(scope="module")
def robot() -> MobileManipulator:
    return pbvs_pin.load_robot("pioneer_cyton")


def _q(robot: MobileManipulator) -> np.ndarray:
    return robot.home()


def _v(robot: MobileManipulator) -> np.ndarray:
    return np.zeros(robot.n)


def _planar(c: float, s: float):
    def q(robot: MobileManipulator) -> np.ndarray:
        q = robot.home()
        q[2:4] = c, s  # the planar root joint's (cos, sin)
        return q

    return q


TOP, BOTTOM = np.array([1.0, 0.0, 0.6]), np.array([1.0, 0.0, 0.5])
SHEARED = pin.SE3(np.array([[1.0, 0.2, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), np.zeros(3))
SCALED = pin.SE3(2.0 * np.eye(3), np.zeros(3))
MIRRORED = pin.SE3(np.diag([1.0, 1.0, -1.0]), np.zeros(3))

# (id, call taking the robot, exception class, argument the message names)
CASES = [
    ("integrate-dt-nan", lambda r: r.integrate(_q(r), _v(r), NAN), NonFiniteValue, "dt"),
    ("integrate-dt-inf", lambda r: r.integrate(_q(r), _v(r), INF), NonFiniteValue, "dt"),
    ("integrate-v-short", lambda r: r.integrate(_q(r), [0.0], 0.01), ShapeError, "v"),
    ("integrate-v-nan", lambda r: r.integrate(_q(r), np.full(r.n, NAN), 0.01), NonFiniteValue,
     "v"),
    ("integrate-q-short", lambda r: r.integrate([0.0, 0.0], _v(r), 0.01), ShapeError, "q"),
    ("integrate-q-unit", lambda r: r.integrate(_planar(5.0, 5.0)(r), _v(r), 0.01), GainError, "q"),
    ("camera-pose-q-unit", lambda r: r.camera_pose(_planar(0.0, 0.0)(r)), GainError, "q"),
    ("jacobian-q-unit", lambda r: r.camera_jacobian(_planar(2.0, 0.0)(r)), GainError, "q"),
    ("camera-pose-q-matrix", lambda r: r.camera_pose(np.zeros((2, 2))), ShapeError, "q"),
    ("arm-positions-short", lambda r: r.with_arm_positions(_q(r), [0.0, 0.0]), ShapeError, "arm"),
    ("arm-positions-long", lambda r: r.with_arm_positions(_q(r), np.zeros(7)), ShapeError, "arm"),
    ("arm-positions-nan", lambda r: r.with_arm_positions(_q(r), [NAN, 0.0, 0.0]), NonFiniteValue,
     "arm"),
    ("arm-positions-q-short", lambda r: r.with_arm_positions([1.0], [0.0, 0.0, 0.0]), ShapeError,
     "q"),
    ("rigid-body-v-short", lambda r: rigid_body_terms(r, _q(r), [0.0, 0.0]), ShapeError, "v"),
    ("rigid-body-v-matrix", lambda r: rigid_body_terms(r, _q(r), np.zeros((r.n, 2))), ShapeError,
     "v"),
    ("rigid-body-q-short", lambda r: rigid_body_terms(r, [0.0], _v(r)), ShapeError, "q"),
    ("rigid-body-q-nan", lambda r: rigid_body_terms(r, np.full(r.model.nq, NAN), _v(r)),
     NonFiniteValue, "q"),
    ("p_top-short", lambda r: TwoSphereFeatures(0.05).jacobians(r, _q(r), [1.0, 0.0], BOTTOM),
     ShapeError, "points_world[0]"),
    ("p_bottom-long", lambda r: TwoSphereFeatures(0.05).jacobians(r, _q(r), TOP, np.zeros(4)),
     ShapeError, "points_world[1]"),
    ("one-point", lambda r: TwoSphereFeatures(0.05).jacobians(r, _q(r), TOP), ShapeError,
     "points_world"),
    ("measure-points-shape", lambda r: TwoSphereFeatures(0.05).measure(r, _q(r), np.zeros(6)),
     ShapeError, "points_world"),
    ("frame-unknown", lambda r: r.frame_pose(_q(r), "no_such_frame"), FrameNotFound,
     "no_such_frame"),
    ("model-error-negative", lambda r: r.with_model_error(-1.0), GainError, "model error"),
    ("frame-dict", lambda r: r.frame_pose(_q(r), {"a": 1}), WrongType, "frame: expected a frame"),
]  # fmt: skip


@pytest.mark.parametrize(("call", "error", "named"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])  # fmt: skip
def test_bad_robot_call_names_the_argument(robot, call, error, named):
    with pytest.raises(error) as err:
        call(robot)
    assert type(err.value) is error
    assert named in str(err.value)
    assert "\n" not in str(err.value)


# (id, call, exception class, argument the message names)
STANDALONE = [
    ("se3-sheared", lambda: as_se3("mount", SHEARED), GainError, "mount"),
    ("se3-scaled", lambda: as_se3("mount", SCALED), GainError, "mount"),
    ("se3-mirrored", lambda: as_se3("camera_pose", MIRRORED), GainError, "camera_pose"),
    ("assemble-mount-scaled", lambda: MobileManipulator.assemble("pioneer3at", "cyton_alpha3",
                                                                 mount=SCALED), GainError, "mount"),
    ("assemble-camera-pose-sheared",
     lambda: MobileManipulator.assemble("pioneer3at", "cyton_alpha3", camera_pose=SHEARED),
     GainError, "camera_pose"),
    ("assemble-mount-short", lambda: MobileManipulator.assemble("pioneer3at", "cyton_alpha3",
                                                                mount=(0.0, 0.0)), ShapeError,
     "mount"),
    ("assemble-mount-nan", lambda: MobileManipulator.assemble("pioneer3at", "cyton_alpha3",
                                                              mount=(NAN, 0, 0, 0, 0, 0)),
     NonFiniteValue, "mount"),
    ("target-start-short", lambda: TwoSphereTarget(np.zeros(2), 0.05, 0.1, Still()), ShapeError,
     "start"),
    ("target-start-nan", lambda: TwoSphereTarget(np.array([NAN, 0, 0]), 0.05, 0.1, Still()),
     NonFiniteValue, "start"),
    ("focal-zero", lambda: CameraIntrinsics(0.0, 640, 480), GainError, "focal_px"),
    ("diameter-negative", lambda: TwoSphereFeatures(-0.05), GainError, "diameter"),
    ("filter-unstable", lambda: AlphaBetaFilter(0.5, 3.5), GainError, "beta"),
    ("wheel-radius-zero", lambda: DifferentialDrive(0.0, 0.4, 6.0), GainError, "wheel_radius"),
    ("unknown-robot", lambda: pbvs_pin.load_robot("no_such_robot"), RobotNotFound,
     "no_such_robot"),
    ("with-values-text", lambda: load_scenario("experiment1").with_values(
        **{"camera.rate": "fast"}), ScenarioError, "camera.rate"),
    ("with-values-unknown", lambda: load_scenario("experiment1").with_values(
        **{"camera.speed": 1.0}), ScenarioError, "camera.speed"),
    # a dict, a name or a ragged list where an object is expected (issue 31)
    *[(f"{fn.__name__}-{kind}", lambda fn=fn, bad=bad: fn(bad, np.zeros(9)), WrongType,
       "robot: expected a MobileManipulator")
      for fn in (arm_manipulability, whole_body_manipulability, assess_home)
      for kind, bad in (("dict", {"a": 1}), ("name", "pioneer_cyton"), ("ragged", [[1], [2, 3]]))],
    *[(f"{fn.__name__}-{kind}", lambda fn=fn, bad=bad: fn(bad), WrongType,
       "robot: expected a MobileManipulator")
      for fn in (compute_home, max_manipulability_posture)
      for kind, bad in (("dict", {"a": 1}), ("name", "pioneer_cyton"))],
    ("rigid-body-robot-dict", lambda: rigid_body_terms({"a": 1}, np.zeros(9), np.zeros(5)),
     WrongType, "robot: expected a MobileManipulator"),
    ("simulate-name", lambda: pbvs_pin.simulate("experiment1"), WrongType,
     "scenario: expected a Scenario, got 'experiment1' (str)"),
    ("load-robot-dict", lambda: pbvs_pin.load_robot({"name": "x"}), WrongType,
     "name: expected a robot name or a URDF path"),
    ("load-robot-list", lambda: pbvs_pin.load_robot(["pioneer_cyton"]), WrongType, "name"),
    ("assemble-base-dict", lambda: MobileManipulator.assemble({"a": 1}, "cyton_alpha3"),
     WrongType, "source: expected a URDF path or a robot name"),
    ("detector-name-list", lambda: register_detector(["a"], lambda c: None), WrongType,
     "name: expected a detector name"),
    ("detector-factory-text", lambda: register_detector("mine", "abc"), WrongType,
     "factory: expected a callable"),
    ("controller-robot-name", lambda: pbvs_pin.Controller("pioneer_cyton"), WrongType,
     "robot: expected a MobileManipulator"),
    ("colour-detector-camera-dict", lambda: pbvs_pin.ColourDetector({"width": 640}), WrongType,
     "camera: expected a CameraIntrinsics"),
    ("platform-forward-axis-list", lambda: pbvs_pin.PlatformFrame(forward_axis=["x"]), GainError,
     "expected one of ('x', 'y', '-x', '-y')"),
    ("with-values-xi_d-swapped", lambda: load_scenario("experiment1").with_values(
        **{"target.xi_d": [0.0, -60.0, 60.0]}), ScenarioError, "target.xi_d"),
]  # fmt: skip


@pytest.mark.parametrize(("call", "error", "named"), [c[1:] for c in STANDALONE],
                         ids=[c[0] for c in STANDALONE])  # fmt: skip
def test_bad_call_names_the_argument(call, error, named):
    with pytest.raises(error) as err:
        call()
    assert type(err.value) is error
    assert named in str(err.value)
    assert "\n" not in str(err.value)


def test_an_orthonormal_rotation_is_kept_exactly():
    rotation = pin.rpy.rpyToMatrix(0.1, -0.2, 0.3)
    pose = as_se3("mount", pin.SE3(rotation, np.array([0.1, 0.0, 0.2])))
    np.testing.assert_array_equal(pose.rotation, rotation)
