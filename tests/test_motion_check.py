"""``irl check``'s motion verification (issue 29): the program's moves run offline through the
runtime's own trajectory generator, motion queue and planners (runtime/loop/offline.py).

What is checked here: every kind of move the runtime refuses is found at its line, all in one
run; a random program is refused by ``irl check`` exactly where ``irl run`` faults, and passes
it exactly when ``irl run`` completes, with the same cycle time; the assumed cell (waits,
branches on inputs, idle polls); the bounds; moves in procedures and modules; ``--json``.
"""
from __future__ import annotations

import json
import re
import shutil

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from compiler.driver import compile_file, compile_source
from runtime.hardware.sim.cell import load_scenario
from runtime.loop.offline import MAX_MOVES, check_motion
from runtime.loop.system import RobotSystem, RunOptions

from conftest import PROGRAMS, ROOT, SPEC, SPEC_PATH, examples, run_cli

HERE = ROOT / "tests" / "motion_check"
DIAG = re.compile(r"^(?P<file>[^:\n]+):(?P<line>\d+):(?P<col>\d+): (?P<severity>error|warning): (?P<msg>.*)$", re.M)


#: a pose out of the arm's reach, as a variable: the compiler checks the reach of constant poses
FAR = "var\n  far : pose := pose(pos(2500, 0, 400), rpy(180, 0, 180));\n"


def program_text(body: str, decls: str = "", name: str = "t") -> str:
    return (f'program {name};\nsystem_specification "{SPEC_PATH}";\n{FAR}{decls}seq\n{body}endseq\nendprogram;\n')


def line_of(text: str, fragment: str, nth: int = 1) -> int:
    """The line of ``text`` that holds ``fragment`` (its ``nth`` such line)."""
    return [i for i, line in enumerate(text.splitlines(), 1) if fragment in line][nth - 1]


def checked(text: str, scenario=None, **kw):
    result = compile_source(text, "t.irl")
    assert result.ok, result.diagnostics
    return check_motion(result.program, result.spec, scenario, **kw)


def errors(outcome) -> list:
    return [f for f in outcome.findings if f.severity == "error"]


