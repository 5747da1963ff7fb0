"""The motion queue: the timeline of planned moves, with look-ahead, blending, the speed
override and pause/resume/abort. It knows nothing of components, ports or the program:
its host (the trajectory generator) hands it moves, samples it every setpoint period and
reads what happened.

Moves and the timeline
----------------------
:meth:`MotionQueue.add` takes a :class:`~runtime.motion.moves.MoveRequest`; it is planned
(:class:`~runtime.motion.moves.MovePlanner`) from the end of the last planned move: at
once when the queue has no worker (the simulated clock: deterministic, simulated time
does not pass), else on the one long-lived :class:`PlanningWorker`, one move at a time in
order, so a Cartesian path check or a blend check never holds up the loop. The planned
moves (segments) run one after the other on one **timeline** (trajectory seconds; the
speed override is its rate): a move without ``approx`` stops exactly at its target and
the next starts at the following tick; a move with ``approx`` blends into the next (the
two are superposed in joint space for a checked overlap, :mod:`runtime.motion.blend`).
:meth:`MotionQueue.sample` advances the timeline by one period: ``positions`` and
``velocities`` are then the setpoint. Each move's line, planned duration and actual
duration are recorded (``moves``).

A move that cannot be planned: :meth:`add` returns the problem (no worker), or the next
:meth:`sample` leaves ``failed = (problem, line, tag)``; the moves queued after it are
dropped, the ones before it run to their end.

Stops
-----
:meth:`pause` and :meth:`abort` bring the motion to a controlled stop on its path: a
running move by its trajectory's own :meth:`~runtime.motion.trajectory.Trajectory.stop`
(a jerk-limited stop on a PTP line or on a Cartesian line or arc, else a uniform ramp);
inside a blend by bringing the timeline's rate to 0, so the robot stays on the blended
path. Both return the time within which the robot will be at rest (the host tells the
safety supervisor). :meth:`resume` plans the rest of an interrupted move from where it
stopped (the stop's :meth:`~runtime.motion.trajectory.Trajectory.rest`), or speeds the
timeline up again inside a blend. An abort ends, once at rest, with ``ended`` (the fault
text); so does a rest that cannot be planned.

To change what "pause inside a blend" does, read :meth:`MotionQueue._stop_on_path` (the
``second.start is not None`` branch), :meth:`SpeedOverride.step` and
:meth:`MotionQueue.resume`; ``tests/test_motionqueue.py`` runs the queue alone. What holds
the motion, and the stop under way, is a :class:`Holds`.

The override
------------
``override`` (percent) scales the time of the moves, the running one too: a smooth,
monotonic change of the timeline's rate (:class:`SpeedOverride`) within every axis's
acceleration limit.

The parts
---------
:class:`MotionQueue` is the timeline (the segments, where the setpoint is, the records)
and what coordinates its parts, each a class with the behaviour of its data:
:class:`Lookahead` (the moves handed over and not planned yet, the worker's job),
:class:`SpeedOverride` (the rate), :class:`Triggers` (armed and due) and :class:`Holds`.

Real time: :meth:`sample`, :meth:`add` with a worker, :meth:`pause`, :meth:`resume`,
:meth:`abort` and the override are real-time safe (no blocking, no thread creation, no
I/O); planning without a worker is not (the simulated clock only).
"""
from __future__ import annotations

import math
import queue
import threading
from collections import deque
from typing import Callable

from compiler.clauses import Motion
from compiler.triggers import PLACES, UNITS

from runtime.motion.moves import MovePlanner, MoveRecord, MoveRequest, Segment
from runtime.motion.stops import StopRamp
from runtime.motion.trajectory import Trajectory

__all__ = ["RATE_CHANGE_MARGIN", "Holds", "Lookahead", "MotionQueue", "PlanningWorker", "SpeedOverride", "Triggers"]

#: Timeline times closer than this are the same instant (the timeline is a running sum).
_SAME_TIME = 1e-9
#: A change of the rate (override, a stop inside a blend) keeps every axis within this
#: fraction of its acceleration limit (the rest is the servo's and the interpolation's).
RATE_CHANGE_MARGIN = 0.9


class _PlanningJob:
    """A plan to compute off the loop; ``done`` once ``result`` is there. The worker
    only computes: the loop takes the result when it is done."""

    def __init__(self, plan: Callable[[], tuple], what: MoveRequest):
        self.plan = plan
        self.what = what
        self.result: tuple = (None, "not planned")
        self.done = False

    def run(self) -> None:
        try:
            self.result = self.plan()
        except Exception:  # the planners never raise; a bug must not hang the move (nor show a Python message)
            self.result = (None, "internal error while planning the move: it could not be planned (not a fault of "
                                 "the program)")
        self.done = True


class PlanningWorker:
    """One long-lived planning thread, started before the loop runs (the tick never
    creates a thread): it takes jobs from a queue (a non-blocking put from the loop) and
    runs them in order."""

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


