"""What the loop hands its writer threads, and how: the report's and the recording's shared
part.

The real-time side of a writer (:class:`Batches`) only appends a tuple per row; every
:data:`~runtime.timing.FLUSH_PERIOD` of rows (100 ms) it hands the batch, with the
supervisor's transitions and the cycle's events (:class:`Events`) since the last hand-over,
to the writer's thread through a bounded queue, never waiting: a batch the queue cannot take
is dropped and counted. The thread (:class:`BatchWriter`) formats and writes each batch, so
a crash loses at most the batches not written yet, and the loop never does I/O. A writer
never dies silently: what it could not write is said by :meth:`BatchWriter.problem` (the
summary's ``files_error``).
"""
from __future__ import annotations

import math
import queue
import threading
from abc import ABCMeta, abstractmethod
from pathlib import Path

from runtime.loop.components.safety import stop_text
from runtime.recording import FAULT, STOP
from runtime.timing import FLUSH_PERIOD

#: Batches a writer's queue holds at most (100 s of rows at 10 rows a batch).
QUEUE_SIZE = 1000


def file_to_write(path: str | Path | None) -> Path | None:
    """Not real-time: ``path`` as a Path with its directory made (None: nothing to write).
    A directory that cannot be made is left to the writer, which says so when it cannot
    open the file."""
    if not path:
        return None
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError:
        pass
    return path


class Events:
    """Real-time: the cycle's events as they come, ``(time, kind, line, text)`` with a kind
    of runtime.recording.EVENTS: the program's log lines (the trajectory generator's
    ``log_lines``: print output, interrupt firings, ...), the supervisor's fault and the
    safety supervisor's stops. Each :meth:`take` gives those since the last, in time order."""

    def __init__(self, trajectory, supervisor, safety):
        self.trajectory = trajectory
        self.supervisor = supervisor  # callable -> the supervisor (made after the writers)
        self.safety = safety
        self.reset()

    def reset(self) -> None:
        """Not real-time: a new cycle."""
        self._lines: list | None = None
        self._seen_lines = 0
        self._seen_stops = 0
        self._fault_taken = False
        self._kept: list = []  # taken, not handed over (a full queue): the next take's first

    def take(self) -> list[tuple[float, str, int, str]]:
        """Real-time: the events since the last call, in time order."""
        out, self._kept = self._kept, []
        lines = self.trajectory.log_lines
        if lines is not self._lines:  # (a program's start makes a new log)
            self._lines, self._seen_lines = lines, 0
        while self._seen_lines < len(lines):
            at, line, text, kind = lines[self._seen_lines]
            self._seen_lines += 1
            out.append((at, kind, line, text))
        supervisor = self.supervisor()
        if not self._fault_taken and supervisor.fault_at is not None:
            self._fault_taken = True
            at, line = supervisor.fault_at
            out.append((at, FAULT, line, supervisor.fault))
        stops = self.safety.stops
        while self._seen_stops < len(stops):
            at, category, cause = stops[self._seen_stops]
            self._seen_stops += 1
            out.append((at, STOP, self.trajectory.line, stop_text(category, cause)))
        if len(out) > 1:
            out.sort(key=lambda event: event[0])
        return out

    def keep(self, events: list) -> None:
        """Real-time: events taken but not handed over: the next :meth:`take` gives them again."""
        self._kept = list(events) + self._kept


