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
* a refused move that the program's own error handler takes (compiler.recovery): the
  handler runs, as it would in ``irl run``, and a note says so;
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
stops there; a search move (``search := N``) finds its input where the move ends, and the
other way (it finds nothing: the program's search error) is explored too; ``pause``
resumes at once (as ``irl run`` does off a terminal).

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
from compiler.zones import forbidden, signals
from compiler.semantics import compose
from compiler.values import Joint, Pose

from runtime.hardware.interface import DigitalIo, IoBackend
from runtime.loop.component import DataPort
from runtime.loop.components.io import IoComponent, ZoneSignals
from runtime.loop.components.trajectory import TrajectoryGenerator
from runtime.loop.executive import SimClock
from runtime.loop.vm import DONE, ERROR
from runtime.motion.moves import MoveRequest, Segment
from runtime.motion.trajectory import Refusal
from runtime.settings import Settings
from runtime.timing import TICK

__all__ = ["AssumedWorld", "BRANCH_MOVES", "Finding", "MAX_INSTRUCTIONS", "MAX_MOVES", "MAX_PATHS", "MAX_SEARCH_INPUTS",
           "MAX_TIME", "OfflineHost", "Outcome", "PlannedMove", "Trace", "check_motion"]

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
    next, the joints it ends at and, for a pose target, the configuration they are in; or
    ``refused`` (then none of these: None)."""

    offset: int
    file: str
    line: int
    column: int
    kind: str
    start: float | None
    duration: float | None
    blended: bool
    joints: tuple | None
    configuration: str | None
    refused: bool = False


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
class Trace:
    """The main run's setpoints, every 5 ms (what ``irl view`` draws): ``times`` (s after
    the program started), ``joints`` (the setpoint's joint values), ``move`` (per sample,
    the number of the move under way or last started, from 1; 0 before the first: an index
    into ``records`` plus one); ``records``: the moves as they ran (their line, kind and
    frames), ``stand_in``: the numbers of those that stand in for a refused move (a PTP
    move to its target)."""

    times: list = field(default_factory=list)
    joints: list = field(default_factory=list)
    move: list = field(default_factory=list)
    records: list = field(default_factory=list)
    stand_in: set = field(default_factory=set)


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
    trace: Trace | None = None  # the main run's setpoints (check_motion(trace=True))


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

    def __init__(self, backend: IoBackend, io: IoComponent, decisions: tuple = (), runs: dict | None = None):
        self.backend, self.io = backend, io
        self.decisions = decisions
        self.choices: list[Choice] = []
        self.decided: dict[int, float] = {}  # input -> when a choice or a wait last set it
        self.runs: dict[int, int] = runs if runs is not None else {}  # instruction -> how many times it ran
        self.waits: list[_Wait] = []  # the waits under way (a handler's above the program's)
        self.visits: dict[tuple, int] = {}  # (read, robot position) -> moves handed over then
        self.idle: str | None = None  # why the run idles for ever (a poll that comes back unchanged)
        self.waited: set[int] = set()  # the waits for whose inputs it set so that they end at once (WAIT_TEST)
        self.hangs: set[int] = set()  # ... of them, those with no time-out: irl run without a cell waits for ever

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

    def search(self, n: int, offset: int, now: float) -> bool:
        """A search move watching input ``n`` is handed over at ``offset``: a choice of
        whether the input becomes true where the move ends (True) or never (the search
        finds nothing)."""
        return self._choose(offset, (f"the search finds in[{n}] where its move ends",
                                     f"in[{n}] does not become true: the search finds nothing"), now) == 0

    def begin_wait(self, timeout: bool, offset: int) -> None:
        self.waits.append(_Wait(timeout, self.runs.get(offset, 1)))

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
        if chosen is not None:
            self.waited.add(wait.offset)
            if not wait.timeout:
                self.hangs.add(wait.offset)
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

#: What to do about an axis that winds up over the program's cycles.
WOUND_HINT = ("the axis turns on each cycle and comes back further round: turn it back every cycle (a ptp move to a "
              "pose with its turn named, e.g. config(..., 0, 0, 0), or move ptp home), or turn the other way every "
              "other cycle")

#: The other configurations (and turns) tried for a hint when a lin or circ move is refused
#: (the same configuration at another turn first, then the nearest).
OTHER_STARTS = 12
#: A singularity margin (kinematics.singularity_margins: |sin| of the wrist's or the elbow's
#: angle) below this names the singularity a corner that never blends lies next to.
NEAR_SINGULAR = 0.05


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


def configuration_hint(host, kind: Motion, targets: tuple, clauses: dict, line: int) -> str | None:
    """A lin or circ move the arm cannot follow from the configuration it is in: the
    configuration (or the turn of A1, A4, A6) to name on the ptp move that chose it (the last
    ptp move, to a pose), in which the arm can follow every lin and circ move from there up
    to and including this one; without such a ptp move, the configuration of this move's
    start pose in which it can. None: none helps (or its clauses are wrong)."""
    checked = validate_move_clauses(kind, clauses, host.spec)
    if isinstance(checked, str) or not all(isinstance(t, (Pose, Joint)) for t in targets):
        return None
    request = MoveRequest(kind, host.in_world(targets), checked.speed, checked.acc, 0.0, line, frames=host.frames)
    planner, program = host.planner, host.program
    k = next((i for i in range(len(host.planned) - 1, -1, -1) if host.planned[i][1].kind == Motion.PTP), None)
    ptp = host.planned[k][1] if k is not None else None
    if ptp is not None and isinstance(ptp.request.targets[0], Pose):
        chain = [segment.request for _offset, segment in host.planned[k + 1:]] + [request]
        reached, pose, frames = tuple(ptp.end), ptp.request.targets[0], ptp.request.frames
    else:  # (no ptp to a pose before it: the configurations of its own start)
        chain, reached, frames = [request], tuple(host.motion.planning_start()), host.frames
        pose = None
    kinematics = planner.kinematics_for(frames)
    if kinematics is None:
        return None
    here, extra = reached[:6], reached[6:]
    same = kinematics.configuration(here)
    candidates = [q for _cid, joints in kinematics.solutions(pose or kinematics.forward(here), near=here)
                  for q in _turns(joints, kinematics.limits) if max(abs(a - b) for a, b in zip(q, here)) > 1e-6]
    candidates.sort(key=lambda q: (kinematics.configuration(q) != same, sum((a - b) ** 2 for a, b in zip(q, here))))
    for q in candidates[:OTHER_STARTS]:
        joints = q + extra
        for step in chain:
            segment, _problem = planner.plan(step, joints, None, host.period)
            if segment is None:
                break
            joints = segment.end
        else:
            named, now = configuration_text(kinematics, q), configuration_text(kinematics, here)
            if pose is None:
                return (f"the arm can follow this path from the same start pose in {named} (it is in {now}): take the "
                        "robot there with a ptp move to that pose in that configuration")
            where = program.line_at(host.planned[k][0])[0]
            file = program.file_at(host.planned[k][0])
            then = " and the lin and circ moves before it" if len(chain) > 1 else ""
            return (f"name {named} on the target of the ptp move at line {where}{f' of {file}' if file else ''} (it "
                    f"takes the arm to {now}): from there the arm can follow this path{then}")
    return None


class OfflineHost(TrajectoryGenerator):
    """The trajectory generator, run offline (module docstring): what the runtime would
    refuse is recorded (``findings``) and the run goes on; every move accepted is kept
    with its place in the code (``planned``)."""

    def __init__(self, spec, settings: Settings, clock: SimClock, world_io: IoComponent,
                 world: AssumedWorld | None, runs: dict[int, int], hints: dict[int, str | None]):
        super().__init__(spec, None, DataPort("desi_pos"), DataPort("sens_pos"), clock, settings.trajectory.period,
                         settings)
        self.io = world_io
        self.world = world
        self.runs = runs  # a located instruction -> how many times it ran (the world's too)
        self.hints = hints  # a refused lin or circ move -> its configuration hint (once per check)
        self.findings: list[Finding] = []
        self.planned: list[tuple[int, Segment]] = []  # (offset, segment) of every move accepted
        self.refused: list[tuple[int, int, str]] = []  # (moves accepted before it, offset, kind) of each refused
        self.corners: dict[int, tuple] = {}  # a move with approx -> (times blended, times not, its approx, why)
        self.starts: dict[int, tuple] = {}  # a move -> the joints it started from the first time
        self.lost: int | None = None  # the line of a refused move no joint values reach: where the robot is is unknown
        self.skipped = 0  # lin and circ moves not checked since (their start is unknown)
        self.handled: dict[int, tuple] = {}  # refused moves a handler takes: offset -> (times, first problem, handler)
        self.lost_at: set[int] = set()  # the lines of such moves
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
            self.runs[pc] = self.runs.get(pc, 0) + 1
            world = self.world
            if world is None:
                return handler(operand, pc)
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

    def tool_position(self) -> tuple:
        self.motion.setpoint_now()  # (a simulated cell's touch sensor: where the tool is now)
        return super().tool_position()

    def _search(self, request: MoveRequest, n: int) -> str | None:
        if self.world is not None:  # the assumed cell: found where the move ends, or nothing (both explored)
            self.search.found_at_end = self.world.search(n, self.at, self.now())
        return super()._search(request, n)

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
        runs = self.runs.get(offset, 1)
        self.findings.append(Finding(offset, program.file_at(offset), line, column, kind, str(message), severity,
                                     hint, fraction, distance, 1, runs))

    def move(self, kind: Motion, targets: tuple, clauses: dict, line: int, tag: int = 0) -> str | None:
        if self.lost is not None and kind != Motion.PTP:  # from where? (after a target no joints reach)
            self.skipped += 1
            self.triggers = []
            return None
        before = self.motion.last_planned
        start = tuple(self.motion.planning_start())
        first = self.starts.setdefault(self.at, start)
        problem = super().move(kind, targets, clauses, line, tag)
        if problem is None:
            segment = self.motion.last_planned
            if segment is not None and segment is not before:
                self._accepted(segment)
                if kind == Motion.PTP:
                    self.lost = None
            return None
        self.triggers = []  # (a refused move's triggers go with it)
        vm = self.vm
        found = vm.recovery.handler_for(len(vm.memory.frames), self.at) if self.program.handlers else None
        if found is not None:  # the program's own error handler takes it: its path is the program's (a note)
            count, first, handler = self.handled.get(self.at, (0, str(problem), found[1].entry))
            self.handled[self.at] = (count + 1, first, handler)
            return problem
        self.refused.append((len(self.planned), self.at, str(kind)))
        hint = None
        said = _wound(problem, self.axes, first, start)
        if isinstance(problem, Refusal):  # (a path the arm cannot follow: another configuration may help)
            if self.at not in self.hints:
                self.hints[self.at] = configuration_hint(self, kind, targets, clauses, line)
            hint = self.hints[self.at] or (WOUND_HINT if said is not problem else PATH_HINTS.get(problem.reason))
        elif said is not problem:
            hint = WOUND_HINT
        self.record("move", said, hint=hint)
        if not self._stand_in(kind, targets, line):
            self.lost = line
            self.lost_at.add(line)
        return None

    def in_world(self, targets: tuple) -> tuple:
        """Pose targets in the world frame (they are given in the active base)."""
        base = self.frames.base
        if base == IDENTITY:
            return targets
        frame = pose_of(base)
        return tuple(compose(frame, t) if isinstance(t, Pose) else t for t in targets)

    def _accepted(self, segment: Segment) -> None:
        self.planned.append((self.at, segment))
        previous = segment.previous
        if previous is not None and previous.blendable:  # a corner with approx: blended, or not
            offset = next((o for o, s in reversed(self.planned) if s is previous), None)
            if offset is not None:
                blended, refused, _approx, why = self.corners.get(offset, (0, 0, 0.0, None))
                approx = previous.request.approx
                if segment.offset is None and why is None:
                    why = self._near_singular(previous)
                self.corners[offset] = ((blended + 1, refused, approx, why) if segment.offset is not None else
                                        (blended, refused + 1, approx, why))

    def _near_singular(self, segment: Segment) -> str | None:
        """Why a corner at the end of ``segment`` may not blend: it lies next to a singularity."""
        kinematics = self.planner.kinematics_for(segment.request.frames)
        if kinematics is None:
            return None
        shoulder, elbow, wrist = kinematics.singularity_margins(segment.end[:6])
        if wrist < NEAR_SINGULAR:
            return (f"the corner lies next to the wrist singularity ({kinematics.names[4]} at "
                    f"{segment.end[4]:.1f} deg), where the axes would have to turn fast to blend: tilt the tool, or "
                    "move the corner")
        if elbow < NEAR_SINGULAR:
            return "the corner lies next to the elbow singularity (the arm nearly stretched): move the corner"
        return None

    def _stand_in(self, kind: Motion, targets: tuple, line: int) -> bool:
        """A refused move: go on as if it had reached its target (a PTP move there, at the
        specification's default speed); False when its target has no joint values."""
        target = targets[-1] if targets else None
        frames = self.frames
        joints = None
        if isinstance(target, Pose) and self.planner.kinematics is not None:
            target = self.in_world((target,))[0]
            joints, _problem = self.planner.joint_target(target, self.motion.planning_start(), frames)
        elif isinstance(target, Joint) and len(target.axes) == self.n:
            if all(axis.target_problem(v) is None for axis, v in zip(self.axes, target.axes)):
                joints = target
        defaults = validate_move_clauses(Motion.PTP, {}, self.spec)
        if joints is None or isinstance(defaults, str):
            return False
        problem = self.motion.add(MoveRequest(Motion.PTP, (joints,), defaults.speed, defaults.acc, 0.0, line,
                                              frames=frames))
        return problem is None

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
                 setpoints: bool = False, cache: dict | None = None, start: tuple | None = None,
                 hints: dict | None = None):
        self.spec, self.limits = spec, limits
        self.clock = SimClock(TICK)
        settings = Settings(spec)
        self.backend = _OfflineIo(spec.inputs, spec.outputs, "the cell", spec.analog_inputs, spec.analog_outputs)
        self.io = IoComponent(self.backend, None)
        self.io.configure()
        runs: dict[int, int] = {}
        self.world = AssumedWorld(self.backend, self.io, decisions or (), runs) if scenario is None else None
        self.host = OfflineHost(spec, settings, self.clock, self.io, self.world, runs, hints if hints is not None else {})
        zones = tuple(spec.zones) + program.zones  # (the specification's, the program's own: compiler.zones)
        if self.host.planner.kinematics is not None:
            self.host.planner.zones = forbidden(zones)
        if signals(zones) and self.host.tcp is not None:  # (the commanded tool: an offline run starts homed)
            self.io.zone_signals = ZoneSignals(signals(zones), self.host.tool_position)
        self.cell = self.io.cell = None
        if scenario is not None:  # (its contact sensors read where the host's tool is)
            from runtime.hardware.sim.cell import Cell

            self.cell = self.io.cell = Cell(scenario, self.backend,
                                            self.host.tool_position if self.host.tcp is not None else None)
        self.host.motion.setpoints = setpoints
        self.host.planner.cache = cache
        self.host.start_position = tuple(float(axis.home) for axis in spec.axes) if start is None else start
        self.host.load(program)
        self.ended = "completed"
        self.end_time: float | None = None
        self.notes: list[str] = []
        self.trace: Trace | None = None  # set: every update's setpoint is kept (needs setpoints)

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
            if cell is not None or io.zone_signals is not None:  # the tick's first task: the cell acts, the
                io.update(now)                                   # signal zones switch, the inputs are read
                outputs = io.outputs.value
            host.update(now)
            if self.trace is not None:
                self._sample(now)
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

    def _sample(self, now: float) -> None:
        trace, motion = self.trace, self.host.motion
        trace.times.append(now)
        trace.joints.append(motion.positions)
        trace.move.append(len(motion.moves))

    def traced(self) -> Trace:
        """The trace with the moves as they ran (after :meth:`run`)."""
        trace, host = self.trace, self.host
        trace.records = list(host.motion.moves)
        accepted = {id(segment.record) for _offset, segment in host.planned if segment.record is not None}
        trace.stand_in = {i + 1 for i, record in enumerate(trace.records) if id(record) not in accepted}
        return trace

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
    analog = [offset for offset, instr in enumerate(program.code) if instr[0] == OP.AIN_GET]
    searched = {c.offset for w in worlds for c in w.choices if c.options[0].startswith("the search finds")}
    if not waited and not read and not analog and not searched:
        return []
    said = "no cell scenario: the inputs are false until the program waits for them"
    if waited:
        said += f"; each wait for ends at once where inputs can make it hold ({_lines(program, waited)})"
    if analog:
        said += f"; each analog input reads the middle of its range ({_lines(program, set(analog))})"
    if searched:
        said += f"; each search move finds its input where the move ends ({_lines(program, searched)})"
    return [said]


