"""Benchmark: the floor of the step and of the loop if compiled code made the Pinocchio calls.

``benchmarks/control_step.py`` shows that, with Pinocchio called from Python, the control step
cannot come within 2.0x of its Pinocchio calls and the loop stays far from 100x real time. This
benchmark measures the other structure, a loop compiled around Pinocchio's C++ API:

1. It builds ``benchmarks/pinocchio_calls.cpp`` against the installed Pinocchio (needs ``g++``
   and Eigen's headers: ``pip install cmeel-eigen``) and checks that its calls give the same
   numbers as the Python calls, on the same ``pin.Model`` and ``pin.Data``.
2. It times the control step's, the plant step's and the prediction's Pinocchio calls made from
   compiled code (a Numba loop calling the C functions: no Python in between) against the same
   calls from Python, interleaved, medians.
3. It times the compiled arithmetic of each kernel the loop runs every millisecond: the control
   step (from ``control_step.py``), the servo step, the sensors' reading and the projection of
   the predicted frame, each from a compiled loop, so that no call from Python is counted.
4. It times, inside a real run of the loop (Experiment 1, 1 kHz controller), the work that
   happens at the camera's and the log's rates rather than every millisecond: capturing a frame
   (with the true camera pose), taking a delivered frame (filter update), recording a log row
   (with the step's diagnostics) and deriving the log's channels at the end.

It prints the ratio the control step would have in a compiled loop; the cost of one simulated
millisecond with nothing but these calls and this arithmetic, the most a loop compiled around
Pinocchio could reach with today's kernels; and what the loop reaches if the events stay in
Python as they are.

Run: ``python benchmarks/compiled_floor.py`` (the first run compiles for about 30 s).
"""

from __future__ import annotations

import ctypes
import hashlib
import importlib.util
import shutil
import statistics
import subprocess
import sys
import sysconfig
import tempfile
import time
from pathlib import Path

import numpy as np
import pinocchio as pin
from control_step import control_step_calls, control_step_ratio, mean_time, plant_step_calls
from numba import njit

from pbvs_pin.control.step import FusedControlStep
from pbvs_pin.control.tracking import TargetTracker
from pbvs_pin.model.camera import project_points
from pbvs_pin.model.servo import packed_servo_step
from pbvs_pin.perception.features import ImageMeasurement
from pbvs_pin.sim.log import RunRecorder
from pbvs_pin.sim.loop import simulate
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.sim.sensing import Sensing, sensing_step
from pbvs_pin.sim.setup import build
from pbvs_pin.sim.vision import CameraSensor

REPEATS = 15
CALLS = 2000
SOURCE = Path(__file__).with_name("pinocchio_calls.cpp")
DEFINITIONS = (  # the INTERFACE_COMPILE_DEFINITIONS of Pinocchio's installed CMake targets
    "BOOST_MPL_LIMIT_LIST_SIZE=30",
    "BOOST_MPL_LIMIT_VECTOR_SIZE=30",
    "BOOST_MPL_CFG_NO_PREPROCESSED_HEADERS",
    "BOOST_FUSION_INVOKE_MAX_ARITY=12",
    "PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION",
)
POINTER = ctypes.c_void_p
CONTROL = ctypes.CFUNCTYPE(None, POINTER, POINTER, ctypes.c_long, POINTER, POINTER, POINTER)
PLANT = ctypes.CFUNCTYPE(None, POINTER, POINTER, POINTER, POINTER, POINTER, POINTER)
PLACEMENT = ctypes.CFUNCTYPE(None, POINTER, POINTER, ctypes.c_long, POINTER, POINTER, POINTER)


