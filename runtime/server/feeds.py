"""Telemetry feeds (protocol 2, the ``feed`` request): a subscriber chooses some sample
fields and a rate, as RTDE's output recipes do, and gets them on a topic of its own.

The server publishes on an XPUB socket, which tells it which topics have subscribers (the
first subscription to a topic and the last unsubscription, a disconnect included). A feed
is encoded and sent only while its topic has one; a feed nobody has subscribed to for
``protocol.FEED_IDLE`` seconds is forgotten, so the table stays bounded
(``protocol.MAX_FEEDS``). Identical requests share one feed (and one topic).

Not real-time: this runs in the server's process, never in the loop's.
"""
from __future__ import annotations

import hashlib
import math
import time

from compiler.diagnostics import did_you_mean

from runtime.wire import protocol
from runtime.wire.protocol import ProtocolError
from runtime.timing import REPORT_PERIOD


class Feed:
    __slots__ = ("topic", "fields", "rate", "events", "count", "last_t", "last_wall", "idle_since")

    def __init__(self, topic: bytes, fields: tuple[str, ...], rate: float, events: bool):
        self.topic = topic
        self.fields = fields
        self.rate = rate
        self.events = events
        self.count = 0  # messages sent: each carries its number (``feed_seq``), a gap is a loss
        self.last_t = -math.inf  # the robot's clock at the last sample sent (a program running)
        self.last_wall = -math.inf  # the wall clock at the last sample sent while idle
        self.idle_since = time.monotonic()  # without a subscriber since (None: subscribed)

    def wants(self, message: dict) -> bool:
        """Whether this feed sends ``message`` (a telemetry sample or event), by its rate:
        at most ``rate`` samples per second of the robot's clock while a program runs, and
        per second of wall time while idle (the robot's clock stands still then)."""
        if message["kind"] != "sample":
            return self.events
        period = 1.0 / self.rate
        if message.get("program") is None:
            now = time.monotonic()
            if now - self.last_wall < period - 0.25:  # idle samples come every 0.5 s at most
                return False
            self.last_wall = now
            return True
        t = message["t"]
        if self.last_t <= t < self.last_t + period - REPORT_PERIOD / 2:  # (half a sample's period of slack)
            return False
        self.last_t = t
        return True

    def message(self, message: dict) -> dict:
        self.count += 1
        head = {"v": message["v"], "seq": message["seq"], "feed_seq": self.count, "t": message["t"],
                "kind": message["kind"]}
        if message["kind"] != "sample":
            return {**message, **head}
        head.update((name, message[name]) for name in self.fields if name in message)
        return head

    def as_dict(self) -> dict:
        return {"topic": self.topic.decode(), "fields": list(self.fields), "rate": self.rate, "events": self.events}


class Feeds:
    """The server's feeds and which telemetry topics have subscribers."""

    def __init__(self):
        self.feeds: dict[bytes, Feed] = {}
        self.subscribed: set[bytes] = set()  # topics with at least one subscriber (from XPUB)

    def request(self, args: dict) -> dict:
        """The ``feed`` request: a feed for ``fields`` at ``rate`` (made, or the same one
        again); ProtocolError ``bad_request`` naming what is wrong, ``refused`` when full."""
        fields = args["fields"]
        names = protocol.SAMPLE_FIELDS
        if not fields or not all(isinstance(f, str) for f in fields):
            raise ProtocolError("bad_request", "feed: fields must be a non-empty array of field names (strings): "
                                               + ", ".join(names))
        unknown = [f for f in fields if f not in names]
        if unknown:
            close = did_you_mean(unknown[0], names)
            raise ProtocolError("bad_request", f"feed: no sample field {unknown[0][:64]!r}"
                                + (f" (did you mean {close!r}?)" if close else "")
                                + "; the fields: " + ", ".join(names))
        rate = float(args.get("rate", protocol.MAX_FEED_RATE))
        if not protocol.MIN_FEED_RATE <= rate <= protocol.MAX_FEED_RATE:
            raise ProtocolError("bad_request", f"feed: rate must be from {protocol.MIN_FEED_RATE:g} to "
                                               f"{protocol.MAX_FEED_RATE:g} samples per second, got {rate:g}")
        chosen = tuple(name for name in names if name in fields)  # the table's order, once each
        events = bool(args.get("events", False))
        key = f"{','.join(chosen)}|{rate!r}|{events}".encode()
        topic = b"feed:" + hashlib.sha1(key).hexdigest()[:16].encode()
        feed = self.feeds.get(topic)
        if feed is None:
            self._forget_idle()
            if len(self.feeds) >= protocol.MAX_FEEDS:
                raise ProtocolError("refused", f"feed: the server already keeps {protocol.MAX_FEEDS} feeds with "
                                               "subscribers; use one of theirs (the same fields, rate and events "
                                               "give the same topic) or the full telemetry topic")
            feed = self.feeds[topic] = Feed(topic, chosen, rate, events)
            if topic in self.subscribed:  # subscribed before it was asked for (a client that reconnected)
                feed.idle_since = None
        return feed.as_dict()

    def _forget_idle(self) -> None:
        now = time.monotonic()
        for topic, feed in list(self.feeds.items()):
            if feed.idle_since is not None and now - feed.idle_since > protocol.FEED_IDLE:
                del self.feeds[topic]

    def subscription(self, frame: bytes) -> None:
        """An XPUB subscription message: ``\\x01topic`` (the first subscriber) or
        ``\\x00topic`` (the last one left)."""
        if not frame:
            return
        topic, subscribed = bytes(frame[1:]), frame[0] == 1
        feed = self.feeds.get(topic)
        if subscribed:
            self.subscribed.add(topic)
            if feed is not None:
                feed.idle_since = None
        else:
            self.subscribed.discard(topic)
            if feed is not None:
                feed.idle_since = time.monotonic()

    def outgoing(self, message: dict):
        """``(topic, message)`` for every subscribed feed that sends ``message``."""
        for topic, feed in self.feeds.items():
            if feed.idle_since is None and feed.wants(message):
                yield topic, feed.message(message)
