"""The simulated cell (issue 16, first step): a scenario file drives the digital inputs,
so a program that talks to its cell runs to completion under `irl run`, with its I/O in
the report."""
from __future__ import annotations

import csv
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from runtime.hardware.sim.cell import RULES, Cell, ScenarioError, load_scenario, parse_scenario
from runtime.timing import TICK

from conftest import ROOT, SPEC, run_cli as run, examples
PICK = ROOT / "programs" / "pick_place.irl"
SCENARIO = ROOT / "programs" / "pick_place.cell.toml"


@pytest.mark.long
def test_pick_and_place_runs_to_completion_against_its_cell_with_the_io_in_the_report(tmp_path):
    code, out, err = run("run", PICK, "--cell-scenario", SCENARIO, "--report", tmp_path / "a.csv")
    assert code == 0, err
    assert "part 10 of 10 loaded" in out and "timed out" not in out
    rows = list(csv.reader((tmp_path / "a.csv").open()))
    header = rows[0]
    assert header[-32:] == [f"in_{n}" for n in range(1, 17)] + [f"out_{n}" for n in range(1, 17)]
    out1, in2 = header.index("out_1"), header.index("in_2")
    vel = header.index("out_vel_A1")  # (not an output: still a number to 1e-6)
    assert all(r[out1] in ("0", "1") and "." in r[vel] for r in rows[1:])
    rises = [float(r[0]) for prev, r in zip(rows[1:], rows[2:]) if r[out1] == "1" and prev[out1] == "0"]
    closed = [float(r[0]) for prev, r in zip(rows[1:], rows[2:]) if r[in2] == "1" and prev[in2] == "0"]
    assert len(rises) == len(closed) == 10  # one grip per part, each sensed 0.3 s later
    assert all(abs(c - r - 0.3) < 0.011 for r, c in zip(rises, closed)), list(zip(rises, closed))
    # deterministic: the same program, seed and scenario give the same bytes (over the first
    # 30 simulated seconds: three parts, grips and machine starts)
    run("run", PICK, "--cell-scenario", SCENARIO, "--report", tmp_path / "b.csv", "--max-time", "30")
    first, again = ((tmp_path / name).read_bytes().split(b"\n")[:2500] for name in ("a.csv", "b.csv"))
    assert len(again) == 2500 and first == again  # (the bounded run stops after them)


def test_without_a_scenario_nothing_answers_and_every_wait_times_out():
    """The first of the ten parts (140 simulated seconds, most of them spent waiting: the
    whole program takes 1037 s, a million ticks): every wait for an input the program
    reaches, each of its four, times out."""
    import json

    code, out, err = run("run", PICK, "--json", "--max-time", "140")
    summary = json.loads(out)
    log = [(entry["line"], entry["text"]) for entry in summary["log"]]
    assert code == 1 and "did not end within 140 s" in summary["fault"], (summary["fault"], err)
    waits = [(line, text) for line, text in log if "wait for" in text]
    assert all("timed out" in text for _line, text in waits), log
    lines = {n for n, text in enumerate(PICK.read_text(encoding="utf-8").splitlines(), 1) if "wait for in[" in text}
    assert {line for line, _text in waits} == lines and len(lines) == 4 and len(waits) >= 5, (lines, log)
    assert [text.split(" in ")[0] for _line, text in log if "loaded" in text] == ["part 1 of 10 loaded"], log


