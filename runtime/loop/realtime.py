"""Real-time scheduling for the loop, and what this host's wake-ups can hold
(``irl latency``).

The 1 ms loop runs in a general-purpose Linux process. What it gets from the host is
measured, not assumed:

* :func:`apply` asks for real-time scheduling for the calling thread (the loop's):
  ``SCHED_FIFO`` at a priority, memory locked (``mlockall``: no page fault in a tick), a
  CPU of its own; it never fails, it says what it got in one line ("SCHED_FIFO 50, memory
  locked, CPU 1", or "normal scheduling: no permission for SCHED_FIFO 50, memory not
  locked (...); grant it with ..."). By default (no flag) the wall clock's loop asks for
  SCHED_FIFO :data:`DEFAULT_PRIORITY` with memory locked, as ros2_control's controller
  manager does; ``--rt-priority 0`` asks for normal scheduling.
* :func:`measure` wakes up every ``period`` for ``duration`` the way the loop does
  (:class:`runtime.loop.executive.WallClock`: sleep, then spin to the deadline) and records
  how late each wake-up was; :func:`verdict` says which deadline policy a 1 ms servo
  could hold on it (the executive's: hard, firm with its limit and window, soft).

The scheduling flags are declared once (:data:`FLAGS`, in runtime/scheduling.py, which
``irl serve``'s server process reads without importing the loop) and read by ``irl run``,
``irl serve`` and ``irl latency``.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import math
import os
from array import array
from dataclasses import dataclass
from functools import cached_property

from runtime.loop.executive import WallClock
from runtime.scheduling import (  # noqa: F401 (the flags and what they ask for: here for the loop's users)
    DEFAULT, DEFAULT_PRIORITY, FLAGS, NORMAL, PRIORITIES, Scheduling, add_arguments, given, scheduling,
)
from runtime.timing import TICK

__all__ = ["DEFAULT", "DEFAULT_PRIORITY", "FLAGS", "GRANT", "Applied", "Latency", "Scheduling", "add_arguments",
           "apply", "given", "measure", "rank_helpers", "scheduling", "verdict"]

#: How a user grants real-time scheduling and memory locking to the runtime.
GRANT = ("grant it with 'sudo setcap cap_sys_nice,cap_ipc_lock+ep \"$(readlink -f .venv/bin/python)\"', or an "
         "rtprio and memlock limit for your user in /etc/security/limits.conf, or run as root")

_MCL_CURRENT, _MCL_FUTURE = 1, 2


def _mlockall() -> str | None:
    """Lock the process's memory; None when done, else why not."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        if libc.mlockall(_MCL_CURRENT | _MCL_FUTURE) == 0:
            return None
        return os.strerror(ctypes.get_errno())
    except (OSError, AttributeError) as exc:
        return str(exc)


def _munlockall() -> None:
    try:
        ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True).munlockall()
    except (OSError, AttributeError):
        pass


def _apply(wanted: Scheduling) -> tuple[str, bool]:
    """:func:`apply`, and whether the memory was locked."""
    parts, refused, locked = [], False, False
    if wanted.priority is not None:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(wanted.priority))
            parts.append(f"SCHED_FIFO {wanted.priority}")
        except PermissionError:
            parts.append(f"normal scheduling: no permission for SCHED_FIFO {wanted.priority}")
            refused = True
        except (OSError, AttributeError) as exc:
            parts.append(f"normal scheduling: SCHED_FIFO {wanted.priority} refused ({exc})")
            refused = True
    else:
        parts.append("normal scheduling")
    if wanted.lock_memory:
        why = _mlockall()
        locked = why is None
        parts.append("memory locked" if locked else f"memory not locked ({why})")
        refused = refused or not locked
    if wanted.cpu is not None:
        try:
            os.sched_setaffinity(0, {wanted.cpu})
            parts.append(f"CPU {wanted.cpu}")
        except (OSError, AttributeError) as exc:
            parts.append(f"any CPU (CPU {wanted.cpu} refused: {exc})")
    return ", ".join(parts) + (f"; {GRANT}" if refused else ""), locked


def apply(wanted: Scheduling) -> str:
    """Ask for ``wanted`` for the calling thread (the loop's: call it there, after any
    thread that must stay at normal priority has started); returns what it got, in one
    line ("SCHED_FIFO 50, memory locked"; where refused, the fallback and how to grant it:
    "normal scheduling: no permission for SCHED_FIFO 50, memory not locked (...); grant it
    with ..."). Never raises."""
    return _apply(wanted)[0]


class Applied:
    """``with Applied(wanted) as got:`` :func:`apply` for the calling thread (``got.text``
    says what it got), and the thread's scheduling, CPUs and the process's memory as they
    were afterwards: for a command run in a process that goes on (``irl run``, ``irl
    latency`` called in-process). Never raises."""

    def __init__(self, wanted: Scheduling):
        self.wanted = wanted
        self.text = ""
        self._before: tuple | None = None
        self._locked = False

    def __enter__(self) -> "Applied":
        try:
            self._before = (os.sched_getscheduler(0), os.sched_getparam(0), os.sched_getaffinity(0))
        except (OSError, AttributeError):
            self._before = None
        self.text, self._locked = _apply(self.wanted)
        return self

    def __exit__(self, *_exc) -> None:
        if self._before is not None:
            policy, param, cpus = self._before
            try:
                os.sched_setscheduler(0, policy, param)
                if self.wanted.cpu is not None:
                    os.sched_setaffinity(0, cpus)
            except OSError:
                pass
        if self._locked:
            _munlockall()


