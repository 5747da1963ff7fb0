"""The object-code interpreter: runs a verified :class:`compiler.objcode.Program` inside
the Trajectory Generator's 5 ms update.

Each :meth:`VM.step` executes at most ``budget`` instructions and returns; it never
blocks and never does I/O itself. Everything the program needs from the world (the
clock, moves, digital I/O, the operator log) goes through a :class:`MotionHost`, which
the trajectory component implements. An instruction that has to wait for the world
(a move, a dwell, a ``wait for``, ``pause``) ends the step with status ``WAITING``; the
next step checks the wait again and carries on when it is over (the lecture's rule: no
action waits in a loop for the world to change).

What the operators and built-in functions compute comes from
:mod:`compiler.semantics`, the definition the compiler's constant folding also uses.
A run-time error never escapes :meth:`VM.step`: the VM stops with status ``ERROR`` and
a :class:`VMError` naming the source line.

The parts. :class:`VM` steps the program (the program counter, the budget, the two
dispatch loops, the status) and carries out the instructions that deal with the world
through the host; :class:`Memory` holds the operand stack, the variables and the call
frames; :class:`Waits` what a step waits for; :class:`Interrupts` the interrupts' state.

Dispatch. The handlers (``op_<name>`` methods, one per instruction, each in the class whose
state it works on: :data:`HANDLER_CLASSES`) are collected from the instruction table when
this module is imported, and the import fails if any instruction has none, or two. The
instructions the table marks as barriers to the motion look-ahead (``InstrDef.barrier``)
run only where the robot is: the VM wraps their handlers (:meth:`VM._at_robot`). Two loops
run them:

* ``dispatch="inline"`` (the default): the most frequent instructions (:data:`INLINE`:
  loads, stores, constants, ``+ - *``, comparisons, jumps, array items) are executed inline
  by an if-chain ordered by frequency, the others through the handler table;
* ``dispatch="table"``: every instruction through the handler table. It is the
  reference the inline loop is tested against, and the baseline of
  ``benchmarks/vm_speed.py``.

Measured with ``benchmarks/vm_speed.py`` (an arithmetic loop, Python 3.11): the inline
loop takes about 170 ns per instruction, the table loop about 280 ns (1.6x slower).

Real-time notes: ``step``, ``pause``, ``resume`` and ``abort`` run in the real-time
loop. ``step`` allocates only what the program's own values need (arrays, strings,
joint and pose values, call frames) and the few objects of a move hand-over.

Bounds (no program, and no forged object file, can stall the loop or exhaust memory):

* instructions: at most ``budget`` per step (``trajectory.budget``, 1..10,000);
* time: given a ``deadline`` (the wall clock; the trajectory generator gives
  :data:`TIME_SLICE` per update), the step runs in slices of :data:`SLICE` instructions
  and ends at the first slice boundary after the deadline (the program goes on at the
  next step). On the simulated clock there is no deadline: the run stays deterministic;
* values: a string of at most :data:`compiler.semantics.MAX_STRING_LENGTH` characters,
  an array of at most :data:`compiler.objcode.MAX_ARRAY_ELEMENTS` elements (all levels
  together), at most :data:`MAX_CALL_DEPTH` nested calls; a program that exceeds one
  stops with an error at its line. The longest single instruction is therefore bounded
  too (copying the largest array);
* the operator log: ``print`` lines of at most MAX_STRING_LENGTH characters, and the
  host keeps a bounded number of them.
"""
from __future__ import annotations

import enum
import operator
from collections import deque
from dataclasses import dataclass
from typing import Protocol

from time import perf_counter

from compiler.clauses import CLAUSES, Motion
from compiler.objcode import BUILTIN_NAMES, FIELDS, INSTRUCTIONS, MAX_ARRAY_ELEMENTS, OP, Program, clause_names, zero_of
from compiler.semantics import (INT_MAX, INT_MIN, MAX_STRING_LENGTH, EvalError, binary, call_builtin,
                                check_index, get_axis, get_field, make_joint, make_pos, make_pose, make_quat,
                                make_rpy, set_axis, unary)
from compiler.configs import TURNS_FLAG, from_operand
from compiler.recovery import BY_NAME as ERROR_KINDS, USER_ERRORS, error_kind
from compiler.robotstate import CLOCKS
from compiler.values import MUTABLE, Pose, Record, copy_value, elements_of, format_number, format_value

from runtime.loop.persistence import fitted
from runtime.recording import HALT, HANDLED, INTERRUPT, PAUSE, PRINT, TIMEOUT

#: Deepest nesting of procedure calls before the program is stopped with an error.
MAX_CALL_DEPTH = 200

#: Instructions run between two looks at the step's deadline.
SLICE = 32

#: What ``print`` puts between its values. The example programs and the language
#: reference write their own spaces (``print "cycle ", n, ": ", kind;``), so the values
#: are joined without a separator.
PRINT_SEPARATOR = ""


_NUMBER_TYPES = (int, float)  # (type(x) in: bool is not a number here)


class VMStatus(enum.IntEnum):
    READY = 0  # not started
    RUNNING = 1  # the budget was used up: call step again
    WAITING = 2  # waiting for motion, a dwell, a 'wait for' condition, or pause
    DONE = 3  # END or HALT reached
    ERROR = 4  # a run-time error, or aborted by the operator


READY, RUNNING, WAITING, DONE, ERROR = (VMStatus.READY, VMStatus.RUNNING, VMStatus.WAITING,
                                         VMStatus.DONE, VMStatus.ERROR)


@dataclass(frozen=True)
class VMError:
    """A run-time error: what went wrong and where (source line and column, code offset)."""

    message: str
    line: int
    column: int
    offset: int

    def __str__(self) -> str:
        return f"line {self.line}: {self.message}"


class MotionHost(Protocol):
    """What the VM needs from the world; the trajectory component implements it.
    Every method is called from the real-time loop and must not block."""

    def now(self) -> float:
        """Seconds, the executive's clock."""

    def move(self, kind: Motion, targets: tuple, clauses: dict, line: int, tag: int = 0) -> str | None:
        """Hand over a move: ``kind`` is a :class:`compiler.clauses.Motion`; ``targets`` is
        ``(target,)``, or ``(via, end)`` for circ; ``clauses`` holds only the clauses the
        program gave ({name: value}). None when accepted, else an error message (the
        program's "move" error at ``line``). ``tag`` names the move: a failure found later
        is reported with it (:meth:`VM.fail`)."""

    def motion_done(self) -> bool:
        """True when the robot has finished every move handed over."""

    def queue_ready(self) -> bool:
        """True when the program may hand over another move (look-ahead room). Optional:
        a host without it gets one move at a time (``motion_done``)."""

    def read_input(self, n: int) -> bool:
        """Digital input n (from 1). May raise EvalError for a number out of range."""

    def read_analog(self, n: int) -> float:
        """What analog input n (from 1) reads now. May raise EvalError for a number out of
        range, or a reading outside the input's range (a sensor's fault)."""

    def write_output(self, n: int, value: bool) -> None:
        """Set digital output n (from 1). May raise EvalError for a number out of range."""

    def read_output(self, n: int) -> bool:
        """Digital output n (from 1) as last set. May raise EvalError for a number out of range."""

    def write_analog(self, n: int, value: float) -> None:
        """Set analog output n (from 1) to ``value``. May raise EvalError for a number out
        of range (the io error), ProgramError for a value outside its range (value)."""

    def read_analog_output(self, n: int) -> float:
        """What analog output n (from 1) was last set to. May raise EvalError."""

    def read_group(self, first: int, bits: int) -> int:
        """Digital inputs first .. first + bits - 1 as one unsigned integer (input first: its
        lowest bit). May raise EvalError (compiler.robotstate.group_problem)."""

    def write_group(self, first: int, bits: int, value: int) -> None:
        """Set digital outputs first .. first + bits - 1 to value's bits, in one tick. May
        raise EvalError (compiler.robotstate.group_problem, group_value_problem)."""

    def pulse_output(self, n: int, seconds: float) -> None:
        """Set digital output n now and clear it ``seconds`` later (the program goes on).
        May raise EvalError for a number out of range."""

    def log(self, text: str, line: int, kind: str = PRINT) -> None:
        """The operator log: ``print`` statements and VM notices, each of its ``kind``
        (runtime.recording.EVENTS: print, pause, timeout, interrupt, halt)."""

    def trigger(self, place: int, unit: int, amount: object, action: tuple) -> str | None:
        """A path trigger of the next move (compiler.triggers): ``action`` is ``("out", n,
        value)`` or ``("set", global slot, value)``. None when accepted, else the problem."""

    def motion_line(self) -> int | None:
        """The source line of the move the robot is executing, or None (what an
        interrupt's log line names: the program itself may have run ahead)."""

    def interrupt_stop(self) -> None:
        """An interrupt fired with ``stop``: bring the motion to a stop on its path and hold
        it until :meth:`interrupt_release`."""

    def interrupt_release(self) -> None:
        """The handler of an interrupt with ``stop`` ended (``then resume``): go on."""

    def interrupt_halt(self, reason: str) -> None:
        """The program ends by an interrupt: stop on the path, drop the moves not made."""

    def current_joint(self) -> object:
        """Where the robot stands (a compiler.values.Joint): every axis's commanded position."""

    def current_pose(self) -> object:
        """The tool centre point of the active tool in the active base, with the arm's
        configuration (a compiler.values.Pose). May raise EvalError (no kinematics)."""

    def kept(self, name: str, type_: str) -> object:
        """The value the runtime kept of persistent variable ``name`` (declared ``type_``)
        from an earlier run, or None (runtime.loop.persistence)."""

    def keep(self, name: str, type_: str, value: object) -> None:
        """Keep ``value`` of persistent variable ``name`` for later runs (never waits)."""

    def search_end(self) -> str | None:
        """The search move handed over last has ended (the robot is at rest): None when its
        input became true on the way, else why not (the program's search error)."""

    def search_pose(self) -> object:
        """Where the last search found its input (a compiler.values.Pose). Raises
        EvalError before any did."""

    def tcp_speed(self) -> float:
        """The speed of the tool centre point now, mm/s."""

    def use_frame(self, keyword: str, name: str, value: object) -> str | None:
        """``use base`` / ``use tool`` (``keyword``): make the pose ``value``, called
        ``name``, the active base or tool for the moves after it. None when accepted, else
        the problem (which stops the program at the statement's line)."""


