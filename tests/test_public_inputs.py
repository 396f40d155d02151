"""One input conversion for the public API (issue 24 item 2), enumerated from ``__all__``.

Every public function, constructor and method of ``pbvs_pin.__all__`` (but the controller's
run-time API, which the lead's rewrite tests) has a valid call in :data:`CALLS`; a new public
name without one fails :func:`test_every_public_callable_has_a_call`. Each argument that is a
number, a vector, a pose or a path (by its annotation) is then replaced, one at a time, by
values of the wrong kind: the call must raise a :class:`pbvs_pin.PbvsError` whose message names
the argument, never a raw ``TypeError``, ``ValueError`` or ``AttributeError``.
"""

from __future__ import annotations

import inspect

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import pytest
from conftest import URDF_DIR

import pbvs_pin
from pbvs_pin import (
    CameraIntrinsics,
    DifferentialDrive,
    HomeCriteria,
    ImageMeasurement,
    ImagePointFeatures,
    Omnidirectional,
    PbvsError,
    TwoSphereFeatures,
)

EXCLUDED = {"Controller", "ServoCommand", "Detector", "ColourDetector", "SecondaryInput",
            "SecondaryObjective"}  # fmt: skip
"""The controller's step is fuzzed in tests/test_controller.py (wrong shapes, NaN, time, stale
and future frames, 400 seeded random steps). The detectors take camera images; a wrong kind of
image is not converted at their door yet (an open item). A SecondaryObjective is the user's
code, which the controller calls with a SecondaryInput it builds itself; what the objective
returns is checked at the controller's side (tests/test_user_objectives.py)."""

SECTIONS_BUILT = {"CameraSection", "CompensationSection", "ControllerSection", "EstimatorSection",
                  "SecondarySection", "TargetSection"}  # fmt: skip
"""A scenario's typed tables: each key's value is checked when a section is built and refused
with its key named by ``load_scenario`` and ``with_values`` (tests/test_bad_scenarios.py)."""

CONVERTED = ("ArrayLike", "float", "int", "ndarray", "SE3", "Path")
"""Annotations of the arguments converted at the door: numbers, vectors, poses, paths."""

WRONG = {
    "text": "abc",
    "number-as-text": "1.5",
    "list-of-text": ["a", "b", "c"],
    "ragged": [[1.0], [2.0, 3.0]],
    "dict": {"x": 1.0},
    "object": object(),
    "complex": 1j,
    "bool": True,
}
"""Values of the wrong kind for a number, a vector, a pose or a path."""

TOP, BOTTOM = np.array([1.0, 0.0, 0.6]), np.array([1.0, 0.0, 0.5])
POINTS = np.array([[10.0, -20.0], [12.0, 30.0]])


def _robot():
    return pbvs_pin.load_robot("pioneer_cyton")


def _measurement():
    return ImageMeasurement(POINTS, np.array([1.0, 1.0]))


def _jacobians(robot, q: npt.ArrayLike):
    """``FeatureSet.jacobians`` with both target points given (its ``*points_world``)."""
    return TwoSphereFeatures(0.05).jacobians(robot, q, TOP, BOTTOM)


def _camera_pose(robot):
    return robot.camera_pose(robot.home())


