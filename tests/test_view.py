"""``irl view`` without a browser (tests/test_view_browser.py opens the page): what it is
given to draw (a program's trace from the offline planners, a report read back), its
usage errors, and the protocol's ``source`` operation it reads a served program's lines from."""
from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from compiler.driver import compile_file
from runtime.loop.offline import check_motion
from compiler.spec import load_spec
from runtime.view.replay import ReplayError, read_recorded, read_report
from runtime.view.stage import source_html, timeline_html
from tests.conftest import ROOT, SPEC_PATH, no_traceback, objcode, run_irl

FIRST_HOUR = ROOT / "tests" / "motion_check" / "first_hour.irl"


def test_the_trace_is_the_planned_motion_and_marks_refused_moves():
    """The paths drawn are the setpoints of irl check's run: every 5 ms, within the axis
    limits, each sample of a move; a refused move is the PTP move standing in for it, on
    the refused move's line."""
    result = compile_file(FIRST_HOUR)
    outcome = check_motion(result.program, result.spec, trace=True)
    trace = outcome.trace
    assert len(trace.times) == len(trace.joints) == len(trace.move) > 100
    steps = {round(b - a, 6) for a, b in zip(trace.times, trace.times[1:])}
    assert steps == {0.005}
    for joints in trace.joints[::25]:
        for axis, v in zip(result.spec.axes, joints):
            assert axis.min - 1e-9 <= v <= axis.max + 1e-9
    assert trace.move == sorted(trace.move) and trace.move[-1] == len(trace.records)
    refused_lines = {f.line for f in outcome.findings if f.kind == "move"}
    assert trace.stand_in and {trace.records[k - 1].line for k in trace.stand_in} <= refused_lines
    assert all(trace.records[k - 1].kind == "ptp" for k in trace.stand_in)
    # the same outcome as irl check's own run (the trace only adds what it saw)
    plain = check_motion(result.program, result.spec)
    assert [(f.line, f.message) for f in plain.findings] == [(f.line, f.message) for f in outcome.findings]
    assert plain.cycle_time == pytest.approx(outcome.cycle_time, abs=1e-9)


def test_a_report_and_a_recording_read_back_for_replay(tmp_path):
    """The same run replayed from its report and from its recording: the same joints at
    the same times, the same phases and lines."""
    report, recording = tmp_path / "test.csv", tmp_path / "test.mcap"
    done = run_irl("run", "programs/test.irl", "--report", report, "--report-columns", "+move,io",
                   "--record", recording)
    assert done.returncode == 0, done.stderr
    spec_axes = ["A1", "A2", "A3", "A4", "A5", "A6"]
    rec = read_report(report, spec_axes)
    spec = load_spec(SPEC_PATH)
    recorded = read_recorded(recording, spec)
    at = {round(t, 3): (j, line) for t, j, line in zip(recorded.times, recorded.joints, recorded.lines)}
    same = [(at[round(t, 3)], (j, line)) for t, j, line in zip(rec.times, rec.joints, rec.lines) if round(t, 3) in at]
    assert len(same) >= len(rec.times) - 1
    for (j1, line1), (j2, line2) in same:
        assert j1 == pytest.approx(j2, abs=1e-6)
        assert line1 == line2 or line2 == 0  # (the report's is the line of a move under way: 0 between moves)
    assert [p[1] for p in recorded.phases if "/" not in p[1]][1:3] == ["Calibrate Offsets", "Initialization Sequence"]
    from runtime.cli.viewing import recorded_spec  # (irl view FILE.mcap needs no --spec where the file is)

    assert Path(recorded_spec(recording)).resolve() == SPEC_PATH.resolve()
    other = tmp_path / "other.spc"
    other.write_text(SPEC_PATH.read_text(encoding="utf-8").replace("max_speed = 2000.0", "max_speed = 1999.0"))
    with pytest.raises(ReplayError, match="give its --spec"):
        read_recorded(recording, load_spec(other))
    assert len(rec.times) == len(rec.joints) == len(rec.lines) > 1000
    assert [p[1].split("/")[0] for p in rec.phases][:2] == ["Calibrate Offsets", "Initialization Sequence"]
    assert rec.phases[-1][1].startswith("Stop Robot")
    assert {4, 5, 6} <= set(rec.lines)
    assert rec.joints[-1] == pytest.approx((45.0, -45.0, 45.0, 0.0, 0.0, 0.0), abs=1e-3)
    assert rec.inputs is not None and len(rec.inputs[0]) == 16


