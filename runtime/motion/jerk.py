"""Jerk-limited ("double-S", seven-phase) point-to-point motion, time-optimal and synchronised.

Units: positions and distances in deg (revolute axis) or mm (prismatic axis), velocities
in unit/s, accelerations in unit/s^2, jerks in unit/s^3, times in seconds. Plain floats
only (no NumPy): the real-time loop samples these every cycle.

One axis, rest to rest (:class:`JerkProfile`)
---------------------------------------------
With ``D = |distance|`` and the limits ``v, a, j > 0`` (velocity, acceleration, jerk), the
profile has seven phases; the deceleration half mirrors the acceleration half::

    acceleration
       a_p    .------.
             /        \\
       0 ---'          '----------.          .----> t
                                   \\        /
      -a_p                          '------'
            |<>|<---->|<>|<------>|<>|<---->|<>|
            t_j  t_a  t_j   t_v   t_j  t_a  t_j     t_acc = 2 t_j + t_a
    phase    1    2    3     4     5    6    7
    jerk    +j    0   -j     0    -j    0   +j

Peak acceleration ``a_p = j t_j``, peak velocity ``v_p = a_p (t_j + t_a)``, duration
``T = 2 t_acc + t_v``; the velocity is symmetric about ``T / 2`` and, in the acceleration
half, point-symmetric about ``(t_acc / 2, v_p / 2)``, so the acceleration half covers
``v_p t_acc / 2`` and ``D = v_p (t_acc + t_v)``.

The time-optimal profile (Biagiotti & Melchiorri, "Trajectory Planning for Automatic
Machines and Robots", sec. 3.4, with zero boundary velocities and accelerations) in
closed form, no iteration:

* Accelerating to ``v``: when ``v j >= a^2`` the acceleration limit is reached,
  ``t_j = a / j``, ``t_a = v / a - a / j``, ``t_acc = v / a + a / j``; otherwise the
  acceleration phase is a pure jerk triangle, ``t_j = sqrt(v / j)``, ``t_a = 0``.
* **(i)** / **(ii)** ``D >= v t_acc``: ``v`` is reached, ``t_v = D / v - t_acc``,
  ``T = D / v + t_acc`` -- (i) with ``a`` reached, (ii) without (``v j < a^2``).
* **(iii)** ``D < v t_acc``: no cruise, ``t_v = 0``, ``T = 2 t_acc``.

  - **(iii-a)** ``D >= 2 a^3 / j^2``: ``a`` is reached, ``t_j = a / j``; the
    constant-acceleration time solves the quadratic
    ``D = a (t_j + t_a) (2 t_j + t_a)``, i.e. ``a t_a^2 + 3 a t_j t_a + 2 a t_j^2 - D = 0``:
    ``t_a = (sqrt(t_j^2 + 4 D / a) - 3 t_j) / 2``, computed without cancellation as
    ``2 (D / a - 2 t_j^2) / (3 t_j + sqrt(t_j^2 + 4 D / a))``.
  - **(iii-b)** ``D < 2 a^3 / j^2``: ``a`` is not reached, ``t_a = 0`` and
    ``D = 2 j t_j^3``: ``t_j = cbrt(D / (2 j))``, ``T = 4 t_j``.

  (When ``v j < a^2``, ``v t_acc = 2 sqrt(v^3 / j) <= 2 a^3 / j^2``, so case (iii-b) is
  the only no-cruise case then; at every case boundary the neighbouring formulas agree.)

A zero distance is a zero-duration profile holding the position.

Sampling evaluates the acceleration half directly and the deceleration half by the
mirror ``p(t) = start + distance - q(T - t)`` (``q`` the displacement of the acceleration
half): the end is exactly ``start + distance``.

A given, longer duration: time scaling
--------------------------------------
:func:`profile_with_duration` stretches the time-optimal profile ``p(t)`` of duration
``T_min`` to ``p(lambda t)``, ``lambda = T_min / T <= 1``: every phase time is divided by
``lambda`` (so the duration is exactly ``T``, the distance unchanged), the velocity is
multiplied by ``lambda``, the acceleration by ``lambda^2``, the jerk by ``lambda^3``.
Since ``lambda <= 1`` every limit is still kept (with margin). A stretched profile is a
double-S of the same normalised shape (the same ratios ``t_j : t_a : t_v : T``).

Synchronised moves (:func:`plan_ptp_jerk`)
------------------------------------------
Two ways, chosen by ``synchronization``:

* ``"line"`` (default): the move is a straight line in joint space. Every axis follows
  one normalised shape ``s(t)`` from 0 to 1, ``p_i(t) = start_i + d_i s(t)``. Axis ``i``
  keeps its limits exactly when ``s' <= v_i / |d_i|``, ``s'' <= a_i / |d_i|`` and
  ``s''' <= j_i / |d_i|``; so ``s`` is the time-optimal double-S over the unit distance
  with ``V = min_i v_i / |d_i|``, ``A = min_i a_i / |d_i|``, ``J = min_i j_i / |d_i|`` (over
  the moving axes). This is the fastest straight-line move. Its duration equals
  ``max_i T_min,i`` -- the fastest synchronised move of any shape, Ruckig's duration --
  whenever the slowest axis's own optimal shape, scaled to the other axes, fits their
  limits (always, for instance, when all axes have the same limits); otherwise it is
  longer (two axes bound by different limits, say one by its velocity, the other by its
  jerk, cannot share one time-optimal shape).
* ``"time"``: every axis reaches its target at ``T = max_i T_min,i`` (time-optimal; the
  slowest axis moves time-optimally); every other axis is its own time-optimal profile
  stretched to ``T`` as above. All axes start and stop together, but each keeps its own
  normalised shape, so the path is a straight line only when those shapes coincide.
  Ruckig's default (``Synchronization.Time``) has the same duration.

Reference (every axis 100 deg/s, 200 deg/s^2, 2000 deg/s^3)::

    >>> from runtime.motion.planner import PtpInput
    >>> v, a, j = (100.0,) * 6, (200.0,) * 6, (2000.0,) * 6
    >>> moves = [(0.0,) * 6, (45.0, 0.0, -45.0, 0.0, 0.0, 0.0), (-45.0, 45.0, 45.0, 0.0, 0.0, 0.0)]
    >>> [f"{plan_ptp_jerk(PtpInput(p, q, v, a, max_jerk=j))[1].duration:.6f}" for p, q in zip(moves, moves[1:])]
    ['1.053939', '1.500000']

(The first is case (iii-a): ``t_j = 0.1``, ``t_a = 0.326970`` s; the second case (i):
``t_j = 0.1``, ``t_a = 0.4``, ``t_v = 0.3`` s.)

(Unlike this module's ``"line"``, :func:`runtime.motion.planner.plan_ptp` gives every
axis but the slowest a trapezoid with the full acceleration and a lower cruise velocity,
so its synchronised axes do not share one normalised shape either.)

Real time: construction (:func:`plan_ptp_jerk`, the profile functions) runs once per
move: closed forms, no iteration, a handful of tuples (about 8 us for six axes with
``"line"``, 14 us with ``"time"``, in CPython 3.11, back to back). :func:`plan_ptp_jerk`
assumes nothing of its input and never raises; the profile functions expect numbers
and raise ``ValueError`` for bad ones. :meth:`JerkProfile.sample` and
:meth:`JerkPtpTrajectory.sample` run every cycle: plain float arithmetic, no allocation
but the result tuples (``"line"``: one shape evaluation and a product per axis, unrolled
for six axes, under 1 us; ``"time"``: the shape per axis, under 2 us), never raise for
a number ``t``. See benchmarks/planner.py.
"""
from __future__ import annotations

