"""The motion queue alone (runtime.motion.motionqueue): no component, no port, no VM.

A queue of the lola15 arm's moves is sampled every 5 ms as the trajectory generator does;
the examples check what it records and where it ends, and a stateful property test drives
it with random sequences of moves (ptp, lin, blends), pauses, resumes, overrides and
aborts, and checks every setpoint against the axis limits.
"""
from __future__ import annotations

import math
import time

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from compiler.values import Joint
from runtime.motion.kinematics import Kinematics
from runtime.motion.motionqueue import MotionQueue, PlanningWorker
from runtime.motion.moves import MovePlanner, MoveRequest
from runtime.motion.interpolator import Interpolator
from runtime.timing import SETPOINT_PERIOD, TICK

from conftest import ROOT, SPEC, examples
KIN = Kinematics(SPEC)
START = (0.0, -30.0, 30.0, 0.0, 45.0, 0.0)
VMAX = [a.max_velocity for a in SPEC.axes]
AMAX = [a.max_acceleration for a in SPEC.axes]
#: Sampling steps a test gives a queue before it must be done (about 5 simulated minutes).
BUDGET = 60_000


def make_queue(worker=None, profile: str = "jerk") -> MotionQueue:
    planner = MovePlanner(SPEC.axes, SPEC.main_axes, profile, KIN)
    queue = MotionQueue(planner, SPEC.axes, worker=worker)
    queue.start(START, SETPOINT_PERIOD)
    return queue


def ptp(joints, line: int, speed: float = 0.5, acc: float = 0.5, approx: float = 0.0) -> MoveRequest:
    return MoveRequest("ptp", (Joint(tuple(joints)),), speed, acc, approx, line)


def lin(dx: float, dy: float, dz: float, line: int, speed: float = 250.0, acc: float = 1000.0,
        approx: float = 0.0) -> MoveRequest:
    x, y, z, r, p, w = KIN.forward(START)
    return MoveRequest("lin", ((x + dx, y + dy, z + dz, r, p, w),), speed, acc, approx, line)


class Run:
    """Samples a queue every period, as the trajectory generator does, keeping the
    setpoints."""

    def __init__(self, queue: MotionQueue):
        self.queue = queue
        self.now = 0.0
        self.setpoints = [(0.0, queue.positions, queue.velocities)]

    def step(self, n: int = 1) -> None:
        for _ in range(n):
            self.now += SETPOINT_PERIOD
            self.queue.sample(self.now)
            self.setpoints.append((self.now, self.queue.positions, self.queue.velocities))

    def until(self, condition, budget: int = BUDGET) -> None:
        for _ in range(budget):
            if condition():
                return
            self.step()
        raise AssertionError("the queue did not get there")

    def ratios(self) -> tuple[float, float]:
        """The largest setpoint velocity and velocity change (per second) against the axis
        limits: what tests/limits_watch.py measures of the whole runtime."""
        velocity = acceleration = 0.0
        for (t0, _p0, v0), (t1, _p1, v1) in zip(self.setpoints, self.setpoints[1:]):
            for i, (a, b) in enumerate(zip(v0, v1)):
                velocity = max(velocity, abs(b) / VMAX[i])
                acceleration = max(acceleration, abs(b - a) / (t1 - t0) / AMAX[i])
        return velocity, acceleration


def test_moves_run_in_order_and_are_recorded():
    queue = make_queue()
    run = Run(queue)
    a, b = (30.0, -20.0, 40.0, 10.0, 30.0, 5.0), (-10.0, -40.0, 60.0, 0.0, 60.0, -20.0)
    assert queue.add(ptp(a, 1)) is None and queue.add(ptp(b, 2)) is None
    assert queue.queued == 2 and not queue.done()
    run.until(queue.done)
    assert queue.positions == b and queue.velocities == (0.0,) * 6
    assert [(m.line, m.kind, m.blended) for m in queue.moves] == [(1, "ptp", False), (2, "ptp", False)]
    assert queue.completed == 2
    for m in queue.moves:  # actual duration within a period of the planned one
        assert abs(m.actual_duration - m.planned_duration) <= SETPOINT_PERIOD + 1e-9
    assert max(run.ratios()) <= 1.0 + 1e-6


