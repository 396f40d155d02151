r"""What the controller reads of the robot: encoders, wheel odometry and the laser.

The loop never hands the plant's exact state to the controller. At every control step
:meth:`Sensing.read` reads the robot as a real one is read, the same way on both plant engines
(:class:`pbvs_pin.plant.pinocchio_plant.Plant` and :class:`pbvs_pin.plant.mujoco_plant.MujocoPlant`
both expose ``q``, and ``wheel_angles`` of the left and right drive wheels):

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
  (:meth:`pbvs_pin.model.base.DifferentialDrive.platform_velocity`);
- **gyro**: the platform's true yaw rate plus a bias and Gaussian noise
  (``sensing.gyro_bias``, ``sensing.gyro_noise``), read once a control step;
- **platform pose**: wheel odometry (:class:`pbvs_pin.plant.odometry.WheelOdometry`) from the
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
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba import njit

from pbvs_pin.model.base import DifferentialDrive, unicycle_twist
from pbvs_pin.model.joint_angles import arm_angles
from pbvs_pin.plant.odometry import WheelOdometry, odometry_update, read_counts

if TYPE_CHECKING:
    import pinocchio as pin

    from pbvs_pin.model.robot import MobileManipulator
    from pbvs_pin.sim.setup import Setup

ENCODER_STREAM = 9
"""Second entry of the encoder-noise generator's seed ``[seed, ENCODER_STREAM]``."""

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
    return planar_of(robot.base_pose(q))


def planar_of(pose: pin.SE3) -> np.ndarray:
    """``[x, y, heading]`` [m, m, rad] of a pose on the floor. Shape (3,)."""
    rotation = pose.rotation
    return np.array([*pose.translation[:2], np.arctan2(rotation[1, 0], rotation[0, 0])])


NOISE_BLOCK = 256
"""Control steps of noise drawn at once (the same numbers, in the same order, as one draw per
step: a generator's draws concatenate)."""


class Constants(NamedTuple):
    """The constant floats of :func:`sensing_step`, in this order."""

    joint_noise: float
    """``sigma`` of the arm joints' velocity noise [rad/s or m/s]."""
    wheel_noise: float
    """``sigma`` of the wheels' velocity noise [rad/s]."""
    filter_time: float
    """``tau`` of the velocity filter [s] (0: no filter)."""
    gyro_bias: float
    """The gyro's bias [rad/s]."""
    gyro_noise: float
    """``sigma`` of the gyro's noise [rad/s]."""
    wheel_radius: float
    """Of the controller's drive model [m]."""
    track: float
    """Effective track of the controller's drive model [m]."""
    n_base: float
    """Platform velocities in ``v``."""
    odometry: float
    """1 with wheel odometry (a differential drive), 0 without wheels."""
    gyro: float
    """1 when the heading comes from the gyro."""
    localise: float
    """1 when the odometry gives the platform pose, 0 for perfect localisation."""