from math import cbrt, isfinite, sqrt

from runtime.motion.planner import DISTANCE_EPSILON, MAX_DURATION, PtpInput, SynchronizedTrajectory, check_axes, format_value
from runtime.motion.stops import LineStop, StopRamp
from runtime.motion.trajectory import Result, Trajectory

__all__ = [
    "JerkProfile",
    "JerkPtpTrajectory",
    "SYNCHRONIZATIONS",
    "minimum_duration",
    "plan_ptp_jerk",
    "profile_with_duration",
    "time_optimal_profile",
]

#: The synchronisation modes of :func:`plan_ptp_jerk` (see the module docstring).
SYNCHRONIZATIONS = ("line", "time", "auto")

# A requested duration may fall short of the minimum by this relative amount (rounding
# in the caller's arithmetic); it is then treated as the minimum.
_DURATION_SLACK = 1e-12


def _sampling_parameters(start: float, distance: float, t_j: float, t_acc: float,
                         duration: float, jerk: float, a_p: float, v_p: float) -> tuple:
    """The flat tuple that sampling unpacks: ``(start, end, t_j, t_2, t_acc, jerk / 2,
    jerk / 6, a_p, v_p, v_1, q_1, q_3, t_acc / 2)`` with ``t_2 = t_acc - t_j`` the end of
    phase 2, ``v_1 = jerk t_j^2 / 2`` and ``q_1 = jerk t_j^3 / 6`` the velocity and
    displacement at the end of phase 1, ``q_3 = v_p t_acc / 2`` the displacement at the
    end of the acceleration half. Shared by :class:`JerkProfile` and
    :class:`JerkPtpTrajectory`, so that both sample the very same numbers."""
    half = 0.5 * duration
    if t_acc > half:  # rounding in a stretched profile
        t_acc = half
    if t_j > 0.5 * t_acc:
        t_j = 0.5 * t_acc
    j6 = jerk / 6.0
    return (start, start + distance, t_j, t_acc - t_j, t_acc, 0.5 * jerk, j6, a_p, v_p,
            0.5 * jerk * t_j * t_j, j6 * t_j * t_j * t_j, 0.5 * v_p * t_acc, 0.5 * t_acc)