# name -> (callable from the robot, valid keyword arguments from the robot)
CALLS = {
    "CameraIntrinsics": (lambda r: CameraIntrinsics, lambda r: {"focal_px": 600.0, "width": 640,
                                                                "height": 480}),
    "CameraIntrinsics.apparent_diameter": (lambda r: CameraIntrinsics().apparent_diameter,
                                           lambda r: {"depth": 1.0, "diameter_m": 0.05}),
    "CameraIntrinsics.back_project": (lambda r: CameraIntrinsics().back_project,
                                      lambda r: {"xi": POINTS, "depths": [1.0, 1.0]}),
    "CameraIntrinsics.depth_from_diameter": (lambda r: CameraIntrinsics().depth_from_diameter,
                                             lambda r: {"diameter_px": 30.0, "diameter_m": 0.05}),
    "CameraIntrinsics.in_image": (lambda r: CameraIntrinsics().in_image,
                                  lambda r: {"xi": [1.0, 2.0], "margin": 0.0}),
    "CameraIntrinsics.project": (lambda r: CameraIntrinsics().project,
                                 lambda r: {"point_in_camera": [0.1, 0.0, 1.0]}),
    "CameraIntrinsics.project_jacobian": (lambda r: CameraIntrinsics().project_jacobian,
                                          lambda r: {"point_in_camera": [0.1, 0.0, 1.0]}),
    "CameraIntrinsics.project_world": (lambda r: CameraIntrinsics().project_world,
                                       lambda r: {"camera_pose": _camera_pose(r),
                                                  "points_world": np.array([TOP, BOTTOM]),
                                                  "min_depth": 0.0}),
    "CameraIntrinsics.to_pixel": (lambda r: CameraIntrinsics().to_pixel,
                                  lambda r: {"xi": [1.0, 2.0]}),
    "CameraIntrinsics.from_pixel": (lambda r: CameraIntrinsics().from_pixel,
                                    lambda r: {"pixel": [1.0, 2.0]}),
    "CameraFrame": (lambda r: pbvs_pin.CameraFrame, lambda r: {"capture_time": 1.0,
                                                              "points": POINTS,
                                                              "depths": [1.0, 1.0]}),
    "CameraFrame.seen": (lambda r: pbvs_pin.CameraFrame.seen,
                         lambda r: {"capture_time": 1.0, "points": POINTS, "depths": [1.0, 1.0]}),
    "CameraFrame.not_visible": (lambda r: pbvs_pin.CameraFrame.not_visible,
                                lambda r: {"capture_time": 1.0}),
    "CameraFrame.from_diameters": (lambda r: pbvs_pin.CameraFrame.from_diameters,
                                   lambda r: {"capture_time": 1.0, "points": POINTS,
                                              "diameters_px": [30.0, 30.0],
                                              "camera": CameraIntrinsics(),
                                              "sphere_diameter": 0.05}),
    "ControllerSettings": (lambda r: pbvs_pin.ControllerSettings,
                           lambda r: {"history": 2.0, "servo_time_constants": [0.2] * 5}),
    "DifferentialDrive": (lambda r: DifferentialDrive,
                          lambda r: {"wheel_radius": 0.1, "track": 0.4, "max_wheel_speed": 6.0,
                                     "track_factor": 1.0}),
    "DifferentialDrive.platform_velocity": (lambda r: DifferentialDrive(0.1, 0.4, 6.0)
                                            .platform_velocity,
                                            lambda r: {"wheel_speeds": [1.0, 2.0]}),
    "DifferentialDrive.wheel_speeds": (lambda r: DifferentialDrive(0.1, 0.4, 6.0).wheel_speeds,
                                       lambda r: {"u": 0.1, "omega": 0.2}),
    "Omnidirectional": (lambda r: Omnidirectional, lambda r: {"max_speed": 1.0,
                                                              "max_yaw_rate": 1.0}),
    "BaseAdapter.per_velocity": (lambda r: Omnidirectional().per_velocity,
                                 lambda r: {"linear": 0.7, "yaw": 1.0}),
    "HomeCriteria": (lambda r: HomeCriteria, lambda r: {"min_height": 0.5, "max_height": 1.0}),
    "ImageMeasurement": (lambda r: ImageMeasurement, lambda r: {"points": POINTS,
                                                                "depths": [1.0, 1.0]}),
    "ImagePointFeatures": (lambda r: ImagePointFeatures, lambda r: {"count": 2}),
    "TwoSphereFeatures": (lambda r: TwoSphereFeatures, lambda r: {"diameter": 0.05}),
    "FeatureSet.jacobians": (lambda r: _jacobians, lambda r: {"robot": r, "q": r.home()}),
    "FeatureSet.measure": (lambda r: TwoSphereFeatures(0.05).measure,
                           lambda r: {"robot": r, "q": r.home(),
                                      "points_world": np.array([TOP, BOTTOM])}),
    "FeatureSet.visible": (lambda r: TwoSphereFeatures(0.05).visible,
                           lambda r: {"robot": r, "q": r.home(),
                                      "points_world": np.array([TOP, BOTTOM])}),
    "FeatureSet.jacobians_from_measurement": (
        lambda r: TwoSphereFeatures(0.05).jacobians_from_measurement,
        lambda r: {"camera": r.camera, "measurement": _measurement(),
                   "camera_jacobian": r.camera_jacobian(r.home()),
                   "rotation_world_to_camera": _camera_pose(r).rotation.T}),
    "FeatureSet.object_jacobian": (lambda r: TwoSphereFeatures(0.05).object_jacobian,
                                   lambda r: {"camera": r.camera, "measurement": _measurement(),
                                              "rotation_world_to_camera":
                                                  _camera_pose(r).rotation.T}),
    "MobileManipulator.arm_positions": (lambda r: r.arm_positions, lambda r: {"q": r.home()}),
    "MobileManipulator.base_pose": (lambda r: r.base_pose, lambda r: {"q": r.home()}),
    "MobileManipulator.camera_jacobian": (lambda r: r.camera_jacobian, lambda r: {"q": r.home()}),
    "MobileManipulator.camera_pose": (lambda r: r.camera_pose, lambda r: {"q": r.home()}),
    "MobileManipulator.check_configuration": (lambda r: r.check_configuration,
                                              lambda r: {"q": r.home()}),
    "MobileManipulator.check_velocity": (lambda r: r.check_velocity,
                                         lambda r: {"v": np.zeros(r.n)}),
    "MobileManipulator.frame_pose": (lambda r: r.frame_pose,
                                     lambda r: {"q": r.home(), "frame": "base_link"}),
    "MobileManipulator.integrate": (lambda r: r.integrate,
                                    lambda r: {"q": r.home(), "v": np.zeros(r.n), "dt": 0.01}),
    "MobileManipulator.with_arm_positions": (lambda r: r.with_arm_positions,
                                             lambda r: {"q": r.home(), "arm": np.zeros(r.n_arm)}),
    "MobileManipulator.with_model_error": (lambda r: r.with_model_error,
                                           lambda r: {"kinematic_scale": 1.1, "mass_scale": 1.0}),
    "MobileManipulator.with_payload": (lambda r: r.with_payload, lambda r: {"mass": 0.1}),
    "MobileManipulator.write_urdf": (lambda r: r.write_urdf, lambda r: {}),
    "MobileManipulator.from_urdf": (lambda r: pbvs_pin.MobileManipulator.from_urdf,
                                    lambda r: {"path": str(URDF_DIR / "pioneer_cyton.urdf")}),
    "MobileManipulator.assemble": (lambda r: pbvs_pin.MobileManipulator.assemble,
                                   lambda r: {"base": "pioneer3at", "arm": "cyton_alpha3", "camera_link": "camera_optical_frame",
                                              "mount": (0.1, 0.0, 0.27, 0.0, 0.0, 0.0)}),
    "arm_manipulability": (lambda r: pbvs_pin.arm_manipulability,
                           lambda r: {"robot": r, "q": r.home()}),
    "whole_body_manipulability": (lambda r: pbvs_pin.whole_body_manipulability,
                                  lambda r: {"robot": r, "q": r.home()}),
    "manipulability": (lambda r: pbvs_pin.manipulability,
                       lambda r: {"jacobian": np.eye(6)}),
    "compute_home": (lambda r: pbvs_pin.compute_home,
                     lambda r: {"robot": r, "starts": 1, "refine": 1, "seed": 0}),
    "max_manipulability_posture": (lambda r: pbvs_pin.max_manipulability_posture,
                                   lambda r: {"robot": r, "starts": 1, "seed": 0}),
    "point_interaction_matrix": (lambda r: pbvs_pin.point_interaction_matrix,
                                 lambda r: {"focal_px": 600.0, "xi": [1.0, 2.0], "depth": 1.0}),
    "rigid_body_terms": (lambda r: pbvs_pin.rigid_body_terms,
                         lambda r: {"robot": r, "q": r.home(), "v": np.zeros(r.n)}),
    "load_robot": (lambda r: pbvs_pin.load_robot, lambda r: {"name": "pioneer_cyton"}),
    "load_scenario": (lambda r: pbvs_pin.load_scenario, lambda r: {"name_or_path": "experiment1"}),
    "simulate": (lambda r: pbvs_pin.simulate,
                 lambda r: {"scenario": pbvs_pin.load_scenario("experiment1").with_values(
                     duration=0.2), "features": pbvs_pin.ImagePointFeatures(2),
                     "xi_d": [0.0, 60.0, 0.0, -60.0]}),
    "RunLog.load": (lambda r: pbvs_pin.RunLog.load, lambda r: {}),
    "RunLog.save": (lambda r: pbvs_pin.RunLog({"t": np.zeros(2)}).save, lambda r: {}),
    "ServoModel.from_robot": (lambda r: pbvs_pin.ServoModel.from_robot,
                              lambda r: {"robot": r, "platform": (0.26, 0.23), "revolute": 0.02,
                                         "prismatic": 0.05}),
}  # fmt: skip
"""A valid call of each public callable; ``{}`` where every argument is an object or a
path tried below without a valid default."""

