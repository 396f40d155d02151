r"""What the controller reads of the robot: encoders, wheel odometry and the laser (issue 9).

The loop never hands the plant's exact state to the controller. At every control step
:meth:`Sensing.read` reads the robot as a real one is read, the same way on both plant engines
(:class:`pbvs_pin.plant.Plant` and :class:`pbvs_pin.mujoco_plant.MujocoPlant` both expose
``q``, and ``wheel_angles`` of the left and right drive wheels):

- **arm positions**: absolute encoders, ``theta = round(theta_true / delta) delta`` with
  ``delta = 2 pi / 2^bits`` (``sensing.arm_encoder_bits``) for a revolute joint and
  ``sensing.arm_linear_resolution`` for a prismatic one;
- **wheel counts**: incremental encoders, ``c = floor((a - a_0) / delta_w)`` with
  ``delta_w = 2 pi / sensing.wheel_encoder_counts``;
- **velocities**: encoder differences over the control period ``T`` (the time between two
  readings), plus Gaussian noise ``sigma n`` (``sensing.joint_velocity_noise``,
  ``sensing.wheel_velocity_noise``), through a first-order low-pass filter of time constant
  ``tau`` (``sensing.velocity_filter``), as a drive reports its filtered velocity:

  .. math:: \hat v_k = \hat v_{k-1} + (1 - e^{-T/\tau}) \left(\frac{\Delta \theta_k}{T}
            + \sigma n_k - \hat v_{k-1}\right)

  (``tau = 0``: no filter). The quantisation bounds the raw difference's error by
  ``delta / T`` (one count); the noise adds a standard deviation ``sigma`` before the filter,
  ``sigma sqrt((1 - p) / (1 + p))`` after it (pole ``p = e^{-T/tau}``). The platform's
  ``[u, omega]`` follow from the filtered wheel speeds
  (:meth:`pbvs_pin.base.DifferentialDrive.platform_velocity`);
- **gyro**: the platform's true yaw rate plus a bias and Gaussian noise
  (``sensing.gyro_bias``, ``sensing.gyro_noise``), read once a control step;
- **platform pose**: wheel odometry (:class:`pbvs_pin.odometry.WheelOdometry`) from the
  counts, with the controller's drive model, started at the true pose at ``t = 0``; its
  heading, and the measured yaw rate, from the gyro reading times the period
  (``sensing.heading = "gyro"``, gyro-corrected odometry) or from the counts
  (``"wheels"``); or the true pose with ``sensing.localisation = "perfect"``;
- **laser**: the scan is taken from the true laser pose; each range gets Gaussian noise and
  is rounded to the resolution (:class:`pbvs_pin.sim.obstacles.Laser`).

``sensing.exact`` gives the controller the plant's true ``q`` and ``v`` (the idealisation of
earlier versions; the laser keeps its own keys). A platform that is not a differential drive
(from Python) has no wheels: its pose and velocities are read exactly.

Every noise is seeded from ``simulation.seed``, each source on its own stream
(:data:`ENCODER_STREAM`, :data:`LASER_STREAM`, :data:`GYRO_STREAM`), so that switching one on
leaves the others' draws unchanged.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from pbvs_pin.base import DifferentialDrive
from pbvs_pin.odometry import WheelOdometry
from pbvs_pin.robot import arm_angles

if TYPE_CHECKING:
    from pbvs_pin.robot import MobileManipulator
    from pbvs_pin.sim.setup import Setup

ENCODER_STREAM = 9
"""Second entry of the encoder-noise generator's seed ``[seed, ENCODER_STREAM]`` (issue 9)."""

LASER_STREAM = 90
"""Second entry of the laser-noise generator's seed ``[seed, LASER_STREAM]``."""

GYRO_STREAM = 91
"""Second entry of the gyro-noise generator's seed ``[seed, GYRO_STREAM]``."""


def prismatic_arm_joints(model: MobileManipulator) -> np.ndarray:
    """Whether each arm joint is prismatic (its position in metres). Shape (n_arm,)."""
    joints = [model.model.joints[model.model.getJointId(name)] for name in model.arm_joint_names]
    return np.array([j.shortname().startswith("JointModelP") and j.nq == 1 for j in joints])


def planar_pose(robot: MobileManipulator, q: np.ndarray) -> np.ndarray:
    """``[x, y, heading]`` [m, m, rad] of the platform (the root joint's frame). Shape (3,)."""
    pose = robot.base_pose(q)
    rotation = pose.rotation
    return np.array([*pose.translation[:2], np.arctan2(rotation[1, 0], rotation[0, 0])])