def test_a_blend_does_not_stop_at_the_corner():
    queue = make_queue()
    run = Run(queue)
    corner = (30.0, -20.0, 40.0, 10.0, 30.0, 5.0)
    queue.add(ptp(corner, 1, approx=1.0))
    queue.add(ptp((60.0, -40.0, 60.0, 20.0, 50.0, 10.0), 2))
    run.until(queue.done)
    assert queue.moves[0].blended
    speeds = [max(abs(v) for v in s[2]) for s in run.setpoints]
    first_move = [i for i, s in enumerate(speeds) if s > 0.0]
    assert all(speeds[i] > 0.0 for i in range(first_move[0], first_move[-1]))  # never at rest on the way
    assert max(run.ratios()) <= 1.0 + 1e-6


def test_pause_inside_a_blend_stops_on_the_blend_and_resume_finishes_it():
    queue = make_queue()
    run = Run(queue)
    queue.add(ptp((30.0, -20.0, 40.0, 10.0, 30.0, 5.0), 1, approx=1.0))
    end = (60.0, -40.0, 60.0, 20.0, 50.0, 10.0)
    queue.add(ptp(end, 2))
    segs = queue._segments
    run.until(lambda: len(segs) > 1 and segs[1].start is not None and queue.t_move > segs[1].start)
    within = queue.pause()
    assert within is not None and within > 0.0
    run.until(queue.at_rest)
    assert queue.rate == 0.0 and queue.velocities == (0.0,) * 6
    assert queue.interrupted is None  # held on the timeline, not a stop of its own
    held = queue.positions
    run.step(50)
    assert queue.positions == held  # stays at rest while paused
    queue.resume()
    run.until(queue.done)
    assert queue.positions == end and max(run.ratios()) <= 1.0 + 1e-6


def test_pause_of_a_lin_move_stops_on_the_line_and_resume_plans_the_rest():
    queue = make_queue()
    run = Run(queue)
    queue.add(lin(0.0, 200.0, -100.0, 1))
    run.step(40)
    queue.pause()
    run.until(lambda: queue.interrupted is not None and queue.current is None)
    stopped = KIN.forward(queue.positions[:6])[:3]
    a, b = KIN.forward(START)[:3], KIN.forward(queue.interrupted.end[:6])[:3]
    d = [q - p for p, q in zip(a, b)]
    u = sum((s - p) * di for s, p, di in zip(stopped, a, d)) / sum(di * di for di in d)
    assert 0.0 < u < 1.0 and math.dist(stopped, [p + u * di for p, di in zip(a, d)]) < 1e-6  # on the line
    queue.resume()
    run.until(queue.done)
    assert math.dist(KIN.forward(queue.positions[:6])[:3], b) < 1e-9
    assert [m.line for m in queue.moves] == [1]  # the rest is the same move


@pytest.mark.parametrize("periods", [0, 20, 60, 200])
def test_a_cut_stops_a_lin_move_on_its_line_drops_the_rest_and_the_next_move_starts_there(periods):
    # a search move that found its input (runtime.loop.search): stop on the path, nothing after it
    queue = make_queue()
    run = Run(queue)
    queue.add(lin(0.0, 200.0, -100.0, 1, speed=100.0))
    queue.add(lin(0.0, 0.0, 0.0, 2))  # (handed over after it: dropped)
    run.step(periods)
    queue.cut()
    run.until(lambda: queue.done())
    assert queue.velocities == (0.0,) * 6 and queue.at_rest() and queue.ended is None and queue.failed is None
    a, b = KIN.forward(START)[:3], KIN.forward(START)[:3]
    b = (b[0], b[1] + 200.0, b[2] - 100.0)
    stopped = KIN.forward(queue.positions[:6])[:3]
    d = [q - p for p, q in zip(a, b)]
    u = sum((s - p) * di for s, p, di in zip(stopped, a, d)) / sum(di * di for di in d)
    assert -1e-9 <= u < 1.0 and math.dist(stopped, [p + u * di for p, di in zip(a, d)]) < 1e-6  # on the line
    assert [m.line for m in queue.moves] == ([1] if periods else [])  # line 2 never ran
    assert max(run.ratios()) <= 1.0 + 1e-6
    queue.add(ptp(START, 3))  # the program goes on from there
    run.until(queue.done)
    assert queue.moves[-1].line == 3 and max(abs(p - q) for p, q in zip(queue.positions, START)) < 1e-9