BUILT = {"DynamicTerms", "RunLog", "ServoModel", "Scenario"}
"""Results the package builds and a user reads (their fields are the package's arrays); a
scenario is built by ``load_scenario`` or ``with_values``, which name the dotted field
(tests/test_bad_scenarios.py)."""

UNCHECKED = {"MobileManipulator.camera_jacobian_unchecked", "MobileManipulator.camera_placement",
             "ServoModel.reference_model"}  # fmt: skip
"""Inner-loop variants, documented as taking a checked ``q``; their checked twins
(``camera_jacobian``, ``camera_pose``, ``rigid_body_terms``) are in :data:`CALLS`."""


def _public_callables() -> dict[str, object]:
    found = {}
    for name in pbvs_pin.__all__:
        obj = getattr(pbvs_pin, name)
        if name in EXCLUDED or not callable(obj) or (
            inspect.isclass(obj) and issubclass(obj, BaseException)
        ):
            continue
        if not inspect.isabstract(obj):
            found[name] = obj
        if inspect.isclass(obj):
            for method in vars(obj):
                function = getattr(obj, method)
                if method.startswith("_") or not callable(function) or inspect.isclass(function):
                    continue
                owner = "FeatureSet" if issubclass(obj, pbvs_pin.FeatureSet) else name
                found[f"{owner}.{method}"] = function
    return found


