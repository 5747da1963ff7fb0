"""The PTP motion layer: profiles, the synchronised planner, the 5 ms -> 1 ms interpolator.

* Analytic checks of single profiles (the paper's 45 deg move, triangular, zero and
  negative distances, a given duration, the discriminant at 0).
* The planner's contract: a documented Result, messages naming quantity, value and
  axis, never an exception.
* Properties (Hypothesis, derandomized) over random six-axis moves and limits: no setpoint
  sampled every 1 ms exceeds an axis's velocity or acceleration limit (analytically and
  by finite differences); all axes start together and reach their targets together at
  ``T``; ``T`` is the largest per-axis minimum, so the slowest axis is time-optimal.
* The interpolator: exact on setpoints and on constant-acceleration stretches; its 1 ms
  references stay within the (sharp) bounds documented in ``runtime.motion.interpolator``;
  planned with the documented velocity margin, they stay within the limit itself.

NumPy is used here only, to check samples in bulk; the motion code is plain floats.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from runtime.motion.interpolator import ACCELERATION_FACTOR, VELOCITY_OVERSHOOT, Interpolator
from runtime.motion.planner import (
    DISTANCE_EPSILON,
    MAX_DURATION,
    PtpInput,
    PtpTrajectory,
    Result,
    plan_ptp,
    scaled_limits,
)
from runtime.motion.profiles import (
    TrapezoidalProfile,
    minimum_duration,
    profile_with_duration,
    time_optimal_profile,
)

from conftest import ROOT, examples
EPS = np.finfo(float).eps
SERVO_DT = 0.001  # s
SETPOINT_DT = 0.005  # s
REL = 1e-9  # relative tolerance on limits

PROPERTY = settings(derandomize=True, deadline=None, max_examples=60,
                    suppress_health_check=[HealthCheck.too_slow])
# the interpolator's properties simulate every 1 ms of a move in Python: fewer examples
INTERPOLATOR_PROPERTY = settings(PROPERTY, max_examples=40)


# --------------------------------------------------------------------------- helpers


def ms_times(duration: float, extra_ms: int = 3) -> np.ndarray:
    """Servo instants 0, 1 ms, 2 ms, ... past ``duration`` (computed as m / 1000)."""
    n = int(math.ceil(duration * 1000.0)) + extra_ms
    return np.arange(n + 1) / 1000.0


def sample_all(traj: PtpTrajectory, times) -> tuple[np.ndarray, np.ndarray]:
    pos, vel = zip(*(traj.sample(float(t)) for t in times))
    return np.array(pos), np.array(vel)


def rounding(positions: np.ndarray) -> np.ndarray:
    """Per-axis absolute rounding scale of positions (a few ulps of the largest one)."""
    return 8.0 * EPS * (np.abs(positions).max(axis=0) + 1.0)


def analytic_minimum(d: float, v: float, a: float) -> float:
    d = abs(d)
    return 2.0 * math.sqrt(d / a) if d < v * v / a else d / v + v / a


def assert_profile_invariants(p: TrapezoidalProfile, v_max: float, a_max: float) -> None:
    assert abs(p.v_cruise) <= v_max * (1 + REL)
    assert abs(p.accel) == a_max
    assert 0.0 <= p.t_acc <= 0.5 * p.t_total
    # the profile covers its distance: v_c (T - t_acc) == d, to rounding
    covered = p.v_cruise * (p.t_total - p.t_acc)
    assert covered == pytest.approx(p.distance, rel=1e-9, abs=1e-12)


# --------------------------------------------------------------------------- profiles


def test_paper_move_45_deg_trapezoid():
    d, v, a = 45.0, 15.6, 40.0
    expected = 45.0 / 15.6 + 15.6 / 40.0
    assert minimum_duration(d, v, a) == expected
    p = time_optimal_profile(0.0, d, v, a)
    assert p.t_total == expected
    assert p.t_acc == pytest.approx(15.6 / 40.0)
    assert p.v_cruise == v and p.accel == a
    # end of the acceleration phase: 1/2 a t_acc^2 = v^2 / (2 a)
    pos, vel, acc = p.sample(p.t_acc - 1e-12)
    assert pos == pytest.approx(v * v / (2 * a), abs=1e-9)
    assert vel == pytest.approx(v, abs=1e-9) and acc == a
    pos, vel, acc = p.sample(expected / 2)
    assert pos == pytest.approx(22.5, abs=1e-12) and vel == v and acc == 0.0
    pos, vel, acc = p.sample(expected - 0.1)
    assert acc == -a and vel == pytest.approx(a * 0.1)
    assert pos == pytest.approx(45.0 - 0.5 * a * 0.01)
    assert p.sample(expected) == (45.0, 0.0, 0.0)
    assert p.sample(1e9) == (45.0, 0.0, 0.0)
    assert p.sample(-1.0) == (0.0, 0.0, 0.0)
    assert p.sample(float("nan")) == (0.0, 0.0, 0.0)
    assert_profile_invariants(p, v, a)


def test_triangular_when_the_distance_is_too_short():
    d, v, a = 2.0, 15.6, 40.0  # v^2/a = 6.084 > 2: never reaches v
    expected = 2.0 * math.sqrt(d / a)
    assert minimum_duration(d, v, a) == expected
    p = time_optimal_profile(10.0, d, v, a)
    assert p.t_total == expected and p.t_acc == expected / 2
    assert p.v_cruise == pytest.approx(math.sqrt(a * d))
    assert p.v_cruise < v
    pos, vel, acc = p.sample(expected / 2)  # the peak: first sample of the deceleration
    assert pos == pytest.approx(11.0) and vel == pytest.approx(math.sqrt(a * d))
    assert p.sample(expected)[0] == 12.0
    assert_profile_invariants(p, v, a)


def test_boundary_between_triangle_and_trapezoid():
    v, a = 15.6, 40.0
    d = v * v / a
    assert minimum_duration(d, v, a) == pytest.approx(2.0 * v / a, rel=1e-15)
    assert minimum_duration(d * (1 - 1e-12), v, a) == pytest.approx(2.0 * v / a, rel=1e-9)
    assert minimum_duration(d * (1 + 1e-12), v, a) == pytest.approx(2.0 * v / a, rel=1e-9)


def test_zero_distance():
    assert minimum_duration(0.0, 1.0, 1.0) == 0.0
    p = time_optimal_profile(3.5, 0.0, 1.0, 1.0)
    assert p.t_total == 0.0 and p.v_cruise == 0.0
    for t in (-1.0, 0.0, 0.5, 2.0):
        assert p.sample(t) == (3.5, 0.0, 0.0)
    q = profile_with_duration(3.5, 0.0, 1.0, 1.0, 2.0)
    assert q.t_total == 2.0 and q.v_cruise == 0.0 and q.t_acc == 0.0
    for t in (-1.0, 0.0, 0.5, 1.0, 1.999, 2.0, 3.0):
        assert q.sample(t) == (3.5, 0.0, 0.0)


def test_negative_distance_mirrors_positive():
    v, a = 15.6, 40.0
    for d in (45.0, 2.0):
        up = time_optimal_profile(0.0, d, v, a)
        down = time_optimal_profile(0.0, -d, v, a)
        assert down.t_total == up.t_total
        assert down.v_cruise == -up.v_cruise and down.accel == -up.accel
        for t in np.linspace(-0.1, up.t_total + 0.1, 101):
            pu, vu, au = up.sample(float(t))
            pd, vd, ad = down.sample(float(t))
            assert (pd, vd, ad) == (-pu, -vu, -au)
        assert down.sample(down.t_total)[0] == -d


def test_profile_with_duration_matches_the_closed_form():
    d, v, a, big_t = -30.0, 100.0, 40.0, 5.0
    p = profile_with_duration(1.0, d, v, a, big_t)
    closed = (a * big_t - math.sqrt(a * a * big_t * big_t - 4 * a * abs(d))) / 2
    assert abs(p.v_cruise) == pytest.approx(closed, rel=1e-14)
    assert p.v_cruise < 0 and p.accel == -a
    assert p.t_total == big_t and p.t_acc == pytest.approx(closed / a)
    assert p.sample(big_t) == (-29.0, 0.0, 0.0)
    assert_profile_invariants(p, v, a)


def test_profile_with_the_minimal_duration_is_the_time_optimal_one():
    for d in (45.0, 2.0, -7.0, 1e-9, 300.0):
        v, a = 15.6, 40.0
        best = time_optimal_profile(0.0, d, v, a)
        same = profile_with_duration(0.0, d, v, a, best.t_total)
        assert same.v_cruise == pytest.approx(best.v_cruise, rel=1e-7)
        assert same.t_acc == pytest.approx(best.t_acc, rel=1e-7)
        for t in np.linspace(0.0, best.t_total, 51):
            assert same.sample(float(t))[0] == pytest.approx(best.sample(float(t))[0],
                                                              rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("factor", [1.0, 1.0 + 1e-16, 1.0 + 4e-16, 1.0 + 1e-13, 1.0 - 1e-13])
def test_discriminant_near_zero_is_robust(factor):
    # T at (or within rounding of) the triangular minimum 2 sqrt(D/a): a double root
    d, v, a = 2.0, 1e6, 40.0
    big_t = 2.0 * math.sqrt(d / a) * factor
    p = profile_with_duration(0.0, d, v, a, big_t)
    assert math.isfinite(p.v_cruise) and 0.0 <= p.t_acc <= big_t / 2
    assert abs(p.v_cruise) <= a * big_t / 2
    # positions stay accurate: continuous at the phase switch, exact at the end
    ts = np.linspace(0.0, big_t, 2001)
    pos = np.array([p.sample(float(t))[0] for t in ts])
    assert np.all(np.diff(pos) >= -1e-12)
    assert pos[-1] == d
    mid = p.sample(big_t / 2)[0]
    assert mid == pytest.approx(d / 2, abs=1e-7)
    jump = p.sample(p.t_acc * (1 - 1e-15))[0] - p.sample(p.t_acc)[0]
    assert abs(jump) < 1e-9


def test_profile_with_too_short_a_duration_raises():
    with pytest.raises(ValueError, match="at least the minimum"):
        profile_with_duration(0.0, 45.0, 15.6, 40.0, 3.0)
    with pytest.raises(ValueError, match="max_velocity must be positive"):
        minimum_duration(1.0, 0.0, 1.0)


def test_profile_sample_is_continuous_at_phase_switches():
    p = profile_with_duration(-5.0, 12.0, 15.6, 40.0, 4.0)
    for ts in (p.t_acc, p.t_total - p.t_acc):
        before, after = p.sample(ts * (1 - 1e-14)), p.sample(ts)
        assert before[0] == pytest.approx(after[0], abs=1e-11)
        assert before[1] == pytest.approx(after[1], abs=1e-9)


# --------------------------------------------------------------------------- planner


def lola15():
    from compiler.spec import load_spec

    return load_spec(ROOT / "programs" / "lola15.spc")


PAPER_MOVES = [
    ((0, 0, 0, 0, 0, 0), (45, 0, -45, 0, 0, 0)),
    ((45, 0, -45, 0, 0, 0), (-45, 45, 45, 0, 0, 0)),
    ((-45, 45, 45, 0, 0, 0), (45, -45, 45, 0, 0, 0)),
]


@pytest.mark.parametrize("start,target", PAPER_MOVES)
def test_paper_program_moves(start, target):
    spec = lola15()
    v, a = scaled_limits([ax.max_velocity for ax in spec.axes],
                         [ax.max_acceleration for ax in spec.axes], 0.1, 0.1)
    assert v[:3] == pytest.approx((15.6,) * 3) and a[:3] == pytest.approx((40.0,) * 3)
    result, traj, message = plan_ptp(PtpInput(tuple(map(float, start)),
                                              tuple(map(float, target)), v, a))
    assert (result, message) == (Result.WORKING, "")
    biggest = max(abs(t - s) for s, t in zip(start, target))
    assert traj.duration == pytest.approx(biggest / 15.6 + 15.6 / 40.0, rel=1e-15)
    assert traj.sample(traj.duration) == (tuple(map(float, target)), (0.0,) * 6)


def test_result_enum_values():
    assert Result.WORKING == 0 and Result.FINISHED == 1 and Result.ERROR == -1
    assert Result.ERROR_INVALID_INPUT == -100 and Result.ERROR_LIMITS == -101
    assert Result.ERROR_POSITION_LIMITS == -102
    for r in Result:
        assert r.__doc__ is not None


def test_nothing_to_move_is_finished():
    result, traj, message = plan_ptp(PtpInput((1.0, 2.0), (1.0, 2.0), (1.0, 1.0), (1.0, 1.0)))
    assert result == Result.FINISHED and message == ""
    assert traj.duration == 0.0
    assert traj.sample(0.0) == ((1.0, 2.0), (0.0, 0.0))
    assert traj.sample(1.0) == ((1.0, 2.0), (0.0, 0.0))


def test_the_example_message_of_the_brief():
    inp = PtpInput((0.0,) * 6, (1.0,) * 6, (1.0, 1.0, 0, 1.0, 1.0, 1.0), (1.0,) * 6)
    assert plan_ptp(inp) == (Result.ERROR_INVALID_INPUT, None,
                             "axis 3: max_velocity must be positive, got 0")


NAN, INF = float("nan"), float("inf")
SIX = (0.0,) * 6
GOOD = dict(current_position=SIX, target_position=(10.0,) * 6, max_velocity=(5.0,) * 6,
            max_acceleration=(20.0,) * 6)


def with_axis(name, axis, value):
    values = list(GOOD[name])
    values[axis - 1] = value
    return {**GOOD, name: tuple(values)}


INVALID = [
    (with_axis("target_position", 2, NAN), "axis 2: target_position must be finite, got nan"),
    (with_axis("current_position", 6, -INF), "axis 6: current_position must be finite, got -inf"),
    (with_axis("max_velocity", 4, NAN), "axis 4: max_velocity must be finite, got nan"),
    (with_axis("max_velocity", 1, INF), "axis 1: max_velocity must be finite, got inf"),
    (with_axis("max_velocity", 5, -2.5), "axis 5: max_velocity must be positive, got -2.5"),
    (with_axis("max_acceleration", 3, 0.0), "axis 3: max_acceleration must be positive, got 0"),
    (with_axis("max_acceleration", 2, -1e-300),
     "axis 2: max_acceleration must be positive, got -1e-300"),
    (with_axis("max_acceleration", 1, "fast"),
     "axis 1: max_acceleration must be a number, got 'fast'"),
    (with_axis("target_position", 6, None), "axis 6: target_position must be a number, got None"),
    ({**GOOD, "target_position": (1.0,) * 5},
     "axis 6: target_position has 5 axes, current_position has 6"),
    ({**GOOD, "max_velocity": (1.0,) * 7},
     "axis 7: max_velocity has 7 axes, current_position has 6"),
    ({**GOOD, "max_acceleration": ()},
     "axis 1: max_acceleration has 0 axes, current_position has 6"),
    ({**GOOD, "max_velocity": None},
     "max_velocity must be a sequence of numbers, one per axis, got None"),
    ({**GOOD, "current_position": (), "target_position": (), "max_velocity": (),
      "max_acceleration": ()}, "current_position must have at least one axis, got 0"),
]


@pytest.mark.parametrize("fields,message", INVALID)
def test_invalid_input_is_an_error_result_never_an_exception(fields, message):
    result, traj, got = plan_ptp(PtpInput(**fields))
    assert (result, traj, got) == (Result.ERROR_INVALID_INPUT, None, message)


def test_not_an_input_at_all():
    for junk in (None, 42, "move"):
        assert plan_ptp(junk) == (Result.ERROR_INVALID_INPUT, None,
                                  f"input must be a PtpInput, got {type(junk).__name__}")


def test_limits_too_small_for_the_distance():
    inp = PtpInput((0.0, 0.0), (1e6, 1.0), (1e-3, 1.0), (1.0, 1.0))
    result, traj, message = plan_ptp(inp)
    assert result == Result.ERROR_LIMITS and traj is None
    assert message.startswith("axis 1: the move needs ") and f"{MAX_DURATION:g}" in message
    inp = PtpInput((0.0,), (1e308,), (1e-308,), (1e-308,))
    assert plan_ptp(inp)[0] == Result.ERROR_LIMITS
    inp = PtpInput((-1e308,), (1e308,), (1.0,), (1.0,))  # the distance overflows
    result, traj, message = plan_ptp(inp)
    assert result == Result.ERROR_INVALID_INPUT and message.startswith("axis 1: ")


def test_position_limits():
    base = dict(current_position=(0.0, 200.0), max_velocity=(1.0, 1.0),
                max_acceleration=(1.0, 1.0), min_position=(-170.0, -170.0),
                max_position=(170.0, 170.0))
    result, _, message = plan_ptp(PtpInput(target_position=(180.0, 0.0), **base))
    assert result == Result.ERROR_POSITION_LIMITS
    assert message == "axis 1: target_position 180 is above max_position 170"
    # moving back into the range from outside it is allowed
    assert plan_ptp(PtpInput(target_position=(10.0, 0.0), **base))[0] == Result.WORKING
    result, _, message = plan_ptp(PtpInput(target_position=(0.0, -171.5), **base))
    assert message == "axis 2: target_position -171.5 is below min_position -170"
    bad = {**base, "min_position": (0.0, 10.0), "max_position": (1.0, 5.0)}
    result, _, message = plan_ptp(PtpInput(target_position=(0.0, 7.0), **bad))
    assert result == Result.ERROR_INVALID_INPUT
    assert message == "axis 2: min_position 10 is above max_position 5"


def test_scaled_limits():
    v, a = scaled_limits((156.0, 330.0), (400.0, 900.0), 0.5, 0.25)
    assert v == (78.0, 165.0) and a == (100.0, 225.0)
    for bad in (0.0, -0.1, 1.5, NAN):
        with pytest.raises(ValueError, match="speed_ptp must be a fraction"):
            scaled_limits((1.0,), (1.0,), bad, 0.5)
        with pytest.raises(ValueError, match="acc_ptp must be a fraction"):
            scaled_limits((1.0,), (1.0,), 0.5, bad)
    with pytest.raises(ValueError, match="axes"):
        scaled_limits((1.0, 2.0), (1.0,), 0.5, 0.5)


# --------------------------------------------------------------------------- properties

position = st.floats(-180.0, 180.0, allow_nan=False)


@st.composite
def six_axis_moves(draw, v_range=(15.0, 700.0), a_range=(40.0, 2000.0)):
    """Six axes: random start, target (some axes still), limits; some axes are scaled
    copies of others (equal minimal durations up to rounding: ties and double roots)."""
    start, target, v, a = [], [], [], []
    for i in range(6):
        s = draw(position)
        kind = draw(st.sampled_from(["move", "move", "move", "still", "tiny", "clone"]))
        if kind == "clone" and i > 0:
            j = draw(st.integers(0, i - 1))
            k = draw(st.floats(0.1, 3.0))
            d = (target[j] - start[j]) * k
            start.append(s)
            target.append(s + d)
            v.append(v[j] * k if v[j] * k > 0 else 1.0)
            a.append(a[j] * k if a[j] * k > 0 else 1.0)
            continue
        start.append(s)
        if kind == "still":
            target.append(s)
        elif kind == "tiny":
            target.append(s + draw(st.floats(-1e-6, 1e-6)))
        else:
            target.append(draw(position))
        v.append(draw(st.floats(*v_range)))
        a.append(draw(st.floats(*a_range)))
    return PtpInput(tuple(start), tuple(target), tuple(v), tuple(a))


def check_planned(inp: PtpInput):
    result, traj, message = plan_ptp(inp)
    assert result in (Result.WORKING, Result.FINISHED), message
    n = len(inp.current_position)
    distances = [t - s for s, t in zip(inp.current_position, inp.target_position)]
    distances = [0.0 if abs(d) < DISTANCE_EPSILON else d for d in distances]  # no motion below it
    minima = [minimum_duration(distances[i], inp.max_velocity[i], inp.max_acceleration[i])
              for i in range(n)]
    # duration: the largest per-axis minimum, so the slowest axis is time-optimal
    assert traj.duration == max(minima)
    k = traj.slowest_axis
    assert minima[k] == traj.duration
    assert traj.duration == pytest.approx(
        analytic_minimum(distances[k], inp.max_velocity[k], inp.max_acceleration[k]),
        rel=1e-12)
    slow = traj.profiles[k]
    best = time_optimal_profile(inp.current_position[k], distances[k], inp.max_velocity[k],
                                inp.max_acceleration[k])
    assert (slow.v_cruise, slow.accel, slow.t_acc, slow.t_total) == (
        best.v_cruise, best.accel, best.t_acc, best.t_total)
    assert abs(slow.v_cruise) == pytest.approx(
        min(inp.max_velocity[k], math.sqrt(inp.max_acceleration[k] * abs(distances[k]))),
        rel=1e-12)
    # every axis: same duration, within its limits, covering its distance
    for i, p in enumerate(traj.profiles):
        assert p.t_total == traj.duration
        assert_profile_invariants(p, inp.max_velocity[i], inp.max_acceleration[i])
    return traj


def check_samples(inp: PtpInput, traj: PtpTrajectory, times: np.ndarray, dense: bool):
    v_max = np.array(inp.max_velocity)
    a_max = np.array(inp.max_acceleration)
    start = np.array(inp.current_position)
    target = np.array(inp.target_position)
    pos, vel = sample_all(traj, times)
    acc = np.array([traj.sample_accelerations(float(t)) for t in times])
    # the trajectory's inlined sampling agrees with its profiles' sample()
    during = times < traj.duration
    by_profile = np.array([[p.sample(float(t))[:2] for p in traj.profiles]
                           for t in times[during]]).reshape(-1, len(traj.profiles), 2)
    assert np.array_equal(pos[during], by_profile[:, :, 0])
    assert np.array_equal(vel[during], by_profile[:, :, 1])
    # analytic samples within the limits
    assert np.all(np.abs(vel) <= v_max * (1 + REL))
    assert np.all(np.abs(acc) <= a_max)
    # start together, stop together, exactly at the targets
    assert np.all(np.abs(pos[0] - start) < DISTANCE_EPSILON) and np.all(vel[0] == 0.0)
    end = traj.sample(traj.duration)
    assert end == (inp.target_position, (0.0,) * len(start))
    for p, goal in zip(traj.profiles, inp.target_position):
        assert abs(p.sample(traj.duration)[0] - goal) <= 1e-9 * max(1.0, abs(goal))
        just_before = p.sample(traj.duration * (1 - 1e-15))[0]
        assert abs(just_before - goal) <= 1e-9 * max(1.0, abs(goal))
    after = times >= traj.duration
    assert np.all(pos[after] == target) and np.all(vel[after] == 0.0)
    inside = (times > 0) & (times < traj.duration)
    moving = np.abs(target - start) >= DISTANCE_EPSILON  # below it an axis is already there
    assert np.all(np.abs(vel[np.ix_(inside, moving)]) > 0.0)
    assert np.all(vel[np.ix_(inside, ~moving)] == 0.0)
    # monotonic towards the target on every axis
    steps = np.diff(pos, axis=0) * np.sign(target - start)
    assert np.all(steps >= -rounding(pos))
    if dense:  # finite differences of the 1 ms samples
        dt = SERVO_DT
        fd_vel = np.diff(pos, axis=0) / dt
        assert np.all(np.abs(fd_vel) <= v_max * (1 + REL) + rounding(pos) / dt)
        fd_acc = np.diff(pos, 2, axis=0) / dt ** 2
        assert np.all(np.abs(fd_acc) <= a_max * (1 + 1e-6) + 4 * rounding(pos) / dt ** 2)


@PROPERTY
@given(six_axis_moves())
def test_property_ptp_within_limits_synchronised_time_optimal(inp):
    traj = check_planned(inp)
    check_samples(inp, traj, ms_times(traj.duration), dense=True)


@settings(derandomize=True, deadline=None, max_examples=examples(150))
@given(six_axis_moves(v_range=(1e-3, 1e4), a_range=(1e-3, 1e5)))
def test_property_wide_limits_analytic_checks(inp):
    result, traj, message = plan_ptp(inp)
    if result == Result.ERROR_LIMITS:
        assert max(analytic_minimum(t - s, v, a) for s, t, v, a in zip(
            inp.current_position, inp.target_position, inp.max_velocity,
            inp.max_acceleration)) > MAX_DURATION * 0.999
        return
    traj = check_planned(inp)
    switches = [0.0, traj.duration]
    for p in traj.profiles:
        switches += [p.t_acc, p.t_total - p.t_acc]
    times = np.unique(np.concatenate([np.linspace(0.0, traj.duration * 1.01, 301),
                                      np.array(switches)]))
    check_samples(inp, traj, times, dense=False)


# --------------------------------------------------------------------------- interpolator


def run_interpolator(traj: PtpTrajectory, n_axes: int, tail_periods: int = 3):
    """Generator at 5 ms pushes setpoints; after each push the servo takes the 5 refs of
    the previous period (one period of delay). Returns servo times and references."""
    interp = Interpolator(traj.start_position)
    periods = int(math.ceil(traj.duration / SETPOINT_DT)) + tail_periods
    times, refs, ref_vel = [], [], []
    for k in range(periods + 1):
        t_k = (5 * k) / 1000.0
        assert interp.push(t_k, *traj.sample(t_k))
        if k == 0:
            continue
        for j in range(5):
            t = (5 * (k - 1) + j) / 1000.0
            times.append(t)
            refs.append(interp.sample(t))
            ref_vel.append(interp.sample_velocity(t))
    return np.array(times), np.array(refs).reshape(-1, n_axes), np.array(ref_vel)


def check_interpolated(inp, traj, v_bound, strict_v=None):
    a_max = np.array(inp.max_acceleration)
    times, refs, ref_vel = run_interpolator(traj, len(a_max))
    exact, _ = sample_all(traj, times)
    # on the 5 ms grid the references are the setpoints themselves
    on_grid = np.arange(len(times)) % 5 == 0
    assert np.array_equal(refs[on_grid], exact[on_grid])
    assert np.all(np.abs(refs - exact) <= a_max * SETPOINT_DT ** 2 / 16 * (1 + 1e-6)
                  + rounding(exact))
    dt = SERVO_DT
    fd_vel = np.diff(refs, axis=0) / dt
    assert np.all(np.abs(ref_vel) <= v_bound * (1 + REL))
    assert np.all(np.abs(fd_vel) <= v_bound * (1 + REL) + rounding(refs) / dt)
    fd_acc = np.diff(refs, 2, axis=0) / dt ** 2
    assert np.all(np.abs(fd_acc) <= ACCELERATION_FACTOR * a_max * (1 + 1e-6)
                  + 4 * rounding(refs) / dt ** 2)
    if strict_v is not None:
        assert np.all(np.abs(ref_vel) <= strict_v * (1 + REL))
        assert np.all(np.abs(fd_vel) <= strict_v * (1 + REL) + rounding(refs) / dt)
    # the references end at the targets and stay there
    assert np.array_equal(refs[-1], np.array(inp.target_position))


@INTERPOLATOR_PROPERTY
@given(six_axis_moves())
def test_property_interpolated_references_within_documented_bounds(inp):
    traj = check_planned(inp)
    a_max = np.array(inp.max_acceleration)
    v_bound = np.array(inp.max_velocity) + VELOCITY_OVERSHOOT * a_max * SETPOINT_DT
    check_interpolated(inp, traj, v_bound)


@INTERPOLATOR_PROPERTY
@given(six_axis_moves())
def test_property_with_the_velocity_margin_references_stay_within_the_limit(inp):
    v = np.array(inp.max_velocity)
    a = np.array(inp.max_acceleration)
    margin = VELOCITY_OVERSHOOT * a * SETPOINT_DT
    derated = PtpInput(inp.current_position, inp.target_position, tuple(v - margin),
                       inp.max_acceleration)
    traj = check_planned(derated)
    check_interpolated(derated, traj, v, strict_v=v)


def test_hermite_overshoot_is_real_and_the_bound_is_sharp():
    """Without the margin the 1 ms references can exceed the velocity limit: a corner at
    27 % of a 5 ms interval gives the worst case, 0.04365 a h."""
    v, a, h = 10.0, 40.0, SETPOINT_DT
    # cruise -> deceleration corner at 0.2713 h into an interval
    t_acc = v / a
    big_t = 0.8 + (1 - 0.2712863) * h + t_acc  # T - t_acc = 0.8 + 0.7287 h
    d = v * (big_t - t_acc)
    result, traj, _ = plan_ptp(PtpInput((0.0,), (d,), (v,), (a,)))
    assert result == Result.WORKING and traj.duration == pytest.approx(big_t)
    interp = Interpolator((0.0,))
    t0, t1 = 0.8, 0.8 + h
    interp.push(t0, *traj.sample(t0))
    interp.push(t1, *traj.sample(t1))
    peak = max(interp.sample_velocity(t0 + h * u)[0] for u in np.linspace(0, 1, 10001)[1:-1])
    assert peak - v == pytest.approx(0.043648 * a * h, rel=1e-3)
    assert peak - v < VELOCITY_OVERSHOOT * a * h


def test_hermite_acceleration_bound_is_sharp():
    # p''(0) = integral (4 - 6u) acc(u) du: +a until 2/3 h, then -a gives 5/3 a
    a, h = 40.0, SETPOINT_DT
    interp = Interpolator((0.0,))
    s = 2 * h / 3
    v1 = a * s - a * (h - s)
    p1 = 0.5 * a * s * s + a * s * (h - s) - 0.5 * a * (h - s) ** 2
    interp.push(0.0, (0.0,), (0.0,))
    interp.push(h, (p1,), (v1,))
    e = 1e-6
    fd = (interp.sample(2 * e)[0] - 2 * interp.sample(e)[0] + 0.0) / e ** 2
    assert fd == pytest.approx(ACCELERATION_FACTOR * a, rel=1e-3)


def test_interpolator_is_exact_on_constant_acceleration():
    a, v0, p0 = 3.0, -1.5, 2.0
    interp = Interpolator((p0, 0.0))

    def state(t):
        return (p0 + v0 * t + 0.5 * a * t * t, 7.0), (v0 + a * t, 0.0)

    for k in range(4):
        interp.push(k * SETPOINT_DT, *state(k * SETPOINT_DT))
    for m in range(10, 15):  # between the last two setpoints (10 ms and 15 ms)
        t = m / 1000.0
        got = interp.sample(t)
        assert got[0] == pytest.approx(state(t)[0][0], abs=1e-14)
        assert got[1] == 7.0
        assert interp.sample_velocity(t)[0] == pytest.approx(state(t)[1][0], abs=1e-11)


def test_interpolator_holds_and_rejects():
    interp = Interpolator((1.0, 2.0))
    assert interp.sample(0.0) == (1.0, 2.0) and interp.interval is None
    assert interp.push(0.0, (3.0, 4.0), (0.0, 0.0))
    assert interp.sample(-1.0) == (3.0, 4.0) and interp.sample(5.0) == (3.0, 4.0)
    assert interp.setpoints == 1
    assert not interp.push(0.0, (5.0, 6.0), (0.0, 0.0))  # not later
    assert not interp.push(-0.1, (5.0, 6.0), (0.0, 0.0))
    assert not interp.push(0.005, (5.0,), (0.0, 0.0))  # wrong length
    assert interp.push(0.005, (5.0, 6.0), (0.0, 0.0))
    assert interp.interval == (0.0, 0.005)
    assert interp.sample(0.0) == (3.0, 4.0) and interp.sample(-3.0) == (3.0, 4.0)
    assert interp.sample(0.005) == (5.0, 6.0) and interp.sample(1.0) == (5.0, 6.0)
    assert interp.sample(float("nan")) == (5.0, 6.0)
    mid = interp.sample(0.0025)
    assert mid == pytest.approx((4.0, 5.0))
    assert interp.sample_velocity(1.0) == (0.0, 0.0)
    # a servo's now - period lands a rounding error before t0: it still gets v0
    interp.push(0.010, (5.0, 6.0), (2.0, -1.0))
    interp.push(0.015, (5.1, 6.0), (3.0, 0.0))
    assert 0.015 - 0.005 < 0.010
    assert interp.sample_velocity(0.015 - 0.005) == pytest.approx((2.0, -1.0), rel=1e-12)
    assert interp.sample(0.015 - 0.005) == (5.0, 6.0)
    interp.reset((9.0, 9.0))
    assert interp.sample(0.003) == (9.0, 9.0) and interp.setpoints == 0


def test_interpolator_is_c1_across_setpoints():
    result, traj, _ = plan_ptp(PtpInput((0.0, 10.0), (45.0, -30.0), (15.6, 15.6), (40.0, 40.0)))
    interp = Interpolator(traj.start_position)
    e = 1e-7
    for k in range(200):
        t_k = k * SETPOINT_DT
        interp.push(t_k, *traj.sample(t_k))
        if k >= 2:
            # velocity at the end of the previous interval == at the start of this one
            _, v_set = traj.sample((k - 1) * SETPOINT_DT)
            left = interp.sample_velocity((k - 1) * SETPOINT_DT + e)
            assert left == pytest.approx(v_set, abs=40.0 * 2 * e * 10)


def test_subnormal_distances_are_no_motion_and_end_exactly_at_the_target():
    """Found by hypothesis: a distance of 5e-324 underflowed to a zero duration (sampled
    at t = 0 it returned the start) and to a zero velocity on a 'moving' axis."""
    start = (0.0, 0.0, 0.0, 5e-324, 0.0, 0.0)
    limits = ((15.0,) * 6, (40.0,) * 6)
    result, traj, _ = plan_ptp(PtpInput(start, (0.0,) * 6, *limits))
    assert result >= 0 and traj.sample(traj.duration) == ((0.0,) * 6, (0.0,) * 6)
    result, traj, _ = plan_ptp(PtpInput(start, (0.0, 0.0, 0.0, 0.0, 0.0, 25.0), *limits))
    pos, vel = traj.sample(traj.duration / 2)
    assert pos[3] == 0.0 and vel[3] == 0.0 and vel[5] > 0.0
    assert traj.sample(traj.duration)[0] == (0.0, 0.0, 0.0, 0.0, 0.0, 25.0)


def _servo_eval(interp: Interpolator, t: float):
    """The reference as the servo evaluates it: its kernel's arithmetic on segment()."""
    from runtime.accel import kernels
    segments, s, inv_h = interp.segment(t)
    return (tuple(kernels.segment_position(c, s) for c in segments),
            tuple(kernels.segment_velocity(c, s, inv_h) for c in segments))


