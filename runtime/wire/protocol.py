"""The runtime's network protocol: msgpack messages over ZeroMQ (see docs/protocol.md).

Requests go from a DEALER (or REQ) socket to the server's ROUTER socket, one msgpack map
per message; every request gets exactly one reply, a result or an error with a code and a
message. Telemetry goes out on a PUB socket as two frames: the topic ``b"telemetry"`` and
a msgpack map with a sequence number, so a subscriber sees the gaps it missed.

This module is the single definition of the messages: the operations and the shape of
their arguments (:data:`OPS`), the error codes (:data:`ERRORS`), and the encoding. The
server and the client both use it; docs/protocol.md is written from it.
"""
from __future__ import annotations

import enum
import math

import msgpack

VERSION = 2  # the newest version this runtime speaks
#: Every version it speaks: a request says its own (``v``), and the reply has the same.
VERSIONS = (1, 2)
#: The longest a ``wait`` may wait (s).
MAX_WAIT = 3600.0
#: Telemetry messages kept for ``telemetry`` replay (about 100 s of samples at 10 ms).
TELEMETRY_HISTORY = 10_000
#: Control's lease (s): it ends this long after its holder's last request.
MIN_LEASE, DEFAULT_LEASE, MAX_LEASE = 0.5, 10.0, 3600.0
#: A request's ``token`` (the one ``control`` with ``take: true`` returned: the request is
#: then the holder's, whatever connection it came on): the version that brought it, and
#: the longest one the server reads.
TOKEN_SINCE, MAX_TOKEN_LENGTH = 2, 256

#: Largest request the server takes (bytes); bigger ones get a ``too_large`` error.
MAX_REQUEST_BYTES = 1 << 20
#: Largest message the transport accepts at all (ZMQ_MAXMSGSIZE): beyond it the
#: connection is dropped without a reply (protects the server's memory).
TRANSPORT_MAX_BYTES = 8 << 20
#: Largest chunk of a report file in one ``report`` reply.
MAX_CHUNK_BYTES = 256 << 10
#: The files of a program's report that ``report`` reads (``file``): the CSV, its states and its events files.
REPORT_FILES = ("report", "states", "events")
#: Most programs (and reconfigurations) waiting in a server's queue, the running one not
#: counted; a ``submit`` or ``reconfigure`` beyond it gets a ``queue_full`` error.
MAX_QUEUED = 100

TELEMETRY_TOPIC = b"telemetry"
#: Feeds (protocol 2): the most a server keeps at once; a feed nobody has subscribed to for
#: FEED_IDLE seconds is forgotten (its topic then carries nothing until asked for again).
MAX_FEEDS, FEED_IDLE = 32, 60.0
#: A feed's rate (samples per second of the robot's clock): a sample comes every 10 ms
#: while a program runs, so at most 100.
MIN_FEED_RATE, MAX_FEED_RATE = 0.1, 100.0
#: Envelope frames a request may come with (a REQ client's delimiter, proxies' identities).
MAX_ENVELOPE_FRAMES = 16

