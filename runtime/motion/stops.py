"""Stops: controlled stops of a move under way (pause, abort), each a
:class:`runtime.motion.trajectory.Trajectory` from where the move was to rest.

A move's :meth:`~runtime.motion.trajectory.Trajectory.stop` picks its own:

* :class:`StopRamp` -- every axis decelerates uniformly to rest in the same time, along
  the direction of motion (a trapezoidal PTP move, a jerk-limited one timed per axis);
* :class:`LineStop` -- jerk-limited, on the straight joint-space line of a jerk-limited
  PTP move;
* :class:`PathStop` -- jerk-limited, on the tool's line or arc of a Cartesian move (its
  :meth:`PathStop.rest` is the rest of the path, as a lin or circ move);
* :class:`JerkStop` -- one coordinate (a path parameter) to rest, jerk-limited: what the
  last two are made of.

Real-time safe: made and sampled in the loop (plain floats; PathStop solves one inverse
kinematics per sample).
"""
from __future__ import annotations

from math import sqrt
from typing import TYPE_CHECKING, Sequence

from runtime.motion.kinematics import KinematicsError
from runtime.motion.trajectory import Trajectory

#: The half-width (s) of the central differences that give the joint velocities and
#: accelerations of a move along a path (lin, circ, and their stops) at a setpoint.
DERIVATIVE_STEP = 1e-4
#: The smallest half-width used: closer to a path's end than this (a sample time a rounding
#: error before it), the differences would divide rounding noise by its square (1e-12 s
#: gave accelerations of 1e16 deg/s^2, which the servo's interpolator turned into a jump
#: the safety supervisor stopped): the path is at rest there, so 0.
MIN_DERIVATIVE_STEP = 1e-7

if TYPE_CHECKING:
    from runtime.motion.cartesian import JointStream

__all__ = ["REST_VELOCITY", "JerkStop", "LineStop", "PathStop", "StopRamp"]


#: Slower than this (deg/s or mm/s) is rest for a stop: no drive is ever commanded it.
REST_VELOCITY = 1e-12


