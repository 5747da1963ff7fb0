"""The first hour with the tool (issue 16, item 3): what a new user meets first."""
from __future__ import annotations

import argparse
import io
import json
import re
from pathlib import Path

from runtime.cli.main import Environment, build_parser, main

from conftest import ROOT, run_cli as run


def test_irl_version_names_the_package_and_the_formats_a_peer_must_share(capsys):
    code, _, _ = run("--version")
    out = capsys.readouterr().out  # (argparse prints the version itself)
    assert code == 0 and re.fullmatch(r"irl \S+ \(object code format \d+, protocol \d+\)\n", out), out


def _commands():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices


def test_every_command_says_what_it_does_and_every_argument_has_help_with_its_default():
    for name, command in _commands().items():
        assert command.description, f"irl {name} --help has no description"
        text = command.format_help()
        for action in command._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            assert action.help, f"irl {name}: {action.option_strings or action.dest} has no help"
            if action.option_strings and action.default not in (None, False, argparse.SUPPRESS):
                shown = {str(action.default)} | ({f"{action.default:g}"} if isinstance(action.default, float) else set())
                assert any(form in " ".join(text.split()) for form in shown), \
                    f"irl {name} --help does not show {action.option_strings[0]}'s default {action.default!r}"


def test_the_network_commands_take_their_endpoint_from_irl_endpoint(monkeypatch):
    monkeypatch.setenv("IRL_ENDPOINT", "tcp://127.0.0.1:7777")
    args = build_parser().parse_args(["status"])
    assert args.endpoint == "tcp://127.0.0.1:7777"
    assert build_parser().parse_args(["status", "--endpoint", "tcp://127.0.0.1:1"]).endpoint == "tcp://127.0.0.1:1"
    monkeypatch.delenv("IRL_ENDPOINT")
    assert build_parser().parse_args(["status"]).endpoint == "tcp://127.0.0.1:5555"


def test_submit_json_and_wait_shows_the_programs_print_output(tmp_path, monkeypatch):
    from conftest import ServerProcess

    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=True).start()
    try:
        monkeypatch.setenv("IRL_ENDPOINT", server.endpoint)  # (no --endpoint: the environment's)
        program = tmp_path / "hello.irl"
        program.write_text(f'program hello;\nsystem_specification "{ROOT / "programs" / "lola15.spc"}";\nseq\n'
                           '  print "hello from the robot";\nendseq\nendprogram;\n', encoding="utf-8")
        code, out, err = run("submit", program, "--json")
        queued = json.loads(out)
        assert code == 0 and queued["program"] == 1 and queued["endpoint"] == server.endpoint, (out, err)
        code, out, err = run("submit", program, "--wait")
        assert code == 0 and "line 4: hello from the robot" in out, (out, err)
        code, out, err = run("submit", program, "--wait", "--json")
        final = json.loads(out)
        assert code == 0 and final["state"] == "completed"
        assert final["summary"]["log"][0]["text"] == "hello from the robot"
    finally:
        assert server.stop() == 0, server.log()