#: Seconds within which two times are the same instant: a dwell or a time-out ends at the
#: step whose time is its end, whatever the rounding of the clock's sum (a clock counts
#: ticks from power-up, and 10.0 + 0.2 need not be the float of tick 10200).
_SAME_INSTANT = 1e-9

# What a step is waiting for before it can execute the next instruction.
_NO_WAIT, _W_MOTION, _W_DWELL, _W_QUEUE = 0, 1, 2, 3

# The return offset of an interrupt handler's frame: its RET goes back to the program.
_FROM_INTERRUPT = -1

_CLAUSE_NAMES = tuple(tuple(clause_names(mask)) for mask in range(1 << len(CLAUSES)))

#: The instructions the inline dispatch loop (:meth:`VM._run_inline`) executes itself, the
#: others going through their handlers. Each gives exactly what its handler gives:
#: tests/test_vm.py runs both on random operands, and finds the loop's own set by running
#: it, so an instruction added to the loop and not here (or here and not to the loop) fails.
INLINE = ("LOAD_GLOBAL", "CONST", "LOAD_LOCAL", "STORE_GLOBAL", "STORE_LOCAL", "JUMP_IF_FALSE",
          "ADD", "SUB", "MUL", "JUMP", "LE", "LT", "GE", "GT", "EQ", "NE", "GET_ITEM")

# The inline loop's arithmetic (semantics.binary's operator of each) and comparisons.
_SYMBOLS = {OP.ADD: "+", OP.SUB: "-", OP.MUL: "*"}
_ARITHMETIC_OPS = frozenset(_SYMBOLS)
_COMPARE = {OP.LE: operator.le, OP.LT: operator.lt, OP.GE: operator.ge, OP.GT: operator.gt, OP.EQ: operator.eq,
            OP.NE: operator.ne}
_COMPARISON_OPS = frozenset(_COMPARE)


#: The instructions whose ZeroDivisionError or OverflowError is the program's arithmetic.
_ARITHMETIC = frozenset({OP.ADD, OP.SUB, OP.MUL, OP.DIV, OP.IDIV, OP.MOD, OP.NEG, OP.TO_REAL, OP.CALL_BUILTIN})


def _describe(exc: Exception, op: int | None = None) -> str:
    """The operator's message for an exception raised while executing instruction ``op``:
    the program's own errors (EvalError) say what the program did wrong; anything else is
    said in the program's terms, the instruction that failed, never as the exception's own
    text (a Python message such as "tuple index out of range" means nothing at a robot)."""
    if isinstance(exc, EvalError):
        return str(exc)
    if op in _ARITHMETIC:  # (the same exceptions from the host are its failure, not the program's)
        if isinstance(exc, ZeroDivisionError):
            return "division by zero"
        if isinstance(exc, OverflowError):
            return "numeric overflow"
    what = ""
    if op is not None and 0 <= op < len(INSTRUCTIONS):
        instruction = INSTRUCTIONS[op]
        what = f" while carrying out {instruction.name} ({instruction.doc.rstrip('.').lower()})"
    return f"internal error of the runtime{what}: not a fault of the program"


class ProgramError(EvalError):
    """An error a program's handler can take (compiler.recovery): its message, its number,
    and the line it was first raised at (0: where it is raised now)."""

    def __init__(self, message: str, number: int, line: int = 0):
        super().__init__(message)
        self.number = number
        self.line = line


_MOVE, _TIMEOUT, _ARITHMETIC_ERROR, _VALUE, _IO, _SEARCH = (
    ERROR_KINDS[name].number for name in ("move", "timeout", "arithmetic", "value", "io", "search"))
#: The instructions whose errors are the program's arithmetic, and its I/O's.
_ARITHMETIC_ONLY = _ARITHMETIC - {OP.CALL_BUILTIN}
_IO_OPS = frozenset({OP.IN_GET, OP.OUT_SET, OP.OUT_GET, OP.PULSE_OUT, OP.AIN_GET, OP.GROUP_IN, OP.GROUP_OUT,
                     OP.AOUT_SET, OP.AOUT_GET})


def error_number(exc: Exception, op: int) -> int | None:
    """The number (compiler.recovery.ERRORS) of the error that ``exc``, raised by
    instruction ``op``, is to the program; None: it is not the program's (the runtime's own
    failure), and no handler takes it."""
    if isinstance(exc, ProgramError):
        return exc.number
    if op in _ARITHMETIC and isinstance(exc, (ZeroDivisionError, OverflowError)):
        return _ARITHMETIC_ERROR
    if not isinstance(exc, EvalError):
        return None
    if op in _ARITHMETIC_ONLY:
        return _ARITHMETIC_ERROR
    return _IO if op in _IO_OPS else _VALUE


