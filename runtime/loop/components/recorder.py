"""The recording (``irl run --record FILE.mcap``, ``irl serve --record DIR``): the robot's
cycle in an MCAP file that Foxglove and Lichtblick open (topics and schemas:
:mod:`runtime.recording`).

Every :data:`~runtime.timing.RECORD_PERIOD` (10 ms), while the report records (from
Calibrate Offsets, or Move Robot on a robot already calibrated and homed, to the end of Stop
Robot), the real-time side (:class:`Recorder`) appends one tuple: the time, the state path,
the measured positions and velocities, the move's tool and base, the digital inputs and
outputs, the source line. Every 100 ms the batch goes, with the supervisor's transitions and
the cycle's events, to the writer thread (:class:`RecordWriter`) as the report's rows do
(:mod:`runtime.loop.batches`: one mechanism); the thread computes the tool centre point and
every link's transform (forward kinematics; the links of the arm's URDF,
:mod:`runtime.motion.urdf`), formats the JSON messages and writes them in compressed
chunks. The loop does no I/O, no JSON and no kinematics for it.

A crash loses at most the chunk being filled (:data:`CHUNK_SIZE` bytes of messages, about
a second of robot time): an MCAP file without its footer is still read, to its last whole
chunk, by mcap's non-seeking reader and by :func:`runtime.recording.read_recording`.
"""
from __future__ import annotations

import base64
import heapq
import json
import os
import time
from math import isfinite
from pathlib import Path

from compiler.geometry import rpy_to_quat

from runtime.loop.batches import Batches, BatchWriter, Events, file_to_write
from runtime.motion.rotation import matrix_to_quat
from runtime.motion.urdf import link_frames, urdf_text
from runtime.recording import (FORMAT, INSTALL, MESSAGE_ENCODING, METADATA, PROFILE, SCHEMA_ENCODING, TOPICS,
                               level_of, schema_text)
from runtime.timing import RECORD_PERIOD

#: Bytes of messages (before compression) per chunk: what a crash may lose at most (about a
#: second of robot time); zstd compresses a chunk about tenfold.
CHUNK_SIZE = 256 * 1024

_NS = 1_000_000_000
#: s the writer stands aside after each row on the wall clock (RecordWriter: a 100 ms batch
#: of ten rows then takes about 2 ms of the wall clock and 1.6 ms of the interpreter's lock).
YIELD = 0.0002


def _stamp(t: float) -> tuple[int, int]:
    """(sec, nsec) of a time in seconds (the robot's clock: never negative)."""
    return divmod(round(t * 1e9), _NS)


class Recorder:
    """The real-time side of a recording: one row every :data:`RECORD_PERIOD` while it is
    open (:meth:`open`; not open: nothing is made), handed over in batches."""

    def __init__(self, spec, sens_pos, robot, trajectory, io: tuple, state_of, history, events: Events, tcp):
        self.spec = spec
        self.sens_pos, self.robot, self.trajectory = sens_pos, robot, trajectory
        self.inputs, self.outputs = io  # the io component's ports
        self.state_of = state_of  # callable -> the FSM's current state path
        self.tcp = tcp  # runtime.motion.tcp.TcpOf (its writer's own), or None (kinematics not usable)
        self.period = RECORD_PERIOD
        self.batches = Batches(history, events)
        self._zeros = (0.0,) * len(spec.axes)
        self.analog = lambda: ()  # real-time: () -> the analog inputs, then outputs (set by the system)

    @property
    def recording(self) -> bool:
        """Real-time: whether a recording is open (the task runs only then)."""
        return self.batches.writer is not None

    def open(self, path: str | Path | None, program=None, job: int | None = None, clock: str = "simulated") -> None:
        """Not real-time: record this cycle into ``path`` (None: no recording); ``program``
        names the source files of its lines, ``job`` the server's program id."""
        path = file_to_write(path)
        writer = RecordWriter(path, self.spec, self.tcp, program, job, clock) if path is not None else None
        self.batches.open(writer, self.period)

    def update(self, now: float) -> None:
        """Real-time: one row (tuples and names only; never blocks)."""
        trajectory = self.trajectory
        line, offset = trajectory.source()
        self.batches.append((now, self.state_of(), self.sens_pos.value or self._zeros, self.robot.velocities,
                             trajectory.frames_now(), self.inputs.value, self.outputs.value, line, offset,
                             self.analog()))

    def close(self) -> str | None:
        """Not real-time: the last batch, the file finished; what went wrong, or None."""
        return self.batches.close("recording")


