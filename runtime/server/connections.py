"""Who sent a request: an identity the server gives each connection (docs/protocol.md,
``control``).

A ROUTER socket names each connection by a routing id, but a client may choose its own
(ZMQ_ROUTING_ID) and libzmq's own are sequential: anyone could copy another client's.
So control is not bound to it. Instead the server answers ZeroMQ's authentication
handshake (ZAP, RFC 27) for every connection of its request socket, with CURVE or
without, and gives each connection a ``User-Id`` of its own: a random prefix, drawn once
per server, and a counter. libzmq attaches it to every message that arrives on that
connection; a client cannot set it (the handshake's metadata cannot override what ZAP
gave) nor guess the prefix (it is never sent to anyone).

With CURVE (``irl serve --keys``) the same handler checks the client's public key
against ``DIR/authorized`` (what pyzmq's authenticator did before), for the telemetry
socket too.

Not real-time: the server's process answers the handshakes in its own poll loop (no
thread), each at once.
"""
from __future__ import annotations

import secrets

import zmq
from zmq.utils import z85

#: ZAP's endpoint (fixed by RFC 27) and version; the domain the request socket asks ZAP for
#: (without a domain, libzmq skips ZAP for connections without CURVE).
ZAP_ENDPOINT, ZAP_VERSION, DOMAIN = "inproc://zeromq.zap.01", b"1.0", b"irl"


class Connections:
    """The ZAP handler of a server's context, and the connection a message came on."""

    def __init__(self, ctx: zmq.Context, authorized: frozenset[bytes] | None = None):
        self.authorized = authorized  # CURVE: the z85 public keys accepted; None: no CURVE
        self.prefix = secrets.token_hex(16)  # never shown: what makes the ids unforgeable
        self.count = 0
        self.socket = ctx.socket(zmq.REP)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.bind(ZAP_ENDPOINT)

    def protect(self, sock: zmq.Socket) -> None:
        """Make every connection of ``sock`` go through this handler (and get an identity)."""
        sock.setsockopt(zmq.ZAP_DOMAIN, DOMAIN)

    def answer(self, limit: int = 100) -> None:
        """Answer the handshakes waiting (never blocks)."""
        for _ in range(limit):
            try:
                request = self.socket.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return
            self.socket.send_multipart(self._reply(request))

    def _reply(self, request: list[bytes]) -> list[bytes]:
        if len(request) < 6 or request[0] != ZAP_VERSION:
            return [ZAP_VERSION, request[1] if len(request) > 1 else b"", b"400", b"malformed ZAP request", b"", b""]
        request_id, mechanism, credentials = request[1], request[5], request[6:]
        if self.authorized is not None:  # CURVE only, and only the authorized keys
            if mechanism != b"CURVE" or len(credentials) != 1 or \
                    z85.encode(credentials[0]) not in self.authorized:
                return [ZAP_VERSION, request_id, b"400", b"key not authorized", b"", b""]
        elif mechanism != b"NULL":
            return [ZAP_VERSION, request_id, b"400", b"unexpected security mechanism", b"", b""]
        self.count += 1
        return [ZAP_VERSION, request_id, b"200", b"OK", f"{self.prefix}:{self.count}".encode(), b""]

    def of(self, frame: zmq.Frame) -> str | None:
        """The identity of the connection ``frame`` (a received frame, ``copy=False``)
        came on; None when it has none this server gave (an ``inproc://`` connection has
        no handshake)."""
        try:
            user = frame.get("User-Id")
        except (zmq.ZMQError, UnicodeDecodeError):
            return None
        return user if isinstance(user, str) and user.startswith(self.prefix + ":") else None

    def close(self) -> None:
        self.socket.close(linger=0)