class Memory:
    """The program's data and its calls: the operand stack, the global slots, the local slots
    of the routine running, the call frames; with the handlers of the instructions that only
    compute on them (constants, loads and stores, operators, values, jumps, calls).

    Real-time (its handlers run in the step); built once per program."""

    def __init__(self, program: Program, max_call_depth: int):
        self.stack: list = []
        # (each slot its declared type's zero: a slot read before its first store, which verified
        # object code need not rule out, still holds a value of its type)
        self.globals: list = [zero_of(slot[1], records=program.record_table)
                              if isinstance(slot, tuple) and len(slot) == 2 else None for slot in program.globals]
        self.records = program.records
        self.locals: list = []  # the current procedure's slots (the main program has none)
        self.frames: list[tuple[int, list, int]] = []  # (return offset, caller's locals, the callee's stack base)
        self.max_call_depth = max_call_depth
        self.consts = list(program.constants)
        self.procs = [(p.entry, p.params, len(p.locals), p.name) for p in program.procedures]
        # each routine's local slots as a call starts them: its declared types' zeros (as the
        # globals': a slot read before its first store still holds its type), and which of
        # them are arrays or records (copied for each call, never shared)
        self.zeros = []
        for p in program.procedures:
            template = [zero_of(typ, records=program.record_table) for _name, typ in p.locals]
            self.zeros.append((template, tuple(i for i, v in enumerate(template) if type(v) in MUTABLE)))
        self.kept: dict = {}  # local slot -> the value a returning procedure kept for its caller (KEEP, TAKE)

    def pop_n(self, n: int) -> list:
        stack = self.stack
        if not n:
            return []
        values = stack[-n:]
        del stack[-n:]
        return values

    def enter_handler(self, proc: int) -> int:
        """An interrupt's handler (procedure ``proc``, without parameters) starts: a frame
        whose return goes back to the program (:data:`_FROM_INTERRUPT`). Returns its entry."""
        entry = self.procs[proc][0]
        self.frames.append((_FROM_INTERRUPT, self.locals, len(self.stack)))
        self.locals = self.fresh_locals(proc)
        return entry

    def fresh_locals(self, proc: int) -> list:
        """Routine ``proc``'s local slots as a call starts them (see ``zeros``)."""
        template, mutable = self.zeros[proc]
        frame = template[:]
        for i in mutable:
            frame[i] = copy_value(frame[i])
        return frame

    def leave(self) -> int:
        """The routine running returns: the caller's slots again; returns where to go on
        (:data:`_FROM_INTERRUPT` for an interrupt's handler)."""
        back, self.locals, _base = self.frames.pop()
        return back

    def base(self) -> int:
        """Where the running routine's part of the operand stack starts."""
        return self.frames[-1][2] if self.frames else 0

    # -- the handlers: op_<name>(operand, pc) -> the next pc --------------------------------
    # ``operand`` is None for an instruction without operands, the operand for one with
    # one, and a tuple for one with two.

    def op_nop(self, _, pc):
        return pc + 1

    def op_const(self, k, pc):
        self.stack.append(self.consts[k])
        return pc + 1

    def op_load_global(self, g, pc):
        self.stack.append(self.globals[g])
        return pc + 1

    def op_store_global(self, g, pc):
        self.globals[g] = self.stack.pop()
        return pc + 1

    def op_load_local(self, slot, pc):
        self.stack.append(self.locals[slot])
        return pc + 1

    def op_store_local(self, slot, pc):
        self.locals[slot] = self.stack.pop()
        return pc + 1

    def op_copy(self, _, pc):
        stack = self.stack
        if type(stack[-1]) in MUTABLE:
            stack[-1] = copy_value(stack[-1])
        return pc + 1

    def op_to_real(self, _, pc):
        stack = self.stack
        stack[-1] = float(stack[-1])
        return pc + 1

    def op_neg(self, _, pc):
        stack = self.stack
        stack[-1] = unary("-", stack[-1])
        return pc + 1

    def op_not(self, _, pc):
        stack = self.stack
        stack[-1] = unary("not", stack[-1])
        return pc + 1

    def _binary(self, op: str, pc: int) -> int:
        stack = self.stack
        b = stack.pop()
        stack[-1] = binary(op, stack[-1], b)
        return pc + 1

    def op_add(self, _, pc):
        return self._binary("+", pc)

    def op_sub(self, _, pc):
        return self._binary("-", pc)

    def op_mul(self, _, pc):
        return self._binary("*", pc)

    def op_div(self, _, pc):
        return self._binary("/", pc)

    def op_idiv(self, _, pc):
        return self._binary("div", pc)

    def op_mod(self, _, pc):
        return self._binary("mod", pc)

    def op_eq(self, _, pc):
        return self._binary("=", pc)

    def op_ne(self, _, pc):
        return self._binary("<>", pc)

    def op_lt(self, _, pc):
        return self._binary("<", pc)

    def op_le(self, _, pc):
        return self._binary("<=", pc)

    def op_gt(self, _, pc):
        return self._binary(">", pc)

    def op_ge(self, _, pc):
        return self._binary(">=", pc)

    def op_and(self, _, pc):
        return self._binary("and", pc)

    def op_or(self, _, pc):
        return self._binary("or", pc)

    def op_call_builtin(self, operands, pc):
        fn, argc = operands
        self.stack.append(call_builtin(BUILTIN_NAMES[fn], self.pop_n(argc)))
        return pc + 1

    def op_make_joint(self, operands, pc):
        main, add = operands
        values = self.pop_n(main + add)
        self.stack.append(make_joint(values[:main], values[main:]))
        return pc + 1

    def op_make_pos(self, _, pc):
        self.stack.append(make_pos(*self.pop_n(3)))
        return pc + 1

    def op_make_rpy(self, _, pc):
        self.stack.append(make_rpy(*self.pop_n(3)))
        return pc + 1

    def op_make_quat(self, _, pc):
        self.stack.append(make_quat(*self.pop_n(4)))
        return pc + 1

    def op_make_pose(self, _, pc):
        stack = self.stack
        orientation = stack.pop()
        stack[-1] = Pose(stack[-1], orientation)
        return pc + 1

    def op_make_config(self, words, pc):
        turns = None
        if words & TURNS_FLAG:
            turns = tuple(self.pop_n(3))
            for k in turns:
                if type(k) is not int:  # (the verifier saw integers: hand-made code is checked again)
                    raise EvalError(f"a turn number must be an integer, not {format_value(k)}")
        self.stack.append(from_operand(words, turns))
        return pc + 1

    def op_make_pose_config(self, _, pc):
        stack = self.stack
        config = stack.pop()
        orientation = stack.pop()
        stack[-1] = make_pose(stack[-1], orientation, config)
        return pc + 1

    def op_make_array(self, n, pc):
        stack = self.stack
        element = stack[-1]
        if n * elements_of(element) > MAX_ARRAY_ELEMENTS:
            raise EvalError(f"an array of {n} x {elements_of(element)} elements is larger than "
                            f"{MAX_ARRAY_ELEMENTS} elements, the largest allowed")
        if type(element) in MUTABLE:
            stack[-1] = [copy_value(element) for _ in range(n)]
        else:
            stack[-1] = [element] * n
        return pc + 1

    def op_get_item(self, low, pc):
        stack = self.stack
        index = stack.pop()
        array = stack[-1]
        stack[-1] = array[check_index(index, low, len(array))]
        return pc + 1

    def op_set_item(self, low, pc):
        stack = self.stack
        value = stack.pop()
        index = stack.pop()
        array = stack.pop()
        array[check_index(index, low, len(array))] = value
        return pc + 1

    def op_get_axis(self, _, pc):
        stack = self.stack
        axis = stack.pop()
        stack[-1] = get_axis(stack[-1], axis)
        return pc + 1

    def op_set_axis(self, _, pc):
        stack = self.stack
        value = stack.pop()
        axis = stack.pop()
        stack[-1] = set_axis(stack[-1], axis, value)
        return pc + 1

    def op_make_record(self, r, pc):
        record = self.records[r]
        self.stack.append(Record(record.name, record.names, self.pop_n(len(record.fields))))
        return pc + 1

    def op_get_member(self, f, pc):
        stack = self.stack
        stack[-1] = stack[-1][f]
        return pc + 1

    def op_set_member(self, f, pc):
        stack = self.stack
        value = stack.pop()
        stack.pop()[f] = value
        return pc + 1

    def op_get_field(self, f, pc):
        stack = self.stack
        stack[-1] = get_field(stack[-1], FIELDS[f])
        return pc + 1

    def op_jump(self, target, pc):
        return target

    def op_jump_if_false(self, target, pc):
        return pc + 1 if self.stack.pop() else target

    def op_call(self, p, pc):
        entry, params, _slots, name = self.procs[p]
        if len(self.frames) >= self.max_call_depth:
            raise EvalError(f"too many nested procedure or function calls (more than {self.max_call_depth}) "
                            f"calling {name}: is the recursion endless?")
        template, mutable = self.zeros[p]
        frame = template[:]  # (fresh_locals, inline: a call is frequent)
        for i in mutable:
            frame[i] = copy_value(frame[i])
        if params:
            stack = self.stack
            frame[:params] = stack[-params:]
            del stack[-params:]
        self.frames.append((pc + 1, self.locals, len(self.stack)))
        self.locals = frame
        return entry

    # A function is called as a procedure is; its RET_VALUE leaves the result on the stack,
    # where the caller's expression goes on from (the verifier checked the depths).
    op_call_func = op_call

    # A 'var' parameter: the procedure keeps its value as it returns (KEEP), the caller takes
    # it just after the call (TAKE) and stores it into the variable it passed.
    def op_keep(self, slot, pc):
        self.kept[slot] = self.locals[slot]
        return pc + 1

    def op_take(self, operands, pc):
        value = self.kept.pop(operands[1], self)
        if value is self:
            raise EvalError(f"procedure {self.procs[operands[0]][3]} kept no value of its local slot {operands[1]} "
                            "(object code that takes a 'var' parameter it did not keep)")
        self.stack.append(value)
        return pc + 1


