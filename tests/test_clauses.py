"""The clause table (compiler.clauses) and the runtime's check of a move's clauses.

* The table: bit order, motions, ranges per motion, defaults; the compiler's and the
  object code's clause lists are its names; the specification's [defaults] follow it.
* validate_move_clauses never raises: any clause table (NaN, infinities, huge integers,
  strings, unknown names, anything) gives either values within the declared ranges or a
  problem naming the clause, its value and the allowed range.
* The compiler and the runtime agree: a constant the checker accepts passes the runtime's
  check with the same value; one it refuses is refused at run time with the same message
  (a value computed at run time, and object code crafted past the checker, through
  ``irl run``).
"""
from __future__ import annotations

import dataclasses
import io
import json
import math
import shutil
from pathlib import Path

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from compiler import clauses as table
from compiler import objcode, syntax
from compiler.clauses import BY_NAME, CLAUSES, MOTIONS, NAMES, MoveClauses, validate_move_clauses
from compiler.driver import compile_source
from compiler.objcode import OP, ObjectCodeError, clause_names, encode, verify
from compiler.params import describe
from compiler.spec import SpecError, load_spec, parse_spec
from compiler.values import Joint
from runtime.cli.main import Environment, main
from runtime.motion.planner import scaled_limits
from runtime.loop.vm import VM, VMStatus

from conftest import SPEC_PATH, SPEC, examples

#: The rules as docs/language.md states them, written out independently of the table:
#: (clause, motion) -> (low, low excluded, high or None).
RULES = {
    ("speed_ptp", "ptp"): (0.01, False, 1.0),
    ("acc_ptp", "ptp"): (0.01, False, 1.0),
    ("speed", "lin"): (0.1, False, SPEC.max_speed),
    ("speed", "circ"): (0.1, False, SPEC.max_speed),
    ("acc", "lin"): (1.0, False, SPEC.max_acceleration),
    ("acc", "circ"): (1.0, False, SPEC.max_acceleration),
    ("approx", "ptp"): (0.0, False, 1.0),
    ("approx", "lin"): (0.0, False, None),
    ("approx", "circ"): (0.0, False, None),
}
TARGETS = {
    "ptp": "joint(mainjoint(0, -30, 30, 0, 60, 0))",
    "lin": "pose(pos(800, 0, 400), rpy(180, 0, 180))",
    "circ": "pose(pos(800, 100, 400), rpy(180, 0, 180)), pose(pos(800, 0, 500), rpy(180, 0, 180))",
}


def allowed(name: str, kind: str, value) -> bool:
    """Does ``RULES`` accept ``value`` for clause ``name`` of a ``kind`` move?"""
    if name == "act_rob":
        return value == SPEC.name
    if name == "search":  # an input's number (not given: no search)
        return type(value) is int and 1 <= value <= SPEC.inputs
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        x = float(value)
    except OverflowError:
        return False
    low, low_open, high = RULES[(name, kind)]
    return math.isfinite(x) and (x > low if low_open else x >= low) and (high is None or x <= high)


# ---- the table ------------------------------------------------------------------------------

def test_the_table_is_the_object_codes_clause_list_in_bit_order():
    assert NAMES == ("speed_ptp", "acc_ptp", "speed", "acc", "approx", "act_rob", "search")  # the format: append only
    assert objcode.CLAUSES == NAMES and syntax.CLAUSES == NAMES and objcode.MOTION_KINDS == MOTIONS
    for clause in CLAUSES:
        assert clause_names(1 << clause.bit) == [clause.name]
    assert clause_names((1 << len(NAMES)) - 1) == list(NAMES)


def test_every_motion_has_its_instruction_target_types_and_handler():
    """The motions are declared once (compiler.clauses.Motion); each has its MOVE_ instruction
    (the code generator's), the types its targets may have (the checker's) and the VM's
    handler, and is its keyword as a string wherever it is shown."""
    from compiler import check, codegen
    from compiler.clauses import Motion
    from compiler.objcode import OP
    from runtime.loop.vm import VM

    assert [m.value for m in Motion] == ["ptp", "lin", "circ"] and MOTIONS == tuple(Motion)  # the format
    assert set(codegen.MOVE_OPS) == set(Motion) == set(check.MOVE_TARGETS)
    for motion in Motion:
        assert codegen.MOVE_OPS[motion] == getattr(OP, f"MOVE_{motion.name}")
        assert callable(getattr(VM, f"op_move_{motion}", None)), motion
        assert motion == motion.value and f"{motion}" == str(motion) == motion.value  # messages show the keyword


