"""Step mode and starting a program from a line (docs/runtime.md, "Step mode and starting
from a line"): the state of both for one program, kept by the Trajectory Generator, and
what they do to its VM.

**Step mode** (``irl run --step``, ``submit``'s ``step``): the program stops before each of
its move instructions until the operator gives a step (the ``step`` operation, ``irl
step``, Enter under ``irl run --step``); the move then runs to its target, and the program
runs on to its next move instruction and stops there again. The look-ahead is 0, so a move
is handed over only once the one before it has ended and no corner is blended: the robot
stops at every target.

**A start from a line** (``--from-line N``, ``submit``'s ``from_line``): the program runs
from its start to the first move instruction on line N of its own source without moving
(*forwarding*): its moves are only remembered (the last one's target is where the move on
line N starts), waits, ``wait for`` and ``pause`` pass at once, outputs are not written and
``print`` prints nothing; everything else runs as it would (the variables, the active tool
and base, the inputs read as they are). Then the robot goes to the last remembered move's
target, in that move's tool and base, with a ptp move at reduced speed (the **approach**:
:data:`APPROACH_SPEED`, KUKA's block coincidence run), and the program runs on from the
move on line N. In step mode the approach is the first step.

Both work on the VM through its handlers (:meth:`runtime.loop.vm.VM.wrap`): the move
instructions (the step's gate; where forwarding ends) and, while forwarding, the ones that
wait, print or write an output. Real-time safe: a wrapper does a few comparisons, and the
approach is one move handed to the motion queue.
"""
from __future__ import annotations

from compiler.clauses import Motion
from compiler.semantics import EvalError

from runtime.loop.vm import DONE
from runtime.motion.moves import MoveRecord, MoveRequest
from runtime.recording import FROM_LINE

__all__ = ["APPROACH_ACC", "APPROACH_SPEED", "FORWARD_BUDGET", "MAX_FORWARD_INSTRUCTIONS", "SKIPPED", "Stepping"]

#: The approach's ``speed_ptp`` and ``acc_ptp``: 10 % of every axis's max_velocity and
#: max_acceleration (and of its jerk), under the override as every move.
APPROACH_SPEED = 0.1
APPROACH_ACC = 0.1
#: Instructions the VM runs per 5 ms update while forwarding (nothing moves then; on the wall
#: clock an update still runs the VM for at most its time slice, runtime.loop.vm).
FORWARD_BUDGET = 5_000
#: Instructions forwarding may run before the start is given up (a loop that never reaches the line).
MAX_FORWARD_INSTRUCTIONS = 5_000_000
#: What forwarding skips, counted for the summary and the log: moves remembered, outputs not
#: written (out[n] := and output triggers of the skipped moves), print statements, waits
#: (wait sec, a wait for whose condition did not hold), the program's pause statements.
SKIPPED = ("moves", "outputs", "prints", "waits", "pauses")

_MOVES = ("MOVE_PTP", "MOVE_LIN", "MOVE_CIRC")
_FORWARDED = ("DWELL", "WAIT_TEST", "PAUSE", "PRINT", "OUT_SET")


