"""The real-time side of ``irl serve``: one robot, its loop, and nothing else.

:class:`RobotLoop` owns the :class:`~runtime.loop.system.RobotSystem` (executive, components,
supervisor, robot interface). It runs at most one cycle of the supervisor at a time (a
program, or a reconfiguration) when the server says ``start``, carries out the operator
commands the server forwards (a bounded number per tick, between ticks), and sends back
what the server needs: replies, telemetry events, a snapshot of the robot every 10 ms
(the server answers ``status`` and publishes telemetry from it), and the summary when
a cycle ends. It decodes no network request, encodes no telemetry for the network and
never waits on the server: whatever it sends goes through a :class:`~runtime.wire.channel.Channel`
(or, in one process, a deque).

``irl serve`` runs it in a process of its own (:func:`child`), at the real-time
priority asked for; tests drive it in-process, tick by tick. Both run the same code, and
with the simulated clock both give the same report bytes.

Messages to the loop: the commands of runtime/wire/messages.py (``{"op": NAME, "ref": N,
...}``), each carried out by its handler here (:data:`COMMANDS`); every one is answered by ``{"kind": "reply", "ref": N, "ok": true, "result": ...}`` or
``{"kind": "reply", "ref": N, "ok": false, "code": C, "message": M}``. Messages from the
loop (``kind``): ``ready`` (once, with the settings' baseline and the scheduling it got),
``failed`` (it could not start), ``snapshot`` (runtime.wire.messages.Snapshot), ``event`` (a state transition or a
program's ``log`` line, for telemetry), ``finished`` (a cycle ended: its summary),
``reply``.
"""
from __future__ import annotations

import gc
import math
import os
import signal
import sys
import time
from collections import deque
from typing import Callable

from compiler.objcode import ObjectCodeError, load

from runtime.motion.tcp import tcp_of
from runtime.loop.supervisor import MOVE
from runtime.loop.persistence import fitted, plain_of, shown_plain, value_of
from runtime.loop.system import RobotSystem, RunOptions
from runtime.timing import PACE_WAIT, TICK
from runtime.wire import messages
from runtime.wire.messages import EXIT_TIMEOUT, LoopOptions, Progress, Snapshot
from runtime.wire.protocol import MODES, ProtocolError, jog_problem

__all__ = ["COMMANDS", "COMMANDS_PER_TICK", "EXIT_TIMEOUT", "RobotLoop", "TELEMETRY_EVERY", "child"]

TELEMETRY_EVERY = 10  # ticks between snapshots while a cycle runs (10 ms)
IDLE_SNAPSHOT_PERIOD = 0.5  # s between snapshots while idle
COMMANDS_PER_TICK = 8  # operator commands applied at most per tick


