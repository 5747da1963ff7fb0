"""The per-axis arithmetic of the 1 ms loop, as plain typed functions.

Four loops run for every axis on every 1 ms tick: the simulated drives and encoders
(:class:`~runtime.hardware.sim.robot.SimRobot`), the alpha-beta estimator
(:class:`~runtime.hardware.sim.estimator.AlphaBeta`), the servo law
(:class:`~runtime.loop.components.servo.ServoController`) and the robot interface's command
clamp (:class:`~runtime.loop.components.robot_interface.RobotInterface`). Once per 5 ms
setpoint, the servo's interpolator (:mod:`runtime.motion.interpolator`) computes each
axis's segment to the next setpoint (:func:`segments`). The components own their state
and their checks; this module holds only their inner loops.

This source is the reference and runs as it is. The build (``setup.py``) also compiles it
with mypyc (C, same source, the same IEEE double arithmetic with contraction off), which
takes a whole 1 ms tick from 102k to 62k machine instructions; :mod:`runtime.accel` picks the compiled module when it was
built from this exact source, and this one otherwise. The two give bit-identical results
(tests/test_kernels.py). Hence the style: concrete types (``tuple[float, ...]``,
``list[float]``; a compiled function rejects a list where a tuple is declared, so callers
pass what is declared), index loops, no closures, ``math.floor`` through the module.

Real-time: no allocation beyond floats and, in :func:`clamp_commands`, one tuple (in
:func:`segments`, a tuple per axis and one of them).
"""
from __future__ import annotations

import math
from typing import Callable

#: (max command, min command, drive offset, encoder origin, counts per unit, encoder base)
DriveConstants = tuple[float, float, float, float, float, int]


def drive_step(dt: float, decay: float, lag_gain: float, commands: tuple[float, ...],
               xs: list[float], vs: list[float], safe_lo: list[float], safe_hi: list[float],
               constants: tuple[DriveConstants, ...], counts: list[int],
               edges: Callable[[int, float, float], tuple[float, float]]) -> None:
    """The simulated drives and encoders over one step of ``dt`` seconds (brakes off).

    Per axis: the command saturated at ``constants[i][0:2]`` (NaN counts as 0), plus the
    drive's offset, through the exact first-order lag (``decay = exp(-dt / tau)``,
    ``lag_gain = tau (1 - decay)``); then, outside the safe interval
    ``safe_lo[i] < x < safe_hi[i]``, ``edges(i, x, v)`` (hard stops, index pulses);
    then the encoder's counts. Updates ``xs``, ``vs`` and ``counts`` in place.
    """
    for i in range(len(xs)):
        c = commands[i]
        vmax, vmin, offset, origin, counts_per_unit, base = constants[i]
        if not vmin <= c <= vmax:  # saturated (a NaN command counts as 0)
            c = vmax if c > vmax else vmin if c < vmin else 0.0
        u = c + offset
        v = vs[i]
        dv = v - u
        x = xs[i] + u * dt + dv * lag_gain
        v = u + dv * decay
        if not safe_lo[i] < x < safe_hi[i]:  # near a hard stop or an index pulse
            x, v = edges(i, x, v)
        xs[i] = x
        vs[i] = v
        counts[i] = base + math.floor((x - origin) * counts_per_unit)


def alpha_beta(counts: tuple[float, ...], scale: tuple[float, ...], offset: list[float],
               xs: list[float], vs: list[float], dt: float, alpha: float, beta_dt: float,
               measured: list[float]) -> None:
    """One alpha-beta filter sample per axis, the measurement made from encoder counts:
    ``z = counts[i] * scale[i] + offset[i]`` goes to ``measured[i]``; the estimates
    ``xs`` (position) and ``vs`` (velocity) are updated in place (``beta_dt = beta / dt``).
    """
    for i in range(len(xs)):
        z = counts[i] * scale[i] + offset[i]
        measured[i] = z
        v = vs[i]
        predicted = xs[i] + v * dt
        residual = z - predicted
        xs[i] = predicted + alpha * residual
        vs[i] = v + beta_dt * residual


