"""Trajectory Generator: the program's interpreter and its motion host, every 5 ms.

It runs the program's object code (``runtime.loop.vm``, a bounded number of instructions per
update) and feeds the moves it hands over to the motion queue
(:mod:`runtime.motion.motionqueue`: planning, look-ahead, blending, the override,
pause/resume/abort), whose setpoint it writes to ``desi_pos`` (time, positions,
velocities) every period; the servo interpolates them to 1 ms.

Look-ahead: a move instruction hands a request to the queue and the program runs on: up
to ``lookahead`` moves (the specification's ``[controller] lookahead``, default 4) may
wait planned ahead of the robot; the VM stops running ahead at instructions that must
happen where the robot really is (waits, digital I/O, ``print``, ``pause``; see
``runtime.loop.vm``).

Planning is synchronous on the simulated clock (deterministic: simulated time does not
pass); on the wall clock it runs on one planning worker, started by :meth:`load`.

A move that cannot be planned (a refused path, an unreachable pose) stops the program
at its line: the moves before it are completed first, then the program ends with the
error, as if there were no look-ahead.
"""
from __future__ import annotations

import time
from typing import Callable

from compiler.clauses import Motion, MoveClauses, validate_move_clauses
from compiler.frames import BY_KEYWORD as FRAME_BY_KEYWORD
from compiler.frames import IDENTITY, describe_name, pose_of, values_of
from compiler.frames import problem as frame_problem
from compiler.objcode import OP, Program
from compiler.params import component_params, describe
from compiler.spec import DEFAULT_LOOKAHEAD
from compiler.configs import config_of
from compiler.recovery import BY_NAME as ERROR_KINDS
from compiler.robotstate import group_problem, group_value_problem
from compiler.zones import forbidden
from compiler.semantics import EvalError, compose, inverse
from compiler.triggers import MAX_PENDING as MAX_TRIGGERS
from compiler.triggers import problem as trigger_problem
from compiler.values import Joint, Pose

from runtime.loop.component import Component, DataPort
from runtime.loop.jogging import HEARTBEAT_TIMEOUT, Jogger
from runtime.loop.stepping import Stepping
from runtime.motion.kinematics import Kinematics
from runtime.recording import LOG_FULL, PRINT
from runtime.motion.motionqueue import MotionQueue, PlanningWorker
from runtime.motion.tcp import TcpOf
from runtime.loop.search import Search
from runtime.motion.moves import Frames, MoveRecord, MovePlanner, MoveRequest
from runtime.settings import Settings
from runtime.timing import SETPOINT_PERIOD
from runtime.wire.protocol import JOG_SESSION_ENDING, ProtocolError
from runtime.loop.vm import DONE, ERROR, READY, VM, ProgramError

__all__ = ["LOOKAHEAD", "MAX_LOG_LINES", "MoveRecord", "TIME_SLICE", "TrajectoryGenerator"]

#: Moves planned ahead of the robot by default (``[controller] lookahead``).
LOOKAHEAD = DEFAULT_LOOKAHEAD
#: Seconds of interpreter time per update on the wall clock (runtime.loop.vm: the step ends at
#: the first slice of instructions after it); none on the simulated clock (deterministic).
TIME_SLICE = 0.0005
#: Lines of the operator log (print) kept per program; later ones are counted, not kept.
MAX_LOG_LINES = 10_000


def motion_profile(spec) -> str:
    """The PTP velocity profile the specification asks for (``[controller] profile``,
    checked when the specification was loaded)."""
    return spec.controller.profile


def lookahead_depth(spec) -> int:
    """How many moves may be planned ahead of the robot (``[controller] lookahead``,
    0..16, default 4; 0: the program waits for each move to end)."""
    return spec.controller.lookahead


def _build_kinematics(spec) -> tuple[Kinematics | None, str | None]:
    """Not real-time: the robot's kinematics, or None and why a pose cannot be used."""
    try:
        return Kinematics(spec), None
    except ValueError as exc:
        return None, f"this robot's kinematics are not usable for poses: {exc}"