def load_module():
    """The compiled ``pinocchio_calls`` module, built once per source and Pinocchio version."""
    prefix = Path(pin.__file__).parents[4]  # cmeel.prefix
    eigen = prefix / "include" / "eigen3"
    if shutil.which("g++") is None:
        sys.exit("compiled_floor.py needs a C++ compiler: g++ was not found")
    if not (eigen / "Eigen").is_dir():
        sys.exit(f"compiled_floor.py needs Eigen's headers in {eigen}: pip install cmeel-eigen")
    key = hashlib.sha256(SOURCE.read_bytes() + pin.__version__.encode()).hexdigest()[:12]
    output = Path(tempfile.gettempdir()) / f"pbvs_pin_calls_{key}"
    library = output / f"pinocchio_calls{sysconfig.get_config_var('EXT_SUFFIX')}"
    if not library.exists():
        output.mkdir(exist_ok=True)
        print(f"compiling {SOURCE.name} against Pinocchio {pin.__version__} ...", flush=True)
        version = f"{sys.version_info.major}{sys.version_info.minor}"
        command = [
            "g++", "-O3", "-DNDEBUG", "-std=c++17", "-shared", "-fPIC",
            "-Wno-deprecated-declarations",
            *(f"-D{definition}" for definition in DEFINITIONS),
            f"-I{prefix / 'include'}", f"-I{eigen}", f"-I{sysconfig.get_paths()['include']}",
            str(SOURCE), "-o", str(library), f"-L{prefix / 'lib'}", "-lpinocchio_default",
            f"-lboost_python{version}", f"-Wl,-rpath,{prefix / 'lib'}",
        ]  # fmt: skip
        subprocess.run(command, check=True)
    spec = importlib.util.spec_from_file_location("pinocchio_calls", library)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def compiled_loops(module):
    """Numba loops that make each group of calls ``calls`` times through the C functions."""
    addresses = module.function_addresses()
    control = CONTROL(addresses["control_calls"])
    plant = PLANT(addresses["plant_calls"])
    placement = PLACEMENT(addresses["camera_placement"])

    @njit
    def control_loop(calls, model, data, frame, q, v_pin, jacobian):
        for _ in range(calls):
            control(model, data, frame, q.ctypes.data, v_pin.ctypes.data, jacobian.ctypes.data)

    @njit
    def plant_loop(calls, model, data, q, v_pin, displacement, q_next):
        for _ in range(calls):
            plant(
                model, data, q.ctypes.data, v_pin.ctypes.data, displacement.ctypes.data,
                q_next.ctypes.data,
            )  # fmt: skip

    @njit
    def placement_loop(calls, model, data, frame, q, rotation, translation):
        for _ in range(calls):
            placement(
                model, data, frame, q.ctypes.data, rotation.ctypes.data, translation.ctypes.data
            )

    return control_loop, plant_loop, placement_loop


@njit
def _kernel_loop(calls, kernel, arguments):
    """Call a compiled kernel ``calls`` times from compiled code."""
    for _ in range(calls):
        kernel(*arguments)


def _loop_time(loop, *arguments) -> float:
    """Mean time of one iteration of a compiled loop of ``CALLS`` iterations [s]."""
    start = time.perf_counter()
    loop(CALLS, *arguments)
    return (time.perf_counter() - start) / CALLS


def _medians(*functions) -> list[float]:
    """Median times of the functions, timed alternately ``REPEATS`` times."""
    for function in functions:
        function()
    rows = [[function() for function in functions] for _ in range(REPEATS)]
    return [statistics.median(row[i] for row in rows) for i in range(len(functions))]


