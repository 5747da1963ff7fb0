"""Cartesian paths (``move lin``, ``move circ``) and their timing: the geometry of the
line and the arc, and a jerk-limited profile along them.

Layers, each usable alone::

    path = LinPath(start_pose, end_pose)             # or CircPath(start, via, end)
    move = CartesianMove(path, speed, acc, jerk)     # double-S timing along the path

Conventions
-----------
* **Units**: mm, deg (joint values, roll/pitch/yaw, angles at the API), seconds; mm/s,
  mm/s^2, mm/s^3 for ``speed``, ``acc``, ``jerk``. Radians only inside.
  take a :class:`compiler.values.Pose` (``Rpy`` or ``Quat``) or a 4x4 / 3x4 matrix
  (:func:`pose_tuple`). Poses returned mid-path have pitch in [-90, 90], roll and yaw in
* **Quaternions** are ``(w, x, y, z)`` tuples, unit norm; ``q`` and ``-q`` are the same
  rotation.
* **Orientation** along a path: slerp (the shortest arc) from the start orientation to
  the end orientation in proportion to the path parameter, ``s / length``: a constant
  angular rate about one fixed axis whenever the path speed is constant. The via pose of
  a circle gives only its position; its orientation is ignored (as in most robot
  controllers' default circular mode).
* **Path length** ``length`` (mm), the parameter the timing runs along, is
  ``max(position_length, rotation_angle_rad * orientation_radius)``, with
  :data:`ORIENTATION_RADIUS` = 100 mm by default: so ``speed``, ``acc`` and ``jerk`` bound
  the tool centre point's speed, acceleration and jerk along the path *and* the
  orientation's angular rate (``speed / 100 mm`` rad/s, 143 deg/s at 250 mm/s) and its
  derivatives. For most moves the position dominates and ``length`` is the TCP's path
  length; a pure reorientation (zero ``position_length``) still has a profile; and a move
  that turns a lot over a short distance does not turn arbitrarily fast. (The TCP then
  moves slower than ``speed``; ``position_length`` is the TCP's path.)
* **Circle**: the one through the three positions; the arc runs from the start through
  the via point to the end (less than a full turn). ``ValueError`` when two points are
  closer than :data:`POINT_TOL` or the three lie on a line (the triangle's smallest
  height below :data:`POINT_TOL`).

Timing
------
:class:`CartesianMove` puts a rest-to-rest double-S profile
(:func:`runtime.motion.jerk.time_optimal_profile`) on ``s`` from 0 to ``length``: path
speed ``<= speed``, acceleration ``<= acc``, jerk ``<= jerk``. The jerk defaults to
``DEFAULT_JERK_FACTOR * acc`` = ``10 * acc`` (per second): the acceleration ramps up in
0.1 s.

Real time: construction runs once per move; :meth:`CartesianMove.sample` about 5 us.
"""
from __future__ import annotations

from math import atan2, cos, inf, isfinite, pi, sin, sqrt

from compiler.clauses import Motion
from compiler.geometry import rpy_of_quat
from compiler.values import Pose, Quat

from runtime.motion.jerk import time_optimal_profile
from runtime.motion.kinematics import matrix_to_rpy
from runtime.motion.pathtiming import PathProfile
from runtime.motion.rotation import R2D, Slerp, quat_to_rpy, rpy_to_quat

__all__ = ["CartesianMove", "CircPath", "DEFAULT_JERK_FACTOR", "LinPath", "ORIENTATION_RADIUS", "POINT_TOL",
           "pose_tuple", "positive"]

#: mm per rad: a rotation by ``angle`` counts as ``angle * ORIENTATION_RADIUS`` mm of path
ORIENTATION_RADIUS = 100.0
#: jerk = this * acc (1/s) when a move gives no jerk: the acceleration ramps in 0.1 s
DEFAULT_JERK_FACTOR = 10.0
#: mm: two circle points closer than this coincide; three points with a triangle height
#: below this are collinear
POINT_TOL = 1e-3
#: deg: a joint moving more than this between two check samples is a jump


# ============================================================================ poses


def pose_tuple(pose) -> tuple[float, float, float, float, float, float]:
    """``(x, y, z, roll, pitch, yaw)`` floats of a pose: a 6-sequence, a
    :class:`compiler.values.Pose` (``Rpy`` or ``Quat`` orientation) or a 4x4 / 3x4
    homogeneous matrix. ``ValueError`` for anything else or a non-finite value."""
    if isinstance(pose, Pose):
        p, o = pose.position, pose.orientation
        if isinstance(o, Quat):
            rpy = quat_to_rpy((o.w, o.x, o.y, o.z))
        else:
            rpy = (o.roll, o.pitch, o.yaw)
        out = (p.x, p.y, p.z) + tuple(rpy)
    else:
        try:
            n = len(pose)
            if n in (3, 4) and len(pose[0]) == 4:
                out = (pose[0][3], pose[1][3], pose[2][3]) + tuple(matrix_to_rpy(pose))
            elif n == 6:
                out = tuple(pose)
            else:
                raise TypeError
        except TypeError:
            raise ValueError(f"a pose is (x, y, z, roll, pitch, yaw), a Pose or a 4x4 matrix, "
                             f"got {pose!r}") from None
    out = tuple(float(v) for v in out)
    if not all(isfinite(v) for v in out):
        raise ValueError(f"the pose {out} is not finite")
    return out


