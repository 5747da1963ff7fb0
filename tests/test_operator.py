"""Operator control inside one robot (in-process, simulated clock): cycles that remember
calibration and initialization, pause that stops a PTP move on its path and resume that
finishes it, abort, emergency stop, speed override, reconfiguration between programs,
and the executive's schedule changes."""
from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from compiler.driver import compile_file
from runtime.loop.executive import Executive, SimClock
from runtime.motion.stops import REST_VELOCITY, StopRamp
from runtime.loop.supervisor import MOVE, RECONFIGURE, STOP
from runtime.loop.system import RobotSystem, RunOptions

from conftest import ROOT, examples
PAPER = compile_file(ROOT / "programs" / "test.irl")
SPEC = PAPER.spec
COUNTS = [1.0 / a.counts_per_unit for a in SPEC.axes]


def states(summary: dict) -> list[str]:
    return [s["name"] for s in summary["states"]]


@pytest.fixture()
def system():
    return RobotSystem(SPEC, RunOptions(seed=2))


def to_move(system, extra_ticks: int = 0):
    ex, sup = system.executive, system.supervisor
    ex.run(lambda: sup.fsm.state == MOVE, 10**6)
    ex.run(lambda: False, extra_ticks)


def finish(system) -> dict:
    system.executive.run(lambda: system.supervisor.done, 10**6)
    return system.finish()


def on_segment(point, start, end, tolerance) -> bool:
    """Is ``point`` on the joint-space segment start -> end (within ``tolerance`` per axis)?"""
    direction = [e - s for s, e in zip(start, end)]
    length2 = sum(d * d for d in direction)
    u = sum((p - s) * d for p, s, d in zip(point, start, direction)) / length2
    return -1e-9 <= u <= 1 + 1e-9 and all(abs(s + u * d - p) <= tolerance
                                          for p, s, d in zip(point, start, direction))


def along(point, origin, direction, tolerance=1e-9) -> bool:
    """Is ``point - origin`` a non-negative multiple of ``direction``?"""
    k = max(range(len(direction)), key=lambda i: abs(direction[i]))
    scale = (point[k] - origin[k]) / direction[k]
    return scale >= 0 and all(abs(o + scale * d - p) <= tolerance for p, o, d in zip(point, origin, direction))


def test_a_second_cycle_remembers_calibration_and_initialization(system):
    system.begin(PAPER.program)
    first = finish(system)
    assert first["fault"] is None
    assert states(first) == ["Start Robot", "Calibrate Offsets", "Initialization Sequence", MOVE, STOP]
    system.begin(PAPER.program)
    second = finish(system)
    assert second["fault"] is None
    assert states(second) == ["Start Robot", MOVE, STOP]
    assert [m["line"] for m in second["moves"]] == [m["line"] for m in first["moves"]]
    for x, target in zip(second["final_position"], (45, -45, 45, 0, 0, 0)):
        assert abs(x - target) <= 2 * max(COUNTS)


def test_pause_comes_to_a_controlled_stop_and_resume_finishes_the_move(system):
    system.begin(PAPER.program)
    to_move(system, 700)  # mid first move: (0..) -> (45, 0, -45, 0, 0, 0)
    tg = system.trajectory
    start, target = tg.trajectory.start_position, tg.trajectory.target_position
    assert any(abs(v) > 1.0 for v in tg.motion.velocities)
    line = tg.line
    at_pause, moving = tg.motion.positions, tg.motion.velocities
    assert tg.pause()
    assert tg.paused
    ex = system.executive
    ex.run(lambda: tg.trajectory is None, 10**5)
    stopped = tg.motion.positions
    assert all(v == 0.0 for v in tg.motion.velocities)
    assert along(stopped, at_pause, moving)  # the setpoints stop along the direction of motion
    assert on_segment(stopped, start, target, 1e-9)  # here A1 and A3 share one shape: on the path
    assert 0 < abs(stopped[0]) < 45
    ex.run(lambda: False, 500)  # stays paused: no new setpoints, the robot holds
    assert tg.motion.positions == stopped and tg.line == line
    assert all(abs(x - s) <= 10 * c for x, s, c in zip(system.robot.positions, stopped, COUNTS))
    assert tg.resume() and not tg.paused
    summary = finish(system)
    assert summary["fault"] is None
    assert len(summary["moves"]) == 3
    for x, want in zip(summary["final_position"], (45, -45, 45, 0, 0, 0)):
        assert abs(x - want) <= 2 * max(COUNTS)