def rank_helpers() -> int:
    """When the calling thread (the loop's) runs under SCHED_FIFO at priority p, put every
    other thread of this process (the move planner, the report and calibration writers)
    at SCHED_FIFO p - 1; returns how many were set. They share the interpreter lock with
    the loop: at normal priority, a busy process could preempt one while it holds the lock
    and the loop would wait for the lock as long as that process runs (a priority
    inversion: ticks 3-12 ms late measured under load); one below the loop, no normal
    process preempts them, and the loop still preempts them for the CPU. Not real-time
    (a few system calls): call it before a cycle starts, after its threads exist. Never
    raises."""
    import threading

    try:
        if os.sched_getscheduler(0) != os.SCHED_FIFO:
            return 0
        priority = max(PRIORITIES[0], os.sched_getparam(0).sched_priority - 1)
    except (OSError, AttributeError):
        return 0
    me, count = threading.get_native_id(), 0
    for thread in threading.enumerate():
        tid = thread.native_id
        if tid is None or tid == me:
            continue
        try:
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
            count += 1
        except OSError:
            pass  # (a thread that has just ended)
    return count


# ---------------------------------------------------------------------------- latency


#: Of each period, the share a tick's own work may take (the loop's components take tens
#: of microseconds of a 1 ms tick): a wake-up later than the rest misses the deadline.
WORK_SHARE = 0.1


@dataclass
class Latency:
    """How late the wake-ups of :func:`measure` were: ``period`` and ``duration`` (s),
    ``late`` (s, one per wake-up, in order)."""

    period: float
    duration: float
    late: array

    @cached_property
    def _ordered(self) -> list[float]:
        return sorted(self.late)

    def percentile(self, q: float) -> float:
        ordered = self._ordered
        if not ordered:
            return 0.0
        return ordered[min(len(ordered) - 1, max(0, math.ceil(q * len(ordered)) - 1))]

    @cached_property
    def misses(self) -> list[int]:
        """The wake-ups (indices) too late for a tick's work to finish within its period."""
        budget = self.period * (1.0 - WORK_SHARE)
        return [k for k, late in enumerate(self.late) if late > budget]

    def histogram(self, bins: int = 10) -> list[tuple[float, float, int]]:
        """``(from, to, count)`` of the lateness in ``bins`` equal bins up to its maximum."""
        top = max(self.late, default=0.0)
        width = top / bins if top > 0.0 else 1e-6
        counts = [0] * bins
        for late in self.late:
            counts[min(int(late / width), bins - 1)] += 1
        return [(i * width, (i + 1) * width, c) for i, c in enumerate(counts)]


def measure(period: float = TICK, duration: float = 10.0, clock: WallClock | None = None) -> Latency:
    """Wake up every ``period`` s for ``duration`` s as the loop does (sleep, then spin to
    each deadline, the schedule fixed from the start) and record how late each wake-up
    was."""
    if not (period > 0.0 and math.isfinite(period)):
        raise ValueError(f"period {period!r}: expected a positive number of seconds")
    if not (duration > 0.0 and math.isfinite(duration)):
        raise ValueError(f"duration {duration!r}: expected a positive number of seconds")
    clock = clock or WallClock()
    late = array("d")
    start = clock.now()
    n = max(1, int(duration / period))
    for k in range(1, n + 1):
        due = start + k * period
        clock.wait_until(due)
        late.append(clock.now() - due)
    return Latency(period, duration, late)


def verdict(latency: Latency, limit: int, window: int) -> tuple[str, str]:
    """The strictest deadline policy a servo task at ``latency.period`` could hold on this
    host, and why: ``("hard", ...)`` without a miss, ``("firm", ...)`` when no ``window``
    wake-ups hold more than ``limit`` misses (the executive's firm rule), else
    ``("soft", ...)``."""
    misses = latency.misses
    if not misses:
        return "hard", f"no wake-up was late enough to miss a {latency.period * 1000:g} ms deadline"
    worst, first = 0, 0
    for last in range(len(misses)):  # the most misses within any window of ``window`` wake-ups
        while misses[last] - misses[first] >= window:
            first += 1
        worst = max(worst, last - first + 1)
    if worst <= limit:
        return "firm", (f"{_late(len(misses))}, at most {worst} within {window} ticks "
                        f"(firm allows {limit})")
    return "soft", (f"{_late(len(misses))}, {worst} within {window} ticks: firm (at most {limit}) "
                    "would fault; use --deadline-policy soft, or real-time scheduling (the default: --rt-priority N, where "
                    "the host grants it)")


def _late(n: int) -> str:
    return f"{n} late wake-up{'' if n == 1 else 's'}"
