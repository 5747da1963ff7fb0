"""Near time-optimal lin and circ timing (runtime/motion/reachability.py, issue 32):
TOPP-RA's reachability analysis equals toppra's on the same joint path, and the profile
averaged to keep the jerk runs from rest to rest within the programmed speed,
acceleration and jerk and every joint's share of its limits."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from runtime.motion.cartesian import REACHABLE_SHARE
from runtime.motion.kinematics import Kinematics
from runtime.motion.pathcheck import check_path
from runtime.motion.paths import CartesianMove, CircPath, LinPath
from runtime.motion.pathtiming import ConstantSpeed, joint_ratios, path_derivatives
from runtime.motion.reachability import STOP_SHARE, _time_law, reachable_profile, topp_ra

from conftest import SPEC

KIN = Kinematics(SPEC)
AXES = SPEC.main_axes
LIMITS = ([a.max_velocity for a in AXES], [a.max_acceleration for a in AXES], [a.max_jerk for a in AXES])
PROPERTY = settings(max_examples=25, deadline=None, derandomize=True, database=None,
                    suppress_health_check=list(HealthCheck))


@st.composite
def paths(draw):
    """(s, joints, speed, acc): the check's joint samples along a random lin or circ move
    (a start within the axes, some near the wrist singularity), with programmed limits."""
    q0 = [draw(st.floats(-150.0, 150.0)) for _ in range(6)]
    q0[1] = draw(st.floats(-60.0, 30.0))
    q0[2] = draw(st.floats(-60.0, 60.0))
    if draw(st.booleans()):
        q0[4] = draw(st.sampled_from([-1.0, 1.0])) * math.degrees(math.asin(draw(st.floats(0.05, 0.2))))
    else:
        q0[4] = draw(st.floats(20.0, 110.0))
    start = KIN.forward(q0)
    direction = [draw(st.floats(-1.0, 1.0)) for _ in range(3)]
    norm = math.sqrt(sum(c * c for c in direction))
    if norm < 0.1:
        direction, norm = [1.0, 0.0, 0.0], 1.0
    length = draw(st.floats(10.0, 400.0))
    tilt = tuple(c + draw(st.floats(-15.0, 15.0)) for c in start[3:])
    end = tuple(c + length * d / norm for c, d in zip(start[:3], direction)) + tilt
    if draw(st.booleans()):
        path = LinPath(start, end)
    else:
        side = (-direction[1], direction[0], 0.3)
        via = tuple(0.5 * (a + b) + 0.3 * length * c for a, b, c in zip(start[:3], end[:3], side)) + tilt
        try:
            path = CircPath(start, via, end)
        except ValueError:
            path = LinPath(start, end)
    speed = draw(st.sampled_from([100.0, 250.0, 500.0, 1000.0]))
    acc = draw(st.sampled_from([500.0, 1500.0, 5000.0]))
    try:
        along = check_path(CartesianMove(path, speed, acc, profile=ConstantSpeed(path.length)), KIN, q0, SPEC,
                           check_velocity=False)
    except Exception:  # noqa: BLE001 - a path the arm cannot follow: not a path to time
        return None
    return np.asarray(along.times, dtype=float), np.asarray(along.joints, dtype=float), speed, acc


def _toppra_time(s, joints, speed, acc) -> float:
    toppra = pytest.importorskip("toppra")
    import toppra.algorithm as algo
    import toppra.constraint as constraint

    toppra.setup_logging("ERROR")
    length = float(s[-1])
    u = s / length
    path = toppra.SplineInterpolator(u, np.hstack([joints, u[:, None]]))
    v = np.array(LIMITS[0] + [speed / length])
    a = np.array(LIMITS[1] + [acc / length])
    instance = algo.TOPPRA([constraint.JointVelocityConstraint(np.vstack([-v, v]).T),
                            constraint.JointAccelerationConstraint(np.vstack([-a, a]).T)], path,
                           gridpoints=np.linspace(0.0, 1.0, max(len(s), 100)), parametrizer="ParametrizeConstAccel")
    trajectory = instance.compute_trajectory(0.0, 0.0)
    return math.nan if trajectory is None else float(trajectory.duration)


@PROPERTY
@given(paths())
def test_property_reachability_is_toppras_time_optimum(drawn):
    """On the same joint path with the same limits (the joints' velocity and acceleration,
    the path's speed and acceleration), the duration of our TOPP-RA equals toppra's
    within 3 % (two discretisations of one problem: toppra's spline through the samples,
    our finite differences)."""
    if drawn is None:
        return
    s, joints, speed, acc = drawn
    derivatives = path_derivatives(s, joints)
    x = topp_ra(s, derivatives.d1, derivatives.d2, LIMITS[0], LIMITS[1], speed, acc)
    ours = _time_law(s, x)[0][-1]
    theirs = _toppra_time(s, joints, speed, acc)
    if math.isnan(theirs):
        return  # (toppra found its discretisation uncontrollable)
    assert abs(ours / theirs - 1.0) < 0.03, (ours, theirs)


@PROPERTY
@given(paths())
def test_property_the_averaged_profile_keeps_every_limit_from_rest_to_rest(drawn):
    """Whatever the path: the profile runs from rest at 0 to rest at the end, never
    backwards; ``sample`` is ``states``; the path's speed, acceleration and jerk keep the
    programmed ones, and every joint, predicted every 0.5 ms, keeps its share of its
    velocity, acceleration and jerk limits (1 % for the interpolation between samples)."""
    if drawn is None:
        return
    s, joints, speed, acc = drawn
    jerk = 10.0 * acc
    derivatives = path_derivatives(s, joints)
    profile = reachable_profile(s, derivatives, LIMITS, speed, acc, jerk, REACHABLE_SHARE)
    if profile is None:
        return
    times = np.linspace(-0.01, profile.duration + 0.01, int(profile.duration / 0.0005) + 3)
    at, v, a, j = profile.states(times)
    assert at[0] == 0.0 and at[-1] == pytest.approx(float(s[-1]))
    assert np.all(np.diff(at) >= -1e-9) and np.all(v >= -1e-9)
    assert v[0] == v[-1] == 0.0 and a[0] == a[-1] == 0.0
    for k in range(0, len(times), 97):
        assert profile.sample(float(times[k])) == pytest.approx((at[k], v[k], a[k]), rel=1e-9, abs=1e-6)
    assert np.max(v) <= speed * (1 + 1e-9) and np.max(np.abs(a)) <= acc * (1 + 1e-9)
    assert np.max(np.abs(j)) <= jerk * (1 + 1e-6)
    ratios = joint_ratios(at, v, a, j, s, derivatives, LIMITS)
    assert np.max(ratios) <= REACHABLE_SHARE * 1.01, np.max(ratios, axis=1)
    slow = profile.scaled(0.5)  # (speeds x 0.5: twice as long)
    assert slow.duration == pytest.approx(2.0 * profile.duration)
    assert slow.sample(profile.duration)[0] == pytest.approx(profile.sample(0.5 * profile.duration)[0])


def _paused(drawn, fraction: float, how: str):
    """A pause at ``fraction`` of the reachability-timed ``drawn`` move, stopped by the
    profile's method ``how``: (s, derivatives, acc, profile, t, stop), or None (no path,
    no profile, or that stop does not fit there)."""
    if drawn is None:
        return None
    s, joints, speed, acc = drawn
    derivatives = path_derivatives(s, joints)
    profile = reachable_profile(s, derivatives, LIMITS, speed, acc, 10.0 * acc, REACHABLE_SHARE)
    if profile is None:
        return None
    t = fraction * profile.duration
    stop = getattr(profile, how)(t)
    event(f"{how}: {stop is not None}")
    return None if stop is None else (s, derivatives, acc, profile, t, stop)


@PROPERTY
@given(paths(), st.sampled_from([0.1, 0.3, 0.5, 0.7]))
def test_property_a_stop_continues_the_profile_and_rests_on_the_path_within_the_limits(drawn, fraction):
    """A pause on a reachability-timed move: when the stop law brakes within the joints'
    limits (it is checked: else the stop is planned as for the other timings), it starts
    from the profile's own speed and acceleration at that instant, never goes backwards,
    rests before the path's end and sooner than the profile, keeps the programmed jerk
    and every joint's acceleration and jerk within STOP_SHARE of its limits."""
    found = _paused(drawn, fraction, "stop_law")
    if found is None:
        return
    s, derivatives, acc, profile, t, law = found
    s0, v0, a0 = profile.sample(t)
    assert law.sample(0.0) == pytest.approx((0.0, v0, a0), rel=1e-6, abs=1e-6)
    assert law.sample(law.duration) == pytest.approx((law.distance, 0.0, 0.0), abs=1e-6)
    assert s0 + law.distance <= profile.length + 1e-9 and law.duration < profile.duration - t + law._law.window
    times = np.linspace(0.0, law.duration, int(law.duration / 0.0005) + 2)
    at, v, a, j = law._law.states(law._t0 + times)
    assert np.all(np.diff(at) >= -1e-9) and np.all(v >= -1e-9)
    assert np.max(np.abs(j)) <= 10.0 * acc * (1 + 1e-6)
    ratios = joint_ratios(at, v, a, j, s, derivatives, LIMITS)
    assert np.max(ratios[1:]) <= STOP_SHARE * 1.01, np.max(ratios, axis=1)