def test_a_cut_inside_a_blend_stops_on_the_blend_and_nothing_is_held():
    queue = make_queue()
    run = Run(queue)
    queue.add(ptp((30.0, -20.0, 40.0, 10.0, 30.0, 5.0), 1, approx=1.0))
    queue.add(ptp((0.0, 0.0, 0.0, 0.0, 45.0, 0.0), 2))
    run.until(lambda: len(queue.moves) == 2)  # in the blend
    queue.cut()
    run.until(queue.done)
    assert queue.at_rest() and queue.velocities == (0.0,) * 6 and not queue.paused and queue.rate == 1.0
    assert max(run.ratios()) <= 1.0 + 1e-6
    queue.add(ptp(START, 3))
    run.until(queue.done)
    assert queue.moves[-1].line == 3


def test_abort_ends_at_rest_with_the_line():
    queue = make_queue()
    run = Run(queue)
    queue.add(ptp((30.0, -20.0, 40.0, 10.0, 30.0, 5.0), 7))
    queue.add(ptp((0.0, 0.0, 0.0, 0.0, 45.0, 0.0), 8))
    run.step(30)
    assert queue.abort("aborted by the operator") is not None
    assert queue.abort("again") is None  # one abort at a time
    run.until(lambda: queue.ended is not None)
    assert queue.ended == "aborted by the operator at line 7"
    assert queue.velocities == (0.0,) * 6 and queue.done()
    assert max(run.ratios()) <= 1.0 + 1e-6


def test_a_move_that_cannot_be_planned_is_refused_and_drops_the_moves_after_it():
    queue = make_queue()
    assert "outside its limits" in queue.add(ptp((0.0, 0.0, 0.0, 0.0, 130.0, 0.0), 3))
    problem = queue.add(lin(2000.0, 0.0, 0.0, 4))
    assert problem.startswith("move lin refused: ") and "reach" in problem
    assert queue.done() and queue.moves == []


def test_on_a_worker_a_failed_plan_is_reported_by_sample():
    queue = make_queue(worker=PlanningWorker())
    run = Run(queue)
    assert queue.add(ptp((30.0, -20.0, 40.0, 10.0, 30.0, 5.0), 1)) is None
    refused = lin(2000.0, 0.0, 0.0, 2)
    refused.tag = 7  # (the program's name for it: its error handler finds the move by it, runtime.loop.vm)
    assert queue.add(refused) is None
    failed = None
    # (the worker is a thread on the wall clock: on a loaded host it may not plan within any
    # number of these quick steps, so the loop is bounded by real time, not by a count)
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline:
        run.step()
        failed = failed or queue.failed
        queue.failed = None
        if queue.plan_waiting() is not None:
            pytest.fail("no problem is returned with a worker")
        if queue.done():
            break
        if queue.current is None:
            time.sleep(0.001)  # (at rest, waiting for the worker: let it run)
    assert failed is not None and failed[1:] == (2, 7) and "refused" in failed[0]
    assert [m.line for m in queue.moves] == [1]


