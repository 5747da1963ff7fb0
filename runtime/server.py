"""``irl serve``: one robot on the network (see docs/protocol.md).

Two threads. The **real-time loop** (the main thread) owns the robot: the executive, the
components, the supervisor and the telemetry PUB socket. Between programs it waits for
work; when a program is queued it runs one cycle of the supervisor (Start Robot ...
Stop Robot; calibration and initialization are remembered) and then takes the next.
Each tick it first applies the operator commands queued for it (a bounded number), then
steps the executive, then publishes telemetry every 10 ms (non-blocking sends on a PUB
socket with a bounded queue: a subscriber that stops reading loses messages, never
slows the loop).

The **I/O thread** owns the ROUTER socket. It decodes and checks every request, answers
the ones that only read (hello, status, property reads, report chunks) itself, verifies
submitted object code before queuing it, and hands everything that changes the robot to
the loop as a command; the loop's reply comes back through a deque and an inproc socket
that wakes the I/O thread. Nothing a client sends can raise into the loop: a bad request
gets an error reply and the server keeps serving.
"""
from __future__ import annotations

import collections
import logging
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import zmq

from compiler.objcode import OP, ObjectCodeError, Program, load

from . import protocol
from .protocol import ProtocolError
from .supervisor import MOVE
from .system import RobotSystem, RunOptions

log = logging.getLogger("irl.serve")

TELEMETRY_EVERY = 10  # ticks between telemetry samples while a program runs (10 ms)
IDLE_TELEMETRY_PERIOD = 0.5  # s between samples while idle
COMMANDS_PER_TICK = 8  # operator commands applied at most per tick
HISTORY = 200  # finished programs kept for status
SHUTDOWN_TIMEOUT = 15.0  # s the loop waits for the robot to come to rest on shutdown


@dataclass
class ServeOptions:
    endpoint: str = "tcp://127.0.0.1:5555"
    telemetry: str = "tcp://127.0.0.1:5556"
    state_dir: str | Path | None = None
    sim_clock: bool = False
    seed: int = 0
    keys: str | Path | None = None  # CURVE key directory (see runtime.keys)
    #: Bind endpoints other machines can reach without CURVE keys (see check_endpoints).
    allow_insecure_remote: bool = False
    #: The servo's deadline policy ("hard", "firm", "soft"); None: the specification's.
    deadline_policy: str | None = None
    #: Real-time scheduling for the loop's thread (wall clock only): runtime.realtime.Scheduling.
    scheduling: object = None


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


class Job:
    """One submitted program and what became of it."""

    def __init__(self, job_id: int, name: str, program: Program | None, report: Path | None,
                 settings: dict | None = None, configuration: str | None = None):
        self.id = job_id
        self.name = name
        self.program = program
        self.report = report
        self.settings = settings  # a reconfiguration (no program): the settings to apply
        self.configuration = configuration
        self.state = "queued"  # queued, running, completed, faulted, aborted, cancelled
        self.fault: str | None = None
        self.submitted = time.time()
        self.started: float | None = None
        self.ended: float | None = None
        self.summary: dict | None = None
        self.moves_total = moves_total(program) if program is not None else 0
        self.abort_reason: str | None = None

    def as_dict(self, system: RobotSystem | None = None, summary: bool = True) -> dict:
        d = {"id": self.id, "name": self.name, "state": self.state, "fault": self.fault,
             "submitted": self.submitted, "started": self.started, "ended": self.ended,
             "report": str(self.report) if self.report else None, "moves_total": self.moves_total,
             "kind": "program" if self.settings is None else "reconfiguration"}
        if system is not None and self.state == "running":
            t = system.trajectory
            d.update(line=t.line, moves_done=t.motion.completed, paused=t.paused,
                     fsm=system.supervisor.fsm.path())
        elif self.summary is not None:
            d.update(line=None, moves_done=sum(1 for m in self.summary["moves"] if m["actual_duration"] is not None))
            if summary:
                d["summary"] = self.summary
        return d


def moves_total(program: Program) -> int | None:
    """How many moves the program makes, when that is known without running it (no
    loops, no procedure calls); else None."""
    moves = 0
    for offset, instr in enumerate(program.code):
        op = instr[0]
        if op in (OP.MOVE_PTP, OP.MOVE_LIN, OP.MOVE_CIRC):
            moves += 1
        elif op == OP.CALL or (op in (OP.JUMP, OP.JUMP_IF_FALSE) and instr[1] <= offset):
            return None
    return moves


