"""Synchronised, time-optimal point-to-point (PTP) motion of all axes.

In the style of Ruckig: an input value object (:class:`PtpInput`), a trajectory value
object (:class:`PtpTrajectory`), a documented result enum (:class:`Result`) and one
function, :func:`plan_ptp`, that never raises. Its messages name the quantity, the value
and the axis (axes are numbered from 1, like the specification's A1..A6)::

    >>> result, trajectory, message = plan_ptp(PtpInput(
    ...     current_position=(0.0, 0.0), target_position=(45.0, -10.0),
    ...     max_velocity=(15.6, 15.6), max_acceleration=(40.0, 40.0)))
    >>> result, round(trajectory.duration, 6), message
    (<Result.WORKING: 0>, 3.274615, '')

Synchronisation: every axis needs at least its own minimal duration ``T_i`` (see
:func:`runtime.motion.profiles.minimum_duration`); the move takes
``T = max_i T_i``. The slowest axis (the one with ``T_i = T``) gets its time-optimal
profile unchanged, so the move is exactly time-optimal; every other axis gets a profile
of exactly ``T`` that uses its full acceleration and the lowest cruise velocity that
covers its distance in ``T`` (:func:`runtime.motion.profiles.profile_with_duration`).
All axes start and stop together and none exceeds its own velocity or acceleration limit.

Units: positions in deg (mm for a prismatic axis), velocities in unit/s, accelerations
in unit/s^2, times in seconds. The limits in :class:`PtpInput` are the ones to obey,
already scaled by the move's ``speed_ptp`` / ``acc_ptp`` (:func:`scaled_limits`).

Real time: :func:`plan_ptp` runs once per move (about 20 us for six axes in CPython: a
fast validation pass, two float formulas per axis, the result objects; the careful,
message-producing validation runs only when the fast pass finds something odd);
:meth:`PtpTrajectory.sample` runs every trajectory cycle (5 ms, about 1 us).
See benchmarks/ptp_planner.py.
"""
from __future__ import annotations

from dataclasses import dataclass
from math import isfinite
from numbers import Real

from runtime.motion.stops import StopRamp
from runtime.motion.trajectory import Result, Trajectory
from runtime.motion.profiles import (
    TrapezoidalProfile,
    unchecked_minimum_duration,
    unchecked_profile_with_duration,
    unchecked_time_optimal_profile,
)

__all__ = [
    "DISTANCE_EPSILON",
    "MAX_DURATION",
    "PtpInput",
    "PtpTrajectory",
    "Result",
    "SynchronizedTrajectory",
    "check_axes",
    "format_value",
    "plan_ptp",
    "scaled_limits",
]

# The longest move plan_ptp accepts (s): beyond this the limits are too small for the
# distance to be a sensible move (and sampling times lose precision). Ruckig's own bound
# (ErrorTrajectoryDuration) plays the same role.
MAX_DURATION = 1.0e5


@dataclass(frozen=True, slots=True)
class PtpInput:
    """One PTP move: where the axes are, where they go, what they may do on the way.

    All sequences have one entry per axis. The axes are at rest at the start.

    * ``current_position`` -- positions now (deg or mm).
    * ``target_position`` -- positions to reach (deg or mm).
    * ``max_velocity`` -- per-axis speed limit (unit/s, > 0), already scaled by the move's
      ``speed_ptp``.
    * ``max_acceleration`` -- per-axis acceleration limit (unit/s^2, > 0), already scaled
      by the move's ``acc_ptp``.
    * ``min_position`` / ``max_position`` -- optional position range of each axis; when
      given, a target outside it is refused (``ERROR_POSITION_LIMITS``). The path of a
      PTP move is monotonic per axis, so a target inside the range keeps the whole
      move inside (a current position outside it may move back in).
    * ``max_jerk`` -- per-axis jerk limit (unit/s^3, > 0), for
      :func:`runtime.motion.jerk.plan_ptp_jerk` (which needs it; :func:`plan_ptp`'s
      trapezoids have no jerk limit and ignore it).
    * ``synchronization`` -- for :func:`runtime.motion.jerk.plan_ptp_jerk`: ``"line"``
      (a straight line in joint space), ``"time"`` (every axis stretched to the slowest
      axis's duration) or ``"auto"`` (the line when it costs no time, else ``"time"``).
    """

    current_position: tuple[float, ...]
    target_position: tuple[float, ...]
    max_velocity: tuple[float, ...]
    max_acceleration: tuple[float, ...]
    min_position: tuple[float, ...] | None = None
    max_position: tuple[float, ...] | None = None
    max_jerk: tuple[float, ...] | None = None
    synchronization: str = "auto"

    @property
    def degrees_of_freedom(self) -> int:
        return len(self.current_position)