def servo_law(segments: tuple[tuple[float, ...], ...], s: float, inv_h: float, position: tuple[float, ...],
              integral: list[float], max_velocity: tuple[float, ...], min_velocity: tuple[float, ...], kp: float,
              ki: float, dt: float, out: list[float]) -> float:
    """The servo's commands for one period; returns the largest |following error|.

    Per axis, the reference and its velocity at ``s`` (0..1) on the axis's segment
    ``segments[i]`` (:func:`segment_position`, :func:`segment_velocity` times ``inv_h``,
    the same arithmetic), then feed-forward plus PI on the error ``e = reference -
    position``. The integral grows by ``e dt`` only while the command is inside
    ``min_velocity..max_velocity`` (anti-windup); otherwise the command is saturated
    there. Writes ``out`` and ``integral`` in place.
    """
    high = 0.0  # the largest and the smallest following error
    low = 0.0
    for i in range(len(out)):
        p0, c1, c2, c3, c4, c5, s1, f1, e1, s2, f2, e2 = segments[i]
        x = p0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))))
        w = c1 + s * (2.0 * c2 + s * (3.0 * c3 + s * (4.0 * c4 + s * (5.0 * c5))))
        if s > s1:
            r = s - s1
            x = x + r * r * (f1 + r * e1)
            w = w + r * (2.0 * f1 + 3.0 * r * e1)
            if s > s2:
                r = s - s2
                x = x + r * r * (f2 + r * e2)
                w = w + r * (2.0 * f2 + 3.0 * r * e2)
        e = x - position[i]
        si = integral[i]
        u = w * inv_h + kp * e + ki * si
        if e > high:
            high = e
        elif e < low:
            low = e
        vmax = max_velocity[i]
        vmin = min_velocity[i]
        if vmin < u < vmax:  # anti-windup: integrate only while the output is not saturated
            integral[i] = si + e * dt
        else:
            u = vmax if u > 0.0 else vmin
        out[i] = u
    return high if high > -low else -low


def clamp_commands(command: tuple[float, ...], compensation: list[float],
                   limits: tuple[float, ...]) -> tuple[float, ...]:
    """``command[i]`` clamped to ``-limits[i]..limits[i]``, plus ``compensation[i]`` (the
    drive's calibrated offset cancelled after the clamp, so that the axis runs at the
    clamped command even at the limit; NaN passes through: the drive treats it as 0)."""
    out = [0.0] * len(limits)
    for i in range(len(limits)):
        v = command[i]
        m = limits[i]
        out[i] = (m if v > m else -m if v < -m else v) + compensation[i]
    return tuple(out)


#: What :func:`safety_check`, :func:`direction_check` and :func:`standstill_check` found (the
#: code is ``kind * 256 + axis``).
SAFE, OVER_VELOCITY, OVER_ACCELERATION, OVER_LIMIT, NO_COUNTS, WRONG_WAY, NOT_STILL, NOT_IN_POSITION = (
    0, 1, 2, 3, 4, 5, 6, 7)


def safety_check(commands: tuple[float, ...], previous: tuple[float, ...], velocity_limits: tuple[float, ...],
                 step_limits: tuple[float, ...], positions: tuple[float, ...], low: tuple[float, ...],
                 high: tuple[float, ...], reaction: float, braking: tuple[float, ...], counts: tuple[int, ...],
                 last_counts: list[int], travel: list[float], window: list[float], plausible: tuple[float, ...],
                 dt: float, leak: float) -> int:
    """The safety supervisor's per-axis checks of one 1 ms command (:mod:`runtime.loop.components.safety`).

    Per axis ``i``, in this order, the first violation is returned as ``kind * 256 + i``
    (0: every axis passed):

    * OVER_VELOCITY: ``|commands[i]| > velocity_limits[i]`` (a NaN command too);
    * OVER_ACCELERATION: ``|commands[i] - previous[i]| > step_limits[i]`` (the velocity
      change one tick allows);
    * OVER_LIMIT: where the axis would come to rest if the stop began now,
      ``positions[i] + c reaction + c |c| braking[i]`` (``braking = 1 / (2 deceleration)``),
      is outside ``low[i]..high[i]`` (infinite bounds: not checked);
    * NO_COUNTS: the recent commanded travel since the encoder last changed exceeds
      ``plausible[i]`` either way: ``travel[i]`` sums ``c dt`` and forgets at the rate
      ``leak`` per tick (``1 - dt / memory``), so a small command that only holds the
      axis against a drift (the axis does not move, rightly) never adds up to a fault.

    ``last_counts``, ``travel`` and ``window`` (the commanded travel of the direction
    check's window, :func:`direction_check`) are updated in place.
    """
    for i in range(len(commands)):
        c = commands[i]
        if not -velocity_limits[i] <= c <= velocity_limits[i]:
            return OVER_VELOCITY * 256 + i
        d = c - previous[i]
        if not -step_limits[i] <= d <= step_limits[i]:
            return OVER_ACCELERATION * 256 + i
        rest = positions[i] + c * reaction + c * abs(c) * braking[i]
        if not low[i] <= rest <= high[i]:
            return OVER_LIMIT * 256 + i
        n = counts[i]
        step = c * dt
        window[i] += step
        if n != last_counts[i]:
            last_counts[i] = n
            travel[i] = 0.0
        else:
            t = travel[i] * leak + step
            travel[i] = t
            p = plausible[i]
            if not -p <= t <= p:
                return NO_COUNTS * 256 + i
    return SAFE


