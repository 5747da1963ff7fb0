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
for`` with a time-out could also time out (or other values of its inputs end it), each
other way is explored (:func:`check_motion` runs the program again with the other
option), once per place in the program and the inputs chosen just before at the same
instant; a run that polls for ever without moving, or waits for what nothing changes,
stops there; ``pause`` resumes at once (as ``irl run`` does off a terminal).

Fast, and the same timeline: the motion queue computes a setpoint only where something
needs one (``MotionQueue.setpoints`` off), and the planner keeps the moves and blends it
planned (``MovePlanner.cache``, shared by every run of a check).

Bounded: at most :data:`MAX_MOVES` moves and :data:`MAX_PATHS` runs in all, and per run
:data:`MAX_TIME` simulated seconds and :data:`MAX_INSTRUCTIONS` instructions; the outcome
says when a bound cut the check short.

Not real-time: this runs in the ``irl check`` process, never in a tick.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from compiler.clauses import Motion, validate_move_clauses
from compiler.configs import config_of, format_config
from compiler.frames import IDENTITY, pose_of
from compiler.objcode import OP, Program
from compiler.semantics import compose
from compiler.values import Joint, Pose

from runtime.hardware.interface import DigitalIo, IoBackend
from runtime.loop.component import DataPort
from runtime.loop.components.io import IoComponent
from runtime.loop.components.trajectory import TrajectoryGenerator
from runtime.loop.executive import SimClock
from runtime.loop.vm import DONE, ERROR
from runtime.motion.moves import MoveRequest, Segment
from runtime.motion.trajectory import Refusal
from runtime.settings import Settings
from runtime.timing import TICK

__all__ = ["AssumedWorld", "BRANCH_MOVES", "Finding", "MAX_INSTRUCTIONS", "MAX_MOVES", "MAX_PATHS", "MAX_SEARCH_INPUTS",
           "MAX_TIME", "OfflineHost", "Outcome", "PlannedMove", "check_motion"]

#: Moves handed over in all runs of one check before it stops (a note says so).
MAX_MOVES = 2000
#: Runs of the program in one check: the main one and the branches explored.
MAX_PATHS = 16
#: Simulated seconds one run may take (``irl run``'s own limit).
MAX_TIME = 3600.0
#: The fewest moves a run exploring a branch may plan (else an eighth of the check's).
BRANCH_MOVES = 50
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
    warning: a corner never blended), ``"wait"`` (a warning: a wait nothing ends),
    ``"error"`` (a run-time error: the program stops). ``fraction`` and ``distance`` (mm): where along the move's path, when it
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
    given: tuple = ()  # the inputs chosen just before at the same instant (the rest of its condition), sorted


@dataclass
class Outcome:
    """The check of one program: its findings, the main run's moves and cycle time (the
    time ``irl run`` spends in Move Robot; None when the main run did not end), what was
    assumed, and notes (bounds)."""

    findings: list[Finding] = field(default_factory=list)
    moves: list[PlannedMove] = field(default_factory=list)
    assumed: list[str] = field(default_factory=list)  # what was assumed of the cell (none: nothing was)
    branches: list[str] = field(default_factory=list)  # the other runs, each by the choice it took otherwise
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

    def __init__(self, backend: IoBackend, io: IoComponent, decisions: tuple = ()):
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

    def _choose(self, offset: int, options: tuple[str, ...], now: float, time: int | None = None) -> int:
        k = len(self.choices)
        taken = min(self.decisions[k], len(options) - 1) if k < len(self.decisions) else 0
        given = tuple(sorted((n, self.backend.input(n)) for n, at in self.decided.items() if at == now))
        self.choices.append(Choice(offset, options, taken, self.runs.get(offset, 1) if time is None else time,
                                   given))
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
        value = values[self._choose(offset, tuple(f"in[{n}] reads {'true' if v else 'false'}" for v in values), now)]
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
        chosen = options[self._choose(wait.offset, tuple(label for label, _values in options), now, wait.time)][1]
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


