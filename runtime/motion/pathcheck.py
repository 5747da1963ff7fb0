"""The check of a whole Cartesian path against the arm before it moves.

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


Runs once per move, when it is planned, not in a tick: about 40 us per sample in CPython
3.11 (13 ms for a 200 mm move at 1 mm steps). :meth:`CheckedPath.joints_at` (one inverse
kinematics, about 22 us) is real-time safe.
"""
from __future__ import annotations

from bisect import bisect_left
from dataclasses import dataclass
from math import atan2, ceil, floor, inf, log10, sqrt
from typing import Sequence

from compiler.spec import Axis, Spec
from compiler.values import Joint

from runtime.motion.kinematics import (
    ELBOW_DOWN,
    SHOULDER_BACK,
    WRIST_FLIP,
    Kinematics,
    KinematicsError,
    configuration_name,
)
from runtime.motion.paths import CartesianMove, positive
from runtime.motion.rotation import R2D, matrix_to_quat, quat_angle, rpy_to_quat

__all__ = ["CheckedPath", "JointLimits", "joint_limits", "MAX_JOINT_STEP", "MIN_SAMPLES", "PathError", "START_TOL",
           "check_path", "percent", "where"]

#: deg: a joint moving more than this between two check samples is a jump
MAX_JOINT_STEP = 10.0
#: the fewest intervals a path is checked in (:func:`check_path`)
MIN_SAMPLES = 50
#: the check's start pose may differ from the forward kinematics of the start joints by
#: this much (mm, deg)
START_TOL = 1e-3



class PathError(ValueError):
    """A Cartesian path the arm cannot follow.

    * ``fraction`` -- where along the path (0..1 of ``length``) it fails;
    * ``reason`` -- ``"start"``, ``"unreachable"``, ``"singular"``, ``"limit"``,
      ``"configuration"``, ``"jump"``, ``"velocity"`` or ``"acceleration"``;
    * ``axis`` -- the axis name concerned, or ``None``;
    * ``str(error)`` -- the message.
    """

    def __init__(self, message: str, fraction: float, reason: str, axis: str | None = None,
                 distance: float | None = None):
        super().__init__(message)
        self.message = message
        self.fraction = fraction
        self.reason = reason
        self.axis = axis
        self.distance = distance  # mm of the tool's path from its start (None: not known)


# ============================================================================ the check


def percent(fraction: float) -> str:
    """Where along a path (``fraction`` 0..1) as a message says it: ``"37 %"``, and a
    tenth of a percent next to either end (``"0.4 %"``, ``"99.6 %"``)."""
    p = 100.0 * fraction
    if 0.0 < p < 1.0 or 99.0 < p < 100.0:
        return f"{p:.1f} %"
    return f"{p:.0f} %"


def where(fraction: float, length: float = 0.0, of: str = "its length") -> str:
    """Where along a path (``fraction`` 0..1 of it) as a message says it: ``"37 % of its
    length"``, and with the tool's path ``length`` (mm, 1 or more) how far from its start:
    ``"37 % of its length, 185.2 mm from its start"``."""
    text = f"{percent(fraction)} of {of}"
    if length >= 1.0:  # (a turn in place has no mm to speak of)
        text += f", {fraction * length:.1f} mm from its start"
    return text


def _start_joints(joints) -> tuple[float, ...]:
    if isinstance(joints, Joint):
        joints = joints.main
    joints = tuple(float(v) for v in joints)
    if len(joints) != 6:
        raise ValueError(f"start_joints: expected six joint values, got {len(joints)}")
    return joints


@dataclass(frozen=True)
class JointLimits:
    """The six main axes' limits a path is checked (and a move timed) against: position
    ranges ``(min, max)``, max velocities, accelerations and jerks; any may be None (not
    checked). :meth:`of` takes them from the specification's axes."""

    positions: tuple[tuple[float, float], ...] | None = None
    velocity: tuple[float, ...] | None = None
    acceleration: tuple[float, ...] | None = None
    jerk: tuple[float, ...] | None = None

    @classmethod
    def of(cls, axes: Sequence[Axis]) -> "JointLimits":
        return cls(tuple((float(a.min), float(a.max)) for a in axes), tuple(float(a.max_velocity) for a in axes),
                   tuple(float(a.max_acceleration) for a in axes), tuple(float(a.max_jerk) for a in axes))


