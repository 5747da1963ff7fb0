"""Jerk-limited (double-S) PTP motion: runtime.motion.jerk.

* The reference moves (100 deg/s, 200 deg/s^2, 2000 deg/s^3 on every axis): 1.053939 s
  and 1.500000 s, in both synchronisation modes; the module's doctest.
* Each closed-form case -- (i) v and a reached, (ii) v reached without a, (iii-a) a
  reached without v, (iii-b) neither -- against hand-derived phase times, peaks and
  durations; the case boundaries; zero and negative distances; continuity of position,
  velocity and acceleration at every phase boundary.
* Properties (Hypothesis, derandomized) of single profiles over random distances (tiny,
  ordinary, huge) and limits (extreme ratios): on a dense grid of 2000 samples every
  velocity, acceleration and jerk (analytic and by finite differences) within its
  limit; exactly at the target at the end; ``duration == minimum_duration``; the
  stretched profile takes exactly the requested time and keeps the limits.
* Optimality: against Ruckig on 200 random single axes (skipped without Ruckig), and
  against a brute-force search over all symmetric double-S profiles.
* The planner: results and messages like plan_ptp; synchronised six-axis moves (all
  axes start and stop together, within their limits, at their targets); ``"line"``
  keeps every sample on the straight joint-space line (equal normalised progress on
  every moving axis, within 1e-9 plus the positions' own rounding); ``"time"`` takes
  the largest per-axis minimal duration.

NumPy is used here only; the motion code is plain floats.
"""
from __future__ import annotations

import doctest
import math
import random

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import runtime.motion.jerk as jerk_module
from runtime.motion.jerk import (
    JerkProfile,
    JerkPtpTrajectory,
    minimum_duration,
    plan_ptp_jerk,
    profile_with_duration,
    time_optimal_profile,
)
from runtime.motion.planner import DISTANCE_EPSILON, MAX_DURATION, PtpInput, Result
from conftest import examples


def jerk_plan(start, target, v_max, a_max, j_max, synchronization="line"):
    """plan_ptp_jerk through its typed input (the line synchronisation unless told)."""
    return plan_ptp_jerk(PtpInput(start, target, v_max, a_max, max_jerk=j_max, synchronization=synchronization))

EPS = float(np.finfo(float).eps)
REL = 1e-9  # relative tolerance on limits
N_SAMPLES = 2000

PROPERTY = settings(derandomize=True, deadline=None, max_examples=examples(150),
                    suppress_health_check=[HealthCheck.too_slow])
PLANNER_PROPERTY = settings(PROPERTY, max_examples=60)

REF_LIMITS = ((100.0,) * 6, (200.0,) * 6, (2000.0,) * 6)
REF_MOVES = [(0.0,) * 6, (45.0, 0.0, -45.0, 0.0, 0.0, 0.0), (-45.0, 45.0, 45.0, 0.0, 0.0, 0.0)]


# --------------------------------------------------------------------------- helpers


def sample_profile(p: JerkProfile, times) -> np.ndarray:
    """(n, 3) array of position, velocity, acceleration."""
    return np.array([p.sample(float(t)) for t in times])


def grid(duration: float, n: int = N_SAMPLES) -> np.ndarray:
    """``n`` instants over [0, duration], plus a few before and after."""
    inside = np.linspace(0.0, duration, n)
    return np.concatenate(([-1.0, -1e-9], inside, [duration * (1 + 1e-12) + 1e-300,
                                                    duration + 1.0]))


def boundaries(p: JerkProfile) -> list[float]:
    """The phase switches 0, t_j, t_j + t_a, t_acc, T - t_acc, ..., T and the midpoint."""
    t_j, t_a, t_acc, big_t = p.t_j, p.t_a, p.t_acc, p.duration
    return [0.0, t_j, t_j + t_a, t_acc, 0.5 * big_t, big_t - t_acc, big_t - t_acc + t_j,
            big_t - t_j, big_t]


def assert_profile_within_limits(p: JerkProfile, v_max: float, a_max: float, j_max: float):
    """Dense samples: limits (analytic and finite differences), rest outside, exact end,
    monotonic progress."""
    big_t = p.duration
    times = grid(big_t)
    s = sample_profile(p, times)
    pos, vel, acc = s[:, 0], s[:, 1], s[:, 2]
    sign = math.copysign(1.0, p.distance)
    scale = abs(p.start) + abs(p.distance)
    # analytic: the stored peaks and every sample
    assert abs(p.jerk) <= j_max * (1 + REL)
    assert abs(p.peak_acceleration) <= a_max * (1 + REL)
    assert abs(p.peak_velocity) <= v_max * (1 + REL)
    assert np.all(np.abs(vel) <= v_max * (1 + REL))
    assert np.all(np.abs(acc) <= a_max * (1 + REL))
    # the velocity never points backwards; positions progress monotonically
    assert np.all(vel * sign >= 0.0)
    assert np.all(np.diff(pos) * sign >= -8 * EPS * scale)
    # finite differences: velocity from positions, jerk from accelerations
    inside = slice(2, 2 + N_SAMPLES)
    dt = big_t / (N_SAMPLES - 1)
    if dt > 0.0:
        fd_vel = np.abs(np.diff(pos[inside])) / dt
        assert np.all(fd_vel <= v_max * (1 + REL) + 8 * EPS * scale / dt)
        fd_jerk = np.abs(np.diff(acc[inside])) / dt
        assert np.all(fd_jerk <= j_max * (1 + REL) + 8 * EPS * (a_max + j_max * big_t) / dt)
        fd_acc = np.abs(np.diff(vel[inside])) / dt
        assert np.all(fd_acc <= a_max * (1 + REL) + 8 * EPS * (v_max + a_max * big_t) / dt)
    # at rest outside [0, T]; exactly at start + distance from T on
    end = p.start + p.distance
    assert p.sample(-1.0) == (p.start, 0.0, 0.0)
    assert p.sample(float("nan")) == (p.start, 0.0, 0.0)
    assert p.sample(big_t) == (end, 0.0, 0.0)
    assert p.sample(big_t + 1.0) == (end, 0.0, 0.0)
    if big_t > 0.0:
        assert p.sample(0.0) == (p.start, 0.0, 0.0)
        just_before = p.sample(big_t * (1 - 1e-15))
        assert abs(just_before[0] - end) <= 1e-9 * max(1.0, scale)