def test_every_public_callable_taking_numbers_vectors_poses_or_paths_has_a_call():
    public = _public_callables()
    converting = {name for name, call in public.items() if _converted(call)}
    assert len(public) > 60 and len(converting) > 40  # the enumeration itself works
    assert sorted(converting - set(CALLS) - UNCHECKED - BUILT - SECTIONS_BUILT) == []


def _converted(call) -> list[str]:
    names = []
    for parameter in inspect.signature(call).parameters.values():
        annotation = str(parameter.annotation)
        if parameter.kind is parameter.VAR_POSITIONAL or parameter.name == "self":
            continue
        if any(kind in annotation for kind in CONVERTED) and "CameraIntrinsics" not in annotation:
            names.append(parameter.name)
    return names


PATH_TEXT = ("text", "number-as-text")
"""Text is a valid path: not a wrong value for a path argument."""


def _cases() -> list[tuple[str, str, str]]:
    robot = _robot()
    cases = []
    for name, (call, _) in CALLS.items():
        annotations = {p.name: str(p.annotation)
                       for p in inspect.signature(call(robot)).parameters.values()}  # fmt: skip
        for argument in _converted(call(robot)):
            path = "Path" in annotations[argument]
            cases += [(name, argument, w) for w in WRONG if not (path and w in PATH_TEXT)]
    return cases


CASES = _cases()


@pytest.fixture(scope="module")
def robot():
    return _robot()


@pytest.mark.parametrize(("name", "argument", "wrong"), CASES,
                         ids=[f"{n}-{a}-{w}" for n, a, w in CASES])  # fmt: skip
def test_a_wrong_kind_of_value_names_the_argument(robot, tmp_path, monkeypatch, name, argument,
                                                  wrong):
    monkeypatch.chdir(tmp_path)  # a path argument writes nothing into the checkout
    call, valid = CALLS[name]
    kwargs = valid(robot)
    kwargs[argument] = WRONG[wrong]
    with pytest.raises(PbvsError) as err:
        call(robot)(**kwargs)
    assert argument in str(err.value)
    assert "\n" not in str(err.value)


def test_the_valid_calls_are_valid(robot):
    """Each call of :data:`CALLS` succeeds as given (so that a refusal above is the value's)."""
    for name, (call, valid) in CALLS.items():
        if name in ("RunLog.load", "RunLog.save", "MobileManipulator.write_urdf"):
            continue
        call(robot)(**valid(robot))


def test_a_pose_must_be_a_rigid_transform():
    with pytest.raises(PbvsError, match="mount"):
        pbvs_pin.MobileManipulator.assemble("pioneer3at", "cyton_alpha3", mount=pin.SE3.Random()
                                            .homogeneous * 2.0)
