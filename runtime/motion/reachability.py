"""Near time-optimal timing of a Cartesian path within every joint's velocity, acceleration
and jerk limit (issue 32): TOPP-RA's reachability analysis, made jerk-limited by a moving
average.

**1. Reachability (TOPP-RA).** Along the path's grid ``s_0 .. s_N`` (the check's samples,
uniform), the state is ``x = v^2`` (v the path speed) and the control ``u`` the path
acceleration, constant over each interval: ``x_{i+1} = x_i + 2 h u_i``. At each grid point
the joints' chain rule (``dq/dt = q' v``, ``d2q/dt2 = q'' x + q' u``) and the programmed
limits bound ``(x, u)`` by linear inequalities:

* ``x <= speed^2`` and ``x |q'_j| <= V_j^2 / |q'_j|``: a ceiling on ``x``;
* ``-A_j <= q''_j x + q'_j u <= A_j`` and ``-acc <= u <= acc``: for a given ``x``, ``u`` lies
  in ``[lo(x), hi(x)]``, the largest of lines ``alpha + beta x`` below and the smallest
  above (``beta = -q''_j / q'_j``, ``alpha = -+A_j / |q'_j|``); where they cross, the
  acceleration ceiling of ``x``.

A backward pass gives the largest ``x`` at each point from which the path can still come
to rest at its end (TOPP-RA's controllable sets: the largest ``x_i`` with ``x_i + 2 h lo(x_i)``
within the next point's, solved in closed form, one line per constraint); a forward pass
then takes the largest ``u`` that stays within them. This is TOPP-RA (Pham and Pham,
2018) with its two-variable linear programs solved exactly; its duration is the time
optimum of the discretised problem.

**2. Jerk.** TOPP-RA's acceleration jumps. Its time law ``s(t)`` averaged over a moving
window of ``T`` seconds, ``s_T(t) = (1/T) int_{t-T}^{t} s``, has speed ``(s(t) - s(t-T))/T``,
acceleration ``(v(t) - v(t-T))/T`` and jerk ``(a(t) - a(t-T))/T``: the jerk is bounded by
the largest change of acceleration over ``T`` divided by ``T``, the speed and
acceleration by the largest of the window's; the move takes ``T`` longer. (A trapezoidal
profile averaged over ``acc / jerk`` is exactly the time-optimal double-S profile.) ``T``
is the smallest that keeps the path's jerk within the programmed one.

**3. Corrections.** The average is not exactly within the joints' limits (it runs a
window's average speed through a narrow slow stretch, and the joints' jerks are not the
path's). The joints' ratios are predicted every 1 ms (:func:`joint_ratios`); where a joint
passes its share, the grid's limits there are lowered by the time scale that would bring
it back (velocity x k, acceleration x k^2, jerk x k^3), widened by the window, and the
two steps run again (CORRECTIONS times at most).

Runs once per move when it is planned (NumPy over the grid; the two passes a loop over
six lines per point), never in a tick; :meth:`AveragedProfile.sample` is real-time safe
(two bisections and plain floats).
"""
from __future__ import annotations

from bisect import bisect_right
from math import sqrt
from typing import Sequence

import numpy as np

from runtime.timing import TICK
from runtime.motion.pathtiming import (SETTLED, PathProfile, joint_ratios, scaled_envelope, stop_envelope,
                                      time_room, within_envelope)

__all__ = ["AveragedProfile", "CORRECTIONS", "StopLaw", "reachable_profile", "topp_ra"]

#: Rounds of lowering (and raising) the grid's limits by the room the averaged profile's joints have.
CORRECTIONS = 5
#: Each round lowers a point's limits by the needed time scale times this (a little more,
#: so that few rounds settle).
OVERSHOOT = 0.98
#: The share of each joint's limits a stop on the path (a pause, an abort) may use: a profile
#: that runs near the limits leaves a stop within its own share no room to slow down.
STOP_SHARE = 0.98
#: The shares of the grid's acceleration limits a stop brakes to, tried in turn (the
#: average over the window and the joints' jerk may ask more than the raw law).
BRAKES = (0.9, 0.7, 0.5)
#: The most points of TOPP-RA's grid (the check's samples, every so many of them).
GRID = 250
#: A round raises a point's limits by the joints' room there, at most this factor.
RAISE = 1.15
#: A profile within every share whose joints have less room than this anywhere is kept
#: (more rounds would gain little).
RAISE_WHEN = 1.03
#: The share of a joint's (share of its) jerk limit the path's jerk may use through q'
#: (the rest: the joint's jerk from the path's speed and acceleration, q''' v^3 + 3 q'' v a).
JERK_SHARE = 0.85
#: A joint's first derivative along the path below this (deg/mm) bounds no acceleration
#: through ``u`` (its acceleration is q'' x alone: a ceiling on x).
_FLAT = 1e-12


