"""One axis, rest to rest: the trapezoidal velocity profile.

Units: positions and distances in deg (revolute axis) or mm (prismatic axis),
velocities in deg/s (mm/s), accelerations in deg/s^2 (mm/s^2), times in seconds.
Plain floats only (no NumPy): the real-time loop samples six of these every cycle.

A profile has three phases, with ``D = |distance|`` and the signed quantities pointing in
the direction of motion::

    velocity
      v_cruise  .......______________
               /|                  |\\
              / |                  | \\
      0 -----/--+------------------+--\\----> t
             0  t_acc     t_total - t_acc  t_total

    accelerate  0 <= t < t_acc                 acc = +accel
    cruise      t_acc <= t < t_total - t_acc   acc = 0, vel = v_cruise
    decelerate  t_total - t_acc <= t < t_total acc = -accel

``t_acc = v_cruise / accel``; the covered distance is ``v_cruise * (t_total - t_acc)``.
When the cruise phase is empty (``t_total == 2 * t_acc``) the profile is triangular.

* :func:`minimum_duration` / :func:`time_optimal_profile` -- the fastest move: full
  acceleration, and cruise at ``max_velocity`` if the distance is long enough to reach it.
  Triangular when ``D < v^2 / a``: ``T = 2 sqrt(D / a)``; else ``T = D / v + v / a``.
* :func:`profile_with_duration` -- a move of a given duration ``T >= T_min`` that uses
  the full acceleration ``a`` and the lowest cruise velocity that covers ``D`` in ``T``:
  ``v_c = (a T - sqrt(a^2 T^2 - 4 a D)) / 2``. The planner gives every axis but the
  slowest one such a profile, so that all axes start and stop together.

The construction functions are not called every cycle and assume validated input
(finite numbers, positive limits: :func:`runtime.motion.planner.plan_ptp` checks them);
they raise ``ValueError`` when a precondition is broken. :meth:`TrapezoidalProfile.sample`
runs in the real-time loop: a few float operations, no allocation but its result tuple,
never raises for a number ``t``.
"""
from __future__ import annotations

from math import sqrt

__all__ = [
    "TrapezoidalProfile",
    "minimum_duration",
    "time_optimal_profile",
    "profile_with_duration",
    "unchecked_minimum_duration",
    "unchecked_profile_with_duration",
    "unchecked_time_optimal_profile",
]

# A requested duration may fall short of the minimum by this relative amount (rounding
# in the caller's arithmetic); it is then treated as the minimum.
_DURATION_SLACK = 1e-12


class TrapezoidalProfile:
    """A rest-to-rest trapezoidal (or triangular) profile of one axis.

    Attributes (read them, do not change them):

    * ``start`` -- position at ``t <= 0`` (deg or mm).
    * ``distance`` -- signed distance travelled; the position at ``t >= t_total`` is
      ``start + distance``.
    * ``v_cruise`` -- cruise (peak) velocity, signed in the direction of motion (unit/s).
    * ``accel`` -- acceleration magnitude of the first phase, signed in the direction of
      motion (unit/s^2); the last phase decelerates with ``-accel``.
    * ``t_acc`` -- duration of the acceleration phase, equal to that of the deceleration
      phase (s).
    * ``t_total`` -- duration of the whole move (s).
    """

    __slots__ = ("start", "distance", "v_cruise", "accel", "t_acc", "t_total", "_end")

    def __init__(self, start: float, distance: float, v_cruise: float, accel: float,
                 t_acc: float, t_total: float):
        self.start = start
        self.distance = distance
        self.v_cruise = v_cruise
        self.accel = accel
        self.t_acc = t_acc
        self.t_total = t_total
        self._end = start + distance

    def sample(self, t: float) -> tuple[float, float, float]:
        """Position (unit), velocity (unit/s), acceleration (unit/s^2) at time ``t`` (s).

        ``t`` is clamped to ``[0, t_total]``: before the start the axis rests at
        ``start``, after the end at ``start + distance`` (velocity and acceleration 0).
        Real-time safe.
        """
        t_total = self.t_total
        if t >= t_total:  # first: a zero-length profile is at its end at once
            return (self._end, 0.0, 0.0)
        if not t > 0.0:  # also catches NaN
            return (self.start, 0.0, 0.0)
        t_acc = self.t_acc
        if t < t_acc:
            a = self.accel
            return (self.start + 0.5 * a * t * t, a * t, a)
        if t < t_total - t_acc:
            v = self.v_cruise
            return (self.start + v * (t - 0.5 * t_acc), v, 0.0)
        a = self.accel
        r = t_total - t  # time left; at most t_acc (rounding of t_total - t_acc aside)
        if r > t_acc:
            r = t_acc
        return (self._end - 0.5 * a * r * r, a * r, -a)

    @property
    def peak_velocity(self) -> float:
        """``|v_cruise|``: the largest speed on the profile (unit/s)."""
        return abs(self.v_cruise)

    def __repr__(self) -> str:
        return (f"TrapezoidalProfile(start={self.start!r}, distance={self.distance!r}, "
                f"v_cruise={self.v_cruise!r}, accel={self.accel!r}, t_acc={self.t_acc!r}, "
                f"t_total={self.t_total!r})")


