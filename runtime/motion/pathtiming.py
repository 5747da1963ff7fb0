"""Timing a Cartesian path within every joint's limits, slower only where the joints
need it (issue 14).

The idea is the one of time-optimal path parameterisation (TOPP): along a path ``s``
(mm), a joint's motion is ``q(s)``, so at path speed ``v``, acceleration ``a`` and jerk
``j``

    dq/dt   = q' v
    d2q/dt2 = q'' v^2 + q' a
    d3q/dt3 = q''' v^3 + 3 q'' v a + q' j

(primes: derivatives along ``s``, finite differences of the joints at uniform ``s``
steps of at most 1 mm: :func:`path_derivatives`; :func:`joint_ratios` is this chain
rule, as ratios to the limits). Where the joints are far from their limits, the
programmed ``speed``, ``acc`` and ``jerk`` bound the path; near a singularity ``q'`` and
its derivatives grow and the joints bound it. Three timings, each within ``share`` of
every joint's limits and within the programmed ``speed``, ``acc`` and ``jerk``; the
planner (:func:`runtime.motion.cartesian.timed_path`) takes the shortest:

* **Uniform** (:func:`uniform_scale`): the programmed double-S profile run k times
  slower (speed x k, acceleration x k^2, jerk x k^3), k the smallest room over the move.
  It also gives a lower bound of what any local slowdown could reach: when that is not
  clearly shorter, the two below are not tried.
* **Segments** (:func:`path_profile`, a :class:`PathProfile`): best where the joints
  need a short stretch slowed a lot (a move that starts next to the wrist singularity).

  1. *A speed limit per sample*: the largest cruise speed ``c`` (no ``a``, no ``j``) at
     which every joint keeps ``share`` of its velocity limit and :data:`CRUISE_SHARE` of
     that share of its acceleration and jerk limits (the rest is left for speeding up
     and slowing down), and at most the programmed ``speed``.
  2. *Segments*: consecutive samples whose limits are within a factor :data:`GROUP` of
     each other form one segment, with speed limit ``V`` (their smallest), and the path
     acceleration ``A`` and jerk ``J`` that keep every joint within ``share`` of its
     limits at any speed up to ``V`` (from the magnitudes of the derivatives, the
     segment's largest), at most the programmed ``acc`` and ``jerk``.
  3. *The profile*: at each boundary the speed is at most both segments' ``V``, and
     reachable from the previous boundary and to the next within each segment's ``A``
     and ``J`` (a forward and a backward pass, as a controller's look-ahead does); in
     each segment the speed rises to the highest peak that fits (at most ``V``),
     cruises, and falls, each change a jerk-limited S-curve with zero acceleration at
     both ends (so the transitions never cross a boundary: a slow stretch is entered at
     its speed). Each segment's limits are then corrected (REFINEMENTS times) by the
     room the joints really have in it, predicted every 2 ms.

* **Warp** (:func:`warped_profile`, a :class:`WarpedProfile`): best where the joints
  limit much of the move by different amounts. The programmed profile's time runs
  slower by a factor ``kappa(tau) <= 1`` that varies smoothly: at most, at each instant,
  the room the joints have there (``kappa`` constant is the uniform timing), changing
  slowly enough that the path's acceleration stays within ``acc`` (a forward and a
  backward pass on ``kappa^2``), smoothed (SMOOTHINGS times: a minimum, then a mean,
  over WARP_SMOOTHING), and lowered where the joints or the path would still break
  their share (WARP_ROUNDS times), judged at the knots (every WARP_KNOTS of programmed
  time and on every switch of its jerk) and halfway between them.

Each profile has ``sample(t) -> (s, v, a)``, the interface of
:class:`runtime.motion.jerk.JerkProfile`, plus vectorised :meth:`PathProfile.states`,
:meth:`PathProfile.times_at`, :meth:`PathProfile.stop_limits` (what a stop on the path
may use where it runs) and :meth:`PathProfile.scaled`. The caller still checks the
setpoints on the servo's 1 ms grid (:func:`runtime.motion.cartesian.setpoint_ratios`)
and slows the whole move down should they break a limit after all (rounding, the path
between samples).

Runs once per move when it is planned (NumPy over the samples and knots), never in a
tick; ``sample`` is real-time safe (a bisection and a polynomial in plain floats).
"""
from __future__ import annotations

from bisect import bisect_right
from math import cbrt, ceil, inf, log, sqrt
from typing import Sequence

import numpy as np

from runtime.timing import TICK

__all__ = ["CRUISE_SHARE", "GROUP", "ConstantSpeed", "PathDerivatives", "PathProfile", "WarpedProfile", "joint_ratios",
           "nominal_profile", "path_derivatives", "path_gains", "path_profile", "predicted_ratios", "uniform_scale",
           "warped_profile"]

#: The share of a joint's (share of its) acceleration and jerk limit a segment's cruise
#: speed may use; the rest is for speeding up and slowing down within the segment.
CRUISE_SHARE = 0.75
#: Samples whose speed limits are within this factor of each other form one segment.
GROUP = 0.85
#: The corrections stop when every segment's factor is within this of 1.
SETTLED = 0.01
#: Times a profile's segment limits are corrected by what the joints would really do
#: (:func:`predicted_ratios`: the bounds that built it add magnitudes, conservatively).
REFINEMENTS = 3
#: Decelerations a stop on a timed path tries, from the programmed one down to
#: STOP_LOWEST of it (geometrically spaced), for the largest that keeps every joint's share.
STOP_SCAN = 12
STOP_LOWEST = 0.05
#: Ramps a stop by slowing the profile down (:meth:`PathProfile.ramp_stop`) tries, each
#: this many times longer than the last.
RAMP_TRIES = 8
RAMP_GROWTH = 1.4
#: Bisection steps (each halves the interval) for the peaks and boundary speeds.
_BISECT = 40


class ConstantSpeed:
    """``s(t) = t`` over ``[0, length]``: a profile at unit speed, so that a path check
    (:func:`runtime.motion.pathcheck.check_path`) samples the path uniformly in ``s``."""

    __slots__ = ("duration", "peak_velocity", "t_acc")

    def __init__(self, length: float):
        self.duration = float(length)
        self.peak_velocity = 1.0
        self.t_acc = 0.0

    def sample(self, t: float) -> tuple[float, float, float]:
        if t >= self.duration:
            return (self.duration, 0.0, 0.0)
        if not t > 0.0:
            return (0.0, 0.0, 0.0)
        return (t, 1.0, 0.0)


