"""Report: every 10 ms, one row of what the components exchanged.

Columns: time, FSM state, and per axis ``sens_pos``, ``desi_pos`` (the servo's reference),
``out_vel`` (the velocity command to the drives, after the safety supervisor) and the
following error (the ``columns`` setting chooses among these, the TCP, and optionally the
I/O and the ``move`` group: ``move``, the number of the program's move under way or last
started, from 1, 0 before the first, and ``line``, the source line of the move under way, 0
when none is: ``irl plot`` marks each move's start with them). The report
records from Calibrate Offsets to the end of Stop Robot (the robot at rest, brakes
applied). The real-time side only appends a tuple of numbers; every 100 ms (ten rows)
it hands the batch, with the state transitions and the cycle's events since the last one,
to a writer thread through a bounded queue (:mod:`runtime.loop.batches`, shared with the
recording), and the thread formats, writes and flushes the CSV, ``<report>.states.csv``
and ``<report>.events.csv`` (the events of runtime.recording.EVENTS: print output,
interrupt firings, the fault, the stop), whole lines only: a crash (kill -9) loses at most
the last 100 ms of each, and the loop never does I/O. The bytes written depend only on the
rows: with the simulated clock the same program and seed give the same files.
"""
from __future__ import annotations

from contextlib import ExitStack
from operator import sub as _sub
from pathlib import Path

from compiler.params import component_params

from runtime.loop.batches import Batches, BatchWriter, Events, file_to_write
from runtime.loop.component import Component, DataPort
from runtime.motion.moves import Frames
from runtime.motion.tcp import tcp_of
from runtime.recording import EVENTS_HEADER
from runtime.settings import Settings
from runtime.timing import REPORT_PERIOD

COLUMNS = ["sens_pos", "desi_pos", "out_vel", "following_error"]  # the per-axis quantities
TCP = "tcp"  # the tool centre point: x, y, z (mm), roll, pitch, yaw (deg), from the measured joints
TCP_FIELDS = ("x", "y", "z", "roll", "pitch", "yaw")
FRAME = "frame"  # the active tool's and base's names, and the tool centre point in that base
IO = "io"  # every digital input, then every output: in_1.., out_1.. (0 or 1)
ANALOG = "analog"  # every analog input, then every output, in its unit: ain_1.., aout_1..
MOVE = "move"  # the move under way: its number (moves started so far) and source line (0: at rest)
MOVE_FIELDS = ("move", "line")


def is_io(name: str) -> bool:
    """Whether a report column is a digital input or output (``in_3``, ``out_12``)."""
    kind, _, number = name.partition("_")
    return kind in ("in", "out") and number.isdigit()


def is_text(name: str) -> bool:
    """Whether a report column holds a name (the frame group's ``tool`` and ``base``)."""
    return name in ("tool", "base")


def _csv_text(text: str) -> str:
    """A name as one CSV field (quoted when it holds a comma, a quote or a line break)."""
    return '"' + text.replace('"', '""') + '"' if any(c in text for c in ',"\r\n') else text


def is_integer(name: str) -> bool:
    """Whether a report column holds whole numbers (written with %d): an input or output,
    or the move group's ``move`` and ``line``."""
    return name in MOVE_FIELDS or is_io(name)