class Server:
    def __init__(self, spec, options: ServeOptions, configurations=None):
        self.spec = spec
        self.options = options
        state_dir = Path(options.state_dir) if options.state_dir else default_state_dir()
        self.state_dir = state_dir
        session = time.strftime("%Y%m%d-%H%M%S") + f"-{os.getpid()}"
        self.report_dir = state_dir / "reports" / session
        self.system = RobotSystem(spec, RunOptions(seed=options.seed, realtime=not options.sim_clock,
                                                   state_dir=state_dir, deadline_policy=options.deadline_policy))
        self.configurations = configurations
        self.configuration = None
        self.baseline = self.system.settings()  # what a configuration's missing keys fall back to
        if configurations is not None:
            from .config import validate_settings

            self.configuration = configurations.default
            self.system.apply_settings(validate_settings(
                merge_settings(self.baseline, configurations[configurations.default].settings),
                f"configuration {configurations.default!r} over the start-up settings"))
        self.jobs: dict[int, Job] = {}
        self.queue: collections.deque[Job] = collections.deque()
        self.finished: collections.deque[int] = collections.deque()
        self.current: Job | None = None
        self.next_id = 1
        self.override = 100.0
        self.commands: collections.deque = collections.deque()  # (identity, request id, fn) for the loop
        self.outbox: collections.deque = collections.deque()  # (identity, reply bytes) for the I/O thread
        self.work = threading.Event()  # set when the loop has something to do
        self.stop_reason: str | None = None
        self._shutdown_deadline: float | None = None
        self.telemetry_seq = 0
        self.telemetry_sent = 0
        self._seen_states = 0
        self._seen_log = 0
        self._last_idle_sample = 0.0
        self._submit_lock = threading.Lock()
        self.ctx = zmq.Context()
        self.router = self.pub = self._wake_tx = self._wake_rx = None
        self.io_thread: threading.Thread | None = None
        self.authenticator = None

    # ---- sockets --------------------------------------------------------------------
    def bind(self) -> None:
        """Bind the request and telemetry sockets (raises zmq.ZMQError when taken)."""
        check_endpoints(self.options)
        ctx = self.ctx
        self.router = ctx.socket(zmq.ROUTER)
        self.pub = ctx.socket(zmq.PUB)
        if self.options.keys:
            from .keys import server_security

            self.authenticator = server_security(ctx, self.options.keys, (self.router, self.pub))
        self.router.setsockopt(zmq.MAXMSGSIZE, protocol.TRANSPORT_MAX_BYTES)
        self.router.setsockopt(zmq.LINGER, 0)
        self.router.setsockopt(zmq.ROUTER_HANDOVER, 1)
        self.router.setsockopt(zmq.SNDHWM, 10_000)
        self.router.bind(self.options.endpoint)
        self.pub.setsockopt(zmq.SNDHWM, 1000)  # bounded: a slow subscriber loses messages
        self.pub.setsockopt(zmq.LINGER, 0)
        self.pub.bind(self.options.telemetry)
        self._wake_rx = ctx.socket(zmq.PAIR)
        self._wake_rx.bind(f"inproc://wake-{id(self)}")
        self._wake_tx = ctx.socket(zmq.PAIR)
        self._wake_tx.connect(f"inproc://wake-{id(self)}")
        self._wake_tx.setsockopt(zmq.SNDHWM, 1)

    def close(self) -> None:
        for sock in (self.router, self.pub, self._wake_tx, self._wake_rx):
            if sock is not None:
                sock.close(linger=0)
        if self.authenticator is not None:
            self.authenticator.stop()
        self.ctx.term()

    # ---- the real-time loop (main thread) ---------------------------------------------
    def serve(self) -> int:
        """Run until a shutdown is requested (``request_shutdown``) and the robot is at
        rest; returns the exit status."""
        self.io_thread = threading.Thread(target=self._io_main, name="irl-io", daemon=True)
        self.io_thread.start()
        if not self.options.sim_clock:  # the loop's thread only (the I/O thread stays at normal priority)
            from .realtime import Scheduling, apply

            log.info("loop: %s", apply(self.options.scheduling or Scheduling()))
        while self.turn():
            pass
        self._publish({"kind": "event", "event": "shutdown", "reason": self.stop_reason})
        return 0

    def turn(self, idle_wait: bool = True) -> bool:
        """One turn of the real-time loop: the queued operator commands, then one tick of
        the running program (or the next program started, or an idle wait when there is
        none and ``idle_wait``). False once a shutdown is done. Tests drive the server
        turn by turn (no sockets, no I/O thread: they call the ``op_*`` handlers)."""
        if self.commands:
            self._apply_commands()
        if self.current is None:
            if self.stop_reason is not None:
                return False
            if self.queue:
                self._start_next()
            elif idle_wait:
                self._idle()
                return True
            else:
                return True
        if self.stop_reason is not None and self._shutdown_deadline is None:
            self._shutdown_deadline = time.monotonic() + SHUTDOWN_TIMEOUT
            self._stop_current(self.stop_reason)
        ex = self.system.executive
        ex.step()
        if ex.ticks % TELEMETRY_EVERY == 0:
            self._publish_progress()
        if self.system.supervisor.done:
            self._finish_current()
        elif self._shutdown_deadline is not None and time.monotonic() > self._shutdown_deadline:
            log.error("the robot did not come to rest within %g s of the shutdown", SHUTDOWN_TIMEOUT)
            self._finish_current()
        return True

    def request_shutdown(self, reason: str = "the server is shutting down") -> None:
        """Safe from a signal handler or another thread: stop after bringing the robot to rest."""
        if self.stop_reason is None:
            self.stop_reason = reason
        self.work.set()

    def _idle(self) -> None:
        """Between programs: wait (not a real-time state: nothing is moving, brakes on)."""
        self.work.wait(0.05)
        self.work.clear()
        now = time.monotonic()
        if now - self._last_idle_sample >= IDLE_TELEMETRY_PERIOD:
            self._last_idle_sample = now
            self._publish_sample()

    def _start_next(self) -> None:
        job = self.queue.popleft()
        system = self.system
        if not self.options.sim_clock:
            system.executive.resync()
        try:
            self.report_dir.mkdir(parents=True, exist_ok=True)
            if job.settings is not None:
                system.begin(None, None, settings=job.settings)
            else:
                system.begin(job.program, job.report)
        except (ValueError, OSError) as exc:
            job.state, job.fault, job.ended = "faulted", str(exc), time.time()
            self._retire(job)
            return
        system.trajectory.override = self.override
        job.state, job.started = "running", time.time()
        self.current = job
        self._seen_states = 0
        self._seen_log = 0
        log.info("program %d (%s) started", job.id, job.name)
        self._publish({"kind": "event", "event": "program", "program": job.id, "state": "running"})

    def _finish_current(self) -> None:
        job = self.current
        summary = self.system.finish()
        self._publish_progress()
        job.summary = summary
        job.ended = time.time()
        job.fault = summary["fault"]
        if job.fault is None:
            job.state = "completed"
            if job.configuration is not None:
                self.configuration = job.configuration
        elif job.abort_reason is not None:
            job.state = "aborted"
        else:
            job.state = "faulted"
        self.current = None
        self._retire(job)
        log.info("program %d %s%s", job.id, job.state, f": {job.fault}" if job.fault else "")
        self._publish({"kind": "event", "event": "program", "program": job.id, "state": job.state,
                       "fault": job.fault})

    def _retire(self, job: Job) -> None:
        job.program = None  # the code is not needed any more
        self.finished.append(job.id)
        while len(self.finished) > HISTORY:
            self.jobs.pop(self.finished.popleft(), None)

    def _stop_current(self, reason: str) -> None:
        """Bring the running program to an end: a controlled stop while moving, else at once."""
        job = self.current
        if job is None:
            return
        job.abort_reason = job.abort_reason or reason
        system = self.system
        if system.supervisor.fsm.state == MOVE and system.trajectory.running:
            system.trajectory.abort(reason)
        else:
            system.supervisor.request_stop(reason)

    def _apply_commands(self) -> None:
        for _ in range(COMMANDS_PER_TICK):
            if not self.commands:
                break
            identity, request_id, fn = self.commands.popleft()
            try:
                reply = protocol.ok(request_id, fn())
            except ProtocolError as exc:
                reply = protocol.error(request_id, exc.code, exc.message)
            except Exception as exc:  # a bug: the client hears of it, the loop goes on
                log.exception("command failed")
                reply = protocol.error(request_id, "internal", f"{type(exc).__name__}: {exc}")
            self.outbox.append((identity, reply))
        if self._wake_tx is None:  # not bound: the caller reads the outbox itself
            return
        try:
            self._wake_tx.send(b"", zmq.NOBLOCK)
        except zmq.Again:
            pass  # the I/O thread has a wake-up pending already

    # ---- telemetry (real-time loop) -----------------------------------------------------
    def _publish(self, message: dict) -> None:
        self.telemetry_seq += 1
        message["v"] = protocol.VERSION
        message["seq"] = self.telemetry_seq
        message["t"] = self.system.clock.now()
        if self.pub is None:  # not bound (driven turn by turn, in-process)
            return
        try:
            self.pub.send_multipart((protocol.TELEMETRY_TOPIC, protocol.pack(message)), zmq.NOBLOCK)
            self.telemetry_sent += 1
        except zmq.Again:
            pass

    def _publish_progress(self) -> None:
        history = self.system.supervisor.fsm.history
        while self._seen_states < len(history):
            t, source, target = history[self._seen_states]
            self._seen_states += 1
            self._publish({"kind": "event", "event": "state", "from": source, "to": target, "at": t})
        lines = self.system.trajectory.log_lines
        while self._seen_log < len(lines):
            t, line, text = lines[self._seen_log]
            self._seen_log += 1
            self._publish({"kind": "event", "event": "log", "line": line, "text": text, "at": t})
        self._publish_sample()

    def _publish_sample(self) -> None:
        system = self.system
        job = self.current
        sample = {"kind": "sample", "state": system.supervisor.fsm.path() if job else "Idle",
                  "program": job.id if job else None, "queued": len(self.queue),
                  "override": self.override, "position": list(system.robot.positions)}
        if job is not None:
            t = system.trajectory
            sample.update(line=t.line, moves_done=t.motion.completed, moves_total=job.moves_total, paused=t.paused,
                          following_error=max((abs(e) for e in system.servo.following_error), default=0.0))
        self._publish(sample)

    # ---- the I/O thread -----------------------------------------------------------------
    def _io_main(self) -> None:
        poller = zmq.Poller()
        poller.register(self.router, zmq.POLLIN)
        poller.register(self._wake_rx, zmq.POLLIN)
        router = self.router
        while True:
            try:
                events = dict(poller.poll(200))
            except zmq.ZMQError:
                return  # the context is closing
            if self._wake_rx in events:
                try:
                    while True:
                        self._wake_rx.recv(zmq.NOBLOCK)
                except zmq.Again:
                    pass
            while self.outbox:
                identity, reply = self.outbox.popleft()
                self._send(identity, reply)
            if router in events:
                for _ in range(100):
                    try:
                        frames = router.recv_multipart(zmq.NOBLOCK, copy=True)
                    except zmq.Again:
                        break
                    except zmq.ZMQError:
                        return
                    self._handle(frames)

    def _send(self, identity: list, reply: bytes) -> None:
        try:
            self.router.send_multipart([*identity, reply], zmq.NOBLOCK)
        except zmq.ZMQError:
            pass  # the client went away or its queue is full: the reply is dropped

    def _handle(self, frames: list[bytes]) -> None:
        """One request: reply now, or queue a command whose reply the loop makes."""
        # ROUTER frames: identity, [empty delimiter (REQ clients)], payload
        if len(frames) < 2:
            return
        identity = frames[:-1]
        payload = frames[-1]
        request_id = None
        try:
            if len(frames) > 3:
                raise ProtocolError("bad_message", "expected one message frame (after the envelope)")
            request_id, op, args = protocol.decode_request(payload)
            handler = getattr(self, f"op_{op}")
            result = handler(args)
            if callable(result):  # to be carried out by the loop
                self.commands.append((identity, request_id, result))
                self.work.set()
                return
            reply = protocol.ok(request_id, result)
        except ProtocolError as exc:
            reply = protocol.error(exc.request_id if exc.request_id is not None else request_id, exc.code,
                                   exc.message)
        except Exception as exc:  # a bug: answer and keep serving
            log.exception("request failed")
            reply = protocol.error(request_id, "internal", f"{type(exc).__name__}: {exc}")
        self._send(identity, reply)

    # ---- operations (I/O thread; a callable result runs in the loop) ----------------------
    def op_hello(self, args: dict) -> dict:
        return {"protocol": protocol.VERSION, "robot": self.spec.name, "spec_hash": self.spec.hash,
                "axes": [a.name for a in self.spec.axes],
                "clock": "simulated" if self.options.sim_clock else "wall",
                "configuration": self.configuration,
                "configurations": list(self.configurations.names()) if self.configurations else [],
                "pid": os.getpid()}

    def op_status(self, args: dict) -> dict:
        current = self.current
        if "program" in args:
            job = self.jobs.get(args["program"])
            if job is None:
                raise ProtocolError("not_found", f"no program {args['program']} (ids start at 1; finished "
                                                 f"programs are kept for the last {HISTORY})")
            return job.as_dict(self.system if job is current else None)
        system = self.system
        return {"state": system.supervisor.fsm.path() if current else "Idle",
                "running": current.as_dict(system) if current else None,
                "queue": [job.id for job in list(self.queue)],
                "programs": [job.as_dict(None, summary=False) for job in list(self.jobs.values())[-21:]
                             if job.state != "running"][-20:],
                "override": self.override, "configuration": self.configuration,
                "calibrated": system.memory.calibrated, "initialized": system.memory.initialized,
                "calibration": system.memory.calibration_why, "initialization": system.memory.initialization_why,
                "position": list(system.robot.positions), "shutting_down": self.stop_reason is not None}

    def _check_queue_room(self) -> None:
        """Refuse (``queue_full``) a program or reconfiguration beyond MAX_QUEUED waiting
        ones (the running one does not count). Call with ``_submit_lock`` held."""
        if len(self.queue) >= protocol.MAX_QUEUED:
            raise ProtocolError("queue_full", f"the queue is full: it holds {len(self.queue)} programs waiting to "
                                              f"run, at most {protocol.MAX_QUEUED} may wait; submit again when "
                                              "one has started (or abort queued ones)")

    def op_submit(self, args: dict) -> dict:
        with self._submit_lock:
            self._check_queue_room()  # before verifying: a full queue costs no verification
        data = args["object"]
        try:
            program = load(data, None)
        except ObjectCodeError as exc:
            raise ProtocolError("invalid_program", f"the object code is invalid: {exc}") from None
        if program.spec_hash != self.spec.hash:
            raise ProtocolError("wrong_robot", f"the program was compiled for {program.spec_name!r} "
                                               f"({program.spec_hash[:12]}), but this runtime drives "
                                               f"{self.spec.name!r} ({self.spec.hash[:12]}): recompile it "
                                               "with this robot's specification")
        others = [r for r in program.robots if r != self.spec.name]
        if others:
            raise ProtocolError("wrong_robot", f"the program moves robot {others[0]!r}, but this runtime drives "
                                               f"{self.spec.name!r}")
        if self.stop_reason is not None:
            raise ProtocolError("refused", "the server is shutting down")
        name = str(args.get("name") or program.name or "program")[:200]
        with self._submit_lock:  # ids in the order programs are queued
            self._check_queue_room()
            job = Job(self.next_id, name, program, self.report_dir / f"program-{self.next_id}.csv")
            self.next_id += 1
            self.jobs[job.id] = job
            self.queue.append(job)
        self.work.set()
        log.info("program %d (%s) queued", job.id, name)
        return {"program": job.id, "queued": len(self.queue)}

    def op_pause(self, args: dict):
        def pause():
            if self.current is None or self.system.supervisor.fsm.state != MOVE:
                raise ProtocolError("refused", "no program is moving the robot")
            if not self.system.trajectory.pause():
                raise ProtocolError("refused", "the program cannot be paused now (it is ending)")
            return {"program": self.current.id, "paused": True}
        return pause

    def op_resume(self, args: dict):
        def resume():
            if self.current is None or not self.system.trajectory.resume():
                raise ProtocolError("refused", "no program is paused")
            return {"program": self.current.id, "paused": False}
        return resume

    def op_abort(self, args: dict):
        wanted = args.get("program")

        def abort():
            if wanted is not None and (self.current is None or self.current.id != wanted):
                for job in list(self.queue):
                    if job.id == wanted:
                        self.queue.remove(job)
                        job.state, job.fault, job.ended = "cancelled", "removed from the queue by the operator", \
                            time.time()
                        self._retire(job)
                        return {"program": wanted, "state": "cancelled"}
                raise ProtocolError("not_found", f"program {wanted} is neither running nor queued")
            if self.current is None:
                raise ProtocolError("refused", "no program is running")
            self._stop_current("aborted by the operator")
            return {"program": self.current.id, "state": "aborting"}
        return abort

    def op_estop(self, args: dict):
        def estop():
            cancelled = self._cancel_queue("cancelled by an emergency stop")
            job = self.current
            if job is not None:
                job.abort_reason = "emergency stop"
                self.system.emergency_stop()
            return {"program": job.id if job else None, "cancelled": cancelled}
        return estop

    def _cancel_queue(self, reason: str) -> list[int]:
        cancelled = []
        while self.queue:
            job = self.queue.popleft()
            job.state, job.fault, job.ended = "cancelled", reason, time.time()
            self._retire(job)
            cancelled.append(job.id)
        return cancelled

    def op_override(self, args: dict):
        percent = float(args["percent"])
        if not 1.0 <= percent <= 100.0:
            raise ProtocolError("bad_request", f"override: percent must be within 1..100, got {percent:g}")

        def override():
            self.override = percent
            self.system.trajectory.override = percent
            return {"override": percent}
        return override

    def op_call(self, args: dict):
        from .scripting_service import call

        return call(self, args["text"])

    def op_reconfigure(self, args: dict) -> dict:
        """Re-read the configuration file and queue a Robot Reconfiguration cycle with the
        named configuration; an invalid file or name is refused and nothing changes."""
        if self.configurations is None or self.configurations.path is None:
            raise ProtocolError("refused", "this server has no configuration file (start it with --config FILE.toml)")
        from .config import ConfigError, load_configurations, validate_settings

        name = args["name"]
        try:
            configurations = load_configurations(self.configurations.path)
            settings = validate_settings(merge_settings(self.baseline, configurations[name].settings),
                                         f"{configurations.path.name}: configuration {name!r} over the start-up "
                                         "settings")
        except ConfigError as exc:
            raise ProtocolError("refused", f"{exc} (the configuration in force, {self.configuration!r}, stays)") \
                from None
        if self.stop_reason is not None:
            raise ProtocolError("refused", "the server is shutting down")
        with self._submit_lock:
            self._check_queue_room()
            job = Job(self.next_id, f"reconfigure {name}", None, None,
                      settings=settings, configuration=name)
            self.next_id += 1
            self.jobs[job.id] = job
            self.queue.append(job)
        self.configurations = configurations
        self.work.set()
        return {"requested": name, "program": job.id}

    def op_report(self, args: dict) -> dict:
        job = self.jobs.get(args["program"])
        if job is None:
            raise ProtocolError("not_found", f"no program {args['program']}")
        which = args.get("file", "report")
        if which not in ("report", "states"):
            raise ProtocolError("bad_request", "report: file must be \"report\" or \"states\"")
        if job.report is None:
            raise ProtocolError("not_found", f"program {job.id} is a reconfiguration: it has no {which} file")
        path = job.report if which == "report" else job.report.with_suffix(".states.csv")
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
        final = job.state not in ("queued", "running")
        return {"data": data, "offset": offset, "size": size, "final": final,
                "eof": final and offset + len(data) >= size}


def merge_settings(base: dict, settings: dict) -> dict:
    """``base`` (component -> key -> value) with ``settings`` laid over it."""
    merged = {component: dict(values) for component, values in base.items()}
    for component, values in settings.items():
        merged.setdefault(component, {}).update(values)
    return merged


def default_state_dir() -> Path:
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
    return Path(base) / "irl"


def serve(spec, options: ServeOptions, configurations=None, stderr=None) -> int:
    """Run a server until SIGINT/SIGTERM; returns the exit status."""
    handler = logging.StreamHandler(stderr or sys.stderr)
    handler.setFormatter(logging.Formatter("irl serve: %(message)s"))
    log.addHandler(handler)
    log.setLevel(logging.INFO)
    from .config import ConfigError

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
    except ConfigError as exc:
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
    sys.setswitchinterval(0.0005)  # the I/O thread yields the interpreter to the loop quickly
    log.info("robot %s (%d axes), %s clock; requests on %s, telemetry on %s, state in %s", spec.name,
             len(spec.axes), "simulated" if options.sim_clock else "wall", options.endpoint, options.telemetry,
             server.state_dir)
    try:
        return server.serve()
    finally:
        server.close()
        log.info("stopped")
        log.removeHandler(handler)
