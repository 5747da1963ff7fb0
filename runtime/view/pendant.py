"""``irl view --endpoint E``'s pendant: the operator's controls of a teach pendant in a page
of its own (``pendant.html``), served by this process on 127.0.0.1 (runtime.view.pagehttp)
beside the 3D view, and talking to the robot over the protocol (docs/protocol.md).

Each page that opens is a **session** with two connections of its own to the server (one
for commands, one for its status polls, so that neither waits behind the other), and the
control token it took (its Take button; opening the page takes nothing): every command
needs this page to hold control (:data:`ACTIONS`), except taking it, teaching a point and
the emergency stop, which has a connection of its own shared by every page (an ``estop`` is
open to every client, and never waits behind another request).

**Hold-to-run.** The page sends a held jog button's request every ``JOG_HEARTBEAT`` (0.1 s)
while the pointer is down on it, and a release (``direction`` 0) when the pointer comes up,
leaves the button or is cancelled, or the page loses the focus or is hidden; this side
never repeats a request by itself. Each message carries the page's sequence number and its
send time, and :class:`JogGate` lets on only the newest (a heartbeat overtaken by a later
message, or late by more than the server's heartbeat timeout, is dropped: it no longer says
that the button is held); a release always goes. A continuous jog's messages go on to the
server as its heartbeats; an increment's first message starts it (a repetition would start
it again: the others only say it is still held). The watch (:meth:`Pendant._watch`)
releases a held jog whose page fell silent (a page that died, a lost connection) and, as
the page's release does, aborts the jog session while it is still homing (the first jog
homes the robot): so homing too moves only while a jog button is held. A press that the
server refused, or that the watch released, starts nothing again, however long the button
stays held: the operator releases it and presses again.
"""
from __future__ import annotations

import math
import secrets
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

from compiler.diagnostics import render_all
from compiler.driver import compile_file
from compiler.objcode import encode

from runtime.client.client import Client, ClientError, source_text
from runtime.loop.jogging import HEARTBEAT_TIMEOUT
from runtime.motion.kinematics import configuration_name
from runtime.motion.teach import frame_names, named_frame, where
from runtime.view.pagehttp import PageServer, RouteError
from runtime.wire import protocol
from runtime.wire.protocol import ProtocolError

#: The page (HTML, CSS and its script in one file, beside this module).
PAGE = Path(__file__).with_name("pendant.html")
#: s between a page's status polls.
POLL = 0.2
#: s a request to the server may take.
REPLY = 2.0
#: Control's lease (s) the pendant takes: its page's polls (every POLL s) renew it, so
#: control ends this long after the page is gone without a word.
LEASE = protocol.DEFAULT_LEASE
#: s a jog message may come later than the quickest one from its page and still be sent on;
#: s after a held jog's last message the watch releases it.
STALE = HEARTBEAT_TIMEOUT
#: s after a page's last request its session is closed (its control given back).
SESSION_IDLE = 30.0
#: The most pages open at once (the oldest is closed for a new one).
MAX_SESSIONS = 16
#: A jog's increments the page offers (mm or deg); none: continuous.
INCREMENTS = (0.1, 1.0, 10.0)
#: The messages kept for the pages (prints, faults, the pendant's notes).
MESSAGES = 200
#: The longest name a page may take control with.
MAX_NAME = 64
#: Which actions a page may ask for, and whether each needs the page to hold control
#: (each is the Session's ``act_<name>``).
ACTIONS = {"take": False, "release": False, "mode": True, "start": True, "pause": True, "resume": True, "step": True,
           "abort": True, "override": True, "input": True, "jog": True, "teach": False}


class Refused(Exception):
    """What the server (or the pendant) said no with: ``code`` and the message to show."""

    def __init__(self, code: str, message: str):
        super().__init__(message)
        self.code, self.message = code, message


def _ms() -> float:
    return time.monotonic() * 1000.0


class Link:
    """A connection to the server that one thread at a time uses."""

    def __init__(self, endpoint: str, keys):
        self.client = Client(endpoint, keys=keys, timeout=REPLY)
        self.lock = threading.Lock()

    def request(self, op: str, args: dict | None = None, token: str | None = None):
        """The result; Refused with the server's code and message, or ``unreachable``."""
        with self.lock:
            self.client.token = token
            try:
                return self.client.request(op, args)
            except (ClientError, ProtocolError) as exc:
                raise Refused(exc.code, exc.message) from None

    def close(self) -> None:
        with self.lock:
            self.client.close()


