"""What real-time scheduling the loop asks of the host, and the flags that say it
(``--rt-priority``, ``--[no-]lock-memory``, ``--cpu``): declared once, read by ``irl run``,
``irl serve`` and ``irl latency``. Asking for it is runtime/loop/realtime.py's (in the loop's
process); this module is plain data, so ``irl serve``'s server process reads the flags
without importing the loop.
"""
from __future__ import annotations

import argparse
import os
from dataclasses import dataclass

#: SCHED_FIFO priorities Linux accepts.
PRIORITIES = (1, 99)

#: The loop's SCHED_FIFO priority unless a command is told otherwise: real-time scheduling
#: (with memory locked) is asked for by default wherever the host permits it, as
#: ros2_control's controller manager does (its update thread: SCHED_FIFO 50, memory
#: locked); where it is refused the loop runs at normal scheduling and says why.
DEFAULT_PRIORITY = 50

#: ``--rt-priority 0``: normal scheduling (no SCHED_FIFO, memory not locked unless asked).
NORMAL = 0

#: The scheduling flags: (flag, dest, argparse keywords). A default of None means "not
#: given": :func:`scheduling` resolves it (:data:`DEFAULT_PRIORITY`, memory locked with
#: SCHED_FIFO).
FLAGS = (
    ("--rt-priority", "rt_priority",
     dict(type=int, metavar="N", default=None,
          help=f"the loop's SCHED_FIFO priority, {PRIORITIES[0]}-{PRIORITIES[1]}, or {NORMAL}: normal scheduling "
               f"(default: SCHED_FIFO {DEFAULT_PRIORITY} where the host permits it, else normal scheduling; the "
               "command says which it got)")),
    ("--lock-memory", "lock_memory",
     dict(action=argparse.BooleanOptionalAction, default=None,
          help="lock the process's memory (no page faults in a tick) where permitted (default: locked with "
               "SCHED_FIFO, not with --rt-priority 0)")),
    ("--cpu", "cpu", dict(type=int, metavar="N", default=None, help="run the loop on CPU N only")),
)


@dataclass(frozen=True)
class Scheduling:
    """What to ask of the host for the loop's thread: ``priority`` (SCHED_FIFO 1-99;
    None: normal scheduling), ``lock_memory`` (mlockall), ``cpu`` (affinity; None: any)."""

    priority: int | None = None
    lock_memory: bool = False
    cpu: int | None = None

    def __post_init__(self):
        if self.priority is not None and not PRIORITIES[0] <= self.priority <= PRIORITIES[1]:
            raise ValueError(f"--rt-priority {self.priority}: expected {PRIORITIES[0]} to {PRIORITIES[1]} "
                             f"(SCHED_FIFO priorities), or {NORMAL} for normal scheduling")
        if self.cpu is not None and not 0 <= self.cpu < (os.cpu_count() or 1):
            raise ValueError(f"--cpu {self.cpu}: expected 0 to {(os.cpu_count() or 1) - 1} (this host's CPUs)")

    @property
    def requested(self) -> bool:
        return self.priority is not None or self.lock_memory or self.cpu is not None


#: What the wall clock's loop asks for when no flag says otherwise.
DEFAULT = Scheduling(DEFAULT_PRIORITY, True, None)


def add_arguments(parser) -> None:
    """The scheduling flags (:data:`FLAGS`) on a command's parser."""
    for flag, dest, keywords in FLAGS:
        parser.add_argument(flag, dest=dest, **keywords)


def given(args) -> list[str]:
    """The scheduling flags given on a command line (the others keep their defaults)."""
    return [flag for flag, dest, _keywords in FLAGS if getattr(args, dest, None) is not None]


def scheduling(args) -> Scheduling:
    """The :class:`Scheduling` a command's parsed flags ask for, the defaults filled in:
    SCHED_FIFO :data:`DEFAULT_PRIORITY` unless ``--rt-priority`` says otherwise (0:
    normal scheduling), memory locked with SCHED_FIFO unless ``--lock-memory`` /
    ``--no-lock-memory`` says otherwise (ValueError: out of range)."""
    priority = DEFAULT_PRIORITY if args.rt_priority is None else args.rt_priority
    priority = None if priority == NORMAL else priority
    lock = args.lock_memory if args.lock_memory is not None else priority is not None
    return Scheduling(priority, lock, args.cpu)