def direction_check(window: list[float], counts: tuple[int, ...], window_counts: list[int],
                    counts_per_unit: tuple[float, ...], distance: tuple[float, ...]) -> int:
    """At the end of a window of ticks: per axis, the commanded travel (``window[i]``)
    against the encoder's (``counts - window_counts``). WRONG_WAY (``kind * 256 + i``)
    when the axis was commanded more than twice ``distance[i]`` one way and its encoder
    went more than ``distance[i]`` the other way; 0 otherwise. Starts the next window
    (``window`` zeroed, ``window_counts`` = ``counts``)."""
    found = SAFE
    for i in range(len(window)):
        commanded = window[i]
        measured = (counts[i] - window_counts[i]) / counts_per_unit[i]
        p = distance[i]
        if found == SAFE and (commanded > 2.0 * p and measured < -p or commanded < -2.0 * p and measured > p):
            found = WRONG_WAY * 256 + i
        window[i] = 0.0
        window_counts[i] = counts[i]
    return found


def standstill_check(positions: tuple[float, ...], segments: tuple[tuple[float, ...], ...], s: float,
                     counts_per_unit: tuple[float, ...], window: float, tolerance: float, hold: float,
                     settle: tuple[float, ...], rest: float, now: float, deadline: float, since: list[float],
                     fixed: list[float], away: list[float]) -> int:
    """Standstill monitoring of one tick while the robot must be at rest. Per axis ``i``:

    * in position (``fixed[i]``, its standstill reference, is a number): NOT_STILL when its
      position is more than ``tolerance`` counts from ``fixed[i]``;
    * not yet (``fixed[i]`` is NaN): its position against the servo's reference (segment
      ``segments[i]`` at ``s``, :func:`segment_position`); within ``window`` counts since
      ``since[i]`` (NaN: not within) for ``hold`` seconds, and no sooner than ``settle[i]``
      seconds after the reference came to rest at ``rest``, the reference becomes
      ``fixed[i]``; an axis not in position at ``deadline`` is NOT_IN_POSITION.

    Positions are in the axis's unit, ``counts_per_unit`` converts. ``away[i]`` gets the
    axis's distance (counts) from the reference it was checked against. Returns the first
    violation as ``kind * 256 + i``, 0 if none; ``since``, ``fixed`` and ``away`` are
    updated in place."""
    for i in range(len(positions)):
        f = fixed[i]
        if f == f:  # in position: strict from here on
            d = (positions[i] - f) * counts_per_unit[i]
            away[i] = d
            if d > tolerance or d < -tolerance:
                return NOT_STILL * 256 + i
            continue
        r = segment_position(segments[i], s)
        d = (positions[i] - r) * counts_per_unit[i]
        away[i] = d
        if -window <= d <= window:
            t = since[i]
            if t != t:
                since[i] = now
            elif now - t >= hold - 1e-9 and now - rest >= settle[i] - 1e-9:  # (a ns: the clock's sums)
                fixed[i] = r
                continue
        else:
            since[i] = math.nan
        if now >= deadline:
            return NOT_IN_POSITION * 256 + i
    return SAFE


# ---- the servo's references: a segment per axis between two setpoints --------------------
#
# runtime/motion/interpolator.py explains the construction; these are its arithmetic. A
# segment is one axis's reference between two setpoints ``h`` seconds apart, in the time
# ``s = (t - t0) / h`` (0..1) and in "s units" (a velocity times h, an acceleration times
# h^2, a jerk times h^3): the tuple ``(p0, c1, c2, c3, c4, c5, s1, f1, e1, s2, f2, e2)``,
#
#     position(s) = p0 + c1 s + c2 s^2 + c3 s^3 + c4 s^4 + c5 s^5
#                   + [s > s1] (s - s1)^2 (f1 + e1 (s - s1)) + [s > s2] (s - s2)^2 (f2 + e2 (s - s2))
#
# (s1 <= s2; NO_BREAK where a segment has fewer breakpoints). Computed once per setpoint
# (every 5 ms), evaluated every tick (servo_law).

#: A breakpoint that ``s`` (0..1) never passes: a segment without that piece.
NO_BREAK = 2.0
#: The relative slack on the limits when a segment is chosen: the rounding of the
#: setpoints, amplified by the differences the segment is made from (about 1e-8 at worst).
LIMIT_SLACK = 1e-7
#: A step of acceleration is taken as one when the position it implies is within this share
#: of the step's effect (h^2 times the step) of the setpoint's (and within rounding).
STEP_MATCH = 1e-9
_EPS = 2.220446049250313e-16
_INF = math.inf
#: what a candidate function returns with False: no segment of that kind
_NO_SEGMENT: tuple[float, ...] = ()