def _half(tau: float, shape: tuple) -> tuple[float, float, float]:
    """Displacement, velocity and acceleration ``tau`` seconds into the acceleration half
    (and the cruise after it), from ``shape``: the parameters of
    :func:`_sampling_parameters` after ``start, end``. The deceleration half is its
    mirror. Runs every tick (every axis of a jerk-limited PTP move)."""
    t_j, t_2, t_acc, j2, j6, a_p, v_p, v1, q1, q3, h3 = shape
    if tau < t_j:
        return j6 * tau * tau * tau, j2 * tau * tau, 2.0 * j2 * tau
    if tau < t_2:
        u = tau - t_j
        return q1 + u * (v1 + 0.5 * a_p * u), v1 + a_p * u, a_p
    if tau < t_acc:
        r = t_acc - tau
        rr = r * r
        return q3 - r * (v_p - j6 * rr), v_p - j2 * rr, 2.0 * j2 * r
    return v_p * (tau - h3), v_p, 0.0

class JerkProfile:
    """A rest-to-rest double-S profile of one axis (time-optimal or stretched).

    Attributes (read them, do not change them); signed ones point in the direction of
    motion:

    * ``start`` -- position at ``t <= 0``.
    * ``distance`` -- signed distance; the position at ``t >= duration`` is exactly
      ``start + distance``.
    * ``t_j`` -- duration of each of the four constant-jerk phases (1, 3, 5, 7).
    * ``t_a`` -- duration of each of the two constant-acceleration phases (2, 6).
    * ``t_v`` -- duration of the cruise phase (4).
    * ``t_acc`` -- duration of the acceleration half, ``2 t_j + t_a``.
    * ``duration`` -- ``2 t_acc + t_v`` (s).
    * ``jerk`` -- signed jerk of phase 1 (phases 3 and 5 have ``-jerk``, 7 ``+jerk``).
    * ``peak_acceleration`` -- signed acceleration of phase 2 (``jerk * t_j``).
    * ``peak_velocity`` -- signed cruise velocity (``peak_acceleration * (t_j + t_a)``).
    """

    __slots__ = ("start", "distance", "t_j", "t_a", "t_v", "t_acc", "duration", "jerk",
                 "peak_acceleration", "peak_velocity", "_end", "_half", "_shape")

    def __init__(self, start: float, distance: float, t_j: float, t_acc: float,
                 duration: float, jerk: float, peak_acceleration: float, peak_velocity: float):
        p = _sampling_parameters(start, distance, t_j, t_acc, duration, jerk,
                                 peak_acceleration, peak_velocity)
        self._shape = p[2:]  # what _half takes
        self.start = start
        self.distance = distance
        self._end = p[1]
        self.t_j = t_j = p[2]
        self.t_acc = t_acc = p[4]
        self.t_a = t_acc - 2.0 * t_j
        self.t_v = duration - 2.0 * t_acc
        self.duration = duration
        self._half = 0.5 * duration
        self.jerk = jerk
        self.peak_acceleration = peak_acceleration
        self.peak_velocity = peak_velocity

    def sample(self, t: float) -> tuple[float, float, float]:
        """Position, velocity, acceleration at time ``t`` (s).

        ``t`` is clamped to ``[0, duration]``: before the start the axis rests at
        ``start``, from ``duration`` on exactly at ``start + distance``. Real-time safe.
        """
        duration = self.duration
        if t >= duration:  # first: a zero-length profile is at its end at once
            return (self._end, 0.0, 0.0)
        if not t > 0.0:  # also catches NaN
            return (self.start, 0.0, 0.0)
        first = t <= self._half
        q, v, acc = _half(t if first else duration - t, self._shape)  # the second half mirrors the first
        if first:
            return (self.start + q, v, acc)
        return (self._end - q, v, -acc)

    def __repr__(self) -> str:
        return (f"JerkProfile(start={self.start!r}, distance={self.distance!r}, "
                f"t_j={self.t_j!r}, t_a={self.t_a!r}, t_v={self.t_v!r}, "
                f"duration={self.duration!r}, jerk={self.jerk!r})")


