"""``irl plot`` shows the homing steps and where each move starts (issue 16, item 3); the
report's optional ``move`` columns it draws them from (``report.columns``, ``irl run
--report-columns``)."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from runtime.cli.main import Environment

from conftest import TEST_IRL, SPEC_PATH as SPEC, run_cli as run
DEFAULT_GROUPS = ["sens_pos", "desi_pos", "out_vel", "following_error", "tcp"]

# three moves, at lines 4, 6 and 7; a dwell between the first two (no move under way)
THREE_MOVES = """program three;
system_specification "{spec}";
seq
  move ptp joint(mainjoint(10, -20, 20, 0, 40, 0)) speed_ptp := 0.5;
  wait 0.3 sec;
  move ptp joint(mainjoint(-10, -20, 20, 0, 40, 0)) speed_ptp := 0.5;
  move ptp joint(mainjoint(-10, -30, 30, 0, 50, 0)) speed_ptp := 0.5;
endseq
endprogram;
"""
LINES = [4, 6, 7]


def moves_of(program: Path) -> list[dict]:
    """The program's moves as they ran (line, t_start, t_end), from a run in-process (the
    simulated clock: the same times as irl run's)."""
    from runtime.cli.main import _load_program
    from runtime.loop.system import RobotSystem, RunOptions

    compiled, spec = _load_program(str(program), None, Environment())
    system = RobotSystem(spec, RunOptions())
    assert system.run(compiled)["fault"] is None
    return [{"line": m.line, "t_start": m.t_start, "t_end": m.t_end} for m in system.trajectory.moves]


