"""Error handlers (compiler/recovery.py, issue 33 item 1): ``when error do`` with retry,
trynext and raise, on the VM (a fake host, both dispatch loops), against a reference model
of the semantics (random programs of routines that raise, handle and pass errors on), on
forged object code, and end to end in the simulated robot (a refused move handled with the
robot at rest; a time-out retried)."""
from __future__ import annotations

import json
import shutil
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from compiler.objcode import HandlerInfo, ObjectCodeError, decode, encode, verify
from compiler.recovery import BY_NAME
from runtime.loop.vm import VM, VMStatus

from conftest import SPEC_PATH, examples, run_cli
from test_vm import DISPATCHES, FakeHost, compile_text, program_text, run, run_source


@pytest.fixture(params=DISPATCHES)
def dispatch(request):
    return request.param


class Lookahead(FakeHost):
    """A host with room for more moves: the program runs ahead of the robot."""

    def queue_ready(self) -> bool:
        return True


def said(host: FakeHost) -> list[str]:
    """What the program printed (not the runtime's notices: "... handled at line N")."""
    return [text for text in host.texts if "(handled at line" not in text]


# ---- the VM -------------------------------------------------------------------------------------

def test_retry_runs_the_statement_again_and_trynext_goes_on_after_it(tmp_path, dispatch):
    body = """  x := 10 div n;
  print "x ", x;
when error do
  print error_name(), " ", error_number(), ": ", error_message();
  tries := tries + 1;
  if tries < 3 then
    n := n + 1 - 1;
    retry;
  endif;
  n := 5;
  retry;"""
    machine, host = run_source(tmp_path, body, "var n, x, tries : integer;", dispatch=dispatch)
    assert machine.status is VMStatus.DONE, machine.error
    assert said(host) == ["arithmetic 3: division by zero (div)"] * 3 + ["x 2"]
    assert any("arithmetic error at line 5: division by zero (div) (handled at line 8)" in t for t in host.texts)


def test_an_error_passes_through_routines_without_a_handler_to_the_callers(tmp_path, dispatch):
    """raise in a routine three calls down, none of which handles it: the main program's
    handler takes it; the statement that raised it, in main, is the call (trynext: after it)."""
    decls = """var log : string;
procedure c(); seq raise 101, "no part"; print "not here"; endseq endprocedure;
procedure b(); seq call c(); print "not here"; endseq endprocedure;
procedure a(); seq call b(); print "not here"; endseq endprocedure;"""
    body = """  call a();
  print "after a";
when error do
  print "main took ", error_number(), " ", error_name(), ": ", error_message();
  trynext;"""
    machine, host = run_source(tmp_path, body, decls, dispatch=dispatch)
    assert machine.status is VMStatus.DONE, machine.error
    assert said(host) == ["main took 101 user: no part", "after a"]
    assert machine.frames == [] and machine.stack == []


def test_raise_passes_the_error_on_and_an_unhandled_one_ends_the_program_at_its_line(tmp_path, dispatch):
    decls = """procedure inner();
seq
  x := 1 / z;
when error do
  print "inner saw ", error_name();
  raise;
endseq
endprocedure;
var x, z : real;"""
    text = program_text("  call inner();\n  print \"not here\";", decls)
    machine, host = run(compile_text(tmp_path, text), dispatch=dispatch)
    assert machine.status is VMStatus.ERROR
    assert machine.error.message == "division by zero (passed on at line 8)"
    assert machine.error.line == 5  # where it was raised first
    assert said(host) == ["inner saw arithmetic"]


def test_an_error_in_a_handler_goes_to_the_caller(tmp_path, dispatch):
    decls = """var x, z : integer;
procedure p();
seq
  x := 1 div z;
when error do
  x := x div z;
endseq
endprocedure;"""
    body = """  call p();
  print "p done";
when error do
  print "main: ", error_message(), " at line ", 7;"""
    machine, host = run_source(tmp_path, body, decls, dispatch=dispatch)
    assert machine.status is VMStatus.DONE, machine.error
    assert said(host) == ["main: division by zero (div) at line 7"]


