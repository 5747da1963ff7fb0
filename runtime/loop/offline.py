"""A program run offline: what ``irl check`` does to find every motion problem before the
robot moves.

The program's object code runs on the trajectory generator's own VM, and its moves go
through the trajectory generator's own motion queue and planners (the same code path as
``irl run``: :class:`OfflineHost` *is* a
:class:`~runtime.loop.components.trajectory.TrajectoryGenerator`), stepped on the simulated
clock every 5 ms, without the 1 ms servo, the safety supervisor, the arm or homing: the
program starts at the specification's home position, where ``irl run`` starts it after
homing. Its I/O is a simulated cell: the one a scenario file describes (``--cell-scenario``,
exactly as ``irl run`` follows it), or, without one, the assumed cell of
:class:`AssumedWorld`.

Where the runtime would stop the program, the offline run records a :class:`Finding` and
goes on from where the robot would then be:

* a move the runtime would refuse (out of reach, a singularity on its path, an axis limit
  along it or at its target, a configuration change on a lin or circ move, a degenerate
  circle, a trigger beyond its path, a clause out of range): the run goes on as if the
  move had reached its target (a PTP move there stands in for it, at the specification's
  default speed), or, when the target has no joint values at all, from where the robot was;
* a refused trigger or ``use`` of a frame: it is left out;
* a blend that no shorter blend keeps within the axis limits: a warning (the robot stops
  at the corner instead);
* a run-time error of the program (a division by zero, an index out of range): the
  program would stop there, and so does this path.

Without a scenario (the documented rule, :class:`AssumedWorld`): inputs start false; every
``wait for`` is satisfied at once (its inputs are set so that the condition holds, if
setting them can make it hold); where the program reads an input elsewhere, or a ``wait
for`` with a time-out could also time out, both ways are explored (:func:`check_motion`
runs the program again with the other value), each choice once per place in the program
and position of the robot; ``pause`` resumes at once (as ``irl run`` does off a terminal).

Bounded: at most :data:`MAX_MOVES` moves and :data:`MAX_PATHS` runs in all, and per run
:data:`MAX_TIME` simulated seconds and :data:`MAX_INSTRUCTIONS` instructions; the outcome
says when a bound cut the check short.

Not real-time: this runs in the ``irl check`` process, never in a tick.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from compiler.clauses import Motion, validate_move_clauses
from compiler.frames import IDENTITY, pose_of
from compiler.objcode import OP, Program
from compiler.semantics import compose
from compiler.values import Joint, Pose

from runtime.hardware.interface import DigitalIo
from runtime.loop.component import DataPort
from runtime.loop.components.io import IoComponent
from runtime.loop.components.trajectory import TrajectoryGenerator
from runtime.loop.executive import SimClock
from runtime.loop.vm import DONE, ERROR
from runtime.motion.kinematics import configuration_name
from runtime.motion.moves import MoveRequest, Segment
from runtime.motion.trajectory import Refusal
from runtime.settings import Settings
from runtime.timing import TICK

__all__ = ["AssumedWorld", "Finding", "MAX_INSTRUCTIONS", "MAX_MOVES", "MAX_PATHS", "MAX_SEARCH_INPUTS",
           "MAX_TIME", "OfflineHost", "Outcome", "PlannedMove", "check_motion"]

#: Moves handed over in all runs of one check before it stops (a note says so).
MAX_MOVES = 2000
#: Runs of the program in one check: the main one and the branches explored.
MAX_PATHS = 16
#: Simulated seconds one run may take (``irl run``'s own limit).
MAX_TIME = 3600.0
#: Instructions one run may execute.
MAX_INSTRUCTIONS = 5_000_000
#: The most inputs a ``wait for``'s condition may read for the assumed cell to look for
#: values that make it hold (2^6 tries at most).
MAX_SEARCH_INPUTS = 6

#: The instructions whose place in the code the host needs while they execute.
_LOCATED = ("MOVE_PTP", "MOVE_LIN", "MOVE_CIRC", "TRIGGER_OUT", "TRIGGER_SET", "USE_BASE", "USE_TOOL", "IN_GET",
            "WAIT_BEGIN", "WAIT_TEST")


@dataclass
class Finding:
    """Something the runtime would refuse or fault on, at an instruction of the program
    (``offset``; ``file`` is the object code's: "" for the program's own source).
    ``kind``: ``"move"`` (a move refused), ``"trigger"``, ``"frame"``, ``"blend"`` (a
    warning: a corner not blended), ``"error"`` (a run-time error: the program stops),
    ``"bound"``. ``fraction`` and ``distance`` (mm): where along the move's path, when it
    is a path's problem. ``count``: how often (all runs); ``first``: which time the
    instruction ran when it first happened; ``assumed``: the choices of the run it was
    found in (empty: the main run)."""

    offset: int
    file: str
    line: int
    column: int
    kind: str
    message: str
    severity: str = "error"
    hint: str | None = None
    fraction: float | None = None
    distance: float | None = None
    count: int = 1
    first: int = 1
    assumed: tuple = ()


@dataclass
class PlannedMove:
    """A move of the main run as planned: where it is in the program, when it starts (s
    after the program started), its planned duration (s), whether it blends into the
    next, the joints it ends at and, for a pose target, the configuration they are in."""

    offset: int
    file: str
    line: int
    column: int
    kind: str
    start: float
    duration: float
    blended: bool
    joints: tuple
    configuration: str | None


@dataclass
class Choice:
    """A place where the assumed cell had a choice: the instruction (``offset``), its
    ``options`` (what each means: ``"in[3] reads true"``, ``"the wait for ends with in[11]
    true"``, ``"the wait for times out"``), the one ``taken`` (an index) and which time the
    instruction ran (``time``)."""

    offset: int
    options: tuple[str, ...]
    taken: int
    time: int


@dataclass
class Outcome:
    """The check of one program: its findings, the main run's moves and cycle time (the
    time ``irl run`` spends in Move Robot; None when the main run did not end), what was
    assumed, and notes (bounds)."""

    findings: list[Finding] = field(default_factory=list)
    moves: list[PlannedMove] = field(default_factory=list)
    assumed: list[str] = field(default_factory=list)  # what was assumed of the cell (none: nothing was)
    cycle_time: float | None = None
    ended: str = "completed"  # the main run: "completed", "stopped" (a run-time error), "bounded"
    notes: list[str] = field(default_factory=list)
    paths: int = 1


class _OfflineIo(DigitalIo):
    """The simulated cell's I/O: its inputs are the world's side (a scenario, the assumed cell)."""

    forcible = True


class AssumedWorld:
    """The cell the check assumes without a scenario (module docstring). Every input is
    false until something sets it. Where the program reads an input (not in a ``wait
    for``), it is a choice of its two values, the one it has first, unless a choice or a
    wait set it at this instant. A ``wait for`` that does not hold at once is a choice of
    the inputs' values that make it hold with the fewest changes (each one found by trying
    every value of at most :data:`MAX_SEARCH_INPUTS` inputs its condition reads, at the
    same instant), and of its time-out; with none of these it waits (something else may
    end it). Choices are taken in order from ``decisions`` (a run that explores a branch:
    the index of the option), else the first option. ``choices`` lists those taken."""

    def __init__(self, backend: DigitalIo, io: IoComponent, decisions: tuple = ()):
        self.backend, self.io = backend, io
        self.decisions = decisions
        self.choices: list[Choice] = []
        self.decided: dict[int, float] = {}  # input -> when a choice or a wait last set it
        self.runs: dict[int, int] = {}  # instruction -> how many times it ran
        self.waits: list[_Wait] = []  # the waits under way (a handler's above the program's)
        self.visits: dict[tuple, int] = {}  # (read, robot position) -> moves handed over then
        self.idle: str | None = None  # why the run idles for ever (a poll that comes back unchanged)
        self.waited: set[int] = set()  # the waits for that ran (their WAIT_BEGIN)

    def ran(self, offset: int) -> None:
        self.runs[offset] = self.runs.get(offset, 0) + 1

    def _choose(self, offset: int, options: tuple[str, ...], time: int | None = None) -> int:
        k = len(self.choices)
        taken = min(self.decisions[k], len(options) - 1) if k < len(self.decisions) else 0
        self.choices.append(Choice(offset, options, taken, self.runs.get(offset, 1) if time is None else time))
        return taken

    def read(self, n: int, offset: int, now: float, where: tuple, moves: int, line: str) -> None:
        """The program reads input ``n`` at ``offset`` (the robot at ``where``, ``moves``
        handed over so far)."""
        if self.waits:
            wait = self.waits[-1]
            if wait.phase == "first" and n not in wait.reads:
                wait.reads.append(n)
            return
        if self.decided.get(n) == now:
            return
        if self.visits.get(where) == moves:  # back here, nothing moved: it polls for ever
            self.idle = (f"the program reads in[{n}] at {line} again and again without moving: in the assumed cell "
                         "(no input changes) it would poll there for ever")
        self.visits[where] = moves
        current = self.backend.input(n)
        values = (current, not current)
        value = values[self._choose(offset, tuple(f"in[{n}] reads {'true' if v else 'false'}" for v in values))]
        self.decided[n] = now
        if value != current:
            self._set({n: value}, now)

    def begin_wait(self, timeout: bool, offset: int) -> None:
        self.waits.append(_Wait(timeout, self.runs.get(offset, 1)))
        self.waited.add(offset)

    def tested(self, holds: bool, offset: int, now: float) -> bool:
        """A ``wait for``'s condition was evaluated: whether it may end the wait (False: the
        search goes on, or the wait is to time out)."""
        if not self.waits:
            return holds
        wait = self.waits[-1]
        if wait.phase == "first":
            if holds:
                return True
            wait.offset = offset
            wait.begin_search({n: self.backend.input(n) for n in wait.reads[:MAX_SEARCH_INPUTS]})
            return False
        if wait.phase == "search":
            if holds:
                wait.found()
            return False
        if wait.phase == "commit" and holds:
            for n in wait.start:
                self.decided[n] = now
            return True
        return holds if wait.phase == "waits" else False

    def passed(self) -> None:
        """The ``wait for`` ended (its condition held, or it timed out)."""
        if self.waits:
            self.waits.pop()

    def searching(self) -> bool:
        return bool(self.waits) and self.waits[-1].phase in ("search", "commit")

    def next_try(self, now: float) -> None:
        """The inputs for the next evaluation of the wait's condition at this instant: the
        next values the search tries, or once all are tried the values chosen."""
        wait = self.waits[-1]
        if wait.phase == "commit":  # (the chosen values did not make it hold: it waits)
            wait.phase = "waits"
            self._set(wait.start, now)
            return
        if wait.tries:
            self._set(wait.next(), now)
            return
        options = wait.options()
        if not options:
            wait.phase = "waits"
            self._set(wait.start, now)
            return
        chosen = options[self._choose(wait.offset, tuple(label for label, _values in options), wait.time)][1]
        wait.phase = "commit" if chosen is not None else "times out"
        self._set(chosen if chosen is not None else wait.start, now)

    def stuck(self) -> bool:
        """The wait under way can never end here: no input values make it hold and it has
        no time-out."""
        return bool(self.waits) and self.waits[-1].phase == "waits" and not self.waits[-1].timeout

    def _set(self, values: dict, now: float) -> None:
        for n, value in values.items():
            self.backend.set_input(n, value)
        self.io.refresh(now)


class _Wait:
    """A ``wait for`` under way in the assumed cell: the inputs its condition read at first
    (``reads``), whether it has a time-out, and its search: ``phase`` "first" (not tested
    yet), "search" (trying ``tries``; ``satisfying`` those that made it hold), "commit" (the
    chosen values set: the next test ends it), "times out" or "waits" (nothing makes it hold)."""

    def __init__(self, timeout: bool, time: int):
        self.timeout = timeout
        self.time = time  # which time the wait runs
        self.reads: list[int] = []
        self.phase = "first"
        self.offset = 0
        self.start: dict[int, bool] = {}
        self.tries: deque = deque()
        self.trying: dict[int, bool] = {}
        self.satisfying: list[dict[int, bool]] = []

    def begin_search(self, start: dict[int, bool]) -> None:
        reads = list(start)
        self.start = start
        order = sorted(range(1, 1 << len(reads)), key=lambda m: (bin(m).count("1"), m))  # fewest changes first
        self.tries = deque({n: start[n] != bool(m >> i & 1) for i, n in enumerate(reads)} for m in order)
        self.phase = "search"

    def next(self) -> dict[int, bool]:
        self.trying = self.tries.popleft()
        return self.trying

    def found(self) -> None:
        self.satisfying.append(self.trying)

    def options(self) -> list[tuple[str, dict | None]]:
        """What may end it: each set of values that makes it hold with the fewest changes,
        then its time-out."""
        def changes(values):
            return sum(values[n] != self.start[n] for n in values)

        fewest = min((changes(v) for v in self.satisfying), default=0)
        options: list[tuple[str, dict | None]] = []
        for values in self.satisfying:
            if changes(values) == fewest:
                set_ = [f"in[{n}] {'true' if v else 'false'}" for n, v in values.items() if v != self.start[n]]
                options.append((f"the wait for ends with {' and '.join(set_)}", values))
        if self.timeout:
            options.append(("the wait for times out", None))
        return options


class OfflineHost(TrajectoryGenerator):
    """The trajectory generator, run offline (module docstring): what the runtime would
    refuse is recorded (``findings``) and the run goes on; every move accepted is kept
    with its place in the code (``planned``)."""

    def __init__(self, spec, settings: Settings, clock: SimClock, world_io: IoComponent,
                 world: AssumedWorld | None):
        super().__init__(spec, None, DataPort("desi_pos"), DataPort("sens_pos"), clock, settings.trajectory.period,
                         settings)
        self.io = world_io
        self.world = world
        self.findings: list[Finding] = []
        self.planned: list[tuple[int, Segment]] = []  # (offset, segment) of every move accepted
        self.corners: dict[int, tuple] = {}  # a move with approx -> (times blended, times not, its approx)
        self.at = 0  # the offset of the located instruction executing
        self.reading = False  # the program (not an interrupt's condition) reads an input

    def on_start(self) -> bool:
        if not super().on_start():
            return False
        for name in _LOCATED:
            self.vm.wrap(name, self._located)
        return True

    def _located(self, handler):
        def run(operand, pc):
            self.at = pc
            world = self.world
            if world is None:
                return handler(operand, pc)
            world.ran(pc)
            op = self.program.code[pc][0]
            if op == OP.IN_GET:
                self.reading = True
                try:
                    return handler(operand, pc)
                finally:
                    self.reading = False
            if op == OP.WAIT_BEGIN:
                world.begin_wait(bool(operand), pc)
            elif op == OP.WAIT_TEST:
                stack = self.vm.stack
                if not world.tested(bool(stack[-1]), pc, self.now()):
                    stack[-1] = False  # (the search goes on, or it is to time out)
                following = handler(operand, pc)
                if following == pc + 1:
                    world.passed()
                return following
            return handler(operand, pc)
        return run

    def read_input(self, n: int) -> bool:
        world = self.world
        if world is not None and self.reading and 1 <= n <= self.spec.inputs:
            line, _column = self.program.line_at(self.at)
            file = self.program.file_at(self.at)
            where = (self.at,) + tuple(round(v, 3) for v in self.motion.positions)
            world.read(n, self.at, self.now(), where, len(self.planned), f"line {line}" + (f" of {file}" if file else ""))
        return super().read_input(n)

    # ---- what the runtime would refuse: recorded, and the run goes on ----
    def record(self, kind: str, message: str, offset: int | None = None, severity: str = "error",
               hint: str | None = None) -> None:
        offset = self.at if offset is None else offset
        program = self.program
        line, column = program.line_at(offset)
        fraction = distance = None
        if isinstance(message, Refusal):
            fraction, distance = message.fraction, message.distance
        runs = self.world.runs.get(offset, 1) if self.world is not None else 1
        self.findings.append(Finding(offset, program.file_at(offset), line, column, kind, str(message), severity,
                                     hint, fraction, distance, 1, runs))

    def move(self, kind: Motion, targets: tuple, clauses: dict, line: int) -> str | None:
        before = self.motion.last_planned
        problem = super().move(kind, targets, clauses, line)
        if problem is None:
            segment = self.motion.last_planned
            if segment is not None and segment is not before:
                self._accepted(segment)
            return None
        self.triggers = []  # (a refused move's triggers go with it)
        self.record("move", problem)
        self._stand_in(kind, targets, line)
        return None

    def _accepted(self, segment: Segment) -> None:
        self.planned.append((self.at, segment))
        previous = segment.previous
        if previous is not None and previous.blendable:  # a corner with approx: blended, or not
            offset = next((o for o, s in reversed(self.planned) if s is previous), None)
            if offset is not None:
                blended, refused, _approx = self.corners.get(offset, (0, 0, 0.0))
                approx = previous.request.approx
                self.corners[offset] = ((blended + 1, refused, approx) if segment.offset is not None else
                                        (blended, refused + 1, approx))

    def _stand_in(self, kind: Motion, targets: tuple, line: int) -> None:
        """A refused move: go on as if it had reached its target (a PTP move there, at the
        specification's default speed), or stay where the robot is when its target has no
        joint values."""
        target = targets[-1] if targets else None
        frames = self.frames
        joints = None
        if isinstance(target, Pose) and self.planner.kinematics is not None:
            if frames.base != IDENTITY:
                target = compose(pose_of(frames.base), target)
            joints, _problem = self.planner.joint_target(target, self.motion.planning_start(), frames)
        elif isinstance(target, Joint) and len(target.axes) == self.n:
            if all(axis.target_problem(v) is None for axis, v in zip(self.axes, target.axes)):
                joints = target
        if joints is None:
            return
        defaults = validate_move_clauses(Motion.PTP, {}, self.spec)
        if isinstance(defaults, str):
            return
        self.motion.add(MoveRequest(Motion.PTP, (joints,), defaults.speed, defaults.acc, 0.0, line, frames=frames))

    def trigger(self, place: int, unit: int, amount: object, action: tuple) -> str | None:
        problem = super().trigger(place, unit, amount, action)
        if problem is not None:
            self.record("trigger", problem)
        return None

    def use_frame(self, keyword: str, name: object, value: object) -> str | None:
        problem = super().use_frame(keyword, name, value)
        if problem is not None:
            self.record("frame", problem)
        return None


@dataclass
class _Limits:
    moves: int = MAX_MOVES
    time: float = MAX_TIME
    instructions: int = MAX_INSTRUCTIONS


class _Run:
    """One run of the program offline, with the choices ``decisions`` (None: with the
    cell ``scenario``)."""

    def __init__(self, program: Program, spec, scenario, decisions: tuple | None, limits: _Limits,
                 setpoints: bool = False, cache: dict | None = None):
        self.spec, self.limits = spec, limits
        self.clock = SimClock(TICK)
        settings = Settings(spec)
        self.backend = _OfflineIo(spec.inputs, spec.outputs, "the cell")
        cell = None
        if scenario is not None:
            from runtime.hardware.sim.cell import Cell

            cell = Cell(scenario, self.backend)
        self.cell = cell
        self.io = IoComponent(self.backend, cell)
        self.io.configure()
        self.world = AssumedWorld(self.backend, self.io, decisions or ()) if scenario is None else None
        self.host = OfflineHost(spec, settings, self.clock, self.io, self.world)
        self.host.motion.setpoints = setpoints
        self.host.planner.cache = cache
        self.host.start_position = tuple(float(axis.home) for axis in spec.axes)
        self.host.load(program)
        self.ended = "completed"
        self.end_time: float | None = None
        self.notes: list[str] = []

    def run(self, moves_left: int) -> None:
        """Run from the program's start to its end, an error, or a bound."""
        host, clock, io, cell, world = self.host, self.clock, self.io, self.cell, self.world
        if cell is not None:
            cell.reset(0.0)
        io.start()
        if cell is not None:
            cell.start_program(0.0)
        host.start()
        every = max(1, round(host.period / TICK))
        vm = host.vm
        outputs = io.outputs.value
        while True:
            now = clock.tick_time
            if cell is not None:  # the tick's first task: the cell acts, the inputs are read
                io.update(now)
                outputs = io.outputs.value
            host.update(now)
            while world is not None and world.searching() and vm.status < DONE:
                world.next_try(now)
                vm.step()  # (the same instant: the wait for is satisfied at once if it can be)
            host.fire_triggers(now)
            if vm.paused and not host.motion.paused:
                host.resume()  # (irl run off a terminal: a pause resumes at once)
            if host.finished:
                self.end_time = now + TICK  # (the supervisor sees it at the next tick)
                return
            if vm.status is ERROR:
                self._stopped()
                return
            if world is not None and self._endless(world):
                return
            if self._bound(moves_left, now):
                return
            # the 1 ms ticks before the next update, where something happens in them: a
            # trigger due, the cell seeing an output change (a tick after it, as in irl run)
            k = 1
            while k < every and (host.motion.due or (cell is not None and io.outputs.value is not outputs)):
                clock.ticks += 1
                k += 1
                t = clock.tick_time
                if cell is not None and io.outputs.value is not outputs:
                    io.update(t)
                    outputs = io.outputs.value
                host.fire_triggers(t)
            clock.ticks += every - k + 1

    def _endless(self, world: AssumedWorld) -> bool:
        """The run can never end in the assumed cell: it polls an input for ever, or waits
        for what nothing will change."""
        host = self.host
        if world.idle is not None:
            self.ended = "idles"
            self.notes.append(world.idle + "; the check stops this run there")
            return True
        if world.stuck() and host.motion.done() and not host.vm.interrupts.armed:
            host.record("wait", "this wait for can never end in the assumed cell: no values of the inputs it reads "
                                "make its condition hold, it has no time-out, and nothing else changes (no move, "
                                "trigger or interrupt is left): the program would wait here for ever",
                        world.waits[-1].offset, "warning")
            self.ended = "waits"
            return True
        return False

    def _bound(self, moves_left: int, now: float) -> bool:
        if len(self.host.planned) > moves_left:
            why = f"the check stopped after {moves_left} moves (the most it checks; --max-moves)"
        elif self.host.vm.instructions > self.limits.instructions:
            why = f"the check stopped after {self.limits.instructions:,} instructions of the program"
        elif now >= self.limits.time:
            why = f"the program did not end within {self.limits.time:g} s"
        else:
            return False
        self.ended = "bounded"
        self.notes.append(why)
        return True

    def _stopped(self) -> None:
        vm = self.host.vm
        e = vm.error
        self.host.record("error", e.message, e.offset)
        self.ended = "stopped"

    def _bounded(self, why: str) -> None:
        self.ended = "bounded"
        self.notes.append(why)


def _describe_choice(program: Program, choice: Choice, option: int) -> str:
    line = program.line_at(choice.offset)[0]
    where = program.file_at(choice.offset)
    at = f"line {line}" + (f" of {where}" if where else "")
    nth = f" (the {_ordinal(choice.time)} time)" if choice.time > 1 else ""
    return f"{choice.options[option]} at {at}{nth}"


def _lines(program: Program, offsets) -> str:
    places = sorted({(program.file_at(o), program.line_at(o)[0]) for o in offsets})
    text = ", ".join(f"{line}" + (f" of {file}" if file else "") for file, line in places[:8])
    return f"line{'s' if len(places) > 1 else ''} {text}" + (f" and {len(places) - 8} more" if len(places) > 8 else "")


def _assumptions(program: Program, worlds: list, explored: list[str]) -> list[str]:
    """What the runs assumed of the cell (nothing, when the program neither reads an input
    nor waits for one)."""
    waited = set().union(*(w.waited for w in worlds))
    read = {c.offset for w in worlds for c in w.choices if c.options[0].startswith("in[")}
    if not waited and not read:
        return []
    said = ["no cell scenario: the inputs are false until the program waits for them"]
    if waited:
        said.append(f"each wait for ends at once where inputs can make it hold ({_lines(program, waited)})")
    if explored:
        shown = "; ".join(explored[:6]) + (f"; and {len(explored) - 6} more" if len(explored) > 6 else "")
        said.append(f"also run with the other way of each choice: {shown}")
    return said


def _ordinal(n: int) -> str:
    return f"{n}{'th' if 10 <= n % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(n % 10, 'th')}"


def _merge(findings: dict, run: _Run, assumed: tuple, corners: dict) -> None:
    for offset, (blended, refused, approx) in run.host.corners.items():
        was = corners.get(offset, (0, 0, approx, assumed))
        corners[offset] = (was[0] + blended, was[1] + refused, approx, was[3])
    for f in run.host.findings:
        key = (f.offset, f.kind)
        known = findings.get(key)
        if known is None:
            f.assumed = assumed
            findings[key] = f
        else:
            known.count += 1


def _planned_moves(run: _Run) -> list[PlannedMove]:
    host = run.host
    program, kinematics = host.program, host.planner.kinematics
    moves = []
    for offset, segment in host.planned:
        record = segment.record
        if record is None:
            continue
        line, column = program.line_at(offset)
        configuration = None
        target = segment.request.targets[-1]
        if isinstance(target, Pose) and kinematics is not None:
            configuration = configuration_name(kinematics.configuration(segment.end[:6]))
        moves.append(PlannedMove(offset, program.file_at(offset), line, column, str(segment.kind), record.t_start,
                                 record.planned_duration, record.blended, tuple(segment.end), configuration))
    return moves


def check_motion(program: Program, spec, scenario=None, *, max_moves: int = MAX_MOVES,
                 max_paths: int = MAX_PATHS, max_time: float = MAX_TIME) -> Outcome:
    """Run ``program`` offline (module docstring): with the cell ``scenario`` (a
    runtime.hardware.sim.cell.Scenario) once, as ``irl run`` would; without one in the
    assumed cell, the main run and up to ``max_paths - 1`` runs that take the other value
    of a choice. The findings of all runs, each once (``count``: how often)."""
    limits = _Limits(max_moves, max_time)
    outcome = Outcome()
    findings: dict = {}
    corners: dict = {}  # a move with approx -> (times blended, times not, its approx, the first run's choices)
    cache: dict = {}  # the moves planned, shared by every run (a branch repeats most of the main run's)
    main = _Run(program, spec, scenario, None if scenario is not None else (), limits, cache=cache)
    main.run(max_moves)
    used = len(main.host.planned)
    outcome.cycle_time = main.end_time
    outcome.ended = main.ended
    outcome.moves = _planned_moves(main)
    outcome.notes.extend(main.notes)
    _merge(findings, main, (), corners)
    if scenario is None:
        explored: set = set()
        branches: deque = deque()

        def offer(run: _Run, forced: int, flips: tuple) -> None:
            choices = run.world.choices
            for i, c in enumerate(choices):
                if i < forced:
                    continue
                explored.add((c.offset, c.options[c.taken]))
                for option in range(len(c.options)):
                    if (c.offset, c.options[option]) not in explored:
                        explored.add((c.offset, c.options[option]))
                        decisions = tuple(x.taken for x in choices[:i]) + (option,)
                        branches.append((decisions, flips + (_describe_choice(program, c, option),)))

        offer(main, 0, ())
        worlds = [main.world]
        explored_flips: list[str] = []
        while branches and outcome.paths < max_paths and used < max_moves:
            decisions, flips = branches.popleft()
            run = _Run(program, spec, None, decisions, limits, cache=cache)
            run.run(max_moves - used)
            outcome.paths += 1
            used += len(run.host.planned)
            _merge(findings, run, flips, corners)
            worlds.append(run.world)
            explored_flips.append(flips[-1])
            offer(run, len(decisions), flips)
        outcome.assumed = _assumptions(program, worlds, explored_flips)
        if branches:
            outcome.notes.append(f"{len(branches)} more branch{'es' if len(branches) != 1 else ''} on inputs not "
                                 f"explored (the check runs the program at most {max_paths} times)")
    for offset, (blended, refused, approx, assumed) in corners.items():
        if refused and not blended:  # a corner never blended (one blended sometimes is the program's choice)
            line, column = program.line_at(offset)
            findings[offset, "blend"] = Finding(
                offset, program.file_at(offset), line, column, "blend",
                f"approx := {approx:g} has no effect: no blend into the next move keeps every axis within its velocity, "
                "acceleration and jerk limits, so the robot stops at the target", "warning",
                "a smaller approx, or lower speeds around the corner, may blend", count=refused, assumed=assumed)
    outcome.findings = sorted(findings.values(), key=lambda f: (f.file, f.line, f.column, f.kind))
    return outcome
