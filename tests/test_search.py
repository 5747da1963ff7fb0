"""Search moves (issue 33 item 7; docs/language.md, "Search moves"): ``move lin T search :=
N`` stops on its line where digital input N becomes true, ``search_pose()`` says where, and a
search that finds nothing is the program's ``search`` error. The simulated cell's
``[[contact]]`` rule is a touch sensor on the tool (true at and below a height that rises as
parts are put on the stack); irl check follows it, or without it explores both outcomes.

The motion queue's cut (the stop on the path without a resume) is tested alone, and in the
random command sequences, by tests/test_motionqueue.py; a wrong [[contact]] rule by
tests/test_cell.py."""
from __future__ import annotations

import json
import re

import pytest

from conftest import SPEC_PATH, run_cli

DOWN = "rpy(180, 0, 180)"
PROGRAM = f"""program stack;
system_specification "lola15.spc";
var
  top : pose;
  n : integer;
seq
  move ptp pose(pos(600, -500, 450), {DOWN});
  for n := 1 to 3 do
    move lin pose(pos(600, -500, 450), {DOWN}) speed := 400;
    move lin pose(pos(600, -500, 300), {DOWN}) search := 7 speed := 50;
    top := search_pose();
    print "part ", n, ": top at ", num_to_str(top.z, 2), " mm";
    move lin top + pos(0, 0, 30) speed := 100;
    call pulse_out(2, 0.2);                        -- a part put on the stack: it is 20 mm higher
  endfor;
  move lin pose(pos(600, -500, 450), {DOWN}) speed := 400;
  move lin pose(pos(600, -500, 400), {DOWN}) search := 8 speed := 50;   -- nothing there
  print "never";
when error do
  print error_name(), " (", error_number(), "): ", error_message();
endseq
endprogram;
"""
CELL = """[[contact]]       # the touch sensor: true at and below the stack's top
input = 7
z = 320.0
step = 20.0
output = 2
"""


@pytest.fixture
def cell(tmp_path):
    (tmp_path / "lola15.spc").write_text(SPEC_PATH.read_text(encoding="utf-8"), encoding="utf-8")
    (tmp_path / "stack.irl").write_text(PROGRAM, encoding="utf-8")
    (tmp_path / "stack.cell.toml").write_text(CELL, encoding="utf-8")
    return tmp_path


def test_a_search_stops_where_the_sensor_fires_and_a_search_that_finds_nothing_is_the_search_error(cell):
    code, out, err = run_cli("run", cell / "stack.irl", "--cell-scenario", cell / "stack.cell.toml", "--json")
    assert code == 0, err
    result = json.loads(out)
    texts = [e["text"] for e in result["log"]]
    tops = [float(m.group(1)) for t in texts if (m := re.match(r"part \d: top at ([\d.]+) mm", t))]
    # each top where the stack is (320, 340, 360 mm): the sensor fires at the tool's measured
    # height, seen within one 5 ms update of 50 mm/s (0.25 mm) and the servo's lag behind it
    assert len(tops) == 3
    for top, stack in zip(tops, (320.0, 340.0, 360.0)):
        assert stack - 1.0 <= top <= stack, tops
    assert texts[-1] == "search (6): the move reached its target and in[8] did not become true on the way", texts
    assert "never" not in texts
    # the three searches that found the stack stopped short of their targets (their rest
    # dropped), the one that found nothing ran to its end; the program ended without a fault
    searches = [m for m in result["moves"] if m["line"] in (10, 17)]
    assert [m["line"] for m in searches] == [10, 10, 10, 17]
    assert all(m["actual_duration"] < m["planned_duration"] - 0.1 for m in searches[:3]), searches
    assert searches[3]["actual_duration"] >= searches[3]["planned_duration"] - 0.01, searches
    assert result["fault"] is None


def test_irl_check_follows_the_cell_and_without_one_explores_both_outcomes(cell):
    code, out, err = run_cli("check", cell / "stack.irl", "--cell-scenario", cell / "stack.cell.toml")
    assert code == 0 and err == "", err
    code, out, err = run_cli("check", cell / "stack.irl")
    assert code == 0, err
    assert "in[7] does not become true: the search finds nothing at line 10" in out, out


def test_an_input_true_already_is_the_search_error_and_the_robot_does_not_move(cell):
    (cell / "early.irl").write_text(f"""program early;
system_specification "lola15.spc";
seq
  move ptp pose(pos(600, -500, 310), {DOWN});
  move lin pose(pos(600, -500, 300), {DOWN}) search := 7 speed := 50;
endseq
endprogram;
""", encoding="utf-8")
    code, out, err = run_cli("run", cell / "early.irl", "--cell-scenario", cell / "stack.cell.toml", "--json")
    assert code != 0 and code != 70
    result = json.loads(out)
    assert "in[7] was true already when the search began" in json.dumps(result), result
    assert [m["line"] for m in result["moves"]] == [4], result["moves"]  # the search move never started


def test_search_pose_before_any_search_is_the_value_error(cell):
    (cell / "none.irl").write_text("""program none;
system_specification "lola15.spc";
var p : pose;
seq
  p := search_pose();
when error do
  print error_name(), ": ", error_message();
endseq
endprogram;
""", encoding="utf-8")
    code, out, err = run_cli("run", cell / "none.irl", "--json")
    assert code == 0, err
    assert json.loads(out)["log"][-1]["text"] == ("value: no search move has found its input yet: search_pose() is "
                                                  "where the last one did")
