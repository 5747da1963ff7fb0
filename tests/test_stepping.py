"""Step mode and starting a program from a line (issue 31, item 3; runtime/loop/stepping.py,
docs/runtime.md "Step mode and starting from a line"): in-process on the simulated clock,
with the robot already calibrated and homed (no Start Robot searches: each cycle costs
only its moves); then ``irl run --step`` and ``--from-line`` driven in-process, and a
served robot stepped with ``irl step`` end to end."""
from __future__ import annotations

import io
import json

import pytest

from compiler.driver import compile_source
from compiler.objcode import from_line_problem
from runtime.cli.main import Environment, main
from runtime.loop.stepping import APPROACH_SPEED
from runtime.loop.system import RobotSystem, RunOptions

from conftest import SPEC, SPEC_PATH, run_irl, no_traceback, status as program_status, wait_for, wait_end

HOME = (0.0, -30.0, 30.0, 0.0, 60.0, 0.0)


def program(body: str, decls: str = ""):
    """A program of ``body`` (its first statement on line 5)."""
    text = f'program st;\nsystem_specification "{SPEC_PATH}";\n{decls or "var n : integer;"}\nseq\n{body}endseq\nendprogram;\n'
    result = compile_source(text, "st.irl", SPEC_PATH)
    assert result.ok, result.diagnostics
    return result.program


def homed() -> RobotSystem:
    """A robot already calibrated and homed: a cycle goes straight to Move Robot."""
    system = RobotSystem(SPEC, RunOptions(max_time=600.0))
    memory = system.memory
    memory.calibrated = memory.initialized = True
    memory.compensation = [0.0] * len(SPEC.axes)
    memory.encoder_offsets = [0.0] * len(SPEC.axes)
    return system


# line:  5                                                                       (body starts on line 5)
THREE = program("  move ptp joint(mainjoint(10, -30, 30, 0, 60, 0)) speed_ptp := 1 acc_ptp := 1;\n"   # 5
                "  print \"between\";\n"                                                                # 6
                "  move ptp joint(mainjoint(10, -20, 30, 0, 60, 0)) speed_ptp := 1 acc_ptp := 1 "
                "approx := 0.5;\n"                                                                      # 7
                "  move ptp joint(mainjoint(0, -20, 30, 0, 60, 0)) speed_ptp := 1 acc_ptp := 1;\n")    # 8


def test_step_mode_stops_before_each_move_with_nothing_ahead_and_no_blend():
    system = homed()
    held = []

    def on_pause(line, kind):
        motion = system.trajectory.motion
        held.append((line, kind, tuple(round(p, 6) for p in motion.positions[:6]), motion.queued, motion.at_rest(),
                     system.trajectory.moves_done))
        return "resume"
    summary = system.run(THREE, on_pause, step=True)
    assert summary["fault"] is None, summary["fault"]
    here = tuple(system.robot.positions[:6])
    assert [h[:2] for h in held] == [(5, "step"), (7, "step"), (8, "step")]
    # at each hold the robot is at rest at the last target, and no move is handed over ahead
    assert [h[2] for h in held][1:] == [(10.0, -30.0, 30.0, 0.0, 60.0, 0.0), (10.0, -20.0, 30.0, 0.0, 60.0, 0.0)]
    assert all(queued == 0 and rest for _l, _k, _p, queued, rest, _d in held)
    assert [h[5] for h in held] == [0, 1, 2]
    assert [m["line"] for m in summary["moves"]] == [5, 7, 8]
    assert not any(m["blended"] for m in summary["moves"])  # (approx := 0.5 on line 7: a stop all the same)
    assert summary["step"] is True and summary["from_line"] is None
    assert here == pytest.approx((0.0, -20.0, 30.0, 0.0, 60.0, 0.0), abs=0.05)
    assert system.trajectory.lookahead == 0


def test_aborting_at_a_step_ends_the_program_before_that_move():
    system = homed()
    answers = iter(["resume", "abort"])
    summary = system.run(THREE, lambda line, kind: next(answers), step=True)
    assert summary["fault"] == "Move Robot: aborted by the operator before the move (step mode) at line 7"
    assert [m["line"] for m in summary["moves"]] == [5]


# line: 5 .. 21
FRAMES = program(
    "  n := 0;\n"                                                                         # 5
    "  flag := false;\n"                                                                  # 6
    "  move ptp joint(mainjoint(0, -30, 30, 0, 60, 0));\n"                                # 7
    "  use tool tool(pos(0, 0, 100), rpy(0, 0, 0));\n"                                    # 8
    "  use base frame(pos(100, 0, 0), rpy(0, 0, 90));\n"                                  # 9
    "  out[1] := true;\n"                                                                 # 10
    "  print \"skipped \", n;\n"                                                          # 11
    "  wait 100 sec;\n"                                                                   # 12
    "  wait for in[3];\n"                                                                 # 13
    "  pause;\n"                                                                          # 14
    "  trigger when 0 ms after start do flag := true;\n"                                  # 15
    "  trigger when 0 ms after start do out[2] := true;\n"                                # 16
    "  move ptp pose(pos(800, 0, 500), rpy(180, 0, 180));\n"                              # 17
    "  n := n + 1;\n"                                                                     # 18
    "  use tool tool(pos(0, 0, 50), rpy(0, 0, 0));\n"                                     # 19
    "  move lin pose(pos(800, 50, 500), rpy(180, 0, 180)) speed := 200;\n"                # 20
    "  print \"n=\", n, \" flag=\", flag;\n",                                              # 21
    "var n : integer; flag : bool;")