class Waits:
    """What a step waits for before it can execute the next instruction: the motion, the
    look-ahead queue's room, a dwell, and the time-out of a ``wait for``. Asks the host."""

    def __init__(self, host: MotionHost):
        self.host = host
        self.kind = _NO_WAIT
        self.dwell_seconds = 0.0
        self.dwell_until: float | None = None
        self.last_timed_out = False  # did the last 'wait for ... timeout' end by its time-out (timed_out())
        self.deadline: float | None = None  # of the current 'wait for', or None
        self.timeout = 0.0
        self._queue_ready = getattr(host, "queue_ready", host.motion_done)

    def over(self) -> bool:
        """Is the wait started by the last instruction over? (Asks the host.)"""
        kind = self.kind
        host = self.host
        if kind == _W_QUEUE:
            return self._queue_ready()
        if kind == _W_MOTION:
            return host.motion_done()
        if kind == _W_DWELL:
            if self.dwell_until is None:
                if not host.motion_done():
                    return False
                self.dwell_until = host.now() + self.dwell_seconds
            return host.now() >= self.dwell_until - _SAME_INSTANT
        return True

    def start(self, kind: int) -> bool:
        """Start a wait; True when it is over at once (then there is none)."""
        self.kind = kind
        if self.over():
            self.kind = _NO_WAIT
            return True
        return False

    def dwell(self, seconds, at_once: bool) -> bool:
        """Start a dwell of ``seconds``: when the motion has ended, or ``at_once`` (in an
        interrupt's handler, beside the motion). True when it is over at once."""
        self.dwell_seconds = float(seconds)
        self.dwell_until = self.host.now() + seconds if at_once else None
        return self.start(_W_DWELL)

    def begin_wait_for(self, timeout) -> None:
        """A ``wait for`` starts: with a time-out in seconds, or None."""
        if timeout is None:
            self.deadline = None
        else:
            self.timeout = timeout
            self.deadline = self.host.now() + timeout

    def end_wait_for(self) -> None:
        """The condition of the ``wait for`` holds."""
        self.deadline = None
        self.last_timed_out = False

    def timed_out(self) -> bool:
        """Has the time-out of the ``wait for`` passed? (Then the wait is over.)"""
        deadline = self.deadline
        if deadline is not None and self.host.now() >= deadline - _SAME_INSTANT:
            self.deadline = None
            self.last_timed_out = True
            return True
        return False

    def saved(self) -> tuple:
        """The wait the program is in (an interrupt's handler runs meanwhile)."""
        return self.kind, self.dwell_seconds, self.dwell_until, self.deadline, self.timeout, self.last_timed_out

    def restore(self, saved: tuple) -> None:
        (self.kind, self.dwell_seconds, self.dwell_until, self.deadline, self.timeout,
         self.last_timed_out) = saved


class Interrupts:
    """The program's interrupts (compiler.interrupts): which are enabled, their conditions
    checked for an edge at each step, the pending ones, and the one whose handler runs (with
    the program's state to go back to). With the handlers of INT_ENABLE and INT_DISABLE."""

    def __init__(self, program: Program, host: MotionHost, memory: Memory, ops: list, args: list):
        self.host = host
        self._memory = memory  # (a condition reads the constants and the globals)
        self._ops, self._args = ops, args
        # per entry (name, condition entry, handler, stop, halt)
        self.table = [(x.name, program.procedures[x.condition].entry, x.handler, x.stop, x.halt)
                      for x in program.interrupts]
        self.order = sorted(range(len(self.table)), key=lambda i: (program.interrupts[i].priority, i))
        self.enabled = [False] * len(self.table)
        self.was = [False] * len(self.table)  # its condition at the last check
        self.pending = [False] * len(self.table)  # fired, its handler not run yet
        self.armed = 0  # how many are enabled
        self.handling: tuple | None = None  # (interrupt, the program's state to go back to, its line)

    def check(self) -> None:
        """Every enabled interrupt's condition: an edge (true now, not at the last check)
        makes it pending, except while its own handler runs."""
        handling = self.handling[0] if self.handling is not None else -1
        for i, enabled in enumerate(self.enabled):
            if enabled:
                now = self._condition(i)
                if now and not self.was[i] and i != handling:
                    self.pending[i] = True
                self.was[i] = now

    def _condition(self, i: int) -> bool:
        """Evaluate interrupt ``i``'s condition: straight-line code of the few instructions
        the verifier allows there (compiler.interrupts.CONDITION_OPS); reads the inputs now."""
        ops, args, consts, globals_ = self._ops, self._args, self._memory.consts, self._memory.globals
        pc = self.table[i][1]
        stack: list = []
        while True:
            op = ops[pc]
            if op == OP.CONST:
                stack.append(consts[args[pc]])
            elif op == OP.LOAD_GLOBAL:
                stack.append(globals_[args[pc]])
            elif op == OP.IN_GET:
                n = stack.pop()
                try:
                    stack.append(self.host.read_input(n))
                except Exception as exc:  # the host's refusal (EvalError), or its failure
                    raise EvalError(f"interrupt {self.table[i][0]}: {_describe(exc, op)}") from None
            elif op == OP.NOT:
                stack.append(not stack.pop())
            elif op == OP.AND:
                b = stack.pop()
                stack[-1] = stack[-1] and b
            elif op == OP.OR:
                b = stack.pop()
                stack[-1] = stack[-1] or b
            else:  # RET_VALUE
                value = stack.pop()
                if type(value) is not bool:
                    raise EvalError(f"interrupt {self.table[i][0]}: its condition is not a bool")
                return value
            pc += 1

    def fire(self, line: int, saved: tuple) -> int:
        """The pending interrupt of the highest priority fires while the program is at
        ``line`` in state ``saved``: the motion stops on its path (``stop``), the log says
        so. Returns its handler (a procedure), which the VM runs."""
        i = next(k for k in self.order if self.pending[k])
        self.pending[i] = False
        name, _cond, handler, stop, _halt = self.table[i]
        moving = self.host.motion_line()
        line = line if moving is None else moving
        if stop:
            self.host.interrupt_stop()
        self.host.log(f"interrupt {name} fired {'at' if moving is None else 'during the move at'} line {line}"
                      f"{'' if stop else ' (the robot goes on)'}", line, INTERRUPT)
        self.handling = (i, saved, line)
        return handler

    def handler_returned(self) -> tuple | None:
        """The handler returned: the program's state to go on from (``then resume``, the
        motion released after ``stop``), or None when the program ends (``then halt``:
        :meth:`halt_program` follows)."""
        i, saved, _line = self.handling
        _name, _cond, _handler, stop, halt = self.table[i]
        if halt:
            return None
        self.handling = None
        if stop:
            self.host.interrupt_release()
        return saved

    def halt_program(self) -> None:
        """The program ends by the interrupt whose handler runs (``then halt``, or ``halt``
        in the handler): stop on the path, drop the moves not made, switch every one off."""
        i, _saved, line = self.handling
        self.handling = None
        name = self.table[i][0]
        self.host.interrupt_halt(f"ended by interrupt {name}")
        self.host.log(f"interrupt {name} ended the program (it fired at line {line})", line, HALT)
        self.enabled = [False] * len(self.table)
        self.armed = 0

    def end_handling(self) -> None:
        """The program stops with an error while an interrupt's handler runs: the handler
        never returns, so an interrupt with ``stop`` would hold the motion for ever (the
        program, waiting for its moves to end before its error ends it, with it). The
        motion stops for good instead, its moves not made dropped (as ``then halt``): the
        error then ends the program with the robot at rest."""
        handling, self.handling = self.handling, None
        if handling is not None and self.table[handling[0]][3]:
            try:
                self.host.interrupt_halt(f"program error in interrupt {self.table[handling[0]][0]}")
            except Exception:  # never raise: the program has ended with its error anyway
                pass

    # enable and disable act where the robot is (barriers in the instruction table, as
    # out[...] is): an interrupt guards the moves after its enable, and the moves before its
    # disable
    def op_int_enable(self, i, pc):
        if not self.enabled[i]:
            self.enabled[i] = True
            self.armed += 1
        self.was[i] = False  # a condition already true fires at the next check
        return pc + 1

    def op_int_disable(self, i, pc):
        if self.enabled[i]:
            self.enabled[i] = False
            self.armed -= 1
        self.pending[i] = False
        return pc + 1