def _point(pose) -> tuple[float, float, float]:
    """The position of a pose, or of a bare ``(x, y, z)``."""
    if not isinstance(pose, Pose) and len(pose) == 3 and not hasattr(pose[0], "__len__"):
        out = tuple(float(v) for v in pose)
        if not all(isfinite(v) for v in out):
            raise ValueError(f"the point {out} is not finite")
        return out
    return pose_tuple(pose)[:3]


def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _norm(a) -> float:
    return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


# ============================================================================ paths


class _Path:
    """What :class:`LinPath` and :class:`CircPath` share: the orientation and the length.

    Attributes: ``start``, ``end`` (pose tuples), ``length`` (mm, the parameter of
    :meth:`pose_at`), ``position_length`` (mm, the TCP's path), ``rotation_angle`` (deg,
    0..180, start to end orientation), ``orientation_radius`` (mm/rad).
    """

    __slots__ = ("start", "end", "length", "position_length", "rotation_angle",
                 "orientation_radius", "_slerp", "_inv_length", "_turns")

    kind = ""

    def _setup(self, start, end, position_length: float, orientation_radius: float) -> None:
        if not (orientation_radius > 0.0 and isfinite(orientation_radius)):
            raise ValueError(f"orientation_radius must be positive and finite, got {orientation_radius!r}")
        self.start, self.end = start, end
        self.orientation_radius = orientation_radius
        self._slerp = sl = Slerp(rpy_to_quat(*start[3:]), rpy_to_quat(*end[3:]))
        self._turns = sl.angle > 0.0
        self.rotation_angle = sl.angle * R2D
        self.position_length = position_length
        self.length = length = max(position_length, sl.angle * orientation_radius)
        self._inv_length = 1.0 / length if length > 0.0 else 0.0

    def orientation_at(self, s: float) -> tuple[float, float, float, float]:
        """The orientation quaternion at path length ``s`` (clamped to 0..length)."""
        u = s * self._inv_length
        if u > 1.0:
            u = 1.0
        elif not u > 0.0:
            u = 0.0
        return self._slerp(u)

    def _rpy_at(self, u: float) -> tuple[float, float, float]:
        if not self._turns:
            return self.start[3:]
        return rpy_of_quat(*self._slerp(u))

    def pose_at(self, s: float) -> tuple[float, float, float, float, float, float]:
        """The pose ``(x, y, z, roll, pitch, yaw)`` at path length ``s`` (mm): the start
        for ``s <= 0``, exactly the end for ``s >= length``. Real-time safe."""
        if s >= self.length:
            return self.end
        if not s > 0.0:  # also NaN
            return self.start
        u = s * self._inv_length
        x, y, z = self._position(u)
        r, p, w = self._rpy_at(u)
        return (x, y, z, r, p, w)

    def position_at(self, s: float) -> tuple[float, float, float]:
        """The TCP position at path length ``s`` (clamped to 0..length)."""
        return self.pose_at(s)[:3]

    def tangent_at(self, s: float) -> tuple[float, float, float]:
        """The unit direction of travel of the TCP at ``s`` ((0, 0, 0) for no motion)."""
        raise NotImplementedError

    def _position(self, u: float) -> tuple[float, float, float]:
        raise NotImplementedError


class LinPath(_Path):
    """The straight line from ``start_pose`` to ``end_pose`` (``move lin``): the TCP moves
    on the segment in proportion to ``s / length``, the orientation slerps.

    ``orientation_radius`` (mm per rad, default :data:`ORIENTATION_RADIUS`) sets how a
    rotation counts in ``length`` (module docstring)."""

    __slots__ = ("_p0", "_d", "_dir")
    kind = Motion.LIN

    def __init__(self, start_pose, end_pose, orientation_radius: float = ORIENTATION_RADIUS):
        start, end = pose_tuple(start_pose), pose_tuple(end_pose)
        self._p0 = start[:3]
        self._d = d = _sub(end[:3], start[:3])
        distance = _norm(d)
        self._dir = (d[0] / distance, d[1] / distance, d[2] / distance) if distance > 0.0 else (0.0, 0.0, 0.0)
        self._setup(start, end, distance, orientation_radius)

    def _position(self, u: float) -> tuple[float, float, float]:
        p0, d = self._p0, self._d
        return (p0[0] + u * d[0], p0[1] + u * d[1], p0[2] + u * d[2])

    def tangent_at(self, s: float) -> tuple[float, float, float]:
        return self._dir

    def __repr__(self) -> str:
        return f"LinPath({self.start!r}, {self.end!r})"