# ----------------------------------------------------------------------------- closed forms


def _phases(d: float, v: float, a: float, j: float) -> tuple[float, float, float, float, float]:
    """``(t_j, t_acc, T, a_p, v_p)`` of the time-optimal profile over ``d >= 0``."""
    tj = a / j
    tv = v / a
    if tv > tj:  # v j > a^2: a is reached on the way to v
        t_acc = tv + tj
        if d >= v * t_acc:  # (i): v and a reached, cruise
            return tj, t_acc, d / v + t_acc, a, v
    else:  # a pure jerk triangle on the way to v
        tjv = sqrt(v / j)
        t_acc = tjv + tjv
        if d >= v * t_acc:  # (ii): v reached, a not, cruise
            return tjv, t_acc, d / v + t_acc, j * tjv, v
    if d >= 2.0 * a * tj * tj:  # (iii-a): a reached, v not, no cruise
        w = d / a
        den = 3.0 * tj + sqrt(tj * tj + 4.0 * w)
        t_a = 2.0 * (w - 2.0 * tj * tj) / den if den > 0.0 else 0.0  # 0: both underflowed
        if t_a < 0.0:
            t_a = 0.0
        t_acc = tj + tj + t_a
        return tj, t_acc, t_acc + t_acc, a, a * (tj + t_a)
    tj = cbrt(0.5 * d / j)  # (iii-b): neither v nor a reached
    t_acc = tj + tj
    a_p = j * tj
    return tj, t_acc, t_acc + t_acc, a_p, a_p * tj


def _minimum_duration(distance: float, v: float, a: float, j: float) -> float:
    if distance == 0.0:
        return 0.0
    return _phases(distance if distance > 0.0 else -distance, v, a, j)[2]


def _spec(start: float, distance: float, phases: tuple | None, j: float,
          big_t: float) -> tuple:
    """The :class:`JerkProfile` constructor arguments over ``distance`` from its
    time-optimal ``phases`` (:func:`_phases` of ``|distance|`` under the jerk limit ``j``;
    ``None`` for no motion),
    stretched to ``big_t`` if that is longer than the minimum (module docstring:
    ``lambda = T_min / big_t``; phase times ``/ lambda``, jerk ``* lambda^3``, acceleration
    ``* lambda^2``, velocity ``* lambda``)."""
    if phases is None:
        return (start, distance, 0.0, 0.0, big_t, 0.0, 0.0, 0.0)
    tj, t_acc, t_min, a_p, v_p = phases
    sign = -1.0 if distance < 0.0 else 1.0
    if not big_t > t_min:
        return (start, distance, tj, t_acc, t_min, sign * j, sign * a_p, sign * v_p)
    lam = t_min / big_t
    k = big_t / t_min
    t_acc = 0.5 * big_t if t_acc + t_acc == t_min else t_acc * k  # no cruise stays so
    return (start, distance, tj * k, t_acc, big_t, sign * j * (lam * lam * lam),
            sign * a_p * (lam * lam), sign * v_p * lam)


def _check(distance: float, max_velocity: float, max_acceleration: float,
           max_jerk: float) -> None:
    for name, value in (("max_velocity", max_velocity), ("max_acceleration", max_acceleration),
                        ("max_jerk", max_jerk)):
        if not 0.0 < value < float("inf"):
            raise ValueError(f"{name} must be positive and finite, got {value!r}")
    if not isfinite(distance):
        raise ValueError(f"distance must be finite, got {distance!r}")