class Sensing:
    """The robot's sensors, read at every control step (see the module docstring).

    Args:
        setup: The run's blocks; the plant is read, the controller's model gives the drive
            and the joints.

    Attributes:
        q: Measured configuration (odometry pose, encoder arm positions). Shape (nq,).
        v: Measured actuated velocity ``[u, omega, arm rates]``. Shape (n,).
        odometry: The wheel odometry (None for exact sensing or a platform without wheels).
    """

    def __init__(self, setup: Setup) -> None:
        scenario = setup.scenario
        spec = scenario.sensing
        self.plant, self.model, self.robot = setup.plant, setup.model, setup.robot
        self.laser, self.obstacles = setup.laser, setup.obstacles
        seed = scenario.simulation.seed
        self.rng = np.random.default_rng([seed, ENCODER_STREAM])
        self.laser_rng = np.random.default_rng([seed, LASER_STREAM])
        self.gyro_rng = np.random.default_rng([seed, GYRO_STREAM])
        self.gyro = spec.heading == "gyro"
        self.gyro_noise, self.gyro_bias = spec.gyro_noise, spec.gyro_bias
        self.exact = spec.exact
        model = self.model
        drive = model.base
        self.drive = drive if isinstance(drive, DifferentialDrive) else None
        prismatic = prismatic_arm_joints(model)
        self._revolute = ~prismatic
        self.arm_resolution = np.where(
            prismatic, spec.arm_linear_resolution, 2.0 * np.pi / 2.0**spec.arm_encoder_bits
        )
        self.joint_noise, self.wheel_noise = spec.joint_velocity_noise, spec.wheel_velocity_noise
        self.filter_time = spec.velocity_filter
        q = self.plant.q
        self.q, self.v = q.copy(), np.zeros(model.n)
        self.odometry: WheelOdometry | None = None
        if self.drive is not None and not self.exact:
            self.odometry = WheelOdometry(
                self.drive, spec.wheel_encoder_counts, planar_pose(model, q),
                self.plant.wheel_angles,
            )  # fmt: skip
        self.perfect_localisation = spec.localisation == "perfect"
        continuous = model.arm_continuous
        self._plain_q = model.arm_q_indices[~continuous]  # where q holds the angle itself
        self._plain, self._continuous = ~continuous, continuous
        self._cos_q = model.arm_q_indices[continuous]  # (cos, sin) pairs start here
        self._arm = self._arm_reading(q)
        self._wheel_speeds = np.zeros(2)
        self._yaw_rate = 0.0
        self._n_base = model.n_base
        self._noise_size = model.n_arm + (2 if self.odometry is not None else 0)
        self._time: float | None = None
        self._laser_frame = "laser_link" if self.robot.model.existFrame("laser_link") else None

    def _arm_reading(self, q: np.ndarray) -> np.ndarray:
        """Absolute encoder positions of the arm joints [rad or m]. Shape (n_arm,)."""
        model, resolution = self.model, self.arm_resolution
        angles = arm_angles(q, model.arm_q_indices, model.arm_continuous)
        return np.round(angles / resolution) * resolution

    def read(self, t: float) -> None:
        """Read every encoder at time ``t`` [s]; update :attr:`q` and :attr:`v`."""
        plant = self.plant
        true_q = plant.q
        if self.exact:
            self.q, self.v = true_q, plant.v
            return
        arm = self._arm_reading(true_q)
        v = self.v.copy()
        n_base, odometry = self._n_base, self.odometry
        period = 0.0 if self._time is None else t - self._time
        self._time = t
        if period > 0:
            change = arm - self._arm
            change[self._revolute] = (change[self._revolute] + np.pi) % (2 * np.pi) - np.pi
            noise = self.rng.standard_normal(self._noise_size)  # arm joints, then wheels
            gain = self._filter_gain(period)
            raw = change / period + self.joint_noise * noise[: arm.size]
            v[n_base:] += gain * (raw - v[n_base:])
            if odometry is not None:
                yaw_rate = self._gyro_reading() if self.gyro else None
                turn = None if yaw_rate is None else yaw_rate * period
                increments = odometry.update(odometry.read_counts(plant.wheel_angles), turn)
                raw = increments * (odometry.resolution / period) + self.wheel_noise * noise[-2:]
                self._wheel_speeds += gain * (raw - self._wheel_speeds)
                v[:n_base] = self.drive.platform_velocity(self._wheel_speeds)
                if yaw_rate is not None:
                    self._yaw_rate += gain * (yaw_rate - self._yaw_rate)
                    v[n_base - 1] = self._yaw_rate
        if odometry is None:
            v[:n_base] = plant.v[:n_base]
        self._arm = arm
        q = true_q.copy()
        if odometry is not None and not self.perfect_localisation:
            x, y, theta = odometry.pose
            q[:4] = x, y, math.cos(theta), math.sin(theta)
        q[self._plain_q] = arm[self._plain]
        q[self._cos_q] = np.cos(arm[self._continuous])
        q[self._cos_q + 1] = np.sin(arm[self._continuous])
        self.q, self.v = q, v

    def _gyro_reading(self) -> float:
        """The gyro: the platform's true yaw rate [rad/s] with its bias and noise."""
        true_rate = float(self.plant.v[self._n_base - 1])
        return true_rate + self.gyro_bias + self.gyro_noise * self.gyro_rng.standard_normal()

    def _filter_gain(self, period: float) -> float:
        """``1 - exp(-T / tau)`` of the velocity filter (1 without a filter)."""
        if self.filter_time == 0:
            return 1.0
        return -math.expm1(-period / self.filter_time)

    def laser_reading(self) -> tuple[float, float]:
        """``(d, alpha)`` of a scan from the true laser frame (or the base), with its noise."""
        robot, q = self.robot, self.plant.q
        pose = robot.frame_pose(q, self._laser_frame) if self._laser_frame else robot.base_pose(q)
        yaw = float(np.arctan2(pose.rotation[1, 0], pose.rotation[0, 0]))
        x, y = pose.translation[:2]
        ranges = self.laser.scan(self.obstacles, x, y, yaw, self.laser_rng)
        return self.laser.nearest(ranges)
