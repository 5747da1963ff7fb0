"""``irl serve``: one robot on the network (see docs/protocol.md).

Two processes (docs/runtime.md, "Process layout"). The **loop process**
(runtime/loop/robotloop.py) owns the robot: the executive, the components, the supervisor, the
robot interface, the report files. It runs one cycle of the supervisor at a time (Start
Robot ... Stop Robot; calibration and initialization are remembered) when the server
says ``start``, applies the operator commands forwarded to it between ticks (a bounded
number per tick), and sends back replies, telemetry events, a snapshot of the robot
every 10 ms and each cycle's summary. It asks for real-time scheduling for itself.

The **server** process owns the network and everything that is not real-time: the ROUTER
socket (it decodes and checks every request, answers the ones that only read, hello,
status, report chunks, from the loop's latest snapshot and its own job table, and
verifies submitted object code), the program queue, the configuration file, and the
telemetry PUB socket (it encodes and publishes what the loop sent; non-blocking sends
with a bounded queue: a subscriber that stops reading loses messages, never slows
anything). The two exchange messages through a :class:`~runtime.wire.channel.Channel` that the
loop never waits on. Nothing a client sends can raise into the loop: a bad request gets
an error reply and the server keeps serving; a flood of requests costs the server's
time, not the loop's.

``Server`` keeps the sockets and the ``op_*`` handlers (one per operation of
runtime.wire.protocol.OPS) and delegates to its parts: :class:`~runtime.server.looplink.LoopLink`
(the loop), :class:`~runtime.server.jobs.Jobs` (the programs),
:class:`~runtime.server.controls.Controls` (control) and
:class:`~runtime.server.telemetry.Telemetry` (what is published).

Tests drive the same server with the loop in-process (``ServeOptions(loop_process=False)``),
turn by turn: one turn is one tick.
"""
from __future__ import annotations

import collections
import logging
import os
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import zmq

from compiler.objcode import ObjectCodeError, from_line_problem, load, spec_mismatch

from runtime.config import merge_settings
from runtime.places import DEFAULT_ENDPOINT, DEFAULT_TELEMETRY, default_state_dir
from runtime.server.controls import Controls
from runtime.server.jobs import Jobs, Wait
from runtime.server.looplink import LoopCommand, LoopGone, LoopLink, LoopRefused
from runtime.server.telemetry import Telemetry
from runtime.wire import messages, protocol
from runtime.wire.messages import LoopOptions, Snapshot
from runtime.wire.protocol import ProtocolError

log = logging.getLogger("irl.serve")

CLOSE_LINGER_MS = 1000  # ms a closing server gives its last replies and telemetry to reach connected peers


@dataclass
class ServeOptions:
    endpoint: str = DEFAULT_ENDPOINT
    telemetry: str = DEFAULT_TELEMETRY
    state_dir: str | Path | None = None
    sim_clock: bool = False
    seed: int = 0
    keys: str | Path | None = None  # CURVE key directory (see runtime.wire.keys)
    #: Bind endpoints other machines can reach without CURVE keys (see check_endpoints).
    allow_insecure_remote: bool = False
    #: The servo's deadline policy ("hard", "firm", "soft"); None: the specification's.
    deadline_policy: str | None = None
    #: Real-time scheduling for the loop process (wall clock only): a runtime.scheduling.Scheduling;
    #: None: runtime.scheduling.DEFAULT (SCHED_FIFO, memory locked, where the host permits it).
    scheduling: object = None
    #: The loop in a process of its own (False: in this one, driven by ``Server.turn``: tests).
    loop_process: bool = True
    #: The file of what the simulated cell does with the I/O (--cell-scenario), or None: read by the loop.
    cell: str | Path | None = None
    #: The file of the I/O on a PLC (--fieldbus), or None: read by the loop.
    fieldbus: str | Path | None = None
    #: The directory of the programs' recordings (--record DIR: one MCAP file per program), or None.
    record: str | Path | None = None
    #: The operating mode the robot starts in (runtime.wire.protocol.MODES; --mode).
    mode: str = "aut"