class SynchronizedTrajectory(Trajectory):
    """What the PTP trajectories share: one profile per axis (``profiles``), all of the
    move's duration, whose accelerations are exact.

    :meth:`sample` gives the positions (unit) and velocities (unit/s) of all axes at time
    ``t`` (s), clamped to ``[0, duration]``: before the start the axes rest at the start
    positions, from ``duration`` on exactly at the target positions; in between, each kind
    evaluates its profiles (:meth:`_moving`). Real-time safe: plain float arithmetic, two
    result tuples."""

    __slots__ = ()

    @property
    def degrees_of_freedom(self) -> int:
        return len(self.start_position)

    def sample(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        if t >= self.duration:  # first: a zero-length move is at its target at once
            return self.target_position, self._zeros
        if not t > 0.0:  # also catches NaN
            return self.start_position, self._zeros
        return self._moving(t)

    def _moving(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """:meth:`sample` for ``0 < t < duration``."""
        raise NotImplementedError

    def sample_accelerations(self, t: float) -> tuple[float, ...]:
        """Accelerations (unit/s^2) of all axes at time ``t`` (s); 0 outside the move."""
        return tuple([p.sample(t)[2] for p in self.profiles])

    def accelerations_at(self, t: float) -> tuple[float, ...]:
        """Exact: :meth:`sample_accelerations`."""
        return self.sample_accelerations(t)

    def at_time(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
        """Exact positions, velocities and accelerations at ``t``."""
        positions, velocities = self.sample(t)
        return positions, velocities, self.sample_accelerations(t)

    @property
    def ramp_time(self) -> float:
        """The longest acceleration phase of any moving axis."""
        return max((p.t_acc for p in self.profiles if p.distance != 0.0), default=0.0)


class PtpTrajectory(SynchronizedTrajectory):
    """A planned, synchronised PTP move: every axis starts at ``t = 0`` and stops at
    ``t = duration`` (a :class:`~runtime.motion.trajectory.Trajectory`).

    * ``duration`` -- seconds (the slowest axis's minimal duration).
    * ``profiles`` -- one :class:`~runtime.motion.profiles.TrapezoidalProfile` per axis.
    * ``slowest_axis`` -- index (from 0) of the axis that sets the duration.
    * ``start_position`` / ``target_position`` -- the input positions.
    * ``max_acceleration`` -- the input's acceleration limits (a stop keeps them).
    """

    __slots__ = ("duration", "profiles", "slowest_axis", "start_position", "target_position",
                 "max_acceleration", "_zeros", "_params")

    def __init__(self, profiles: tuple[TrapezoidalProfile, ...], duration: float,
                 slowest_axis: int, start_position: tuple[float, ...],
                 target_position: tuple[float, ...], max_acceleration: tuple[float, ...] | None = None):
        self.profiles = profiles
        self.max_acceleration = (tuple(p.accel for p in profiles) if max_acceleration is None
                                 else tuple(max_acceleration))
        self.duration = duration
        self.slowest_axis = slowest_axis
        self.start_position = start_position
        self.target_position = target_position
        self._zeros = (0.0,) * len(profiles)
        # Flattened per-axis parameters for sample(): one tuple unpack per axis instead
        # of six attribute look-ups.
        self._params = tuple(
            (p.start, p.start + p.distance, p.v_cruise, p.accel, p.t_acc, duration - p.t_acc)
            for p in profiles)

    def _moving(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Each axis on its trapezoid."""
        duration = self.duration
        positions = []
        velocities = []
        for start, end, v, a, t_acc, t_dec in self._params:
            if t < t_acc:
                positions.append(start + 0.5 * a * t * t)
                velocities.append(a * t)
            elif t < t_dec:
                positions.append(start + v * (t - 0.5 * t_acc))
                velocities.append(v)
            else:
                r = duration - t  # at most t_acc, but t_dec = duration - t_acc is rounded
                if r > t_acc:
                    r = t_acc
                positions.append(end - 0.5 * a * r * r)
                velocities.append(a * r)
        return tuple(positions), tuple(velocities)

    def stop(self, t: float, positions: tuple, velocities: tuple, rate: float = 1.0) -> StopRamp:
        """Every axis to rest in the same time, within this move's acceleration limits
        (times ``rate^2``), along the direction of motion (:class:`StopRamp`)."""
        return StopRamp(positions, velocities, tuple([a * rate * rate for a in self.max_acceleration]))

    def __repr__(self) -> str:
        return (f"PtpTrajectory(duration={self.duration!r}, slowest_axis={self.slowest_axis}, "
                f"degrees_of_freedom={len(self.profiles)})")


def format_value(value: object) -> str:
    """A value for a message: ``0`` rather than ``0.0``, full precision otherwise."""
    if isinstance(value, float):
        if value == value and value.is_integer() and abs(value) < 1e16:
            return str(int(value))
        return repr(value)
    return repr(value)


def check_axes(named: list[tuple[str, object]],
               positive: tuple[str, ...]) -> tuple[Result, str, dict[str, tuple]]:
    """The per-axis quantities of a PTP input, ``(name, value)`` pairs (the first:
    ``current_position``), checked: sequences of as many finite numbers (not bools) as
    the first has axes, at least one, those ``positive`` named above 0. Returns
    ``(Result.WORKING, "", the sequences by name)``, or the error, its message (naming the
    axis, the quantity and the value) and the sequences read so far. The careful check of
    :func:`plan_ptp` and of :func:`runtime.motion.jerk.plan_ptp_jerk`."""
    sequences: dict[str, tuple] = {}
    for name, value in named:
        try:
            sequences[name] = tuple(value)
        except TypeError:
            return (Result.ERROR_INVALID_INPUT,
                    f"{name} must be a sequence of numbers, one per axis, got {value!r}", sequences)
    first = named[0][0]
    n = len(sequences[first])
    if n == 0:
        return Result.ERROR_INVALID_INPUT, f"{first} must have at least one axis, got 0", sequences
    for name, values in sequences.items():
        if len(values) != n:
            axis = min(len(values), n) + 1
            return (Result.ERROR_INVALID_INPUT,
                    f"axis {axis}: {name} has {len(values)} axes, {first} has {n}", sequences)
    for name, values in sequences.items():
        for i, value in enumerate(values):
            if isinstance(value, bool) or not isinstance(value, Real):
                return (Result.ERROR_INVALID_INPUT,
                        f"axis {i + 1}: {name} must be a number, got {value!r}", sequences)
            if not isfinite(value):
                return (Result.ERROR_INVALID_INPUT,
                        f"axis {i + 1}: {name} must be finite, got {format_value(value)}", sequences)
    for name in positive:
        for i, value in enumerate(sequences[name]):
            if not value > 0:
                return (Result.ERROR_INVALID_INPUT,
                        f"axis {i + 1}: {name} must be positive, got {format_value(value)}", sequences)
    return Result.WORKING, "", sequences


_QUANTITIES = ("current_position", "target_position", "max_velocity", "max_acceleration")


def _validate(inp: PtpInput) -> tuple[Result, str]:
    """(Result.WORKING, "") if ``inp`` can be planned, else the error and its message."""
    if not all(hasattr(inp, name) for name in _QUANTITIES):
        return Result.ERROR_INVALID_INPUT, f"input must be a PtpInput, got {type(inp).__name__}"
    named = [(name, getattr(inp, name)) for name in _QUANTITIES]
    named += [(name, value) for name in ("min_position", "max_position")
              if (value := getattr(inp, name, None)) is not None]
    result, message, sequences = check_axes(named, ("max_velocity", "max_acceleration"))
    if result != Result.WORKING:
        return result, message
    n = len(sequences["current_position"])
    lows, highs = sequences.get("min_position"), sequences.get("max_position")
    if lows is not None and highs is not None:
        for i in range(n):
            if not lows[i] <= highs[i]:
                return (Result.ERROR_INVALID_INPUT,
                        f"axis {i + 1}: min_position {format_value(lows[i])} is above "
                        f"max_position {format_value(highs[i])}")
    targets = sequences["target_position"]
    for i in range(n):
        if lows is not None and targets[i] < lows[i]:
            return (Result.ERROR_POSITION_LIMITS,
                    f"axis {i + 1}: target_position {format_value(targets[i])} is below "
                    f"min_position {format_value(lows[i])}")
        if highs is not None and targets[i] > highs[i]:
            return (Result.ERROR_POSITION_LIMITS,
                    f"axis {i + 1}: target_position {format_value(targets[i])} is above "
                    f"max_position {format_value(highs[i])}")
    return Result.WORKING, ""


_INF = float("inf")
_NUMBER_TYPES = (float, int)


def _plainly_valid(inp: object) -> bool:
    """The common case, checked fast: four equally long, non-empty sequences of plain
    floats or ints, all finite, the limits positive, no position range. ``False`` means
    "look closer" (:func:`_validate` finds and words the problem), not "invalid"."""
    try:
        if inp.min_position is not None or inp.max_position is not None:
            return False
        current, target = inp.current_position, inp.target_position
        velocity, acceleration = inp.max_velocity, inp.max_acceleration
        n = len(current)
        if not n or len(target) != n or len(velocity) != n or len(acceleration) != n:
            return False
        for c, t, v, a in zip(current, target, velocity, acceleration):
            # x - x == 0 exactly when x is finite; the comparisons are False for NaN
            if not (type(c) in _NUMBER_TYPES and type(t) in _NUMBER_TYPES
                    and type(v) in _NUMBER_TYPES and type(a) in _NUMBER_TYPES
                    and c - c == 0.0 and t - t == 0.0 and 0.0 < v < _INF and 0.0 < a < _INF):
                return False
        return True
    except Exception:  # noqa: BLE001 - anything odd goes to the careful check
        return False


#: Distances (deg or mm) below this are no motion: the axis counts as at its target.
DISTANCE_EPSILON = 1e-12


def plan_ptp(inp: PtpInput) -> tuple[Result, PtpTrajectory | None, str]:
    """Plan the synchronised time-optimal PTP move described by ``inp``.

    Returns ``(result, trajectory, message)``: on success ``Result.WORKING`` (or
    ``Result.FINISHED`` when there is nothing to move), the trajectory and ``""``; on
    failure a negative :class:`Result`, ``None`` and a message that names the quantity,
    the value and the axis, e.g. ``"axis 3: max_velocity must be positive, got 0"``.
    Never raises. Runs once per move (not every cycle): a few tens of microseconds for
    six axes in CPython.
    """
    try:
        if not _plainly_valid(inp):
            result, message = _validate(inp)
            if result != Result.WORKING:
                return result, None, message
        start = tuple(map(float, inp.current_position))
        target = tuple(map(float, inp.target_position))
        v_max = tuple(map(float, inp.max_velocity))
        a_max = tuple(map(float, inp.max_acceleration))
        n = len(start)
        distances = [0.0] * n
        minima = [0.0] * n
        for i in range(n):
            d = target[i] - start[i]
            if not d - d == 0.0:
                return (Result.ERROR_INVALID_INPUT, None,
                        f"axis {i + 1}: target_position - current_position overflows, got "
                        f"{format_value(target[i])} - {format_value(start[i])}")
            if -DISTANCE_EPSILON < d < DISTANCE_EPSILON:  # already there: no motion at all
                d = 0.0
                start = start[:i] + (target[i],) + start[i + 1:]
            distances[i] = d
            minima[i] = unchecked_minimum_duration(d, v_max[i], a_max[i])
        duration = max(minima)
        slowest = minima.index(duration)
        if not duration <= MAX_DURATION:
            return (Result.ERROR_LIMITS, None,
                    f"axis {slowest + 1}: the move needs {format_value(duration)} s, more than "
                    f"{format_value(MAX_DURATION)} s (max_velocity {format_value(v_max[slowest])}, "
                    f"max_acceleration {format_value(a_max[slowest])}, distance "
                    f"{format_value(distances[slowest])})")
        profiles = tuple([
            unchecked_time_optimal_profile(start[i], distances[i], v_max[i], a_max[i])
            if minima[i] == duration else
            unchecked_profile_with_duration(start[i], distances[i], v_max[i], a_max[i], duration)
            for i in range(n)])
        trajectory = PtpTrajectory(profiles, duration, slowest, start, target, a_max)
        return (Result.WORKING if duration > 0.0 else Result.FINISHED), trajectory, ""
    except Exception:  # noqa: BLE001 - the contract is: never raise (and never show a Python message)
        return (Result.ERROR, None,
                "internal error in the PTP planner: the move could not be planned (not a fault of the program)")


def scaled_limits(axes_max_velocity, axes_max_acceleration, speed_ptp: float,
                  acc_ptp: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The limits of one PTP move: the axes' limits times the move's fractions.

    ``axes_max_velocity`` (unit/s) and ``axes_max_acceleration`` (unit/s^2) are the
    specification's per-axis limits; ``speed_ptp`` and ``acc_ptp`` are the move's clause
    values, fractions within the clause table's ranges (compiler.clauses). Returns ``(max_velocity, max_acceleration)`` tuples
    for :class:`PtpInput`.

    Raises ``ValueError`` for a fraction outside those ranges or sequences of different
    lengths: the compiler and the specification loader already reject those, so in the
    loop this would be a programming error, not a program's.
    """
    from compiler.clauses import BY_NAME, Motion

    for name, value in (("speed_ptp", speed_ptp), ("acc_ptp", acc_ptp)):
        rng = BY_NAME[name].range_for(Motion.PTP)
        if not (isinstance(value, Real) and isfinite(value) and rng.contains(value, None)):
            raise ValueError(f"{name} must be a fraction {rng.expected('x', None)}, got {format_value(value)}")
    velocities = tuple(float(v) * speed_ptp for v in axes_max_velocity)
    accelerations = tuple(float(a) * acc_ptp for a in axes_max_acceleration)
    if len(velocities) != len(accelerations):
        raise ValueError(f"axes_max_velocity has {len(velocities)} axes, "
                         f"axes_max_acceleration has {len(accelerations)}")
    return velocities, accelerations
