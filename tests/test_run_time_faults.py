"""The controller at run time under injected faults (issue 31 items 1, 2 and 5).

A closed loop of public names only: the controller's ``v_ref`` is tracked exactly (the model's
own integration), a pinhole camera written in conftest (eq. 2) sees a still target at 30 Hz
with no latency. Into this loop a seeded fuzz injects one fault at a time, of
:data:`FAULTS`' kinds (frames, laser, ``q``, ``v``, ``t``, the target velocity), on the
reference robot and on TIAGo Pro's holonomic base. Each faulty step either raises the
project's error in one line or gives a finite command within the velocity limits; the normal
steps after it never raise, give finite limited commands at once, and servo the error back
below :data:`ERROR_BOUND`. ``PBVS_FUZZ_EXAMPLES`` multiplies the number of faults (1 in CI:
2 200 faults of 48 kinds; e.g. 20 for a nightly run), ``PBVS_FUZZ_SEED`` replaces the fixed
seed.
"""

from __future__ import annotations

import copy
import io
import math
import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import project_world
from scipy.stats import chi2

import pbvs_pin
from pbvs_pin import CameraFrame, Controller
from pbvs_pin.compile_cache import announce_compiles, cached_kernels
from pbvs_pin.control.gating import RESTART_AFTER, FaultCounts, InnovationGate
from pbvs_pin.control.step import fused_control_step
from pbvs_pin.exceptions import WrongType
from pbvs_pin.study.experiments import with_robot

SCALE = max(1, int(os.environ.get("PBVS_FUZZ_EXAMPLES", "1")))
"""Multiplier of the number of faults (see the module docstring)."""
SEED = int(os.environ.get("PBVS_FUZZ_SEED", "31"))
FAULTS_PER_ROBOT = 1100
RECOVERY_STEPS = 9
"""Normal steps after each fault (three frames) before the error is checked."""
ERROR_BOUND = 30.0
"""Largest ``|xi - xi_d|`` [px] after a fault's recovery steps (the loop settles below 1 px;
a fault that passes as a plausible frame moves the robot for a moment)."""
RESETTLE_EVERY = 50
"""Faults after which the loop starts again from its settled state (faults that passed as
plausible frames add up otherwise)."""
PERIOD = 0.01  # [s] the controller's 100 Hz
FRAME_EVERY = 3  # control steps per frame: 33 Hz
ROBOTS = Path(__file__).resolve().parents[1] / "robots"