def pinocchio_times(robot_name: str, module, loops) -> dict[str, tuple[float, float]]:
    """Per group of calls: (from Python, from compiled code) [s], after checking equal results."""
    setup = build(load_scenario("experiment1").with_values(**{"robot.name": robot_name}))
    robot = setup.model
    model, data, frame = robot.model, robot.data, robot.camera_frame_id
    addresses = module.model_address(model), module.data_address(data)
    q = setup.plant.q.copy()
    v_pin = robot.selection @ np.full(robot.n, 0.05)
    displacement = v_pin * 1e-3
    jacobian, q_next = np.zeros((6, model.nv)), np.zeros(model.nq)
    rotation, translation = np.zeros((3, 3)), np.zeros(3)
    control_loop, plant_loop, placement_loop = loops

    def python_control() -> None:
        control_step_calls(model, data, frame, q, v_pin)

    def python_plant() -> None:
        plant_step_calls(model, data, q, v_pin, displacement)

    def python_placement() -> None:
        robot.camera_placement(q)

    control_loop(1, *addresses, frame, q, v_pin, jacobian)
    compiled = (jacobian.copy(), np.triu(data.M), data.nle.copy(), data.g.copy())
    python_control()  # the bindings' crba also fills the lower triangle, which the kernels skip
    reference = (
        pin.getFrameJacobian(model, data, frame, pin.LOCAL),
        np.triu(data.M),
        data.nle,
        data.g,
    )
    plant_loop(1, *addresses, q, v_pin, displacement, q_next)
    placement_loop(1, *addresses, frame, q, rotation, translation)
    placement = robot.camera_placement(q)
    differences = [np.max(np.abs(a - b)) for a, b in zip(compiled, reference, strict=True)]
    differences += [
        np.max(np.abs(q_next - pin.integrate(model, q, displacement))),
        np.max(np.abs(rotation - placement.rotation)),
        np.max(np.abs(translation - placement.translation)),
    ]
    if max(differences) > 1e-12:
        sys.exit(f"the compiled calls differ from Python's by {max(differences):.3g}")
    times = _medians(
        lambda: mean_time(python_control, CALLS),
        lambda: _loop_time(control_loop, *addresses, frame, q, v_pin, jacobian),
        lambda: mean_time(python_plant, CALLS),
        lambda: _loop_time(plant_loop, *addresses, q, v_pin, displacement, q_next),
        lambda: mean_time(python_placement, CALLS),
        lambda: _loop_time(placement_loop, *addresses, frame, q, rotation, translation),
    )
    names = ("control", "plant", "placement")
    return {name: (times[2 * i], times[2 * i + 1]) for i, name in enumerate(names)}


def kernel_arithmetic() -> dict[str, float]:
    """Time [s] of one call of each per-millisecond kernel from compiled code, reference robot.

    The servo step (:func:`~pbvs_pin.model.servo.packed_servo_step`) on a moving plant, the sensors'
    reading (:func:`~pbvs_pin.sim.sensing.sensing_step`) and the projection of the predicted
    frame (:func:`~pbvs_pin.model.camera.project_points`), on the arguments the loop gives them.
    """
    setup = build(load_scenario("experiment1"))
    plant = setup.plant
    for _ in range(20):
        plant.step(np.full(setup.robot.n, 0.1))
    model, data, q = plant.robot.model, plant.robot.data, plant.q.copy()
    mass = pin.crba(model, data, q).copy()
    bias = pin.nonLinearEffects(model, data, q, plant.robot.selection @ plant.v).copy()
    gravity = pin.computeGeneralizedGravity(model, data, q).copy()
    nv = model.nv
    servo = (
        mass, mass, bias, gravity, plant._params, plant._indices, q, plant.v.copy(),
        np.full(setup.robot.n, 0.1), plant.integral.copy(), np.zeros(nv), np.zeros(nv),
    )  # fmt: skip
    sensing = Sensing(setup)
    sensing.read(0.0)
    reading = (
        q, plant.v, plant.wheel_angles, 1e-3, sensing._noise, sensing._gyro_draws, 0,
        sensing._joints, sensing._arm, sensing._constants, sensing._state.copy(),
        sensing._odometry_state.copy(), np.empty(q.shape[0]), np.empty(setup.robot.n),
    )  # fmt: skip
    tracker = setup.control.tracker
    placement = setup.model.camera_pose(q)
    points, depths = setup.model.camera.project_world(placement, setup.target.centres(0.0))
    tracker.take(ImageMeasurement(points, depths), 0.0, q, np.zeros(3))
    pose = setup.model.camera_placement(q)
    projection = (
        tracker.world, pose.translation.copy(), pose.rotation.copy(),
        setup.model.camera.focal_px, 0.0,
    )  # fmt: skip
    kernels = {"servo": (packed_servo_step, servo), "sensing": (sensing_step, reading)}
    kernels["projection"] = (project_points, projection)
    times = _medians(
        *(
            lambda kernel=kernel, arguments=arguments: _loop_time(_kernel_loop, kernel, arguments)
            for kernel, arguments in kernels.values()
        )
    )
    return dict(zip(kernels, times, strict=True))


EVENTS = {
    "camera: capture a frame (true camera pose, projection, noise)": (CameraSensor, "capture"),
    "camera: take a delivered frame (back-projection, filter)": (TargetTracker, "take"),
    "log: the step's diagnostics": (FusedControlStep, "output"),
    "log: record a row": (RunRecorder, "record"),
    "log: derive the channels at the end": (RunRecorder, "finish"),
}
"""The loop's work at the camera's and the log's rates: (class, method) timed in a real run."""


