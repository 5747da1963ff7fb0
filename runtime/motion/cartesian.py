"""Cartesian paths (``move lin``, ``move circ``): geometry, jerk-limited timing, the check
of a whole path against the arm's kinematics, and the per-tick joint values.

Layers, each usable alone::

    path  = LinPath(start_pose, end_pose)            # or CircPath(start, via, end)
    move  = CartesianMove(path, speed, acc, jerk)    # double-S timing along the path
    check = check_path(move, kinematics, start_joints, axis_limits=spec.main_axes)
    stream = check.stream(period=0.005)              # .duration, .sample(t) -> (q, qdot)

or in one call that never raises, shaped like :func:`runtime.motion.jerk.plan_ptp_jerk`
(the trajectory generator's ``self.trajectory`` only needs ``duration`` and
``sample(t) -> (positions, velocities)``)::

    stream, message = plan_lin(kinematics, positions, target_pose, speed, acc,
                               axis_limits=spec.main_axes)
    stream, message = plan_circ(kinematics, positions, via_pose, target_pose, speed, acc,
                                axis_limits=spec.main_axes)

Conventions
-----------
* **Units**: mm, deg (joint values, roll/pitch/yaw, angles at the API), seconds; mm/s,
  mm/s^2, mm/s^3 for ``speed``, ``acc``, ``jerk``. Radians only inside.
* **Poses** are ``(x, y, z, roll, pitch, yaw)`` tuples with the RPY convention of
  :mod:`runtime.motion.kinematics`: ``R = Rz(yaw) Ry(pitch) Rx(roll)``. Constructors also
  take a :class:`compiler.values.Pose` (``Rpy`` or ``Quat``) or a 4x4 / 3x4 matrix
  (:func:`pose_tuple`). Poses returned mid-path have pitch in [-90, 90], roll and yaw in
  [-180, 180] (like ``Kinematics.forward``); the first and the last pose of a path are the
  caller's tuples, unchanged.
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

The check before the move (:func:`check_path`)
----------------------------------------------
Samples the timed path uniformly in time, densely enough that the TCP moves at most
``step`` mm (default 1) and the orientation at most ``step_deg`` deg (default 1) between
two samples, and at least ``min_samples`` (50) intervals; solves the inverse kinematics
of every sample with ``near`` = the previous sample's joints (the first: the start
joints, which must put the TCP at the path's start). It fails (:class:`PathError`, a
``ValueError``, with ``fraction`` 0..1 of the path, ``reason`` and ``axis``) when

* a sample has no joint values: ``"unreachable"``, ``"singular"`` (within the
  kinematics' tolerances of a singularity), ``"limit"`` (outside the axis limits; also
  ``axis_limits``' ``min``/``max`` when given);
* a joint moves more than ``max_joint_step`` deg (default 10) between two samples. The
  cause is named: the arm's configuration cannot go on (the inverse kinematics fell back
  to another configuration because the current one runs into an axis limit or out of
  reach: ``"limit"`` / ``"unreachable"``, with the kinematics' reason); an axis reaches
  its limit and its solution would wrap by 360 deg (``"limit"``); the path passes next
  to a singularity (``"jump"``, named after the smallest margin of
  :meth:`Kinematics.singularity_margins`); else the solution jumps (``"jump"``);
* the configuration (shoulder / elbow / wrist-flip bits) changes between two samples
  without a jump (``"configuration"``): the path passes through a singularity --
  through the wrist singularity A5 changes sign, over axis 1 the shoulder flips;
* a joint velocity (finite differences over the samples, with the profile's timing)
  exceeds that axis's ``max_velocity`` from ``axis_limits`` (``"velocity"``): the
  message names the axis, the velocity, the limit, where, and the highest ``speed``
  at which the path would pass (the joint rates are proportional to the path speed);
* with ``check_acceleration=True``, likewise for ``max_acceleration`` (second
  differences), off by default: the Cartesian limits of the specification (8000 mm/s^2)
  can exceed the main axes' acceleration limits far from the base.

Geometric failures are reported at the first sample where they occur; velocity
(acceleration) violations after the whole path is known good, at the worst one.

:func:`plan_lin` and :func:`plan_circ` with a specification's axes never refuse a move
for its joint velocities: they time it within every joint's velocity, acceleration and
jerk limit first (:func:`joint_limit_scale`: the move run k times slower, the one factor
that brings every joint within JOINT_LIMIT_SHARE of its limits at samples at least as
fine as the setpoints), then check it as above.

Real time
---------
Construction and :func:`check_path` run once per move (the check: about 40 us per
sample in CPython 3.11, so about 13 ms for a 200 mm move at 1 mm steps; it is not
real-time code: run it when the move is planned, ahead of its start). Per tick:
:meth:`CartesianMove.sample` (about 5 us), :meth:`CheckedPath.joints_at` (one inverse
kinematics, about 22 us) and :meth:`JointStream.sample` (about 29 us: one inverse
kinematics per call when called at successive ticks ``t, t + period, ...``; it solves
one period ahead and returns central-difference velocities). Plain floats and
``math``; no NumPy.
"""
from __future__ import annotations

from bisect import bisect_left
from math import atan2, ceil, cos, floor, inf, isfinite, log10, pi, sin, sqrt
from typing import Sequence

import numpy as np

from compiler.values import Joint, Pose, Quat

from ..timing import SETPOINT_PERIOD
from .jerk import JerkStop, time_optimal_profile
from .kinematics import (
    ELBOW_DOWN,
    SHOULDER_BACK,
    WRIST_FLIP,
    Kinematics,
    KinematicsError,
    configuration_name,
    matrix_to_rpy,
    rotation_to_rpy,
)

