"""One trajectory interface for every kind of motion, and the planners' one result enum.

Every motion the trajectory generator runs -- a PTP move (trapezoidal,
:class:`runtime.motion.planner.PtpTrajectory`, or jerk-limited,
:class:`runtime.motion.jerk.JerkPtpTrajectory`), a lin or circ move
(:class:`runtime.motion.cartesian.JointStream`), and the stops on a path
(:mod:`runtime.motion.stops`) -- is a :class:`Trajectory`: joint positions over time,
from rest at ``t = 0`` to rest at ``t = duration``. A blend is two trajectories on one
timeline (:mod:`runtime.motion.blend`, :mod:`runtime.motion.motionqueue`).

The planners share Ruckig's shape: a typed input, and one function that never raises and
returns ``(result, trajectory, message)``:

========================================  =========================================
planner                                   input
========================================  =========================================
:func:`runtime.motion.planner.plan_ptp`    :class:`~runtime.motion.planner.PtpInput`
:func:`runtime.motion.jerk.plan_ptp_jerk`  :class:`~runtime.motion.planner.PtpInput`
                                          with ``max_jerk``
:func:`runtime.motion.cartesian.plan_cartesian`  :class:`~runtime.motion.cartesian.CartesianInput`
========================================  =========================================

``result`` is a :class:`Result`: non-negative with a trajectory, negative with ``None``
and a message that says what is wrong, with the quantity, the value and the axis, or
where along the path.

Units: positions in deg (revolute axes) or mm (prismatic), velocities per second,
accelerations per second squared, times in seconds.
"""
from __future__ import annotations

import enum

from compiler.clauses import Motion

__all__ = ["Refusal", "Result", "Trajectory"]


class Refusal(str):
    """Why a move cannot be planned: its text (a ``str``, so it goes wherever a problem's
    text goes: the program's error, the log), and, for a path the arm cannot follow, where
    along it: ``fraction`` (0..1 of the path), ``distance`` (mm of the tool's path from its
    start) and ``reason`` (runtime.motion.pathcheck's: ``"limit"``, ``"singular"``, ...).
    What the offline check (runtime.loop.offline) reports besides the text."""

    def __new__(cls, text: str, fraction: float | None = None, distance: float | None = None,
                reason: str | None = None) -> "Refusal":
        self = super().__new__(cls, text)
        self.fraction, self.distance, self.reason = fraction, distance, reason
        return self

    def prefixed(self, prefix: str) -> "Refusal":
        """The same refusal, its text after ``prefix``."""
        return Refusal(prefix + self, self.fraction, self.distance, self.reason)


class Result(enum.IntEnum):
    """What a planner did. Non-negative: a trajectory; negative: an error (no trajectory,
    and a message). The values follow Ruckig's ``Result`` where the meaning is the same."""

    #: A trajectory was planned and has a positive duration: sample it until the end.
    WORKING = 0
    #: Nothing to do: the target equals the current position; the trajectory has
    #: duration 0 and holds the position.
    FINISHED = 1
    #: An unexpected internal error (a bug): the message carries the exception.
    ERROR = -1
    #: The input is malformed: lengths differ, a value is not a finite number, a limit
    #: is not positive. The message names the quantity, the value and the axis.
    ERROR_INVALID_INPUT = -100
    #: The input is well formed, but the limits make the move impossible to plan: its
    #: duration is not finite or exceeds ``MAX_DURATION`` (tiny limits against a long
    #: distance).
    ERROR_LIMITS = -101
    #: The target lies outside the axis's position range (only when the input gives
    #: ``min_position`` / ``max_position``).
    ERROR_POSITION_LIMITS = -102
    #: A Cartesian path the arm cannot follow: out of reach, through a singularity, a
    #: change of configuration, an axis limit along the way. The message says where
    #: along the path (percent of its length) and why.
    ERROR_PATH = -110