def _io_number(n: int, count: int, what: str, kind: str = "digital") -> int:
    """``n`` when ``kind`` ``what`` (digital input, output; analog input) ``n`` exists
    (1..``count``); else EvalError."""
    if not 1 <= n <= count:
        raise EvalError(f"{kind} {what} {n} does not exist ({f'1..{count}' if count else 'there are none'})")
    return n


class TrajectoryGenerator(Component):
    """Operator control (real-time safe, called between ticks): :meth:`pause` stops the
    program before its next instruction and brings the motion to a controlled stop on
    its path; :meth:`resume` continues; :meth:`abort` stops the same way, then ends the
    program with a fault; ``override`` (percent) scales the time of the moves, the one
    under way too. The motion itself is :attr:`motion`, a
    :class:`~runtime.motion.motionqueue.MotionQueue`."""

    PROPERTIES = component_params("trajectory")

    def __init__(self, spec, robot, desi_pos: DataPort, sens_pos: DataPort, clock, period: float = SETPOINT_PERIOD,
                 settings: Settings | None = None):
        settings = settings if settings is not None else Settings(spec)
        super().__init__("trajectory", period, settings)
        self.own = settings.trajectory  # budget
        self.spec, self.robot, self.desi_pos, self.sens_pos = spec, robot, desi_pos, sens_pos
        self.clock = clock
        self.persistent = None  # the persistent variables' store (runtime.loop.persistence), or None
        self.lookahead = lookahead_depth(spec)
        self.program: Program | None = None
        self.vm: VM | None = None
        self.log_lines: list[tuple[float, int, str, str]] = []
        self.fault: str | None = None
        self.start_position: tuple | None = None  # the commanded position to plan from (else sens_pos)
        self.safety = None  # the safety supervisor: told when the motion is at rest, and of stops on the path
        self.io = None  # the io component (runtime.loop.components.io): the program's inputs and outputs
        # real-time: told the time of the program's first step (a simulated cell's timelines count from it)
        self.on_program_start: Callable[[float], None] | None = None
        self.started_at: float | None = None  # the time of the program's first step (None: not yet)
        # the robot's kinematics, built here (never in a tick), or why poses cannot be used
        kinematics, problem = _build_kinematics(spec)
        self.planner = MovePlanner(spec.axes, spec.main_axes, motion_profile(spec), kinematics, problem,
                                   forbidden(spec.zones))
        self.tcp = TcpOf(kinematics) if kinematics is not None else None  # the arm with each tool (cached)
        self.search = Search()  # a search move's watch (runtime.loop.search)
        self.motion = MotionQueue(self.planner, spec.axes, holds=self._holds, program_line=self._program_line)
        # the motion queue plans at most at robot.velocity_limit_scale (told of every change)
        self._set_velocity_limit_scale(settings.robot.velocity_limit_scale)
        settings.watch("robot", "velocity_limit_scale", self._set_velocity_limit_scale)
        #: the base and tool jogs use: the last program's last move's (runtime.loop.jogging)
        self.jog_frames = Frames.default(spec)
        self.jogging = False  # the cycle is a jog session (no program)
        self.jogger: Jogger | None = None
        self._jog_waiting: tuple | None = None  # (request, time) of a jog asked for before Move Robot
        self.stepping = Stepping()  # step mode and a start from a line (runtime.loop.stepping)
        self._forget()

    def load(self, program: Program | None, jog: bool = False, step: bool = False,
             from_line: int | None = None) -> None:
        """Not real-time: the program to run at the next start (or, with ``jog``, a jog
        session: runtime.loop.jogging), in step mode (``step``) and from the move on line
        ``from_line`` (runtime.loop.stepping; a line with a move: RobotSystem.begin checks
        it); forgets the last one (its moves and log, its fault, an abort). On the wall
        clock, starts the planning worker the first time (never in a tick)."""
        if not self.clock.simulated and self.motion.worker is None:
            self.motion.worker = PlanningWorker()
        if self.motion.moves:
            self.jog_frames = self.frames_now()
        self.program = program
        self.jogging = jog
        self._jog_waiting = None
        self.stepping = Stepping(step and not jog, None if jog else from_line)
        # step mode: a move is handed over only when the one before it has ended (no blend)
        self.lookahead = 0 if self.stepping.step else lookahead_depth(self.spec)
        self._forget()

    @property
    def axes(self) -> tuple:
        return self.spec.axes

    @property
    def n(self) -> int:
        """How many axes the robot has."""
        return len(self.spec.axes)

    @property
    def default_frames(self) -> Frames:
        """The world as base and the specification's tool: a program's frames at its start."""
        return Frames.default(self.spec)

    def _forget(self) -> None:
        self.vm = None
        self.started_at = None
        self.triggers: list = []  # handed over by the program, for its next move
        self.frames = self.default_frames  # the active base and tool (use base, use tool)
        self.log_lines = []
        self.log_dropped = 0
        self.fault = None
        self.jogger = None
        self.pulses: dict[int, float] = {}  # output -> when its pulse ends (pulse_out)
        self.motion.reset()
        self.search.reset()

    def on_start(self) -> bool:
        """Run the loaded program from its beginning (or begin the jog session)."""
        if self.program is None and not self.jogging:
            return False
        self._forget()
        position = self.start_position or self.sens_pos.read() or (0.0,) * self.n
        self.motion.start(position, self.period)
        if self.jogging:
            self.jogger = Jogger(self, self.clock.tick_time)
            waiting, self._jog_waiting = self._jog_waiting, None
            if waiting is not None:
                jog, at = waiting
                if jog.step is not None or self.clock.tick_time - at <= HEARTBEAT_TIMEOUT:
                    try:
                        self.jogger.request(jog, self.clock.tick_time)
                    except ProtocolError as exc:
                        self.jogger.reason = exc.message
        else:
            self.vm = VM(self.program, self, self.own.budget)
            if self.program.persistent and (self.persistent is None or self.persistent.path is None):
                declared = next((self.program.line_at(i)[0] for i, instr in enumerate(self.program.code)
                                 if instr[0] == OP.PERS_LOAD), 0)  # (as bounded as the VM's own decoding)
                self.log("its persistent variables are kept for this run only: there is no state directory "
                         "(irl run --state-dir DIR; irl serve keeps them)", declared)
            if self.stepping.active:
                self.stepping = self.stepping.fresh()
                self.stepping.install(self.vm, self)
        # the first setpoint at this tick's time, as every later one (never the wall clock's
        # now: after a stall of the host that lies ahead of the ticks, and the servo would
        # interpolate from it to where the move is by then)
        now = self.clock.tick_time
        self.desi_pos.write((now, self.motion.positions, self.motion.velocities), now)
        return True

    def _holds(self) -> bool:
        """The motion queue starts no new move: no program, or it paused itself."""
        vm = self.vm
        return (vm is None or vm.paused) and self.jogger is None

    def _program_line(self) -> int:
        return self.vm.line if self.vm is not None else 0

    # ---- what the rest of the runtime reads ----
    def frames_now(self) -> Frames:
        """Real-time: the base and tool of the move under way or last started (what the
        report and telemetry give the TCP in); the defaults before the first."""
        moves = self.motion.moves
        frames = moves[-1].frames if moves else None
        return self.default_frames if frames is None else frames

    @property
    def moves(self) -> list[MoveRecord]:
        """The moves of the program so far, as they ran (not a start's approach)."""
        return self.stepping.program_moves(self.motion.moves)

    @property
    def moves_done(self) -> int:
        """Real-time: the program's moves completed (not a start's approach)."""
        return self.stepping.moves_done(self.motion.moves, self.motion.completed)

    @property
    def trajectory(self):
        """What is being sampled now (a move or a stop); None when the robot is not moving."""
        return self.motion.current

    @property
    def override(self) -> float:
        """The speed override in percent (1-100); see :attr:`MotionQueue.override`."""
        return self.motion.override

    @override.setter
    def override(self, percent: float) -> None:
        self.motion.override = percent

    def _set_velocity_limit_scale(self, scale: float) -> None:
        """Not real-time (told by the settings): robot.velocity_limit_scale, which the
        override's rate never exceeds."""
        self.motion.velocity_limit_scale = scale

    @property
    def finished(self) -> bool:
        """The program ended (DONE) and all its motion is complete (a jog session: it is over)."""
        if self.jogger is not None:
            return self.jogger.finished
        return (self.vm is not None and self.vm.status is DONE and self.fault is None and self.motion.done()
                and not self.pulses)  # (its last output pulse has ended)

    @property
    def line(self) -> int:
        """The source line of the move the robot is executing (stopping on, or waiting to
        resume); else of the instruction the program is at."""
        return self.source()[0]

    def source(self) -> tuple[int, int | None]:
        """Real-time: :attr:`line`, and the code offset of the program's instruction it is
        the line of (None: the line of a move under way, or no program)."""
        line = self.motion.line
        if line is not None:
            return line, None
        vm = self.vm
        return (vm.line, vm.offset) if vm is not None else (0, None)

    @property
    def waiting_for_step(self) -> bool:
        """Real-time: step mode: the program waits before a move for the operator's step
        (not while it is paused or ending)."""
        vm = self.vm
        return self.stepping.waiting and vm is not None and not vm.paused and vm.status < DONE

    @property
    def paused(self) -> bool:
        """Held by the operator or by the program's ``pause``."""
        return self.vm is not None and (self.motion.paused or self.vm.paused)

    def _busy(self) -> bool:
        """The program has something left to do: instructions, or motion it handed over."""
        vm = self.vm
        return vm is not None and (vm.status < DONE or not self.motion.done())

    # ---- the 5 ms update (real-time) ----
    def update(self, now: float) -> None:
        """Real-time: sample the motion, write the setpoint, then let the VM run its budget."""
        motion = self.motion
        if self.pulses:
            self._end_pulses(now)
        motion.sample(now)
        self._take_motion_events()
        if self.search.armed:
            self._expect_rest(self.search.watch(self.io.inputs.value, motion, self.sens_pos.read()))
        if self.jogger is not None:
            self.jogger.update(now)
        accelerations = motion.accelerations
        self.desi_pos.write((now, motion.positions, motion.velocities) if accelerations is None
                            else (now, motion.positions, motion.velocities, accelerations), now)
        safety = self.safety
        if safety is not None:
            safety.expect_standstill(motion.at_rest())
        vm = self.vm
        if vm is not None and vm.status < DONE:
            if vm.status is READY:
                self.started_at = now
                if self.on_program_start is not None:
                    self.on_program_start(now)
            vm.step(None if self.clock.simulated else time.perf_counter() + TIME_SLICE)
            if self.stepping.forwarding and self.fault is None:
                self.fault = self.stepping.unreached(vm)
                if self.fault is not None:
                    vm.abort()
        failed = motion.plan_waiting()
        if failed is not None:
            vm.fail(*failed)
        self._take_motion_events()
        if self.fault is None and vm is not None and vm.status is ERROR and motion.done(triggers=False):
            e = vm.error  # an error ends the program once the moves before it are done
            where = vm.program.file_at(e.offset)
            self.fault = f"program error at {f'{where} ' if where else ''}line {e.line}: {e.message}"

    def _take_motion_events(self) -> None:
        """A move that could not be planned in the background stops the program at its
        line; an abort at rest (or a rest that cannot be planned) ends it."""
        motion = self.motion
        if motion.failed is not None:
            problem, line, tag = motion.failed
            motion.failed = None
            if self.jogger is not None:
                self.jogger.failed(problem)
            else:
                self.search.cancel(motion)
                self.vm.fail(problem, line, tag)
        if motion.ended is not None:
            self.search.cancel(motion)
            ended, motion.ended = motion.ended, None
            if self.vm is not None:
                self.fault = self.fault or ended
                self.vm.abort()

    # ---- operator control (real-time safe) ----
    def pause(self) -> bool:
        """Hold the program; the motion decelerates to rest on its path. False if there
        is no program to pause."""
        if not self._busy() or self.motion.abort_reason is not None:
            return False
        self.vm.pause()
        self._expect_rest(self.motion.pause())
        return True

    def resume(self) -> bool:
        """Continue after :meth:`pause` (or the program's ``pause``)."""
        if not self.paused or self.motion.abort_reason is not None:
            return False
        self.vm.resume()
        if self.safety is not None:
            self.safety.rest_not_expected()
        self.motion.resume()
        self._take_motion_events()
        return True

    def step(self) -> str | None:
        """The operator's step (step mode): the move the program waits before (or the
        approach of a start from a line) goes. Why not, else None."""
        stepping = self.stepping
        if self.vm is None or not stepping.step:
            return "it does not run in step mode (submit it with step, irl run --step)"
        if self.paused:
            return "it is paused: resume it first"
        if self.motion.abort_reason is not None or self.vm.status >= DONE:
            return "it is ending"
        if not stepping.waiting:
            if stepping.forwarding:
                return f"it is running to the move at line {stepping.from_line} without moving"
            line = self.motion.line
            return (f"a move is under way (line {line})" if line is not None
                    else f"it is not waiting before a move (it is at line {self.line})")
        stepping.give()
        return None

    def jog(self, jog, now: float) -> dict:
        """A jog request of the jog session (runtime.loop.jogging.Jogger.request): kept
        until Move Robot when the session is still starting (homing, brakes)."""
        if self.jogger is None:
            self._jog_waiting = (jog, now)
            return {"active": None, "stopping": False, "reason": "the robot is starting", "jogs": 0}
        if not self.running:
            raise ProtocolError("refused", JOG_SESSION_ENDING)
        return self.jogger.request(jog, now)

    def abort(self, reason: str = "aborted by the operator") -> bool:
        """A controlled stop, then end the program with ``reason`` as its fault (a jog
        session: the jog stops on its path and the session ends)."""
        if self.jogger is not None:
            self.jogger.end(reason)
            return True
        if not self._busy():
            return False
        if self.motion.abort_reason is None:
            self.vm.pause()
            self._expect_rest(self.motion.abort(reason))
            self._take_motion_events()
        return True

    # ---- the VM's interrupts (real-time safe) ----
    def motion_line(self) -> int | None:
        """The source line of the move the robot is executing (None: none is)."""
        return self.motion.line

    def interrupt_stop(self) -> None:
        """An interrupt fired with ``stop``: the motion stops on its path (held while its
        handler runs)."""
        self._expect_rest(self.motion.interrupt_stop())

    def interrupt_release(self) -> None:
        """Its handler ended with ``then resume``: the motion goes on (the rest of the
        interrupted move from where the robot stopped)."""
        if self.safety is not None and not self.motion.paused:
            self.safety.rest_not_expected()
        self.motion.interrupt_release()
        self._take_motion_events()

    def interrupt_halt(self, reason: str) -> None:
        """The program ends by an interrupt (``then halt``, or ``halt`` in a handler): the
        motion stops on its path and the moves not yet made are dropped, without a fault."""
        self._expect_rest(self.motion.abort(reason, fault=False))
        self._take_motion_events()

    def _expect_rest(self, within: float | None) -> None:
        if within is not None and self.safety is not None:
            self.safety.expect_rest_within(within)

    def expect_rest(self, within: float | None) -> None:
        """Real-time safe: a stop on the path began, at rest within ``within`` s (None: it is
        already): the safety supervisor watches it end in time."""
        self._expect_rest(within)

    # ---- the VM's motion host ----
    def now(self) -> float:
        """The program's time (waits, timeouts): the tick's, as the motion's."""
        return self.clock.tick_time

    def move(self, kind: Motion, targets: tuple, clauses: dict, line: int, tag: int = 0) -> str | None:
        """The VM's move instruction: check the move, hand it to the motion queue; the
        problem of a move that cannot be made (the program stops at its line)."""
        checked = validate_move_clauses(kind, clauses, self.spec)  # the clause table's rules and defaults
        if isinstance(checked, str):
            return checked
        kind = Motion(kind)  # (one of them: checked)
        frames = self.frames
        if frames.base != IDENTITY:  # pose targets are in the active base
            base = pose_of(frames.base)
            targets = tuple(compose(base, t) if isinstance(t, Pose) else t for t in targets)
        if kind == Motion.PTP:
            target = targets[0]
            if isinstance(target, Pose):
                if self.planner.kinematics is None:
                    return self.planner.kinematics_problem
            elif not isinstance(target, Joint) or len(target.axes) != self.n:
                return f"the target must be a joint value with {self.n} axes"
            request = MoveRequest(kind, (target,), checked.speed, checked.acc, checked.approx, line, frames=frames,
                                  triggers=self._take_triggers(), tag=tag)
        else:
            request, problem = self._cartesian_request(kind, targets, checked, line)
            if problem is not None:
                return problem
            request.tag = tag
        if self.stepping.forwarding:  # a start from a line: moves before it are only remembered
            self.stepping.remember(request, self.vm.globals)
            return None
        if checked.search is not None:
            return self._search(request, checked.search)
        return self.motion.add(request)

    def _search(self, request: MoveRequest, n: int) -> str | None:
        """A search move (runtime.loop.search): handed over with the robot at rest and its
        input false, else it ends at once (found nothing)."""
        motion = self.motion
        if not motion.done():
            return "a search move starts with the robot at rest (SEARCH_BEGIN before it)"
        if not self.search.arm(n, request.line, self.frames, motion, self.io.input(n)):
            return None
        problem = motion.add(request)
        if problem is not None:
            self.search.cancel(motion)
        return problem

    def search_end(self) -> str | None:
        return self.search.end()

    def search_pose(self) -> Pose:
        found = self.search.found
        if found is None:
            raise EvalError("no search move has found its input yet: search_pose() is where the last one did")
        joints, frames = found
        return self._pose_at(joints, frames)

    def _take_triggers(self) -> tuple:
        triggers, self.triggers = tuple(self.triggers), []
        return triggers

    def trigger(self, place: int, unit: int, amount: object, action: tuple) -> str | None:
        """The VM's ``TRIGGER_OUT`` / ``TRIGGER_SET``: a trigger of the next move
        (compiler.triggers); the problem, else None. Object code is untrusted: never raises."""
        problem = trigger_problem(place, unit, amount)
        if problem is not None:
            return problem
        if len(self.triggers) >= MAX_TRIGGERS:
            return f"more than {MAX_TRIGGERS} triggers for one move"
        if action[0] == "out":
            _kind, n, value = action
            if not (isinstance(n, int) and not isinstance(n, bool) and 1 <= n <= self.spec.outputs):
                return f"digital output {describe(n)} does not exist (1..{self.spec.outputs})"
            if not isinstance(value, bool):
                return f"a digital output's value must be true or false, not {describe(value)}"
        self.triggers.append((place, unit, float(amount), action))
        return None

    def fire_triggers(self, now: float) -> None:
        """Real-time, every 1 ms: the triggers whose place the servo's reference has reached
        (within this tick): an output switched, or a variable set."""
        due = self.motion.due
        if not due:
            return
        keep = []
        for at, action in due:
            if at > now + 1e-9:
                keep.append((at, action))
            elif action[0] == "out":
                self.io.set_output(action[1], action[2])
            elif self.vm is not None:
                self.vm.globals[action[1]] = action[2]
        due[:] = keep

    def use_frame(self, keyword: str, name: object, value: object) -> str | None:
        """The VM's ``USE_BASE`` / ``USE_TOOL``: make ``value`` the active base or tool for
        the moves handed over after it (compiler.frames' bounds); the problem, else None.
        Object code is untrusted: never raises."""
        kind = FRAME_BY_KEYWORD.get(keyword)
        if kind is None:  # pragma: no cover - the VM names one of the two
            return f"unknown frame kind {keyword!r}"
        if not isinstance(value, Pose):
            return f"use {keyword}: expected a pose, not {describe(value)}"
        values = values_of(value)
        problem = frame_problem(kind, values)
        if problem is not None:
            return problem
        self.frames = self.frames.using(keyword, describe_name(name if isinstance(name, str) else "?"),
                                        tuple(float(v) for v in values))
        return None

    def queue_ready(self) -> bool:
        """May the program hand over another move (is there room in the look-ahead)?
        With ``lookahead = 0``: only when the last move has ended."""
        if self.lookahead == 0:
            return self.motion_done()
        return self.motion.queued < self.lookahead

    def _cartesian_request(self, kind: Motion, targets: tuple, clauses: MoveClauses, line: int):
        """``move lin TARGET`` / ``move circ VIA, TARGET``: the path is checked whole
        against the kinematics, the axis limits and velocities before it starts (a refused
        move leaves the robot where it is, and the program stops at its line with the
        reason and where along the path it fails)."""
        if self.planner.kinematics is None:
            return None, self.planner.kinematics_problem
        if not all(isinstance(target, (Joint, Pose)) for target in targets):
            return None, f"a {kind} target must be a pose or a joint value"
        return MoveRequest(kind, tuple(targets), clauses.speed, clauses.acc, clauses.approx, line,
                           frames=self.frames, triggers=self._take_triggers()), None

    def motion_done(self) -> bool:
        """Every move handed over has ended (and no stop is under way)."""
        return self.motion.done()

    # ---- the robot's own state (compiler.robotstate; real-time: one forward kinematics or two) ----
    def current_joint(self) -> Joint:
        """Where the robot stands: the commanded position of every axis."""
        n = len(self.spec.main_axes)
        q = tuple(float(v) for v in self.motion.positions)
        return Joint(q[:n], q[n:])

    def _arm(self, frames: Frames | None = None) -> Kinematics:
        """The arm with the program's active tool (or ``frames``' tool)."""
        if self.tcp is None:
            raise EvalError(self.planner.kinematics_problem)
        return self.tcp.arm((frames or self.frames).tool)

    def current_pose(self) -> Pose:
        """The TCP of the active tool in the active base, with the arm's configuration."""
        return self._pose_at(self.motion.positions, self.frames)

    def _pose_at(self, positions: tuple, frames: Frames) -> Pose:
        """The TCP of ``frames``' tool in their base at joint ``positions``, with the arm's
        configuration."""
        arm = self._arm(frames)
        joints = tuple(float(v) for v in positions[:6])
        pose = arm.forward_pose(joints)
        base = frames.base
        if base != IDENTITY:
            pose = compose(inverse(pose_of(base)), pose)
        return Pose(pose.position, pose.orientation, config_of(arm.configuration(joints), joints))

    def tool_position(self) -> tuple:
        """Real-time: where the active tool's centre point is in the world (x, y, z, mm),
        from the measured joints (the commanded ones where none are measured: an offline
        run). A simulated cell's sensors read it (runtime.hardware.sim.cell)."""
        joints = self.sens_pos.read() or self.motion.positions
        if self.tcp is None:
            raise EvalError(self.planner.kinematics_problem)
        return self.tcp.kinematics.flange_and_tcp(joints[:6], self.frames.tool[:3])[1]  # (no tool's tables built)

    def tcp_speed(self) -> float:
        """The TCP's speed (mm/s) from the commanded joint velocities (0 without kinematics)."""
        if self.planner.kinematics is None:
            return 0.0
        arm = self._arm()
        q = [float(v) for v in self.motion.positions[:6]]
        dt = 1e-4
        ahead = [v + w * dt for v, w in zip(q, self.motion.velocities[:6])]
        here, there = arm.forward(q), arm.forward(ahead)
        return ((there[0] - here[0]) ** 2 + (there[1] - here[1]) ** 2 + (there[2] - here[2]) ** 2) ** 0.5 / dt

    # ---- persistent variables (runtime.loop.persistence; real-time: no file is touched) ----
    def kept(self, name: str, type_: str) -> object:
        store = self.persistent
        return store.kept(self.program.name, name, type_) if store is not None else None

    def keep(self, name: str, type_: str, value: object) -> None:
        if self.persistent is not None:
            self.persistent.keep(self.program.name, name, type_, value)

    def read_input(self, n: int) -> bool:
        return self.io.input(_io_number(n, self.spec.inputs, "input"))

    def read_analog(self, n: int) -> float:
        channels = self.spec.analog_inputs
        try:
            value = self.io.analog_input(_io_number(n, len(channels), "input", "analog"))
        except IndexError as exc:  # (a backend without them: a PLC whose fieldbus file maps none)
            raise EvalError(str(exc)) from None
        problem = channels[n - 1].problem(n, value)
        if problem is not None:  # (a reading the sensor's range does not hold: its fault, the program's error)
            raise EvalError(problem)
        return value

    def write_output(self, n: int, value: bool) -> None:
        self.io.set_output(_io_number(n, self.spec.outputs, "output"), value)

    def read_output(self, n: int) -> bool:
        return self.io.output(_io_number(n, self.spec.outputs, "output"))

    def write_analog(self, n: int, value: float) -> None:
        channels = self.spec.analog_outputs
        n = _io_number(n, len(channels), "output", "analog")
        problem = channels[n - 1].problem(n, value, "output")
        if problem is not None:  # (the value's fault, not the I/O's)
            raise ProgramError(problem, ERROR_KINDS["value"].number)
        try:
            self.io.set_analog_output(n, float(value))
        except IndexError as exc:  # (a backend without them: a PLC whose fieldbus file maps none)
            raise EvalError(str(exc)) from None

    def read_analog_output(self, n: int) -> float:
        n = _io_number(n, len(self.spec.analog_outputs), "output", "analog")
        try:
            return self.io.analog_output(n)
        except IndexError as exc:
            raise EvalError(str(exc)) from None

    def read_group(self, first: int, bits: int) -> int:
        problem = group_problem(first, bits, self.spec.inputs, "input")
        if problem is not None:
            raise EvalError(problem)
        read = self.io.input
        return sum(1 << i for i in range(bits) if read(first + i))

    def write_group(self, first: int, bits: int, value: int) -> None:
        problem = group_problem(first, bits, self.spec.outputs, "output")
        if problem is not None:
            raise EvalError(problem)
        problem = group_value_problem(value, bits)
        if problem is not None:  # (the value's fault, not the I/O's)
            raise ProgramError(problem, ERROR_KINDS["value"].number)
        self.io.set_outputs(first, [bool(value >> i & 1) for i in range(bits)])

    def pulse_output(self, n: int, seconds: float) -> None:
        """Output ``n`` on now and off ``seconds`` later (:meth:`_end_pulses`, every update)."""
        self.write_output(n, True)
        self.pulses[n] = self.clock.tick_time + seconds

    def _end_pulses(self, now: float) -> None:
        """Real-time: the outputs whose pulse has ended, off."""
        for n, until in tuple(self.pulses.items()):
            if now >= until - 1e-9:
                del self.pulses[n]
                self.write_output(n, False)

    def log(self, text: str, line: int, kind: str = PRINT) -> None:
        """The operator log: ``(time, line, text, kind)`` (its kind of
        runtime.recording.EVENTS), at most MAX_LOG_LINES lines per program (then one line
        that says how many more were not kept)."""
        if len(self.log_lines) < MAX_LOG_LINES:
            self.log_lines.append((self.clock.tick_time, line, text, kind))
        else:
            self.log_dropped += 1
            if self.log_dropped == 1:
                self.log_lines.append((self.clock.tick_time, line, f"(more than {MAX_LOG_LINES} lines: the rest of "
                                                                   "the log is not kept)", LOG_FULL))