def hermite_segment(p0: float, v0: float, p1: float, v1: float, h: float) -> tuple[float, ...]:
    """The cubic Hermite segment from ``(p0, v0)`` to ``(p1, v1)`` over ``h`` seconds: the
    setpoints without accelerations (continuous in position and velocity)."""
    c1 = h * v0
    d1 = h * v1
    dp = p1 - p0
    return (p0, c1, 3.0 * dp - 2.0 * c1 - d1, c1 + d1 - 2.0 * dp, 0.0, 0.0, NO_BREAK, 0.0, 0.0, NO_BREAK, 0.0, 0.0)


def segment_position(c: tuple[float, ...], s: float) -> float:
    """The position of segment ``c`` at ``s`` (servo_law's arithmetic, bit for bit)."""
    p0, c1, c2, c3, c4, c5, s1, f1, e1, s2, f2, e2 = c
    x = p0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))))
    if s > s1:
        r = s - s1
        x = x + r * r * (f1 + r * e1)
        if s > s2:
            r = s - s2
            x = x + r * r * (f2 + r * e2)
    return x


def segment_velocity(c: tuple[float, ...], s: float, inv_h: float) -> float:
    """The velocity (unit/s) of segment ``c`` at ``s``, ``inv_h = 1 / h`` (servo_law's
    arithmetic, bit for bit)."""
    p0, c1, c2, c3, c4, c5, s1, f1, e1, s2, f2, e2 = c
    w = c1 + s * (2.0 * c2 + s * (3.0 * c3 + s * (4.0 * c4 + s * (5.0 * c5))))
    if s > s1:
        r = s - s1
        w = w + r * (2.0 * f1 + 3.0 * r * e1)
        if s > s2:
            r = s - s2
            w = w + r * (2.0 * f2 + 3.0 * r * e2)
    return w * inv_h


def segment_acceleration(c: tuple[float, ...], s: float, inv_h: float) -> float:
    """The acceleration (unit/s^2) of segment ``c`` at ``s`` (the right-hand value at a
    step); for the tests and the benchmarks."""
    p0, c1, c2, c3, c4, c5, s1, f1, e1, s2, f2, e2 = c
    a = 2.0 * c2 + s * (6.0 * c3 + s * (12.0 * c4 + s * (20.0 * c5)))
    if s >= s1:
        a = a + 2.0 * f1 + 6.0 * (s - s1) * e1
        if s >= s2:
            a = a + 2.0 * f2 + 6.0 * (s - s2) * e2
    return a * inv_h * inv_h


def _roots2(a: float, b: float, c: float) -> tuple[int, float, float]:
    """The real roots of ``a x^2 + b x + c`` (``a`` may be 0): ``(count, x1, x2)``."""
    if a != 0.0:
        disc = b * b - 4.0 * a * c
        if not disc >= 0.0:
            return 0, 0.0, 0.0
        q = -0.5 * (b + math.copysign(math.sqrt(disc), b))
        if q == 0.0:
            return 1, 0.0, 0.0
        return 2, q / a, c / q
    if b != 0.0:
        return 1, -c / b, 0.0
    return 0, 0.0, 0.0


def _piece(nu: float, ua: float, aa: float, ub: float, ab: float, vl: float, rv: float, jl: float,
           rj: float) -> tuple[float, float, float]:
    """Along one piece of linear acceleration, ``aa`` at ``ua`` to ``ab`` at ``ub``, from
    the velocity ``nu``: the velocity at its end, and the largest velocity and jerk ratios
    so far (``rv``, ``rj``; ``vl``, ``jl`` the limits in s units)."""
    du = ub - ua
    if not du > 0.0:
        return nu, rv, rj
    g = (ab - aa) / du
    x = abs(g) / jl
    if x > rj:
        rj = x
    if (aa < 0.0 < ab) or (ab < 0.0 < aa):  # the velocity turns inside the piece
        z = -aa / g
        x = abs(nu + z * (aa + 0.5 * g * z)) / vl
        if x > rv:
            rv = x
    nu = nu + 0.5 * (aa + ab) * du
    x = abs(nu) / vl
    if x > rv:
        rv = x
    return nu, rv, rj


def _largest_abs(a: float, b: float, c: float, d: float, e: float, f: float) -> float:
    """The largest magnitude of six values (plain floats and comparisons: compiled, no
    tuple)."""
    m = abs(a)
    x = abs(b)
    if x > m:
        m = x
    x = abs(c)
    if x > m:
        m = x
    x = abs(d)
    if x > m:
        m = x
    x = abs(e)
    if x > m:
        m = x
    x = abs(f)
    if x > m:
        m = x
    return m