__all__ = [
    "CartesianMove",
    "CheckedPath",
    "CircPath",
    "DEFAULT_JERK_FACTOR",
    "JointStream",
    "PathStop",
    "LinPath",
    "MAX_JOINT_STEP",
    "ORIENTATION_RADIUS",
    "POINT_TOL",
    "PathError",
    "START_TOL",
    "check_path",
    "matrix_to_quat",
    "plan_circ",
    "plan_lin",
    "pose_tuple",
    "quat_angle",
    "quat_multiply",
    "quat_to_matrix",
    "quat_to_rpy",
    "rpy_to_quat",
    "slerp",
]

#: mm per rad: a rotation by ``angle`` counts as ``angle * ORIENTATION_RADIUS`` mm of path
ORIENTATION_RADIUS = 100.0
#: jerk = this * acc (1/s) when a move gives no jerk: the acceleration ramps in 0.1 s
DEFAULT_JERK_FACTOR = 10.0
#: mm: two circle points closer than this coincide; three points with a triangle height
#: below this are collinear
POINT_TOL = 1e-3
#: deg: a joint moving more than this between two check samples is a jump
MAX_JOINT_STEP = 10.0
#: the fewest intervals a path is checked in (:func:`check_path`)
MIN_SAMPLES = 50
#: the check's start pose may differ from the forward kinematics of the start joints by
#: this much (mm, deg)
START_TOL = 1e-3

_D2R = pi / 180.0
_R2D = 180.0 / pi
# below this slerp angle (rad) the slerp weights use their series (error ~ omega^4 / 100)
_SMALL_ANGLE = 1e-4


class PathError(ValueError):
    """A Cartesian path the arm cannot follow.

    * ``fraction`` -- where along the path (0..1 of ``length``) it fails;
    * ``reason`` -- ``"start"``, ``"unreachable"``, ``"singular"``, ``"limit"``,
      ``"configuration"``, ``"jump"``, ``"velocity"`` or ``"acceleration"``;
    * ``axis`` -- the axis name concerned, or ``None``;
    * ``str(error)`` -- the message.
    """

    def __init__(self, message: str, fraction: float, reason: str, axis: str | None = None):
        super().__init__(message)
        self.message = message
        self.fraction = fraction
        self.reason = reason
        self.axis = axis


# ============================================================================ orientation


def rpy_to_quat(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """The unit quaternion ``(w, x, y, z)`` of ``Rz(yaw) Ry(pitch) Rx(roll)`` (degrees)."""
    hr, hp, hy = 0.5 * roll * _D2R, 0.5 * pitch * _D2R, 0.5 * yaw * _D2R
    cr, sr, cp, sp, cy, sy = cos(hr), sin(hr), cos(hp), sin(hp), cos(hy), sin(hy)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def quat_to_matrix(q) -> tuple:
    """The 3x3 rotation matrix (nested tuples) of a quaternion ``(w, x, y, z)``
    (normalised here, so any non-zero quaternion will do)."""
    w, x, y, z = q
    n = w * w + x * x + y * y + z * z
    if not (n > 0.0 and isfinite(n)):
        raise ValueError(f"the quaternion {tuple(q)} is not a rotation")
    s = 2.0 / n
    return ((1.0 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)),
            (s * (x * y + w * z), 1.0 - s * (x * x + z * z), s * (y * z - w * x)),
            (s * (x * z - w * y), s * (y * z + w * x), 1.0 - s * (x * x + y * y)))


def matrix_to_quat(matrix) -> tuple[float, float, float, float]:
    """The unit quaternion ``(w, x, y, z)``, ``w >= 0``, of a 3x3 rotation matrix (or the
    rotation of a 4x4 / 3x4 one). Shepperd's method: it divides by the largest of
    ``4 w^2, 4 x^2, 4 y^2, 4 z^2``, accurate for every rotation, 180 deg included."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = (tuple(row[:3]) for row in matrix[:3])
    tr = r00 + r11 + r22
    if tr > 0.0:
        s = 2.0 * sqrt(tr + 1.0)
        w, x, y, z = 0.25 * s, (r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s
    elif r00 >= r11 and r00 >= r22:
        s = 2.0 * sqrt(max(1.0 + r00 - r11 - r22, 0.0)) or 1.0
        w, x, y, z = (r21 - r12) / s, 0.25 * s, (r01 + r10) / s, (r02 + r20) / s
    elif r11 >= r22:
        s = 2.0 * sqrt(max(1.0 + r11 - r00 - r22, 0.0)) or 1.0
        w, x, y, z = (r02 - r20) / s, (r01 + r10) / s, 0.25 * s, (r12 + r21) / s
    else:
        s = 2.0 * sqrt(max(1.0 + r22 - r00 - r11, 0.0)) or 1.0
        w, x, y, z = (r10 - r01) / s, (r02 + r20) / s, (r12 + r21) / s, 0.25 * s
    n = sqrt(w * w + x * x + y * y + z * z)
    if w < 0.0:
        n = -n
    return (w / n, x / n, y / n, z / n)


def _rpy_of_quat(w: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in degrees of a unit quaternion: the matrix entries that
    :func:`runtime.motion.kinematics.matrix_to_rpy` uses, and its method (yaw first, then
    roll and pitch from ``Rz(-yaw) R``; at gimbal lock yaw = 0)."""
    r00 = 1.0 - 2.0 * (y * y + z * z)
    r01 = 2.0 * (x * y - w * z)
    r02 = 2.0 * (x * z + w * y)
    r10 = 2.0 * (x * y + w * z)
    r11 = 1.0 - 2.0 * (x * x + z * z)
    r12 = 2.0 * (y * z - w * x)
    r20 = 2.0 * (x * z - w * y)
    r21 = 2.0 * (y * z + w * x)
    r22 = 1.0 - 2.0 * (x * x + y * y)
    return rotation_to_rpy(r00, r01, r02, r10, r11, r12, r20, r21, r22)