@pytest.mark.parametrize("text, said", [
    ("", "empty"),
    ("time,state,sens_pos_A1\n", "no column sens_pos_A2"),
    ("time,state," + ",".join(f"sens_pos_A{i}" for i in range(1, 7)) + "\n", "no rows"),
    ("time,state," + ",".join(f"sens_pos_A{i}" for i in range(1, 7)) + "\n0.01,Move Robot,1,2,x,4,5,6\n",
     "line 2"),
])
def test_a_bad_report_is_said(tmp_path, text, said):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ReplayError, match=said):
        read_report(path, ["A1", "A2", "A3", "A4", "A5", "A6"])


@pytest.mark.parametrize("args, said", [
    ([], "give a file"),
    (["programs/test.irl", "--endpoint", "tcp://127.0.0.1:1"], "one of the two"),
    (["README.md"], "expected a program"),
    (["nothing.irl"], "no such file"),
    (["programs/lola15.toml"], "expected a program"),
    (["--endpoint", "tcp://127.0.0.1:1", "--cell-scenario", "programs/cell.toml"], "not a live view"),
    (["programs/test.irl", "--port", "0"], "--port 0"),
])
def test_usage_errors(args, said):
    done = run_irl("view", *args)
    no_traceback(done)
    assert done.returncode == 2, done
    assert said in done.stderr


def test_a_report_needs_its_robot_and_a_bad_one_is_said(tmp_path):
    bad = tmp_path / "r.csv"
    bad.write_text("time,state\n")
    done = run_irl("view", bad)
    assert done.returncode == 2 and "--spec" in done.stderr
    done = run_irl("view", bad, "--spec", SPEC_PATH)
    no_traceback(done)
    assert done.returncode == 2 and "not a report of this robot" in done.stderr


def test_no_server_there_is_said():
    done = run_irl("view", "--endpoint", "tcp://127.0.0.1:9", "--telemetry", "tcp://127.0.0.1:10")
    no_traceback(done)
    assert done.returncode == 2 and "no reply" in done.stderr


def test_the_source_a_program_was_submitted_with(start_server):
    """The ``source`` operation (protocol 2): the text sent with ``submit``, or nil."""
    server = start_server()
    client = server.client()
    text = (ROOT / "programs" / "test.irl").read_text(encoding="utf-8")
    with_text = client.request("submit", {"object": objcode(ROOT / "programs" / "test.irl"), "source": text})
    without = client.request("submit", {"object": objcode(ROOT / "programs" / "test.irl")})
    assert client.request("source", {"program": with_text["program"]})["source"] == text
    assert client.request("source", {"program": without["program"]})["source"] is None
    from runtime.client.client import ClientError

    with pytest.raises(ClientError) as err:
        client.request("source", {"program": 99})
    assert err.value.code == "not_found"
    hello = client.request("hello")
    assert Path(hello["spec_file"]).resolve() == SPEC_PATH.resolve()


def test_irl_submit_sends_the_source(start_server, tmp_path):
    server = start_server()
    done = run_irl("submit", "programs/test.irl", "--endpoint", server.endpoint)
    assert done.returncode == 0, done.stderr
    client = server.client()
    assert "move ptp" in client.request("source", {"program": 1})["source"]


def test_the_panel_pieces():
    lines = [f"line {n}" for n in range(1, 41)]
    page = source_html(lines, 30, "p.irl", {12: "#fcc"})
    assert 'id="current-line"' in page and 'data-line="30"' in page and "line 30" in page
    assert 'data-line="12"' not in page  # (out of the window around line 30)
    assert "&lt;b&gt;" in source_html(["<b>"], 1)  # the program's text is escaped
    bands = timeline_html([(0.0, "Start Robot"), (0.05, "Calibrate Offsets"), (0.35, "Initialization Sequence/Home"),
                           (1.0, "Initialization Sequence/Check"), (9.0, "Move Robot")], 0.0, 20.0, 10.0)
    assert bands.count('class="phase"') == 4  # the top-level phases, each once