#: The fields of a telemetry ``sample``: name -> (type, description). A feed names some
#: of them; docs/protocol.md's table is generated from this one.
SAMPLE_FIELDS: dict[str, tuple[str, str]] = {
    "state": ("str", "the supervisor's state path (`\"Move Robot\"`, ...), or `\"Idle\"`"),
    "program": ("int or nil", "the running program's id"),
    "queued": ("int", "programs waiting in the queue"),
    "override": ("float", "speed override, percent"),
    "position": ("[float]", "measured axis positions (deg), one per axis"),
    "inputs": ("[bool]", "digital inputs, input n at index n - 1"),
    "outputs": ("[bool]", "digital outputs, output n at index n - 1"),
    "line": ("int", "while a program runs: the source line executing"),
    "moves_done": ("int", "while a program runs: moves completed"),
    "moves_total": ("int or nil", "while a program runs: its moves (nil when it loops or calls procedures)"),
    "paused": ("bool", "while a program runs: it is paused"),
    "step": ("bool", "while a program runs: it runs in step mode (`submit`'s `step`)"),
    "waiting_for_step": ("bool", "while a program runs: it waits before a move for a `step`"),
    "approach": ("bool", "while a program runs: the next move (or the one under way) is the approach of a start "
                         "from a line (`submit`'s `from_line`)"),
    "following_error": ("float", "while a program runs: the largest absolute following error (deg)"),
    "tool": ("str", "the tool of the move under way or last started (its `use tool` name; `default_tool` before)"),
    "base": ("str", "the base of the move under way or last started (its `use base` name; `world` before)"),
    "tcp": ("[float] or nil", "the tool centre point of that tool in the world frame, from the measured "
                              "position: x, y, z (mm), roll, pitch, yaw (deg); nil when the robot's kinematics "
                              "give none"),
    "tcp_base": ("[float] or nil", "the same in that base"),
    "mode": ("str", "the operating mode: \"aut\" or \"t1\""),
    "jog": ("map or nil", "while jogging: the jog under way (`active`), whether it is stopping, why the last one "
                          "ended (`reason`)"),
}

#: The operating modes: name -> what it is (the ``mode`` op, ``irl mode``, docs/safety.md;
#: runtime/motion/reduced.py plans T1's moves, the safety supervisor enforces its speeds).
MODES = {
    "aut": "automatic: programs run at their programmed speeds; no jogging",
    "t1": "manual reduced speed (ISO 10218-1): the tool centre point and the flange at most [safety] t1_speed "
          "(250 mm/s), each axis at most [safety] t1_velocity_factor x max_velocity, checked by the safety "
          "supervisor every 1 ms; programs run as a test at reduced speed; jogging",
}

#: Jogging (the ``jog`` op, ``irl jog``, the pendant): the Cartesian directions (besides the
#: axes by name: translations along x, y, z in mm, rotations about them in deg), the frames
#: they are in, and the largest increment (mm or deg).
JOG_CARTESIAN = ("x", "y", "z", "rx", "ry", "rz")
JOG_FRAMES = ("world", "base", "tool")
MAX_JOG_STEP = 100.0
#: s between the repetitions (heartbeats) of a held continuous jog that ``irl jog --hold``
#: and the pendant send (the loop stops a jog 0.25 s after the last one: at least every 0.2 s).
JOG_HEARTBEAT = 0.1
#: A jog that reaches a jog session as it ends is refused with this text: the client sends it
#: again (the next heartbeat does), and a new session starts.
JOG_SESSION_ENDING = "the jog session is ending (its brakes are closing): send the jog again"

ERRORS = {
    "bad_message": "the request is not a msgpack map (or is not valid msgpack)",
    "bad_version": "the request's protocol version \"v\" is missing or not supported",
    "bad_request": "the request's fields or arguments have the wrong shape or type",
    "unknown_op": "no such operation",
    "too_large": f"the request is larger than {MAX_REQUEST_BYTES} bytes",
    "invalid_program": "the object code failed verification, or cannot run on this runtime",
    "wrong_robot": "the program was compiled for another robot or another version of its specification",
    "not_found": "no such program (or report)",
    "refused": "the request is well-formed but cannot be done now (the reason says why)",
    "queue_full": f"the queue already holds {MAX_QUEUED} programs waiting to run: submit again when one has started",
    "script_error": "the scripting command is malformed or names no property or operation",
    "internal": "the server failed to handle the request (a bug: the message says what)",
}

# Argument kinds: name -> (python types, description for the docs)
_INT, _NUM, _STR, _BIN, _BOOL, _LIST = (int,), (int, float), (str,), (bytes,), (bool,), (list,)
_PLAIN = (bool, int, float, str, list)  # a value of the language as plain data (compiler.values.to_plain)