def test_a_functions_handler_returns_a_value_and_the_stack_of_the_expression_is_dropped(tmp_path, dispatch):
    """f fails inside an expression of its caller (values on the stack: 1 + ...); g's
    handler takes it: g's stack, f's frame and the half-done expression are dropped."""
    decls = """function f(k : integer) : integer;
seq
  return 10 div k;
endseq
endfunction;
function g(k : integer) : integer;
seq
  return 1 + 2 * f(k);
when error do
  return -1;
endseq
endfunction;"""
    body = '  print g(5), " ", g(0), " ", g(2);'
    machine, host = run_source(tmp_path, body, decls, dispatch=dispatch)
    assert machine.status is VMStatus.DONE, machine.error
    assert said(host) == ["5 -1 11"]
    assert machine.stack == [] and machine.frames == []


def test_trynext_inside_a_loop_goes_on_with_the_loops_next_statement(tmp_path, dispatch):
    body = """  for i := 1 to 4 do
    x := 12 div (i - 2);
    print i, ":", x;
  endfor;
when error do
  print "skip ", i;
  trynext;"""
    machine, host = run_source(tmp_path, body, "var i, x : integer;", dispatch=dispatch)
    assert machine.status is VMStatus.DONE, machine.error
    assert said(host) == ["1:-12", "skip 2", "2:-12", "3:12", "4:6"]


def test_a_var_parameter_of_a_routine_left_by_an_error_gives_nothing_back(tmp_path, dispatch):
    decls = """var n : integer;
procedure bump(var k : integer);
seq
  k := k + 1;
  raise 200;
endseq
endprocedure;"""
    body = """  n := 1;
  call bump(n);
when error do
  print "n ", n, " error ", error_number(), " ", error_message();"""
    machine, host = run_source(tmp_path, body, decls, dispatch=dispatch)
    assert machine.status is VMStatus.DONE, machine.error
    assert said(host) == ["n 1 error 200 error 200 raised by the program"]


def test_a_timed_out_wait_raises_only_where_a_handler_takes_it(tmp_path, dispatch):
    decls = """var tries : integer;
procedure wait_grip();
seq
  wait for in[2] timeout 0.1 sec;
  print "gripped: ", not timed_out();
when error do
  tries := tries + 1;
  print "try ", tries, " ", error_name();
  if tries < 2 then retry; endif;
  trynext;
endseq
endprocedure;"""
    body = """  wait for in[1] timeout 0.1 sec;
  print "went on: ", timed_out();
  call wait_grip();"""
    machine, host = run_source(tmp_path, body, decls, dispatch=dispatch)
    assert machine.status is VMStatus.DONE, machine.error
    assert said(host) == ["wait for timed out after 0.1 s", "went on: true", "wait for timed out after 0.1 s",
                          "try 1 timeout", "wait for timed out after 0.1 s", "try 2 timeout", "gripped: false"]


def test_an_interrupts_handler_passes_no_error_on_to_the_program(tmp_path, dispatch):
    decls = """var go : bool;
var z : integer;
interrupt watch when in[1] continue;
seq
  go := 1 div z = 0;
endseq
endinterrupt;"""
    body = """  enable watch;
  wait for go timeout 1 sec;
  print "not here";
when error do
  print "main took it";"""
    host = FakeHost(inputs={1: True})
    machine, host = run_source(tmp_path, body, decls, host=host, dispatch=dispatch)
    assert machine.status is VMStatus.ERROR and machine.error.message == "division by zero (div)"
    assert said(host)[-1:] != ["main took it"]


def test_the_handler_runs_once_the_moves_before_the_error_have_ended(tmp_path, dispatch):
    """A move the host refuses at once: the moves before it run to their end first."""
    class Refusing(Lookahead):
        def move(self, kind, targets, clauses, line, tag=0):
            if len(self.moves) == 2:
                return "the target is out of reach"
            return super().move(kind, targets, clauses, line, tag)

    body = """  move ptp joint(mainjoint(10, 0, 0, 0, 30, 0));
  move ptp joint(mainjoint(20, 0, 0, 0, 30, 0));
  move ptp joint(mainjoint(90, 0, 0, 0, 30, 0));
  print "not here";
when error do
  print "handler: ", error_name(), ": ", error_message();"""
    program = compile_text(tmp_path, program_text(body))
    host = Refusing(instant=False)
    machine = VM(program, host, dispatch=dispatch)
    for _ in range(20):
        machine.step()
    assert said(host) == [] and machine.status is VMStatus.WAITING  # the robot is still moving
    host.finish()
    for _ in range(5):
        machine.step()
    assert machine.status is VMStatus.DONE
    assert said(host) == ["handler: move: the target is out of reach"]


