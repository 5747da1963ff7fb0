"""The per-axis arithmetic of the 1 ms loop, as plain typed functions.

Four loops run for every axis on every 1 ms tick: the simulated drives and encoders
(:class:`~runtime.sim.robot.SimRobot`), the alpha-beta estimator
(:class:`~runtime.sim.estimator.AlphaBeta`), the servo law
(:class:`~runtime.components.servo.ServoController`) and the robot interface's command
clamp (:class:`~runtime.components.robot_interface.RobotInterface`). The components own
their state and their checks; this module holds only their inner loops.

This source is the reference and runs as it is. The build (``setup.py``) also compiles it
with mypyc (C, same source, the same IEEE double arithmetic with contraction off), which
takes a whole 1 ms tick from 102k to 62k machine instructions; :mod:`runtime.accel` picks the compiled module when it was
built from this exact source, and this one otherwise. The two give bit-identical results
(tests/test_kernels.py). Hence the style: concrete types (``tuple[float, ...]``,
``list[float]``; a compiled function rejects a list where a tuple is declared, so callers
pass what is declared), index loops, no closures, ``math.floor`` through the module.

Real-time: no allocation beyond floats and, in :func:`clamp_commands`, one tuple.
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


def servo_law(coeffs: tuple[tuple[float, float, float, float], ...], h01: float, h10: float, h11: float,
              d01: float, d10: float, d11: float, position: tuple[float, ...], integral: list[float],
              max_velocity: tuple[float, ...], min_velocity: tuple[float, ...], kp: float, ki: float,
              dt: float, out: list[float]) -> float:
    """The servo's commands for one period; returns the largest |following error|.

    Per axis, the reference ``p0 + h01 dp + h10 hv0 + h11 hv1`` and its velocity
    ``d01 dp + d10 hv0 + d11 hv1`` (the interpolator's Hermite weights and the axis's
    ``coeffs[i] = (p0, dp, hv0, hv1)``), then feed-forward plus PI on the error
    ``e = reference - position``. The integral grows by ``e dt`` only while the command
    is inside ``min_velocity..max_velocity`` (anti-windup); otherwise the command is
    saturated there. Writes ``out`` and ``integral`` in place.
    """
    high = 0.0  # the largest and the smallest following error
    low = 0.0
    for i in range(len(out)):
        p0, dp, hv0, hv1 = coeffs[i]
        x = position[i]
        s = integral[i]
        if dp != 0.0 or hv0 != 0.0 or hv1 != 0.0:
            e = p0 + h01 * dp + h10 * hv0 + h11 * hv1 - x
            u = d01 * dp + d10 * hv0 + d11 * hv1 + kp * e + ki * s
        else:  # an axis whose reference stands still this interval: no interpolation
            e = p0 - x
            u = kp * e + ki * s
        if e > high:
            high = e
        elif e < low:
            low = e
        vmax = max_velocity[i]
        vmin = min_velocity[i]
        if vmin < u < vmax:  # anti-windup: integrate only while the output is not saturated
            integral[i] = s + e * dt
        else:
            u = vmax if u > 0.0 else vmin
        out[i] = u
    return high if high > -low else -low


def clamp_commands(command: tuple[float, ...], compensation: list[float],
                   limits: tuple[float, ...]) -> tuple[float, ...]:
    """``command[i] + compensation[i]`` clamped to ``-limits[i]..limits[i]`` (NaN passes
    through: the drive treats it as 0)."""
    out = [0.0] * len(limits)
    for i in range(len(limits)):
        v = command[i] + compensation[i]
        m = limits[i]
        out[i] = m if v > m else -m if v < -m else v
    return tuple(out)


#: What :func:`safety_check` and :func:`direction_check` found (the code is ``kind * 256 + axis``).
SAFE, OVER_VELOCITY, OVER_ACCELERATION, OVER_LIMIT, NO_COUNTS, WRONG_WAY, NOT_STILL = 0, 1, 2, 3, 4, 5, 6


def safety_check(commands: tuple[float, ...], previous: tuple[float, ...], velocity_limits: tuple[float, ...],
                 step_limits: tuple[float, ...], positions: tuple[float, ...], low: tuple[float, ...],
                 high: tuple[float, ...], reaction: float, braking: tuple[float, ...], counts: tuple[int, ...],
                 last_counts: list[int], travel: list[float], window: list[float], plausible: tuple[float, ...],
                 dt: float, leak: float) -> int:
    """The safety supervisor's per-axis checks of one 1 ms command (:mod:`runtime.components.safety`).

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


def standstill_check(counts: tuple[int, ...], reference: tuple[int, ...], tolerance: int) -> int:
    """NOT_STILL (``kind * 256 + i``) for the first axis whose encoder moved more than
    ``tolerance`` counts from ``reference``; 0 otherwise."""
    for i in range(len(counts)):
        d = counts[i] - reference[i]
        if d > tolerance or d < -tolerance:
            return NOT_STILL * 256 + i
    return SAFE