def event_costs(duration: float = 10.0, repeats: int = 3) -> dict[str, float]:
    """Time [s] per simulated second of each of :data:`EVENTS`, in a run of the loop.

    Each method is wrapped in a timer for the run (a wrapper costs well under 1 us a call,
    these calls tens of us). Medians over ``repeats`` runs of Experiment 1 on the reference
    robot, 1 kHz controller, after a run that compiles the kernels.
    """
    scenario = load_scenario("experiment1").with_values(
        **{"controller.rate": 1000.0, "duration": duration}
    )
    simulate(scenario.with_values(duration=0.1))
    runs = []
    for _ in range(repeats):
        spent = dict.fromkeys(EVENTS, 0.0)
        originals = {label: getattr(owner, name) for label, (owner, name) in EVENTS.items()}

        def timed(label, original, spent=spent):
            def wrapper(*args, **kwargs):
                start = time.perf_counter()
                result = original(*args, **kwargs)
                spent[label] += time.perf_counter() - start
                return result

            return wrapper

        for label, (owner, name) in EVENTS.items():
            setattr(owner, name, timed(label, originals[label]))
        try:
            simulate(scenario)
        finally:
            for label, (owner, name) in EVENTS.items():
                setattr(owner, name, originals[label])
        runs.append({label: value / duration for label, value in spent.items()})
    return {label: statistics.median(run[label] for run in runs) for label in EVENTS}


def main() -> None:
    """Print the measurements."""
    module = load_module()
    loops = compiled_loops(module)
    print("Pinocchio calls from Python and from compiled code [us] (same calls, same results):")
    print(f"{'robot':<16}{'group':<11}{'from Python':>13}{'from compiled':>15}")
    calls = {}
    for name in ("pioneer_cyton", "pioneer_xarm7"):
        calls[name] = pinocchio_times(name, module, loops)
        for group, (python, compiled) in calls[name].items():
            print(f"{name:<16}{group:<11}{python * 1e6:>13.2f}{compiled * 1e6:>15.2f}")
    print("\nthe control step in a compiled loop: its Pinocchio calls from compiled code plus")
    print("its compiled arithmetic, over its Pinocchio calls from Python (the issue's ratio):")
    arithmetic = {}
    for name in calls:
        step, python_calls, _, compiled_step, no_op = control_step_ratio(name)
        arithmetic[name] = compiled_step - no_op
        compiled_calls = calls[name]["control"][1]
        ratio = (compiled_calls + arithmetic[name]) / python_calls
        print(
            f"  {name:<16}calls {compiled_calls * 1e6:.2f} + arithmetic "
            f"{arithmetic[name] * 1e6:.2f} us = {ratio:.2f}x (today {step / python_calls:.2f}x)"
        )
    kernels = kernel_arithmetic()
    reference = calls["pioneer_cyton"]
    rows = (
        ("control step: Pinocchio calls from compiled code", reference["control"][1]),
        ("control step: compiled arithmetic", arithmetic["pioneer_cyton"]),
        ("plant step: Pinocchio calls and integrate from compiled code", reference["plant"][1]),
        ("plant step: servo kernel", kernels["servo"]),
        ("sensing kernel", kernels["sensing"]),
        ("prediction: camera placement from compiled code", reference["placement"][1]),
        ("prediction: projection kernel", kernels["projection"]),
    )
    print("\none simulated millisecond in a loop compiled around Pinocchio, pioneer_cyton [us]:")
    for label, value in rows:
        print(f"  {label:<64}{value * 1e6:>7.2f}")
    total = sum(value for _, value in rows)
    print(f"  {'total, before camera frames, filter and log':<64}{total * 1e6:>7.2f}")
    print(f"  at most {1e-3 / total:.0f}x real time")
    events = event_costs()
    print("\nthe loop's events, in a run of Experiment 1 [us per simulated millisecond]:")
    for label, value in events.items():
        print(f"  {label:<64}{value * 1e3:>7.2f}")
    with_events = total + sum(events.values()) * 1e-3
    print(f"  {'the compiled millisecond above plus these events':<64}{with_events * 1e6:>7.2f}")
    print(f"  at most {1e-3 / with_events:.0f}x real time with the events as they are")


if __name__ == "__main__":
    main()