class SpeedOverride:
    """The speed override and the rate of the timeline it sets (trajectory seconds per real
    second): ``rate`` now, ``target`` (the override's rate, what the rate goes to),
    ``percent`` (as the operator set it) and ``velocity_limit_scale`` (the rate never
    exceeds it). A change of rate while a move runs takes ``change_time`` seconds (0:
    steady), a smooth, monotonic schedule slowed down where the path would break an
    axis's acceleration limit (:meth:`step`), which is why it follows the path's velocity
    and acceleration (:meth:`observe`). Real-time safe."""

    def __init__(self, axes):
        self.rate = 1.0
        self.target = 1.0
        self.percent = 100.0
        self.velocity_limit_scale = 1.0
        self._from = self._to = 1.0
        self._t = self.change_time = 0.0  # progress and length (s) of a change of rate
        zeros = (0.0,) * len(axes)
        self._path_velocity: tuple = zeros  # the timeline's velocity per trajectory second
        self._path_acceleration: tuple = zeros  # ... and acceleration (estimated)
        self._limits = tuple(a.max_acceleration * RATE_CHANGE_MARGIN for a in axes)
        self._v_per_a = max((a.max_velocity / a.max_acceleration for a in axes), default=0.0)

    def set_percent(self, percent: float) -> float:
        """The override in percent (clamped to 1-100); returns its rate, the new target."""
        self.percent = min(max(float(percent), 1.0), 100.0)
        self.target = min(self.percent / 100.0, self.velocity_limit_scale)
        return self.target

    def jump_to(self, rate: float) -> None:
        """The rate at once (nothing moves)."""
        self.rate = self._from = self._to = rate
        self._t = self.change_time = 0.0

    def change_to(self, rate: float) -> None:
        """Start a change of the rate to ``rate``: a quintic smoothstep (continuous in rate,
        its derivative and second derivative) long enough that v * dr/dt stays within the
        acceleration limits (dr/dt peaks at 1.875 |dr| / T for the quintic), and at least
        0.2 s."""
        self._from, self._to, self._t = self.rate, rate, 0.0
        self.change_time = max(0.2, 1.875 * abs(rate - self.rate) * self._v_per_a)

    def settle(self) -> None:
        """End a change of rate under way at its end (the next move starts at it)."""
        self.rate = self._from = self._to
        self.change_time = 0.0

    def restore(self) -> None:
        """The override's rate at once, after an abort's stop."""
        self.rate = self.target
        self.change_time = 0.0

    def step(self, dt: float) -> float:
        """The rate for the next period: towards the quintic schedule, but never changing
        faster than every axis's acceleration limit allows where the path is now. With the
        rate r of trajectory time, an axis moving at v (per trajectory second) and
        accelerating at a has the acceleration ``r^2 a + r' v``: a change of rate adds
        ``r' v`` to what the path itself asks, so r' is kept where the sum stays within the
        limit (0 always is: r <= 1). The rate then only lags the schedule, monotonically."""
        self._t += dt
        u = self._t / self.change_time
        target = self._to
        if u >= 1.0:
            scheduled = target
        else:
            scheduled = self._from + (target - self._from) * u * u * u * (10.0 + u * (6.0 * u - 15.0))
        rate = self.rate
        wanted = (scheduled - rate) / dt
        peak = 1.875 * abs(target - self._from) / self.change_time  # the schedule's steepest
        low, high = self._change_bounds(rate)
        change = min(max(wanted, low, -peak), high, peak)
        rate += change * dt
        if (change >= 0.0 and rate >= target) or (change <= 0.0 and rate <= target):
            if u >= 1.0 or rate == target:
                rate = target
        if u >= 1.0 and rate == target:
            self._from = target
            self.change_time = 0.0
        self.rate = rate
        return rate

    def _change_bounds(self, rate: float) -> tuple[float, float]:
        """How fast (1/s) the rate may change now: every axis within RATE_CHANGE_MARGIN of
        its acceleration limit, given the path's velocity and acceleration here."""
        low, high = -math.inf, math.inf
        r2 = rate * rate
        for v, a, limit in zip(self._path_velocity, self._path_acceleration, self._limits):
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

    def observe(self, velocities: tuple, step: float) -> None:
        """The path's velocities (per trajectory second) after a ``step`` of trajectory
        time: its acceleration, for the next change of rate."""
        if step > 1e-9:
            self._path_acceleration = tuple([(v - w) / step for v, w in zip(velocities, self._path_velocity)])
        self._path_velocity = velocities