def test_the_stop_ramp_keeps_within_the_deceleration_limit():
    ramp = StopRamp((1.0, 2.0, 3.0), (10.0, -5.0, 0.0), (40.0, 40.0, 40.0))
    assert ramp.duration == pytest.approx(0.25)
    assert ramp.sample(ramp.duration) == (ramp.target_position, (0.0, 0.0, 0.0))
    assert ramp.target_position == pytest.approx((1.0 + 1.25, 2.0 - 0.625, 3.0))
    p, v = ramp.sample(0.1)
    assert v == pytest.approx((6.0, -3.0, 0.0))
    resting = StopRamp((1.0, 2.0), (0.0, 0.0), (40.0, 40.0))
    assert resting.duration == 0.0 and resting.sample(0.0) == ((1.0, 2.0), (0.0, 0.0))


# velocities of an axis: any, subnormal ones (2.2e-311) and the rest threshold's neighbours
# included: a subnormal velocity once gave a subnormal stop time whose fractions lost their
# precision (the stop is now at rest below REST_VELOCITY)
VELOCITIES = st.one_of(st.floats(-200, 200), st.sampled_from([0.0, -0.0, 2.2e-311, -5e-324, REST_VELOCITY,
                                                              REST_VELOCITY * 0.999, -REST_VELOCITY]))


@settings(max_examples=examples(100), deadline=None, derandomize=True, database=None)
@given(st.lists(st.tuples(VELOCITIES, st.floats(0.5, 500)), min_size=1, max_size=6))
def test_property_stop_ramp_respects_every_axis_limit_and_stays_proportional(axes):
    v0 = tuple(v for v, _ in axes)
    a_max = tuple(a for _, a in axes)
    ramp = StopRamp((0.0,) * len(axes), v0, a_max)
    _, start = ramp.sample(0.0)
    for v, v_start, a in zip(v0, start, a_max):
        assert v_start == (v if abs(v) >= REST_VELOCITY else 0.0)  # (slower is rest)
        assert abs(v_start) / ramp.duration <= a * (1 + 1e-12) if ramp.duration > 0 else v_start == 0.0
    for k in range(11):
        t = ramp.duration * k / 10
        pos, vel = ramp.sample(t)
        for v, v_now, x in zip(v0, vel, pos):  # every axis keeps the same fraction of its start velocity
            assert math.isclose(v_now, v * (1 - k / 10), rel_tol=1e-9, abs_tol=1e-9)
            assert math.isclose(x, v * t * (1 - k / 20), rel_tol=1e-9, abs_tol=1e-9)  # (its integral)
    assert ramp.sample(ramp.duration)[1] == (0.0,) * len(axes)


def test_abort_stops_then_ends_with_the_operator_named(system):
    system.begin(PAPER.program)
    to_move(system, 700)
    tg = system.trajectory
    at_abort, moving = tg.motion.positions, tg.motion.velocities
    assert tg.abort()
    system.executive.run(lambda: tg.trajectory is None, 10**5)
    assert along(tg.motion.positions, at_abort, moving)
    summary = finish(system)
    assert summary["fault"] == "Move Robot: aborted by the operator at line 4"
    assert states(summary)[-1] == STOP
    assert summary["max_following_error"] < SPEC.controller.following_error_limit


def test_emergency_stop_applies_the_brakes_and_ends_the_cycle(system):
    system.begin(PAPER.program)
    to_move(system, 700)
    system.emergency_stop()
    summary = finish(system)
    assert "emergency stop" in summary["fault"]
    assert system.backend.brakes_applied()
    assert not system.servo.running and not system.robot.running


def test_override_slows_the_moves_planned_afterwards(system):
    system.begin(PAPER.program)
    full = finish(system)
    system.begin(PAPER.program)
    system.trajectory.override = 50.0
    half = finish(system)
    assert half["fault"] is None
    # the same moves (the first starts where the last program ended, so it differs): v * p and
    # a * p^2 take twice as long, up to the small velocity margin the planner keeps for the
    # interpolator (it scales with the acceleration)
    for a, b in zip(full["moves"][1:], half["moves"][1:]):
        assert b["planned_duration"] == pytest.approx(2 * a["planned_duration"], rel=2e-3)