def test_a_move_refused_after_the_program_ran_on_is_raised_at_that_move(tmp_path, dispatch):
    """The host reports the failure later (the planning worker), with the move's tag: the
    procedure that issued it has returned meanwhile, so the error counts at the call that
    led to it, in main, whose handler retries it with the target changed."""
    decls = """var x : real;
procedure go();
seq
  move lin pose(pos(x, 0, 800), rpy(180, 0, 180));
endseq
endprocedure;"""
    body = """  x := 3000;
  call go();
  x := x + 1;
  print "x ", x;
when error do
  print "took ", error_name(), " at ", x;
  x := 900;
  retry;"""
    text = program_text(body, decls)
    program = compile_text(tmp_path, text)
    host = Lookahead(instant=False)
    machine = VM(program, host, dispatch=dispatch)
    machine.step()  # hands the move over, returns from go, runs on to the print (a barrier)
    assert len(host.moves) == 1 and machine.status is VMStatus.WAITING and machine.globals[0] == 3001
    host.done = host.instant = True  # the motion dropped the move (nothing left to do); the next ones end at once
    machine.fail("the path leaves the arm's reach", 11, 0)
    for _ in range(5):
        machine.step()
    assert machine.status is VMStatus.DONE, machine.error
    assert said(host) == ["took move at 3001", "x 901"]
    assert host.moves[1][1][0].position.x == 900


def test_a_late_failure_without_a_handler_ends_the_program_as_before(tmp_path):
    program = compile_text(tmp_path, program_text("  move ptp joint(mainjoint(10, 0, 0, 0, 30, 0));"))
    host = FakeHost(instant=False)
    machine = VM(program, host)
    machine.step()
    machine.fail("cannot be planned", 5, 0)
    assert machine.status is VMStatus.ERROR and machine.error.message == "cannot be planned"


# ---- the semantics against a reference model ------------------------------------------------------

class _Raised(Exception):
    def __init__(self, number):
        super().__init__(number)
        self.number = number


_ACTIONS = ("none", "fall", "trynext", "retry", "raise", "return")


def _model(procs, main, limits):
    """What the program of :func:`_source` prints, and how it ends (None, or the number of
    the error that ends it): the semantics as the manual states it, in Python."""
    out, hits = [], [0] * len(limits)

    def run_body(name, body, action):
        i = 0
        while i < len(body):
            try:
                run_stmt(body[i])
                i += 1
            except _Raised as e:
                if action == "none":
                    raise
                out.append(f"h{name} {e.number}")
                if action == "trynext":
                    i += 1
                elif action == "retry":
                    pass
                elif action == "raise":
                    raise
                else:  # fall, return: the routine ends
                    return

    def run_stmt(stmt):
        if stmt[0] == "print":
            out.append(f"s{stmt[1]}")
        elif stmt[0] == "site":
            _, k, number = stmt
            hits[k] += 1
            if hits[k] <= limits[k]:
                raise _Raised(number)
        else:
            body, action = procs[stmt[1]]
            run_body(stmt[1], body, action)

    try:
        run_body("m", *main)
    except _Raised as e:
        return out, e.number
    return out, None


def _source(procs, main, limits) -> str:
    def stmt_text(stmt):
        if stmt[0] == "print":
            return f'  print "s{stmt[1]}";'
        if stmt[0] == "site":
            return f"  x := site({stmt[1] + 1}, {stmt[2]});"
        return f"  call p{stmt[1]}();"

    def handler(name, action):
        if action == "none":
            return ""
        words = {"fall": "", "trynext": "trynext;", "retry": "retry;", "raise": "raise;",
                 "return": "return;" if name != "m" else "halt;"}
        return f'when error do\n  print "h{name} ", error_number();\n  {words[action]}\n'

    parts = [f"var hits, limits : array[1..{len(limits)}] of integer;\nvar x : integer;",
             """function site(k : integer; n : integer) : integer;
seq
  hits[k] := hits[k] + 1;
  if hits[k] <= limits[k] then raise n, "e"; endif;
  return 0;
endseq
endfunction;"""]
    for i, (body, action) in enumerate(procs):
        parts.append(f"procedure p{i}();\nseq\n" + "\n".join(map(stmt_text, body)) + "\n" + handler(str(i), action)
                     + "endseq\nendprocedure;")
    sets = "\n".join(f"  limits[{k + 1}] := {v};" for k, v in enumerate(limits))
    body, action = main
    main_text = sets + "\n" + "\n".join(map(stmt_text, body)) + "\n" + handler("m", action)
    return program_text(main_text.rstrip("\n"), "\n".join(parts))