def _ordinal(n: int) -> str:
    return f"{n}{'th' if 10 <= n % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(n % 10, 'th')}"


def _planned_moves(run: _Run) -> list[PlannedMove]:
    """The main run's moves in the order the program handed them over, the refused ones too."""
    host = run.host
    program, kinematics = host.program, host.planner.kinematics
    moves = []
    refused = list(host.refused)
    for i, (offset, segment) in enumerate(host.planned + [(None, None)]):
        while refused and refused[0][0] == i:
            _i, at, kind = refused.pop(0)
            line, column = program.line_at(at)
            moves.append(PlannedMove(at, program.file_at(at), line, column, kind, None, None, False, None, None, True))
        record = segment.record if segment is not None else None
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
        self.hints: dict = {}  # a refused lin or circ move -> its configuration hint (computed once)
        self.corners: dict = {}  # a move with approx -> (times blended, times not, approx, why, first run's choices)
        self.used = 0  # moves planned in all runs
        self.runs = 0
        self.worlds: list[AssumedWorld] = []
        self.explored: set = set()  # (offset, option) of every choice taken or queued
        self.branches: deque = deque()  # (decisions, the choices that lead there, described)
        self.flips: list[str] = []  # the branches run, each by its last choice
        self.cut = 0  # branch runs stopped at their bound

    def run(self, decisions: tuple | None, assumed: tuple, moves: int, trace: bool = False) -> _Run:
        run = _Run(self.program, self.spec, self.scenario, decisions, self.limits, setpoints=self.setpoints,
                   cache=self.cache, start=self.start, hints=self.hints)
        if trace:
            run.trace = Trace()
        run.run(moves)
        self.runs += 1
        self.used += len(run.host.planned)
        for offset, (blended, refused, approx, why) in run.host.corners.items():
            was = self.corners.get(offset, (0, 0, approx, why, assumed))
            self.corners[offset] = (was[0] + blended, was[1] + refused, approx, was[3] or why, was[4])
        new: dict = {}  # (each finding as the first run that has it found it: how often in that run)
        for f in run.host.findings:
            key = (f.offset, f.kind)
            if key in self.findings:
                continue
            if key in new:
                new[key].count += 1
            else:
                f.assumed = assumed
                new[key] = f
        self.findings.update(new)
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
        for offset, (blended, refused, approx, why, assumed) in self.corners.items():
            if refused and not blended:
                line, column = program.line_at(offset)
                self.findings[offset, "blend"] = Finding(
                    offset, program.file_at(offset), line, column, "blend",
                    f"approx := {approx:g} has no effect: no blend into the next move keeps every axis within its "
                    "velocity, acceleration and jerk limits, so the robot stops at the target", "warning",
                    why or "a smaller approx, or lower speeds around the corner, may blend", count=refused,
                    assumed=assumed)
        return sorted(self.findings.values(), key=lambda f: (f.file, f.line, f.column, f.kind))


