"""The faults a real camera brings (issue 13): drops, occlusion, latency jitter, exposure delay.

The sensor is driven by hand on a fixed scene (expected values follow from the keys'
definitions, not from the sensor); ``tests/test_knobs.py`` shows every key moves a log.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from pbvs_pin.exceptions import ScenarioError
from pbvs_pin.model.camera import CameraIntrinsics
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.vision import CameraFaults, CameraSensor

CENTRES = np.array([[0.0, -0.05, 1.0], [0.0, 0.05, 1.0]])
"""Two spheres 1 m in front of a camera at the world origin (optical axis = world z)."""

RATE = 100.0
"""Frame rate of the hand-driven sensor [Hz]; it is stepped at the frame period."""


def drive(faults: CameraFaults, seconds: float, latency: float = 0.0, rng_seed: int = 0):
    """Step a sensor every frame period; return (delivery time, frame) for each delivery."""
    sensor = CameraSensor(
        CameraIntrinsics(600.0, 628, 582), 0.05, RATE, latency, 0.0,
        np.random.default_rng(0), faults, np.random.default_rng(rng_seed),
    )  # fmt: skip
    delivered = []
    for step in range(round(seconds * RATE)):
        t = step / RATE
        q = np.array([t])  # the "encoder" reads the time, to check which instant is stamped
        if sensor.capture_due(t):
            sensor.capture(t, pin.SE3.Identity(), CENTRES, q)
        sensor.stamp(t, q)
        frame = sensor.deliver(t)
        if frame is not None:
            delivered.append((t, frame))
    return delivered


def test_a_perfect_camera_delivers_every_frame_at_once():
    delivered = drive(CameraFaults(), 1.0)
    assert len(delivered) == 100
    assert all(arrival == frame.time and frame.visible for arrival, frame in delivered)


def test_drops_lose_frames_at_the_given_probability():
    delivered = drive(CameraFaults(drop_probability=0.3), 20.0)
    # 2000 frames, binomial(2000, 0.7): mean 1400, sd 20.5; 5 sd either side.
    assert 1300 < len(delivered) < 1500


def test_occlusion_episodes_hide_the_target_exactly_while_they_last():
    delivered = drive(CameraFaults(occlusion_starts=(0.5, 1.2), occlusion_duration=0.25), 2.0)
    for _, frame in delivered:
        hidden = 0.5 <= frame.time < 0.75 or 1.2 <= frame.time < 1.45
        assert frame.visible is not hidden
        assert bool(np.all(np.isnan(frame.points))) is hidden


def test_random_occlusions_cover_about_rate_times_duration_of_the_time():
    delivered = drive(CameraFaults(occlusion_rate=0.5, occlusion_duration=0.4), 60.0)
    hidden = np.mean([not frame.visible for _, frame in delivered])
    # Poisson episodes of 0.5/s lasting 0.4 s: the fraction covered is 1 - exp(-0.2) = 0.18.
    assert 0.10 < hidden < 0.27


def test_jitter_delays_within_its_bound_and_never_delivers_an_older_frame():
    delivered = drive(CameraFaults(latency_jitter=0.05), 5.0, latency=0.1)
    delays = np.array([arrival - frame.time for arrival, frame in delivered])
    assert np.all(delays >= 0.1 - 1e-9) and np.all(delays <= 0.15 + 1e-9)
    assert np.ptp(delays) > 0.02  # the delays vary
    stamps = [frame.time for _, frame in delivered]
    assert np.all(np.diff(stamps) > 0)


def test_exposure_delay_stamps_the_frame_later_with_the_encoders_of_the_stamp():
    delivered = drive(CameraFaults(exposure_delay=0.03), 1.0, latency=0.02)
    assert delivered[0][1].time == pytest.approx(0.03)
    for arrival, frame in delivered:
        assert arrival == pytest.approx(frame.time + 0.02)
        assert frame.q[0] == pytest.approx(frame.time)  # encoders read at the stamp


def test_a_certain_drop_is_refused_naming_the_key():
    with pytest.raises(ScenarioError, match=r"camera\.drop_probability"):
        load_scenario("experiment1").with_values(**{"camera.drop_probability": 1.0})


def test_smoothing_above_one_is_refused_naming_the_key():
    with pytest.raises(ScenarioError, match=r"estimator\.smoothing"):
        load_scenario("experiment1").with_values(**{"estimator.smoothing": 1.5})