def write(tmp_path, text: str, name: str = "p.irl"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# ---- the first hour: five programs refused at run time, one refusal per run -----------------------

FIRST_HOUR = HERE / "first_hour.irl"


def test_the_first_hours_five_refusals_are_found_at_their_lines_all_at_once():
    code, out, err = run_cli("check", FIRST_HOUR)
    assert code == 1, out + err
    found = [(int(m["line"]), m["msg"]) for m in DIAG.finditer(err)]
    assert [line for line, _ in found] == [16, 19, 23, 29, 33], err
    lin_singular, glue, press, tool_down, walk = (msg for _, msg in found)
    assert "passes through the wrist singularity" in lin_singular and "mm from its start" in lin_singular
    assert "A4 would pass its limit 185 deg" in glue and "% of its length" in glue
    assert press.startswith("the 2nd time it runs: ") and "A6 would pass its limit 350 deg" in press
    assert "A6 starts it at 270.0 deg, +360 deg from the first time it ran: it winds up" in press
    assert "A4 would pass its limit 185 deg" in tool_down
    assert walk.startswith("the 5th time it runs: the target pose cannot be reached: unreachable")
    assert err.rstrip().endswith("5 errors in " + str(FIRST_HOUR))
    assert "before" not in out and out.startswith("motion: ")  # the summary: no "ok"
    # each of the configuration and turn problems comes with the configuration that works
    hints = re.findall(r"^  hint: (.*)$", err, re.M)
    assert "make this motion a ptp move" in hints[0]
    assert hints[1] == ("name config(front, elbow_up, flip, 0, 0, 0) on the target of the ptp move at line 18 (it "
                        "takes the arm to config(front, elbow_up, noflip, 0, 0, 0)): from there the arm can follow "
                        "this path")
    assert hints[2] == ("name config(front, elbow_up, noflip, 0, 0, 0) on the target of the ptp move at line 22 (it "
                        "takes the arm to config(front, elbow_up, noflip, 0, 0, 1)): from there the arm can follow "
                        "this path")
    assert "name config(front, elbow_up, flip, 0, 0, 0) on the target of the ptp move at line 28" in hints[3]
    # the robot: refused at the first of them, as irl check said
    code, out, err = run_cli("run", FIRST_HOUR)
    assert code == 1 and "program error at line 16: move lin refused: the path passes through the wrist " \
                           "singularity" in out, out + err


def test_the_first_hours_program_mended_as_the_hints_say_checks_and_runs():
    """Each of the five mended in the program: a configuration (with its turn, for the press)
    named on a ptp move, the path through the singularity as a ptp move, the walk in reach."""
    mended = HERE / "first_hour_fixed.irl"
    code, out, err = run_cli("check", "--json", mended)
    assert code == 0 and json.loads(out)["diagnostics"] == [], err
    cycle = json.loads(out)["motion"]["cycle_time"]
    code, out, err = run_cli("run", "--json", mended)
    assert code == 0, out + err
    summary = json.loads(out)
    [move] = [s for s in summary["states"] if s["name"] == "Move Robot"]
    assert abs(cycle - (move["t_exit"] - move["t_enter"])) <= 0.005 * len(summary["moves"])


def test_a_lin_move_whose_target_names_another_configuration_is_refused_by_check_and_run():
    text = program_text(HOME + "  move ptp pose(pos(800, -200, 300), rpy(180, 30, 180), config(noflip));\n"
                               "  move lin pose(pos(800, 200, 300), rpy(180, 30, 180), config(flip));\n")
    [finding] = errors(checked(text))
    assert finding.line == line_of(text, "move lin") and "keeps the arm's configuration" in finding.message
    result = compile_source(text, "t.irl")
    summary = RobotSystem(result.spec, RunOptions()).run(result.program)
    assert summary["fault"] == f"Move Robot: program error at line {finding.line}: {finding.message}"


def test_json_names_the_configuration_each_pose_target_resolves_to():
    text = program_text(HOME + "  move ptp pose(pos(800, -200, 300), rpy(180, 30, 180), config(flip));\n"
                               "  move lin pose(pos(800, 200, 300), rpy(180, 30, 180));\n")
    outcome = checked(text)
    assert outcome.findings == []
    home, ptp, lin = outcome.moves
    assert home.configuration is None  # (a joint target)
    assert ptp.configuration == "config(front, elbow_up, flip, 0, 0, 0)"
    assert lin.configuration == "config(front, elbow_up, flip, 0, 0, 1)"  # (A6 from 177.7 to 182.3 deg: turn 1)


# ---- every kind of refusal, at its line ---------------------------------------------------------

HOME = "  move ptp joint(mainjoint(0, -30, 30, 0, 60, 0));\n"
KINDS = {
    "reach": (HOME + "  move ptp far;\n",
              "the target pose cannot be reached: unreachable"),
    "target limit": ("  j := joint(mainjoint(0, -30, 30, 0, 60, 0));\n  j[1] := 100 + 100;\n  move ptp j;\n",
                     "axis A1 target 200 deg is outside its limits -170..170 deg"),
    "singular path": ("  move ptp pose(pos(900, 0, 1000), rpy(0, 90, 0));\n"
                      "  move lin pose(pos(900, 0, 1500), rpy(0, 90, 0));\n",
                      "the path passes through the wrist singularity"),
    "limit along the path": (HOME + "  move ptp pose(pos(800, -200, 300), rpy(180, 30, 180));\n"
                                    "  move lin pose(pos(800, 200, 300), rpy(180, 30, 180));\n",
                             "the path leaves the axis limits at"),
    "degenerate circle": (HOME + "  move ptp pose(pos(800, 0, 400), rpy(180, 0, 180));\n"
                                 "  move circ pose(pos(800, 100, 400), rpy(180, 0, 180)), "
                                 "pose(pos(800, 200, 400), rpy(180, 0, 180));\n",
                          "move circ refused"),
    "trigger beyond the path": (HOME + "  move ptp pose(pos(800, 0, 400), rpy(180, 0, 180));\n"
                                       "  trigger when 500 mm before end do out[3] := false;\n"
                                       "  move lin pose(pos(800, 100, 400), rpy(180, 0, 180));\n",
                                "trigger when 500 mm before end: the tool's path of this move is only 100 mm long"),
    "clause out of range": ("  s := 100000.0;\n" + HOME + "  move lin pose(pos(800, 0, 400), rpy(180, 0, 180)) "
                                                          "speed := s;\n",
                            "speed = 100000 mm/s is out of range"),
}


@pytest.mark.parametrize("kind", list(KINDS))
def test_each_kind_of_refusal_is_found_at_its_move_and_irl_run_refuses_it_there(kind):
    body, expected = KINDS[kind]
    text = program_text(body, "  j : joint;\n  s : real;\n")
    outcome = checked(text)
    [finding] = errors(outcome)
    line = line_of(text, body.splitlines()[-1].strip())
    assert finding.line == line and expected in finding.message, (finding, line)
    assert finding.kind == "move"
    # the robot refuses the same move, with the same words
    result = compile_source(text, "t.irl")
    summary = RobotSystem(result.spec, RunOptions()).run(result.program)
    assert summary["fault"] == f"Move Robot: program error at line {line}: {finding.message}", summary["fault"]


def test_a_run_time_error_ends_the_check_of_that_path_where_the_program_would_stop():
    text = program_text(HOME + "  k := 0;\n  k := 10 div k;\n  move ptp far;\n",
                        "  k : integer;\n")
    outcome = checked(text)
    [finding] = outcome.findings
    assert (finding.kind, finding.line, finding.message) == ("error", line_of(text, "10 div k"), "division by zero (div)")
    assert outcome.ended == "stopped" and outcome.cycle_time is None


def test_a_blend_that_never_happens_is_a_warning_and_one_that_happens_sometimes_is_not():
    # approx on a move before a wait: the next move is not known in time, not a refused blend
    text = program_text(HOME + "  move ptp joint(mainjoint(40, -30, 30, 0, 60, 0)) approx := 0.5;\n  wait 1 sec;\n"
                               "  move ptp joint(mainjoint(0, -30, 30, 0, 60, 0));\n")
    assert checked(text).findings == []
    # spot_weld's first approach is not blended, every later one is: no warning
    outcome = check_motion(*_compiled(PROGRAMS / "spot_weld.irl"))
    assert not [f for f in outcome.findings if f.kind == "blend"]


def _compiled(path):
    result = compile_file(path, None)
    assert result.ok, result.diagnostics
    return result.program, result.spec


# ---- check and run agree ---------------------------------------------------------------------------

ORIENTATIONS = ("rpy(180, 0, 180)", "rpy(180, 30, 180)", "rpy(180, 20, 90)", "rpy(0, 90, 0)", "rpy(90, 0, 0)",
                "rpy(180, 0, 45)")


@st.composite
def programs(draw):
    """A ptp move to a pose, then moves around it: lin, circ and ptp moves to places a few
    hundred mm away, mostly in the same orientation, some in another (a turn of the wrist, a
    singularity near), some far (out of reach), a ptp to joint values now and then (beyond a
    limit, rarely); blends. The targets add ``o`` (0 at run time), so the compiler does not
    check them: the check and the robot do."""
    x0, y0, z0 = draw(st.integers(550, 1000)), draw(st.integers(-400, 400)), draw(st.integers(250, 850))
    o0 = draw(st.sampled_from(ORIENTATIONS[:3]))
    lines = [f"  move ptp pose(pos({x0} + o, {y0}, {z0}), {o0});\n"]

    def near() -> str:
        d = 700 if draw(st.integers(0, 7)) == 0 else 250
        x, y, z = (v + draw(st.integers(-d, d)) for v in (x0, y0, z0))
        orientation = o0 if draw(st.integers(0, 3)) else draw(st.sampled_from(ORIENTATIONS))
        return f"pose(pos({x} + o, {y}, {z}), {orientation})"

    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(("lin", "lin", "lin", "circ", "ptp", "ptp joint")))
        speed = draw(st.sampled_from((100, 250, 1000)))
        if kind == "ptp joint":
            spread = draw(st.sampled_from((0.8, 0.8, 0.8, 1.05)))  # now and then beyond a limit
            axes = [draw(st.integers(round(a.min * spread), round(a.max * spread))) for a in SPEC.axes]
            lines.append(f"  move ptp joint(mainjoint({axes[0]} + o, {', '.join(map(str, axes[1:]))})) "
                         f"approx := {draw(st.sampled_from((0, 0.5)))};\n")
        elif kind == "ptp":
            lines.append(f"  move ptp {near()} approx := {draw(st.sampled_from((0, 0.5)))};\n")
        elif kind == "lin":
            lines.append(f"  move lin {near()} speed := {speed} approx := {draw(st.sampled_from((0, 20)))};\n")
        else:
            lines.append(f"  move circ {near()}, {near()} speed := {speed};\n")
    return "".join(lines)


