"""Cartesian moves (``move lin``, ``move circ``) for the trajectory generator: a path
(:mod:`runtime.motion.paths`) timed within every joint's limits and checked whole
(:mod:`runtime.motion.pathcheck`), as joint values per tick (:class:`JointStream`).

In one call that never raises, shaped like the PTP planners::

    result, stream, message = plan_cartesian(CartesianInput(
        kinematics, joints, target_pose, speed, acc, axis_limits=spec.main_axes))
    result, stream, message = plan_cartesian(CartesianInput(
        kinematics, joints, target_pose, speed, acc, via=via_pose, axis_limits=spec.main_axes))

With a specification's axes, a move is never refused for its joint velocities: its path
is checked at uniform steps along it, then timed within JOINT_LIMIT_SHARE of every
joint's velocity, acceleration and jerk limit (:func:`timed_path`): slower only where
the joints need it (:func:`runtime.motion.pathtiming.path_profile`), or, when the joints
limit the whole path alike and that is faster, the programmed profile run k times slower
(:func:`runtime.motion.pathtiming.uniform_scale`). The setpoints are then solved on the
servo's 1 ms grid wherever the joints come above PREDICTED_HOT_SHARE of a limit and the move is
slowed down again (uniformly) should they break one (:func:`setpoint_ratios`).

Per tick: :meth:`JointStream.sample` (about 29 us: one inverse kinematics per call when
called at successive ticks ``t, t + period, ...``; it solves one period ahead and returns
central-difference velocities), and, once the move is paused or aborted, its stop on the
line or arc (:class:`PathStop`). Plain floats and ``math``; no NumPy in a tick.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from math import ceil
from typing import Mapping, Sequence

import numpy as np

from compiler.clauses import Motion
from compiler.values import Joint

from runtime.timing import SETPOINT_PERIOD, TICK
from runtime.motion.kinematics import Kinematics, KinematicsError
from runtime.motion.stops import JerkStop
from runtime.motion.trajectory import Refusal, Result, Trajectory
from runtime.motion.pathcheck import CheckedPath, PathError, check_path, joint_limits, percent
from runtime.motion.paths import CircPath, LinPath, CartesianMove, positive
from runtime.motion.pathtiming import (ConstantSpeed, PathProfile, nominal_profile, path_derivatives, path_profile,
                         predicted_ratios, uniform_scale, warped_profile)
from runtime.motion.reachability import AveragedProfile, reachable_profile

__all__ = ["DERIVATIVE_STEP", "JOINT_LIMIT_SHARE", "MIN_DERIVATIVE_STEP", "CartesianInput", "JointStream",
           "PathStop", "joint_limit_scale", "plan_cartesian"]


# ============================================================================ per tick

#: The half-width (s) of the central differences that give the joint velocities and
#: accelerations of a move along a path (lin, circ, and their stops) at a setpoint.
DERIVATIVE_STEP = 1e-4
#: The smallest half-width used: closer to a path's end than this (a sample time a rounding
#: error before it), the differences would divide rounding noise by its square (1e-12 s
#: gave accelerations of 1e16 deg/s^2, which the servo's interpolator turned into a jump
#: the safety supervisor stopped): the path is at rest there, so 0.
MIN_DERIVATIVE_STEP = 1e-7

_ZEROS6 = (0.0,) * 6


def _central_differences(joints_at, t: float, q: tuple, duration: float) -> tuple[tuple, tuple]:
    """Velocities and accelerations of the six main axes at ``t`` (0 < ``t`` <
    ``duration``) of a path's joints ``joints_at(t, near)``, ``q`` the joints at ``t``:
    central differences over +-DERIVATIVE_STEP, less near the ends, two more joint values
    near ``q``; 0 within MIN_DERIVATIVE_STEP of an end (a rounding error from it, where
    the path is at rest). What a lin or circ move (:class:`JointStream`) and its stop
    (:class:`PathStop`) give as their velocities and accelerations. May raise
    ``KinematicsError`` (from ``joints_at``)."""
    e = min(DERIVATIVE_STEP, 0.5 * t, 0.5 * (duration - t))
    if not e > MIN_DERIVATIVE_STEP:
        return _ZEROS6, _ZEROS6
    before, after = joints_at(t - e, q), joints_at(t + e, q)
    k1, k2 = 0.5 / e, 1.0 / (e * e)
    return (tuple([(c - a) * k1 for a, c in zip(before, after)]),
            tuple([(a - 2.0 * b + c) * k2 for a, b, c in zip(before, q, after)]))


class JointStream(Trajectory):
    """The joint trajectory of a :class:`CheckedPath` for the trajectory generator (a
    :class:`~runtime.motion.trajectory.Trajectory`): ``duration`` and
    ``sample(t) -> (positions, velocities)`` over the six main axes followed by the
    held ``additional`` axes, and :meth:`accelerations_at` (what the servo's references
    need to keep every limit between the setpoints).

    The positions are one inverse kinematics of the commanded pose, ``near`` the joint
    values of the previous call (extrapolated linearly) when called at ``t, t + period,
    ...`` (the generator's ticks), else near the check's nearest sample; the velocities and
    accelerations are central differences of the joint path over +-DERIVATIVE_STEP
    (0.1 ms; less near the ends): two more inverse kinematics, near the first. Before 0 the
    start joints, from ``duration`` on the end joints, both at rest.

    Never raises for a number ``t``: should an inverse kinematics fail after all
    (impossible after the check but for rounding), ``fault`` gets the message and the
    stream holds its last positions with zero velocity.
    """

    __slots__ = ("checked", "period", "duration", "fault", "_additional", "_zeros",
                 "_start", "_end", "_qp", "_tc", "_qc", "_ac")

    def __init__(self, checked: CheckedPath, period: float = SETPOINT_PERIOD, additional: Sequence[float] = ()):
        self.checked = checked
        self.period = positive("period", period)
        self.duration = checked.duration
        self.fault: str | None = None
        self._additional = add = tuple(float(v) for v in additional)
        self._zeros = (0.0,) * (6 + len(add))
        self._start = tuple(checked.start_joints) + add
        self._end = tuple(checked.end_joints) + add
        self._tc = None
        self._qp = self._qc = self._ac = None

    def joints_at(self, t: float, near: Sequence[float] | None = None) -> tuple[float, ...]:
        """The six main axes at ``t`` (:meth:`CheckedPath.joints_at`); may raise
        ``KinematicsError``."""
        return self.checked.joints_at(t, near)

    def position_at(self, t: float) -> tuple[float, ...]:
        """All axes at ``t`` (one inverse kinematics from the check's nearest sample),
        touching none of the state :meth:`sample` keeps: safe from another thread (the
        blend check). May raise ``KinematicsError``."""
        if t >= self.duration:
            return self._end
        if not t > 0.0:
            return self._start
        return self.checked.joints_at(t) + self._additional

    @property
    def start_position(self) -> tuple[float, ...]:
        """All axes at the start of the move."""
        return self._start

    @property
    def target_position(self) -> tuple[float, ...]:
        """All axes at the end of the move."""
        return self._end

    @property
    def ramp_time(self) -> float:
        """How long the path parameter accelerates."""
        return self.checked.move.profile.t_acc

    def tool_path_length(self) -> float:
        """The length (mm) of the tool's path."""
        return self.checked.move.path.position_length

    def path_distance(self, t: float, stop: PathStop | None = None) -> float:
        """How far (mm) along the tool's path the move is at its time ``t`` (or, with
        ``stop``, where that stop of it ends)."""
        move = self.checked.move
        length = move.path.length
        s = stop.s_end if stop is not None else move.profile.sample(t)[0]
        return s * move.path.position_length / length if length > 0.0 else 0.0

    def path_time(self, distance: float, at_end: bool) -> float:
        """The time (s) for the first (``at_end`` False) or last ``distance`` mm of tool
        path (the whole move when it is shorter)."""
        move = self.checked.move
        profile, length = move.profile, move.path.length
        tcp = move.path.position_length / length if length > 0.0 else 0.0
        s_goal = distance / tcp if tcp > 0.0 else length
        if s_goal >= length:
            return move.duration
        if at_end:
            s_goal = length - s_goal
        lo, hi = 0.0, move.duration  # s(t) is non-decreasing: bisection
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            if profile.sample(mid)[0] < s_goal:
                lo = mid
            else:
                hi = mid
        return move.duration - hi if at_end else hi

    def stop(self, t: float, positions: tuple, velocities: tuple, rate: float = 1.0) -> PathStop:
        """Along the line or arc itself: the path speed to rest, jerk-limited within the
        move's ``acc`` and jerk (:class:`PathStop`)."""
        return PathStop(self, t, positions, rate=rate)

    def _derivatives(self, t: float, q: tuple) -> tuple[tuple, tuple]:
        """Velocities and accelerations of the six main axes at ``t`` (q: the joints at
        ``t``): :func:`_central_differences`; may raise KinematicsError."""
        return _central_differences(self.checked.joints_at, t, q, self.duration)

    def sample(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        duration = self.duration
        if t >= duration:  # (at rest: the next call near the check's samples, not these joints)
            self._tc, self._ac, self._qp, self._qc = t, self._zeros, None, None
            return self._end, self._zeros
        if not t > 0.0:
            self._tc, self._ac, self._qp, self._qc = t, self._zeros, None, None
            return self._start, self._zeros
        if self.fault is not None:
            return (self._qc or self.checked.start_joints) + self._additional, self._zeros
        h = self.period
        tc = self._tc
        try:
            if tc is not None and self._qc is not None and abs(t - tc - h) <= 1e-9 * h and self._qp is not None:
                near = tuple([2.0 * b - a for a, b in zip(self._qp, self._qc)])  # the last two, extrapolated
                q = self.checked.joints_at(t, near)
            else:
                q = self.checked.joints_at(t)  # near: the check's nearest sample
            velocities, accelerations = self._derivatives(t, q)
        except KinematicsError as exc:
            self.fault = (f"the arm cannot follow the path at {percent(self.checked.move.fraction(t))} "
                          f"of its length: {exc}")
            self._ac = None
            return (self._qc or self.checked.start_joints) + self._additional, self._zeros
        self._qp, self._qc = self._qc, q
        self._tc = t
        add = self._additional
        self._ac = accelerations + (0.0,) * len(add)
        if add:
            return q + add, velocities + (0.0,) * len(add)
        return q, velocities

    def at_time(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
        """Positions, velocities and accelerations at ``t`` as :meth:`sample` and
        :meth:`accelerations_at` give them, keeping no state (three inverse kinematics).
        May raise ``KinematicsError``."""
        if t >= self.duration:
            return self._end, self._zeros, self._zeros
        if not t > 0.0:
            return self._start, self._zeros, self._zeros
        q = self.checked.joints_at(t)
        velocities, accelerations = self._derivatives(t, q)
        add = self._additional
        zeros = (0.0,) * len(add)
        return q + add, velocities + zeros, accelerations + zeros

    def accelerations_at(self, t: float) -> tuple[float, ...] | None:
        """The accelerations of the last :meth:`sample` when ``t`` is its time (central
        differences over +-0.1 ms of the joint path, consistent with its velocities);
        else from three inverse kinematics; None after a fault."""
        if t == self._tc:
            return self._ac
        if t >= self.duration or not t > 0.0:
            return self._zeros
        if self.fault is not None:
            return None
        try:
            q = self.checked.joints_at(t)
            return self._derivatives(t, q)[1] + (0.0,) * len(self._additional)
        except KinematicsError:
            return None

    def __repr__(self) -> str:
        return f"JointStream(duration={self.duration!r}, period={self.period!r})"


class _ProfileRest:
    """The rest of a path's profile from its time ``t``, run at ``rate``: what a stop on
    the path does when stopping sooner within the limits of the stretch ahead would take
    it past the path's end (the profile itself comes to rest there within every limit).
    ``sample(t)`` gives the distance from the start, the speed and the acceleration, like
    :class:`JerkStop`."""

    __slots__ = ("duration", "distance", "_profile", "_t", "_rate", "_s0")

    def __init__(self, profile, t: float, rate: float):
        self._profile, self._t, self._rate = profile, t, rate
        self._s0 = profile.sample(t)[0]
        self.duration = max(profile.duration - t, 0.0) / rate
        self.distance = profile.sample(profile.duration)[0] - self._s0

    def sample(self, t: float) -> tuple[float, float, float]:
        s, v, a = self._profile.sample(self._t + self._rate * max(t, 0.0))
        return s - self._s0, v * self._rate, a * self._rate * self._rate


def _ramp_stop(profile, t: float, rate: float):
    """``profile``'s :meth:`~runtime.motion.pathtiming.PathProfile.ramp_stop` from its time
    ``t``, sampled at ``rate`` (a speed override: the profile run 1/rate times slower), or
    None (no profile with the joints' derivatives, or none fits)."""
    if not isinstance(profile, PathProfile):
        return None
    return (profile if rate == 1.0 else profile.scaled(rate)).ramp_stop(t / rate)


class PathStop(Trajectory):
    """A controlled stop **on** a Cartesian path (pause, abort): from the path parameter,
    speed and acceleration of ``stream`` at its time ``t``, the path speed falls to rest
    jerk-limited (:class:`runtime.motion.stops.JerkStop` within the move's ``acc`` and
    jerk); every sample is one inverse kinematics of the path's pose
    at ``s(t)`` near the last joints, so the tool stays on the line or arc. Velocities and
    accelerations are central differences over +-DERIVATIVE_STEP of the path's joints
    (two more inverse kinematics), as a move's stream gives them (0 at rest). Same interface as
    :class:`JointStream`; ``s_end`` is where it stops (resume plans the rest from there).
    Never raises: should an inverse kinematics fail, ``fault`` says why and the joints hold.
    """

    __slots__ = ("path", "kinematics", "duration", "s_end", "fault", "_s0", "_stop", "_last", "_last_t",
                 "_add", "_zeros", "_end", "_acc")

    def __init__(self, stream: JointStream, t: float, joints: Sequence[float], deceleration: float | None = None,
                 rate: float = 1.0):
        """``rate``: the stream was sampled at ``rate`` seconds of its time per real second
        (a speed override): the real path speed is the profile's times ``rate``; the stop
        itself is in real time, within the path acceleration and jerk of the stretch it
        runs through (:meth:`runtime.motion.paths.CartesianMove.stop_limits`: the move's
        ``acc`` and jerk, or less where the joints slowed the move down)."""
        move = stream.checked.move
        s0, v0, a0 = move.profile.sample(t)
        self.path, self.kinematics = move.path, stream.checked.kinematics
        law = None
        if isinstance(move.profile, AveragedProfile) and deceleration is None:  # (braking as hard as the grid allows)
            law = (move.profile if rate == 1.0 else move.profile.scaled(rate)).stop_law(t / rate)
        if law is not None:
            self._stop = law
        else:
            limits = move.stop_limits(s0, v0 * rate, a0 * rate * rate)
            if limits is not None:
                acc, jerk = limits
                self._stop = JerkStop(v0 * rate, a0 * rate * rate, acc if deceleration is None else deceleration, jerk)
            if limits is None or s0 + self._stop.distance >= move.path.length:
                # no braking keeps the limits sooner: the move's own law slowed down to rest, or its end
                ramp = _ramp_stop(move.profile, t, rate) if deceleration is None else None
                self._stop = ramp if ramp is not None else _ProfileRest(move.profile, t, rate)
        self._s0 = s0
        self.duration = self._stop.duration
        self.s_end = min(s0 + self._stop.distance, move.path.length)
        self.fault: str | None = None
        self._add = tuple(joints[6:])
        self._last = tuple(joints[:6])
        self._last_t = 0.0
        self._zeros = (0.0,) * len(joints)
        self._end = None
        self._acc = (None, None)  # (time, accelerations) of the last sample

    def sample(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        if t >= self.duration:
            if self._end is None:
                self._end = self._solve(self.s_end, self._last)
            self._acc = (t, self._zeros)
            return self._end + self._add, self._zeros
        if not t > 0.0:
            return self._last + self._add, self._zeros
        q, velocities, accelerations = self._state(t, self._last)
        self._last, self._last_t, self._acc = q, t, (t, accelerations + self._zeros[6:])
        return q + self._add, velocities + self._zeros[6:]

    def accelerations_at(self, t: float) -> tuple[float, ...]:
        """The joints' accelerations at ``t`` (central differences of the path's joints
        over +-DERIVATIVE_STEP, as the velocities :meth:`sample` gives): what the servo's
        interpolator needs to keep the limits between the setpoints of a stop."""
        if t == self._acc[0]:
            return self._acc[1]
        if t >= self.duration or not t > 0.0:
            return self._zeros
        return self._state(t, self._last)[2] + self._zeros[6:]

    def _state(self, t: float, near: tuple) -> tuple[tuple, tuple, tuple]:
        """The six main axes' positions, velocities and accelerations at ``t`` (0 <
        ``t`` < duration): one inverse kinematics at ``t`` and two at +-DERIVATIVE_STEP
        (less near the ends), central differences (:func:`_central_differences`)."""
        q = self._joints_at(t, near)
        velocities, accelerations = _central_differences(self._joints_at, t, q, self.duration)
        return q, velocities, accelerations

    def _joints_at(self, t: float, near: tuple) -> tuple[float, ...]:
        """The six main axes at the stop's time ``t``, near ``near``."""
        return self._solve(self._s_at(t), near)

    def _s_at(self, t: float) -> float:
        return min(self._s0 + self._stop.sample(t)[0], self.s_end)

    def _solve(self, s: float, near: tuple) -> tuple[float, ...]:
        try:
            return tuple(self.kinematics.inverse(self.path.pose_at(s), near=near))
        except KinematicsError as exc:
            self.fault = self.fault or f"the stop left the arm's reach ({exc})"
            return near

    def rest(self, end: tuple = ()) -> tuple[Motion, tuple] | None:
        """What is left of the path after the stop: ``(Motion.LIN, (end,))`` or
        ``(Motion.CIRC, (via, end))`` -- the lin or circ move from the stop on (the via
        point halfway along the rest of the arc); None when the stop ends at the path's
        end (no sooner stop kept the limits: nothing is left)."""
        path = self.path
        if self.s_end >= path.length - 1e-9 * max(path.length, 1.0):
            return None
        end = path.pose_at(path.length)
        if path.kind == Motion.CIRC:
            return Motion.CIRC, (path.pose_at(0.5 * (self.s_end + path.length)), end)
        return Motion.LIN, (end,)


# ============================================================================ one call


#: The share of each joint's velocity, acceleration and jerk limit that a Cartesian move is
#: timed to at the check's samples (the rest: what lies between the samples, and the
#: interpolation to the servo's 1 ms references).
JOINT_LIMIT_SHARE = 0.9
#: The share the reachability timing (:mod:`runtime.motion.reachability`) plans to: its
#: prediction every 1 ms is the chain rule on its own time law (no bound that adds
#: magnitudes), so it may come closer; the setpoints are checked against the limits all the same.
REACHABLE_SHARE = 0.96


def _ratios(q: np.ndarray, h: float, limits: Sequence[Sequence[float]]) -> list[float]:
    """The largest ratio to its limit of the first, second and third differences of the
    joint samples ``q`` (every ``h`` s), over all axes."""
    out = []
    derivative = q
    for limit in limits:
        derivative = np.diff(derivative, axis=0) / h if len(derivative) > 1 else derivative[:0]
        out.append(float(np.max(np.abs(derivative) / np.asarray(limit, dtype=float))) if len(derivative) else 0.0)
    return out


#: Where the check's samples show a joint above this share of a limit, the setpoints
#: around are solved and checked too (elsewhere the samples' differences are far enough
#: from the limits that the setpoints', over windows of the same size, are too).
HOT_SHARE = 0.7
#: Where the joints are predicted (pathtiming's chain rule, every 1 ms) above this share of
#: a limit, the setpoints around are solved and checked (the prediction is close to what
#: the setpoints do: the samples' differences, which average the peaks, need HOT_SHARE).
PREDICTED_HOT_SHARE = 0.8


def setpoint_ratios(checked: CheckedPath, limits: Sequence[Sequence[float]], period: float,
                    hot_times: np.ndarray | None = None) -> list[float]:
    """The largest ratio of any joint's velocity, acceleration and jerk to ``limits`` at
    the setpoints of the move (its joints every ``period`` s from the start, one inverse
    kinematics each, as the stream makes them; the end from ``duration`` on; at rest
    before and after): first, second and third differences, what the drives see. Solved
    around ``hot_times`` (s), or, without them, between the check's samples around those
    above HOT_SHARE of a limit (the hot stretches); 0 elsewhere."""
    times, joints = checked.times, checked.joints
    n = ceil(checked.duration / period - 1e-9)
    if len(times) < 2 or n < 1:
        return [0.0, 0.0, 0.0]
    if hot_times is not None:
        steps = set()
        # (sorted(set(...)), not np.unique: its first call imports numpy.ma, in a tick file I/O)
        for step in sorted(set((np.asarray(hot_times) / period).astype(int).tolist())):
            steps.update(range(max(step - 4, -3), min(step + 6, n + 4)))
        return _solved_ratios(checked, limits, period, n, steps)
    q = np.asarray(joints, dtype=float)
    at = np.asarray(times, dtype=float)
    hot = np.zeros(len(q), dtype=bool)
    derivative = q
    for limit in limits:  # divided differences (the samples need not be uniform in time)
        if len(derivative) < 2:
            break
        derivative = np.diff(derivative, axis=0) / np.maximum(np.diff(at), 1e-12)[:, None]
        at = 0.5 * (at[1:] + at[:-1])
        over = np.max(np.abs(derivative) / np.asarray(limit, dtype=float), axis=1) > HOT_SHARE
        hot[:len(over)] |= over
        hot[len(hot) - len(over):] |= over
    steps = set()
    last = len(times) - 1
    for i in np.flatnonzero(hot):  # the setpoints from the sample before a hot one to the one after, and four more
        lo, hi = int(times[max(i - 1, 0)] / period), int(times[min(i + 1, last)] / period)
        steps.update(range(max(lo - 4, -3), min(hi + 6, n + 4)))
    return _solved_ratios(checked, limits, period, n, steps)


def _solved_ratios(checked: CheckedPath, limits, period: float, n: int, steps: set) -> list[float]:
    """:func:`setpoint_ratios` over the setpoints ``steps`` (runs of consecutive ones)."""
    worst = [0.0, 0.0, 0.0]
    run: list = []
    for step in sorted(steps) + [None]:
        if step is None or (run and step != run[-1][0] + 1):
            if len(run) > 1:
                ratios = _ratios(np.asarray([r[1] for r in run], dtype=float), period, limits)
                worst = [max(a, b) for a, b in zip(worst, ratios)]
            run = []
        if step is None:
            break
        if step <= 0:
            q_step = checked.start_joints
        elif step >= n:
            q_step = checked.end_joints
        else:
            t = step * period
            q_step = checked.joints_at(t, run[-1][1] if run else checked.seed(t))
        run.append((step, q_step))
    return worst


def timed_path(move: CartesianMove, kinematics: Kinematics, start_joints: Sequence[float], axis_limits,
               limits: Sequence[Sequence[float]], check: Mapping) -> tuple[CheckedPath, np.ndarray | None]:
    """``move``'s path checked (:func:`check_path`, at uniform steps along it) and timed
    within every joint's ``limits`` (:func:`runtime.motion.pathtiming.path_profile`, at
    JOINT_LIMIT_SHARE of them): the programmed profile where no joint limits it, else one
    that slows down only where the joints need it. Also returns the times at which the
    joints are predicted above PREDICTED_HOT_SHARE of a limit (every 1 ms; None: not predicted, a
    path too short to tell). Raises ``PathError``."""
    path = move.path
    along = check_path(CartesianMove(path, move.speed, move.acc, move.jerk, profile=ConstantSpeed(path.length)),
                       kinematics, start_joints, axis_limits, check_velocity=False, **check)
    s = np.asarray(along.times, dtype=float)  # (at unit speed, the times are the path lengths)
    joints = np.asarray(along.joints, dtype=float)
    profile = k = None
    if len(s) >= 4 and s[-1] > 0.0:  # the shortest of: slowed down as a whole, by segments, by a warp
        derivatives = path_derivatives(s, joints)
        k, fastest = uniform_scale(s, derivatives, limits, move.speed, move.acc, move.jerk, JOINT_LIMIT_SHARE)
        beat = move.duration / k
        if fastest < LOCAL_GAIN * beat:  # slowing down locally may gain something
            segments = path_profile(s, joints, limits, move.speed, move.acc, move.jerk, JOINT_LIMIT_SHARE,
                                    derivatives)
            if segments is not None:
                beat = min(beat, segments.duration)
            reachable = reachable_profile(s, derivatives, limits, move.speed, move.acc, move.jerk, REACHABLE_SHARE)
            if reachable is not None and reachable.duration < beat:
                beat, segments = reachable.duration, reachable
            warped = (warped_profile(s, derivatives, limits, move.speed, move.acc, move.jerk, JOINT_LIMIT_SHARE, beat)
                      if fastest < LOCAL_GAIN * beat else None)  # (unless the segments are about as short as can be)
            profile = warped or segments
    if profile is not None and profile.duration < move.duration / k:  # slower only where the joints need it
        move = CartesianMove(path, move.speed, move.acc, move.jerk, profile=profile)
    else:  # the joints limit the whole path alike: the programmed profile, k times slower
        if k is not None and k < 1.0:
            move = CartesianMove(path, move.speed * k, move.acc * k * k, move.jerk * k * k * k)
        profile = nominal_profile(path.length, move.speed, move.acc, move.jerk)  # (the same, vectorised)
    hot = None
    if k is not None:
        at, ratios = predicted_ratios(profile, s, derivatives, limits)
        hot = profile.times_at(at[np.max(ratios, axis=0) > PREDICTED_HOT_SHARE])
    times = profile.times_at(s)
    dt = np.diff(times)[:, None]
    moved = np.abs(np.diff(joints, axis=0))
    peaks = np.max(np.divide(moved, dt, out=np.zeros_like(moved), where=dt > 0.0), axis=0, initial=0.0)
    return CheckedPath(move, kinematics, along.start_joints, tuple(times.tolist()), along.fractions, along.joints,
                       tuple(peaks.tolist()), along.min_margins), hot


def _slower(move: CartesianMove, k: float) -> CartesianMove:
    """``move`` run k times slower (its profile scaled in time)."""
    profile = move.profile.scaled(k) if isinstance(move.profile, PathProfile) else None
    return CartesianMove(move.path, move.speed * k, move.acc * k * k, move.jerk * k * k * k, profile=profile)


def _retimed(checked: CheckedPath, move: CartesianMove, k: float) -> CheckedPath:
    """``checked`` for ``move``: the same path run k times slower (the same joints, at
    their times / k; no inverse kinematics)."""
    return CheckedPath(move, checked.kinematics, checked.start_joints, tuple([t / k for t in checked.times]),
                       checked.fractions, checked.joints, tuple([v * k for v in checked.peak_velocities]),
                       checked.min_margins)


def joint_limit_scale(checked: CheckedPath, limits: Sequence[Sequence[float]],
                      share: float = JOINT_LIMIT_SHARE) -> float:
    """(What the planner before the local slowdown timed moves by; ``benchmarks/lin_limits.py``
    measures against it.) The largest k <= 1 such that the move of ``checked`` run k times slower in time
    (path speed x k, acceleration x k^2, jerk x k^3: the time-optimal profile scales so)
    keeps every joint's velocity, acceleration and jerk within ``share`` of ``limits``
    (three sequences of six: max velocity, max acceleration, max jerk), measured by finite
    differences over the check's samples (uniform in time)."""
    times, joints = checked.times, checked.joints
    if len(times) < 2 or not checked.duration > 0.0:
        return 1.0
    return _scale(_ratios(np.asarray(joints, dtype=float), times[1] - times[0], limits), share)


def _scale(ratios: Sequence[float], share: float) -> float:
    """The k <= 1 that brings velocity, acceleration and jerk ``ratios`` within ``share``."""
    k = 1.0
    for order, ratio in enumerate(ratios, start=1):
        if ratio > share:
            k = min(k, (share / ratio) ** (1.0 / order))
    return k


#: A move is timed locally (pathtiming's segments and warp) only when the lower bound of
#: what that could give is below this share of the uniform slowdown's duration.
LOCAL_GAIN = 0.97
#: Times a lin/circ move is timed slower again when its setpoints still break a limit.
RETIMINGS = 4
#: The share of the limits the first retiming brings the setpoints' largest ratio to.
RETIME_SHARE = 0.98


@dataclass(frozen=True)
class CartesianInput:
    """One ``move lin`` or ``move circ``, for :func:`plan_cartesian`.

    * ``kinematics`` -- the arm's :class:`~runtime.motion.kinematics.Kinematics`;
    * ``start_joints`` -- where the move starts: the six main axes, then any additional
      axes (held through the move); a sequence or a ``Joint``;
    * ``target`` -- the end pose (a pose tuple, a ``Pose`` or a matrix);
    * ``via`` -- for a circ move, the pose whose position the arc passes through (its
      orientation is ignored); None for a lin move;
    * ``speed`` (mm/s), ``acc`` (mm/s^2), ``jerk`` (mm/s^3; default
      ``DEFAULT_JERK_FACTOR * acc``) -- the tool's limits along the path;
    * ``axis_limits`` -- a specification (or its main axes): the move is timed within
      every joint's velocity, acceleration and jerk limit and checked against the
      position limits; None: only the kinematics are checked;
    * ``period`` -- the setpoint period (s) the joints are streamed at;
    * ``check`` -- further keyword arguments of :func:`runtime.motion.pathcheck.check_path`
      (``step``, ``step_deg``, ``min_samples``, ...).
    """

    kinematics: Kinematics
    start_joints: Sequence[float]
    target: object
    speed: float
    acc: float
    via: object = None
    jerk: float | None = None
    axis_limits: object = None
    period: float = SETPOINT_PERIOD
    check: Mapping = field(default_factory=dict)


def plan_cartesian(inp: CartesianInput) -> tuple[Result, JointStream | None, str]:
    """Plan the lin move (``inp.via`` None) or circ move ``inp`` describes: the straight
    line (or the arc through ``via``'s position) from the forward kinematics of the start
    joints to ``target``, timed with ``speed``, ``acc``, ``jerk`` and, with
    ``axis_limits``, within every joint's limits (slower where the joints demand it),
    then checked whole (:func:`runtime.motion.pathcheck.check_path`).

    Returns ``(Result.WORKING, stream, "")``; ``(Result.ERROR_PATH, None, message)`` for a
    path the arm cannot follow (the message says where along it and why);
    ``(Result.ERROR_INVALID_INPUT, None, message)`` for a malformed input (a limit that
    is not positive, circle points on a line). Never raises."""
    try:
        kinematics, start_joints, check = inp.kinematics, inp.start_joints, dict(inp.check)
        joints = tuple(start_joints.axes if isinstance(start_joints, Joint) else start_joints)
        if len(joints) < 6:
            return (Result.ERROR_INVALID_INPUT, None,
                    f"expected at least six joint values (the main axes), got {len(joints)}")
        main, additional = joints[:6], joints[6:]
        start = kinematics.forward(main)
        path = LinPath(start, inp.target) if inp.via is None else CircPath(start, inp.via, inp.target)
        move = CartesianMove(path, inp.speed, inp.acc, inp.jerk)
        axis_limits, period = joint_limits(inp.axis_limits), inp.period
        limits = (axis_limits.velocity, axis_limits.acceleration, axis_limits.jerk)
        if None in limits:  # not a specification's axes: nothing to time the move within
            checked = check_path(move, kinematics, main, axis_limits, **check)
        else:
            # timed within every joint's limits: slower where the programmed speed, acc
            # and jerk would ask more of a joint than it can give (pathtiming), from the
            # joints at uniform steps along the path
            checked, hot = timed_path(move, kinematics, main, axis_limits, limits, check)
            move = checked.move
            k = 1.0
            for attempt in range(RETIMINGS):  # until the setpoints themselves keep every limit
                if k < 1.0:  # the same path, k times slower: the same joints at times / k
                    move = _slower(move, k)
                    checked = _retimed(checked, move, k)
                    hot = None if hot is None else hot / k
                ratios = setpoint_ratios(checked, limits, TICK, hot)  # (its 5 ms differences average these)
                if max(ratios) <= 1.0:
                    break
                # (first just within the limits: a move timed close to them is not slowed
                # down to JOINT_LIMIT_SHARE for a small excess; then with that margin)
                k = _scale(ratios, RETIME_SHARE if attempt == 0 else JOINT_LIMIT_SHARE)
        return Result.WORKING, JointStream(checked, period, additional), ""
    except PathError as exc:
        return Result.ERROR_PATH, None, Refusal(str(exc), exc.fraction, exc.distance, exc.reason)
    except KinematicsError as exc:
        return Result.ERROR_PATH, None, str(exc)
    except (ValueError, TypeError) as exc:
        return Result.ERROR_INVALID_INPUT, None, str(exc)
    except Exception:  # noqa: BLE001 - the contract is: never raise (and never show a Python message)
        return (Result.ERROR, None,
                "internal error in the Cartesian planner: the move could not be planned (not a fault of the program)")
