"""The controller's tables of a scenario file, one frozen dataclass each.

Camera, target, estimator, controller, compensation and secondary objectives, each validated by
its constructor. :class:`~pbvs_pin.control.settings.ControllerSettings` is built from these six
alone, so a controller needs no scenario file and no simulator; :mod:`pbvs_pin.sim.sections`
holds the simulator's tables (robot, plant, motion, laser, ...) and the order of the key
reference. Each key is declared with :func:`pbvs_pin.toml_keys.key` (default, documentation
with unit, check). The ``[camera]`` table also carries the simulated camera's keys (latency,
noise, faults, the rendered model): one table a scenario writes, read by both sides.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from pbvs_pin.control.gains import FEEDBACK_LAWS, ServoGains
from pbvs_pin.control.upright import LOOP_GAIN_MARGIN, RESTORING_RATE
from pbvs_pin.exceptions import GainError
from pbvs_pin.model.camera import CameraIntrinsics
from pbvs_pin.model.support import COM_MARGIN
from pbvs_pin.perception.estimation import NOISE_ADAPTIVE, velocity_filter
from pbvs_pin.toml_keys import NON_NEGATIVE, POSITIVE, Section, key

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
        "(pbvs_pin.perception.detection.register_detector).",
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
            from pbvs_pin.perception.detection import detector_names  # OpenCV only when rendering

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
    process_noise: float = key(0.03, NOISE_ADAPTIVE, sign=NON_NEGATIVE)
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
        "passivity",
        "passivity (eq. 34) or ibvs (classic baseline: -lambda J# e in place of the feedback, "
        "the rest as the passivity law's; pbvs_pin.control.ibvs).",
        choices=("passivity", "ibvs"),
    )
    k: tuple[float, ...] = key(
        (0.15,),
        "k_i of K_c [1/s]: 1 or 3 values (the balanced law's feedback takes only their ratios, "
        "which weight the features; their scale sets V1 and the other laws' gain).",
        sign=POSITIVE,
    )
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
    feature_scale: float = key(
        150.0,
        "Pixels per controller feature unit [px] (V1's units; the balanced law's feedback does "
        "not depend on it, the transpose law's gain scales with 1 / feature_scale^2).",
        sign=POSITIVE,
    )
    weights: tuple = key(
        (1.0,),
        "W: its positive diagonal (1 or n values) or the full n x n symmetric positive "
        "definite matrix.",
        matrix=True,
    )
    feedback: str = key(
        "balanced",
        "balanced (every direction of J J^T at the loop-gain margin per camera sample, in "
        "velocity-limit units, joints at their stops left out; "
        "pbvs_pin.control.balanced.balanced_feedback), transpose (-J^T K_c e, the paper's) or "
        "pseudoinverse (-J# K_c e).",
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
        "with the camera looking forward, upright: pbvs_pin.bringup.home), "
        "with joint_limits moved out of the joint-limit zones "
        "(pbvs_pin.control.secondary.rest_outside_limit_zones), or 'max_manipulability', the "
        "paper's unconstrained maximum of the arm's manipulability.",
        choices=("home", "max_manipulability"),
    )
    joint_limits: bool = key(True, "Keep the arm joints away from their limits.")
    k_uobs: float = key(0.5, "k_uobs of eq. (17) [1/(rad s)].", sign=POSITIVE)
    k_wobs: float = key(0.9, "k_wobs of eq. (18) [1/s].", sign=POSITIVE)
    d0: float = key(1.0, "Distance d_0 at which avoidance starts [m].", sign=POSITIVE)
    impedance_mass: float = key(0.5, "Inertia m of the impedance Z [s].", sign=POSITIVE)
    impedance_damping: float = key(1.0, "Damping b of the impedance Z [1].", sign=POSITIVE)
    k_lambda: float = key(1.0, "k_Lambda of eq. (19) [1/s].", sign=POSITIVE)
    support: bool = key(
        True,
        f"Keep the centre of mass {COM_MARGIN} m inside the platform's support polygon in the "
        "null space, and, above the image task, keep the command from taking it within 0.01 m "
        "of an edge (a barrier; pbvs_pin.control.support; for a robot whose support is known: "
        "a two-wheel or skid-steer platform with a URDF) [bool].",
    )
    k_support: float = key(
        10.0,
        "k_s [1/s]: the rate at which the support objective closes the centre of mass's "
        "shortfall of its margin.",
        sign=POSITIVE,
    )
    k_heading: float = key(
        1.0,
        "k_psi [1/s]: turn the platform to where the camera looks (secondary.heading_term): "
        "a holonomic one fully; a two-wheel one times heading_factor, 0 for an arm that moves "
        "the camera along its axis (most), whose platform turns only while the support "
        "objective holds the arm at the edge (support.KeepSupported); 0: off.",
        sign=NON_NEGATIVE,
    )