def assert_continuous(p: JerkProfile, v_max: float, a_max: float, j_max: float):
    """Position, velocity, acceleration continuous at every phase boundary: the jump
    over ``[b - h, b + h]`` is what the limits allow in ``2 h`` plus rounding."""
    big_t = p.duration
    h = 1e-9 * big_t
    scale = abs(p.start) + abs(p.distance)
    for b in boundaries(p):
        left = p.sample(b - h) if b - h > 0.0 else (p.start, 0.0, 0.0)
        right = p.sample(b + h) if b + h < big_t else (p.start + p.distance, 0.0, 0.0)
        assert abs(left[0] - right[0]) <= v_max * 2 * h + 16 * EPS * scale, (b, left, right)
        assert abs(left[1] - right[1]) <= a_max * 2 * h + 64 * EPS * (v_max + a_max * big_t)
        assert abs(left[2] - right[2]) <= j_max * 2 * h + 64 * EPS * (a_max + j_max * big_t)


def distance_by_integration(p: JerkProfile) -> float:
    """The distance as the integral of the sampled velocity (Simpson, 20001 points)."""
    times = np.linspace(0.0, p.duration, 20001)
    vel = np.array([p.sample(float(t))[1] for t in times])
    dt = times[1] - times[0]
    return float(dt / 3 * (vel[0] + vel[-1] + 4 * vel[1:-1:2].sum() + 2 * vel[2:-1:2].sum()))


# --------------------------------------------------------------------------- reference


@pytest.mark.parametrize("synchronization", ["line", "time"])
def test_reference_moves(synchronization):
    expected = [1.053939, 1.500000]
    for (start, target), want in zip(zip(REF_MOVES, REF_MOVES[1:]), expected):
        result, traj, message = jerk_plan(start, target, *REF_LIMITS, synchronization)
        assert (result, message) == (Result.WORKING, "")
        assert abs(traj.duration - want) < 1e-6, traj.duration
        assert traj.sample(traj.duration) == (target, (0.0,) * 6)
        assert traj.sample(0.0) == (start, (0.0,) * 6)
    # the closed forms: case (iii-a), t_j = a / j = 0.1; case (i): 90 / 100 + 0.5 + 0.1
    assert jerk_plan(REF_MOVES[0], REF_MOVES[1], *REF_LIMITS)[1].duration == \
        pytest.approx(0.1 + math.sqrt(0.01 + 4 * 45 / 200), rel=1e-15)
    assert jerk_plan(REF_MOVES[1], REF_MOVES[2], *REF_LIMITS)[1].duration == \
        pytest.approx(1.5, rel=1e-15)


def test_module_doctest():
    assert doctest.testmod(jerk_module).failed == 0


# --------------------------------------------------------------------------- the cases


def test_case_i_velocity_and_acceleration_reached():
    # v j = 2e5 >= a^2 = 4e4: t_j = a/j = 0.1, t_a = v/a - a/j = 0.4, t_acc = 0.6;
    # D = 200 >= v t_acc = 60: t_v = 200/100 - 0.6 = 1.4, T = 2.6
    p = time_optimal_profile(10.0, 200.0, 100.0, 200.0, 2000.0)
    assert p.t_j == pytest.approx(0.1, rel=1e-15)
    assert p.t_a == pytest.approx(0.4, rel=1e-14)
    assert p.t_v == pytest.approx(1.4, rel=1e-14)
    assert p.t_acc == pytest.approx(0.6, rel=1e-15)
    assert p.duration == pytest.approx(2.6, rel=1e-15) and p.duration == minimum_duration(
        200.0, 100.0, 200.0, 2000.0)
    assert (p.jerk, p.peak_acceleration, p.peak_velocity) == (2000.0, 200.0, 100.0)
    assert p.sample(1.3) == pytest.approx((110.0, 100.0, 0.0))  # the middle of the cruise
    # hand-integrated: phase 1 ends at 2000 * 0.1^3 / 6, with velocity 10 and acc 200
    assert p.sample(0.1) == pytest.approx((10.0 + 1 / 3, 10.0, 200.0), rel=1e-12)
    # end of the acceleration half: v_p t_acc / 2 = 30
    assert p.sample(0.6) == pytest.approx((40.0, 100.0, 0.0), rel=1e-12, abs=1e-9)
    assert distance_by_integration(p) == pytest.approx(200.0, rel=1e-9)
    assert_continuous(p, 100.0, 200.0, 2000.0)
    assert_profile_within_limits(p, 100.0, 200.0, 2000.0)


def test_case_ii_velocity_reached_acceleration_not():
    # v j = 1e4 < a^2 = 4e4: a pure jerk triangle, t_j = sqrt(v/j) = 1, a_p = 100,
    # t_acc = 2; D = 300 >= v t_acc = 200: t_v = 3 - 2 = 1, T = 5
    p = time_optimal_profile(0.0, 300.0, 100.0, 200.0, 100.0)
    assert (p.t_j, p.t_a, p.t_acc) == (1.0, 0.0, 2.0)
    assert p.t_v == pytest.approx(1.0, rel=1e-15)
    assert p.duration == 5.0 == minimum_duration(300.0, 100.0, 200.0, 100.0)
    assert (p.peak_acceleration, p.peak_velocity) == (100.0, 100.0)
    assert p.sample(1.0) == pytest.approx((100.0 / 6, 50.0, 100.0), rel=1e-12)
    assert p.sample(2.5) == pytest.approx((150.0, 100.0, 0.0), rel=1e-12)
    assert distance_by_integration(p) == pytest.approx(300.0, rel=1e-9)
    assert_continuous(p, 100.0, 200.0, 100.0)
    assert_profile_within_limits(p, 100.0, 200.0, 100.0)


