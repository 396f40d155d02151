"""pbvs_pin: passivity-based visual servoing of mobile manipulators, built on Pinocchio.

The model layer turns URDF into what the controller needs: :class:`MobileManipulator` (one
Pinocchio model of platform, arm and camera frame), base adapters, the pinhole camera of the
paper's eq. (2), feature sets with the Jacobians of eq. (3), dynamics in actuated coordinates
and the velocity-reference model of eq. (1) with the URDF's servos (:class:`ServoModel`).

The simulation layer runs the paper's closed loop: :func:`load_scenario` reads a scenario (a
shipped name such as ``"experiment1"`` or a TOML path) and :func:`simulate` runs it and returns
its :class:`~pbvs_pin.sim.log.RunLog`. :class:`Controller` is the controller that
:func:`simulate` steps, for a loop of your own: encoders, :class:`CameraFrame` s with their
capture times and laser readings in, velocity references out; built from
:class:`ControllerSettings` or a scenario.

The names below are imported when first used (PEP 562's module ``__getattr__``): ``import
pbvs_pin`` loads neither Numba nor Pinocchio nor MuJoCo, so that the command line answers
``--help`` and refuses a bad input at once; the first use of, say, :func:`simulate` loads what
it needs.
"""

# interrupts first: a Ctrl-C while the command loads its modules is one line (its docstring)
from pbvs_pin import interrupts as interrupts

# isort: split
import importlib
import sys
import types
from importlib.metadata import PackageNotFoundError, version
from typing import Any

# compile_cache (first, as sorted) keys Numba's cache on the kernels' sources, before any kernel
from pbvs_pin import compile_cache as compile_cache

try:
    __version__ = version("pbvs_pin")
    """The installed distribution's version (``pyproject.toml``)."""
except PackageNotFoundError:  # a source tree that was never installed
    __version__ = "0+unknown"

_EXPORTS = {
    "BaseAdapter": "pbvs_pin.model.base",
    "DifferentialDrive": "pbvs_pin.model.base",
    "FixedBase": "pbvs_pin.model.base",
    "Omnidirectional": "pbvs_pin.model.base",
    "CameraIntrinsics": "pbvs_pin.model.camera",
    "point_interaction_matrix": "pbvs_pin.model.camera",
    "CameraFrame": "pbvs_pin.perception.camera_frame",
    "ROBOT_NAMES": "pbvs_pin.bringup.catalogue",
    "load_robot": "pbvs_pin.bringup.catalogue",
    "ControllerSettings": "pbvs_pin.control.settings",
    "Controller": "pbvs_pin.controller",
    "ServoCommand": "pbvs_pin.controller",
    "DynamicTerms": "pbvs_pin.model.dynamics",
    "rigid_body_terms": "pbvs_pin.model.dynamics",
    "BaseJointsError": "pbvs_pin.exceptions",
    "ChainError": "pbvs_pin.exceptions",
    "ControlInputError": "pbvs_pin.exceptions",
    "DriveAxleNotFound": "pbvs_pin.exceptions",
    "FrameNotFound": "pbvs_pin.exceptions",
    "GainError": "pbvs_pin.exceptions",
    "HomeNotFound": "pbvs_pin.exceptions",
    "NoMovableJoint": "pbvs_pin.exceptions",
    "NonFiniteValue": "pbvs_pin.exceptions",
    "PbvsError": "pbvs_pin.exceptions",
    "PointBehindCamera": "pbvs_pin.exceptions",
    "RobotNotFound": "pbvs_pin.exceptions",
    "ScenarioError": "pbvs_pin.exceptions",
    "ShapeError": "pbvs_pin.exceptions",
    "UrdfError": "pbvs_pin.exceptions",
    "ViewerUnavailable": "pbvs_pin.exceptions",
    "SecondaryInput": "pbvs_pin.control.secondary",
    "SecondaryObjective": "pbvs_pin.control.secondary",
    "FeatureSet": "pbvs_pin.perception.features",
    "ImageMeasurement": "pbvs_pin.perception.features",
    "ImagePointFeatures": "pbvs_pin.perception.features",
    "TwoSphereFeatures": "pbvs_pin.perception.features",
    "HomeCriteria": "pbvs_pin.bringup.home",
    "compute_home": "pbvs_pin.bringup.home",
    "arm_manipulability": "pbvs_pin.model.manipulability",
    "manipulability": "pbvs_pin.model.manipulability",
    "max_manipulability_posture": "pbvs_pin.model.manipulability",
    "whole_body_manipulability": "pbvs_pin.model.manipulability",
    "PlatformFrame": "pbvs_pin.model.platform_frame",
    "MobileManipulator": "pbvs_pin.model.robot",
    "ServoModel": "pbvs_pin.model.servo",
    "ColourDetector": "pbvs_pin.perception.detection",
    "Detector": "pbvs_pin.perception.detection",
    "register_detector": "pbvs_pin.perception.detection",
    "RunLog": "pbvs_pin.sim.log",
    "simulate": "pbvs_pin.sim.loop",
    "Scenario": "pbvs_pin.sim.scenario",
    "load_scenario": "pbvs_pin.sim.scenario",
    "CameraSection": "pbvs_pin.control.tables",
    "CompensationSection": "pbvs_pin.control.tables",
    "ControllerSection": "pbvs_pin.control.tables",
    "EstimatorSection": "pbvs_pin.control.tables",
    "SecondarySection": "pbvs_pin.control.tables",
    "TargetSection": "pbvs_pin.control.tables",
}
"""Each public name and the module that defines it (imported on first use)."""


