"""Helpers shared by the controller and closed-loop tests.

Everything here is an *independent reference* written from the paper or from textbook
formulas, without calling the code under test (integration rules, the weighted
pseudo-inverse, the storage function of eq. (7)), or a small scenario built from a shipped
file. Imported by the test modules as ``from simhelpers import ...`` (pytest puts ``tests/``
on ``sys.path``).
"""

from __future__ import annotations

import tomllib
from typing import Any

import numpy as np

from pbvs_pin.sim.scenario import Scenario, load_scenario, parse_scenario, scenario_dir

IMAGE_WIDTH_PX = 628
IMAGE_HEIGHT_PX = 582
"""The paper's camera (628 x 582 px), the shipped scenarios' default."""

TRANSIENT_S = 2.0
"""Initial transient excluded from 'throughout' checks (the paper's figures settle in ~2 s)."""


# ---------------------------------------------------------------- numerical references
def cumulative_trapezoid(values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``int_0^t values dt`` at every sample, trapezoid rule, starting at 0. Shape (k,)."""
    values = np.asarray(values, dtype=float)
    steps = 0.5 * (values[1:] + values[:-1]) * np.diff(t)
    return np.concatenate([[0.0], np.cumsum(steps)])


def trapezoid(values: np.ndarray, t: np.ndarray) -> float:
    """``int values dt`` over the whole run, trapezoid rule."""
    return float(cumulative_trapezoid(values, t)[-1])


def rowwise_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a[i] . b[i]`` for every sample. Shape (k,)."""
    return np.einsum("ij,ij->i", a, b)


def weighted_pinv(jacobian: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """The paper's right pseudo-inverse ``W^-1 J^T (J W^-1 J^T)^-1`` with numpy's ``inv``.

    Args:
        jacobian: ``J``. Shape (r, n).
        weights: ``W``, symmetric positive definite. Shape (n, n).
    """
    w_inv = np.linalg.inv(weights)
    return w_inv @ jacobian.T @ np.linalg.inv(jacobian @ w_inv @ jacobian.T)


def storage_reference(error_units: np.ndarray, k: np.ndarray) -> np.ndarray:
    """``V1`` of eq. (7) for each row of ``error_units``: ``sum k (|e| - ln(1 + |e|))``.

    The antiderivative of ``k eta / (1 + |eta|)`` worked out by hand (the controller module
    has its own; tests compare the two, and this one against quadrature).
    """
    e = np.abs(np.atleast_2d(error_units))
    return np.sum(np.asarray(k) * (e - np.log(1.0 + e)), axis=1)


def random_spd(rng: np.random.Generator, n: int, spread: float = 3.0) -> np.ndarray:
    """A random symmetric positive definite (n, n) matrix with eigenvalues in [1, spread]."""
    basis, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return basis @ np.diag(rng.uniform(1.0, spread, n)) @ basis.T


def feature_error(log: Any) -> np.ndarray:
    """True feature error ``xi - xi_d`` [px] of a run (what the camera would see, no noise)."""
    return log["xi_true"] - log["xi_d"]


# ---------------------------------------------------------------- scenarios
def exact_passivity_scenario(duration: float = 8.0, feedback: str = "transpose") -> Scenario:
    """Experiment 1 shortened, with every model exact and the camera at the control rate.

    Exact target velocity, no pixel noise, no latency, camera, controller and log at 100 Hz,
    so the logged ``nu``, ``passivity_input`` and ``storage`` are samples of the continuous
    signals of eq. (9) at the control instants. ``feedback``: ``controller.feedback``, the
    paper's law unless named.
    """
    return load_scenario("experiment1").with_values(
        **{
            "duration": duration,
            "controller.feedback": feedback,
            "estimator.kind": "exact",
            "camera.noise_px": 0.0,
            "camera.latency": 0.0,
            "camera.rate": 100.0,
            "controller.rate": 100.0,
            "simulation.log_rate": 100.0,
        }
    )


OBSTACLE_ON_PATH = {"kind": "circle", "x": 0.9, "y": 0.1, "radius": 0.12, "height": 0.3}
"""A short cylinder on the platform's path in Experiment 1: without avoidance the platform's
front reaches it after about 6 s (measured: clearance -0.11 m at 6.6 s)."""


def obstacle_scenario(avoidance: bool, duration: float = 9.0) -> Scenario:
    """Experiment 1 shortened, with :data:`OBSTACLE_ON_PATH` and Experiment 2's avoidance gains.

    Built from the shipped TOML (``with_values`` cannot add obstacles), so every value is
    validated by :func:`parse_scenario` as a user's file would be.
    """
    raw = tomllib.loads((scenario_dir() / "experiment1.toml").read_text())
    raw["duration"] = duration
    raw["controller"] = {"k2": [1.0, 1.0, 2.0, 2.0, 2.0]}  # Experiment 2's slopes
    raw["secondary"] = {"obstacle_avoidance": avoidance, "d0": 1.2}
    raw["obstacles"] = [dict(OBSTACLE_ON_PATH)]
    return parse_scenario(raw, f"experiment1+obstacle(avoidance={avoidance})")


def controller_with_first_frame(scenario: Scenario, modular: bool = False):
    """A run's setup and its public controller, given a frame of the target taken at t = 0.

    The frame is the exact projection (eq. 2) of the true sphere centres from the start.

    Args:
        scenario: The scenario.
        modular: Step the modular classes instead of the compiled step
            (:func:`step_modular_reference`).
    """
    from pbvs_pin import CameraFrame
    from pbvs_pin.sim.setup import build

    setup = build(scenario)
    control = setup.control
    if modular:
        step_modular_reference(control)
    q = setup.plant.q
    points, depths = setup.model.camera.project_world(
        setup.model.camera_pose(q), setup.target.centres(0.0)
    )
    frame = CameraFrame.seen(0.0, points, depths)
    control.step(0.0, q, np.zeros(setup.model.n), frame, target_velocity=np.zeros(3))
    return setup, control


def step_modular_reference(control) -> None:
    """Make ``control`` step the modular classes in place of its compiled step.

    The reference composition of the control step, one class per equation: the tracker's
    NumPy prediction (``TargetTracker.current``), the objectives' ``contribution`` (eq. 16,
    each with its own state), ``PassivityController.step`` (eq. 34, with the support's
    barrier) and ``DynamicCompensator.step`` (eq. 20, its own derivative filter). With nothing to servo on
    the command is zero and the derivative restarts from zero, as the controller documents.
    ``control.diagnostics()`` then gives the reference's output; ``control.reference`` is True.
    """
    from pbvs_pin.control.balanced import joint_room
    from pbvs_pin.control.secondary import secondary_input, secondary_vector
    from pbvs_pin.control.support import KeepSupported
    from pbvs_pin.control.upright import upright_row

    model, last = control.model, {}
    limits = model.arm_position_limits()

    def command(t, q, v, velocity, dt):
        measurement = control.tracker.current(t, q, velocity)
        compensator = control.compensator
        camera_jacobian = model.camera_jacobian_unchecked(q)
        rotation = model.data.oMf[model.camera_frame_id].rotation
        state = secondary_input(model, q, control.laser, dt, rotation)
        secondary = secondary_vector(control.objectives, state, model.n_base, model.n)
        if measurement is None:
            last["output"] = control.law.zero_output(control.features.size), None
            compensator.u_dot[:] = 0.0
            compensator.has_previous = False
            v_ref, v2 = compensator.step(q, v, np.zeros(model.n), dt)
            compensator.has_previous = False
            return np.zeros(model.n), v_ref, v2, np.full(control.features.size, np.nan), False
        xi, jacobian, object_jacobian = control.features.jacobians_from_measurement(
            model.camera, measurement, camera_jacobian, rotation.T
        )
        room = joint_room(state.arm_positions, *limits, model.n_base, model.n)
        supports = [o for o in control.objectives if isinstance(o, KeepSupported)]
        barrier = supports[0].barrier(q, model.n) if supports else None
        output = control.law.step(
            xi - control.xi_d, jacobian, object_jacobian, velocity, secondary,
            upright_row(rotation, camera_jacobian), room, barrier,
        )  # fmt: skip
        last["output"] = output, (jacobian, object_jacobian)
        v_ref, v2 = compensator.step(q, v, output.u, dt)
        return output.u, v_ref, v2, output.error, True

    control._command = command
    control.diagnostics = lambda: last["output"]
    control.reference = True


def past_the_margin(robot, margin: float, past: float) -> np.ndarray:
    """The robot's home with its shoulder lift (second arm joint) turned, 0.005 rad at a time,
    until the centre of mass is ``past`` [m] past the support's ``margin`` [m]."""
    from pbvs_pin.model.support import SupportRows, at_origin

    q = robot.home()
    joint = robot.arm_q_indices[1]
    rows = SupportRows(robot, robot.support, margin)
    for _ in range(400):
        if rows.slack(at_origin(q))[0].min() < -past:
            return q
        q[joint] += 0.005 * np.sign(robot.home()[joint] or -1.0)
    raise AssertionError("no posture past the margin")
