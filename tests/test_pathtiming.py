"""Local slowdown of Cartesian moves (runtime/motion/pathtiming.py, issue 14): the
profile along a path with a speed limit that varies along it, and lin moves that slow
down only where the joints need it."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from runtime.motion.cartesian import CartesianInput, JOINT_LIMIT_SHARE, plan_cartesian
from runtime.motion.kinematics import Kinematics
from runtime.motion.pathcheck import check_path
from runtime.motion.paths import CartesianMove, LinPath
from runtime.motion.pathtiming import (
    ConstantSpeed,
    PathProfile,
    WarpedProfile,
    _build,
    joint_ratios,
    nominal_profile,
    path_derivatives,
    uniform_scale,
    warped_profile,
)
from runtime.motion.jerk import time_optimal_profile
from runtime.motion.reachability import AveragedProfile

from conftest import ROOT, SPEC, examples
KIN = Kinematics(SPEC)
AXES = SPEC.main_axes
LIMITS = ([a.max_velocity for a in AXES], [a.max_acceleration for a in AXES], [a.max_jerk for a in AXES])


@st.composite
def segments(draw):
    """(length, bounds, tops, accs, jerks): 1-8 segments of 0.5-200 mm, each with its own
    speed limit, path acceleration and jerk."""
    m = draw(st.integers(1, 8))
    lengths = [draw(st.floats(0.5, 200.0)) for _ in range(m)]
    bounds = [0.0]
    for x in lengths[:-1]:
        bounds.append(bounds[-1] + x)
    tops = [draw(st.floats(1.0, 1000.0)) for _ in range(m)]
    accs = [draw(st.floats(10.0, 5000.0)) for _ in range(m)]
    jerks = [draw(st.floats(100.0, 50000.0)) for _ in range(m)]
    return sum(lengths), bounds, tops, accs, jerks


@settings(max_examples=examples(300), deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
@given(segments())
def test_property_the_profile_keeps_each_segments_limits_from_rest_to_rest(drawn):
    """Whatever the segments, the profile runs from rest at 0 to rest at the length, never
    backwards, continuous in speed and acceleration, and within every segment's speed
    limit, acceleration and jerk wherever it is (a change of speed never crosses into a
    slower segment)."""
    length, bounds, tops, accs, jerks = drawn
    profile = _build(length, bounds, tops, accs, jerks)
    assert profile.duration > 0.0
    times = np.concatenate([np.linspace(0.0, profile.duration, 4001), np.asarray(profile._t) + 1e-12,
                            np.asarray(profile._t) - 1e-12])
    times = np.sort(np.clip(times, 0.0, profile.duration))
    s, v, a, j = profile.states(times)
    assert s[0] == 0.0 and s[-1] == length and v[-1] == 0.0
    assert np.all(np.diff(s) >= -1e-9 * length)
    assert np.all(v >= -1e-9 * max(tops))
    # the state at the end of the last piece is rest at the length
    end = profile.sample(profile.duration * (1.0 - 1e-12))
    assert abs(end[0] - length) <= 1e-6 * length + 1e-9 and abs(end[1]) <= 1e-6 * max(tops)
    segment = np.clip(np.searchsorted(bounds, s, side="right") - 1, 0, len(bounds) - 1)
    assert np.all(v <= np.asarray(tops)[segment] * (1.0 + 1e-9) + 1e-9)
    # acceleration and jerk: each piece lies in one segment and keeps its limits (at both ends)
    starts, ends = np.asarray(profile._s), np.append(np.asarray(profile._s)[1:], length)
    durations = np.diff(np.append(profile._t, profile.duration))
    for s0, s1, a0, j0, dt in zip(starts, ends, profile._a, profile._j, durations):
        first = min(max(int(np.searchsorted(bounds, 0.5 * (s0 + s1), side="right")) - 1, 0), len(bounds) - 1)
        end = bounds[first + 1] if first + 1 < len(bounds) else length
        assert bounds[first] - 1e-7 * length <= s0 and s1 <= end + 1e-7 * length, (s0, s1, bounds)
        for acc in (a0, a0 + j0 * dt):
            assert abs(acc) <= accs[first] * (1.0 + 1e-9) + 1e-9
        assert abs(j0) <= jerks[first] * (1.0 + 1e-9)
    # continuity: speed and acceleration at every piece boundary
    for i in range(1, len(profile._t)):
        before = profile.states(np.asarray([profile._t[i] - 1e-9]))
        after = profile.states(np.asarray([profile._t[i]]))
        assert abs(before[1][0] - after[1][0]) <= 1e-6 * max(tops) + 1e-9
        assert abs(before[2][0] - after[2][0]) <= 1e-4 * max(accs) + 1e-6 * max(jerks)


@settings(max_examples=examples(100), deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
@given(segments(), st.floats(0.05, 1.0))
def test_property_times_at_inverts_the_profile_and_scaling_slows_it_down(drawn, k):
    length, bounds, tops, accs, jerks = drawn
    profile = _build(length, bounds, tops, accs, jerks)
    s = np.linspace(0.0, length, 257)
    times = profile.times_at(s)
    assert np.all(np.diff(times) >= 0.0)
    assert np.max(np.abs(profile.sample_many(times) - s)) <= 1e-6 * length
    slow = profile.scaled(k)
    assert math.isclose(slow.duration, profile.duration / k, rel_tol=1e-12)
    for t in np.linspace(0.0, profile.duration, 37):
        fast_s, fast_v, fast_a = profile.sample(t)
        slow_s, slow_v, slow_a = slow.sample(t / k)
        assert math.isclose(slow_s, fast_s, rel_tol=1e-9, abs_tol=1e-9)
        assert math.isclose(slow_v, fast_v * k, rel_tol=1e-9, abs_tol=1e-9)
        assert math.isclose(slow_a, fast_a * k * k, rel_tol=1e-9, abs_tol=1e-6)


def test_one_segment_at_the_programmed_limits_is_the_time_optimal_double_s():
    for length, speed, acc, jerk in ((300.0, 250.0, 1500.0, 15000.0), (2.0, 1000.0, 5000.0, 50000.0),
                                     (80.0, 100.0, 500.0, 5000.0)):
        ours, theirs = nominal_profile(length, speed, acc, jerk), time_optimal_profile(0.0, length, speed, acc, jerk)
        assert math.isclose(ours.duration, theirs.duration, rel_tol=1e-9)
        for t in np.linspace(0.0, ours.duration, 101):
            assert np.allclose(ours.sample(t), theirs.sample(t), rtol=1e-7, atol=1e-7)


# a lin that starts 7 deg from the wrist singularity and runs away from it (found by
# benchmarks/lin_limits.py: 3x faster than the move slowed down as a whole)
NEAR_WRIST = (8.935, 34.423, -65.86, 9.993, 7.213, -84.805)
AWAY = (1347.193, 492.812, 1365.021, 55.56, 4.094, 87.277)


def test_a_lin_move_slows_down_only_where_the_joints_need_it():
    _, stream, message = plan_cartesian(CartesianInput(KIN, NEAR_WRIST, AWAY, 500.0, 1500.0, axis_limits=SPEC))
    assert stream is not None, message
    move = stream.checked.move
    assert isinstance(move.profile, PathProfile)
    # the same path slowed down as a whole: the one factor from the same samples
    along = check_path(CartesianMove(move.path, 500.0, 1500.0, profile=ConstantSpeed(move.path.length)),
                       KIN, NEAR_WRIST, SPEC, check_velocity=False)
    s, joints = np.asarray(along.times), np.asarray(along.joints)
    k, _fastest = uniform_scale(s, path_derivatives(s, joints), LIMITS, 500.0, 1500.0, 15000.0, JOINT_LIMIT_SHARE)
    uniform = time_optimal_profile(0.0, move.path.length, 500.0 * k, 1500.0 * k * k, 15000.0 * k ** 3).duration
    assert stream.duration < 0.5 * uniform, (stream.duration, uniform)
    # slow near the singularity, at the programmed speed away from it; every joint within its limits
    speeds = [move.sample_with_speed(t)[1] for t in np.linspace(0.0, stream.duration, 400)]
    fractions = [move.fraction(t) for t in np.linspace(0.0, stream.duration, 400)]
    near = min(v for v, f in zip(speeds, fractions) if 0.01 < f < 0.2)  # (the slowest, by the singularity)
    assert max(speeds) > 5.0 * near and max(speeds) <= 500.0 * (1.0 + 1e-9), (near, max(speeds))
    from test_cartesian import setpoint_ratios
    assert max(setpoint_ratios(stream)) <= 1.0


def test_a_move_the_joints_do_not_limit_keeps_the_programmed_profile():
    q0 = (0.0, -20.0, 30.0, 0.0, 60.0, 0.0)
    start = KIN.forward(q0)
    target = (start[0] + 50.0,) + start[1:]
    _, stream, message = plan_cartesian(CartesianInput(KIN, q0, target, 100.0, 500.0, axis_limits=SPEC))
    assert stream is not None, message
    assert not isinstance(stream.checked.move.profile, PathProfile)
    assert math.isclose(stream.duration, CartesianMove(LinPath(start, target), 100.0, 500.0).duration, rel_tol=1e-12)


def _ratios(positions, period: float) -> list[float]:
    out, d = [], np.asarray(positions, dtype=float)
    for limit in LIMITS:
        d = np.diff(d, axis=0) / period
        out.append(float(np.max(np.abs(d) / np.asarray(limit))))
    return out


def _stopped(stream, steps: int, period: float, setpoints: list):
    """Stop ``stream`` at its setpoint ``steps`` (sampled up to it into ``setpoints``):
    the stop's setpoints every ``period`` appended, then three more at rest; the stop."""
    q, v = stream.sample(steps * period)
    stop = stream.stop(steps * period, q, v)
    i = 1
    while True:
        setpoints.append(stop.sample(i * period)[0][:6])
        if i * period >= stop.duration:
            break
        i += 1
    setpoints += [setpoints[-1]] * 3
    return stop