def _linear_ratios(nu0: float, a0: float, x1: float, l1: float, r1: float, x2: float, l2: float, r2: float,
                   a1: float, vl: float, al: float, jl: float) -> tuple[float, float, float]:
    """Velocity, acceleration and jerk ratios (to ``vl``, ``al``, ``jl``) of a segment
    whose acceleration is linear between the nodes ``(0, a0)``, ``(x1, l1 | r1)``,
    ``(x2, l2 | r2)``, ``(1, a1)`` (``l | r``: the values left and right of a node; a jump
    is an infinite jerk), starting at the velocity ``nu0``. Sharp: the extremes of a piece
    are at its ends, or where its acceleration crosses 0."""
    rv = abs(nu0) / vl
    rj = _INF if (l1 != r1 or l2 != r2) and jl < _INF else 0.0
    ra = _largest_abs(a0, l1, r1, l2, r2, a1)
    nu, rv, rj = _piece(nu0, 0.0, a0, x1, l1, vl, rv, jl, rj)
    nu, rv, rj = _piece(nu, x1, r1, x2, l2, vl, rv, jl, rj)
    nu, rv, rj = _piece(nu, x2, r2, 1.0, a1, vl, rv, jl, rj)
    return rv, ra / al, rj


def _quintic_ratios(c1: float, c2: float, c3: float, c4: float, c5: float, vl: float, al: float,
                    jl: float) -> tuple[float, float, float]:
    """Velocity, acceleration and jerk ratios of the quintic ``c1 s + ... + c5 s^5``: the
    jerk (a quadratic) and the acceleration (a cubic, its extremes at the jerk's roots)
    exactly; the velocity (a quartic) by the hull of its Bernstein coefficients (never
    less than the largest velocity; equal when it is at an end)."""
    j0 = 6.0 * c3
    j1 = 24.0 * c4
    j2 = 60.0 * c5
    mj = abs(j0)
    x = abs(j0 + j1 + j2)
    if x > mj:
        mj = x
    if j2 != 0.0:
        u = -j1 / (2.0 * j2)
        if 0.0 < u < 1.0:
            x = abs(j0 + u * (j1 + u * j2))
            if x > mj:
                mj = x
    a0 = 2.0 * c2
    ma = abs(a0)
    x = abs(a0 + j0 + 0.5 * j1 + j2 / 3.0)
    if x > ma:
        ma = x
    n, u1, u2 = _roots2(j2, j1, j0)
    if n > 0 and 0.0 < u1 < 1.0:
        x = abs(a0 + u1 * (j0 + u1 * (0.5 * j1 + u1 * (j2 / 3.0))))
        if x > ma:
            ma = x
    if n > 1 and 0.0 < u2 < 1.0:
        x = abs(a0 + u2 * (j0 + u2 * (0.5 * j1 + u2 * (j2 / 3.0))))
        if x > ma:
            ma = x
    b1 = c1 + 0.5 * c2
    b2 = c1 + c2 + 0.5 * c3
    b3 = c1 + 1.5 * c2 + 1.5 * c3 + c4
    b4 = c1 + 2.0 * c2 + 3.0 * c3 + 4.0 * c4 + 5.0 * c5
    mv = _largest_abs(c1, b1, b2, b3, b4, 0.0)
    return mv / vl, ma / al, mj / jl


def _end_fix(c: tuple[float, ...], p1: float, nu1: float, al1: float,
             smooth: bool) -> tuple[tuple[float, ...], float, float, float]:
    """Segment ``c`` made to end exactly at ``(p1, nu1, al1)``, or at ``(p1, nu1)`` if
    not ``smooth`` (a segment that ends with a step of acceleration): the Hermite polynomial
    of the residuals (the rounding of the segment, or its ill-conditioning) is added.
    Returns the segment and the largest velocity, acceleration and jerk (s units) that
    addition has (its basis functions' largest derivatives on 0..1, rounded up)."""
    p0, c1, c2, c3, c4, c5, s1, f1, e1, s2, f2, e2 = c
    x = p0 + c1 + c2 + c3 + c4 + c5
    w = c1 + 2.0 * c2 + 3.0 * c3 + 4.0 * c4 + 5.0 * c5
    a = 2.0 * c2 + 6.0 * c3 + 12.0 * c4 + 20.0 * c5
    if s1 < 1.0:
        r = 1.0 - s1
        x = x + r * r * (f1 + r * e1)
        w = w + r * (2.0 * f1 + 3.0 * r * e1)
        a = a + 2.0 * f1 + 6.0 * r * e1
        if s2 < 1.0:
            r = 1.0 - s2
            x = x + r * r * (f2 + r * e2)
            w = w + r * (2.0 * f2 + 3.0 * r * e2)
            a = a + 2.0 * f2 + 6.0 * r * e2
    dp = p1 - x
    dv = nu1 - w
    fixed: tuple[float, ...]
    if not smooth:  # cubic: 3 s^2 - 2 s^3 and s^3 - s^2
        fixed = (p0, c1, c2 + 3.0 * dp - dv, c3 - 2.0 * dp + dv, c4, c5, s1, f1, e1, s2, f2, e2)
        dp = abs(dp)
        dv = abs(dv)
        return fixed, 1.5 * dp + dv, 6.0 * dp + 4.0 * dv, 12.0 * dp + 6.0 * dv
    da = al1 - a
    fixed = (p0, c1, c2, c3 + 10.0 * dp - 4.0 * dv + 0.5 * da, c4 - 15.0 * dp + 7.0 * dv - da,
             c5 + 6.0 * dp - 3.0 * dv + 0.5 * da, s1, f1, e1, s2, f2, e2)
    dp = abs(dp)
    dv = abs(dv)
    da = abs(da)
    return fixed, 1.875 * dp + dv + 0.068 * da, 5.78 * dp + 3.95 * dv + da, 60.0 * dp + 36.0 * dv + 9.0 * da