#: What to do about a path the arm cannot follow, by its reason (runtime.motion.pathcheck),
#: when no other configuration of its start helps.
PATH_HINTS = {
    "configuration": "a lin or circ path cannot pass through a singularity (the arm would flip on the way): make "
                     "this motion a ptp move (the axes pass it in joint space), or tilt the tool so that the path "
                     "passes beside it",
    "singular": "a lin or circ path cannot start, end or run on a singularity: tilt the tool a few degrees, or "
                "make this motion a ptp move",
    "jump": "a lin or circ path cannot pass next to a singularity, where the axes would have to turn too fast: "
            "make this motion a ptp move, or tilt the tool so that the path passes farther from it",
    "unreachable": "the path leaves the arm's reach: keep it nearer the robot, or go around with ptp moves",
    "limit": "an axis would have to pass its limit on this path: go around with a ptp move, or change the "
             "orientation along the path",
}

#: The other start joints tried for a hint when a lin or circ move is refused (nearest first).
OTHER_STARTS = 12


def _turns(joints: tuple, limits) -> list[tuple]:
    """``joints`` and the same with A1, A4 or A6 a whole turn (360 deg) away, within
    ``limits``: the start joints of one pose that differ only by a turn."""
    out = [tuple(joints)]
    for i in (0, 3, 5):
        lo, hi = limits[i]
        out += [q[:i] + (q[i] + k,) + q[i + 1:] for q in list(out) for k in (-360.0, 360.0) if lo <= q[i] + k <= hi]
    return out


def _wound(problem: str, axes, first: tuple, now: tuple) -> str:
    """A move refused: said with the axes that start it a turn or more from where they
    started it the first time it ran (an axis winding up over a program's cycles)."""
    wound = [f"{axis.name} starts it at {b:.1f} {axis.unit}, {b - a:+.0f} {axis.unit} from the first time it ran"
             for axis, a, b in zip(axes, first, now) if abs(b - a) >= 300.0]
    if not wound:
        return problem
    text = f"{problem} ({'; '.join(wound)}: it winds up over the cycles)"
    return Refusal(text, problem.fraction, problem.distance, problem.reason) if isinstance(problem, Refusal) else text


def configuration_text(kinematics, joints) -> str:
    """The configuration of joint values as a program names it: ``config(front, elbow_up,
    noflip, 0, 0, 1)`` (compiler.configs: every group, and the turns of A1, A4, A6)."""
    return format_config(config_of(kinematics.configuration(joints), joints))


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
        self.starts: dict[int, tuple] = {}  # a move -> the joints it started from the first time
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
        start = tuple(self.motion.planning_start())
        first = self.starts.setdefault(self.at, start)
        problem = super().move(kind, targets, clauses, line)
        if problem is None:
            segment = self.motion.last_planned
            if segment is not None and segment is not before:
                self._accepted(segment)
            return None
        self.triggers = []  # (a refused move's triggers go with it)
        hint = self._other_start(kind, targets, clauses, line) if kind != Motion.PTP else None
        if hint is None and isinstance(problem, Refusal):
            hint = PATH_HINTS.get(problem.reason)
        self.record("move", _wound(problem, self.axes, first, start), hint=hint)
        self._stand_in(kind, targets, line)
        return None

    def _in_world(self, targets: tuple) -> tuple:
        """Pose targets in the world frame (they are given in the active base)."""
        base = self.frames.base
        if base == IDENTITY:
            return targets
        frame = pose_of(base)
        return tuple(compose(frame, t) if isinstance(t, Pose) else t for t in targets)

    def _other_start(self, kind: Motion, targets: tuple, clauses: dict, line: int) -> str | None:
        """A lin or circ move refused from where it starts: is there another configuration,
        or another turn of an axis, of the same start pose from which the arm can follow
        it? Then a hint that says so (None: there is none)."""
        kinematics = self.planner.kinematics_for(self.frames)
        checked = validate_move_clauses(kind, clauses, self.spec)
        if kinematics is None or isinstance(checked, str) or not all(isinstance(t, (Pose, Joint)) for t in targets):
            return None
        start = tuple(self.motion.planning_start())
        here, extra = start[:6], start[6:]
        request = MoveRequest(kind, self._in_world(targets), checked.speed, checked.acc, 0.0, line,
                              frames=self.frames)
        candidates = [q for _cid, joints in kinematics.solutions(kinematics.forward(here), near=here)
                      for q in _turns(joints, kinematics.limits)
                      if max(abs(a - b) for a, b in zip(q, here)) > 1e-6]
        same = kinematics.configuration(here)  # the same configuration at another turn first: the least change
        candidates.sort(key=lambda q: (kinematics.configuration(q) != same, sum((a - b) ** 2 for a, b in zip(q, here))))
        for joints in candidates[:OTHER_STARTS]:
            segment, _problem = self.planner.plan(request, joints + extra, None, self.period)
            if segment is not None:
                return (f"from the same start pose the arm can follow this path in {configuration_text(kinematics, joints)}"
                        f" (it is in {configuration_text(kinematics, here)}): name that configuration on the target "
                        f"of the ptp move that takes the robot there{self._last_ptp()}")
        return None

    def _last_ptp(self) -> str:
        for offset, segment in reversed(self.planned):
            if segment.kind == Motion.PTP:
                line = self.program.line_at(offset)[0]
                file = self.program.file_at(offset)
                return f" (line {line}{f' of {file}' if file else ''})"
        return ""

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
            target = self._in_world((target,))[0]
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
                 setpoints: bool = False, cache: dict | None = None, start: tuple | None = None):
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
        self.host.start_position = tuple(float(axis.home) for axis in spec.axes) if start is None else start
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
            host.on_program_start = cell.start_program  # (as irl run: its timelines from the first step)
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
            why = (f"the check stopped after {moves_left} moves, the most it plans (--max-moves N plans more: about "
                   "20 ms a move)")
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