def test_a_stop_on_a_locally_slowed_path_keeps_every_limit_and_sampling_again_starts_afresh():
    """A pause anywhere along a move slowed near the wrist singularity stops on the path
    within the limits of the stretch it runs through; the stream, sampled again from its
    start after a stop, gives the same joints as a fresh one (it once extrapolated from
    the joints of the last run: a 360 deg jump of A4)."""
    _, stream, message = plan_cartesian(CartesianInput(KIN, NEAR_WRIST, AWAY, 500.0, 1500.0, axis_limits=SPEC))
    assert stream is not None, message
    _, fresh, _ = plan_cartesian(CartesianInput(KIN, NEAR_WRIST, AWAY, 500.0, 1500.0, axis_limits=SPEC))
    period = 0.005
    for fraction in (0.05, 0.2, 0.5, 0.7, 0.85):
        steps = int(fraction * stream.duration / period)
        setpoints = [stream.sample(i * period)[0][:6] for i in range(steps + 1)]
        assert setpoints[-1] == fresh.sample(steps * period)[0][:6] or np.allclose(
            setpoints[-1], fresh.position_at(steps * period)[:6], atol=1e-9)
        stop = _stopped(stream, steps, period, setpoints)
        assert stop.fault is None
        assert max(_ratios(setpoints, period)) <= 1.0, (fraction, _ratios(setpoints, period))