class Recovery:
    """The program's error handlers (compiler.recovery): which handler takes an error raised
    where, the errors being handled (one per routine whose handler runs), and the moves handed
    over (where each was issued, for an error the motion reports later). With the handlers of
    RAISE, RERAISE, RETRY, TRYNEXT and what a handler reads of its error."""

    #: Moves remembered with where they were issued (the motion reports a failure of one of
    #: the last few it was handed: those the look-ahead holds).
    ISSUED = 64

    def __init__(self, program: Program, memory: Memory):
        self.program = program
        self._memory = memory
        # per error being handled: (depth of its routine, number, message, line, retry at, trynext at)
        self.taking: list[tuple] = []
        self.last: tuple = (0, "", 0)  # the last error taken: (number, message, line)
        self.issued: deque = deque(maxlen=self.ISSUED)  # (tag, offset, frames, locals) per move handed over

    def handler_for(self, depth: int, pc: int) -> tuple | None:
        """The handler that takes an error raised at ``pc`` in the routine running at
        ``depth`` (call frames), or in a caller of it: (its routine's depth, the handler, the
        offset in that routine the error counts at). None: none does (an interrupt's handler
        passes no error on to the program it interrupted)."""
        frames = self._memory.frames
        program = self.program
        while True:
            handler = program.handler_at(pc)
            if handler is not None:
                return depth, handler, pc
            if depth == 0:
                return None
            back = frames[depth - 1][0]
            if back == _FROM_INTERRUPT:
                return None
            pc, depth = back - 1, depth - 1  # (the CALL of the routine that raised it)

    def enter(self, found: tuple, number: int, message: str, line: int) -> int:
        """The handler ``found`` (:meth:`handler_for`) takes an error: the routines after
        its own are left, its stack emptied, the error recorded for ``retry``, ``trynext``
        and ``raise``. Returns the handler's entry."""
        depth, handler, pc = found
        memory = self._memory
        while len(memory.frames) > depth:
            memory.leave()
        del memory.stack[memory.base():]
        memory.kept = {}
        start, end = handler.statement_at(pc)
        self.taking = [t for t in self.taking if t[0] < depth]
        self.taking.append((depth, number, message, line, start, end))
        self.last = (number, message, line)
        return handler.entry

    def left(self, depth: int) -> None:
        """The routine at ``depth + 1`` returned: the error its handler took is over."""
        if self.taking and self.taking[-1][0] > depth:
            self.taking = [t for t in self.taking if t[0] <= depth]

    def remember(self, tag: int, pc: int) -> None:
        """A move was handed over as ``tag``, by the instruction at ``pc``, in the calls
        running now."""
        memory = self._memory
        self.issued.append((tag, pc, tuple(memory.frames), memory.locals))

    def raise_point(self, tag: int) -> tuple[int, int] | None:
        """Where the error of move ``tag``, reported by the motion after the program ran on,
        counts: (depth, offset) of its move instruction when the routine that issued it
        still runs, else of the call, in the innermost routine still running, that led to
        it; None when the move is not remembered, or an interrupt's handler runs between."""
        record = next((r for r in self.issued if r[0] == tag), None)
        if record is None:
            return None
        _tag, pc, then, then_locals = record
        memory = self._memory
        now = memory.frames
        chain_then = [f[1] for f in then] + [then_locals]
        chain_now = [f[1] for f in now] + [memory.locals]
        same = 0
        while same < min(len(chain_then), len(chain_now)) and chain_then[same] is chain_now[same]:
            same += 1
        if same == 0:
            return None
        depth = same - 1
        if same < len(chain_then):  # (that routine has returned: the call that led to it)
            pc = then[depth][0] - 1
            if then[depth][0] == _FROM_INTERRUPT:
                return None
        if any(f[0] == _FROM_INTERRUPT for f in now[depth:]):
            return None
        return depth, pc

    def _taken(self) -> tuple:
        depth = len(self._memory.frames)
        taking = self.taking
        if not taking or taking[-1][0] != depth:
            raise RuntimeError("an error handler's instruction where no handler runs")
        return taking.pop()

    # ---- the handlers' instructions ----
    def op_retry(self, _, pc):
        return self._taken()[4]

    def op_trynext(self, _, pc):
        return self._taken()[5]

    def op_raise(self, _, pc):
        stack = self._memory.stack
        message = stack.pop()
        number = stack.pop()
        if not USER_ERRORS[0] <= number <= USER_ERRORS[1]:
            raise EvalError(f"raise {number}: a program's own errors are numbered {USER_ERRORS[0]}..{USER_ERRORS[1]}")
        raise ProgramError(message or f"error {number} raised by the program", number)

    def op_reraise(self, _, pc):
        _depth, number, message, line, _retry, _next = self._taken()
        raise ProgramError(message, number, line)

    def _error(self) -> tuple:
        """(number, message, line) of the error the running handler took (else the last)."""
        depth = len(self._memory.frames)
        for t in reversed(self.taking):
            if t[0] == depth:
                return t[1:4]
        return self.last

    def op_error_number(self, _, pc):
        self._memory.stack.append(self._error()[0])
        return pc + 1

    def op_error_name(self, _, pc):
        number = self._error()[0]
        self._memory.stack.append(error_kind(number).name if number else "")
        return pc + 1

    def op_error_message(self, _, pc):
        self._memory.stack.append(self._error()[1])
        return pc + 1