class JogGate:
    """Which of one page's jog messages go on to the server. Each carries the page's
    sequence number and its send time (the page's monotonic clock, ms): a message older
    than one already sent on is dropped; a press or heartbeat also when a later message has
    come, or when it came more than STALE later than the quickest one from the page (its
    clock's offset from ours is not known, but it is the same on every message); a release
    always goes (it only stops)."""

    def __init__(self):
        self.lock = threading.Lock()
        self.received = -1  # the newest sequence number received
        self.sent = -1  # the newest sent on
        self.lag = math.inf  # the least (our receipt - the page's send time) seen: offset + quickest transport

    def receive(self, seq: int, page_ms: float, now_ms: float) -> None:
        with self.lock:
            self.received = max(self.received, seq)
            self.lag = min(self.lag, now_ms - page_ms)

    def admit(self, seq: int, page_ms: float, release: bool, now_ms: float) -> str | None:
        """None: send it on (and it is the newest sent); else why it is dropped."""
        with self.lock:
            if seq <= self.sent:
                return "a later message was sent on already"
            if not release:
                if seq < self.received:
                    return "a later message came"
                late = now_ms - page_ms - self.lag
                if late > STALE * 1000.0:
                    return f"it came {late:.0f} ms later than the page's quickest"
            self.sent = seq
            return None


@dataclass
class Held:
    """The jog button a page holds: its press (the page numbers them), the request, and
    when its last message came (monotonic ms)."""

    press: int
    request: dict
    last: float


class Messages:
    """What the pages show in their message lists, numbered (a page asks for those after
    the last it has): the program's prints and faults, and the pendant's notes."""

    def __init__(self):
        self.lock = threading.Lock()
        self.entries: deque = deque(maxlen=MESSAGES)
        self.count = 0

    def add(self, level: str, text: str) -> None:
        with self.lock:
            self.count += 1
            self.entries.append({"id": self.count, "at": time.strftime("%H:%M:%S"), "level": level, "text": text})

    def since(self, seen: int) -> list[dict]:
        with self.lock:
            return [e for e in self.entries if e["id"] > seen]


def _integer(args: dict, name: str, low: int, high: int, required: bool = True) -> int | None:
    value = args.get(name)
    if value is None and not required:
        return None
    if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
        raise Refused("bad_request", f"{name}: expected a whole number from {low} to {high}, got {str(value)[:40]!r}")
    return value


def _number(args: dict, name: str) -> float:
    value = args.get(name)
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
        raise Refused("bad_request", f"{name}: expected a number, got {str(value)[:40]!r}")
    return float(value)


def _text(args: dict, name: str, choices=None) -> str:
    value = args.get(name)
    if not isinstance(value, str) or (choices is not None and value not in choices):
        also = f" (one of {', '.join(choices)})" if choices is not None else ""
        raise Refused("bad_request", f"{name}: expected a name{also}, got {str(value)[:40]!r}")
    return value