#: op -> {argument: (types, required, description)}, and the op's description.
#: (:data:`SINCE` says which protocol version brought an op; the others are in every version.)
OPS: dict[str, tuple[dict[str, tuple[tuple, bool, str]], str]] = {
    "hello": ({}, "who the server is: protocol version, robot, specification hash, clock, configurations"),
    "status": ({"program": (_INT, False, "a program id: that program only")},
               "the robot's state, the running program, the queue and recent programs"),
    "submit": ({"object": (_BIN, True, "the object code (an .irlo file's bytes)"),
                "name": (_STR, False, "a name to show for the program (e.g. its file name)"),
                "source": (_STR, False, "the program's source text, kept for viewers (`source`, irl view)"),
                "step": (_BOOL, False, "true: run it in step mode, each move waiting for a `step` (default false)"),
                "from_line": (_INT, False, "start at the move on this line of the program's source, after an "
                                           "approach to its start (default: from the start)")},
               "verify the object code and queue it; returns its id"),
    "pause": ({"program": (_INT, False, "the program meant (refused if another one runs)")},
              "hold the running program; a move under way comes to a controlled stop"),
    "resume": ({"program": (_INT, False, "the program meant (refused if another one is paused)")},
               "continue the paused program (the interrupted move is finished first)"),
    "step": ({"program": (_INT, False, "the program meant (refused if another one runs)")},
             "step mode: the move the running program waits before goes (to its target, where the program stops "
             "again before its next move)"),
    "abort": ({"program": (_INT, False, "a queued program to remove instead of the running one")},
              "bring the running program to a controlled stop and end it (or remove a queued one)"),
    "estop": ({}, "emergency stop: brakes on and drives off now; the running program and the queue are ended"),
    "override": ({"percent": (_NUM, True, "1 to 100")},
                 "speed override: the move under way changes smoothly, the next ones follow"),
    "call": ({"text": (_STR, True, "a scripting command, e.g. trajectory.budget = 500 (see 'help')")},
             "the scripting interface: read or set a property, call an operation"),
    "reconfigure": ({"name": (_STR, True, "a configuration of the server's configuration file")},
                    "switch configuration between programs (in the Robot Reconfiguration state)"),
    "report": ({"program": (_INT, True, "a program id"),
                "file": (_STR, False, "\"report\" (default), \"states\" or \"events\""),
                "offset": (_INT, False, "byte offset to read from (default 0)")},
               f"a chunk (at most {MAX_CHUNK_BYTES} bytes) of a program's report CSV"),
    "wait": ({"program": (_INT, True, "a program id"),
              "timeout": (_NUM, False, f"seconds to wait at most, more than 0, at most {MAX_WAIT:g} (default 60)")},
             "answer when the program has ended (its status, with the summary), or at the timeout (its status "
             "then, with \"timed_out\": true)"),
    "control": ({"take": (_BOOL, True, "true: take control of the robot; false: give it back"),
                 "name": (_STR, False, "who you are, shown in status and to the clients that are refused "
                                       "(default: \"client #N\", N counting the times control was taken)"),
                 "lease": (_NUM, False, f"seconds the control lasts without a request from you, "
                                        f"{MIN_LEASE:g} to {MAX_LEASE:g} (default {DEFAULT_LEASE:g})")},
                "one controlling client at a time: while one holds control, the others may only read (and "
                "estop); control ends when given back, or after its lease without a request from its holder"),
    "telemetry": ({"since": (_INT, False, "a telemetry seq: the messages after it (default: none, the latest "
                                         "sample only)")},
                  f"the latest telemetry sample, and the messages after ``since`` from a history of the last "
                  f"{TELEMETRY_HISTORY} (a subscriber that joined late or lost messages catches up)"),
    "source": ({"program": (_INT, True, "a program id")},
               "the source text a program was submitted with (nil when it came without), to show its lines"),
    "mode": ({"mode": (_STR, True, "\"t1\" (manual reduced speed) or \"aut\" (automatic)")},
             "switch the operating mode, only while no program runs and the robot is at rest (docs/safety.md)"),
    "jog": ({"axis": (_STR, True, "an axis by name (A1 .. A6), or x, y, z, rx, ry, rz (along and about the frame's "
                                  "axes, through the tool centre point)"),
             "direction": (_INT, True, "+1 or -1; 0 releases (stops) a continuous jog"),
             "frame": (_STR, False, "for x .. rz: \"world\" (default), \"base\" (the active base) or \"tool\""),
             "step": (_NUM, False, f"an increment, mm or deg, more than 0 and at most {MAX_JOG_STEP:g} (default: "
                                   "continuous: the robot moves while the same request is repeated, at least every "
                                   "0.2 s)")},
            "in T1, move the arm by hand: an axis or the tool centre point, continuously (hold-to-run: the same "
            "request repeated is the heartbeat; silence stops the robot) or by one increment"),
    "feed": ({"fields": (_LIST, True, "the sample fields wanted (an array of names, see the sample table)"),
              "rate": (_NUM, False, f"samples per second, {MIN_FEED_RATE:g} to {MAX_FEED_RATE:g} (default "
                                    f"{MAX_FEED_RATE:g}: every sample)"),
              "events": (_BOOL, False, "true: the events too (default false: samples only)")},
             "a telemetry feed of some sample fields at a chosen rate: the reply names its topic; subscribe to "
             "it on the telemetry socket"),
    "persistent": ({"program": (_STR, False, "a program's name (from its 'program NAME;'): its values only")},
                   "the values the runtime keeps of programs' persistent variables (docs/language.md, Persistent "
                   "variables): per program, each variable's type and value"),
    "persistent_set": ({"program": (_STR, True, "the program's name"),
                        "name": (_STR, True, "a persistent variable the runtime keeps a value of"),
                        "value": (_PLAIN, True, "its new value, of its type, as plain data (docs/protocol.md)")},
                       "set a kept value (not while that program runs): its next run starts from it"),
    "persistent_reset": ({"program": (_STR, True, "the program's name"),
                          "name": (_STR, False, "one variable (default: all of the program's)")},
                         "forget kept values (not while that program runs): its next run starts from the initial "
                         "values"),
}