def test_a_reconfiguration_cycle_applies_settings_with_the_brakes_on(system):
    system.begin(PAPER.program)
    finish(system)
    settings_before = system.settings()
    new = {"servo": {"kp": 25.0}, "report": {"period": 0.02, "columns": ["sens_pos", "out_vel"]},
           "trajectory": {"period": 0.01}, "initialization": {"period": 0.01}}
    system.begin(None, None, settings=new)
    summary = finish(system)
    assert summary["fault"] is None
    assert states(summary) == ["Start Robot", RECONFIGURE, STOP]
    assert system.backend.brakes_applied()
    now = system.settings()
    assert now["servo"]["kp"] == 25.0 and now["servo"]["ki"] == settings_before["servo"]["ki"]
    assert now["report"] == {"period": 0.02, "columns": ["sens_pos", "out_vel"]}
    assert system.servo.setpoint_period == 0.01
    assert system.report.header() == ["time", "state"] + [f"{k}_{a.name}" for k in ("sens_pos", "out_vel")
                                                           for a in SPEC.axes]
    system.begin(PAPER.program)  # and a program still runs, at the new periods
    after = finish(system)
    assert after["fault"] is None
    runs = {name: s["runs"] for name, s in after["deadlines"].items()}
    assert runs["report"] > 0


def test_executive_periods_can_change_and_the_schedule_follows():
    ex = Executive(SimClock(0.001), 0.001)
    calls = {"a": 0, "b": 0}
    ex.add("a", lambda now: calls.__setitem__("a", calls["a"] + 1), 0.001, "sense")
    ex.add("b", lambda now: calls.__setitem__("b", calls["b"] + 1), 0.005, "plan")
    ex.run(lambda: False, 100)
    assert calls == {"a": 100, "b": 20}
    ex.set_period("b", 0.01)
    ex.run(lambda: False, 100)
    assert calls == {"a": 200, "b": 30}
    with pytest.raises(ValueError):
        ex.set_period("b", 0.0015)
    with pytest.raises(KeyError):
        ex.set_period("nope", 0.001)


def test_resync_skips_to_the_clock_instead_of_catching_up():
    clock = SimClock(0.001)
    ex = Executive(clock, 0.001)
    ex.add("a", lambda now: None, 0.001, "sense")
    ex.run(lambda: False, 10)
    clock.ticks = 500  # time passed while nothing was stepped
    ex.resync()
    assert ex.ticks == 500


class _WallLike:
    """The simulated clock, presented as a wall clock (``simulated`` False): the
    trajectory generator then plans Cartesian moves on a thread of their own."""

    simulated = False

    def __init__(self, clock):
        self._clock = clock

    def now(self) -> float:
        return self._clock.now()

    @property
    def tick_time(self) -> float:
        return self._clock.tick_time


def test_on_the_wall_clock_cartesian_moves_are_planned_off_the_loop(system, monkeypatch):
    from runtime.motion import motionqueue as tg_module

    source = ('program linbg;\nsystem_specification "lola15.spc";\nseq\n'
              "  move ptp joint(mainjoint(0, -30, 30, 0, 45, 0));\n"
              "  move lin pose(pos(900, 150, 900), rpy(180, 30, 180)) speed := 200;\n"
              "  move lin pose(pos(0, 0, 1800), rpy(180, 0, 180));\n"  # through a singularity: refused
              "endseq\nendprogram;\n")
    from compiler.driver import compile_source

    result = compile_source(source, "linbg.irl", ROOT / "programs" / "lola15.spc")
    assert result.ok, result.diagnostics
    system.trajectory.clock = _WallLike(system.clock)
    started = []
    real_job = tg_module._PlanningJob

    class CountingJob(real_job):
        def __init__(self, plan, move):
            started.append(move)
            super().__init__(plan, move)

    monkeypatch.setattr(tg_module, "_PlanningJob", CountingJob)
    system.begin(result.program)
    summary = finish(system)
    # every move (and its blend check) is planned on a planning thread, in program order
    assert [request.kind for request in started] == ["ptp", "lin", "lin"]
    assert [m["line"] for m in summary["moves"]] == [4, 5]
    assert "line 6" in summary["fault"] and "move lin refused" in summary["fault"]


