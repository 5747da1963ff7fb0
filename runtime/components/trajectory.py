"""Trajectory Generator: interpreter, path planner and interpolator, every 5 ms.

It runs the program's object code (``runtime.vm``, a bounded number of instructions per
update), and is the VM's motion host. A move instruction hands a request to the
planner and the program runs on (**look-ahead**): up to ``lookahead`` moves (the
specification's ``[controller] lookahead``, default 4) may wait planned ahead of the
robot; the VM stops running ahead at instructions that must happen where the robot
really is (waits, digital I/O, ``print``, ``pause``; see ``runtime.vm``). The planned
moves (segments) run one after the other on one **timeline** (trajectory seconds; the
speed override is its rate): a move without ``approx`` stops exactly at its target and
the next starts at the following tick; a move with ``approx`` blends into the next (the
two are superposed in joint space for a checked overlap, :mod:`runtime.motion.blend`).
The timeline is sampled every 5 ms into ``desi_pos`` (time, positions, velocities),
which the servo interpolates to 1 ms. Each move's line, planned duration and actual
duration (from its first setpoint to its last) are recorded for the run's summary.

Planning is synchronous on the simulated clock (deterministic: simulated time does not
pass); on the wall clock it runs on a planning thread, one move at a time in program
order, so a Cartesian path check or a blend check never holds up the loop.

A move that cannot be planned (a refused path, an unreachable pose) stops the program
at its line: the moves before it are completed first, then the program ends with the
error, as if there were no look-ahead.
"""
from __future__ import annotations

import math
import queue
import threading
import time
from collections import deque
from dataclasses import dataclass

from compiler.clauses import MoveClauses, validate_move_clauses
from compiler.objcode import Program
from compiler.params import component_params
from compiler.spec import DEFAULT_LOOKAHEAD
from compiler.values import Joint, Pose

from ..component import Component, DataPort
from ..motion.blend import Limits, blend_offset
from ..motion.cartesian import PathStop, plan_circ, plan_lin  # imported here: never in a tick (file I/O)
from ..motion.jerk import LineStop, plan_ptp_jerk
from ..motion.kinematics import Kinematics, KinematicsError
from ..motion.planner import PtpInput, StopRamp, plan_ptp, scaled_limits
from ..timing import SETPOINT_PERIOD
from ..vm import DONE, ERROR, VM

#: Moves planned ahead of the robot by default (``[controller] lookahead``).
LOOKAHEAD = DEFAULT_LOOKAHEAD
#: Timeline times closer than this are the same instant (the timeline is a running sum).
_SAME_TIME = 1e-9
#: Seconds of interpreter time per update on the wall clock (runtime.vm: the step ends at
#: the first slice of instructions after it); none on the simulated clock (deterministic).
TIME_SLICE = 0.0005
#: A change of the rate (override, a stop inside a blend) keeps every axis within this
#: fraction of its acceleration limit (the rest is the servo's and the interpolation's).
RATE_CHANGE_MARGIN = 0.9
#: Lines of the operator log (print) kept per program; later ones are counted, not kept.
MAX_LOG_LINES = 10_000


def motion_profile(spec) -> str:
    """The PTP velocity profile the specification asks for (``[controller] profile``,
    checked when the specification was loaded)."""
    return spec.controller["profile"]


def lookahead_depth(spec) -> int:
    """How many moves may be planned ahead of the robot (``[controller] lookahead``,
    0..16, default 4; 0: the program waits for each move to end)."""
    return spec.controller["lookahead"]


@dataclass
class MoveRecord:
    line: int
    kind: str
    target: tuple
    planned_duration: float
    t_start: float
    t_end: float | None = None
    blended: bool = False  # the move blended into the next one (it did not stop at its target)

    @property
    def actual_duration(self) -> float | None:
        return None if self.t_end is None else self.t_end - self.t_start


class _Request:
    """A move the program handed over, not planned yet."""

    __slots__ = ("kind", "targets", "speed", "acc", "approx", "line", "rest_of")

    def __init__(self, kind, targets, speed, acc, approx, line, rest_of=None):
        self.kind, self.targets, self.speed, self.acc, self.approx, self.line = kind, targets, speed, acc, approx, line
        self.rest_of = rest_of  # the interrupted segment whose rest this is (planned from where it stopped)