#: The ops a protocol version brought (every other op is in every version).
SINCE = {"wait": 2, "telemetry": 2, "control": 2, "feed": 2, "source": 2, "mode": 2, "jog": 2, "step": 2,
         "persistent": 2, "persistent_set": 2, "persistent_reset": 2}
#: The ops that control the robot: refused to every client but the holder while one holds
#: control (``estop`` never is: an emergency stop is open to every client).
CONTROLLING = frozenset({"submit", "pause", "resume", "step", "abort", "override", "call", "reconfigure", "mode",
                         "jog", "persistent_set", "persistent_reset"})



class JobState(enum.StrEnum):
    """What became of a submitted program (or reconfiguration): a job's ``state`` in
    ``status``, ``wait`` and the ``program`` telemetry event. Its values are the strings
    the wire carries."""

    QUEUED = "queued"
    RUNNING = "running"
    COMPLETED = "completed"
    FAULTED = "faulted"
    ABORTED = "aborted"
    CANCELLED = "cancelled"

    @property
    def ended(self) -> bool:
        """Whether the job has ended (or will never run): its state changes no more."""
        return self in TERMINAL


#: The states a job ends in (it changes no more).
TERMINAL = frozenset({JobState.COMPLETED, JobState.FAULTED, JobState.ABORTED, JobState.CANCELLED})

def jog_problem(axes: list[str], axis: str, direction: int, frame: str | None, step) -> str | None:
    """What is wrong with a ``jog`` request's arguments for a robot whose axes are named
    ``axes`` (the server checks it, and the loop again), or None."""
    names = [a.lower() for a in axes]
    if axis.lower() not in names and axis not in JOG_CARTESIAN:
        return f"jog: axis must be one of {', '.join(axes)}, {', '.join(JOG_CARTESIAN)}; got {axis[:40]!r}"
    if direction not in (-1, 0, 1):
        return f"jog: direction must be +1, -1 or 0 (release), got {direction}"
    if frame is not None and frame not in JOG_FRAMES:
        return f"jog: frame must be {', '.join(JOG_FRAMES)}, got {frame[:40]!r}"
    if step is not None and not 0.0 < step <= MAX_JOG_STEP:
        return f"jog: step must be more than 0 and at most {MAX_JOG_STEP:g} (mm or deg), got {step:g}"
    return None