def __getattr__(name: str) -> Any:
    """The public ``name``, imported from its module on first use (PEP 562)."""
    if name not in _EXPORTS:
        raise AttributeError(f"module 'pbvs_pin' has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})


class _Package(types.ModuleType):
    """The package, whose public names stay what they name when a submodule shares one.

    A guard: no public name now shares its name with a submodule of the package itself (the
    function ``pbvs_pin.manipulability`` once did, before the module moved into ``model``);
    should one again, importing that submodule (which sets the package's attribute to the
    module) sets the attribute to the module's function of that name instead.
    """

    def __setattr__(self, name: str, value: Any) -> None:
        if isinstance(value, types.ModuleType) and _EXPORTS.get(name) == value.__name__:
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


__all__ = [
    "ROBOT_NAMES",
    "BaseAdapter",
    "BaseJointsError",
    "CameraFrame",
    "CameraIntrinsics",
    "CameraSection",
    "ChainError",
    "ColourDetector",
    "CompensationSection",
    "ControlInputError",
    "Controller",
    "ControllerSection",
    "ControllerSettings",
    "Detector",
    "DifferentialDrive",
    "DriveAxleNotFound",
    "DynamicTerms",
    "EstimatorSection",
    "FeatureSet",
    "FixedBase",
    "FrameNotFound",
    "GainError",
    "HomeCriteria",
    "HomeNotFound",
    "ImageMeasurement",
    "ImagePointFeatures",
    "MobileManipulator",
    "NoMovableJoint",
    "NonFiniteValue",
    "Omnidirectional",
    "PbvsError",
    "PlatformFrame",
    "PointBehindCamera",
    "RobotNotFound",
    "RunLog",
    "Scenario",
    "ScenarioError",
    "SecondaryInput",
    "SecondaryObjective",
    "SecondarySection",
    "ServoCommand",
    "ServoModel",
    "ShapeError",
    "TargetSection",
    "TwoSphereFeatures",
    "UrdfError",
    "ViewerUnavailable",
    "__version__",
    "arm_manipulability",
    "compute_home",
    "load_robot",
    "load_scenario",
    "manipulability",
    "max_manipulability_posture",
    "point_interaction_matrix",
    "register_detector",
    "rigid_body_terms",
    "simulate",
    "whole_body_manipulability",
]