def _controller(robot_name: str, noise_px: float = 0.5) -> Controller:
    """Experiment 1's controller with obstacle avoidance (the laser's faults reach it)."""
    scenario = pbvs_pin.load_scenario("experiment1").with_values(
        **{"camera.noise_px": noise_px, "secondary.obstacle_avoidance": True}
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # placement warnings of the zoo's robot file
        if robot_name != "pioneer_cyton":
            scenario = with_robot(scenario, str(ROBOTS / f"{robot_name}.toml"))
        return Controller.from_scenario(scenario, announce=False)


class Loop:
    """Exact velocity tracking, a still target, an ideal camera and a laser around a controller.

    The laser sees nothing (``inf``) and reads with every frame.

    The target's two centres are placed where the camera at home sees ``xi_d`` plus
    ``offset`` [px] (the pinhole of eq. 2 inverted, separation 0.1 m).
    """

    def __init__(self, controller: Controller, offset: float = 20.0) -> None:
        self.controller, self.robot = controller, controller.model
        self.focal = self.robot.camera.focal_px
        self.q, self.v, self.t, self.steps = self.robot.home(), np.zeros(self.robot.n), 0.0, 0
        xi = controller.xi_d + np.array([offset, 0.0, 0.0])
        z = self.focal * 0.1 / (xi[1] - xi[2])
        pose = self.robot.camera_pose(self.q)
        self.centres = [
            pose.act(np.array([-xi[0] * z / self.focal, -v * z / self.focal, z])) for v in xi[1:]
        ]
        self.limits = np.asarray(self.robot.velocity_limits)

    def frame(self, t: float) -> CameraFrame:
        """What the ideal camera at the loop's ``q`` sees at ``t``."""
        pose = self.robot.camera_pose(self.q)
        points = np.array([project_world(self.focal, pose, c) for c in self.centres])
        depths = np.array([(pose.rotation.T @ (c - pose.translation))[2] for c in self.centres])
        return CameraFrame.seen(t, points, depths)

    def inputs(self) -> dict:
        """The next normal step's arguments."""
        t = self.t + PERIOD
        due = self.steps % FRAME_EVERY == 0
        frame, laser = (self.frame(t), (math.inf, 0.0)) if due else (None, None)
        return {"t": t, "q": self.q.copy(), "v": self.v.copy(), "frame": frame, "laser": laser}

    def apply(self, inputs: dict, command) -> None:
        """Advance the plant by one step of ``command`` (the step at ``inputs['t']`` ran)."""
        self.t = max(self.t + PERIOD, float(inputs["t"])) if _is_number(inputs["t"]) else self.t
        self.v = command.v_ref.copy()
        self.q = self.robot.integrate(self.q, self.v, PERIOD)
        self.steps += 1

    def normal_step(self):
        """One fault-free step: it must not raise and must give a finite, limited command."""
        inputs = self.inputs()
        command = self.controller.step(**inputs)
        self.check(command)
        self.apply(inputs, command)
        return command

    def check(self, command) -> None:
        """A finite command within the velocity limits, and bounded internal state."""
        assert np.isfinite(command.v_ref).all() and np.isfinite(command.u).all()
        assert np.all(np.abs(command.v_ref) <= self.limits + 1e-12)
        assert np.linalg.norm(command.target_velocity) <= 10.0 + 1e-9
        assert np.all(np.abs(self.controller.fused.views.impedance_velocity) < 1e3)


def _is_number(value) -> bool:
    return isinstance(value, float | int) and not isinstance(value, bool) and math.isfinite(value)


def _frame_points(loop: Loop, t: float, change) -> CameraFrame:
    """The ideal frame at ``t`` with its points and depths changed by ``change``."""
    good = loop.frame(t)
    points, depths = change(good.points.copy(), good.depths.copy())
    return CameraFrame.seen(t, points, depths)


def _set(array: np.ndarray, index, value) -> np.ndarray:
    array[index] = value
    return array


# name -> function(loop, inputs, rng) that changes one step's arguments (in place)
FAULTS = {
    # frames: impossible values, outliers, timing, types
    "point 1e300": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (_set(p, (0, 0), 1e300), d))),
    "point 1e4 px off": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (_set(p, (1, 1), p[1, 1] + 1e4), d))),
    "points at 1e6 px": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (p + 1e6, d))),
    "point outside the image": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (_set(p, (0, 0), r.choice([-1, 1]) * 3000.0), d))),
    "points 250 px off": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (p + r.choice([-250.0, 250.0]), d))),
    "random points": lambda lp, a, r: a.update(frame=CameraFrame.seen(a["t"], r.uniform(-300, 300, (2, 2)), r.uniform(0.1, 5.0, 2))),
    "depth 1e300": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (p, _set(d, 0, 1e300)))),
    "depth 1e-300": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (p, _set(d, 1, 1e-300)))),
    "depth negative": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (p, -d))),
    "depth ten times": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (p, 10 * d))),
    "depth NaN": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (p, _set(d, 0, np.nan)))),
    "point NaN": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (_set(p, (1, 0), np.nan), d))),
    "point inf": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (_set(p, (0, 1), -np.inf), d))),
    "points equal": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (p[[0, 0]], d[[0, 0]]))),
    "points swapped": lambda lp, a, r: a.update(frame=_frame_points(lp, a["t"], lambda p, d: (p[::-1].copy(), d[::-1].copy()))),
    "three points": lambda lp, a, r: a.update(frame=CameraFrame.seen(a["t"], np.zeros((3, 2)), np.ones(3))),
    "not a frame": lambda lp, a, r: a.update(frame=(a["t"], None)),
    "not visible": lambda lp, a, r: a.update(frame=CameraFrame.not_visible(a["t"])),
    "stamped 1 us late": lambda lp, a, r: a.update(frame=lp.frame(a["t"] + 1e-6)),
    "stamped in the future": lambda lp, a, r: a.update(frame=lp.frame(a["t"] + r.uniform(0.01, 1e6))),
    "stamped -1e300": lambda lp, a, r: a.update(frame=lp.frame(-1e300)),
    "stamped again": lambda lp, a, r: a.update(frame=lp.frame(a["t"] - PERIOD * FRAME_EVERY)),
    # laser
    "laser -1e308": lambda lp, a, r: a.update(laser=(-1e308, 0.1)),
    "laser 1e300": lambda lp, a, r: a.update(laser=(1e300, 0.1)),
    "laser -inf": lambda lp, a, r: a.update(laser=(-np.inf, 0.0)),
    "laser NaN": lambda lp, a, r: a.update(laser=(np.nan, 0.0)),
    "laser bearing 1e300": lambda lp, a, r: a.update(laser=(0.2, 1e300)),
    "laser touching": lambda lp, a, r: a.update(laser=(0.0, r.uniform(-np.pi, np.pi))),
    "laser text": lambda lp, a, r: a.update(laser=("near", 0.0)),
    # measured velocity
    "v 1e155": lambda lp, a, r: a.update(v=_set(a["v"], r.integers(len(a["v"])), 1e155)),
    "v -1e300": lambda lp, a, r: a.update(v=_set(a["v"], 0, -1e300)),
    "v NaN": lambda lp, a, r: a.update(v=_set(a["v"], -1, np.nan)),
    "v list of ints": lambda lp, a, r: a.update(v=[0] * len(a["v"])),
    "v float32 read-only": lambda lp, a, r: a.update(v=_read_only(a["v"].astype(np.float32))),
    "v too short": lambda lp, a, r: a.update(v=a["v"][:-1]),
    # configuration
    "q 1e300": lambda lp, a, r: a.update(q=_set(a["q"], -1, 1e300)),
    "q odometry 1e7 m": lambda lp, a, r: a.update(q=_set(a["q"], 0, 1e7)),
    "q NaN": lambda lp, a, r: a.update(q=_set(a["q"], 1, np.nan)),
    "q angle not unit": lambda lp, a, r: a.update(q=_set(a["q"], 2, 3.0)),
    "q odometry jump": lambda lp, a, r: a.update(q=_set(a["q"], 0, a["q"][0] + 1.0)),
    "q non-contiguous": lambda lp, a, r: a.update(q=np.repeat(a["q"], 2)[::2]),
    # time
    "t text": lambda lp, a, r: a.update(t=str(a["t"])),
    "t NaN": lambda lp, a, r: a.update(t=np.nan),
    "t backwards": lambda lp, a, r: a.update(t=a["t"] - 2 * PERIOD),
    "t +1e300": lambda lp, a, r: a.update(t=1e300),
    "t 1 ns step": lambda lp, a, r: a.update(t=lp.t + 1e-9),
    # target velocity given
    "target velocity 1e300": lambda lp, a, r: a.update(target_velocity=[1e300, 0.0, 0.0]),
    "target velocity NaN": lambda lp, a, r: a.update(target_velocity=[0.0, np.nan, 0.0]),
}  # fmt: skip


