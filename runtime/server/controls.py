"""Control of the robot (protocol 2, the ``control`` request; docs/protocol.md): one client
at a time may hold it, by the connection that took it (the identity the server gave it,
runtime.server.connections) or the token ``take`` returned, for a lease renewed by each of
its requests; while one holds it, the others may read, and estop.

Not real-time: this runs in the server's process.
"""
from __future__ import annotations

import hmac
import logging
import secrets
import time

from runtime.wire import protocol
from runtime.wire.protocol import ProtocolError

log = logging.getLogger("irl.serve")


class Control:
    """Control's holder (protocol 2, ``control``): the connection that took it (the
    identity the server gave it, runtime.server.connections), the token ``take`` returned, the
    name shown, the lease and the time of its last request."""

    __slots__ = ("connection", "token", "name", "lease", "last")

    def __init__(self, connection: str | None, token: str, name: str, lease: float):
        self.connection = connection
        self.token = token
        self.name = name
        self.lease = lease
        self.last = time.monotonic()

    def owns(self, connection: str | None, token: str | None) -> bool:
        """Whether a request from ``connection`` carrying ``token`` is the holder's (a
        connection without an identity is nobody's)."""
        if connection is not None and connection == self.connection:
            return True
        return token is not None and hmac.compare_digest(token.encode(), self.token.encode())


def reads_only(args: dict) -> bool:
    """Whether a ``call`` request only reads (anyone may send it while a client holds control)."""
    from runtime.wire.scripting import CallOperation, SetProperty, ScriptError, parse

    try:
        return not isinstance(parse(args["text"]), (SetProperty, CallOperation))
    except ScriptError:
        return True  # (answered with its script_error)


class Controls:
    """Who holds control (``holder``, None: nobody), and how many have taken it."""

    def __init__(self):
        self.holder: Control | None = None
        self.taken = 0  # (an unnamed holder is shown as "client #N")

    def held(self) -> Control | None:
        """Control's holder, once its lease is checked (it ends ``lease`` seconds after the
        holder's last request)."""
        holder = self.holder
        if holder is not None and time.monotonic() - holder.last > holder.lease:
            log.info("control of %s ended: no request from it for %g s", holder.name, holder.lease)
            self.holder = holder = None
        return holder

    def name(self) -> str | None:
        """The holder's name as status shows it, or None."""
        holder = self.held()
        return holder.name if holder is not None else None

    def check(self, connection: str | None, token: str | None, op: str, args: dict) -> bool:
        """Whether the request is control's holder's (it came on the connection that took
        control, or carries its token; then it renews the lease). Refuses a controlling
        request from anyone else while a client holds control."""
        holder = self.held()
        if holder is None:
            return False
        if holder.owns(connection, token):
            holder.last = time.monotonic()
            return True
        if op in protocol.CONTROLLING and not (op == "call" and reads_only(args)) or \
                (op == "control" and args.get("take")):
            left = holder.lease - (time.monotonic() - holder.last)
            stale = " (the token this request carries is not the holder's: a token is void once control is given " \
                    "back or its lease ends)" if token is not None else ""
            raise ProtocolError("refused", f"{holder.name} holds control of the robot (for {left:.1f} s more "
                                           f"without a request from it): this client may read, and estop{stale}")
        return False

    def request(self, args: dict, connection: str | None = None, holder: bool = False) -> dict:
        """``take: true``: this connection (and whoever sends the token returned) holds
        control; the holder taking it again changes its name and lease. ``take: false``:
        the holder gives it back (refused from another client while one holds it)."""
        current = self.held()
        if not args["take"]:
            if current is not None:
                if not holder:
                    raise ProtocolError("refused", f"{current.name} holds control of the robot, not this client: "
                                                   "only the holder (its connection, or a request with its token) "
                                                   "gives it back")
                log.info("control given back by %s", current.name)
                self.holder = None
            return {"control": False}
        lease = float(args.get("lease", protocol.DEFAULT_LEASE))
        if not protocol.MIN_LEASE <= lease <= protocol.MAX_LEASE:
            raise ProtocolError("bad_request", f"control: lease must be from {protocol.MIN_LEASE:g} to "
                                               f"{protocol.MAX_LEASE:g} s, got {lease:g}")
        if current is None:
            self.taken += 1
            name = str(args.get("name") or f"client #{self.taken}")[:100]
            current = self.holder = Control(connection, secrets.token_urlsafe(32), name, lease)
        else:  # the holder again (anyone else was refused): a new name or lease, the same token
            current.name = str(args.get("name") or current.name)[:100]
            current.lease = lease
            current.last = time.monotonic()
        log.info("control taken by %s (lease %g s)", current.name, lease)
        return {"control": True, "name": current.name, "lease": lease, "token": current.token}