def rows_of(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


@pytest.fixture(scope="module")
def three(tmp_path_factory) -> dict:
    """THREE_MOVES run with the move columns: the report, its rows and the summary."""
    d = tmp_path_factory.mktemp("three")
    program = d / "three.irl"
    program.write_text(THREE_MOVES.format(spec=SPEC), encoding="utf-8")
    code, out, err = run("run", program, "--report", d / "r.csv", "--report-columns", "+move", "--json")
    assert code == 0, err
    header, rows = rows_of(d / "r.csv")
    return {"report": d / "r.csv", "header": header, "rows": rows, "summary": json.loads(out),
            "moves": moves_of(program)}


@pytest.fixture(scope="module")
def paper(tmp_path_factory) -> dict:
    """programs/test.irl (the paper's program) with the default columns and with +move."""
    d = tmp_path_factory.mktemp("paper")
    code, _, err = run("run", TEST_IRL, "--report", d / "default.csv")
    assert code == 0, err
    code, out, err = run("run", TEST_IRL, "--report", d / "moves.csv", "--report-columns", "+move", "--json")
    assert code == 0, err
    return {"default": d / "default.csv", "moves": d / "moves.csv", "summary": json.loads(out),
            "records": moves_of(TEST_IRL)}


# ---- the report's move columns ------------------------------------------------------------------

def test_the_default_report_has_no_move_columns_and_adding_them_changes_nothing_else(paper):
    header, rows = rows_of(paper["default"])
    assert "move" not in header and "line" not in header
    moves_header, moves_rows = rows_of(paper["moves"])
    assert moves_header == header + ["move", "line"]  # after the default groups
    assert [r[:-2] for r in moves_rows] == rows  # the same rows, byte for byte, before them
    # the paper's program: three moves, lines 4, 5, 6
    starts = [(int(r[-2]), int(r[-1])) for a, r in zip(moves_rows, moves_rows[1:]) if r[-2] != a[-2]]
    assert starts == [(1, 4), (2, 5), (3, 6)]


def test_the_move_columns_count_the_moves_and_name_their_lines(three):
    header, rows, summary, moves = three["header"], three["rows"], three["summary"], three["moves"]
    assert header[-2:] == ["move", "line"]
    i = header.index("move")
    assert all(r[i].isdigit() and r[i + 1].isdigit() for r in rows)  # integers (%d)
    move = [int(r[i]) for r in rows]
    line = [int(r[i + 1]) for r in rows]
    times = [float(r[0]) for r in rows]
    assert move == sorted(move) and sorted(set(move)) == [0, 1, 2, 3]  # up by one at each start
    assert all(n == 0 for n, r in zip(move, rows) if r[1].split("/")[0] != "Move Robot" and r[1] != "Stop Robot")
    assert [m["line"] for m in summary["moves"]] == [m["line"] for m in moves] == LINES
    for number, m in enumerate(moves, start=1):
        during = [k for k, t in enumerate(times) if m["t_start"] + 0.011 <= t <= m["t_end"] - 0.011]
        assert during and all(move[k] == number and line[k] == m["line"] for k in during), number
        first = move.index(number)  # the first row of the move: within a row of its first setpoint
        assert m["t_start"] <= times[first] < m["t_start"] + 0.011 + 1e-9, (number, times[first], m)
    # the dwell between the first two moves: the first move's number, no move under way
    dwell = [k for k, t in enumerate(times)
             if moves[0]["t_end"] + 0.011 <= t <= moves[1]["t_start"] - 0.011]
    assert len(dwell) >= 20 and all(move[k] == 1 and line[k] == 0 for k in dwell)
    # after the last move: its number, line 0
    assert move[-1] == 3 and line[-1] == 0


def test_the_move_columns_from_a_configuration(tmp_path):
    """report.columns with "move" (as irl serve --config sets it): the same columns."""
    from runtime.cli.main import _load_program
    from runtime.config import validate_settings
    from runtime.loop.system import RobotSystem, RunOptions

    program = tmp_path / "three.irl"
    program.write_text(THREE_MOVES.format(spec=SPEC), encoding="utf-8")
    settings = validate_settings({"report": {"columns": ["sens_pos", "move"]}}, "t.toml")
    loaded = _load_program(str(program), None, Environment())
    assert loaded is not None
    compiled, spec = loaded
    system = RobotSystem(spec, RunOptions(report=tmp_path / "r.csv"))
    system.apply_settings(settings)
    summary = system.run(compiled)
    assert summary["fault"] is None
    header, rows = rows_of(tmp_path / "r.csv")
    assert header == ["time", "state"] + [f"sens_pos_A{n}" for n in range(1, 7)] + ["move", "line"]
    assert sorted({(int(r[-2]), int(r[-1])) for r in rows if r[-1] != "0"}) == [(1, 4), (2, 6), (3, 7)]


@pytest.mark.parametrize("value, message", [
    ("+mov", "--report-columns +mov: unknown column 'mov' (did you mean 'move'?)"),
    ("", "--report-columns : expected a non-empty list of distinct names"),
    ("move,sens_pos,move", "--report-columns move,sens_pos,move: duplicate column 'move'"),
])
def test_bad_report_columns_are_usage_errors(tmp_path, value, message):
    code, _, err = run("run", TEST_IRL, "--report", tmp_path / "r.csv", "--report-columns", value)
    assert code == 2 and message in err, err
    assert not (tmp_path / "r.csv").exists()  # refused before running


def test_report_columns_need_a_report(tmp_path):
    code, _, err = run("run", TEST_IRL, "--report-columns", "+move")
    assert code == 2 and "--report-columns needs --report" in err, err


def test_a_report_columns_list_replaces_the_default_in_its_order(tmp_path):
    program = tmp_path / "three.irl"
    program.write_text(THREE_MOVES.format(spec=SPEC), encoding="utf-8")
    code, _, err = run("run", program, "--report", tmp_path / "r.csv", "--report-columns", "move,out_vel")
    assert code == 0, err
    header, _ = rows_of(tmp_path / "r.csv")
    assert header == ["time", "state", "move", "line"] + [f"out_vel_A{n}" for n in range(1, 7)]


# ---- what the plot draws ------------------------------------------------------------------------

def test_homing_steps_of_the_paper_program_span_its_initialization(paper):
    from runtime.cli.plot import homing_steps, phases, read_report, read_transitions

    times, states, _ = read_report(paper["default"])
    steps = homing_steps(times, states)
    assert [name for _t0, _t1, name in steps] == ["Find Sensors", "Find Index", "Go To Start"]
    init = next(p for p in phases(times, states, read_transitions(paper["default"]))
                if p[2] == "Initialization Sequence")
    assert steps[0][0] == pytest.approx(init[0], abs=0.0105)
    assert steps[-1][1] == pytest.approx(init[1], abs=0.0105)
    assert all(a[1] == b[0] for a, b in zip(steps, steps[1:]))  # one after another, no gap
    assert all(t0 < t1 for t0, t1, _ in steps)


def test_homing_steps_from_rows():
    from runtime.cli.plot import homing_steps

    times = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]
    states = ["Calibrate Offsets", "Initialization Sequence/Find Sensors", "Initialization Sequence/Find Sensors",
              "Initialization Sequence/Find Index", "Initialization Sequence", "Initialization Sequence/Go To Start",
              "Move Robot", "Move Robot"]
    assert homing_steps(times, states) == [(0.1, 0.3, "Find Sensors"), (0.3, 0.4, "Find Index"),
                                           (0.5, 0.6, "Go To Start")]
    assert homing_steps(times[:3], states[:3]) == [(0.1, 0.2, "Find Sensors")]  # open at the end: the last row
    assert homing_steps(times, ["Move Robot"] * len(times)) == []