class CircPath(_Path):
    """The arc of the circle through the positions of ``start_pose``, ``via_pose`` and
    ``end_pose`` (``move circ VIA, END``), from the start through the via point to the end.
    The orientation slerps from the start's to the end's in proportion to ``s / length``;
    the via pose's orientation is not used (``via_pose`` may be a bare ``(x, y, z)``).

    Attributes besides those of every path: ``centre`` (mm), ``radius`` (mm),
    ``normal`` (unit vector: the arc turns counter-clockwise about it), ``angle``
    (deg, the swept angle, 0..360), ``via_angle`` (deg, where the via point is),
    ``via_length`` (the path length ``s`` at the via point).

    Raises ``ValueError`` when two of the points coincide (closer than
    :data:`POINT_TOL`) or the three lie on a line.
    """

    __slots__ = ("centre", "radius", "normal", "angle", "via_angle", "via_length", "via",
                 "_re1", "_re2", "_sweep", "_e1", "_e2")
    kind = Motion.CIRC

    def __init__(self, start_pose, via_pose, end_pose, orientation_radius: float = ORIENTATION_RADIUS):
        start, end = pose_tuple(start_pose), pose_tuple(end_pose)
        p0, p1, p2 = start[:3], _point(via_pose), end[:3]
        self.via = p1
        u, w, v = _sub(p1, p0), _sub(p2, p0), _sub(p2, p1)
        lu, lw, lv = _norm(u), _norm(w), _norm(v)
        for dist, what in ((lu, "the via point coincides with the start point"),
                           (lv, "the via point coincides with the end point"),
                           (lw, "the end point coincides with the start point")):
            if dist < POINT_TOL:
                hint = ("; a circle needs three distinct points: split a full circle into two "
                        "moves" if dist is lw else "")
                raise ValueError(f"move circ: {what} ({dist:.3f} mm apart){hint}")
        n = _cross(u, w)
        area2 = _norm(n)  # twice the triangle's area
        longest = max(lu, lw, lv)
        height = area2 / longest
        if height < POINT_TOL:
            raise ValueError(f"move circ: the start, via and end points are collinear (the "
                             f"triangle they span is {height:.3g} mm high): no circle through them")
        # circumcentre of (p0, p1, p2): p0 + (|u|^2 w - |w|^2 u) x n / (2 |n|^2)
        k = 1.0 / (2.0 * area2 * area2)
        a = (lu * lu * w[0] - lw * lw * u[0], lu * lu * w[1] - lw * lw * u[1],
             lu * lu * w[2] - lw * lw * u[2])
        c = _cross(a, n)
        centre = (p0[0] + k * c[0], p0[1] + k * c[1], p0[2] + k * c[2])
        nz = (n[0] / area2, n[1] / area2, n[2] / area2)
        r0 = _sub(p0, centre)
        along = _dot(r0, nz)  # rounding only: keep e1 in the plane
        r0 = (r0[0] - along * nz[0], r0[1] - along * nz[1], r0[2] - along * nz[2])
        radius = _norm(r0)
        e1 = (r0[0] / radius, r0[1] / radius, r0[2] / radius)
        e2 = _cross(nz, e1)
        e2n = _norm(e2)
        e2 = (e2[0] / e2n, e2[1] / e2n, e2[2] / e2n)
        two_pi = 2.0 * pi

        def angle_of(p):
            d = _sub(p, centre)
            a = atan2(_dot(d, e2), _dot(d, e1))
            return a + two_pi if a <= 0.0 else a

        via_angle = angle_of(p1)
        sweep = angle_of(p2)
        if not 0.0 < via_angle < sweep:  # cannot happen but for rounding: the order is fixed by n
            raise ValueError("move circ: the start, via and end points are too close to collinear")
        self.centre, self.radius, self.normal = centre, radius, nz
        self._e1, self._e2 = e1, e2
        self._re1 = (radius * e1[0], radius * e1[1], radius * e1[2])
        self._re2 = (radius * e2[0], radius * e2[1], radius * e2[2])
        self._sweep = sweep
        self.angle = sweep * R2D
        self.via_angle = via_angle * R2D
        self._setup(start, end, radius * sweep, orientation_radius)
        self.via_length = self.length * via_angle / sweep

    def _position(self, u: float) -> tuple[float, float, float]:
        phi = u * self._sweep
        c, s = cos(phi), sin(phi)
        (cx, cy, cz), (ax, ay, az), (bx, by, bz) = self.centre, self._re1, self._re2
        return (cx + c * ax + s * bx, cy + c * ay + s * by, cz + c * az + s * bz)

    def tangent_at(self, s: float) -> tuple[float, float, float]:
        u = min(max(s * self._inv_length, 0.0), 1.0)
        phi = u * self._sweep
        c, sn = cos(phi), sin(phi)
        e1, e2 = self._e1, self._e2
        return (-sn * e1[0] + c * e2[0], -sn * e1[1] + c * e2[1], -sn * e1[2] + c * e2[2])

    def __repr__(self) -> str:
        return f"CircPath({self.start!r}, {self.via!r}, {self.end!r})"