class _Segment:
    """A planned move on the timeline: ``trajectory`` from the previous move's end to
    ``end``; ``offset``: when it starts after the previous segment's start if it is
    blended into it (None: after the previous one has stopped); ``start``: its start on
    the timeline once scheduled."""

    __slots__ = ("request", "trajectory", "duration", "end", "limits", "offset", "start", "record",
                 "blendable", "previous", "stop")

    def __init__(self, request, trajectory, end, limits, previous=None):
        self.request = request
        self.trajectory = trajectory
        self.duration = trajectory.duration
        self.end = tuple(end)
        self.limits = limits
        self.offset: float | None = None
        self.start: float | None = None
        self.record: MoveRecord | None = None
        self.blendable = True  # cleared when the move is interrupted (its blend is off)
        self.previous = previous  # the segment it was planned after (its blend partner)
        self.stop = None  # the controlled stop that interrupted it

    @property
    def kind(self) -> str:
        return self.request.kind


class _PlanningJob:
    """A plan to compute off the loop; ``done`` once ``result`` is there. The planner
    thread only computes: the loop takes the result when it is done."""

    def __init__(self, plan, what):
        self.plan = plan
        self.what = what
        self.result = (None, "not planned")
        self.done = False

    def run(self) -> None:
        try:
            self.result = self.plan()
        except Exception as exc:  # the planners never raise; a bug must not hang the move
            self.result = (None, f"internal error while planning ({type(exc).__name__}: {exc})")
        self.done = True


class _Planner:
    """One planning thread, started before the loop runs (the tick never creates a
    thread): it takes jobs from a queue (a non-blocking put from the loop) and runs them
    in order."""

    def __init__(self):
        self.jobs: queue.SimpleQueue = queue.SimpleQueue()
        self.thread = threading.Thread(target=self._main, name="irl-plan", daemon=True)
        self.thread.start()

    def submit(self, job: _PlanningJob) -> _PlanningJob:
        """Real-time safe: queue ``job`` (never waits)."""
        self.jobs.put_nowait(job)
        return job

    def _main(self) -> None:
        while True:
            self.jobs.get().run()


def _build_kinematics(spec) -> tuple[Kinematics | None, str | None]:
    """Not real-time: the robot's kinematics, or None and why a pose cannot be used."""
    try:
        return Kinematics(spec), None
    except ValueError as exc:
        return None, f"this robot's kinematics are not usable for poses: {exc}"