class Stepping:
    """Step mode (``step``) and a start from a line (``from_line``) of one run of a program.

    ``waiting``: held before a move for want of a step; ``forwarding``: running to the line
    without moving; ``skipped``: what forwarding skipped (:data:`SKIPPED`)."""

    def __init__(self, step: bool = False, from_line: int | None = None):
        self.step = step
        self.from_line = from_line
        self.forwarding = from_line is not None
        self.granted = False  # a step given, not taken yet
        self.waiting = False
        self.last: MoveRequest | None = None  # the last move remembered while forwarding
        self.pending: MoveRequest | None = None  # the approach, not handed over yet
        self.approaching = False  # the approach handed over, the VM waiting for it to end
        self.skipped = dict.fromkeys(SKIPPED, 0)
        self.budget = 0  # the VM's own budget, back when forwarding ends

    @property
    def active(self) -> bool:
        return self.step or self.from_line is not None

    def fresh(self) -> "Stepping":
        """Not real-time: the same options, for a new run of the program."""
        return Stepping(self.step, self.from_line)

    @property
    def approach_next(self) -> bool:
        """The next move (or the one under way) is the approach."""
        return self.pending is not None or self.approaching

    # ---- the VM's handlers -------------------------------------------------------------
    def install(self, vm, host) -> None:
        """Not real-time (the VM is being made): wrap the VM's handlers. ``host``: the
        Trajectory Generator (its motion queue, the operator log, the spec's outputs)."""
        if not self.active:
            return
        self.budget = vm.budget
        for name in _MOVES:
            vm.wrap(name, lambda handler: self._gate(handler, vm, host))
        if self.forwarding:
            vm.budget = max(vm.budget, FORWARD_BUDGET)
            outputs = host.spec.outputs
            for name in _FORWARDED:
                vm.wrap(name, lambda handler, name=name: self._forwarded(name, handler, vm, outputs))

    def _gate(self, handler, vm, host):
        """A move instruction's handler: while forwarding, the move is remembered (the
        host's ``move``) until the first one on the line; in step mode, it waits for a step;
        the approach goes first (and waits for its own step)."""
        program = vm.program

        def run(operand, pc):
            if self.forwarding:
                if not program.starts_at(pc, self.from_line):
                    return handler(operand, pc)
                self._arrived(vm, host)
            if self.approaching:  # (the VM waited for the approach's end)
                self.approaching = False
            if self.step and not self.granted:
                self.waiting = True
                vm.hold()
                return pc
            self.granted = self.waiting = False
            approach, self.pending = self.pending, None
            if approach is not None:
                problem = host.motion.add(approach)
                if problem is not None:
                    raise EvalError(f"the approach to the start of the move at line {self.from_line} (the target "
                                    f"of the move at line {self.last.line}) cannot be made: {problem}")
                self.approaching = True
                vm.hold(motion=True)  # this move runs once the approach has ended
                return pc
            return handler(operand, pc)
        return run

    def _arrived(self, vm, host) -> None:
        """Forwarding reached the move on the line: the VM's budget back, the approach
        made ready (none when no move came before), the log says what was skipped."""
        self.forwarding = False
        vm.budget = self.budget
        last = self.last
        skipped = ", ".join(f"{n} {what if n != 1 else what.rstrip('s')}" for what, n in self.skipped.items() if n)
        text = (f"start from the move at line {self.from_line}: the program ran to it without moving"
                f"{f' (skipped: {skipped})' if skipped else ''}; ")
        if last is None:
            text += "no approach: it is the program's first move"
        else:
            self.pending = MoveRequest(Motion.PTP, (last.targets[-1],), APPROACH_SPEED, APPROACH_ACC, 0.0,
                                       self.from_line, frames=last.frames, approach=True)
            text += (f"approach: a ptp move at {APPROACH_SPEED * 100:g} % speed to the target of the move at line "
                     f"{last.line} (tool {last.frames.tool_name if last.frames else 'default_tool'}, base "
                     f"{last.frames.base_name if last.frames else 'world'})")
        host.log(text, self.from_line, FROM_LINE)

    def _forwarded(self, name: str, handler, vm, outputs: int):
        """While forwarding: waits pass at once, pause too, print prints nothing, an output
        is not written (its number checked all the same); afterwards, ``handler`` itself."""
        skipped = self.skipped
        stack = vm.stack

        def run(operand, pc):
            if not self.forwarding:
                return handler(operand, pc)
            if name == "WAIT_TEST":
                if not stack[-1]:
                    stack[-1] = True  # (the condition is taken to hold)
                    skipped["waits"] += 1
                return handler(operand, pc)
            if name == "DWELL":
                if not stack[-1] >= 0:  # (a negative wait: the handler's error)
                    return handler(operand, pc)
                skipped["waits"] += stack.pop() > 0
            elif name == "PAUSE":
                skipped["pauses"] += 1
            elif name == "PRINT":
                vm.memory.pop_n(operand)
                skipped["prints"] += 1
            else:  # OUT_SET
                stack.pop()
                n = stack.pop()
                if not 1 <= n <= outputs:
                    raise EvalError(f"digital output {n} does not exist (1..{outputs})")
                skipped["outputs"] += 1
            return pc + 1
        return run

    def remember(self, request: MoveRequest, variables: list) -> None:
        """Real-time: forwarding's move (the host's ``move``): remembered, not made; the
        variables its triggers set take their values (the move is taken as made), the
        outputs they switch are skipped."""
        self.last = request
        self.skipped["moves"] += 1
        for _place, _unit, _amount, action in request.triggers:
            if action[0] == "set":
                variables[action[1]] = action[2]
            else:
                self.skipped["outputs"] += 1

    # ---- the operator's side, and what the rest of the runtime reads ----------------------
    def give(self) -> None:
        """Real-time: the operator's step (the caller checked ``waiting``): the move waiting
        (or the approach) goes at the next update."""
        self.granted = True
        self.waiting = False

    def unreached(self, vm) -> str | None:
        """Real-time, after the VM's step while forwarding: why the start cannot be made (the
        program ended before the line, or ran too long without reaching it), else None."""
        if vm.status is DONE:
            return (f"start from line {self.from_line}: the program ended without reaching the move at line "
                    f"{self.from_line} (it is in a branch or a loop the program did not run)")
        if vm.instructions > MAX_FORWARD_INSTRUCTIONS:
            return (f"start from line {self.from_line}: the program ran {MAX_FORWARD_INSTRUCTIONS:,} instructions "
                    f"from its start without reaching the move at line {self.from_line} (it is at line {vm.line}: a "
                    "loop that does not end before it?)")
        return None

    @staticmethod
    def program_moves(moves: list[MoveRecord]) -> list[MoveRecord]:
        """The program's own moves of a run's records (the approach left out)."""
        return [m for m in moves if not m.approach] if moves and moves[0].approach else moves

    @staticmethod
    def moves_done(moves: list[MoveRecord], completed: int) -> int:
        """The program's moves completed, of the motion queue's ``completed`` (real-time)."""
        return completed - 1 if moves and moves[0].approach and moves[0].t_end is not None else completed

    def summary(self, moves: list[MoveRecord]) -> dict | None:
        """Not real-time: the start from a line for the run's summary (None: from the start)."""
        if self.from_line is None:
            return None
        approach = moves[0] if moves and moves[0].approach else None
        return {"line": self.from_line, "reached": not self.forwarding, "skipped": dict(self.skipped),
                "approach": None if approach is None else
                {"to_line": self.last.line if self.last is not None else None, "target": list(approach.target),
                 "planned_duration": approach.planned_duration, "actual_duration": approach.actual_duration}}