@PROPERTY
@given(paths(), st.sampled_from([0.05, 0.1, 0.3, 0.5, 0.7]))
def test_property_a_ramp_stop_slows_the_profile_down_to_rest_within_the_limits(drawn, fraction):
    """Where no braking law fits, a pause slows the move's own profile down to rest
    (PathProfile.ramp_stop): it starts from the profile's speed and acceleration, its
    speed, acceleration and jerk are the derivatives of its position (sample and states
    agree), it never goes backwards, rests before the path's end and sooner than the
    profile would, keeps the programmed acc and jerk and every joint's acceleration and
    jerk within STOP_SHARE of its limits (checked here every 0.1 ms)."""
    found = _paused(drawn, fraction, "ramp_stop")
    if found is None:
        return
    s, derivatives, acc, profile, t, stop = found
    s0, v0, a0 = profile.sample(t)
    assert stop.sample(0.0) == pytest.approx((0.0, v0, a0), rel=1e-9, abs=1e-9)
    assert stop.sample(stop.duration) == (stop.distance, 0.0, 0.0)
    assert 0.0 <= stop.distance <= profile.length - s0 + 1e-9 and stop.duration < profile.duration - t
    times = np.linspace(0.0, stop.duration, int(stop.duration / 0.0001) + 2)
    at, v, a, j = stop.states(times)
    assert np.allclose([stop.sample(x) for x in times[::97]], np.stack([at - s0, v, a], axis=1)[::97], atol=1e-7)
    h = times[1] - times[0]
    assert np.allclose(np.gradient(at, h)[1:-1], v[1:-1], atol=1e-3 * max(v0, 1.0) + 0.5 * h * acc)
    assert np.allclose(np.gradient(v, h)[1:-1], a[1:-1], atol=h * 10.0 * acc)
    integrated = a[0] + np.concatenate([[0.0], np.cumsum(0.5 * h * (j[1:] + j[:-1]))])  # (the jerk may jump)
    assert np.allclose(integrated, a, atol=1e-3 * acc)
    assert np.all(np.diff(at) >= -1e-9) and np.all(v >= -1e-9) and at[-1] == pytest.approx(s0 + stop.distance)
    assert np.max(np.abs(a)) <= acc * (1 + 1e-6) and np.max(np.abs(j)) <= 10.0 * acc * (1 + 1e-6)
    ratios = joint_ratios(at, v, a, j, s, derivatives, LIMITS)
    assert np.max(ratios[1:]) <= STOP_SHARE * 1.01, np.max(ratios, axis=1)


@pytest.mark.parametrize("target", [(996.562, 0.0, 1351.573, 180.0, -60.0, 0.0),  # (as taught in tests/test_modes.py)
                                    (600.0, 100.0, 900.0, 180.0, -30.0, 10.0)])
def test_a_lin_to_where_the_robot_stands_is_planned(target):
    """A taught pose moved to with a lin right after the ptp that reached it: the path is
    a rounding long (about 1e-14 mm and deg). Before, the averaging window of so short a
    law grew to petabytes and the move was refused as an internal error of the planner."""
    from runtime.motion.cartesian import CartesianInput, plan_cartesian
    from runtime.motion.planner import Result

    q = tuple(KIN.inverse(target, near=(0.0, 0.0, 0.0, 0.0, 30.0, 0.0)))
    for end in (target, KIN.forward(q)):
        result, stream, message = plan_cartesian(CartesianInput(KIN, q, end, 250.0, 1000.0, axis_limits=SPEC))
        assert result == Result.WORKING and stream is not None, message
        assert stream.duration < 0.5