def test_case_iii_a_acceleration_reached_no_cruise():
    # the reference's 45 deg: t_j = 0.1; v t_acc = 60 > 45 >= 2 a^3 / j^2 = 4:
    # D = a (t_j + t_a)(2 t_j + t_a)  ->  t_a = (sqrt(t_j^2 + 4 D / a) - 3 t_j) / 2
    t_a = (math.sqrt(0.01 + 4 * 45 / 200) - 0.3) / 2
    p = time_optimal_profile(0.0, 45.0, 100.0, 200.0, 2000.0)
    assert p.t_j == pytest.approx(0.1, rel=1e-15)
    assert p.t_a == pytest.approx(t_a, rel=1e-13) and p.t_a == pytest.approx(0.3269696, abs=1e-7)
    assert p.t_v == 0.0
    assert p.duration == pytest.approx(2 * (0.2 + t_a), rel=1e-15)
    assert p.duration == minimum_duration(45.0, 100.0, 200.0, 2000.0)
    assert p.peak_acceleration == 200.0
    assert p.peak_velocity == pytest.approx(200.0 * (0.1 + t_a), rel=1e-14)
    assert p.peak_velocity < 100.0
    assert p.sample(p.duration / 2) == pytest.approx((22.5, p.peak_velocity, 0.0), rel=1e-12,
                                                    abs=1e-9)
    assert distance_by_integration(p) == pytest.approx(45.0, rel=1e-9)
    assert_continuous(p, 100.0, 200.0, 2000.0)
    assert_profile_within_limits(p, 100.0, 200.0, 2000.0)


# a reachable before v (v j > a^2), or not (v = 5: v j = 1e4 < a^2 = 4e4, and
# D = 0.2 < v t_acc = 2 sqrt(v^3 / j) = 0.5)
@pytest.mark.parametrize("v_max,d", [(100.0, 1.0), (5.0, 0.2)])
def test_case_iii_b_neither_reached(v_max, d):
    # D < 2 a^3 / j^2 = 4 (and < v t_acc): t_a = 0, D = 2 j t_j^3, T = 4 t_j
    t_j = (d / (2 * 2000.0)) ** (1 / 3)
    p = time_optimal_profile(0.0, d, v_max, 200.0, 2000.0)
    assert p.t_j == pytest.approx(t_j, rel=1e-15)
    if d == 1.0:
        assert p.t_j == pytest.approx(0.0629960525)
    assert (p.t_a, p.t_v) == (0.0, 0.0)
    assert p.duration == pytest.approx(4 * t_j, rel=1e-15)
    assert p.duration == minimum_duration(d, v_max, 200.0, 2000.0)
    assert p.peak_acceleration == pytest.approx(2000.0 * t_j, rel=1e-15)
    assert p.peak_velocity == pytest.approx(2000.0 * t_j * t_j, rel=1e-15)
    assert p.peak_acceleration < 200.0 and p.peak_velocity < v_max
    assert distance_by_integration(p) == pytest.approx(d, rel=1e-9)
    assert_continuous(p, v_max, 200.0, 2000.0)
    assert_profile_within_limits(p, v_max, 200.0, 2000.0)


@pytest.mark.parametrize("v,a,j,d_boundary", [
    (100.0, 200.0, 2000.0, 60.0),  # D = v t_acc: (i) | (iii-a)
    (100.0, 200.0, 2000.0, 4.0),  # D = 2 a^3 / j^2: (iii-a) | (iii-b)
    (100.0, 200.0, 100.0, 200.0),  # D = 2 sqrt(v^3 / j): (ii) | (iii-b)
    (20.0, 200.0, 2000.0, 2 * math.sqrt(20.0 ** 3 / 2000.0)),  # v j = a^2: (i) | (ii) edge
])
def test_cases_meet_continuously_at_their_boundaries(v, a, j, d_boundary):
    below = minimum_duration(d_boundary * (1 - 1e-9), v, a, j)
    at = minimum_duration(d_boundary, v, a, j)
    above = minimum_duration(d_boundary * (1 + 1e-9), v, a, j)
    assert below <= at <= above
    assert above - below <= 1e-8 * at
    for d in (d_boundary * (1 - 1e-9), d_boundary, d_boundary * (1 + 1e-9)):
        p = time_optimal_profile(0.0, d, v, a, j)
        assert_continuous(p, v, a, j)
        assert_profile_within_limits(p, v, a, j)


def test_the_acceleration_limit_switches_at_v_j_equal_a_squared():
    # a just reachable (v j = a^2 (1 + 1e-9)) or just not: the same profile up to 1e-9
    for d in (1.0, 100.0):
        p1 = time_optimal_profile(0.0, d, 20.0, 200.0, 2000.0 * (1 + 1e-9))
        p2 = time_optimal_profile(0.0, d, 20.0, 200.0, 2000.0 * (1 - 1e-9))
        assert p1.duration == pytest.approx(p2.duration, rel=1e-8)
        assert p1.t_j == pytest.approx(p2.t_j, rel=1e-8)


def test_zero_distance():
    p = time_optimal_profile(3.0, 0.0, 1.0, 1.0, 1.0)
    assert p.duration == 0.0 == minimum_duration(0.0, 1.0, 1.0, 1.0)
    for t in (-1.0, 0.0, 1.0):
        assert p.sample(t) == (3.0, 0.0, 0.0)
    held = profile_with_duration(3.0, 0.0, 1.0, 1.0, 1.0, 2.0)
    assert held.duration == 2.0
    for t in np.linspace(-1.0, 3.0, 41):
        assert held.sample(float(t)) == (3.0, 0.0, 0.0)


def test_negative_distance_mirrors_positive():
    for d in (45.0, 200.0, 1.0, 300.0):
        pos = time_optimal_profile(5.0, d, 100.0, 200.0, 150.0)
        neg = time_optimal_profile(5.0, -d, 100.0, 200.0, 150.0)
        assert neg.duration == pos.duration
        assert (neg.jerk, neg.peak_acceleration, neg.peak_velocity) == (
            -pos.jerk, -pos.peak_acceleration, -pos.peak_velocity)
        for t in np.linspace(0.0, pos.duration, 101):
            pp, vp, ap = pos.sample(float(t))
            pn, vn, an = neg.sample(float(t))
            assert (pn - 5.0) == pytest.approx(-(pp - 5.0), abs=1e-12 * d)
            assert (vn, an) == (-vp, -ap)