def _switch_candidate(kind: int, p0: float, nu0: float, al0: float, al1: float, mv: float, mp: float, pr: float,
                      vr: float, ar: float, vl: float, al: float,
                      jl: float) -> tuple[bool, tuple[float, ...], float, float, float]:
    """:func:`segment`'s candidate ``kind`` 1-9, continuous in acceleration (switches of jerk),
    from the setpoints in s units (``nu0``, ``al0``, ``al1``: the velocity and the accelerations;
    ``mv``, ``mp``: the integrals of the acceleration and of (1 - s) times it; ``pr``, ``vr``,
    ``ar``: what the quintic has to make up): ``(True, segment, velocity, acceleration and
    jerk ratios)``, or ``(False, ...)`` where that kind has no segment."""
    if kind == 1:  # one switch of jerk: the moments of the jerk are 1, 2 (1 - s), 3 (1 - s)^2
        m0 = ar
        m1 = 2.0 * vr
        m2 = 6.0 * pr
        den = m0 + m2 - 2.0 * m1
        if den != 0.0:
            g1 = (m0 * m2 - m1 * m1) / den
            if m0 != g1:
                w = (m1 - g1) / (m0 - g1)  # the length of the second piece
                if 0.0 < w < 1.0:
                    sk = 1.0 - w
                    am = al0 + g1 * sk
                    candidate = (p0, nu0, 0.5 * al0, g1 / 6.0, 0.0, 0.0, sk, 0.0, (m0 - g1) / w / 6.0, NO_BREAK,
                                 0.0, 0.0)
                    rv, ra, rj = _linear_ratios(nu0, al0, sk, am, am, sk, am, am, al1, vl, al, jl)
                    return True, candidate, rv, ra, rj
    elif kind <= 7:  # two switches around a constant acceleration c: 0, +amax, -amax
        c = 0.0 if kind <= 3 else al if kind <= 5 else -al
        if c - c == 0.0:  # (a finite level)
            b0 = al0 - c
            b1 = al1 - c
            bv = mv - c
            bp = mp - 0.5 * c
            if b1 != 0.0:
                n, x1, x2 = _roots2(b0 * (b0 - b1), b0 * (3.0 * b1 - 4.0 * bv), 4.0 * bv * bv - 6.0 * b1 * bp)
                if n > (kind - 2) % 2:
                    t1 = x1 if kind % 2 == 0 else x2
                    t2 = (2.0 * bv - b0 * t1) / b1  # the length of the last piece
                    if t1 >= 0.0 and t2 > 0.0 and t1 + t2 <= 1.0 and (t1 > 0.0 or b0 == 0.0):
                        g1 = -b0 / t1 if t1 > 0.0 else 0.0
                        g2 = b1 / t2
                        candidate = (p0, nu0, 0.5 * al0, g1 / 6.0, 0.0, 0.0, t1, 0.0, -g1 / 6.0, 1.0 - t2, 0.0,
                                     g2 / 6.0)
                        rv, ra, rj = _linear_ratios(nu0, al0, t1, c, c, 1.0 - t2, c, c, al1, vl, al, jl)
                        return True, candidate, rv, ra, rj
    elif kind <= 9:  # a0 constant, a ramp, a1 constant
        if al0 != al1:
            q1 = 2.0 * (mv - al1) / (al0 - al1)
            q2 = (mp - 0.5 * al1) / (al0 - al1)
            n, x1, x2 = _roots2(1.0, -q1, q1 * q1 - 3.0 * q1 + 6.0 * q2)
            if n > kind - 8:
                t1 = x1 if kind == 8 else x2
                ramp = q1 - 2.0 * t1
                t2 = 1.0 + t1 - q1  # the length of the last piece
                if t1 >= 0.0 and t2 >= 0.0 and ramp > 0.0:
                    g = (al1 - al0) / ramp
                    candidate = (p0, nu0, 0.5 * al0, 0.0, 0.0, 0.0, t1, 0.0, g / 6.0,
                                 t1 + ramp if t2 > 0.0 else NO_BREAK, 0.0, -g / 6.0)
                    rv, ra, rj = _linear_ratios(nu0, al0, t1, al0, al0, t1 + ramp, al1, al1, al1, vl, al, jl)
                    return True, candidate, rv, ra, rj
    return False, _NO_SEGMENT, 0.0, 0.0, 0.0