def _lines(g1: np.ndarray, g2: np.ndarray, amax: np.ndarray, acc, scale: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per grid point, the lines ``alpha + beta x`` that bound ``u`` from below (``lo``) and
    above (``hi``) for each joint and the path, and the ceiling on ``x`` of the joints
    whose ``q'`` is flat: (alpha_lo, alpha_hi, beta, flat_cap) with (n, 7) arrays (the
    seventh: the path's ``acc``, beta 0); the accelerations lowered by ``scale`` (per
    point) as a time scale would (x k^2)."""
    n = len(g1)
    k2 = (np.asarray(scale, dtype=float) ** 2)[:, None]
    amax = np.asarray(amax, dtype=float)[None, :] * k2
    path = np.full((n, 1), float(acc)) * k2
    steep = np.abs(g1) > _FLAT
    safe = np.where(steep, g1, 1.0)
    beta = np.where(steep, -g2 / safe, 0.0)
    reach = np.where(steep, amax / np.abs(safe), np.inf)
    alpha_lo = np.concatenate([-reach, -path], axis=1)
    alpha_hi = np.concatenate([reach, path], axis=1)
    beta = np.concatenate([beta, np.zeros((n, 1))], axis=1)
    with np.errstate(divide="ignore"):
        flat = np.where(steep, np.inf, amax / np.maximum(np.abs(g2), 1e-300))
    return alpha_lo, alpha_hi, beta, np.min(flat, axis=1)


def _braking(grid: np.ndarray, g1: np.ndarray, g2: np.ndarray, amax: np.ndarray, acc: float, scale: np.ndarray,
             cap: np.ndarray) -> tuple:
    """What a stop brakes within (:meth:`AveragedProfile.stop_law`), as plain lists: the
    grid, its lower lines (alpha, beta) with the limits the corrections left, and the path
    jerk allowed at each point."""
    alpha_lo, _alpha_hi, beta, _flat = _lines(g1, g2, amax, acc, scale)
    return grid.tolist(), alpha_lo.tolist(), beta.tolist(), cap.tolist()


def _acceleration_ceiling(alpha_lo: np.ndarray, alpha_hi: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """Per grid point, the largest x at which some u lies within every line: every lower
    line below every upper line (``alpha_lo_k + beta_k x <= alpha_hi_m + beta_m x``)."""
    a = alpha_hi[:, None, :] - alpha_lo[:, :, None]  # (n, lower k, upper m): >= 0 at x = 0
    b = beta[:, :, None] - beta[:, None, :]  # (beta_k - beta_m) x <= a
    with np.errstate(divide="ignore", invalid="ignore"):
        cap = np.where(b > 0.0, a / np.where(b > 0.0, b, 1.0), np.inf)
    return np.min(cap, axis=(1, 2))


def topp_ra(s: np.ndarray, g1: np.ndarray, g2: np.ndarray, vmax, amax, speed: float, acc: float,
            scale: np.ndarray | None = None) -> np.ndarray:
    """The time-optimal ``x = v^2`` at the grid ``s`` (from rest to rest) within
    the joints' ``vmax`` and ``amax`` (joint derivatives ``g1``, ``g2`` along the path,
    signed (n, 6) arrays) and the path's ``speed`` and ``acc``; ``scale`` (per point, <= 1)
    lowers the limits there as a time scale would (velocities x k, accelerations x k^2)."""
    n = len(s)
    h = np.append(np.diff(s), s[-1] - s[-2])[:, None]  # (each point's interval to the next)
    vmax = np.asarray(vmax, dtype=float)[None, :]
    k = np.ones(n) if scale is None else np.asarray(scale, dtype=float)
    alpha_lo, alpha_hi, beta, flat = _lines(g1, g2, amax, acc, k)
    with np.errstate(divide="ignore", over="ignore"):
        velocity = np.min((vmax * k[:, None] / np.maximum(np.abs(g1), 1e-150)) ** 2, axis=1)
    ceiling = np.minimum.reduce([velocity, (speed * k) ** 2, flat, _acceleration_ceiling(alpha_lo, alpha_hi, beta)])
    ceiling = np.maximum(ceiling, 0.0)
    # backward: the largest x_i from which x_{i+1} <= top_{i+1} is reachable:
    # x + 2h (alpha_k + beta_k x) <= top for every lower line k
    gain = 1.0 + 2.0 * h * beta  # (n, 7)
    shift = 2.0 * h * alpha_lo
    rising = gain > 0.0
    inv = np.where(rising, 1.0 / np.where(rising, gain, 1.0), 0.0).tolist()
    shift_l = shift.tolist()
    ceiling_l = ceiling.tolist()
    top = [0.0] * n
    last = 0.0
    for i in range(n - 2, -1, -1):
        best = ceiling_l[i]
        for g, c in zip(inv[i], shift_l[i]):
            if g > 0.0:
                bound = (last - c) * g
                if bound < best:
                    best = bound
        last = top[i] = best if best > 0.0 else 0.0
    # forward: the largest u that stays within the tops
    ahi = (2.0 * h * alpha_hi).tolist()
    bhi = (1.0 + 2.0 * h * beta).tolist()
    x = [0.0] * n
    current = 0.0
    for i in range(n - 1):
        nxt = top[i + 1]
        for a, b in zip(ahi[i], bhi[i]):
            reach = a + b * current
            if reach < nxt:
                nxt = reach
        current = x[i + 1] = nxt if nxt > 0.0 else 0.0
    x[-1] = 0.0
    return np.asarray(x)


class AveragedProfile(PathProfile):
    """TOPP-RA's piecewise-constant-acceleration time law ``s(t)`` (from the grid's ``x``)
    averaged over a moving window of ``window`` seconds: the same interface as
    :class:`PathProfile` (``sample``, ``states``, ``times_at``, ``stop_limits`` from
    ``envelope``, ``scaled``); ``duration`` is TOPP-RA's plus the window."""

    __slots__ = ("window", "_pieces", "_big", "_end", "_braking")

    def __init__(self, length: float, t, s, v, a, window: float, acc: float, jerk: float, envelope: tuple | None,
                 blended: bool = True):
        self.length = length
        self.window = window
        self._braking = None  # (grid, alpha_lo, beta, jerk cap): what a stop brakes within (set by the planner)
        t, s, v, a = (np.asarray(x, dtype=float) for x in (t, s, v, a))
        d = np.diff(t)
        big = np.concatenate([[0.0], np.cumsum(d * (s[:-1] + d * (0.5 * v[:-1] + d * a[:-1] / 6.0)))])
        self._t, self._s, self._v, self._a, self._big = t, s, v, a, big
        self._pieces = (t.tolist(), s.tolist(), v.tolist(), a.tolist(), big.tolist())
        self._end = float(t[-1])
        self._j = None
        self.duration = self._end + window
        self.peak_velocity = float(np.max(v)) if len(v) else 0.0
        self.t_acc = self._t_acc() if blended else 0.0  # (a stop's law is never blended)
        self._bounds, self._acc, self._jerk = [0.0], [acc], [jerk]
        self._envelope = envelope

    def _raw(self, t: float) -> tuple[float, float, float, float]:
        """The unaveraged law at ``t``: (its integral, s, v, a); at rest outside it."""
        ts, ss, vs, as_, bs = self._pieces
        if t <= 0.0:
            return 0.0, 0.0, 0.0, 0.0
        if t >= self._end:
            return bs[-1] + self.length * (t - self._end), self.length, 0.0, 0.0
        i = min(bisect_right(ts, t) - 1, len(ts) - 2)
        u = t - ts[i]
        s0, v0, a0 = ss[i], vs[i], as_[i]
        return (bs[i] + u * (s0 + u * (0.5 * v0 + u * a0 / 6.0)), s0 + u * (v0 + 0.5 * u * a0), v0 + u * a0, a0)

    def sample(self, t: float) -> tuple[float, float, float]:
        if t >= self.duration:
            return (self.length, 0.0, 0.0)
        if not t > 0.0:
            return (0.0, 0.0, 0.0)
        w = self.window
        b1, s1, v1, _ = self._raw(t)
        b0, s0, v0, _ = self._raw(t - w)
        return (min(max((b1 - b0) / w, 0.0), self.length), (s1 - s0) / w, (v1 - v0) / w)

    def _raw_many(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        ts = self._t
        i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
        u = np.clip(t, 0.0, self._end) - ts[i]
        s0, v0, a0 = self._s[i], self._v[i], self._a[i]
        big = self._big[i] + u * (s0 + u * (0.5 * v0 + u * a0 / 6.0))
        s = s0 + u * (v0 + 0.5 * u * a0)
        v = v0 + u * a0
        after = t >= self._end
        before = t <= 0.0
        big = np.where(after, self._big[-1] + self.length * (t - self._end), np.where(before, 0.0, big))
        s = np.where(after, self.length, np.where(before, 0.0, s))
        return big, s, np.where(after | before, 0.0, v), np.where(after | before, 0.0, a0)

    def states(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        times = np.asarray(times, dtype=float)
        w = self.window
        b1, s1, v1, a1 = self._raw_many(times)
        b0, s0, v0, a0 = self._raw_many(times - w)
        inside = (times > 0.0) & (times < self.duration)
        s = np.where(times >= self.duration, self.length,
                     np.where(inside, np.clip((b1 - b0) / w, 0.0, self.length), 0.0))
        return (s, np.where(inside, (s1 - s0) / w, 0.0), np.where(inside, (v1 - v0) / w, 0.0),
                np.where(inside, (a1 - a0) / w, 0.0))

    def stop_law(self, t: float) -> "StopLaw | None":
        """A stop on the path from the profile's time ``t`` (a pause, an abort) that keeps
        every joint within STOP_SHARE of its acceleration and jerk limits, predicted all
        along it: braking at each of BRAKES of the grid's limits in turn
        (:meth:`_brake`), the first that fits; None when none does (or without the grid's
        limits, or at rest)."""
        if self._braking is None or self._envelope is None:
            return None
        for brake in BRAKES:
            law = self._brake(t, brake)
            if law is None:
                return None
            if _keeps(law, self._envelope, self._acc[0], self._jerk[0]):
                return law
        return None

    def _brake(self, t: float, brake: float) -> "StopLaw | None":
        """A stop from the profile's time ``t``: the unaveraged law from ``t`` on brakes as
        hard as ``brake`` of the grid's limits allow (the lowest acceleration of the lines
        TOPP-RA used, each point's), its change over a window within the jerk the window
        allows, until it rests; averaged over the same window, it continues the profile
        exactly at ``t`` (speed, acceleration). None when it would not rest before the
        path's end, or the profile is at rest."""
        if not 0.0 < t < self.duration:
            return None
        grid, alpha_lo, beta, cap = self._braking
        w = self.window
        ts, ss, vs, as_ = (list(x) for x in self._pieces[:4])
        keep = bisect_right(ts, t)
        if t >= self._end:  # (the raw law already rests: the averaged one is finishing)
            return None
        _big, s0, v0, _a0 = self._raw(t)
        law_t, law_s, law_v, law_a = ts[:keep] + [t], ss[:keep] + [s0], vs[:keep] + [v0], as_[:keep] + [0.0]
        i = bisect_right(grid, s0)
        n = len(grid)
        x = v0 * v0
        now, here = t, s0
        while x > 0.0:
            k = min(max(i - 1, 0), n - 1)  # (the lines of the point the interval starts at)
            lo = max(brake * al + b * x for al, b in zip(alpha_lo[k], beta[k]))
            back = self._raw_acceleration(now - w, law_t, law_a)  # (the raw law's acceleration a window ago)
            u = min(max(lo, back - w * cap[k]), back + w * cap[k])
            end = grid[i] if i < n else self.length
            step = max(end - here, 0.0)
            v = sqrt(x)
            if u < 0.0 and x + 2.0 * step * u <= 0.0:  # (at rest within the interval)
                dt = v / -u
                law_a[-1] = u
                here += 0.5 * v * dt
                now += dt
                law_t.append(now), law_s.append(here), law_v.append(0.0), law_a.append(0.0)
                break
            if step <= 0.0 and i >= n:
                break  # (the path's end: the profile's own end is the stop)
            x2 = max(x + 2.0 * step * u, 0.0)
            v2 = sqrt(x2)
            dt = 2.0 * step / max(v + v2, 1e-300)
            law_a[-1] = u
            here, x, now = end, x2, now + dt
            law_t.append(now), law_s.append(here), law_v.append(v2), law_a.append(0.0)
            i += 1
            if i > n:
                break
        if law_v[-1] > 0.0 or here > self.length:
            return None
        raw = AveragedProfile(here, law_t, law_s, law_v, law_a, w, self._acc[0], self._jerk[0], None, blended=False)
        return StopLaw(raw, t, self.sample(t)[0])

    @staticmethod
    def _raw_acceleration(t: float, ts: list, as_: list) -> float:
        if t <= 0.0:
            return 0.0
        return as_[max(bisect_right(ts, t) - 1, 0)]

    def _t_acc(self) -> float:
        """The shorter of the first speed-up and the last slow-down (what a blend overlaps)."""
        times = np.linspace(0.0, self.duration, max(int(self.duration / TICK), 2) + 1)
        a = self.states(times)[2]
        rising = np.flatnonzero(a <= 0.0)
        first = times[rising[rising > 0][0]] if np.any(rising > 0) else self.duration
        falling = np.flatnonzero(a >= 0.0)
        last = self.duration - times[falling[falling < len(times) - 1][-1]] if np.any(falling < len(times) - 1) \
            else self.duration
        return float(min(first, last))

    def scaled(self, k: float) -> "AveragedProfile":
        out = AveragedProfile.__new__(AveragedProfile)
        out.length, out.window, out._end = self.length, self.window / k, self._end / k
        out._t, out._s, out._v, out._a = self._t / k, self._s, self._v * k, self._a * k * k
        out._big = self._big / k
        out._pieces = tuple(x.tolist() for x in (out._t, out._s, out._v, out._a, out._big))
        out._j = None
        out.duration, out.peak_velocity, out.t_acc = self.duration / k, self.peak_velocity * k, self.t_acc / k
        out._bounds = self._bounds
        out._acc = [x * k * k for x in self._acc]
        out._jerk = [x * k * k * k for x in self._jerk]
        out._envelope = scaled_envelope(self._envelope, k)
        out._braking = None if self._braking is None else (
            self._braking[0], [[x * k * k for x in row] for row in self._braking[1]], self._braking[2],
            [x * k * k * k for x in self._braking[3]])
        return out

    def __repr__(self) -> str:
        return f"AveragedProfile(length={self.length!r}, duration={self.duration!r}, window={self.window!r})"


class StopLaw:
    """A stop on the path of an :class:`AveragedProfile` (:meth:`AveragedProfile.stop_law`),
    as :class:`runtime.motion.stops.JerkStop` gives one: ``sample(t) -> (distance from
    where it starts, speed, acceleration)``, ``duration``, ``distance``. Real-time safe."""

    __slots__ = ("duration", "distance", "_law", "_t0", "_s0")

    def __init__(self, law: AveragedProfile, t0: float, s0: float):
        self._law, self._t0, self._s0 = law, t0, s0
        self.duration = law.duration - t0
        self.distance = law.length - s0

    def sample(self, t: float) -> tuple[float, float, float]:
        s, v, a = self._law.sample(self._t0 + max(t, 0.0))
        return s - self._s0, v, a


def _keeps(law: StopLaw, envelope: tuple, acc: float, jerk: float) -> bool:
    """Whether the stop ``law`` keeps the path's ``acc`` and ``jerk`` and every joint its
    share (the envelope's: its limits times STOP_SHARE) of its acceleration and jerk limits
    all along it, predicted every 1 ms (and at its pieces' ends, where its jerk changes)."""
    start, end = law._t0, law._t0 + law.duration
    knots = np.concatenate([law._law._t, law._law._t + law._law.window, [start, end]])
    knots = np.unique(knots[(knots >= start) & (knots <= end)])
    times = np.concatenate([start + np.linspace(0.0, law.duration, max(int(law.duration / TICK), 2) + 1),
                            0.5 * (knots[1:] + knots[:-1])])  # (and inside each piece: its jerk is constant)
    return within_envelope(*law._law.states(times), envelope[:6] + (acc, jerk))


def _time_law(s: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The grid's x as a time law of constant accelerations: (t, s, v, a) at each point
    (a: over the interval that starts there)."""
    v = np.sqrt(np.maximum(x, 0.0))
    ds = np.diff(s)
    dt = 2.0 * ds / np.maximum(v[:-1] + v[1:], 1e-300)
    a = np.append((v[1:] - v[:-1]) / np.maximum(dt, 1e-300), 0.0)
    return np.concatenate([[0.0], np.cumsum(dt)]), s, v, a


def _window(t: np.ndarray, s: np.ndarray, v: np.ndarray, a: np.ndarray, grid_s: np.ndarray, cap: np.ndarray) -> float:
    """The shortest window over which the law (``s``, ``v`` at the times ``t``, ``a`` over
    the intervals from them) changes its acceleration by at most ``cap * window``, ``cap``
    the path jerk allowed at the grid's path lengths ``grid_s`` (the programmed jerk, and
    what each joint's jerk limit leaves through its ``q'``), taken where the averaged
    path is then (the window's mean position)."""
    end = float(t[-1])
    times = np.linspace(0.0, end, max(int(end / (0.5 * TICK)), 8) + 1)
    dt = times[1] - times[0]
    idx = np.clip(np.searchsorted(t, times, side="right") - 1, 0, len(a) - 1)
    u = times - t[idx]
    sampled = a[idx]
    position = s[idx] + u * (v[idx] + 0.5 * u * sampled)
    integral = np.concatenate([[0.0], np.cumsum(0.5 * dt * (position[1:] + position[:-1]))])
    peak = float(np.max(np.abs(a))) if len(a) else 0.0
    window = peak / float(np.max(cap))
    length = float(s[-1])
    for _ in range(8):  # (the change over a longer window can be larger: to the fixed point)
        # (at most a few times the law's own length: a longer window only makes a profile
        # that another timing beats, and a tiny path's steps would make it enormous)
        lag = min(max(int(round(window / dt)), 1), 4 * len(times))
        w = lag * dt
        padded = np.concatenate([np.zeros(lag), sampled, np.zeros(lag)])
        big = np.concatenate([np.zeros(lag), integral, integral[-1] + length * dt * np.arange(1, lag + 1)])
        mean = (big[lag:] - big[:-lag]) / w  # (where the averaged path is)
        allowed = np.interp(mean, grid_s, cap)
        needed = float(np.max(np.abs(padded[lag:] - padded[:-lag]) / allowed))
        if needed <= window * 1.0001:
            break
        window = needed
    return max(window, 2.0 * TICK)


def reachable_profile(s: np.ndarray, derivatives, limits: Sequence[Sequence[float]], speed: float, acc: float,
                      jerk: float, share: float) -> AveragedProfile | None:
    """The near time-optimal profile along the path with joint ``derivatives`` (signed,
    a :class:`~runtime.motion.pathtiming.PathDerivatives`) at the uniform path lengths
    ``s``, within ``speed``, ``acc``, ``jerk`` and ``share`` of every joint's ``limits``
    (max velocities, accelerations, jerks), predicted every 1 ms; None when the path is too
    short to tell (fewer than four samples). Two windows are tried, the shorter kept: one
    that keeps the path's jerk within what each joint's jerk limit leaves through its
    ``q'`` as well as the programmed jerk, and one for the programmed jerk alone (the
    corrections then slow down where a joint's jerk needs it)."""
    s = np.asarray(s, dtype=float)
    n = len(s)
    length = float(s[-1]) if n else 0.0
    if n < 4 or not length > 0.0:
        return None
    d1 = derivatives.d1
    jmax = share * np.asarray(limits[2], dtype=float)
    with np.errstate(divide="ignore"):  # (the path jerk each joint's q' j term leaves, the most of it)
        joints = np.minimum(jerk, np.min(JERK_SHARE * jmax / np.maximum(np.abs(d1), 1e-300), axis=1))
    envelope = stop_envelope(s, derivatives, limits, STOP_SHARE, acc, jerk)
    caps = (joints, np.full(n, jerk)) if np.min(joints) < jerk else (joints,)  # (the same when no joint binds)
    found = [_corrected(s, derivatives, limits, speed, acc, jerk, share, cap, envelope) for cap in caps]
    found = [profile for profile in found if profile is not None]
    return min(found, key=lambda profile: profile.duration) if found else None


def _corrected(s: np.ndarray, derivatives, limits, speed: float, acc: float, jerk: float, share: float,
               cap: np.ndarray, envelope: tuple) -> AveragedProfile | None:
    """:func:`reachable_profile` with the path jerk ``cap`` (per grid point) for its window:
    TOPP-RA, averaged, corrected CORRECTIONS times by the room the joints have."""
    length = float(s[-1])
    stride = max(1, -(-(len(s) - 1) // GRID))  # (TOPP-RA's grid: every stride-th sample, the last included)
    pick = np.unique(np.append(np.arange(0, len(s), stride), len(s) - 1))
    if len(pick) > 2 and s[pick[-1]] - s[pick[-2]] < 0.5 * (s[pick[1]] - s[pick[0]]):
        pick = np.delete(pick, -2)  # (no sliver at the end: the grid's steps nearly uniform)
    d1, d2 = derivatives.d1[pick], derivatives.d2[pick]
    grid = s[pick]
    n = len(grid)
    vmax, amax = (share * np.asarray(limit, dtype=float) for limit in limits[:2])
    scale = np.ones(n)
    best = fallback = None
    for _ in range(CORRECTIONS):
        x = topp_ra(grid, d1, d2, vmax, amax, speed, acc, scale)
        t, ss, v, a = _time_law(grid, x)
        if not np.all(np.isfinite(t)) or not t[-1] > 0.0:
            break
        window = _window(t, ss, v, a, s, cap)
        profile = AveragedProfile(length, t, ss, v, a, window, acc, jerk, envelope)
        times = np.linspace(0.0, profile.duration, int(profile.duration / (2.0 * TICK)) + 2)
        at, pv, pa, pj = profile.states(times)
        room = time_room(joint_ratios(at, pv, pa, pj, s, derivatives, limits), share)
        least = float(np.min(room))
        if least >= 1.0 - 1e-9:
            settled = best is not None and profile.duration > (1.0 - SETTLED) * best[0].duration
            if best is None or profile.duration < best[0].duration:
                best = (profile, scale)
            if settled or least < RAISE_WHEN:
                break  # (settled: another round gained less than SETTLED, or nowhere much room is left)
        elif fallback is None or profile.duration / least < fallback[0]:
            fallback = (profile.duration / least, profile, scale, least)
        # the grid's limits by the room the joints have there: lowered where a joint passes
        # its share, raised (never above the limits) where all have room, over the stretch
        # the window spans there
        factor = np.full(n, np.inf)
        np.minimum.at(factor, np.clip(np.searchsorted(grid, at), 0, n - 1), np.minimum(room, RAISE))
        factor[np.isinf(factor)] = 1.0
        tight = np.flatnonzero(room < 1.0)
        if len(tight):  # (what the window averaged there: the grid from its start to its end)
            first = np.searchsorted(grid, profile._raw_many(times[tight] - window)[1], side="right") - 1
            last = np.searchsorted(grid, profile._raw_many(times[tight])[1]) + 1
            for lo, hi, k in zip(np.clip(first, 0, n - 1).tolist(), np.clip(last, 1, n).tolist(),
                                 (room[tight] * OVERSHOOT).tolist()):
                np.minimum(factor[lo:hi], k, out=factor[lo:hi])
        scale = np.minimum(scale * factor, 1.0)
    if best is None and fallback is None:
        return None
    profile, kept = best if best is not None else fallback[1:3]
    profile._braking = _braking(grid, d1, d2, amax, acc, kept, np.interp(grid, s, cap))  # (what its stops brake within)
    if best is None:  # (none settled: the one that slowed down as a whole fits soonest)
        return profile.scaled(fallback[3] * OVERSHOOT)
    return profile