@pytest.fixture(scope="module")
def robot():
    """One simulated robot for the property below: it homes once, then each program starts
    where the last one left it (the check is told where)."""
    return RobotSystem(SPEC, RunOptions())


@pytest.mark.long
@settings(max_examples=examples(5), suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(body=programs())
def test_check_refuses_exactly_where_irl_run_faults_and_times_the_cycle_as_it_runs(robot, body):
    """For a random program of ptp, lin and circ moves (targets in and out of reach, near
    singularities, with blends): when the robot completes it, irl check finds no error and
    gives its time in Move Robot within a 5 ms tick per move; when the robot refuses a move,
    irl check refuses that move, at that line, with the same words."""
    text = program_text(body, "  o : real := 0.0;\n")  # (targets with o are checked when they run, as computed ones)
    result = compile_source(text, "t.irl")
    assert result.ok, result.diagnostics
    summary = robot.run(result.program)
    outcome = check_motion(result.program, result.spec, start=robot.trajectory.start_position)
    found = errors(outcome)
    fault = summary["fault"]
    if fault is None:
        assert not found, (body, found)
        [move] = [s for s in summary["states"] if s["name"] == "Move Robot"]
        n = body.count("move ")
        assert abs(outcome.cycle_time - (move["t_exit"] - move["t_enter"])) <= 0.005 * (n + 1), body
        assert len(outcome.moves) == len(summary["moves"])
        for planned, ran in zip(outcome.moves, summary["moves"]):
            assert planned.line == ran["line"] and planned.duration == pytest.approx(ran["planned_duration"])
    else:
        m = re.fullmatch(r"Move Robot: program error at line (\d+): (.*)", fault, re.S)
        assert m, (body, fault)
        assert any(f.line == int(m[1]) and f.message == m[2] for f in found), (body, fault, found)


@pytest.mark.long
def test_the_cycle_time_is_irl_runs_time_in_move_robot_on_the_shipped_programs():
    for name, scenario in (("blend", None), ("pick_place", "pick_place"), ("robots/kuka_kr6_r900_sixx", None)):
        program, spec = _compiled(PROGRAMS / f"{name}.irl")
        cell = load_scenario(PROGRAMS / f"{scenario}.cell.toml", spec) if scenario else None
        summary = RobotSystem(spec, RunOptions(cell=cell)).run(program)
        assert summary["fault"] is None, (name, summary["fault"])
        outcome = check_motion(program, spec, cell)
        [move] = [s for s in summary["states"] if s["name"] == "Move Robot"]
        n = len(summary["moves"])
        assert abs(outcome.cycle_time - (move["t_exit"] - move["t_enter"])) <= 0.005 * n, name
        assert [m.line for m in outcome.moves] == [m["line"] for m in summary["moves"]], name
        assert [m.blended for m in outcome.moves] == [m["blended"] for m in summary["moves"]], name


# ---- no false alarm ------------------------------------------------------------------------------

SHIPPED = sorted(PROGRAMS.glob("*.irl")) + sorted((PROGRAMS / "robots").glob("*.irl"))


@pytest.mark.parametrize("path", SHIPPED, ids=[p.name for p in SHIPPED])
def test_every_shipped_program_checks_without_a_finding(path):
    scenario = path.with_suffix(".cell.toml")
    argv = ["check", path] + (["--cell-scenario", scenario] if scenario.exists() else [])
    code, out, err = run_cli(*argv)
    assert code == 0 and err == "", err
    assert out.splitlines()[0] == f"{path}: ok"


# ---- the assumed cell -------------------------------------------------------------------------------

def test_without_a_scenario_each_wait_ends_at_once_and_the_time_out_is_explored():
    text = program_text(HOME + "  out[1] := true;\n  wait for in[3] timeout 5 sec;\n  if not in[3] then\n"
                               "    move ptp far;\n  endif;\n"
                               "  move ptp joint(mainjoint(30, -30, 30, 0, 60, 0));\n")
    outcome = checked(text)
    assert outcome.paths == 3  # the main run; the wait timing out; after it, in[3] true after all
    wait = line_of(text, "wait for")
    [finding] = outcome.findings  # only on the branch where the wait times out
    assert finding.line == line_of(text, "move ptp far") and finding.assumed == (f"the wait for times out at line {wait}",)
    assert outcome.cycle_time < 5.0  # the main run: the wait ended at once
    code, out, err = run_cli("check", write_program(text))
    assert code == 1 and f"  when: the wait for times out at line {wait}" in err
    assert f"each wait for ends at once where inputs can make it hold (line {wait})" in out
    assert f"branches: 2 more runs of the program, each another way at one choice: the wait for times out at " \
           f"line {wait}; in[3] reads true at line {wait + 1}" in out
    assert outcome.branches == [f"the wait for times out at line {wait}", f"in[3] reads true at line {wait + 1}"]


def write_program(text: str, name: str = "p.irl"):
    import tempfile
    from pathlib import Path

    folder = Path(tempfile.mkdtemp())
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def test_a_wait_on_two_inputs_is_explored_with_each_and_the_branch_it_leads_to():
    text = program_text(HOME + "  wait for in[11] or in[12] timeout 3 sec;\n  if in[12] then\n"
                               "    move lin far;\n  endif;\n")
    outcome = checked(text)
    [finding] = outcome.findings
    assert finding.line == line_of(text, "move lin far")
    assert finding.assumed == (f"the wait for ends with in[12] true at line {line_of(text, 'wait for')}",)


def test_a_program_that_polls_for_ever_is_stopped_with_a_note_and_its_branches_still_run():
    text = program_text(HOME + "  while not in[4] do\n    wait 0.5 sec;\n  endwhile;\n"
                               "  move ptp far;\n")
    outcome = checked(text)
    assert outcome.ended == "idles" and outcome.cycle_time is None
    poll = line_of(text, "while not")
    assert any(f"reads in[4] at line {poll} again and again without moving" in n for n in outcome.notes)
    [finding] = outcome.findings
    assert finding.line == line_of(text, "move ptp far") and finding.assumed == (f"in[4] reads true at line {poll}",)


def test_a_wait_nothing_can_end_is_a_warning():
    text = program_text(HOME + "  wait for done;\n", "  done : bool;\n")
    outcome = checked(text)
    [finding] = outcome.findings
    assert (finding.severity, finding.kind, finding.line) == ("warning", "wait", line_of(text, "wait for done"))
    assert outcome.ended == "waits"


def test_a_wait_a_trigger_ends_is_no_warning():
    text = program_text(HOME + "  trigger when 0 ms before end do done := true;\n"
                               "  move ptp joint(mainjoint(30, -30, 30, 0, 60, 0));\n  wait for done;\n",
                        "  done : bool;\n")
    outcome = checked(text)
    assert outcome.findings == [] and outcome.ended == "completed"


def test_with_a_scenario_the_check_follows_it_as_irl_run_does(tmp_path):
    program, spec = _compiled(PROGRAMS / "pick_place.irl")
    cell = load_scenario(PROGRAMS / "pick_place.cell.toml", spec)
    outcome = check_motion(program, spec, cell)
    assert outcome.paths == 1 and outcome.assumed == [] and len(outcome.moves) == 62
    code, out, err = run_cli("check", PROGRAMS / "pick_place.irl", "--cell-scenario",
                             PROGRAMS / "pick_place.cell.toml")
    assert code == 0 and "assumed: the cell of" in out and "pick_place.cell.toml" in out
    code, _, err = run_cli("check", PROGRAMS / "pick_place.irl", "--cell-scenario", tmp_path / "none.toml")
    assert code == 2 and "--cell-scenario" in err


# ---- bounds --------------------------------------------------------------------------------------

def test_an_endless_cycle_is_checked_up_to_the_bound_with_a_note():
    text = program_text("  while true do\n    move ptp joint(mainjoint(30, -30, 30, 0, 60, 0));\n"
                        "    move ptp joint(mainjoint(-30, -30, 30, 0, 60, 0));\n  endwhile;\n")
    outcome = checked(text, max_moves=40)
    assert outcome.ended == "bounded" and outcome.cycle_time is None
    assert any("after 40 moves" in note for note in outcome.notes)
    path = write_program(text)
    code, out, _ = run_cli("check", path, "--max-moves", "40")
    assert code == 0 and "note: the check stopped after 40 moves" in out
    assert out.splitlines()[0] == f"{path}: ok as far as the check went: it stopped at a bound (below)"
    assert run_cli("check", write_program(text), "--max-moves", "0")[0] == 2
    from runtime.cli.main import MAX_CHECKED_MOVES

    assert MAX_CHECKED_MOVES == MAX_MOVES


# ---- where: procedures, modules, JSON ----------------------------------------------------------------

def test_a_move_in_a_module_is_reported_in_that_file_at_its_line(tmp_path):
    (tmp_path / "lib").mkdir()
    # (reachable by its position, not with the tool pointing back at the robot: found when it is planned)
    write(tmp_path, "module cell;\nprocedure far();\nseq\n  move ptp pose(pos(1500, 0, 675), rpy(0, -90, 0));\n"
                    "endseq\nendprocedure;\nendmodule;\n", "lib/cell.irl")
    shutil.copy(SPEC_PATH, tmp_path / "lola15.spc")
    main = write(tmp_path, 'program m;\nsystem_specification "lola15.spc";\nimport "lib/cell.irl";\nseq\n'
                           '  call far();\nendseq\nendprogram;\n', "main.irl")
    code, out, err = run_cli("check", main)
    assert code == 1
    [m] = list(DIAG.finditer(err))
    assert (m["file"], m["line"], m["col"]) == (str(tmp_path / "lib" / "cell.irl"), "4", "3"), err
    assert "  move ptp pose(pos(1500, 0, 675), rpy(0, -90, 0));" in err  # the module's line shown
    code, out, _ = run_cli("check", main, "--json")
    data = json.loads(out)
    [d] = data["diagnostics"]
    assert d["file"] == str(tmp_path / "lib" / "cell.irl") and d["motion"] is True and d["kind"] == "move"


def test_json_gives_the_cycle_time_each_move_and_where_along_a_path():
    code, out, err = run_cli("check", "--json", FIRST_HOUR)
    assert code == 1 and err == ""
    data = json.loads(out)
    assert data["ok"] is False
    first = data["diagnostics"][0]
    assert first["motion"] is True and first["line"] == 16 and first["severity"] == "error"
    assert 0.0 < first["at"]["fraction"] < 1.0 and first["at"]["mm"] == pytest.approx(
        first["at"]["fraction"] * 500.0)
    motion = data["motion"]
    assert motion["cycle_time"] > 0 and motion["runs"] == 1 and motion["assumed"] == []
    moves = motion["moves"]
    assert [(m["line"], m["refused"]) for m in moves][:4] == [(15, False), (16, True), (18, False), (19, True)]
    assert all(m["duration"] > 0 and len(m["joints"]) == 6 for m in moves if not m["refused"])
    assert all(m["duration"] is None and m["joints"] is None for m in moves if m["refused"])
    assert moves[0]["configuration"] and moves[0]["kind"] == "ptp"
    code, out, _ = run_cli("check", "--json", PROGRAMS / "test.irl")
    assert json.loads(out)["motion"]["cycle_time"] == pytest.approx(15.896, abs=0.005)


def test_no_motion_skips_the_motion_check():
    code, out, err = run_cli("check", "--no-motion", FIRST_HOUR)
    assert (code, out.strip(), err) == (0, f"{FIRST_HOUR}: ok", "")
    assert run_cli("check", "--no-motion", "--cell-scenario", "x.toml", FIRST_HOUR)[0] == 2


# ---- the offline shortcuts change nothing ------------------------------------------------------

STOP_IN_A_BLEND = """\
program stop_in_a_blend;
system_specification "{spec}";
interrupt curtain when in[5] stop then resume;
seq
  wait for not in[5];
endseq
endinterrupt;
seq
  enable curtain;
  move ptp joint(mainjoint(60, -30, 30, 0, 60, 0)) approx := 1;
  move ptp joint(mainjoint(-60, -20, 40, 30, 50, 90)) approx := 1;
  move lin pose(pos(800, 0, 400), rpy(180, 0, 180)) approx := 50;
  move lin pose(pos(800, 300, 400), rpy(180, 0, 180)) speed := 500 approx := 50;
  move lin pose(pos(700, 300, 600), rpy(180, 0, 180)) speed := 500;
  disable curtain;
endseq
endprogram;
"""


@pytest.mark.parametrize("at", [0.8, 1.4, 2.05, 3.3, 5.0, 7.6])
def test_setpoints_off_and_the_plan_cache_give_the_timeline_of_a_full_run(tmp_path, at):
    """An interrupt's stop at various moments (in ptp and lin blends, in a lin of its own):
    computing a setpoint only where needed, and reusing planned moves, leave every move's
    start, end and planned duration, and the cycle time, as computing every period's."""
    result = compile_source(STOP_IN_A_BLEND.format(spec=SPEC_PATH), "t.irl")
    assert result.ok, result.diagnostics
    scenario = tmp_path / "cell.toml"
    scenario.write_text(f"[[timeline]]\ninput = 5\nat = [{at}, {at + 0.4}]\n", encoding="utf-8")
    cell = load_scenario(scenario, result.spec)
    fast = check_motion(result.program, result.spec, cell)
    full = check_motion(result.program, result.spec, cell, setpoints=True)
    assert fast.findings == full.findings == []
    assert [(m.line, m.start, m.duration, m.blended, m.joints) for m in fast.moves] == \
        [(m.line, m.start, m.duration, m.blended, m.joints) for m in full.moves]
    assert fast.cycle_time == full.cycle_time
    summary = RobotSystem(result.spec, RunOptions(cell=cell)).run(result.program)
    assert summary["fault"] is None and any("interrupt curtain fired" in line["text"] for line in summary["log"])
    [move] = [s for s in summary["states"] if s["name"] == "Move Robot"]
    assert abs(fast.cycle_time - (move["t_exit"] - move["t_enter"])) <= 0.005 * len(summary["moves"])


EDGE = """\
program edge;
system_specification "{spec}";
const
  stop := pose(pos(400, 600, 300), rpy(180, 0, 180));
var
  far : pose := pose(pos(2500, 0, 400), rpy(180, 0, 180));
seq
  move ptp joint(mainjoint(0, -30, 30, 0, 60, 0));
  move ptp stop + pos(0, 0, 100);
  if in[1] then
    move ptp far;
  endif;
endseq
endprogram;
"""


def test_with_a_scenario_an_input_that_changes_as_the_program_reads_it_is_read_alike_by_check_and_run(tmp_path):
    """The program reads in[1] where its second move ends; a part arriving (a timeline) a few
    ms before or after that instant, at every 1 ms tick around it: irl check, following
    the scenario, takes the branch irl run takes (a refused move in one, none in the other),
    because a scenario's times count from the program's first step in both."""
    result = compile_source(EDGE.format(spec=SPEC_PATH), "t.irl")
    assert result.ok, result.diagnostics
    arrives = checked(EDGE.format(spec=SPEC_PATH)).moves[1]
    read = arrives.start + arrives.duration  # (about when the program reads the input)
    taken = set()
    for k in range(-1, 7):  # (the read is at the first 5 ms step after the move's end)
        at = round(read + 0.001 * k, 3)
        scenario = tmp_path / "cell.toml"
        scenario.write_text(f"[[timeline]]\ninput = 1\nat = [{at}]\n", encoding="utf-8")
        cell = load_scenario(scenario, result.spec)
        outcome = check_motion(result.program, result.spec, cell)
        summary = RobotSystem(result.spec, RunOptions(cell=cell)).run(result.program)
        refused = summary["fault"] is not None
        assert bool(errors(outcome)) == refused, (at, summary["fault"], outcome.findings)
        taken.add(refused)
    assert taken == {True, False}  # (the sweep crossed the instant the program reads the input)
