"""The client side of the protocol (docs/protocol.md): requests over a DEALER socket,
telemetry over a SUB socket. Used by the ``irl`` commands that talk to ``irl serve``."""
from __future__ import annotations

import itertools
from pathlib import Path

import zmq

from runtime.places import DEFAULT_ENDPOINT, DEFAULT_TELEMETRY  # noqa: F401 (DEFAULT_TELEMETRY: for clients)
from runtime.wire import protocol


def source_text(path: Path) -> str | None:
    """A program's source to send with it (``submit``'s ``source``, for viewers), when it is
    readable and not too large (a quarter of the largest request)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    return text if len(text.encode()) <= protocol.MAX_REQUEST_BYTES // 4 else None


class ClientError(Exception):
    """An error reply (``code`` from protocol.ERRORS), ``code="unreachable"`` when the
    server did not answer in time, or ``code="keys"`` for the client's own key files."""

    def __init__(self, code: str, message: str):
        super().__init__(message)
        self.code = code
        self.message = message


def _secure(sock, keys) -> None:
    """Make ``sock`` a CURVE client with the keys in ``keys``; a missing, unreadable or
    unprotected key file is a ClientError ``"keys"`` naming it (the socket closed)."""
    from runtime.wire.keys import KeyError_, client_security

    try:
        client_security(sock, keys)
    except KeyError_ as exc:
        sock.close()
        raise ClientError("keys", str(exc)) from None


class Client:
    def __init__(self, endpoint: str = DEFAULT_ENDPOINT, keys: str | Path | None = None, timeout: float = 5.0,
                 token: str | None = None):
        self.endpoint = endpoint
        self.timeout = timeout
        self.token = token  # a control token (protocol 2): sent with every request
        self.ctx = zmq.Context.instance()
        self.sock = self.ctx.socket(zmq.DEALER)
        self.sock.setsockopt(zmq.LINGER, 0)
        if keys:
            _secure(self.sock, keys)
        try:
            self.sock.connect(endpoint)
        except zmq.ZMQError as exc:
            self.sock.close()
            raise ClientError("unreachable", f"cannot connect to {endpoint}: {exc}") from None
        self._ids = itertools.count(1)

    def request(self, op: str, args: dict | None = None, timeout: float | None = None):
        """Send one request and return its result; ClientError for an error reply or no reply."""
        request_id = next(self._ids)
        self.sock.send(protocol.request(op, args, request_id, token=self.token))
        wait_ms = int(1000 * (self.timeout if timeout is None else timeout))
        while True:
            if not self.sock.poll(wait_ms, zmq.POLLIN):
                raise ClientError("unreachable", f"no reply from {self.endpoint} within {wait_ms / 1000:g} s "
                                                 "(is 'irl serve' running there, with the same --keys?)")
            reply = protocol.decode_reply(self.sock.recv())
            if reply.get("id") != request_id:
                continue  # the late reply to an earlier request that timed out
            if reply["ok"]:
                return reply.get("result")
            err = reply.get("error") or {}
            raise ClientError(str(err.get("code", "internal")), str(err.get("message", "unknown error")))

    def download(self, program: int, which: str, out: Path) -> int:
        """Write a program's report (``which``: one of protocol.REPORT_FILES) to ``out``; returns bytes."""
        offset = 0
        tmp = out.with_name(f".{out.name}.part")
        out.parent.mkdir(parents=True, exist_ok=True)
        with open(tmp, "wb") as f:
            while True:
                chunk = self.request("report", {"program": program, "file": which, "offset": offset})
                f.write(chunk["data"])
                offset += len(chunk["data"])
                if chunk["eof"] or not chunk["data"]:
                    break
        tmp.replace(out)
        return offset

    def close(self) -> None:
        self.sock.close(linger=0)


class Subscriber:
    """Telemetry: ``receive(timeout)`` returns the next message (a dict) or None. ``topic``:
    the full telemetry (default) or a feed's; ``missed`` counts the gaps in ``seq`` (in a
    feed's ``feed_seq``), and ``gap`` is the last message's (the ``telemetry`` request
    replays what it missed, from the server's history)."""

    def __init__(self, endpoint: str = DEFAULT_TELEMETRY, keys: str | Path | None = None,
                 topic: bytes = protocol.TELEMETRY_TOPIC):
        self.ctx = zmq.Context.instance()
        self.sock = self.ctx.socket(zmq.SUB)
        self.sock.setsockopt(zmq.LINGER, 0)
        if keys:
            _secure(self.sock, keys)
        self.topic = topic
        self.counter = "seq" if topic == protocol.TELEMETRY_TOPIC else "feed_seq"
        self.sock.setsockopt(zmq.SUBSCRIBE, topic)
        try:
            self.sock.connect(endpoint)
        except zmq.ZMQError as exc:
            self.sock.close()
            raise ClientError("unreachable", f"cannot connect to {endpoint}: {exc}") from None
        self.last_seq: int | None = None
        self.missed = 0
        self.gap: tuple[int, int] | None = None  # the last message's gap: (the seq before it, its seq), or None

    def receive(self, timeout: float) -> dict | None:
        if not self.sock.poll(int(timeout * 1000), zmq.POLLIN):
            return None
        frames = self.sock.recv_multipart()
        if len(frames) != 2 or frames[0] != self.topic:
            return None
        message = protocol.decode_telemetry(frames[1])
        if message is None or not isinstance(message.get(self.counter), int):
            return None
        seq = message[self.counter]
        self.gap = None
        if self.last_seq is not None and seq > self.last_seq + 1:
            self.missed += seq - self.last_seq - 1
            self.gap = (self.last_seq, seq)
        self.last_seq = seq
        return message

    def close(self) -> None:
        self.sock.close(linger=0)
