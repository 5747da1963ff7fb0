"""Group I/O (issue 33 item 4; docs/language.md, "The robot's own state and clocks"):
``group_in(FIRST, BITS)`` reads digital inputs as one unsigned integer, ``call
group_out(FIRST, BITS, VALUE)`` sets outputs to a value's bits in one tick. The rules of a
group (compiler.robotstate.group_problem, group_value_problem) are the checker's and the
runtime's; tests/diagnostics/group_io has the compile-time errors."""
from __future__ import annotations

import json

from hypothesis import given, settings
from hypothesis import strategies as st

from compiler.robotstate import GROUP_BITS, group_problem, group_value_problem

from conftest import SPEC_PATH, run_cli, examples

PROGRAM = """program codes;
system_specification "lola15.spc";
var
  v : integer;
  k : integer;
seq
  for k := 0 to 3 do
    v := 37 * k + 5;
    call group_out(1, 8, v);               -- out[1..8]: the cell copies them to in[1..8]
    wait 0.1 sec;
    print v, " -> ", group_in(1, 8), " (out[1] ", out[1], ", in[1] ", in[1], ")";
  endfor;
  k := 14;
  call group_out(k, 4, 1);                 -- outputs 14..17: one too many
when error do
  print error_name(), ": ", error_message();
  if error_name() = "io" then
    call group_out(1, 2, v);               -- 116 does not fit 2 outputs: the value error, unhandled
  endif;
endseq
endprogram;
"""
CELL = "".join(f"[[follow]]\ninput = {k}\noutput = {k}\n\n" for k in range(1, 9))


def test_a_group_written_is_the_group_read_back_through_the_cell(tmp_path):
    (tmp_path / "lola15.spc").write_text(SPEC_PATH.read_text(encoding="utf-8"), encoding="utf-8")
    (tmp_path / "codes.irl").write_text(PROGRAM, encoding="utf-8")
    (tmp_path / "cell.toml").write_text(CELL, encoding="utf-8")
    code, out, err = run_cli("run", tmp_path / "codes.irl", "--cell-scenario", tmp_path / "cell.toml", "--json")
    summary = json.loads(out)
    texts = [e["text"] for e in summary["log"] if e.get("kind") != "handled"]
    assert texts[:4] == [f"{v} -> {v} (out[1] {str(bool(v & 1)).lower()}, in[1] {str(bool(v & 1)).lower()})"
                         for v in (5, 42, 79, 116)], texts
    assert "io: outputs 14..17 do not exist: the robot has outputs 1..16" in texts, texts
    assert code == 1 and "116 does not fit a group of 2 outputs: expected 0..3" in summary["fault"], summary["fault"]


@settings(max_examples=examples(200), deadline=None, derandomize=True, database=None)
@given(first=st.integers(-3, 40), bits=st.integers(-2, 40), value=st.integers(-5, 1 << 34), count=st.integers(0, 40))
def test_a_group_is_accepted_exactly_when_its_signals_exist_and_its_value_fits(first, bits, value, count):
    problem = group_problem(first, bits, count, "output")
    assert (problem is None) == (1 <= bits <= GROUP_BITS and first >= 1 and first + bits - 1 <= count), problem
    if problem is None:
        assert (group_value_problem(value, bits) is None) == (0 <= value < 2 ** bits)
    assert group_problem(True, 1, 5, "input") is not None and group_value_problem(True, 4) is not None
