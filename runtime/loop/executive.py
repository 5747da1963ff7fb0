"""The cyclic executive: one thread, a 1 ms base tick, components at multiples of it.

Each tick runs the due tasks in the fixed order sense -> decide -> plan -> control ->
guard -> act -> record. Two clocks stand behind one interface: the simulated clock (time moves
by exactly one tick per tick, as fast as the CPU allows, bit-for-bit deterministic) and
the wall clock (sleep, then spin to the tick's deadline). Per task the executive measures
execution time and lateness and counts deadline misses (with the simulated clock, execution times are sampled on one tick
in eight, and nothing is late); each task has a miss policy:
hard (one miss faults), firm (more than N misses in a window of W ticks faults), soft
(counted only). Statistics live in preallocated arrays: a tick allocates nothing.

The simulated clock's untimed ticks take a short path: the executive keeps, per tick of
its schedule table, the tasks that can run (bound to a running component, or to none),
refreshed when a component's lifecycle changes (``Component.watch``), and counts the
runs per table entry instead of per task. A change during a tick (the supervisor starts
the servo) sends the rest of that tick through the full per-task checks, so which tasks
run on which tick is the same on both paths.
"""
from __future__ import annotations

import math
import os
import time
from array import array
from dataclasses import dataclass, field
from typing import Callable

from runtime.loop.component import Lifecycle
from runtime.timing import TICK

_RUNNING = Lifecycle.RUNNING
_sleep = time.sleep

PHASES = ("sense", "decide", "plan", "control", "guard", "act", "record")

#: With the simulated clock, execution times are measured on one tick in this many.
SIM_SAMPLE_EVERY = 8

#: The largest schedule table (ticks of the periods' least common multiple) precomputed.
MAX_HYPERPERIOD = 10_000

#: What a deadline fault's message adds: how to find out what this host can hold, and what
#: to do about it.
DEADLINE_HINT = ("; measure what this host can hold with 'irl latency', let the loop have real-time "
                 "scheduling (asked for by default: the line at start says whether the host granted it, and how "
                 "to grant it), or count misses only (--deadline-policy soft)")

#: Lateness histogram: 10 us bins up to 20 ms (the last bin holds everything later).
_BIN = 10e-6
_BINS = 2000
#: The ticks' wake-up lateness: 1 us bins up to 20 ms (a host under SCHED_FIFO wakes up
#: within tens of microseconds: compared with ``irl latency``'s exact figures).
_WAKE_BIN = 1e-6
_WAKE_BINS = 20_000


class SimClock:
    """Simulated time: ``now`` is exactly ``ticks * tick``; waiting costs nothing."""

    simulated = True

    def __init__(self, tick: float = TICK):
        self.tick = tick
        self.ticks = 0

    def now(self) -> float:
        return self.ticks * self.tick

    @property
    def tick_time(self) -> float:
        """The time the current tick is scheduled for (here: ``now``)."""
        return self.ticks * self.tick

    def wait_until(self, t: float) -> None:
        """Real-time: jump to ``t`` (never backwards)."""
        target = round(t / self.tick)
        if target > self.ticks:
            self.ticks = target


#: How long before a deadline the wall clock stops sleeping and spins: at normal scheduling
#: a sleep may wake up late by the kernel's timer slack and by other processes, so it stops
#: early; a SCHED_FIFO/SCHED_RR thread wakes within tens of microseconds (no timer slack, it
#: preempts normal threads), and a long spin would only take a core from the rest of the
#: host (two spinning loops on a 2-core machine starve everything else).
SPIN_NORMAL = 0.0008
SPIN_REALTIME = 0.00025


def _spin_for_this_thread() -> float:
    try:
        policy = os.sched_getscheduler(0)
    except (OSError, AttributeError):
        return SPIN_NORMAL
    return SPIN_REALTIME if policy in (getattr(os, "SCHED_FIFO", -1), getattr(os, "SCHED_RR", -1)) else SPIN_NORMAL