# ============================================================================ timing


def positive(name: str, value) -> float:
    """``value`` as a float, or ``ValueError`` naming ``name`` unless it is a positive,
    finite number (not a bool): the check of a move's and a path check's limits."""
    if isinstance(value, bool):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number, got {value!r}") from None
    if not 0.0 < value < inf:
        raise ValueError(f"{name} must be positive and finite, got {value!r}")
    return value


class CartesianMove:
    """A path with a jerk-limited rest-to-rest timing: ``s(t)`` is the time-optimal
    double-S profile from 0 to ``path.length`` with path speed ``<= speed`` (mm/s),
    acceleration ``<= acc`` (mm/s^2) and jerk ``<= jerk`` (mm/s^3; default
    ``DEFAULT_JERK_FACTOR * acc``), or the ``profile`` given (any with ``sample(t) ->
    (s, v, a)``, ``duration``, ``peak_velocity`` and ``t_acc`` from 0 to
    ``path.length``, within those limits: a
    :class:`runtime.motion.pathtiming.PathProfile` that slows down where the joints need
    it). Raises ``ValueError`` for a limit that is not positive and finite.

    Attributes: ``path``, ``speed``, ``acc``, ``jerk``, ``profile`` (the
    :class:`runtime.motion.jerk.JerkProfile` of ``s``), ``duration`` (s).
    """

    __slots__ = ("path", "speed", "acc", "jerk", "profile", "duration", "_tcp_ratio")

    def __init__(self, path: _Path, speed: float, acc: float, jerk: float | None = None, profile=None):
        self.speed = speed = positive("speed", speed)
        self.acc = acc = positive("acc", acc)
        self.jerk = jerk = positive("jerk", DEFAULT_JERK_FACTOR * acc if jerk is None else jerk)
        self.path = path
        self.profile = time_optimal_profile(0.0, path.length, speed, acc, jerk) if profile is None else profile
        self.duration = self.profile.duration
        self._tcp_ratio = path.position_length / path.length if path.length > 0.0 else 0.0

    def stop_limits(self, s: float, v: float, a: float = 0.0) -> tuple[float, float] | None:
        """The path acceleration and jerk a stop from ``s`` at path speed ``v`` and
        acceleration ``a`` may use:
        the move's ``acc`` and ``jerk``, or, when its profile slows down where the joints
        need it (:class:`runtime.motion.pathtiming.PathProfile`), those of the stretch
        the stop runs through."""
        if isinstance(self.profile, PathProfile):
            return self.profile.stop_limits(s, v, a)
        return self.acc, self.jerk

    def progress(self, t: float) -> tuple[float, float, float]:
        """``(s, ds/dt, d2s/dt2)`` at time ``t`` (clamped to the move)."""
        return self.profile.sample(t)

    def fraction(self, t: float) -> float:
        """How far along the path (0..1) the move is at time ``t``."""
        length = self.path.length
        return self.profile.sample(t)[0] / length if length > 0.0 else 1.0 if t >= self.duration else 0.0

    def sample(self, t: float) -> tuple[float, float, float, float, float, float]:
        """The commanded pose at time ``t``: the start before 0, exactly the end from
        ``duration`` on. Real-time safe."""
        return self.path.pose_at(self.profile.sample(t)[0])

    def sample_with_speed(self, t: float) -> tuple[tuple, float]:
        """``(pose, tcp_speed)`` at time ``t``: ``tcp_speed`` (mm/s) is the TCP's speed
        along its path, ``ds/dt * position_length / length`` (equal to ``ds/dt`` unless the
        orientation sets the length)."""
        s, v, _ = self.profile.sample(t)
        return self.path.pose_at(s), v * self._tcp_ratio

    def __repr__(self) -> str:
        return (f"CartesianMove({self.path!r}, speed={self.speed!r}, acc={self.acc!r}, "
                f"jerk={self.jerk!r}, duration={self.duration!r})")