def test_stretched_profile_is_the_time_scaled_minimal_one():
    v, a, j = 100.0, 200.0, 2000.0
    for d in (1.0, 45.0, 200.0):
        fast = time_optimal_profile(0.0, d, v, a, j)
        for k in (1.0, 1.5, 3.0):
            big_t = fast.duration * k
            slow = profile_with_duration(0.0, d, v, a, j, big_t)
            assert slow.duration == big_t
            lam = 1.0 / k
            assert slow.peak_velocity == pytest.approx(fast.peak_velocity * lam, rel=1e-14)
            assert slow.peak_acceleration == pytest.approx(fast.peak_acceleration * lam ** 2,
                                                           rel=1e-14)
            assert slow.jerk == pytest.approx(fast.jerk * lam ** 3, rel=1e-14)
            for t in np.linspace(0.0, fast.duration, 57):
                pf, vf, af = fast.sample(float(t))
                ps, vs, as_ = slow.sample(float(t) * k)
                assert ps == pytest.approx(pf, abs=1e-12 * d)
                assert vs == pytest.approx(vf * lam, abs=1e-12 * v)
                assert as_ == pytest.approx(af * lam ** 2, abs=1e-11 * a)
            assert_continuous(slow, v, a, j)
            assert_profile_within_limits(slow, v, a, j)


def test_profile_functions_check_their_input():
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="max_velocity"):
            minimum_duration(1.0, bad, 1.0, 1.0)
        with pytest.raises(ValueError, match="max_acceleration"):
            time_optimal_profile(0.0, 1.0, 1.0, bad, 1.0)
        with pytest.raises(ValueError, match="max_jerk"):
            profile_with_duration(0.0, 1.0, 1.0, 1.0, bad, 10.0)
    with pytest.raises(ValueError, match="distance"):
        minimum_duration(float("nan"), 1.0, 1.0, 1.0)
    t_min = minimum_duration(1.0, 1.0, 1.0, 1.0)
    with pytest.raises(ValueError, match="at least the minimum"):
        profile_with_duration(0.0, 1.0, 1.0, 1.0, 1.0, t_min * 0.999)
    with pytest.raises(ValueError, match="finite"):
        profile_with_duration(0.0, 1.0, 1.0, 1.0, 1.0, float("inf"))
    # a hair short (rounding in the caller) is the minimum itself
    p = profile_with_duration(0.0, 1.0, 1.0, 1.0, 1.0, t_min * (1 - 1e-13))
    assert p.duration == t_min


# --------------------------------------------------------------------------- properties

log_uniform = lambda lo, hi: st.floats(math.log10(lo), math.log10(hi)).map(  # noqa: E731
    lambda x: 10.0 ** x)


@st.composite
def axis_cases(draw):
    """start, signed distance (tiny, ordinary or huge), limits with extreme ratios."""
    kind = draw(st.sampled_from(["tiny", "ordinary", "ordinary", "huge"]))
    magnitude = draw({"tiny": log_uniform(1e-12, 1e-3), "ordinary": log_uniform(1e-3, 1e3),
                      "huge": log_uniform(1e3, 1e7)}[kind])
    distance = magnitude * draw(st.sampled_from([-1.0, 1.0]))
    start = draw(st.floats(-1e3, 1e3))
    v = draw(log_uniform(1e-3, 1e5))
    a = draw(log_uniform(1e-3, 1e6))
    j = draw(log_uniform(1e-3, 1e7))
    return start, distance, v, a, j


@PROPERTY
@given(axis_cases(), st.floats(1.0, 100.0))
def test_property_profiles_within_limits_exact_end_and_stretched(case, stretch):
    start, distance, v, a, j = case
    p = time_optimal_profile(start, distance, v, a, j)
    assert p.duration == minimum_duration(distance, v, a, j)
    assert p.duration > 0.0
    assert p.t_j > 0.0 and p.t_a >= 0.0 and p.t_v >= 0.0
    assert p.duration == pytest.approx(4 * p.t_j + 2 * p.t_a + p.t_v, rel=1e-12)
    # the phases are consistent: a_p = j t_j, v_p = a_p (t_j + t_a), D = v_p (t_acc + t_v)
    assert p.peak_acceleration == pytest.approx(p.jerk * p.t_j, rel=1e-12)
    assert p.peak_velocity == pytest.approx(p.peak_acceleration * (p.t_j + p.t_a), rel=1e-12)
    assert distance == pytest.approx(p.peak_velocity * (p.t_acc + p.t_v), rel=1e-12)
    # time-optimal: at least one limit is active in each half (jerk always is)
    assert abs(p.jerk) == j
    assert_profile_within_limits(p, v, a, j)
    assert_continuous(p, v, a, j)
    # stretched to a longer duration: exactly that long, within the limits
    big_t = p.duration * stretch
    q = profile_with_duration(start, distance, v, a, j, big_t)
    assert q.duration == big_t
    lam = p.duration / big_t
    assert abs(q.peak_velocity) <= v * lam * (1 + REL)
    assert abs(q.peak_acceleration) <= a * lam * lam * (1 + REL)
    assert abs(q.jerk) <= j * lam ** 3 * (1 + REL)
    assert_profile_within_limits(q, v, a, j)
    assert_continuous(q, v, a, j)


def brute_force_minimum(d: float, v: float, a: float, j: float, n: int = 600) -> float:
    """The shortest symmetric double-S with jerk +-j over ``d``, by exhaustive search over
    a grid of (t_j, t_a): ``a_p = j t_j <= a``, ``v_p = a_p (t_j + t_a) <= v``; one that
    covers less than ``d`` without cruise cruises at ``v_p`` for the rest, one that
    covers more is discarded. The grid spans ``t_j <= cbrt(d / 2j)`` (beyond it even
    ``t_a = 0`` covers more than ``d``) and ``t_a <= sqrt(d / a_p)`` (the acceleration
    half alone covers at least ``a_p t_a^2``)."""
    tj_top = min(a / j, math.sqrt(v / j), (d / (2 * j)) ** (1 / 3))
    tj = tj_top * np.linspace(0.0, 1.0, n + 1)[1:, None]
    a_p = j * tj
    ta_top = np.minimum(np.maximum(v / a_p - tj, 0.0), np.sqrt(d / a_p))
    ta = ta_top * np.linspace(0.0, 1.0, n + 1)[None, :]
    v_p = np.minimum(a_p * (tj + ta), v)
    t_acc = 2 * tj + ta
    covered = v_p * t_acc
    total = np.where(covered > d, np.inf, 2 * t_acc + (d - np.minimum(covered, d)) / v_p)
    return float(total.min())