class WallClock:
    """Wall time since construction: sleep until shortly before a deadline, then spin.

    The spin's length is chosen at the first wait, in the thread that runs the loop (after it
    has asked for its scheduling): :data:`SPIN_REALTIME` under SCHED_FIFO/SCHED_RR, else
    :data:`SPIN_NORMAL`; ``spin=`` fixes it."""

    simulated = False

    def __init__(self, spin: float | None = None):
        self.spin = spin  # how long before the deadline sleeping stops and spinning starts
        self._t0 = time.perf_counter()
        self.tick_time = 0.0  # the time the current tick is scheduled for (the last wait_until)

    def now(self) -> float:
        return time.perf_counter() - self._t0

    def wait_until(self, t: float) -> None:
        """Sleep, then spin to ``t`` (the only place the loop waits). The spin gives the
        interpreter lock away on every turn, so other threads are not shut out for the
        spin's whole length."""
        self.tick_time = t
        if self.spin is None:
            self.spin = _spin_for_this_thread()
        remaining = t - self.now()
        if remaining > self.spin:
            time.sleep(remaining - self.spin)
        while self.now() < t:
            _sleep(0)  # a zero sleep lets another thread (a server's I/O) take the interpreter


@dataclass
class MissPolicy:
    kind: str = "soft"  # "hard", "firm" or "soft"
    limit: int = 3  # firm: more than `limit` misses ...
    window: int = 1000  # ... within this many ticks faults


class TaskStats:
    """Execution time and lateness of one task (preallocated; no allocation per tick)."""

    __slots__ = ("runs", "timed", "exec_total", "exec_max", "late_max", "misses", "histogram", "recent", "bin")

    def __init__(self, bin: float = _BIN, bins: int = _BINS):
        self.runs = 0  # every run
        self.timed = 0  # runs whose execution time was measured
        self.exec_total = 0.0
        self.exec_max = 0.0
        self.late_max = 0.0
        self.misses = 0
        self.bin = bin
        self.histogram = array("l", bytes(8 * bins))
        self.recent: list[int] = []  # ticks of recent misses (firm policy only)

    def percentile(self, q: float) -> float:
        """Lateness (s) at quantile q, from the histogram: the upper edge of the bin that
        holds it (``bin`` s wide)."""
        total = sum(self.histogram)
        if not total:
            return 0.0
        rank, seen = max(q * total, 1), 0
        for i, n in enumerate(self.histogram):
            seen += n
            if seen >= rank:
                return (i + 1) * self.bin
        return len(self.histogram) * self.bin

    def summary(self) -> dict:
        return {"runs": self.runs, "misses": self.misses,
                "exec_mean_us": 1e6 * self.exec_total / self.timed if self.timed else 0.0,
                "exec_max_us": 1e6 * self.exec_max, "late_max_us": 1e6 * self.late_max,
                "late_p99_us": 1e6 * self.percentile(0.99)}


@dataclass(slots=True)
class Task:
    name: str
    run: Callable[[float], None]
    period: int  # in ticks
    phase: str
    enabled: Callable[[], bool] | None = None  # another condition, checked each due tick
    component: object = None  # runs only while this component is RUNNING
    policy: MissPolicy = field(default_factory=MissPolicy)
    stats: TaskStats = field(default_factory=TaskStats)
    # never on the short path: an enabled() condition, or a component that cannot be watched
    checked_each_tick: bool = False

    def __post_init__(self) -> None:
        self.checked_each_tick = self.enabled is not None


