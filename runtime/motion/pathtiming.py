"""Timing a Cartesian path within every joint's limits, slower only where the joints
need it (issue 14): a jerk-limited path-speed profile with a speed limit that varies
along the path.

The idea is the one of time-optimal path parameterisation (TOPP): along a path ``s``
(mm), a joint's motion is ``q(s)``, so at path speed ``v``, acceleration ``a`` and jerk
``j``

    dq/dt   = q' v
    d2q/dt2 = q'' v^2 + q' a
    d3q/dt3 = q''' v^3 + 3 q'' v a + q' j

(primes: derivatives along ``s``, finite differences of the joints at uniform ``s``
steps of at most 1 mm, taken as their largest magnitude over the neighbouring samples).
Where the joints are far from their limits, the programmed ``speed``, ``acc`` and
``jerk`` bound the path; near a singularity ``q'`` and its derivatives grow and the
joints bound it. So:

1. **A speed limit per sample**: the largest cruise speed ``c`` (no ``a``, no ``j``) at
   which every joint keeps ``share`` of its velocity limit and :data:`CRUISE_SHARE` of
   that share of its acceleration and jerk limits (the rest is left for speeding up and
   slowing down), and at most the programmed ``speed``.
2. **Segments**: consecutive samples whose limits are within a factor
   :data:`GROUP` of each other form one segment, with speed limit ``V`` (their
   smallest), and the path acceleration ``A`` and jerk ``J`` that keep every joint within
   ``share`` of its limits at any speed up to ``V`` (from the gains' bounds above, by the
   segment's largest gains), at most the programmed ``acc`` and ``jerk``.
3. **The profile**: at each boundary the speed is at most both segments' ``V``, and
   reachable from the previous boundary and to the next within each segment's ``A`` and
   ``J`` (a forward and a backward pass, as a controller's look-ahead does); in each
   segment the speed rises to the highest peak that fits (at most ``V``), cruises, and
   falls, each change a jerk-limited S-curve with zero acceleration at both ends (so the
   transitions never cross a boundary: a slow stretch is entered at its speed).

:func:`path_profile` returns a :class:`PathProfile` (``sample(t) -> (s, v, a)``, the
same interface as :class:`runtime.motion.jerk.JerkProfile`), or None when no joint limits
the move anywhere (the time-optimal double-S profile with the programmed limits is then
the move's). The bounds are conservative (sums of magnitudes); the caller still checks
the setpoints on the servo's 1 ms grid (:func:`runtime.motion.cartesian.setpoint_ratios`)
and slows the whole move down should they break a limit after all (rounding, the path
between samples).

Runs once per move when it is planned (NumPy for the samples, a few hundred segments at
most), never in a tick; :meth:`PathProfile.sample` is real-time safe (a bisection over
the pieces and a cubic).
"""
from __future__ import annotations

from bisect import bisect_right
from math import ceil, log, sqrt
from typing import Sequence

import numpy as np

from ..timing import TICK

__all__ = ["CRUISE_SHARE", "GROUP", "ConstantSpeed", "PathProfile", "nominal_profile", "path_derivatives", "path_gains",
           "path_profile", "predicted_ratios", "uniform_scale"]

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
#: Bisection steps (each halves the interval) for the peaks and boundary speeds.
_BISECT = 60


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
    ``length`` (``cap`` itself when it is at most ``v0`` or fits)."""
    if cap <= v0 or _change_distance(v0, cap, a, j) <= length:
        return cap
    lo, hi = v0, cap
    for _ in range(_BISECT):
        mid = 0.5 * (lo + hi)
        if _change_distance(v0, mid, a, j) <= length:
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
    lo, hi = max(v0, v1), top
    for _ in range(_BISECT):
        mid = 0.5 * (lo + hi)
        if need(mid) <= length:
            lo = mid
        else:
            hi = mid
    return lo


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
                 "_bounds", "_acc", "_jerk")

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

    def stop_limits(self, s: float, v: float) -> tuple[float, float]:
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
        return out

    def __repr__(self) -> str:
        return (f"PathProfile(length={self.length!r}, duration={self.duration!r}, "
                f"segments={len(self._bounds)}, pieces={len(self._t)})")


def path_derivatives(s: np.ndarray, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The joints' first, second and third derivatives along the path (signed; (n, 6)
    arrays) from their values ``joints`` at the uniform path lengths ``s``."""
    h = float(s[1] - s[0])
    d1 = np.gradient(np.asarray(joints, dtype=float), h, axis=0)
    d2 = np.gradient(d1, h, axis=0)
    return d1, d2, np.gradient(d2, h, axis=0)


