"""Exceptions raised by pbvs_pin.

Every error a user can cause derives from :class:`PbvsError`, so that a caller can catch the
package's errors without catching Python's own, and every message names the file, frame,
field or value at fault and what was expected.
"""

from __future__ import annotations

from collections.abc import Iterable


class PbvsError(Exception):
    """Base class of every error raised by pbvs_pin."""


class PbvsWarning(UserWarning):
    """A value pbvs_pin accepts but changes (e.g. a rate rounded to whole control steps)."""


class UrdfError(PbvsError):
    """A URDF file cannot be read or does not describe what was asked for."""

    def __init__(self, source: str, problem: str) -> None:
        """Name the file and the problem.

        Args:
            source: Path of the URDF file, or the name it was loaded by.
            problem: What is wrong and what was expected.
        """
        self.source, self.problem = source, problem
        super().__init__(f"{source}: {problem}")


class ChainError(UrdfError):
    """``arm_tip`` does not hang below ``arm_root`` in the arm's URDF."""


class BaseJointsError(UrdfError):
    """``base_joints`` names joints that do not model a base's motion."""


class FrameNotFound(PbvsError):
    """A link or frame name does not exist in a robot description."""

    def __init__(self, name: str, available: Iterable[str], where: str = "") -> None:
        """Name the missing frame and list the valid names.

        Args:
            name: The name asked for.
            available: The names that do exist.
            where: The file or robot that was searched.
        """
        self.name = name
        self.available = sorted(available)
        place = f" in {where}" if where else ""
        super().__init__(f"frame {name!r} not found{place}; available: {', '.join(self.available)}")


class NoMovableJoint(UrdfError):
    """The arm has no joint between its root and the camera frame."""


class DriveAxleNotFound(UrdfError):
    """A differential-drive platform has no usable pair of left and right drive wheels."""


class ShapeError(PbvsError):
    """An array has the wrong shape."""

    def __init__(self, name: str, expected: tuple[int, ...], got: tuple[int, ...]) -> None:
        """Name the array and both shapes.

        Args:
            name: Name of the argument or field.
            expected: The expected shape.
            got: The shape received.
        """
        self.name = name
        super().__init__(f"{name}: expected shape {expected}, got {got}")


class NonFiniteValue(PbvsError):
    """An array holds NaN or infinity where finite numbers are required."""

    def __init__(self, name: str) -> None:
        """Name the array.

        Args:
            name: Name of the argument or field.
        """
        self.name = name
        super().__init__(f"{name}: expected finite values, got NaN or infinity")


class GainError(PbvsError):
    """A gain or parameter is outside its valid range."""

    def __init__(self, message: str, field: str = "") -> None:
        """Keep the message and, when known, the parameter's name.

        Args:
            message: What is wrong and what was expected.
            field: Name of the parameter at fault (e.g. ``"alpha"``), so that a scenario can
                report its dotted field.
        """
        self.field = field
        super().__init__(message)


class PointBehindCamera(PbvsError):
    """A point to project lies behind (or on) the camera's image plane."""

    def __init__(self, depth: float) -> None:
        """Record the offending depth.

        Args:
            depth: Depth of the point along the optical axis [m].
        """
        self.depth = depth
        super().__init__(
            f"point at depth {depth:.4g} m is not in front of the camera (expected depth > 0)"
        )


class RobotNotFound(PbvsError):
    """A robot name is neither a shipped robot, an example-robot-data name, nor a file."""

    def __init__(
        self, name: str, available: Iterable[str], example_robot_data: Iterable[str] = ()
    ) -> None:
        """Name the unknown robot and list the valid names, shipped ones apart.

        Args:
            name: The name asked for.
            available: Valid shipped names.
            example_robot_data: Valid example-robot-data names, where those are accepted
                (empty where only shipped names are).
        """
        self.name = name
        self.available = sorted(available)
        self.example_robot_data = sorted(example_robot_data)
        if self.example_robot_data:
            message = (
                f"robot {name!r} is not a URDF file, a shipped robot or an example-robot-data "
                f"name; shipped: {', '.join(self.available)}; example-robot-data: "
                f"{', '.join(self.example_robot_data)}"
            )
        else:
            message = (
                f"robot {name!r} is not a URDF file or a shipped robot; shipped robots: "
                f"{', '.join(self.available)} (an example-robot-data arm goes on the reference "
                'platform with a [robot] table, e.g. arm = "ur5"; `pbvs-pin list` names them)'
            )
        super().__init__(message)


class ScenarioError(PbvsError):
    """A scenario file is missing, malformed, or holds an invalid value."""

    def __init__(self, source: str, field: str, problem: str) -> None:
        """Name the file, the field and the problem.

        Args:
            source: Path or name of the scenario.
            field: Dotted name of the field at fault ("" for the whole file).
            problem: What is wrong and what was expected.
        """
        self.source = source
        self.field = field
        where = f"{source}: {field}" if field else source
        super().__init__(f"{where}: {problem}")


class ViewerUnavailable(PbvsError):
    """The Meshcat viewer cannot be started or reached."""

    def __init__(self, reason: str, advice: str) -> None:
        """Say why, and what to do instead.

        Args:
            reason: What failed (one line).
            advice: What the user can do instead, e.g. write a standalone HTML file.
        """
        self.reason = reason
        self.advice = advice
        super().__init__(f"Meshcat viewer unavailable: {reason}; {advice}")


