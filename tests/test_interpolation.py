"""The servo's 1 ms references keep the axes' limits (issue 14, item 5).

Setpoints every 5 ms with positions, velocities and accelerations go through the
interpolator (runtime/motion/interpolator.py) as the servo takes them: one period behind,
a reference every 1 ms. What a drive sees is measured: the first, second and third
differences of successive references over 1 ms, against each axis's velocity,
acceleration and jerk limit; every ratio within ``1 + 1e-6`` (and the rounding of the
differences):

* jerk-limited PTP moves (runtime/motion/jerk.py, "line", "time" and "auto"), at the axes'
  full limits and scaled, with the Lola 15's limits and random ones, whose jerk phases last
  a setpoint period or longer (the documented exceptions are tested apart);
* trapezoidal PTP moves (runtime/motion/planner.py): velocity and acceleration (their
  setpoints have no jerk limit);
* blends of two jerk-limited moves whose superposition keeps the limits;
* lin and circ moves of the Lola 15 with exact derivatives in the setpoints (velocity and
  acceleration; the jerk within 0.1 of the limit above the path's own);
* the references hit every setpoint and are continuous in position, velocity and
  acceleration (C2) across setpoints;
* mutations of the interpolant (runtime/kernels.py, changed in memory) make these checks
  fail: each candidate is needed, and the checks see it.

NumPy only here, to check samples in bulk.
"""
from __future__ import annotations

import math
import types
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from runtime import kernels as kernels_source
from runtime.motion import interpolator as interpolator_module
from runtime.motion.interpolator import Interpolator
from runtime.motion.jerk import plan_ptp_jerk as _plan_ptp_jerk
from runtime.motion.planner import PtpInput, plan_ptp

from conftest import ROOT, SPEC
LOLA = (tuple(a.max_velocity for a in SPEC.axes), tuple(a.max_acceleration for a in SPEC.axes),
        tuple(a.max_jerk for a in SPEC.axes))
H = 0.005  # the setpoint period
TAU = 0.001  # the servo's
SLACK = 1e-6  # the acceptance: every ratio <= 1 + 1e-6
EPS = np.finfo(float).eps