class ReportWriter(BatchWriter):
    """Formats and writes batches of rows (the CSV), transitions (``.states.csv``) and
    events (``.events.csv``); not real-time (its own thread)."""

    WHAT = "report"

    def __init__(self, path: Path, header: list[str], expand=None):
        super().__init__(path, "report-writer")
        self.states_path = path.with_suffix(".states.csv")
        self.events_path = path.with_suffix(".events.csv")
        self.header = header
        self.expand = expand  # when set: row -> the row written (joints -> the TCP, in the active tool and base)
        self._files: tuple = ()
        # one C-level format per row (time to the ms, the state, every value to 1e-6, I/O 0 or 1,
        # the move's number and line as integers)
        self.row_format = "%.3f,%s," + ",".join(["%d" if is_integer(name) else "%s" if is_text(name) else "%.6f"
                                                 for name in header[2:]]) + "\n"

    def opened(self):
        """The three files, each with its header."""
        stack = ExitStack()
        try:
            self._files = tuple(stack.enter_context(open(p, "w", encoding="utf-8", newline=""))
                                for p in (self.path, self.states_path, self.events_path))
            for f, header in zip(self._files, (",".join(self.header) + "\n", STATES_HEADER, EVENTS_HEADER)):
                f.write(header)
                f.flush()
        except BaseException:
            stack.close()
            raise
        return stack

    def write(self, rows: list, transitions=(), events=()) -> None:
        """Whole lines of what can be formatted; the rest counted in ``bad_rows``."""
        f, states, log = self._files
        for items, line, out in ((transitions, state_row, states), (events, event_row, log)):
            if items:
                out.write("".join(self.each(items, line)))
                out.flush()
        if rows:
            lines = self.each(rows, self._row)
            f.write("".join(lines))
            f.flush()
            self.rows_written += len(lines)

    def _row(self, row: tuple) -> str:
        if self.expand is not None:
            row = self.expand(row)
        return self.row_format % row

    def bad_rows_text(self) -> str:
        return (f"{self.bad_rows} rows of {self.path.name} were left out: they did not fit its "
                f"{len(self.header)} columns (every other row is kept)")