def test_the_override_slows_the_moves_down():
    def duration(percent: float) -> float:
        queue = make_queue()
        queue.override = percent
        run = Run(queue)
        queue.add(ptp((30.0, -20.0, 40.0, 10.0, 30.0, 5.0), 1))
        run.until(queue.done)
        return run.now

    assert duration(50.0) == pytest.approx(2.0 * duration(100.0), rel=0.02)


# ----------------------------------------------------------------------------- stateful

JOINTS = st.tuples(*(st.floats(lo, hi) for lo, hi in ((-60, 60), (-60, 10), (0, 90), (-90, 90), (20, 90),
                                                      (-90, 90))))
OFFSETS = st.tuples(st.floats(-150, 150), st.floats(-150, 150), st.floats(-150, 150))


class QueueMachine(RuleBasedStateMachine):
    """Random moves, pauses, resumes, overrides and aborts: every setpoint within every
    axis's velocity limit and acceleration limit (setpoint differences, as
    tests/limits_watch.py measures them), inside the position limits, and the queue
    always ends at rest."""

    def __init__(self):
        super().__init__()
        self.queue = make_queue()
        self.run = Run(self.queue)
        self.line = 0
        self.aborts = 0

    def step(self, periods: int) -> None:
        """Sample; an abort that ended starts a new program from where the robot is (as
        the trajectory generator's host does)."""
        for _ in range(periods):
            self.run.step()
            if self.queue.ended is not None:
                self.aborts += 1
                self.queue.start(self.queue.positions, SETPOINT_PERIOD)

    @rule(joints=JOINTS, speed=st.floats(0.05, 1.0), acc=st.floats(0.05, 1.0), approx=st.floats(0.0, 1.0))
    def move_ptp(self, joints, speed, acc, approx):
        self.line += 1
        self.queue.add(ptp(joints, self.line, speed, acc, approx))

    @rule(offset=OFFSETS, speed=st.floats(20.0, 1000.0), acc=st.floats(200.0, 8000.0), approx=st.floats(0.0, 50.0))
    def move_lin(self, offset, speed, acc, approx):
        self.line += 1
        self.queue.add(lin(*offset, self.line, speed, acc, approx))

    @rule(periods=st.integers(1, 400))
    def sample(self, periods):
        self.step(periods)

    @rule(periods=st.integers(0, 200))
    def pause(self, periods):
        self.step(periods)
        queue = self.queue
        for _ in range(2000):  # into the next move, if one is to start
            if queue.current is not None or queue.done() or queue.paused or queue.interrupted is not None:
                break
            self.step(1)
        queue.pause()

    @precondition(lambda self: self.queue.abort_reason is None)
    @rule(periods=st.integers(0, 200))
    def resume(self, periods):
        self.step(periods)
        self.queue.resume()

    @rule(periods=st.integers(0, 200), percent=st.floats(1.0, 100.0))
    def override(self, periods, percent):
        self.step(periods)
        self.queue.override = percent

    @rule(periods=st.integers(0, 400))
    def cut(self, periods):  # a search move found its input
        self.step(periods)
        self.queue.cut()

    @rule(periods=st.integers(0, 400))
    def abort(self, periods):
        self.step(periods)
        self.queue.abort("aborted")

    @invariant()
    def within_the_limits(self):
        velocity, acceleration = self.run.ratios()
        assert velocity <= 1.0 + 1e-9 and acceleration <= 1.0 + 1e-6, (velocity, acceleration)
        for axis, p in zip(SPEC.axes, self.queue.positions):
            assert axis.min - 1e-9 <= p <= axis.max + 1e-9
        self.run.setpoints = self.run.setpoints[-1:]

    def teardown(self):
        queue = self.queue
        queue.override = 100.0  # (at 1 %, the moves take a hundred times longer)
        if queue.abort_reason is None:
            queue.resume()
        self.run.until(lambda: queue.done() or queue.ended is not None)
        self.run.step(2)
        assert queue.velocities == (0.0,) * 6 and queue.at_rest()
        velocity, acceleration = self.run.ratios()
        assert velocity <= 1.0 + 1e-9 and acceleration <= 1.0 + 1e-6, (velocity, acceleration)