class Triggers:
    """The triggers of the moves on the timeline (``armed``: ``[timeline time, action,
    trigger, segment]`` in time order) and the ones reached (``due``: ``(real time the
    servo's reference is there, action)``, for the host to take). Real-time safe."""

    def __init__(self):
        self.armed: list = []
        self.due: list = []

    def clear(self) -> None:
        self.armed = []
        self.due = []

    def arm(self, segment: Segment) -> None:
        """A move placed on the timeline: its triggers at their times there."""
        if segment.triggers:
            self.armed.extend([[segment.start + t, action, trigger, segment]
                               for t, action, trigger in segment.triggers])
            self.armed.sort(key=lambda x: x[0])

    def fire(self, t_before: float, t_now: float, now: float, period: float) -> None:
        """The armed triggers the timeline reached from ``t_before`` to ``t_now`` (this
        tick's setpoint): each is due when the servo's reference passes it, between this
        tick and the next (it runs a ``period`` behind, interpolating these two setpoints)."""
        armed = self.armed
        span = t_now - t_before
        while armed and armed[0][0] <= t_now + 1e-12:
            at, action, _trigger, _segment = armed.pop(0)
            fraction = min(max((at - t_before) / span, 0.0), 1.0) if span > 0.0 else 1.0
            self.due.append((now + fraction * period, action))

    def carry(self, segment: Segment, t: float, stop: Trajectory) -> None:
        """A move stops on its path from its time ``t`` (``stop``): its triggers not reached
        go with the rest of the move (counted from its end as before; from its start, the
        distance left after the stop, or the time left when it began; at once where the
        robot has passed them)."""
        left = []
        for entry in [e for e in self.armed if e[3] is segment]:
            self.armed.remove(entry)
            place, unit, amount, action = entry[2]
            if PLACES[place].words == "after start":
                done = segment.trajectory.path_distance(t, stop) if UNITS[unit].name == "mm" else t * 1000.0
                amount = max(amount - (done if done is not None else amount), 0.0)
            left.append((place, unit, amount, action))
        segment.request.carried = tuple(left)


class Lookahead:
    """The moves handed over and not planned yet (``requests``, oldest first) and the one
    being planned on the ``worker`` (``job``; None: no worker, or it is free): planned at
    once without a worker (the simulated clock: deterministic), else on the worker, one
    at a time in order. Real-time safe with a worker."""

    def __init__(self, planner: MovePlanner, worker: PlanningWorker | None):
        self.planner = planner
        self.worker = worker
        self.clear()

    def clear(self) -> None:
        self.requests: deque[MoveRequest] = deque()
        self.job: _PlanningJob | None = None

    @property
    def count(self) -> int:
        """Moves handed over and not planned yet."""
        return len(self.requests) + (self.job is not None)

    def plan_oldest(self, start: tuple, previous: Segment | None, period: float) -> tuple | None:
        """Plan the oldest request from ``start`` after ``previous``: without a worker at
        once (the request leaves the queue; returns ``(request, segment, problem)``), else
        on the worker (None; :meth:`finished` gives it when done)."""
        request = self.requests[0]
        planner = self.planner

        def plan():
            return planner.plan(request, start, previous, period)

        if self.worker is None:
            self.requests.popleft()
            return (request, *plan())
        self.job = self.worker.submit(_PlanningJob(plan, request))
        return None

    def finished(self) -> _PlanningJob | None:
        """The worker's job, once done (then no longer the queue's)."""
        job = self.job
        if job is None or not job.done:
            return None
        self.job = None
        return job


class Holds:
    """Why no new move may start, and the controlled stop under way: the operator's pause
    (``paused``), an interrupt's stop (``interrupt``, released at rest when its handler
    ended first: ``release_at_rest``), an abort (``abort_reason``; ``abort_fault``: it
    ends the program with a fault, else quietly, an interrupt's halt); a cut (``cut``: the
    moves are dropped at rest, a search move that found its input); a stop on a move's
    path (``stop``, at its time ``t_stop``; ``interrupted``: the move, whose rest resumes)
    or on the timeline inside a blend (``on_timeline``: its rate to 0)."""

    def __init__(self):
        self.abort_reason: str | None = None
        self.abort_fault = True
        self.clear()

    def clear(self) -> None:
        """No stop under way and nothing held (an abort's reason aside)."""
        self.stop: Trajectory | None = None
        self.t_stop = 0.0
        self.interrupted: Segment | None = None
        self.on_timeline = False
        self.paused = False
        self.interrupt = False
        self.release_at_rest = False
        self.cut = False

    def holding(self) -> bool:
        """Paused, stopped for an interrupt, aborting, stopping, or a move to resume first."""
        return (self.paused or self.interrupt or self.abort_reason is not None or self.stop is not None
                or self.interrupted is not None or self.on_timeline)

    @property
    def released(self) -> bool:
        """Neither the operator nor an interrupt holds the motion."""
        return not (self.paused or self.interrupt)

    def stop_on_path(self, segment: Segment, stop: Trajectory) -> None:
        """``segment`` stops on its path by ``stop`` (real seconds from now)."""
        segment.blendable = False
        segment.stop = stop
        self.interrupted = segment
        self.stop, self.t_stop = stop, 0.0

    def sample_stop(self, period: float) -> tuple[tuple, tuple, tuple | None, bool]:
        """The stop one ``period`` on: positions, velocities, accelerations and whether it
        reached rest (the stop is then over)."""
        stop = self.stop
        self.t_stop += period
        positions, velocities = stop.sample(self.t_stop)
        accelerations = stop.accelerations_at(self.t_stop)  # exact for a StopRamp and a LineStop
        at_rest = self.t_stop >= stop.duration - 1e-12
        if at_rest:
            self.stop = None
        return positions, velocities, accelerations, at_rest


