"""The tables of a scenario file, one frozen dataclass each, validated by their constructors.

Each key is declared with :func:`pbvs_pin.sim.keys.key` (default, documentation with unit,
check); a section's :meth:`~pbvs_pin.sim.keys.Section.validate` adds what the package's own
blocks refuse (camera intrinsics, filter gains, servo gains).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar, Self

from pbvs_pin.camera import CameraIntrinsics
from pbvs_pin.catalogue import REFERENCE_ROBOT
from pbvs_pin.control.kinematic import FEEDBACK_LAWS, ServoGains
from pbvs_pin.control.upright import LOOP_GAIN_MARGIN, RESTORING_RATE
from pbvs_pin.estimation import NOISE_ADAPTIVE, velocity_filter
from pbvs_pin.exceptions import GainError
from pbvs_pin.platform_frame import FORWARD_AXES
from pbvs_pin.robot import MobileManipulator
from pbvs_pin.robot_spec import build_robot_from, check_forms, forms_given, is_path
from pbvs_pin.sim.keys import (
    NON_NEGATIVE,
    POSITIVE,
    Section,
    key,
)


@dataclass(frozen=True)
class RobotSection(Section):
    """``[robot]``: which robot, in one of three forms, and where its arm starts.

    The forms (:data:`~pbvs_pin.robot_spec.ROBOT_FORMS`) are a shipped ``name``; a ``urdf``
    file with its ``camera_frame``; or an assembly of a ``base`` and an ``arm`` at ``mount``
    with the camera at ``camera_pose`` in ``camera_link``. A file gives exactly one; none is
    the reference robot. Relative URDF paths (``urdf``, and ``base``/``arm`` ending in
    ``.urdf``) are read against the folder of the file (:attr:`source`) and kept absolute. The
    drive parameters replace the drive axle found in the platform URDF
    (:mod:`pbvs_pin.robot_spec`).

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
        "collision geometry (pbvs_pin.link_inertia); the links go to the run's meta. Absent: "
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


MAX_IMAGE_PX = 100_000
"""Largest image width or height [px] a ``[camera]`` table accepts."""

MIN_FIELD_OF_VIEW_DEG = 0.1
"""Smallest field of view [deg] (across the larger image side) a ``[camera]`` table accepts."""


@dataclass(frozen=True)
class CameraSection(Section):
    """``[camera]``: intrinsics and the image stream with its faults (pbvs_pin.sim.vision)."""

    TABLE: ClassVar[str] = "camera"
    focal_px: float = key(600.0, "Focal length f [px].", sign=POSITIVE)
    width: int = key(628, "Image width [px].", sign=POSITIVE)
    height: int = key(582, "Image height [px].", sign=POSITIVE)
    rate: float = key(30.0, "Frame rate [Hz].", sign=POSITIVE)
    latency: float | None = key(
        None, "Delay from capture to delivery [s]; one frame period (1 / rate) if absent.",
        sign=NON_NEGATIVE, optional=float,
    )  # fmt: skip
    noise_px: float = key(
        0.0, "Standard deviation of the pixel noise [px] (points camera; a rendered camera "
        "has image_noise).", sign=NON_NEGATIVE,
    )  # fmt: skip
    drop_probability: float = key(0.0, "Chance a frame is lost, in [0, 1).", sign=NON_NEGATIVE)
    occlusion_starts: tuple[float, ...] = key((), "Occlusion starts [s].", sign=NON_NEGATIVE)
    occlusion_rate: float = key(0.0, "Random occlusion episodes per second.", sign=NON_NEGATIVE)
    occlusion_duration: float = key(0.0, "Length of an occlusion [s].", sign=NON_NEGATIVE)
    latency_jitter: float = key(0.0, "Largest extra (uniform) latency [s].", sign=NON_NEGATIVE)
    exposure_delay: float = key(0.0, "Exposure to timestamp delay [s].", sign=NON_NEGATIVE)
    model: str = key(
        "points", "points (eq. 2 on the sphere centres) or rendered (MuJoCo draws the scene, a "
        "detector finds the spheres: pbvs_pin.sim.rendered_camera).",
        choices=("points", "rendered"),
    )  # fmt: skip
    detector: str = key(
        "colour", "Detector of a rendered camera, by its registered name "
        "(pbvs_pin.sim.detection.register_detector).",
    )  # fmt: skip
    image_noise: float = key(
        0.0, "Rendered camera: standard deviation of the per-pixel noise [grey levels of 255].",
        sign=NON_NEGATIVE,
    )  # fmt: skip
    exposure_time: float = key(
        0.0, "Rendered camera: exposure averaged over the control steps it spans, motion blur "
        "[s] (0: none).", sign=NON_NEGATIVE,
    )  # fmt: skip
    light_change_time: float = key(
        0.0, "Rendered camera: time the lighting changes [s].", sign=NON_NEGATIVE
    )
    light_change_scale: float = key(
        1.0, "Rendered camera: factor on the lights' intensity from light_change_time on (1: "
        "no change).", sign=NON_NEGATIVE,
    )  # fmt: skip

    @property
    def delivery_latency(self) -> float:
        """The latency [s]: ``latency``, or one frame period ``1 / rate`` when not given.

        A camera's frame reaches the controller at the earliest one frame period after its
        exposure starts (the sensor is read out while the next frame is exposed), so a
        delivery without delay is the idealisation and one frame the realistic default.
        """
        return 1.0 / self.rate if self.latency is None else self.latency

    def intrinsics(self) -> CameraIntrinsics:
        """The pinhole intrinsics."""
        return CameraIntrinsics(self.focal_px, self.width, self.height)

    def validate(self) -> None:
        """Valid, plausible intrinsics (GainError naming the key).

        The image is at most :data:`MAX_IMAGE_PX` px a side and the field of view at least
        :data:`MIN_FIELD_OF_VIEW_DEG` across the larger side; drop_probability < 1; a
        registered detector.
        """
        if self.drop_probability >= 1:
            raise GainError(f"expected < 1, got {self.drop_probability:g}", "drop_probability")
        for name in ("width", "height"):
            if getattr(self, name) > MAX_IMAGE_PX:
                raise GainError(
                    f"expected at most {MAX_IMAGE_PX} px, got {getattr(self, name)}", name
                )
        half_view = math.radians(MIN_FIELD_OF_VIEW_DEG) / 2
        largest = max(self.width, self.height) / (2 * math.tan(half_view))
        if self.focal_px > largest:
            raise GainError(
                f"expected at most {largest:.4g} px (a field of view of at least "
                f"{MIN_FIELD_OF_VIEW_DEG} deg for this image), got {self.focal_px:g}",
                "focal_px",
            )
        self.intrinsics()
        if self.model == "rendered":
            from pbvs_pin.sim.detection import detector_names  # OpenCV only when rendering

            if self.detector not in detector_names():
                raise GainError(
                    f"expected one of {detector_names()}, got {self.detector!r}", "detector"
                )