def test_every_motion_and_clause_has_the_documented_rule():
    applies = {(c.name, kind) for c in CLAUSES for kind in c.motions}
    assert applies == set(RULES) | {("act_rob", kind) for kind in MOTIONS} | {("search", "lin")}
    for (name, kind), (low, low_open, high) in RULES.items():
        rng = BY_NAME[name].range_for(kind)
        assert rng.bounds(SPEC) == (low, high) and rng.low_open == low_open, (name, kind)
    assert BY_NAME["approx"].range_for("lin").unit == "mm" and BY_NAME["approx"].range_for("ptp").unit == ""
    assert BY_NAME["speed"].range_for("lin").unit == "mm/s"


def test_a_move_without_clauses_takes_the_specifications_defaults():
    d = SPEC.defaults
    assert validate_move_clauses("ptp", {}, SPEC) == MoveClauses("ptp", d.speed_ptp, d.acc_ptp, d.approx, SPEC.name)
    for kind in ("lin", "circ"):
        assert validate_move_clauses(kind, {}, SPEC) == MoveClauses(kind, d.speed, d.acc, d.approx, SPEC.name)
    checked = validate_move_clauses("lin", {"speed": 100.0, "approx": 2}, SPEC)
    assert checked.value("speed") == 100.0 and checked.value("approx") == 2.0 and checked.value("acc") == d.acc
    with pytest.raises(KeyError):
        checked.value("speed_ptp")


SPEC_TEXT = SPEC_PATH.read_text(encoding="utf-8")
DEFAULTS_TABLE = SPEC_TEXT[SPEC_TEXT.index("[defaults]"):SPEC_TEXT.index("[io]")]


def spec_with(defaults: str, robot: str = "") -> str:
    text = SPEC_TEXT.replace(DEFAULTS_TABLE, defaults)
    return text.replace("max_speed = 2000.0", robot) if robot else text


def test_the_specifications_defaults_follow_the_table():
    bare = parse_spec(spec_with(""))
    assert dataclasses.astuple(bare.defaults) == (0.5, 0.5, 250.0, 1000.0, 0.0)
    slow = parse_spec(spec_with("", robot="max_speed = 100.0"))
    assert slow.defaults.speed == 100.0  # capped at the robot's maximum
    assert parse_spec(spec_with("[defaults]\napprox = 5.0\n")).defaults.approx == 5.0  # mm after lin and circ
    refused = {
        "speed_ptp = 1.5": "expected 0.01 <= x <= 1, got 1.5",
        "speed = 2500.0": "expected 0.1 <= x <= 2000 mm/s (robot.max_speed), got 2500.0",
        "acc = 0.0": "expected 1 <= x <= 8000 mm/s^2 (robot.max_acceleration), got 0.0",
        "approx = -1.0": "expected 0 <= x <= 1 (after ptp) or x >= 0 mm (after lin, circ), got -1.0",
        "approx = nan": "expected 0 <= x <= 1 (after ptp)",
    }
    for line, message in refused.items():
        with pytest.raises(SpecError) as info:
            parse_spec(spec_with(f"[defaults]\n{line}\n"))
        assert info.value.key == f"defaults.{line.split()[0]}" and message in info.value.message, info.value


def test_a_default_that_the_motion_does_not_take_is_refused_by_checker_and_runtime(tmp_path):
    spec_file = tmp_path / "approx5.spc"
    spec_file.write_text(spec_with("[defaults]\napprox = 5.0\n"), encoding="utf-8")
    spec = load_spec(spec_file)
    problem = validate_move_clauses("ptp", {}, spec)
    assert problem == ("the specification's default approx = 5 is out of range for a ptp move: expected "
                       "0 <= approx <= 1; give approx on the move, or change [defaults] approx in the specification")
    assert validate_move_clauses("ptp", {"approx": 0.5}, spec).approx == 0.5
    assert validate_move_clauses("lin", {}, spec).approx == 5.0
    result = compile_source(program("ptp", "", spec_file), str(tmp_path / "p.irl"))
    assert [f"{d.message}; {d.hint}" for d in result.diagnostics] == [problem]


# ---- validate_move_clauses: never raises, and says what, which value, which range -----------

ODD_VALUES = st.one_of(
    st.floats(),  # NaN, infinities, subnormals, -0.0
    st.floats(min_value=-2.0, max_value=2.0),
    st.floats(min_value=-1e5, max_value=1e5),
    st.integers(min_value=-10, max_value=10_000),
    st.integers(min_value=2 ** 1023, max_value=2 ** 1100),  # beyond the floats
    st.booleans(),
    st.none(),
    st.text(max_size=8),
    st.sampled_from([SPEC.name, "LOLA_15", "", [1.0], {"x": 1}, Joint((0.0,) * 6, ())]),
)
CLAUSE_TABLES = st.dictionaries(st.one_of(st.sampled_from(NAMES), st.text(max_size=6), st.integers()),
                                ODD_VALUES, max_size=6)