class Trajectory:
    """Joint positions over time, at rest at both ends; what every kind of motion gives.

    Attributes (every trajectory has them):

    * ``duration`` -- seconds; ``sample(t)`` for ``t >= duration`` is the end, at rest;
    * ``start_position`` / ``target_position`` -- all axes at ``t = 0`` and at the end.

    Methods, with what they cost:

    * :meth:`sample` -- ``(positions, velocities)`` at ``t``: the trajectory generator's
      call every 5 ms (real-time; may keep state between successive calls, as a
      Cartesian move's inverse kinematics does, so call it from the loop only);
    * :meth:`at_time` -- ``(positions, velocities, accelerations)`` at ``t``, keeping no
      state (Ruckig's ``at_time``; safe from a planning thread);
    * :meth:`position_at` -- positions at ``t``, keeping no state (the blend check);
    * what **blending** needs: :attr:`ramp_time` (how long it accelerates) and
      :meth:`path_time` (a Cartesian move's time for its first or last ``d`` mm);
    * what **stopping** needs: :meth:`stop` -- a controlled stop on its own path from
      time ``t``, itself a trajectory, whose :meth:`rest` names what is left of the move.
    """

    __slots__ = ()

    duration: float
    start_position: tuple
    target_position: tuple

    def sample(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Positions and velocities of all axes at time ``t`` (s), clamped to the move:
        the start before 0, exactly the end (with zero velocities) from ``duration`` on."""
        raise NotImplementedError

    def position_at(self, t: float) -> tuple[float, ...]:
        """Positions at ``t`` without touching any state :meth:`sample` keeps."""
        return self.sample(t)[0]

    def at_time(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
        """Positions, velocities and accelerations at ``t`` (keeping no state). By default
        central differences of :meth:`position_at` over :data:`AT_TIME_STEP`; the PTP
        trajectories give the exact values."""
        h = AT_TIME_STEP
        p = self.position_at(t)
        before, after = self.position_at(t - h), self.position_at(t + h)
        return (p, tuple([(b - a) / (2.0 * h) for a, b in zip(before, after)]),
                tuple([(b - 2.0 * x + a) / (h * h) for a, x, b in zip(before, p, after)]))

    def accelerations_at(self, t: float) -> tuple[float, ...] | None:
        """The exact accelerations at ``t`` when the trajectory knows them in closed form
        (the PTP profiles; the setpoints then carry them and the servo's references keep
        every limit exactly), else None (a Cartesian move's, from differences, are too
        rough for that)."""
        return None

    @property
    def ramp_time(self) -> float:
        """How long the move accelerates (= decelerates), s: the blend's overlap never
        exceeds it."""
        return 0.0

    def tool_path_length(self) -> float | None:
        """The length (mm) of the tool's path of a lin or circ move; None for others."""
        return None

    def path_distance(self, t: float, stop: "Trajectory | None" = None) -> float | None:
        """How far (mm) along the tool's path a lin or circ move is at its time ``t`` (or,
        with ``stop``, where that stop of it ends); None for others."""
        return None

    def path_time(self, distance: float, at_end: bool) -> float | None:
        """A Cartesian move's time (s) for its first (``at_end`` False) or last
        ``distance`` mm of tool path; None for a move in joint space."""
        return None

    def stop(self, t: float, positions: tuple, velocities: tuple, rate: float = 1.0) -> "Trajectory":
        """A controlled stop from this move's time ``t``, where the commanded positions and
        velocities are ``positions`` and ``velocities`` (real time, the override's ``rate``
        applied): to rest on the move's own path where it can (a jerk-limited line, a
        Cartesian line or arc), within the move's acceleration limits."""
        raise NotImplementedError

    def rest(self, end: tuple) -> tuple[Motion, tuple] | None:
        """For a stop: what is left of the interrupted move whose end is ``end`` (all
        axes), as ``(kind, targets)`` to plan from where the stop ends: by default a
        ptp move to ``end``; None when nothing is left."""
        return Motion.PTP, (tuple(end),)


#: The step (s) of :meth:`Trajectory.at_time`'s central differences.
AT_TIME_STEP = 1e-4
