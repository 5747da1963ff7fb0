"""From the trajectory generator's 5 ms setpoints to the servo's 1 ms references.

The trajectory generator pushes a setpoint every 5 ms: its time, and the positions,
velocities and (when the motion has exact ones) accelerations of all axes. The servo
asks for a position reference (and its velocity, for the feed-forward) every 1 ms. Between
the last two setpoints each axis follows a **segment** (:mod:`runtime.kernels` computes and
evaluates them): a polynomial in ``s = (t - t0) / h`` (``h = t1 - t0``) that starts and
ends exactly at the two setpoints -- position and velocity, and acceleration when both
setpoints carry one -- so the references hit every setpoint, are continuous in position
and velocity (C1), and in acceleration too (C2) while the setpoints carry accelerations.

Setpoints without accelerations ``(t, positions, velocities)``: the cubic Hermite
polynomial, as before (C1; exact on a constant acceleration). Its 1 ms references leave
the limits at the corners of a profile: up to :data:`ACCELERATION_FACTOR` (5/3) of the
acceleration limit at an acceleration reversal (``p''`` at an end of the interval is
``integral of (4 - 6u) acc(u) du``), and up to :data:`VELOCITY_OVERSHOOT` ``* a * h``
beyond the profile's velocity range (a corner at 27 % of an interval), the position within
``a h^2 / 16`` of the profile.

Setpoints with accelerations ``(t, positions, velocities, accelerations)``: **the
references keep every axis's velocity, acceleration and jerk limit** (``max_velocity``,
``max_acceleration``, ``max_jerk``, given at construction). Why the plain answer does not:
the quintic Hermite polynomial (C2, what ros2_control's joint_trajectory_controller does
with positions, velocities and accelerations) reproduces every cubic, so every stretch of
constant jerk, exactly; but in an interval that holds a switch of jerk its jerk is the
least-squares quadratic fit of the profile's step of jerk, which overshoots it (up to
1.19 of the jerk limit on the planners' profiles; at most 2.18 for any jerk within the
limit, the Lebesgue constant of that fit), and so do its acceleration (1.0015) and
velocity (1.000005). No interpolation that is a linear function of the setpoints can do
better: its jerk would have to be a positive-weighted average of the profile's, and the
three moments it must match (the ends' acceleration, velocity and position) leave only a
point mass. And where the profile runs along a limit, nothing but the profile itself
keeps it: a corner of a trapezoid into a cruise at the velocity limit, or a ramp of jerk
into the acceleration limit, is the only curve with those end values that stays within
the limits.

So the segment is the profile itself wherever the setpoints identify it: the planners'
profiles are piecewise polynomials with a few switches, and between two setpoints
there is most often none (a cubic), or one. Of the candidates below the first that keeps
the three limits everywhere between the setpoints is taken (its bounds are computed with
it: exactly for the piecewise candidates, whose extremes are at their breakpoints or
where the acceleration crosses 0; for the quintic the velocity by the hull of its
Bernstein coefficients); if none does, the one that comes closest (keeping velocity and
acceleration first):

* one step of acceleration, where the setpoints say so to rounding (a trapezoid's corner);
* the quintic Hermite polynomial (exact on a cubic: no switch in the interval);
* one switch of jerk: a cubic spline with one free knot. In ``s`` units (a jerk times
  ``h^3``...), what the second setpoint adds to the first one's Taylor polynomial --
  acceleration ``m0``, velocity ``m1 / 2``, position ``m2 / 6`` -- are the moments
  ``m_k = integral of (k + 1) (1 - s)^k G(s) ds`` of the jerk ``G``; a step ``g1 -> g1 + d``
  at ``1 - w`` gives ``m_k = g1 + d w^(k+1)``, so ``g1 = (m0 m2 - m1^2) / (m0 + m2 - 2 m1)``,
  ``w = (m1 - g1) / (m0 - g1)``: closed form, exact on any one switch;
* two switches around a constant acceleration of 0 (a cruise shorter than a period) or of
  +-max_acceleration (a stretch at the limit shorter than a period), and two switches
  around a ramp between constant accelerations (jerk phases shorter than a period): the
  two breakpoints solve a quadratic;
* steps of acceleration: from or to an unknown value (a trapezoid starting or ending), two
  steps around 0 or +-max_acceleration -- only where they keep velocity and acceleration.

Every candidate is made to end exactly at the second setpoint (the quintic Hermite of its
rounding residual is added, and its bounds counted). So the 1 ms references of a
jerk-limited PTP move (runtime/motion/jerk.py, at the axes' full limits too), of a
trapezoidal one (runtime/motion/planner.py; no jerk limit there: its profile has none),
and of blends of such moves that keep the limits, keep velocity, acceleration and jerk --
as the drive sees them, differences of successive references over 1 ms -- within the
limits (tests/test_interpolation.py; benchmarks/lin_limits.py): a divided difference is
an average of the derivative over its window, and the continuous derivatives are
bounded. (A stretch of constant acceleration shorter than a period below the limit is
followed by the one-knot spline, which rises up to 0.3 % above it: within the limit up to
0.997 of it, and closer the segment with the stretch at the limit keeps it.) Exceptions:
an interval that holds three switches or more, or two that are neither of those -- jerk
phases shorter than a period: a move shorter than ``2 J h^3`` (0.001 deg at 4000
deg/s^3), or a specification with ``A / J`` under a period -- gets the closest candidate
(measured: up to 1.19 of the jerk limit, velocity and acceleration kept). The
accelerations must be the derivatives of the velocities (an estimate from differences of
velocities breaks the jerk: 5x the limit, measured); lin and circ moves (not polynomials
in the joints) with exact ones stay within their path's own 1 ms jerk plus 0.08 of the
limit, velocity and acceleration kept (benchmarks/lin_limits.py).

Cost: a segment is computed once per setpoint and axis (compiled; most intervals take the
quintic at once, one with a switch the one-knot spline); the servo evaluates it every
tick in its per-axis loop (:func:`runtime.kernels.servo_law`).

Delay: a reference for time ``t`` needs the setpoint at or after ``t``, so the servo
samples one period behind the generator: at servo time ``now`` it asks for
``sample(now - 0.005)``, between the setpoints pushed at ``now - 5 ms`` and ``now``
(or the generator pushes setpoints one period ahead). The interpolation therefore adds
one 5 ms period of delay between planning and the servo.

Real time: :meth:`Interpolator.push` and :meth:`Interpolator.segment` (or :meth:`sample`)
run in the loop: plain floats and tuples, no NumPy, one tuple of segments per push.
"""
from __future__ import annotations