def first_problem(kind, clauses) -> tuple[str, object] | None:
    """Which clause (and value) the runtime must complain about first, by RULES."""
    for clause in CLAUSES:
        if clause.name in clauses and kind not in clause.motions:
            return clause.name, clauses[clause.name]
        if kind in clause.motions:
            if clause.name == "search" and "search" not in clauses:
                continue  # (the default: no search)
            if clause.name == "search" and "approx" in clauses:
                return "search", "approx"  # (a search move ends at rest: no approx)
            value = clauses.get(clause.name, clause.default_value(SPEC))
            if not allowed(clause.name, kind, value):
                return clause.name, value
    return None


@settings(max_examples=examples(500), deadline=None, derandomize=True, database=None)
@example(kind="lin", clauses={"search": None})
@example(kind="lin", clauses={"search": 3, "approx": 1.0})
@example(kind="lin", clauses={"search": 3})
@given(kind=st.one_of(st.sampled_from(MOTIONS), st.sampled_from(["PTP", "", "spline"]), st.integers()),
       clauses=CLAUSE_TABLES)
def test_any_clauses_give_values_in_range_or_a_problem_naming_clause_value_and_range(kind, clauses):
    result = validate_move_clauses(kind, clauses, SPEC)
    assert isinstance(result, (MoveClauses, str))
    if kind not in MOTIONS:
        assert isinstance(result, str) and result.startswith(f"unknown motion {describe(kind)}:")
        return
    unknown = [name for name in clauses if name not in NAMES]
    if unknown:
        assert isinstance(result, str) and result.startswith(f"unknown clause {describe(unknown[0])}:")
        return
    expected = first_problem(kind, clauses)
    if expected is None:
        assert isinstance(result, MoveClauses), result
        for clause in CLAUSES:
            if kind in clause.motions and (clause.name in clauses or clause.type != "input"):
                value = result.value(clause.name)
                assert allowed(clause.name, kind, value), (clause.name, value)
                given_value = clauses.get(clause.name, clause.default_value(SPEC))
                assert value == (given_value if clause.type in ("robot", "input") else float(given_value))
        return
    name, value = expected
    assert isinstance(result, str), (kind, clauses, result)
    assert result.startswith((f"{name} ", f"clause '{name}'", f"the specification's default {name} ")), result
    clause = BY_NAME[name]
    if kind not in clause.motions:
        assert f"applies to {clause.motions_text()}, not {kind}" in result
    elif name == "search":
        assert ("cannot be given with 'approx'" in result if value == "approx" else
                f"search = {table._show(value)} " in result and f"a digital input 1..{SPEC.inputs}" in result)
    elif clause.type == "robot":
        assert table._quoted(SPEC.name) in result
        assert (table._quoted(value) if isinstance(value, str) else table._show(value)) in result
    else:
        assert f" = {table._show(value)}" in result
        assert f"expected {clause.range_for(kind).expected(name, SPEC)}" in result


def test_problems_say_what_which_value_and_which_range():
    cases = {
        ("ptp", "speed_ptp", 1.5): "speed_ptp = 1.5 is out of range: expected 0.01 <= speed_ptp <= 1; "
                                   "it is a fraction of each axis's max_velocity",
        ("ptp", "speed_ptp", 1.0000001): "speed_ptp = 1.0000001 is out of range: expected 0.01 <= speed_ptp <= 1; "
                                         "it is a fraction of each axis's max_velocity",  # not "= 1"
        ("ptp", "acc_ptp", float("nan")): "acc_ptp = nan is not a number: expected 0.01 <= acc_ptp <= 1; "
                                          "it is a fraction of each axis's max_acceleration",
        ("lin", "speed", 2500): "speed = 2500 mm/s is out of range: expected 0.1 <= speed <= 2000 (the robot's maximum)",
        ("circ", "acc", "fast"): "acc = 'fast' is not a number: expected 1 <= acc <= 8000 (the robot's maximum)",
        ("lin", "approx", float("inf")): "approx = inf is not a finite number: expected approx >= 0",
        ("lin", "approx", -1): "approx = -1 mm is out of range for a lin move: expected approx >= 0",
        ("ptp", "approx", 10 ** 400): "approx = a very large integer is out of range for a ptp move: expected "
                                      "0 <= approx <= 1; after a ptp move it is a fraction of the slowdown "
                                      "(after lin and circ a distance in mm)",
        ("ptp", "speed", 100.0): "clause 'speed' applies to lin and circ moves, not ptp; use 'speed_ptp' "
                                 "(a fraction of each axis's max_velocity) for a ptp move",
        ("lin", "acc_ptp", 0.5): "clause 'acc_ptp' applies to ptp moves, not lin; use 'acc' (mm/s^2) for a lin move",
        ("ptp", "act_rob", "lola_16"): 'act_rob names robot "lola_16", but the system specification describes '
                                       '"lola_15"; did you mean "lola_15"?',
        ("lin", "act_rob", True): 'act_rob = true is not a robot\'s name: expected "lola_15"',
    }
    for (kind, name, value), message in cases.items():
        assert validate_move_clauses(kind, {name: value}, SPEC) == message
    assert validate_move_clauses("ptp", [("speed_ptp", 0.5)], SPEC).startswith("the move's clauses must be a table")