class StopRamp(Trajectory):
    """A controlled stop: from positions ``p0`` moving at ``v0``, every axis decelerates
    uniformly to rest in the same time ``duration``, the shortest that keeps each axis
    within its deceleration limit ``a_max``: ``T = max |v0_i| / a_max_i``.

    The axes stop together, moving along the direction of motion at the moment of the
    stop (the tangent of the path). That is exactly on the move's path when the move's
    axes are proportional in time (every axis sharing one profile shape, as when they
    have the same limits); the trapezoidal planner's non-leading axes accelerate at their
    own limit, so in general the stop point is within a fraction of a degree of the path.
    Not jerk-limited (the deceleration starts at once). Same sampling interface as
    :class:`PtpTrajectory`. Real-time safe.
    """

    __slots__ = ("duration", "start_position", "target_position", "_v0", "_zeros")

    def __init__(self, p0: tuple[float, ...], v0: tuple[float, ...], a_max: tuple[float, ...]):
        # A velocity below REST_VELOCITY is rest: a subnormal one (2e-311) would give a
        # subnormal duration, and the fractions t / duration would lose their precision.
        v0 = tuple(v if abs(v) >= REST_VELOCITY else 0.0 for v in v0)
        duration = 0.0
        for v, a in zip(v0, a_max):
            if a > 0.0 and abs(v) / a > duration:
                duration = abs(v) / a
        self.duration = duration
        self.start_position = tuple(p0)
        self._v0 = v0 if duration > 0.0 else (0.0,) * len(p0)
        self.target_position = tuple(p + 0.5 * v * duration for p, v in zip(p0, self._v0))
        self._zeros = (0.0,) * len(p0)

    def sample(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        if t >= self.duration:
            return self.target_position, self._zeros
        if not t > 0.0:
            return self.start_position, self._v0
        # every axis at the same fraction of its start velocity: (1 - t / T) v0
        left = 1.0 - t / self.duration
        travelled = t * (1.0 + left) * 0.5  # (t - t^2 / 2T)
        return (tuple([p + v * travelled for p, v in zip(self.start_position, self._v0)]),
                tuple([v * left for v in self._v0]))

    def accelerations_at(self, t: float) -> tuple[float, ...]:
        """Exact: ``-v0 / duration`` on every axis while it stops, 0 before and after."""
        if not 0.0 < t < self.duration:
            return self._zeros
        k = -1.0 / self.duration
        return tuple([v * k for v in self._v0])


class JerkStop:
    """A jerk-limited stop of one coordinate (a path parameter): from velocity ``v0 >= 0``
    and acceleration ``a0`` to rest, within ``|a| <= a_max`` and ``|jerk| <= j_max``.

    The acceleration ramps at ``-j_max`` from ``a0`` to ``-a_p``, holds ``-a_p``, and
    ramps back to 0 at ``+j_max``; ``a_p = a_max`` when there is room, else the value
    that ends exactly at rest (``a_p = sqrt(V j_max)`` with ``V = v0 + a0^2 / (2 j_max)``).
    When the coordinate is already braking harder than that (``a0 < -a_p``), the
    acceleration only ramps up to 0; should the velocity reach 0 first, the stop ends
    there (the last step of acceleration is then at most ``|a0|``). When it brakes harder
    than ``a_max`` and that ramp would not reach rest, the acceleration ramps up to
    ``-a_max``, holds it and ramps to 0 at rest. ``sample(t)`` gives the
    displacement from the start, the velocity and the acceleration; ``distance`` is where
    it stops. Real-time safe (plain floats; a handful of segments)."""

    __slots__ = ("duration", "distance", "_segments")

    def __init__(self, v0: float, a0: float, a_max: float, j_max: float):
        # below REST_VELOCITY is rest: a subnormal v0 (5e-324) would make a stop of 1e-163 s
        v0 = v0 if v0 >= REST_VELOCITY else 0.0
        big_v = v0 + a0 * a0 / (2.0 * j_max)
        a_p = a_max
        hold = (big_v - a_p * a_p / j_max) / a_p
        if hold < 0.0:
            hold = 0.0
            a_p = sqrt(max(big_v * j_max, 0.0))
        if a0 < -a_max and v0 > a0 * a0 / (2.0 * j_max):
            # braking harder than allowed, and ramping the acceleration up to 0 would not
            # reach rest: up to -a_max, hold it, then up to 0 (the hold ends at rest)
            plan = [((-a0 - a_max) / j_max, j_max), ((v0 - a0 * a0 / (2.0 * j_max)) / a_max, 0.0),
                    (a_max / j_max, j_max)]
        elif a0 < -a_p:  # already braking harder: only ramp the acceleration up to 0
            plan = [(-a0 / j_max, j_max)]
        else:
            plan = [((a0 + a_p) / j_max, -j_max), (hold, 0.0), (a_p / j_max, j_max)]
        segments = []  # (t_start, duration, s, v, a, jerk)
        t = s = 0.0
        v, a = v0, a0
        for length, jerk in plan:
            if length <= 0.0:
                continue
            if jerk > 0.0 and a < 0.0:  # the velocity may reach 0 before the acceleration does
                disc = a * a - 2.0 * jerk * v
                if disc >= 0.0:
                    root = (-a - sqrt(disc)) / jerk
                    if 0.0 <= root < length:
                        length = root
            segments.append((t, length, s, v, a, jerk))
            s += v * length + 0.5 * a * length * length + jerk * length ** 3 / 6.0
            v += a * length + 0.5 * jerk * length * length
            a += jerk * length
            t += length
        self._segments = tuple(segments)
        self.duration = t
        self.distance = s

    def sample(self, t: float) -> tuple[float, float, float]:
        if not t > 0.0 or not self._segments:
            if self._segments:
                _t, _l, s, v, a, _j = self._segments[0]
                return s, v, a
            return 0.0, 0.0, 0.0
        if t >= self.duration:
            return self.distance, 0.0, 0.0
        for t0, length, s, v, a, jerk in self._segments:
            if t < t0 + length:
                u = t - t0
                return (s + v * u + 0.5 * a * u * u + jerk * u * u * u / 6.0,
                        v + a * u + 0.5 * jerk * u * u, a + jerk * u)
        return self.distance, 0.0, 0.0


class LineStop(Trajectory):
    """A jerk-limited stop **on** the straight joint-space line ``base + d * s`` of a
    ``"line"`` :class:`runtime.motion.jerk.JerkPtpTrajectory`: the shared path parameter
    ``s`` stops (:class:`JerkStop` within the line's own acceleration and jerk limits,
    ``limits = (v_max, a_max, j_max)`` per axis, so every axis keeps its limits) from the
    positions, velocities and accelerations of the move at the moment of the stop (its
    velocities and accelerations times the override's ``rate`` and ``rate^2``).
    ``target_position`` is where it stops. Real-time safe."""

    __slots__ = ("duration", "start_position", "target_position", "_stop", "_base", "_d", "_s0", "_zeros")

    def __init__(self, base: tuple, distances: tuple, limits: tuple, positions: tuple, velocities: tuple,
                 accelerations: tuple, rate: float = 1.0):
        d = distances
        k = max(range(len(d)), key=lambda i: abs(d[i]))
        s0 = (positions[k] - base[k]) / d[k] if d[k] else 1.0
        v_s, a_s = (velocities[k] / d[k] * rate, accelerations[k] / d[k] * rate * rate) if d[k] else (0.0, 0.0)
        moving = [(abs(di), vi) for di, vi in zip(d, zip(*limits)) if di]
        big_a = min((lim[1] / di for di, lim in moving), default=1.0)
        big_j = min((lim[2] / di for di, lim in moving), default=1.0)
        self._stop = JerkStop(v_s, a_s, big_a, big_j)
        self._base, self._d, self._s0 = base, d, s0
        self.duration = self._stop.duration
        self.start_position = positions
        self.target_position = tuple([b + di * (s0 + self._stop.distance) for b, di in zip(base, d)])
        self._zeros = (0.0,) * len(d)

    def sample(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        if t >= self.duration:
            return self.target_position, self._zeros
        ds, v, _a = self._stop.sample(t)
        s = self._s0 + ds
        return (tuple([b + di * s for b, di in zip(self._base, self._d)]), tuple([di * v for di in self._d]))

    def accelerations_at(self, t: float) -> tuple[float, ...]:
        """Exact: every axis's distance times the path parameter's acceleration."""
        if t >= self.duration:
            return self._zeros
        a = self._stop.sample(t)[2]
        return tuple([di * a for di in self._d])


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


class PathStop(Trajectory):
    """A controlled stop **on** a Cartesian path (pause, abort): from the path parameter,
    speed and acceleration of ``stream`` at its time ``t``, the path speed falls to rest
    jerk-limited (:class:`runtime.motion.jerk.JerkStop` within the move's ``acc`` and
    jerk); every sample is one inverse kinematics of the path's pose
    at ``s(t)`` near the last joints, so the tool stays on the line or arc. Velocities and
    accelerations are central differences over +-DERIVATIVE_STEP of the path's joints
    (two more inverse kinematics), as a move's stream gives them (0 at rest). Same interface as
    :class:`JointStream`; ``s_end`` is where it stops (resume plans the rest from there).
    Never raises: should an inverse kinematics fail, ``fault`` says why and the joints hold.
    """

    __slots__ = ("path", "kinematics", "duration", "s_end", "fault", "_s0", "_stop", "_last", "_last_t",
                 "_add", "_zeros", "_end", "_acc")

    def __init__(self, stream: "JointStream", t: float, joints: Sequence[float], deceleration: float | None = None,
                 rate: float = 1.0):
        """``rate``: the stream was sampled at ``rate`` seconds of its time per real second
        (a speed override): the real path speed is the profile's times ``rate``; the stop
        itself is in real time, within the path acceleration and jerk of the stretch it
        runs through (:meth:`runtime.motion.paths.CartesianMove.stop_limits`: the move's
        ``acc`` and jerk, or less where the joints slowed the move down)."""
        move = stream.checked.move
        s0, v0, a0 = move.profile.sample(t)
        limits = move.stop_limits(s0, v0 * rate, a0 * rate * rate)
        self.path, self.kinematics = move.path, stream.checked.kinematics
        if limits is not None:
            acc, jerk = limits
            self._stop = JerkStop(v0 * rate, a0 * rate * rate, acc if deceleration is None else deceleration, jerk)
        if limits is None or s0 + self._stop.distance >= move.path.length:
            self._stop = _ProfileRest(move.profile, t, rate)  # (no sooner stop keeps the limits: the move's own end)
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
        (less near the ends), central differences."""
        q = self._solve(self._s_at(t), near)
        e = min(DERIVATIVE_STEP, 0.5 * t, 0.5 * (self.duration - t))
        if not e > MIN_DERIVATIVE_STEP:
            return q, self._zeros[:6], self._zeros[:6]
        before, after = self._solve(self._s_at(t - e), q), self._solve(self._s_at(t + e), q)
        k1, k2 = 0.5 / e, 1.0 / (e * e)
        return (q, tuple([(c - a) * k1 for a, c in zip(before, after)]),
                tuple([(a - 2.0 * b + c) * k2 for a, b, c in zip(before, q, after)]))

    def _s_at(self, t: float) -> float:
        return min(self._s0 + self._stop.sample(t)[0], self.s_end)

    def _solve(self, s: float, near: tuple) -> tuple[float, ...]:
        try:
            return tuple(self.kinematics.inverse(self.path.pose_at(s), near=near))
        except KinematicsError as exc:
            self.fault = self.fault or f"the stop left the arm's reach ({exc})"
            return near

    def rest(self, end: tuple = ()) -> tuple[str, tuple] | None:
        """What is left of the path after the stop: ``("lin", (end,))`` or
        ``("circ", (via, end))`` -- the arguments of :func:`plan_lin` / :func:`plan_circ`
        from the stop on (the via point halfway along the rest of the arc); None when the
        stop ends at the path's end (no sooner stop kept the limits: nothing is left)."""
        path = self.path
        if self.s_end >= path.length - 1e-9 * max(path.length, 1.0):
            return None
        end = path.pose_at(path.length)
        if path.kind == "circ":
            return "circ", (path.pose_at(0.5 * (self.s_end + path.length)), end)
        return "lin", (end,)