import math

from runtime.accel import kernels

__all__ = ["ACCELERATION_FACTOR", "VELOCITY_OVERSHOOT", "Interpolator"]

#: Setpoints without accelerations (cubic Hermite): the largest velocity excursion of the
#: interpolated reference beyond the range of the interpolated profile's velocity, in units
#: of ``a * h`` (acceleration limit times setpoint period). The sharp value is 0.043648
#: (one corner at 27 % of an interval).
VELOCITY_OVERSHOOT = 0.0437

#: Setpoints without accelerations (cubic Hermite): the largest acceleration of the
#: interpolated reference, in units of the profile's acceleration limit: ``p''`` at an end
#: point is ``integral of (4 - 6u) acc(u) du``, at most ``(4/3 + 1/3) a``.
ACCELERATION_FACTOR = 5.0 / 3.0

_NO_BREAK = kernels.NO_BREAK


class Interpolator:
    """The segments between the last two pushed setpoints.

    Construct it with the positions to hold before any setpoint arrives (deg or mm per
    axis) and, for setpoints with accelerations, the axes' limits ``(max_velocity,
    max_acceleration, max_jerk)`` (three sequences, positive; None: no limits, the segment
    with the smallest jerk is taken). Before two setpoints exist, and after the last one,
    :meth:`sample` holds the last position (the initial one if nothing was pushed); before
    the earlier of the two it returns that one's positions.
    """

    __slots__ = ("_n", "_t0", "_t1", "_h", "_inv_h", "_p0", "_p1", "_v1", "_a1", "_zeros", "_segments", "_count",
                 "_hold", "_hold_for", "_limits")

    def __init__(self, initial_positions, limits=None):
        n = len(initial_positions)
        if limits is None:
            inf = (math.inf,) * n
            self._limits = (inf, inf, inf)
        else:
            self._limits = tuple(tuple(float(x) for x in values) for values in limits)
            if len(self._limits) != 3 or any(len(values) != n or not all(x > 0.0 for x in values)
                                             for values in self._limits):
                raise ValueError(f"limits must be three sequences of {n} positive numbers: max_velocity, "
                                 f"max_acceleration, max_jerk")
        self.reset(initial_positions)

    def reset(self, positions) -> None:
        """Forget all setpoints and hold ``positions``. Real-time safe."""
        p = tuple([float(x) for x in positions])
        n = self._n = len(p)
        self._p0 = self._p1 = p
        self._zeros = self._v1 = (0.0,) * n
        self._a1 = None
        self._segments = ()  # per axis: the segment of the current interval (runtime.kernels)
        self._t0 = self._t1 = self._h = self._inv_h = 0.0
        self._count = 0
        self._hold_for = None  # the positions self._hold was made for
        self._hold = ()

    def shift(self, axis: int, delta: float) -> None:
        """Move every stored setpoint of ``axis`` by ``delta`` (its coordinates changed:
        an encoder reset). The interpolated path is the same, shifted. Real-time safe."""
        def moved(values: tuple) -> tuple:
            values = list(values)
            values[axis] += delta
            return tuple(values)

        self._p0 = moved(self._p0)
        self._p1 = moved(self._p1)
        if self._segments:
            segments = list(self._segments)
            segments[axis] = (segments[axis][0] + delta,) + segments[axis][1:]
            self._segments = tuple(segments)
        self._hold_for = None

    @property
    def setpoints(self) -> int:
        """How many setpoints were pushed since construction or :meth:`reset`."""
        return self._count

    @property
    def interval(self) -> tuple[float, float] | None:
        """``(t0, t1)`` of the two setpoints interpolated between, or ``None`` if fewer
        than two were pushed."""
        return (self._t0, self._t1) if self._count >= 2 else None

    def push(self, t: float, positions, velocities, accelerations=None) -> bool:
        """Add the setpoint at time ``t`` (s): positions (unit), velocities (unit/s) and,
        when the motion has them, accelerations (unit/s^2, the derivatives of the
        velocities) of every axis, as tuples of floats of the length given at
        construction. The interval to it is C2 when both setpoints have accelerations,
        else C1 (cubic Hermite).

        Returns ``False`` (and ignores the setpoint) if ``t`` is not later than the last
        setpoint's time or a length differs; ``True`` otherwise. Real-time safe: one tuple
        of segments per call.
        """
        n = self._n
        if len(positions) != n or len(velocities) != n or (accelerations is not None and len(accelerations) != n):
            return False
        if self._count:
            if not t > self._t1:  # also NaN
                return False
            h = t - self._t1
            self._t0 = self._t1
            self._h = h
            self._inv_h = 1.0 / h
            self._p0 = self._p1
            if accelerations is not None and self._a1 is not None:
                vmax, amax, jmax = self._limits
                self._segments = kernels.segments(tuple(self._p1), tuple(self._v1), tuple(self._a1),
                                                  tuple(positions), tuple(velocities), tuple(accelerations), h,
                                                  vmax, amax, jmax)
            else:
                self._segments = kernels.hermite_segments(tuple(self._p1), tuple(self._v1), tuple(positions),
                                                          tuple(velocities), h)
        self._t1 = t
        self._p1 = positions
        self._v1 = velocities
        self._a1 = accelerations
        self._count += 1
        return True

    def segment(self, t: float) -> tuple:
        """The servo's call, for evaluating the reference inside its own per-axis loop:
        ``(segments, s, inv_h)``, where per axis (:mod:`runtime.kernels`)::

            position = segment_position(segments[i], s)          (= sample(t)[i])
            velocity = segment_velocity(segments[i], s, inv_h)   (= sample_velocity(t)[i])

        bit for bit, in every case (holding the last position, before the first of the
        two setpoints, between them). Real-time safe: no allocation except when a new
        last setpoint is first held.
        """
        if self._count < 2 or not t < self._t1:  # hold the last position, at rest
            if self._hold_for is not self._p1:
                self._hold_for = self._p1
                self._hold = (tuple([(float(p), 0.0, 0.0, 0.0, 0.0, 0.0, _NO_BREAK, 0.0, 0.0, _NO_BREAK, 0.0, 0.0)
                                     for p in self._p1]), 0.0, 0.0)
            return self._hold
        s = t - self._t0
        if not s > 0.0:  # before t0: its position, its velocity
            return self._segments, 0.0, self._inv_h
        return self._segments, s * self._inv_h, self._inv_h

    def sample(self, t: float) -> tuple[float, ...]:
        """Position reference of every axis at time ``t`` (s). Real-time safe.

        Between the last two setpoints: the segments. At or after the last setpoint, or
        before two exist: the last position. Before the earlier of the two: its position.
        """
        if self._count < 2 or not t < self._t1:  # NaN holds too
            return self._p1
        segments, s, _ = self.segment(t)
        if s == 0.0:
            return self._p0
        position = kernels.segment_position
        return tuple([position(c, s) for c in segments])

    def sample_velocity(self, t: float) -> tuple[float, ...]:
        """Velocity (unit/s) of the interpolated reference at ``t`` (s), for a servo's
        feed-forward: the derivative of :meth:`sample` for ``t0 <= t < t1`` (the first
        setpoint's velocity at ``t0``). Zero before two setpoints exist and from ``t1`` on
        (the stream of setpoints has ended: the reference holds still). A ``t`` before
        ``t0`` counts as ``t0``: a servo that computes ``now - period`` lands a rounding
        error before ``t0`` every fifth tick and must still get ``v0``. Real-time safe.
        """
        if self._count < 2 or not t < self._t1:
            return self._zeros
        segments, s, inv_h = self.segment(t)
        velocity = kernels.segment_velocity
        return tuple([velocity(c, s, inv_h) for c in segments])

    def sample_acceleration(self, t: float) -> tuple[float, ...]:
        """Acceleration (unit/s^2) of the interpolated reference at ``t`` (s) (the
        right-hand value at a step), zero outside the interval as for the velocity. For the
        tests and the benchmarks."""
        if self._count < 2 or not t < self._t1:
            return self._zeros
        segments, s, inv_h = self.segment(t)
        acceleration = kernels.segment_acceleration
        return tuple([acceleration(c, s, inv_h) for c in segments])