def _check_limits(max_velocity: float, max_acceleration: float) -> None:
    if not max_velocity > 0.0:
        raise ValueError(f"max_velocity must be positive, got {max_velocity!r}")
    if not max_acceleration > 0.0:
        raise ValueError(f"max_acceleration must be positive, got {max_acceleration!r}")


def minimum_duration(distance: float, max_velocity: float, max_acceleration: float) -> float:
    """The shortest rest-to-rest duration (s) for ``distance`` under the two limits.

    Triangular (the axis never reaches ``max_velocity``) when
    ``|distance| < max_velocity^2 / max_acceleration``: ``T = 2 sqrt(|d| / a)``;
    otherwise ``T = |d| / v + v / a``. The two agree at the boundary. ``0`` for ``d = 0``.
    May be ``inf`` when the limits are tiny against the distance.
    """
    _check_limits(max_velocity, max_acceleration)
    return unchecked_minimum_duration(distance, max_velocity, max_acceleration)


def time_optimal_profile(start: float, distance: float, max_velocity: float,
                         max_acceleration: float) -> TrapezoidalProfile:
    """The fastest rest-to-rest profile from ``start`` over the signed ``distance``."""
    _check_limits(max_velocity, max_acceleration)
    return unchecked_time_optimal_profile(start, distance, max_velocity, max_acceleration)


def profile_with_duration(start: float, distance: float, max_velocity: float,
                          max_acceleration: float, duration: float) -> TrapezoidalProfile:
    """A rest-to-rest profile of exactly ``duration`` seconds.

    It accelerates with the full ``max_acceleration`` ``a`` and cruises at the lowest
    velocity that covers ``D = |distance|`` in ``T = duration``: the smaller root of
    ``v_c (T - v_c / a) = D``,

        v_c = (a T - sqrt(a^2 T^2 - 4 a D)) / 2  =  2 D / (T + sqrt(T^2 - 4 D / a)),

    computed in the second form, which has no cancellation (and gives ``v_c = 0`` for
    ``D = 0``); the discriminant is formed as ``(T - r) (T + r)`` with
    ``r = 2 sqrt(D / a)``, so it is exactly 0 when ``T`` is the triangular minimum.
    Rounding that pushes it below 0 (``T`` a hair under the triangular minimum) is
    treated as 0. ``v_c`` never exceeds ``max_velocity`` nor ``a T / 2``.

    Near the double root (``T`` close to ``2 sqrt(D / a)``) ``v_c`` is ill-conditioned
    (an error of ``e`` in the discriminant moves it by ``sqrt(e)``), but the covered
    distance is stationary there, so positions stay accurate to rounding.

    Raises ``ValueError`` if ``duration`` is shorter than :func:`minimum_duration`
    (beyond a relative slack of 1e-12) or not finite.
    """
    t_min = minimum_duration(distance, max_velocity, max_acceleration)
    if not (duration >= t_min * (1.0 - _DURATION_SLACK) and duration < float("inf")):
        raise ValueError(f"duration must be finite and at least the minimum {t_min!r} s, "
                         f"got {duration!r}")
    return unchecked_profile_with_duration(start, distance, max_velocity, max_acceleration, duration)


# The unchecked forms, for the planner (runtime.motion.planner), which has validated its
# input and knows that the duration is at least each axis's minimum. Same arithmetic, no
# checks: for valid input only.


def unchecked_minimum_duration(distance: float, v: float, a: float) -> float:
    d = abs(distance)
    if d * a < v * v:
        return 2.0 * sqrt(d / a)
    return d / v + v / a


def unchecked_time_optimal_profile(start: float, distance: float, v: float, a: float) -> TrapezoidalProfile:
    d = abs(distance)
    sign = -1.0 if distance < 0.0 else 1.0
    if d * a < v * v:  # triangular: the peak velocity sqrt(a d) stays below v
        t_acc = sqrt(d / a)
        return TrapezoidalProfile(start, distance, sign * a * t_acc, sign * a, t_acc, 2.0 * t_acc)
    t_acc = v / a
    return TrapezoidalProfile(start, distance, sign * v, sign * a, t_acc, d / v + t_acc)


def unchecked_profile_with_duration(start: float, distance: float, max_velocity: float, a: float,
                                    big_t: float) -> TrapezoidalProfile:
    sign = -1.0 if distance < 0.0 else 1.0
    d = abs(distance)
    if d == 0.0:
        return TrapezoidalProfile(start, distance, 0.0, sign * a, 0.0, big_t)
    r = 2.0 * sqrt(d / a)
    disc = (big_t - r) * (big_t + r)
    v_c = 2.0 * d / (big_t + sqrt(disc)) if disc > 0.0 else 2.0 * d / big_t
    half = 0.5 * a * big_t
    if v_c > half:
        v_c = half
    if v_c > max_velocity:
        v_c = max_velocity
    t_acc = v_c / a
    if t_acc > 0.5 * big_t:
        t_acc = 0.5 * big_t
    return TrapezoidalProfile(start, distance, sign * v_c, sign * a, t_acc, big_t)
