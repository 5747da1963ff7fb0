"""``irl view --endpoint E``: a served robot, live, read-only.

Attached to ``irl serve`` over the protocol (docs/protocol.md): it subscribes to the
telemetry and asks for nothing that needs control. Each time round it takes every message
that has come (so it never falls behind: the arm shows the latest sample, the events are
all shown), and poses the arm, marks the running program's line in its source (the
``source`` operation: the text the program was submitted with), and shows the phase, the
override, the I/O as lamps, the prints and faults. A server sends a message at least every
0.5 s: after :data:`SILENCE` seconds without one the page says the connection is lost (and
goes on as soon as messages come again).
"""
from __future__ import annotations

import collections
import html
import threading
import time

from compiler.frames import pose_of, values_of
from compiler.semantics import compose, inverse

from runtime.client.client import Client, ClientError, Subscriber
from runtime.motion.moves import Frames
from runtime.view.stage import Stage, lamps_html, log_html, source_html

#: Seconds without a telemetry message before the page says the connection is lost.
SILENCE = 2.0
#: The most times a second the arm is posed anew (a screen's frames: the page draws no
#: faster, and a browser sent more falls behind), and the text is rewritten.
POSES, TEXTS = 30.0, 5.0
#: Each line the program passes stays marked at least this long (s), however quickly the
#: next one comes, so that every one reaches the page (its updates go out at their pace);
#: at most MARKS_WAITING wait their turn (a program faster than that: the oldest skipped).
#: The page's box also names the last MARKS_WAITING lines shown (source_html's trail): a
#: transport that sends a page only the latest of several quick updates loses none.
MARK_HOLD, MARKS_WAITING = 0.25, 8
#: The most messages taken in one round (then the arm is posed and the page updated).
BATCH = 2000


def event_entry(message: dict) -> tuple[float, str, str] | None:
    """A telemetry event as the views log it: (the robot's time, level, text); None for
    one they do not log (the supervisor's transitions: the phase is shown)."""
    t = message.get("t")
    t = float(t) if isinstance(t, (int, float)) else 0.0
    event = message.get("event")
    if event == "log":
        return t, "INFO", f"line {message.get('line')}: {message.get('text', '')}"
    if event == "program" and message.get("fault"):
        return t, "ERROR", f"program {message.get('program')}: {message.get('fault')}"
    if event == "program":
        return t, "INFO", f"program {message.get('program')} {message.get('state')}"
    if event == "shutdown":
        return t, "WARNING", f"the server is shutting down: {message.get('reason', '')}"
    return None