PROPERTY = settings(derandomize=True, deadline=None, max_examples=40, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


# ---------------------------------------------------------------------------- helpers

def plan_ptp_jerk(start, target, v, a, j, synchronization: str = "auto"):
    """runtime.motion.jerk.plan_ptp_jerk of these limits."""
    return _plan_ptp_jerk(PtpInput(tuple(start), tuple(target), tuple(v), tuple(a), max_jerk=tuple(j),
                                   synchronization=synchronization))


def references(stream, start, limits, accelerations, tail: int = 3):
    """The 1 ms references of ``stream`` (``sample(t) -> (positions, velocities)``) with
    ``accelerations(t)`` (or None: setpoints without), sampled every 5 ms from two periods
    before its start to ``tail`` periods after its end, as the servo takes them (one period
    behind). Returns the reference times (ms), the references, and the setpoints."""
    interp = Interpolator(start, limits)
    periods = int(math.ceil(stream.duration / H)) + tail
    times, refs, knots = [], [], []
    for k in range(-2, periods + 1):
        t = (5 * k) / 1000.0
        p, v = stream.sample(t)
        a = accelerations(t) if accelerations is not None else None
        assert interp.push(t, p, v, a)
        knots.append((t, p, v, a))
        if k == -2:
            continue
        for j in range(5):
            ms = 5 * (k - 1) + j
            times.append(ms)
            refs.append(interp.sample(ms / 1000.0))
    return np.array(times), np.array(refs, dtype=float), knots


def ratios(refs, limits):
    """The largest ratio of each difference (velocity, acceleration, jerk over 1 ms) to its
    limit per axis, less the rounding of the differences."""
    scale = EPS * (np.abs(refs).max(axis=0) + 1.0)
    out = []
    for order, limit in enumerate(limits, start=1):
        d = np.abs(np.diff(refs, order, axis=0)) / TAU ** order
        rounding = 4.0 * 2 ** order * scale / TAU ** order
        out.append(float(np.max((d - rounding) / np.asarray(limit))) if len(d) else 0.0)
    return out


def assert_within(refs, limits, orders=(0, 1, 2)):
    found = ratios(refs, limits)
    for order in orders:
        assert found[order] <= 1.0 + SLACK, (("velocity", "acceleration", "jerk")[order], found)


def profile_phases(trajectory):
    """(t_j, t_acc) of every moving axis of a jerk-limited trajectory."""
    return [(p.t_j, p.t_acc) for p in trajectory.profiles if p.distance != 0.0]


# ---------------------------------------------------------------------------- strategies

@st.composite
def limits_strategy(draw):
    """The Lola 15's limits, or random ones per axis."""
    if draw(st.booleans()):
        return LOLA
    v = tuple(draw(st.floats(5.0, 600.0)) for _ in range(6))
    a = tuple(draw(st.floats(20.0, 5000.0)) for _ in range(6))
    j = tuple(x * draw(st.floats(1.0, 200.0)) for x in a)  # jerk phases a / j of 5 ms or longer
    return v, a, j


@st.composite
def ptp_moves(draw):
    """(start, target, limits, fraction of the limits, synchronization)."""
    limits = draw(limits_strategy())
    start = tuple(draw(st.floats(-170.0, 170.0)) for _ in range(6))
    kind = draw(st.sampled_from(["far", "near", "mixed"]))
    if kind == "far":
        target = tuple(draw(st.floats(-170.0, 170.0)) for _ in range(6))
    elif kind == "near":
        target = tuple(s + draw(st.floats(-12.0, 12.0)) for s in start)
    else:
        target = tuple(s + draw(st.sampled_from([0.0, 1.0])) * draw(st.floats(-200.0, 200.0)) for s in start)
    fraction = draw(st.sampled_from([1.0, 1.0, draw(st.floats(0.05, 1.0))]))
    sync = draw(st.sampled_from(["auto", "line", "time"]))
    return start, target, limits, fraction, sync


def plan_jerk(move):
    start, target, limits, fraction, sync = move
    v, a, j = limits
    result, trajectory, message = plan_ptp_jerk(start, target, [x * fraction for x in v], [x * fraction for x in a],
                                                [x * fraction for x in j], synchronization=sync)
    assert result >= 0, message
    return trajectory


# ---------------------------------------------------------------------------- PTP

@PROPERTY
@given(ptp_moves())
def test_property_jerk_limited_ptp_references_keep_every_limit(move):
    trajectory = plan_jerk(move)
    assume(trajectory.duration < 20.0)
    assume(all(t_j >= H for t_j, _ in profile_phases(trajectory)))  # the exceptions: below
    _, refs, _ = references(trajectory, trajectory.start_position, move[2], trajectory.sample_accelerations)
    assert_within(refs, move[2])


def test_the_cases_the_plain_interpolants_miss_are_kept():
    """At the full limits: a stretch at the acceleration limit shorter than a period (the
    quintic Hermite reaches 1.0015, one switch 1.003 of the acceleration limit), a cruise
    shorter than a period (1.09 and 1.17 of the jerk limit), every switch of jerk (the
    quintic: 1.18 of the jerk limit; the cubic Hermite: 1.50). All within."""
    v, a, j = 156.0, 400.0, 4000.0
    t_j = a / j
    t_acc = v / a + a / j
    cases = [a * (t_j + t_a) * (2 * t_j + t_a) for t_a in (0.0007, 0.0021, 0.0043)]
    cases += [v * t_acc + v * t_v for t_v in (0.0009, 0.0026, 0.0048)]
    cases += [100.0, 8.0]
    for distance in cases:
        for delay in (0.0, 0.0013, 0.0031):  # where the switches fall between setpoints
            _, trajectory, _ = plan_ptp_jerk([0.0], [distance], [v], [a], [j])
            shifted = types.SimpleNamespace(duration=trajectory.duration + delay,
                                            sample=lambda t, tr=trajectory, d=delay: tr.sample(t - d))
            _, refs, _ = references(shifted, (0.0,), ((v,), (a,), (j,)),
                                    lambda t, tr=trajectory, d=delay: tr.sample_accelerations(t - d))
            assert_within(refs, ((v,), (a,), (j,)))


@PROPERTY
@given(ptp_moves())
def test_property_short_jerk_phases_keep_velocity_and_acceleration(move):
    """The documented exception: jerk phases shorter than a period (a move shorter than
    2 J h^3, or A / J < h) put more switches in one interval than the candidates can
    follow; the closest is taken: velocity and acceleration within the limits, the jerk
    within 1.25 of it."""
    start, target, limits, fraction, sync = move
    v, a, j = limits
    j = tuple(x * 20.0 for x in j)  # jerk phases down to 0.25 ms
    tiny = tuple(s + (t - s) * 1e-4 for s, t in zip(start, target))  # and moves down to 0.001 deg
    for goal in (target, tiny):
        trajectory = plan_jerk((start, goal, (v, a, j), fraction, sync))
        if trajectory.duration > 20.0:
            continue
        _, refs, _ = references(trajectory, trajectory.start_position, (v, a, j), trajectory.sample_accelerations)
        found = ratios(refs, (v, a, j))
        assert found[0] <= 1.0 + SLACK and found[1] <= 1.0 + SLACK and found[2] <= 1.25, found


@st.composite
def trapezoid_moves(draw):
    start, target, limits, fraction, _ = draw(ptp_moves())
    return start, target, limits, fraction


@PROPERTY
@given(trapezoid_moves())
def test_property_trapezoidal_ptp_references_keep_velocity_and_acceleration(move):
    start, target, (v, a, j), fraction = move
    result, trajectory, message = plan_ptp(PtpInput(start, target, tuple(x * fraction for x in v),
                                                    tuple(x * fraction for x in a)))
    assert result >= 0, message
    assume(trajectory.duration < 20.0)
    _, refs, _ = references(trajectory, trajectory.start_position, (v, a, j), trajectory.sample_accelerations)
    assert_within(refs, (v, a, j), orders=(0, 1))


# ---------------------------------------------------------------------------- blends

@PROPERTY
@given(st.tuples(st.lists(st.floats(-100.0, 100.0), min_size=6, max_size=6),
                 st.lists(st.floats(-40.0, 40.0), min_size=6, max_size=6),
                 st.lists(st.floats(-40.0, 40.0), min_size=6, max_size=6),
                 st.floats(0.6, 1.0), st.floats(0.05, 0.45)))
def test_property_blends_that_keep_the_limits_stay_within_them(case):
    """Two jerk-limited moves superposed (as the trajectory generator blends them), where
    the superposition itself keeps the limits (the blend check accepts only those): the
    references keep them too."""
    q0, d1, d2, fraction, overlap = case
    q1 = [x + d for x, d in zip(q0, d1)]
    q2 = [x + d for x, d in zip(q1, d2)]
    v, a, j = LOLA
    scaled = ([x * fraction for x in v], [x * fraction ** 2 for x in a], [x * fraction ** 3 for x in j])
    _, first, _ = plan_ptp_jerk(q0, q1, *scaled, synchronization="auto")
    _, second, _ = plan_ptp_jerk(q1, q2, *scaled, synchronization="auto")
    assume(first.duration > 0.0 and second.duration > 0.0)
    offset = max(1, int(first.duration / H) - int(overlap * first.duration / H)) * H

    def sample(t):
        p, w = first.sample(t)
        pp, ww = second.sample(t - offset)
        return tuple(x + y - c for x, y, c in zip(p, pp, q1)), tuple(x + y for x, y in zip(w, ww))

    def accelerations(t):
        return tuple(x + y for x, y in zip(first.sample_accelerations(t), second.sample_accelerations(t - offset)))

    blend = types.SimpleNamespace(duration=offset + second.duration, sample=sample)
    true = np.array([sample(ms / 1000.0)[0] for ms in range(-10, int(blend.duration * 1000) + 15)])
    assume(max(ratios(true, LOLA)) <= 1.0)
    _, refs, _ = references(blend, tuple(q0), LOLA, accelerations)
    assert_within(refs, LOLA)


# ---------------------------------------------------------------------------- lin / circ

@settings(PROPERTY, max_examples=12)
@given(st.integers(0, 10 ** 6))
def test_property_lin_and_circ_references_with_exact_derivatives_keep_the_limits(seed):
    """Lin and circ moves of the Lola 15 (drawn as benchmarks/lin_limits.py draws them),
    timed at 0.9 of the joint limits, with exact velocities and accelerations in the
    setpoints: velocity and acceleration within the limits; the jerk within 0.1 of the
    limit above the move's own (its positions every 1 ms: the path itself reaches 1.10 of
    a joint's jerk limit between the check's samples; the interpolation, not a polynomial
    there, adds at most 0.08, measured over 450 moves)."""
    import random
    import sys
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import lin_limits
    from runtime.motion.kinematics import Kinematics

    kin = Kinematics(SPEC)
    rng = random.Random(seed)
    for _ in range(50):
        drawn = lin_limits.random_move(rng, kin, SPEC, rng.random() < 0.5)
        if drawn is None:
            continue
        q0, kind, move = drawn
        stream, _ = lin_limits.plan(kin, SPEC, q0, kind, move)
        if stream is not None:
            break
    assume(stream is not None and stream.duration < 4.0)
    main = tuple(lim[:6] for lim in LOLA)

    class Exact:
        duration = stream.duration

        @staticmethod
        def sample(t):
            return stream.position_at(t)[:6] if 0.0 < t < stream.duration else stream.sample(t)[0][:6], \
                lin_limits.exact_derivatives(stream, t)[0]

    _, refs, _ = references(Exact, tuple(q0), main, lambda t: lin_limits.exact_derivatives(stream, t)[1])
    own = np.array([stream.position_at(ms / 1000.0)[:6] for ms in range(-10, int(stream.duration * 1000) + 15)])
    assert_within(refs, main, orders=(0, 1))
    assert ratios(refs, main)[2] <= ratios(own, main)[2] + 0.1


# ---------------------------------------------------------------------------- exactness

@PROPERTY
@given(ptp_moves())
def test_property_references_hit_the_setpoints_and_are_continuous_in_acceleration(move):
    trajectory = plan_jerk(move)
    assume(trajectory.duration < 10.0)
    interp = Interpolator(trajectory.start_position, move[2])
    previous = None  # the segments of the interval before, and its 1 / h
    for k in range(int(math.ceil(trajectory.duration / H)) + 3):
        t = (5 * k) / 1000.0
        p, v = trajectory.sample(t)
        interp.push(t, p, v, trajectory.sample_accelerations(t))
        if k == 0:
            continue
        knot = (5 * (k - 1)) / 1000.0
        assert interp.sample(knot) == trajectory.sample(knot)[0]  # the reference at a setpoint is the setpoint
        segments, s, inv_h = interp.segment(knot)
        assert s == 0.0
        if previous is not None:  # the interval before ends where this one starts
            old, old_inv_h = previous
            for i, (c_old, c_new) in enumerate(zip(old, segments)):
                scale = 1.0 + abs(c_new[0])
                assert kernels_source.segment_position(c_old, 1.0) == pytest.approx(
                    kernels_source.segment_position(c_new, 0.0), abs=64 * EPS * scale)
                assert kernels_source.segment_velocity(c_old, 1.0, old_inv_h) == pytest.approx(
                    kernels_source.segment_velocity(c_new, 0.0, inv_h), abs=1e-9 * scale)
                assert kernels_source.segment_acceleration(c_old, 1.0, old_inv_h) == pytest.approx(
                    kernels_source.segment_acceleration(c_new, 0.0, inv_h), abs=1e-6 * scale * move[2][1][i] * inv_h)
        previous = (segments, inv_h)


def test_setpoints_without_accelerations_are_interpolated_as_before():
    """A 3-tuple setpoint (or a mix): the cubic Hermite polynomial, the same as before."""
    interp = Interpolator((0.0,), ((156.0,), (400.0,), (4000.0,)))
    interp.push(0.0, (0.0,), (1.0,))
    interp.push(0.005, (0.01,), (3.0,), (100.0,))  # a mix: no acceleration at the first
    for u in (0.2, 0.4, 0.6, 0.8):
        h01, h10, h11 = 3 * u * u - 2 * u ** 3, u ** 3 - 2 * u * u + u, u ** 3 - u * u
        assert interp.sample(0.005 * u)[0] == pytest.approx(0.01 * h01 + 0.005 * (1.0 * h10 + 3.0 * h11), abs=1e-15)
    # both with accelerations: C2, and exact on a cubic (constant jerk)
    def cubic(t):
        return (0.01 + 3.0 * t + 50.0 * t * t + 500.0 * t ** 3,), (3.0 + 100.0 * t + 1500.0 * t * t,), \
            (100.0 + 3000.0 * t,)

    interp.reset((0.0,))
    for t in (0.0, 0.005, 0.010):
        interp.push(t, *cubic(t))
    for t in (0.005, 0.006, 0.0075, 0.0099):
        assert interp.sample(t)[0] == pytest.approx(cubic(t)[0][0], abs=1e-15)
        assert interp.sample_velocity(t)[0] == pytest.approx(cubic(t)[1][0], abs=1e-11)
        assert interp.sample_acceleration(t)[0] == pytest.approx(cubic(t)[2][0], abs=1e-7)


# ---------------------------------------------------------------------------- mutations

MUTATIONS = {
    "the quintic only": ("    if limited and hard <= top and rj <= top:\n        return best\n",
                         "    return best\n"),
    "no one-switch spline": ("    if kind == 1:  # one switch of jerk", "    if kind == -1:  # one switch of jerk"),
    "no plateau at the acceleration limit": ("        c = 0.0 if kind <= 3 else al if kind <= 5 else -al\n"
                                             "        if c - c == 0.0:  # (a finite level)",
                                             "        c = 0.0\n        if c - c == 0.0:  # (a finite level)"),
    "a wrong switch": ("                w = (m1 - g1) / (m0 - g1)", "                w = (m1 - g1) / (m0 - g1) * 0.999"),
    "a wrong evaluation": ("    if s > s1:\n        r = s - s1\n        x = x + r * r * (f1 + r * e1)\n        if s > s2:",
                           "    if s > s1:\n        r = s - s1\n        x = x + r * (f1 + r * e1)\n        if s > s2:"),
}


def mutated_kernels(name: str) -> types.ModuleType:
    old, new = MUTATIONS[name]
    text = Path(kernels_source.__file__).read_text(encoding="utf-8")
    assert text.count(old) == 1, name
    module = types.ModuleType(f"mutated kernels ({name})")
    exec(compile(text.replace(old, new), module.__name__, "exec"), module.__dict__)  # noqa: S102
    return module


def worst_over_the_checks() -> list[float]:
    """The checks above on a fixed set: full-limit jerk PTP moves (one with a stretch at the
    acceleration limit shorter than a period), and trapezoidal ones (velocity and
    acceleration only)."""
    worst = [0.0, 0.0, 0.0]
    v, a, j = 156.0, 400.0, 4000.0
    t_j = a / j
    limits = ((v,), (a,), (j,))
    # a cruise; a stretch at the acceleration limit shorter than a period; a triangle of acceleration
    for distance in (100.0, a * (t_j + 0.002) * (2 * t_j + 0.002), 5.0):
        for delay in (0.0, 0.0013):
            _, trajectory, _ = plan_ptp_jerk([0.0], [distance], [v], [a], [j])
            shifted = types.SimpleNamespace(duration=trajectory.duration + delay,
                                            sample=lambda t, tr=trajectory, d=delay: tr.sample(t - d))
            _, refs, _ = references(shifted, (0.0,), limits,
                                    lambda t, tr=trajectory, d=delay: tr.sample_accelerations(t - d))
            worst = [max(x, y) for x, y in zip(worst, ratios(refs, limits))]
    for distance in (100.0, 30.0):
        _, trajectory, _ = plan_ptp(PtpInput((0.0,), (distance,), (v,), (a,)))
        _, refs, _ = references(trajectory, (0.0,), limits, trajectory.sample_accelerations)
        worst[:2] = [max(x, y) for x, y in zip(worst[:2], ratios(refs, limits)[:2])]
    return worst


def test_the_checks_pass_on_the_interpolant_itself():
    assert max(worst_over_the_checks()) <= 1.0 + SLACK


@pytest.mark.parametrize("name", sorted(MUTATIONS))
def test_a_mutation_of_the_interpolant_fails_the_checks(name, monkeypatch):
    monkeypatch.setattr(interpolator_module, "kernels", mutated_kernels(name))
    assert max(worst_over_the_checks()) > 1.0 + SLACK


def test_the_servo_takes_setpoints_with_and_without_accelerations():
    """desi_pos carries (t, positions, velocities) or (t, positions, velocities,
    accelerations); the servo interpolates both (C1 between a mix), within the limits."""
    from runtime.loop.component import DataPort
    from runtime.loop.components.servo import ServoController

    ports = {name: DataPort(name) for name in ("sens_pos", "desi_pos", "init_pos", "out_vel")}
    servo = ServoController(SPEC, ports["sens_pos"], ports["desi_pos"], ports["init_pos"], ports["out_vel"],
                            Interpolator)
    n = len(SPEC.axes)
    ports["sens_pos"].write((0.0,) * n, 0.0)
    servo.set_mode("trajectory")
    assert servo.interpolator._limits == LOLA
    _, trajectory, _ = plan_ptp_jerk((0.0,) * n, (30.0, -20.0, 10.0, 5.0, 0.0, -5.0), *LOLA)
    references_ = []
    for ms in range(0, int(trajectory.duration * 1000) + 20):
        now = ms / 1000.0
        if ms % 5 == 0:
            p, v = trajectory.sample(now)
            value = (now, p, v) if ms < 100 else (now, p, v, trajectory.sample_accelerations(now))
            ports["desi_pos"].write(value, now)
        ports["sens_pos"].write(servo.reference, now)  # a perfect drive
        servo.update(now)
        references_.append(servo.reference)
    assert servo.reference == trajectory.target_position
    assert_within(np.array(references_), LOLA, orders=(0, 1))