# ---- the time warp --------------------------------------------------------------------------


def _drawn_path(seed: int):
    """A lin/circ move as benchmarks/lin_limits.py draws them (half near the wrist
    singularity), checked at uniform steps: (move, s, joints), or None."""
    import random
    import sys
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import lin_limits
    from runtime.motion.paths import CircPath

    rng = random.Random(seed)
    for _ in range(50):
        drawn = lin_limits.random_move(rng, KIN, SPEC, rng.random() < 0.5)
        if drawn is None:
            continue
        q0, kind, args = drawn
        start = KIN.forward(q0)
        path = LinPath(start, args[0]) if kind == "lin" else CircPath(start, args[0], args[1])
        speed, acc = args[-2], args[-1]
        try:
            along = check_path(CartesianMove(path, speed, acc, profile=ConstantSpeed(path.length)), KIN, q0, SPEC,
                               check_velocity=False)
        except ValueError:
            continue
        return CartesianMove(path, speed, acc), np.asarray(along.times), np.asarray(along.joints)
    return None


@settings(max_examples=25, deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
@given(st.integers(0, 10 ** 6))
def test_property_a_warped_profile_keeps_the_joints_and_the_programmed_limits(seed):
    """Wherever the joints slow a drawn move down, its warped profile runs from rest to
    rest along the whole path, never faster than the programmed speed, never above the
    programmed acceleration and jerk, smooth (speed and acceleration continuous), and every
    joint within its limits every 0.25 ms; the scalar sample agrees with the vectorised."""
    drawn = _drawn_path(seed)
    if drawn is None:
        return
    move, s, joints = drawn
    derivatives = path_derivatives(s, joints)
    profile = warped_profile(s, derivatives, LIMITS, move.speed, move.acc, move.jerk, JOINT_LIMIT_SHARE)
    if profile is None:  # the joints limit it nowhere, or no correction kept them within their share
        return
    assert isinstance(profile, WarpedProfile)
    times = np.arange(0.0, profile.duration + 0.00025, 0.00025)
    at, v, a, j = profile.states(times)
    assert at[0] == 0.0 and at[-1] == move.path.length and v[-1] == 0.0
    assert np.all(np.diff(at) >= -1e-9)
    assert np.max(v) <= move.speed * (1.0 + 1e-6)
    assert np.max(np.abs(a)) <= move.acc * (1.0 + 1e-6)
    assert np.max(np.abs(j)) <= move.jerk * (1.0 + 1e-6)
    # smooth: the speed's differences give the acceleration, the acceleration's the jerk's size
    assert np.max(np.abs(np.diff(v) / 0.00025 - 0.5 * (a[1:] + a[:-1]))) <= 1e-3 * move.acc + 1e-6 * move.jerk
    assert np.max(np.abs(np.diff(a))) / 0.00025 <= move.jerk * (1.0 + 1e-3)
    ratios = joint_ratios(at, v, a, j, s, derivatives, LIMITS)
    assert np.max(ratios) <= 1.0, np.max(ratios, axis=1)
    for t in times[::97]:
        assert np.allclose(profile.sample(t), [x[0] for x in profile.states(np.asarray([t]))[:3]], atol=1e-9)


@pytest.mark.parametrize("kind, reachability", [(WarpedProfile, False), (AveragedProfile, True)])
def test_each_local_timing_is_chosen_where_it_is_the_fastest_and_its_setpoints_keep_every_limit(
        kind, reachability, monkeypatch):
    """A move drawn by the benchmark that the warp (with the reachability timing left out:
    it is shorter on most) or the reachability timing times fastest: planned through
    plan_cartesian, its 5 ms setpoints keep every joint's limits."""
    if not reachability:
        monkeypatch.setattr("runtime.motion.cartesian.reachable_profile", lambda *args: None)
    for seed in range(40):
        drawn = _drawn_path(seed)
        if drawn is None:
            continue
        move, s, joints = drawn
        _, stream, _ = plan_cartesian(CartesianInput(KIN, joints[0], move.path.end, move.speed, move.acc,
                                                     via=getattr(move.path, "via", None), axis_limits=SPEC))
        if stream is not None and isinstance(stream.checked.move.profile, kind):
            break
    else:
        raise AssertionError(f"no drawn move was timed by {kind.__name__}")
    from test_cartesian import setpoint_ratios
    assert max(setpoint_ratios(stream)) <= 1.0


def test_midpoints_are_exact_for_cubics_on_any_grid():
    from runtime.motion.pathtiming import _midpoints
    for x in (np.array([0.0, 1.0, 2.0, 2.5, 3.5, 4.5, 5.0]), np.linspace(-1.0, 3.0, 9), np.array([0.0, 1.0, 2.0]),
              np.array([0.0, 1.0])):
        y = x ** 3 - 2.0 * x if len(x) >= 4 else x ** (len(x) - 1)
        middle = 0.5 * (x[:-1] + x[1:])
        want = middle ** 3 - 2.0 * middle if len(x) >= 4 else middle ** (len(x) - 1)
        assert np.allclose(_midpoints(x, y), want, atol=1e-12)


def test_stops_anywhere_on_locally_timed_moves_keep_every_limit_and_end_at_rest():
    """Drawn moves the joints slow down locally (segments or warp), paused at fractions of
    their duration: every stop's 5 ms setpoints keep every joint's limits and end at rest
    on the path (before its end, or at it when no sooner stop keeps the limits: then the
    stop is the rest of the move). Before: a stop could take the segments' smallest
    deceleration while the move was still speeding up, run past the end of the path and
    jump there (350x the jerk limit), or end while still braking."""
    period = 0.005
    checked = 0
    for seed in range(0, 60, 3):
        drawn = _drawn_path(seed)
        if drawn is None:
            continue
        move, s, joints = drawn
        via = getattr(move.path, "via", None)
        plan = CartesianInput(KIN, joints[0], move.path.end, move.speed, move.acc, via=via, axis_limits=SPEC)
        _, stream, _ = plan_cartesian(plan)
        if stream is None or not isinstance(stream.checked.move.profile, PathProfile):
            continue
        checked += 1
        for fraction in (0.03, 0.2, 0.45, 0.7, 0.88):
            _, stream, _ = plan_cartesian(plan)
            steps = int(fraction * stream.duration / period)
            setpoints = [stream.sample(i * period)[0][:6] for i in range(steps + 1)]
            stop = _stopped(stream, steps, period, setpoints)
            assert stop.fault is None and stop.s_end <= move.path.length + 1e-9
            assert stop.sample(stop.duration)[1] == (0.0,) * 6
            assert max(_ratios(setpoints, period)) <= 1.0, (seed, fraction, _ratios(setpoints, period))
    assert checked >= 5