class LiveView:
    """The robot served at ``endpoint`` (telemetry at ``telemetry``) on ``stage``."""

    def __init__(self, stage: Stage, endpoint: str, telemetry: str, keys=None):
        self.stage, self.endpoint, self.telemetry, self.keys = stage, endpoint, telemetry, keys
        gui = stage.server.gui
        self.status = gui.add_markdown(f"connecting to {html.escape(endpoint)} ...")
        self.now = gui.add_markdown("")
        self.lamps = gui.add_html(lamps_html([False] * stage.spec.inputs, [False] * stage.spec.outputs))
        self.log_box = gui.add_html(log_html([]))
        self.source_box = gui.add_html(source_html([], None))
        self.logs: list[tuple[float, str, str]] = []
        self.program: int | None = None
        self.lines: list[str] = []
        self.name: str | None = ""  # the running program's name (as submitted; None: not known yet)
        self.source_retry = 0.0  # when a source the server did not give in time is asked for again
        self.line = 0
        self.marks: collections.deque = collections.deque()  # (program, line) marks waiting their turn
        self.marked_at = -MARK_HOLD  # (monotonic s) when the source box last changed its mark
        self.shown = 0  # marks shown so far (their running count)
        self.trail: collections.deque = collections.deque(maxlen=MARKS_WAITING)  # (count, line, program): this program's marks shown
        self.samples = 0  # samples shown
        self.missed = 0  # telemetry messages the subscriber missed (sequence gaps)
        self.pending: dict | None = None  # the latest sample, not shown yet
        self.next_pose = 0.0  # (monotonic s) the arm is posed again from then on
        self.next_text = 0.0  # the text rewritten from then on
        self.io: tuple = ()  # the I/O the lamps show
        self.rate = 0.0  # samples shown per second, over the last second
        self.latest: dict | None = None  # the latest sample (the pendant reads its tool centre point)
        self.listeners: list = []  # called with each event logged, (time, level, text) (the pendant's messages)
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name="view-live", daemon=True)

    def start(self) -> None:
        self.thread.start()

    def _run(self) -> None:
        try:
            sub = Subscriber(self.telemetry, keys=self.keys)
            client = Client(self.endpoint, keys=self.keys, timeout=2.0)
        except ClientError as exc:
            self.status.content = f"**cannot connect**: {html.escape(exc.message)}"
            return
        try:
            self._follow(sub, client)
        finally:
            sub.close()
            client.close()

    def _follow(self, sub: Subscriber, client: Client) -> None:
        heard = time.monotonic()
        lost = False
        counted, since = 0, time.monotonic()
        while not self._stop.is_set():
            # (nobody looks while no page is connected: the first sample after one comes shows
            # everything, and the pendant alone costs no posing)
            looking = bool(self.stage.server.get_clients())
            wait = 0.1 if self.pending is None or not looking else \
                min(0.1, max(0.0, self.next_pose - time.monotonic()))
            message = sub.receive(wait)
            latest = None
            taken = 0
            while message is not None and taken < BATCH:
                taken += 1
                if sub.gap is not None and sub.counter == "seq":
                    self._recover(client, *sub.gap, looking)  # (what it missed first: a print is never lost)
                if message.get("kind") == "sample":
                    latest = message
                    if looking and (message.get("line") or 0) != self.line:
                        self._mark(message, client)  # every line the program passes, not only the posed ones'
                elif message.get("kind") == "event":
                    self._event(message)
                message = sub.receive(0.0)
            now = time.monotonic()
            if taken:
                heard = now
                if lost:
                    lost = False
            elif now - heard > SILENCE and not lost:
                self.next_text = now + SILENCE  # (the notice stays until messages come again)
                lost = True
                self.status.content = (f"**connection lost**: no telemetry from {html.escape(self.telemetry)} for "
                                       f"{SILENCE:g} s (is irl serve running?); waiting for it")
            if latest is not None:
                self.latest = latest
                self.missed = sub.missed
                self.pending = latest
            if self.pending is not None and now >= self.next_pose and looking:
                self._sample(self.pending, client, now)
                self.pending = None
                self.next_pose = now + 1.0 / POSES
                counted += 1
            if self.marks:
                self._show_mark(now)
            if now - since >= 1.0:
                self.rate, counted, since = counted / (now - since), 0, now

    def _recover(self, client: Client, after: int, before: int, looking: bool) -> None:
        """The events between telemetry ``seq`` ``after`` and ``before`` (a gap: the view
        fell behind and the sockets dropped them), from the server's history; and, while a
        page looks, the lines the missed samples passed (a short move's line is marked even
        when all its samples were dropped)."""
        since = after
        while since < before - 1:
            try:
                replay = client.request("telemetry", {"since": since})
            except ClientError:
                return  # (counted as missed all the same)
            messages = replay.get("messages") if isinstance(replay, dict) else None
            if not messages:
                return
            for message in messages:
                seq = message.get("seq")
                if not isinstance(seq, int) or seq >= before:
                    return
                since = seq
                if message.get("kind") == "event":
                    self._event(message)
                elif looking and message.get("kind") == "sample" and (message.get("line") or 0) != self.line:
                    self._mark(message, client)
            if not replay.get("more"):
                return

    def _event(self, message: dict) -> None:
        entry = event_entry(message)
        if entry is None:
            return
        self.logs.append(entry)
        self.log_box.content = log_html(self.logs)
        for listener in self.listeners:
            listener(entry)

    def _sample(self, sample: dict, client: Client, now: float) -> None:
        position = sample.get("position")
        if isinstance(position, list) and len(position) >= 6:
            self.stage.show(position, self._frames(sample), tcp=sample.get("tcp"))
        self.samples += 1
        line = self._mark(sample, client)
        inputs, outputs = sample.get("inputs"), sample.get("outputs")
        if isinstance(inputs, list) and isinstance(outputs, list) and (inputs, outputs) != self.io:
            self.io = (inputs, outputs)
            self.lamps.content = lamps_html(inputs, outputs)
        if now < self.next_text:
            return
        self.next_text = now + 1.0 / TEXTS
        self.status.content = (f"**live** from {html.escape(self.endpoint)}: the arm posed {self.rate:.0f} times/s"
                               + (f", {self.missed} telemetry messages missed" if self.missed else ""))
        paused = " (paused)" if sample.get("paused") else ""
        self.now.content = (f"**{float(sample.get('t', 0.0)):.3f} s** · {html.escape(str(sample.get('state')))}{paused}"
                            f" · override {float(sample.get('override', 100.0)):g} %"
                            f" · tool {html.escape(str(sample.get('tool', '')))}"
                            + (f" · line {line}" if line else ""))

    def _mark(self, sample: dict, client: Client) -> int:
        """The sample's program's source with its line marked, when either changed (a
        source the server did not give is asked for again, at most once a second); the line."""
        program = sample.get("program")
        now = time.monotonic()
        if program != self.program or (program is not None and self.name is None and now >= self.source_retry):
            self.program = program
            self.name, self.lines = self._source(client, program)
            if program is not None and self.name is None:  # (not answered in time: once more at once)
                self.name, self.lines = self._source(client, program)
            self.source_retry = now + 1.0
            self.line = -1
        line = sample.get("line") or 0
        if line != self.line:
            self.line = line
            self.marks.append((program, line or None))
            while len(self.marks) > MARKS_WAITING:
                self.marks.popleft()
            self._show_mark(now)
        return line

    def _show_mark(self, now: float) -> None:
        """The next mark waiting, once the one shown has been for MARK_HOLD: in its program's
        source as known now (a source that came late still marks the lines that waited)."""
        if now - self.marked_at >= MARK_HOLD:
            program, line = self.marks.popleft()
            lines = self.lines if program == self.program else []
            title = f"program {program}: {self.name or ''}" if program is not None else "no program running"
            if self.trail and self.trail[-1][2] != program:
                self.trail.clear()
            self.shown += 1
            self.trail.append((self.shown, line, program))
            self.source_box.content = source_html(lines, line, title, trail=[t[:2] for t in self.trail])
            self.marked_at = now

    def _frames(self, sample: dict) -> Frames | None:
        """The active base (its name; its pose from the TCP in the world and in the base)."""
        tcp, in_base = sample.get("tcp"), sample.get("tcp_base")
        if not (isinstance(tcp, list) and isinstance(in_base, list) and len(tcp) == len(in_base) == 6):
            return None
        base = values_of(compose(pose_of(tuple(tcp)), inverse(pose_of(tuple(in_base)))))
        return Frames(str(sample.get("base", "")), base, str(sample.get("tool", "")), tuple(self.stage.spec.tool))

    def _source(self, client: Client, program) -> tuple[str, list[str]]:
        """The program's name and the lines of its source (none: it came without); the
        name None when the server did not answer in time (asked again later)."""
        if program is None:
            return "", []
        try:
            reply = client.request("source", {"program": program})
        except ClientError as exc:
            return (None if exc.code == "unreachable" else ""), []
        if not isinstance(reply, dict):
            return "", []
        text = reply.get("source")
        return str(reply.get("name") or ""), text.splitlines() if isinstance(text, str) else []

    def close(self) -> None:
        self._stop.set()
        self.thread.join(timeout=2.0)