@dataclass(frozen=True)
class TargetSection(Section):
    """``[target]``: two spheres, one above the other, and the features asked for."""

    TABLE: ClassVar[str] = "target"
    diameter: float = key(0.05, "Diameter of each sphere [m].", sign=POSITIVE)
    separation: float = key(0.10, "Distance between the sphere centres [m].", sign=POSITIVE)
    xi0: tuple[float, ...] = key(
        (-150.0, 20.0, -100.0), "Features xi(0) = [u1, v1, v2] at the start [px].", length=3
    )
    xi_d: tuple[float, ...] = key(
        (0.0, 60.0, -60.0), "Desired features xi_d = [u1, v1, v2] [px].", length=3
    )

    def validate(self) -> None:
        """Two separate spheres: the diameter must be below the centres' separation."""
        if not self.diameter < self.separation:
            raise GainError(
                f"the spheres overlap: diameter {self.diameter:g} m is not below their "
                f"separation {self.separation:g} m (expected diameter < separation)",
                "diameter",
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
class EstimatorSection(Section):
    """``[estimator]``: the target-velocity estimate ``phat_dot``."""

    TABLE: ClassVar[str] = "estimator"
    kind: str = key(
        "alpha_beta",
        "alpha_beta (filter on the measured position) or exact (the true velocity).",
        choices=("alpha_beta", "exact"),
    )
    alpha: float = key(0.5, "Position gain of the alpha-beta filter, 0 < alpha <= 1.")
    beta: float = key(0.1, "Velocity gain of the alpha-beta filter, 0 < beta < 4 - 2 alpha.")
    process_noise: float = key(0.0, NOISE_ADAPTIVE, sign=NON_NEGATIVE)
    predict: bool = key(False, "Bring each frame up to now along eq. (3) (control.tracking).")
    hold: float = key(0.0, "Servo on predictions this long after a loss [s].", sign=NON_NEGATIVE)
    smoothing: float = key(1.0, "Weight of a frame against its prediction, <= 1.", sign=POSITIVE)

    def validate(self) -> None:
        """Stable filter gains (GainError naming alpha or beta), smoothing <= 1."""
        if self.smoothing > 1:
            raise GainError(f"expected <= 1, got {self.smoothing:g}", "smoothing")
        velocity_filter(self.alpha, self.beta, self.process_noise)


@dataclass(frozen=True)
class ControllerSection(Section):
    """``[controller]``: the kinematic controller of eq. (34) (or classic IBVS)."""

    TABLE: ClassVar[str] = "controller"
    law: str = key(
        "passivity", "passivity (eq. 34) or ibvs (classic baseline).", choices=("passivity", "ibvs")
    )
    k: tuple[float, ...] = key((0.15,), "k_i of K_c [1/s]: 1 or 3 values.", sign=POSITIVE)
    k1: tuple[float, ...] = key(
        (0.7, 1.0, 0.1, 0.1, 0.1),
        "Diagonal of k_1, null-space amplitude [m/s or rad/s]: 1 or n values (5 values for "
        "2 base + 3 arm dof fit any robot: the last is repeated for every arm joint).",
        sign=POSITIVE,
    )
    k2: tuple[float, ...] = key(
        (0.2,), "Diagonal of k_2, null-space slope [1/unit of Lambda]: 1 or n values.",
        sign=POSITIVE,
    )  # fmt: skip
    feature_scale: float = key(150.0, "Pixels per controller feature unit [px].", sign=POSITIVE)
    weights: tuple = key(
        (1.0,),
        "W: its positive diagonal (1 or n values) or the full n x n symmetric positive "
        "definite matrix.",
        matrix=True,
    )
    feedback: str = key(
        "transpose",
        "transpose (-J^T K_c e, the paper's), pseudoinverse (-J# K_c e) or balanced (every "
        "direction of J J^T at the loop-gain margin per camera sample, in velocity-limit units, "
        "joints at their stops left out; pbvs_pin.control.kinematic.balanced_feedback).",
        choices=FEEDBACK_LAWS,
    )
    ibvs_gain: float = key(0.5, "lambda of the classic IBVS law [1/s].", sign=POSITIVE)
    rate: float = key(100.0, "Control rate [Hz].", sign=POSITIVE)
    upright: bool = key(
        True,
        "Keep the null-space motion from rolling the image about the optical axis (a "
        "departure from the paper; pbvs_pin.control.upright) [bool].",
    )
    upright_rate: float = key(
        RESTORING_RATE,
        "k_phi, decay rate of the image's upright angle inside the null space [1/s].",
        sign=NON_NEGATIVE,
    )
    loop_gain_margin: float = key(
        LOOP_GAIN_MARGIN,
        "Largest feedback gain per camera sample, k T lambda_max(J J^T) in controller units; "
        "above it the feature gains are scaled down and the log's gain_limited is set; scaled "
        "by sin(pi / (2 (2 d + 1))) for a latency of d camera periods not predicted "
        "(pbvs_pin.control.upright) [1].",
        sign=POSITIVE,
    )

    def gains(self) -> ServoGains:
        """The servo gains as written (before they are fitted to a robot's dof)."""
        return ServoGains(
            k=self.k,
            k1=self.k1,
            k2=self.k2,
            feature_scale=self.feature_scale,
            weights=self.weights,
            feedback=self.feedback,
            upright=self.upright,
            upright_rate=self.upright_rate,
            loop_gain_margin=self.loop_gain_margin,
        )

    def validate(self) -> None:
        """The gains must be valid servo gains (GainError naming the key)."""
        self.gains()


@dataclass(frozen=True)
class CompensationSection(Section):
    """``[compensation]``: the dynamic compensation of eq. (20)."""

    TABLE: ClassVar[str] = "compensation"
    mode: str = key(
        "platform",
        "off, platform (the base's dof) or all (every dof).",
        choices=("off", "platform", "all"),
    )
    k_d: tuple[float, ...] = key((4.0,), "k_d [1/s]: 1 or n values.", sign=POSITIVE)
    derivative_time_constant: float = key(
        0.05, "Time constant of the command's filtered derivative [s].", sign=POSITIVE
    )


@dataclass(frozen=True)
class SecondarySection(Section):
    """``[secondary]``: the secondary objectives of eqs. (16)-(19)."""

    TABLE: ClassVar[str] = "secondary"
    obstacle_avoidance: bool = key(False, "Avoid obstacles seen by the laser, eqs. (17)-(18).")
    posture: bool = key(False, "Pull the arm to theta_d, eq. (19).")
    posture_target: str = key(
        "home",
        "theta_d of eq. (19): 'home', the robot's home posture (the most manipulable posture "
        "with the camera looking forward, upright: pbvs_pin.home), or 'max_manipulability', "
        "the paper's unconstrained maximum of the arm's manipulability.",
        choices=("home", "max_manipulability"),
    )
    joint_limits: bool = key(True, "Keep the arm joints away from their limits.")
    k_uobs: float = key(0.5, "k_uobs of eq. (17) [1/(rad s)].", sign=POSITIVE)
    k_wobs: float = key(0.9, "k_wobs of eq. (18) [1/s].", sign=POSITIVE)
    d0: float = key(1.0, "Distance d_0 at which avoidance starts [m].", sign=POSITIVE)
    impedance_mass: float = key(0.5, "Inertia m of the impedance Z [s].", sign=POSITIVE)
    impedance_damping: float = key(1.0, "Damping b of the impedance Z [1].", sign=POSITIVE)
    k_lambda: float = key(1.0, "k_Lambda of eq. (19) [1/s].", sign=POSITIVE)
    k_heading: float = key(1.0, "k_psi [1/s]: turn a two-wheel platform to where the camera looks "
        "(secondary.heading_term), times heading_factor: 0 for an arm that moves the camera "
        "along its axis (most); 0: off.", sign=NON_NEGATIVE)


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