class Report(Component):
    PROPERTIES = component_params("report")

    def __init__(self, spec, sens_pos: DataPort, out_vel: DataPort, servo, state_of, period: float = REPORT_PERIOD,
                 history=lambda: (), io: tuple = (), settings: Settings | None = None, events: Events | None = None):
        super().__init__("report", period, settings if settings is not None else Settings(spec))
        self.spec = spec
        self.sens_pos, self.out_vel, self.servo = sens_pos, out_vel, servo
        self.state_of = state_of  # callable -> the FSM's current state path
        self.io = io  # the io component's ports (inputs, outputs): the io columns
        self.motion = None  # the trajectory generator's motion queue (the move columns; set by the supervisor)
        # real-time: () -> every analog input, then output, now (the analog columns; set by the system)
        nan = (float("nan"),) * (len(spec.analog_inputs) + len(spec.analog_outputs))
        self.analog = lambda: nan
        # the rows, with the FSM's transitions ((time, from, to)) and the events, to the writer
        self.batches = Batches(history, events)
        self.names = [a.name for a in spec.axes]
        self._zeros = (0.0,) * len(self.names)
        self.main = len(spec.main_axes)
        self.tcp = tcp_of(spec)  # None when the spec's kinematics are not usable
        # the base and tool of the move under way (the trajectory generator's; set by the system)
        default_frames = Frames.default(spec)
        self.frames_now = lambda: default_frames
        # which quantities the rows hold, in this order (report.columns; the TCP when the kinematics allow)
        if self.tcp is None and TCP in self.columns:
            self.columns = [c for c in self.columns if c != TCP]

    @property
    def columns(self) -> list[str]:
        """report.columns, the setting (runtime.settings): which quantities the rows hold."""
        return self.settings.report.columns

    @columns.setter
    def columns(self, names) -> None:
        self.settings.set("report", "columns", names)

    def _names_of(self, kind: str) -> list[str]:
        if kind == TCP:
            return [f"tcp_{f}" for f in TCP_FIELDS]
        if kind == IO:
            return [f"in_{n}" for n in range(1, self.spec.inputs + 1)] + \
                [f"out_{n}" for n in range(1, self.spec.outputs + 1)]
        if kind == MOVE:
            return list(MOVE_FIELDS)
        if kind == ANALOG:
            return [f"ain_{n}" for n in range(1, len(self.spec.analog_inputs) + 1)] + \
                [f"aout_{n}" for n in range(1, len(self.spec.analog_outputs) + 1)]
        if kind == FRAME:
            return ["tool", "base"] + [f"base_{f}" for f in TCP_FIELDS]
        return [f"{kind}_{n}" for n in self.names]

    def header(self) -> list[str]:
        cols = ["time", "state"]
        for kind in self.columns:
            cols += self._names_of(kind)
        return cols

    def open(self, path: str | Path | None) -> None:
        """Not real-time: where to write (None: rows are made but not kept)."""
        path = file_to_write(path)
        writer = ReportWriter(path, self.header(), self._expander()) if path is not None else None
        self.batches.open(writer, self.period)

    def _expander(self):
        """Not real-time: the writer's row -> written row, when the rows hold joints for the
        TCP (the tcp and frame groups: the joints and the move's frames); else None."""
        if TCP not in self.columns and FRAME not in self.columns:
            return None
        tcp = self.tcp
        if tcp is None:  # (the configuration loader refuses tcp without kinematics)
            return None
        main = self.main
        layout = []
        for kind in self.columns:
            if kind == TCP:
                layout.append((main + 1, lambda seg: tcp.world(seg[:-1], seg[-1])))
            elif kind == FRAME:
                layout.append((main + 1, lambda seg: (_csv_text(seg[-1].tool_name), _csv_text(seg[-1].base_name),
                                                      *tcp.in_base(seg[:-1], seg[-1]))))
            else:
                layout.append((len(self._names_of(kind)), None))

        def expand(row: tuple) -> tuple:
            out = [row[0], row[1]]
            i = 2
            for width, fn in layout:
                segment = row[i:i + width]
                i += width
                out.extend(segment if fn is None else fn(segment))
            return tuple(out)
        return expand

    def update(self, now: float) -> None:
        """Real-time: append one row; hand a full batch to the writer (never blocks)."""
        zeros = self._zeros
        pos = self.sens_pos.value or zeros
        servo = self.servo
        reference = servo.reference
        values = {"sens_pos": pos, "desi_pos": reference, "out_vel": self.out_vel.value or zeros,
                  "following_error": tuple(map(_sub, reference, servo.position)),
                  }
        if IO in self.columns:
            inputs, outputs = self.io
            values[IO] = (*inputs.value, *outputs.value)
        if MOVE in self.columns:
            values[MOVE] = self._move()
        if ANALOG in self.columns:
            values[ANALOG] = self.analog()
        if TCP in self.columns or FRAME in self.columns:  # the writer turns these joints into the TCP
            values[TCP] = values[FRAME] = (*pos[:self.main], self.frames_now())
        row = (now, self.state_of())
        for kind in self.columns:
            row += values[kind]
        self.batches.append(row)

    def _move(self) -> tuple[int, int]:
        """Real-time: (the number of the move under way or last started, from 1: 0 before
        the first; the source line of the move under way, 0 when none is). A move resumed
        after a pause is the same move; in a blend, the move blended into. The approach of a
        start from a line (runtime.loop.stepping) is not a program's move: 0, at rest."""
        motion = self.motion
        if motion is None:
            return (0, 0)
        moves = motion.moves
        started = len(moves)
        if started and moves[0].approach:
            started -= 1
            if not started:
                return (0, 0)
        return (started, moves[-1].line if started and motion.line is not None else 0)

    def on_stop(self) -> None:
        self.batches.hand_over()

    def close(self) -> str | None:
        """Not real-time: flush and close the files; returns an error message or None."""
        return self.batches.close("report")





STATES_HEADER = "time,from,to\n"


def state_row(transition) -> str:
    """One line of ``<report>.states.csv``: a transition (time, from, to)."""
    t, source, target = transition
    return f"{t:.3f},{source or ''},{target}\n"


def event_row(event) -> str:
    """One line of ``<report>.events.csv``: an event (time, kind, line, text)."""
    t, kind, line, text = event
    return f"{t:.3f},{_csv_text(kind)},{int(line)},{_csv_text(text)}\n"