def test_submit_wait_shows_print_output_while_the_program_runs(tmp_path):
    """The first print is on the terminal while the program runs, not only in the final
    summary: the program holds at its own ``pause`` after the first print, and only once
    ``irl submit --wait`` has shown that line does the test resume it. Nothing here
    depends on how fast the machine is (the simulated clock; the pause holds until the
    resume, however long the client takes)."""
    import subprocess
    import threading

    from conftest import IRL, SAFETY, ServerProcess, status

    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=True).start()
    try:
        client = server.client(timeout=SAFETY)
        program = tmp_path / "held.irl"
        program.write_text(f'program held;\nsystem_specification "{ROOT / "programs" / "lola15.spc"}";\nseq\n'
                           '  print "first";\n  pause;\n  print "second";\nendseq\nendprogram;\n',
                           encoding="utf-8")
        proc = subprocess.Popen([*IRL, "submit", str(program), "--wait", "--endpoint", server.endpoint],
                                cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        lines: list[str] = []
        first_seen = threading.Event()

        def read() -> None:
            for line in proc.stdout:
                lines.append(line)
                if "first" in line:
                    first_seen.set()
            first_seen.set()  # (the output ended: the assertions below say what was missing)

        reader = threading.Thread(target=read)
        reader.start()
        try:
            first_seen.wait(SAFETY)
            held = status(client, 1)  # the program is still held at its pause, after the first print
            assert any("line 4: first" in line for line in lines), (lines, held)
            assert held["state"] == "running" and held.get("paused"), (held, lines)
            client.request("resume")
            code = proc.wait(SAFETY)
        finally:
            if proc.poll() is None:
                proc.kill()
            reader.join(SAFETY)
            stderr = proc.stderr.read()
            proc.stderr.close()
        explain = f"exit status {proc.returncode}\nstdout:\n{''.join(lines)}\nstderr:\n{stderr}\nserver:\n{server.log()}"
        assert code == 0, explain
        order = [text for line in lines for text in ("first", "second", "completed") if text in line]
        assert order == ["first", "second", "completed"], explain  # as they came; "first" once, not again at the end
    finally:
        assert server.stop() == 0, server.log()


def test_the_plot_shows_all_five_phases_from_the_states_file(tmp_path):
    from runtime.cli.plot import phases, read_report, read_transitions

    code, _, err = run("run", ROOT / "programs" / "test.irl", "--report", tmp_path / "r.csv", "--plot",
                       tmp_path / "r.png")
    assert code == 0, err
    times, states, _ = read_report(tmp_path / "r.csv")
    names = [name for _t0, _t1, name in phases(times, states, read_transitions(tmp_path / "r.csv"))]
    assert names == ["Start Robot", "Calibrate Offsets", "Initialization Sequence", "Move Robot", "Stop Robot"]
    assert (tmp_path / "r.png").stat().st_size > 10_000


from hypothesis import given, strategies as st  # noqa: E402


@given(st.lists(st.tuples(st.floats(0.0, 10.0), st.text(min_size=1, max_size=30)), min_size=1, max_size=8))
def test_phase_labels_never_overlap(raw):
    from runtime.cli.plot import label_rows

    spans, t = [], 0.0
    for width, name in raw:
        spans.append((t, t + width, name))
        t += width
    total = max(t, 1e-9)
    rows = label_rows(spans, total)
    placed: dict[int, list[tuple[float, float]]] = {}
    for (t0, t1, name), row in zip(spans, rows):
        centre, half = (t0 + t1) / 2 / total, len(name) / 130.0 / 2
        for a, b in placed.get(row, []):
            assert centre - half > b or centre + half < a, (spans, rows)
        placed.setdefault(row, []).append((centre - half, centre + half))


PAUSING = """program pausing;
system_specification "{spec}";
seq
  move ptp joint(mainjoint(10, -30, 30, 0, 60, 0));
  pause;
  print "after the pause";
endseq
endprogram;
"""


def _written(tmp_path, name: str, template: str) -> Path:
    """``template`` (a program naming {spec}) written to tmp_path/NAME.irl for the paper's robot."""
    path = tmp_path / f"{name}.irl"
    path.write_text(template.format(spec=ROOT / "programs" / "lola15.spc"), encoding="utf-8")
    return path


def _pausing(tmp_path) -> Path:
    return _written(tmp_path, "pausing", PAUSING)


def test_a_pause_under_irl_run_resumes_or_aborts_as_asked_instead_of_idling_for_an_hour(tmp_path):
    path = _pausing(tmp_path)
    code, out, err = run("run", path, "--json")  # not a terminal: resumes, and says so
    summary = json.loads(out)
    assert code == 0 and summary["log"][-1]["text"] == "after the pause" and summary["sim_time"] < 60, summary
    assert "paused by the program: resumed (not a terminal" in err
    code, out, err = run("run", path, "--on-pause", "abort", "--json")
    summary = json.loads(out)
    assert code == 1 and summary["fault"] == "Move Robot: aborted at the program's pause at line 5", summary


def test_on_a_terminal_a_pause_waits_for_enter_and_abort_aborts(tmp_path):
    class Terminal(io.StringIO):
        def isatty(self):
            return True

    path = _pausing(tmp_path)
    for answer, code_wanted in (("\n", 0), ("abort\n", 1)):
        out, err = io.StringIO(), io.StringIO()
        code = main(["run", str(path)], Environment(stdout=out, stderr=err, stdin=Terminal(answer)))
        assert code == code_wanted, (answer, out.getvalue(), err.getvalue())
        assert "paused by the program. Enter resumes" in err.getvalue()


PRINTING = """program printing;
system_specification "{spec}";
seq
  print "before the pause";
  pause;
  print "after the pause";
endseq
endprogram;
"""


def _printing(tmp_path) -> Path:
    return _written(tmp_path, "printing", PRINTING)


def test_irl_run_shows_print_output_as_it_happens_before_the_pause_that_follows_it(tmp_path):
    """Simulated clock: each print line is shown when the program prints it, once: before
    the pause after it asks, and before the summary (before: all of them in the summary
    at the end, after the pause's prompt)."""
    both = io.StringIO()  # stdout and stderr in one stream: the order a terminal shows
    code = main(["run", str(_printing(tmp_path)), "--on-pause", "resume"], Environment(stdout=both, stderr=both))
    text = both.getvalue()
    assert code == 0, text
    before, paused = text.find("line 4: before the pause"), text.find("irl run: line 5: paused by the program")
    after, summary = text.find("line 6: after the pause"), text.find("program printing on lola_15: completed")
    assert -1 < before < paused < after < summary, text
    assert text.count("before the pause") == 1 and text.count("after the pause") == 1, text


def test_on_the_wall_clock_print_output_is_handed_over_as_it_comes_and_never_by_the_loop(tmp_path):
    """RobotSystem.run on the wall clock (calibrated and homed already, so that the cycle
    is short): the lines come before the pause's question and are handed over by a thread
    other than the loop's while the cycle runs."""
    import threading

    from compiler.driver import compile_file
    from runtime.loop.supervisor import RobotMemory
    from runtime.loop.system import RobotSystem, RunOptions

    result = compile_file(str(_printing(tmp_path)), None)
    n = len(result.spec.axes)
    memory = RobotMemory(calibrated=True, compensation=[0.0] * n, initialized=True, encoder_offsets=[0.0] * n)
    system = RobotSystem(result.spec, RunOptions(realtime=True, deadline_policy="soft"), memory=memory)
    events = []
    loop = threading.current_thread()

    def on_log(at, line, text):
        events.append(("log", line, text, threading.current_thread() is loop))

    summary = system.run(result.program, lambda line, kind: events.append(("pause", line)) or "resume", on_log)
    assert summary["fault"] is None, summary["fault"]
    assert [e[:3] for e in events] == [("log", 4, "before the pause"),
                                       ("log", 5, "paused by the program: resume to continue"),
                                       ("pause", 5), ("log", 6, "after the pause")], events
    assert not any(e[3] for e in events[:2]), events  # (the last may come after the cycle, from the caller)


def _report_times(path: Path) -> list[float]:
    import csv

    with open(path, newline="") as f:
        return [float(row["time"]) for row in csv.DictReader(f)]


def test_irl_run_reports_every_1_ms_with_report_period_or_a_configuration(tmp_path):
    """A report every tick (to check triggers) without a server: --report-period MS, or
    --config FILE.toml as irl serve takes it (its default configuration); the flag applies
    over the file; values outside report.period's declared range are refused with it."""
    program = ROOT / "programs" / "test.irl"
    short = ("--max-time", "0.2")  # (calibration only: the rows' spacing is what is checked)
    code, out, err = run("run", program, "--report-period", "1", "--report", tmp_path / "a.csv", *short)
    times = _report_times(tmp_path / "a.csv")
    steps = {round(b - a, 6) for a, b in zip(times, times[1:])}
    assert steps == {0.001} and len(times) > 100, (steps, err)
    config = tmp_path / "fine.toml"
    config.write_text('default = "fine"\n[configurations.fine.report]\nperiod = 0.002\n'
                      '[configurations.other.report]\nperiod = 0.5\n', encoding="utf-8")
    run("run", program, "--config", config, "--report", tmp_path / "b.csv", *short)
    times = _report_times(tmp_path / "b.csv")
    assert {round(b - a, 6) for a, b in zip(times, times[1:])} == {0.002}
    run("run", program, "--config", config, "--report-period", "5", "--report", tmp_path / "c.csv", *short)
    times = _report_times(tmp_path / "c.csv")
    assert {round(b - a, 6) for a, b in zip(times, times[1:])} == {0.005}
    for bad, says in (("0.5", "expected a period of 0.001 to 1 s"), ("1.5", "a whole multiple of the 1 ms tick"),
                      ("nan", "expected a period of 0.001 to 1 s"), ("2000", "expected a period of 0.001 to 1 s")):
        code, out, err = run("run", program, "--report-period", bad)
        assert code == 2 and f"irl: --report-period {bad} (ms): report.period would be" in err and says in err, err
    config.write_text('[configurations.x.servo]\nkp = -1\n', encoding="utf-8")
    code, _, err = run("run", program, "--config", config)
    assert code == 2 and "servo.kp" in err and "expected" in err and "Traceback" not in err, err
