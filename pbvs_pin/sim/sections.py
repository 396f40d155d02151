"""The simulator's tables of a scenario file, and :data:`SECTIONS`, every table in order.

Each table is one frozen dataclass, validated by its constructor; :data:`SECTIONS` gives the
order of the key reference.
The controller's tables (camera, target, estimator, controller, compensation, secondary) are in
:mod:`pbvs_pin.control.tables`. Each key is declared with :func:`pbvs_pin.toml_keys.key`
(default, documentation with unit, check); a section's
:meth:`~pbvs_pin.toml_keys.Section.validate` adds what the package's own blocks refuse.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar, Self

from pbvs_pin.bringup.catalogue import REFERENCE_ROBOT
from pbvs_pin.bringup.robot_spec import build_robot_from, check_forms, forms_given, is_path
from pbvs_pin.control.tables import (
    CameraSection,
    CompensationSection,
    ControllerSection,
    EstimatorSection,
    SecondarySection,
    TargetSection,
)
from pbvs_pin.exceptions import GainError
from pbvs_pin.model.camera import CameraIntrinsics
from pbvs_pin.model.platform_frame import FORWARD_AXES
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.toml_keys import NON_NEGATIVE, POSITIVE, Section, key


@dataclass(frozen=True)
class RobotSection(Section):
    """``[robot]``: which robot, in one of three forms, and where its arm starts.

    The forms (:data:`~pbvs_pin.bringup.robot_spec.ROBOT_FORMS`) are a shipped ``name``; a ``urdf``
    file with its ``camera_frame``; or an assembly of a ``base`` and an ``arm`` at ``mount``
    with the camera at ``camera_pose`` in ``camera_link``. A file gives exactly one; none is
    the reference robot. Relative URDF paths (``urdf``, and ``base``/``arm`` ending in
    ``.urdf``) are read against the folder of the file (:attr:`source`) and kept absolute. The
    drive parameters replace the drive axle found in the platform URDF
    (:mod:`pbvs_pin.bringup.robot_spec`).

    Attributes:
        source: File the table was read from, for error messages and relative paths.
    """

    TABLE: ClassVar[str] = "robot"
    name: str = key("", "Shipped robot name; pioneer_cyton when no form is given.")
    urdf: str = key("", "URDF file holding platform, arm and camera frame.")
    camera_frame: str = key("", "The urdf's camera optical frame (z forward, x right, y down).")
    base: str = key(
        "", "Platform of an assembly: shipped URDF name, URDF path or example-robot-data name."
    )
    arm: str = key("", "Arm mounted on the base (as base); absent when the base carries one.")
    mount: tuple[float, ...] | None = key(
        None, "Arm root pose in the platform's root link, [x, y, z, roll, pitch, yaw] [m, rad].",
        length=6,
    )  # fmt: skip
    camera_link: str = key("", "Link of the assembly the camera is fixed to.")
    camera_pose: tuple[float, ...] | None = key(
        None, "Optical frame in camera_link, [x, y, z, roll, pitch, yaw] [m, rad].", length=6
    )
    wheel_radius: float | None = key(
        None, "Drive wheel radius [m]; from the platform URDF if absent.", sign=POSITIVE,
        optional=float,
    )  # fmt: skip
    track: float | None = key(
        None, "Distance between left and right wheels [m]; from the platform URDF if absent.",
        sign=POSITIVE, optional=float,
    )  # fmt: skip
    wheel_speed_limit: float | None = key(
        None, "Largest wheel speed [rad/s]; from the platform URDF if absent.", sign=POSITIVE,
        optional=float,
    )  # fmt: skip
    drive: str = key(
        "differential", "differential (a drive axle: u, omega) or omnidirectional (a holonomic "
        "base driven in vx, vy, omega: mecanum, omni or swerve wheels).",
        choices=("differential", "omnidirectional"),
    )  # fmt: skip
    speed_limit: float | None = key(
        None, "Omnidirectional drive: largest vx and vy [m/s]; 1.0 if absent.", sign=POSITIVE,
        optional=float,
    )  # fmt: skip
    yaw_rate_limit: float | None = key(
        None, "Omnidirectional drive: largest omega [rad/s]; 1.0 if absent.", sign=POSITIVE,
        optional=float,
    )  # fmt: skip
    base_joints: tuple[str, ...] | None = key(
        None, "Joints of the urdf (or base) that model the base's motion (x, y and yaw "
        "joints, a planar or a floating joint), fixed at zero so that the drive moves the "
        "platform; recognised automatically if absent; [] for none.", names=True,
    )  # fmt: skip
    forward_axis: str = key(
        "x", "The axis of the platform URDF's root link the platform drives along.",
        choices=tuple(FORWARD_AXES),
    )  # fmt: skip
    arm_root: str = key(
        "", "First link of the arm: of the arm URDF mounted (at mount), or of the urdf or base "
        "that carries its arm; the URDF's root if absent.",
    )  # fmt: skip
    arm_tip: str = key(
        "", "Last link of the arm (camera_link or camera_frame if absent); with arm_root or "
        "alone, the arm is the chain between them: only it is mounted of an arm URDF, and "
        "a URDF carrying its arm has every movable joint off it locked. Both absent: the "
        "whole arm URDF; every joint moving the camera.",
    )  # fmt: skip
    repair_inertia: bool = key(
        False, "Replace inertias breaking I1 + I2 >= I3 by their mean principal moment "
        "(MuJoCo's balanceinertia); the links changed go to the run's meta.",
    )  # fmt: skip
    geometry_density: float | None = key(
        None, "Density [kg/m^3] giving each link without <inertial> the inertia of its "
        "collision geometry (pbvs_pin.model.link_inertia); the links go to the run's meta. Absent: "
        "such links stay massless.", sign=POSITIVE, optional=float,
    )  # fmt: skip
    home: tuple[float, ...] | None = key(
        None, "Arm home posture [rad or m], one per arm joint; the robot's own if absent."
    )
    initial_arm: tuple[float, ...] | None = key(
        None, "Arm joint positions at the start [rad or m], one per arm joint; home if absent."
    )
    source: str = field(default="", compare=False)

    @classmethod
    def from_toml(cls, table: Mapping[str, Any], source: str) -> Self:
        """The table with relative URDF paths read against ``source``'s folder.

        Raises:
            ScenarioError: On an unknown key, an invalid value or an invalid combination of
                forms, naming the dotted field.
        """
        folder = Path(source).parent
        table = {
            name: str(folder / value) if isinstance(value, str) and is_path(name, value) else value
            for name, value in table.items()
        }
        return replace(super().from_toml(table, source), source=source)

    def validate(self) -> None:
        """Exactly one form, with every key it needs (GainError naming the key at fault)."""
        if not forms_given(self):
            object.__setattr__(self, "name", REFERENCE_ROBOT)
        check_forms(self)

    @property
    def form(self) -> str:
        """``"name"``, ``"urdf"`` or ``"assembly"``."""
        return forms_given(self)[0]

    @property
    def label(self) -> str:
        """A short name of the robot: the shipped name, the URDF file, or base + arm."""
        if self.form == "name":
            return self.name
        if self.form == "urdf":
            return self.urdf
        return f"{self.base} + {self.arm}" if self.arm else self.base

    def build(self, camera: CameraIntrinsics | None = None) -> MobileManipulator:
        """The robot this table describes, at its home (``home`` if given).

        Args:
            camera: Intrinsics; the paper's camera by default.

        Raises:
            ScenarioError: If the robot cannot be built, naming the file and the dotted field.
        """
        return build_robot_from(self, camera)


@dataclass(frozen=True)
class ModelErrorSection(Section):
    """``[model_error]``: how the controller's model differs from the true robot (the plant)."""

    TABLE: ClassVar[str] = "model_error"
    kinematic_scale: float = key(
        1.0, "Factor on the model's link lengths (1.2: 20 % kinematic error).", sign=POSITIVE
    )
    mass_scale: float = key(1.0, "Factor on the true robot's masses and inertias.", sign=POSITIVE)
    payload: float = key(
        0.0,
        "Mass [kg] at the camera frame's origin in the true robot only; its servos do not know it.",
        sign=NON_NEGATIVE,
    )