def _read_only(value: np.ndarray) -> np.ndarray:
    value = np.array(value)
    value.flags.writeable = False
    return value


@pytest.fixture(scope="module", params=["pioneer_cyton", "tiago_pro"])
def settled(request) -> Loop:
    """A loop settled on its target for 2 s."""
    loop = Loop(_controller(request.param))
    for _ in range(200):
        loop.normal_step()
    return loop


def test_every_fault_is_refused_or_safe_and_the_loop_recovers(settled):
    """Seeded faults, one at a time: the project's error or a safe command; then recovery."""
    rng = np.random.default_rng([SEED, settled.robot.n])
    names = sorted(FAULTS)
    seen_kinds = set()
    for case in range(FAULTS_PER_ROBOT * SCALE):
        if case % RESETTLE_EVERY == 0:
            loop = copy.deepcopy(settled)
        name = names[rng.integers(len(names))]
        inputs = loop.inputs()
        FAULTS[name](loop, inputs, rng)
        try:
            command = loop.controller.step(**inputs)
        except pbvs_pin.PbvsError as err:
            assert "\n" not in str(err), (name, str(err))
            loop.normal_step()  # the same step, now normal: the controller was left as it was
        else:
            loop.check(command)
            loop.apply(inputs, command)
        seen_kinds.add(name)
        for _ in range(RECOVERY_STEPS):
            command = loop.normal_step()
        assert command.seen, name
        assert np.abs(command.error).max() < ERROR_BOUND, (name, command.error)
    assert len(seen_kinds) >= 25