def minimum_duration(distance: float, max_velocity: float, max_acceleration: float,
                     max_jerk: float) -> float:
    """The shortest rest-to-rest duration (s) for ``distance`` under the three limits
    (cases (i)-(iii) of the module docstring); ``0`` for ``d = 0``. Raises
    ``ValueError`` for a limit that is not positive and finite or a non-finite distance."""
    _check(distance, max_velocity, max_acceleration, max_jerk)
    return _minimum_duration(distance, max_velocity, max_acceleration, max_jerk)


def time_optimal_profile(start: float, distance: float, max_velocity: float,
                         max_acceleration: float, max_jerk: float) -> JerkProfile:
    """The fastest rest-to-rest double-S profile from ``start`` over the signed
    ``distance``; its ``duration`` equals :func:`minimum_duration`."""
    _check(distance, max_velocity, max_acceleration, max_jerk)
    phases = (_phases(abs(distance), max_velocity, max_acceleration, max_jerk)
              if distance else None)
    return JerkProfile(*_spec(start, distance, phases, max_jerk, 0.0))


def profile_with_duration(start: float, distance: float, max_velocity: float,
                          max_acceleration: float, max_jerk: float,
                          duration: float) -> JerkProfile:
    """A rest-to-rest profile of exactly ``duration`` seconds: the time-optimal one
    stretched by ``lambda = T_min / duration`` (velocity ``* lambda``, acceleration
    ``* lambda^2``, jerk ``* lambda^3``, phase times ``/ lambda``; see the module
    docstring), so it keeps every limit. A zero distance holds the position for
    ``duration``.

    Raises ``ValueError`` if ``duration`` is shorter than :func:`minimum_duration`
    (beyond a relative slack of 1e-12; within it the time-optimal profile is returned)
    or not finite.
    """
    t_min = minimum_duration(distance, max_velocity, max_acceleration, max_jerk)
    if not (duration >= t_min * (1.0 - _DURATION_SLACK) and duration < float("inf")):
        raise ValueError(f"duration must be finite and at least the minimum {t_min!r} s, "
                         f"got {duration!r}")
    phases = (_phases(abs(distance), max_velocity, max_acceleration, max_jerk)
              if distance else None)
    return JerkProfile(*_spec(start, distance, phases, max_jerk, duration))


# ----------------------------------------------------------------------------- trajectory