@pytest.mark.parametrize("text, words", [
    ("[[latch]]\ninput = 2\nset = 1\nreset = 2\ndelay = -1\n",
     "[[latch]] #1 delay: expected a number of seconds 0..86400, got -1"),
    ("[[latch]]\ninput = 17\nset = 1\nreset = 2\n", "[[latch]] #1 input: expected an input number 1..16, got 17"),
    ("[[folow]]\ninput = 2\noutput = 1\n", "unknown 'folow' (did you mean 'follow'?)"),
    ("[[follow]]\ninput = 2\noutput = 1\ndealy = 0.3\n", "unknown 'dealy' (did you mean 'delay'?)"),
    ("[[follow]]\ninput = 2\n", "[[follow]] #1: output is missing"),
    ("[[follow]]\ninput = 2\noutput = 1\n[[follow]]\ninput = 2\noutput = 3\n",
     "[[follow]] #2: input 2 is already driven by [[follow]] #1"),
    ("[[timeline]]\ninput = 6\nat = [2.0, 1.0]\n", "[[timeline]] #1 at: expected a list of increasing times"),
    ("[[timeline]]\ninput = 6\nat = [1.0, 3.0]\nevery = 1.0\n", "the period must be longer than the list's span"),
    ("[inputs]\n1 = 5\n", "[inputs] 1: expected true or false, got 5"),
    ("[inputs]\n99 = true\n", "[inputs] 99: expected an input number 1..16"),
    ("[[follow]\n", "invalid TOML"),
    ("a = " + "[" * 2000 + "]" * 2000 + "\n", "invalid TOML"),
    ("[[follow]]\ninput = 2\noutput = 1\ndelay = nan\n", "expected a number of seconds"),
    ("[[contact]]\ninput = 7\nz = 100\noutput = 99\n",
     "[[contact]] #1 output: expected an output number 1..16, or 0 (none), got 99"),
    ("[[contact]]\ninput = 7\nz = true\n", "[[contact]] #1 z: expected a finite number"),
    ("[[contact]]\ninput = 7\n", "[[contact]] #1: z is missing"),
    ("[[contact]]\ninput = 7\nz = 1\nheight = 3\n", "unknown 'height'"),
    ("[inputs]\n7 = true\n[[contact]]\ninput = 7\nz = 1\n", "[inputs] 7: the input is driven by a [[contact]] rule"),
])
def test_a_bad_scenario_is_refused_before_anything_moves_saying_where_and_what_is_allowed(tmp_path, text, words):
    path = tmp_path / "cell.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ScenarioError) as error:
        load_scenario(path, SPEC)
    assert words in str(error.value) and str(path) in str(error.value), str(error.value)
    code, out, err = run("run", PICK, "--cell-scenario", path)
    assert code == 2 and words in err and "Traceback" not in err, err


def test_a_scenario_that_is_not_text_is_refused(tmp_path):
    path = tmp_path / "cell.toml"
    path.write_bytes(b"[inputs]\n1 = \xff\xfe\n")
    with pytest.raises(ScenarioError, match="not UTF-8 text"):
        load_scenario(path, SPEC)


def test_every_rule_kind_is_in_the_docs():
    text = (ROOT / "docs" / "runtime.md").read_text(encoding="utf-8")
    for kind, (_doc, fields) in RULES.items():
        assert f"`[[{kind}]]`" in text
        for name in fields:
            assert f"| `{name}` |" in text


class FakeIO:
    """The simulated robot's I/O as the cell sees it."""

    def __init__(self, inputs: int = 16, outputs: int = 16):
        self._in = [False] * inputs
        self._out = [False] * outputs

    def set_input(self, n, value):
        self._in[n - 1] = bool(value)

    def input(self, n):
        return self._in[n - 1]

    @property
    def inputs(self):
        return tuple(self._in)

    @property
    def outputs(self):
        return tuple(self._out)


@settings(max_examples=examples(150), deadline=None)
@given(kind=st.sampled_from(["follow", "latch"]), delay_ticks=st.integers(0, 400), invert=st.booleans(),
       toggles=st.lists(st.tuples(st.integers(1, 600), st.sampled_from([1, 2])), max_size=12))
