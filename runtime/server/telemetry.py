"""The server's telemetry (docs/protocol.md, "Telemetry"): every message numbered
(``seq``), the recent ones kept for replay (the ``telemetry`` request), the last sample, the
subscribers' feeds (runtime.server.feeds) and the PUB socket they are published on.

Sends never block: a subscriber that stops reading loses messages, never slows anything.
Not real-time: this runs in the server's process.
"""
from __future__ import annotations

import collections
import itertools

import zmq

from runtime.server.feeds import Feeds
from runtime.server.looplink import LoopLink
from runtime.wire import protocol
from runtime.wire.protocol import ProtocolError


class Telemetry:
    """What the server publishes; ``link``: the loop, whose latest snapshot gives a
    message without a time of its own its time."""

    #: The most telemetry messages one ``telemetry`` reply carries (ask again from the last).
    REPLAY_CHUNK = 2000

    def __init__(self, link: LoopLink):
        self.seq = 0
        self.sent = 0
        self.history: collections.deque = collections.deque(maxlen=protocol.TELEMETRY_HISTORY)
        self.last_sample: dict | None = None
        self.feeds = Feeds()  # the subscribers' chosen fields and rates (the feed request)
        self.pub = None  # the XPUB socket, once bound (None: driven turn by turn, in-process)
        self.link = link

    def open(self, ctx: zmq.Context):
        """Make the publishing socket (a PUB that says which topics have subscribers: feeds)."""
        self.pub = ctx.socket(zmq.XPUB)
        return self.pub

    def bind(self, endpoint: str) -> None:
        """Bind the socket (raises zmq.ZMQError when taken)."""
        self.pub.setsockopt(zmq.SNDHWM, 1000)  # bounded: a slow subscriber loses messages
        self.pub.setsockopt(zmq.LINGER, 0)
        self.pub.bind(endpoint)

    def publish(self, message: dict) -> None:
        """Number, keep and publish a message (to every feed that wants it)."""
        self.seq += 1
        message["v"] = protocol.VERSION
        message["seq"] = self.seq
        message.setdefault("t", self.link.time())
        self.history.append(message)  # (for replay: the telemetry request)
        if message["kind"] == "sample":
            self.last_sample = message
        if self.pub is None:  # not bound (driven turn by turn, in-process)
            return
        try:
            self.pub.send_multipart((protocol.TELEMETRY_TOPIC, protocol.pack(message)), zmq.NOBLOCK)
            self.sent += 1
        except zmq.Again:
            pass
        for topic, fed in self.feeds.outgoing(message):
            try:
                self.pub.send_multipart((topic, protocol.pack(fed)), zmq.NOBLOCK)
            except zmq.Again:
                pass

    def publish_sample(self, job, queued: int, override: float) -> None:
        """A sample of the loop's latest snapshot: ``job`` the running one (or None),
        ``queued`` how many wait, at ``override`` percent."""
        snap = self.link.snapshot
        running = job is not None and snap.job == job.id
        sample = {"kind": "sample", "state": snap.state if running else "Idle",
                  "program": job.id if running else None, "queued": queued,
                  "override": override, "position": snap.position, "inputs": snap.inputs,
                  "outputs": snap.outputs, "t": snap.t,
                  "tool": snap.tool, "base": snap.base, "tcp": snap.tcp, "tcp_base": snap.tcp_base,
                  "mode": snap.mode, "jog": snap.jog if running else None}
        progress = snap.progress
        if running and progress is not None:
            sample.update(line=progress.line, moves_done=progress.moves_done, moves_total=job.moves_total,
                          paused=progress.paused, following_error=progress.following_error, step=progress.step,
                          waiting_for_step=progress.waiting_for_step, approach=progress.approach)
        self.publish(sample)

    def poll_subscriptions(self) -> None:
        """Which telemetry topics have subscribers (XPUB's subscription messages)."""
        for _ in range(1000):
            try:
                self.feeds.subscription(self.pub.recv(zmq.NOBLOCK))
            except zmq.ZMQError:  # (zmq.Again: none left)
                return

    def replay(self, since: int | None) -> dict:
        """The ``telemetry`` request: the latest seq and sample, and the messages after
        ``since`` still kept (at most REPLAY_CHUNK)."""
        result = {"seq": self.seq, "sample": self.last_sample}
        if since is not None:
            if not 0 <= since <= self.seq:
                raise ProtocolError("bad_request", f"telemetry: since must be a seq from 0 to the latest, "
                                                   f"{self.seq}, got {since}")
            history = self.history
            oldest = history[0]["seq"] if history else self.seq + 1
            start = max(since + 1, oldest)
            messages = [m for m in itertools.islice(history, start - oldest, None)][:self.REPLAY_CHUNK]
            result.update(messages=messages, missing=start - (since + 1),
                          more=bool(messages) and messages[-1]["seq"] < self.seq)
        return result
