"""A bounded, never-blocking message channel between the server and its real-time loop
process (see runtime/loop/robotloop.py and docs/runtime.md, "Process layout").

Each end of a ``socketpair`` (a Unix stream socket, non-blocking) carries msgpack
messages framed by a 4-byte length. The kernel's socket buffers are the shared memory:
they are bounded, need no lock the loop could wait on, keep every message whole and in
order, and wake a ``poll`` on the other side. (A ring buffer in ``multiprocessing``
shared memory would need memory barriers that Python cannot express; a datagram
socketpair queues only 10 messages on Linux.)

:meth:`Channel.send` never waits: what the socket will not take now is kept in the
sender's outbox (bounded by :data:`OUTBOX_BYTES`) and goes with the next send or
:meth:`Channel.flush`. A message marked ``droppable`` (a telemetry sample) is dropped,
and counted, rather than queued behind a backlog; any message that would overflow the
outbox is dropped and counted (``dropped``), never blocks.
"""
from __future__ import annotations

import select
import socket
import struct

import msgpack

__all__ = ["Channel", "ChannelClosed", "pair"]

#: Bytes a sender keeps for the socket when it is full (then messages are dropped, counted).
OUTBOX_BYTES = 8 << 20
#: The socket buffers asked for (the kernel may grant less: net.core.wmem_max).
SOCKET_BUFFER = 1 << 20
#: The largest message accepted (a summary of a long program is the largest).
MAX_MESSAGE = 64 << 20

_HEADER = struct.Struct("<I")


class ChannelClosed(Exception):
    """The other end is gone (its process ended)."""


class Channel:
    def __init__(self, sock: socket.socket):
        sock.setblocking(False)
        for option in (socket.SO_SNDBUF, socket.SO_RCVBUF):
            try:
                sock.setsockopt(socket.SOL_SOCKET, option, SOCKET_BUFFER)
            except OSError:
                pass
        self.sock = sock
        self._out = bytearray()
        self._in = bytearray()
        self.sent = 0
        self.dropped = 0
        self.closed = False

    def fileno(self) -> int:
        return self.sock.fileno()

    def send(self, message, droppable: bool = False) -> bool:
        """Queue ``message`` for the other side and send what the socket takes now; False
        (and ``dropped`` counts it) when it was dropped. Never waits."""
        if droppable and self._out:
            self.dropped += 1
            return False
        data = msgpack.packb(message, use_bin_type=True)
        if len(self._out) + len(data) + 4 > OUTBOX_BYTES:
            self.dropped += 1
            return False
        self._out += _HEADER.pack(len(data))
        self._out += data
        self.sent += 1
        self.flush()
        return True

    def flush(self) -> bool:
        """Send what the socket takes now; True when nothing is left waiting."""
        out = self._out
        while out:
            try:
                n = self.sock.send(out)
            except (BlockingIOError, InterruptedError):
                return False
            except OSError:  # the other end is gone: nothing more can be sent
                self.closed = True
                out.clear()
                return True
            del out[:n]
        return True

    @property
    def pending(self) -> int:
        """Bytes waiting in the outbox."""
        return len(self._out)

    def receive(self) -> list:
        """Every whole message that has arrived (possibly none). Raises ChannelClosed when
        the other end is gone and nothing is left to read."""
        while True:
            try:
                data = self.sock.recv(1 << 16)
            except (BlockingIOError, InterruptedError):
                break
            except ConnectionResetError:
                data = b""
            if not data:
                self.closed = True
                break
            self._in += data
        messages = []
        buf = self._in
        start = 0
        while len(buf) - start >= 4:
            (size,) = _HEADER.unpack_from(buf, start)
            if size > MAX_MESSAGE:
                raise ChannelClosed(f"a message of {size} bytes (the limit is {MAX_MESSAGE}): the stream is corrupt")
            if len(buf) - start - 4 < size:
                break
            messages.append(msgpack.unpackb(bytes(buf[start + 4:start + 4 + size]), raw=False))
            start += 4 + size
        if start:
            del buf[:start]
        if not messages and self.closed:
            raise ChannelClosed("the other end of the channel is closed")
        return messages

    def wait(self, timeout: float) -> bool:
        """Not real-time: wait up to ``timeout`` s for something to read."""
        if self._in and len(self._in) >= 4:
            return True
        readable, _, _ = select.select([self.sock], [], [], max(0.0, timeout))
        return bool(readable)

    def drain(self, timeout: float) -> bool:
        """Not real-time: wait up to ``timeout`` s for the outbox to empty."""
        import time

        deadline = time.monotonic() + timeout
        while not self.flush():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            select.select([], [self.sock], [], remaining)
        return True

    def close(self) -> None:
        self.sock.close()


def pair() -> tuple[Channel, Channel]:
    """Two connected ends."""
    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
    return Channel(a), Channel(b)
