"""Functions (issue 17, item 3): a routine with a result type, called in expressions, and
`return` (with a value in a function, without one in a procedure); recursion bounded as
for procedures; a function computes, it does not act. Object code: CALL_FUNC and
RET_VALUE, checked by the verifier against the procedure table."""
from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from compiler.objcode import OP, ObjectCodeError, ProcInfo, decode, encode, verify

from test_vm import DISPATCHES, compile_text, printed, program_text, raw_program, run

FUNCTIONS = """
function fact(n : integer) : integer;
seq
  if n <= 1 then
    return 1;
  endif;
  return n * fact(n - 1);
endseq
endfunction;

function fib(n : integer) : integer;
var a, b, t, i : integer;
seq
  a := 0;
  b := 1;
  for i := 1 to n do
    t := a + b;
    a := b;
    b := t;
  endfor;
  return a;
endseq
endfunction;

function half(x : real) : real;
seq
  return x / 2;
endseq
endfunction;

function above(p : pose; h : real) : pose;
seq
  return p + pos(0, 0, h);
endseq
endfunction;

function sign(x : integer) : integer;
seq
  if x > 0 then
    return 1;
  elsif x < 0 then
    return -1;
  else
    return 0;
  endif;
endseq
endfunction;

procedure early(x : integer);
seq
  if x > 0 then
    return;
  endif;
  print "not positive";
endseq
endprocedure;
"""


def source(body: str, decls: str = "") -> str:
    text = program_text(body, decls + FUNCTIONS)
    return text


@settings(max_examples=40, deadline=None)
@given(n=st.integers(0, 20), x=st.integers(-50, 50), r=st.floats(-1e6, 1e6))
def test_functions_compute_what_python_computes(tmp_path_factory, n, x, r):
    tmp_path = tmp_path_factory.mktemp("f")
    decls = "var k : integer;\n    q : real;\n"
    body = (f"  k := {n};\n  q := {r!r};\n  print fact(k);\n  print fib(k);\n  print half(q);\n  print sign({x});\n"
            f"  print 1 + fact(3) * fib(10) - sign(-k - 1);\n  call early({x});\n")
    out = printed(tmp_path, body, decls + FUNCTIONS)
    assert out[:4] == [str(math.factorial(n)), str(_fib(n)), _real(r / 2), str((x > 0) - (x < 0))]
    assert out[4] == str(1 + 6 * 55 + 1)
    assert out[5:] == ([] if x > 0 else ["not positive"])


def _fib(n: int) -> int:
    a, b = 0, 1
    for _ in range(n):
        a, b = b, a + b
    return a


def _real(v: float) -> str:
    from compiler.values import format_value

    return format_value(float(v))


def test_a_function_in_a_moves_target_and_an_integer_result_converted(tmp_path):
    program = compile_text(tmp_path, source(
        "  move lin above(pose(pos(800, 0, 300), rpy(180, 0, 180)), fact(3)) speed := half(400);\n"
        "  q := fact(4);\n  print q;\n", "var q : real;\n"))
    names = [d[0] for d in program.code]
    assert OP.CALL_FUNC in names and OP.RET_VALUE in names
    assert [p.result for p in program.procedures] == ["integer", "integer", "real", "pose", "integer", ""]
    machine, host = run(program)
    assert machine.status.name == "DONE", machine.error
    (_kind, targets, clauses, _line), = host.moves
    assert targets[0].position.z == 306.0 and clauses["speed"] == 200.0
    assert host.texts == ["24"]  # (a real that is whole prints without a point)
    assert decode(encode(program)) == program


def test_recursion_too_deep_is_an_error_at_the_line(tmp_path):
    text = program_text("  print down(100000);\n", "function down(n : integer) : integer;\nseq\n"
                                                   "  if n = 0 then\n    return 0;\n  endif;\n"
                                                   "  return down(n - 1);\nendseq\nendfunction;\n")
    program = compile_text(tmp_path, text)
    for d in DISPATCHES:
        machine, _ = run(program, dispatch=d)
        assert machine.status.name == "ERROR"
        assert "too many nested procedure or function calls" in machine.error.message
        assert "calling down" in machine.error.message


def _raw_function_program(call_op, ret_op, result: str):
    """main: CONST 0; <call_op> f; STORE g0; END. f(x): LOAD_LOCAL 0; <ret_op>."""
    code = [(OP.CONST, 0), (call_op, 0), (OP.STORE_GLOBAL, 0), (OP.END,), (OP.LOAD_LOCAL, 0), (ret_op,)]
    if call_op == OP.CALL:
        code[2] = (OP.NOP,)
    if ret_op == OP.RET:
        code[4] = (OP.NOP,)
    return raw_program(code, (7,), procedures=(ProcInfo("f", 4, 1, (("x", "integer"),), result),))


def test_the_verifier_checks_function_calls_and_returns():
    good = _raw_function_program(OP.CALL_FUNC, OP.RET_VALUE, "integer")
    verify(good)
    for d in DISPATCHES:
        machine, _ = run(good, dispatch=d)
        assert machine.status.name == "DONE" and machine.globals[0] == 7
    for call_op, ret_op, result, words in [
        (OP.CALL, OP.RET_VALUE, "integer", "CALL of function 'f'"),
        (OP.CALL_FUNC, OP.RET, "", "CALL_FUNC of procedure 'f'"),
        (OP.CALL_FUNC, OP.RET, "integer", "RET in a function"),
    ]:
        with pytest.raises(ObjectCodeError, match=words):
            verify(_raw_function_program(call_op, ret_op, result))
    wrong = raw_program([(OP.CONST, 0), (OP.RET_VALUE,)], (1,))
    with pytest.raises(ObjectCodeError, match="RET_VALUE outside a procedure or function"):
        verify(wrong)
    proc = raw_program([(OP.CALL, 0), (OP.END,), (OP.CONST, 0), (OP.RET_VALUE,)], (1,),
                       procedures=(ProcInfo("p", 2, 0, ()),))
    with pytest.raises(ObjectCodeError, match="RET_VALUE in a procedure"):
        verify(proc)


def test_a_function_table_entry_is_decoded_strictly(tmp_path):
    program = compile_text(tmp_path, source("  print fact(3);\n"))
    data = encode(program)
    assert decode(data).procedures[0].result == "integer"
    plain = compile_text(tmp_path, program_text("  call p();\n", "procedure p;\nseq\n  print 1;\nendseq\n"
                                                                   "endprocedure;\n"))
    assert decode(encode(plain)).procedures[0].result == ""  # (4 fields: the format procedures had)


def test_a_function_called_by_an_initialiser_sees_zero_values_not_nothing(tmp_path):
    """Globals hold their zero values before any initialiser runs: a function an earlier
    initialiser calls may read a later global."""
    text = program_text('  print a, " ", b, " ", d;\n',
                        "function getb : integer;\nseq\n  return b;\nendseq\nendfunction;\n"
                        "function getc : real;\nseq\n  return c[2];\nendseq\nendfunction;\n"
                        "var a : integer := getb();\n  b : integer := 5;\n  c : array[1..2] of real;\n"
                        "  d : real := getc();\n")
    for d in DISPATCHES:
        machine, host = run(compile_text(tmp_path, text), dispatch=d)
        assert machine.status.name == "DONE", machine.error
        assert host.texts == ["0 5 0"]