def test_quick_marks_each_reach_a_page_that_gets_only_the_latest_update():
    # a transport (viser's message buffer) sends a slow page only the latest content of a box:
    # the box names the last marks shown, so a page learns every line passed, in order
    import re
    from types import SimpleNamespace

    from runtime.view import live as live_view

    class Box(SimpleNamespace):
        content = ""

    gui = SimpleNamespace(add_markdown=lambda *_: Box(), add_html=lambda *_: Box())
    stage = SimpleNamespace(server=SimpleNamespace(gui=gui), spec=SimpleNamespace(inputs=2, outputs=2))
    view = live_view.LiveView(stage, "tcp://x", "tcp://y")
    view.program, view.name, view.lines = 7, "p.irl", [f"line {n}" for n in range(1, 11)]
    now = 100.0
    for line in (4, 5, 6):  # three moves, quicker than a page is updated
        view.marks.append((7, line))
        view._show_mark(now)
        now += live_view.MARK_HOLD
    last = view.source_box.content
    trail = re.search(r'data-trail="([^"]*)"', last).group(1)
    assert [int(item.split(":")[1]) for item in trail.split()] == [4, 5, 6]
    assert 'id="current-line"' in last and 'data-line="6" id="current-line"' in last
    view.marks.append((None, None))  # the program ended: a new trail
    view._show_mark(now)
    assert re.search(r'data-trail="([^"]*)"', view.source_box.content).group(1).endswith(":0")


def _small_report(tmp_path_factory) -> str:
    """A real report's first rows, as text (made once)."""
    global _REPORT
    if _REPORT is None:
        path = tmp_path_factory.mktemp("report") / "r.csv"
        done = run_irl("run", "programs/test.irl", "--report", path, "--report-columns", "sens_pos,move,io")
        assert done.returncode == 0, done.stderr
        _REPORT = "".join(path.read_text(encoding="utf-8").splitlines(keepends=True)[:40])
    return _REPORT


_REPORT = None
_EDITS = st.tuples(st.integers(0, 10_000), st.integers(0, 40), st.sampled_from(
    ["", ",", "\n", "nan", "-inf", "1e999", "x", '"', "\r", "-", "9", ",,", "\x00", "é"]))


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(edits=st.lists(_EDITS, min_size=1, max_size=4))
def test_any_report_is_replayed_or_refused_with_the_reason(tmp_path_factory, edits):
    """Every input is untrusted: a report cut, spliced and garbled anywhere is replayed
    with finite joints at times that never go back, or refused with a ReplayError that
    says where; nothing else (no traceback)."""
    text = _small_report(tmp_path_factory)
    for at, cut, put in edits:
        at %= len(text) + 1
        text = text[:at] + put + text[at + cut:]
    path = tmp_path_factory.mktemp("bad") / "r.csv"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        rec = read_report(path, ["A1", "A2", "A3", "A4", "A5", "A6"])
    except ReplayError as exc:
        assert str(path) in str(exc)
        return
    assert rec.times == sorted(rec.times) and all(math.isfinite(t) for t in rec.times)
    assert all(math.isfinite(v) for joints in rec.joints for v in joints)
    assert len(rec.joints) == len(rec.times) and all(len(j) == 6 for j in rec.joints)


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=400))
def test_any_file_named_mcap_is_refused_with_the_reason(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("bad") / "r.mcap"
    path.write_bytes(b"\x89MCAP0\r\n" + data if data[:1] == b"M" else data)
    with pytest.raises(ReplayError):
        read_recorded(path, load_spec(SPEC_PATH))


def test_the_stage_draws_the_world_zones_where_they_are():
    """The cell's zones (lola15_cell.spc: a box and a cylinder) and a program's own (a
    signal box): each drawn once, at its place and size (m), forbidden red, signal amber;
    tests/test_view_browser.py looks at the page itself."""
    from compiler.zones import Zone
    from runtime.view.stage import ZONE_COLOURS, Stage
    from tests.conftest import free_port

    stage = Stage(load_spec(ROOT / "programs" / "lola15_cell.spc"), free_port())
    try:
        assert set(stage.zones) == {"fixture body", "guard post"}
        body = stage.zones["fixture body"]
        assert tuple(body.dimensions) == pytest.approx((0.14, 0.14, 0.32)) and \
            tuple(body.position) == pytest.approx((0.9, 0.3, 0.16))
        post = stage.zones["guard post"]
        assert (post.radius, post.height) == pytest.approx((0.06, 2.2)) and \
            tuple(post.position) == pytest.approx((1.0, 0.7, 1.1))
        belt = Zone("belt", "box", (300.0, -600.0, 0.0), (900.0, -200.0, 1500.0), kind="signal", output=6)
        stage.show_zones((belt, belt))
        assert set(stage.zones) == {"fixture body", "guard post", "belt"}
        assert tuple(stage.zones["belt"].color) == ZONE_COLOURS["signal"]
        assert tuple(body.color) == ZONE_COLOURS["forbidden"]
    finally:
        stage.close()