class RobotLoop:
    """The robot and its loop. ``send(message, droppable)`` hands a message to the server
    (never waits; returns False when it was dropped)."""

    def __init__(self, spec, options: RunOptions, send: Callable[..., bool]):
        self.system = RobotSystem(spec, options)
        self.tcp = tcp_of(spec)  # the snapshot's TCP (None: the robot's kinematics give none)
        self.main_axes = len(spec.main_axes)
        self.send = send
        self.job: int | None = None  # the running cycle's program id (the server's)
        self.abort_reason: str | None = None
        self.front: dict = {}  # the server's state a script may read (configuration, override)
        self.commands: deque = deque()
        self.exit_reason: str | None = None
        self._exit_deadline: float | None = None
        self._seen_states = 0
        self._seen_log = 0
        self._last_idle_snapshot = -math.inf
        self._gc_was_enabled = True
        self._paced: tuple[float, float] | None = None  # (robot clock, wall clock) a jog session's pace began at

    # ---- what the server asks ----------------------------------------------------------
    def ready(self, scheduling: str | None = None) -> dict:
        return {"kind": "ready", "baseline": self.system.settings(), "pid": os.getpid(), "scheduling": scheduling,
                "snapshot": self.snapshot().to_wire()}

    def command(self, message: dict) -> None:
        """Carry out one command and send its reply (and, before it, a fresh snapshot:
        a client that reads the status after the reply sees the command's effect)."""
        ref = message.get("ref")
        try:
            ref, command = messages.command_of(message)
            result = COMMANDS[command.OP](self, command)
            reply = {"kind": "reply", "ref": ref, "ok": True, "result": result}
        except ProtocolError as exc:
            reply = {"kind": "reply", "ref": ref, "ok": False, "code": exc.code, "message": exc.message}
        except Exception as exc:  # a bug: the server hears of it, the loop goes on
            reply = {"kind": "reply", "ref": ref, "ok": False, "code": "internal",
                     "message": f"{type(exc).__name__}: {exc}"}
        self.send(self.snapshot().to_wire())
        self.send(reply)

    def _start(self, m: messages.Start) -> dict:
        if self.job is not None:
            raise ProtocolError("refused", f"program {self.job} is running")
        if self.exit_reason is not None:
            raise ProtocolError("refused", self.exit_reason)
        system = self.system
        try:
            program = load(m.object, None) if m.object is not None else None
        except ObjectCodeError as exc:
            raise ProtocolError("invalid_program", f"the object code is invalid: {exc}") from None
        try:
            system.begin(program, m.report, settings=m.settings, record=m.record, job=m.job, jog=m.jog, step=m.step,
                         from_line=m.from_line)
        except (ValueError, OSError) as exc:
            raise ProtocolError("refused", str(exc)) from None
        system.trajectory.override = m.override
        self.job = m.job
        self.abort_reason = None
        self._seen_states = self._seen_log = 0
        # The loop allocates small, cycle-free objects every tick; reference counting frees
        # them. A cyclic collection would walk the heap at an arbitrary tick: paused for the
        # cycle (as RobotSystem.run does), run when it ends.
        self._gc_was_enabled = gc.isenabled()
        gc.freeze()
        gc.disable()
        return {"t": system.clock.now()}

    def _meant(self, m: messages.Pause | messages.Resume | messages.Step) -> None:
        """Refuse a command meant for another program than the running one."""
        wanted = m.program
        if wanted is not None and wanted != self.job:
            raise ProtocolError("refused", f"program {wanted} is not the running program"
                                           + (f" (program {self.job} is)" if self.job is not None else ""))

    def _pause(self, m: messages.Pause) -> dict:
        system = self.system
        self._meant(m)
        if self.job is None or system.supervisor.fsm.state != MOVE:
            raise ProtocolError("refused", "no program is moving the robot")
        if system.trajectory.paused:
            raise ProtocolError("refused", f"program {self.job} is already paused")
        if not system.trajectory.pause():
            raise ProtocolError("refused", "the program cannot be paused now (it is ending)")
        return {"program": self.job, "paused": True}

    def _resume(self, m: messages.Resume) -> dict:
        self._meant(m)
        if self.job is None or not self.system.trajectory.resume():
            raise ProtocolError("refused", "no program is paused")
        return {"program": self.job, "paused": False}

    def _step(self, m: messages.Step) -> dict:
        """Step mode: the move the program waits before goes (refused, with why, when it
        does not wait for a step)."""
        system = self.system
        self._meant(m)
        if self.job is None:
            raise ProtocolError("refused", "no program is running")
        trajectory = system.trajectory
        if system.supervisor.fsm.state != MOVE:
            why = ("it does not run in step mode (submit it with step, irl submit --step)" if not trajectory.stepping.step
                   else f"it is starting ({system.supervisor.fsm.path()}): its first move waits for a step in Move Robot")
        else:
            why = trajectory.step()
        if why is not None:
            raise ProtocolError("refused", f"program {self.job}: {why}")
        return {"program": self.job, "line": trajectory.line, "approach": trajectory.stepping.approach_next}

    def _abort(self, m: messages.Abort) -> dict:
        wanted = m.program
        if self.job is None or (wanted is not None and wanted != self.job):
            raise ProtocolError("not_found" if wanted is not None else "refused",
                                f"program {wanted} is neither running nor queued" if wanted is not None
                                else "no program is running")
        self.stop(m.reason or "aborted by the operator")
        return {"program": self.job, "state": "aborting"}

    def _estop(self, m: messages.Estop) -> dict:
        if self.job is not None:
            self.abort_reason = "emergency stop"
            self.system.emergency_stop()
        return {"program": self.job}

    def _override(self, m: messages.Override) -> dict:
        percent = float(m.percent)
        if not 1.0 <= percent <= 100.0:  # checked by the server too: the loop trusts no one
            raise ProtocolError("bad_request", f"override: percent must be within 1..100, got {percent:g}")
        self.system.trajectory.override = percent
        self.front["override"] = percent
        return {"override": percent}

    def _call(self, m: messages.Call) -> dict:
        from runtime.loop.scripting import call, loop_targets

        self.front = dict(m.front or {})
        result = call(loop_targets(self), self.job, m.text)
        return result() if callable(result) else result

    def _mode(self, m: messages.Mode) -> dict:
        """Switch the operating mode: with no cycle running, or in a jog session at rest
        (which then ends: jogging is T1's)."""
        system = self.system
        if m.mode not in MODES:
            raise ProtocolError("bad_request", f"mode: no operating mode {str(m.mode)[:40]!r}; the modes are "
                                               f"{', '.join(MODES)}")
        if self.job is not None:
            jogger = system.trajectory.jogger
            idle = jogger is not None and jogger.active is None and jogger.pending is None and not jogger.stopping
            if not idle:
                raise ProtocolError("refused", f"the operating mode changes only with the robot at rest and no "
                                               f"program running ({'a jog is under way' if jogger is not None else f'program {self.job} is running'})")
            jogger.end(f"operating mode {m.mode.upper()}")
        try:
            system.set_mode(m.mode)
        except ValueError as exc:
            raise ProtocolError("refused", str(exc)) from None
        return {"mode": system.mode}

    def _jog(self, m: messages.Jog) -> dict:
        """A jog request, to the running jog session (the server started it)."""
        system = self.system
        problem = jog_problem([a.name for a in system.spec.axes], m.axis, m.direction, m.frame, m.step)
        if problem is not None:
            raise ProtocolError("bad_request", problem)
        if system.mode != "t1":
            raise ProtocolError("refused", "jogging needs operating mode T1 (manual reduced speed): irl mode t1")
        if self.job is None or not system.trajectory.jogging:
            raise ProtocolError("refused", "no jog session is running" if self.job is None
                                else f"program {self.job} is running")
        return {**system.trajectory.jog(m, system.clock.tick_time), "t": system.clock.tick_time, "program": self.job}

    def _settings(self, m: messages.Settings) -> dict:
        if self.job is not None:
            raise ProtocolError("refused", "settings change only between programs")
        self.system.apply_settings(m.settings)
        return {"applied": True}

    def _persistent(self, m: messages.Persistent) -> dict:
        """Show, set or reset kept values of persistent variables (not of the program running)."""
        store = self.system.persistent
        entries = store.entries()
        if m.action == "show":
            wanted = {m.program: entries.get(m.program, {})} if m.program else entries
            count = sum(len(names) for names in entries.values())
            found = f"{count} kept value{'s' if count != 1 else ''} of {len(entries)} program" \
                    f"{'s' if len(entries) != 1 else ''}" if count else store.why
            return {"store": str(store.path) if store.path is not None else None, "found": found,
                    "programs": {program: {name: {"type": t, "value": shown_plain(plain), "plain": plain}
                                           for name, (t, plain) in sorted(names.items())}
                                 for program, names in sorted(wanted.items())}}
        program = self.system.trajectory.program
        if self.job is not None and program is not None and program.name == m.program:
            raise ProtocolError("refused", f"program {m.program!r} is running: change its kept values between runs")
        if m.action == "reset":
            return {"program": m.program, "forgotten": store.reset(m.program, m.name or None)}
        entry = entries.get(m.program, {}).get(m.name)
        if entry is None:
            known = ", ".join(sorted(entries.get(m.program, {}))) or "none"
            raise ProtocolError("refused", f"the runtime keeps no value of {m.program}.{m.name[:64]} (it keeps: "
                                           f"{known}); a value is kept once the program has set it")
        try:
            value, like = value_of(m.value), value_of(entry[1])
        except (ValueError, TypeError, RecursionError) as exc:
            raise ProtocolError("bad_request", f"persistent_set: the value is not a value of the language: {exc}") \
                from None
        value = fitted(value, like)
        if value is None:
            raise ProtocolError("bad_request", f"persistent_set: {m.program}.{m.name} is {entry[0]} (like "
                                               f"{shown_plain(entry[1])}); got {shown_plain(m.value)}")
        store.set(m.program, m.name, entry[0], value)
        store.flush()
        return {"program": m.program, "name": m.name, "type": entry[0], "value": shown_plain(plain_of(value))}

    def _exit(self, m: messages.Exit) -> dict:
        self.exit_reason = m.reason or "the server is shutting down"
        if self.job is not None:
            self.stop(self.exit_reason)
            self._exit_deadline = time.monotonic() + EXIT_TIMEOUT
        return {"exiting": True}

    # ---- the loop ------------------------------------------------------------------------
    def stop(self, reason: str) -> None:
        """Bring the running cycle to an end: a controlled stop on the path while moving,
        else through Stop Robot at once."""
        self.abort_reason = self.abort_reason or reason
        system = self.system
        if system.supervisor.fsm.state == MOVE and system.trajectory.running:
            system.trajectory.abort(reason)
        else:
            system.supervisor.request_stop(reason)

    def turn(self) -> None:
        """Between two ticks: the queued commands (at most COMMANDS_PER_TICK); then one
        tick of the running cycle (real-time), or an idle snapshot now and then."""
        commands = self.commands
        if self.job is None:  # no cycle, no io task: the I/O's ports as the backend has it now (a PLC's)
            self.system.io.refresh()
        for _ in range(COMMANDS_PER_TICK):
            if not commands:
                break
            self.command(commands.popleft())
        if self.job is None:
            now = time.monotonic()
            if now - self._last_idle_snapshot >= IDLE_SNAPSHOT_PERIOD:
                self._last_idle_snapshot = now
                self.send(self.snapshot().to_wire(), True)
            return
        ex = self.system.executive
        ex.step()
        if ex.ticks % TELEMETRY_EVERY == 0:
            self.progress()
        if self.system.supervisor.done:
            self.finish()
        elif self._exit_deadline is not None and time.monotonic() > self._exit_deadline:
            self._exit_deadline = None  # once: the emergency stop's own ramp then ends the cycle
            self.system.emergency_stop("the robot did not come to rest within "
                                       f"{EXIT_TIMEOUT:g} s of the shutdown")

    def progress(self) -> None:
        """The state transitions and log lines since the last call, then a snapshot."""
        system = self.system
        history = system.supervisor.fsm.history
        t = system.clock.now()
        while self._seen_states < len(history):
            at, source, target = history[self._seen_states]
            self._seen_states += 1
            self.send({"kind": "event", "event": "state", "from": source, "to": target, "at": at, "t": t})
        lines = system.trajectory.log_lines
        while self._seen_log < len(lines):
            at, line, text, kind = lines[self._seen_log]
            self._seen_log += 1
            self.send({"kind": "event", "event": "log", "program": self.job, "line": line, "text": text,
                       "log_kind": kind, "at": at, "t": t})
        self.send(self.snapshot().to_wire(), True)

    def snapshot(self) -> Snapshot:
        """What the server answers ``status`` and publishes as a telemetry sample from."""
        system = self.system
        memory = system.memory
        position = list(system.robot.positions)
        frames = system.trajectory.frames_now()
        tcp = tcp_base = None
        if self.tcp is not None:
            joints = position[:self.main_axes]
            world = self.tcp.world(joints, frames)  # (the forward kinematics once for both)
            tcp, tcp_base = list(world), list(self.tcp.in_base(joints, frames, world))
        progress = None
        if self.job is not None:
            t = system.trajectory
            stepping = t.stepping
            progress = Progress(t.line, t.moves_done, t.paused,
                                max((abs(e) for e in system.servo.following_error), default=0.0), stepping.step,
                                t.waiting_for_step, stepping.approach_next)
        # while a cycle runs, the time of the tick the positions were measured at (a snapshot
        # is made after its tick, late by the host's jitter); idle, the clock's now
        at = system.clock.tick_time if self.job is not None else system.clock.now()
        return Snapshot(at, self.job, system.supervisor.fsm.path() if self.job is not None else "Idle",
                        position, list(system.io.inputs.read()), list(system.io.outputs.read()),
                        frames.tool_name, frames.base_name, tcp, tcp_base, memory.calibrated, memory.initialized,
                        memory.calibration_why, memory.initialization_why, progress, system.mode,
                        system.trajectory.jogger.state() if system.trajectory.jogger is not None else None)

    def finish(self) -> None:
        """Not real-time: the cycle ended; flush its files and send its summary."""
        summary = self.system.finish()
        if self._gc_was_enabled:
            gc.enable()
        gc.unfreeze()
        self.progress()
        job, self.job = self.job, None
        self.send({"kind": "finished", "job": job, "summary": summary,
                   "aborted": self.abort_reason is not None, "t": self.system.clock.now()})
        self.send(self.snapshot().to_wire())

    def _ahead_of_the_operator(self) -> float:
        """On the simulated clock, a jog session in Move Robot runs at the pace of the wall
        clock (a person holds the button: heartbeats and the session's end count in
        seconds a person lives); how far (s, at most PACE_WAIT) the robot's clock is ahead of it.
        Elsewhere (a program, homing) the simulated clock runs as fast as it can: 0."""
        system = self.system
        if not system.clock.simulated or system.trajectory.jogger is None:
            self._paced = None
            return 0.0
        if self._paced is None:
            self._paced = (system.clock.tick_time, time.monotonic())
            return 0.0
        ahead = (system.clock.tick_time - self._paced[0]) - (time.monotonic() - self._paced[1])
        return min(ahead, PACE_WAIT) if ahead > TICK else 0.0

    def run(self, channel) -> None:
        """The loop process's main loop, until an ``exit`` has brought the robot to rest
        (or the server is gone: then the running cycle is stopped first)."""
        from runtime.wire.channel import ChannelClosed

        while True:
            try:
                if self.job is None and not self.commands:
                    if self.exit_reason is not None:
                        break
                    channel.wait(0.05)  # idle: nothing moves, brakes on (not a real-time state)
                elif not self.commands:
                    ahead = self._ahead_of_the_operator()
                    if ahead > 0.0:
                        channel.wait(ahead)  # (a command wakes it at once)
                self.commands.extend(channel.receive())
            except ChannelClosed:
                if self.exit_reason is None:
                    self._exit(messages.Exit("the server process ended"))
                    if self.job is None:
                        break
            self.turn()
            if channel.pending:
                channel.flush()
        channel.drain(5.0)