QueueMachine.TestCase.settings = settings(max_examples=examples(40), stateful_step_count=25, deadline=None, derandomize=True,
                                          database=None, suppress_health_check=list(HealthCheck))
test_random_commands_keep_the_limits_and_end_at_rest = pytest.mark.long(QueueMachine.TestCase)


# ----------------------------------------------------------------------------- programs


@st.composite
def programs(draw):
    """A start (half of them with the wrist 2-8 deg from its singularity) and up to five
    moves: ptp, lin and circ, random speeds, accelerations, tool orientations and approx."""
    near_wrist = draw(st.booleans())
    q0 = (draw(st.floats(-60, 60)), draw(st.floats(-50, 0)), draw(st.floats(10, 80)), draw(st.floats(-90, 90)),
          draw(st.floats(2, 8)) if near_wrist else draw(st.floats(20, 90)), draw(st.floats(-90, 90)))
    x, y, z, r, p, w = KIN.forward(q0)
    moves = []
    for line in range(1, draw(st.integers(1, 5)) + 1):
        kind = draw(st.sampled_from(["ptp", "lin", "circ"]))
        if kind == "ptp":
            target = tuple(c + draw(st.floats(-20, 20)) for c in q0)
            moves.append(MoveRequest("ptp", (Joint(target),), draw(st.floats(0.05, 1.0)), draw(st.floats(0.05, 1.0)),
                                     draw(st.sampled_from([0.0, 0.5, 1.0])), line))
            continue
        d = [draw(st.floats(-150, 150)) for _ in range(3)]
        end = (x + d[0], y + d[1], z + d[2], r + draw(st.floats(-20, 20)), p + draw(st.floats(-10, 10)),
               w + draw(st.floats(-20, 20)))
        targets = (end,)
        if kind == "circ":
            targets = ((x + d[0] / 2 + draw(st.floats(-60, 60)), y + d[1] / 2 + draw(st.floats(-60, 60)),
                        z + d[2] / 2, r, p, w), end)
        moves.append(MoveRequest(kind, targets, draw(st.floats(20.0, 1000.0)), draw(st.floats(200.0, 8000.0)),
                                 draw(st.sampled_from([0.0, 5.0, 40.0])), line))
    return q0, moves


def run_program(q0, moves) -> tuple[list, list]:
    """The setpoints of a program's moves (the ones before the first that cannot be
    planned), and for each the requests whose segments run at it."""
    queue = MotionQueue(MovePlanner(SPEC.axes, SPEC.main_axes, "jerk", KIN), SPEC.axes)
    queue.start(q0, SETPOINT_PERIOD)
    for move in moves:
        if queue.add(move) is not None:
            break
    positions, running, now = [queue.positions], [()], 0.0
    setpoints = [(0.0, queue.positions, queue.velocities, queue.accelerations)]
    while not queue.done():
        now += SETPOINT_PERIOD
        queue.sample(now)
        positions.append(queue.positions)
        running.append(tuple(s.request for s in list(queue._segments)[:2]
                             if s.start is not None and queue.t_move > s.start + 1e-9))
        a = queue.accelerations
        setpoints.append((now, queue.positions, queue.velocities) + ((a,) if a is not None else ()))
    return positions, running, setpoints


def servo_references(q0, setpoints) -> list:
    """The servo's 1 ms references of ``setpoints`` (its interpolator, one setpoint period
    behind, as runtime/loop/components/servo.py takes them), and a few more at rest."""
    interpolator = Interpolator(tuple(q0), LIMITS)
    references, k = [], 0
    for setpoint in setpoints + [(setpoints[-1][0] + SETPOINT_PERIOD * i,) + setpoints[-1][1:] for i in (1, 2)]:
        interpolator.push(*setpoint)
        while k * TICK < setpoint[0] + SETPOINT_PERIOD - 1e-12:  # the ticks until the next setpoint
            references.append(interpolator.sample(k * TICK - SETPOINT_PERIOD))
            k += 1
    return references