@settings(derandomize=True, deadline=None, max_examples=60)
@given(axis_cases())
def test_property_brute_force_finds_nothing_faster(case):
    _start, distance, v, a, j = case
    d = abs(distance)
    best = minimum_duration(distance, v, a, j)
    brute = brute_force_minimum(d, v, a, j)
    assert brute >= best * (1 - 1e-12)
    # and the grid search comes close to it (its resolution)
    assert brute <= best * 1.02


def test_against_ruckig_single_axis():
    import ruckig  # (in the test extra: the comparison always runs)
    otg = ruckig.Ruckig(1)
    inp = ruckig.InputParameter(1)
    traj = ruckig.Trajectory(1)
    rng = random.Random(20240601)
    worst = 0.0
    for _ in range(200):
        kind = rng.choice(["tiny", "ordinary", "huge"])
        lo, hi = {"tiny": (-6, -2), "ordinary": (-2, 3), "huge": (3, 5)}[kind]
        d = 10 ** rng.uniform(lo, hi) * rng.choice((-1.0, 1.0))
        v, a, j = 10 ** rng.uniform(-1, 4), 10 ** rng.uniform(-1, 5), 10 ** rng.uniform(-1, 6)
        start = rng.uniform(-180.0, 180.0)
        inp.current_position, inp.target_position = [start], [start + d]
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = [v], [a], [j]
        assert otg.calculate(inp, traj) == ruckig.Result.Working
        ours = minimum_duration(d, v, a, j)
        assert ours == pytest.approx(traj.duration, abs=1e-6, rel=1e-9), (d, v, a, j)
        worst = max(worst, abs(ours - traj.duration))
        # and the same trajectory, sampled: position, velocity, acceleration
        p = time_optimal_profile(start, d, v, a, j)
        for t in np.linspace(0.0, ours, 7):
            mine = p.sample(float(t))
            theirs = [x[0] for x in traj.at_time(min(float(t), traj.duration))]
            assert mine == pytest.approx(theirs, rel=1e-6, abs=1e-6 * (abs(d) + v + a))
    assert worst < 1e-6


def test_against_ruckig_six_axes_time_synchronised():
    import ruckig  # (in the test extra: the comparison always runs)
    otg = ruckig.Ruckig(6)
    inp = ruckig.InputParameter(6)
    traj = ruckig.Trajectory(6)
    rng = random.Random(7)
    for _ in range(100):
        start = [rng.uniform(-180, 180) for _ in range(6)]
        target = [rng.uniform(-180, 180) for _ in range(6)]
        v = [rng.uniform(10, 600) for _ in range(6)]
        a = [rng.uniform(20, 2000) for _ in range(6)]
        j = [rng.uniform(100, 20000) for _ in range(6)]
        inp.current_position, inp.target_position = start, target
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = v, a, j
        assert otg.calculate(inp, traj) == ruckig.Result.Working
        _, ours, _ = jerk_plan(start, target, v, a, j, "time")
        assert ours.duration == pytest.approx(traj.duration, abs=1e-9)
        _, line, _ = jerk_plan(start, target, v, a, j, "line")
        assert line.duration >= traj.duration - 1e-9


# --------------------------------------------------------------------------- the planner


def test_result_of_nothing_to_move_is_finished():
    for sync in ("line", "time"):
        result, traj, message = jerk_plan((1.0, 2.0), (1.0, 2.0), (1.0, 1.0), (1.0, 1.0),
                                              (1.0, 1.0), sync)
        assert (result, message) == (Result.FINISHED, "")
        assert traj.duration == 0.0 and traj.degrees_of_freedom == 2
        assert traj.sample(0.0) == ((1.0, 2.0), (0.0, 0.0))
        assert traj.sample(1.0) == ((1.0, 2.0), (0.0, 0.0))
        assert traj.sample_accelerations(0.5) == (0.0, 0.0)
        assert [p.duration for p in traj.profiles] == [0.0, 0.0]


NAN, INF = float("nan"), float("inf")
GOOD = dict(start=(0.0,) * 6, target=(10.0,) * 6, v_max=(5.0,) * 6, a_max=(20.0,) * 6,
            j_max=(100.0,) * 6)


def with_axis(name, axis, value):
    values = list(GOOD[name])
    values[axis - 1] = value
    return {**GOOD, name: tuple(values)}


INVALID = [
    (with_axis("target", 2, NAN), "axis 2: target_position must be finite, got nan"),
    (with_axis("start", 6, -INF), "axis 6: current_position must be finite, got -inf"),
    (with_axis("v_max", 4, NAN), "axis 4: max_velocity must be finite, got nan"),
    (with_axis("v_max", 1, INF), "axis 1: max_velocity must be finite, got inf"),
    (with_axis("v_max", 5, -2.5), "axis 5: max_velocity must be positive, got -2.5"),
    (with_axis("a_max", 3, 0.0), "axis 3: max_acceleration must be positive, got 0"),
    (with_axis("a_max", 2, -1e-300), "axis 2: max_acceleration must be positive, got -1e-300"),
    (with_axis("j_max", 3, 0), "axis 3: max_jerk must be positive, got 0"),
    (with_axis("j_max", 6, INF), "axis 6: max_jerk must be finite, got inf"),
    (with_axis("j_max", 1, NAN), "axis 1: max_jerk must be finite, got nan"),
    (with_axis("a_max", 1, "fast"), "axis 1: max_acceleration must be a number, got 'fast'"),
    (with_axis("j_max", 4, True), "axis 4: max_jerk must be a number, got True"),
    (with_axis("target", 6, None), "axis 6: target_position must be a number, got None"),
    ({**GOOD, "target": (1.0,) * 5}, "axis 6: target_position has 5 axes, current_position has 6"),
    ({**GOOD, "v_max": (1.0,) * 7}, "axis 7: max_velocity has 7 axes, current_position has 6"),
    ({**GOOD, "j_max": ()}, "axis 1: max_jerk has 0 axes, current_position has 6"),
    ({**GOOD, "v_max": None}, "max_velocity must be a sequence of numbers, one per axis, got None"),
    ({**GOOD, "j_max": 3.0}, "max_jerk must be a sequence of numbers, one per axis, got 3.0"),
    ({"start": (), "target": (), "v_max": (), "a_max": (), "j_max": ()},
     "current_position must have at least one axis, got 0"),
]