@dataclass(frozen=True)
class PlantSection(Section):
    """``[plant]``: the true robot's physics, in Pinocchio or in MuJoCo (wheels on a floor)."""

    TABLE: ClassVar[str] = "plant"
    engine: str = key(
        "pinocchio", "Physics: pinocchio (fast, no slip), mujoco.", choices=("pinocchio", "mujoco")
    )


@dataclass(frozen=True)
class MotionSection(Section):
    """``[motion]``: how the target moves."""

    TABLE: ClassVar[str] = "motion"
    kind: str = key(
        "still",
        "still, line_then_stop (velocity until stop_time) or weave (line plus a sine).",
        choices=("still", "line_then_stop", "weave"),
    )
    velocity: tuple[float, ...] = key((0.0, 0.0, 0.0), "Velocity in the world [m/s].", length=3)
    amplitude: tuple[float, ...] = key(
        (0.0, 0.0, 0.0), "Half peak-to-peak of the weave per world axis [m].", length=3
    )
    frequency: float = key(0.0, "Frequency of the weave [Hz].", sign=NON_NEGATIVE)
    stop_time: float = key(0.0, "Time the target stops [s].", sign=NON_NEGATIVE)


@dataclass(frozen=True)
class LaserSection(Section):
    """``[laser]``: the platform's planar rangefinder."""

    TABLE: ClassVar[str] = "laser"
    rate: float = key(20.0, "Scan rate [Hz].", sign=POSITIVE)
    beams: int = key(181, "Rays per scan.", sign=POSITIVE)
    field_of_view: float = key(3.14159, "Angle covered by the rays [rad].", sign=POSITIVE)
    max_range: float = key(8.0, "Longest measured distance [m].", sign=POSITIVE)
    range_noise: float = key(
        0.01, "Standard deviation of the Gaussian range noise [m] (a SICK/Hokuyo-class "
        "scanner: 1-3 cm).", sign=NON_NEGATIVE,
    )  # fmt: skip
    range_resolution: float = key(
        0.001, "Range resolution [m]: ranges are reported in multiples of it (0: exact).",
        sign=NON_NEGATIVE,
    )  # fmt: skip


