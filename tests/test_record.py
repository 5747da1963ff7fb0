"""Recordings (issue 30, part 2): ``irl run --record FILE.mcap`` and ``irl serve --record
DIR`` write an MCAP file of JSON messages with their JSON schemas (runtime/recording.py
declares the topics); read back here with mcap's own readers and with
``runtime.recording.read_recording``. And ``irl plot``'s marks of faults and interrupt
firings, from the report's events file."""
from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from compiler.geometry import rpy_to_matrix
from runtime import recording
from runtime.recording import EVENTS, LEVELS, SCHEMAS, TOPICS, read_recording

from conftest import PROGRAMS, SPEC, SPEC_PATH, TEST_IRL, run_cli as run

jsonschema = pytest.importorskip("jsonschema")
mcap_reader = pytest.importorskip("mcap.reader")
from mcap.exceptions import EndOfFile  # noqa: E402 (after the skip: the view extra's library)

# a print at line 33 of configurations.irl: its moves' lines, lin moves and a configuration
CONFIGURATIONS = PROGRAMS / "configurations.irl"
PRINT_LINE = 33

# an interrupt that fires during the first move (in[5] rises 0.3 s into the program), then a
# run-time error at line 17
MARKS = """program marks;
system_specification "{spec}";
var
  n : integer;
  b : bool;

interrupt part when in[5] priority 1 continue;
seq
  print "part seen";
endseq
endinterrupt;

seq
  enable part;
  move ptp joint(mainjoint(10, -20, 20, 0, 40, 0)) speed_ptp := 0.5;
  n := 99;
  b := in[n];
endseq
endprogram;
"""


def messages(path: Path) -> tuple[object, dict[str, list]]:
    """(mcap's summary, {topic: [(log_time, publish_time, message)]}) read with mcap.reader.make_reader."""
    with open(path, "rb") as f:
        reader = mcap_reader.make_reader(f)
        summary = reader.get_summary()
        out: dict[str, list] = {}
        for _schema, channel, message in reader.iter_messages():
            out.setdefault(channel.topic, []).append((message.log_time, message.publish_time,
                                                      json.loads(message.data)))
    return summary, out


def seconds(stamp: dict) -> float:
    return stamp["sec"] + stamp["nsec"] * 1e-9


def rows_of(path: Path) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def configurations(tmp_path_factory) -> dict:
    """configurations.irl run with --report and --record (the simulated clock)."""
    d = tmp_path_factory.mktemp("record")
    code, out, err = run("run", CONFIGURATIONS, "--report", d / "r.csv", "--record", d / "r.mcap", "--json")
    assert code == 0, err
    summary, topics = messages(d / "r.mcap")
    return {"dir": d, "record": d / "r.mcap", "report": d / "r.csv", "run": json.loads(out), "summary": summary,
            "topics": topics}


def test_the_joint_states_are_the_reports_measured_positions_at_the_same_times(configurations):
    rows = rows_of(configurations["report"])
    joints = configurations["topics"]["/joint_states"]
    assert len(joints) == len(rows) > 1000  # every 10 ms, as the report's rows
    names = [a.name for a in SPEC.axes]
    for (log_time, publish_time, m), row in zip(joints, rows):
        t = seconds(m["timestamp"])
        assert log_time == publish_time == round(t * 1e9)
        assert t == pytest.approx(float(row["time"]), abs=1e-9)
        assert m["name"] == names and len(m["velocity"]) == len(names)
        assert np.allclose(m["position"], [float(row[f"sens_pos_{n}"]) for n in names], atol=1e-6, rtol=0)
    moving = [m for _l, _p, m in joints if max(map(abs, m["velocity"])) > 1.0]
    assert moving, "no velocity in the joint states"