class Batches:
    """The real-time side of a writer: rows appended (:meth:`append`), handed over every
    :data:`FLUSH_PERIOD` s of rows with the transitions (``history()``: the supervisor's,
    ``(time, from, to)``) and the events (an :class:`Events`, or None) since the last."""

    def __init__(self, history=lambda: (), events: Events | None = None):
        self.history = history
        self.events = events
        self.writer: BatchWriter | None = None
        self.rows: list = []
        self.size = 1  # rows per batch
        self.dropped = 0  # rows a full queue did not take
        self._transitions_sent = 0

    def open(self, writer: BatchWriter | None, period: float) -> None:
        """Not real-time: a new cycle, written by ``writer`` (started here; None: the rows
        are made and dropped), a row every ``period`` s."""
        self.writer = writer
        self.rows = []
        self.size = max(1, math.ceil((FLUSH_PERIOD - 1e-9) / period))
        self.dropped = 0
        self._transitions_sent = 0
        if self.events is not None:
            self.events.reset()
        if writer is not None:
            writer.start()

    def append(self, row: tuple) -> None:
        """Real-time: one row; a full batch is handed over (never blocks)."""
        rows = self.rows
        rows.append(row)
        if len(rows) >= self.size:
            self.hand_over()

    def hand_over(self) -> None:
        """Real-time: the rows, transitions and events so far to the writer's queue (a full
        queue drops the rows, counted; the transitions and events wait for the next)."""
        writer = self.writer
        if writer is not None:
            history = self.history()
            transitions = history[self._transitions_sent:] if len(history) > self._transitions_sent else ()
            events = self.events.take() if self.events is not None else ()
            if self.rows or transitions or events:
                try:
                    writer.queue.put_nowait((self.rows, transitions, events))
                    self._transitions_sent += len(transitions)
                except queue.Full:
                    self.dropped += len(self.rows)
                    if events:  # (taken: kept for the next hand-over)
                        self.events.keep(events)
        self.rows = []

    def close(self, what: str) -> str | None:
        """Not real-time: the last batch, then the writer's end; what went wrong (``what``
        names the file kind in the message), or None."""
        self.hand_over()
        writer, self.writer = self.writer, None
        if writer is None:
            return None
        try:
            writer.queue.put(None, timeout=10)  # (a writer that ended on an error no longer empties it)
        except queue.Full:
            pass
        writer.join(timeout=10)
        problems = [writer.problem()]
        if writer.is_alive():
            problems.append(f"the {what} writer did not finish {writer.path.name} within 10 s: its last rows may be "
                            "missing")
        if self.dropped:
            problems.append(f"{self.dropped} rows were not written: the {what} writer fell behind")
        return "; ".join(p for p in problems if p) or None


class BatchWriter(threading.Thread, metaclass=ABCMeta):
    """A writer's thread (not real-time): takes the batches off its bounded queue until the
    None that ends them and writes each (:meth:`write`, in the files :meth:`opened` gives).
    It never dies of a row: a row it cannot format is left out and counted (``bad_rows``),
    every other one is written; a write that fails is said in ``error``. Either way
    :meth:`problem` says it, and the summary with it."""

    #: The files' kind in messages ("report", "recording").
    WHAT = "file"

    def __init__(self, path: Path, name: str):
        super().__init__(name=name, daemon=True)
        self.path = path
        self.queue: queue.Queue = queue.Queue(maxsize=QUEUE_SIZE)
        self.error: str | None = None
        self.rows_written = 0
        self.bad_rows = 0  # rows (or transitions, events) that could not be formatted: left out, counted

    @abstractmethod
    def opened(self):
        """A context manager: the files open while the batches come."""

    @abstractmethod
    def write(self, rows: list, transitions=(), events=()) -> None:
        """One batch: its rows, the transitions and the events handed over with them."""

    def run(self) -> None:
        """Until the None that ends the batches (module docstring)."""
        try:
            with self.opened():
                while True:
                    item = self.queue.get()
                    if item is None:
                        break
                    self.write(*item)
        except OSError as exc:
            self.error = f"cannot write the {self.WHAT} {self.path}: {exc.strerror or exc}"
        except Exception:  # noqa: BLE001 - said, never a silent death (the batches so far are on disk)
            self.error = f"the {self.WHAT} writer of {self.path} stopped on an internal error: the rows after it are lost"

    def each(self, items, make) -> list:
        """``make(item)`` of every item that can be made; the others are counted in
        ``bad_rows`` (a row of another shape, a value that cannot be written)."""
        try:
            return [make(item) for item in items]
        except Exception:  # noqa: BLE001 - a bad item: each on its own, the bad ones left out
            made = []
            for item in items:
                try:
                    made.append(make(item))
                except Exception:  # noqa: BLE001
                    self.bad_rows += 1
            return made

    def problem(self) -> str | None:
        """What went wrong writing the files, in the operator's terms (None: nothing)."""
        parts = [self.error] if self.error else []
        if self.bad_rows:
            parts.append(self.bad_rows_text())
        return "; ".join(parts) or None

    def bad_rows_text(self) -> str:
        return f"{self.bad_rows} rows of {self.path.name} were left out: they could not be written (every other " \
               "row is kept)"