LIN_PROGRAM = ('program linpause;\nsystem_specification "lola15.spc";\nseq\n'
               "  move ptp joint(mainjoint(0, -30, 30, 0, 45, 0));\n"
               "  move lin pose(pos(900, 150, 900), rpy(180, 30, 180)) speed := 100;\n"
               "endseq\nendprogram;\n")


def _distance_from_segment(p, a, b) -> float:
    d = [y - x for x, y in zip(a, b)]
    u = sum((pi - ai) * di for pi, ai, di in zip(p, a, d)) / sum(di * di for di in d)
    u = min(max(u, 0.0), 1.0)
    return math.dist(p, [ai + u * di for ai, di in zip(a, d)])


def test_pause_of_a_lin_move_stops_on_the_line_and_resume_finishes_it(system):
    from compiler.driver import compile_source
    from runtime.motion.kinematics import Kinematics

    result = compile_source(LIN_PROGRAM, "linpause.irl", ROOT / "programs" / "lola15.spc")
    assert result.ok, result.diagnostics
    kin = Kinematics(SPEC)
    system.begin(result.program)
    to_move(system)
    tg, ex = system.trajectory, system.executive
    ex.run(lambda: tg.line == 5 and tg.trajectory is not None, 10**5)
    start = kin.forward(tg.trajectory.checked.start_joints)[:3]
    end = (900.0, 150.0, 900.0)
    ex.run(lambda: False, 1500)  # well into the line
    assert tg.pause()
    seen = []
    while tg.trajectory is not None:
        ex.run(lambda: False, 5)
        seen.append(kin.forward(tg.motion.positions)[:3])
    for p in seen:  # every setpoint of the stop is on the line
        assert _distance_from_segment(p, start, end) < 1e-6, p
    stopped = seen[-1]
    assert 10.0 < math.dist(stopped, start) and math.dist(stopped, end) > 10.0
    ex.run(lambda: False, 300)
    assert kin.forward(tg.motion.positions)[:3] == pytest.approx(stopped, abs=1e-9)  # held
    assert tg.resume()
    rest = []
    while not tg.motion_done():
        ex.run(lambda: False, 5)
        rest.append(kin.forward(tg.motion.positions)[:3])
    for p in rest:
        assert _distance_from_segment(p, start, end) < 1e-6, p
    summary = finish(system)
    assert summary["fault"] is None
    assert len(summary["moves"]) == 2
    assert math.dist(kin.forward(summary["final_position"])[:3], end) < 0.5


def test_override_changed_during_a_move_is_a_smooth_monotonic_transition(system):
    system.begin(PAPER.program)
    to_move(system, 0)
    tg, ex = system.trajectory, system.executive
    ex.run(lambda: tg.line == 5 and tg.trajectory is not None, 10**5)  # the 90 deg move
    ex.run(lambda: False, 2500)  # into its cruise
    v_cruise = abs(tg.motion.velocities[0])
    assert v_cruise > 10.0
    tg.override = 50.0
    assert tg.override == 50.0 and tg.motion.rate == 1.0  # the transition starts, no jump
    speeds = []
    while tg.motion.rate != 0.5:
        ex.run(lambda: False, 5)
        speeds.append(abs(tg.motion.velocities[0]))
    ex.run(lambda: False, 50)
    speeds.append(abs(tg.motion.velocities[0]))
    assert all(b <= a + 1e-9 for a, b in zip(speeds, speeds[1:]))  # monotonic: no overshoot
    assert speeds[-1] == pytest.approx(0.5 * v_cruise, rel=1e-9)
    a_max = SPEC.axes[0].max_acceleration * 0.1  # the move's acc_ptp
    steps = [abs(b - a) / 0.005 for a, b in zip(speeds, speeds[1:])]
    assert max(steps) <= a_max * 1.01  # the change of speed stays within the move's deceleration
    summary = finish(system)
    assert summary["fault"] is None
    for x, want in zip(summary["final_position"], (45, -45, 45, 0, 0, 0)):
        assert abs(x - want) <= 2 * max(COUNTS)


# ---- every 5 ms setpoint of random PTP programs within the axis limits -----------------------

_LIMITS_SYSTEM: list = []


