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
:meth:`sample` leaves ``failed = (problem, line)``; the moves queued after it are
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
``second.start is not None`` branch), :meth:`MotionQueue._step_rate` and
:meth:`MotionQueue.resume`; ``tests/test_motionqueue.py`` runs the queue alone.

The override
------------
``override`` (percent) scales the time of the moves, the running one too: a smooth,
monotonic change of the timeline's rate (:meth:`_step_rate`) within every axis's
acceleration limit.

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

from compiler.triggers import PLACES, UNITS

from runtime.motion.moves import MovePlanner, MoveRecord, MoveRequest, Segment
from runtime.motion.trajectory import Trajectory

__all__ = ["RATE_CHANGE_MARGIN", "MotionQueue", "PlanningWorker"]

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


class MotionQueue:
    """The timeline of one robot's moves (module docstring).

    ``planner`` plans the moves; ``axes`` (with ``max_velocity`` and
    ``max_acceleration``) bound the changes of rate; ``worker``: plan there (None: at
    once). ``holds()`` says whether the host holds new moves back (no program, or the
    program's own pause); ``program_line()`` is the line an abort names when no move is
    under way.

    What the host reads: ``positions`` / ``velocities`` (the last setpoint), ``moves``
    and ``completed``, ``failed`` (a move that could not be planned in the background:
    ``(problem, line)``, taken by the host) and ``ended`` (the fault that ends the
    program: an abort at rest, a rest that cannot be planned).
    """

    def __init__(self, planner: MovePlanner, axes, worker: PlanningWorker | None = None,
                 holds: Callable[[], bool] = lambda: False, program_line: Callable[[], int] = lambda: 0):
        self.planner = planner
        self.axes = tuple(axes)
        self.n = len(self.axes)
        self.worker = worker
        self.holds = holds
        self.program_line = program_line
        self.period = 0.0
        self.t_move = 0.0  # the timeline (trajectory seconds)
        self.positions: tuple = (0.0,) * self.n
        self.velocities: tuple = (0.0,) * self.n
        self.accelerations: tuple | None = (0.0,) * self.n  # exact ones, or None (the setpoint goes without)
        self.rate = 1.0  # trajectory seconds per real second: the override, now
        self._override = 1.0  # the override's rate (what the rate goes to)
        self._percent = 100.0  # the override as the operator set it
        self.velocity_limit_scale = 1.0  # robot.velocity_limit_scale: the rate never exceeds it
        self._rate_from = self._rate_to = 1.0
        self._rate_t = self._rate_T = 0.0  # progress and length (s) of a change of rate
        self._path_velocity: tuple = (0.0,) * self.n  # the timeline's velocity per trajectory second
        self._path_acceleration: tuple = (0.0,) * self.n  # ... and acceleration (estimated)
        self._accelerations = tuple(a.max_acceleration * RATE_CHANGE_MARGIN for a in self.axes)
        self._now = 0.0  # the time of the last sample
        self.reset()

    def reset(self) -> None:
        """Forget the last program's moves and records (not real-time)."""
        self.moves: list[MoveRecord] = []
        self.completed = 0  # moves that reached their end (telemetry reads it every 10 ms)
        self.abort_reason: str | None = None  # set by abort(): end once at rest
        self._abort_fault = True  # the abort ends the program with a fault (else: quietly, an interrupt's halt)
        self.failed: tuple[str, int] | None = None
        self.ended: str | None = None
        self.clear()

    def clear(self) -> None:
        """Drop every move, planned or not, and any stop (the robot is at rest)."""
        self._segments: deque[Segment] = deque()  # planned, in order; the first one or two run
        self._requests: deque[MoveRequest] = deque()  # handed over, not planned yet (worker)
        self._planning: _PlanningJob | None = None
        self._last: Segment | None = None  # the last segment planned (the next plans from its end)
        self._stop: Trajectory | None = None  # a controlled stop under way (real seconds)
        self.t_stop = 0.0
        self.interrupted: Segment | None = None  # a move stopped before its end (pause/abort)
        self._hold = False  # stopping (or stopped) by bringing the timeline's rate to 0
        self._paused = False  # by the operator (the program may have handed over all its moves)
        self._interrupt = False  # stopped for an interrupt's handler (compiler.interrupts: stop)
        self._release_at_rest = False
        self._armed: list = []  # triggers of moves on the timeline: [timeline time, action, trigger, segment]
        self.due: list = []  # triggers reached: (real time the servo's reference is there, action), for the host
        self._release_at_rest = False  # an interrupt's handler ended before its stop did: go on at rest

    def start(self, positions: tuple, period: float) -> None:
        """A new program starts with the robot at ``positions``, setpoints every ``period``."""
        self.reset()
        self.period = period
        self.positions = tuple(positions)
        self.velocities = (0.0,) * self.n
        self.accelerations = (0.0,) * self.n
        self.t_move = 0.0

    # ---- what is moving ----
    @property
    def current(self) -> Trajectory | None:
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

    @property
    def line(self) -> int | None:
        """The source line of the move the robot is executing (stopping on, or waiting to
        resume); None when no move is under way."""
        if self.interrupted is not None:
            return self.interrupted.request.line
        segs = self._segments
        if segs and segs[0].start is not None:
            return segs[0].request.line
        return None

    @property
    def paused(self) -> bool:
        """Paused by the operator (:meth:`pause`)."""
        return self._paused

    def done(self, triggers: bool = True) -> bool:
        """Every move handed over has ended (and no stop is under way), and (``triggers``)
        its triggers have fired (the servo's reference is where they are)."""
        return (not self._segments and not self._requests and self._planning is None
                and self._stop is None and self.interrupted is None
                and (not triggers or (not self._armed and not self.due)))

    def at_rest(self) -> bool:
        return self.current is None or (self._hold and self.rate == 0.0 and not self._rate_T)

    def _holding(self) -> bool:
        """No new move may start: held by the host, paused, aborting, stopping, or a move
        to resume first."""
        return (self.holds() or self._paused or self._interrupt or self.abort_reason is not None
                or self._stop is not None
                or self.interrupted is not None or self._hold)

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
        if self.current is None or self._stop is not None:
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

    # ---- the period's sample (real-time) ----
    def sample(self, now: float) -> None:
        """Real-time: take a finished plan, then advance the motion by one period:
        ``positions`` and ``velocities`` are the setpoint for ``now``."""
        self._now = now
        if self._planning is not None and self._planning.done:
            self._planned()
        if self._stop is not None:
            self._sample_stop()
        elif self._segments:
            self._sample_timeline(now)
        elif self._armed:  # at rest with triggers 'after end' to come: the timeline goes on
            before = self.t_move
            self.t_move += self.period * self.rate
            self._fire(before, self.t_move, now)

    def _sample_stop(self) -> None:
        stop = self._stop
        self.t_stop += self.period
        self.positions, self.velocities = stop.sample(self.t_stop)
        self.accelerations = stop.accelerations_at(self.t_stop)  # exact for a StopRamp and a LineStop
        if self.t_stop >= stop.duration - 1e-12:
            self._stop = None
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
            self._arm(first)
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
        t_before = self.t_move
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
            self.accelerations = self._exact_accelerations((first, second), tm, rate)
        else:
            self.accelerations = self._exact_accelerations((first,), tm, rate)
        self.positions = positions
        if self._armed:
            self._fire(t_before, tm, now)
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

    def _exact_accelerations(self, running: tuple, tm: float, rate: float) -> tuple | None:
        """The timeline's accelerations at ``tm`` (per real second squared) when every move
        running has exact ones (:meth:`Trajectory.accelerations_at`) and the rate is steady;
        else None: the setpoint goes without, and the servo interpolates it C1 as before."""
        if self._rate_T:
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
        rate = max(self.rate, 1e-9)
        # it began (its time 0) between the last tick and this one: its first setpoint
        t_start = now - (self.t_move - segment.start) / rate
        segment.record = MoveRecord(request.line, request.kind, segment.end, segment.duration / rate, t_start,
                                    frames=request.frames)
        if segment.previous is not None and segment.offset is not None and segment.previous.record is not None:
            segment.previous.record.blended = True
        self.moves.append(segment.record)

    def _arm(self, segment: Segment) -> None:
        """A move placed on the timeline: its triggers at their times there."""
        if segment.triggers:
            self._armed.extend([[segment.start + t, action, trigger, segment] for t, action, trigger in segment.triggers])
            self._armed.sort(key=lambda x: x[0])

    def _fire(self, t_before: float, t_now: float, now: float) -> None:
        """The armed triggers the timeline reached from ``t_before`` to ``t_now`` (this
        tick's setpoint): each is due when the servo's reference passes it, between this
        tick and the next (it runs a period behind, interpolating these two setpoints)."""
        armed = self._armed
        span = t_now - t_before
        while armed and armed[0][0] <= t_now + 1e-12:
            at, action, _trigger, _segment = armed.pop(0)
            fraction = min(max((at - t_before) / span, 0.0), 1.0) if span > 0.0 else 1.0
            self.due.append((now + fraction * self.period, action))

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
            self._arm(second)
        else:
            second.offset = None  # too late (or interrupted): the corner is a stop

    # ---- operator control (real-time safe) ----
    def pause(self) -> float | None:
        """Hold: the motion decelerates to rest on its path (a PTP move in a controlled
        stop, a lin or circ move along its own line or arc, a blend along the blend); no
        new move starts until :meth:`resume`. Returns the time (s) within which the
        robot will be at rest, or None when it is already."""
        self._paused = True
        return self._stop_on_path()

    def resume(self) -> None:
        """Continue after :meth:`pause` (or the host's hold): the rest of an interrupted
        move is re-planned from where the robot stopped (at once, or when its stop ends);
        a blend stopped on the timeline speeds up again on it. Not while an interrupt's
        stop holds it (:meth:`interrupt_stop`)."""
        self._paused = False
        self._release()

    def interrupt_stop(self) -> float | None:
        """An interrupt fired with ``stop``: the motion stops on its path as for
        :meth:`pause`, held until :meth:`interrupt_release` (and the operator's resume, if
        the operator paused too). Returns the time within which the robot is at rest."""
        self._interrupt = True
        return self._stop_on_path()

    def interrupt_release(self) -> None:
        """The interrupt's handler ended (``then resume``): go on as :meth:`resume` does,
        once the robot is at rest (the stop is never cut short: ``stop`` stops)."""
        if self._stop is not None or (self._hold and (self.rate > 0.0 or self._rate_T)):
            self._release_at_rest = True
            return
        self._interrupt = False
        self._release()

    def _release(self) -> None:
        if self._paused or self._interrupt:
            return
        if self._hold:
            self._hold = False
            self._change_rate(self._override)
        elif self.interrupted is not None and self._stop is None:
            self._resume_move()

    def abort(self, reason: str, fault: bool = True) -> float | None:
        """A controlled stop as for :meth:`pause`, then ``ended`` is ``reason at line N``
        (at once when the robot is at rest); without ``fault`` (an interrupt's ``then
        halt``) the moves are dropped and nothing ends with a fault. Returns the time
        within which it will be at rest (None: already, or an abort is already under way)."""
        if self.abort_reason is not None:
            return None
        self.abort_reason = reason
        self._abort_fault = fault
        within = self._stop_on_path()
        if self.at_rest():
            self._at_rest_after_stop()
        return within

    def _stop_on_path(self) -> float | None:
        if self._stop is not None or self.interrupted is not None or self._hold:
            return None
        segs = self._segments
        if not segs or segs[0].start is None:
            return None  # at rest: the moves still queued wait (no new move starts while held)
        first = segs[0]
        second = segs[1] if len(segs) > 1 else None
        if second is not None and second.start is not None:
            # in (or scheduled into) a blend: stop on the timeline itself, so the robot stays
            # on the blended path and resume speeds up again on it
            self._hold = True
            self._change_rate(0.0)
            return self._rate_T
        stop = first.trajectory.stop(self.t_move - first.start, self.positions, self.velocities, self.rate)
        self._disarm(first, self.t_move - first.start, stop)
        segs.popleft()
        first.blendable = False
        if second is not None:
            second.offset = None
        first.stop = stop
        self.interrupted = first
        self._stop, self.t_stop = stop, 0.0
        return stop.duration

    def _disarm(self, segment: Segment, t: float, stop: Trajectory) -> None:
        """A move stops on its path from its time ``t`` (``stop``): its triggers not reached
        go with the rest of the move (counted from its end as before; from its start, the
        distance left after the stop, or the time left when it began; at once where the
        robot has passed them)."""
        left = []
        for entry in [e for e in self._armed if e[3] is segment]:
            self._armed.remove(entry)
            place, unit, amount, action = entry[2]
            if PLACES[place].words == "after start":
                done = segment.trajectory.path_distance(t, stop) if UNITS[unit].name == "mm" else t * 1000.0
                amount = max(amount - (done if done is not None else amount), 0.0)
            left.append((place, unit, amount, action))
        segment.request.carried = tuple(left)

    def _held(self) -> None:
        """The timeline's rate reached 0 (a stop inside a blend): at rest."""
        self.velocities = (0.0,) * self.n
        if self.abort_reason is not None:
            self._at_rest_after_stop()
        elif self._release_at_rest:
            self._release_at_rest = self._interrupt = False
            self._release()

    def _at_rest_after_stop(self) -> None:
        if self.abort_reason is not None:
            line = self.line
            self.clear()
            self.rate = self._override
            self._rate_T = 0.0
            if self._abort_fault:
                self.ended = self.ended or f"{self.abort_reason} at line {self.program_line() if line is None else line}"
            return
        if self._release_at_rest:
            self._release_at_rest = self._interrupt = False
        if not (self._paused or self._interrupt or self.holds()):
            self._resume_move()

    def _resume_move(self) -> None:
        """Plan the rest of the interrupted move from where the robot stopped (a PTP move
        at once; the rest of a line or arc like any Cartesian move: at once without a
        worker, else first in the planning queue)."""
        move = self.interrupted
        request = move.request
        left = move.stop.rest(move.end)
        if left is None:  # the stop ended at the move's target: the move is done
            self.interrupted = None
            if move.record is not None:
                move.record.t_end = self._now
            self.completed += 1
            if self._last is move:
                self._last = None
            self.due.extend([(self._now, action) for _place, _unit, _amount, action in request.carried])
            return
        kind, targets = left
        rest = MoveRequest(kind, tuple(targets), request.speed, request.acc, 0.0, request.line, rest_of=move,
                           frames=request.frames, triggers=request.carried)
        if kind == "ptp":
            self._take_plan(rest, *self.planner.plan(rest, self.positions, None, self.period))
            return
        self._requests.appendleft(rest)
        if self.worker is None:
            self._plan_next()

    # ---- planning ----
    def add(self, request: MoveRequest) -> str | None:
        """Hand over a move: planned at once without a worker (returns the problem of a
        move that cannot be planned), else when the worker is free."""
        self._requests.append(request)
        if self.worker is None:  # deterministic: plan at once (simulated time does not pass)
            return self._plan_next()
        return None

    def plan_waiting(self) -> tuple[str, int] | None:
        """Real-time: start planning the oldest waiting move if the worker is free;
        ``(problem, line)`` of one that cannot be planned (no worker)."""
        if self._requests and self._planning is None:
            request = self._requests[0]
            problem = self._plan_next()
            if problem is not None:
                return problem, request.line
        return None

    def _plan_next(self) -> str | None:
        """Plan the oldest request (from the end of the last planned move): at once
        without a worker (returns the problem of a move that cannot be planned), else on
        the worker."""
        request = self._requests[0]
        if request.rest_of is not None:  # from where the robot stopped, no blend before it
            previous, start = None, self.positions
        else:
            previous = self._last
            start = previous.end if previous is not None else self._chain_start()
        planner, period = self.planner, self.period

        def plan():
            return planner.plan(request, start, previous, period)

        if self.worker is None:
            self._requests.popleft()
            return self._take_plan(request, *plan())
        self._planning = self.worker.submit(_PlanningJob(plan, request))
        return None

    def _chain_start(self) -> tuple:
        if self.interrupted is not None:
            return self.interrupted.end
        return self.positions

    def _planned(self) -> None:
        """Real-time: take a finished background plan."""
        job, self._planning = self._planning, None
        if self.abort_reason is not None:
            return
        request = job.what
        if request in self._requests:
            self._requests.remove(request)
            problem = self._take_plan(request, *job.result)
            if problem is not None:
                self.failed = (problem, request.line)

    def _take_plan(self, request: MoveRequest, segment: Segment | None, problem: str | None) -> str | None:
        """Put a planned move on the timeline; the problem of a move that cannot be
        planned (the program stops at it, after the moves before it)."""
        move = request.rest_of
        if move is not None:  # the rest of an interrupted move: it goes first
            self.interrupted = None
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
            self._requests.clear()
            return problem
        if segment.previous is not None and segment.previous is not self._last:
            segment.offset = None  # the move it was to blend with was interrupted meanwhile
        self._segments.append(segment)
        self._last = segment
        self._schedule()
        return None