def _assumptions(program: Program, worlds: list) -> list[str]:
    """What the runs assumed of the cell (nothing, when the program neither reads an input
    nor waits for one)."""
    waited = set().union(*(w.waited for w in worlds))
    read = {c.offset for w in worlds for c in w.choices if c.options[0].startswith("in[")}
    if not waited and not read:
        return []
    said = "no cell scenario: the inputs are false until the program waits for them"
    if waited:
        said += f"; each wait for ends at once where inputs can make it hold ({_lines(program, waited)})"
    return [said]


def _ordinal(n: int) -> str:
    return f"{n}{'th' if 10 <= n % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(n % 10, 'th')}"


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
            configuration = configuration_text(kinematics, segment.end[:6])
        moves.append(PlannedMove(offset, program.file_at(offset), line, column, str(segment.kind), record.t_start,
                                 record.planned_duration, record.blended, tuple(segment.end), configuration))
    return moves


class _Check:
    """The runs of one check and what they found: the findings of all (each once, with
    how often), the corners with ``approx`` (blended or not), the moves planned so far (the
    bound), and, in the assumed cell, the branches still to explore."""

    def __init__(self, program: Program, spec, scenario, limits: _Limits, start: tuple | None, setpoints: bool):
        self.program, self.spec, self.scenario, self.limits, self.start = program, spec, scenario, limits, start
        self.setpoints = setpoints
        # the moves planned, shared by every run (a branch repeats most of the main run)
        self.cache: dict | None = None if setpoints else {}
        self.findings: dict = {}
        self.corners: dict = {}  # a move with approx -> (times blended, times not, its approx, first run's choices)
        self.used = 0  # moves planned in all runs
        self.runs = 0
        self.worlds: list[AssumedWorld] = []
        self.explored: set = set()  # (offset, option) of every choice taken or queued
        self.branches: deque = deque()  # (decisions, the choices that lead there, described)
        self.flips: list[str] = []  # the branches run, each by its last choice
        self.cut = 0  # branch runs stopped at their bound

    def run(self, decisions: tuple | None, assumed: tuple, moves: int) -> _Run:
        run = _Run(self.program, self.spec, self.scenario, decisions, self.limits, setpoints=self.setpoints,
                   cache=self.cache, start=self.start)
        run.run(moves)
        self.runs += 1
        self.used += len(run.host.planned)
        for offset, (blended, refused, approx) in run.host.corners.items():
            was = self.corners.get(offset, (0, 0, approx, assumed))
            self.corners[offset] = (was[0] + blended, was[1] + refused, approx, was[3])
        for f in run.host.findings:
            known = self.findings.get((f.offset, f.kind))
            if known is None:
                f.assumed = assumed
                self.findings[f.offset, f.kind] = f
            else:
                known.count += 1
        if run.world is not None:
            self.worlds.append(run.world)
            self._offer(run, len(decisions or ()), assumed)
        return run

    def _offer(self, run: _Run, forced: int, flips: tuple) -> None:
        """The other options of the run's own choices (after those it was given), each once
        per place in the program."""
        choices = run.world.choices
        for i, c in enumerate(choices):
            if i < forced:
                continue
            self.explored.add((c.offset, c.given, c.options[c.taken]))
            for option in range(len(c.options)):
                if (c.offset, c.given, c.options[option]) not in self.explored:
                    self.explored.add((c.offset, c.given, c.options[option]))
                    decisions = tuple(x.taken for x in choices[:i]) + (option,)
                    self.branches.append((decisions, flips + (_describe_choice(self.program, c, option),)))

    def explore(self, max_paths: int) -> list[str]:
        """Run the branches (breadth first) until none is left or a bound is reached; the
        notes to say."""
        per_run = max(BRANCH_MOVES, self.limits.moves // 8)
        while self.branches and self.runs < max_paths and self.used < self.limits.moves:
            decisions, flips = self.branches.popleft()
            run = self.run(decisions, flips, min(per_run, self.limits.moves - self.used))
            self.flips.append(flips[-1])
            self.cut += run.ended == "bounded"
        notes = []
        if self.cut:
            notes.append(f"{self.cut} of the branches explored ran longer than {per_run} moves: the check stopped "
                         "each there")
        if self.branches:
            why = (f"the check runs the program at most {max_paths} times" if self.runs >= max_paths else
                   f"the check plans at most {self.limits.moves} moves in all (--max-moves)")
            notes.append(f"{len(self.branches)} more branch{'es' if len(self.branches) != 1 else ''} on inputs not "
                         f"explored: {why}")
        return notes

    def sorted_findings(self) -> list[Finding]:
        """Every finding, by place; with a warning for each corner never blended (one
        blended sometimes is the program's choice: it may move on before the robot is
        there)."""
        program = self.program
        for offset, (blended, refused, approx, assumed) in self.corners.items():
            if refused and not blended:
                line, column = program.line_at(offset)
                self.findings[offset, "blend"] = Finding(
                    offset, program.file_at(offset), line, column, "blend",
                    f"approx := {approx:g} has no effect: no blend into the next move keeps every axis within its "
                    "velocity, acceleration and jerk limits, so the robot stops at the target", "warning",
                    "a smaller approx, or lower speeds around the corner, may blend", count=refused, assumed=assumed)
        return sorted(self.findings.values(), key=lambda f: (f.file, f.line, f.column, f.kind))


def check_motion(program: Program, spec, scenario=None, *, max_moves: int = MAX_MOVES,
                 max_paths: int = MAX_PATHS, max_time: float = MAX_TIME, start: tuple | None = None,
                 setpoints: bool = False) -> Outcome:
    """Run ``program`` offline (module docstring) from ``start`` (joint values; default:
    every axis at its home, where ``irl run`` starts a program): with the cell
    ``scenario`` (a runtime.hardware.sim.cell.Scenario) once, as ``irl run`` would;
    without one in the assumed cell, the main run and up to ``max_paths - 1`` runs that take
    the other option of a choice (each at most ``max_moves // 8`` moves). The findings of
    all runs, each once (``count``: how often). ``setpoints``: compute every period's
    setpoint, as the runtime does, and plan every move anew (slower; the same outcome:
    what the tests compare)."""
    if start is not None:
        start = tuple(float(v) for v in start)
        if len(start) != len(spec.axes):
            raise ValueError(f"start: expected {len(spec.axes)} joint values, got {len(start)}")
    check = _Check(program, spec, scenario, _Limits(max_moves, max_time), start, setpoints)
    main = check.run(None if scenario is not None else (), (), max_moves)
    outcome = Outcome(cycle_time=main.end_time, ended=main.ended, moves=_planned_moves(main), notes=list(main.notes))
    if scenario is None:
        outcome.notes += check.explore(max_paths)
        outcome.assumed = _assumptions(program, check.worlds)
        outcome.branches = list(check.flips)
    outcome.paths = check.runs
    outcome.findings = check.sorted_findings()
    return outcome
