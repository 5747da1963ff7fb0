"""Operating mode T1 (manual reduced speed, ISO 10218-1) as the planners keep it.

In T1 the tool centre point and the flange never move faster than ``[safety] t1_speed``
(at most 250 mm/s) and each axis never faster than ``[safety] t1_velocity_factor`` x its
``max_velocity``. The safety supervisor checks every 1 ms reference against both and
stops the robot beyond them (runtime/loop/components/safety.py); the planners plan every
move under them, with a margin (:data:`PLAN_SHARE`) for the interpolation and the servo, so
a healthy robot never meets that stop:

* a ptp move is planned with the reduced axis speeds, then its largest Cartesian speed is
  measured (:func:`cartesian_peak`, the flange's and the tool centre point's along the
  planned trajectory) and the move planned again slower until it keeps the speed; a
  move whose peak still does not fall is timed slower as a whole (velocities x s,
  accelerations x s^2, jerks x s^3: the same path, exactly s times the speed);
* a lin or circ move is planned at a path speed that keeps both points under the reduced
  speed (:func:`path_speed`: the flange moves at most the tool centre point's speed plus the
  orientation's angular rate times the tool's length, and both follow the path speed), within
  the reduced axis speeds;
* moves are not blended (each stops at its target, as a test run checks each one);
* homing's searches and its move to the start position use :func:`axis_speed_bounds`,
  which hold in any configuration (before homing the positions are not known).

Not real-time: :func:`cartesian_peak` samples a whole move (the planning worker's time).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from runtime.motion.kinematics import Kinematics, KinematicsError
from runtime.motion.paths import CircPath, LinPath

__all__ = ["PLAN_SHARE", "Reduced", "axis_speed_bounds", "cartesian_peak", "path_speed", "point_speed"]

#: Moves are planned to this share of the T1 speeds (the rest is the 1 ms interpolation's
#: and the servo's).
PLAN_SHARE = 0.9
#: Seconds between the samples :func:`cartesian_peak` measures a move at, and the most samples
#: of one move (a long slow move is measured more coarsely: its speed changes slowly).
PEAK_STEP, MAX_SAMPLES = 0.004, 400
_D2R = math.pi / 180.0


@dataclass(frozen=True)
class Reduced:
    """T1's limits for the planners: ``speed`` (mm/s, the flange's and the tool centre
    point's, planned: t1_speed x PLAN_SHARE) and ``velocities`` (each axis's, planned).
    Built once per robot (:meth:`of`); hashable (a planned move's cache key holds it)."""

    speed: float
    velocities: tuple

    @classmethod
    def of(cls, spec) -> "Reduced":
        safety = spec.safety
        return cls(safety.t1_speed * PLAN_SHARE,
                   tuple(a.max_velocity * safety.t1_velocity_factor * PLAN_SHARE for a in spec.axes))


def point_speed(columns_before: tuple, columns_after: tuple, tool: tuple, dt: float) -> float:
    """The larger speed (mm/s) of the flange and of the tool centre point (``tool``: its
    x, y, z in the flange) between two flange frames (:meth:`Kinematics.flange_columns`)
    ``dt`` s apart. Real-time safe."""
    x0, x1, x2, y0, y1, y2, z0, z1, z2, p0, p1, p2 = columns_before
    a0, a1, a2, b0, b1, b2, c0, c1, c2, q0, q1, q2 = columns_after
    tx, ty, tz = tool
    d0, d1, d2 = q0 - p0, q1 - p1, q2 - p2
    flange = d0 * d0 + d1 * d1 + d2 * d2
    e0 = d0 + (a0 - x0) * tx + (b0 - y0) * ty + (c0 - z0) * tz
    e1 = d1 + (a1 - x1) * tx + (b1 - y1) * ty + (c1 - z1) * tz
    e2 = d2 + (a2 - x2) * tx + (b2 - y2) * ty + (c2 - z2) * tz
    tcp = e0 * e0 + e1 * e1 + e2 * e2
    return math.sqrt(flange if flange > tcp else tcp) / dt


def path_speed(kinematics: Kinematics, start_joints, target, via, tool: tuple, cap: float) -> float:
    """The largest path speed (mm/s) of a lin (``via`` None) or circ move from ``start_joints``
    to ``target`` (poses in the world frame; ``tool``: x, y, z of the tool centre point in
    the flange) that keeps its tool centre point and its flange at most ``cap`` mm/s. Along
    the path (runtime.motion.paths) the tool centre point moves ``position_length / length``
    and the orientation turns ``rotation_angle / length`` per mm of path speed; the flange
    moves at most the tool centre point's speed plus the angular rate times the tool's
    length: ``cap x length / (position_length + angle x |tool|)``."""
    try:
        start = kinematics.forward(tuple(start_joints)[:6])
        path = LinPath(start, target) if via is None else CircPath(start, via, target)
    except (ValueError, KinematicsError):  # (the planner refuses the move, saying why)
        return cap
    arm = math.sqrt(sum(v * v for v in tool[:3]))
    reach = path.position_length + math.radians(path.rotation_angle) * arm
    return cap if reach <= 0.0 else min(cap, cap * path.length / reach)


def cartesian_peak(kinematics: Kinematics, trajectory, tool: tuple, step: float = PEAK_STEP) -> float:
    """The largest speed (mm/s) of the flange and of the tool centre point (``tool``: x, y,
    z in the flange) along ``trajectory`` (its six main axes), measured between samples
    ``step`` s apart. Not real-time."""
    duration = trajectory.duration
    if not duration > 0.0:
        return 0.0
    n = min(max(2, int(math.ceil(duration / step))), MAX_SAMPLES)
    dt = duration / n
    peak = 0.0
    try:
        before = kinematics.flange_columns(trajectory.position_at(0.0)[:6])
        for k in range(1, n + 1):
            after = kinematics.flange_columns(trajectory.position_at(k * dt)[:6])
            v = point_speed(before, after, tool, dt)
            if v > peak:
                peak = v
            before = after
    except KinematicsError:  # (a path checked whole cannot fail here but for rounding)
        return math.inf
    return peak


def axis_speed_bounds(kinematics: Kinematics | None, spec, tool: tuple | None = None) -> tuple[float, ...]:
    """Each axis's speed (deg/s or mm/s) at which, moving alone, it keeps the flange and the
    tool centre point within T1's planned speed in any configuration (its lever arm, 
    :meth:`Kinematics.lever_arms`), and within its reduced speed. A prismatic axis moves
    them at its own speed. Without kinematics: the reduced axis speeds alone (revolute
    axes at a speed no arm longer than 2 m turns faster than the T1 speed)."""
    reduced = Reduced.of(spec)
    arms = kinematics.lever_arms(tool) if kinematics is not None else (2000.0,) * len(spec.main_axes)
    bounds = []
    for i, (axis, v) in enumerate(zip(spec.axes, reduced.velocities)):
        if axis.kind == "prismatic":
            bounds.append(min(v, reduced.speed))
        else:
            arm = arms[i] if i < len(arms) else 0.0
            bounds.append(min(v, reduced.speed / (arm * _D2R)) if arm > 0.0 else v)
    return tuple(bounds)
