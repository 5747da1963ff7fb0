"""Rotations and poses in plain floats: shared by the compiler (constant folding of pose
arithmetic), the VM and the runtime's Cartesian paths, so every one computes the same bits.

* **Quaternions** are ``(w, x, y, z)`` tuples, unit norm; ``q`` and ``-q`` are the same
  rotation.
* **Roll/pitch/yaw** in degrees: ``R = Rz(yaw) Ry(pitch) Rx(roll)``; returned angles
  have pitch in [-90, 90], roll and yaw in [-180, 180].

Imports only ``math``: the compiler and the loop both use it.
"""
from __future__ import annotations

from math import atan2, cos, frexp, isfinite, ldexp, pi, sin, sqrt

_D2R = pi / 180.0
_R2D = 180.0 / pi


def rpy_to_quat(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """The unit quaternion ``(w, x, y, z)`` of ``Rz(yaw) Ry(pitch) Rx(roll)`` (degrees)."""
    hr, hp, hy = 0.5 * roll * _D2R, 0.5 * pitch * _D2R, 0.5 * yaw * _D2R
    cr, sr, cp, sp, cy, sy = cos(hr), sin(hr), cos(hp), sin(hp), cos(hy), sin(hy)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def rpy_to_matrix(roll: float, pitch: float, yaw: float) -> tuple:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` (degrees) as a 3x3 nested tuple."""
    r, p, y = roll * _D2R, pitch * _D2R, yaw * _D2R
    cr, sr, cp, sp, cy, sy = cos(r), sin(r), cos(p), sin(p), cos(y), sin(y)
    return ((cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
            (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
            (-sp, cp * sr, cp * cr))


def rotation_to_rpy(r00, r01, r02, r10, r11, r12, r20, r21, r22) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in degrees of a rotation matrix. Yaw first, then roll and pitch
    from ``Rz(-yaw) R``: exact to rounding even next to gimbal lock."""
    if abs(r00) + abs(r10) < 1e-12:  # gimbal lock: pitch = +-90, yaw taken as 0
        cy, sy, yaw = 1.0, 0.0, 0.0
    else:
        yaw = atan2(r10, r00)
        cy, sy = cos(yaw), sin(yaw)
    roll = atan2(sy * r02 - cy * r12, cy * r11 - sy * r01)
    pitch = atan2(-r20, cy * r00 + sy * r10)
    return roll * _R2D, pitch * _R2D, yaw * _R2D


def rpy_of_quat(w: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in degrees of a unit quaternion: the matrix entries that
    :func:`rotation_to_rpy` uses, and its method (yaw first, then
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


def normalise(q) -> tuple[float, float, float, float] | None:
    """``q / |q|`` for a quaternion ``(w, x, y, z)`` of any size, or None when it is not a
    rotation (zero, or a component not finite). Scaled by its largest component first, so
    the sum of squares can neither overflow (``quat(1e308, 1e308, 1e308, 1e308)``) nor
    underflow (subnormal components): every place that normalises a quaternion calls this."""
    w, x, y, z = q
    if not (isfinite(w) and isfinite(x) and isfinite(y) and isfinite(z)):
        return None
    m = max(abs(w), abs(x), abs(y), abs(z))
    if m == 0.0:
        return None
    # by a power of two (exact: a quaternion of ordinary size gives the same bits as
    # without the scaling); the largest component is then 0.5..1, the norm 0.5..2
    e = -frexp(m)[1]
    w, x, y, z = ldexp(w, e), ldexp(x, e), ldexp(y, e), ldexp(z, e)
    n = sqrt(w * w + x * x + y * y + z * z)
    return (w / n, x / n, y / n, z / n)


def unit_rotation(q) -> tuple[float, float, float, float]:
    """:func:`normalise`, raising ValueError for a quaternion that is not a rotation."""
    unit_q = normalise(q)
    if unit_q is None:
        raise ValueError(f"the quaternion {tuple(q)} is not a rotation")
    return unit_q


def quat_to_rpy(q) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in degrees of a quaternion ``(w, x, y, z)`` (normalised here),
    in the ranges of ``Kinematics.forward``."""
    return rpy_of_quat(*unit_rotation(q))


def quat_multiply(a, b) -> tuple[float, float, float, float]:
    """The Hamilton product ``a b`` (the rotation ``b`` first, then ``a``)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw)


def quat_conjugate(q) -> tuple[float, float, float, float]:
    """The inverse rotation of a unit quaternion."""
    w, x, y, z = q
    return (w, -x, -y, -z)


def rotate(q, v) -> tuple[float, float, float]:
    """The vector ``v`` turned by the unit quaternion ``q``."""
    w, qx, qy, qz = q
    vx, vy, vz = v
    tx, ty, tz = 2.0 * (qy * vz - qz * vy), 2.0 * (qz * vx - qx * vz), 2.0 * (qx * vy - qy * vx)
    return (vx + w * tx + (qy * tz - qz * ty), vy + w * ty + (qz * tx - qx * tz), vz + w * tz + (qx * ty - qy * tx))


def unit(q) -> tuple[float, float, float, float]:
    """``q`` normalised, with ``w >= 0`` (one of the two quaternions of a rotation)."""
    w, x, y, z = unit_rotation(q)
    return (-w, -x, -y, -z) if w < 0.0 else (w, x, y, z)