def _limits_system():
    if not _LIMITS_SYSTEM:
        _LIMITS_SYSTEM.append(RobotSystem(SPEC, RunOptions(seed=5)))
    return _LIMITS_SYSTEM[0]


def _program(targets, fractions) -> bytes:
    lines = "".join(f"  move ptp joint(mainjoint({', '.join(f'{v:.3f}' for v in t)})) "
                    f"speed_ptp := {s:.3f} acc_ptp := {a:.3f};\n" for t, (s, a) in zip(targets, fractions))
    return f'program limits;\nsystem_specification "lola15.spc";\nseq\n{lines}endseq\nendprogram;\n'


_joint = st.tuples(*[st.floats(max(a.min, -120.0), min(a.max, 120.0)) for a in SPEC.axes])
_fraction = st.tuples(st.floats(0.05, 1.0), st.floats(0.05, 1.0))


@settings(max_examples=12, deadline=None, derandomize=True)
@given(st.lists(st.tuples(_joint, _fraction), min_size=1, max_size=3))
def test_property_every_setpoint_of_random_ptp_programs_keeps_the_limits(moves):
    """The 5 ms setpoint stream (what the servo interpolates), differentiated: velocity,
    acceleration and jerk within each axis's limits scaled by the move's fractions (the
    differences of exact samples of a limited profile are bounded by the limits)."""
    from compiler.driver import compile_source

    result = compile_source(_program([m[0] for m in moves], [m[1] for m in moves]), "limits.irl",
                            ROOT / "programs" / "lola15.spc")
    assert result.ok, result.diagnostics
    system = _limits_system()
    tg = system.trajectory
    samples = []
    (task,) = [t for t in system.executive.tasks if t.name == "trajectory"]
    real_update = task.run

    def recording(now):
        real_update(now)
        samples.append((tg.line, tg.motion.positions))

    task.run = recording
    try:
        system.begin(result.program)
        summary = finish(system)
    finally:
        task.run = real_update
    assert summary["fault"] is None, summary["fault"]
    checked = 0
    h = 0.005
    fractions = {4 + i: (round(sp, 3), round(ac, 3)) for i, (_t, (sp, ac)) in enumerate(moves)}  # as written
    for k in range(3, len(samples)):
        line = samples[k][0]
        if line not in fractions or any(samples[k - j][0] != line for j in range(1, 4)):
            continue  # only within one move (its limits)
        speed, acc = fractions[line]
        p0, p1, p2, p3 = (samples[k - j][1] for j in (3, 2, 1, 0))
        for i, axis in enumerate(SPEC.axes):
            v = (p3[i] - p2[i]) / h
            a = (p3[i] - 2 * p2[i] + p1[i]) / h ** 2
            j = (p3[i] - 3 * p2[i] + 3 * p1[i] - p0[i]) / h ** 3
            assert abs(v) <= axis.max_velocity * speed * (1 + 1e-6) + 1e-6, (line, i, v)
            assert abs(a) <= axis.max_acceleration * acc * (1 + 1e-6) + 1e-3, (line, i, a)
            assert abs(j) <= axis.max_jerk * acc * (1 + 1e-6) + 1.0, (line, i, j)
        checked += 1
    assert checked >= 20 * len(moves) or all(m["planned_duration"] < 0.2 for m in summary["moves"]), checked


def test_a_ptp_pause_is_a_jerk_limited_stop_on_the_line(system):
    system.begin(PAPER.program)
    to_move(system, 700)
    tg, ex = system.trajectory, system.executive
    assert tg.trajectory.synchronization == "line"
    start, target = tg.trajectory.start_position, tg.trajectory.target_position
    samples = [tg.motion.positions]
    tg.pause()
    while tg.trajectory is not None:
        ex.run(lambda: False, 5)
        samples.append(tg.motion.positions)
    ex.run(lambda: False, 20)
    samples.append(tg.motion.positions)
    h = 0.005
    for p in samples:
        assert on_segment(p, start, target, 1e-9)
    for k in range(3, len(samples)):
        for i, axis in enumerate(SPEC.axes):
            jerk = (samples[k][i] - 3 * samples[k - 1][i] + 3 * samples[k - 2][i] - samples[k - 3][i]) / h ** 3
            assert abs(jerk) <= axis.max_jerk * 0.1 * (1 + 1e-6) + 1e-3, (k, i, jerk)  # acc_ptp 0.1