def quat_to_rpy(q) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in degrees of a quaternion ``(w, x, y, z)`` (normalised here),
    in the ranges of ``Kinematics.forward``."""
    w, x, y, z = q
    n = sqrt(w * w + x * x + y * y + z * z)
    if not (n > 0.0 and isfinite(n)):
        raise ValueError(f"the quaternion {tuple(q)} is not a rotation")
    return _rpy_of_quat(w / n, x / n, y / n, z / n)


def quat_multiply(a, b) -> tuple[float, float, float, float]:
    """The Hamilton product ``a b`` (the rotation ``b`` first, then ``a``)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw)


def _half_angle(q0, q1) -> float:
    """The angle (rad, 0..pi/2) between the unit 4-vectors ``q0`` and the one of
    ``+-q1`` nearer it: half the rotation angle from ``q0`` to ``q1``. Computed as
    ``2 atan2(|q1 - q0|, |q1 + q0|)``, accurate at 0 and at pi/2 (where ``acos`` of the
    dot product is not)."""
    w0, x0, y0, z0 = q0
    w1, x1, y1, z1 = q1
    if w0 * w1 + x0 * x1 + y0 * y1 + z0 * z1 < 0.0:
        w1, x1, y1, z1 = -w1, -x1, -y1, -z1
    dw, dx, dy, dz = w1 - w0, x1 - x0, y1 - y0, z1 - z0
    sw, sx, sy, sz = w1 + w0, x1 + x0, y1 + y0, z1 + z0
    return 2.0 * atan2(sqrt(dw * dw + dx * dx + dy * dy + dz * dz),
                       sqrt(sw * sw + sx * sx + sy * sy + sz * sz))


def quat_angle(q0, q1) -> float:
    """The rotation angle (deg, 0..180) that turns orientation ``q0`` into ``q1``."""
    return 2.0 * _half_angle(_unit(q0), _unit(q1)) * _R2D


def _unit(q) -> tuple[float, float, float, float]:
    w, x, y, z = q
    n = sqrt(w * w + x * x + y * y + z * z)
    if not (n > 0.0 and isfinite(n)):
        raise ValueError(f"the quaternion {tuple(q)} is not a rotation")
    return (w / n, x / n, y / n, z / n)


def _sin_ratio(k: float, omega: float, inv_sin: float) -> float:
    """``sin(k omega) / sin(omega)``; for ``omega`` below :data:`_SMALL_ANGLE` its series
    ``k (1 + (1 - k^2) omega^2 / 6)`` (exact to ~1e-17 there)."""
    if omega < _SMALL_ANGLE:
        return k * (1.0 + (1.0 - k * k) * omega * omega / 6.0)
    return sin(k * omega) * inv_sin


class _Slerp:
    """Slerp from ``q0`` to ``q1`` with the constants worked out once (for the paths)."""

    __slots__ = ("q0", "q1", "omega", "inv_sin", "angle")

    def __init__(self, q0, q1):
        q0 = _unit(q0)
        q1 = _unit(q1)
        if q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3] < 0.0:
            q1 = (-q1[0], -q1[1], -q1[2], -q1[3])  # the shortest arc
        self.q0, self.q1 = q0, q1
        self.omega = omega = _half_angle(q0, q1)
        self.inv_sin = 1.0 / sin(omega) if omega >= _SMALL_ANGLE else 0.0
        self.angle = 2.0 * omega  # rad: the rotation from q0 to q1

    def __call__(self, u: float) -> tuple[float, float, float, float]:
        omega, inv_sin = self.omega, self.inv_sin
        a = _sin_ratio(1.0 - u, omega, inv_sin)
        b = _sin_ratio(u, omega, inv_sin)
        w0, x0, y0, z0 = self.q0
        w1, x1, y1, z1 = self.q1
        w, x, y, z = a * w0 + b * w1, a * x0 + b * x1, a * y0 + b * y1, a * z0 + b * z1
        n = 1.0 / sqrt(w * w + x * x + y * y + z * z)
        return (w * n, x * n, y * n, z * n)


def slerp(q0, q1, s: float) -> tuple[float, float, float, float]:
    """Spherical linear interpolation of orientations: ``q0`` at ``s = 0``, ``q1`` (or
    ``-q1``, the same rotation) at ``s = 1``, turning about one fixed axis at a constant
    rate by ``s`` times the rotation angle from ``q0`` to ``q1``, along the shorter way
    (``q1`` is negated when ``q0 . q1 < 0``; at exactly 180 deg, ``q0 . q1 = 0``, the
    way ``q1`` is given is taken). The weights ``sin((1 - s) omega) / sin(omega)`` and
    ``sin(s omega) / sin(omega)`` use their series for tiny ``omega``; the result is
    renormalised. ``s`` outside 0..1 extrapolates along the same great circle."""
    return _Slerp(q0, q1)(s)


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
        self._slerp = sl = _Slerp(rpy_to_quat(*start[3:]), rpy_to_quat(*end[3:]))
        self._turns = sl.angle > 0.0
        self.rotation_angle = sl.angle * _R2D
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
        return _rpy_of_quat(*self._slerp(u))

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
    kind = "lin"

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
    kind = "circ"

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
                raise ValueError(f"move circ: {what} ({dist:.3g} mm apart){hint}")
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
        self.angle = sweep * _R2D
        self.via_angle = via_angle * _R2D
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