def test_the_faults_are_counted(settled):
    """Outliers and impossible frames and ranges are counted where the controller says so."""
    loop = copy.deepcopy(settled)
    for name, count in (("points 250 px off", "frames_gated"), ("points at 1e6 px",
                        "frames_out_of_bounds"), ("laser -1e308", "laser_dropped"),
                        ("stamped 1 us late", "clock_jitter")):  # fmt: skip
        while loop.steps % FRAME_EVERY:
            loop.normal_step()
        before = getattr(loop.controller.counts, count)
        inputs = loop.inputs()
        FAULTS[name](loop, inputs, np.random.default_rng(0))
        command = loop.controller.step(**inputs)
        loop.apply(inputs, command)
        assert getattr(loop.controller.counts, count) == before + 1, name
        if count != "clock_jitter":
            assert command.rejected, name
    assert loop.controller.counts.restarts == 0


def test_an_impossible_laser_range_leaves_the_obstacle_impedance_at_rest(settled):
    """A range of -1e308 m is dropped: the impedance of eq. (17) stays at rest (it was driven
    to 4e304 by the reading before)."""
    loop = copy.deepcopy(settled)
    impedance = loop.controller.fused.views.impedance_velocity
    np.testing.assert_array_equal(impedance, 0.0)  # nothing seen so far
    for laser in ((-1e308, 0.1), (0.2, 1e300), (1e300, 0.0)):
        inputs = loop.inputs()
        inputs["laser"] = laser
        command = loop.controller.step(**inputs)
        loop.apply(inputs, command)
        assert "laser" in command.rejected
        np.testing.assert_array_equal(impedance, 0.0)
    assert loop.controller.counts.laser_dropped == 3
    inputs = loop.inputs()
    inputs["laser"] = (0.2, 0.1)  # a real obstacle 0.2 m ahead, within d0: the impedance moves
    loop.controller.step(**inputs)
    assert 0.0 < np.abs(impedance).max() < 1.0


@pytest.mark.parametrize(
    "name, frames",
    [("point 1e300", 1), ("point 1e4 px off", 1), ("points at 1e6 px", 100),
     ("point outside the image", 100), ("random points", 1)],
)  # fmt: skip
def test_after_bad_frames_the_target_is_tracked_again_within_2_s(settled, name, frames):
    """Bad frames for up to 3 s, then good ones: tracked within 2 s, the estimate bounded."""
    loop = copy.deepcopy(settled)
    rng = np.random.default_rng(5)
    sent = 0
    while sent < frames:
        inputs = loop.inputs()
        if inputs["frame"] is not None:
            FAULTS[name](loop, inputs, rng)
            sent += 1
        command = loop.controller.step(**inputs)
        loop.check(command)
        loop.apply(inputs, command)
    errors = [np.abs(loop.normal_step().error).max() for _ in range(200)]
    assert max(errors[-20:]) < 2.0  # the settled loop's error, tracked again
    assert np.linalg.norm(loop.controller.tracker.estimator.velocity) < 0.05


def test_a_target_that_really_jumped_is_acquired_again(settled):
    """The target moves 0.12 m at once: the first frames fail the gate, then it is tracked."""
    loop = copy.deepcopy(settled)
    counts = loop.controller.counts
    loop.centres = [c + np.array([0.0, 0.12, 0.0]) for c in loop.centres]
    for _ in range(200):
        loop.normal_step()
    assert 1 <= counts.frames_gated + counts.restarts <= RESTART_AFTER
    assert np.abs(loop.normal_step().error).max() < 5.0  # from 145 px


def test_rejections_in_a_row_restart_the_estimate():
    """RESTART_AFTER rejections in a row: the last is used and restarts; a pass ends a run."""
    counts = FaultCounts()
    gate = InnovationGate(0.5, 600.0, 0.05, 2, counts)
    far, near = 10 * gate.threshold, 0.1 * gate.threshold
    assert [gate.verdict(far) for _ in range(RESTART_AFTER)] == [(False, False)] * (
        RESTART_AFTER - 1
    ) + [(True, True)]
    assert gate.verdict(far) == (False, False) and gate.verdict(near) == (True, False)
    assert gate.verdict(far) == (False, False)  # the pass ended the run: no restart yet
    assert counts.frames_gated == RESTART_AFTER + 1 and counts.restarts == 1