class Executive:
    """Runs tasks tick by tick; ``fault`` names the first deadline fault (then it stops)."""

    def __init__(self, clock, tick: float = TICK):
        self.clock = clock
        self.tick = tick
        self.ticks = 0
        self.tasks: list[Task] = []
        self.fault: str | None = None
        self.wakeups = TaskStats(_WAKE_BIN, _WAKE_BINS)  # how late each tick started (wall clock)
        # the ticks in which at least one task missed its deadline (a late tick makes every
        # task due in it miss: summing the tasks' misses counts one late tick many times)
        self.missed_ticks = 0
        self._last_missed_tick = -1
        self._last_tick_late = 0.0  # how late the last tick started (wall clock)
        self._hyper = 1  # ticks in the schedule table (0: no table)
        self._due: list[tuple[Task, ...]] = [()]  # tasks due on each tick of the table
        # The short path (simulated clock, untimed ticks; see the module's doc): per tick of
        # the table, the due tasks that can run now, or None where a due task has an
        # enabled() condition or a component that cannot be watched; and how many ticks ran
        # each entry since the runs were last added to the tasks' statistics.
        self._short = clock.simulated and getattr(clock, "tick", None) == tick
        self._runnable: list[tuple[Task, ...] | None] = [()]
        self._runnable_ticks: list[int] = [0]
        self._stale = True  # _runnable must be rebuilt before it is used

    def add(self, name: str, run: Callable[[float], None], period: float, phase: str,
            enabled: Callable[[], bool] | None = None, policy: MissPolicy | None = None,
            component=None) -> Task:
        """Schedule ``run(now)`` every ``period`` seconds (a multiple of the tick), only
        while ``component`` (if given) is running and ``enabled()`` (if given) holds."""
        if phase not in PHASES:
            raise ValueError(f"phase must be one of {PHASES}, not {phase!r}")
        ticks = round(period / self.tick)
        if ticks < 1 or abs(ticks * self.tick - period) > 1e-9:
            raise ValueError(f"{name}: period {period} s is not a multiple of the {self.tick} s tick")
        task = Task(name, run, ticks, phase, enabled, component, policy or MissPolicy())
        if component is not None and hasattr(component, "watch"):
            component.watch(self._invalidate)
        elif component is not None:
            task.checked_each_tick = True  # a component that cannot tell of its changes
        self.tasks.append(task)
        self.tasks.sort(key=lambda t: PHASES.index(t.phase))  # stable: insertion order within a phase
        self._plan()
        return task

    def set_period(self, name: str, period: float) -> None:
        """Not real-time (between programs): run task ``name`` every ``period`` seconds."""
        ticks = round(period / self.tick)
        if ticks < 1 or abs(ticks * self.tick - period) > 1e-9:
            raise ValueError(f"{name}: period {period} s is not a multiple of the {self.tick} s tick")
        for task in self.tasks:
            if task.name == name:
                task.period = ticks
                self._plan()
                return
        raise KeyError(f"no task {name!r}")

    def _plan(self) -> None:
        """The schedule: for each tick of the hyperperiod (the periods' least common
        multiple), the tasks due on it, in phase order. Periods whose hyperperiod exceeds
        MAX_HYPERPERIOD ticks get no table: each tick then picks its due tasks itself."""
        self._count_short_runs()
        hyper = math.lcm(*(t.period for t in self.tasks))
        self._hyper = hyper if hyper <= MAX_HYPERPERIOD else 0
        self._due = [tuple([t for t in self.tasks if k % t.period == 0]) for k in range(self._hyper)]
        self._runnable, self._runnable_ticks = [None] * self._hyper, [0] * self._hyper
        self._stale = True

    def _invalidate(self) -> None:
        """A component's lifecycle changed (real-time safe): rebuild the runnable lists."""
        self._stale = True

    def _count_short_runs(self) -> None:
        """Add the runs made on the short path to the tasks' statistics."""
        for runnable, ticks in zip(self._runnable, self._runnable_ticks):
            if runnable and ticks:
                for task in runnable:
                    task.stats.runs += ticks
        self._runnable_ticks = [0] * len(self._runnable_ticks)

    def _refresh(self) -> None:
        """Real-time (only after a lifecycle change): the runnable tasks of each tick of
        the table, from the components' states now."""
        self._count_short_runs()
        runnable = []
        for due in self._due:
            if any(t.checked_each_tick for t in due):
                runnable.append(None)
            else:
                runnable.append(tuple([t for t in due if t.component is None or t.component.lifecycle is _RUNNING]))
        self._runnable = runnable
        self._stale = False

    def step(self) -> None:
        """One tick (real-time): wait for its start, then run every due task in phase order."""
        k = self.ticks
        clock = self.clock
        if self._short and k % SIM_SAMPLE_EVERY and self._hyper:  # the short path (see the module's doc)
            if k > clock.ticks:
                clock.ticks = k  # the simulated clock's wait_until
            if self._stale:
                self._refresh()
            slot = k % self._hyper
            runnable = self._runnable[slot]
            if runnable is not None:
                scheduled = k * self.tick
                for task in runnable:
                    task.run(scheduled)
                    if self._stale:  # a lifecycle changed: check each of the tick's other tasks
                        self._finish_tick(k, scheduled, runnable, task)
                        return
                self._runnable_ticks[slot] += 1
                self.ticks = k + 1
                return
        scheduled = k * self.tick
        clock.wait_until(scheduled)
        simulated = clock.simulated
        # Simulated time does not pass while code runs: no lateness, no misses, and the
        # execution times are sampled on one tick in SIM_SAMPLE_EVERY; other ticks just run.
        timed = not simulated or k % SIM_SAMPLE_EVERY == 0
        perf = time.perf_counter
        if not simulated:
            start_late = clock.now() - scheduled
            self._last_tick_late = start_late
            wakeups = self.wakeups
            if start_late > wakeups.late_max:
                wakeups.late_max = start_late
            wakeups.histogram[min(int(start_late / _WAKE_BIN), _WAKE_BINS - 1)] += 1
        t1 = perf() if timed else 0.0
        due = self._due[k % self._hyper] if self._hyper else [t for t in self.tasks if k % t.period == 0]
        for task in due:
            component = task.component
            if component is not None and component.lifecycle is not _RUNNING:
                continue
            if task.enabled is not None and not task.enabled():
                continue
            if not timed:
                task.run(scheduled)
                task.stats.runs += 1
                continue
            t0 = t1
            task.run(scheduled)
            t1 = perf()
            spent = t1 - t0
            stats = task.stats
            stats.runs += 1
            stats.timed += 1
            stats.exec_total += spent
            if spent > stats.exec_max:
                stats.exec_max = spent
            if simulated:
                continue
            late = clock.now() - scheduled
            if late > stats.late_max:
                stats.late_max = late
            stats.histogram[min(int(late / _BIN), _BINS - 1)] += 1
            if late > task.period * self.tick:
                self._missed(task, k)
        self.ticks = k + 1

    def _finish_tick(self, k: int, scheduled: float, runnable: tuple, last: Task) -> None:
        """The short path's tick after a lifecycle change during ``last``'s run: count the
        runs so far, then run the due tasks after ``last`` that can run now."""
        done = runnable.index(last) + 1
        for task in runnable[:done]:
            task.stats.runs += 1
        due = self._due[k % self._hyper]
        for task in due[due.index(last) + 1:]:
            component = task.component
            if component is not None and component.lifecycle is not _RUNNING:
                continue
            task.run(scheduled)
            task.stats.runs += 1
        self.ticks = k + 1

    def _missed(self, task: Task, k: int) -> None:
        stats = task.stats
        stats.misses += 1
        if k != self._last_missed_tick:
            self._last_missed_tick = k
            self.missed_ticks += 1
        policy = task.policy
        if policy.kind == "hard":
            self.fault = self.fault or (f"deadline: {task.name} missed its {task.period * self.tick * 1000:g} ms "
                                        f"deadline (hard){DEADLINE_HINT}")
        elif policy.kind == "firm":
            recent = stats.recent
            recent.append(k)
            while recent and recent[0] <= k - policy.window:
                recent.pop(0)
            if len(recent) > policy.limit:
                self.fault = self.fault or (f"deadline: {task.name} missed {len(recent)} deadlines "
                                            f"within {policy.window} ticks (firm){DEADLINE_HINT}")

    def reset_statistics(self) -> None:
        """Not real-time: start counting afresh (a new cycle): forget a deadline fault,
        the misses and the execution-time and lateness statistics."""
        self.fault = None
        self.wakeups = TaskStats(_WAKE_BIN, _WAKE_BINS)
        self.missed_ticks = 0
        self._last_missed_tick = -1
        self._runnable_ticks = [0] * len(self._runnable_ticks)
        for task in self.tasks:
            task.stats = TaskStats()

    def resync(self) -> None:
        """Not real-time: after a pause in stepping (a server idle between programs), skip
        to the next tick boundary of the clock instead of catching up tick by tick; the
        clock's ``tick_time`` is then that tick's (what the components count in)."""
        self.ticks = max(self.ticks, math.ceil(self.clock.now() / self.tick))
        self.clock.wait_until(self.ticks * self.tick)

    def run(self, until: Callable[[], bool], max_ticks: int) -> int:
        """Step until ``until()`` holds or ``max_ticks`` ticks have run; returns ticks run."""
        start = self.ticks
        while self.ticks - start < max_ticks and not until():
            self.step()
        return self.ticks - start

    def statistics(self) -> dict:
        self._count_short_runs()
        return {task.name: task.stats.summary() for task in self.tasks}

    def wakeup_statistics(self) -> dict:
        """How late the ticks started (wall clock; zeros on the simulated clock): what the
        host's scheduling gave the loop, before any task's work (compare ``irl latency``)."""
        w = self.wakeups
        return {"late_max_us": 1e6 * w.late_max, "late_p99_us": 1e6 * w.percentile(0.99),
                "late_p999_us": 1e6 * w.percentile(0.999)}