LIMITS = ([a.max_velocity for a in SPEC.axes], [a.max_acceleration for a in SPEC.axes],
          [a.max_jerk for a in SPEC.axes])


def difference_ratios(positions, h: float) -> list[float]:
    """The largest first, second and third difference of ``positions`` (every ``h`` s)
    against each axis's velocity, acceleration and jerk limit."""
    worst = [0.0, 0.0, 0.0]
    for k in range(1, len(positions)):
        for i in range(len(positions[k])):
            diffs = (positions[k][i] - positions[k - 1][i],
                     positions[k][i] - 2 * positions[k - 1][i] + positions[k - 2][i] if k >= 2 else 0.0,
                     positions[k][i] - 3 * positions[k - 1][i] + 3 * positions[k - 2][i] - positions[k - 3][i]
                     if k >= 3 else 0.0)
            for order, (d, limit) in enumerate(zip(diffs, LIMITS)):
                worst[order] = max(worst[order], abs(d) / h ** (order + 1) / limit[i])
    return worst


#: Counter-examples found: a lin move slowed down near the wrist singularity (its check's
#: samples 16 ms apart: the 1 ms check had gaps between them), and two 1 deg moves blended
#: at full speed (more jerk switches in a period than the servo's interpolator follows).
FOUND = [
    ((0.0, 0.0, 10.0, 0.0, 5.0, 0.0),
     [MoveRequest("ptp", (Joint((0.0, 0.0, 10.0, 0.0, 0.5, 0.0)),), 1.0, 1.0, 0.0, 1),
      MoveRequest("lin", ((1133.5729333886716, 0.0, 1217.477897621542, 180.0, -75.0, 1.0),), 22.0, 2263.0, 0.0, 2)]),
    ((0.0, 0.0, 10.0, 0.0, 20.0, 0.0),
     [MoveRequest("ptp", (Joint((0.0, 0.0, 10.0, 0.0, 21.0, 0.0)),), 1.0, 1.0, 0.5, 1),
      MoveRequest("ptp", (Joint((0.0, 0.0, 10.0, 0.0, 20.0, 0.0)),), 1.0, 1.0, 0.0, 2)]),
]