class RecordWriter(BatchWriter):
    """Writes a recording's batches as MCAP messages; not real-time (its own thread)."""

    WHAT = "recording"

    def __init__(self, path: Path, spec, tcp, program, job: int | None, clock: str):
        super().__init__(path, "record-writer")
        self.tcp = tcp
        self.program = program
        self.main = len(spec.main_axes)
        self.names = [a.name for a in spec.axes]
        self.named_frames = tuple(spec.named_frames)  # the URDF's tool_ and frame_ links
        self.spec = spec
        self.urdf: str | None = None  # the arm's URDF, until /robot_description has it (made by opened)
        self.links = False  # /tf: every link of the URDF (when there is one)
        self.metadata = {"format": str(FORMAT), "program": program.name if program is not None else "",
                         "source": program.source if program is not None else "", "robot": spec.name,
                         "spec_hash": spec.hash, "spec_file": os.path.abspath(spec.file) if spec.file else "",
                         "job": "" if job is None else str(job), "clock": clock,
                         "axes": json.dumps(self.names), "units": json.dumps([a.unit for a in spec.axes]),
                         "analog_inputs": json.dumps([[c.name, c.unit] for c in spec.analog_inputs]),
                         "analog_outputs": json.dumps([[c.name, c.unit] for c in spec.analog_outputs]),
                         "period": repr(RECORD_PERIOD), "recorded": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
        self.mcap = self.stream = None
        self.channels: dict[str, int] = {}
        self.last: dict[str, object] = {}  # per change-only topic: what it last said
        n = len(self.names)
        numbers = ",".join(["%.6f"] * n)
        # the per-row messages, formatted in C (the report's precision: 1e-6 deg, 1e-9 m)
        self.joint_format = ('{"timestamp":{"sec":%d,"nsec":%d},"name":' + json.dumps(self.names)
                             + ',"position":[' + numbers + '],"velocity":[' + numbers + ']}')
        self.tcp_format = ('{"timestamp":{"sec":%d,"nsec":%d},"frame_id":"world","pose":' + _POSE_FORMAT + '}')
        self.link_formats: dict[tuple[str, str], str] = {}  # per (parent, child): its transform's format
        # on the wall clock the loop wakes every 1 ms and needs the interpreter's lock at once: the
        # writer sleeps a little after each row (YIELD s), so that a waiting loop takes the lock at
        # once and at most a row's work (~0.2 ms) is ever in its way, not the switch interval; on the
        # simulated clock the loop never sleeps, and a writer that stood aside would fall behind it
        self.pause = YIELD if clock == "wall" else 0.0

    def _urdf(self) -> str:
        """Make the arm's URDF (:attr:`urdf`, :attr:`links`); what the recording's links
        are (the metadata's ``links``): the URDF's, or why there are none."""
        if self.tcp is None:
            return "none: this robot's kinematics give no links"
        try:
            self.urdf = urdf_text(self.spec)
            link_frames(self.tcp.kinematics, [0.0] * self.main, self.named_frames)
        except ValueError as exc:  # (names a URDF cannot carry): the rest is recorded
            self.urdf = None
            return f"none: {exc}"
        self.links = True
        return "the links of irl urdf's URDF"

    # ---- the file ---------------------------------------------------------------------------
    def opened(self):
        """The MCAP file: started, its schemas, channels and metadata written; finished (its
        summary and footer) when the batches end."""
        try:
            from mcap.writer import CompressionType, Writer
        except ImportError:
            raise OSError(INSTALL) from None
        from contextlib import ExitStack

        stack = ExitStack()
        stream = self.stream = stack.enter_context(open(self.path, "wb"))  # (closed after _finish, pushed later)
        try:
            mcap = self.mcap = Writer(stream, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
            mcap.start(profile=PROFILE, library=f"irl {_version()}")
            schemas: dict[str, int] = {}
            for topic in TOPICS:
                if topic.schema not in schemas:
                    schemas[topic.schema] = mcap.register_schema(topic.schema, SCHEMA_ENCODING,
                                                                 schema_text(topic.schema))
                self.channels[topic.name] = mcap.register_channel(topic.name, MESSAGE_ENCODING,
                                                                  schemas[topic.schema])
            self.metadata["links"] = self._urdf()
            mcap.add_metadata(METADATA, self.metadata)
            stream.flush()
        except BaseException:
            stack.close()
            raise
        stack.push(self._finish)
        return stack

    def _finish(self, kind, _exc, _tb) -> bool:
        """The last chunk, the summary and the footer, also after a batch that failed (the
        file then opens whole, its messages up to the failure); when even that cannot be
        written, the file is still read to its last whole chunk, and the first error is
        the one said."""
        try:
            self.mcap.finish()
            self.stream.flush()
        except Exception:  # noqa: BLE001 - (raised when nothing else was)
            if kind is None:
                raise
        return False

    def write(self, rows: list, transitions=(), events=()) -> None:
        """A batch: its rows, transitions and events in time order (a transition before the
        row of its tick), each as its messages; an item that cannot be written is counted in
        ``bad_rows``, the others are written."""
        items = heapq.merge(((t[0], 0, t) for t in transitions), ((r[0], 1, r) for r in rows),
                            ((e[0], 2, e) for e in events), key=_order)
        add = self.mcap.add_message
        channels = self.channels
        for at, kind, item in items:
            if self.urdf is not None:  # once, with the first item
                ns = round(at * 1e9)
                add(channels["/robot_description"], ns, _json({"url": "", "format": "urdf", "data": base64.b64encode(
                    self.urdf.encode()).decode()}), ns)
                self.urdf = None
            try:
                messages = (self._transition if kind == 0 else self._row if kind == 1 else self._event)(item)
            except Exception:  # noqa: BLE001 - a bad item is left out, counted; the others are written
                self.bad_rows += 1
                continue
            ns = round(at * 1e9)
            for topic, data in messages:
                add(channels[topic], ns, data, ns)
            if kind == 1:
                self.rows_written += 1
                if self.pause:
                    time.sleep(self.pause)
        self.stream.flush()  # (the chunks the MCAP writer has closed: to the disk's cache)

    # ---- the messages -----------------------------------------------------------------------
    def _transition(self, transition) -> list:
        t, _source, target = transition
        return self._phase(t, target)

    def _phase(self, t: float, state: str) -> list:
        """The /phase message when the state path changed."""
        if state == self.last.get("/phase"):
            return []
        self.last["/phase"] = state
        phase, _, step = state.partition("/")
        return [("/phase", _json({"timestamp": _time(t), "state": state, "phase": phase, "step": step}))]

    def _row(self, row) -> list:
        t, state, positions, velocities, frames, inputs, outputs, line, offset, analog = row
        if not isfinite(sum(positions) + sum(velocities)):
            raise ValueError("a position or velocity that is not a number")
        sec, nsec = _stamp(t)
        out = [("/joint_states", (self.joint_format % (sec, nsec, *positions, *velocities)).encode())]
        if self.tcp is not None:
            m = self.tcp.world_matrix(positions[:self.main], frames)
            w, x, y, z = self._continuous("/tcp", matrix_to_quat(m))
            out.append(("/tcp", (self.tcp_format % (sec, nsec, m[0][3] / 1000.0, m[1][3] / 1000.0, m[2][3] / 1000.0,
                                                    x, y, z, w)).encode()))
            if self.links:
                out.append(("/tf", self._links(sec, nsec, positions[:self.main])))
        out += self._phase(t, state)
        if frames != self.last.get("/frames"):
            self.last["/frames"] = frames
            out.append(("/frames", _json({"timestamp": _time(t), "tool": frames.tool_name, "base": frames.base_name,
                                          "tool_pose": _pose(frames.tool), "base_pose": _pose(frames.base)})))
        io = (inputs, outputs)
        if io != self.last.get("/io"):
            self.last["/io"] = io
            out.append(("/io", _json({"timestamp": _time(t), "inputs": [bool(v) for v in inputs],
                                      "outputs": [bool(v) for v in outputs]})))
        shown = [v if isfinite(v) else None for v in analog]  # (NaN: a channel the I/O does not have)
        if shown and shown != self.last.get("/io/analog"):
            self.last["/io/analog"] = shown
            n = len(self.spec.analog_inputs)
            out.append(("/io/analog", _json({"timestamp": _time(t), "inputs": shown[:n], "outputs": shown[n:]})))
        source = (line, self._file(offset) if line else "")
        if source != self.last.get("/line"):
            self.last["/line"] = source
            out.append(("/line", _json({"timestamp": _time(t), "line": line, "file": source[1]})))
        return out

    def _links(self, sec: int, nsec: int, joints) -> bytes:
        """The /tf message: every link of the URDF in its parent (m, quaternions)."""
        formats = self.link_formats
        parts = []
        for parent, child, m in link_frames(self.tcp.kinematics, joints, self.named_frames):
            form = formats.get((parent, child))
            if form is None:
                form = formats[(parent, child)] = (
                    '{"timestamp":{"sec":%d,"nsec":%d},"parent_frame_id":' + _escaped(parent) + ',"child_frame_id":'
                    + _escaped(child) + ',"translation":{"x":%.9f,"y":%.9f,"z":%.9f},'
                    '"rotation":{"x":%.9f,"y":%.9f,"z":%.9f,"w":%.9f}}')
            w, x, y, z = self._continuous(("/tf", child), matrix_to_quat(m))
            parts.append(form % (sec, nsec, m[0][3] / 1000.0, m[1][3] / 1000.0, m[2][3] / 1000.0, x, y, z, w))
        return ('{"transforms":[' + ",".join(parts) + "]}").encode()

    def _continuous(self, key, q: tuple) -> tuple:
        """``q`` or ``-q`` (the same rotation), whichever is nearer the last one of ``key``:
        consecutive messages never flip the sign (an interpolation between them takes the
        short way)."""
        last = self.last.get(key)
        if last is not None and q[0] * last[0] + q[1] * last[1] + q[2] * last[2] + q[3] * last[3] < 0.0:
            q = (-q[0], -q[1], -q[2], -q[3])
        self.last[key] = q
        return q

    def _file(self, offset: int | None) -> str:
        """The source file of a line: the instruction's at ``offset``; a move's line (None)
        is the program's own file when it has no modules, else not known ("")."""
        program = self.program
        if program is None:
            return ""
        if offset is None:
            return "" if program.files else program.source
        return program.file_at(offset) or program.source

    def _event(self, event) -> list:
        t, kind, line, text = event
        return [("/log", _json({"timestamp": _time(t), "level": level_of(kind), "message": text, "name": kind,
                                "file": self._file(None) if line else "",
                                "line": max(0, int(line))}))]


_POSE_FORMAT = ('{"position":{"x":%.9f,"y":%.9f,"z":%.9f},'
                '"orientation":{"x":%.9f,"y":%.9f,"z":%.9f,"w":%.9f}}')


def _order(item) -> tuple:
    return item[0], item[1]


def _time(t: float) -> dict:
    sec, nsec = _stamp(t)
    return {"sec": sec, "nsec": nsec}


def _pose(values: tuple) -> dict:
    """A frame's x, y, z (mm), roll, pitch, yaw (deg) as a foxglove.Pose (m, quaternion)."""
    x, y, z, roll, pitch, yaw = values
    w, qx, qy, qz = rpy_to_quat(roll, pitch, yaw)
    return {"position": {"x": x / 1000.0, "y": y / 1000.0, "z": z / 1000.0},
            "orientation": {"x": qx, "y": qy, "z": qz, "w": w}}


def _escaped(name: str) -> str:
    """A name as a JSON string inside a %-format."""
    return json.dumps(name).replace("%", "%%")


def _json(message: dict) -> bytes:
    return json.dumps(message, separators=(",", ":"), allow_nan=False).encode()


def _version() -> str:
    from importlib import metadata

    try:
        return metadata.version("irl")
    except metadata.PackageNotFoundError:
        return "(not installed)"