INSECURE_FLAG = "--insecure-allow-remote-without-encryption"


class InsecureEndpoint(Exception):
    """An endpoint reachable from other machines, without CURVE keys and without the
    explicit permission (:data:`INSECURE_FLAG`)."""


def is_local_endpoint(endpoint: str) -> bool:
    """Whether only this machine can connect to a ZeroMQ endpoint bound here:
    ``ipc://`` and ``inproc://``, and ``tcp://`` (or ``ws://``) on a loopback address
    (127.0.0.0/8, ::1, ``localhost``). Anything else is taken as reachable from the
    network: ``*``, 0.0.0.0, ::, another address, a host or interface name (``eth0``),
    and the other transports (pgm, epgm, udp, tipc, vmci...)."""
    import ipaddress

    scheme, sep, rest = endpoint.partition("://")
    scheme = scheme.lower()
    if not sep:
        return False
    if scheme in ("ipc", "inproc"):
        return True
    if scheme not in ("tcp", "ws", "wss"):
        return False
    address = rest.split("/", 1)[0]  # ws://host:port/path
    host, sep, _port = address.rpartition(":")
    if not sep or not host:
        return False
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if host.lower() == "localhost":
        return True
    try:
        ip = ipaddress.ip_address(host)
    except ValueError:
        return False  # a host or interface name: it may well face the network
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        ip = ip.ipv4_mapped
    return ip.is_loopback


def check_endpoints(options: ServeOptions) -> None:
    """Refuse (InsecureEndpoint, with what to do) to serve the robot unencrypted and
    unauthenticated on an endpoint other machines can reach, unless asked explicitly."""
    if options.keys or options.allow_insecure_remote:
        return
    for what, endpoint in (("request", options.endpoint), ("telemetry", options.telemetry)):
        if not is_local_endpoint(endpoint):
            raise InsecureEndpoint(
                f"refusing to bind the {what} endpoint {endpoint} without CURVE keys: other machines can reach "
                f"it (only loopback, 127.0.0.0/8, ::1 or localhost, and ipc:// are local), so anyone on the "
                f"network could "
                + ("submit programs to the robot, move it and change its settings"
                   if what == "request" else "watch the robot's telemetry")
                + f". Give --keys DIR (make them with 'irl keys DIR') to require authenticated, encrypted "
                  f"clients, or, on a network you trust completely, {INSECURE_FLAG}")


