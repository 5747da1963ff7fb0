"""Rotations for Cartesian paths: quaternions, roll/pitch/yaw and slerp.

* **Quaternions** are ``(w, x, y, z)`` tuples, unit norm; ``q`` and ``-q`` are the same
  rotation.
* **Roll/pitch/yaw** in deg with the convention of :mod:`runtime.motion.kinematics`:
  ``R = Rz(yaw) Ry(pitch) Rx(roll)``; returned angles have pitch in [-90, 90], roll and
  yaw in [-180, 180].
* **Slerp** (:func:`slerp`, :class:`Slerp` for many samples of one pair): the shortest
  arc between two orientations, at a constant angular rate about one fixed axis.

Plain floats and ``math``; no NumPy (sampled every tick).
"""
from __future__ import annotations

from math import atan2, pi, sin, sqrt

from compiler.geometry import quat_multiply, quat_to_rpy, rpy_to_quat
from compiler.geometry import unit_rotation as _unit

__all__ = ["R2D", "Slerp", "matrix_to_quat", "quat_angle", "quat_multiply", "quat_to_matrix", "quat_to_rpy",
           "rpy_to_quat", "slerp"]

#: degrees per radian
R2D = 180.0 / pi
# below this slerp angle (rad) the slerp weights use their series (error ~ omega^4 / 100)
_SMALL_ANGLE = 1e-4


def quat_to_matrix(q) -> tuple:
    """The 3x3 rotation matrix (nested tuples) of a quaternion ``(w, x, y, z)``
    (normalised here, so any non-zero quaternion will do)."""
    w, x, y, z = _unit(q)
    s = 2.0
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
    return 2.0 * _half_angle(_unit(q0), _unit(q1)) * R2D


def _sin_ratio(k: float, omega: float, inv_sin: float) -> float:
    """``sin(k omega) / sin(omega)``; for ``omega`` below :data:`_SMALL_ANGLE` its series
    ``k (1 + (1 - k^2) omega^2 / 6)`` (exact to ~1e-17 there)."""
    if omega < _SMALL_ANGLE:
        return k * (1.0 + (1.0 - k * k) * omega * omega / 6.0)
    return sin(k * omega) * inv_sin


class Slerp:
    """Slerp from ``q0`` to ``q1`` with the constants worked out once: ``Slerp(q0,
    q1)(u)`` is :func:`slerp` ``(q0, q1, u)``, for the many samples of a path's
    orientation (:mod:`runtime.motion.paths`). ``angle``: the rotation (rad) from ``q0``
    to ``q1``."""

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
    return Slerp(q0, q1)(s)