def check_motion(program: Program, spec, scenario=None, *, max_moves: int = MAX_MOVES,
                 max_paths: int = MAX_PATHS, max_time: float = MAX_TIME, start: tuple | None = None,
                 setpoints: bool = False, trace: bool = False) -> Outcome:
    """Run ``program`` offline (module docstring) from ``start`` (joint values; default:
    every axis at its home, where ``irl run`` starts a program): with the cell
    ``scenario`` (a runtime.hardware.sim.cell.Scenario) once, as ``irl run`` would;
    without one in the assumed cell, the main run and up to ``max_paths - 1`` runs that take
    the other option of a choice (each at most ``max_moves // 8`` moves). The findings of
    all runs, each once (``count``: how often). ``setpoints``: compute every period's
    setpoint, as the runtime does, and plan every move anew (slower; the same outcome:
    what the tests compare). ``trace``: keep the main run's setpoints (``Outcome.trace``;
    implies ``setpoints``)."""
    if start is not None:
        start = tuple(float(v) for v in start)
        if len(start) != len(spec.axes):
            raise ValueError(f"start: expected {len(spec.axes)} joint values, got {len(start)}")
    check = _Check(program, spec, scenario, _Limits(max_moves, max_time), start, setpoints or trace)
    main = check.run(None if scenario is not None else (), (), max_moves, trace)
    outcome = Outcome(cycle_time=main.end_time, ended=main.ended, moves=_planned_moves(main), notes=list(main.notes),
                      trace=main.traced() if trace else None)
    for offset, (count, first, handler) in main.host.handled.items():
        times = "once" if count == 1 else f"{count} times"
        outcome.notes.append(f"line {program.line_at(offset)[0]}: the move is refused {times} (first: {first}); the "
                             f"error handler at line {program.line_at(handler)[0]} takes it, and the check follows it")
    if main.host.skipped:
        lines = ", ".join(str(line) for line in sorted(main.host.lost_at))
        outcome.notes.append(f"{main.host.skipped} lin or circ move{'s' if main.host.skipped != 1 else ''} after a refused "
                             f"move whose target no joint values reach (line {lines}) were not checked: where they "
                             "start is not known, up to the next ptp move")
    if scenario is None:
        outcome.notes += check.explore(max_paths)
        outcome.assumed = _assumptions(program, check.worlds)
        outcome.branches = list(check.flips)
        hangs = set().union(*(w.hangs for w in check.worlds))
        if hangs:
            outcome.notes.append(f"irl run and irl serve on the simulated robot leave every input false without a cell "
                                 f"scenario: the program would wait there for ever at the wait for with no time-out at "
                                 f"{_lines(program, hangs)} (give them --cell-scenario FILE.toml)")
    outcome.paths = check.runs
    outcome.findings = check.sorted_findings()
    return outcome