class VM:
    """Runs one program; see the module docstring. The VM steps the program (the program
    counter, the budget, the two dispatch loops) and carries out the instructions that deal
    with the world through the host; its :class:`Memory` (the stack, variables and calls),
    :class:`Waits` and :class:`Interrupts` hold the rest.

    Attributes: ``status`` (:class:`VMStatus`), ``error`` (:class:`VMError` or None),
    ``line`` (the line of the instruction executing or last executed),
    ``moves_issued`` (moves the host accepted), ``paused`` (by the operator or a
    ``pause`` statement); ``stack``, ``globals`` and ``frames`` are the memory's.
    """

    def __init__(self, program: Program, host: MotionHost, budget: int = 200, *,
                 dispatch: str = "inline", max_call_depth: int = MAX_CALL_DEPTH):
        """Not real-time: decodes the code into flat lists once. ``program`` must have
        been verified (:func:`compiler.objcode.verify`): the VM trusts its structure."""
        if budget < 1:
            raise ValueError(f"budget must be at least 1 instruction per step, not {budget}")
        if dispatch not in ("inline", "table"):
            raise ValueError(f"dispatch must be 'inline' or 'table', not {dispatch!r}")
        self.program = program
        self.host = host
        self.budget = budget
        self.status = READY
        self.error: VMError | None = None
        self.moves_issued = 0
        self.instructions = 0  # instructions executed so far
        self.paused = False
        # the code, flattened: opcode and operand (None, one int, or a tuple of ints)
        self._ops = [instr[0] for instr in program.code]
        self._args = [None if len(instr) == 1 else instr[1] if len(instr) == 2 else tuple(instr[1:])
                      for instr in program.code]
        self.memory = Memory(program, max_call_depth)
        self.waits = Waits(host)
        self.clocks = [[None, 0.0] for _ in range(CLOCKS)]  # per clock: (running since, seconds before that)
        self.interrupts = Interrupts(program, host, self.memory, self._ops, self._args)
        self.recovery = Recovery(program, self.memory)
        owners = {VM: self, Memory: self.memory, Interrupts: self.interrupts, Recovery: self.recovery}
        self._own = [handler.__get__(owners[owner]) for owner, handler in HANDLERS]  # (before the barrier)
        self._handlers = [self._at_robot(handler) if definition.barrier else handler
                          for definition, handler in zip(INSTRUCTIONS, self._own)]
        self._run = self._run_inline if dispatch == "inline" else self._run_table
        # stepping
        self.pc = 0
        self._here = 0  # offset of the instruction executing or last executed
        self._yield = False  # set by a handler: end this step after the instruction
        self._back_here: int | None = None  # the program's offset, when a handler has just returned

    def wrap(self, name: str, wrapper) -> None:
        """Not real-time: the handler of instruction ``name`` becomes ``wrapper(handler)``, a
        function ``(operand, pc) -> next pc`` as every handler is, called when the instruction
        really executes (a look-ahead barrier's wrapper runs only where the robot is, as the
        handler does). An offline run (runtime.loop.offline) sees this way where the program
        reads an input and tests a ``wait for``; step mode and a start from a line
        (runtime.loop.stepping) hold the moves and pass the waits. The instructions of :data:`INLINE` are
        executed by the inline loop itself: they cannot be wrapped (ValueError)."""
        if name in INLINE or not hasattr(OP, name):
            raise ValueError(f"instruction {name!r} cannot be wrapped")
        code = getattr(OP, name)
        handler = self._own[code] = wrapper(self._own[code])
        self._handlers[code] = self._at_robot(handler) if INSTRUCTIONS[code].barrier else handler

    def hold(self, motion: bool = False) -> None:
        """Real-time, for a wrapped handler (:meth:`wrap`) that cannot carry out its
        instruction yet (runtime.loop.stepping: a move waiting for a step): the step ends
        before the instruction, which runs again at the next step (``motion``: once every
        move handed over has ended). The wrapper then returns the instruction's own offset,
        its stack untouched."""
        if motion:
            self.waits.kind = _W_MOTION
        self._block()

    # -- the memory's, by their old names ----------------------------------------------
    @property
    def stack(self) -> list:
        return self.memory.stack

    @property
    def globals(self) -> list:
        return self.memory.globals

    @property
    def frames(self) -> list:
        return self.memory.frames

    # -- the operator's side (real-time) ------------------------------------------------
    @property
    def line(self) -> int:
        """The source line of the instruction executing or last executed (0 if none)."""
        return self.program.line_at(self._here)[0]

    @property
    def offset(self) -> int:
        """The code offset of the instruction executing or last executed."""
        return self._here

    def pause(self) -> None:
        """Real-time. Hold the program before its next instruction until :meth:`resume`."""
        if self.status < DONE:
            self.paused = True

    def resume(self) -> None:
        """Real-time. Continue after :meth:`pause` or a ``pause`` statement."""
        self.paused = False

    def abort(self) -> None:
        """Real-time. Stop the program for good: status ERROR, "aborted by the operator"."""
        if self.status < DONE:
            self._stop_with("aborted by the operator", self._here)
            self.paused = False

    def fail(self, message: str, line: int, tag: int | None = None) -> None:
        """Real-time. Stop the program with an error found by the host after the VM ran on
        (a move that could not be planned): status ERROR, the error at source ``line``,
        even if the program has reached its end meanwhile (look-ahead). The move's ``tag``
        (the one :meth:`MotionHost.move` was given): a handler of the routine that issued
        it (or of one that called it) takes it instead, when there is one."""
        if self.status < DONE and tag is not None and self._take_move_error(message, line, tag):
            return
        if self.status is not ERROR:
            self.error = VMError(message, line, 0, self._here)
            self.status = ERROR
            self.waits.kind = _NO_WAIT
            self.paused = False
            self.interrupts.end_handling()

    # -- running (real-time) --------------------------------------------------------------
    def step(self, deadline: float | None = None) -> VMStatus:
        """Real-time. Execute at most ``budget`` instructions; stop early at a wait, or
        at the first slice of :data:`SLICE` instructions that ends after ``deadline``
        (``time.perf_counter`` seconds; None: no time bound).

        Returns the new status: RUNNING (budget or time used up), WAITING, DONE or ERROR.
        Never raises.
        """
        status = self.status
        if status >= DONE:
            return status
        if self._back_here is not None:  # (the loop that ran the handler's RET ended at the handler)
            self._here, self._back_here = self._back_here, None
        interrupts = self.interrupts
        if interrupts.armed:
            try:
                interrupts.check()
            except Exception as exc:  # an input the host refuses: stop, never raise
                self._stop_with(_describe(exc, OP.IN_GET), self._here)
                return ERROR
        if self.paused:
            self.status = WAITING
            return WAITING
        if interrupts.handling is None and True in interrupts.pending:
            self._fire()
        waits = self.waits
        if waits.kind:
            try:
                if not waits.over():
                    self.status = WAITING
                    return WAITING
            except Exception as exc:  # the host failed: stop, never raise
                self._stop_with(_describe(exc, OP.WAIT_TEST), self._here)
                return ERROR
            waits.kind = _NO_WAIT
        self.status = RUNNING
        if deadline is None:
            self._run(self.budget)
            return self.status
        left = self.budget
        while left > 0:
            chunk = SLICE if left > SLICE else left
            self._run(chunk)
            left -= chunk
            if self.status is not RUNNING or perf_counter() > deadline:
                break
        return self.status

    # -- interrupts (real-time): the program's side --------------------------------------
    def _fire(self) -> None:
        """Run the handler of the pending interrupt of the highest priority: the program's
        state is kept, the motion stops on its path (``stop``), the handler starts."""
        handler = self.interrupts.fire(self.line, (self.pc, self._here, (self.waits.saved(), self.memory.kept)))
        self.memory.kept = {}
        self.pc = self.memory.enter_handler(handler)
        self.waits.kind = _NO_WAIT

    def _handler_done(self) -> int:
        """The handler returned: the program goes on where it was (``then resume``), or
        ends (``then halt``). Ends the step (the inline loop's locals change)."""
        saved = self.interrupts.handler_returned()
        if saved is None:
            return self._halt_by_interrupt()
        pc, self._back_here, (waits, kept) = saved
        self.waits.restore(waits)
        self.memory.kept = kept
        self._yield = True
        return pc

    def _halt_by_interrupt(self) -> int:
        """The program ends by the interrupt whose handler runs."""
        self.interrupts.halt_program()
        return self._end(self._here)

    # -- ending a step ---------------------------------------------------------------------
    def _await(self, wait: int) -> None:
        """Start a wait; when it is not over at once, end the step with WAITING."""
        if not self.waits.start(wait):
            self._block()

    def _block(self) -> None:
        self.status = WAITING
        self._yield = True

    def _at_robot(self, handler):
        """The handler of an instruction the instruction table marks as a barrier to the
        motion look-ahead (``InstrDef.barrier``: I/O, print, ``wait for``, ``pause``, switching
        an interrupt): it must happen where the robot really is. It runs when every move
        handed over has ended; else the step ends waiting for the motion, and the
        instruction runs again after it (the stack untouched). In an interrupt's handler, at
        once: it acts beside the motion."""
        interrupts, host = self.interrupts, self.host

        def at_robot(operand, pc):
            if interrupts.handling is not None or host.motion_done():
                return handler(operand, pc)
            self.waits.kind = _W_MOTION
            self._block()
            return pc
        return at_robot

    def _stop_with(self, message: str, offset: int, line: int = 0) -> None:
        at, column = self.program.line_at(offset)
        if line:
            column = 0
        else:
            line = at
        self.error = VMError(message, line, column, offset)
        self.status = ERROR
        self._here = offset
        self.waits.kind = _NO_WAIT
        self.interrupts.end_handling()

    def _ran(self, executed: int, pc: int, here: int) -> None:
        """A dispatch loop's end: ``executed`` instructions, the next at ``pc``."""
        self.instructions += executed
        self.pc = pc
        self._here = here

    def _failed(self, executed: int, exc: Exception, here: int) -> None:
        """A dispatch loop's end at an instruction that raised: a handler takes the error
        (compiler.recovery), or the program stops with it at its line (never raised out of
        step())."""
        self.instructions += executed
        op = self._ops[here]
        message = _describe(exc, op)
        number = error_number(exc, op)
        if number is not None:
            found = self.recovery.handler_for(len(self.memory.frames), here)
            if found is not None:
                line = (exc.line if isinstance(exc, ProgramError) else 0) or self.program.line_at(here)[0]
                self._here = here
                self._handle(found, number, message, line)
                return
        if isinstance(exc, ProgramError) and exc.line:  # (raise; with no handler above: where it was raised first)
            self._stop_with(f"{message} (passed on at line {self.program.line_at(here)[0]})", here, exc.line)
            return
        self._stop_with(message, here)

    def _handle(self, found: tuple, number: int, message: str, line: int) -> None:
        """Run the handler ``found`` for an error: once every move handed over before it has
        ended (the robot at rest where the motion stopped; in an interrupt's handler at
        once, beside the motion). The operator's log says so."""
        self.pc = self.recovery.enter(found, number, message, line)
        handler_line = self.program.line_at(self.pc)[0]
        kind = error_kind(number)
        what = f"error {number}" if kind.name == "user" else f"{kind.name} error"
        self.host.log(f"{what} at line {line}: {message} (handled at line {handler_line})", line, HANDLED)
        self.waits.kind = _NO_WAIT
        if self.interrupts.handling is None and not self.waits.start(_W_MOTION):
            self.status = WAITING
        else:
            self.status = RUNNING

    def _take_move_error(self, message: str, line: int, tag: int) -> bool:
        """A move the motion could not make after the program ran on: its handler takes it
        (:meth:`fail`). Whether one did."""
        point = self.recovery.raise_point(tag)
        found = self.recovery.handler_for(*point) if point is not None else None
        if found is None:
            return False
        self._back_here = None
        self._here = found[2]
        self._handle(found, _MOVE, message, line)
        return True

    def _run_table(self, budget: int) -> None:
        """Every instruction through the handler table."""
        n = budget
        ops, args, handlers = self._ops, self._args, self._handlers
        pc = here = self.pc
        try:
            while n:
                n -= 1
                here = pc
                pc = handlers[ops[pc]](args[pc], pc)
                if self._yield:
                    self._yield = False
                    break
        except Exception as exc:  # never raise out of step()
            self._failed(budget - n, exc, here)
            return
        self._ran(budget - n, pc, here)

    def _run_inline(self, budget: int) -> None:
        """The instructions of :data:`INLINE` inline, ordered by frequency; the rest through
        the handler table. Each inline case computes exactly what its handler computes
        (tests/test_vm.py checks it on random operands)."""
        n = budget
        ops, args, handlers = self._ops, self._args, self._handlers
        memory = self.memory
        consts, globals_, locals_, stack = memory.consts, memory.globals, memory.locals, memory.stack
        push, pop = stack.append, stack.pop
        LOAD_GLOBAL, CONST, LOAD_LOCAL, STORE_GLOBAL, STORE_LOCAL = (
            OP.LOAD_GLOBAL, OP.CONST, OP.LOAD_LOCAL, OP.STORE_GLOBAL, OP.STORE_LOCAL)
        JUMP_IF_FALSE, JUMP, ADD, SUB, GET_ITEM = OP.JUMP_IF_FALSE, OP.JUMP, OP.ADD, OP.SUB, OP.GET_ITEM
        arithmetic, symbols, comparisons, compare = _ARITHMETIC_OPS, _SYMBOLS, _COMPARISON_OPS, _COMPARE
        lo, hi = INT_MIN, INT_MAX
        numbers = _NUMBER_TYPES
        pc = here = self.pc
        try:
            while n:
                n -= 1
                here = pc
                op = ops[pc]
                if op == LOAD_GLOBAL:
                    push(globals_[args[pc]])
                    pc += 1
                elif op == CONST:
                    push(consts[args[pc]])
                    pc += 1
                elif op == LOAD_LOCAL:
                    push(locals_[args[pc]])
                    pc += 1
                elif op == STORE_GLOBAL:
                    globals_[args[pc]] = pop()
                    pc += 1
                elif op == STORE_LOCAL:
                    locals_[args[pc]] = pop()
                    pc += 1
                elif op == JUMP_IF_FALSE:
                    pc = pc + 1 if pop() else args[pc]
                elif op in arithmetic:
                    b = pop()
                    a = stack[-1]
                    pc += 1
                    # two numbers and a common result here; anything else (strings, positions,
                    # poses, orientations, overflow, non-finite reals) through semantics.binary
                    if type(a) in numbers and type(b) in numbers:
                        r = a + b if op == ADD else a - b if op == SUB else a * b
                        if (lo <= r <= hi) if type(r) is int else r - r == 0.0:
                            stack[-1] = r
                            continue
                    stack[-1] = binary(symbols[op], a, b)
                elif op == JUMP:
                    pc = args[pc]
                elif op in comparisons:
                    b = pop()
                    stack[-1] = compare[op](stack[-1], b)
                    pc += 1
                elif op == GET_ITEM:
                    index = pop()
                    array = stack[-1]
                    i = index - args[pc]
                    if not 0 <= i < len(array):
                        i = check_index(index, args[pc], len(array))  # raises
                    stack[-1] = array[i]
                    pc += 1
                else:
                    pc = handlers[op](args[pc], pc)
                    locals_ = memory.locals  # CALL and RET switch frames
                    if self._yield:
                        self._yield = False
                        break
        except Exception as exc:  # never raise out of step()
            self._failed(budget - n, exc, here)
            return
        self._ran(budget - n, pc, here)

    # -- the handlers of the instructions that deal with the world, and of RET ----------------
    # op_<name>(operand, pc) -> the next pc, as the memory's; a handler that ends the step
    # sets _yield (and the status).

    def op_ret(self, _, pc):
        back = self.memory.leave()
        self.recovery.left(len(self.memory.frames))
        if back == _FROM_INTERRUPT:
            return self._handler_done()
        return back

    # A function returns as a procedure does; its RET_VALUE leaves the result on the stack,
    # where the caller's expression goes on from (the verifier checked the depths).
    op_ret_value = op_ret

    # The host reports an I/O number out of range as EvalError (its message stops the
    # program); any other exception is the host's failure (see _describe).
    def op_in_get(self, _, pc):
        stack = self.memory.stack
        stack[-1] = bool(self.host.read_input(stack[-1]))
        return pc + 1

    def op_ain_get(self, _, pc):
        stack = self.memory.stack
        stack[-1] = float(self.host.read_analog(stack[-1]))
        return pc + 1

    def op_aout_set(self, _, pc):
        stack = self.memory.stack
        value = stack.pop()
        self.host.write_analog(stack.pop(), value)
        return pc + 1

    def op_aout_get(self, _, pc):
        stack = self.memory.stack
        stack[-1] = float(self.host.read_analog_output(stack[-1]))
        return pc + 1

    def op_group_in(self, _, pc):
        stack = self.memory.stack
        bits = stack.pop()
        stack[-1] = int(self.host.read_group(stack[-1], bits))
        return pc + 1

    def op_group_out(self, _, pc):
        stack = self.memory.stack
        value = stack.pop()
        bits = stack.pop()
        first = stack.pop()
        self.host.write_group(first, bits, value)
        return pc + 1

    def op_out_get(self, _, pc):
        stack = self.memory.stack
        stack[-1] = bool(self.host.read_output(stack[-1]))
        return pc + 1

    def op_pulse_out(self, _, pc):
        stack = self.memory.stack
        seconds = stack.pop()
        n = stack.pop()
        if not seconds > 0.0:
            raise EvalError(f"a pulse of {format_number(seconds)} s: it must last more than 0 s")
        self.host.pulse_output(n, float(seconds))
        return pc + 1

    def op_out_set(self, _, pc):
        stack = self.memory.stack
        value = stack.pop()
        n = stack.pop()
        self.host.write_output(n, value)
        return pc + 1

    def _move(self, kind: Motion, targets: int, mask: int, pc: int) -> int:
        names = _CLAUSE_NAMES[mask]
        pop_n = self.memory.pop_n
        clauses = dict(zip(names, pop_n(len(names)))) if names else {}
        tag = self.moves_issued
        problem = self.host.move(kind, tuple(pop_n(targets)), clauses, self.program.line_at(pc)[0], tag)
        if problem is not None:
            raise ProgramError(str(problem), _MOVE)
        if self.program.handlers:
            self.recovery.remember(tag, pc)
        self.moves_issued += 1
        self._motion_barrier()
        return pc + 1

    def _motion_barrier(self) -> None:
        """After a move: run on (look-ahead) while the host has room for another move;
        else wait until it has. END and HALT need no wait: the program is finished when
        its motion is (the host's business)."""
        self._await(_W_QUEUE)

    def op_move_ptp(self, mask, pc):
        return self._move(Motion.PTP, 1, mask, pc)

    def op_move_lin(self, mask, pc):
        return self._move(Motion.LIN, 1, mask, pc)

    def op_move_circ(self, mask, pc):
        return self._move(Motion.CIRC, 2, mask, pc)

    def op_trigger_out(self, operands, pc):
        place, unit = operands
        stack = self.memory.stack
        value, n, amount = stack.pop(), stack.pop(), stack.pop()
        problem = self.host.trigger(place, unit, amount, ("out", n, value))
        if problem is not None:
            raise EvalError(problem)
        return pc + 1

    def op_trigger_set(self, operands, pc):
        place, unit, g = operands
        stack = self.memory.stack
        value, amount = stack.pop(), stack.pop()
        problem = self.host.trigger(place, unit, amount, ("set", g, value))
        if problem is not None:
            raise EvalError(problem)
        return pc + 1

    def _use(self, keyword: str, name: int, pc: int) -> int:
        problem = self.host.use_frame(keyword, self.program.constants[name], self.memory.stack.pop())
        if problem is not None:
            raise EvalError(problem)
        return pc + 1

    def op_use_base(self, name, pc):
        return self._use("base", name, pc)

    def op_use_tool(self, name, pc):
        return self._use("tool", name, pc)

    def op_dwell(self, _, pc):
        seconds = self.memory.stack.pop()
        if seconds < 0:
            raise EvalError(f"wait {format_number(seconds)} sec: a wait cannot be negative")
        # (in an interrupt's handler the wait starts at once, beside the motion)
        if not self.waits.dwell(seconds, at_once=self.interrupts.handling is not None):
            self._block()
        return pc + 1

    def op_wait_begin(self, timeout, pc):
        seconds = None
        if timeout:
            seconds = self.memory.stack.pop()
            if seconds < 0:
                raise EvalError(f"wait for ... timeout {format_number(seconds)} sec: "
                                f"a time-out cannot be negative")
        self.waits.begin_wait_for(seconds)
        return pc + 1

    def op_wait_test(self, target, pc):
        waits = self.waits
        if self.memory.stack.pop():
            waits.end_wait_for()
            return pc + 1
        if waits.timed_out():
            said = f"wait for timed out after {format_number(waits.timeout)} s"
            self.host.log(said, self.program.line_at(pc)[0], TIMEOUT)
            if self.program.handlers and self.recovery.handler_for(len(self.memory.frames), pc) is not None:
                raise ProgramError(said, _TIMEOUT)  # (no handler to take it: the program goes on, as it always did)
            return pc + 1
        self._block()  # test again next cycle
        return target

    def op_print(self, n, pc):
        parts, length = [], 0
        for v in self.memory.pop_n(n):
            if length > MAX_STRING_LENGTH:
                break
            part = v if type(v) is str else format_value(v)
            parts.append(part)
            length += len(part)
        text = PRINT_SEPARATOR.join(parts)
        if len(text) > MAX_STRING_LENGTH:  # a line of the operator log is at most this long
            text = text[:MAX_STRING_LENGTH - 3] + "..."
        self.host.log(text, self.program.line_at(pc)[0])
        return pc + 1

    # ---- the robot's own state and the clocks (compiler.robotstate) ----
    def op_robot_joint(self, _, pc):
        self.memory.stack.append(self.host.current_joint())
        return pc + 1

    def op_robot_pose(self, _, pc):
        self.memory.stack.append(self.host.current_pose())
        return pc + 1

    # ---- search moves (compiler.clauses' search; SEARCH_BEGIN and SEARCH_END are barriers) ----
    def op_search_begin(self, _, pc):
        return pc + 1  # (a barrier: it runs once the robot is at rest)

    def op_search_end(self, _, pc):
        problem = self.host.search_end()
        if problem is not None:
            raise ProgramError(problem, _SEARCH)
        return pc + 1

    def op_search_pose(self, _, pc):
        self.memory.stack.append(self.host.search_pose())
        return pc + 1

    def op_tcp_speed(self, _, pc):
        self.memory.stack.append(float(self.host.tcp_speed()))
        return pc + 1

    def op_timed_out(self, _, pc):
        self.memory.stack.append(self.waits.last_timed_out)
        return pc + 1

    def _clock(self, n) -> list:
        if not 1 <= n <= CLOCKS:
            raise EvalError(f"clock {n} does not exist: a program has clocks 1..{CLOCKS}")
        return self.clocks[n - 1]

    def op_clock_start(self, _, pc):
        clock = self._clock(self.memory.stack.pop())
        if clock[0] is None:
            clock[0] = self.host.now()
        return pc + 1

    def op_clock_stop(self, _, pc):
        clock = self._clock(self.memory.stack.pop())
        if clock[0] is not None:
            clock[1] += self.host.now() - clock[0]
            clock[0] = None
        return pc + 1

    def op_clock_reset(self, _, pc):
        clock = self._clock(self.memory.stack.pop())
        clock[1] = 0.0
        if clock[0] is not None:
            clock[0] = self.host.now()
        return pc + 1

    def op_clock_read(self, _, pc):
        stack = self.memory.stack
        clock = self._clock(stack[-1])
        stack[-1] = clock[1] + (self.host.now() - clock[0] if clock[0] is not None else 0.0)
        return pc + 1

    # ---- persistent variables (compiler.persistent) ----
    def op_pers_load(self, g, pc):
        name, type_ = self.program.globals[g]
        value = self.host.kept(name, type_)
        globals_ = self.memory.globals
        if value is not None:
            value = fitted(value, globals_[g])
            if value is not None:
                globals_[g] = value
            else:
                self.host.log(f"the value kept of persistent variable {name} does not fit its declaration now "
                              f"({type_}): it starts from its initial value", self.program.line_at(pc)[0])
        return pc + 1

    def op_pers_store(self, g, pc):
        name, type_ = self.program.globals[g]
        self.host.keep(name, type_, self.memory.globals[g])
        return pc + 1

    def op_pause(self, _, pc):
        self.paused = True
        self.host.log("paused by the program: resume to continue", self.program.line_at(pc)[0], PAUSE)
        self._block()
        return pc + 1

    def _end(self, pc: int) -> int:
        self.status = DONE
        self._yield = True
        return pc

    def op_halt(self, _, pc):
        if self.interrupts.handling is not None:  # 'halt' in a handler: as 'then halt'
            self._here = pc
            return self._halt_by_interrupt()
        return self._armed_end(pc)

    def op_end(self, _, pc):
        return self._armed_end(pc)

    def _armed_end(self, pc: int) -> int:
        """The program's end: with interrupts enabled, not before the motion has ended (so
        they can still fire during the last moves); with error handlers neither (a move the
        motion refuses late is still the program's error, to handle)."""
        if (self.interrupts.armed or self.program.handlers) and not self.host.motion_done():
            self.waits.kind = _W_MOTION
            self._block()
            return pc
        return self._end(pc)