@dataclass(frozen=True)
class PlatformSection(Section):
    """``[platform]``: the base's footprint, for the clearance."""

    TABLE: ClassVar[str] = "platform"
    length: float = key(0.50, "Footprint length [m].", sign=POSITIVE)
    width: float = key(0.49, "Footprint width [m].", sign=POSITIVE)


@dataclass(frozen=True)
class SimulationSection(Section):
    """``[simulation]``: integration, logging and randomness."""

    TABLE: ClassVar[str] = "simulation"
    plant_dt: float = key(0.001, "Integration step of the plant [s].", sign=POSITIVE)
    log_rate: float = key(50.0, "Samples per second in the log [Hz].", sign=POSITIVE)
    seed: int = key(
        0, "Seed of every noise generator (camera, camera faults, encoders, laser; each draws "
        "from its own stream).", sign=NON_NEGATIVE,
    )  # fmt: skip


MAX_ENCODER_BITS = 40
"""Most bits an arm encoder may have (2^40 counts a turn is far below float resolution)."""


@dataclass(frozen=True)
class SensingSection(Section):
    """``[sensing]``: what the controller reads of the robot (:mod:`pbvs_pin.sim.sensing`).

    The platform pose from wheel odometry with the heading from a yaw-rate gyro, the arm's
    positions from absolute encoders, every velocity from encoder differences over the control
    period with noise and a first-order filter. The defaults are a Pioneer-class platform (a
    500-line quadrature encoder on each motor, 20:1 gearbox, a MEMS yaw-rate gyro) with 17-bit
    absolute arm encoders.
    """

    TABLE: ClassVar[str] = "sensing"
    exact: bool = key(
        False, "The controller reads the plant's true configuration and velocity (no "
        "encoders, no odometry: an idealisation) [bool].",
    )  # fmt: skip
    localisation: str = key(
        "odometry",
        "Platform pose: odometry (integrated wheel-encoder counts, which drift when the wheels "
        "slip) or perfect (the true pose, as from an external tracker).",
        choices=("odometry", "perfect"),
    )
    heading: str = key(
        "gyro",
        "Odometry heading and yaw rate: gyro (integrated from the platform's yaw-rate gyro, "
        "gyro-corrected odometry) or wheels (from the wheel counts alone, which over-count "
        "the turns of a skid-steer platform whose wheels slip).",
        choices=("gyro", "wheels"),
    )
    gyro_noise: float = key(
        0.005, "Standard deviation of the Gaussian noise on each gyro reading [rad/s] (a "
        "MEMS gyro, 0.01 deg/s/sqrt(Hz) read at 1 kHz).", sign=NON_NEGATIVE,
    )  # fmt: skip
    gyro_bias: float = key(
        0.001, "Constant bias of the gyro [rad/s] (0.06 deg/s left after calibration).",
    )  # fmt: skip
    wheel_encoder_counts: int = key(
        40_000, "Encoder counts per wheel revolution (500 lines x 4 edges x 20:1 gearbox).",
        sign=POSITIVE,
    )  # fmt: skip
    arm_encoder_bits: int = key(
        17, "Bits of each revolute arm joint's absolute encoder: 2^bits counts a turn.",
        sign=POSITIVE,
    )  # fmt: skip
    arm_linear_resolution: float = key(
        1e-6, "Resolution of each prismatic arm joint's encoder [m].", sign=POSITIVE
    )
    joint_velocity_noise: float = key(
        0.005, "Standard deviation of the Gaussian noise on each arm joint's velocity reading "
        "[rad/s or m/s] (about one 17-bit count per 10 ms).", sign=NON_NEGATIVE,
    )  # fmt: skip
    wheel_velocity_noise: float = key(
        0.02, "Standard deviation of the Gaussian noise on each wheel's velocity reading "
        "[rad/s] (about one count per 10 ms).", sign=NON_NEGATIVE,
    )  # fmt: skip
    velocity_filter: float = key(
        0.02, "Time constant of the first-order low-pass on every velocity reading [s] (0: "
        "none), as a drive reports filtered velocities.", sign=NON_NEGATIVE,
    )  # fmt: skip

    def validate(self) -> None:
        """At most :data:`MAX_ENCODER_BITS` arm encoder bits (GainError naming the key)."""
        if self.arm_encoder_bits > MAX_ENCODER_BITS:
            raise GainError(
                f"expected at most {MAX_ENCODER_BITS}, got {self.arm_encoder_bits}",
                "arm_encoder_bits",
            )


SECTIONS: tuple[type[Section], ...] = (
    RobotSection, ModelErrorSection, PlantSection, CameraSection, TargetSection, MotionSection,
    EstimatorSection, ControllerSection, CompensationSection, SecondarySection, LaserSection,
    PlatformSection, SimulationSection, SensingSection,
)  # fmt: skip
"""Every table of a scenario file, in the order of the key reference."""
