"""Cartesian paths (runtime.motion.cartesian): move lin / move circ.

* Orientation helpers: quaternion <-> matrix <-> RPY against the kinematics module's
  matrices; slerp (Hypothesis, derandomized): unit norm, the end points, a constant
  angular rate about one axis, the shortest arc, safe at 0 and 180 degrees.
* LinPath / CartesianMove: every 1 ms sample of the commanded path lies on the straight
  line (1e-9 mm relative), the move starts and ends exactly at the given poses, the
  path speed, acceleration and jerk (finite differences) stay within the limits; the
  orientation follows the slerp in proportion to the path length; a pure reorientation
  has a profile; the length rule max(position, angle * 100 mm).
* CircPath: every sample on the circle (1e-9 relative) and in its plane, through the
  via point, from the start through the via to the end (the right arc), exact end
  points; errors for collinear and coincident points.
* check_path on the Lola 15: a reachable 200 mm lin move passes and the forward
  kinematics of its joints reproduce the path; leaving the reach fails where the
  reach ends (found independently by bisection); passing through the wrist singularity
  (A5 through 0) fails naming it, passing next to it too; a too-high speed fails naming
  the axis and the speed it suggests passes; a joint limit, a wrong start, a singular
  start; a circ move passes.
* JointStream / plan_cartesian: per 5 ms tick, positions on the path, velocities
  matching the positions' derivative, zero velocity and the exact target at the end, the
  additional axes held; errors returned, never raised.

NumPy is used here only.
"""
from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from compiler.values import Pose, Position, Quat, Rpy
from runtime.motion.cartesian import CartesianInput, JointStream, plan_cartesian
from runtime.motion.pathcheck import PathError, check_path
from runtime.motion.paths import DEFAULT_JERK_FACTOR, ORIENTATION_RADIUS, CartesianMove, CircPath, LinPath, pose_tuple
from runtime.motion.rotation import (
    matrix_to_quat,
    quat_angle,
    quat_multiply,
    quat_to_matrix,
    quat_to_rpy,
    rpy_to_quat,
    slerp,
)
from runtime.motion.trajectory import Result
from runtime.motion.kinematics import Kinematics, KinematicsError, matrix_to_rpy, rpy_to_matrix

from conftest import ROOT, SPEC, examples
KIN = Kinematics(SPEC)
AXES = SPEC.main_axes
START = (0.0, -30.0, 30.0, 0.0, 45.0, 0.0)  # front, elbow up, A5 at 45 deg: far from singular

SETTINGS = settings(max_examples=examples(200), deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.too_slow])


# ----------------------------------------------------------------------------- helpers


def rot(pose) -> np.ndarray:
    return np.array(rpy_to_matrix(*pose[3:6]))


def rot_angle(r0, r1) -> float:
    """Rotation angle (deg) between two rotation matrices: |R0 - R1|_F = 2 sqrt(2) sin(angle / 2)
    (accurate near 0, where the acos of the trace is not)."""
    d = np.linalg.norm(np.asarray(r0, dtype=float) - np.asarray(r1, dtype=float)) / (2.0 * math.sqrt(2.0))
    return math.degrees(2.0 * math.asin(min(1.0, d)))


def qarr(q) -> np.ndarray:
    return np.array(q, dtype=float)


def same_rotation(q0, q1, tol=1e-12) -> bool:
    a, b = qarr(q0), qarr(q1)
    return min(np.abs(a - b).max(), np.abs(a + b).max()) <= tol


def grid(move, dt=0.001):
    n = int(math.ceil(move.duration / dt))
    return [min(i * dt, move.duration) for i in range(n + 1)]


quats = st.tuples(*[st.floats(-1.0, 1.0)] * 4).filter(
    lambda q: sum(v * v for v in q) > 0.01).map(lambda q: tuple(qarr(q) / np.linalg.norm(q)))
angles = st.floats(-180.0, 180.0)
positions = st.tuples(*[st.floats(-1500.0, 1500.0)] * 3)
poses = st.tuples(positions, st.tuples(angles, st.floats(-89.0, 89.0), angles)).map(
    lambda pr: pr[0] + pr[1])
limits = st.tuples(st.floats(100.0, 2000.0), st.floats(500.0, 10000.0), st.floats(1.0, 50.0))


# ----------------------------------------------------------------------------- orientation


@SETTINGS
@given(angles, st.floats(-90.0, 90.0), angles)
def test_rpy_quaternion_matrix_agree_with_the_kinematics(roll, pitch, yaw):
    q = rpy_to_quat(roll, pitch, yaw)
    assert abs(np.linalg.norm(q) - 1.0) < 1e-15
    m = np.array(rpy_to_matrix(roll, pitch, yaw))
    assert np.abs(np.array(quat_to_matrix(q)) - m).max() < 1e-14
    assert same_rotation(matrix_to_quat(m), q, 1e-14)
    assert np.abs(np.array(rpy_to_matrix(*quat_to_rpy(q))) - m).max() < 1e-13
    assert np.allclose(quat_to_rpy(q), matrix_to_rpy(quat_to_matrix(q)), atol=1e-9) or \
        abs(abs(pitch) - 90.0) < 1e-6  # the same numbers but at gimbal lock


def test_matrix_to_quat_at_180_degrees_and_composition():
    for axis in np.eye(3):
        m = 2.0 * np.outer(axis, axis) - np.eye(3)  # 180 deg about the axis
        q = matrix_to_quat(m)
        assert abs(q[0]) < 1e-15 and np.allclose(np.abs(q[1:]), axis)
        assert np.allclose(quat_to_matrix(q), m, atol=1e-15)
    a, b = rpy_to_quat(10, 20, 30), rpy_to_quat(-40, 5, 100)
    assert np.allclose(quat_to_matrix(quat_multiply(a, b)),
                       np.array(quat_to_matrix(a)) @ np.array(quat_to_matrix(b)), atol=1e-14)
    assert matrix_to_quat(np.eye(4)) == (1.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError):
        quat_to_matrix((0.0, 0.0, 0.0, 0.0))


