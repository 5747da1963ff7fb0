"""Recordings (``irl run --record FILE.mcap``, ``irl serve --record DIR``): what a recording
holds, declared once, and how to read one back.

A recording is an `MCAP <https://mcap.dev>`_ file of JSON messages, each channel with its JSON
Schema, so that Foxglove and Lichtblick open it without ROS. :data:`TOPICS` is the table of
its topics (the schema, the rate, what each message holds, in which units); :data:`SCHEMAS`
holds the schemas: Foxglove's own where one exists (``foxglove.FrameTransforms``,
``foxglove.PoseInFrame``, ``foxglove.Log``, ``foxglove.RobotDescription``: their fields and
units, meters and unit quaternions, as Foxglove's SDK declares them), ours (``irl.*``) for
the rest.
:data:`EVENTS` is the table of the events the loop records (in a recording's ``/log``, in the
report's events file): each kind and its level. The loop's writer
(:mod:`runtime.loop.components.recorder`) writes by these tables, docs/runtime.md's tables are
rendered from them (``python -m runtime.cli.docgen``), and :func:`read_recording` reads a
recording back into arrays (for ``irl``'s commands and a viewer).

Every message is stamped with the robot's clock, the time base of the report's ``time``
column (seconds from the power-up of the loop's robot): the message's ``timestamp`` and its
MCAP ``log_time`` and ``publish_time`` are that instant. Not real-time; imports nothing of
the loop, and the ``mcap`` library (``pip install 'irl[view]'``) only to read.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

#: The recording's format: the ``irl`` metadata record's ``format`` (a reader refuses another).
FORMAT = 1
#: The MCAP profile (none: the messages are JSON, not ROS), the encodings, and the metadata record's name.
PROFILE = ""
SCHEMA_ENCODING = "jsonschema"
MESSAGE_ENCODING = "json"
METADATA = "irl"
#: What ``--record`` needs, said when it is missing.
INSTALL = "recordings need the mcap library: pip install 'irl[view]'"

# ---- the events: the kinds of what happens in a cycle, and their levels (foxglove.LogLevel) -----
LEVELS = {"UNKNOWN": 0, "DEBUG": 1, "INFO": 2, "WARNING": 3, "ERROR": 4, "FATAL": 5}

PRINT, PAUSE, TIMEOUT, INTERRUPT, HALT, HANDLED, LOG_FULL, FROM_LINE, FAULT, STOP = (
    "print", "pause", "timeout", "interrupt", "halt", "handled", "log full", "from line", "fault", "stop")

#: Every kind of event the loop records: its level and what it is. The program's log lines
#: (``runtime.loop.vm``: ``MotionHost.log``) are the first eight; the supervisor's fault and the
#: safety supervisor's stop the last two. ``irl plot`` marks faults and interrupt firings.
EVENTS: dict[str, tuple[str, str]] = {
    PRINT: ("INFO", "a line of the program's print output"),
    PAUSE: ("INFO", "the program paused itself (pause;)"),
    TIMEOUT: ("WARNING", "a wait for ended by its time-out"),
    INTERRUPT: ("INFO", "an interrupt fired (its name, and where the program or the move under way was)"),
    HALT: ("WARNING", "an interrupt ended the program (then halt, or halt in its handler)"),
    HANDLED: ("WARNING", "an error handler took a run-time error (its name and message, and the handler's line)"),
    LOG_FULL: ("WARNING", "the program's log is full: later lines are counted, not kept"),
    FROM_LINE: ("INFO", "a start from a line (--from-line): what running to it without moving skipped, and the "
                        "approach to its start"),
    FAULT: ("ERROR", "the cycle's fault: what ended it early, with the state it ended in"),
    STOP: ("WARNING", "the safety supervisor's stop: its category and its cause (docs/safety.md)"),
}

#: The events file beside a report (``OUT.events.csv``): its header.
EVENTS_HEADER = "time,kind,line,text\n"


def read_events(report: str | Path) -> list[tuple[float, str, int, str]]:
    """The report's events file (``<report>.events.csv``: time, kind, line, text), if it is
    there and readable (a report written before it existed has none; a garbled one: none
    either)."""
    import csv

    path = Path(report).with_suffix(".events.csv")
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))[1:]
        return [(float(r[0]), r[1], int(r[2]), r[3]) for r in rows if len(r) == 4]
    except (OSError, ValueError, csv.Error):
        return []


def level_of(kind: str) -> int:
    """The foxglove.LogLevel of an event's kind (UNKNOWN for a kind not in :data:`EVENTS`)."""
    entry = EVENTS.get(kind)
    return LEVELS[entry[0]] if entry is not None else LEVELS["UNKNOWN"]


