"""The object-code interpreter (runtime/loop/vm.py): programs compiled from source run on a
fake host (a settable clock, moves recorded, inputs, outputs, the log), step by step,
as the Trajectory Generator runs them."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from compiler import semantics
from compiler.driver import compile_source
from compiler.objcode import BY_CODE, INSTRUCTIONS, OP, Program, verify
from compiler.semantics import EvalError
from compiler.values import Joint, Pose, Position, Rpy, format_value
from runtime.loop import vm as vm_module
from runtime.loop.vm import HANDLERS, VM, VMError, VMStatus, build_dispatch

from conftest import PROGRAMS, examples
DISPATCHES = ("inline", "table")


# ---- the fake world -------------------------------------------------------------------

class FakeHost:
    """Records what the VM asks of the world. ``instant`` completes every move at once;
    otherwise a test sets ``done`` (or calls finish())."""

    def __init__(self, inputs=None, instant=True, all_inputs=False, move_error=None):
        self.t = 0.0
        self.moves: list[tuple] = []
        self.frames: list[tuple] = []  # (use base / use tool): (keyword, name, pose)
        self.interrupt_log: list = []  # what interrupts asked of the motion
        self.triggers: list = []  # path triggers handed over: (place, unit, amount, action)
        self.vm = None  # the machine (run() sets it): an instant host's triggers set its globals
        self.inputs: dict[int, bool] = dict(inputs or {})
        self.all_inputs = all_inputs
        self.outputs: dict[int, bool] = {}
        self.output_log: list[tuple[int, bool]] = []
        self.log_lines: list[tuple[int, str]] = []
        self.instant = instant
        self.done = True
        self.move_error = move_error
        self.input_reads = 0

    def now(self) -> float:
        return self.t

    def move(self, kind, targets, clauses, line, tag=0):
        if self.move_error is not None:
            return self.move_error
        self.moves.append((kind, targets, clauses, line))
        if not self.instant:
            self.done = False
        return None

    def motion_line(self):
        return None

    def trigger(self, place, unit, amount, action):
        self.triggers.append((place, unit, amount, action))
        if action[0] == "set" and self.vm is not None and self.instant:  # (its moves end at once: so do these)
            self.vm.globals[action[1]] = action[2]
        return None

    def interrupt_stop(self):
        self.interrupt_log.append("stop")

    def interrupt_release(self):
        self.interrupt_log.append("release")

    def interrupt_halt(self, reason):
        self.interrupt_log.append(("halt", reason))

    def use_frame(self, keyword, name, value):
        self.frames.append((keyword, name, value))
        return None

    def motion_done(self) -> bool:
        return self.instant or self.done

    def finish(self) -> None:
        self.done = True

    def read_input(self, n):
        self.input_reads += 1
        if not 1 <= n <= 16:
            raise EvalError(f"digital input {n} does not exist: lola_15 has inputs 1..16")
        return self.all_inputs or self.inputs.get(n, False)

    def write_output(self, n, value):
        if not 1 <= n <= 16:
            raise EvalError(f"digital output {n} does not exist: lola_15 has outputs 1..16")
        self.outputs[n] = value
        self.output_log.append((n, value))

    def write_analog(self, n, value):
        self.outputs[("analog", n)] = value

    def read_analog_output(self, n):
        return self.outputs.get(("analog", n), 0.0)

    def log(self, text, line, kind="print"):
        self.log_lines.append((line, text))

    def kept(self, name, type_):
        return None  # (no persistent value kept: tests/test_persistent.py keeps them)

    def keep(self, name, type_, value):
        pass

    @property
    def texts(self) -> list[str]:
        return [text for _, text in self.log_lines]


# ---- helpers ------------------------------------------------------------------------------

def compile_text(tmp_path: Path, text: str) -> Program:
    for spec in PROGRAMS.glob("*.spc"):  # lola15.spc, and the cell's (its frames and tools)
        shutil.copy(spec, tmp_path / spec.name)
    if not (tmp_path / "lib").exists():
        shutil.copytree(PROGRAMS / "lib", tmp_path / "lib")  # the modules the examples import
    src = tmp_path / "p.irl"
    src.write_text(text)
    result = compile_source(text, str(src))
    assert result.ok, "\n".join(str(d) for d in result.diagnostics)
    verify(result.program)
    return result.program


def program_text(body: str, decls: str = "") -> str:
    return f'program p;\nsystem_specification "lola15.spc";\n{decls}\nseq\n{body}\nendseq\nendprogram;\n'


def line_of(text: str, marker: str) -> int:
    """The 1-based line of the first line containing ``marker``."""
    for number, line in enumerate(text.splitlines(), 1):
        if marker in line:
            return number
    raise AssertionError(f"{marker!r} not in the program")


def run(program: Program, host: FakeHost | None = None, *, dispatch: str = "inline", budget: int = 200,
        dt: float = 0.005, max_steps: int = 100_000) -> tuple[VM, FakeHost]:
    host = host or FakeHost()
    machine = VM(program, host, budget, dispatch=dispatch)
    host.vm = machine
    for _ in range(max_steps):
        status = machine.step()
        if status >= VMStatus.DONE:
            return machine, host
        host.t += dt
    raise AssertionError(f"the program did not finish in {max_steps} steps (status {machine.status.name})")


def run_source(tmp_path, body, decls="", host=None, **kw) -> tuple[VM, FakeHost]:
    return run(compile_text(tmp_path, program_text(body, decls)), host, **kw)


def printed(tmp_path, body, decls="", **kw) -> list[str]:
    machine, host = run_source(tmp_path, body, decls, **kw)
    assert machine.status == VMStatus.DONE, machine.error
    return host.texts


def raw_program(code, constants=(), globals_=1, procedures=(), global_type="integer") -> Program:
    """A hand-made program (no compiler), for exact instruction tests. (The verifier checks
    the global slots' types; the VM, running a program unverified, does not.)"""
    return Program("raw", "raw.irl", "lola_15", "0" * 64, ("lola_15",), tuple(constants), tuple(code),
                   ((0, 1, 1),), tuple((f"g{i}", global_type) for i in range(globals_)), tuple(procedures))


@pytest.fixture(params=DISPATCHES)
def dispatch(request):
    return request.param


# ---- the dispatch table ----------------------------------------------------------------------

def test_every_instruction_has_a_handler():
    assert len(HANDLERS) == len(INSTRUCTIONS)
    for definition in INSTRUCTIONS:
        owner, handler = HANDLERS[definition.code]
        assert owner in vm_module.HANDLER_CLASSES
        assert handler is getattr(owner, "op_" + definition.name.lower()), definition.name
        assert callable(handler)


def test_a_missing_handler_is_detected():
    attrs = {k: v for k, v in vars(vm_module.Memory).items() if k != "op_make_quat"}
    partial = type("PartialMemory", (), attrs)
    with pytest.raises(ImportError, match="MAKE_QUAT"):
        build_dispatch((partial, vm_module.Interrupts, VM))


def test_a_handler_written_twice_is_detected():
    twice = type("Twice", (), {"op_make_quat": vm_module.Memory.op_make_quat})
    with pytest.raises(ImportError, match=r"MAKE_QUAT \(Memory, Twice\)"):
        build_dispatch(vm_module.HANDLER_CLASSES + (twice,))


class _LookAheadHost(FakeHost):
    """A host with look-ahead room: a move does not end the step, the robot moves on."""

    def __init__(self):
        super().__init__(instant=False)

    def queue_ready(self) -> bool:
        return True


@pytest.mark.parametrize("definition", [d for d in INSTRUCTIONS if d.barrier], ids=lambda d: d.name)
def test_a_barrier_of_the_table_waits_for_the_motion_with_its_stack_untouched(definition, dispatch):
    """The VM reads the instruction table's barrier column: while a move runs, each barrier
    instruction waits before it (its own offset, nothing popped), whatever its operands."""
    machine = VM(raw_program([(OP.END,)]), _LookAheadHost(), dispatch=dispatch)
    machine.host.done = False  # a move handed over is running
    machine.stack.append("untouched")
    assert machine._handlers[definition.code](None, 7) == 7
    assert machine.stack == ["untouched"] and machine.status == VMStatus.WAITING


@pytest.mark.parametrize("barrier", [False, True])
def test_the_look_ahead_stops_where_the_table_says(monkeypatch, barrier, dispatch):
    """NOP made a barrier in the table: the program that ran on past it (look-ahead) now
    waits before it until the move has ended."""
    import dataclasses

    table = tuple(dataclasses.replace(d, barrier=barrier) if d.name == "NOP" else d for d in INSTRUCTIONS)
    monkeypatch.setattr(vm_module, "INSTRUCTIONS", table)
    program = raw_program([(OP.CONST, 0), (OP.MOVE_PTP, 0), (OP.NOP,), (OP.END,)],
                          (Joint((0.0, 0.0, 0.0, 0.0, 0.0, 0.0)),))
    machine = VM(program, _LookAheadHost(), dispatch=dispatch)
    status = machine.step()
    assert len(machine.host.moves) == 1
    if barrier:
        assert status == VMStatus.WAITING and machine.offset == 2  # before the NOP, the robot moving
        machine.host.finish()
        status = machine.step()
    assert status == VMStatus.DONE


# ---- the inline fast path against the handler table --------------------------------------------

def _inline_set() -> set[str]:
    """The instructions the inline loop executes itself, found by running it: one instruction
    each, every handler replaced by one that records its call (whatever the operands and the
    stack: an inline instruction that fails on them has not called its handler either)."""
    inline = set()
    for definition in INSTRUCTIONS:
        code = [(definition.code,) + (0,) * len(definition.operands), (OP.END,)]
        machine = VM(raw_program(code), FakeHost(), budget=1, dispatch="inline")
        called = []
        machine._handlers = [lambda operand, pc, op=op: called.append(op) or pc + 1 for op in range(len(INSTRUCTIONS))]
        machine.stack.extend([[0], 0, 0])
        machine.memory.locals = [0]
        machine.step()
        if not called:
            inline.add(definition.name)
    return inline


def test_the_inline_loop_executes_exactly_the_declared_instructions():
    """vm.INLINE names instructions of the table, and is what the inline loop executes
    itself: an instruction added to the loop, or to INLINE, alone fails here."""
    assert set(vm_module.INLINE) <= {d.name for d in INSTRUCTIONS}
    assert len(set(vm_module.INLINE)) == len(vm_module.INLINE)
    assert _inline_set() == set(vm_module.INLINE)
    assert set(_INLINE_CASES) == set(vm_module.INLINE)  # each has its property test below


_FINITE = st.floats(allow_nan=False, allow_infinity=False)
_NUMBER = st.one_of(st.integers(-(2 ** 63), 2 ** 63 - 1), st.integers(-100, 100), _FINITE)
_VALUE = st.one_of(_NUMBER, st.text(max_size=3), st.booleans(),
                   st.builds(Position, _FINITE, _FINITE, _FINITE),
                   st.builds(Rpy, st.floats(-180, 180), st.floats(-90, 90), st.floats(-180, 180)))
_SLOTS = st.lists(_VALUE, min_size=1, max_size=4)
#: An operand of + - *: mostly numbers, the extremes too (overflow, non-finite results).
_ARITHMETIC_OPERAND = st.one_of(_NUMBER, st.sampled_from([2 ** 63 - 1, -(2 ** 63), 1.7e308, -1.7e308]), _VALUE)


def _ordered_pair(draw):
    """Two values LT, LE, GT and GE take (the verifier's rule: two numbers or two strings)."""
    strings = draw(st.booleans())
    values = st.text(max_size=3) if strings else _NUMBER
    return [draw(values), draw(values)]


def _slot_case(draw, where: str, load: bool):
    slots = draw(_SLOTS)
    i = draw(st.integers(0, len(slots) - 1))
    stack = [] if load else [draw(_VALUE)]
    return {"operands": (i,), "stack": stack, where: slots}


#: For each instruction of vm.INLINE: its operands and a state (stack, globals, locals,
#: constants) of the values the verifier lets reach it.
_INLINE_CASES = {
    "LOAD_GLOBAL": lambda draw: _slot_case(draw, "globals", True),
    "STORE_GLOBAL": lambda draw: _slot_case(draw, "globals", False),
    "LOAD_LOCAL": lambda draw: _slot_case(draw, "locals", True),
    "STORE_LOCAL": lambda draw: _slot_case(draw, "locals", False),
    "CONST": lambda draw: _slot_case(draw, "consts", True),
    "JUMP": lambda draw: {"operands": (draw(st.integers(0, 1)),), "stack": []},
    "JUMP_IF_FALSE": lambda draw: {"operands": (draw(st.integers(0, 1)),), "stack": [draw(st.booleans())]},
    "GET_ITEM": lambda draw: {"operands": (draw(st.integers(-3, 3)),),
                              "stack": [draw(st.lists(_VALUE, max_size=5)),
                                        draw(st.one_of(st.integers(-8, 8), st.integers(-(2 ** 63), 2 ** 63 - 1)))]},
    **{name: (lambda draw: {"operands": (), "stack": [draw(_ARITHMETIC_OPERAND), draw(_ARITHMETIC_OPERAND)]})
       for name in ("ADD", "SUB", "MUL")},
    **{name: (lambda draw: {"operands": (), "stack": _ordered_pair(draw)}) for name in ("LT", "LE", "GT", "GE")},
    **{name: (lambda draw: {"operands": (), "stack": [draw(_VALUE), draw(_VALUE)]}) for name in ("EQ", "NE")},
}


def _after_one(name: str, case: dict, dispatch: str) -> str:
    """What one instruction leaves (status, error, next offset, stack, variables), as text
    that tells 1 from 1.0 and True."""
    program = raw_program([(getattr(OP, name),) + case["operands"], (OP.END,)], case.get("consts", ()),
                          globals_=len(case.get("globals", ())))
    machine = VM(program, FakeHost(), budget=1, dispatch=dispatch)
    machine.globals[:] = case.get("globals", [])
    machine.memory.locals = list(case.get("locals", []))
    machine.stack.extend(case["stack"])
    machine.step()
    return repr((machine.status, machine.error and machine.error.message, machine.pc, machine.stack,
                 machine.globals, machine.memory.locals))


@settings(max_examples=examples(400), deadline=None)
@given(name=st.sampled_from(vm_module.INLINE), data=st.data())
def test_each_inline_instruction_gives_what_its_handler_gives(name, data):
    """Each instruction the inline loop executes itself leaves exactly what its handler in
    the table leaves, errors included, on random operands of the types it takes."""
    case = data.draw(st.composite(lambda draw: _INLINE_CASES[name](draw))())
    assert _after_one(name, case, "inline") == _after_one(name, case, "table")


def test_both_dispatch_loops_agree_on_every_example_program(tmp_path):
    for path in sorted(PROGRAMS.glob("*.irl")):
        program = compile_text(tmp_path, path.read_text())
        results = []
        for d in DISPATCHES:
            machine, host = run(program, FakeHost(all_inputs=True), dispatch=d)
            results.append((machine.status, host.moves, host.log_lines, host.output_log, machine.instructions))
        assert results[0] == results[1], path.name


# ---- the example programs -----------------------------------------------------------------------

@pytest.mark.parametrize("name", sorted(p.stem for p in PROGRAMS.glob("*.irl")))
def test_example_program_runs_to_done(tmp_path, name, dispatch):
    program = compile_text(tmp_path, (PROGRAMS / f"{name}.irl").read_text())
    machine, host = run(program, FakeHost(all_inputs=True), dispatch=dispatch)
    assert machine.status == VMStatus.DONE, machine.error
    assert machine.error is None
    assert machine.moves_issued == len(host.moves) > 0
    assert machine.stack == [] and machine.frames == []


def test_example_program_moves_and_log(tmp_path):
    program = compile_text(tmp_path, (PROGRAMS / "cycle_control.irl").read_text())
    machine, host = run(program, FakeHost(all_inputs=True))
    assert host.texts == ["cycle 1: reject", "shift done: 0 small, 0 large, 1 rejected, 0 idle polls"]
    kinds = [m[0] for m in host.moves]
    assert kinds == ["ptp", "ptp", "lin", "lin", "ptp", "ptp", "ptp"]
    assert host.moves[1][2] == {"approx": 0.2}
    assert host.moves[4][2] == {"speed_ptp": 0.9, "acc_ptp": 0.7}
    assert host.moves[4][1] == (Pose(Position(1000.0, 400.0, 500.0), Rpy(180.0, 0.0, 180.0)),)
    assert host.output_log == [(1, True), (1, False)]


def test_test_irl_moves(tmp_path):
    program = compile_text(tmp_path, (PROGRAMS / "test.irl").read_text())
    machine, host = run(program)
    assert [(m[0], m[1], m[2], m[3]) for m in host.moves][0] == (
        "ptp", (Joint((45.0, 0.0, -45.0, 0.0, 0.0, 0.0)),),
        {"speed_ptp": 0.1, "acc_ptp": 0.1, "act_rob": "lola_15"}, 4)


# ---- expressions: the VM computes what the compiler folds ------------------------------------------

NUMERIC_CASES = [
    ("{a} + {b}", 7, 3), ("{a} + {b}", 7, 2.5), ("{a} - {b}", -7, 3), ("{a} * {b}", 6, -4),
    ("{a} * {b}", 1.5, 2.25), ("{a} / {b}", 7, 2), ("{a} / {b}", 1, 3), ("{a} / {b}", -7.5, 2),
    ("{a} div {b}", 7, 2), ("{a} div {b}", -7, 2), ("{a} div {b}", 7, -2), ("{a} div {b}", -7, -2),
    ("{a} mod {b}", 7, 2), ("{a} mod {b}", -7, 2), ("{a} mod {b}", 7, -2), ("{a} mod {b}", -7, -2),
    ("{a} mod {b}", 0, 5), ("({a} div {b}) * {b} + {a} mod {b}", -13, 4),
    ("{a} = {b}", 1, 1.0), ("{a} <> {b}", 2, 3), ("{a} < {b}", -1, 0.5), ("{a} <= {b}", 2, 2),
    ("{a} > {b}", 3.5, 3), ("{a} >= {b}", 1, 2),
    ("-{a} * {b}", 3, 4), ("-({a} - {b})", 3.25, 4),
    ("sin({a}) + cos({b})", 30, 60.5), ("tan({a}) * {b}", 45, 2), ("asin({a}) + acos({b})", 0.5, -1),
    ("atan2({a}, {b})", -1, -1), ("atan2({a}, {b})", 0, 0), ("sqrt({a}) + {b}", 2, 0),
    ("abs({a}) + abs({b})", -3, -2.5), ("min({a}, {b})", 3, -4), ("max({a}, {b})", 3, 4.5),
    ("round({a}) + round({b})", 2.5, -2.5), ("round({a}) + trunc({b})", 0.49999999999999994, -2.7),
    ("trunc({a}) * {b}", 1e10 + 0.5, 3),
    ("{a} * {a} * {a} - {b} / 7", 12345, 0.1),
    ("({a} + {b}) * ({a} - {b}) / ({a} * {b} + 1)", 1.1, 2.2),
]


def _literal(value) -> str:
    text = repr(value)
    return f"({text})"


def test_run_time_arithmetic_equals_folding(tmp_path, dispatch):
    """Each expression once with literals (folded by the compiler) and once with
    variables (computed by the VM): the two printed values must be identical, and equal
    to what compiler.semantics computes."""
    decls = "var ia, ib : integer;\n    ra, rb : real;\n    bv : bool;\n"
    body = []
    for template, a, b in NUMERIC_CASES:
        va = ("ia" if isinstance(a, int) else "ra")
        vb = ("ib" if isinstance(b, int) else "rb")
        body.append(f"  {va} := {_literal(a)}; {vb} := {_literal(b)};")
        body.append(f"  print {template.format(a=_literal(a), b=_literal(b))};")
        body.append(f"  print {template.format(a=va, b=vb)};")
    text = program_text("\n".join(body), decls)
    program = compile_text(tmp_path, text)
    # the variable forms really are computed at run time
    ops = {BY_CODE[i[0]].name for i in program.code}
    assert {"IDIV", "MOD", "DIV", "CALL_BUILTIN", "NEG", "LT", "GE"} <= ops
    machine, host = run(program, dispatch=dispatch)
    assert machine.status == VMStatus.DONE, machine.error
    out = host.texts
    assert len(out) == 2 * len(NUMERIC_CASES)
    for k, (template, a, b) in enumerate(NUMERIC_CASES):
        assert out[2 * k] == out[2 * k + 1], (template, a, b)


def test_string_bool_and_structured_values_agree_with_folding(tmp_path):
    decls = ('var s1, s2 : string;\n    b1, b2 : bool;\n    x, y : real;\n    q : orientation;\n'
             '    j : joint;\n    pp : pose;\n    k : integer;\n')
    pairs = [
        ('"ab" + "cd"', 's1 + s2', 's1 := "ab"; s2 := "cd";'),
        ('"B" < "a"', 's1 < s2', 's1 := "B"; s2 := "a";'),
        ('true and not false or false', 'b1 and not b2 or b2', 'b1 := true; b2 := false;'),
        ('quat(1, 1, 0, 0)', 'quat(x, y, 0, 0)', 'x := 1; y := 1;'),
        ('pose(pos(1, 2, 3), rpy(0, 90, 0)).z', 'pose(pos(x, y, 3), rpy(0, 90, 0)).z', 'x := 1; y := 2;'),
        ('joint(mainjoint(1, 2, 3, 4, 5, 6))[4]', 'joint(mainjoint(x, 2, 3, y, 5, 6))[k]', 'x := 1; y := 4; k := 4;'),
        ('pos(1, 2, 3) = pos(1, 2, 3.0)', 'pos(x, 2, 3) = pos(1, y, 3)', 'x := 1; y := 2;'),
        ('rpy(0, 0, 0) = quat(1, 0, 0, 0)', 'rpy(x, 0, 0) = quat(1, y, 0, 0)', 'x := 0; y := 0;'),
    ]
    body = []
    for folded, computed, setup in pairs:
        body += [f"  {setup}", f"  print {folded};", f"  print {computed};"]
    out = printed(tmp_path, "\n".join(body), decls)
    for k, (folded, computed, _) in enumerate(pairs):
        assert out[2 * k] == out[2 * k + 1], folded
    assert out[0] == "abcd" and out[2] == "true" and out[14] == "false"


@settings(max_examples=examples(300), deadline=None)
@given(op=st.sampled_from(["+", "-", "*", "/", "div", "mod", "=", "<>", "<", "<=", ">", ">="]),
       a=st.one_of(st.integers(-(2 ** 63), 2 ** 63 - 1), st.integers(-100, 100),
                   st.floats(allow_nan=False, allow_infinity=False)),
       b=st.one_of(st.integers(-(2 ** 63), 2 ** 63 - 1), st.integers(-100, 100),
                   st.floats(allow_nan=False, allow_infinity=False)))
def test_binary_instructions_agree_with_semantics(op, a, b):
    """Both dispatch loops (the inline fast paths too) compute exactly semantics.binary,
    including its errors (integer overflow, non-finite reals, division by zero)."""
    if op in ("div", "mod") and not (isinstance(a, int) and isinstance(b, int)):
        return
    opcode = {"+": OP.ADD, "-": OP.SUB, "*": OP.MUL, "/": OP.DIV, "div": OP.IDIV, "mod": OP.MOD,
              "=": OP.EQ, "<>": OP.NE, "<": OP.LT, "<=": OP.LE, ">": OP.GT, ">=": OP.GE}[op]
    program = raw_program([(OP.CONST, 0), (OP.CONST, 1), (opcode,), (OP.STORE_GLOBAL, 0), (OP.END,)], (a, b))
    try:
        expected, error = semantics.binary(op, a, b), None
    except EvalError as exc:
        expected, error = None, str(exc)
    for d in DISPATCHES:
        machine, _ = run(program, dispatch=d)
        if error is None:
            assert machine.status == VMStatus.DONE, machine.error
            got = machine.globals[0]
            assert type(got) is type(expected) and (got == expected or (got != got and expected != expected))
        else:
            assert machine.status == VMStatus.ERROR
            assert machine.error.message == error


def test_div_and_mod(tmp_path):
    decls = "var a, b : integer;\n"
    body = "\n".join(f"  a := {a}; b := {b}; print a div b, \" \", a mod b;"
                     for a, b in [(7, 2), (-7, 2), (7, -2), (-7, -2), (6, 3), (0, -3)])
    assert printed(tmp_path, body, decls) == ["3 1", "-3 -1", "-3 1", "3 -1", "2 0", "0 0"]


def test_integer_overflow_and_real_overflow_are_errors(tmp_path):
    decls = "var a, b : integer;\n    x : real;\n"
    cases = [
        ("a := 9223372036854775807; b := a + 1;", "integer overflow in '+'"),
        ("a := -9223372036854775807 - 1; b := -1; b := a div b;", "integer overflow in 'div'"),
        ("a := -9223372036854775807 - 1; b := -a;", "integer overflow in '-'"),
        ("a := 3037000500; b := a * a;", "integer overflow in '*'"),
        ("x := 1e308; x := x * 10;", "the result of '*' is not a finite number"),
        ("x := -1; x := sqrt(x);", "sqrt(-1) is undefined"),
        ("x := 2; x := asin(x);", "asin(2) is undefined"),
    ]
    for k, (body, message) in enumerate(cases):
        sub = tmp_path / str(k)
        sub.mkdir()
        text = program_text(f"  print 1;\n  {body}  -- here\n  print 2;", decls)
        machine, host = run(compile_text(sub, text))
        assert machine.status == VMStatus.ERROR, body
        assert message in machine.error.message, (body, machine.error.message)
        assert machine.error.line == line_of(text, "-- here")
        assert host.texts == ["1"]


# ---- variables, arrays, joints, poses --------------------------------------------------------------

def test_nested_arrays_and_copy_semantics(tmp_path, dispatch):
    decls = """var a, b : array[1..3] of array[0..1] of integer;
    m : array[-2..2] of integer;
    i, k : integer;
procedure change(x : array[1..3] of array[0..1] of integer);
seq
  x[1][0] := -1;
  print "in: ", x[1][0];
endseq
endprocedure;
"""
    body = """
  for i := 1 to 3 do
    a[i][0] := i * 10;
    a[i][1] := i * 10 + 1;
  endfor;
  b := a;                   -- a copy
  b[1][0] := 99;
  print a[1][0], " ", b[1][0];
  call change(a);           -- by value
  print a[1][0];
  b[2] := a[3];             -- an element array is copied too
  b[2][1] := 77;
  print a[3][1], " ", b[2][1];
  print b;
  a[2][1] := 5;             -- the default rows are independent copies
  print a;
  m[-2] := 4; m[2] := 6; k := -2;
  print m[k] + m[k + 4], " ", m;
"""
    out = printed(tmp_path, body, decls, dispatch=dispatch)
    assert out == ["10 99", "in: -1", "10", "31 77", "[[99, 11], [30, 77], [30, 31]]",
                   "[[10, 11], [20, 5], [30, 31]]", "10 [4, 0, 0, 0, 6]"]


def test_default_array_rows_are_independent(tmp_path):
    decls = "var g : array[1..2] of array[1..2] of integer;\n    js : array[1..2] of joint;\n"
    body = """
  g[1][1] := 5;
  js[2][3] := 30;
  print g, " ", js[1][3], " ", js[2][3];
"""
    assert printed(tmp_path, body, decls) == ["[[5, 0], [0, 0]] 0 30"]


def test_joint_axes(tmp_path, dispatch):
    decls = "var j, k : joint;\n    n : integer;\n"
    body = """
  j := joint(mainjoint(1, 2, 3, 4, 5, 6));
  k := j;
  j[2] := 30;
  n := 6;
  j[n] := j[n] + 0.5;
  print j[2], " ", j[6], " ", k[2], " ", j;
"""
    out = printed(tmp_path, body, decls, dispatch=dispatch)
    assert out == ["30 6.5 2 joint(mainjoint(1, 30, 3, 4, 5, 6.5))"]


def test_poses_and_fields(tmp_path):
    decls = "var p : pose;\n    q : position;\n    x : real;\n    o : orientation;\n"
    body = """
  x := 2.5;
  q := pos(x, -x, 10);
  o := quat(0, 0, 0, x);
  p := pose(q, rpy(180, 0, x));
  print p.x + p.y + p.z, " ", q.y, " ", o, " ", p;
"""
    out = printed(tmp_path, body, decls)
    assert out == ["10 -2.5 quat(0, 0, 0, 1) pose(pos(2.5, -2.5, 10), rpy(180, 0, 2.5))"]


# ---- procedures and control flow ---------------------------------------------------------------------

def test_procedures_params_locals_and_recursion(tmp_path, dispatch):
    decls = """var r : integer;
    total : real;
procedure fact(n : integer);
  var m : integer;
seq
  m := n;
  if n <= 1 then
    r := 1;
  else
    call fact(n - 1);
    r := r * m;
  endif;
endseq
endprocedure;
procedure add(x : real; times : integer);
  var i : integer;
seq
  for i := 1 to times do
    total := total + x;
  endfor;
endseq
endprocedure;
procedure fib(n : integer);
  var a : integer;
seq
  if n < 2 then
    r := n;
  else
    call fib(n - 1);
    a := r;
    call fib(n - 2);
    r := r + a;
  endif;
endseq
endprocedure;
"""
    body = """
  call fact(20);
  print r;
  call add(2, 3);           -- an integer argument for a real parameter
  call add(0.25, 2);
  print total;
  call fib(15);
  print r;
"""
    assert printed(tmp_path, body, decls, dispatch=dispatch) == ["2432902008176640000", "6.5", "610"]


def test_control_flow(tmp_path, dispatch):
    decls = "var i, s, n : integer;\n"
    body = """
  s := 0;
  for i := 1 to 10 step 3 do s := s + i; endfor;
  print s, " ", i;
  for i := 10 to 1 step -4 do print "down ", i; endfor;
  n := 0;
  for i := 5 to n do print "never"; endfor;
  print "after empty loop ", i;
  while s > 0 do s := s - 7; endwhile;
  print s;
  repeat s := s + 5; until s >= 12;
  print s;
  repeat n := n + 1; until true;
  print n;
  for i := 1 to 4 do
    if i = 1 then print "one";
    elsif i = 2 then print "two";
    elsif i mod 2 = 1 then print "odd";
    else print "other";
    endif;
  endfor;
"""
    assert printed(tmp_path, body, decls, dispatch=dispatch) == [
        "22 13", "down 10", "down 6", "down 2", "after empty loop 5", "-6", "14", "1",
        "one", "two", "odd", "other"]


def test_halt_inside_a_procedure(tmp_path):
    decls = "procedure stop_here();\nseq\n  print \"stopping\";\n  halt;\n  print \"never\";\nendseq\nendprocedure;\n"
    machine, host = run_source(tmp_path, "  call stop_here();\n  print \"never either\";", decls)
    assert machine.status == VMStatus.DONE and machine.error is None
    assert host.texts == ["stopping"]
    assert machine.step() == VMStatus.DONE  # stays done


# ---- print -------------------------------------------------------------------------------------------------

def test_print_formats(tmp_path):
    decls = 'var a : array[1..2] of string;\n    r : real;\n'
    body = """
  a[1] := "x"; r := 45.0;
  print "text", 3, " ", r, " ", 0.1, " ", true, " ", -2.5e-7;
  print a;
  print joint(mainjoint(45, 0, -45, 0, 0, 0)), pos(1, 2, 3);
"""
    out = printed(tmp_path, body, decls)
    assert out == ["text3 45 0.1 true -2.5e-07", '["x", ""]',
                   "joint(mainjoint(45, 0, -45, 0, 0, 0))pos(1, 2, 3)"]
    assert out[1] == format_value(["x", ""])


def test_print_logs_the_statement_line(tmp_path):
    text = program_text('  print "a";\n  print "b";  -- b')
    machine, host = run(compile_text(tmp_path, text))
    assert host.log_lines[1] == (line_of(text, "-- b"), "b")


# ---- moves, waits and the clock ----------------------------------------------------------------------

def test_move_waits_for_the_motion(tmp_path, dispatch):
    decls = "var v : real;\n    p : pose;\n"
    text = program_text("""
  v := 0.25;
  move ptp joint(mainjoint(0, -30, 30, 0, 60, 0)) speed_ptp := v acc_ptp := 0.5;  -- m1
  out[1] := true;
  p := pose(pos(800, 0, 400), rpy(180, 0, 180));
  move circ pose(pos(800, 100, 400), rpy(180, 0, 180)), p speed := 2 * 50 approx := 1 act_rob := "lola_15";  -- m2
  out[2] := true;
""", decls)
    host = FakeHost(instant=False)
    machine = VM(compile_text(tmp_path, text), host, dispatch=dispatch)
    assert machine.status == VMStatus.READY
    assert machine.step() == VMStatus.WAITING
    assert machine.moves_issued == 1 and machine.line == line_of(text, "-- m1")
    assert host.moves[0] == ("ptp", (Joint((0.0, -30.0, 30.0, 0.0, 60.0, 0.0)),),
                             {"speed_ptp": 0.25, "acc_ptp": 0.5}, line_of(text, "-- m1"))
    for _ in range(5):
        assert machine.step() == VMStatus.WAITING
    assert host.outputs == {}
    host.finish()
    assert machine.step() == VMStatus.WAITING  # went on, then waits for the circ move
    assert host.outputs == {1: True}
    kind, targets, clauses, line = host.moves[1]
    assert kind == "circ" and len(targets) == 2 and line == line_of(text, "-- m2")
    assert targets[1] == Pose(Position(800.0, 0.0, 400.0), Rpy(180.0, 0.0, 180.0))
    assert clauses == {"speed": 100.0, "approx": 1.0, "act_rob": "lola_15"}
    assert list(clauses) == ["speed", "approx", "act_rob"]  # CLAUSES bit order
    host.finish()
    assert machine.step() == VMStatus.DONE
    assert host.outputs == {1: True, 2: True} and machine.moves_issued == 2


def test_move_error_from_the_host(tmp_path, dispatch):
    text = program_text('  x := 5000;\n  print "before";\n  move lin pose(pos(x, 0, 0), rpy(0, 0, 0));  -- far\n'
                        '  print "after";', "var x : real;\n")
    host = FakeHost(move_error="target out of reach: 5000 mm from the base")
    machine, host = run(compile_text(tmp_path, text), host, dispatch=dispatch)
    assert machine.status == VMStatus.ERROR
    assert machine.error == VMError("target out of reach: 5000 mm from the base", line_of(text, "-- far"), 3,
                                    machine.error.offset)
    assert machine.moves_issued == 0 and host.texts == ["before"]


def test_dwell_waits_for_motion_then_time(tmp_path, dispatch):
    text = program_text("""
  move ptp joint(mainjoint(0, 0, 0, 0, 0, 0));
  wait 1.5 sec;
  out[1] := true;
  wait 0 sec;
  out[2] := true;
""")
    host = FakeHost(instant=False)
    machine = VM(compile_text(tmp_path, text), host, dispatch=dispatch)
    assert machine.step() == VMStatus.WAITING
    host.t = 1.0
    assert machine.step() == VMStatus.WAITING  # still moving: the dwell has not started
    host.finish()
    host.t = 2.0
    assert machine.step() == VMStatus.WAITING  # the dwell starts now: until 3.5
    for t in (2.5, 3.0, 3.49):
        host.t = t
        assert machine.step() == VMStatus.WAITING
        assert host.outputs == {}
    host.t = 3.5
    assert machine.step() == VMStatus.DONE  # wait 0 sec does not wait
    assert host.outputs == {1: True, 2: True}


@pytest.mark.parametrize("statement", ["wait x sec;", "wait for in[1] timeout x sec;"])
def test_negative_wait_times_are_errors(tmp_path, statement):
    text = program_text(f"  x := -1;\n  {statement}  -- w", "var x : real;\n")
    machine, _ = run(compile_text(tmp_path, text))
    assert machine.status == VMStatus.ERROR
    assert machine.error.line == line_of(text, "-- w") and "negative" in machine.error.message


def test_a_zero_time_out_tests_the_condition_once(tmp_path):
    text = program_text("  x := 0;\n  wait for in[1] timeout x sec;\n  print \"on\";", "var x : real;\n")
    host = FakeHost()
    machine = VM(compile_text(tmp_path, text), host)
    assert machine.step() == VMStatus.DONE
    assert host.texts == ["wait for timed out after 0 s", "on"] and host.input_reads == 1


def test_wait_for_without_timeout(tmp_path, dispatch):
    text = program_text("  wait for in[3] and not in[4];\n  print \"go\";")
    host = FakeHost()
    machine = VM(compile_text(tmp_path, text), host, dispatch=dispatch)
    for k in range(1, 6):
        host.t += 100.0
        assert machine.step() == VMStatus.WAITING
        assert host.input_reads == 2 * k  # the condition is evaluated once per step
    host.inputs[3] = True
    host.inputs[4] = True
    assert machine.step() == VMStatus.WAITING
    host.inputs[4] = False
    assert machine.step() == VMStatus.DONE
    assert host.texts == ["go"]


def test_wait_for_true_at_once_does_not_wait(tmp_path):
    machine = VM(compile_text(tmp_path, program_text("  wait for true;\n  print \"go\";")), FakeHost())
    assert machine.step() == VMStatus.DONE


def test_wait_for_with_timeout(tmp_path, dispatch):
    decls = "var t : real;\n"
    text = program_text("""
  t := 2;
  wait for in[1] timeout t sec;   -- w1
  print "after 1";
  wait for in[2] timeout 10 sec;  -- w2
  print "after 2";
""", decls)
    host = FakeHost()
    host.t = 5.0
    machine = VM(compile_text(tmp_path, text), host, dispatch=dispatch)
    assert machine.step() == VMStatus.WAITING  # deadline 7.0
    for t in (6.0, 6.99):
        host.t = t
        assert machine.step() == VMStatus.WAITING
    host.t = 7.0
    assert machine.step() == VMStatus.WAITING  # timed out; now waits at w2 (deadline 17)
    assert host.log_lines == [(line_of(text, "-- w1"), "wait for timed out after 2 s"), (line_of(text, "-- w1") + 1,
                                                                                          "after 1")]
    host.t = 8.0
    host.inputs[2] = True  # the condition comes true before the deadline: no notice
    assert machine.step() == VMStatus.DONE
    assert host.texts[-1] == "after 2" and len(host.texts) == 3


def test_pause_statement_and_resume(tmp_path, dispatch):
    text = program_text('  print "a";\n  pause;  -- p\n  print "b";')
    host = FakeHost()
    machine = VM(compile_text(tmp_path, text), host, dispatch=dispatch)
    assert machine.step() == VMStatus.WAITING
    assert machine.paused and machine.line == line_of(text, "-- p")
    assert host.texts[0] == "a" and len(host.texts) == 2  # print, then the pause notice
    for _ in range(3):
        assert machine.step() == VMStatus.WAITING
    machine.resume()
    assert machine.step() == VMStatus.DONE
    assert host.texts[-1] == "b" and not machine.paused


def test_operator_pause_and_resume_in_a_long_loop(tmp_path, dispatch):
    decls = "var i, s : integer;\n"
    program = compile_text(tmp_path, program_text("  for i := 1 to 1000 do s := s + i; endfor;\n  print s;", decls))
    machine = VM(program, FakeHost(), budget=50, dispatch=dispatch)
    assert machine.step() == VMStatus.RUNNING
    machine.pause()
    done = machine.instructions
    for _ in range(3):
        assert machine.step() == VMStatus.WAITING
    assert machine.instructions == done
    machine.resume()
    while machine.step() == VMStatus.RUNNING:
        pass
    assert machine.status == VMStatus.DONE and machine.host.texts == ["500500"]


def test_abort(tmp_path):
    program = compile_text(tmp_path, program_text("  wait for in[1];  -- w"))
    machine = VM(program, FakeHost())
    machine.step()
    machine.abort()
    assert machine.status == VMStatus.ERROR
    assert machine.error.message == "aborted by the operator"
    assert machine.error.line == line_of(program_text("  wait for in[1];  -- w"), "-- w")
    assert machine.step() == VMStatus.ERROR


# ---- digital I/O -------------------------------------------------------------------------------------------

def test_inputs_and_outputs(tmp_path, dispatch):
    decls = "var n : integer;\n    b : bool;\n"
    body = """
  for n := 1 to 4 do
    out[n + 10] := in[n] or n = 4;
  endfor;
  b := in[2];
  out[1] := not b;
"""
    machine, host = run_source(tmp_path, body, decls, host=FakeHost(inputs={2: True}), dispatch=dispatch)
    assert machine.status == VMStatus.DONE
    assert host.output_log == [(11, False), (12, True), (13, False), (14, True), (1, False)]


#: What a host calls for, in a program that asks each of them several times.
HOST_CALLS = ("read_input", "write_output", "move", "log", "motion_done", "now", "trigger", "use_frame")
PYTHON_ERRORS = (IndexError, KeyError, TypeError, ValueError, AttributeError, RuntimeError, ZeroDivisionError,
                 OverflowError, AssertionError, StopIteration, LookupError, ArithmeticError)
PYTHON_MESSAGE = "tuple index out of range"
BUSY_PROGRAM = """program busy;
system_specification "lola15.spc";
var
  i : integer;
  seen : integer;
interrupt watch when in[2] priority 1 continue;
seq
  seen := seen + 1;
endseq
endinterrupt;
seq
  enable watch;
  for i := 1 to 4 do
    use tool tool(pos(0, 0, 100), rpy(0, 0, 0));
    out[1] := true;
    trigger when 5 ms after start do out[2] := true;
    move ptp joint(mainjoint(5, 0, 0, 0, 0, 0)) speed_ptp := 0.5;  -- move
    wait for in[3] timeout 0.01 sec;
    print i, in[4];
  endfor;
endseq
endprogram;
"""


@pytest.fixture(scope="module")
def busy_program(tmp_path_factory) -> Program:
    return compile_text(tmp_path_factory.mktemp("busy"), BUSY_PROGRAM)


class FailingHost(FakeHost):
    """A host whose ``call`` raises ``error(PYTHON_MESSAGE)`` from its ``after + 1``-th time on."""

    def __init__(self, call: str, error: type, after: int):
        super().__init__(all_inputs=False)
        self.calls = 0
        original = getattr(self, call)

        def failing(*args):
            self.calls += 1
            if self.calls > after:
                raise error(PYTHON_MESSAGE)
            return original(*args)
        setattr(self, call, failing)


@settings(max_examples=80, deadline=None)
@given(call=st.sampled_from(HOST_CALLS), error=st.sampled_from(PYTHON_ERRORS), after=st.integers(0, 3),
       dispatch=st.sampled_from(DISPATCHES))
def test_a_failing_host_stops_the_program_and_the_fault_is_never_a_python_message(busy_program, call, error, after,
                                                                                 dispatch):
    """Issue 26, fault 1: whatever the host raises, from whichever call, the program stops
    at a line with a message in the program's terms (the instruction that failed, "internal
    error of the runtime"), never the exception's own text."""
    host = FailingHost(call, error, after)
    machine, _ = run(busy_program, host, dispatch=dispatch)
    assert machine.status == VMStatus.ERROR, (call, error, after)
    message = machine.error.message
    assert PYTHON_MESSAGE not in message and error.__name__ not in message, message
    assert "internal error of the runtime" in message and machine.error.line >= 1, message


def test_an_io_number_refused_by_the_host_stops_the_program_with_its_message(tmp_path):
    class Refusing(FakeHost):
        def read_input(self, n):
            raise EvalError(f"no input {n}")

    text = program_text("  print in[3];  -- i")
    machine, _ = run(compile_text(tmp_path, text), Refusing())
    assert machine.status == VMStatus.ERROR
    assert machine.error.message == "no input 3" and machine.error.line == line_of(text, "-- i")


def test_io_number_out_of_range(tmp_path):
    decls = "var n : integer;\n"
    text = program_text("  n := 17;\n  out[n] := true;  -- o", decls)
    machine, _ = run(compile_text(tmp_path, text))
    assert machine.status == VMStatus.ERROR
    assert machine.error.message == "digital output 17 does not exist: lola_15 has outputs 1..16"
    assert machine.error.line == line_of(text, "-- o")
    sub = tmp_path / "in"
    sub.mkdir()
    text = program_text("  n := 0;\n  print in[n];  -- i", decls)
    machine, _ = run(compile_text(sub, text))
    assert machine.error.message.startswith("digital input 0 does not exist")
    assert machine.error.line == line_of(text, "-- i")


# ---- run-time errors name the line -----------------------------------------------------------------------

ERROR_CASES = {
    "division by zero": ("var a, b : integer;\n    x : real;\n",
                         "  a := 1; b := 0;\n  x := 1.5;\n  x := x + a / b;  -- here\n", "division by zero"),
    "div by zero": ("var a, b : integer;\n", "  a := 1;\n  b := a div (a - 1);  -- here\n",
                    "division by zero (div)"),
    "mod by zero": ("var a, b : integer;\n", "  a := 1;\n  b := a mod (a - 1);  -- here\n",
                    "division by zero (mod)"),
    "index out of range": ("var v : array[1..3] of real;\n    i : integer;\n    x : real;\n",
                           "  i := 4;\n  x := v[i];  -- here\n", "index 4 is outside the array bounds 1..3"),
    "store out of range": ("var v : array[-1..1] of array[1..2] of real;\n    i : integer;\n",
                           "  i := 3;\n  v[0][i] := 1;  -- here\n", "index 3 is outside the array bounds 1..2"),
    "axis out of range": ("var j : joint;\n    i : integer;\n", "  i := 7;\n  j[i] := 1;  -- here\n",
                          "axis 7 does not exist (the joint value has axes 1..6)"),
    "axis read out of range": ("var j : joint;\n    i : integer;\n    x : real;\n",
                               "  i := 0;\n  x := j[i];  -- here\n", "axis 0 does not exist"),
    "zero quaternion": ("var x : real;\n    o : orientation;\n", "  x := 0;\n  o := quat(x, 0, 0, 0);  -- here\n",
                        "quat(0, 0, 0, 0) is not a rotation"),
    "tan": ("var x : real;\n", "  x := 90;\n  x := tan(x);  -- here\n", "tan(90) is undefined"),
}


@pytest.mark.parametrize("name", sorted(ERROR_CASES))
def test_run_time_errors_name_the_line(tmp_path, name, dispatch):
    decls, body, message = ERROR_CASES[name]
    text = program_text('  print "start";\n' + body + '  print "not reached";', decls)
    machine, host = run(compile_text(tmp_path, text), dispatch=dispatch)
    assert machine.status == VMStatus.ERROR
    assert message in machine.error.message
    assert machine.error.line == line_of(text, "-- here") == machine.line
    assert machine.error.column == 3
    assert host.texts == ["start"]
    assert machine.step() == VMStatus.ERROR  # and it stays stopped, without raising


def test_endless_recursion_is_an_error_not_a_crash(tmp_path, dispatch):
    decls = "var depth : integer;\nprocedure down(n : integer);\nseq\n  depth := n;\n  call down(n + 1);  -- rec\nendseq\nendprocedure;\n"
    text = program_text("  call down(1);", decls)
    machine, _ = run(compile_text(tmp_path, text), dispatch=dispatch)
    assert machine.status == VMStatus.ERROR
    assert "too many nested procedure or function calls (more than 200)" in machine.error.message
    assert "down" in machine.error.message
    assert machine.error.line == line_of(text, "-- rec")
    assert machine.globals[0] == 200


def test_deep_but_finite_recursion_is_fine(tmp_path):
    decls = ("var r : integer;\nprocedure sum(n : integer);\nseq\n  if n = 0 then r := 0; else call sum(n - 1); "
             "r := r + n; endif;\nendseq\nendprocedure;\n")
    assert printed(tmp_path, "  call sum(199);\n  print r;", decls) == ["19900"]


def test_the_vm_never_raises():
    # unverified, broken code: a stack underflow
    machine = VM(raw_program([(OP.ADD,), (OP.END,)]), FakeHost())
    assert machine.step() == VMStatus.ERROR
    assert "internal error" in machine.error.message

    class Broken(FakeHost):
        def motion_done(self):
            raise RuntimeError("drive bus lost")

    program = raw_program([(OP.CONST, 0), (OP.MOVE_PTP, 0), (OP.END,)], (Joint((0.0,) * 6),))
    machine = VM(program, Broken())
    assert machine.step() == VMStatus.ERROR
    # said in the program's terms (the instruction), never as the exception's own text
    assert "drive bus lost" not in machine.error.message
    assert "internal error of the runtime while carrying out MOVE_PTP" in machine.error.message
    assert machine.moves_issued == 1


# ---- the budget ----------------------------------------------------------------------------------------------

def test_budget_yields_running_and_resumes(tmp_path, dispatch):
    decls = "var i, s : integer;\n    x : real;\n"
    program = compile_text(tmp_path, program_text(
        "  for i := 1 to 500 do s := s + i * i; x := x + 0.5; endfor;\n  print s, \" \", x;", decls))
    outputs = set()
    for budget in (1, 7, 50, 200, 100_000):
        machine = VM(program, FakeHost(), budget=budget, dispatch=dispatch)
        steps = 0
        while True:
            before = machine.instructions
            status = machine.step()
            steps += 1
            if status == VMStatus.RUNNING:
                assert machine.instructions - before == budget
            else:
                assert machine.instructions - before <= budget
                break
        assert status == VMStatus.DONE
        assert steps == -(-machine.instructions // budget)
        outputs.add((tuple(machine.host.texts), machine.instructions))
    assert outputs == {(("41791750 250",), machine.instructions)}
    assert machine.instructions > 5000


def test_constructor_checks_arguments(tmp_path):
    program = raw_program([(OP.END,)])
    with pytest.raises(ValueError):
        VM(program, FakeHost(), budget=0)
    with pytest.raises(ValueError):
        VM(program, FakeHost(), dispatch="jit")
    machine = VM(program, FakeHost())
    assert (machine.status, machine.error, machine.line, machine.moves_issued, machine.paused) == (
        VMStatus.READY, None, 1, 0, False)
    assert machine.step() == VMStatus.DONE


def test_print_separator_is_documented():
    assert vm_module.PRINT_SEPARATOR == ""