class JerkPtpTrajectory(SynchronizedTrajectory):
    """A planned, synchronised, jerk-limited PTP move: every axis starts at ``t = 0`` and
    stops at ``t = duration`` (a :class:`~runtime.motion.trajectory.Trajectory`); made by
    :func:`plan_ptp_jerk`.

    * ``duration`` -- seconds.
    * ``profiles`` -- one :class:`JerkProfile` per axis, all of ``duration`` (built on
      first use: sampling does not need them).
    * ``slowest_axis`` -- index (from 0) of the axis with the largest minimal duration
      of its own: the one that sets ``duration`` with ``"time"``; with ``"line"`` the
      duration may be set by several axes' limits together.
    * ``start_position`` / ``target_position`` -- the positions at the start and at the
      end (an axis closer than ``DISTANCE_EPSILON`` to its target starts at the target).
    * ``synchronization`` -- ``"line"`` or ``"time"``.
    """

    __slots__ = ("duration", "start_position", "target_position", "synchronization",
                 "_distances", "_limits", "_slowest", "_specs", "_profiles", "_zeros", "_half",
                 "_shape", "_params")

    def __init__(self, duration: float, start_position: tuple[float, ...],
                 target_position: tuple[float, ...], distances: tuple[float, ...],
                 limits: tuple, shape: tuple | None = None,
                 specs: tuple[tuple, ...] | None = None, slowest_axis: int | None = None):
        """Made by :func:`plan_ptp_jerk` from the (snapped) positions, the per-axis
        signed ``distances`` (0 for an axis that does not move) and
        ``limits = (v_max, a_max, j_max)``; and either ``shape``, for ``"line"``: the
        ``(t_j, t_acc, jerk, a_p, v_p)`` of the unit-distance profile every axis follows
        (axis ``i``: ``start_i + d_i * s(t)``); or ``specs``, for ``"time"``: per axis, the
        :class:`JerkProfile` constructor arguments. ``slowest_axis`` is worked out from
        the limits on first use when not given."""
        self.duration = duration
        self.start_position = start_position
        self.target_position = target_position
        self._distances = distances
        self._limits = limits
        self._slowest = slowest_axis
        self._profiles = None
        self._zeros = (0.0,) * len(distances)
        self._half = 0.5 * duration
        if specs is None:
            self.synchronization = "line"
            self._specs = None
            if shape is None:  # nothing moves
                shape = (0.0, 0.0, 0.0, 0.0, 0.0)
            self._shape = shape
            self._params = _sampling_parameters(0.0, 1.0, shape[0], shape[1], duration,
                                                *shape[2:])[2:]  # what _half takes
        else:
            self.synchronization = "time"
            self._specs = specs
            self._shape = None
            # per axis: (start, end, what _half takes)
            self._params = tuple([(p[0], p[1], p[2:]) for p in (_sampling_parameters(*s) for s in specs)])

    @property
    def profiles(self) -> tuple[JerkProfile, ...]:
        """One :class:`JerkProfile` per axis (made on first use)."""
        profiles = self._profiles
        if profiles is None:
            specs = self._specs
            if specs is None:  # "line": axis i is d_i times the unit shape
                duration = self.duration
                tj, t_acc, jerk, a_p, v_p = self._shape
                specs = [(s, d, tj, t_acc, duration, d * jerk, d * a_p, d * v_p) if d != 0.0
                         else (s, d, 0.0, 0.0, duration, 0.0, 0.0, 0.0)
                         for s, d in zip(self.start_position, self._distances)]
            profiles = self._profiles = tuple([JerkProfile(*s) for s in specs])
        return profiles

    @property
    def slowest_axis(self) -> int:
        """Index (from 0) of the axis with the largest minimal duration of its own."""
        slowest = self._slowest
        if slowest is None:
            minima = [_minimum_duration(d, v, a, j)
                      for d, v, a, j in zip(self._distances, *self._limits)]
            slowest = self._slowest = minima.index(max(minima))
        return slowest

    def _moving(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """``"line"``: one evaluation of the shape, scaled per axis; ``"time"``: each
        axis's own."""
        duration = self.duration
        first = t <= self._half
        tau = t if first else duration - t  # the deceleration half mirrors the first
        if self._specs is None:  # "line": one normalised shape s(t), scaled per axis
            q, v, _a = _half(tau, self._params)
            ds = self._distances
            if first:
                base = self.start_position
            else:
                base = self.target_position
                q = -q
            if len(ds) == 6:  # the arm's six axes, unrolled: twice as fast as a loop
                p0, p1, p2, p3, p4, p5 = base
                d0, d1, d2, d3, d4, d5 = ds
                return ((p0 + d0 * q, p1 + d1 * q, p2 + d2 * q, p3 + d3 * q, p4 + d4 * q,
                         p5 + d5 * q), (d0 * v, d1 * v, d2 * v, d3 * v, d4 * v, d5 * v))
            return (tuple([p + d * q for p, d in zip(base, ds)]),
                    tuple([d * v for d in ds]))
        positions = []
        velocities = []
        put_position = positions.append
        put_velocity = velocities.append
        for start, end, shape in self._params:
            q, v, _a = _half(tau, shape)
            put_position((start + q) if first else (end - q))
            put_velocity(v)
        return tuple(positions), tuple(velocities)

    def stop(self, t: float, positions: tuple, velocities: tuple, rate: float = 1.0) -> Trajectory:
        """On the joint-space line (``"line"``): a jerk-limited :class:`LineStop` on it;
        else (``"time"``) every axis to rest together within its acceleration limit
        (times ``rate^2``) along the direction of motion (:class:`StopRamp`)."""
        if self.synchronization == "line":
            p, v, a = self.at_time(t)
            return LineStop(self.start_position, self._distances, self._limits, p, v, a, rate)
        return StopRamp(positions, velocities, tuple([a * rate * rate for a in self._limits[1]]))

    def __repr__(self) -> str:
        return (f"JerkPtpTrajectory(duration={self.duration!r}, "
                f"slowest_axis={self.slowest_axis}, degrees_of_freedom={len(self._distances)}, "
                f"synchronization={self.synchronization!r})")


# ----------------------------------------------------------------------------- planner

_QUANTITIES = ("current_position", "target_position", "max_velocity", "max_acceleration",
               "max_jerk")
_INF = float("inf")


def _validate(values: tuple) -> tuple[Result, str]:
    """(Result.WORKING, "") if the five sequences can be planned, else the error and its
    message, worded as :func:`runtime.motion.planner.plan_ptp` words it."""
    result, message, _sequences = check_axes(list(zip(_QUANTITIES, values)), _QUANTITIES[2:])
    return result, message


def _plainly_valid(current, target, velocity, acceleration, jerk) -> bool:
    """The common case, checked fast: five equally long, non-empty tuples or lists of
    plain floats, all finite, the limits positive. ``False`` means "look closer"
    (:func:`_validate` finds and words any problem, ints are converted)."""
    try:
        n = len(current)
        if (not n or len(target) != n or len(velocity) != n or len(acceleration) != n
                or len(jerk) != n):
            return False
        for c, t, v, a, j in zip(current, target, velocity, acceleration, jerk):
            # x - x == 0 exactly when x is finite; the comparisons are False for NaN
            if not (type(c) is float and type(t) is float and type(v) is float
                    and type(a) is float and type(j) is float and c - c == 0.0
                    and t - t == 0.0 and 0.0 < v < _INF and 0.0 < a < _INF
                    and 0.0 < j < _INF):
                return False
        return True
    except Exception:  # noqa: BLE001 - anything odd goes to the careful check
        return False


def _too_long(duration, slowest, distances, v_max, a_max, j_max):
    return (Result.ERROR_LIMITS, None,
            f"axis {slowest + 1}: the move needs {format_value(duration)} s, more than "
            f"{format_value(MAX_DURATION)} s (max_velocity {format_value(v_max[slowest])}, "
            f"max_acceleration {format_value(a_max[slowest])}, "
            f"max_jerk {format_value(j_max[slowest])}, "
            f"distance {format_value(distances[slowest])})")


def _too_short(distances, minima, v_max, a_max, j_max):
    """A moving axis whose minimal duration underflowed to 0: limits beyond ~1e290 against
    its distance, not a move that can be sampled."""
    axis = next(i for i, (d, t) in enumerate(zip(distances, minima)) if d != 0.0 and not t > 0.0)
    return (Result.ERROR_LIMITS, None,
            f"axis {axis + 1}: the limits are too large for the distance, the move would take "
            f"0 s (max_velocity {format_value(v_max[axis])}, "
            f"max_acceleration {format_value(a_max[axis])}, "
            f"max_jerk {format_value(j_max[axis])}, distance {format_value(distances[axis])})")


def plan_ptp_jerk(inp: PtpInput) -> tuple[Result, JerkPtpTrajectory | None, str]:
    """Plan the synchronised, jerk-limited PTP move ``inp`` describes
    (:class:`runtime.motion.planner.PtpInput` with ``max_jerk``).

    ``current_position``, ``target_position`` (positions), ``max_velocity``,
    ``max_acceleration``, ``max_jerk`` (per-axis limits, > 0, already scaled by the move's
    fractions): one number per axis; the axes are at rest at the start.
    ``synchronization``: ``"line"`` (a straight line in joint space, the fastest such
    move), ``"time"`` (every axis stretched to the slowest axis's minimal duration;
    Ruckig's default) -- see the module docstring -- or ``"auto"`` (the default): the
    straight line when it is as fast as ``"time"`` (axes whose limits bind alike, the
    common case), else ``"time"``: always the time-optimal duration. The position range
    (``min_position`` / ``max_position``) is not checked here.

    Returns ``(result, trajectory, message)`` like
    :func:`runtime.motion.planner.plan_ptp`, with the same results and messages: on
    success ``Result.WORKING`` (``Result.FINISHED`` when there is nothing to move), the
    :class:`JerkPtpTrajectory` and ``""``; on failure a negative ``Result``, ``None`` and
    a message naming the axis, the quantity and the value. The quantities are named
    ``current_position``, ``target_position``, ``max_velocity``, ``max_acceleration``
    and ``max_jerk`` (the five arguments, in order), e.g.
    ``"axis 3: max_jerk must be positive, got 0"``. Never raises. Runs once per move.
    """
    try:
        start, target = inp.current_position, inp.target_position
        v_max, a_max, j_max = inp.max_velocity, inp.max_acceleration, inp.max_jerk
        synchronization = inp.synchronization
        auto = synchronization == "auto"
        if synchronization == "line" or auto:
            line = True
        elif synchronization == "time":
            line = False
        else:
            return (Result.ERROR_INVALID_INPUT, None,
                    f"synchronization must be 'line', 'time' or 'auto', got {synchronization!r}")
        if _plainly_valid(start, target, v_max, a_max, j_max):
            start, target = tuple(start), tuple(target)
            v_max, a_max, j_max = tuple(v_max), tuple(a_max), tuple(j_max)
        else:
            result, message = _validate((start, target, v_max, a_max, j_max))
            if result != Result.WORKING:
                return result, None, message
            start = tuple([float(x) for x in start])
            target = tuple([float(x) for x in target])
            v_max = tuple([float(x) for x in v_max])
            a_max = tuple([float(x) for x in a_max])
            j_max = tuple([float(x) for x in j_max])
        distances = [t - s for s, t in zip(start, target)]
        snapped = False
        for i, d in enumerate(distances):
            if not (DISTANCE_EPSILON <= d < _INF or -_INF < d <= -DISTANCE_EPSILON):
                if d - d != 0.0:  # +-inf (or NaN): the subtraction overflowed
                    return (Result.ERROR_INVALID_INPUT, None,
                            f"axis {i + 1}: target_position - current_position overflows, "
                            f"got {format_value(target[i])} - {format_value(start[i])}")
                distances[i] = 0.0  # closer than DISTANCE_EPSILON: no motion at all
                snapped = True
        if snapped:
            start = tuple([t if d == 0.0 else s for s, t, d in zip(start, target, distances)])
        limits = (v_max, a_max, j_max)
        if line:
            # the unit-distance shape within every moving axis's limits divided by |d_i|
            big_v = big_a = big_j = _INF
            moving = False
            for d, v, a, j in zip(distances, v_max, a_max, j_max):
                if d != 0.0:
                    moving = True
                    if d < 0.0:
                        d = -d
                    if v < big_v * d:
                        big_v = v / d
                    if a < big_a * d:
                        big_a = a / d
                    if j < big_j * d:
                        big_j = j / d
            if moving:
                if big_v > 0.0 and big_a > 0.0 and big_j > 0.0:
                    tj, t_acc, duration, a_p, v_p = _phases(1.0, big_v, big_a, big_j)
                else:  # a ratio underflowed: tiny limits against a huge distance
                    duration = _INF
            else:
                tj = t_acc = duration = a_p = v_p = 0.0
            if not (duration <= MAX_DURATION and (duration > 0.0 or not moving)):
                minima = [_minimum_duration(d, v, a, j)
                          for d, v, a, j in zip(distances, v_max, a_max, j_max)]
                if moving and not all(t > 0.0 for d, t in zip(distances, minima) if d != 0.0):
                    return _too_short(distances, minima, *limits)
                return _too_long(duration, minima.index(max(minima)), distances, *limits)
            if auto and duration > 0.0:  # the straight line only when it costs no time
                phases = [_phases(d if d > 0.0 else -d, v, a, j) if d != 0.0 else None
                          for d, v, a, j in zip(distances, v_max, a_max, j_max)]
                line = duration <= max(p[2] for p in phases if p is not None) * (1.0 + 1e-12)
            if line:
                trajectory = JerkPtpTrajectory(
                    duration, start, target, tuple(distances), limits,
                    shape=(tj, t_acc, big_j, a_p, v_p) if duration > 0.0 else None)
        if not line:
            if not auto:  # ("auto" has them already)
                phases = [_phases(d if d > 0.0 else -d, v, a, j) if d != 0.0 else None
                          for d, v, a, j in zip(distances, v_max, a_max, j_max)]
            minima = [p[2] if p is not None else 0.0 for p in phases]
            duration = max(minima)
            slowest = minima.index(duration)
            if not duration <= MAX_DURATION:
                return _too_long(duration, slowest, distances, *limits)
            if not all(p[2] > 0.0 for p in phases if p is not None):
                return _too_short(distances, minima, *limits)
            specs = tuple([_spec(s, d, p, j, duration)
                           for s, d, p, j in zip(start, distances, phases, j_max)])
            trajectory = JerkPtpTrajectory(duration, start, target, tuple(distances), limits,
                                           specs=specs, slowest_axis=slowest)
        return (Result.WORKING if duration > 0.0 else Result.FINISHED), trajectory, ""
    except Exception:  # noqa: BLE001 - the contract is: never raise (and never show a Python message)
        return (Result.ERROR, None,
                "internal error in the jerk-limited PTP planner: the move could not be planned (not a "
                "fault of the program)")