class HomeNotFound(PbvsError):
    """No arm posture makes the camera look forward: the robot has no computable home."""

    def __init__(self, source: str, forward_error_deg: float, criteria: object) -> None:
        """Name the robot, the best forward error reached and the criteria used.

        Args:
            source: File or name the robot was built from.
            forward_error_deg: Smallest angle between the optical axis and the platform's x
                axis that was found [deg].
            criteria: The :class:`pbvs_pin.bringup.home.HomeCriteria` in force.
        """
        self.source = source
        self.forward_error_deg = forward_error_deg
        super().__init__(
            f"{source}: no arm posture points the camera forward: the optical axis stays "
            f"{forward_error_deg:.1f} deg from the platform's x axis (criteria: {criteria}); "
            "check camera_link and camera_pose (optical frame: z forward, x right, y down), or "
            "give the home posture explicitly"
        )


class ControlInputError(PbvsError):
    """A control step's input cannot be used: time not increasing, a frame from the future."""


class OutputError(PbvsError):
    """An output folder or file cannot be written (not writable, a full disk)."""

    def __init__(self, path: str, problem: str) -> None:
        """Name the path and the problem.

        Args:
            path: The folder or file that cannot be written.
            problem: What went wrong, and what was (not) left behind.
        """
        self.path = path
        super().__init__(f"{path}: {problem}")


class RunInterrupted(KeyboardInterrupt):
    """A simulation was stopped by Ctrl-C; it carries the run so far.

    A :class:`KeyboardInterrupt`, so that code which does not know it still stops.

    Attributes:
        log: The run so far (a :class:`pbvs_pin.sim.log.RunLog` whose ``meta["interrupted"]``
            is true), or None when nothing had been recorded yet.
        saved: Where the log was written, once it was.
        lost: What the finished run would also have written (``"the summary"``, ...).
    """

    def __init__(
        self, log: object | None, saved: str | None = None, lost: Iterable[str] = ()
    ) -> None:
        """Keep the partial log.

        Args:
            log: The run so far, or None.
            saved: Path of the saved log, if it was saved.
            lost: What the finished run would also have written.
        """
        self.log = log
        self.saved = saved
        self.lost = tuple(lost)
        super().__init__("run interrupted")


class OutputsInterrupted(KeyboardInterrupt):
    """Ctrl-C while a finished run's outputs were being written.

    A :class:`KeyboardInterrupt`, so that code which does not know it still stops.

    Attributes:
        kept: The outputs written whole, each named with its path.
        lost: The outputs not written, or not whole, each named with its path.
    """

    def __init__(self, kept: Iterable[str], lost: Iterable[str]) -> None:
        """Name what was kept and what was lost.

        Args:
            kept: The outputs written whole.
            lost: The outputs not written.
        """
        self.kept = tuple(kept)
        self.lost = tuple(lost)
        super().__init__("outputs interrupted")


class SweepIncomplete(PbvsError):
    """A sweep ended with runs it could not finish (executor lost, or interrupted).

    Their rows are not written, so that running the same command again runs them.
    """

    def __init__(self, out: str, unfinished: int, total: int, reason: str) -> None:
        """Name the folder, the count and why.

        Args:
            out: The sweep's output folder.
            unfinished: Runs that did not finish.
            total: Runs of the sweep.
            reason: What stopped them (one line).
        """
        self.unfinished = unfinished
        super().__init__(
            f"{out}: {unfinished} of {total} runs did not finish ({reason}); the finished runs "
            "are saved: run the same command again to resume"
        )


class RenderingUnavailable(PbvsError):
    """The rendered camera cannot draw: no offscreen OpenGL context, or nothing to draw."""


class RosUnavailable(PbvsError):
    """ROS 2's Python client cannot be imported: the ``ros`` extra is not installed."""

    def __init__(self, problem: str) -> None:
        """Say what failed and how to install the extra.

        Args:
            problem: The import error's message.
        """
        super().__init__(
            f"ROS 2 is not available ({problem}); install it with pip install 'pbvs_pin[ros]'"
        )


class UsageError(PbvsError):
    """Command-line options that contradict each other, or one that needs another."""

    def __init__(self, option: str, problem: str) -> None:
        """Name the option and the problem.

        Args:
            option: The option at fault, e.g. ``"--speed"``.
            problem: What is wrong and what to give instead.
        """
        self.option = option
        super().__init__(f"{option}: {problem}")


class LogError(PbvsError):
    """A file read as a run log is missing, truncated, foreign, or lacks a channel."""

    def __init__(self, source: str, problem: str) -> None:
        """Name the file and the problem.

        Args:
            source: Path of the log.
            problem: What is wrong and what was expected.
        """
        self.source, self.problem = source, problem
        super().__init__(f"{source}: {problem}")


class WrongType(PbvsError):
    """An argument is of the wrong kind: text, an object or a ragged list for numbers, say."""

    def __init__(self, name: str, expected: str, value: object) -> None:
        """Name the argument, what was expected and what was given.

        Args:
            name: Name of the argument or field.
            expected: What it must be, e.g. ``"a number"``.
            value: The value given (shown shortened, with its type).
        """
        self.name = name
        shown = repr(value)
        shown = shown if len(shown) <= 40 else shown[:37] + "..."
        super().__init__(f"{name}: expected {expected}, got {shown} ({type(value).__name__})")