def predicted_ratios(profile: PathProfile, s: np.ndarray, derivatives, limits) -> tuple[np.ndarray, np.ndarray]:
    """How close the joints come to their ``limits`` along ``profile``, every 1 ms: the
    path length at each instant and a (3, n) array of the largest ratio of any joint's
    velocity, acceleration and jerk to its limit (the chain rule of the module
    docstring with the joints' signed ``derivatives`` along the path, interpolated)."""
    times = np.linspace(0.0, profile.duration, int(profile.duration / TICK) + 2)
    at, v, a, j = profile.states(times)
    vmax, amax, jmax = (np.asarray(limit, dtype=float) for limit in limits)
    d1, d2, d3 = derivatives
    ratios = np.zeros((3, len(times)))
    for axis in range(6):
        g1, g2, g3 = (np.interp(at, s, d[:, axis]) for d in (d1, d2, d3))
        ratios[0] = np.maximum(ratios[0], np.abs(g1 * v) / vmax[axis])
        ratios[1] = np.maximum(ratios[1], np.abs(g2 * v * v + g1 * a) / amax[axis])
        ratios[2] = np.maximum(ratios[2], np.abs(g3 * v * v * v + 3.0 * g2 * v * a + g1 * j) / jmax[axis])
    return at, ratios


def _room(ratios: np.ndarray, share: float) -> np.ndarray:
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
                  share: float) -> float:
    """The largest k <= 1 such that the programmed double-S profile run k times slower
    keeps every joint within ``share`` of its ``limits`` (predicted every 1 ms)."""
    length = float(s[-1])
    _at, ratios = predicted_ratios(nominal_profile(length, speed, acc, jerk), s, derivatives, limits)
    return min(1.0, float(np.min(_room(ratios, share))))


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
    starts = [0] + [int(i) for i in np.flatnonzero(np.diff(levels)) + 1]
    bounds, tops, accs, jerks = [], [], [], []
    for k, a in enumerate(starts):
        b = starts[k + 1] if k + 1 < len(starts) else n - 1  # its samples: a..b (b is the next one's first)
        span = slice(a, b + 1)
        top = float(np.min(cruise[span]))
        G1, G2, G3 = (np.max(g[span], axis=0) for g in (g1, g2, g3))
        with np.errstate(divide="ignore", invalid="ignore"):
            room_a = amax - G2 * top * top
            room_j = jmax - G3 * top ** 3
            seg_acc = min(acc, float(np.min(np.where(G1 > 0.0, room_a / G1, np.inf))),
                          float(np.min(np.where(G2 > 0.0, room_j / (6.0 * G2 * top), np.inf))))
            seg_jerk = min(jerk, float(np.min(np.where(G1 > 0.0, (room_j - 3.0 * G2 * top * seg_acc) / G1, np.inf))))
        if not (seg_acc > 0.0 and seg_jerk > 0.0):
            return None
        bounds.append(float(s[a]))
        tops.append(top)
        accs.append(seg_acc)
        jerks.append(seg_jerk)
    if all(t >= speed for t in tops) and all(x >= acc for x in accs) and all(x >= jerk for x in jerks):
        return None
    if derivatives is None:
        derivatives = path_derivatives(s, joints)
    profile = _build(length, bounds, tops, accs, jerks)
    best = profile
    for _ in range(REFINEMENTS):  # each segment corrected by how close its joints really come
        at, ratios = predicted_ratios(profile, s, derivatives, limits)
        if float(np.max(ratios)) <= share * (1.0 + 1e-9) and profile.duration < best.duration:
            best = profile
        factors = np.full(len(bounds), 2.0)
        np.minimum.at(factors, np.clip(np.searchsorted(bounds, at, side="right") - 1, 0, len(bounds) - 1),
                      _room(ratios, share))
        factors = np.clip(factors, 0.5, 2.0)
        if np.all(np.abs(factors - 1.0) < SETTLED):
            break
        tops = [min(speed, t * f) for t, f in zip(tops, factors)]
        accs = [min(acc, x * f * f) for x, f in zip(accs, factors)]
        jerks = [min(jerk, x * f * f * f) for x, f in zip(jerks, factors)]
        profile = _build(length, bounds, tops, accs, jerks)
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