@SETTINGS
@given(quats, quats, st.floats(0.0, 1.0))
def test_slerp_unit_norm_end_points_and_shortest_arc(q0, q1, s):
    q = slerp(q0, q1, s)
    assert abs(np.linalg.norm(q) - 1.0) < 1e-15
    assert same_rotation(slerp(q0, q1, 0.0), q0, 1e-14)
    assert same_rotation(slerp(q0, q1, 1.0), q1, 1e-14)
    total = quat_angle(q0, q1)
    assert 0.0 <= total <= 180.0
    # the shortest arc: the rotation from q0 grows as s * total (never 360 - ...)
    assert abs(quat_angle(q0, q) - s * total) < 1e-9
    assert abs(quat_angle(q, q1) - (1.0 - s) * total) < 1e-9
    # q1 and -q1 are the same orientation: the same path
    assert same_rotation(slerp(q0, tuple(-v for v in q1), s), q, 1e-12) or abs(total - 180.0) < 1e-6


@SETTINGS
@given(quats, quats, st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_slerp_constant_angular_rate_about_one_axis(q0, q1, s1, s2):
    total = quat_angle(q0, q1)
    assume(total < 179.9)  # at 180 deg either way is the shortest
    a, b = slerp(q0, q1, s1), slerp(q0, q1, s2)
    assert abs(quat_angle(a, b) - abs(s2 - s1) * total) < 1e-9
    # one fixed axis: the relative rotation q0^-1 q(s) has the same axis for every s
    if total > 1e-3:
        inv0 = (q0[0], -q0[1], -q0[2], -q0[3])
        axes = []
        for s in (0.25, 0.5, 1.0):
            d = quat_multiply(inv0, slerp(q0, q1, s))
            v = qarr(d[1:]) * (1.0 if d[0] >= 0.0 else -1.0)
            axes.append(v / np.linalg.norm(v))
        assert np.abs(axes[0] - axes[2]).max() < 1e-8 and np.abs(axes[1] - axes[2]).max() < 1e-8


def test_slerp_numerically_safe_near_0_and_180_degrees():
    q0 = rpy_to_quat(10.0, 20.0, 30.0)
    assert slerp(q0, q0, 0.5) == pytest.approx(q0, abs=3e-16)
    for tiny in (1e-15, 1e-12, 1e-9, 1e-6, 1e-4, 2e-4):  # degrees
        q1 = rpy_to_quat(10.0, 20.0, 30.0 + tiny)
        for s in (0.0, 0.3, 0.5, 1.0):
            q = slerp(q0, q1, s)
            assert all(math.isfinite(v) for v in q)
            assert abs(np.linalg.norm(q) - 1.0) < 1e-15
            expected = rpy_to_quat(10.0, 20.0, 30.0 + s * tiny)
            assert same_rotation(q, expected, 1e-15)
    # exactly 180 deg (q0 . q1 = 0) and just below and above it
    for yaw in (180.0, 179.9999999, 180.0000001, 179.0):
        q1 = rpy_to_quat(0.0, 0.0, yaw)
        half = slerp((1.0, 0.0, 0.0, 0.0), q1, 0.5)
        assert abs(np.linalg.norm(half) - 1.0) < 1e-15
        assert abs(quat_angle((1.0, 0.0, 0.0, 0.0), half) - 0.5 * quat_angle((1, 0, 0, 0), q1)) < 1e-9
        assert abs(half[1]) < 1e-15 and abs(half[2]) < 1e-15  # about z, as it should
    # long way round is never taken: from yaw 170 to yaw -170 is 20 deg
    q = slerp(rpy_to_quat(0, 0, 170.0), rpy_to_quat(0, 0, -170.0), 0.5)
    assert abs(abs(quat_to_rpy(q)[2]) - 180.0) < 1e-9


# ----------------------------------------------------------------------------- lin


def line_deviation(points, a, b) -> float:
    """The largest distance (mm) of the points from the line through a and b."""
    a, b, p = np.asarray(a, dtype=float), np.asarray(b, dtype=float), np.atleast_2d(points)
    d = b - a
    n = np.linalg.norm(d)
    if n == 0.0:
        return float(np.linalg.norm(p - a, axis=1).max())
    return float(np.linalg.norm(np.cross(p - a, d / n), axis=1).max())


def check_profile_limits(s, dt, speed, acc, jerk):
    """The path parameter's finite-difference speed, acceleration, jerk within limits."""
    v = np.diff(s) / dt
    a = np.diff(v) / dt
    j = np.diff(a) / dt
    noise = 4e-16 * max(1.0, float(np.abs(s).max()))  # rounding of the positions
    assert v.min() >= -noise / dt
    assert v.max() <= speed * (1 + 1e-9) + 2 * noise / dt
    assert np.abs(a).max() <= acc * (1 + 1e-9) + 4 * noise / dt ** 2
    assert np.abs(j).max() <= jerk * (1 + 1e-9) + 8 * noise / dt ** 3


def test_lin_every_millisecond_on_the_line_exact_ends_and_limits():
    start = (742.0, 0.0, 1146.9, 180.0, -45.0, 0.0)
    end = (700.0, 180.0, 1060.0, 170.0, -40.0, 20.0)
    path = LinPath(start, end)
    move = CartesianMove(path, 250.0, 1000.0, 5000.0)
    assert path.kind == "lin" and path.length == pytest.approx(math.dist(start[:3], end[:3]), rel=1e-15)
    ts = grid(move)
    poses = [move.sample(t) for t in ts]
    pts = np.array([p[:3] for p in poses])
    dev = line_deviation(pts, start[:3], end[:3])
    assert dev <= 1e-9 * path.length  # the brief's bound is 0.01 mm
    assert move.sample(move.duration) == end and move.sample(move.duration + 1.0) == end
    assert move.sample(0.0) == start and move.sample(-1.0) == start
    # distance along the line: speed, acceleration, jerk
    u = (pts - np.array(start[:3])) @ (np.array(end[:3]) - start[:3]) / path.length
    check_profile_limits(u, 0.001, 250.0, 1000.0, 5000.0)
    assert np.diff(u).max() * 1000 > 0.99 * 250.0  # and it does reach the speed
    # the orientation: the slerp in proportion to the distance travelled
    q0, q1 = rpy_to_quat(*start[3:]), rpy_to_quat(*end[3:])
    for p, uu in zip(poses[::50], u[::50]):
        assert rot_angle(rot(p), quat_to_matrix(slerp(q0, q1, uu / path.length))) < 1e-9


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(poses, poses, limits)
def test_lin_random_moves(start, end, lim):
    speed, acc, jerk_factor = lim
    path = LinPath(start, end)
    move = CartesianMove(path, speed, acc, jerk_factor * acc)
    assume(0.01 < move.duration < 30.0)
    dt = max(0.001, move.duration / 3000)
    ts = [min(i * dt, move.duration) for i in range(int(math.ceil(move.duration / dt)) + 1)]
    pts = np.array([move.sample(t)[:3] for t in ts])
    scale = max(1.0, np.abs(np.array(start[:3] + end[:3])).max())
    assert line_deviation(pts, start[:3], end[:3]) <= 1e-12 * scale + 1e-9 * path.length
    assert move.sample(move.duration) == end
    s = np.array([move.progress(t)[0] for t in ts])
    check_profile_limits(s, dt, speed, acc, jerk_factor * acc)
    # the TCP speed never exceeds the speed (the length may be the orientation's)
    tcp = np.linalg.norm(np.diff(pts, axis=0), axis=1) / dt
    assert tcp.max() <= speed * (1 + 1e-9) + 1e-12 * scale / dt
    assert path.length == pytest.approx(max(path.position_length,
                                            math.radians(path.rotation_angle) * ORIENTATION_RADIUS))


def test_pure_reorientation_has_a_profile_and_length_rule():
    start = (800.0, 100.0, 900.0, 180.0, -45.0, 0.0)
    end = (800.0, 100.0, 900.0, 180.0, -45.0, 90.0)
    path = LinPath(start, end)
    assert path.position_length == 0.0
    assert path.rotation_angle == pytest.approx(90.0, abs=1e-12)
    assert path.length == pytest.approx(math.pi / 2 * ORIENTATION_RADIUS)
    move = CartesianMove(path, 250.0, 1000.0)
    assert move.jerk == DEFAULT_JERK_FACTOR * 1000.0
    assert move.duration > 0.0
    for t in grid(move, 0.01):
        pose, speed = move.sample_with_speed(t)
        assert pose[:3] == start[:3] and speed == 0.0
    assert move.sample(move.duration) == end
    # the angular rate is bounded by speed / radius
    qs = [rpy_to_quat(*move.sample(t)[3:]) for t in grid(move)]
    rates = [quat_angle(a, b) / 0.001 for a, b in zip(qs, qs[1:])]
    assert max(rates) <= math.degrees(250.0 / ORIENTATION_RADIUS) * (1 + 1e-6)
    # a short move with a big turn: the orientation sets the length, the TCP is slower
    path = LinPath(start, (810.0,) + end[1:])
    assert path.length == pytest.approx(math.pi / 2 * ORIENTATION_RADIUS)
    move = CartesianMove(path, 250.0, 1000.0)
    assert max(move.sample_with_speed(t)[1] for t in grid(move)) <= 250.0 * 10.0 / path.length + 1e-9
    # identical poses: nothing to do
    move = CartesianMove(LinPath(start, start), 250.0, 1000.0)
    assert move.duration == 0.0 and move.sample(0.0) == start and move.sample(1.0) == start


def test_sample_with_speed_is_the_tcp_speed():
    move = CartesianMove(LinPath((0, 0, 0, 0, 0, 0), (300, 400, 0, 0, 0, 30)), 500.0, 2000.0)
    for t in np.linspace(0.01, move.duration - 0.01, 37):
        (p, v), p2 = move.sample_with_speed(t), move.sample(t + 1e-6)
        assert v == pytest.approx(math.dist(p[:3], p2[:3]) / 1e-6, rel=1e-4, abs=1e-3)
    assert move.sample_with_speed(move.duration) == (move.path.end, 0.0)


def test_move_and_pose_arguments():
    with pytest.raises(ValueError, match="speed"):
        CartesianMove(LinPath((0,) * 6, (1, 0, 0, 0, 0, 0)), 0.0, 100.0)
    with pytest.raises(ValueError, match="acc"):
        CartesianMove(LinPath((0,) * 6, (1, 0, 0, 0, 0, 0)), 10.0, float("inf"))
    with pytest.raises(ValueError, match="jerk"):
        CartesianMove(LinPath((0,) * 6, (1, 0, 0, 0, 0, 0)), 10.0, 100.0, -1.0)
    with pytest.raises(ValueError, match="not finite"):
        LinPath((0,) * 6, (float("nan"), 0, 0, 0, 0, 0))
    # a language Pose (rpy or quat) and a matrix are poses too
    rpy = Pose(Position(1.0, 2.0, 3.0), Rpy(10.0, 20.0, 30.0))
    assert pose_tuple(rpy) == (1.0, 2.0, 3.0, 10.0, 20.0, 30.0)
    w, x, y, z = rpy_to_quat(10.0, 20.0, 30.0)
    assert pose_tuple(Pose(Position(1, 2, 3), Quat(2 * w, 2 * x, 2 * y, 2 * z))) == \
        pytest.approx((1.0, 2.0, 3.0, 10.0, 20.0, 30.0), abs=1e-12)
    m = [list(r) + [t] for r, t in zip(rpy_to_matrix(10.0, 20.0, 30.0), (1.0, 2.0, 3.0))] + [[0, 0, 0, 1]]
    assert pose_tuple(m) == pytest.approx((1.0, 2.0, 3.0, 10.0, 20.0, 30.0), abs=1e-12)
    assert LinPath(rpy, (1, 2, 3, 10, 20, 30)).length == 0.0


# ----------------------------------------------------------------------------- circ


def test_circ_geometry_half_and_three_quarter_circles():
    # the arc through the via point, not the other one
    c = CircPath((100, 0, 0, 0, 0, 0), (0, -100, 0), (-100, 0, 0, 0, 0, 0))
    assert c.centre == pytest.approx((0, 0, 0), abs=1e-12) and c.radius == pytest.approx(100.0)
    assert c.angle == pytest.approx(180.0) and c.via_angle == pytest.approx(90.0)
    assert c.normal == pytest.approx((0, 0, -1))
    assert c.pose_at(c.length / 2)[:3] == pytest.approx((0, -100, 0), abs=1e-12)
    c = CircPath((100, 0, 0, 0, 0, 0), (-100, 0, 0), (0, -100, 0, 0, 0, 0))
    assert c.angle == pytest.approx(270.0) and c.via_angle == pytest.approx(180.0)
    assert c.position_length == pytest.approx(1.5 * math.pi * 100.0)
    assert c.pose_at(c.length / 3)[:3] == pytest.approx((0, 100, 0), abs=1e-12)
    # the via pose's orientation is ignored, a bare position will do
    a = CircPath((100, 0, 0, 0, 0, 0), (0, 100, 0, 50, 60, 70), (-100, 0, 0, 0, 0, 90))
    b = CircPath((100, 0, 0, 0, 0, 0), (0, 100, 0), (-100, 0, 0, 0, 0, 90))
    assert a.pose_at(77.0) == b.pose_at(77.0)


def circle_check(start, via, end, speed=400.0, acc=3000.0):
    path = CircPath(start, via, end)
    move = CartesianMove(path, speed, acc)
    c, r, n = np.array(path.centre), path.radius, np.array(path.normal)
    ts = grid(move)
    pts = np.array([move.sample(t)[:3] for t in ts])
    radial = np.abs(np.linalg.norm(pts - c, axis=1) - r) / r
    assert radial.max() <= 1e-9
    assert np.abs((pts - c) @ n).max() <= 1e-9 * r  # in the circle's plane
    # through the via point: exactly at via_length, and the samples pass it
    assert np.linalg.norm(np.array(path.pose_at(path.via_length)[:3]) - via[:3]) <= 1e-9 * r
    step = np.linalg.norm(np.diff(pts, axis=0), axis=1).max()
    assert np.linalg.norm(pts - np.array(via[:3]), axis=1).min() <= step
    # exact ends; the angle grows monotonically from 0 to the swept angle
    assert move.sample(0.0) == tuple(float(v) for v in start)
    assert move.sample(move.duration) == tuple(float(v) for v in end)
    e1 = (np.array(start[:3]) - c) / r
    e2 = np.cross(n, e1)
    phi = np.unwrap(np.arctan2((pts - c) @ e2, (pts - c) @ e1))
    assert np.diff(phi).min() >= -1e-12 and phi[-1] == pytest.approx(math.radians(path.angle), abs=1e-9)
    # the TCP speed stays within the speed, the profile within its limits
    tcp = np.linalg.norm(np.diff(pts, axis=0), axis=1) / 0.001
    assert tcp.max() <= speed * (1 + 1e-9)
    check_profile_limits(np.array([move.progress(t)[0] for t in ts]), 0.001, speed, acc, move.jerk)
    return path


def test_circ_samples_on_the_circle_through_the_via_point():
    path = circle_check((800.0, 0.0, 1000.0, 180.0, -45.0, 0.0), (850.0, 150.0, 1100.0),
                        (700.0, 250.0, 1000.0, 170.0, -30.0, 40.0))
    assert 0.0 < path.via_angle < path.angle < 360.0


@settings(max_examples=40, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(positions, positions, positions, st.tuples(angles, st.floats(-89, 89), angles),
       st.tuples(angles, st.floats(-89, 89), angles))
def test_circ_random_triples(p0, p1, p2, o0, o2):
    u, w = np.subtract(p1, p0), np.subtract(p2, p0)
    area = np.linalg.norm(np.cross(u, w))
    longest = max(np.linalg.norm(u), np.linalg.norm(w), np.linalg.norm(np.subtract(p2, p1)))
    assume(longest > 1.0 and area / longest > 0.05 * longest)  # well-shaped triangles
    path = CircPath(p0 + o0, p1, p2 + o2)
    assume(path.length / 2000.0 < 20.0)
    circle_check(p0 + o0, p1, p2 + o2, speed=2000.0, acc=8000.0)


@pytest.mark.parametrize("via, end, message", [
    ((0, 0, 0), (100, 0, 0, 0, 0, 0), "via point coincides with the start"),
    ((50, 0, 0), (50, 0, 0.0001, 0, 0, 0), "via point coincides with the end"),
    ((50, 50, 0), (0, 0, 0, 0, 0, 90), "end point coincides with the start"),
    ((50, 0, 0), (100, 0, 0, 0, 0, 0), "collinear"),
    ((150, 0, 0), (100, 0, 0, 0, 0, 0), "collinear"),  # via beyond the end
    ((50, 0.0001, 0), (100, 0, 0, 0, 0, 0), "collinear"),
])
def test_circ_errors(via, end, message):
    with pytest.raises(ValueError, match=message):
        CircPath((0, 0, 0, 0, 0, 0), via, end)


# ----------------------------------------------------------------------------- check_path


def lin_move(target, speed=250.0, acc=1000.0, start=START, jerk=None):
    return CartesianMove(LinPath(KIN.forward(start), target), speed, acc, jerk)


def offset(pose, dx=0.0, dy=0.0, dz=0.0, droll=0.0, dpitch=0.0, dyaw=0.0):
    x, y, z, r, p, w = pose
    return (x + dx, y + dy, z + dz, r + droll, p + dpitch, w + dyaw)


def assert_fk_reproduces(checked, tol_mm=1e-6, tol_deg=1e-6):
    for t, q in zip(checked.times, checked.joints):
        pose = checked.move.sample(t)
        fk = KIN.forward(q)
        assert math.dist(fk[:3], pose[:3]) <= tol_mm
        assert rot_angle(rot(fk), rot(pose)) <= tol_deg


def test_start_pose_is_not_singular():
    shoulder, elbow, wrist = KIN.singularity_margins(START)
    assert shoulder > 500.0 and elbow > 0.5 and wrist > 0.5
    assert KIN.inverse(KIN.forward(START), near=START) == pytest.approx(START, abs=1e-9)


@pytest.mark.parametrize("delta", [dict(dy=200.0), dict(dx=-120.0, dy=100.0, dz=-120.0, dyaw=30.0),
                                   dict(dz=200.0, dpitch=-20.0)])
def test_reachable_lin_move_passes_and_fk_reproduces_the_path(delta):
    target = offset(KIN.forward(START), **delta)
    move = lin_move(target)
    assert move.path.position_length == pytest.approx(200.0, abs=1e-6) or delta.get("dz") == -120.0
    checked = check_path(move, KIN, START, AXES)
    assert checked.times[0] == 0.0 and checked.times[-1] == move.duration
    assert len(checked.times) >= 201  # 1 mm steps, at least 50 samples
    assert checked.joints[0] == pytest.approx(START, abs=1e-9)
    assert_fk_reproduces(checked)
    steps = np.abs(np.diff(np.array(checked.joints), axis=0)).max()
    assert steps < 1.0
    assert all(v <= a.max_velocity for v, a in zip(checked.peak_velocities, AXES))
    assert checked.min_margins[2] > 0.3
    # joints_at: one inverse kinematics near the previous joints, on the path
    for t in np.linspace(0.0, move.duration, 23):
        q = checked.joints_at(t, near=checked.seed(t))
        assert math.dist(KIN.forward(q)[:3], move.sample(t)[:3]) < 1e-6
    assert checked.joints_at(move.duration + 1.0) == checked.end_joints


def test_check_samples_densely_enough():
    checked = check_path(lin_move(offset(KIN.forward(START), dy=300.0, dyaw=60.0), 1000.0, 4000.0),
                         KIN, START, AXES)
    poses = [checked.move.sample(t) for t in checked.times]
    assert max(math.dist(a[:3], b[:3]) for a, b in zip(poses, poses[1:])) <= 1.0 + 1e-9
    assert max(rot_angle(rot(a), rot(b)) for a, b in zip(poses, poses[1:])) <= 1.0 + 1e-9
    short = check_path(lin_move(offset(KIN.forward(START), dx=2.0)), KIN, START)
    assert len(short.times) == 51


def expected_reach_fraction(path) -> float:
    """Where along the path the inverse kinematics first fails: bisection."""
    lo, hi = 0.0, path.length
    assert KIN.solutions(path.pose_at(lo)) and not KIN.solutions(path.pose_at(hi))
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        try:
            KIN.inverse(path.pose_at(mid), near=START)
            lo = mid
        except KinematicsError:
            hi = mid
    return lo / path.length


def test_leaving_the_reach_fails_where_it_leaves():
    target = offset(KIN.forward(START), dx=1000.0)
    move = lin_move(target)
    with pytest.raises(PathError) as info:
        check_path(move, KIN, START, AXES)
    err = info.value
    assert isinstance(err, ValueError) and err.reason == "unreachable"
    expected = expected_reach_fraction(move.path)
    assert 0.5 < expected < 0.95
    assert abs(err.fraction - expected) <= 2.0 / move.path.length + 1e-9  # within a sample
    m = re.search(r"leaves the arm's reach at \d+ % of its length, ([\d.]+) mm from its start \(the wrist centre "
                  r"is [\d.]+ mm beyond the arm's reach\)", str(err))
    assert m, str(err)
    assert f"{round(100 * err.fraction)} %" in str(err)
    # where along the tool's path, in mm: the fraction of its length
    assert err.distance == pytest.approx(err.fraction * move.path.position_length)
    assert float(m.group(1)) == pytest.approx(err.distance, abs=0.051)


def wrist_path(dy=0.0):
    """From A5 = +10 to A5 = -10 at one orientation: on the way A5 passes 0."""
    a, b = KIN.forward((0, -30, 30, 0, 10, 0)), KIN.forward((0, -10, 30, 0, -10, 0))
    assert rot_angle(rot(a), rot(b)) < 1e-9  # the same orientation
    return LinPath(a, offset(b, dy=dy)), (0.0, -30.0, 30.0, 0.0, 10.0, 0.0)


def test_a_path_through_the_wrist_singularity_fails_naming_it():
    path, start = wrist_path()
    with pytest.raises(PathError) as info:
        check_path(CartesianMove(path, 250.0, 1000.0), KIN, start, AXES)
    err = info.value
    assert err.reason in ("configuration", "singular", "jump")
    assert "wrist singularity" in str(err) and "A5" in str(err)
    # where A5 passes 0: independently, by bisection on the sign of A5
    lo, hi = 0.0, path.length
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        try:
            a5 = KIN.inverse(path.pose_at(mid), near=start)[4]  # A4, A6 stay 0: A5 changes sign
        except KinematicsError as exc:  # on it (|sin A5| < 1e-6)
            assert "wrist singularity" in str(exc)
            lo = mid
            break
        lo, hi = (mid, hi) if a5 > 0 else (lo, mid)
    assert abs(err.fraction - lo / path.length) < 0.01


def test_a_path_next_to_the_wrist_singularity_fails_naming_it():
    path, start = wrist_path(dy=5.0)
    with pytest.raises(PathError) as info:
        check_path(CartesianMove(path, 250.0, 1000.0), KIN, start)
    assert info.value.reason == "jump" and info.value.axis in ("A4", "A6")
    assert "next to the wrist singularity" in str(info.value)
    # 20 mm away, slowly, the wrist can turn through (fast): it passes, at 250 mm/s not
    path, start = wrist_path(dy=20.0)
    checked = check_path(CartesianMove(path, 50.0, 1000.0), KIN, start, AXES)
    assert checked.min_margins[2] < 0.05 and max(checked.peak_velocities[3:]) > 100.0
    with pytest.raises(PathError) as info:
        check_path(CartesianMove(path, 250.0, 1000.0), KIN, start, AXES)
    assert info.value.reason == "velocity" and info.value.axis in ("A4", "A6")


def test_too_high_a_speed_fails_naming_the_axis():
    target = KIN.forward((0.0, -30.0, 30.0, 90.0, 45.0, 0.0))  # a turn of the wrist
    with pytest.raises(PathError) as info:
        check_path(lin_move(target, 2000.0, 8000.0), KIN, START, AXES)
    err = info.value
    assert err.reason == "velocity" and err.axis == "A4"
    a4 = AXES[3].max_velocity  # 330 deg/s
    m = re.fullmatch(rf"A4 would need (\d+) deg/s \(limit {a4:g}\) at (\d+) % of the path, [\d.]+ mm from its "
                     rf"start: lower the speed \(to at most ([\d.]+) mm/s\)", str(err))
    assert m, str(err)
    assert int(m.group(1)) > a4 and 0.0 < err.fraction < 1.0
    # the speed it suggests passes, and keeps A4 within its limit
    checked = check_path(lin_move(target, float(m.group(3)), 8000.0), KIN, START, AXES)
    assert checked.peak_velocities[3] <= a4
    # max velocities as plain numbers work too; no limits: no velocity check
    with pytest.raises(PathError, match="A4 would need"):
        check_path(lin_move(target, 2000.0, 8000.0), KIN, START, [a.max_velocity for a in AXES])
    check_path(lin_move(target, 2000.0, 8000.0), KIN, START)


def test_acceleration_check_is_optional():
    target = offset(KIN.forward(START), dy=400.0)
    move = lin_move(target, 2000.0, 8000.0)
    check_path(move, KIN, START, AXES)
    with pytest.raises(PathError) as info:
        check_path(move, KIN, START, AXES, check_acceleration=True)
    assert info.value.reason == "acceleration" and "deg/s^2" in str(info.value)
    check_path(lin_move(target, 250.0, 1000.0), KIN, START, AXES, check_acceleration=True)
    with pytest.raises(ValueError, match="max_acceleration"):
        check_path(move, KIN, START, [a.max_velocity for a in AXES], check_acceleration=True)


def test_axis_limits_start_and_singular_start():
    # a chord around the base: A1 would pass its limit
    start = (160.0, -30.0, 30.0, 0.0, 45.0, 0.0)
    move = CartesianMove(LinPath(KIN.forward(start), KIN.forward((-160.0, -30.0, 30.0, 0.0, 45.0, 0.0))),
                         250.0, 1000.0)
    with pytest.raises(PathError) as info:
        check_path(move, KIN, start, AXES)
    assert info.value.reason == "limit" and info.value.axis == "A1" and "axis limits" in str(info.value)
    # tighter limits than the kinematics' own
    axes = [dataclasses.replace(a, max=60.0) if a.name == "A5" else a for a in AXES]
    move = lin_move(KIN.forward((0.0, -30.0, 30.0, 0.0, 80.0, 0.0)))
    check_path(move, KIN, START, AXES)
    with pytest.raises(PathError) as info:
        check_path(move, KIN, START, axes)
    assert info.value.axis == "A5" and f"limit {AXES[4].min:g}..60" in str(info.value)
    assert 0.3 < info.value.fraction < 0.5  # 45 -> 80: 60 is reached after 15/35 of the turn
    # the path must start where the arm is
    with pytest.raises(PathError) as info:
        check_path(move, KIN, (0.0, -30.0, 30.0, 0.0, 46.0, 0.0))
    assert info.value.reason == "start" and info.value.fraction == 0.0
    # the zero position is singular (A5 = 0)
    zero = (0.0,) * 6
    move = CartesianMove(LinPath(KIN.forward(zero), offset(KIN.forward(zero), dx=-100.0)), 250.0, 1000.0)
    with pytest.raises(PathError, match="starts at a singularity .*wrist") as info:
        check_path(move, KIN, zero)
    assert info.value.reason == "singular" and info.value.fraction == 0.0


def test_circ_move_on_the_arm():
    p0 = KIN.forward(START)
    path = CircPath(p0, offset(p0, dy=100.0, dz=100.0)[:3], offset(p0, dy=200.0, dyaw=20.0))
    checked = check_path(CartesianMove(path, 300.0, 2000.0), KIN, START, AXES)
    assert_fk_reproduces(checked)
    assert len(checked.times) > path.position_length


def test_zero_length_move_checks_and_streams():
    p0 = KIN.forward(START)
    checked = check_path(CartesianMove(LinPath(p0, p0), 250.0, 1000.0), KIN, START, AXES)
    assert len(checked.joints) == 1 and checked.duration == 0.0
    stream = JointStream(checked)
    assert stream.sample(0.005) == (checked.end_joints, (0.0,) * 6)


# ----------------------------------------------------------------------------- per tick


def test_joint_stream_per_tick():
    target = offset(KIN.forward(START), dx=-100.0, dy=150.0, dz=-50.0, droll=10.0, dyaw=-25.0)
    result, stream, message = plan_cartesian(CartesianInput(KIN, START + (12.5,), target, 400.0, 2000.0,
                                                            axis_limits=SPEC))
    assert result == Result.WORKING and message == "" and isinstance(stream, JointStream)
    move = stream.checked.move
    h = 0.005
    t, qs, vs, ts = 0.0, [], [], []
    while t < stream.duration:
        t += h
        q, v = stream.sample(t)
        assert len(q) == 7 and q[6] == 12.5 and v[6] == 0.0
        qs.append(q[:6]), vs.append(v[:6]), ts.append(t)
    assert stream.fault is None
    assert qs[-1] == stream.checked.end_joints and vs[-1] == (0.0,) * 6
    assert math.dist(KIN.forward(qs[-1])[:3], target[:3]) < 1e-9
    assert stream.sample(0.0) == (START + (12.5,), (0.0,) * 7)
    for t, q in zip(ts, qs):
        pose = move.sample(t)
        fk = KIN.forward(q)
        assert math.dist(fk[:3], pose[:3]) < 1e-6 and rot_angle(rot(fk), rot(pose)) < 1e-6
    # the velocities: the derivative of the joint path (central differences, O(h^2))
    qa, va = np.array(qs), np.array(vs)
    for k in range(1, len(qs) - 2):
        exact = (np.array(stream.joints_at(ts[k] + 1e-6, qs[k])) -
                 np.array(stream.joints_at(ts[k] - 1e-6, qs[k]))) / 2e-6
        assert np.abs(va[k] - exact).max() < 0.05 + 1e-3 * np.abs(exact).max()
    assert np.abs(np.diff(qa, axis=0)).max() < 1.0
    # random access gives the same as the tick-by-tick sequence
    fresh = JointStream(stream.checked, additional=(12.5,))
    for k in (3, 40, len(ts) // 2):
        q, v = fresh.sample(ts[k])
        assert q[:6] == pytest.approx(qs[k], abs=1e-9) and v[:6] == pytest.approx(vs[k], abs=1e-6)


def test_plan_cartesian_returns_a_result_and_a_message_and_never_raises():
    def plan(*args, **kwargs):
        return plan_cartesian(CartesianInput(KIN, *args, **kwargs))

    result, stream, message = plan(START, "nowhere", 250.0, 1000.0)
    assert result == Result.ERROR_INVALID_INPUT and stream is None and "a pose is" in message
    result, stream, message = plan(START, offset(KIN.forward(START), dx=1000.0), 250.0, 1000.0)
    assert result == Result.ERROR_PATH and stream is None and "leaves the arm's reach" in message
    p0 = KIN.forward(START)
    result, stream, message = plan(START, offset(p0, dy=100.0), 250.0, 1000.0, via=offset(p0, dy=50.0)[:3])
    assert result == Result.ERROR_INVALID_INPUT and stream is None and "collinear" in message
    result, stream, message = plan(START, offset(p0, dy=10.0), -1.0, 1000.0)
    assert result == Result.ERROR_INVALID_INPUT and stream is None and "speed" in message
    result, stream, message = plan(START[:5], p0, 250.0, 1000.0)
    assert result == Result.ERROR_INVALID_INPUT and stream is None and "six" in message
    result, stream, message = plan(START, Pose(Position(*offset(p0, dy=200.0)[:3]), Rpy(*p0[3:])), 250.0, 1000.0,
                                   via=Pose(Position(*offset(p0, dy=100.0, dz=100.0)[:3]), Rpy(0, 0, 0)),
                                   axis_limits=AXES)
    assert result == Result.WORKING and message == "" and stream.duration > 0.0
    q, _ = stream.sample(stream.duration)
    assert math.dist(KIN.forward(q)[:3], offset(p0, dy=200.0)[:3]) < 1e-9


def test_shoulder_singularity_limits_and_branch_switches_are_named():
    p0 = KIN.forward(START)
    # straight over axis 1: the shoulder flips
    move = CartesianMove(LinPath(p0, (-300.0, 0.0) + p0[2:]), 50.0, 1000.0)
    with pytest.raises(PathError) as info:
        check_path(move, KIN, START, AXES)
    assert info.value.reason == "configuration" and "shoulder singularity" in str(info.value)
    # 1 mm beside it: A1 whirls round
    move = CartesianMove(LinPath(p0, (-300.0, 1.0) + p0[2:]), 50.0, 1000.0)
    with pytest.raises(PathError) as info:
        check_path(move, KIN, START, AXES)
    assert info.value.reason == "jump" and info.value.axis == "A1"
    assert "next to the shoulder singularity" in str(info.value)
    # 30 mm beside it A5 runs into its limit and the elbow would have to flip
    move = CartesianMove(LinPath(p0, (-300.0, 30.0) + p0[2:]), 50.0, 1000.0)
    with pytest.raises(PathError) as info:
        check_path(move, KIN, START, AXES)
    assert info.value.reason == "limit" and info.value.axis == "A5"
    assert "A5 would be 12" in str(info.value) and "elbow down" in str(info.value)
    # A6 turning past its limit of 350: the solution would wrap (or the wrist flip)
    start = (0.0, -30.0, 30.0, 0.0, 45.0, 300.0)
    move = CartesianMove(LinPath(KIN.forward(start), KIN.forward(start[:5] + (390.0,))), 250.0, 1000.0)
    with pytest.raises(PathError) as info:
        check_path(move, KIN, start, AXES)
    assert info.value.reason == "limit" and info.value.axis == "A6"
    assert f"A6 would pass its limit {AXES[5].max:g} deg" in str(info.value)
    assert info.value.fraction == pytest.approx(50.0 / 90.0, abs=0.01)


def test_tangents_and_orientation_at():
    lin = LinPath((0, 0, 0, 0, 0, 0), (30, 40, 0, 0, 0, 60))
    assert lin.tangent_at(10.0) == pytest.approx((0.6, 0.8, 0.0))
    assert same_rotation(lin.orientation_at(lin.length), rpy_to_quat(0, 0, 60), 1e-15)
    assert same_rotation(lin.orientation_at(-5.0), (1.0, 0.0, 0.0, 0.0), 1e-15)
    circ = CircPath((800.0, 0.0, 1000.0, 180.0, -45.0, 0.0), (850.0, 150.0, 1100.0),
                    (700.0, 250.0, 1000.0, 170.0, -30.0, 40.0))
    for s in np.linspace(1.0, circ.length - 1.0, 9):
        fd = (np.array(circ.position_at(s + 1e-4)) - circ.position_at(s - 1e-4)) / 2e-4
        assert np.allclose(circ.tangent_at(s), fd / np.linalg.norm(fd), atol=1e-7)


# ---- every joint within its limits (issue 14): the move slows down instead ------------------

LIMITS = ([a.max_velocity for a in AXES], [a.max_acceleration for a in AXES], [a.max_jerk for a in AXES])
SETPOINT = 0.005


def setpoint_ratios(stream) -> tuple[float, float, float]:
    """The largest ratio of any joint's velocity (as sampled), acceleration and jerk
    (differences of consecutive samples) to its limit, over the 5 ms setpoints."""
    steps = int(math.ceil(stream.duration / SETPOINT)) + 2
    samples = [stream.sample(n * SETPOINT) for n in range(steps + 1)]
    v = np.array([s[1][:6] for s in samples])
    a = np.diff(v, axis=0) / SETPOINT
    j = np.diff(a, axis=0) / SETPOINT
    return tuple(float(np.max(np.abs(x) / np.array(limit))) for x, limit in zip((v, a, j), LIMITS))


def tcp_speed(stream) -> float:
    """The largest TCP speed (mm/s) between two 5 ms setpoints."""
    steps = int(math.ceil(stream.duration / SETPOINT)) + 1
    points = [KIN.forward(stream.sample(n * SETPOINT)[0][:6])[:3] for n in range(steps + 1)]
    return max((math.dist(p, q) / SETPOINT for p, q in zip(points, points[1:])), default=0.0)


@st.composite
def cartesian_moves(draw):
    """(start joints, "lin"/"circ", arguments, speed): a start within the limits (half of
    them with the wrist near its singularity), 50-500 mm in any direction, a tilted tool."""
    q0 = [draw(st.floats(max(a.min, -150), min(a.max, 150))) for a in AXES]
    if draw(st.booleans()):
        q0[4] = math.copysign(math.degrees(math.asin(draw(st.floats(0.05, 0.2)))), draw(st.sampled_from([-1, 1])))
    margins = KIN.singularity_margins(q0)
    assume(margins[0] >= 50.0 and margins[1] >= 0.2 and margins[2] >= 0.05)
    x, y, z, r, p, w = KIN.forward(q0)
    direction = np.array([draw(st.floats(-1, 1)) for _ in range(3)])
    assume(np.linalg.norm(direction) > 0.1)
    direction /= np.linalg.norm(direction)
    length = draw(st.floats(50, 500))
    tilt = tuple(c + draw(st.floats(-20, 20)) for c in (r, p, w))
    end = tuple(np.array((x, y, z)) + length * direction) + tilt
    speed = draw(st.sampled_from([100.0, 250.0, 500.0, 1000.0]))
    acc = draw(st.sampled_from([500.0, 1500.0, 5000.0]))
    if draw(st.booleans()):
        return q0, "lin", (end, speed, acc), speed
    side = np.cross(direction, [0.0, 0.0, 1.0] if abs(direction[2]) < 0.9 else [1.0, 0.0, 0.0])
    side /= np.linalg.norm(side)
    via = tuple(np.array((x, y, z)) + 0.5 * length * direction + draw(st.floats(0.1, 0.5)) * length * side)
    return q0, "circ", (via + tilt, end, speed, acc), speed


@settings(max_examples=examples(30), deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
@given(cartesian_moves())
def test_property_lin_and_circ_setpoints_keep_every_joint_limit_and_the_speed(drawn):
    q0, kind, args, speed = drawn
    if kind == "lin":
        _, stream, message = plan_cartesian(CartesianInput(KIN, q0, args[0], args[1], args[2], axis_limits=SPEC))
    else:
        _, stream, message = plan_cartesian(CartesianInput(KIN, q0, args[1], args[2], args[3], via=args[0],
                                                           axis_limits=SPEC))
    assume(stream is not None)  # out of reach or through a singularity: refused (tested above)
    assert "would need" not in message
    velocity, acceleration, jerk = setpoint_ratios(stream)
    assert velocity <= 1.0 + 1e-6 and acceleration <= 1.0 + 1e-6 and jerk <= 1.0 + 1e-6, (velocity, acceleration,
                                                                                            jerk)
    assert tcp_speed(stream) <= speed * (1.0 + 1e-6)


def test_a_lin_move_near_the_wrist_singularity_slows_down_instead_of_exceeding_the_limits():
    """Issue 14's example: a vertical lin with a tilted tool that asked A4 for 7.8x its
    acceleration limit now takes longer, within every limit."""
    q0 = (0.0, -30.0, 30.0, 0.0, 4.0, 0.0)  # the wrist 4 deg from its singularity
    x, y, z, r, p, w = KIN.forward(q0)
    target = (x, y, z - 120.0, r, p, w + 10.0)
    fast = check_path(CartesianMove(LinPath(KIN.forward(q0), target), 200.0, 1500.0), KIN, q0, SPEC,
                      check_velocity=False, min_samples=200)
    before = max(setpoint_ratios(JointStream(fast))[1:])
    _, stream, message = plan_cartesian(CartesianInput(KIN, q0, target, 200.0, 1500.0, axis_limits=SPEC))
    assert stream is not None, message
    assert before > 1.5  # (the move as programmed would break a limit)
    assert max(setpoint_ratios(stream)) <= 1.0
    assert stream.duration > fast.duration


@pytest.mark.long
def test_the_shipped_palletizing_program_keeps_every_joint_limit_end_to_end():
    """programs/palletize.irl's lin moves reached 1.77x A4's acceleration limit; run whole
    (homing included), the setpoints and the drives' commands stay within the limits."""
    from compiler.driver import compile_source
    from limits_watch import LimitWatch, run_cycle
    from runtime.loop.system import RobotSystem, RunOptions

    path = ROOT / "programs" / "palletize.irl"
    result = compile_source(path.read_text(encoding="utf-8"), str(path), ROOT / "programs" / "lola15.spc")
    assert result.ok, result.diagnostics
    system = RobotSystem(SPEC, RunOptions(seed=0))
    watch = LimitWatch(system)
    summary = run_cycle(system, result.program)
    assert summary["fault"] is None, summary["fault"]
    assert watch.planned_velocity_ratio <= 1.0 and watch.planned_acceleration_ratio <= 1.0, watch.worst
    assert watch.acceleration_ratio <= 1.0, watch.worst  # (the servo's corrections included)