@pytest.mark.parametrize("fields,message", INVALID)
@pytest.mark.parametrize("sync", ["line", "time"])
def test_invalid_input_is_an_error_result_never_an_exception(fields, message, sync):
    result = jerk_plan(fields["start"], fields["target"], fields["v_max"], fields["a_max"],
                           fields["j_max"], sync)
    assert result == (Result.ERROR_INVALID_INPUT, None, message)


def test_invalid_synchronization_and_junk():
    assert jerk_plan(*GOOD.values(), "phase") == (
        Result.ERROR_INVALID_INPUT, None, "synchronization must be 'line', 'time' or 'auto', got 'phase'")
    for junk in (None, 42, "move", object()):
        result, traj, message = jerk_plan(junk, junk, junk, junk, junk)
        assert result == Result.ERROR_INVALID_INPUT and traj is None and message


@pytest.mark.parametrize("sync", ["line", "time"])
def test_limits_too_small_for_the_distance(sync):
    result, traj, message = jerk_plan((0.0, 0.0), (1e6, 1.0), (1e-3, 1.0), (1.0, 1.0),
                                          (1.0, 1.0), sync)
    assert result == Result.ERROR_LIMITS and traj is None
    assert message.startswith("axis 1: the move needs ") and f"{MAX_DURATION:g}" in message
    assert "max_jerk 1," in message and "distance 1000000)" in message
    assert jerk_plan((0.0,), (1e308,), (1e-308,), (1e-308,), (1e-308,), sync)[0] == \
        Result.ERROR_LIMITS
    result, traj, message = jerk_plan((-1e308,), (1e308,), (1.0,), (1.0,), (1.0,), sync)
    assert result == Result.ERROR_INVALID_INPUT
    assert message == "axis 1: target_position - current_position overflows, got 1e+308 - -1e+308"


def test_ints_and_lists_are_accepted_like_floats():
    a = jerk_plan([0, 0, 0], [45, 0, -45], [100, 100, 100], [200, 200, 200],
                      [2000, 2000, 2000])
    b = jerk_plan((0.0, 0.0, 0.0), (45.0, 0.0, -45.0), (100.0,) * 3, (200.0,) * 3,
                      (2000.0,) * 3)
    assert a[0] == b[0] == Result.WORKING and a[1].duration == b[1].duration
    assert a[1].sample(0.3) == b[1].sample(0.3)
    assert all(type(x) is float for x in a[1].sample(0.3)[0] + a[1].target_position)


def test_subnormal_distances_are_no_motion_and_end_exactly_at_the_target():
    start = (0.0, 0.0, 0.0, 5e-324, 0.0, 0.0)
    lim = ((15.0,) * 6, (40.0,) * 6, (400.0,) * 6)
    for sync in ("line", "time"):
        result, traj, _ = jerk_plan(start, (0.0,) * 6, *lim, sync)
        assert result == Result.FINISHED and traj.sample(traj.duration) == ((0.0,) * 6,) * 2
        target = (0.0, 0.0, 0.0, 0.0, 0.0, 25.0)
        result, traj, _ = jerk_plan(start, target, *lim, sync)
        assert traj.start_position == (0.0,) * 6  # the still axis starts at its target
        pos, vel = traj.sample(traj.duration / 2)
        assert pos[3] == 0.0 and vel[3] == 0.0 and vel[5] > 0.0
        assert traj.sample(traj.duration)[0] == target


def test_time_synchronisation_is_not_a_straight_line_in_general():
    """The reference's second move: the 45 deg axis stretched to 1.5 s keeps its own
    no-cruise shape, the 90 deg axes cruise: "time" leaves the joint-space line, "line"
    does not (here at no cost: all limits are equal)."""
    start, target = REF_MOVES[1], REF_MOVES[2]
    _, timed, _ = jerk_plan(start, target, *REF_LIMITS, "time")
    _, line, _ = jerk_plan(start, target, *REF_LIMITS, "line")
    assert timed.duration == line.duration == 1.5
    d = np.subtract(target, start)[:3]
    worst_time = worst_line = 0.0
    for t in np.linspace(0.0, 1.5, 301):
        for traj, name in ((timed, "time"), (line, "line")):
            progress = (np.subtract(traj.sample(float(t))[0], start)[:3]) / d
            spread = float(progress.max() - progress.min())
            if name == "time":
                worst_time = max(worst_time, spread)
            else:
                worst_line = max(worst_line, spread)
    assert worst_time > 0.01 and worst_line < 1e-12


def test_line_costs_time_when_the_axes_are_bound_by_different_limits():
    # axis 1 velocity-bound, axis 2 jerk-bound: no shape is time-optimal for both
    start, target = (0.0, 0.0), (90.0, 10.0)
    v, a, j = (100.0, 100.0), (200.0, 200.0), (2000.0, 130.0)
    _, timed, _ = jerk_plan(start, target, v, a, j, "time")
    _, line, _ = jerk_plan(start, target, v, a, j, "line")
    assert timed.duration == pytest.approx(1.5, rel=1e-15)  # axis 1's own minimum
    assert line.duration > timed.duration + 0.01
    # and it is the unit-distance optimum under V = min v_i/|d_i|, A, J likewise
    assert line.duration == minimum_duration(1.0, min(100 / 90, 100 / 10),
                                             min(200 / 90, 200 / 10), min(2000 / 90, 130 / 10))


position = st.floats(-180.0, 180.0, allow_nan=False)


@st.composite
def six_axis_moves(draw):
    """Six axes: random start, target (some axes still or tiny), limits within wide
    plausible ranges; some axes scaled copies of others (equal shapes: ties)."""
    start, target, v, a, j = [], [], [], [], []
    for i in range(6):
        s = draw(position)
        kind = draw(st.sampled_from(["move", "move", "move", "still", "tiny", "clone"]))
        if kind == "clone" and i > 0:
            k_axis = draw(st.integers(0, i - 1))
            k = draw(st.floats(0.1, 3.0))
            d = (target[k_axis] - start[k_axis]) * k
            start.append(s)
            target.append(s + d)
            v.append(v[k_axis] * k or 1.0)
            a.append(a[k_axis] * k or 1.0)
            j.append(j[k_axis] * k or 1.0)
            continue
        start.append(s)
        if kind == "still":
            target.append(s)
        elif kind == "tiny":
            target.append(s + draw(st.floats(-1e-6, 1e-6)))
        else:
            target.append(draw(position))
        v.append(draw(log_uniform(5.0, 1000.0)))
        a.append(draw(log_uniform(10.0, 5000.0)))
        j.append(draw(log_uniform(50.0, 1e5)))
    return tuple(start), tuple(target), tuple(v), tuple(a), tuple(j)