#: The handler of every command (runtime.wire.messages.COMMANDS, which says what each does).
COMMANDS: dict[str, Callable[[RobotLoop, messages.Command], dict]] = {
    messages.Start.OP: RobotLoop._start,
    messages.Pause.OP: RobotLoop._pause,
    messages.Resume.OP: RobotLoop._resume,
    messages.Abort.OP: RobotLoop._abort,
    messages.Estop.OP: RobotLoop._estop,
    messages.Override.OP: RobotLoop._override,
    messages.Call.OP: RobotLoop._call,
    messages.Settings.OP: RobotLoop._settings,
    messages.Exit.OP: RobotLoop._exit,
    messages.Mode.OP: RobotLoop._mode,
    messages.Jog.OP: RobotLoop._jog,
    messages.Step.OP: RobotLoop._step,
    messages.Persistent.OP: RobotLoop._persistent,
}


def run_options(spec, options: LoopOptions) -> RunOptions:
    """The robot's options in the loop process: the cell scenario's and the PLC's files
    read here (ValueError: what is wrong with them, in the command line's words)."""
    problem = options.problem()
    if problem is not None:
        raise ValueError(problem)
    from runtime.hardware.backends import load_io_files

    cell, fieldbus = load_io_files(options.cell, options.fieldbus, spec)
    return RunOptions(seed=options.seed, realtime=options.realtime, state_dir=options.state_dir,
                      deadline_policy=options.deadline_policy, cell=cell, fieldbus=fieldbus, mode=options.mode)


