"""The server's side of the real-time loop (docs/runtime.md, "Process layout"): the loop
process (or, in tests, the loop in this process), the channel to it, the commands waiting
to be forwarded, the ones sent and not yet answered (by reference), the loop's latest
snapshot, and the stopping of it.

Not real-time: this runs in the server's process. It never waits on the loop except where
a method says so (start-up, :meth:`LoopLink.ask`, :meth:`LoopLink.stop`).
"""
from __future__ import annotations

import collections
import logging
import time

from runtime.wire import messages, protocol
from runtime.wire.messages import EXIT_TIMEOUT, LOOP_MODULE, LoopOptions, Snapshot
from runtime.wire.protocol import ProtocolError

log = logging.getLogger("irl.serve")

LOOP_START_TIMEOUT = 30.0  # s the server waits for the loop process to be ready


class LoopCommand:
    """What an ``op_*`` handler returns for a request the loop must carry out: the
    command (runtime.wire.messages.COMMANDS); the loop's reply becomes the client's (through
    ``finish``, when given, for what the server adds to it)."""

    __slots__ = ("command", "finish", "failed", "version")

    def __init__(self, command: messages.Command, finish=None, failed=None):
        self.command = command
        self.finish = finish  # result -> the client's result (may raise ProtocolError)
        self.failed = failed  # called with the loop's refusal
        self.version = protocol.VERSION  # the request's protocol version (its reply's)


class LoopGone(Exception):
    """The loop process ended, or never became ready."""


class LoopRefused(LoopGone):
    """The loop process could not start with the options given (a cell scenario's or a
    PLC's file): the command line's error."""


def _loop_process(spec, options: LoopOptions, channel, servers_end) -> None:
    """The forked loop process: only here is the loop imported (the server's process has
    none of runtime.loop, runtime.motion, runtime.hardware)."""
    import importlib

    importlib.import_module(LOOP_MODULE).child(spec, options, channel, servers_end)


def start_process(spec, options: LoopOptions):
    """Fork the loop process; returns (process, the server's end of the channel). Call
    before the server starts any thread or ZeroMQ context (a fork copies only the caller)."""
    import multiprocessing

    from runtime.wire.channel import pair

    ours, theirs = pair()
    context = multiprocessing.get_context("fork")
    process = context.Process(target=_loop_process, args=(spec, options, theirs, ours), name="irl-loop", daemon=True)
    process.start()
    theirs.close()
    return process, ours