def check_trajectory(move, sync) -> JerkPtpTrajectory:
    start, target, v, a, j = move
    result, traj, message = jerk_plan(start, target, v, a, j, sync)
    assert result in (Result.WORKING, Result.FINISHED), message
    assert traj.synchronization == sync
    n = len(start)
    distances = np.subtract(target, start)
    moving = np.abs(distances) >= DISTANCE_EPSILON
    minima = [minimum_duration(d if m else 0.0, *lim)
              for d, m, lim in zip(distances, moving, zip(v, a, j))]
    k = traj.slowest_axis
    assert minima[k] == max(minima)
    if sync == "time":
        assert traj.duration == max(minima)
        best = time_optimal_profile(traj.start_position[k], target[k] - start[k], v[k], a[k],
                                    j[k]) if moving[k] else None
        if best is not None:
            slow = traj.profiles[k]
            assert (slow.t_j, slow.t_acc, slow.duration, slow.jerk) == (
                best.t_j, best.t_acc, best.duration, best.jerk)
    else:
        assert traj.duration >= max(minima) * (1 - 1e-12)
    times = np.linspace(0.0, traj.duration, N_SAMPLES)
    pos, vel = (np.array(x) for x in zip(*(traj.sample(float(t)) for t in times)))
    acc = np.array([traj.sample_accelerations(float(t)) for t in times])
    # start together, stop together, exactly at the targets
    assert traj.sample(0.0) == (traj.start_position, (0.0,) * n)
    assert traj.sample(-1.0) == (traj.start_position, (0.0,) * n)
    assert traj.sample(traj.duration) == (target, (0.0,) * n)
    assert traj.sample(traj.duration + 1.0) == (target, (0.0,) * n)
    assert np.all(np.abs(np.subtract(traj.start_position, start)) < DISTANCE_EPSILON)
    inside = slice(1, N_SAMPLES - 1)
    if traj.duration > 0.0:
        assert np.all(np.abs(vel[inside][:, moving]) > 0.0)
    assert np.all(vel[:, ~moving] == 0.0)
    assert np.all(pos[:, ~moving] == np.array(target)[~moving])
    # within every axis's limits, analytically and by finite differences
    v_max, a_max, j_max = np.array(v), np.array(a), np.array(j)
    assert np.all(np.abs(vel) <= v_max * (1 + REL))
    assert np.all(np.abs(acc) <= a_max * (1 + REL))
    for p, jm in zip(traj.profiles, j_max):
        assert abs(p.jerk) <= jm * (1 + REL) and p.duration == traj.duration
    if traj.duration > 0.0:
        dt = traj.duration / (N_SAMPLES - 1)
        scale = np.abs(pos).max(axis=0) + 1.0
        assert np.all(np.abs(np.diff(pos, axis=0)) / dt <= v_max * (1 + REL) + 8 * EPS * scale / dt)
        fd_jerk = np.abs(np.diff(acc, axis=0)) / dt
        assert np.all(fd_jerk <= j_max * (1 + REL) + 8 * EPS * (a_max + j_max * traj.duration) / dt)
        # monotonic towards the target on every axis
        steps = np.diff(pos, axis=0) * np.sign(distances)
        assert np.all(steps >= -8 * EPS * scale)
    # the trajectory's inlined sampling agrees with its profiles' sample()
    for t, p_row, v_row in zip(times[::50], pos[::50], vel[::50]):
        by_profile = np.array([p.sample(float(t))[:2] for p in traj.profiles])
        assert np.allclose(p_row, by_profile[:, 0], rtol=0, atol=1e-12 * (np.abs(p_row).max() + 1))
        assert np.allclose(v_row, by_profile[:, 1], rtol=1e-12, atol=1e-12 * v_max.max())
    return traj, pos, moving


@PLANNER_PROPERTY
@given(six_axis_moves())
def test_property_line_synchronised_moves_stay_on_the_joint_space_line(move):
    traj, pos, moving = check_trajectory(move, "line")
    start, target = np.array(traj.start_position), np.array(move[1])
    if not moving.any():
        return
    d = (target - start)[moving]
    progress = (pos[:, moving] - start[moving]) / d
    # 1e-9 plus the rounding of the positions themselves, relative to each distance
    tolerance = 1e-9 + 4 * EPS * (np.abs(start[moving]) + np.abs(target[moving])) / np.abs(d)
    spread = np.abs(progress - progress[:, :1])
    assert np.all(spread <= tolerance + tolerance[:1])
    # the normalised progress runs from 0 to 1 monotonically
    assert np.all(np.abs(progress[0]) <= tolerance)
    assert np.all(np.abs(progress[-1] - 1) <= tolerance)
    assert np.all(np.diff(progress, axis=0) >= -tolerance)
    # axes that move at least 1 deg: literally within 1e-9
    big = np.abs(d) >= 1.0
    if big.any():
        p_big = progress[:, big]
        assert np.all(np.abs(p_big - p_big[:, :1]) <= 1e-9)
    # the duration is the unit-distance optimum under the tightest ratios of limits
    v, a, j = (np.array(x)[moving] / np.abs(d) for x in move[2:])
    assert traj.duration == minimum_duration(1.0, float(v.min()), float(a.min()),
                                             float(j.min()))


@PLANNER_PROPERTY
@given(six_axis_moves())
def test_property_time_synchronised_moves(move):
    check_trajectory(move, "time")


@PLANNER_PROPERTY
@given(six_axis_moves(), st.floats(0.05, 1.0), st.floats(0.05, 1.0), st.floats(0.05, 1.0))
def test_property_equal_shapes_cost_the_line_nothing(move, fv, fa, fj):
    """With limits in the same ratio on every axis (the reference's case), the
    straight line is as fast as the fastest synchronised move."""
    start, target = move[0], move[1]
    v, a, j = (156.0 * fv,) * 6, (400.0 * fa,) * 6, (4000.0 * fj,) * 6
    _, line, _ = jerk_plan(start, target, v, a, j, "line")
    _, timed, _ = jerk_plan(start, target, v, a, j, "time")
    assert line.duration == pytest.approx(timed.duration, rel=1e-12, abs=1e-15)