def _step_candidate(kind: int, p0: float, nu0: float, al0: float, al1: float, mv: float, mp: float, vl: float,
                    al: float, jl: float) -> tuple[bool, tuple[float, ...], float, float, float]:
    """:func:`segment`'s candidate ``kind`` 10-17, with steps of acceleration (a trapezoid
    starting, ending, its short cruise or ramp), as :func:`_switch_candidate` gives them."""
    if kind == 10:  # a step from an unknown acceleration c to a1 (a trapezoid starting)
        den = al1 - mv
        if den != 0.0:
            t1 = 2.0 * (mp - mv + 0.5 * al1) / den
            if 0.0 < t1 <= 1.0:
                c = (mv - al1 * (1.0 - t1)) / t1
                candidate = (p0, nu0, 0.5 * c, 0.0, 0.0, 0.0, t1, 0.5 * (al1 - c), 0.0, NO_BREAK, 0.0, 0.0)
                rv, ra, rj = _linear_ratios(nu0, c, t1, c, al1, t1, al1, al1, al1, vl, al, jl)
                return True, candidate, rv, ra, rj
    elif kind == 11:  # a step from a0 to an unknown acceleration c (a trapezoid ending)
        den = al0 - mv
        if den != 0.0:
            t1 = (2.0 * mp - mv) / den
            if 0.0 <= t1 < 1.0:
                c = (mv - al0 * t1) / (1.0 - t1)
                candidate = (p0, nu0, 0.5 * al0, 0.0, 0.0, 0.0, t1, 0.5 * (c - al0), 0.0, NO_BREAK, 0.0, 0.0)
                rv, ra, rj = _linear_ratios(nu0, al0, t1, al0, c, t1, c, c, c, vl, al, jl)
                return True, candidate, rv, ra, rj
    else:  # two steps around a constant acceleration c: 0, +amax, -amax (a short cruise or ramp)
        c = 0.0 if kind <= 13 else al if kind <= 15 else -al
        if c - c == 0.0:
            b0 = al0 - c
            b1 = al1 - c
            bv = mv - c
            bp = mp - 0.5 * c
            if b0 != 0.0 and b1 != 0.0:
                n, x1, x2 = _roots2(b0 * b0 - b0 * b1, 2.0 * b0 * b1 - 2.0 * b0 * bv, bv * bv - 2.0 * b1 * bp)
                if n > kind % 2:
                    t1 = x1 if kind % 2 == 0 else x2
                    t2 = (bv - b0 * t1) / b1  # the length of the last piece
                    if t1 > 0.0 and t2 > 0.0 and t1 + t2 <= 1.0:
                        candidate = (p0, nu0, 0.5 * al0, 0.0, 0.0, 0.0, t1, 0.5 * (c - al0), 0.0, 1.0 - t2,
                                     0.5 * (al1 - c), 0.0)
                        rv, ra, rj = _linear_ratios(nu0, al0, t1, al0, c, 1.0 - t2, c, al1, al1, vl, al, jl)
                        return True, candidate, rv, ra, rj
    return False, _NO_SEGMENT, 0.0, 0.0, 0.0


