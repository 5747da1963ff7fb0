"""``irl view REPORT.csv | FILE.mcap``: what the robot did, replayed.

A report (the 10 ms rows of ``irl run --report`` or a served program's report, with its
``.states.csv`` beside it when there is one) or a recording (``--record``, MCAP) is read
into a :class:`Recorded`: the measured joints over time, the phases, the program's line,
the tool, the I/O and the log where the file has them. The view replays it: a time slider,
play and pause at 0.25x to 20x, the tool centre point's trace over the whole run, the
phases on a time line, the current phase, line and I/O.
"""
from __future__ import annotations

import csv
import html
import math
from bisect import bisect_right
from dataclasses import dataclass, field
from pathlib import Path

from runtime.motion.moves import Frames
from runtime.recording import read_events
from runtime.view.stage import Player, Stage, lamps_html, log_html, source_html, timeline_html


#: The colour of the tool centre point's trace (RGB).
TRACE_COLOUR = (0, 150, 170)


class ReplayError(ValueError):
    """A file that cannot be replayed: the message says what is wrong, and where."""


@dataclass
class Recorded:
    """A run as read from its file: per sample ``times`` (s, the robot's clock), ``joints``
    (deg), and, where the file has them, ``lines`` (the source line under way, 0: none),
    ``tools`` (the active tool's name), ``inputs``/``outputs``; ``phases``: ``(from time,
    state path)``; ``logs``: ``(time, level, text)``."""

    times: list = field(default_factory=list)
    joints: list = field(default_factory=list)
    lines: list | None = None
    tools: list | None = None
    inputs: list | None = None
    outputs: list | None = None
    phases: list = field(default_factory=list)
    logs: list = field(default_factory=list)
    source: str | None = None  # the program's text, when the file carries it


