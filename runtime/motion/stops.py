"""Stops: controlled stops of a move under way (pause, abort), each a
:class:`runtime.motion.trajectory.Trajectory` from where the move was to rest.

A move's :meth:`~runtime.motion.trajectory.Trajectory.stop` picks its own:

* :class:`StopRamp` -- every axis decelerates uniformly to rest in the same time, along
  the direction of motion (a trapezoidal PTP move, a jerk-limited one timed per axis);
* :class:`LineStop` -- jerk-limited, on the straight joint-space line of a jerk-limited
  PTP move;
* :class:`JerkStop` -- one coordinate (a path parameter) to rest, jerk-limited: what
  :class:`LineStop` and a Cartesian move's stop are made of.

A lin or circ move stops on its line or arc: :class:`runtime.motion.cartesian.PathStop`
(beside the move's :class:`~runtime.motion.cartesian.JointStream`, whose kinematics it
solves), a :class:`JerkStop` of the path parameter.

Real-time safe: made and sampled in the loop (plain floats).
"""
from __future__ import annotations

from math import sqrt

from runtime.motion.trajectory import Trajectory

__all__ = ["REST_VELOCITY", "JerkStop", "LineStop", "StopRamp"]


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