def sample_markdown() -> str:
    """docs/protocol.md's table of the sample fields (:data:`SAMPLE_FIELDS`)."""
    rows = [f"| `{name}` | {kind} | {text} |" for name, (kind, text) in SAMPLE_FIELDS.items()]
    return "\n".join(["| Field | Type | |", "|---|---|---|", *rows]) + "\n"


class ProtocolError(Exception):
    """A request that gets an error reply: ``code`` (one of :data:`ERRORS`) and message."""

    def __init__(self, code: str, message: str, request_id=None):
        super().__init__(message)
        self.code = code
        self.message = message
        self.request_id = request_id
        self.version: int | None = None  # the request's protocol version, once read


def pack(obj) -> bytes:
    return msgpack.packb(obj, use_bin_type=True)


def _valid_id(value) -> bool:
    return value is None or (isinstance(value, int) and not isinstance(value, bool)
                             and -(1 << 63) <= value < (1 << 64)) or (isinstance(value, str) and len(value) <= 256)


def decode_request(payload: bytes) -> tuple[object, str, dict]:
    """``(request id, op, args)`` of a request, or ProtocolError with what is wrong."""
    request_id, op, args, _version, _token = decode(payload)
    return request_id, op, args


def decode(payload: bytes) -> tuple[object, str, dict, int, str | None]:
    """``(request id, op, args, version, token)`` of a request (``token``: the control
    token it carries, or None), or ProtocolError with what is wrong (its ``version``: the
    request's when it is one this server speaks, for the reply; else VERSION)."""
    try:
        return _decode(payload)
    except ProtocolError as exc:
        if exc.version is None:
            exc.version = VERSION
        raise


def _decode(payload: bytes) -> tuple[object, str, dict, int, str | None]:
    if len(payload) > MAX_REQUEST_BYTES:
        raise ProtocolError("too_large", f"the request has {len(payload)} bytes; the limit is {MAX_REQUEST_BYTES}")
    try:
        message = msgpack.unpackb(payload, raw=False, strict_map_key=True, max_bin_len=MAX_REQUEST_BYTES,
                                  max_str_len=MAX_REQUEST_BYTES, max_array_len=10_000, max_map_len=1_000)
    except Exception as exc:  # msgpack raises several kinds (ValueError, ExtraData, FormatError...)
        raise ProtocolError("bad_message", f"not valid msgpack ({type(exc).__name__})") from None
    if not isinstance(message, dict):
        raise ProtocolError("bad_message", f"expected a msgpack map, got {type(message).__name__}")
    version = message.get("v")
    known = version in VERSIONS and not isinstance(version, bool)
    request_id = message.get("id")
    try:
        if not _valid_id(request_id):  # answered with id nil: the client's id cannot be echoed
            raise ProtocolError("bad_request", f"\"id\" must be an integer (signed or unsigned, 64-bit) or a "
                                               f"string of at most 256 characters, got {_shown(request_id)}: this "
                                               "reply's id is nil")
        if not known:
            raise ProtocolError("bad_version", f"protocol version {repr(version)[:40]} is not supported; this server "
                                               f"speaks versions {', '.join(map(str, VERSIONS))}", request_id)
        token = message.get("token")
        if token is not None and (version < TOKEN_SINCE or not isinstance(token, str) or
                                  not 0 < len(token) <= MAX_TOKEN_LENGTH):
            raise ProtocolError("bad_request", f"\"token\" must be a string of 1 to {MAX_TOKEN_LENGTH} characters "
                                               f"(a control token), in a request of version {TOKEN_SINCE} or later; "
                                               f"got {_shown(token)} with \"v\": {version}", request_id)
        op, args = _operation(message, request_id, version)
    except ProtocolError as exc:
        if known:
            exc.version = version
        raise
    return request_id, op, args, version, token