@pytest.mark.long
@settings(max_examples=examples(30), deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
@given(programs())
@example(FOUND[0])
@example(FOUND[1])
def test_random_programs_keep_every_limit_and_the_programmed_speed(program):
    """Issue 14: random programs mixing ptp, lin, circ and approx, near the wrist singularity
    too: every 5 ms setpoint and every 1 ms reference the servo makes of them within every
    axis's velocity, acceleration and jerk limit (differences, as a drive sees them), and
    the tool never faster than the programmed speed (in a blend of two Cartesian moves, the
    larger of the two)."""
    positions, running, setpoints = run_program(*program)
    for series, h in ((positions, SETPOINT_PERIOD), (servo_references(program[0], setpoints), TICK)):
        velocity, acceleration, jerk = difference_ratios(series, h)
        assert velocity <= 1.0 + 1e-6 and acceleration <= 1.0 + 1e-6 and jerk <= 1.0 + 1e-6, (h, velocity,
                                                                                                acceleration, jerk)
    for k in range(1, len(positions)):
        now = running[k]
        if not now or any(r.kind == "ptp" for r in now + running[k - 1]):
            continue
        speed = math.dist(KIN.forward(positions[k][:6])[:3], KIN.forward(positions[k - 1][:6])[:3]) / SETPOINT_PERIOD
        assert speed <= max(r.speed for r in now + running[k - 1]) * (1.0 + 1e-6)


@pytest.mark.parametrize("profile", ["jerk", "trapezoid"])
def test_a_pause_keeps_the_limits_at_the_servos_references(profile):
    """A controlled stop's setpoints carry its exact accelerations (LineStop, StopRamp), so
    the servo's 1 ms references keep the limits through the stop: velocity, acceleration,
    and the jerk of a jerk-limited move (a trapezoid has none to keep)."""
    for pause_at in (20, 37, 55, 80):  # accelerating, cruising, decelerating
        queue = make_queue(profile=profile)
        queue.add(ptp((60.0, -40.0, 60.0, 40.0, 80.0, 90.0), 1, 1.0, 1.0))
        run = Run(queue)
        setpoints = [(0.0, queue.positions, queue.velocities, queue.accelerations)]
        for i in range(2000):
            if i == pause_at:
                assert queue.pause() is not None
            run.step()
            a = queue.accelerations
            setpoints.append((run.now, queue.positions, queue.velocities) + ((a,) if a is not None else ()))
            if queue.interrupted is not None and queue.current is None:
                break
        velocity, acceleration, jerk = difference_ratios(servo_references(START, setpoints), TICK)
        assert velocity <= 1.0 + 1e-6 and acceleration <= 1.0 + 1e-6, (pause_at, velocity, acceleration)
        if profile == "jerk":
            assert jerk <= 1.0 + 1e-6, (pause_at, jerk)


def test_a_pause_on_a_lin_or_circ_move_keeps_every_limit_at_the_servo():
    """A pause during lin and circ moves (timed as a whole and slower only where the
    joints need it), then a resume: the 5 ms setpoints and the servo's 1 ms references
    within every axis's velocity, acceleration and jerk limit. Before, a stop on the path
    gave backward-difference velocities and no accelerations: the references reached 2x
    the acceleration and 130x the jerk limit. Among the pauses: stops that brake on the
    path and one that slows the move's own profile down to rest."""
    import sys
    sys.path.insert(0, str(ROOT / "tests"))
    from test_pathtiming import _drawn_path

    runs = 0
    stops = set()  # (how the pauses stopped)
    for seed in (0, 6, 9, 21, 36):
        drawn = _drawn_path(seed)
        if drawn is None:
            continue
        move, _s, joints = drawn
        via = getattr(move.path, "via", None)
        kind, targets = ("lin", (move.path.end,)) if via is None else (
            "circ", (tuple(via) + tuple(move.path.end[3:]), move.path.end))
        for fraction in (0.05, 0.3, 0.6):
            queue = MotionQueue(MovePlanner(SPEC.axes, SPEC.main_axes, "jerk", KIN), SPEC.axes)
            queue.start(tuple(joints[0]), SETPOINT_PERIOD)
            assert queue.add(MoveRequest(kind, targets, move.speed, move.acc, 0.0, 1)) is None
            now, paused, resumed = 0.0, None, False
            positions, setpoints = [queue.positions], [(0.0, queue.positions, queue.velocities, queue.accelerations)]
            while not queue.done():
                now += SETPOINT_PERIOD
                if paused is None and queue.current is not None and queue.t_move > fraction * queue.current.duration:
                    queue.pause()
                    paused = now
                    stops.add(type(getattr(queue.hold.stop, "_stop", None)).__name__)
                if paused is not None and not resumed and queue.at_rest() and now > paused + 0.05:
                    queue.resume()
                    resumed = True
                queue.sample(now)
                positions.append(queue.positions)
                a = queue.accelerations
                setpoints.append((now, queue.positions, queue.velocities) + ((a,) if a is not None else ()))
                assert now < 60.0
            assert paused is not None and resumed
            runs += 1
            for series, h in ((positions, SETPOINT_PERIOD), (servo_references(joints[0], setpoints), TICK)):
                assert max(difference_ratios(series, h)) <= 1.0 + 1e-6, (seed, fraction, h,
                                                                         difference_ratios(series, h))
    assert runs >= 9
    # braking on the path, and slowing the profile down where no braking fits (PathProfile.ramp_stop)
    assert {"StopLaw", "RampStop"} <= stops, stops
