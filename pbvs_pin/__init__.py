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
"""

# interrupts first: a Ctrl-C while the command loads its modules is one line (its docstring)
from pbvs_pin import interrupts as interrupts

# isort: split
from importlib.metadata import PackageNotFoundError, version

# compile_cache (first, as sorted) keys Numba's cache on the kernels' sources
from pbvs_pin import compile_cache as compile_cache
from pbvs_pin.base import BaseAdapter, DifferentialDrive, FixedBase, Omnidirectional
from pbvs_pin.camera import CameraIntrinsics, point_interaction_matrix
from pbvs_pin.camera_frame import CameraFrame
from pbvs_pin.catalogue import ROBOT_NAMES, load_robot
from pbvs_pin.control.settings import ControllerSettings
from pbvs_pin.controller import Controller, ServoCommand
from pbvs_pin.dynamics import DynamicTerms, rigid_body_terms
from pbvs_pin.exceptions import (
    BaseJointsError,
    ChainError,
    ControlInputError,
    DriveAxleNotFound,
    FrameNotFound,
    GainError,
    HomeNotFound,
    NoMovableJoint,
    NonFiniteValue,
    PbvsError,
    PointBehindCamera,
    RobotNotFound,
    ScenarioError,
    ShapeError,
    UrdfError,
    ViewerUnavailable,
)
from pbvs_pin.features import FeatureSet, ImageMeasurement, ImagePointFeatures, TwoSphereFeatures
from pbvs_pin.home import HomeCriteria, compute_home
from pbvs_pin.manipulability import (
    arm_manipulability,
    manipulability,
    max_manipulability_posture,
    whole_body_manipulability,
)
from pbvs_pin.platform_frame import PlatformFrame
from pbvs_pin.robot import MobileManipulator
from pbvs_pin.servo import ServoModel
from pbvs_pin.sim.detection import ColourDetector, Detector, register_detector
from pbvs_pin.sim.log import RunLog
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import Scenario, load_scenario
from pbvs_pin.sim.sections import (
    CameraSection,
    CompensationSection,
    ControllerSection,
    EstimatorSection,
    SecondarySection,
    TargetSection,
)

try:
    __version__ = version("pbvs_pin")
    """The installed distribution's version (``pyproject.toml``)."""
except PackageNotFoundError:  # a source tree that was never installed
    __version__ = "0+unknown"

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