def joint_limits(axis_limits) -> JointLimits:
    """``axis_limits`` as :class:`JointLimits`: None (none), a :class:`JointLimits`, a
    specification (its main axes), six of its axes, or six max velocities."""
    if axis_limits is None:
        return JointLimits()
    if isinstance(axis_limits, JointLimits):
        limits = axis_limits
    else:
        items = tuple(axis_limits.main_axes if isinstance(axis_limits, Spec) else axis_limits)
        if len(items) != 6:
            raise ValueError(f"axis_limits: expected six axes, got {len(items)}")
        if all(isinstance(a, Axis) for a in items):
            limits = JointLimits.of(items)
        else:
            limits = JointLimits(velocity=tuple(float(v) for v in items))
    if limits.velocity is not None and not all(v > 0.0 for v in limits.velocity):
        raise ValueError(f"axis_limits: every max_velocity must be positive, got {limits.velocity}")
    return limits


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


def check_path(move: CartesianMove, kinematics: Kinematics, start_joints: Sequence[float],
               axis_limits=None, step: float = 1.0, step_deg: float = 1.0,
               min_samples: int = MIN_SAMPLES, max_joint_step: float = MAX_JOINT_STEP,
               check_acceleration: bool = False, start_tolerance: float = START_TOL,
               check_velocity: bool = True) -> CheckedPath:
    """Check that the arm can follow ``move`` from ``start_joints`` (module docstring);
    return the :class:`CheckedPath` or raise :class:`PathError`.

    ``axis_limits``: the six main axes' limits (:func:`joint_limits`: a
    :class:`JointLimits`, the specification's axes, the ``Spec`` itself, or six max
    velocities in deg/s); ``None``: no velocity check (the position limits are the
    kinematics' own). ``step``
    (mm) and ``step_deg`` (deg): the largest TCP and orientation motion between two
    samples; ``min_samples``: the fewest intervals; ``max_joint_step`` (deg): the largest
    joint motion between two samples; ``start_tolerance`` (mm and deg): how far the
    path's start may be from the forward kinematics of ``start_joints``;
    ``check_velocity=False``: the joint velocities are not checked (what
    :func:`joint_limit_scale` measures).
    ``ValueError`` (not ``PathError``) for arguments that make no sense.
    """
    q = _start_joints(start_joints)
    limits = joint_limits(axis_limits)
    pos_limits, vel_limits, acc_limits = limits.positions, limits.velocity, limits.acceleration
    step = positive("step", step)
    step_deg = positive("step_deg", step_deg)
    max_joint_step = positive("max_joint_step", max_joint_step)
    if check_acceleration and acc_limits is None:
        raise ValueError("check_acceleration needs axis_limits with max_acceleration (the spec's axes)")
    path, profile = move.path, move.profile
    names = kinematics.names
    length = path.length
    mm = path.position_length  # the tool's path (mm): where a failure is, from its start

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

    inverse, configuration_and_margins, margins = (kinematics.inverse, kinematics.configuration_and_margins,
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
            raise _kinematics_failure(str(exc), fraction, mm) from None
        if pos_limits is not None:
            for j, ((lo, hi), v) in enumerate(zip(pos_limits, qi)):
                if not lo - 1e-9 <= v <= hi + 1e-9:
                    raise PathError(f"the path leaves the axis limits at {where(fraction, mm)} "
                                    f"({names[j]} would be {v:.2f} deg, limit {lo:g}..{hi:g})",
                                    fraction, "limit", names[j], fraction * mm)
        c, m = configuration_and_margins(qi)
        for k in range(3):
            if m[k] < min_margins[k]:
                min_margins[k] = m[k]
        if i == 0:
            config = c
        else:
            dq = [b - a for a, b in zip(q, qi)]
            if max(map(abs, dq)) > max_joint_step:
                big = max(range(6), key=lambda j: abs(dq[j]))
                raise _jump_failure(kinematics, pose, q, qi, config, c, big, s - prev_s, path,
                                    fraction, max_joint_step, margins(q), m)
            if c != config:
                raise _configuration_failure(config, c, fraction, names, q, qi, mm)
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
                        f"{where(fraction, mm, 'the path')}: lower the speed{hint}",
                        fraction, "velocity", names[j], fraction * mm)
    if worst_acceleration is not None:
        _, j, need, fraction = worst_acceleration
        raise PathError(f"{names[j]} would need {need:.0f} deg/s^2 (limit {acc_limits[j]:g}) at "
                        f"{where(fraction, mm, 'the path')}: lower the acceleration (acc) or the speed",
                        fraction, "acceleration", names[j], fraction * mm)
    return CheckedPath(move, kinematics, _start_joints(start_joints), tuple(times),
                       tuple(fractions), tuple(joints), tuple(peak), tuple(min_margins))