class Sensing:
    """The robot's sensors, read at every control step (see the module docstring).

    The arithmetic of a reading is one compiled call, :func:`sensing_step`; the noise is drawn
    :data:`NOISE_BLOCK` steps at a time.

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
        self.exact = spec.exact
        model = self.model
        drive = model.base
        drive = drive if isinstance(drive, DifferentialDrive) else None
        q = self.plant.q
        self.q, self.v = q.copy(), np.zeros(model.n)
        self.odometry: WheelOdometry | None = None
        if drive is not None and not self.exact:
            self.odometry = WheelOdometry(
                drive, spec.wheel_encoder_counts, planar_pose(model, q), self.plant.wheel_angles
            )
        odometry = self.odometry is not None
        self._gyro = odometry and spec.heading == "gyro"
        self._constants = np.array(
            Constants(
                joint_noise=spec.joint_velocity_noise, wheel_noise=spec.wheel_velocity_noise,
                filter_time=spec.velocity_filter, gyro_bias=spec.gyro_bias,
                gyro_noise=spec.gyro_noise,
                wheel_radius=drive.wheel_radius if drive else 0.0,
                track=drive.effective_track if drive else 0.0, n_base=model.n_base,
                odometry=odometry, gyro=self._gyro,
                localise=odometry and spec.localisation != "perfect",
            ),
            dtype=float,
        )  # fmt: skip
        prismatic = prismatic_arm_joints(model)
        resolution = 2.0 * np.pi / 2.0**spec.arm_encoder_bits
        self._arm = np.where(prismatic, spec.arm_linear_resolution, resolution)
        self._joints = np.concatenate(
            [model.arm_q_indices, model.arm_continuous, prismatic]
        ).astype(np.int64)
        n_arm = model.n_arm
        # the filter's memory: arm readings, v, wheel speeds, yaw rate
        self._state = np.zeros(n_arm + model.n + 3)
        self._state[:n_arm] = encoder_positions(q, self._joints, self._arm)
        self._odometry_state = self.odometry.state if odometry else np.zeros(10)
        self._noise_size = n_arm + (2 if odometry else 0)
        self._noise = np.zeros((0, self._noise_size))
        self._gyro_draws = np.zeros(NOISE_BLOCK)
        self._draw = 0
        self._time: float | None = None
        self._laser_frame = "laser_link" if self.robot.model.existFrame("laser_link") else None

    def read(self, t: float) -> None:
        """Read every encoder at time ``t`` [s]; update :attr:`q` and :attr:`v` (new arrays)."""
        plant = self.plant
        if self.exact:
            self.q, self.v = plant.q, plant.v
            return
        period = 0.0 if self._time is None else t - self._time
        self._time = t
        draw = self._draw
        if period > 0:
            if draw == self._noise.shape[0]:
                self._noise = self.rng.standard_normal((NOISE_BLOCK, self._noise_size))
                if self._gyro:
                    self._gyro_draws = self.gyro_rng.standard_normal(NOISE_BLOCK)
                draw = 0
            self._draw = draw + 1
        true_q = plant.q
        q, v = np.empty(true_q.shape[0]), np.empty(self.v.shape[0])
        sensing_step(
            true_q, plant.v, plant.wheel_angles, period, self._noise, self._gyro_draws, draw,
            self._joints, self._arm, self._constants, self._state, self._odometry_state, q, v,
        )  # fmt: skip
        self.q, self.v = q, v

    def laser_reading(self) -> tuple[float, float]:
        """``(d, alpha)`` of a scan from the true laser frame (or the base), with its noise."""
        return self.laser.nearest(self.laser_ranges())

    def laser_ranges(self) -> np.ndarray:
        """A scan's ranges [m] from the true laser frame (or the base), with their noise.

        Returns:
            Shape (beams,), counter-clockwise (:meth:`pbvs_pin.sim.obstacles.Laser.angles`).
        """
        robot, q = self.robot, self.plant.q
        pose = robot.frame_pose(q, self._laser_frame) if self._laser_frame else robot.base_pose(q)
        yaw = float(np.arctan2(pose.rotation[1, 0], pose.rotation[0, 0]))
        x, y = pose.translation[:2]
        return self.laser.scan(self.obstacles, x, y, yaw, self.laser_rng)


@njit(cache=True, inline="always")
def _constants(block: np.ndarray) -> Constants:
    """:class:`Constants` from their array. Shape (11,)."""
    return Constants(
        block[0], block[1], block[2], block[3], block[4], block[5], block[6], block[7],
        block[8], block[9], block[10],
    )  # fmt: skip


@njit(cache=True)
def encoder_positions(q: np.ndarray, joints: np.ndarray, resolution: np.ndarray) -> np.ndarray:
    """Absolute encoder positions ``round(theta / delta) delta`` of the arm joints [rad or m].

    Args:
        q: Configuration. Shape (nq,).
        joints: Each arm joint's index in ``q``, whether it is continuous (cos, sin), whether
            it is prismatic. Shape (3 n_arm,).
        resolution: ``delta`` of each joint [rad or m]. Shape (n_arm,).

    Returns:
        Shape (n_arm,).
    """
    n_arm = resolution.shape[0]
    angles = arm_angles(q, joints[:n_arm], joints[n_arm : 2 * n_arm])
    return np.round(angles / resolution) * resolution


@njit(cache=True)
def sensing_step(
    true_q: np.ndarray,
    true_v: np.ndarray,
    wheel_angles: np.ndarray,
    period: float,
    noise: np.ndarray,
    gyro_draws: np.ndarray,
    draw: int,
    joints: np.ndarray,
    resolution: np.ndarray,
    constants: np.ndarray,
    state: np.ndarray,
    odometry: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
) -> None:
    """One reading of the encoders, the gyro and the odometry (module docstring).

    Args:
        true_q: The plant's configuration. Shape (nq,).
        true_v: The plant's actuated velocity. Shape (n,).
        wheel_angles: The plant's left and right wheel angles [rad]. Shape (2,).
        period: Time since the last reading [s]; 0 at the first (no velocity update).
        noise: Standard normal draws, a row per step: arm joints, then wheels.
            Shape (steps, n_arm [+ 2]).
        gyro_draws: Standard normal draws of the gyro, one per step. Shape (steps,).
        draw: The row (and gyro draw) of this step.
        joints: As :func:`encoder_positions`. Shape (3 n_arm,).
        resolution: Encoder resolution of each arm joint [rad or m]. Shape (n_arm,).
        constants: :class:`Constants`. Shape (11,).
        state: ``[arm readings, filtered v, filtered wheel speeds, filtered yaw rate]``,
            updated in place. Shape (n_arm + n + 3,).
        odometry: :attr:`pbvs_pin.plant.odometry.WheelOdometry.state` (unused without wheels),
            updated in place. Shape (10,).
        q: Output: the measured configuration. Shape (nq,).
        v: Output: the measured actuated velocity. Shape (n,).
    """
    c = _constants(constants)
    n_arm, n, n_base = resolution.shape[0], v.shape[0], int(c.n_base)
    previous = state[:n_arm]
    filtered = state[n_arm : n_arm + n]
    wheel_speeds = state[n_arm + n : n_arm + n + 2]
    arm = encoder_positions(true_q, joints, resolution)
    if period > 0:
        gain = 1.0 if c.filter_time == 0 else -math.expm1(-period / c.filter_time)
        for i in range(n_arm):
            change = arm[i] - previous[i]
            if joints[2 * n_arm + i] == 0:  # revolute: the shortest way round
                change = (change + np.pi) % (2 * np.pi) - np.pi
            raw = change / period + c.joint_noise * noise[draw, i]
            filtered[n_base + i] += gain * (raw - filtered[n_base + i])
        if c.odometry:
            yaw_rate = true_v[n_base - 1] + c.gyro_bias + c.gyro_noise * gyro_draws[draw]
            counts, increments = np.empty(2), np.empty(2)
            read_counts(wheel_angles, odometry, counts)
            odometry_update(odometry, counts, yaw_rate * period, c.gyro != 0, increments)
            for side in range(2):
                raw = (
                    increments[side] * (odometry[7] / period)
                    + c.wheel_noise * noise[draw, n_arm + side]
                )
                wheel_speeds[side] += gain * (raw - wheel_speeds[side])
            filtered[0], filtered[n_base - 1] = unicycle_twist(
                c.wheel_radius, c.track, wheel_speeds[0], wheel_speeds[1]
            )
            if c.gyro:
                state[-1] += gain * (yaw_rate - state[-1])
                filtered[n_base - 1] = state[-1]
    if not c.odometry:
        filtered[:n_base] = true_v[:n_base]
    previous[:] = arm
    v[:] = filtered
    q[:] = true_q
    if c.localise:
        theta = odometry[2]
        q[0], q[1], q[2], q[3] = odometry[0], odometry[1], math.cos(theta), math.sin(theta)
    for i in range(n_arm):
        j = joints[i]
        if joints[n_arm + i]:
            q[j], q[j + 1] = math.cos(arm[i]), math.sin(arm[i])
        else:
            q[j] = arm[i]