finite = st.floats(-1e3, 1e3, allow_nan=False)


@settings(max_examples=examples(200), deadline=None)
@given(st.lists(st.tuples(st.floats(1e-3, 0.02), finite, finite, finite, finite, st.none() | st.tuples(finite, finite)),
                min_size=0, max_size=4),
       st.lists(st.floats(-0.05, 0.1), min_size=1, max_size=8))
def test_property_servo_evaluation_reproduces_sample_bit_for_bit(setpoints, times):
    """The servo evaluates the reference from segment(); it must equal sample() and
    sample_velocity() exactly: holding, before t0, between the setpoints, after them; with
    and without accelerations."""
    interp = Interpolator((1.5, -2.0), ((100.0, 100.0), (400.0, 400.0), (4000.0, 4000.0)))
    t = 0.0
    for dt, p0, p1, v0, v1, acc in setpoints:
        t += dt
        interp.push(t, (p0, p1), (v0, v1), acc)
        for q in times:
            position, velocity = _servo_eval(interp, t + q)
            assert position == interp.sample(t + q)
            assert velocity == interp.sample_velocity(t + q)


# ----------------------------------------------------------------------------- the package's layers


def test_every_motion_module_imports_only_from_the_ones_before_it():
    """runtime/motion/ is layered as its ``MODULES`` declares: no circle of imports (lazy and
    type-checking ones included), no private name taken from another module, every module
    in the list."""
    import house
    from runtime.motion import MODULES

    prefix = "runtime.motion."
    found = {name[len(prefix):] for name in house.modules() if name.startswith(prefix)}
    assert found == set(MODULES), "runtime/motion/__init__.py MODULES lists every module once"
    assert len(MODULES) == len(set(MODULES))
    rank = {name: i for i, name in enumerate(MODULES)}
    edges = [e for e in house.imports() if e.source.startswith(prefix) and e.target.startswith(prefix)]
    upward = [f"{e.source} -> {e.target} (line {e.line})" for e in edges
              if rank[e.target[len(prefix):]] >= rank[e.source[len(prefix):]]]
    assert upward == [], "imports of a module at or above the importer in MODULES"
    assert house.private_imports(edges) == []