def read_report(path: Path, axes: list[str]) -> Recorded:
    """A report CSV (runtime.loop.components.report) of a robot with the axes ``axes``."""
    try:
        with open(path, encoding="utf-8", newline="") as f:
            rows = csv.reader(f)
            header = next(rows, None)
            if header is None:
                raise ReplayError(f"{path}: empty: no header row")
            column = {name: i for i, name in enumerate(header)}
            need = ["time", "state"] + [f"sens_pos_{a}" for a in axes]
            missing = [n for n in need if n not in column]
            if missing:
                raise ReplayError(f"{path}: not a report of this robot: no column {', '.join(missing[:3])} (the "
                                  f"header has {', '.join(header[:6])}{', ...' if len(header) > 6 else ''})")
            return _rows(path, rows, column, axes)
    except OSError as exc:
        raise ReplayError(f"cannot read {path}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise ReplayError(f"{path}: not a UTF-8 text file") from None


def _rows(path: Path, rows, column: dict, axes: list[str]) -> Recorded:
    rec = Recorded()
    pos = [column[f"sens_pos_{a}"] for a in axes]
    t_i, state_i = column["time"], column["state"]
    line_i, tool_i = column.get("line"), column.get("tool")
    ins = sorted((int(n[3:]), i) for n, i in column.items() if n.startswith("in_") and n[3:].isdigit())
    outs = sorted((int(n[4:]), i) for n, i in column.items() if n.startswith("out_") and n[4:].isdigit())
    rec.lines = [] if line_i is not None else None
    rec.tools = [] if tool_i is not None else None
    rec.inputs, rec.outputs = ([], []) if ins or outs else (None, None)
    state = None
    for number, row in enumerate(rows, start=2):
        if not row:
            continue
        try:
            t = float(row[t_i])
            rec.joints.append(tuple(float(row[i]) for i in pos))
            if rec.lines is not None:
                rec.lines.append(int(row[line_i]))
            if rec.tools is not None:
                rec.tools.append(row[tool_i])
            if rec.inputs is not None:
                rec.inputs.append(tuple(row[i] == "1" for _n, i in ins))
                rec.outputs.append(tuple(row[i] == "1" for _n, i in outs))
        except (ValueError, IndexError):
            raise ReplayError(f"{path}, line {number}: not a row of numbers that fits the header") from None
        rec.times.append(t)
        if row[state_i] != state:
            state = row[state_i]
            rec.phases.append((t, state))
    if not rec.times:
        raise ReplayError(f"{path}: no rows: nothing to replay")
    return _checked(path, rec, lambda i: f"line {i + 2}")


def _checked(path: Path, rec: Recorded, where) -> Recorded:
    """``rec`` when its times are finite and never go back and its joints are finite; else
    ReplayError naming the first sample (``where(i)``) that is not."""
    last = -math.inf
    for i, (t, joints) in enumerate(zip(rec.times, rec.joints)):
        if not math.isfinite(t) or t < last:
            raise ReplayError(f"{path}, {where(i)}: time {t!r}: a time must be a finite number of seconds, never "
                              f"before the one before it ({last:g})")
        if not all(map(math.isfinite, joints)):
            raise ReplayError(f"{path}, {where(i)}: joint values {joints}: every one must be a finite number")
        last = t
    return rec


def read_recorded(path: Path, spec) -> Recorded:
    """A report (``.csv``, with the prints and faults of its ``.events.csv`` when it is
    there) or a recording (``.mcap``) of ``spec``'s robot."""
    axes = [a.name for a in spec.axes]
    if path.suffix.lower() == ".mcap":
        return read_mcap(path, spec)
    rec = read_report(path, axes)
    rec.logs = _logs(read_events(path))
    return rec


def _logs(events: list) -> list:
    """The events of a report's events file as ``(time, level, text)``."""
    from runtime.recording import EVENTS

    return [(t, EVENTS.get(kind, ("INFO", ""))[0], (f"line {line}: " if line else "") + f"{kind}: {text}")
            for t, kind, line, text in events]


def read_mcap(path: Path, spec) -> Recorded:
    """A recording (runtime.recording) of ``spec``'s robot (refused when its robot's
    specification has another hash), as a :class:`Recorded`: the joint states' samples,
    and per sample the line, the tool and the I/O as they last changed."""
    from runtime.recording import RecordingError, read_recording

    try:
        data = read_recording(path)
    except RecordingError as exc:
        raise ReplayError(f"{path}: {exc}") from None
    except OSError as exc:
        raise ReplayError(f"cannot read {path}: {exc.strerror or exc}") from None
    meta = data["metadata"]
    if meta.get("spec_hash") and meta["spec_hash"] != spec.hash:
        raise ReplayError(f"{path} is a recording of {meta.get('robot')} (specification {meta['spec_hash'][:12]}), not "
                          f"of {spec.file} ({spec.hash[:12]}): give its --spec")
    times = [float(t) for t in data["times"]]
    if not times:
        raise ReplayError(f"{path}: no joint states: nothing to replay")
    rec = _checked(path, Recorded(times=times, joints=[tuple(map(float, j)) for j in data["joints"]]),
                   lambda i: f"joint state {i + 1}")
    rec.lines = _held(times, [(t, line) for t, line, _file in data["lines"]], 0)
    rec.tools = _held(times, [(t, tool) for t, tool, _base in data["frames"]], "default_tool")
    io = data["io"]
    if len(io["times"]):
        changes = list(zip(io["times"], map(tuple, io["inputs"]), map(tuple, io["outputs"])))
        rec.inputs = _held(times, [(t, i) for t, i, _o in changes], changes[0][1])
        rec.outputs = _held(times, [(t, o) for t, _i, o in changes], changes[0][2])
    rec.phases = [(float(t), state) for t, state in data["phases"]]
    rec.logs = [(float(e["time"]), e["level"], (f"line {e['line']}: " if e.get("line") else "") + f"{e['kind']}: "
                 f"{e['text']}") for e in data["logs"]]
    try:
        rec.source = Path(meta.get("source") or "").read_text(encoding="utf-8") if meta.get("source") else None
    except (OSError, UnicodeDecodeError):
        rec.source = None
    return rec


def _held(times: list, changes: list, initial) -> list:
    """Per time of ``times``, the value of the last of ``changes`` (``(time, value)``, in
    time order) at or before it (``initial`` before the first)."""
    out, value, i = [], initial, 0
    for t in times:
        while i < len(changes) and changes[i][0] <= t + 1e-9:
            value = changes[i][1]
            i += 1
        out.append(value)
    return out


class ReplayView:
    """``recorded`` replayed on ``stage``."""

    def __init__(self, stage: Stage, name: str, recorded: Recorded, source: str | None = None):
        self.stage, self.rec, self.name = stage, recorded, name
        spec = stage.spec
        default = Frames.default(spec)
        tools = {n: Frames("world", default.base, n, tuple(v)) for t, n, v in spec.named_frames if t == "tool"}
        self.frames = ([tools.get(n, default) for n in recorded.tools] if recorded.tools is not None
                       else [default] * len(recorded.times))
        self.lines = (source if source is not None else recorded.source or "").splitlines()
        self.start, self.end = recorded.times[0], recorded.times[-1]
        self.phase_times = [t for t, _state in recorded.phases]
        points = stage.tcp_points(recorded.joints, self.frames)
        if len(points) >= 2:  # the TCP's trace over the whole run
            step = max(1, len(points) // 5000)
            trace = points[::step] + [points[-1]]
            stage.server.scene.add_line_segments("/trace", points=[(a, b) for a, b in zip(trace, trace[1:])],
                                                 colors=TRACE_COLOUR, line_width=1.5)
        gui = stage.server.gui
        gui.add_markdown(f"**{html.escape(name)}**: {self.end - self.start:.2f} s of the robot's clock, "
                         f"{len(recorded.times)} samples")
        self.timeline = gui.add_html(timeline_html(recorded.phases, self.start, self.end, self.start))
        self.now = gui.add_markdown("")
        self.lamps = gui.add_html(lamps_html(recorded.inputs[0], recorded.outputs[0])) \
            if recorded.inputs else None
        self.log = gui.add_html(log_html([])) if recorded.logs else None
        self.source = gui.add_html(source_html(self.lines, None, "program")) if self.lines else None
        self.player = Player(gui, self.start, self.end, self.show_time)
        self.show_time(self.start)

    def show_time(self, t: float) -> None:
        rec = self.rec
        i = max(bisect_right(rec.times, t) - 1, 0)
        self.stage.show(rec.joints[i], self.frames[i])
        phase = rec.phases[max(bisect_right(self.phase_times, rec.times[i]) - 1, 0)][1]
        line = rec.lines[i] if rec.lines is not None else 0
        self.now.content = (f"**{rec.times[i]:.3f} s** · {html.escape(phase)}"
                            + (f" · line {line}" if line else ""))
        self.timeline.content = timeline_html(rec.phases, self.start, self.end, rec.times[i])
        if self.lamps is not None:
            self.lamps.content = lamps_html(rec.inputs[i], rec.outputs[i])
        if self.log is not None:
            self.log.content = log_html([e for e in rec.logs if e[0] <= rec.times[i]])
        if self.source is not None and line:
            self.source.content = source_html(self.lines, line, "program")

    def close(self) -> None:
        self.player.close()