def path_gains(joints: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(g1, g2, g3)``: per sample and axis, the magnitude of the joints' first, second
    and third derivatives along the path (deg/mm, deg/mm^2, deg/mm^3) from the joints
    ``joints`` (an (n, 6) array, n >= 4) at uniform steps of ``h`` mm: finite differences,
    each sample taking the largest of those around it and its neighbours'."""
    q = np.asarray(joints, dtype=float)
    n = len(q)
    idx = np.arange(n)
    d1 = np.abs(np.diff(q, axis=0)) / h  # intervals i..i+1
    d2 = np.abs(np.diff(q, 2, axis=0)) / (h * h)  # centred at samples 1..n-2
    d3 = np.abs(np.diff(q, 3, axis=0)) / (h * h * h)  # centred between samples k+1 and k+2
    g1 = np.maximum(d1[np.clip(idx - 1, 0, n - 2)], d1[np.clip(idx, 0, n - 2)])
    g2 = d2[np.clip(idx - 1, 0, n - 3)]
    g3 = np.maximum(d3[np.clip(idx - 2, 0, n - 4)], d3[np.clip(idx - 1, 0, n - 4)])
    return _widen(g1), _widen(g2), _widen(g3)


def _widen(g: np.ndarray) -> np.ndarray:
    """Each sample's value: the largest of its own and its two neighbours'."""
    out = g.copy()
    out[1:] = np.maximum(out[1:], g[:-1])
    out[:-1] = np.maximum(out[:-1], g[1:])
    return out


# ---------------------------------------------------------------------------- S-curves


def _change_time(dv: float, a: float, j: float) -> float:
    """The duration of a jerk-limited speed change by ``dv >= 0`` (zero acceleration at
    both ends) within acceleration ``a`` and jerk ``j``."""
    if dv * j <= a * a:
        return 2.0 * sqrt(dv / j)
    return dv / a + a / j


def _change_distance(v0: float, v1: float, a: float, j: float) -> float:
    """The path length the change from ``v0`` to ``v1`` takes (the S-curve is point
    symmetric: the mean speed times its duration)."""
    return 0.5 * (v0 + v1) * _change_time(abs(v1 - v0), a, j)


def _change_pieces(v0: float, v1: float, a: float, j: float) -> list[tuple[float, float]]:
    """The ``(duration, jerk)`` pieces of the change from ``v0`` to ``v1``."""
    dv = v1 - v0
    if dv == 0.0:
        return []
    sign = 1.0 if dv > 0.0 else -1.0
    dv = abs(dv)
    if dv * j <= a * a:
        tj, ta = sqrt(dv / j), 0.0
    else:
        tj, ta = a / j, dv / a - a / j
    return [(tj, sign * j), (ta, 0.0), (tj, -sign * j)]


def _reach(v0: float, cap: float, length: float, a: float, j: float) -> float:
    """The highest speed up to ``cap`` that a change from ``v0`` reaches within
    ``length`` (``cap`` itself when it is at most ``v0`` or fits). Closed form: with ``x``
    the gain, ``(2 v0 + x) sqrt(x / j) = length`` (a cubic in ``sqrt(x)``) while the
    acceleration does not reach ``a``, else ``(2 v0 + x) (x / a + a / j) = 2 length``
    (a quadratic)."""
    if cap <= v0 or _change_distance(v0, cap, a, j) <= length:
        return cap
    p, q = 2.0 * v0, -length * sqrt(j)  # y^3 + p y + q = 0, y = sqrt(x): one real root (p >= 0)
    d = sqrt(q * q / 4.0 + p * p * p / 27.0)
    y = cbrt(-q / 2.0 + d) + cbrt(-q / 2.0 - d)
    x = y * y
    if x * j > a * a:
        b = 2.0 * v0 / a + a / j
        c = 2.0 * v0 * a / j - 2.0 * length
        x = 2.0 * -c / (b + sqrt(b * b - 4.0 * c / a))  # (the root of x^2 / a + b x + c, without cancellation)
    out = min(v0 + max(x, 0.0) * (1.0 - 1e-6), cap)  # (to stay within ``length`` despite rounding)
    if _change_distance(v0, out, a, j) <= length:
        return out
    return _largest(v0, out, lambda u: _change_distance(v0, u, a, j) <= length)  # (not expected)


def _largest(lo: float, hi: float, fits) -> float:
    """The largest value in ``lo .. hi`` that ``fits`` (true at ``lo``, monotone), to
    _BISECT halvings."""
    for _ in range(_BISECT):
        mid = 0.5 * (lo + hi)
        if fits(mid):
            lo = mid
        else:
            hi = mid
    return lo


def _peak(v0: float, v1: float, top: float, length: float, a: float, j: float) -> float:
    """The highest speed up to ``top`` that a segment of ``length`` entered at ``v0`` and
    left at ``v1`` can rise to (at least ``max(v0, v1)``, which the passes made fit)."""
    def need(u: float) -> float:
        return _change_distance(v0, u, a, j) + _change_distance(u, v1, a, j)

    if need(top) <= length:
        return top
    return _largest(max(v0, v1), top, lambda u: need(u) <= length)


# ---------------------------------------------------------------------------- the profile


class PathProfile:
    """A path-speed profile made of constant-jerk pieces, from rest at ``s = 0`` to rest at
    ``s = length``: ``sample(t) -> (s, v, a)``, ``duration``, ``peak_velocity``,
    ``t_acc`` (the shorter of its first speed-up and its last slow-down: what blending
    overlaps), and per segment the path acceleration and jerk that keep the joints within
    their limits (:meth:`stop_limits`: what a stop on the path may use).

    Built by :func:`path_profile`; :meth:`scaled` gives the same profile run ``k`` times
    slower in time."""

    __slots__ = ("length", "duration", "peak_velocity", "t_acc", "_t", "_s", "_v", "_a", "_j",
                 "_bounds", "_acc", "_jerk", "_envelope")

    def __init__(self, length: float, pieces: Sequence[tuple[float, float]], bounds: Sequence[float],
                 acc: Sequence[float], jerk: Sequence[float], t_acc: float):
        self.length = length
        ts, ss, vs, as_, js = [], [], [], [], []
        t = s = v = a = 0.0
        peak = 0.0
        for duration, j in pieces:
            if not duration > 0.0:
                continue
            ts.append(t), ss.append(s), vs.append(v), as_.append(a), js.append(j)
            s += duration * (v + duration * (0.5 * a + duration * j / 6.0))
            v += duration * (a + 0.5 * duration * j)
            a += duration * j
            t += duration
            peak = max(peak, v)
        self._t, self._s, self._v, self._a, self._j = ts, ss, vs, as_, js
        self.duration = t
        self.peak_velocity = peak
        self.t_acc = t_acc
        self._bounds, self._acc, self._jerk = list(bounds), list(acc), list(jerk)
        self._envelope = None

    def sample(self, t: float) -> tuple[float, float, float]:
        """Path length, speed and acceleration at ``t``: 0 at rest before the start,
        exactly ``length`` at rest from ``duration`` on. Real-time safe."""
        if t >= self.duration:
            return (self.length, 0.0, 0.0)
        if not t > 0.0 or not self._t:
            return (0.0, 0.0, 0.0)
        i = bisect_right(self._t, t) - 1
        u = t - self._t[i]
        a, j = self._a[i], self._j[i]
        s = self._s[i] + u * (self._v[i] + u * (0.5 * a + u * j / 6.0))
        return (min(s, self.length), self._v[i] + u * (a + 0.5 * u * j), a + u * j)

    def sample_many(self, times: np.ndarray) -> np.ndarray:
        """The path lengths at ``times`` (an array), as :meth:`sample` gives them."""
        return self.states(times)[0]

    def states(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Path length, speed, acceleration and jerk at ``times`` (an array; at rest
        outside the profile)."""
        times = np.asarray(times, dtype=float)
        if not self._t:
            zeros = np.zeros(len(times))
            return np.where(times >= self.duration, self.length, 0.0), zeros, zeros, zeros
        i = np.clip(np.searchsorted(self._t, times, side="right") - 1, 0, len(self._t) - 1)
        u = np.clip(times, 0.0, self.duration) - np.asarray(self._t)[i]
        v0, a0, j = np.asarray(self._v)[i], np.asarray(self._a)[i], np.asarray(self._j)[i]
        s = np.asarray(self._s)[i] + u * (v0 + u * (0.5 * a0 + u * j / 6.0))
        inside = (times > 0.0) & (times < self.duration)
        s = np.where(times >= self.duration, self.length, np.where(inside, np.minimum(s, self.length), 0.0))
        return (s, np.where(inside, v0 + u * (a0 + 0.5 * u * j), 0.0), np.where(inside, a0 + u * j, 0.0),
                np.where(inside, j, 0.0))

    def times_at(self, s: np.ndarray) -> np.ndarray:
        """The times at which the profile reaches the path lengths ``s`` (an array; s(t)
        never decreases): interpolated between its samples every 1 ms, then two Newton
        steps where it moves."""
        s = np.asarray(s, dtype=float)
        grid = np.linspace(0.0, self.duration, max(ceil(self.duration / TICK), 2) + 1)
        out = np.interp(s, self.sample_many(grid), grid)
        for _ in range(2):
            at, v, _a, _j = self.states(out)
            moving = v > 1e-9 * max(self.peak_velocity, 1e-300)
            out = np.where(moving, np.clip(out - (at - s) / np.where(moving, v, 1.0), 0.0, self.duration), out)
        out[s <= 0.0] = 0.0
        out[s >= self.length] = self.duration
        return out

    def stop_limits(self, s: float, v: float, a: float = 0.0) -> tuple[float, float] | None:
        """The path deceleration and jerk a stop from ``s`` at speed ``v`` and acceleration
        ``a`` may use, or None when no stop sooner than the profile's own end keeps every
        joint within its share (the stop is then the rest of the move). Without the
        joints' derivatives along the path (an envelope): the segments' own limits
        (:meth:`_segment_stop_limits`). With them: the largest deceleration from the
        programmed ``acc`` down to STOP_LOWEST of it such that, all along the stretch the
        stop runs through, every joint keeps its share of its acceleration limit (signed
        q'' v(x)^2 + q' a, with v(x) the stop's own speed there: a harder stop asks more
        here but reaches the stretch ahead slower), with the largest jerk (at most the
        programmed) that keeps the joints' jerks within their share, large enough to turn
        the acceleration round before the speed is gone, and stopping before the path's
        end. Runs when a stop is made (a pause, an abort): vectorised passes over the
        samples of the stretch."""
        if self._envelope is None or not v > 0.0:
            return self._segment_stop_limits(s, v)
        at, g1, g2, g3, amax, jmax, acc, jerk = self._envelope
        lo = max(bisect_right(at, s) - 1, 0)
        hi = min(bisect_right(at, s + v * (v / (acc * STOP_LOWEST) + 2.0 * acc / jerk)) + 2, len(at))
        x = np.asarray(at[lo:hi]) - s
        G1, G2, G3 = g1[lo:hi], g2[lo:hi], g3[lo:hi]

        rising = max(a, 0.0)
        # every candidate deceleration at once: (candidates, samples, axes) arrays
        decs = acc * STOP_LOWEST ** (np.arange(STOP_SCAN + 1) / STOP_SCAN)
        dec = decs[:, None, None]
        G1, G2, G3 = G1[None], G2[None], G3[None]

        def speed(j: np.ndarray) -> np.ndarray:  # the stop's speed along the stretch, per candidate
            top = v + rising * rising / (2.0 * j)  # (still speeding up while its acceleration ramps down)
            ramp = top * (rising + dec) / j
            return np.sqrt(np.maximum(top * top - 2.0 * dec * np.maximum(x[None, :, None] - ramp, 0.0), 0.0))

        j = np.full((len(decs), 1, 1), jerk)
        for _ in range(2):  # the jerk each deceleration leaves, and the stretch it then runs
            w = speed(j)
            cubic = G3 * w ** 3
            worst = np.maximum(np.abs(cubic - 3.0 * G2 * w * dec), np.abs(cubic + 3.0 * G2 * w * rising))
            with np.errstate(divide="ignore", invalid="ignore"):
                room = np.where(G1 != 0.0, (jmax - worst) / np.abs(G1), np.inf)
            j = np.minimum(jerk, np.min(room, axis=(1, 2)))[:, None, None]
            j = np.where(j > 0.0, j, jerk * STOP_LOWEST)
        jerks = j[:, 0, 0]
        w2 = G2 * speed(j) ** 2  # (signed: q'' v^2 and q' a, the stop's a from ``a`` to -dec)
        over = np.maximum(np.max(np.abs(w2 - G1 * dec) / amax, axis=(1, 2)),
                          np.max(np.abs(w2 + G1 * rising) / amax, axis=(1, 2)))
        ok = ((room.min(axis=(1, 2)) > 0.0) & (over <= 1.0)
              # a jerk too small to turn the acceleration round before the speed is gone
              # would end the stop still braking
              & (jerks * v >= np.maximum(abs(a), decs) ** 2)
              & (v * v / (2.0 * decs) + 2.0 * v * decs / jerks <= self.length - s))
        if not np.any(ok):
            return None
        k = int(np.argmax(ok))  # the largest deceleration that fits
        return float(decs[k]), float(jerks[k])

    def ramp_stop(self, t: float) -> "RampStop | None":
        """A stop on the path from ``t`` (a pause, an abort) that runs this profile's own
        time law ever slower (:class:`RampStop`): the shortest ramp of RAMP_TRIES, each
        RAMP_GROWTH times longer than the last, that keeps the path's acc and jerk and
        every joint its share of its acceleration and jerk limits (the envelope's),
        predicted every half millisecond; None when none does before the move's own end
        would (or without the joints' derivatives, or at rest). For where no braking law
        fits (near the limits, by a singularity): slowing the profile down keeps what the
        profile keeps, and the ramp adds what its own rate change asks."""
        envelope = self._envelope
        if envelope is None or not 0.0 <= t < self.duration:
            return None
        _s0, v0, _a0 = self.sample(t)
        if not v0 > 0.0:
            return None
        ramp = max(1.875 * v0 / envelope[6], 2.0 * TICK)  # (the ramp alone decelerates at most 1.875 v0 / D)
        for _ in range(RAMP_TRIES):
            if ramp >= self.duration - t:
                return None  # (the move's own end comes sooner)
            stop = RampStop(self, t, ramp)
            times = np.linspace(0.0, ramp, max(int(ramp / (0.5 * TICK)), 2) + 1)
            if within_envelope(*stop.states(times), envelope):
                return stop
            ramp *= RAMP_GROWTH
        return None

    def _segment_stop_limits(self, s: float, v: float) -> tuple[float, float]:
        """The path acceleration and jerk a stop from ``s`` at speed ``v`` may use: the
        smallest of the segments it may run through (those within the stop's length at
        the current segment's limits, again with the smaller limits)."""
        bounds = self._bounds
        first = max(bisect_right(bounds, s) - 1, 0)
        acc, jerk = self._acc[first], self._jerk[first]
        for _ in range(3):
            reach = s + v * (v / acc + acc / jerk)  # at least the stop's length
            last = max(bisect_right(bounds, reach) - 1, first)
            a2, j2 = min(self._acc[first:last + 1]), min(self._jerk[first:last + 1])
            if a2 == acc and j2 == jerk:
                break
            acc, jerk = a2, j2
        return acc, jerk

    def scaled(self, k: float) -> "PathProfile":
        """The same profile run ``k`` times slower in time (speeds x k, accelerations x
        k^2, jerks x k^3)."""
        out = PathProfile.__new__(PathProfile)
        out.length = self.length
        out._t = [t / k for t in self._t]
        out._s = list(self._s)
        out._v = [v * k for v in self._v]
        out._a = [a * k * k for a in self._a]
        out._j = [j * k * k * k for j in self._j]
        out.duration = self.duration / k
        out.peak_velocity = self.peak_velocity * k
        out.t_acc = self.t_acc / k
        out._bounds = self._bounds
        out._acc = [a * k * k for a in self._acc]
        out._jerk = [j * k * k * k for j in self._jerk]
        out._envelope = scaled_envelope(self._envelope, k)
        return out

    def __repr__(self) -> str:
        return (f"PathProfile(length={self.length!r}, duration={self.duration!r}, "
                f"segments={len(self._bounds)}, pieces={len(self._t)})")


class RampStop:
    """A stop on the path by running ``profile``'s time law from its time ``t0`` ever
    slower: the rate falls from 1 to 0 as a quintic smoothstep over ``ramp`` seconds
    (continuous in rate, its derivative and second derivative, all 0 at the end), so the
    path's speed is v(tau) r, its acceleration a r^2 + v r' and its jerk j r^3 + 3 a r r' +
    v r'', tau the profile's time; it covers half the ramp of the profile's time. As
    :class:`runtime.motion.stops.JerkStop` gives one: ``sample(t) -> (distance from where
    it starts, speed, acceleration)``, ``duration``, ``distance``. Real-time safe."""

    __slots__ = ("duration", "distance", "_profile", "_t0", "_s0")

    def __init__(self, profile, t0: float, ramp: float):
        self._profile, self._t0, self.duration = profile, t0, ramp
        self._s0 = profile.sample(t0)[0]
        self.distance = profile.sample(t0 + 0.5 * ramp)[0] - self._s0

    def sample(self, t: float) -> tuple[float, float, float]:
        if t >= self.duration:
            return (self.distance, 0.0, 0.0)
        t = max(t, 0.0)
        d = self.duration
        u = t / d
        rate = 1.0 - u * u * u * (10.0 + u * (6.0 * u - 15.0))
        slope = -30.0 * u * u * (1.0 - u) * (1.0 - u) / d
        s, v, a = self._profile.sample(self._t0 + t - d * u * u * u * u * (2.5 + u * (u - 3.0)))
        return (s - self._s0, v * rate, a * rate * rate + v * slope)

    def states(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The path length (absolute), speed, acceleration and jerk at the stop's ``times``."""
        d = self.duration
        u = np.clip(np.asarray(times, dtype=float) / d, 0.0, 1.0)
        rate = 1.0 - u ** 3 * (10.0 + u * (6.0 * u - 15.0))
        slope = -30.0 * u * u * (1.0 - u) ** 2 / d
        bend = -60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / (d * d)
        s, v, a, j = self._profile.states(self._t0 + u * d - d * u ** 4 * (2.5 + u * (u - 3.0)))
        return s, v * rate, a * rate * rate + v * slope, j * rate ** 3 + 3.0 * a * rate * slope + v * bend


def within_envelope(s: np.ndarray, v: np.ndarray, a: np.ndarray, j: np.ndarray, envelope: tuple) -> bool:
    """Whether the path states (lengths ``s``, speeds ``v``, accelerations ``a``, jerks
    ``j``) keep the ``envelope``'s acc and jerk and every joint within its acceleration and
    jerk limits there (a stop's check: velocities only fall)."""
    at, g1, g2, g3, amax, jmax, acc, jerk = envelope
    if np.max(np.abs(a)) > acc * (1.0 + 1e-9) or np.max(np.abs(j)) > jerk * (1.0 + 1e-9):
        return False
    ratios = joint_ratios(s, v, a, j, np.asarray(at), (g1, g2, g3), (np.full(len(amax), np.inf), amax, jmax))
    return bool(np.max(ratios[1:]) <= 1.0)


class PathDerivatives:
    """The joints' first, second and third derivatives along the path (signed; (n, 6)
    arrays ``d1``, ``d2``, ``d3``; unpacks as the three) at the path lengths ``s``, with
    :meth:`at`: all three anywhere along it, interpolated linearly."""

    __slots__ = ("s", "d1", "d2", "d3", "_base", "_slope")

    def __init__(self, s: np.ndarray, d1: np.ndarray, d2: np.ndarray, d3: np.ndarray):
        self.s, self.d1, self.d2, self.d3 = s, d1, d2, d3
        stacked = np.concatenate([d1, d2, d3], axis=1)
        self._base = stacked[:-1]
        self._slope = np.diff(stacked, axis=0) / np.diff(s)[:, None]

    def __iter__(self):
        return iter((self.d1, self.d2, self.d3))

    def at(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The three at the path lengths ``x`` (an array): (len(x), 6) arrays."""
        s = self.s
        i = np.clip(np.searchsorted(s, x, side="right") - 1, 0, len(s) - 2)
        g = self._base[i] + (np.clip(x, s[0], s[-1]) - s[i])[:, None] * self._slope[i]
        return g[:, :6], g[:, 6:12], g[:, 12:]


def path_derivatives(s: np.ndarray, joints: np.ndarray) -> PathDerivatives:
    """The joints' first, second and third derivatives along the path from their values
    ``joints`` at the uniform path lengths ``s``."""
    h = float(s[1] - s[0])
    d1 = np.gradient(np.asarray(joints, dtype=float), h, axis=0)
    d2 = np.gradient(d1, h, axis=0)
    return PathDerivatives(np.asarray(s, dtype=float), d1, d2, np.gradient(d2, h, axis=0))


def predicted_ratios(profile: PathProfile, s: np.ndarray, derivatives, limits,
                     step: float = TICK) -> tuple[np.ndarray, np.ndarray]:
    """How close the joints come to their ``limits`` along ``profile``, every ``step`` s: the
    path length at each instant and a (3, n) array of the largest ratio of any joint's
    velocity, acceleration and jerk to its limit (the chain rule of the module
    docstring with the joints' signed ``derivatives`` along the path, interpolated)."""
    times = np.linspace(0.0, profile.duration, int(profile.duration / step) + 2)
    at, v, a, j = profile.states(times)
    return at, joint_ratios(at, v, a, j, s, derivatives, limits)


def joint_ratios(at: np.ndarray, v: np.ndarray, a: np.ndarray, j: np.ndarray, s: np.ndarray, derivatives,
                 limits) -> np.ndarray:
    """The (3, n) array of :func:`predicted_ratios` for path states: lengths ``at``,
    speeds ``v``, accelerations ``a`` and jerks ``j`` (arrays)."""
    vmax, amax, jmax = (np.asarray(limit, dtype=float) for limit in limits)
    if not isinstance(derivatives, PathDerivatives):
        derivatives = PathDerivatives(np.asarray(s, dtype=float), *derivatives)
    g1, g2, g3 = derivatives.at(at)  # (interpolated linearly between the samples)
    v, a, j = v[:, None], a[:, None], j[:, None]
    ratios = np.empty((3, len(at)))
    ratios[0] = np.max(np.abs(g1 * v) / vmax, axis=1)
    ratios[1] = np.max(np.abs(g2 * v * v + g1 * a) / amax, axis=1)
    ratios[2] = np.max(np.abs(g3 * v * v * v + 3.0 * g2 * v * a + g1 * j) / jmax, axis=1)
    return ratios


def time_room(ratios: np.ndarray, share: float) -> np.ndarray:
    """Per instant, the time scale that brings velocity, acceleration and jerk
    ``ratios`` (a (3, n) array) to ``share``: above 1 where there is room."""
    with np.errstate(divide="ignore"):
        return np.minimum.reduce([share / ratios[0], np.sqrt(share / ratios[1]), np.cbrt(share / ratios[2])])


def nominal_profile(length: float, speed: float, acc: float, jerk: float) -> PathProfile:
    """The time-optimal rest-to-rest double-S profile over ``length`` within ``speed``,
    ``acc`` and ``jerk`` (as :func:`runtime.motion.jerk.time_optimal_profile`, up to
    rounding), with the vectorised :meth:`PathProfile.states`."""
    return _build(length, [0.0], [speed], [acc], [jerk])


def uniform_scale(s: np.ndarray, derivatives, limits, speed: float, acc: float, jerk: float,
                  share: float) -> tuple[float, float]:
    """``(k, fastest)``: the largest k <= 1 such that the programmed double-S profile run
    k times slower keeps every joint within ``share`` of its ``limits`` (predicted every
    1 ms), and a lower bound of the duration of any slowdown that keeps them there at
    every instant (each instant slowed down by its own factor only: what slowing down
    locally could gain at most)."""
    length = float(s[-1])
    nominal = nominal_profile(length, speed, acc, jerk)
    _at, ratios = predicted_ratios(nominal, s, derivatives, limits)
    room = np.minimum(time_room(ratios, share), 1.0)
    step = nominal.duration / max(len(room) - 1, 1)
    return float(np.min(room)), float(np.sum(step / np.maximum(0.5 * (room[1:] + room[:-1]), 1e-300)))


def path_profile(s: np.ndarray, joints: np.ndarray, limits: Sequence[Sequence[float]], speed: float,
                 acc: float, jerk: float, share: float, derivatives=None) -> PathProfile | None:
    """The profile along the path whose joints are ``joints`` (an (n, 6) array) at the
    uniform path lengths ``s`` (0 .. length): within ``speed``, ``acc`` and ``jerk`` and,
    for every joint, ``share`` of ``limits`` (max velocities, accelerations and jerks);
    None when the joints limit the path nowhere (or the path is too short to tell:
    fewer than four samples)."""
    s = np.asarray(s, dtype=float)
    n = len(s)
    length = float(s[-1]) if n else 0.0
    if n < 4 or not length > 0.0:
        return None
    g1, g2, g3 = path_gains(joints, length / (n - 1))
    vmax, amax, jmax = (share * np.asarray(limit, dtype=float) for limit in limits)
    with np.errstate(divide="ignore"):
        cruise = np.minimum.reduce([
            np.full(n, speed),
            np.min(vmax / g1, axis=1),
            np.min(np.sqrt(CRUISE_SHARE * amax / g2), axis=1),
            np.min(np.cbrt(CRUISE_SHARE * jmax / g3), axis=1),
        ])
    if not np.all(cruise > 0.0):
        return None  # (a joint's gain is not finite: the check refuses such a path)
    levels = np.floor(np.log(speed / cruise) / -log(GROUP) + 1e-9).astype(int)
    starts = np.concatenate([[0], np.flatnonzero(np.diff(levels)) + 1])
    nxt = np.append(starts[1:], n - 1)  # each segment's samples: its start .. the next one's start

    def spans(x: np.ndarray, reduce) -> np.ndarray:  # per segment, over its samples
        return reduce(reduce.reduceat(x, starts, axis=0), x[nxt])

    top = spans(cruise, np.minimum)
    G1, G2, G3 = (spans(g, np.maximum) for g in (g1, g2, g3))  # (segments, 6)
    t1 = top[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        room_a = amax - G2 * t1 * t1
        room_j = jmax - G3 * t1 ** 3
        seg_acc = np.minimum.reduce([np.full(len(top), acc),
                                     np.min(np.where(G1 > 0.0, room_a / G1, np.inf), axis=1),
                                     np.min(np.where(G2 > 0.0, room_j / (6.0 * G2 * t1), np.inf), axis=1)])
        seg_jerk = np.minimum(jerk, np.min(np.where(G1 > 0.0, (room_j - 3.0 * G2 * t1 * seg_acc[:, None]) / G1,
                                                    np.inf), axis=1))
    if not (np.all(seg_acc > 0.0) and np.all(seg_jerk > 0.0)):
        return None
    bounds, tops, accs, jerks = s[starts].tolist(), top.tolist(), seg_acc.tolist(), seg_jerk.tolist()
    if all(t >= speed for t in tops) and all(x >= acc for x in accs) and all(x >= jerk for x in jerks):
        return None
    if derivatives is None:
        derivatives = path_derivatives(s, joints)
    best = profile = _build(length, bounds, tops, accs, jerks)  # (within the bounds: conservative)
    for rounds in range(REFINEMENTS + 1):  # each segment corrected by how close its joints really come
        at, ratios = predicted_ratios(profile, s, derivatives, limits, 2 * TICK)
        if float(np.max(ratios)) <= share * (1.0 + 1e-9) and profile.duration < best.duration:
            best = profile
        if rounds == REFINEMENTS:
            break
        factors = np.full(len(bounds), 2.0)
        np.minimum.at(factors, np.clip(np.searchsorted(bounds, at, side="right") - 1, 0, len(bounds) - 1),
                      time_room(ratios, share))
        factors = np.clip(factors, 0.5, 2.0)
        if np.all(np.abs(factors - 1.0) < SETTLED):
            break
        tops = [min(speed, t * f) for t, f in zip(tops, factors)]
        accs = [min(acc, x * f * f) for x, f in zip(accs, factors)]
        jerks = [min(jerk, x * f * f * f) for x, f in zip(jerks, factors)]
        profile = _build(length, bounds, tops, accs, jerks)
    best._envelope = stop_envelope(s, derivatives, limits, share, acc, jerk)
    return best


def _build(length: float, bounds: list, tops: list, accs: list, jerks: list) -> PathProfile:
    """The profile over segments starting at ``bounds`` (the last ends at ``length``) with
    speed limits ``tops`` and path accelerations ``accs`` and jerks ``jerks`` (module
    docstring, step 3)."""
    m = len(bounds)
    ends = bounds[1:] + [length]
    lengths = [e - b for b, e in zip(bounds, ends)]
    w = [0.0] + [min(tops[k - 1], tops[k]) for k in range(1, m)] + [0.0]
    for k in range(m):  # forward: what speeding up within each segment reaches
        w[k + 1] = min(w[k + 1], _reach(w[k], w[k + 1], lengths[k], accs[k], jerks[k]))
    for k in reversed(range(m)):  # backward: what slowing down within each segment reaches
        w[k] = min(w[k], _reach(w[k + 1], w[k], lengths[k], accs[k], jerks[k]))
    pieces: list[tuple[float, float]] = []
    ramps = []
    for k in range(m):
        a_k, j_k = accs[k], jerks[k]
        u = _peak(w[k], w[k + 1], tops[k], lengths[k], a_k, j_k)
        up, down = _change_pieces(w[k], u, a_k, j_k), _change_pieces(u, w[k + 1], a_k, j_k)
        cruise_length = lengths[k] - _change_distance(w[k], u, a_k, j_k) - _change_distance(u, w[k + 1], a_k, j_k)
        pieces += up
        if u > 0.0 and cruise_length > 0.0:
            pieces.append((cruise_length / u, 0.0))
        pieces += down
        if k == 0:
            ramps.append(sum(d for d, _ in up))
        if k == m - 1:
            ramps.append(sum(d for d, _ in down))
    return PathProfile(length, pieces, bounds, accs, jerks, min(ramps))


# ---------------------------------------------------------------------------- time warp


#: Nominal time (s) over which a warp's slowdown is smoothed (twice: a minimum, then a
#: mean over this window), so that its rate of change is continuous.
WARP_SMOOTHING = 0.04
#: The largest interval (s of nominal time) between a warp's knots: s(t) between them is
#: one quintic (the joints are judged at the knots and halfway between them).
WARP_KNOTS = 4 * TICK
#: Times the slowdown is smoothed: each time it gains a continuous derivative.
SMOOTHINGS = 3
#: Times a warp is corrected where the joints would still come above their share.
WARP_ROUNDS = 4


class WarpedProfile(PathProfile):
    """The programmed double-S profile run slower by a factor that varies smoothly along
    it: ``s(t) = s_n(tau(t))`` with ``dtau/dt = kappa(tau) <= 1`` (``kappa`` constant is the
    uniform slowdown). Known at knots (every WARP_KNOTS of nominal time: real time, path length,
    speed, acceleration), quintic between them (continuous acceleration, jerk piecewise
    quadratic). Same interface as :class:`PathProfile`; the path acceleration and jerk a
    stop may use come from ``envelope`` (:meth:`PathProfile.stop_limits`).
    :meth:`sample` is real-time safe (a bisection and plain floats)."""

    __slots__ = ("_knots",)

    def __init__(self, length: float, t, s, v, a, acc: float, jerk: float, t_acc: float, envelope: tuple):
        self.length = length
        self._t, self._s, self._v, self._a = (np.asarray(x, dtype=float) for x in (t, s, v, a))
        self._j = None
        self._knots = tuple(x.tolist() for x in (self._t, self._s, self._v, self._a))
        self.duration = float(self._t[-1])
        self.peak_velocity = float(np.max(self._v))
        self.t_acc = t_acc
        self._bounds, self._acc, self._jerk = [0.0], [acc], [jerk]  # (one segment: the programmed limits)
        self._envelope = envelope

    @staticmethod
    def _quintic(h, s0, s1, v0, v1, a0, a1):
        """The quintic from (s0, v0, a0) to (s1, v1, a1) over ``h`` s, in ``u = (t - t0) / h``:
        its coefficients of u^1 .. u^5 (floats or arrays)."""
        d, v0, v1, a0, a1 = s1 - s0, v0 * h, v1 * h, a0 * h * h, a1 * h * h
        return (v0, 0.5 * a0, 10.0 * d - 6.0 * v0 - 4.0 * v1 - 1.5 * a0 + 0.5 * a1,
                -15.0 * d + 8.0 * v0 + 7.0 * v1 + 1.5 * a0 - a1, 6.0 * d - 3.0 * (v0 + v1) - 0.5 * (a0 - a1))

    def sample(self, t: float) -> tuple[float, float, float]:
        if t >= self.duration:
            return (self.length, 0.0, 0.0)
        if not t > 0.0:
            return (0.0, 0.0, 0.0)
        ts, ss, vs, as_ = self._knots
        i = min(bisect_right(ts, t) - 1, len(ts) - 2)
        h = ts[i + 1] - ts[i]
        b1, b2, c3, c4, c5 = self._quintic(h, ss[i], ss[i + 1], vs[i], vs[i + 1], as_[i], as_[i + 1])
        u = (t - ts[i]) / h
        s = ss[i] + u * (b1 + u * (b2 + u * (c3 + u * (c4 + u * c5))))
        v = (b1 + u * (2.0 * b2 + u * (3.0 * c3 + u * (4.0 * c4 + u * 5.0 * c5)))) / h
        a = (2.0 * b2 + u * (6.0 * c3 + u * (12.0 * c4 + u * 20.0 * c5))) / (h * h)
        return (min(s, self.length), v, a)

    def states(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        times = np.asarray(times, dtype=float)
        ts, ss, vs, as_ = self._t, self._s, self._v, self._a
        i = np.clip(np.searchsorted(ts, times, side="right") - 1, 0, len(ts) - 2)
        h = ts[i + 1] - ts[i]
        b1, b2, c3, c4, c5 = self._quintic(h, ss[i], ss[i + 1], vs[i], vs[i + 1], as_[i], as_[i + 1])
        u = (np.clip(times, 0.0, self.duration) - ts[i]) / h
        s = ss[i] + u * (b1 + u * (b2 + u * (c3 + u * (c4 + u * c5))))
        v = (b1 + u * (2.0 * b2 + u * (3.0 * c3 + u * (4.0 * c4 + u * 5.0 * c5)))) / h
        a = (2.0 * b2 + u * (6.0 * c3 + u * (12.0 * c4 + u * 20.0 * c5))) / (h * h)
        j = (6.0 * c3 + u * (24.0 * c4 + u * 60.0 * c5)) / (h * h * h)
        inside = (times > 0.0) & (times < self.duration)
        s = np.where(times >= self.duration, self.length, np.where(inside, np.minimum(s, self.length), 0.0))
        return s, np.where(inside, v, 0.0), np.where(inside, a, 0.0), np.where(inside, j, 0.0)

    def scaled(self, k: float) -> "WarpedProfile":
        out = WarpedProfile.__new__(WarpedProfile)
        out.length = self.length
        out._t, out._s, out._v, out._a, out._j = self._t / k, self._s, self._v * k, self._a * k * k, None
        out._knots = tuple(x.tolist() for x in (out._t, out._s, out._v, out._a))
        out._envelope = scaled_envelope(self._envelope, k)
        out.duration, out.peak_velocity, out.t_acc = self.duration / k, self.peak_velocity * k, self.t_acc / k
        out._bounds = self._bounds
        out._acc = [x * k * k for x in self._acc]
        out._jerk = [x * k * k * k for x in self._jerk]
        return out

    def __repr__(self) -> str:
        return f"WarpedProfile(length={self.length!r}, duration={self.duration!r}, knots={len(self._t)})"


def stop_envelope(s: np.ndarray, derivatives, limits, share: float, acc: float, jerk: float) -> tuple:
    """What :meth:`PathProfile.stop_limits` needs: the samples' path lengths, the joints'
    (signed) derivatives along the path, the joints' shares of their acceleration and jerk
    limits, and the programmed acceleration and jerk."""
    return (s.tolist(),) + tuple(derivatives) + tuple(
        share * np.asarray(limit, dtype=float) for limit in limits[1:]) + (acc, jerk)


def scaled_envelope(envelope, k: float):
    """``envelope`` for the profile run k times slower (the programmed limits scale)."""
    if envelope is None:
        return None
    return envelope[:6] + (envelope[6] * k * k, envelope[7] * k * k * k)


def _eroded(x: np.ndarray, width: int) -> np.ndarray:
    """Each value: the smallest within ``width`` samples either side."""
    padded = np.pad(x, width, mode="edge")
    return np.min(np.lib.stride_tricks.sliding_window_view(padded, 2 * width + 1), axis=1)


def _mean(x: np.ndarray, width: int) -> np.ndarray:
    """Each value: the mean of those within ``width`` samples either side."""
    padded = np.pad(x, width, mode="edge")
    c = np.concatenate([[0.0], np.cumsum(padded)])
    return (c[2 * width + 1:] - c[:-2 * width - 1]) / (2 * width + 1)


def _slope_limited(ceiling: np.ndarray, rise: np.ndarray) -> np.ndarray:
    """The largest sequence under ``ceiling`` whose neighbours differ by at most ``rise``
    (per interval): a forward and a backward pass, vectorised."""
    c = np.concatenate([[0.0], np.cumsum(rise)])
    w = c + np.minimum.accumulate(ceiling - c)
    r = c[-1] - c  # the backward pass, on the reversed sequence
    return np.minimum(w, (r + np.minimum.accumulate((w - r)[::-1])[::-1]))


def _midpoints(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``y`` at the middle of each interval of ``x``: the cubic through the four samples
    around it (three at the ends)."""
    n = len(x)
    if n >= 4:  # where the four are evenly spaced, the cubic's midpoint in closed form
        h = np.diff(x)
        out = np.empty(n - 1)
        out[1:-1] = (9.0 * (y[1:-2] + y[2:-1]) - y[:-3] - y[3:]) / 16.0
        even = np.zeros(n - 1, dtype=bool)
        even[1:-1] = (np.abs(h[:-2] - h[1:-1]) <= 1e-9 * h[1:-1]) & (np.abs(h[2:] - h[1:-1]) <= 1e-9 * h[1:-1])
        for i in np.flatnonzero(~even).tolist():  # (the ends, and a few switches between)
            lo = min(max(i - 1, 0), n - 4)
            xs, ys, xm = x[lo:lo + 4].tolist(), y[lo:lo + 4].tolist(), 0.5 * float(x[i] + x[i + 1])
            out[i] = sum(yk * _lagrange(xs, k, xm) for k, yk in enumerate(ys))
        return out
    return _midpoints_at(x, y, np.arange(n - 1))


def _lagrange(xs: list, k: int, x: float) -> float:
    """The Lagrange basis polynomial of node ``k`` of ``xs`` at ``x``."""
    out = 1.0
    for m, xm in enumerate(xs):
        if m != k:
            out *= (x - xm) / (xs[k] - xm)
    return out


def _midpoints_at(x: np.ndarray, y: np.ndarray, i: np.ndarray) -> np.ndarray:
    """:func:`_midpoints` of the intervals ``i`` (any spacing; fewer than four samples)."""
    n = len(x)
    m = len(i)
    lo = np.clip(i - 1, 0, max(n - 4, 0))
    idx = [np.minimum(lo + k, n - 1) for k in range(4)]
    xm = 0.5 * (x[i] + x[i + 1])
    first = [np.ones(m, dtype=bool)]  # whether each of the four is not a repeat of an earlier one
    for k in range(1, 4):
        fresh = np.ones(m, dtype=bool)
        for q in range(k):
            fresh &= idx[q] != idx[k]
        first.append(fresh)
    out = np.zeros(m)
    for k in range(4):
        weight = np.ones(m)
        for q in range(4):
            if q != k:
                use = first[q] & (idx[q] != idx[k])
                weight = np.where(use, weight * (xm - x[idx[q]]) / np.where(use, x[idx[k]] - x[idx[q]], 1.0), weight)
        out += np.where(first[k], weight * y[idx[k]], 0.0)
    return out


def warped_profile(s: np.ndarray, derivatives, limits, speed: float, acc: float, jerk: float,
                   share: float, beat: float = inf) -> WarpedProfile | None:
    """The programmed profile slowed down by a smooth factor ``kappa`` that is, at each
    instant, at most what keeps every joint within ``share`` of its ``limits`` there (the
    room of :func:`predicted_ratios` at that instant of the programmed profile), and that
    changes slowly enough that the path's acceleration stays within ``acc``; corrected
    (WARP_ROUNDS times) where the joints, or the path's speed, acceleration and jerk,
    would still come above their share (judged at the knots and between them). None when
    the joints limit the path nowhere, or no correction keeps them within it, or none
    would be shorter than ``beat`` (s: each correction only slows it down)."""
    length = float(s[-1])
    nominal = nominal_profile(length, speed, acc, jerk)
    # knots every WARP_KNOTS of nominal time or less, and on every switch of the nominal jerk
    # (a quintic cannot follow a step of the jerk inside an interval)
    switches = sorted(set(nominal._t + [nominal.duration]))
    tau = np.concatenate([np.linspace(a, b, max(ceil((b - a) / WARP_KNOTS), 1) + 1)[:-1]
                          for a, b in zip(switches, switches[1:])] + [[nominal.duration]])
    if len(tau) < 16:
        tau = np.linspace(0.0, nominal.duration, 17)
    dtau = np.diff(tau)
    s_n, v_n, a_n, j_n = nominal.states(tau)
    s_n[-1], v_n[-1], a_n[-1], j_n[-1] = length, 0.0, 0.0, 0.0
    room = time_room(joint_ratios(s_n, v_n, a_n, j_n, s, derivatives, limits), share)
    ceiling = np.minimum(room, 1.0) ** 2  # of w = kappa^2
    if np.all(ceiling >= 1.0):
        return None
    width = max(1, round(WARP_SMOOTHING / WARP_KNOTS))
    envelope = stop_envelope(s, derivatives, limits, share, acc, jerk)
    for _ in range(WARP_ROUNDS):
        # |path acceleration| = |w a_n + v_n w' / 2| <= acc, with w <= ceiling: the slope
        # of w per interval
        top = np.maximum(ceiling[:-1], ceiling[1:])
        with np.errstate(divide="ignore", invalid="ignore"):
            rise = np.where(v_n[:-1] > 0.0, 2.0 * np.maximum(acc - top * np.abs(a_n[:-1]), 0.0) / v_n[:-1], np.inf)
        w = _slope_limited(ceiling, np.minimum(rise * dtau, 1.0))
        for _ in range(SMOOTHINGS):
            w = _mean(_eroded(w, width), width)
        w = np.clip(w, 1e-12, 1.0)
        kappa = np.sqrt(w)
        lam = np.log(kappa)
        d1 = np.gradient(lam, tau)
        # real time: dt = dtau / kappa, by Simpson's rule with kappa at the midpoints from a
        # cubic through the knots around: the knots' times must agree with their speeds
        # and accelerations to far better than 1e-5 (the quintics between them turn a
        # mismatch of 1e-5 into jerks of 1e5 mm/s^3 at 1 ms)
        step = dtau / 6.0 * (1.0 / kappa[:-1] + 4.0 / _midpoints(tau, kappa) + 1.0 / kappa[1:])
        t = np.concatenate([[0.0], np.cumsum(step)])
        v = v_n * kappa
        a = w * (a_n + v_n * d1)
        ramp = float(np.interp(nominal.t_acc, tau, t))
        profile = WarpedProfile(length, t, s_n, v, a, acc, jerk, min(ramp, float(t[-1]) - ramp), envelope)
        if profile.duration >= beat:
            return None
        # judged where it runs: at the knots, and when they pass, halfway between them too
        knots = _warp_ratios(profile, t, s, derivatives, limits, share, speed, acc, jerk)
        over = np.minimum(time_room(knots, share), 1.0)
        if float(np.max(knots)) <= share * (1.0 + 1e-6):  # (the quintics' rounding at a limit)
            middle = _warp_ratios(profile, 0.5 * (t[:-1] + t[1:]), s, derivatives, limits, share, speed, acc,
                                  jerk)
            if float(np.max(middle)) <= share * (1.0 + 1e-6):
                return profile
            room = np.minimum(time_room(middle, share), 1.0)
            over[:-1] = np.minimum(over[:-1], room)
            over[1:] = np.minimum(over[1:], room)
        over = _eroded(over, 2 * width)  # (and around: the smoothing's reach)
        ceiling = np.minimum(ceiling, over * over * w)
    return None


def _warp_ratios(profile: WarpedProfile, times: np.ndarray, s: np.ndarray, derivatives, limits, share: float,
                 speed: float, acc: float, jerk: float) -> np.ndarray:
    """The joints' ratios to their limits along ``profile`` at ``times`` (a (3, n) array,
    as :func:`joint_ratios`), and the path's speed, acceleration and jerk to the
    programmed ones, times ``share``."""
    at, v, a, j = profile.states(times)
    ratios = joint_ratios(at, v, a, j, s, derivatives, limits)
    ratios[0] = np.maximum(ratios[0], share * v / speed)  # the path's: within the programmed
    ratios[1] = np.maximum(ratios[1], share * np.abs(a) / acc)
    ratios[2] = np.maximum(ratios[2], share * np.abs(j) / jerk)
    return ratios