class MotionQueue:
    """The timeline of one robot's moves (module docstring), with its parts: the
    look-ahead (:class:`Lookahead`: the moves not planned yet), the speed override
    (:class:`SpeedOverride`: the timeline's rate), the triggers on the timeline
    (:class:`Triggers`) and what holds the motion (:class:`Holds`: pause, interrupt,
    abort and the stop under way).

    ``planner`` plans the moves; ``axes`` (with ``max_velocity`` and
    ``max_acceleration``) bound the changes of rate; ``worker``: plan there (None: at
    once). ``holds()`` says whether the host holds new moves back (no program, or the
    program's own pause); ``program_line()`` is the line an abort names when no move is
    under way.

    What the host reads: ``positions`` / ``velocities`` (the last setpoint), ``moves``
    and ``completed``, ``failed`` (a move that could not be planned in the background:
    ``(problem, line)``, taken by the host), ``ended`` (the fault that ends the program:
    an abort at rest, a rest that cannot be planned) and ``due`` (the triggers reached).
    """

    def __init__(self, planner: MovePlanner, axes, worker: PlanningWorker | None = None,
                 holds: Callable[[], bool] = lambda: False, program_line: Callable[[], int] = lambda: 0):
        self.axes = tuple(axes)
        self.n = len(self.axes)
        self.holds = holds
        self.program_line = program_line
        self.lookahead = Lookahead(planner, worker)
        self.speed = SpeedOverride(self.axes)
        self.triggers = Triggers()
        self.hold = Holds()
        self.period = 0.0
        self.t_move = 0.0  # the timeline (trajectory seconds)
        self.positions: tuple = (0.0,) * self.n
        self.velocities: tuple = (0.0,) * self.n
        self.accelerations: tuple | None = (0.0,) * self.n  # exact ones, or None (the setpoint goes without)
        #: compute the setpoint every period (False: an offline run, which needs the timeline
        #: only: the setpoint is computed where a move ends and when a stop needs it)
        self.setpoints = True
        self._stale: float | None = None  # (setpoints off) the step of the period whose setpoint was not computed
        self._now = 0.0  # the time of the last sample
        self.reset()

    def reset(self) -> None:
        """Forget the last program's moves and records (not real-time)."""
        self.moves: list[MoveRecord] = []
        self.completed = 0  # moves that reached their end (telemetry reads it every 10 ms)
        self.hold.abort_reason = None  # set by abort(): end once at rest
        self.hold.abort_fault = True
        self.failed: tuple[str, int, int | None] | None = None  # (problem, line, the request's tag)
        self.ended: str | None = None
        self.clear()

    def clear(self) -> None:
        """Drop every move, planned or not, and any stop (the robot is at rest)."""
        self._segments: deque[Segment] = deque()  # planned, in order; the first one or two run
        self.lookahead.clear()
        self._last: Segment | None = None  # the last segment planned (the next plans from its end)
        self.hold.clear()
        self.triggers.clear()

    def start(self, positions: tuple, period: float) -> None:
        """A new program starts with the robot at ``positions``, setpoints every ``period``."""
        self.reset()
        self.period = period
        self.positions = tuple(positions)
        self.velocities = (0.0,) * self.n
        self.accelerations = (0.0,) * self.n
        self.t_move = 0.0
        self._stale = None

    # ---- the parts' names the host and the tests use ----
    @property
    def planner(self) -> MovePlanner:
        return self.lookahead.planner

    @property
    def worker(self) -> PlanningWorker | None:
        """Where the moves are planned (None: at once, in the caller)."""
        return self.lookahead.worker

    @worker.setter
    def worker(self, worker: PlanningWorker | None) -> None:
        self.lookahead.worker = worker

    @property
    def rate(self) -> float:
        """Trajectory seconds per real second: the override, now."""
        return self.speed.rate

    @property
    def velocity_limit_scale(self) -> float:
        """robot.velocity_limit_scale: the rate never exceeds it."""
        return self.speed.velocity_limit_scale

    @velocity_limit_scale.setter
    def velocity_limit_scale(self, scale: float) -> None:
        self.speed.velocity_limit_scale = scale

    @property
    def due(self) -> list:
        """The triggers reached: (real time the servo's reference is there, action), for the host."""
        return self.triggers.due

    @property
    def interrupted(self) -> Segment | None:
        """A move stopped before its end (pause, abort), its rest to resume."""
        return self.hold.interrupted

    @property
    def abort_reason(self) -> str | None:
        """The abort under way (the program ends once the robot is at rest)."""
        return self.hold.abort_reason

    # ---- what is moving ----
    @property
    def current(self) -> Trajectory | None:
        """What is being sampled now: a controlled stop, or the first running move's
        trajectory; None when the robot is not moving."""
        if self.hold.stop is not None:
            return self.hold.stop
        segs = self._segments
        if segs and segs[0].start is not None:
            return segs[0].trajectory
        return None

    @property
    def queued(self) -> int:
        """Moves handed over that have not started yet."""
        return sum(1 for s in self._segments if s.start is None) + self.lookahead.count

    @property
    def line(self) -> int | None:
        """The source line of the move the robot is executing (stopping on, or waiting to
        resume); None when no move is under way."""
        if self.hold.interrupted is not None:
            return self.hold.interrupted.request.line
        segs = self._segments
        if segs and segs[0].start is not None:
            return segs[0].request.line
        return None

    @property
    def paused(self) -> bool:
        """Paused by the operator (:meth:`pause`)."""
        return self.hold.paused

    def done(self, triggers: bool = True) -> bool:
        """Every move handed over has ended (and no stop is under way), and (``triggers``)
        its triggers have fired (the servo's reference is where they are)."""
        hold = self.hold
        return (not self._segments and not self.lookahead.count and hold.stop is None and hold.interrupted is None
                and (not triggers or (not self.triggers.armed and not self.triggers.due)))

    def at_rest(self) -> bool:
        return self.current is None or (self.hold.on_timeline and self.speed.rate == 0.0 and not self.speed.change_time)

    def _holding(self) -> bool:
        """No new move may start: held by the host, paused, aborting, stopping, or a move
        to resume first."""
        return self.holds() or self.hold.holding()

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
        return self.speed.percent

    @override.setter
    def override(self, percent: float) -> None:
        rate = self.speed.set_percent(percent)
        if self.hold.on_timeline:  # stopping or stopped on the timeline: resume goes to the new rate
            return
        if self.current is None or self.hold.stop is not None:
            self.speed.jump_to(rate)
            return
        self.speed.change_to(rate)

    # ---- the period's sample (real-time) ----
    def sample(self, now: float) -> None:
        """Real-time: take a finished plan, then advance the motion by one period:
        ``positions`` and ``velocities`` are the setpoint for ``now``."""
        self._now = now
        job = self.lookahead.finished()
        if job is not None:
            self._planned(job)
        if self.hold.stop is not None:
            self._sample_stop()
        elif self._segments:
            self._sample_timeline(now)
        elif self.triggers.armed:  # at rest with triggers 'after end' to come: the timeline goes on
            before = self.t_move
            self.t_move += self.period * self.speed.rate
            self.triggers.fire(before, self.t_move, now, self.period)

    def _sample_stop(self) -> None:
        self.positions, self.velocities, self.accelerations, at_rest = self.hold.sample_stop(self.period)
        if at_rest:
            self.velocities = (0.0,) * self.n
            self.accelerations = self.velocities  # at rest (not the stop's value a rounding error before its end)
            self._at_rest_after_stop()

    def _sample_timeline(self, now: float) -> None:
        segs = self._segments
        first = segs[0]
        if first.start is None:
            if self._holding():
                return
            first.start = self.t_move  # starts now: its first sample one period on
            self.triggers.arm(first)
            self._schedule()
        held = False
        speed = self.speed
        changing = bool(speed.change_time)
        if changing:
            before = speed.rate
            rate = speed.step(self.period)
            held = self.hold.on_timeline and not speed.change_time  # the rate reached 0: at rest on the path
            # trajectory time over the period at the mean rate: the setpoints' positions then
            # agree with their velocities (rate x the path's), which the servo interpolates
            step = self.period * 0.5 * (before + rate)
        else:
            rate = speed.rate
            step = self.period * rate
        t_before = self.t_move
        tm = self.t_move = self.t_move + step
        if first.record is None:
            self._started(first, now)
        t = tm - first.start
        second = self._blending(tm)
        if second is not None and second.record is None:
            self._started(second, now)
        if self.setpoints or changing or t >= first.duration - 1e-12:
            self._stale = None
            velocities = self._setpoint(tm, second, rate)
            speed.observe(velocities, step)  # the path's acceleration, for the next change of rate
            self.velocities = velocities if rate == 1.0 else tuple([v * rate for v in velocities])
        else:
            self._stale = step  # (an offline run: the setpoint when something needs it, _refresh)
        if self.triggers.armed:
            self.triggers.fire(t_before, tm, now, self.period)
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
                if speed.change_time and not self.hold.on_timeline:
                    speed.settle()  # a change of override under way: the next move has it
                if self.hold.on_timeline:
                    self._held()

    def _blending(self, tm: float) -> Segment | None:
        """The second move when it runs at timeline time ``tm`` (blended into the first)."""
        segs = self._segments
        second = segs[1] if len(segs) > 1 else None
        if second is not None and second.start is not None and tm > second.start + _SAME_TIME:
            return second
        return None

    def _setpoint(self, tm: float, second: Segment | None, rate: float) -> tuple:
        """The setpoint at timeline time ``tm``: ``positions`` and ``accelerations`` set, the
        path's velocities (per trajectory second) returned; ``second`` blended in if given."""
        first = self._segments[0]
        positions, velocities = first.trajectory.sample(tm - first.start)
        if second is not None:
            p2, v2 = second.trajectory.sample(tm - second.start)
            corner = first.end
            positions = tuple([a + b - c for a, b, c in zip(positions, p2, corner)])
            velocities = tuple([a + b for a, b in zip(velocities, v2)])
            self.accelerations = self._exact_accelerations((first, second), tm, rate)
        else:
            self.accelerations = self._exact_accelerations((first,), tm, rate)
        self.positions = positions
        return velocities

    def setpoint_now(self) -> None:
        """Make ``positions`` and ``velocities`` the setpoint of now where the last periods'
        were not computed (``setpoints`` off: an offline run, for a sensor of the simulated
        cell that reads where the tool is)."""
        self._refresh()

    def _refresh(self) -> None:
        """Not every period's setpoint was computed (``setpoints`` off): compute the one of
        now, with the path's velocity and acceleration as sampling every period would
        have left them (from this period's sample and the one before)."""
        step = self._stale
        if step is None or not self._segments or self._segments[0].start is None:
            return
        self._stale = None
        speed, tm, rate = self.speed, self.t_move, self.speed.rate
        before = tm - step
        if before - self._segments[0].start > 0.0:
            speed.observe(self._setpoint(before, self._blending(before), rate), 0.0)
        velocities = self._setpoint(tm, self._blending(tm), rate)
        speed.observe(velocities, step)
        self.velocities = velocities if rate == 1.0 else tuple([v * rate for v in velocities])

    def _exact_accelerations(self, running: tuple, tm: float, rate: float) -> tuple | None:
        """The timeline's accelerations at ``tm`` (per real second squared) when every move
        running has exact ones (:meth:`Trajectory.accelerations_at`) and the rate is steady;
        else None: the setpoint goes without, and the servo interpolates it C1 as before."""
        if self.speed.change_time:
            return None
        total = None
        for segment in running:
            a = segment.trajectory.accelerations_at(tm - segment.start)
            if a is None:
                return None
            total = a if total is None else tuple([x + y for x, y in zip(total, a)])
        return total if rate == 1.0 else tuple([x * rate * rate for x in total])

    def _started(self, segment: Segment, now: float) -> None:
        request = segment.request
        rate = max(self.speed.rate, 1e-9)
        # it began (its time 0) between the last tick and this one: its first setpoint
        t_start = now - (self.t_move - segment.start) / rate
        segment.record = MoveRecord(request.line, request.kind, segment.end, segment.duration / rate, t_start,
                                    frames=request.frames, approach=request.approach)
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
            self.triggers.arm(second)
        else:
            second.offset = None  # too late (or interrupted): the corner is a stop

    # ---- operator control (real-time safe) ----
    def pause(self) -> float | None:
        """Hold: the motion decelerates to rest on its path (a PTP move in a controlled
        stop, a lin or circ move along its own line or arc, a blend along the blend); no
        new move starts until :meth:`resume`. Returns the time (s) within which the
        robot will be at rest, or None when it is already."""
        self.hold.paused = True
        return self._stop_on_path()

    def resume(self) -> None:
        """Continue after :meth:`pause` (or the host's hold): the rest of an interrupted
        move is re-planned from where the robot stopped (at once, or when its stop ends);
        a blend stopped on the timeline speeds up again on it. Not while an interrupt's
        stop holds it (:meth:`interrupt_stop`)."""
        self.hold.paused = False
        self._release()

    def interrupt_stop(self) -> float | None:
        """An interrupt fired with ``stop``: the motion stops on its path as for
        :meth:`pause`, held until :meth:`interrupt_release` (and the operator's resume, if
        the operator paused too). Returns the time within which the robot is at rest."""
        self.hold.interrupt = True
        return self._stop_on_path()

    def interrupt_release(self) -> None:
        """The interrupt's handler ended (``then resume``): go on as :meth:`resume` does,
        once the robot is at rest (the stop is never cut short: ``stop`` stops)."""
        hold = self.hold
        if hold.stop is not None or (hold.on_timeline and (self.speed.rate > 0.0 or self.speed.change_time)):
            hold.release_at_rest = True
            return
        hold.interrupt = False
        self._release()

    def _release(self) -> None:
        hold = self.hold
        if not hold.released:
            return
        if hold.on_timeline:
            hold.on_timeline = False
            self.speed.change_to(self.speed.target)
        elif hold.interrupted is not None and hold.stop is None:
            self._resume_move()

    def abort(self, reason: str, fault: bool = True) -> float | None:
        """A controlled stop as for :meth:`pause`, then ``ended`` is ``reason at line N``
        (at once when the robot is at rest); without ``fault`` (an interrupt's ``then
        halt``) the moves are dropped and nothing ends with a fault. Returns the time
        within which it will be at rest (None: already, or an abort is already under way)."""
        if self.hold.abort_reason is not None:
            return None
        self.hold.abort_reason = reason
        self.hold.abort_fault = fault
        within = self._stop_on_path()
        if self.at_rest():
            self._at_rest_after_stop()
        return within

    def cut(self) -> float | None:
        """Stop on the path now and drop the rest (a search move that found its input): the
        motion stops as for :meth:`pause` (on a lin or circ move's own line or arc; inside
        a blend on the blended path); the move under way ends where the robot comes to rest
        (its record ends there), and every move after it, planned or not, is dropped with
        its triggers not reached. Nothing is held afterwards and nothing ends with a fault:
        the next move handed over starts from there. A pause or an interrupt's stop under
        way goes on as it was, and the moves are dropped at its rest. Returns the time
        within which the robot will be at rest (None: it is already, or a stop is under way)."""
        hold = self.hold
        if hold.abort_reason is not None:
            return None  # (an abort drops every move at its rest)
        hold.cut = True
        within = self._stop_on_path()
        self.lookahead.clear()
        segs = self._segments
        while segs and segs[-1].start is None:  # the moves not started: dropped now
            segs.pop()
        self._last = None
        if hold.stop is None and not hold.on_timeline:  # at rest (nothing had started, or it was held)
            self._drop_cut()
        return within

    def _drop_cut(self) -> None:
        """A cut reached rest: the move it stopped has ended there, nothing else is left."""
        hold = self.hold
        hold.cut = False
        move, hold.interrupted = hold.interrupted, None
        if move is not None and move.record is not None:
            move.record.t_end = self._now
            self.completed += 1
        for segment in self._segments:  # (stopped on the timeline, in a blend)
            if segment.record is not None:
                segment.record.t_end = self._now
                self.completed += 1
        self._segments.clear()
        self.lookahead.clear()
        self._last = None
        self.triggers.armed = []  # (those reached are still due)
        self.velocities = (0.0,) * self.n
        self.accelerations = self.velocities

    def stop_in_joint_space(self, deceleration: tuple) -> float | None:
        """Replace the stop under way (a pause's, an abort's) by every axis ramped to rest
        together at ``deceleration`` (per axis) along the direction of motion
        (:class:`runtime.motion.stops.StopRamp`): a lin or circ move's tool then leaves its
        line by a little. For a jog's release, where a prompt stop matters more than the
        line (a stop on a Cartesian path may run to the move's end where no sooner one
        keeps the joints' limits). Returns its duration (None: no stop under way)."""
        hold = self.hold
        if hold.stop is None:
            return None
        stop = StopRamp(self.positions, self.velocities, deceleration)
        hold.stop, hold.t_stop = stop, 0.0
        if hold.interrupted is not None:
            hold.interrupted.stop = stop
        return stop.duration

    def _stop_on_path(self) -> float | None:
        hold = self.hold
        if hold.stop is not None or hold.interrupted is not None or hold.on_timeline:
            return None
        self._refresh()
        segs = self._segments
        if not segs or segs[0].start is None:
            return None  # at rest: the moves still queued wait (no new move starts while held)
        first = segs[0]
        second = segs[1] if len(segs) > 1 else None
        if second is not None and second.start is not None:
            # in (or scheduled into) a blend: stop on the timeline itself, so the robot stays
            # on the blended path and resume speeds up again on it
            hold.on_timeline = True
            self.speed.change_to(0.0)
            return self.speed.change_time
        stop = first.trajectory.stop(self.t_move - first.start, self.positions, self.velocities, self.speed.rate)
        self.triggers.carry(first, self.t_move - first.start, stop)
        segs.popleft()
        if second is not None:
            second.offset = None
        hold.stop_on_path(first, stop)
        return stop.duration

    def _held(self) -> None:
        """The timeline's rate reached 0 (a stop inside a blend): at rest."""
        self.velocities = (0.0,) * self.n
        hold = self.hold
        if hold.abort_reason is not None:
            self._at_rest_after_stop()
        elif hold.cut:
            hold.on_timeline = False
            self.speed.restore()
            self._drop_cut()
        elif hold.release_at_rest:
            hold.release_at_rest = hold.interrupt = False
            self._release()

    def _at_rest_after_stop(self) -> None:
        hold = self.hold
        if hold.abort_reason is not None:
            line = self.line
            self.clear()
            self.speed.restore()
            if hold.abort_fault and not self.ended:
                self.ended = f"{hold.abort_reason} at line {self.program_line() if line is None else line}"
            return
        if hold.cut:
            self._drop_cut()
            return
        if hold.release_at_rest:
            hold.release_at_rest = hold.interrupt = False
        if hold.released and not self.holds():
            self._resume_move()

    def _resume_move(self) -> None:
        """Plan the rest of the interrupted move from where the robot stopped (a PTP move
        at once; the rest of a line or arc like any Cartesian move: at once without a
        worker, else first in the planning queue)."""
        move = self.hold.interrupted
        request = move.request
        left = move.stop.rest(move.end)
        if left is None:  # the stop ended at the move's target: the move is done
            self.hold.interrupted = None
            if move.record is not None:
                move.record.t_end = self._now
            self.completed += 1
            if self._last is move:
                self._last = None
            self.triggers.due.extend([(self._now, action) for _place, _unit, _amount, action in request.carried])
            return
        kind, targets = left
        rest = MoveRequest(kind, tuple(targets), request.speed, request.acc, 0.0, request.line, rest_of=move,
                           frames=request.frames, triggers=request.carried)
        if kind == Motion.PTP:
            self._take_plan(rest, *self.lookahead.planner.plan(rest, self.positions, None, self.period))
            return
        self.lookahead.requests.appendleft(rest)
        if self.lookahead.worker is None:
            self._plan_next()

    # ---- planning ----
    def add(self, request: MoveRequest) -> str | None:
        """Hand over a move: planned at once without a worker (returns the problem of a
        move that cannot be planned), else when the worker is free."""
        self.lookahead.requests.append(request)
        if self.lookahead.worker is None:  # deterministic: plan at once (simulated time does not pass)
            return self._plan_next()
        return None

    def plan_waiting(self) -> tuple[str, int, int | None] | None:
        """Real-time: start planning the oldest waiting move if the worker is free;
        ``(problem, line, tag)`` of one that cannot be planned (no worker)."""
        lookahead = self.lookahead
        if lookahead.requests and lookahead.job is None:
            request = lookahead.requests[0]
            problem = self._plan_next()
            if problem is not None:
                return problem, request.line, request.tag
        return None

    def _plan_next(self) -> str | None:
        """Plan the oldest request (from the end of the last planned move): at once
        without a worker (returns the problem of a move that cannot be planned), else on
        the worker."""
        if self.lookahead.requests[0].rest_of is not None:  # from where the robot stopped, no blend before it
            previous, start = None, self.positions
        else:
            previous, start = self._last, self.planning_start()
        planned = self.lookahead.plan_oldest(start, previous, self.period)
        return None if planned is None else self._take_plan(*planned)

    @property
    def last_planned(self) -> Segment | None:
        """The move planned last (the next one is planned from its end and may blend with
        it); None when no planned move is left on the timeline."""
        return self._last

    def planning_start(self) -> tuple:
        """The joints the next move handed over is planned from: the end of the move planned
        last, else the end of the interrupted move, else where the robot is."""
        return self._last.end if self._last is not None else self._chain_start()

    def _chain_start(self) -> tuple:
        if self.hold.interrupted is not None:
            return self.hold.interrupted.end
        return self.positions

    def _planned(self, job: _PlanningJob) -> None:
        """Real-time: take a finished background plan."""
        if self.hold.abort_reason is not None:
            return
        request = job.what
        requests = self.lookahead.requests
        if request in requests:
            requests.remove(request)
            problem = self._take_plan(request, *job.result)
            if problem is not None:
                self.failed = (problem, request.line, request.tag)

    def _take_plan(self, request: MoveRequest, segment: Segment | None, problem: str | None) -> str | None:
        """Put a planned move on the timeline; the problem of a move that cannot be
        planned (the program stops at it, after the moves before it)."""
        move = request.rest_of
        if move is not None:  # the rest of an interrupted move: it goes first
            self.hold.interrupted = None
            if segment is None:
                self.ended = self.ended or f"cannot resume the move at line {request.line}: {problem}"
                self.clear()
                return None
            segment.record = move.record  # the same move, continued
            self._segments.appendleft(segment)
            if self._last is move:
                self._last = segment
            return None
        if segment is None:
            self.lookahead.requests.clear()
            return problem
        if segment.previous is not None and segment.previous is not self._last:
            segment.offset = None  # the move it was to blend with was interrupted meanwhile
        self._segments.append(segment)
        self._last = segment
        self._schedule()
        return None
