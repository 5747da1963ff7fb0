"""Blending a corner (``approx``): the next move starts before the last one has stopped.

The blend is a **superposition in joint space**: while both moves run, the commanded
joints are ``q1(t) + q2(t - T) - corner``, where ``q1`` is the move that ends at the
corner, ``q2`` the one that starts there and ``T`` the time (after the first move's start)
at which the second starts. Every move is planned rest to rest, so outside the overlap
each is exactly its own trajectory; inside, the robot leaves the first path shortly
before the corner and joins the second shortly after it without stopping. This works
the same for every pair of kinds (ptp-ptp, lin-lin, lin-circ, ptp-lin, ...), because
the trajectory generator sees every move as joint values over time.

How long the overlap may be (:func:`overlap_wanted`):

* after a **ptp** move, ``approx`` is a fraction ``0..1``: the overlap is that fraction of
  the shorter of the first move's deceleration and the second move's acceleration (1: the
  whole slowdown of the one overlaps the whole speed-up of the other);
* after a **lin** or **circ** move, ``approx`` is a distance (mm): the overlap is at most
  the time the first move takes for its last ``approx`` mm of path and the time the next
  (Cartesian) move takes for its first ``approx`` mm -- the tool leaves the first path
  within ``approx`` of the corner -- and never longer than the first move's deceleration
  and the next move's acceleration, so the two speeds hand over instead of adding up.

The overlap is then rounded **down** to whole trajectory-generator periods (the next
move starts on a tick) and **checked** (:func:`check_blend`): the superposed joint
trajectory is sampled every millisecond from three samples before the overlap to three
after it, and its first, second and third differences (velocity, acceleration and jerk)
must stay within the larger of the two moves' limits on every axis. A divided
difference of a smooth function equals its derivative somewhere in the window, so the
1 ms differences are the continuous derivatives' values averaged over at most 3 ms; the
5 ms setpoint stream's differences are weighted averages of these (positive weights), so
they are within the limits whenever these are. An overlap that fails is halved (up to
:data:`TRIES` times); one that never passes means the corner is not blended: the first
move stops exactly at it, which is always within the limits.
"""
from __future__ import annotations

from math import ceil

import numpy as np

from compiler.clauses import Motion

from runtime.timing import TICK
from runtime.motion.interpolator import Interpolator
from runtime.motion.trajectory import Trajectory

#: The verification grid (s): the servo's tick, where the 1 ms references are made.
STEP = TICK
#: Halvings of an overlap that breaks a limit before the corner is not blended.
TRIES = 4
#: Relative slack for rounding in the limit comparison.
_SLACK = 1e-9


class Limits:
    """Per-axis velocity, acceleration and jerk limits (tuples) a blend must keep: the
    trajectory generator gives every move the axis limits themselves (``max_velocity``,
    ``max_acceleration``, ``max_jerk``; no jerk limit for a trapezoidal move), so inside a
    blend a ptp move may exceed its own ``speed_ptp`` and ``acc_ptp`` fractions, never the
    axis's limits."""

    __slots__ = ("velocity", "acceleration", "jerk")

    def __init__(self, velocity, acceleration, jerk):
        self.velocity, self.acceleration, self.jerk = tuple(velocity), tuple(acceleration), tuple(jerk)

    def union(self, other: "Limits") -> "Limits":
        return Limits(map(max, self.velocity, other.velocity), map(max, self.acceleration, other.acceleration),
                      map(max, self.jerk, other.jerk))


def overlap_wanted(first_kind: Motion, first: Trajectory, approx: float, second_kind: Motion,
                   second: Trajectory) -> float:
    """The overlap (s) that ``approx`` on the move ``first`` asks for with the move
    ``second`` (module docstring; the kinds say what ``approx`` means: a fraction after
    a ptp move, a distance after a lin or circ move); 0 when the corner is not to be
    blended."""
    if not approx > 0.0 or first.duration <= 0.0 or second.duration <= 0.0:
        return 0.0
    ramp = min(first.ramp_time, second.ramp_time)
    if first_kind == Motion.PTP:
        return min(approx, 1.0) * ramp
    wanted = min(ramp, first.path_time(approx, at_end=True))
    if second_kind != Motion.PTP:
        wanted = min(wanted, second.path_time(approx, at_end=False))
    return wanted