def in_process(spec, options: LoopOptions, send) -> RobotLoop:
    """The loop in the server's own process (tests: ``ServeOptions(loop_process=False)``),
    sending its messages through ``send``."""
    return RobotLoop(spec, run_options(spec, options), send)


def child(spec, options: LoopOptions, channel, servers_end) -> None:
    """The loop process (forked by the server: runtime/server/looplink.py): build the robot,
    ask for real-time scheduling, serve the loop."""
    servers_end.close()  # (inherited: kept open, the server's death would never be seen)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the server decides how to stop (Ctrl-C reaches both)

    loop_ref: list = []

    def terminate(*_):  # a SIGTERM sent to this process alone: bring the robot to rest, then end
        if loop_ref and loop_ref[0].exit_reason is None:
            loop_ref[0].commands.append(messages.Exit("the loop process was terminated").to_wire(None))

    signal.signal(signal.SIGTERM, terminate)
    try:
        run = run_options(spec, options)
    except ValueError as exc:  # the options given: the command line's error
        channel.send({"kind": "failed", "error": str(exc), "usage": True})
        channel.drain(5.0)
        os._exit(1)
    try:
        loop = RobotLoop(spec, run, channel.send)
    except Exception as exc:
        channel.send({"kind": "failed", "error": f"{type(exc).__name__}: {exc}"})
        channel.drain(5.0)
        os._exit(1)
    loop_ref.append(loop)
    got = None
    if run.realtime:  # by default (none given) the real-time scheduling irl serve asks for
        from runtime.loop.realtime import DEFAULT, apply

        got = apply(options.scheduling if options.scheduling is not None else DEFAULT)
    sys.setswitchinterval(0.0005)  # a helper thread (a planner, the report writer) hands the GIL back quickly
    channel.send(loop.ready(got))
    try:
        loop.run(channel)
    finally:
        channel.close()
    os._exit(0)