@st.composite
def _programs(draw):
    n_procs = draw(st.integers(0, 4))
    n_sites = draw(st.integers(1, 5))
    limits = draw(st.lists(st.integers(0, 3), min_size=n_sites, max_size=n_sites))

    def body(callable_from):
        stmts = []
        for _ in range(draw(st.integers(0, 4))):
            choice = draw(st.sampled_from(("print", "site", "call") if callable_from < n_procs else ("print", "site")))
            if choice == "print":
                stmts.append(("print", draw(st.integers(0, 9))))
            elif choice == "site":
                stmts.append(("site", draw(st.integers(0, n_sites - 1)), draw(st.integers(100, 103))))
            else:
                stmts.append(("call", draw(st.integers(callable_from, n_procs - 1))))
        return stmts

    procs = [(body(i + 1), draw(st.sampled_from(_ACTIONS))) for i in range(n_procs)]
    main = (body(0), draw(st.sampled_from(_ACTIONS)))
    return procs, main, limits


@settings(max_examples=examples(60), deadline=None)
@given(_programs(), st.sampled_from(DISPATCHES))
def test_handlers_do_what_the_manual_says_on_random_programs(tmp_path_factory, case, dispatch):
    """Routines that raise (a function that fails its first N calls at a place), handle
    (trynext, retry, raise, return, or the handler's end) or not, calling each other: the
    VM prints what the model of the manual's rules prints, and ends as it does."""
    procs, main, limits = case
    expected, unhandled = _model(procs, main, limits)
    program = compile_text(tmp_path_factory.mktemp("p"), _source(procs, main, limits))
    machine, host = run(program, dispatch=dispatch)
    got = [t.replace(" ", " ", 1) for t in said(host)]
    assert got == expected
    if unhandled is None:
        assert machine.status is VMStatus.DONE, machine.error
        assert machine.frames == [] and machine.stack == []
    else:
        assert machine.status is VMStatus.ERROR and machine.error.message.split(" (passed on")[0] == "e"


# ---- forged object code --------------------------------------------------------------------------

def _protected(tmp_path):
    body = """  x := 1 div z;
when error do
  print "took it";
  trynext;"""
    return compile_text(tmp_path, program_text(body, "var x, z : integer;"))


def test_the_handler_table_round_trips_and_verifies(tmp_path):
    program = _protected(tmp_path)
    assert len(program.handlers) == 1
    again = decode(encode(program))
    assert again.handlers == program.handlers
    verify(again)


@pytest.mark.parametrize("forge, why", [
    (lambda h, n: replace(h, end=n + 5), "not inside the code"),
    (lambda h, n: replace(h, entry=h.start), "outside what it protects"),
    (lambda h, n: replace(h, statements=h.statements + ((h.start, h.end + 1),)), "not inside what it protects"),
    (lambda h, n: replace(h, statements=((h.start + 1, h.start + 2),)), "stack holds"),
])
def test_a_forged_handler_table_is_refused(tmp_path, forge, why):
    program = _protected(tmp_path)
    forged = replace(program, handlers=(forge(program.handlers[0], len(program.code)),))
    with pytest.raises(ObjectCodeError, match=why):
        verify(decode(encode(forged)))


def test_a_handler_over_two_routines_is_refused(tmp_path):
    decls = "procedure p(); seq print 1; endseq endprocedure;"
    body = """  call p();
when error do
  trynext;"""
    program = compile_text(tmp_path, program_text(body, decls))
    proc = program.procedures[0]
    handler = program.handlers[0]
    forged = replace(program, handlers=(HandlerInfo(handler.start, proc.entry + 1, handler.entry, ()),))
    with pytest.raises(ObjectCodeError):
        verify(forged)


# ---- end to end in the simulated robot -----------------------------------------------------------

CELL_PROGRAM = """program recover;
system_specification "lola15.spc";
var
  reach : real;
  tries : integer;
procedure place();
seq
  move ptp joint(mainjoint(10, 0, 0, 0, 30, 0));
  move lin pose(pos(reach, 0, 800), rpy(180, 0, 180)) speed := 400;
  print "reached ", reach;
when error do
  print "at rest ", tcp_speed(), " at ", current_joint();
  tries := tries + 1;
  if tries < 5 then
    reach := reach - 500;
    retry;
  endif;
  raise;
endseq
endprocedure;
seq
  reach := 2500;
  call place();
  wait for in[3] timeout 0.2 sec;
  print "not here";
when error do
  print "main: ", error_name();
endseq
endprogram;
"""