def composite(first, second, offset: float, corner, times) -> np.ndarray:
    """Positions of the superposition at ``times`` (first move's time): an (n, axes) array."""
    rows = []
    for t in times:
        p1 = first.position_at(t)
        if t > offset:
            p2 = second.position_at(t - offset)
            rows.append([a + b - c for a, b, c in zip(p1, p2, corner)])
        else:
            rows.append(p1)
    return np.asarray(rows, dtype=float)


def limit_ratios(positions: np.ndarray, step: float, limits: Limits) -> tuple[float, float, float]:
    """The largest ratio to its limit of any velocity, acceleration and jerk sample
    (first, second, third differences of ``positions`` every ``step`` s), over all axes."""
    out = []
    d = positions
    for order, limit in enumerate((limits.velocity, limits.acceleration, limits.jerk), start=1):
        d = np.diff(d, axis=0)
        if len(d) == 0:
            out.append(0.0)
            continue
        lim = np.asarray(limit, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.abs(d) / (step ** order) / lim
        ratio = np.where(np.isfinite(lim), ratio, 0.0)
        out.append(float(np.max(ratio)) if ratio.size else 0.0)
    return out[0], out[1], out[2]


def check_blend(first, second, offset: float, corner, limits: Limits, step: float = STEP,
                period: float | None = None) -> tuple[float, float, float]:
    """The limit ratios (velocity, acceleration, jerk) of the superposition of ``first``
    and ``second`` started ``offset`` s after ``first``, over the overlap and three steps
    either side of it; with ``period``, also of the servo's 1 ms references made of its
    setpoints every ``period`` s (:func:`servo_ratios`). All three <= 1 means the blend
    keeps every limit."""
    k0 = int(round(offset / step)) - 3
    k1 = int(ceil(first.duration / step)) + 3
    times = [k * step for k in range(k0, k1 + 1)]
    ratios = limit_ratios(composite(first, second, offset, corner, times), step, limits)
    if period is None:
        return ratios
    return tuple(max(a, b) for a, b in zip(ratios, servo_ratios(first, second, offset, corner, limits, period)))


def servo_ratios(first, second, offset: float, corner, limits: Limits, period: float) -> tuple[float, float, float]:
    """The limit ratios of the servo's 1 ms references (its interpolator, from the blend's
    setpoints every ``period`` s with their positions, velocities and accelerations: what
    the trajectory generator writes) over the overlap and two setpoints either side. The
    interpolator keeps the limits wherever the setpoints allow a segment within them; a
    short blend of short moves may put more switches of the jerk into one period than it
    can follow, and then this says so."""
    k0 = int(offset / period) - 2
    k1 = int(ceil(first.duration / period)) + 2
    interpolator = None
    references = []
    for k in range(k0, k1 + 1):
        t = k * period
        p, v, a = first.at_time(t)
        if t > offset:
            p2, v2, a2 = second.at_time(t - offset)
            p = tuple([x + y - c for x, y, c in zip(p, p2, corner)])
            v = tuple([x + y for x, y in zip(v, v2)])
            a = tuple([x + y for x, y in zip(a, a2)])
        if interpolator is None:
            interpolator = Interpolator(p, (limits.velocity, limits.acceleration, limits.jerk))
        interpolator.push(t, p, v, a)
        if k > k0:
            references.extend(interpolator.sample(t - period + i * STEP) for i in range(int(round(period / STEP))))
    references.append(interpolator.sample(k1 * period))
    return limit_ratios(np.asarray(references, dtype=float), STEP, limits)


def blend_offset(first_kind: str, first, approx: float, second_kind: str, second, corner,
                 limits: Limits, period: float, max_overlap: float | None = None) -> float | None:
    """When (s after the start of ``first``, a whole number of ``period``\\ s) ``second``
    may start so that the corner is blended within every limit; None when it is not
    blended (no approx, or no overlap keeps the limits: the first move stops at the
    corner). ``max_overlap`` caps the overlap (the part of ``first`` not already
    overlapping the move before it)."""
    wanted = overlap_wanted(first_kind, first, approx, second_kind, second)
    if max_overlap is not None:
        wanted = min(wanted, max_overlap)
    duration = first.duration
    for _ in range(TRIES + 1):
        if wanted < period:
            break
        k = ceil((duration - wanted) / period - 1e-9)
        offset = k * period
        if offset >= duration:
            break
        ratios = check_blend(first, second, offset, corner, limits, period=period)
        if max(ratios) <= 1.0 + _SLACK:
            return offset
        wanted *= 0.5
    return None