def test_the_tcp_is_the_reports_in_meters_and_a_quaternion(configurations):
    rows = rows_of(configurations["report"])
    for (_l, _p, m), row in list(zip(configurations["topics"]["/tcp"], rows))[::97]:
        assert m["frame_id"] == "world"
        p, q = m["pose"]["position"], m["pose"]["orientation"]
        assert np.allclose([p["x"] * 1000, p["y"] * 1000, p["z"] * 1000],
                           [float(row[f"tcp_{c}"]) for c in "xyz"], atol=1e-5, rtol=0)
        w, x, y, z = q["w"], q["x"], q["y"], q["z"]
        assert w * w + x * x + y * y + z * z == pytest.approx(1.0, abs=1e-8)
        from_quaternion = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                                    [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                                    [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        report = np.array(rpy_to_matrix(*(float(row[f"tcp_{c}"]) for c in ("roll", "pitch", "yaw"))))
        assert np.allclose(from_quaternion, report, atol=1e-6), row["time"]


def test_every_topic_has_its_declared_schema_which_is_valid_json_schema_and_its_messages_follow_it(configurations):
    summary = configurations["summary"]
    channels = {c.topic: c for c in summary.channels.values()}
    assert [t.name for t in TOPICS] == list(channels)
    for topic in TOPICS:
        channel = channels[topic.name]
        schema = summary.schemas[channel.schema_id]
        assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
        assert schema.name == topic.schema
        declared = json.loads(schema.data)
        assert declared == SCHEMAS[topic.schema]
        jsonschema.Draft202012Validator.check_schema(declared)
        validator = jsonschema.Draft202012Validator(declared)
        sent = configurations["topics"].get(topic.name, [])
        for _l, _p, m in sent[:40] + sent[-40:]:
            validator.validate(m)
    # Foxglove's own schemas keep Foxglove's names, fields and time type
    assert SCHEMAS["foxglove.Log"]["properties"]["timestamp"]["title"] == "time"
    assert set(SCHEMAS["foxglove.FrameTransforms"]["properties"]["transforms"]["items"]["properties"]) == {
        "timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"}
    assert summary.statistics.message_count == sum(len(v) for v in configurations["topics"].values())


def test_the_phases_are_named_as_the_reports_state_column_at_the_transitions(configurations):
    phases = [(seconds(m["timestamp"]), m["state"], m["phase"], m["step"])
              for _l, _p, m in configurations["topics"]["/phase"]]
    assert [state for _t, state, _p, _s in phases] == [
        "Start Robot", "Calibrate Offsets", "Initialization Sequence", "Initialization Sequence/Find Sensors",
        "Initialization Sequence/Find Index", "Initialization Sequence/Go To Start", "Move Robot", "Stop Robot"]
    for _t, state, phase, step in phases:
        assert f"{phase}/{step}" == state if step else phase == state
    transitions = [(float(r["time"]), r["to"]) for r in rows_of(configurations["report"].with_suffix(".states.csv"))]
    top = [(t, state) for t, state, _p, step in phases if not step]
    assert [s for _t, s in top] == [s for _t, s in transitions]
    assert np.allclose([t for t, _s in top], [t for t, _s in transitions], atol=1e-6)
    rows = rows_of(configurations["report"])  # each homing step from the report's first row in it
    for t, state, _p, step in phases:
        if step:
            assert next(float(r["time"]) for r in rows if r["state"] == state) == pytest.approx(t, abs=1e-9)


def test_a_print_is_an_info_log_at_its_line_and_time_and_the_lines_are_the_programs(configurations):
    logs = [m for _l, _p, m in configurations["topics"]["/log"]]
    printed = configurations["run"]["log"]
    assert [(m["message"], m["name"], m["level"], m["line"], m["file"]) for m in logs] == [
        ("configuration config(flip) kept", "print", LEVELS["INFO"], PRINT_LINE, "configurations.irl")]
    assert seconds(logs[0]["timestamp"]) == pytest.approx(printed[0]["time"], abs=1e-9)
    lines = {m["line"] for _l, _p, m in configurations["topics"]["/line"]}
    assert {m["line"] for m in configurations["run"]["moves"]} | {PRINT_LINE} <= lines
    assert {m["file"] for _l, _p, m in configurations["topics"]["/line"] if m["line"]} == {"configurations.irl"}
    frames = [m for _l, _p, m in configurations["topics"]["/frames"]]
    assert [(m["tool"], m["base"]) for m in frames] == [("default_tool", "world")]
    io = [m for _l, _p, m in configurations["topics"]["/io"]]
    assert len(io) == 1 and io[0]["inputs"] == [False] * SPEC.inputs and len(io[0]["outputs"]) == SPEC.outputs


def test_the_links_are_the_urdfs_and_compose_to_the_forward_kinematics(configurations):
    """/tf: every link of irl urdf's URDF in its parent, every row; composed from world they
    give the kinematics' flange and TCP at the recorded joints; /robot_description embeds
    that URDF."""
    import base64
    import xml.etree.ElementTree as ET

    from runtime.motion.kinematics import Kinematics
    from runtime.motion.urdf import urdf_text

    urdf = urdf_text(SPEC)
    (_l, _p, description), = configurations["topics"]["/robot_description"]
    assert description["format"] == "urdf" and base64.b64decode(description["data"]).decode() == urdf
    links = {link.get("name") for link in ET.fromstring(urdf).iter("link")}
    joints = {(j.find("parent").get("link"), j.find("child").get("link")) for j in ET.fromstring(urdf).iter("joint")}
    tf = configurations["topics"]["/tf"]
    assert len(tf) == len(configurations["topics"]["/joint_states"])
    for _l, _p, m in tf[:3]:
        assert {(t["parent_frame_id"], t["child_frame_id"]) for t in m["transforms"]} == joints
    r = read_recording(configurations["record"], links=True)
    assert set(r["links"]) | {"world"} == links
    kinematics = Kinematics(SPEC)
    for k in (0, len(r["times"]) // 2, len(r["times"]) - 1):
        def world(link: str) -> np.ndarray:
            parent, m = r["links"][link]
            return m[k] if parent == "world" else world(parent) @ m[k]
        frames = kinematics.frames(r["joints"][k])
        assert np.allclose(world("flange"), np.array(frames[5]), atol=1e-5)
        assert np.allclose(world("tcp"), np.array(kinematics.forward_matrix(r["joints"][k])), atol=1e-5)
        assert np.allclose(world("tcp")[:3, 3], r["tcp"][k], atol=1e-5)


def test_read_recording_gives_arrays_in_the_languages_units(configurations):
    r = read_recording(configurations["record"])
    assert r["complete"] and r["metadata"]["program"] == "configurations" and r["metadata"]["robot"] == SPEC.name
    assert json.loads(r["metadata"]["units"]) == ["deg"] * 6 and r["names"] == [a.name for a in SPEC.axes]
    rows = rows_of(configurations["report"])
    assert r["joints"].shape == (len(rows), 6) and r["times"].shape == (len(rows),)
    assert np.allclose(r["joints"][-1], [float(rows[-1][f"sens_pos_A{k}"]) for k in range(1, 7)], atol=1e-6)
    assert np.allclose(r["tcp"][-1], [float(rows[-1][f"tcp_{c}"]) for c in "xyz"], atol=1e-5)
    assert r["tcp_rotation"].shape == (len(rows), 4)
    assert [p[1] for p in r["phases"]][-2:] == ["Move Robot", "Stop Robot"]
    assert r["logs"][0]["level"] == "INFO" and r["logs"][0]["kind"] == "print"


def test_a_recording_cut_short_is_read_to_its_last_whole_chunk(configurations, tmp_path):
    """A crash leaves no footer (nor the last chunk): mcap's non-seeking reader and
    read_recording read what is there."""
    whole = read_recording(configurations["record"])
    cut = tmp_path / "cut.mcap"
    data = configurations["record"].read_bytes()
    cut.write_bytes(data[:len(data) * 2 // 3])
    with open(cut, "rb") as f:
        seen = []
        with pytest.raises(EndOfFile):  # (the end: a record cut in its middle)
            for _schema, channel, _message in mcap_reader.NonSeekingReader(f).iter_messages(log_time_order=False):
                seen.append(channel.topic)
    assert seen.count("/joint_states") > 100
    r = read_recording(cut)
    assert not r["complete"] and 100 < len(r["times"]) < len(whole["times"])
    assert np.array_equal(r["times"], whole["times"][:len(r["times"])])
    with pytest.raises(recording.RecordingError, match="not an MCAP recording"):
        read_recording(configurations["report"])


def test_a_fault_is_an_error_log_and_the_stop_a_warning(tmp_path):
    code, out, err = run("run", TEST_IRL, "--max-time", "1", "--record", tmp_path / "f.mcap", "--json")
    assert code == 1, err
    fault = json.loads(out)["fault"]
    r = read_recording(tmp_path / "f.mcap")
    assert r["complete"]
    assert [(e["kind"], e["level"], e["text"]) for e in r["logs"]] == [
        ("fault", "ERROR", fault),
        ("stop", "WARNING", "safety stop of category 1 (fault): every axis ramped to rest at its max_acceleration, "
                            "then brakes, then torque off")]
    assert r["logs"][0]["time"] == pytest.approx(1.0, abs=1e-9)
    assert r["phases"][-1][1] == "Stop Robot" and r["times"][-1] > 1.0


def test_an_interrupt_and_a_fault_are_in_the_recording_the_events_file_and_marked_on_the_plot(tmp_path):
    from runtime.cli import plot

    program = tmp_path / "marks.irl"
    program.write_text(MARKS.format(spec=SPEC_PATH), encoding="utf-8")
    cell = tmp_path / "cell.toml"
    cell.write_text("[[timeline]]\ninput = 5\nat = [0.3]\n", encoding="utf-8")
    report = tmp_path / "r.csv"
    code, out, err = run("run", program, "--cell-scenario", cell, "--report", report, "--record", tmp_path / "r.mcap",
                         "--json")
    assert code == 1, err
    summary = json.loads(out)
    fired = next(e for e in summary["log"] if e["kind"] == "interrupt")
    assert "line 17" in summary["fault"]
    events = plot.read_events(report)
    assert [kind for _t, kind, _l, _x in events] == ["interrupt", "print", "fault", "stop"]
    marks = plot.event_marks(events)
    assert [(kind, label) for _t, kind, label in marks] == [("interrupt", "interrupt part (L15)"), ("fault", "FAULT (L17)")]
    assert marks[0][0] == pytest.approx(fired["time"], abs=1e-3) and marks[1][0] > marks[0][0]
    logs = read_recording(tmp_path / "r.mcap")["logs"]
    assert [(e["kind"], e["level"]) for e in logs] == [("interrupt", "INFO"), ("print", "INFO"), ("fault", "ERROR"),
                                                       ("stop", "WARNING")]
    assert [e["time"] for e in logs[:3]] == pytest.approx([t for t, _k, _l, _x in events[:3]], abs=1e-3)
    figure = plot.figure(report)  # every panel has a line at each mark, in the mark's colour
    try:
        for ax in [a for a in figure.axes if a.get_xlabel() == "time (s)" or a.get_ylabel().endswith("(deg)")]:
            lines = {(round(line.get_xdata()[0], 3), line.get_color()) for line in ax.get_lines()
                     if len(set(line.get_xdata())) == 1}
            for t, kind, _label in marks:
                assert (round(t, 3), plot.MARKED[kind][0]) in lines, (ax.get_ylabel(), kind)
        texts = [t.get_text() for t in figure.axes[0].texts] + [t.get_text() for t in figure.texts]
        assert any("interrupt part (L15)" in t for t in texts) and any(summary["fault"] in t for t in texts)
    finally:
        import matplotlib.pyplot as plt

        plt.close(figure)


def test_a_recording_that_cannot_be_written_is_said_and_the_run_goes_on(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code, out, err = run("run", TEST_IRL, "--max-time", "0.5", "--record", blocker / "r.mcap", "--report",
                         tmp_path / "r.csv", "--json")
    summary = json.loads(out)
    assert code == 1 and "Traceback" not in err
    assert summary["files_error"].startswith(f"cannot write the recording {blocker / 'r.mcap'}")
    assert rows_of(tmp_path / "r.csv")  # the report is written all the same


def test_record_without_the_mcap_library_is_a_usage_error(tmp_path, monkeypatch):
    monkeypatch.setattr(recording, "missing", lambda: recording.INSTALL)
    code, _out, err = run("run", TEST_IRL, "--record", tmp_path / "r.mcap")
    assert code == 2 and "pip install 'irl[view]'" in err and not (tmp_path / "r.mcap").exists()


def test_events_a_full_queue_did_not_take_come_with_the_next_batch():
    """Nothing is lost silently: a batch the writer's queue cannot take is counted (rows)
    or handed over with the next one (transitions, events)."""
    import queue

    from runtime.loop.batches import Batches

    class Source:
        def __init__(self):
            self.events = [[(0.01, "print", 3, "a")], [(0.02, "print", 4, "b")]]

        def take(self):
            return self.events.pop(0) if self.events else []

        def keep(self, events):
            self.events.insert(0, events)

        def reset(self):
            pass

    class Writer:
        def __init__(self):
            self.queue = queue.Queue(maxsize=1)

        def start(self):
            pass

    history = [(0.0, None, "Start Robot")]
    batches = Batches(lambda: history, Source())
    writer = Writer()
    batches.open(writer, 0.05)  # two rows a batch
    batches.append((0.0,))
    batches.append((0.05,))
    assert writer.queue.get_nowait() == ([(0.0,), (0.05,)], history, [(0.01, "print", 3, "a")])
    writer.queue.put_nowait("full")
    batches.append((0.1,))
    batches.append((0.15,))  # not taken: the rows counted, the transitions and events kept
    assert batches.dropped == 2
    writer.queue.get_nowait()
    batches.append((0.2,))
    batches.append((0.25,))
    assert writer.queue.get_nowait() == ([(0.2,), (0.25,)], (), [(0.02, "print", 4, "b")])


def test_irl_serve_records_each_program_in_a_file_named_by_its_id_and_name(tmp_path):
    from compiler.driver import compile_source
    from compiler.objcode import encode
    from runtime.server.server import ServeOptions, Server

    programs = []
    for name in ("first", "second"):
        result = compile_source(f'program {name};\nsystem_specification "{SPEC_PATH}";\nseq\n  print "{name}";\n'
                                'endseq\nendprogram;\n', f"{name}.irl")
        assert result.ok, result.diagnostics
        programs.append(encode(result.program))
    server = Server(SPEC, ServeOptions(sim_clock=True, state_dir=tmp_path / "state", loop_process=False,
                                       record=tmp_path / "rec"))
    try:
        jobs = [server.request("submit", {"object": data})["program"] for data in programs]
        while server.jobs.current is not None or server.jobs.queue:
            server.turn(idle_wait=False)
        paths = [Path(server.request("status", {"program": job})["record"]) for job in jobs]
    finally:
        server.close()
    assert sorted(p.name for p in (tmp_path / "rec").iterdir()) == sorted(p.name for p in paths)
    for job, name, path in zip(jobs, ("first", "second"), paths):
        assert path.name.endswith(f"-program-{job}-{name}.mcap")
        r = read_recording(path)
        assert r["complete"] and r["metadata"]["job"] == str(job) and r["metadata"]["program"] == name
        assert [e["text"] for e in r["logs"]] == [name]
    first, second = (read_recording(p) for p in paths)
    assert second["times"][0] > first["times"][-1]  # the server's clock runs on: each file its own program
    assert "Initialization Sequence" in [s for _t, s in first["phases"]]
    assert "Initialization Sequence" not in [s for _t, s in second["phases"]]  # (homed once, by the first)


def test_the_tables_name_every_schema_and_every_event_kind_a_level():
    assert {t.schema for t in TOPICS} == set(SCHEMAS)
    assert all(level in LEVELS for level, _what in EVENTS.values())
    assert recording.recording_name("20250101-120000-42", 3, "pick place/ü") == \
        "20250101-120000-42-program-3-pick_place.mcap"
    assert recording.recording_name("s", 4, "cell.irl").endswith("-program-4-cell.mcap")
    assert recording.recording_name("s", 5, "../..").endswith("-program-5-program.mcap")
    markdown = recording.topics_markdown()
    assert all(f"`{t.name}`" in markdown for t in TOPICS)


def test_the_analog_channels_are_recorded_at_the_start_and_on_each_change(tmp_path):
    """A robot with analog channels (lola15_cell.spc: the part's height in, the glue's pressure
    out): /io/analog at the start and where the program sets the output, in their units, as
    its schema says; the metadata names each channel and its unit; read_recording gives them."""
    shutil.copy(PROGRAMS / "lola15_cell.spc", tmp_path / "cell.spc")
    program = tmp_path / "glue.irl"
    program.write_text('program glue;\nsystem_specification "cell.spc";\nseq\n  wait 0.2 sec;\n'
                       "  call analog_out(1, 3.5);\n  wait 0.2 sec;\n  call analog_out(1, 0);\nendseq\nendprogram;\n",
                       encoding="utf-8")
    code, out, err = run("run", program, "--record", tmp_path / "r.mcap")
    assert code == 0, err
    summary, topics = messages(tmp_path / "r.mcap")
    validator = jsonschema.Draft202012Validator(SCHEMAS["irl.AnalogIO"])
    sent = [m for _l, _p, m in topics["/io/analog"]]
    for m in sent:
        validator.validate(m)
    assert [(m["inputs"], m["outputs"]) for m in sent] == [([50.0], [0.0]), ([50.0], [3.5]), ([50.0], [0.0])]
    recorded = read_recording(tmp_path / "r.mcap")
    assert json.loads(recorded["metadata"]["analog_outputs"]) == [["glue pressure", "bar"]]
    times = recorded["analog"]["times"]
    assert recorded["analog"]["outputs"][:, 0].tolist() == [0.0, 3.5, 0.0]
    assert times[2] - times[1] == pytest.approx(0.2, abs=0.011)  # (the 10 ms rows)
