"""The encoder history against a plain list of every reading, searched linearly."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import pbvs_pin
from pbvs_pin.control.encoders import TIME_TOLERANCE, EncoderHistory


def _reference(held: list[tuple[float, np.ndarray]], model: pin.Model, t: float):
    """The configuration at ``t`` from the readings held, oldest first; None if not covered."""
    times = [time for time, _ in held]
    if not times[0] - TIME_TOLERANCE <= t <= times[-1] + TIME_TOLERANCE:
        return None
    after = next(i for i, time in enumerate(times) if time >= t - TIME_TOLERANCE)
    if abs(times[after] - t) <= TIME_TOLERANCE:
        return held[after][1]
    if after == 0:
        return None
    (t0, q0), (t1, q1) = held[after - 1], held[after]
    return pin.interpolate(model, q0, q1, (t - t0) / (t1 - t0))


@pytest.mark.parametrize("seed", range(4))
def test_the_ring_buffer_returns_what_a_list_of_every_reading_gives(seed):
    """Before and after the ring wraps, at and between readings, and outside the span."""
    model = pbvs_pin.load_robot("pioneer_cyton").model
    rng = np.random.default_rng(seed)
    for _ in range(25):
        history = EncoderHistory(model, rng.uniform(0.003, 0.04), 0.001)
        times = np.cumsum(rng.uniform(0.0005, 0.002, rng.integers(1, 80)))
        readings = [(t, pin.integrate(model, pin.neutral(model), rng.normal(size=model.nv)))
                    for t in times]  # fmt: skip
        for t, q in readings:
            history.record(t, q)
        held = readings[-history.times.size :]
        probes = [*rng.uniform(times[0] - 0.01, times[-1] + 0.01, 12), held[0][0], held[-1][0]]
        for t in probes:
            expected, got = _reference(held, model, t), history.at(t)
            assert (got is None) == (expected is None), (t, held[0][0], held[-1][0])
            if expected is not None:
                assert np.array_equal(got, expected)
        assert history.oldest_time == held[0][0]
        assert history.newest_time == held[-1][0]