def _positive(name: str, value) -> float:
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
    ``DEFAULT_JERK_FACTOR * acc``). Raises ``ValueError`` for a limit that is not
    positive and finite.

    Attributes: ``path``, ``speed``, ``acc``, ``jerk``, ``profile`` (the
    :class:`runtime.motion.jerk.JerkProfile` of ``s``), ``duration`` (s).
    """

    __slots__ = ("path", "speed", "acc", "jerk", "profile", "duration", "_tcp_ratio")

    def __init__(self, path: _Path, speed: float, acc: float, jerk: float | None = None):
        self.speed = speed = _positive("speed", speed)
        self.acc = acc = _positive("acc", acc)
        self.jerk = jerk = _positive("jerk", DEFAULT_JERK_FACTOR * acc if jerk is None else jerk)
        self.path = path
        self.profile = time_optimal_profile(0.0, path.length, speed, acc, jerk)
        self.duration = self.profile.duration
        self._tcp_ratio = path.position_length / path.length if path.length > 0.0 else 0.0

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


# ============================================================================ the check


def _percent(fraction: float) -> str:
    p = 100.0 * fraction
    if 0.0 < p < 1.0 or 99.0 < p < 100.0:
        return f"{p:.1f} %"
    return f"{p:.0f} %"


def _start_joints(joints) -> tuple[float, ...]:
    if isinstance(joints, Joint):
        joints = joints.main
    joints = tuple(float(v) for v in joints)
    if len(joints) != 6:
        raise ValueError(f"start_joints: expected six joint values, got {len(joints)}")
    return joints


def _axis_limits(axis_limits):
    """``(positions, velocities, accelerations, jerks)``: six ``(min, max)`` pairs or None,
    six max velocities or None, six max accelerations or None, six max jerks or None."""
    if axis_limits is None:
        return None, None, None, None
    if hasattr(axis_limits, "main_axes"):  # a Spec
        axis_limits = axis_limits.main_axes
    items = list(axis_limits)
    if len(items) != 6:
        raise ValueError(f"axis_limits: expected six axes, got {len(items)}")
    if all(hasattr(a, "max_velocity") for a in items):
        vel = tuple(float(a.max_velocity) for a in items)
        acc = (tuple(float(a.max_acceleration) for a in items)
               if all(hasattr(a, "max_acceleration") for a in items) else None)
        jerk = tuple(float(a.max_jerk) for a in items) if all(hasattr(a, "max_jerk") for a in items) else None
        pos = (tuple((float(a.min), float(a.max)) for a in items)
               if all(hasattr(a, "min") and hasattr(a, "max") for a in items) else None)
    else:
        vel = tuple(float(v) for v in items)
        acc = pos = jerk = None
    if not all(v > 0.0 for v in vel):
        raise ValueError(f"axis_limits: every max_velocity must be positive, got {vel}")
    return pos, vel, acc, jerk


def _nice_speed(speed: float) -> str:
    """A speed rounded down to three significant digits, as text."""
    if not speed > 0.0:
        return "0"
    unit = 10.0 ** (floor(log10(speed)) - 2)
    v = floor(speed / unit * (1.0 + 1e-12)) * unit
    return f"{v:.0f}" if v >= 100.0 else f"{v:.3g}"


class CheckedPath:
    """A :class:`CartesianMove` that :func:`check_path` found the arm can follow, with
    the joint values it found.

    * ``move``, ``kinematics``, ``start_joints``;
    * ``times`` (s), ``fractions`` (0..1), ``joints`` (six-tuples): the check's samples,
      uniform in time, the first at 0 (the start joints' solution), the last at
      ``duration`` (the end's solution, nearest along the path);
    * ``peak_velocities`` (deg/s per axis, the largest finite-difference velocity);
    * ``min_margins`` -- the smallest ``(shoulder mm, elbow, wrist)`` singularity margins
      along the path (:meth:`Kinematics.singularity_margins`);
    * ``duration`` (s).
    """

    __slots__ = ("move", "kinematics", "start_joints", "times", "fractions", "joints",
                 "peak_velocities", "min_margins", "duration")

    def __init__(self, move, kinematics, start_joints, times, fractions, joints,
                 peak_velocities, min_margins):
        self.move, self.kinematics, self.start_joints = move, kinematics, start_joints
        self.times, self.fractions, self.joints = times, fractions, joints
        self.peak_velocities, self.min_margins = peak_velocities, min_margins
        self.duration = move.duration

    @property
    def end_joints(self) -> tuple[float, ...]:
        return self.joints[-1]

    def seed(self, t: float) -> tuple[float, ...]:
        """The check's joint values at the sample nearest time ``t``: a ``near`` for an
        inverse kinematics at ``t`` that stays on the checked branch."""
        times = self.times
        i = bisect_left(times, t)
        if i >= len(times):
            return self.joints[-1]
        if i > 0 and t - times[i - 1] < times[i] - t:
            i -= 1
        return self.joints[i]

    def joints_at(self, t: float, near: Sequence[float] | None = None) -> tuple[float, ...]:
        """The joint values at time ``t``: one inverse kinematics of the commanded pose,
        nearest ``near`` (the last tick's joints; default the check's nearest sample).
        Raises ``KinematicsError`` only if the arm cannot follow after all (a check with
        the same kinematics makes that impossible but for rounding). About 20 us."""
        if t >= self.duration:
            return self.joints[-1]
        if not t > 0.0:
            return self.start_joints
        return self.kinematics.inverse(self.move.sample(t), near=self.seed(t) if near is None else near)

    def stream(self, period: float = SETPOINT_PERIOD, additional: Sequence[float] = ()) -> "JointStream":
        """A :class:`JointStream` over this path, sampled every ``period`` s; the
        ``additional`` axes (positions) are held."""
        return JointStream(self, period, additional)


def check_path(move: CartesianMove, kinematics: Kinematics, start_joints: Sequence[float],
               axis_limits=None, step: float = 1.0, step_deg: float = 1.0,
               min_samples: int = MIN_SAMPLES, max_joint_step: float = MAX_JOINT_STEP,
               check_acceleration: bool = False, start_tolerance: float = START_TOL,
               check_velocity: bool = True) -> CheckedPath:
    """Check that the arm can follow ``move`` from ``start_joints`` (module docstring);
    return the :class:`CheckedPath` or raise :class:`PathError`.

    ``axis_limits``: the six main axes' limits -- the specification's axes
    (``spec.main_axes`` or the ``Spec`` itself: ``min``, ``max``, ``max_velocity``, and
    ``max_acceleration`` for ``check_acceleration``), or six max velocities (deg/s);
    ``None``: no velocity check (the position limits are the kinematics' own). ``step``
    (mm) and ``step_deg`` (deg): the largest TCP and orientation motion between two
    samples; ``min_samples``: the fewest intervals; ``max_joint_step`` (deg): the largest
    joint motion between two samples; ``start_tolerance`` (mm and deg): how far the
    path's start may be from the forward kinematics of ``start_joints``;
    ``check_velocity=False``: the joint velocities are not checked (what
    :func:`joint_limit_scale` measures).
    ``ValueError`` (not ``PathError``) for arguments that make no sense.
    """
    q = _start_joints(start_joints)
    pos_limits, vel_limits, acc_limits, _ = _axis_limits(axis_limits)
    step = _positive("step", step)
    step_deg = _positive("step_deg", step_deg)
    max_joint_step = _positive("max_joint_step", max_joint_step)
    if check_acceleration and acc_limits is None:
        raise ValueError("check_acceleration needs axis_limits with max_acceleration (the spec's axes)")
    path, profile = move.path, move.profile
    names = kinematics.names
    length = path.length

    # the path must start where the arm is
    fk = kinematics.forward_matrix(q)
    start = path.start
    off = sqrt(sum((fk[i][3] - start[i]) ** 2 for i in range(3)))
    turn = quat_angle(matrix_to_quat(fk), rpy_to_quat(*start[3:]))
    if off > start_tolerance or turn > start_tolerance:
        raise PathError(f"the path does not start where the arm is: the start joints put the "
                        f"tool {off:.3f} mm and {turn:.3f} deg away from the path's start",
                        0.0, "start")

    duration = move.duration
    if duration > 0.0:
        v_peak = abs(profile.peak_velocity)
        n = max(int(min_samples), 1,
                ceil(duration * v_peak * path.position_length / length / step),
                ceil(duration * v_peak * path.rotation_angle / length / step_deg))
        dt = duration / n
    else:
        n, dt = 0, 0.0

    inverse, configuration, margins = (kinematics.inverse, kinematics.configuration,
                                       kinematics.singularity_margins)
    sample = profile.sample
    pose_at = path.pose_at
    times, fractions, joints = [], [], []
    config = None
    peak = [0.0] * 6
    worst_velocity = None  # (ratio, axis, need, fraction)
    worst_acceleration = None
    gain = [0.0] * 6  # the largest |dq/ds| per axis (deg per mm of s)
    min_margins = [inf, inf, inf]
    prev_s = 0.0
    prev_v = None  # the previous interval's joint velocities
    for i in range(n + 1):
        t = duration if i == n else i * dt
        s = sample(t)[0]
        fraction = s / length if length > 0.0 else 1.0 if i == n else 0.0
        pose = pose_at(s)
        try:
            qi = inverse(pose, near=q)
        except KinematicsError as exc:
            raise _kinematics_failure(str(exc), fraction) from None
        if pos_limits is not None:
            for j, ((lo, hi), v) in enumerate(zip(pos_limits, qi)):
                if not lo - 1e-9 <= v <= hi + 1e-9:
                    raise PathError(f"the path leaves the axis limits at {_percent(fraction)} of its "
                                    f"length ({names[j]} would be {v:.2f} deg, limit {lo:g}..{hi:g})",
                                    fraction, "limit", names[j])
        c = configuration(qi)
        m = margins(qi)
        for k in range(3):
            if m[k] < min_margins[k]:
                min_margins[k] = m[k]
        if i == 0:
            config = c
        else:
            dq = [b - a for a, b in zip(q, qi)]
            big = max(range(6), key=lambda j: abs(dq[j]))
            if abs(dq[big]) > max_joint_step:
                raise _jump_failure(kinematics, pose, q, qi, config, c, big, s - prev_s, path,
                                    fraction, max_joint_step, margins(q), m)
            if c != config:
                raise _configuration_failure(config, c, fraction, names, q, qi)
            h = t - times[-1]
            vel = [d / h for d in dq]
            ds = s - prev_s
            for j in range(6):
                rate = abs(vel[j])
                if rate > peak[j]:
                    peak[j] = rate
                if ds > 0.0:
                    g = abs(dq[j]) / ds
                    if g > gain[j]:
                        gain[j] = g
                if check_velocity and vel_limits is not None and rate > vel_limits[j] * (1.0 + 1e-9):
                    ratio = rate / vel_limits[j]
                    if worst_velocity is None or ratio > worst_velocity[0]:
                        worst_velocity = (ratio, j, rate, 0.5 * (fraction + fractions[-1]))
            if check_acceleration and prev_v is not None:
                h2 = 0.5 * (h + (times[-1] - times[-2]))
                for j in range(6):
                    acc = abs(vel[j] - prev_v[j]) / h2
                    if acc > acc_limits[j] * (1.0 + 1e-9):
                        ratio = acc / acc_limits[j]
                        if worst_acceleration is None or ratio > worst_acceleration[0]:
                            worst_acceleration = (ratio, j, acc, fractions[-1])
            prev_v = vel
        times.append(t)
        fractions.append(fraction)
        joints.append(qi)
        q = qi
        config = c
        prev_s = s
    if worst_velocity is not None:
        _, j, need, fraction = worst_velocity
        fit = min((vel_limits[k] / gain[k] for k in range(6) if gain[k] > 0.0), default=inf)
        hint = f" (to at most {_nice_speed(fit)} mm/s)" if fit < move.speed else ""
        raise PathError(f"{names[j]} would need {need:.0f} deg/s (limit {vel_limits[j]:g}) at "
                        f"{_percent(fraction)} of the path: lower the speed{hint}",
                        fraction, "velocity", names[j])
    if worst_acceleration is not None:
        _, j, need, fraction = worst_acceleration
        raise PathError(f"{names[j]} would need {need:.0f} deg/s^2 (limit {acc_limits[j]:g}) at "
                        f"{_percent(fraction)} of the path: lower the acceleration (acc) or the speed",
                        fraction, "acceleration", names[j])
    return CheckedPath(move, kinematics, _start_joints(start_joints), tuple(times),
                       tuple(fractions), tuple(joints), tuple(peak), tuple(min_margins))


def _kinematics_failure(text: str, fraction: float) -> PathError:
    at = _percent(fraction)
    if text.startswith("unreachable: "):
        return PathError(f"the path leaves the arm's reach at {at} of its length "
                         f"({text[len('unreachable: '):]})", fraction, "unreachable")
    if text.startswith("singular: "):
        detail = text[len("singular: "):]
        where = ("the path starts at a singularity" if fraction == 0.0 else
                 f"the path passes through a singularity at {at} of its length")
        return PathError(f"{where} ({detail})", fraction, "singular")
    if text.startswith("no solution within the axis limits"):
        detail = text[len("no solution within the axis limits"):].strip(" ()")
        axis = detail.split(" ", 1)[0] if detail else None
        return PathError(f"the path leaves the axis limits at {at} of its length ({detail})",
                         fraction, "limit", axis)
    return PathError(f"the arm cannot follow the path at {at} of its length ({text})",
                     fraction, "unreachable")


def _configuration_failure(before: int, after: int, fraction: float, names, q0, q1) -> PathError:
    """The configuration changed between two close samples without a jump: the path
    passes through a singularity. (Over axis 1 the elbow bit, defined in world terms,
    changes with the shoulder bit.)"""
    changed = before ^ after
    at = _percent(fraction)
    axis = None
    parts = []
    if changed & SHOULDER_BACK:
        parts.append(f"the shoulder singularity (the wrist centre passes over axis {names[0]}: "
                     f"the arm would swing over)")
    elif changed & ELBOW_DOWN:
        parts.append("the elbow singularity (the arm stretched or folded: the elbow would flip)")
    if changed & WRIST_FLIP:
        axis = names[4]
        parts.append(f"the wrist singularity ({names[4]} passes 0 deg, from {q0[4]:.2f} to "
                     f"{q1[4]:.2f} deg: axes {names[3]} and {names[5]} in line; the wrist "
                     f"would flip)")
    return PathError(f"the path passes through {' and '.join(parts)} at {at} of its length",
                     fraction, "configuration", axis)


#: a singularity margin below this (|sin| of the elbow or wrist angle; the shoulder's mm
#: over 100 mm) names the singularity a jump is blamed on
_NEAR_SINGULAR = 0.1


def _jump_failure(kinematics, pose, q0, q1, config0: int, config1: int, axis: int, ds: float,
                  path, fraction: float, max_step: float, m0, m1) -> PathError:
    """A joint moved more than ``max_step`` between two samples. Why, in this order: the
    configuration the arm is in cannot go on (a limit, the reach: the inverse
    kinematics fell back to another one); the axis runs into a limit and its solution
    wrapped by 360 deg; the path passes next to a singularity; else the solution jumps."""
    names = kinematics.names
    at = _percent(fraction)
    dq = q1[axis] - q0[axis]
    turn = (f"{names[axis]} would turn {abs(dq):.1f} deg between two points of the path "
            f"(the arm would change from {configuration_name(config0)} to "
            f"{configuration_name(config1)})" if config1 != config0 else
            f"{names[axis]} would turn {abs(dq):.1f} deg between two points of the path")
    same = q1  # the solution in the arm's configuration
    if config1 != config0:
        try:
            same = kinematics.inverse(pose, near=q0, configuration=config0)
        except KinematicsError as exc:
            err = _kinematics_failure(str(exc), fraction)
            return PathError(f"{err.message}: {turn}", fraction, err.reason, err.axis or names[axis])
    # in its configuration the arm would jump too: an axis at its limit wrapped by 360 deg
    j = max(range(6), key=lambda k: abs(same[k] - q0[k]))
    d = same[j] - q0[j]
    lo, hi = kinematics.limits[j]
    if abs(d) > max_step and ((d > 0.0 and q0[j] - lo < max_step) or
                              (d < 0.0 and hi - q0[j] < max_step)):
        limit = lo if d > 0.0 else hi
        return PathError(f"the path leaves the axis limits at {at} of its length ({names[j]} "
                         f"would pass its limit {limit:g} deg, limit {lo:g}..{hi:g}): {turn}",
                         fraction, "limit", names[j])
    shoulder = min(m0[0], m1[0])
    elbow = min(m0[1], m1[1])
    wrist = min(m0[2], m1[2])
    # comparable scales: |sin| for elbow and wrist; the shoulder's mm over 100 mm
    margin, kind = min((wrist, "wrist"), (elbow, "elbow"), (shoulder / 100.0, "shoulder"))
    moved = ds * path.position_length / path.length if path.length > 0.0 else 0.0
    turned = ds * path.rotation_angle / path.length if path.length > 0.0 else 0.0
    motion = f"{turn} while the tool moves {moved:.2f} mm and turns {turned:.2f} deg"
    if margin >= _NEAR_SINGULAR:
        return PathError(f"the arm's joint solution jumps at {at} of the path: {motion}",
                         fraction, "jump", names[axis])
    if kind == "wrist":
        what = f"the wrist singularity ({names[4]} within {abs(_asin_deg(wrist)):.2f} deg of 0)"
    elif kind == "elbow":
        what = "the elbow singularity (the arm nearly stretched or folded)"
    else:
        what = f"the shoulder singularity (the wrist centre {shoulder:.1f} mm from axis {names[0]})"
    return PathError(f"the path passes next to {what} at {at} of its length: {motion}",
                     fraction, "jump", names[axis])


def _asin_deg(x: float) -> float:
    return atan2(x, sqrt(max(1.0 - x * x, 0.0))) * _R2D


# ============================================================================ per tick


class JointStream:
    """The joint trajectory of a :class:`CheckedPath` for the trajectory generator: the
    interface of :class:`runtime.motion.jerk.JerkPtpTrajectory` -- ``duration`` and
    ``sample(t) -> (positions, velocities)`` over the six main axes followed by the
    held ``additional`` axes.

    The positions are one inverse kinematics of the commanded pose, ``near`` the joint
    values of the previous call (extrapolated linearly); the velocities are central
    differences ``(q(t + period) - q(t - period)) / (2 period)`` of the joint path
    (second-order accurate; the profile holds still outside the move, so they are 0 at
    both ends). Called at ``t, t + period, t + 2 period, ...`` (the generator's ticks),
    each call solves one inverse kinematics, one period ahead; any other ``t`` costs
    three (from the check's nearest sample). Before 0 the start joints, from
    ``duration`` on the end joints, both with zero velocity.

    Never raises for a number ``t``: should an inverse kinematics fail after all
    (impossible after the check but for rounding), ``fault`` gets the message and the
    stream holds its last positions with zero velocity.
    """

    __slots__ = ("checked", "period", "duration", "fault", "_additional", "_zeros",
                 "_start", "_end", "_tp", "_qp", "_tc", "_qc", "_tn", "_qn")

    def __init__(self, checked: CheckedPath, period: float = SETPOINT_PERIOD, additional: Sequence[float] = ()):
        self.checked = checked
        self.period = _positive("period", period)
        self.duration = checked.duration
        self.fault: str | None = None
        self._additional = add = tuple(float(v) for v in additional)
        self._zeros = (0.0,) * (6 + len(add))
        self._start = tuple(checked.start_joints) + add
        self._end = tuple(checked.end_joints) + add
        self._tc = self._tn = None
        self._qp = self._qc = self._qn = None

    def joints_at(self, t: float, near: Sequence[float] | None = None) -> tuple[float, ...]:
        """The six main axes at ``t`` (:meth:`CheckedPath.joints_at`); may raise
        ``KinematicsError``."""
        return self.checked.joints_at(t, near)

    def position_at(self, t: float) -> tuple[float, ...]:
        """All axes at ``t`` (one inverse kinematics from the check's nearest sample),
        touching none of the state :meth:`sample` keeps: safe from another thread (the
        blend check). May raise ``KinematicsError``."""
        if t >= self.duration:
            return self._end
        if not t > 0.0:
            return self._start
        return self.checked.joints_at(t) + self._additional

    @property
    def end(self) -> tuple[float, ...]:
        """All axes at the end of the move."""
        return self._end

    def sample(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        duration = self.duration
        if t >= duration:
            return self._end, self._zeros
        if not t > 0.0:
            return self._start, self._zeros
        if self.fault is not None:
            return (self._qc or self.checked.start_joints) + self._additional, self._zeros
        h = self.period
        joints_at = self.checked.joints_at
        try:
            tn = self._tn
            if tn is not None and abs(t - tn) <= 1e-9 * h:
                qp, qc = self._qc, self._qn
                near = tuple([2.0 * b - a for a, b in zip(qp, qc)])
                qn = joints_at(t + h, near)
            else:
                qc = joints_at(t)  # near: the check's nearest sample
                qp = joints_at(t - h, qc)
                qn = joints_at(t + h, qc)
        except KinematicsError as exc:
            self.fault = (f"the arm cannot follow the path at {_percent(self.checked.move.fraction(t))} "
                          f"of its length: {exc}")
            return (self._qc or self.checked.start_joints) + self._additional, self._zeros
        self._qp, self._qc, self._qn = qp, qc, qn
        self._tc, self._tn = t, t + h
        k = 0.5 / h
        velocities = tuple([(b - a) * k for a, b in zip(qp, qn)])
        add = self._additional
        if add:
            return qc + add, velocities + (0.0,) * len(add)
        return qc, velocities

    def __repr__(self) -> str:
        return f"JointStream(duration={self.duration!r}, period={self.period!r})"


# ============================================================================ one call


#: The share of each joint's velocity, acceleration and jerk limit that a Cartesian move is
#: timed to at the check's samples (the rest: what lies between the samples, and the
#: interpolation to the servo's 1 ms references).
JOINT_LIMIT_SHARE = 0.9


def joint_limit_scale(checked: CheckedPath, limits: Sequence[Sequence[float]],
                      share: float = JOINT_LIMIT_SHARE) -> float:
    """The largest k <= 1 such that the move of ``checked`` run k times slower in time
    (path speed x k, acceleration x k^2, jerk x k^3: the time-optimal profile scales so)
    keeps every joint's velocity, acceleration and jerk within ``share`` of ``limits``
    (three sequences of six: max velocity, max acceleration, max jerk), measured by finite
    differences over the check's samples (uniform in time)."""
    times, joints = checked.times, checked.joints
    if len(times) < 2 or not checked.duration > 0.0:
        return 1.0
    dt = times[1] - times[0]
    q = np.asarray(joints, dtype=float)
    k = 1.0
    derivative = q
    for order, limit in enumerate(limits, start=1):
        if len(derivative) < 2:
            break
        derivative = np.diff(derivative, axis=0) / dt
        ratio = float(np.max(np.abs(derivative) / np.asarray(limit, dtype=float)))
        if ratio > share:
            k = min(k, (share / ratio) ** (1.0 / order))
    return k


def _plan(kinematics, start_joints, make_path, speed, acc, jerk, axis_limits, period, **check):
    try:
        joints = tuple(start_joints.axes if isinstance(start_joints, Joint) else start_joints)
        if len(joints) < 6:
            return None, f"expected at least six joint values (the main axes), got {len(joints)}"
        main, additional = joints[:6], joints[6:]
        path = make_path(kinematics.forward(main))
        move = CartesianMove(path, speed, acc, jerk)
        _, *limits = _axis_limits(axis_limits)  # (velocities, accelerations, jerks)
        if None in limits:  # not a specification's axes: nothing to time the move within
            checked = check_path(move, kinematics, main, axis_limits, **check)
        else:
            # timed within every joint's limits: slower (uniformly) where the programmed
            # speed, acc and jerk would ask more of a joint than it can give; measured at
            # least as finely as the setpoints will be made
            fine = dict(check, min_samples=max(check.get("min_samples", MIN_SAMPLES), ceil(move.duration / period)))
            checked = check_path(move, kinematics, main, axis_limits, check_velocity=False, **fine)
            k = joint_limit_scale(checked, limits)
            if k < 1.0:
                move = CartesianMove(path, move.speed * k, move.acc * k * k, move.jerk * k * k * k)
                checked = check_path(move, kinematics, main, axis_limits, **check)
        return checked.stream(period, additional), ""
    except (ValueError, TypeError) as exc:  # PathError and KinematicsError are ValueErrors
        return None, str(exc)
    except Exception as exc:  # noqa: BLE001 - the contract is: never raise
        return None, f"internal error in the Cartesian planner: {type(exc).__name__}: {exc}"


def plan_lin(kinematics: Kinematics, start_joints, target, speed: float, acc: float,
             jerk: float | None = None, axis_limits=None, period: float = SETPOINT_PERIOD,
             **check) -> tuple[JointStream | None, str]:
    """Plan ``move lin target`` from the joint values ``start_joints`` (the six main axes,
    then any additional axes, which are held): the straight line from the forward
    kinematics of the main axes to ``target`` (a pose tuple, a ``Pose`` or a matrix),
    timed with ``speed``, ``acc``, ``jerk`` and checked (:func:`check_path` with
    ``axis_limits`` and the keyword arguments in ``check``).

    Returns ``(stream, "")`` or ``(None, message)``. Never raises."""
    return _plan(kinematics, start_joints, lambda start: LinPath(start, target), speed, acc,
                 jerk, axis_limits, period, **check)


def plan_circ(kinematics: Kinematics, start_joints, via, target, speed: float, acc: float,
              jerk: float | None = None, axis_limits=None, period: float = SETPOINT_PERIOD,
              **check) -> tuple[JointStream | None, str]:
    """Plan ``move circ via, target`` (the language's order: the via point first) like
    :func:`plan_lin`: the arc from the current pose through ``via``'s position to
    ``target``. Returns ``(stream, "")`` or ``(None, message)``. Never raises."""
    return _plan(kinematics, start_joints, lambda start: CircPath(start, via, target), speed,
                 acc, jerk, axis_limits, period, **check)


class PathStop:
    """A controlled stop **on** a Cartesian path (pause, abort): from the path parameter,
    speed and acceleration of ``stream`` at its time ``t``, the path speed falls to rest
    jerk-limited (:class:`runtime.motion.jerk.JerkStop` within the move's ``acc`` and
    jerk); every sample is one inverse kinematics of the path's pose
    at ``s(t)`` near the last joints, so the tool stays on the line or arc. Velocities are
    the backward differences of the samples (0 at rest). Same interface as
    :class:`JointStream`; ``s_end`` is where it stops (resume plans the rest from there).
    Never raises: should an inverse kinematics fail, ``fault`` says why and the joints hold.
    """

    __slots__ = ("path", "kinematics", "duration", "s_end", "fault", "_s0", "_stop", "_last", "_last_t",
                 "_add", "_zeros", "_end")

    def __init__(self, stream: "JointStream", t: float, joints: Sequence[float], deceleration: float | None = None,
                 rate: float = 1.0):
        """``rate``: the stream was sampled at ``rate`` seconds of its time per real second
        (a speed override): the real path speed is the profile's times ``rate``; the stop
        itself is in real time, decelerating at the move's ``acc`` times ``rate^2``."""
        move = stream.checked.move
        s0, v0, a0 = move.profile.sample(t)
        dec = move.acc if deceleration is None else deceleration
        self.path, self.kinematics = move.path, stream.checked.kinematics
        self._stop = JerkStop(v0 * rate, a0 * rate * rate, dec, move.jerk)
        self._s0 = s0
        self.duration = self._stop.duration
        self.s_end = min(s0 + self._stop.distance, move.path.length)
        self.fault: str | None = None
        self._add = tuple(joints[6:])
        self._last = tuple(joints[:6])
        self._last_t = 0.0
        self._zeros = (0.0,) * len(joints)
        self._end = None

    def sample(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        if t >= self.duration:
            if self._end is None:
                self._end = self._solve(self.s_end)
            return self._end + self._add, self._zeros
        if not t > 0.0:
            return self._last + self._add, self._zeros
        q = self._solve(min(self._s0 + self._stop.sample(t)[0], self.s_end))
        h = t - self._last_t
        velocities = tuple([(b - a) / h for a, b in zip(self._last, q)]) if h > 0.0 else self._zeros[:6]
        self._last, self._last_t = q, t
        return q + self._add, velocities + self._zeros[6:]

    def _solve(self, s: float) -> tuple[float, ...]:
        try:
            return tuple(self.kinematics.inverse(self.path.pose_at(s), near=self._last))
        except KinematicsError as exc:
            self.fault = self.fault or f"the stop left the arm's reach ({exc})"
            return self._last

    def rest(self) -> tuple[str, tuple]:
        """What is left of the path after the stop: ``("lin", (end,))`` or
        ``("circ", (via, end))`` -- the arguments of :func:`plan_lin` / :func:`plan_circ`
        from the stop on (the via point halfway along the rest of the arc)."""
        path = self.path
        end = path.pose_at(path.length)
        if isinstance(path, CircPath):
            return "circ", (path.pose_at(0.5 * (self.s_end + path.length)), end)
        return "lin", (end,)