class TrajectoryGenerator(Component):
    """Operator control (real-time safe, called between ticks): :meth:`pause` stops the
    program before its next instruction and brings the motion to a controlled stop on
    its path; :meth:`resume` continues (the rest of an interrupted move is re-planned
    from where the robot stopped; a stop inside a blend continues on the blend itself);
    :meth:`abort` stops the same way, then ends the program with a fault; ``override``
    (percent) scales the time of the moves, the one under way too (a smooth, monotonic
    change of rate)."""

    PROPERTIES = component_params("trajectory")

    def __init__(self, spec, robot, desi_pos: DataPort, sens_pos: DataPort, clock, period: float = SETPOINT_PERIOD):
        super().__init__("trajectory", period)
        self.spec, self.robot, self.desi_pos, self.sens_pos = spec, robot, desi_pos, sens_pos
        self.clock = clock
        self.n = len(spec.axes)
        self.axes = spec.axes
        self.budget = 200
        self.lookahead = lookahead_depth(spec)
        self.program: Program | None = None
        self.vm: VM | None = None
        self.t_move = 0.0  # the timeline (trajectory seconds)
        self.positions: tuple = (0.0,) * self.n
        self.velocities: tuple = (0.0,) * self.n
        self.moves: list[MoveRecord] = []
        self.completed = 0
        self.log_lines: list[tuple[float, int, str]] = []
        self.fault: str | None = None
        self.start_position: tuple | None = None  # the commanded position to plan from (else sens_pos)
        self.rate = 1.0  # trajectory seconds per real second: the override, now
        self._override = 1.0  # the override's rate (what the rate goes to)
        self._percent = 100.0  # the override as the operator set it
        self.velocity_limit_scale = 1.0  # robot.velocity_limit_scale: the rate never exceeds it
        self.safety = None  # the safety supervisor: told when the motion is at rest, and of stops on the path
        self._rate_from = self._rate_to = 1.0
        self._rate_t = self._rate_T = 0.0  # progress and length (s) of a change of rate
        self._path_velocity: tuple = (0.0,) * self.n  # the timeline's velocity per trajectory second
        self._path_acceleration: tuple = (0.0,) * self.n  # ... and acceleration (estimated)
        self._accelerations = tuple(a.max_acceleration * RATE_CHANGE_MARGIN for a in spec.axes)
        self.profile = motion_profile(spec)
        # the robot's kinematics, built here (never in a tick), or why poses cannot be used
        self._kinematics, self._kinematics_problem = _build_kinematics(spec)
        self.abort_reason: str | None = None  # set by abort(): end the program once at rest
        self._planner: _Planner | None = None  # on the wall clock: the planning thread (made by load)
        self._forget()

    def load(self, program: Program | None) -> None:
        """Not real-time: the program to run at the next start; forgets the last one
        (its moves and log, its fault, an abort). On the wall clock, starts the planning
        thread the first time (never in a tick)."""
        if not self.clock.simulated and self._planner is None:
            self._planner = _Planner()
        self.program = program
        self._forget()

    def _forget(self) -> None:
        self.vm = None
        self.moves = []
        self.completed = 0  # moves that reached their end (telemetry reads it every 10 ms)
        self.log_lines = []
        self.log_dropped = 0
        self.fault = None
        self.abort_reason = None
        self._clear_motion()

    def _clear_motion(self) -> None:
        self._segments: deque[_Segment] = deque()  # planned, in order; the first one or two run
        self._requests: deque[_Request] = deque()  # handed over, not planned yet (wall clock)
        self._planning: _PlanningJob | None = None
        self._last: _Segment | None = None  # the last segment planned (the next plans from its end)
        self._stop = None  # a controlled stop under way (real seconds)
        self.t_stop = 0.0
        self.interrupted: _Segment | None = None  # a move stopped before its end (pause/abort)
        self._hold = False  # stopping (or stopped) by bringing the timeline's rate to 0
        self._paused = False  # by the operator (the program may have handed over all its moves)

    def on_start(self) -> bool:
        """Run the loaded program from its beginning."""
        if self.program is None:
            return False
        self._forget()
        position = self.start_position or self.sens_pos.read() or (0.0,) * self.n
        self.positions = tuple(position)
        self.velocities = (0.0,) * self.n
        self.t_move = 0.0
        self.vm = VM(self.program, self, self.budget)
        self.desi_pos.write((self.clock.now(), self.positions, self.velocities), self.clock.now())
        return True

    # ---- what is moving ----
    @property
    def trajectory(self):
        """What is being sampled now: a controlled stop, or the first running move's
        trajectory; None when the robot is not moving."""
        if self._stop is not None:
            return self._stop
        segs = self._segments
        if segs and segs[0].start is not None:
            return segs[0].trajectory
        return None

    @property
    def queued(self) -> int:
        """Moves handed over that have not started yet."""
        return (sum(1 for s in self._segments if s.start is None) + len(self._requests)
                + (self._planning is not None))

    # ---- the speed override: a rate of trajectory time (real-time safe) ----
    @property
    def override(self) -> float:
        """The speed override in percent (1-100): the moves run at this fraction of their
        planned speed. Every move is planned at 100 % and its time is scaled, which is
        exactly the move planned with velocity x p, acceleration x p^2 and jerk x p^3: the
        same path. A change while a move runs is a smooth transition of the rate (a
        quintic smoothstep: continuous in rate, its derivative and second derivative),
        monotonic, so the speed never overshoots the new value. The rate never exceeds
        ``velocity_limit_scale`` (reduced speed: every axis within that fraction of its
        max_velocity)."""
        return self._percent

    @override.setter
    def override(self, percent: float) -> None:
        self._percent = min(max(float(percent), 1.0), 100.0)
        rate = min(self._percent / 100.0, self.velocity_limit_scale)
        self._override = rate
        if self._hold:  # stopping or stopped on the timeline: resume goes to the new rate
            return
        if self.trajectory is None or self._stop is not None:
            self.rate = self._rate_from = self._rate_to = rate
            self._rate_t = self._rate_T = 0.0
            return
        self._change_rate(rate)

    def _change_rate(self, rate: float) -> None:
        self._rate_from, self._rate_to, self._rate_t = self.rate, rate, 0.0
        # long enough that v * dr/dt stays within the acceleration limits (dr/dt peaks at
        # 1.875 |dr| / T for the quintic), and at least 0.2 s
        ratio = max((a.max_velocity / a.max_acceleration for a in self.axes), default=0.0)
        self._rate_T = max(0.2, 1.875 * abs(rate - self.rate) * ratio)

    def _step_rate(self, dt: float) -> float:
        """The rate for the next period: towards the quintic schedule, but never changing
        faster than every axis's acceleration limit allows where the path is now. With the
        rate r of trajectory time, an axis moving at v (per trajectory second) and
        accelerating at a has the acceleration ``r^2 a + r' v``: a change of rate adds
        ``r' v`` to what the path itself asks, so r' is kept where the sum stays within the
        limit (0 always is: r <= 1). The rate then only lags the schedule, monotonically."""
        self._rate_t += dt
        u = self._rate_t / self._rate_T
        target = self._rate_to
        if u >= 1.0:
            scheduled = target
        else:
            scheduled = self._rate_from + (target - self._rate_from) * u * u * u * (10.0 + u * (6.0 * u - 15.0))
        rate = self.rate
        wanted = (scheduled - rate) / dt
        peak = 1.875 * abs(target - self._rate_from) / self._rate_T  # the schedule's steepest
        low, high = self._rate_change_bounds(rate)
        change = min(max(wanted, low, -peak), high, peak)
        rate += change * dt
        if (change >= 0.0 and rate >= target) or (change <= 0.0 and rate <= target):
            if u >= 1.0 or rate == target:
                rate = target
        if u >= 1.0 and rate == target:
            self._rate_from = target
            self._rate_T = 0.0
        self.rate = rate
        return rate

    def _rate_change_bounds(self, rate: float) -> tuple[float, float]:
        """How fast (1/s) the rate may change now: every axis within RATE_CHANGE_MARGIN of
        its acceleration limit, given the path's velocity and acceleration here."""
        low, high = -math.inf, math.inf
        r2 = rate * rate
        for v, a, limit in zip(self._path_velocity, self._path_acceleration, self._accelerations):
            if -1e-9 < v < 1e-9:
                continue
            lo, hi = (-limit - r2 * a) / v, (limit - r2 * a) / v
            if v < 0.0:
                lo, hi = hi, lo
            if lo > low:
                low = lo
            if hi < high:
                high = hi
        return min(low, 0.0), max(high, 0.0)

    @property
    def finished(self) -> bool:
        """The program ended (DONE) and all its motion is complete."""
        return self.vm is not None and self.vm.status is DONE and self.fault is None and self.motion_done()

    @property
    def line(self) -> int:
        """The source line of the move the robot is executing (stopping on, or waiting to
        resume); else of the instruction the program is at."""
        if self.interrupted is not None:
            return self.interrupted.request.line
        segs = self._segments
        if segs and segs[0].start is not None:
            return segs[0].request.line
        return self.vm.line if self.vm is not None else 0

    @property
    def paused(self) -> bool:
        """Held by the operator or by the program's ``pause``."""
        return self.vm is not None and (self._paused or self.vm.paused)

    def _busy(self) -> bool:
        """The program has something left to do: instructions, or motion it handed over."""
        vm = self.vm
        return vm is not None and (vm.status < DONE or not self.motion_done())

    def _holding(self) -> bool:
        """No new move may start: paused, aborting, stopping, or a move to resume first."""
        vm = self.vm
        return (vm is None or self._paused or vm.paused or self.abort_reason is not None or self._stop is not None
                or self.interrupted is not None or self._hold)

    # ---- the 5 ms update (real-time) ----
    def update(self, now: float) -> None:
        """Real-time: take finished plans, sample the motion, then let the VM run its budget."""
        if self._planning is not None and self._planning.done:
            self._planned()
        if self._stop is not None:
            self._sample_stop()
        elif self._segments:
            self._sample_timeline(now)
        self.desi_pos.write((now, self.positions, self.velocities), now)
        safety = self.safety
        if safety is not None:
            safety.expect_standstill(self._at_rest())
        vm = self.vm
        if vm is not None and vm.status < DONE:
            vm.step(None if self.clock.simulated else time.perf_counter() + TIME_SLICE)
        if self._requests and self._planning is None:
            request = self._requests[0]
            problem = self._plan_next()
            if problem is not None:
                vm.fail(problem, request.line)
        if self.fault is None and vm is not None and vm.status is ERROR and self.motion_done():
            e = vm.error  # an error ends the program once the moves before it are done
            self.fault = f"program error at line {e.line}: {e.message}"

    def _sample_stop(self) -> None:
        stop = self._stop
        self.t_stop += self.period
        self.positions, self.velocities = stop.sample(self.t_stop)
        if self.t_stop >= stop.duration - 1e-12:
            self._stop = None
            self.velocities = (0.0,) * self.n
            self._at_rest_after_stop()

    def _sample_timeline(self, now: float) -> None:
        segs = self._segments
        first = segs[0]
        if first.start is None:
            if self._holding():
                return
            first.start = self.t_move  # starts now: its first sample one period on
            self._schedule()
        held = False
        if self._rate_T:
            before = self.rate
            rate = self._step_rate(self.period)
            held = self._hold and not self._rate_T  # the rate reached 0: at rest on the path
            # trajectory time over the period at the mean rate: the setpoints' positions then
            # agree with their velocities (rate x the path's), which the servo interpolates
            step = self.period * 0.5 * (before + rate)
        else:
            rate = self.rate
            step = self.period * rate
        tm = self.t_move = self.t_move + step
        if first.record is None:
            self._started(first, now)
        t = tm - first.start
        positions, velocities = first.trajectory.sample(t)
        second = segs[1] if len(segs) > 1 else None
        if second is not None and second.start is not None and tm > second.start + _SAME_TIME:
            if second.record is None:
                self._started(second, now)
            p2, v2 = second.trajectory.sample(tm - second.start)
            corner = first.end
            positions = tuple([a + b - c for a, b, c in zip(positions, p2, corner)])
            velocities = tuple([a + b for a, b in zip(velocities, v2)])
        self.positions = positions
        if step > 1e-9:  # the path's acceleration, for the next change of rate
            self._path_acceleration = tuple([(v - w) / step for v, w in zip(velocities, self._path_velocity)])
        self._path_velocity = velocities
        self.velocities = velocities if rate == 1.0 else tuple([v * rate for v in velocities])
        if held:
            self._held()
            return
        if t >= first.duration - 1e-12:
            segs.popleft()
            first.record.t_end = now
            self.completed += 1
            if self._last is first:
                self._last = None
            if segs:
                self._schedule()
            if not segs or segs[0].start is None:  # nothing moving on: at rest
                self.velocities = (0.0,) * self.n
                if self._rate_T and not self._hold:  # a change of override under way: the next move has it
                    self.rate = self._rate_from = self._rate_to
                    self._rate_T = 0.0
                if self._hold:
                    self._held()

    def _started(self, segment: _Segment, now: float) -> None:
        request = segment.request
        rate = max(self.rate, 1e-9)
        # it began (its time 0) between the last tick and this one: its first setpoint
        t_start = now - (self.t_move - segment.start) / rate
        segment.record = MoveRecord(request.line, request.kind, segment.end, segment.duration / rate, t_start)
        if segment.previous is not None and segment.offset is not None and segment.previous.record is not None:
            segment.previous.record.blended = True
        self.moves.append(segment.record)

    def _schedule(self) -> None:
        """Put the next segment on the timeline if it is blended into the running one
        and its start is still ahead (else it starts after the running one has stopped)."""
        segs = self._segments
        if len(segs) < 2:
            return
        first, second = segs[0], segs[1]
        if second.start is not None or second.offset is None or first.start is None:
            return
        start = first.start + second.offset
        if first.blendable and second.previous is first and start >= self.t_move - _SAME_TIME and not self._holding():
            second.start = start
        else:
            second.offset = None  # too late (or interrupted): the corner is a stop

    # ---- operator control (real-time safe) ----
    def pause(self) -> bool:
        """Hold the program; the motion decelerates to rest on its path: a PTP move in a
        controlled stop, a lin or circ move along its own line or arc, a blend along the
        blend. False if there is no program to pause."""
        if not self._busy() or self.abort_reason is not None:
            return False
        self._paused = True
        self.vm.pause()
        self._stop_on_path()
        return True

    def resume(self) -> bool:
        """Continue after :meth:`pause`; the rest of an interrupted move is re-planned
        from where the robot stopped (at once, or when its stop ends); a blend stopped
        on the timeline speeds up again on it."""
        vm = self.vm
        if not self.paused or self.abort_reason is not None:
            return False
        self._paused = False
        vm.resume()
        if self.safety is not None:
            self.safety.rest_not_expected()
        if self._hold:
            self._hold = False
            self._change_rate(self._override)
        elif self.interrupted is not None and self._stop is None:
            self._resume_move()
        return True

    def abort(self, reason: str = "aborted by the operator") -> bool:
        """A controlled stop, then end the program with ``reason`` as its fault."""
        if not self._busy():
            return False
        if self.abort_reason is None:
            self.abort_reason = reason
            self.vm.pause()
            self._stop_on_path()
            if self._at_rest():
                self._at_rest_after_stop()
        return True

    def _at_rest(self) -> bool:
        return self.trajectory is None or (self._hold and self.rate == 0.0 and not self._rate_T)

    def _stop_on_path(self) -> None:
        if self._stop is not None or self.interrupted is not None or self._hold:
            return
        segs = self._segments
        if not segs or segs[0].start is None:
            return  # at rest: the moves still queued wait (no new move starts while held)
        first = segs[0]
        second = segs[1] if len(segs) > 1 else None
        if second is not None and second.start is not None:
            # in (or scheduled into) a blend: stop on the timeline itself, so the robot stays
            # on the blended path and resume speeds up again on it
            self._hold = True
            self._change_rate(0.0)
            if self.safety is not None:
                self.safety.expect_rest_within(self._rate_T)
            return
        t = self.t_move - first.start
        request = first.request
        if request.kind != "ptp":  # decelerate along the line or arc itself
            stop = PathStop(first.trajectory, t, self.positions, rate=self.rate)
        elif getattr(first.trajectory, "synchronization", None) == "line":  # jerk-limited, on the line
            stop = LineStop(first.trajectory, t, rate=self.rate)
        else:
            amax = tuple(a.max_acceleration * request.acc * self.rate * self.rate for a in self.axes)
            stop = StopRamp(self.positions, self.velocities, amax)
        segs.popleft()
        first.blendable = False
        if second is not None:
            second.offset = None
        first.stop = stop
        self.interrupted = first
        self._stop, self.t_stop = stop, 0.0
        if self.safety is not None:
            self.safety.expect_rest_within(stop.duration)

    def _held(self) -> None:
        """The timeline's rate reached 0 (a stop inside a blend): at rest."""
        self.velocities = (0.0,) * self.n
        if self.abort_reason is not None:
            self._at_rest_after_stop()

    def _at_rest_after_stop(self) -> None:
        if self.abort_reason is not None:
            line = self.line
            self._clear_motion()
            self.rate = self._override
            self._rate_T = 0.0
            self.fault = self.fault or f"{self.abort_reason} at line {line}"
            self.vm.abort()
        elif not self.paused:
            self._resume_move()

    def _resume_move(self) -> None:
        """Plan the rest of the interrupted move from where the robot stopped (a PTP move
        at once; the rest of a line or arc like any Cartesian move: at once on the
        simulated clock, else first in the planning queue)."""
        move = self.interrupted
        request = move.request
        if request.kind == "ptp":
            main = len(self.spec.main_axes)
            rest = _Request("ptp", (Joint(move.end[:main], move.end[main:]),), request.speed, request.acc, 0.0,
                            request.line, rest_of=move)
            self._take_plan(rest, *self._plan_segment(rest, self.positions, None))
            return
        kind, poses = move.stop.rest()
        self._requests.appendleft(_Request(kind, tuple(poses), request.speed, request.acc, 0.0, request.line,
                                           rest_of=move))
        if self.clock.simulated:
            self._plan_next()

    # ---- planning ----
    def _plan_next(self) -> str | None:
        """Plan the oldest request (from the end of the last planned move): at once on
        the simulated clock (returns the problem of a move that cannot be planned), else
        on a planning thread."""
        request = self._requests[0]
        if request.rest_of is not None:  # from where the robot stopped, no blend before it
            previous, start = None, self.positions
        else:
            previous = self._last
            start = previous.end if previous is not None else self._chain_start()

        def plan():
            return self._plan_segment(request, start, previous)

        if self.clock.simulated:
            self._requests.popleft()
            return self._take_plan(request, *plan())
        self._planning = self._planner.submit(_PlanningJob(plan, request))
        return None

    def _chain_start(self) -> tuple:
        if self.interrupted is not None:
            return self.interrupted.end
        return self.positions

    def _planned(self) -> None:
        """Real-time: take a finished background plan."""
        job, self._planning = self._planning, None
        if self.vm is None or self.abort_reason is not None:
            return
        request = job.what
        if request in self._requests:
            self._requests.remove(request)
            problem = self._take_plan(request, *job.result)
            if problem is not None:
                self.vm.fail(problem, request.line)

    def _take_plan(self, request: _Request, segment, problem) -> str | None:
        """Put a planned move on the timeline; the problem of a move that cannot be
        planned (the program stops at it, after the moves before it)."""
        move = request.rest_of
        if move is not None:  # the rest of an interrupted move: it goes first
            self.interrupted = None
            if segment is None:
                self.fault = self.fault or f"cannot resume the move at line {request.line}: {problem}"
                self._clear_motion()
                self.vm.abort()
                return
            segment.record = move.record  # the same move, continued
            self._segments.appendleft(segment)
            if self._last is move:
                self._last = segment
            return None
        if segment is None:
            self._requests.clear()
            return problem
        if segment.previous is not None and segment.previous is not self._last:
            segment.offset = None  # the move it was to blend with was interrupted meanwhile
        self._segments.append(segment)
        self._last = segment
        self._schedule()
        return None

    def _plan_segment(self, request: _Request, start: tuple, previous: _Segment | None):
        """Plan ``request`` from the joints ``start``; ``(segment, None)`` or ``(None,
        problem)``. Pure (reads the specification and the previous segment's plan), so it
        may run on the planning thread."""
        if request.kind == "ptp":
            segment, problem = self._plan_ptp(request, start)
        else:
            segment, problem = self._plan_cartesian(request, start)
        if segment is None:
            return None, problem
        if previous is not None and previous.request.approx > 0.0 and previous.blendable:
            overlap_before = (previous.previous.duration - previous.offset
                              if previous.offset is not None and previous.previous is not None else 0.0)
            cap = previous.duration - overlap_before
            offset = blend_offset(previous.kind, previous.trajectory, previous.request.approx,
                                        request.kind, segment.trajectory, previous.end,
                                        previous.limits.union(segment.limits), self.period, cap)
            segment.previous = previous
            segment.offset = offset
        return segment, None

    def _plan_ptp(self, request: _Request, start: tuple):
        target = request.targets[0]
        if isinstance(target, Pose):
            target, problem = self._joint_target(target, start)
            if problem is not None:
                return None, problem
        values = target.axes
        for axis, v in zip(self.axes, values):
            problem = axis.target_problem(v)
            if problem is not None:
                return None, problem
        speed, acc = request.speed, request.acc
        vmax, amax = scaled_limits(tuple(a.max_velocity for a in self.axes),
                                   tuple(a.max_acceleration for a in self.axes), speed, acc)
        if self.profile == "jerk":  # the jerk limit scales with acc_ptp
            jmax = tuple(a.max_jerk * acc for a in self.axes)
            result, trajectory, message = plan_ptp_jerk(start, values, vmax, amax, jmax, synchronization="auto")
        else:
            result, trajectory, message = plan_ptp(PtpInput(start, values, vmax, amax))
        if result < 0:
            return None, message
        return _Segment(request, trajectory, values, self._axis_limits(jerk=self.profile == "jerk")), None

    def _axis_limits(self, jerk: bool = True) -> Limits:
        """What a blend must keep: every axis's velocity, acceleration and jerk limit (the
        jerk only for jerk-limited moves: a trapezoid has none)."""
        return Limits((a.max_velocity for a in self.axes), (a.max_acceleration for a in self.axes),
                      (a.max_jerk if jerk else float("inf") for a in self.axes))

    def _plan_cartesian(self, request: _Request, start: tuple):
        kinematics = self._kinematics
        poses = request.targets
        if request.kind == "lin":
            stream, message = plan_lin(kinematics, start, poses[0], request.speed, request.acc,
                                       axis_limits=self.spec, period=self.period)
        else:
            stream, message = plan_circ(kinematics, start, poses[0], poses[1], request.speed, request.acc,
                                        axis_limits=self.spec, period=self.period)
        if stream is None:
            return None, f"move {request.kind} refused: {message}"
        return _Segment(request, stream, stream.end, self._axis_limits()), None

    # ---- the VM's motion host ----
    def now(self) -> float:
        return self.clock.now()

    def move(self, kind: str, targets: tuple, clauses: dict, line: int) -> str | None:
        checked = validate_move_clauses(kind, clauses, self.spec)  # the clause table's rules and defaults
        if isinstance(checked, str):
            return checked
        if kind == "ptp":
            target = targets[0]
            if isinstance(target, Pose):
                _, problem = self._kinematics_or_problem()
                if problem is not None:
                    return problem
            elif not isinstance(target, Joint) or len(target.axes) != self.n:
                return f"the target must be a joint value with {self.n} axes"
            request = _Request(kind, (target,), checked.speed, checked.acc, checked.approx, line)
        else:
            request, problem = self._cartesian_request(kind, targets, checked, line)
            if problem is not None:
                return problem
        self._requests.append(request)
        if self.clock.simulated:  # deterministic: plan at once (simulated time does not pass)
            return self._plan_next()
        return None

    def queue_ready(self) -> bool:
        """May the program hand over another move (is there room in the look-ahead)?
        With ``lookahead = 0``: only when the last move has ended."""
        if self.lookahead == 0:
            return self.motion_done()
        return self.queued < self.lookahead

    def _kinematics_or_problem(self):
        return self._kinematics, self._kinematics_problem

    def _cartesian_request(self, kind: str, targets: tuple, clauses: MoveClauses, line: int):
        """``move lin TARGET`` / ``move circ VIA, TARGET``: the path is checked whole
        against the kinematics, the axis limits and velocities before it starts (a refused
        move leaves the robot where it is, and the program stops at its line with the
        reason and where along the path it fails)."""
        kinematics, problem = self._kinematics_or_problem()
        if problem is not None:
            return None, problem
        main = len(self.spec.main_axes)
        poses = []
        for target in targets:
            if isinstance(target, Joint):
                poses.append(kinematics.forward(target.axes[:main]))
            elif isinstance(target, Pose):
                poses.append(target)
            else:
                return None, f"a {kind} target must be a pose or a joint value"
        return _Request(kind, tuple(poses), clauses.speed, clauses.acc, clauses.approx, line), None

    def _joint_target(self, pose: Pose, near: tuple) -> tuple[Joint | None, str | None]:
        """The joint values that put the tool at ``pose``: the inverse kinematics'
        configuration nearest the joints the move starts from."""
        kinematics = self._kinematics
        main = len(self.spec.main_axes)
        try:
            joints = kinematics.inverse(pose, near=near[:main])
        except KinematicsError as exc:
            return None, f"the target pose cannot be reached: {exc}"
        return Joint(tuple(joints), tuple(near[main:])), None

    def motion_done(self) -> bool:
        """Every move handed over has ended (and no stop is under way)."""
        return (not self._segments and not self._requests and self._planning is None
                and self._stop is None and self.interrupted is None)

    def read_input(self, n: int) -> bool:
        if not 1 <= n <= self.spec.inputs:
            raise IndexError(f"digital input {n} does not exist (1..{self.spec.inputs})")
        return self.robot.read_input(n)

    def write_output(self, n: int, value: bool) -> None:
        if not 1 <= n <= self.spec.outputs:
            raise IndexError(f"digital output {n} does not exist (1..{self.spec.outputs})")
        self.robot.write_output(n, value)

    def log(self, text: str, line: int) -> None:
        """The operator log: at most MAX_LOG_LINES lines per program (then one line that
        says how many more were not kept)."""
        if len(self.log_lines) < MAX_LOG_LINES:
            self.log_lines.append((self.clock.now(), line, text))
        else:
            self.log_dropped += 1
            if self.log_dropped == 1:
                self.log_lines.append((self.clock.now(), line, f"(more than {MAX_LOG_LINES} lines: the rest of "
                                                              "the log is not kept)"))