class LoopLink:
    """The loop, as the server reaches it. ``on_message(message)`` handles what the loop
    sends that a waiting method is not waiting for (snapshots, events, replies, summaries)."""

    def __init__(self, on_message):
        self.on_message = on_message
        self.loop = self.process = self.channel = None
        self.commands: collections.deque = collections.deque()  # (identity, request id, LoopCommand) to forward
        self.inbox: collections.deque = collections.deque()  # messages of an in-process loop
        self.pending: dict[int, tuple] = {}  # ref -> (identity, request id, LoopCommand) awaiting the loop
        self.ref = 0
        self.snapshot: Snapshot | None = None  # the loop's latest
        self.stopping = False  # the loop was told to stop the running program and end (shutdown)
        self.gone: str | None = None  # why the loop process ended (then no program runs)
        self.scheduling: str | None = None
        self.pid: int | None = None

    def start(self, spec, options: LoopOptions, in_process: bool) -> dict:
        """Start the loop (a process of its own, or ``in_process``: tests) and wait until it
        is ready; returns its ``ready`` message. Call before any ZeroMQ context exists."""
        if not in_process:
            self.process, self.channel = start_process(spec, options)
            ready = self._await("ready", LOOP_START_TIMEOUT)
        else:  # (tests: the loop in this process)
            import importlib

            self.loop = importlib.import_module(LOOP_MODULE).in_process(spec, options, self._from_loop)
            ready = self.loop.ready()
        self.snapshot = Snapshot.from_wire(ready["snapshot"])
        self.scheduling = ready["scheduling"]
        self.pid = ready["pid"]
        return ready

    @property
    def system(self):
        """The robot, when the loop runs in this process (tests); else AttributeError."""
        if self.loop is None:
            raise AttributeError("the loop runs in its own process: its system is not here")
        return self.loop.system

    def time(self) -> float:
        """The robot's clock at the loop's latest snapshot (0 before the first)."""
        return self.snapshot.t if self.snapshot is not None else 0.0

    def _from_loop(self, message: dict, droppable: bool = False) -> bool:
        self.inbox.append(message)
        return True

    def send(self, command: LoopCommand, identity=None, request_id=None) -> int:
        """Send a command to the loop; returns its reference (its reply's)."""
        self.ref += 1
        self.pending[self.ref] = (identity, request_id, command)
        message = command.command.to_wire(self.ref)
        if self.loop is not None:
            self.loop.commands.append(message)
        else:
            self.channel.send(message)
        return self.ref

    def forward(self) -> None:
        """Send the commands the requests asked for (``commands``)."""
        while self.commands:
            identity, request_id, command = self.commands.popleft()
            self.send(command, identity, request_id)

    def exit(self, reason: str) -> None:
        """Tell the loop to stop the running program on its path and end: it makes that
        an emergency stop if the robot is not at rest within EXIT_TIMEOUT."""
        self.stopping = True
        self.send(LoopCommand(messages.Exit(reason)))

    def receive(self) -> list:
        """What the loop has sent since (without waiting); LoopGone once its process ended."""
        if self.loop is not None:
            received = list(self.inbox)
            self.inbox.clear()
            return received
        from runtime.wire.channel import ChannelClosed

        try:
            return self.channel.receive()
        except ChannelClosed:
            raise LoopGone(self._gone_reason()) from None

    def answered(self, ref: int):
        """The request a reply of the loop answers, ``(identity, request id, LoopCommand)``
        (no longer pending), or None."""
        return self.pending.pop(ref, None)

    def fail(self, reason: str) -> list:
        """The loop process has ended: the requests it will never answer (no longer pending)."""
        self.gone = reason
        unanswered = list(self.pending.values())
        self.pending.clear()
        return unanswered

    def turn(self) -> None:
        """One turn of the loop in this process (tests)."""
        self.loop.turn()

    def _gone_reason(self) -> str:
        process = self.process  # (kept until stop has joined it: a LoopGone may be raised meanwhile)
        process.join(1.0)
        code = process.exitcode
        how = "still running" if code is None else (f"killed by signal {-code}" if code < 0 else f"exit status {code}")
        return f"the real-time loop process ({process.pid}) ended unexpectedly ({how})"

    def _wait(self, timeout: float) -> None:
        if self.loop is not None:
            self.loop.turn()
        else:
            self.channel.wait(timeout)

    def _await(self, kind: str, timeout: float) -> dict:
        """Not real-time: wait for the loop's next message of ``kind`` (handling the others)."""
        deadline = time.monotonic() + timeout
        while True:
            for message in self.receive():
                if message["kind"] == "failed":
                    if message.get("usage"):
                        raise LoopRefused(message["error"])
                    raise LoopGone(f"the real-time loop could not start: {message['error']}")
                if message["kind"] == kind:
                    return message
                self.on_message(message)
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise LoopGone(f"the real-time loop sent no {kind!r} within {timeout:g} s")
            self._wait(min(remaining, 0.1))

    def ask(self, command: LoopCommand, timeout: float = LOOP_START_TIMEOUT):
        """Not real-time: one command and its result (ProtocolError when refused)."""
        ref = self.send(command)
        deadline = time.monotonic() + timeout
        while ref in self.pending:
            for message in self.receive():
                if message["kind"] == "reply" and message["ref"] == ref:
                    self.pending.pop(ref)
                    if not message["ok"]:
                        if command.failed is not None:
                            command.failed(message)
                        raise ProtocolError(message["code"], message["message"])
                    result = message["result"]
                    return command.finish(result) if command.finish is not None else result
                self.on_message(message)
            if time.monotonic() > deadline:
                raise LoopGone(f"the real-time loop did not answer {command.command.OP!r} within {timeout:g} s")
            self._wait(0.1)

    def stop(self, reason: str) -> None:
        """End the loop process (it brings the robot to rest first). A loop already told
        to exit by the shutdown (``stopping``) is ending on its own: it is not asked
        again (it may have closed its end of the channel already), only waited for."""
        process = self.process
        if process is None:
            return
        if process.is_alive():
            if not self.stopping:
                self.stopping = True
                try:
                    self.ask(LoopCommand(messages.Exit(reason)), timeout=5.0)
                except (LoopGone, ProtocolError):
                    pass  # it ended meanwhile, or it refused: the join below says
            process.join(EXIT_TIMEOUT + 5.0)
            if process.is_alive():
                log.error("the loop process %d did not end: terminated", process.pid)
                process.kill()
                process.join(1.0)
        self.process = None
        self.channel.close()