@settings(max_examples=examples(300), deadline=None, derandomize=True, database=None)
@given(st.one_of(st.floats(), st.floats(min_value=-0.5, max_value=1.5)))
def test_scaled_limits_holds_the_same_rule_as_the_table(fraction):
    """runtime.motion.planner.scaled_limits keeps its own guard (a library function);
    it refuses exactly the fractions that the table refuses."""
    for name, args in (("speed_ptp", (fraction, 0.5)), ("acc_ptp", (0.5, fraction))):
        refused = isinstance(validate_move_clauses("ptp", {name: fraction}, SPEC), str)
        try:
            scaled_limits((100.0,), (100.0,), *args)
        except ValueError:
            assert refused, (name, fraction)
        else:
            assert not refused, (name, fraction)


# ---- the compiler and the runtime agree -----------------------------------------------------

def program(kind: str, clause_text: str, spec: Path = SPEC_PATH, decls: str = "", before: str = "") -> str:
    return (f'program p;\nsystem_specification "{spec}";\n{decls}seq\n{before}'
            f"  move {kind} {TARGETS[kind]} {clause_text};\nendseq\nendprogram;\n")


class RecordingHost:
    """A motion host that records the clauses of each move and completes it at once."""

    def __init__(self):
        self.moves = []

    def now(self):
        return 0.0

    def move(self, kind, targets, clauses, line, tag=0):
        self.moves.append((kind, clauses))
        return None

    def motion_done(self):
        return True

    def read_input(self, n):
        return False

    def write_output(self, n, value):
        pass

    def log(self, text, line, kind="print"):
        pass


def literal(value) -> str:
    return repr(value) if isinstance(value, float) else str(value)


@settings(max_examples=examples(300), deadline=None, derandomize=True, database=None)
@given(kind=st.sampled_from(MOTIONS), name=st.sampled_from([n for n in NAMES if n not in ("act_rob", "search")]),
       value=st.one_of(st.floats(allow_nan=False, allow_infinity=False), st.floats(min_value=-0.5, max_value=1.5),
                       st.floats(min_value=-10.0, max_value=1e4), st.integers(min_value=-10, max_value=10_000)))
def test_a_constant_the_checker_accepts_passes_at_run_time_and_one_it_refuses_is_refused_alike(kind, name, value):
    result = compile_source(program(kind, f"{name} := {literal(value)}"), "p.irl")
    runtime = validate_move_clauses(kind, {name: float(value)}, SPEC)
    if result.ok:
        assert isinstance(runtime, MoveClauses), runtime
        host = RecordingHost()
        machine = VM(result.program, host)
        assert machine.step() == VMStatus.DONE
        [(moved, given_clauses)] = host.moves
        assert moved == kind and validate_move_clauses(kind, given_clauses, SPEC) == runtime
        assert runtime.value(name) == float(value)
    else:
        [diagnostic] = result.diagnostics
        problem = diagnostic.message + (f"; {diagnostic.hint}" if diagnostic.hint else "")
        assert runtime == problem
        assert name in problem and (kind not in BY_NAME[name].motions or table._show(value) in problem)


def test_act_rob_the_checker_accepts_or_refuses_alike():
    for robot in (SPEC.name, "lola_16", "LOLA_15", "kuka"):
        result = compile_source(program("lin", f'act_rob := "{robot}"'), "p.irl")
        runtime = validate_move_clauses("lin", {"act_rob": robot}, SPEC)
        if result.ok:
            assert runtime.robot == robot
        else:
            [d] = result.diagnostics
            assert runtime == d.message + (f"; {d.hint}" if d.hint else "")