# ---- the schemas -------------------------------------------------------------------------------
def _time(what: str) -> dict:
    """A timestamp as Foxglove's JSON schemas declare one (title "time": Foxglove reads it as a time)."""
    return {"type": "object", "title": "time", "description": what,
            "properties": {"sec": {"type": "integer", "minimum": 0},
                           "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}},
            "required": ["sec", "nsec"]}


def _object(title: str, what: str, properties: dict, required: list | None = None) -> dict:
    return {"title": title, "description": what, "type": "object", "properties": properties,
            "required": list(properties) if required is None else required}


def _numbers(title: str, what: str, names: str, unit: str) -> dict:
    return _object(title, what, {n: {"type": "number", "description": f"{n} {unit}"} for n in names})


def _vector(what: str) -> dict:
    return _numbers("foxglove.Vector3", what, "xyz", "(m)")


def _quaternion(what: str) -> dict:
    return _numbers("foxglove.Quaternion", what, "xyzw", "component of a unit quaternion")


def _pose(what: str) -> dict:
    return _object("foxglove.Pose", what, {"position": _vector("position (m)"),
                                           "orientation": _quaternion("orientation")})


def _string(what: str) -> dict:
    return {"type": "string", "description": what}


def _array(item: str, what: str) -> dict:
    return {"type": "array", "items": {"type": item}, "description": what}


_TRANSFORM = _object(
    "foxglove.FrameTransform", "where a child frame is in its parent frame: the translation, then the rotation",
    {"timestamp": _time("the robot's time of the transform"),
     "parent_frame_id": _string("the parent frame (a link of the arm's URDF, irl urdf)"),
     "child_frame_id": _string("the child frame (a link of the arm's URDF)"),
     "translation": _vector("the child frame's origin in the parent frame (m)"),
     "rotation": _quaternion("the child frame's orientation in the parent frame")})

#: Every schema, by name: Foxglove's (the fields and units its SDK declares) and ours.
SCHEMAS: dict[str, dict] = {
    "foxglove.FrameTransforms": _object("foxglove.FrameTransforms", "an array of FrameTransform messages",
                                        {"transforms": {"type": "array", "items": _TRANSFORM,
                                                        "description": "every link of the arm"}}),
    "foxglove.PoseInFrame": _object(
        "foxglove.PoseInFrame", "a timestamped pose in a frame",
        {"timestamp": _time("the robot's time of the pose"), "frame_id": _string("the frame of the pose"),
         "pose": _pose("the pose in that frame")}),
    "foxglove.Log": _object(
        "foxglove.Log", "a log message",
        {"timestamp": _time("the robot's time of the event"),
         "level": {"title": "foxglove.LogLevel", "description": "log level",
                   "oneOf": [{"title": name, "const": value} for name, value in LEVELS.items()]},
         "message": _string("what happened, as irl run and the summary say it"),
         "name": _string("the event's kind (print, interrupt, fault, ...: docs/runtime.md)"),
         "file": _string("the program's source file of the line (empty when not known)"),
         "line": {"type": "integer", "minimum": 0, "description": "the program's source line (0: none)"}}),
    "foxglove.RobotDescription": _object(
        "foxglove.RobotDescription", "the arm as a robot description (its links posed by /tf)",
        {"url": _string("where the description is (empty: it is embedded in data)"),
         "format": _string("the description's format: urdf"),
         "data": {"type": "string", "contentEncoding": "base64",
                  "description": "the URDF of irl urdf, embedded (base64)"}}),
    "irl.JointState": _object(
        "irl.JointState", "the measured position and velocity of every axis, in the units of the report and the "
                          "language: deg and deg/s (mm and mm/s for a prismatic axis), not radians",
        {"timestamp": _time("the robot's time of the measurement"),
         "name": _array("string", "the axes' names (the specification's: A1 ... A6)"),
         "position": _array("number", "each axis's measured position (the report's sens_pos), deg (mm)"),
         "velocity": _array("number", "each axis's measured velocity (the encoder's estimate), deg/s (mm/s)")}),
    "irl.Frames": _object(
        "irl.Frames", "the tool and base of the move under way or last started (use tool, use base)",
        {"timestamp": _time("the robot's time of the change"),
         "tool": _string("the active tool's name (default_tool: the specification's)"),
         "base": _string("the active base's name (world: none)"),
         "tool_pose": _pose("the tool's TCP in the flange frame (m, quaternion)"),
         "base_pose": _pose("the base in the world frame (m, quaternion)")}),
    "irl.DigitalIO": _object(
        "irl.DigitalIO", "every digital input and output (input n at index n - 1)",
        {"timestamp": _time("the robot's time of the change"),
         "inputs": _array("boolean", "the digital inputs"), "outputs": _array("boolean", "the digital outputs")}),
    "irl.AnalogIO": _object(
        "irl.AnalogIO", "every analog input as read and output as last set, in its unit (the metadata's "
                        "analog_inputs and analog_outputs name each and its unit: [[name, unit], ...]; input n at "
                        "index n - 1); null for one the robot's I/O does not have (a PLC that maps none)",
        {"timestamp": _time("the robot's time of the change"),
         "inputs": {"type": "array", "items": {"type": ["number", "null"]}, "description": "the analog inputs"},
         "outputs": {"type": "array", "items": {"type": ["number", "null"]}, "description": "the analog outputs"}}),
    "irl.Phase": _object(
        "irl.Phase", "the supervisor's state, by name",
        {"timestamp": _time("the robot's time of the change"),
         "state": _string("the state path, as the report's state column: Initialization Sequence/Find Index"),
         "phase": _string("the top-level state: Start Robot, Calibrate Offsets, Initialization Sequence, "
                          "Move Robot, Robot Reconfiguration, Stop Robot"),
         "step": _string("the sub-machine's state (the homing step), empty when none")}),
    "irl.SourceLine": _object(
        "irl.SourceLine", "the program's current source line: the move under way's, else the instruction's",
        {"timestamp": _time("the robot's time of the change"),
         "line": {"type": "integer", "minimum": 0, "description": "the source line (0: none)"},
         "file": _string("its source file (empty when not known: a move's line in a program with modules)")}),
}


@dataclass(frozen=True)
class Topic:
    """One topic of a recording: its name, its schema (a key of :data:`SCHEMAS`), when a
    message comes, and what it holds."""

    name: str
    schema: str
    rate: str
    what: str


#: Every topic of a recording, in the order the writer registers them.
TOPICS: tuple[Topic, ...] = (
    Topic("/joint_states", "irl.JointState", "every 10 ms",
          "each axis's measured position (the report's sens_pos), deg, and velocity, deg/s"),
    Topic("/tcp", "foxglove.PoseInFrame", "every 10 ms",
          "the tool centre point of the active tool in the world frame (the report's tcp group), m and a unit "
          "quaternion; frame_id world"),
    Topic("/tf", "foxglove.FrameTransforms", "every 10 ms",
          "every link of the arm in its parent link, frame ids the link names of irl urdf's URDF (world, base_link, "
          "link_1 ... link_6, flange, the tools and frames), m and unit quaternions"),
    Topic("/robot_description", "foxglove.RobotDescription", "once, at the start",
          "the arm's URDF (irl urdf's, embedded): a 3D panel that reads it shows the arm without a file"),
    Topic("/frames", "irl.Frames", "at the start and on a change",
          "the active tool's and base's names and poses (use tool, use base)"),
    Topic("/io", "irl.DigitalIO", "at the start and on a change", "every digital input and output"),
    Topic("/io/analog", "irl.AnalogIO", "at the start and on a change (a robot with analog channels)",
          "every analog input (as read) and output (as last set), in its unit"),
    Topic("/phase", "irl.Phase", "at the start and on a change",
          "the supervisor's state by name: at each transition's tick, and each homing step at its first row"),
    Topic("/line", "irl.SourceLine", "at the start and on a change", "the program's current source line and file"),
    Topic("/log", "foxglove.Log", "as they come",
          "every event (the table below): print output (INFO), interrupt firings, the fault (ERROR), the stop"),
)


def missing() -> str | None:
    """What ``--record`` lacks (the mcap library), said with how to install it; None: nothing."""
    from importlib.util import find_spec

    return INSTALL if find_spec("mcap") is None else None


def schema_text(name: str) -> bytes:
    """A schema as the bytes of its MCAP schema record."""
    return json.dumps(SCHEMAS[name], separators=(",", ":")).encode("utf-8")


def recording_name(session: str, job: int, program: str) -> str:
    """The file name of a served program's recording (``irl serve --record DIR``): the
    server's session (its start time and process id, as its reports' directory), the
    program's id and its name (a file's name, as ``irl submit`` sends it, without its
    ``.irl`` or ``.irlo``): ``20250101-120000-4242-program-3-pick_place.mcap``."""
    stem = re.sub(r"\.irlo?$", "", program)
    safe = re.sub(r"[^A-Za-z0-9_.-]+", "_", stem).strip("._")[:60] or "program"
    return f"{session}-program-{job}-{safe}.mcap"


# ---- the docs' tables -----------------------------------------------------------------------------
def topics_markdown() -> str:
    lines = ["| topic | schema | when | what (units) |", "|---|---|---|---|"]
    for topic in TOPICS:
        lines.append(f"| `{topic.name}` | `{topic.schema}` | {topic.rate} | {topic.what} |")
    return "\n".join(lines) + "\n"


def events_markdown() -> str:
    lines = ["| kind | level | what |", "|---|---|---|"]
    for kind, (level, what) in EVENTS.items():
        lines.append(f"| `{kind}` | {level} | {what} |")
    return "\n".join(lines) + "\n"


# ---- reading -------------------------------------------------------------------------------------
class RecordingError(Exception):
    """A file that is not a recording irl can read (said in the user's terms)."""


def _seconds(stamp: dict) -> float:
    return stamp["sec"] + stamp["nsec"] * 1e-9


def read_messages(path: str | Path, topics: set[str] | None = None):
    """``(metadata, messages, complete)`` of a recording: its ``irl`` metadata record (a
    dict of strings), ``[(topic, message)]`` in file order (each message decoded from its
    JSON; ``topics``: only those), and whether the file is whole (False: it ends early, as
    after a crash, and holds every message up to its last complete chunk). RecordingError
    for a file that is not a recording."""
    try:
        from mcap.records import Channel, Message, Metadata
        from mcap.stream_reader import StreamReader
    except ImportError:
        raise RecordingError(INSTALL) from None
    channels: dict[int, str] = {}
    metadata: dict = {}
    messages: list = []
    complete = False
    try:
        with open(path, "rb") as f:
            try:
                for record in StreamReader(f).records:
                    if isinstance(record, Message):
                        topic = channels.get(record.channel_id)
                        if topic is not None and (topics is None or topic in topics):
                            messages.append((topic, json.loads(record.data)))
                    elif isinstance(record, Channel):
                        channels[record.id] = record.topic
                    elif isinstance(record, Metadata) and record.name == METADATA:
                        metadata = dict(record.metadata)
                complete = True
            except Exception:  # noqa: BLE001
                # (the mcap library and its decompressors on an untrusted file fail in many ways:
                # struct.error on a file of a few bytes, zstd's and lz4's own errors on a bad chunk;
                # every one ends the file here, or says it is none)
                if not channels and not metadata:
                    raise RecordingError(f"{path} is not an MCAP recording: its records cannot be read") from None
    except OSError as exc:
        raise RecordingError(f"cannot read {path}: {exc.strerror or exc}") from None
    if metadata.get("format") != str(FORMAT):
        raise RecordingError(f"{path} is not an irl recording of format {FORMAT} (its metadata: "
                             f"{metadata.get('format', 'none')})")
    return metadata, messages, complete


def read_recording(path: str | Path, links: bool = False) -> dict:
    """A recording as arrays (NumPy) and lists, for a viewer or a command:

    - ``metadata``: the ``irl`` record (program, robot, spec_hash, job, axes, units, ...);
      ``complete``: False when the file ends early (a crash): everything up to its last
      complete chunk is there;
    - ``times`` (n,) s, ``names`` (the axes), ``joints`` (n, axes) deg (mm for a prismatic
      axis), ``velocities`` (n, axes) deg/s: ``/joint_states``;
    - ``tcp_times`` (m,) s, ``tcp`` (m, 3) mm and ``tcp_rotation`` (m, 4), a unit quaternion
      (w, x, y, z) as :mod:`runtime.motion.rotation`'s: ``/tcp`` in the world frame;
    - ``phases`` [(time, state path)], ``lines`` [(time, line, file)], ``frames`` [(time,
      tool, base)], ``logs`` [{time, level (its name), kind, text, file, line}];
    - ``io``: {times (k,), inputs (k, n) bool, outputs (k, n) bool}, one row per change;
    - ``analog``: {times (k,), inputs (k, n), outputs (k, m)}, in their units (NaN: none), one
      row per change (k = 0 for a robot without analog channels);
    - with ``links``: ``links`` {child link: (parent link, (n, 4, 4) transforms in mm)} from
      ``/tf`` (read only when asked: the largest topic).

    RecordingError for a file that is not a recording."""
    import numpy as np

    wanted = {t.name for t in TOPICS} - (set() if links else {"/tf"})
    metadata, messages, complete = read_messages(path, wanted)
    by_topic: dict[str, list] = {t.name: [] for t in TOPICS}
    for topic, message in messages:
        by_topic[topic].append(message)
    names_by_level = {v: k for k, v in LEVELS.items()}
    joints = by_topic["/joint_states"]
    tcp = by_topic["/tcp"]
    io = by_topic["/io"]
    analog = by_topic["/io/analog"]

    def values(key: str):
        rows = [[np.nan if v is None else v for v in m[key]] for m in analog]
        if rows:
            return np.array(rows, dtype=float).reshape(len(rows), -1)
        try:  # (none recorded: as many columns as the metadata names; a recording of an earlier build: none)
            width = len(json.loads(metadata.get(f"analog_{key}", "[]")))
        except (TypeError, ValueError):
            width = 0
        return np.zeros((0, width))
    out = {
        "metadata": metadata, "complete": complete,
        "times": np.array([_seconds(m["timestamp"]) for m in joints]),
        "names": list(joints[0]["name"]) if joints else json.loads(metadata.get("axes", "[]")),
        "joints": np.array([m["position"] for m in joints], dtype=float).reshape(len(joints), -1),
        "velocities": np.array([m["velocity"] for m in joints], dtype=float).reshape(len(joints), -1),
        "tcp_times": np.array([_seconds(m["timestamp"]) for m in tcp]),
        "tcp": np.array([[m["pose"]["position"][c] * 1000.0 for c in "xyz"] for m in tcp]).reshape(len(tcp), 3),
        "tcp_rotation": np.array([[m["pose"]["orientation"][c] for c in "wxyz"] for m in tcp]).reshape(len(tcp), 4),
        "phases": [(_seconds(m["timestamp"]), m["state"]) for m in by_topic["/phase"]],
        "lines": [(_seconds(m["timestamp"]), m["line"], m["file"]) for m in by_topic["/line"]],
        "frames": [(_seconds(m["timestamp"]), m["tool"], m["base"]) for m in by_topic["/frames"]],
        "logs": [{"time": _seconds(m["timestamp"]), "level": names_by_level.get(m["level"], "UNKNOWN"),
                  "kind": m["name"], "text": m["message"], "file": m["file"], "line": m["line"]}
                 for m in by_topic["/log"]],
        "io": {"times": np.array([_seconds(m["timestamp"]) for m in io]),
               "inputs": np.array([m["inputs"] for m in io], dtype=bool).reshape(len(io), -1),
               "outputs": np.array([m["outputs"] for m in io], dtype=bool).reshape(len(io), -1)},
        "analog": {"times": np.array([_seconds(m["timestamp"]) for m in analog]), "inputs": values("inputs"),
                   "outputs": values("outputs")},
    }
    if links:
        out["links"] = _links(by_topic["/tf"])
    return out


def _links(messages: list) -> dict:
    """{child: (parent, (n, 4, 4) homogeneous transforms, mm)} of the /tf messages."""
    import numpy as np

    rows: dict[str, tuple[str, list]] = {}
    for message in messages:
        for t in message["transforms"]:
            q, p = t["rotation"], t["translation"]
            rows.setdefault(t["child_frame_id"], (t["parent_frame_id"], []))[1].append(
                (q["w"], q["x"], q["y"], q["z"], p["x"], p["y"], p["z"]))
    out = {}
    for child, (parent, values) in rows.items():
        a = np.array(values)
        w, x, y, z = (a[:, k] for k in range(4))
        m = np.zeros((len(a), 4, 4))
        m[:, 0, 0], m[:, 0, 1], m[:, 0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
        m[:, 1, 0], m[:, 1, 1], m[:, 1, 2] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
        m[:, 2, 0], m[:, 2, 1], m[:, 2, 2] = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
        m[:, :3, 3] = a[:, 4:] * 1000.0
        m[:, 3, 3] = 1.0
        out[child] = (parent, m)
    return out
