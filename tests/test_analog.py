"""Analog inputs (issue 33 item 4, the inputs): declared in the specification
([[analog_input]]: name, unit, range), read by a program with analog_in(N), set in the
simulated cell by a scenario's [[analog]] rule, read at the middle of their range without one (irl run and irl check alike)."""
from __future__ import annotations

import json

import pytest

from compiler.spec import SpecError, load_spec
from runtime.hardware.sim.cell import ScenarioError, load_scenario

from conftest import SPEC_PATH, run_cli
from test_vm import FakeHost, compile_text, program_text, run

SENSORS = """
[[analog_input]]
name = "part height"
unit = "mm"
min = 0
max = 200

[[analog_input]]
name = "air pressure"
unit = "bar"
min = -1
max = 10
"""

PROGRAM = """program heights;
system_specification "sensed.spc";
var h : real;
    n : integer;
seq
  for n := 1 to 3 do
    h := analog_in(1);
    print "part ", n, ": ", num_to_str(h, 1), " mm, air ", analog_in(2), " bar";
    wait 1 sec;
  endfor;
endseq
endprogram;
"""

CELL = """[[analog]]
input = 1
value = 42.5
at = [1.5]
values = [57.25]

[[analog]]
input = 2
value = 6
"""


@pytest.fixture
def cell(tmp_path):
    (tmp_path / "sensed.spc").write_text(SPEC_PATH.read_text(encoding="utf-8") + SENSORS, encoding="utf-8")
    (tmp_path / "heights.irl").write_text(PROGRAM, encoding="utf-8")
    (tmp_path / "heights.cell.toml").write_text(CELL, encoding="utf-8")
    return tmp_path


def test_the_specification_declares_them_in_order(cell):
    spec = load_spec(cell / "sensed.spc")
    assert [(c.name, c.unit, c.low, c.high) for c in spec.analog_inputs] == [("part height", "mm", 0.0, 200.0),
                                                                           ("air pressure", "bar", -1.0, 10.0)]
    assert load_spec(SPEC_PATH).analog_inputs == () and spec.hash != load_spec(SPEC_PATH).hash
    assert spec.analog_inputs[0].problem(1, 250.0) == \
        "analog input 1 (part height) reads 250 mm: its range is 0..200 mm"


@pytest.mark.parametrize("table, why", [
    ('min = 5\nmax = 5', "more than min"), ('max = 5', r"analog_input\[1\]\.min: missing"),
    ('min = 0\nmax = 5\nscale = 2', "scale"), ('min = 0\nmax = "5"', r"analog_input\[1\]\.max"),
])
def test_a_wrong_declaration_names_its_key(tmp_path, table, why):
    path = tmp_path / "bad.spc"
    path.write_text(SPEC_PATH.read_text(encoding="utf-8") + f"\n[[analog_input]]\n{table}\n", encoding="utf-8")
    with pytest.raises(SpecError, match=why):
        load_spec(path)


def test_a_program_reads_the_cells_values_as_they_change(cell):
    from runtime.cli.plot import analog_lines, read_report

    code, out, err = run_cli("run", cell / "heights.irl", "--cell-scenario", cell / "heights.cell.toml", "--json",
                             "--report", cell / "r.csv")
    assert code == 0, err
    # (the height changes 1.5 s after the program starts: between the second and the third part)
    assert [e["text"] for e in json.loads(out)["log"]] == ["part 1: 42.5 mm, air 6 bar", "part 2: 42.5 mm, air 6 bar",
                                                          "part 3: 57.3 mm, air 6 bar"]
    # the report's analog columns (a cell adds them): the inputs as the cell set them, row by row
    times, states, cols = read_report(cell / "r.csv")
    assert analog_lines(cols) == ["ain_1", "ain_2"]
    moving = [k for k, s in enumerate(states) if s.startswith("Move Robot")]
    assert cols["ain_1"][moving[0]] == 42.5 and cols["ain_1"][moving[-1]] == 57.25 and cols["ain_2"][moving[-1]] == 6
    code, out, err = run_cli("check", cell / "heights.irl", "--cell-scenario", cell / "heights.cell.toml")
    assert code == 0 and err == "", err
    code, out, err = run_cli("check", cell / "heights.irl")  # (no scenario: each reads the middle of its range)
    assert code == 0 and "each analog input reads the middle of its range (lines 7, 8)" in out, out
    code, out, err = run_cli("run", cell / "heights.irl", "--json")
    assert [e["text"] for e in json.loads(out)["log"]][0] == "part 1: 100.0 mm, air 4.5 bar"


def test_the_checker_knows_which_exist(cell):
    (cell / "wrong.irl").write_text(PROGRAM.replace("analog_in(2)", "analog_in(3)"), encoding="utf-8")
    code, _, err = run_cli("check", cell / "wrong.irl")
    assert code == 1 and "analog input 3 does not exist: lola_15 has analog inputs 1..2" in err, err


def test_a_reading_is_the_io_error_a_handler_can_take(tmp_path):
    class Sensing(FakeHost):
        def read_analog(self, n):
            from compiler.semantics import EvalError

            raise EvalError("analog input 1 (part height) reads 250 mm: its range is 0..200 mm")

    body = """  h := analog_in(k);
  print "not here";
when error do
  print error_name(), ": ", error_message();"""
    program = compile_text(tmp_path, program_text(body, "var h : real;\nvar k : integer := 1;"))
    machine, host = run(program, Sensing())
    assert [t for t in host.texts if "handled" not in t] == [
        "io: analog input 1 (part height) reads 250 mm: its range is 0..200 mm"]


@pytest.mark.parametrize("rule, why", [
    ("input = 1\nvalue = 300", "reads 300 mm: its range is 0..200"),
    ("input = 3\nvalue = 1", "an analog input number 1..2"),
    ("input = 1\nvalue = 1\nat = [1, 2]\nvalues = [3]", "one reading per time"),
    ("input = 1\nvalue = true", "a finite number"),
])
def test_a_wrong_analog_rule_is_refused_with_what_and_where(cell, rule, why):
    path = cell / "bad.cell.toml"
    path.write_text(f"[[analog]]\n{rule}\n", encoding="utf-8")
    with pytest.raises(ScenarioError, match=why):
        load_scenario(path, load_spec(cell / "sensed.spc"))


def test_an_analog_output_is_set_within_its_range_and_read_back(tmp_path):
    (tmp_path / "sensed.spc").write_text(SPEC_PATH.read_text(encoding="utf-8") + SENSORS + """
[[analog_output]]
name = "glue pressure"
unit = "bar"
min = 0
max = 6
""", encoding="utf-8")
    (tmp_path / "glue.irl").write_text("""program glue;
system_specification "sensed.spc";
var p : real;
seq
  print "at first ", analog_out_value(1);
  call analog_out(1, 2.5);
  print "set ", analog_out_value(1), " bar";
  p := 7.5;
  call analog_out(1, p);
when error do
  print error_name(), ": ", error_message(), "; it stays at ", analog_out_value(1);
endseq
endprogram;
""", encoding="utf-8")
    code, out, err = run_cli("run", tmp_path / "glue.irl", "--json")
    assert code == 0, err
    texts = [e["text"] for e in json.loads(out)["log"] if e.get("kind") != "handled"]
    assert texts == ["at first 0", "set 2.5 bar",
                     "value: analog output 1 (glue pressure) cannot be set to 7.5 bar: its range is 0..6 bar; it "
                     "stays at 2.5"], texts
    code, out, err = run_cli("check", tmp_path / "glue.irl")
    assert code == 0, err