class Session:
    """One page: its connections to the server, the control it holds (its name and
    token), its jog gate and the jog button it holds, and the times from a jog button's
    press and release to the request sent (ms: the page's pointer event to our send)."""

    def __init__(self, pendant: "Pendant", page: str):
        self.pendant, self.page = pendant, page
        self.commands = Link(pendant.endpoint, pendant.keys)
        self.reads = Link(pendant.endpoint, pendant.keys)
        self.name: str | None = None
        self.token: str | None = None
        self.gate = JogGate()
        self.jog_lock = threading.Lock()  # a jog message admitted and sent on before the next is looked at
        self.held: Held | None = None
        self.spent: int | None = None  # a press refused, or released for its silent page: it starts nothing again
        self.seen = time.monotonic()
        self.timings: dict[str, deque] = {"press": deque(maxlen=50), "release": deque(maxlen=50)}

    # ---- what the page asks ----------------------------------------------------------------
    def act(self, name: str, args: dict) -> dict:
        """Run action ``name``: the reply for the page (``ok``, and ``error`` when refused)."""
        self.seen = time.monotonic()
        if name not in ACTIONS:
            return {"ok": False, "error": f"no action {name[:40]!r}"}
        if ACTIONS[name] and self.token is None:
            return {"ok": False, "error": "this page does not hold control: take it first"}
        try:
            return {"ok": True, **getattr(self, f"act_{name}")(args)}
        except Refused as exc:
            return {"ok": False, "error": exc.message, "code": exc.code}

    def request(self, op: str, args: dict | None = None):
        return self.commands.request(op, args, self.token)

    def act_take(self, args: dict) -> dict:
        name = _text(args, "name").strip()
        if not 0 < len(name) <= MAX_NAME or not name.isprintable():
            raise Refused("bad_request", f"a name of 1 to {MAX_NAME} printable characters, please")
        reply = self.commands.request("control", {"take": True, "name": name, "lease": LEASE}, self.token)
        self.name, self.token = reply["name"], reply["token"]
        self.pendant.messages.add("INFO", f"control taken by {self.name} (the pendant)")
        return {"name": self.name}

    def act_release(self, args: dict) -> dict:
        if self.token is None:
            raise Refused("refused", "this page does not hold control")
        self.release_jog("control given back")
        self.request("control", {"take": False})
        self.token = None
        self.pendant.messages.add("INFO", f"control given back by {self.name} (the pendant)")
        return {}

    def act_mode(self, args: dict) -> dict:
        return self.request("mode", {"mode": _text(args, "mode", tuple(protocol.MODES))})

    def act_start(self, args: dict) -> dict:
        """A program of the directory, compiled and submitted with its source; ``step``: in
        step mode (each move waits for Step)."""
        name = _text(args, "program", self.pendant.programs())
        step = args.get("step", False)
        if not isinstance(step, bool):
            raise Refused("bad_request", f"step: expected true or false, got {str(step)[:40]!r}")
        data, source = self.pendant.compile(name)
        reply = self.request("submit", {"object": data, "name": name, **({"source": source} if source else {}),
                                        **({"step": True} if step else {})})
        return {"program": reply["program"], "queued": reply["queued"]}

    def _program_op(self, op: str, args: dict) -> dict:
        program = _integer(args, "program", 1, 2**62, required=False)
        return self.request(op, {"program": program} if program is not None else {})

    def act_pause(self, args: dict) -> dict:
        return self._program_op("pause", args)

    def act_resume(self, args: dict) -> dict:
        return self._program_op("resume", args)

    def act_step(self, args: dict) -> dict:
        return self._program_op("step", args)

    def act_abort(self, args: dict) -> dict:
        return self._program_op("abort", args)

    def act_override(self, args: dict) -> dict:
        percent = _number(args, "percent")
        if not 1.0 <= percent <= 100.0:
            raise Refused("bad_request", f"override: 1 to 100 %, got {percent:g}")
        return self.request("override", {"percent": percent})

    def act_input(self, args: dict) -> dict:
        n = _integer(args, "input", 1, self.pendant.spec.inputs)
        value = args.get("value")
        if not isinstance(value, bool):
            raise Refused("bad_request", f"value: expected true or false, got {str(value)[:40]!r}")
        return self.request("call", {"text": f"io.in[{n}] = {'true' if value else 'false'}"})

    def act_teach(self, args: dict) -> dict:
        status = self.reads.request("status", None, self.token)
        return self.pendant.teach(status.get("position") or [], args.get("tool"), args.get("base"))

    # ---- jogging -------------------------------------------------------------------------------
    def act_jog(self, args: dict) -> dict:
        request = self.pendant.jog_request(args)
        press = _integer(args, "press", 0, 2**53)
        seq = _integer(args, "seq", 0, 2**53)
        page_ms = _number(args, "t")
        event = args.get("at")  # (the pointer event's time, epoch ms: press and release only)
        now = _ms()
        self.gate.receive(seq, page_ms, now)
        release = request["direction"] == 0
        if not release and press == self.spent:  # (a jog never starts again by itself)
            raise Refused("refused", "this press of the button was refused or stopped: release the button and "
                                     "press it again")
        held = self.held
        if not release and held is not None and held.press == press:
            held.last = now  # (the page is there: said on receipt, whatever the server's answer waits on)
        with self.jog_lock:
            dropped = self.gate.admit(seq, page_ms, release, _ms())
            if dropped is not None:
                return {"dropped": dropped}
            held = self.held
            if release:
                self.held = None
            elif held is not None and held.press == press:
                held.last = max(held.last, now)
                if request.get("step") is not None:
                    return {"holding": True}  # (an increment's hold: sent on, it would start it again)
            else:
                self.held = Held(press, request, now)
            sent = time.time() * 1000.0
            try:
                reply = self.request("jog", request)
            except Refused as exc:
                if release or exc.code == "unreachable":
                    raise
                if self.held is not None and self.held.press == press:
                    self.held = None  # (nothing started)
                if protocol.JOG_SESSION_ENDING in exc.message:  # (the next message of the press tries again)
                    return {"again": exc.message}
                self.spent = press  # (nor will it by this press)
                raise
            if isinstance(event, (int, float)) and not isinstance(event, bool) and (release or held is None
                                                                                     or held.press != press):
                self.timings["release" if release else "press"].append(round(sent - float(event), 1))
        note = self.stop_homing() if release else None
        return {"jog": reply, **({"note": note} if note else {})}

    def release_jog(self, why: str, silent_for: float | None = None) -> None:
        """Release the jog button this page holds (the page is gone, or gives control back;
        ``silent_for``: only if no message of it came for that long, ms): the jog stops, and
        so does homing."""
        with self.jog_lock:
            held = self.held
            if held is None or (silent_for is not None and _ms() - held.last <= silent_for):
                return
            self.held, self.spent = None, held.press
            try:
                self.request("jog", {"axis": held.request["axis"], "direction": 0, "frame": held.request["frame"]})
            except Refused:
                pass  # (the server stops it by itself, its heartbeat gone)
        self.pendant.messages.add("WARNING", f"jog {held.request['axis']} released: {why}")
        note = self.stop_homing()
        if note:
            self.pendant.messages.add("WARNING", note)

    def stop_homing(self) -> str | None:
        """Abort the jog session while it is still starting (homing), as the button that
        started it is no longer held; the note that says so, or None."""
        try:
            running = self.reads.request("status", None, self.token).get("running")
            if not running or running.get("kind") != "jog" or str(running.get("fsm", "")).startswith("Move Robot"):
                return None
            self.request("abort", {"program": running["id"]})
        except Refused:
            return None
        return (f"the robot was still starting ({running.get('fsm')}): the jog session is aborted, as homing moves "
                "only while a jog button is held")

    # ---- what the page shows -------------------------------------------------------------------
    def state(self, since: int) -> dict:
        """The robot's status as the page shows it, and the messages after ``since``."""
        self.seen = time.monotonic()
        pendant = self.pendant
        reply: dict = {"ok": True, "messages": pendant.messages.since(since), "programs": pendant.programs(),
                       "timings": {k: list(v) for k, v in self.timings.items()}}
        try:
            status = self.reads.request("status", None, self.token)
        except Refused as exc:
            return {**reply, "connected": False, "error": exc.message}
        holder = status.get("control")
        if self.token is not None and holder != self.name:  # (its lease ran out: another may hold it now)
            self.token = None
            pendant.messages.add("WARNING", f"{self.name} (the pendant) lost control: its lease ran out")
        sample = pendant.latest() or {}
        running = status.get("running")
        return {**reply, "connected": True, "you": self.token is not None, "name": self.name, "control": holder,
                "mode": status.get("mode"), "state": status.get("state"), "override": status.get("override"),
                "position": status.get("position"), "inputs": status.get("inputs"), "outputs": status.get("outputs"),
                "jog": status.get("jog"), "queue": len(status.get("queue") or []),
                "initialized": status.get("initialized"), "calibrated": status.get("calibrated"),
                "loop_gone": status.get("loop_gone"), "shutting_down": status.get("shutting_down"),
                "running": _running(running) if running else None,
                "tcp": sample.get("tcp"), "tool": sample.get("tool"), "base": sample.get("base")}

    def close(self) -> None:
        """The page is gone: its jog released, its control given back, its connections closed."""
        self.release_jog("the page was closed")
        if self.token is not None:
            try:
                self.request("control", {"take": False})
                self.pendant.messages.add("INFO", f"control given back by {self.name} (the pendant was closed)")
            except Refused:
                pass
            self.token = None
        self.commands.close()
        self.reads.close()