def test_the_gate_keeps_every_noisy_frame_at_4_px():
    """4 px of Gaussian noise on points and apparent diameters: 1 500 frames, none gated."""
    loop = Loop(_controller("pioneer_cyton", noise_px=4.0), offset=0.0)
    rng = np.random.default_rng(3)
    size = loop.focal * 0.05  # f D [px m], the experiments' spheres

    exact = loop.frame

    def noisy(t):
        frame = exact(t)
        diameters = size / frame.depths + rng.normal(0.0, 4.0, 2)
        return CameraFrame.seen(t, frame.points + rng.normal(0.0, 4.0, (2, 2)), size / diameters)

    loop.frame = noisy
    for _ in range(1500 * FRAME_EVERY):
        loop.normal_step()
    assert loop.controller.counts.frames_gated == 0 and loop.controller.counts.restarts == 0


@pytest.mark.parametrize("noise_px", [0.5, 4.0])
def test_the_gate_is_the_stated_chi_square_test(noise_px):
    """A frame displaced by ``d`` px one 30 Hz frame after the last passes iff
    ``d^2 / (2 s_n^2 + s_p^2) <= chi2_6(1 - 1e-6)`` (docs/controller.rst, control.gating)."""
    age, depth = 1.0 / 30.0, 0.5
    sigma_p = 5.0 + 600.0 / depth * (0.2 * age + 0.5 * 2.0 * age**2)
    radius = math.sqrt(chi2.isf(1e-6, 6) * (2 * noise_px**2 + sigma_p**2))
    for displacement, passes in ((0.98 * radius, True), (1.02 * radius, False)):
        loop = Loop(_controller("pioneer_cyton", noise_px=noise_px), offset=0.0)
        loop.controller.step(0.0, loop.q, loop.v, loop.frame(0.0))
        shifted = loop.frame(age)
        depths = shifted.depths
        frame = CameraFrame.seen(
            age, shifted.points + np.array([[displacement, 0.0], [0.0, 0.0]]), depths
        )
        command = loop.controller.step(age, loop.q, loop.v, frame)
        assert (command.rejected == "") == passes, (displacement, radius, command.rejected)


# ---------------------------------------------------------------- one conversion at the door
def _signatures() -> int:
    """Compiled specialisations of every imported package kernel and the fused step."""
    return sum(len(kernel.signatures) for kernel in cached_kernels()) + len(
        fused_control_step.signatures
    )


def test_every_kind_of_array_is_converted_once_and_compiles_nothing(settled):
    """Lists, ints, float32, read-only and non-contiguous arrays: the same command as float64
    arrays, and no new compiled specialisation of any kernel."""
    before = _signatures()
    reference, converted = copy.deepcopy(settled), copy.deepcopy(settled)
    for kind in ("list", "int", "float32", "read-only", "non-contiguous"):
        inputs = reference.inputs()
        frame, q, v = inputs["frame"], inputs["q"], inputs["v"]
        if frame is None:
            frame = reference.frame(inputs["t"])
            inputs["frame"] = frame
        change = {
            "list": lambda x: x.tolist(),
            "int": lambda x: np.round(x).astype(int) if x.ndim == 2 else x,  # points only
            "float32": lambda x: x.astype(np.float32).astype(np.float64) * 0 + x.astype(np.float32),
            "read-only": _read_only,
            "non-contiguous": lambda x: np.repeat(x, 2, axis=0)[::2],
        }[kind]
        if kind == "int":
            frame = CameraFrame.seen(frame.capture_time, np.round(frame.points), frame.depths)
            inputs["frame"] = frame
        expected = reference.controller.step(**inputs)
        given = {**inputs, "q": change(q) if kind != "int" else q, "v": change(v),
                 "frame": CameraFrame.seen(frame.capture_time, change(frame.points), change(frame.depths)),
                 "laser": change(np.array([2.0, 0.1])), "t": inputs["t"]}  # fmt: skip
        if kind == "float32":  # float32 rounds: compare with the rounded values
            given["q"], given["v"] = q, v
            given["frame"] = frame
        command = converted.controller.step(**given)
        np.testing.assert_allclose(command.v_ref, expected.v_ref, rtol=0, atol=1e-12, err_msg=kind)
        reference.apply(inputs, expected)
        converted.apply(inputs, command)
    assert _signatures() == before