def _operation(message: dict, request_id, version: int) -> tuple[str, dict]:
    op = message.get("op")
    if not isinstance(op, str):
        raise ProtocolError("bad_request", "\"op\" must be a string", request_id)
    if op not in OPS or SINCE.get(op, 1) > version:
        if op in OPS:
            raise ProtocolError("unknown_op", f"{op!r} is an operation of protocol version {SINCE[op]}; the "
                                              f"request says \"v\": {version}", request_id)
        known = [name for name in OPS if SINCE.get(name, 1) <= version]
        raise ProtocolError("unknown_op", f"unknown operation {op[:64]!r}; known: {', '.join(known)}", request_id)
    args = message.get("args", {})
    if not isinstance(args, dict):
        raise ProtocolError("bad_request", f"\"args\" must be a map, got {type(args).__name__}", request_id)
    spec, _doc = OPS[op]
    for name in args:
        if name not in spec:
            known = ", ".join(spec) or "none"
            raise ProtocolError("bad_request", f"{op}: unknown argument {str(name)[:64]!r} (arguments: {known})",
                                request_id)
    for name, (types, required, _d) in spec.items():
        if name not in args:
            if required:
                raise ProtocolError("bad_request", f"{op}: missing argument {name!r}", request_id)
            continue
        value = args[name]
        if (isinstance(value, bool) and bool not in types) or not isinstance(value, types) or \
                (isinstance(value, float) and not math.isfinite(value)):
            raise ProtocolError("bad_request", f"{op}: argument {name!r} must be {_kind(types)}, "
                                               f"got {type(value).__name__}", request_id)
    return op, args


def _kind(types: tuple) -> str:
    return {_INT: "an integer", _NUM: "a finite number", _STR: "a string", _BIN: "binary (msgpack bin)",
            _BOOL: "true or false", _LIST: "an array", _PLAIN: "a value (a number, true or false, a string or an array)"}[types]


def _shown(value) -> str:
    """A malformed value, for an error message: its type, and its text when short."""
    kind = {bool: "bool", float: "float", int: "an integer out of range", type(None): "nil", str: "a string of "
            f"{len(value) if isinstance(value, str) else 0} characters"}.get(type(value), type(value).__name__)
    text = repr(value)
    return f"{kind} {text}" if len(text) <= 40 and not isinstance(value, str) else kind


def ok(request_id, result, version: int = VERSION) -> bytes:
    return pack({"v": version, "id": request_id, "ok": True, "result": result})


def error(request_id, code: str, message: str, version: int = VERSION) -> bytes:
    return pack({"v": version, "id": request_id, "ok": False, "error": {"code": code, "message": message}})


def request(op: str, args: dict | None = None, request_id=None, version: int = VERSION,
            token: str | None = None) -> bytes:
    message = {"v": version, "op": op, "args": args or {}}
    if request_id is not None:
        message["id"] = request_id
    if token is not None:
        message["token"] = token
    return pack(message)


def decode_reply(payload: bytes) -> dict:
    """A reply as a dict (the client's side); ProtocolError if it is not one."""
    try:
        message = msgpack.unpackb(payload, raw=False)
    except Exception as exc:
        raise ProtocolError("bad_message", f"the server's reply is not valid msgpack ({type(exc).__name__})") from None
    if not isinstance(message, dict) or "ok" not in message:
        raise ProtocolError("bad_message", "the server's reply is not a reply map")
    return message


def decode_telemetry(payload: bytes) -> dict | None:
    try:
        message = msgpack.unpackb(payload, raw=False)
    except Exception:
        return None
    return message if isinstance(message, dict) and isinstance(message.get("seq"), int) else None