def test_an_input_follows_its_rule_exactly_delay_after_each_edge(kind, delay_ticks, invert, toggles):
    """Random output sequences: at every tick the input is what its rule says it must be,
    given the outputs delay ago (to the tick), whatever the order of the edges."""
    delay = delay_ticks * TICK
    rule = {"input": 5, "delay": delay}
    rule.update({"output": 1, "invert": invert} if kind == "follow" else {"set": 1, "reset": 2})
    scenario = parse_scenario({kind: [rule]}, SPEC)
    backend = FakeIO()
    cell = Cell(scenario, backend)
    cell.reset(0.0)
    changes = {}
    tick = 0
    for gap, output in toggles:
        tick += gap
        changes.setdefault(tick, []).append(output)
    history = []  # outputs at each tick
    latched, seen = False, 0  # the latch: its value (initially false) from the edges of history[:seen]
    for k in range(tick + delay_ticks + 2):
        for output in changes.get(k, []):
            backend._out[output - 1] = not backend._out[output - 1]
        history.append(backend.outputs)
        cell.update(k * TICK)
        # what the rule says, from the outputs delay ago
        if kind == "follow":
            past = history[k - delay_ticks] if k >= delay_ticks else (False,) * 16  # (outputs start false)
            expected = past[0] != invert
        else:
            for j in range(seen, k - delay_ticks + 1):  # the edges up to delay ago, each once
                before = history[j - 1] if j else (False,) * 16
                if history[j][0] and not before[0]:
                    latched = True
                if history[j][1] and not before[1]:
                    latched = False
                seen = j + 1
            expected = latched
        assert backend.input(5) == expected, (k, history[max(0, k - delay_ticks)])


def test_a_timeline_toggles_its_input_at_the_times_given_and_repeats():
    scenario = parse_scenario({"timeline": [{"input": 6, "at": [0.5, 0.75], "every": 2.0}],
                               "inputs": {"6": True}}, SPEC)
    backend = FakeIO()
    cell = Cell(scenario, backend)
    cell.reset(1.0)  # (power-up at 1 s on the clock: the timeline waits for the program)
    for k in range(0, 9000):
        cell.update(1.0 + k * TICK)
    assert backend.input(6) is True
    cell.start_program(10.0)  # (the program starts at 10 s: times count from its start)
    seen = []
    for k in range(0, 5000):
        now = 10.0 + k * TICK
        before = backend.input(6)
        cell.update(now)
        if backend.input(6) != before:
            seen.append((round(now - 10.0, 6), backend.input(6)))
    assert seen == [(0.5, False), (0.75, True), (2.5, False), (2.75, True), (4.5, False), (4.75, True)]
    once = Cell(parse_scenario({"timeline": [{"input": 6, "at": [0.001]}]}, SPEC), backend)
    once.reset(0.0)
    once.start_program(0.0)
    for k in range(0, 3000):
        once.update(k * TICK)
    assert backend.input(6) is True  # toggled once, from false, and never again


@pytest.mark.long
def test_irl_serve_runs_pick_and_place_against_its_cell_and_shows_the_io(tmp_path):
    """End to end: `irl serve --sim-clock --cell-scenario`: a grip with pick and place's
    gripper completes (its jaw sensors follow the outputs), its report has the io columns,
    and status shows the I/O."""
    from conftest import ServerProcess, objcode, wait_end

    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=True,
                           extra=("--cell-scenario", SCENARIO)).start()
    try:
        client = server.client(timeout=30.0)
        status = client.request("status")
        assert status["inputs"][:4] == [True, False, True, True] and not any(status["outputs"])
        grip = tmp_path / "grip.irl"  # (one grip of pick_place's gripper: tests above run its ten parts)
        grip.write_text(f'program grip;\nsystem_specification "{ROOT / "programs" / "lola15.spc"}";\nseq\n'
                        '  out[2] := false;\n  out[1] := true;\n  wait for in[2] timeout 2 sec;\n'
                        '  print "closed ", in[2], " open ", in[3];\nendseq\nendprogram;\n', encoding="utf-8")
        job = client.request("submit", {"object": objcode(grip), "name": "grip"})["program"]
        final = wait_end(client, job, server)
        assert final["state"] == "completed", final
        log = [entry["text"] for entry in final["summary"]["log"]]
        assert log == ["closed true open false"], log
        header = Path(final["report"]).read_text().splitlines()[0].split(",")
        assert header[-1] == "out_16"
    finally:
        assert server.stop() == 0, server.log()
    code, _, err = run("serve", "--spec", ROOT / "programs" / "lola15.spc", "--sim-clock", "--cell-scenario",
                       tmp_path / "missing.toml")
    assert code == 2 and "--cell-scenario: cannot read" in err