def test_a_start_from_a_line_runs_the_program_to_it_without_moving_then_approaches_its_start():
    system = homed()
    summary = system.run(FRAMES, from_line=20)
    assert summary["fault"] is None, summary["fault"]
    assert [m["line"] for m in summary["moves"]] == [20]  # the moves before line 20 did not run
    start = summary["from_line"]
    assert start["line"] == 20 and start["reached"]
    assert start["skipped"] == {"moves": 2, "outputs": 2, "prints": 1, "waits": 2, "pauses": 1}
    approach = start["approach"]
    assert approach["to_line"] == 17 and approach["actual_duration"] is not None
    # the approach ended at line 17's target: pos(800, 0, 500) in the base (turned 90 deg about z,
    # 100 mm along x), reached by line 17's tool (100 mm), not line 19's
    tool = system.trajectory.planner.kinematics.with_tool((0.0, 0.0, 100.0, 0.0, 0.0, 0.0))
    x, y, z, *_ = tool.forward(approach["target"][:6])
    assert (x, y, z) == pytest.approx((100.0, 800.0, 500.0), abs=1e-6)
    # variables as the program computed them (line 15's trigger taken as made), nothing printed
    # or written before line 20, no wait waited
    log = [(entry["line"], entry["text"], entry["kind"]) for entry in summary["log"]]
    assert log[0][0] == 20 and log[0][2] == "from line" and "skipped: 2 moves, 2 outputs, 1 print" in log[0][1]
    assert log[1:] == [(21, "n=1 flag=true", "print")]
    assert list(system.io.outputs.read()[:2]) == [False, False]
    move_robot = next(s for s in summary["states"] if s["name"] == "Move Robot")
    assert move_robot["t_exit"] - move_robot["t_enter"] < 20.0
    planned = approach["planned_duration"]
    # at APPROACH_SPEED of the axes' speeds (slower than the line's own ptp default, 0.5)
    assert APPROACH_SPEED == 0.1 and planned > 1.0


def test_with_step_mode_the_approach_is_the_first_step_and_a_first_move_has_none():
    system = homed()
    held = []
    summary = system.run(THREE, lambda line, kind: held.append((line, kind)) or "resume", step=True, from_line=7)
    assert held == [(7, "approach"), (7, "step"), (8, "step")]
    assert [m["line"] for m in summary["moves"]] == [7, 8]
    assert summary["from_line"]["approach"]["to_line"] == 5
    summary = system.run(THREE, from_line=5)  # the first move: nothing before it to approach
    assert summary["from_line"]["approach"] is None and [m["line"] for m in summary["moves"]] == [5, 7, 8]
    assert "no approach" in summary["log"][0]["text"]


def test_a_line_without_a_move_is_refused_naming_the_lines_that_have_one():
    problem = from_line_problem(THREE, 6)
    assert problem == "line 6 of st.irl has no move to start at; the lines with a move: 5, 7, 8"
    assert from_line_problem(THREE, 7) is None and from_line_problem(THREE, True) is not None
    with pytest.raises(ValueError, match="--from-line 6: line 6 of st.irl has no move"):
        homed().begin(THREE, from_line=6)


def test_a_start_whose_line_the_program_never_reaches_faults_at_its_end():
    branch = program("  n := 1;\n"
                     "  move ptp joint(mainjoint(5, -30, 30, 0, 60, 0));\n"          # 6
                     "  if n = 2 then\n"
                     "    move ptp joint(mainjoint(0, -30, 30, 0, 60, 0));\n"          # 8
                     "  endif;\n")
    summary = homed().run(branch, from_line=8)
    assert summary["fault"] == ("Move Robot: start from line 8: the program ended without reaching the move at line "
                                "8 (it is in a branch or a loop the program did not run)"), summary["fault"]
    assert summary["moves"] == []


# ---- irl run, in-process ------------------------------------------------------------------------------
class Terminal(io.StringIO):
    """Standard input on a terminal: what the operator types."""

    def isatty(self) -> bool:
        return True


