"""'var' parameters (issue 33 item 3; RAPID's INOUT): copied in at the call, copied back
into the caller's variable when the procedure returns (KEEP before its RET, TAKE after
the CALL), at its end and at an early return, through recursion, for locals and
globals of any type, and not when the program ends inside it."""
from __future__ import annotations

import pytest

from runtime.loop.vm import VMStatus

from test_vm import DISPATCHES, run_source


@pytest.fixture(params=DISPATCHES)
def dispatch(request):
    return request.param


DECLS = """
var
  count : integer := 1;
  total : real;
  where : joint;
  names : array[1..2] of string;
procedure bump(var n : integer; inc : integer; var t : real);
seq
  n := n + inc;
  t := t + 0.5;
  if n > 100 then
    return;
  endif;
  n := n * 2;
endseq
endprocedure;
procedure fact(k : integer; var f : integer);
var
  g : integer;
seq
  if k <= 1 then
    f := 1;
  else
    call fact(k - 1, g);
    f := k * g;
  endif;
endseq
endprocedure;
procedure label(var a : array[1..2] of string; var q : joint);
seq
  a[2] := "second";
  q := joint(mainjoint(1, 2, 3, 4, 5, 6));
endseq
endprocedure;
procedure outer(var m : integer);
var
  mine : integer := 40;
seq
  call bump(mine, 2, total);
  m := mine;
endseq
endprocedure;
"""


def test_var_parameters_give_their_values_back(tmp_path, dispatch):
    body = """
      call bump(count, 3, total);
      print count, " ", total;
      count := 99;
      call bump(count, 3, total);
      print count, " ", total;
      call fact(6, count);
      print count;
      call label(names, where);
      print names[2], " ", where;
      call outer(count);
      print count;
    """
    machine, host = run_source(tmp_path, body, DECLS, dispatch=dispatch)
    assert machine.status == VMStatus.DONE, machine.error
    assert host.texts == ["8 0.5", "102 1", "720", "second joint(mainjoint(1, 2, 3, 4, 5, 6))", "84"]


def test_a_program_that_ends_inside_the_procedure_leaves_the_variable_as_it_was(tmp_path):
    decls = DECLS + "procedure stop_here(var n : integer);\nseq\n  n := 7;\n  print n;\n  halt;\nendseq\nendprocedure;\n"
    machine, host = run_source(tmp_path, "call stop_here(count);\nprint \"not here\";", decls)
    assert machine.status == VMStatus.DONE and host.texts == ["7"]
    assert machine.globals[0] == 1  # (count: untouched)