class Server:
    def __init__(self, spec, options: ServeOptions, configurations=None):
        self.spec = spec
        # the specification's file as a client on this host can name it (messages)
        self.spec_file = os.path.abspath(spec.file) if os.path.isfile(spec.file) else spec.file
        self.options = options
        state_dir = Path(options.state_dir) if options.state_dir else default_state_dir()
        self.state_dir = state_dir
        session = time.strftime("%Y%m%d-%H%M%S") + f"-{os.getpid()}"
        self.override = 100.0
        self.outbox: collections.deque = collections.deque()  # (identity, reply bytes) when no socket is bound
        self.stop_reason: str | None = None
        self.controls = Controls()  # control's holder (protocol 2)
        self.link = LoopLink(self._on_loop)
        self.telemetry = Telemetry(self.link)
        self.jobs = Jobs(state_dir / "reports" / session, self.link, self.telemetry.publish, self._reply,
                         Path(os.path.abspath(options.record)) if options.record else None, session)
        self.router = self.connections = None
        loop_options = LoopOptions(seed=options.seed, realtime=not options.sim_clock, state_dir=state_dir,
                                   deadline_policy=options.deadline_policy, cell=options.cell,
                                   fieldbus=options.fieldbus, scheduling=options.scheduling, mode=options.mode)
        # the loop first: the fork copies only this thread, before any ZeroMQ context exists
        ready = self.link.start(spec, loop_options, in_process=not options.loop_process)
        self.baseline = ready["baseline"]  # what a configuration's missing keys fall back to
        self.configurations = configurations
        self.configuration = None
        if configurations is not None:
            from runtime.config import validate_settings

            self.configuration = configurations.default
            try:
                settings = validate_settings(merge_settings(self.baseline,
                                                            configurations[configurations.default].settings),
                                             f"configuration {configurations.default!r} over the start-up settings")
                self.link.ask(LoopCommand(messages.Settings(settings)))
            except BaseException:
                self.link.stop(self.stop_reason or "the server is closing")
                raise
        self.ctx = zmq.Context()

    @property
    def system(self):
        """The robot, when the loop runs in this process (tests); else AttributeError."""
        return self.link.system

    # ---- the loop -------------------------------------------------------------------------
    def request(self, op: str, args: dict | None = None):
        """Not real-time (tests, tools): one request's result, a loop command carried out
        and waited for; raises ProtocolError when refused."""
        result = getattr(self, f"op_{op}")(args or {})
        return self.link.ask(result) if isinstance(result, LoopCommand) else result

    def _on_loop(self, message: dict) -> None:
        kind = message["kind"]
        if kind == Snapshot.KIND:
            self.link.snapshot = Snapshot.from_wire(message)
            self.telemetry.publish_sample(self.jobs.current, len(self.jobs.queue), self.override)
        elif kind == "reply":
            self._on_reply(message)
        elif kind == "event":
            del message["kind"]
            self.telemetry.publish({"kind": "event", **message})
        elif kind == "finished":
            self.jobs.finish(message, self._completed)

    def _on_reply(self, message: dict) -> None:
        entry = self.link.answered(message["ref"])
        if entry is None:
            return
        identity, request_id, command = entry
        if message["ok"]:
            result = message["result"]
            try:
                if command.finish is not None:
                    result = command.finish(result)
                reply = protocol.ok(request_id, result, command.version)
            except ProtocolError as exc:
                reply = protocol.error(request_id, exc.code, exc.message, command.version)
        else:
            if command.failed is not None:
                command.failed(message)
            reply = protocol.error(request_id, message["code"], message["message"], command.version)
        if identity is not None:
            self._reply(identity, reply)

    def _dispatch(self) -> bool:
        """Start the next program when the loop is free; bring the shutdown along. False
        once a shutdown is done (the robot at rest, no program running)."""
        if self.stop_reason is not None and self.jobs.queue:  # a shutdown: what waits will never run
            self.jobs.cancel_queue(f"cancelled: {self.stop_reason}")
        if self.jobs.current is None:
            if self.stop_reason is not None:
                return False
            if self.jobs.queue and self.link.gone is None:
                self.jobs.start_next(self.override)
        elif self.stop_reason is not None and not self.link.stopping:
            self.link.exit(self.stop_reason)
        return True

    def turn(self, idle_wait: bool = True) -> bool:
        """With the loop in this process: one turn of it (the forwarded commands, then one
        tick of the running program, or of the next one started), and what it sent
        handled. False once a shutdown is done. Tests drive the server turn by turn (no
        sockets: they call the ``op_*`` handlers and read ``outbox``)."""
        if not self._dispatch():
            return False
        self.link.forward()
        self.link.turn()
        for message in self.link.receive():
            self._on_loop(message)
        self.jobs.answer_waiters()
        return True

    def request_shutdown(self, reason: str = "the server is shutting down") -> None:
        """Safe from a signal handler: stop after bringing the robot to rest."""
        if self.stop_reason is None:
            self.stop_reason = reason

    def _completed(self, job) -> None:
        """A job has ended without a fault: a reconfiguration's configuration is in force."""
        if job.configuration is not None:
            self.configuration = job.configuration

    # ---- sockets and the server's own loop ------------------------------------------------
    def bind(self) -> None:
        """Bind the request and telemetry sockets (raises zmq.ZMQError when taken)."""
        check_endpoints(self.options)
        from runtime.server.connections import Connections

        ctx = self.ctx
        self.router = ctx.socket(zmq.ROUTER)
        pub = self.telemetry.open(ctx)
        authorized = None
        if self.options.keys:
            from runtime.wire.keys import server_security

            authorized = server_security(self.options.keys, (self.router, pub))
        # every connection's handshake is answered here: each gets an identity of its own
        # (control is bound to it, not to a routing id a client can choose; and with CURVE,
        # only the authorized keys connect)
        self.connections = Connections(ctx, authorized)
        self.connections.protect(self.router)
        if authorized is not None:
            self.connections.protect(pub)
        self.router.setsockopt(zmq.MAXMSGSIZE, protocol.TRANSPORT_MAX_BYTES)
        self.router.setsockopt(zmq.LINGER, 0)
        # handover: a connection with a routing id another one has takes it over (libzmq closes
        # the older one); without it libzmq ignores the newer connection for good when the older
        # one has not closed yet (a client that reconnects at once would be locked out, and
        # anyone could squat on a client's id). Control does not depend on routing ids.
        self.router.setsockopt(zmq.ROUTER_HANDOVER, 1)
        self.router.setsockopt(zmq.SNDHWM, 10_000)
        self.router.bind(self.options.endpoint)
        self.telemetry.bind(self.options.telemetry)

    def close(self) -> None:
        self.link.stop(self.stop_reason or "the server is closing")
        for sock in (self.router, self.telemetry.pub):
            if sock is not None:  # the last replies and events (the queue cancelled, the shutdown) still go out
                sock.close(linger=CLOSE_LINGER_MS)
        if self.connections is not None:
            self.connections.close()
        self.ctx.term()

    def serve(self) -> int:
        """Run until a shutdown is requested (``request_shutdown``) and the robot is at
        rest; returns the exit status."""
        if self.link.loop is not None:  # the loop in this process (a debugging layout): one thread does all
            while self.turn():
                self._poll_requests(0)
            self.telemetry.publish({"kind": "event", "event": "shutdown", "reason": self.stop_reason})
            return 0
        log.info("loop: %s (process %d)", self.link.scheduling or "simulated clock", self.link.pid)
        poller = zmq.Poller()
        poller.register(self.router, zmq.POLLIN)
        poller.register(self.link.channel.fileno(), zmq.POLLIN)
        poller.register(self.telemetry.pub, zmq.POLLIN)
        poller.register(self.connections.socket, zmq.POLLIN)
        while self._dispatch():
            if self.link.gone is not None:  # keep answering (status says why), refuse work
                self._poll_requests(200, poller)
                continue
            try:
                self.link.forward()
                self._poll_requests(5 if self.link.channel.pending else (50 if self.jobs.waiters else 200), poller)
                for message in self.link.receive():
                    self._on_loop(message)
                self.link.channel.flush()
                self.jobs.answer_waiters()
            except LoopGone as exc:
                log.error("%s: the server answers requests but runs no program; restart it", exc)
                poller.unregister(self.link.channel.fileno())
                self._fail_all(str(exc))
        self.telemetry.publish({"kind": "event", "event": "shutdown", "reason": self.stop_reason})
        return 1 if self.link.gone is not None else 0

    def _poll_requests(self, timeout: int, poller=None) -> None:
        if poller is not None:
            events = dict(poller.poll(timeout))
            if self.connections.socket in events:
                self.connections.answer()
            if self.telemetry.pub in events:
                self.telemetry.poll_subscriptions()
            if self.router not in events:
                return
        elif self.telemetry.pub is not None:
            self.connections.answer()
            self.telemetry.poll_subscriptions()
        for _ in range(100):
            try:
                parts = self.router.recv_multipart(zmq.NOBLOCK, copy=False)
            except zmq.Again:
                return
            except zmq.ZMQError:
                return
            self._handle([part.bytes for part in parts], self._connection(parts[0]))

    def _connection(self, frame) -> str | None:
        """Who sent a message: the identity the server gave its connection (see
        runtime.server.connections); an ``inproc://`` connection (no handshake, no identity: only
        this process can make one) is known by its routing id."""
        identity = self.connections.of(frame)
        if identity is None and self.options.endpoint.startswith("inproc://"):
            identity = "inproc:" + frame.bytes.hex()
        return identity

    def _fail_all(self, reason: str) -> None:
        """The loop is gone: the running program faulted, the waiting ones cancelled."""
        unanswered = self.link.fail(reason)
        self.jobs.fail(reason)
        for identity, request_id, _command in unanswered:
            if identity is not None:
                self._reply(identity, protocol.error(request_id, "internal", reason))

    def _reply(self, identity: list, reply: bytes) -> None:
        if self.router is None:  # not bound: the caller reads the outbox itself
            self.outbox.append((identity, reply))
            return
        try:
            self.router.send_multipart([*identity, reply], zmq.NOBLOCK)
        except zmq.ZMQError:
            pass  # the client went away or its queue is full: the reply is dropped

    def _handle(self, frames: list[bytes], connection: str | None = None) -> None:
        """One request (``connection``: the identity of the connection it came on, see
        _connection): reply now, or forward a command whose reply the loop makes."""
        # ROUTER frames: identity, [envelope ending in an empty delimiter (REQ clients, proxies)], payload
        if len(frames) < 2:
            return
        identity, payload = envelope(frames)
        request_id = None
        version = protocol.VERSION
        try:
            if payload is None:
                raise ProtocolError("bad_message", f"expected one message frame after the envelope, got "
                                                   f"{len(frames) - len(identity)} frames (an envelope ends with an "
                                                   "empty frame, and holds at most "
                                                   f"{protocol.MAX_ENVELOPE_FRAMES} frames)")
            request_id, op, args, version, token = protocol.decode(payload)
            holder = self.controls.check(connection, token, op, args)
            handler = getattr(self, f"op_{op}")
            result = self.op_control(args, connection, holder) if op == "control" else handler(args)
            if isinstance(result, LoopCommand):  # to be carried out by the loop
                if self.link.gone is not None:
                    raise ProtocolError("refused", f"{self.link.gone}: restart irl serve")
                result.version = version
                self.link.commands.append((identity, request_id, result))
                return
            if isinstance(result, Wait):  # answered when the program ends (or at the deadline)
                self.jobs.add_waiter(result, identity, request_id, version)
                return
            reply = protocol.ok(request_id, result, version)
        except ProtocolError as exc:
            reply = protocol.error(exc.request_id if exc.request_id is not None else request_id, exc.code,
                                   exc.message, exc.version or version)
        except Exception as exc:  # a bug: answer and keep serving
            log.exception("request failed")
            reply = protocol.error(request_id, "internal", f"{type(exc).__name__}: {exc}", version)
        self._reply(identity, reply)

    def op_control(self, args: dict, connection: str | None = None, holder: bool = False) -> dict:
        """``take: true``: this connection (and whoever sends the token returned) holds
        control; ``take: false``: the holder gives it back (see Controls.request)."""
        return self.controls.request(args, connection, holder)

    # ---- operations (a LoopCommand result is carried out by the loop) ----------------------------
    def op_hello(self, args: dict) -> dict:
        return {"protocol": protocol.VERSION, "protocols": list(protocol.VERSIONS), "robot": self.spec.name,
                "spec_hash": self.spec.hash, "spec_file": self.spec_file,
                "axes": [a.name for a in self.spec.axes],
                "clock": "simulated" if self.options.sim_clock else "wall",
                "configuration": self.configuration,
                "configurations": list(self.configurations.names()) if self.configurations else [],
                "pid": os.getpid(), "loop_pid": self.link.pid, "loop_scheduling": self.link.scheduling}

    def op_status(self, args: dict) -> dict:
        if "program" in args:
            return self.jobs.status(args["program"])
        current = self.jobs.current
        snap = self.link.snapshot
        running = self.jobs.running(current) if current else None
        return {"state": running["fsm"] if running else "Idle",
                "running": running,
                "queue": [job.id for job in self.jobs.queue],
                "programs": self.jobs.recent(),
                "override": self.override, "configuration": self.configuration, "mode": snap.mode,
                "jog": snap.jog if running and running.get("kind") == "jog" else None,
                "calibrated": snap.calibrated, "initialized": snap.initialized,
                "calibration": snap.calibration, "initialization": snap.initialization,
                "position": snap.position, "inputs": snap.inputs, "outputs": snap.outputs,
                "shutting_down": self.stop_reason is not None,
                "control": self.controls.name(),
                "loop_gone": self.link.gone}

    def _check_accepting(self) -> None:
        if self.stop_reason is not None:
            raise ProtocolError("refused", "the server is shutting down")
        if self.link.gone is not None:
            raise ProtocolError("refused", f"{self.link.gone}: restart irl serve")

    def op_submit(self, args: dict) -> dict:
        self.jobs.check_room()  # before verifying: a full queue costs no verification
        data = args["object"]
        try:
            program = load(data, None)
        except ObjectCodeError as exc:
            raise ProtocolError("invalid_program", f"the object code is invalid: {exc}") from None
        if program.spec_hash != self.spec.hash:
            raise ProtocolError("wrong_robot", "the program was " + spec_mismatch(
                program, self.spec, spec_file=self.spec_file, unknown="its file is not known to this runtime",
                instead="submit it to a runtime started with the specification it was "
                                            "compiled for (irl serve --spec {})"))
        others = [r for r in program.robots if r != self.spec.name]
        if others:
            raise ProtocolError("wrong_robot", f"the program moves robot {others[0]!r}, but this runtime drives "
                                               f"{self.spec.name!r}")
        from_line = args.get("from_line")
        if from_line is not None:
            problem = from_line_problem(program, from_line)
            if problem is not None:
                raise ProtocolError("bad_request", f"submit: from_line {from_line}: {problem}")
        self._check_accepting()
        name = str(args.get("name") or program.name or "program")[:200]
        job = self.jobs.submit(name, program, bytes(data), bool(args.get("step", False)), from_line)
        job.source = args.get("source")
        return {"program": job.id, "queued": len(self.jobs.queue)}

    def op_source(self, args: dict) -> dict:
        job = self.jobs.get(args["program"])
        if job is None:
            raise ProtocolError("not_found", f"no program {args['program']} on this server")
        return {"program": job.id, "name": job.name, "source": job.source}

    def op_pause(self, args: dict) -> LoopCommand:
        return LoopCommand(messages.Pause(args.get("program")))

    def op_resume(self, args: dict) -> LoopCommand:
        return LoopCommand(messages.Resume(args.get("program")))

    def op_step(self, args: dict) -> LoopCommand:
        return LoopCommand(messages.Step(args.get("program")))

    def op_mode(self, args: dict) -> LoopCommand:
        mode = args["mode"]
        if mode not in protocol.MODES:
            raise ProtocolError("bad_request", f"mode: no operating mode {mode[:40]!r}; the modes are "
                                               f"{', '.join(protocol.MODES)}")
        return LoopCommand(messages.Mode(mode))

    def op_jog(self, args: dict) -> LoopCommand:
        """A jog: to the jog session under way, or one started for it (the robot idle, the
        queue empty); refused while a program runs or waits."""
        problem = protocol.jog_problem([a.name for a in self.spec.axes], args["axis"], args["direction"],
                                       args.get("frame"), args.get("step"))
        if problem is not None:
            raise ProtocolError("bad_request", problem)
        if self.link.snapshot.mode != "t1":
            raise ProtocolError("refused", "jogging needs operating mode T1 (manual reduced speed): irl mode t1")
        self._check_accepting()
        current = self.jobs.current
        if current is not None and not current.jog:
            raise ProtocolError("refused", f"program {current.id} ({current.name}) is running: jog when it has ended "
                                           "(or abort it)")
        if current is None:
            if self.jobs.queue:
                raise ProtocolError("refused", f"programs are waiting to run ({', '.join(str(j.id) for j in self.jobs.queue)}): "
                                               "jog when they have run (or abort them)")
            if args["direction"] == 0:  # a release with nothing to release: nothing moves
                return {"active": None, "stopping": False, "reason": None, "jogs": 0}
            self.jobs.start_jog(self.override)
        return LoopCommand(messages.Jog(args["axis"], args["direction"], args.get("frame", "world"), args.get("step")))

    def op_wait(self, args: dict) -> Wait:
        timeout = float(args.get("timeout", 60.0))
        if not 0.0 < timeout <= protocol.MAX_WAIT:
            raise ProtocolError("bad_request", f"wait: timeout must be more than 0 and at most "
                                               f"{protocol.MAX_WAIT:g} s, got {timeout:g}")
        return self.jobs.wait(args["program"], timeout)

    def op_telemetry(self, args: dict) -> dict:
        return self.telemetry.replay(args.get("since"))

    def op_feed(self, args: dict) -> dict:
        return self.telemetry.feeds.request(args)

    def op_abort(self, args: dict):
        wanted = args.get("program")
        current = self.jobs.current
        if wanted is not None and (current is None or current.id != wanted):
            return self.jobs.cancel(wanted)
        if current is None:
            raise ProtocolError("refused", "no program is running")
        return LoopCommand(messages.Abort(current.id, "aborted by the operator"))

    # the persistent variables' store is the loop's (runtime.loop.persistence): asked there
    def op_persistent(self, args: dict) -> LoopCommand:
        return LoopCommand(messages.Persistent("show", args.get("program", "")))

    def op_persistent_set(self, args: dict) -> LoopCommand:
        return LoopCommand(messages.Persistent("set", args["program"], args["name"], args["value"]))

    def op_persistent_reset(self, args: dict) -> LoopCommand:
        return LoopCommand(messages.Persistent("reset", args["program"], args.get("name", "")))

    def op_estop(self, args: dict) -> LoopCommand:
        cancelled = self.jobs.cancel_queue("cancelled by an emergency stop")
        return LoopCommand(messages.Estop(), finish=lambda result: {**result, "cancelled": cancelled})

    def op_override(self, args: dict) -> LoopCommand:
        percent = float(args["percent"])
        if not 1.0 <= percent <= 100.0:
            raise ProtocolError("bad_request", f"override: percent must be within 1..100, got {percent:g}")

        def applied(result: dict) -> dict:
            self.override = result["override"]
            return result
        return LoopCommand(messages.Override(percent), finish=applied)

    def op_call(self, args: dict):
        from runtime.server.scripting_service import call_in_server, runs_in_server
        from runtime.wire.scripting import parse_call

        text = args["text"]
        front = {"configuration": self.configuration, "override": self.override,
                 "configurations": list(self.configurations.names()) if self.configurations else []}
        command = parse_call(text)
        if runs_in_server(command):
            return call_in_server(command, front, lambda name: self.op_reconfigure({"name": name}))
        return LoopCommand(messages.Call(text, front))

    def op_reconfigure(self, args: dict) -> dict:
        """Re-read the configuration file and queue a Robot Reconfiguration cycle with the
        named configuration; an invalid file or name is refused and nothing changes."""
        if self.configurations is None or self.configurations.path is None:
            raise ProtocolError("refused", "this server has no configuration file (start it with --config FILE.toml)")
        from runtime.config import ConfigError, load_configurations, validate_settings

        name = args["name"]
        try:
            configurations = load_configurations(self.configurations.path)
            settings = validate_settings(merge_settings(self.baseline, configurations[name].settings),
                                         f"{configurations.path.name}: configuration {name!r} over the start-up "
                                         "settings")
        except ConfigError as exc:
            raise ProtocolError("refused", f"{exc} (the configuration in force, {self.configuration!r}, stays)") \
                from None
        self._check_accepting()
        self.jobs.check_room()
        job = self.jobs.reconfigure(name, settings)
        self.configurations = configurations
        return {"requested": name, "program": job.id}

    def op_report(self, args: dict) -> dict:
        job = self.jobs.get(args["program"])
        if job is None:
            raise ProtocolError("not_found", f"no program {args['program']}")
        which = args.get("file", "report")
        if which not in protocol.REPORT_FILES:
            raise ProtocolError("bad_request", "report: file must be " + " or ".join(f'"{f}"' for f in
                                                                                  protocol.REPORT_FILES))
        if job.report is None:
            raise ProtocolError("not_found", f"program {job.id} is a reconfiguration: it has no {which} file")
        path = job.report if which == "report" else job.report.with_suffix(f".{which}.csv")
        offset = args.get("offset", 0)  # an int (not a bool): protocol.decode_request checked the type
        try:
            with open(path, "rb") as f:
                size = os.fstat(f.fileno()).st_size
                if not 0 <= offset <= size:
                    raise ProtocolError("bad_request", f"report: offset must be an integer from 0 to the size of "
                                                       f"the {which} file ({size} bytes now), got {offset}")
                f.seek(offset)
                data = f.read(protocol.MAX_CHUNK_BYTES)
        except FileNotFoundError:
            raise ProtocolError("not_found", f"program {job.id} has no {which} file yet") from None
        except OSError as exc:
            raise ProtocolError("internal", f"cannot read {path}: {exc.strerror or exc}") from None
        final = job.state.ended
        return {"data": data, "offset": offset, "size": size, "final": final,
                "eof": final and offset + len(data) >= size}