@pytest.fixture(scope="module")
def three_irl(tmp_path_factory):
    path = tmp_path_factory.mktemp("step") / "three.irl"
    path.write_text(
        "program three;\n"
        f'system_specification "{SPEC_PATH}";\n'
        "seq\n"
        "  move ptp joint(mainjoint(10, 0, 0, 0, 0, 0)) speed_ptp := 1 acc_ptp := 1;\n"    # 4
        "  print \"one\";\n"                                                                 # 5
        "  move ptp joint(mainjoint(10, 10, 0, 0, 0, 0)) speed_ptp := 1 acc_ptp := 1;\n"   # 6
        "  move ptp joint(mainjoint(0, 10, 0, 0, 0, 0)) speed_ptp := 1 acc_ptp := 1;\n"    # 7
        "endseq\nendprogram;\n", encoding="utf-8")
    return path


def test_irl_run_step_on_a_terminal_asks_before_each_move(three_irl):
    out, err = io.StringIO(), io.StringIO()
    code = main(["run", str(three_irl), "--step"], Environment(stdout=out, stderr=err, stdin=Terminal("\nabort\n")))
    assert code == 1, err.getvalue()
    prompts = err.getvalue()
    assert prompts.count("step mode: the move waits. Enter moves it, 'abort' Enter aborts: ") == 2
    assert "irl run: line 4: step mode" in prompts and "irl run: line 6: step mode" in prompts
    assert "FAULT: Move Robot: aborted by the operator before the move (step mode) at line 6" in out.getvalue()
    assert "line 5: one" in out.getvalue()


def test_irl_run_step_without_a_terminal_goes_on_by_itself_and_a_start_from_a_line_lists_what_ran(three_irl):
    proc = run_irl("run", three_irl, "--step", "--from-line", 6, "--json")
    no_traceback(proc)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert [m["line"] for m in summary["moves"]] == [6, 7]  # the approach is not among them
    assert summary["from_line"]["approach"]["target"] == pytest.approx([10, 0, 0, 0, 0, 0])
    assert summary["from_line"]["skipped"]["prints"] == 1 and summary["step"]
    went = [line for line in proc.stderr.splitlines() if "step mode" in line]
    assert went == ["irl run: line 6: step mode: the approach to this move's start waits: it goes (not a terminal; "
                    "--on-pause ask|resume|abort chooses)",
                    "irl run: line 6: step mode: the move waits: it goes (not a terminal; --on-pause "
                    "ask|resume|abort chooses)",
                    "irl run: line 7: step mode: the move waits: it goes (not a terminal; --on-pause "
                    "ask|resume|abort chooses)"], proc.stderr


def test_a_from_line_without_a_move_is_a_usage_error_of_run_and_submit(three_irl):
    for command in (("run",), ("submit", "--endpoint", "tcp://127.0.0.1:1")):
        proc = run_irl(*command, three_irl, "--from-line", 5)
        no_traceback(proc)
        assert proc.returncode == 2
        assert proc.stderr.strip() == ("irl: --from-line 5: line 5 of three.irl has no move to start at; the lines "
                                       "with a move: 4, 6, 7"), proc.stderr


# ---- a served robot, end to end -------------------------------------------------------------------------
def test_a_served_program_in_step_mode_moves_one_move_per_irl_step(server, three_irl):
    client = server.client()
    submitted = run_irl("submit", three_irl, "--step", "--endpoint", server.endpoint)
    assert submitted.returncode == 0, submitted.stderr
    job = int(submitted.stdout.split()[1])
    refused = run_irl("step", "--endpoint", server.endpoint)  # (homing: not waiting for a step yet)
    assert refused.returncode == 1 and "refused" in refused.stderr, refused.stderr
    lines = []
    for done in range(3):
        s = wait_for(client, job, lambda s: s.get("waiting_for_step"), f"waiting for step {done + 1}", server)
        assert s["step"] and s["moves_done"] == done and s["fsm"] == "Move Robot" and not s["paused"]
        lines.append(s["line"])
        stepped = run_irl("step", "--endpoint", server.endpoint)
        assert stepped.returncode == 0, stepped.stderr
        assert stepped.stdout.strip() == f"program {job}: the move at line {s['line']} goes"
    final = wait_end(client, job, server)
    assert lines == [4, 6, 7]
    assert final["state"] == "completed" and final["moves_done"] == 3 and final["step"] is True
    assert [m["line"] for m in final["summary"]["moves"]] == [4, 6, 7]
    # the same robot (homed), from line 7: the approach to line 6's target, then line 7's move alone
    started = client.request("submit", {"object": _object(three_irl), "from_line": 7})["program"]
    final = wait_end(client, started, server)
    assert final["state"] == "completed", final["fault"]
    assert [m["line"] for m in final["summary"]["moves"]] == [7] and final["from_line"] == 7
    assert final["summary"]["from_line"]["approach"]["target"] == pytest.approx([10, 10, 0, 0, 0, 0])
    with pytest.raises(Exception, match="line 5 of three.irl has no move"):
        client.request("submit", {"object": _object(three_irl), "from_line": 5})
    assert program_status(client, started)["moves_total"] == 1


def _object(path) -> bytes:
    from compiler.driver import compile_file
    from compiler.objcode import encode

    return encode(compile_file(path).program)