def test_sample_of_line_and_time_with_other_axis_counts():
    # the unrolled six-axis path and the general loop agree
    for n in (1, 2, 6, 7):
        start = tuple(float(i) for i in range(n))
        target = tuple(10.0 * (i + 1) * (-1) ** i for i in range(n))
        lim = ((50.0,) * n, (100.0,) * n, (1000.0,) * n)
        for sync in ("line", "time"):
            _, traj, _ = jerk_plan(start, target, *lim, sync)
            for t in np.linspace(0.0, traj.duration, 23):
                pos, vel = traj.sample(float(t))
                assert len(pos) == len(vel) == n
                by_profile = [p.sample(float(t)) for p in traj.profiles]
                assert pos == pytest.approx([x[0] for x in by_profile], abs=1e-12)
                assert vel == pytest.approx([x[1] for x in by_profile], abs=1e-12)
            assert traj.sample(traj.duration) == (target, (0.0,) * n)
            assert "JerkPtpTrajectory(" in repr(traj) and "JerkProfile(" in repr(traj.profiles[0])


def test_every_case_occurs_and_ends_exactly_over_many_random_axes():
    """The four closed-form cases all occur over the property's ranges; each profile's
    phases are consistent and it ends exactly at its target."""
    rng = random.Random(11)
    seen = set()
    for _ in range(5000):
        d = 10 ** rng.uniform(-12, 7) * rng.choice((-1.0, 1.0))
        v, a, j = 10 ** rng.uniform(-3, 5), 10 ** rng.uniform(-3, 6), 10 ** rng.uniform(-3, 7)
        p = time_optimal_profile(1.5, d, v, a, j)
        cruise, const_acc = p.t_v > 0.0, p.t_a > 0.0
        seen.add({(True, True): "i", (True, False): "ii", (False, True): "iii-a",
                  (False, False): "iii-b"}[(cruise, const_acc)])
        assert p.sample(p.duration) == (1.5 + d, 0.0, 0.0)
        assert abs(p.peak_velocity) <= v * (1 + REL) and abs(p.peak_acceleration) <= a * (1 + REL)
        assert p.duration == minimum_duration(d, v, a, j)
        assert d == pytest.approx(p.peak_velocity * (p.t_acc + p.t_v), rel=1e-12)
    assert seen == {"i", "ii", "iii-a", "iii-b"}


extreme = st.floats(-1e300, 1e300, allow_nan=False)
extreme_limit = st.floats(1e-300, 1e300)


@settings(derandomize=True, deadline=None, max_examples=examples(300))
@given(st.integers(1, 3).flatmap(lambda n: st.tuples(
    *(st.lists(x, min_size=n, max_size=n).map(tuple)
      for x in (extreme, extreme, extreme_limit, extreme_limit, extreme_limit)))),
    st.sampled_from(["line", "time"]))
def test_property_extreme_input_never_raises_nor_samples_non_finite(args, sync):
    result, traj, message = jerk_plan(*args, sync)
    assert result in (Result.WORKING, Result.FINISHED, Result.ERROR_LIMITS,
                      Result.ERROR_INVALID_INPUT), message
    if traj is not None:
        assert 0.0 <= traj.duration <= MAX_DURATION
        for x in (0.0, 0.1, 0.5, 0.9, 1.0):
            pos, vel = traj.sample(traj.duration * x)
            assert all(math.isfinite(y) for y in pos + vel)
            assert all(math.isfinite(y) for y in traj.sample_accelerations(traj.duration * x))
        assert traj.sample(traj.duration)[0] == tuple(args[1])


@settings(max_examples=examples(200), deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.floats(-180, 180), st.floats(5, 300), st.floats(20, 2000), st.floats(200, 20000)),
                min_size=6, max_size=6))
def test_property_auto_is_time_optimal_and_a_straight_line_when_that_is_free(axes):
    start = (0.0,) * 6
    target = tuple(d for d, _v, _a, _j in axes)
    limits = [tuple(x[k] for x in axes) for k in (1, 2, 3)]
    r_auto, auto, _ = jerk_plan(start, target, *limits, synchronization="auto")
    r_time, timed, _ = jerk_plan(start, target, *limits, synchronization="time")
    r_line, line, _ = jerk_plan(start, target, *limits, synchronization="line")
    assert r_auto == r_time == r_line
    if auto is None:
        return
    assert auto.duration == pytest.approx(timed.duration, rel=1e-12, abs=1e-12)  # never slower
    if line.duration <= timed.duration * (1 + 1e-12):  # the line is free: auto takes it
        assert auto.synchronization == "line"


@settings(max_examples=examples(300), deadline=None, derandomize=True)
@given(st.floats(0.0, 500.0), st.floats(-300.0, 300.0), st.floats(1.0, 400.0), st.floats(10.0, 5000.0))
def test_property_jerk_stop_comes_to_rest_within_the_limits(v0, a0, a_max, j_max):
    """The stop from (v0, a0): never backwards, ends at rest at `distance`, |a| within
    max(a_max, |a0|), and the jerk within j_max (by differences of the acceleration)."""
    from runtime.motion.stops import JerkStop

    a0 = max(min(a0, a_max), -a_max)
    stop = JerkStop(v0, a0, a_max, j_max)
    assert stop.sample(stop.duration + 1.0) == (stop.distance, 0.0, 0.0)
    if stop.duration == 0.0:
        return
    ts = np.linspace(0.0, stop.duration, 4001)
    s, v, a = np.array([stop.sample(float(t)) for t in ts]).T
    assert v.min() >= -1e-9 * max(1.0, v0)
    assert np.all(np.diff(s) >= -1e-9 * max(1.0, stop.distance))
    assert np.abs(a).max() <= a_max * (1 + 1e-9) + 1e-9
    degenerate = a0 < 0 and v0 < a0 * a0 / (2 * j_max)  # ends when v = 0, before a = 0
    if not degenerate:
        assert s[-1] == pytest.approx(stop.distance, rel=1e-9, abs=1e-12)
        jerk = np.abs(np.diff(a)) / (ts[1] - ts[0])
        assert jerk.max() <= j_max * (1 + 1e-3)  # the last grid step meets the exact end (rounding)