#: The classes whose ``op_<name>`` methods are the instructions' handlers: each handler
#: lives with the state it works on.
HANDLER_CLASSES = (Memory, Interrupts, Recovery, VM)


def build_dispatch(classes: tuple = HANDLER_CLASSES) -> tuple:
    """The handler of every instruction, indexed by opcode, from the instruction table:
    (its class, its ``op_<name>`` function). Raises ImportError naming each instruction that
    has no handler in ``classes``, or more than one."""
    if [d.code for d in INSTRUCTIONS] != list(range(len(INSTRUCTIONS))):
        raise ImportError("runtime.loop.vm: the instruction table's opcodes are not 0..n-1 in order")
    handlers, missing, twice = [], [], []
    for d in INSTRUCTIONS:
        found = [(cls, getattr(cls, "op_" + d.name.lower())) for cls in classes
                 if callable(getattr(cls, "op_" + d.name.lower(), None))]
        if not found:
            missing.append(d.name)
        elif len(found) > 1:
            twice.append(f"{d.name} ({', '.join(cls.__name__ for cls, _ in found)})")
        handlers.extend(found[:1])
    if missing:
        raise ImportError(f"runtime.loop.vm: no VM handler for instruction(s) {', '.join(missing)}")
    if twice:
        raise ImportError(f"runtime.loop.vm: more than one handler for instruction(s) {', '.join(twice)}")
    return tuple(handlers)


#: The handler of each opcode: (its class, the unbound ``op_*`` function); checked at import.
HANDLERS = build_dispatch()