def test_an_input_forced_by_hand_releases_a_waiting_program_and_outputs_cannot_be_forced(tmp_path):
    """`irl call 'io.in[5] = true'` (simulation only): a program waiting for in[5] goes on
    at the next tick; an output is the program's and is refused; the range is checked."""
    from compiler.driver import compile_source
    from compiler.objcode import encode

    from runtime.wire.protocol import ProtocolError
    from runtime.server.server import ServeOptions, Server

    source = (f'program w;\nsystem_specification "{ROOT / "programs" / "lola15.spc"}";\nseq\n'
              '  wait for in[5] timeout 30 sec;\n  print "released";\nendseq\nendprogram;\n')
    result = compile_source(source, "w.irl")
    assert result.ok, result.diagnostics
    server = Server(SPEC, ServeOptions(sim_clock=True, state_dir=tmp_path / "state", loop_process=False))
    try:
        job = server.request("submit", {"object": encode(result.program)})["program"]
        while not (server.jobs.current is not None and server.system.trajectory.line == 4):
            server.turn(idle_wait=False)
        for _ in range(500):  # waiting: nothing sets in[5]
            server.turn(idle_wait=False)
        assert server.jobs.current is not None
        assert server.request("call", {"text": "io.in[5] = true"})["value"] is True
        assert server.request("call", {"text": "io.in[5]"})["value"] is True
        while server.jobs.current is not None:
            server.turn(idle_wait=False)
        summary = server.jobs[job].summary
        assert summary["fault"] is None and [e["text"] for e in summary["log"]] == ["released"]
        with pytest.raises(ProtocolError, match="read-only"):
            server.request("call", {"text": "io.out[1] = true"})
        with pytest.raises(ProtocolError, match="no input 17"):
            server.request("call", {"text": "io.in[17] = true"})
        with pytest.raises(ProtocolError, match="expected true or false"):
            server.request("call", {"text": "io.in[2] = 1"})
        assert "in[n]  (writable in simulation)" in server.request("call", {"text": "help io"})["output"]
    finally:
        server.close()


def test_a_timeline_counts_from_the_first_step_of_each_program(tmp_path):
    """``at`` counts from the program's start (its first step, the trajectory generator's
    first 5 ms update in Move Robot), not from power-up: the first cycle calibrates and homes
    (about 9 s) before its program starts, the second (a served robot's next program)
    starts its program at once; in both the input toggled at ``at = 0.5`` is in the 1 ms
    report 0.5 s after the program's first step, within a tick, and that step is within a
    5 ms period of Move Robot's start (irl check's offline run, which has no homing, sees
    the same instants of the program's steps)."""
    from compiler.driver import compile_source
    from runtime.loop.supervisor import MOVE
    from runtime.loop.system import RobotSystem, RunOptions

    spec_path = ROOT / "programs" / "lola15.spc"
    result = compile_source(f'program p;\nsystem_specification "{spec_path}";\nseq\n'
                            '  wait for in[6] timeout 5 sec;\n  print "part";\nendseq\nendprogram;\n', "p.irl")
    assert result.ok, result.diagnostics
    system = RobotSystem(SPEC, RunOptions(cell=parse_scenario({"timeline": [{"input": 6, "at": [0.5]}]}, SPEC)))
    system.apply_settings({"report": {"period": TICK}})
    started = []
    for k in range(2):
        report = tmp_path / f"r{k}.csv"
        system.begin(result.program, report)
        while not system.supervisor.done:
            system.executive.step()
        summary = system.finish()
        assert summary["fault"] is None and [e["text"] for e in summary["log"]] == ["part"]
        moved = [t for t, _source, state in system.supervisor.fsm.history if state == MOVE]
        started.append(system.trajectory.started_at)
        assert len(moved) == 1
        assert moved[0] - 1e-9 <= started[k] < moved[0] + 0.005
        rows = list(csv.DictReader(report.open()))
        seen = next(float(r["time"]) for r in rows if r["in_6"] == "1")
        assert started[k] + 0.5 - 1e-9 <= seen <= started[k] + 0.5 + TICK + 1e-9, (k, started[k], seen)