def run_json(*argv) -> tuple[int, dict]:
    out, err = io.StringIO(), io.StringIO()
    code = main([str(a) for a in argv] + ["--json"], Environment(stdout=out, stderr=err))
    assert code != 70 and "Traceback" not in err.getvalue() and "internal error" not in out.getvalue(), err.getvalue()
    return code, json.loads(out.getvalue())


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("clauses")
    shutil.copy(SPEC_PATH, d / "lola15.spc")
    return d


def crafted(work: Path, name: str, kind: str, clause_text: str, change) -> Path:
    """Object code for a valid move, changed by ``change(program)`` past the checker."""
    result = compile_source(program(kind, clause_text, Path("lola15.spc")), str(work / f"{name}.irl"))
    assert result.ok, result.diagnostics
    changed = change(result.program)
    assert changed != result.program
    verify(changed)  # the verifier checks the code's shape, not clause values: the runtime must
    path = work / f"{name}.irlo"
    path.write_bytes(encode(changed))
    return path


def with_constant(old, new):
    def change(p):
        return dataclasses.replace(p, constants=tuple(new if type(c) is type(old) and c == old else c
                                                      for c in p.constants))
    return change


def with_mask(old: int, new: int):
    def change(p):
        move_ops = (OP.MOVE_PTP, OP.MOVE_LIN, OP.MOVE_CIRC)
        return dataclasses.replace(p, code=tuple((op, new) if op in move_ops and tuple(rest) == (old,) else (op, *rest)
                                                 for op, *rest in p.code))
    return change


CRAFTED = [  # (name, kind, clauses the checker accepted, change past the checker, the checker's message)
    ("speed_ptp_15", "ptp", "speed_ptp := 0.25", with_constant(0.25, 1.5),
     "speed_ptp = 1.5 is out of range: expected 0.01 <= speed_ptp <= 1; it is a fraction of each axis's max_velocity"),
    ("speed_ptp_on_lin", "lin", "speed := 0.25", with_mask(1 << BY_NAME["speed"].bit, 1 << BY_NAME["speed_ptp"].bit),
     "clause 'speed_ptp' applies to ptp moves, not lin; use 'speed' (mm/s) for a lin move"),
]


def test_a_clause_value_of_another_type_is_refused_by_the_verifier(work):
    """A string where a move's real clause belongs: the verifier types the stack (issue 26),
    so the loader refuses it, naming the instruction and the types, before anything moves."""
    result = compile_source(program("lin", "speed := 0.25", Path("lola15.spc")), str(work / "speed_string.irl"))
    changed = with_constant(0.25, "fast")(result.program)
    with pytest.raises(ObjectCodeError, match="MOVE_LIN: value 2 of 2 must be real, not string"):
        verify(changed)
    path = work / "speed_string.irlo"
    path.write_bytes(encode(changed))
    out, err = io.StringIO(), io.StringIO()
    code = main(["run", str(path), "--spec", str(work / "lola15.spc")], Environment(stdout=out, stderr=err))
    text = out.getvalue() + err.getvalue()
    assert code == 1 and "MOVE_LIN: value 2 of 2 must be real, not string" in text and "Traceback" not in text, text


@pytest.mark.parametrize("name, kind, clause_text, change, message", CRAFTED, ids=[c[0] for c in CRAFTED])
def test_object_code_crafted_past_the_checker_is_refused_at_run_time(work, name, kind, clause_text, change, message):
    obj = crafted(work, name, kind, clause_text, change)
    code, summary = run_json("run", obj, "--spec", work / "lola15.spc")
    assert code == 1 and summary["moves"] == []
    assert summary["fault"].endswith(message) and "line 4" in summary["fault"], summary["fault"]


def test_a_value_computed_at_run_time_is_refused_with_the_checkers_message(work):
    """The checker accepts ``approx := x`` (not a constant); the runtime refuses x = -2
    after a lin move with the message the checker gives for a constant -2."""
    text = program("lin", "approx := x", Path("lola15.spc"), decls="var x : real;\n", before="  x := -2;\n")
    path = work / "computed.irl"
    path.write_text(text, encoding="utf-8")
    constant = compile_source(program("lin", "approx := -2"), "p.irl")
    [diagnostic] = constant.diagnostics
    code, summary = run_json("run", path)
    assert code == 1 and summary["moves"] == []
    assert summary["fault"].endswith(diagnostic.message) and "line 6" in summary["fault"], summary["fault"]