def _kinematics_failure(text: str, fraction: float, mm: float) -> PathError:
    at, distance = where(fraction, mm), fraction * mm
    if text.startswith("unreachable: "):
        return PathError(f"the path leaves the arm's reach at {at} "
                         f"({text[len('unreachable: '):]})", fraction, "unreachable", None, distance)
    if text.startswith("singular: "):
        detail = text[len("singular: "):]
        place = ("the path starts at a singularity" if fraction == 0.0 else
                 f"the path passes through a singularity at {at}")
        return PathError(f"{place} ({detail})", fraction, "singular", None, distance)
    if text.startswith("no solution within the axis limits"):
        detail = text[len("no solution within the axis limits"):].strip(" ()")
        axis = detail.split(" ", 1)[0] if detail else None
        return PathError(f"the path leaves the axis limits at {at} ({detail})",
                         fraction, "limit", axis, distance)
    return PathError(f"the arm cannot follow the path at {at} ({text})",
                     fraction, "unreachable", None, distance)


def _configuration_failure(before: int, after: int, fraction: float, names, q0, q1, mm: float) -> PathError:
    """The configuration changed between two close samples without a jump: the path
    passes through a singularity. (Over axis 1 the elbow bit, defined in world terms,
    changes with the shoulder bit.)"""
    changed = before ^ after
    at = where(fraction, mm)
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
    return PathError(f"the path passes through {' and '.join(parts)} at {at}",
                     fraction, "configuration", axis, fraction * mm)


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
    mm = path.position_length
    at, distance = where(fraction, mm), fraction * mm
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
            err = _kinematics_failure(str(exc), fraction, mm)
            return PathError(f"{err.message}: {turn}", fraction, err.reason, err.axis or names[axis], distance)
    # in its configuration the arm would jump too: an axis at its limit wrapped by 360 deg
    j = max(range(6), key=lambda k: abs(same[k] - q0[k]))
    d = same[j] - q0[j]
    lo, hi = kinematics.limits[j]
    if abs(d) > max_step and ((d > 0.0 and q0[j] - lo < max_step) or
                              (d < 0.0 and hi - q0[j] < max_step)):
        limit = lo if d > 0.0 else hi
        return PathError(f"the path leaves the axis limits at {at} ({names[j]} "
                         f"would pass its limit {limit:g} deg, limit {lo:g}..{hi:g}): {turn}",
                         fraction, "limit", names[j], distance)
    shoulder = min(m0[0], m1[0])
    elbow = min(m0[1], m1[1])
    wrist = min(m0[2], m1[2])
    # comparable scales: |sin| for elbow and wrist; the shoulder's mm over 100 mm
    margin, kind = min((wrist, "wrist"), (elbow, "elbow"), (shoulder / 100.0, "shoulder"))
    moved = ds * path.position_length / path.length if path.length > 0.0 else 0.0
    turned = ds * path.rotation_angle / path.length if path.length > 0.0 else 0.0
    motion = f"{turn} while the tool moves {moved:.2f} mm and turns {turned:.2f} deg"
    if margin >= _NEAR_SINGULAR:
        return PathError(f"the arm's joint solution jumps at {where(fraction, mm, 'the path')}: {motion}",
                         fraction, "jump", names[axis], distance)
    if kind == "wrist":
        what = f"the wrist singularity ({names[4]} within {abs(_asin_deg(wrist)):.2f} deg of 0)"
    elif kind == "elbow":
        what = "the elbow singularity (the arm nearly stretched or folded)"
    else:
        what = f"the shoulder singularity (the wrist centre {shoulder:.1f} mm from axis {names[0]})"
    return PathError(f"the path passes next to {what} at {at}: {motion}",
                     fraction, "jump", names[axis], distance)


def _asin_deg(x: float) -> float:
    return atan2(x, sqrt(max(1.0 - x * x, 0.0))) * R2D