def test_a_refused_move_is_handled_with_the_robot_at_rest_in_the_simulated_robot(tmp_path):
    """irl run: the lin move is refused twice (out of reach), each time after the ptp before
    it has ended (the handler reads speed 0 and the ptp's target), then made; the wait's
    time-out goes to main's handler; the program completes. (On the wall clock the refusal
    comes from the planning worker after the program ran on, with the move's tag:
    test_a_move_refused_after_the_program_ran_on_is_raised_at_that_move, and
    tests/test_motionqueue.py::test_on_a_worker_a_failed_plan_is_reported_by_sample.)"""
    shutil.copy(SPEC_PATH, tmp_path / "lola15.spc")
    source = tmp_path / "recover.irl"
    source.write_text(CELL_PROGRAM, encoding="utf-8")
    code, out, err = run_cli("run", source, "--json")
    assert code == 0, err
    summary = json.loads(out)
    texts = [e["text"] for e in summary["log"]]
    prints = [t for t in texts if not t.startswith(("move error", "timeout error", "wait for timed out"))]
    assert prints == ["at rest 0 at joint(mainjoint(10, 0, 0, 0, 30, 0))"] * 2 + ["reached 1500", "main: timeout"]
    assert sum(t.startswith("move error at line 9") for t in texts) == 2
    assert summary["fault"] is None


def test_irl_check_follows_a_handled_refusal_and_warns_of_an_unbounded_retry(tmp_path):
    shutil.copy(SPEC_PATH, tmp_path / "lola15.spc")
    source = tmp_path / "recover.irl"
    source.write_text(CELL_PROGRAM, encoding="utf-8")
    code, out, err = run_cli("check", source)
    assert code == 0 and err == "", err
    assert "line 9: the move is refused 2 times" in out and "error handler at line 12" in out
    source.write_text(CELL_PROGRAM.replace("  if tries < 5 then\n    reach := reach - 500;\n    retry;\n  endif;",
                                           "  reach := reach - 500;\n  retry;"), encoding="utf-8")
    code, out, err = run_cli("check", source)
    assert code == 0 and "warning: this 'retry' has no bound" in err, err


def test_the_error_table_names_are_unique_and_the_words_are_not_reserved(tmp_path):
    assert len(BY_NAME) == len({k.number for k in BY_NAME.values()})
    body = """  retry := 1; trynext := 2; raise := 3; error := 4;
  print retry + trynext + raise + error;"""
    machine, host = run_source(tmp_path, body, "var retry, trynext, raise, error : integer;")
    assert said(host) == ["10"]


def test_the_production_cell_retries_its_missed_grip_and_loads_every_part():
    """The shipped example in its cell (whose gripper misses its first grip): the handler
    opens, retracts and grips again once, then the parts are loaded, each found on the feeder's
    stack by a search move and gripped at the middle of the height its sensor reads, each cycle
    timed and counted (its first 45 simulated seconds: the later
    cycles are the same); irl check, following the same cell through all ten parts, finds
    nothing."""
    from conftest import PROGRAMS

    program, cell = PROGRAMS / "production_cell.irl", PROGRAMS / "production_cell.cell.toml"
    code, out, err = run_cli("run", program, "--cell-scenario", cell, "--json", "--max-time", "45")
    texts = [e["text"] for e in json.loads(out)["log"]][1:]  # (after: kept for this run only)
    assert texts[:3] == ["wait for timed out after 2 s",
                         "timeout error at line 58: wait for timed out after 2 s (handled at line 80)",
                         "grip 1 missed: open, retract and grip again"]
    loaded = [t for t in texts if " loaded in " in t]  # (the first three parts, in 45 s)
    assert [t.split(" (")[0] for t in loaded] == [f"part {n} of 10" for n in range(1, 4)]
    assert loaded[1].endswith("(2 in all)") and len(texts) == 3 + 3
    # the cell's heights, and the stack's top as each search found it (10 mm lower each part, seen
    # within one 5 ms update of 100 mm/s and the servo's lag)
    assert [t.split("(")[1].split(",")[0] for t in loaded] == ["10.0 mm", "10.5 mm", "9.5 mm"]
    tops = [float(t.split("topped at ")[1].split(" mm")[0]) for t in loaded]
    assert all(stack - 1.0 <= top <= stack for top, stack in zip(tops, (400.0, 390.0, 380.0))), tops
    code, out, err = run_cli("check", program, "--cell-scenario", cell)
    assert code == 0 and err == "", err