def envelope(frames: list[bytes]) -> tuple[list[bytes], bytes | None]:
    """``(envelope, payload)`` of a message the ROUTER received: the frames a reply goes
    back with, and the request (None when the frames are not one request). The first frame
    is the connection's identity; a request is the last frame, alone after it (a DEALER) or
    after an envelope that ends with an empty delimiter frame (a REQ, or a client behind a
    proxy); anything else is answered as a ``bad_message`` to the identity alone."""
    if len(frames) == 2:
        return frames[:1], frames[1]
    if frames[-2] == b"" and len(frames) - 2 <= protocol.MAX_ENVELOPE_FRAMES:  # (identity, envelope, request)
        return frames[:-1], frames[-1]
    return frames[:1] + ([b""] if frames[1] == b"" else []), None


def serve(spec, options: ServeOptions, configurations=None, stderr=None) -> int:
    """Run a server until SIGINT/SIGTERM; returns the exit status."""
    handler = logging.StreamHandler(stderr or sys.stderr)
    handler.setFormatter(logging.Formatter("irl serve: %(message)s"))
    log.addHandler(handler)
    log.setLevel(logging.INFO)
    from runtime.config import ConfigError

    try:
        check_endpoints(options)
    except InsecureEndpoint as exc:
        log.error("%s", exc)
        log.removeHandler(handler)
        return 2
    if not options.keys and not (is_local_endpoint(options.endpoint) and is_local_endpoint(options.telemetry)):
        log.warning("serving without CURVE keys on an endpoint other machines can reach (%s): anyone on the "
                    "network can control the robot", INSECURE_FLAG)
    try:
        server = Server(spec, options, configurations)
    except LoopRefused:
        log.removeHandler(handler)
        raise
    except (ConfigError, LoopGone) as exc:
        log.error("%s", exc)
        log.removeHandler(handler)
        return 2
    try:
        server.bind()
    except zmq.ZMQError as exc:
        log.error("cannot bind %s / %s: %s", options.endpoint, options.telemetry, exc)
        server.close()
        return 2
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: server.request_shutdown())
    log.info("robot %s (%d axes), %s clock; requests on %s, telemetry on %s, state in %s", spec.name,
             len(spec.axes), "simulated" if options.sim_clock else "wall", options.endpoint, options.telemetry,
             server.state_dir)
    try:
        return server.serve()
    finally:
        server.close()
        log.info("stopped")
        log.removeHandler(handler)