def _running(running: dict) -> dict:
    """What the page shows of the running program."""
    return {key: running.get(key) for key in ("id", "name", "kind", "fsm", "line", "paused", "moves_done",
                                              "moves_total", "step", "waiting_for_step", "approach")}


class Pendant:
    """The pendant of the robot served at ``endpoint``, for the page on 127.0.0.1 from
    ``port`` (the next free one): ``hello`` the server's, ``spec`` its specification (read
    from ``spec_file``), ``programs`` the directory whose .irl files the page offers (None:
    none), ``view`` the 3D view's URL, ``latest()`` the latest telemetry sample."""

    def __init__(self, endpoint: str, keys, spec, spec_file: str, hello: dict, programs: Path | None, view: str,
                 port: int, latest=lambda: None):
        self.endpoint, self.keys, self.spec, self.spec_file = endpoint, keys, spec, spec_file
        self.hello, self.programs_dir, self.view, self.latest = hello, programs, view, latest
        self.messages = Messages()
        self.sessions: dict[str, Session] = {}
        self.lock = threading.Lock()
        self.estop_link = Link(endpoint, keys)
        self.key = secrets.token_urlsafe(18)
        post = {"session": self.open_session, "act": self.act, "estop": self.estop, "bye": self.bye}
        self.http = PageServer("127.0.0.1", port, self.key, PAGE.read_bytes(), {"state": self.state}, post)
        self._stop = threading.Event()
        self.watch = threading.Thread(target=self._watch, name="view-pendant-watch", daemon=True)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.http.port}/{self.key}/"

    def start(self) -> None:
        self.http.start()
        self.watch.start()

    # ---- the routes ------------------------------------------------------------------------------
    def open_session(self, body: dict) -> dict:
        """A new page: its id and what it shows (the robot, its axes, the choices)."""
        page = secrets.token_hex(8)
        with self.lock:
            oldest = min(self.sessions.values(), key=lambda s: s.seen) if len(self.sessions) >= MAX_SESSIONS else None
            if oldest is not None:
                del self.sessions[oldest.page]
            self.sessions[page] = Session(self, page)
        if oldest is not None:
            oldest.close()
        spec = self.spec
        return {"ok": True, "page": page, "robot": self.hello.get("robot"), "endpoint": self.endpoint,
                "clock": self.hello.get("clock"), "axes": [{"name": a.name, "unit": a.unit} for a in spec.axes],
                "cartesian": list(protocol.JOG_CARTESIAN), "frames": list(protocol.JOG_FRAMES),
                "increments": list(INCREMENTS), "heartbeat": protocol.JOG_HEARTBEAT, "poll": POLL,
                "inputs": spec.inputs, "outputs": spec.outputs, "modes": protocol.MODES,
                "programs_dir": str(self.programs_dir) if self.programs_dir is not None else None,
                "tools": frame_names(spec, "tool", "default_tool"), "bases": frame_names(spec, "frame", "world"),
                "view": self.view}

    def _session(self, args: dict) -> Session:
        page = args.get("page")
        session = self.sessions.get(page) if isinstance(page, str) else None
        if session is None:
            raise RouteError("this page's session has ended (the pendant was restarted, or the page was idle): "
                             "reload the page", 410)
        return session

    def state(self, query: dict) -> dict:
        since = query.get("since", "0")
        return self._session(query).state(int(since) if since.isdigit() else 0)

    def act(self, body: dict) -> dict:
        action = body.get("action")
        args = body.get("args") or {}
        if not isinstance(action, str) or not isinstance(args, dict):
            raise RouteError("expected {page, action, args}")
        return self._session(body).act(action, args)

    def estop(self, body: dict) -> dict:
        """The emergency stop, from any page, holding control or not."""
        try:
            reply = self.estop_link.request("estop")
        except Refused as exc:
            return {"ok": False, "error": f"EMERGENCY STOP NOT SENT: {exc.message}", "code": exc.code}
        self.messages.add("ERROR", "emergency stop (the pendant)"
                          + (f": program {reply['program']} stopped" if reply.get("program") else ""))
        return {"ok": True, **reply}

    def bye(self, body: dict) -> dict:
        """The page is going (closed, reloaded)."""
        page = body.get("page")
        with self.lock:
            session = self.sessions.pop(page, None) if isinstance(page, str) else None
        if session is not None:
            session.close()
        return {"ok": True}

    # ---- what the sessions share -----------------------------------------------------------------
    def programs(self) -> list[str]:
        """The .irl files the page offers (the names in the directory given)."""
        if self.programs_dir is None:
            return []
        try:
            return sorted(p.name for p in self.programs_dir.iterdir() if p.suffix == ".irl" and p.is_file())
        except OSError:
            return []

    def compile(self, name: str) -> tuple[bytes, str | None]:
        """A program of the directory compiled for the server's specification: its object
        code and its source; Refused with the diagnostics when it does not compile."""
        path = self.programs_dir / name
        try:
            result = compile_file(path, self.spec_file)
        except (OSError, UnicodeDecodeError) as exc:
            raise Refused("compile", f"cannot read {name}: {getattr(exc, 'strerror', None) or exc}") from None
        if not result.ok:
            count = sum(1 for d in result.diagnostics if d.severity == "error")
            raise Refused("compile", f"{name} does not compile ({count} error{'s' if count != 1 else ''}):\n"
                                     + render_all(result.diagnostics, result.source, result.sources))
        return encode(result.program), source_text(path)

    def jog_request(self, args: dict) -> dict:
        """A page's jog as the protocol's ``jog`` arguments (checked as the server does)."""
        axis = _text(args, "axis")
        direction = _integer(args, "direction", -1, 1)
        frame = _text(args, "frame", protocol.JOG_FRAMES)
        step = args.get("step")
        if step is not None:
            step = _number(args, "step")
        problem = protocol.jog_problem([a.name for a in self.spec.axes], axis, direction, frame, step)
        if problem is not None:
            raise Refused("bad_request", problem)
        return {"axis": axis, "direction": direction, "frame": frame, **({"step": step} if step is not None else {})}

    def teach(self, position: list, tool: str | None, base: str | None) -> dict:
        """The literals of ``position`` with the named tool in the named base."""
        try:
            tool_name, tool_values = named_frame(self.spec, "tool", tool if isinstance(tool, str) else None,
                                                 "default_tool")
            base_name, base_values = named_frame(self.spec, "frame", base if isinstance(base, str) else None, "world")
        except ValueError as exc:
            raise Refused("bad_request", str(exc)) from None
        if len(position) < len(self.spec.main_axes):
            raise Refused("refused", "the server reports no position of the main axes")
        found = where(self.spec, position, tool_values, base_values)
        taught = found.taught
        return {"joint": found.joint, "pose": taught.text if taught else None,
                "note": (f"tool {tool_name}, base {base_name}; {configuration_name(taught.config_id)}" if taught
                         else f"no pose literal: {found.problem}")}

    def event(self, entry: tuple) -> None:
        """A telemetry event the live view logged, (time, level, text)."""
        _t, level, text = entry
        self.messages.add(level, text)

    # ---- the watch -------------------------------------------------------------------------------
    def _watch(self) -> None:
        """Release the jog of a page that fell silent; close the sessions of pages long gone."""
        while not self._stop.wait(0.05):
            now, now_ms = time.monotonic(), _ms()
            for session in list(self.sessions.values()):
                held = session.held
                if held is not None and now_ms - held.last > STALE * 1000.0:
                    session.release_jog(f"no heartbeat from the page for {STALE:g} s", silent_for=STALE * 1000.0)
                if now - session.seen > SESSION_IDLE:
                    with self.lock:
                        gone = self.sessions.pop(session.page, None)
                    if gone is not None:
                        gone.close()

    def close(self) -> None:
        self._stop.set()
        if self.watch.is_alive():
            self.watch.join(timeout=2.0)
        with self.lock:
            sessions, self.sessions = list(self.sessions.values()), {}
        for session in sessions:
            session.close()
        self.estop_link.close()
        self.http.close()