def segment(p0: float, v0: float, a0: float, p1: float, v1: float, a1: float, h: float, vmax: float,
            amax: float, jmax: float) -> tuple[float, ...]:
    """One axis's segment between the setpoints ``(p0, v0, a0)`` and ``(p1, v1, a1)``
    ``h`` seconds apart (positions, velocities, accelerations): of the candidates below,
    the first whose velocity, acceleration and jerk stay within ``vmax``, ``amax``,
    ``jmax`` everywhere between the setpoints; else the one that comes closest (one that
    keeps the velocity and the acceleration first). Every candidate ends exactly at the
    second setpoint (position, velocity, acceleration). With infinite limits the
    candidate with the smallest largest jerk. The candidates, in this order:

    * one step of acceleration where the setpoints say so exactly (a trapezoid's corner);
    * the quintic Hermite polynomial (exact on every cubic: a stretch of constant jerk);
    * one switch of jerk (a cubic spline with one free knot; exact on it);
    * two switches around a constant acceleration of 0, or of +-amax (a short cruise, a
      short stretch at the acceleration limit);
    * two switches around a ramp from a0 to a1 (short jerk phases);
    * a step of acceleration from or to an unknown value (a trapezoid starting), two steps
      around an acceleration of 0 or +-amax (a trapezoid's short cruise or acceleration);
      only where they keep the velocity and the acceleration.
    """
    limited = vmax < _INF or amax < _INF or jmax < _INF
    nu0 = h * v0
    nu1 = h * v1
    al0 = h * h * a0
    al1 = h * h * a1
    vl = h * vmax
    al = h * h * amax
    jl = h * h * h * jmax if limited else h * h * h
    mv = nu1 - nu0  # the integral of the acceleration over the segment (s units)
    mp = p1 - p0 - nu0  # ... and of (1 - s) times it
    top = 1.0 + LIMIT_SLACK
    # a step of acceleration (a trapezoid's corner): one unknown, the position checks it
    if al0 != al1:
        st = (mv - al1) / (al0 - al1)
        if -1e-9 <= st <= 1.0 + 1e-9:
            st = 0.0 if st < 0.0 else 1.0 if st > 1.0 else st
            rest = mp - (al0 * (st - 0.5 * st * st) + 0.5 * al1 * (1.0 - st) * (1.0 - st))
            if abs(rest) <= STEP_MATCH * abs(al1 - al0) + 64.0 * _EPS * (abs(p0) + abs(p1)):
                return (p0, nu0, 0.5 * al0 + 3.0 * rest, -2.0 * rest, 0.0, 0.0, st, 0.5 * (al1 - al0), 0.0, NO_BREAK,
                        0.0, 0.0)
    # the quintic Hermite polynomial
    pr = p1 - p0 - nu0 - 0.5 * al0  # what remains of the position, velocity and acceleration
    vr = mv - al0
    ar = al1 - al0
    c3 = 10.0 * pr - 4.0 * vr + 0.5 * ar
    c4 = -15.0 * pr + 7.0 * vr - ar
    c5 = 6.0 * pr - 3.0 * vr + 0.5 * ar
    best: tuple[float, ...] = (p0, nu0, 0.5 * al0, c3, c4, c5, NO_BREAK, 0.0, 0.0, NO_BREAK, 0.0, 0.0)
    rv, ra, rj = _quintic_ratios(nu0, 0.5 * al0, c3, c4, c5, vl, al, jl)
    hard = rv if rv > ra else ra
    if limited and hard <= top and rj <= top:
        return best
    k0, k1, k2 = (0.0, rj, hard) if hard <= top else (1.0, hard, rj)
    candidate: tuple[float, ...] = best  # the candidates below, one at a time
    for kind in range(1, 18):
        if kind < 10:
            ok, candidate, rv, ra, rj = _switch_candidate(kind, p0, nu0, al0, al1, mv, mp, pr, vr, ar, vl, al, jl)
        else:
            ok, candidate, rv, ra, rj = _step_candidate(kind, p0, nu0, al0, al1, mv, mp, vl, al, jl)
        if not ok:
            continue
        candidate, ev, ea, ej = _end_fix(candidate, p1, nu1, al1, kind != 11)
        rv = rv + ev / vl
        ra = ra + ea / al
        rj = rj + ej / jl
        hard = rv if rv > ra else ra
        if hard <= top:
            if limited and rj <= top:
                return candidate
            if 0.0 < k0 or rj < k1 or (rj == k1 and hard < k2):
                k0, k1, k2 = 0.0, rj, hard
                best = candidate
        elif kind < 10 and k0 > 0.0 and (hard < k1 or (hard == k1 and rj < k2)):
            k1, k2 = hard, rj
            best = candidate
    return best


def segments(p0: tuple[float, ...], v0: tuple[float, ...], a0: tuple[float, ...], p1: tuple[float, ...],
             v1: tuple[float, ...], a1: tuple[float, ...], h: float, vmax: tuple[float, ...],
             amax: tuple[float, ...], jmax: tuple[float, ...]) -> tuple[tuple[float, ...], ...]:
    """:func:`segment` of every axis (the setpoints' values and the limits per axis)."""
    return tuple([segment(p0[i], v0[i], a0[i], p1[i], v1[i], a1[i], h, vmax[i], amax[i], jmax[i])
                  for i in range(len(p0))])


def hermite_segments(p0: tuple[float, ...], v0: tuple[float, ...], p1: tuple[float, ...],
                     v1: tuple[float, ...], h: float) -> tuple[tuple[float, ...], ...]:
    """:func:`hermite_segment` of every axis (setpoints without accelerations)."""
    return tuple([hermite_segment(p0[i], v0[i], p1[i], v1[i], h) for i in range(len(p0))])