@pytest.mark.parametrize("kind", ["float32", "int", "read-only", "non-contiguous", "list"])
def test_a_configuration_of_any_dtype_or_layout_compiles_nothing(settled, kind):
    """``q`` itself as float32, int, read-only, strided or a list (the test above keeps its
    float64 values to compare commands): converted at the door, no kernel specialises."""
    loop = copy.deepcopy(settled)
    before = _signatures()
    inputs = loop.inputs()
    inputs["q"] = {
        "float32": lambda x: x.astype(np.float32),
        "int": lambda x: np.round(x).astype(np.int64),  # (cos, sin) rounds to a unit pair
        "read-only": _read_only,
        "non-contiguous": lambda x: np.repeat(x, 2)[::2],
        "list": lambda x: x.tolist(),
    }[kind](inputs["q"])
    command = loop.controller.step(**inputs)
    assert np.isfinite(command.v_ref).all()
    assert _signatures() == before, f"a {kind} q compiled a new specialisation"


@pytest.mark.parametrize("t", ["1.0", b"1.0", True, None, [1.0], object()])
def test_a_time_that_is_not_a_number_is_refused(settled, t):
    loop = copy.deepcopy(settled)
    with pytest.raises((WrongType, pbvs_pin.ShapeError)) as raised:
        loop.controller.step(t, loop.q, loop.v)
    assert "t" in str(raised.value)
    loop.normal_step()


def test_a_frame_stamped_within_the_clock_jitter_is_used(settled):
    loop = copy.deepcopy(settled)
    while loop.steps % FRAME_EVERY:
        loop.normal_step()
    t = loop.t + PERIOD
    command = loop.controller.step(t, loop.q, loop.v, loop.frame(t + 0.004))
    assert command.rejected == "" and command.seen and loop.controller.counts.clock_jitter == 1
    with pytest.raises(pbvs_pin.ControlInputError, match="after now"):
        loop.controller.step(t + PERIOD, loop.q, loop.v, loop.frame(t + PERIOD + 0.006))


def test_a_deep_copy_steps_as_the_original(settled):
    """The copy's compiled step writes into the copy's buffers: the same commands, step by step."""
    original = copy.deepcopy(settled)
    twin = copy.deepcopy(original)
    for _ in range(10):
        inputs = original.inputs()
        inputs["v"] = inputs["v"] + 0.05  # a command that differs from the previous step's
        a, b = original.controller.step(**inputs), twin.controller.step(**inputs)
        np.testing.assert_array_equal(a.v_ref, b.v_ref)
        assert not np.shares_memory(original.controller.fused.state, twin.controller.fused.state)
        original.apply(inputs, a)
        twin.apply(inputs, b)


def test_the_compile_notice_only_when_a_kernel_compiles(settled):
    from numba import njit

    def probe(x):
        return x + 1.0

    probe.__module__ = "pbvs_pin.probe"  # a package kernel that no cache holds

    quiet = io.StringIO()
    with announce_compiles(stream=quiet) as announcer:
        _controller("pioneer_cyton")  # its kernels are compiled in this process already
    assert quiet.getvalue() == "" and announcer.compiled == 0
    loud = io.StringIO()
    with announce_compiles(stream=loud) as announcer:
        njit(probe)(1.0)
    assert loud.getvalue().startswith("compiling the control kernels")
    assert announcer.compiled >= 1


@pytest.mark.parametrize("name", ["point 1e300", "points at 1e6 px", "depth 1e300"])
def test_a_first_frame_beyond_the_bounds_is_dropped(settled, name):
    """With no estimate to gate against (just reset), the bounds alone drop the frame."""
    loop = copy.deepcopy(settled)
    loop.controller.reset()
    while loop.steps % FRAME_EVERY:
        loop.steps += 1
    inputs = loop.inputs()
    FAULTS[name](loop, inputs, np.random.default_rng(0))
    command = loop.controller.step(**inputs)
    loop.apply(inputs, command)
    assert not command.seen and loop.controller.tracker.measurement is None
    assert loop.controller.counts.frames_out_of_bounds == 1 and "dropped" in command.rejected
    for _ in range(FRAME_EVERY):
        command = loop.normal_step()
    assert command.seen


def test_a_run_logs_and_summarises_the_counts():
    """The simulator's log keeps the counts and the summary gives the gated frames."""
    from pbvs_pin.sim.loop import simulate
    from pbvs_pin.sim.metrics import summarize

    log = simulate(pbvs_pin.load_scenario("experiment1").with_values(duration=0.5))
    counts = log.meta["controller_counts"]
    assert set(counts) == {"frames_gated", "restarts", "frames_out_of_bounds", "laser_dropped",
                           "clock_jitter"}  # fmt: skip
    summary = summarize(log)
    assert summary["frames_gated"] == counts["frames_gated"] == 0  # good frames all pass
    assert summary["estimator_restarts"] == 0