def test_move_starts_from_the_move_columns(paper):
    import numpy as np

    from runtime.cli.plot import move_starts, read_report

    times, _, cols = read_report(paper["moves"])
    starts = move_starts(times, cols)
    moves = paper["records"]
    assert [(n, line) for _t, n, line in starts] == [(k, m["line"]) for k, m in enumerate(moves, start=1)]
    for (t, _n, _line), m in zip(starts, moves):
        assert m["t_start"] <= t < m["t_start"] + 0.011 + 1e-9
    assert move_starts(*read_report(paper["default"])[::2]) == []  # no move columns: none
    # a move that started and ended between two rows: its number still counts, line 0
    cols = {"move": np.array([0, 0, 2, 2, 3.0]), "line": np.array([0, 0, 9, 0, 0.0])}
    assert move_starts(np.array([0.0, 0.01, 0.02, 0.03, 0.04]), cols) == [(0.02, 2, 9), (0.04, 3, 0)]


def _labels_never_overlap(fig) -> list[str]:
    """The texts above the first panel (phases, homing steps, moves): none overlaps another."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    top = fig.axes[0]
    boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in top.texts]
    for k, (a, box_a) in enumerate(boxes):
        for b, box_b in boxes[k + 1:]:
            assert not box_a.overlaps(box_b), (a, b)
    return [text for text, _ in boxes]


def test_the_plot_names_the_homing_steps_and_marks_each_move(paper, tmp_path):
    import matplotlib.pyplot as plt

    from runtime.cli.plot import figure, plot_report

    fig = figure(paper["moves"])
    try:
        texts = _labels_never_overlap(fig)
        assert {"Find Sensors", "Find Index", "Go To Start", "L4", "L5", "L6", "Move Robot"} <= set(texts)
        # a dotted line at each move's start on every axis panel (the TCP views have none)
        panels = [ax for ax in fig.axes if ax.get_xlabel() in ("", "time (s)") and ax.get_ylabel().endswith("(deg)")]
        assert len(panels) == 6  # every axis moves (homing)
        starts = [m["t_start"] for m in paper["records"]]
        for ax in panels:
            xs = [line.get_xdata()[0] for line in ax.get_lines() if line.get_linestyle() == ":"]
            assert xs == pytest.approx(starts, abs=0.0115)
    finally:
        plt.close(fig)
    fig = figure(paper["default"])  # without the move columns: the homing steps, no move
    try:
        texts = _labels_never_overlap(fig)
        assert "Find Index" in texts and not any(t.startswith("L") and t[1:].isdigit() for t in texts)
    finally:
        plt.close(fig)
    png = tmp_path / "moves.png"
    plot_report(paper["moves"], png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000


def test_many_moves_labels_never_overlap(paper, tmp_path):
    """A move every 50 ms (the paper's report, renumbered): the labels that fit are drawn,
    none over another, in at most four rows; every move keeps its line."""
    import matplotlib.pyplot as plt

    from runtime.cli.plot import MARK_ROWS, figure

    header, rows = rows_of(paper["moves"])
    moving = [k for k, r in enumerate(rows) if r[1] == "Move Robot"]
    for k in moving:
        number = (k - moving[0]) // 5 + 1
        rows[k][-2:] = [str(number), str(100 + number % 7)]
    dense = tmp_path / "dense.csv"
    with open(dense, "w", newline="", encoding="utf-8") as f:
        csv.writer(f, lineterminator="\n").writerows([header] + rows)
    fig = figure(dense)
    try:
        texts = _labels_never_overlap(fig)
        marks = [t for t in fig.axes[0].texts if t.get_text().startswith("L")]
        assert 10 < len(marks) < len(moving) // 5  # some drawn, not all
        heights = sorted({round(t.get_position()[1], 6) for t in marks})
        assert len(heights) <= MARK_ROWS
        lines = [ln for ln in fig.axes[0].get_lines() if ln.get_linestyle() == ":"]
        assert len(lines) == (len(moving) - 1) // 5 + 1
        assert "Move Robot" in texts
    finally:
        plt.close(fig)
