"""The language of a real cell (issue 17), end to end: programs/pallet_and_glue.irl --
palletizing on a moved pallet with a tool change, a glue bead switched by path triggers,
a light-curtain interrupt -- compiled, run against its cell scenario, reported and plotted,
as a user runs it from the command line."""
from __future__ import annotations

import csv
import json

import numpy as np

from runtime.cli.main import Environment, main

from conftest import ROOT


def test_the_cell_program_runs_reports_and_plots(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    report = tmp_path / "cell.csv"
    assert main(["run", "programs/pallet_and_glue.irl", "--cell-scenario", "programs/pallet_and_glue.cell.toml",
                 "--report", str(report), "--report-columns", "+frame,move", "--state-dir", str(tmp_path / "state"),
                 "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["fault"] is None
    texts = [entry["text"] for entry in summary["log"]]
    assert any(t.startswith("interrupt curtain fired during the move at line") for t in texts), texts
    assert texts[-1] == "4 boxes and a bead; the curtain stopped the robot 1 time(s)"
    rows = list(csv.DictReader(open(report)))
    assert {r["tool"] for r in rows} == {"default_tool", "gripper", "glue_gun"}
    assert {r["base"] for r in rows} >= {"world", "pallet_station * moved", "glue_table"}
    # the curtain: the lamp on while it was broken, and the robot at rest on its path meanwhile
    # (the scenario's 4.8 s and 6.3 s count from the program's start: Move Robot, after homing)
    started = next(s["t_enter"] for s in summary["states"] if s["name"] == "Move Robot")
    lamp = [float(r["time"]) - started for r in rows if r["out_9"] == "1"]
    assert lamp and 4.8 <= lamp[0] <= 4.82 and 6.28 <= lamp[-1] <= 6.32  # (rows every 10 ms)
    still = [r for r in rows if 5.5 <= float(r["time"]) - started <= 6.25]  # (after its controlled stop: about 0.6 s)
    assert np.ptp([[float(r[f"sens_pos_A{i}"]) for i in range(1, 7)] for r in still], axis=0).max() < 0.01
    # the glue: on only along the bead, the nozzle 5 mm above the table all the while
    glue = [r for r in rows if r["out_3"] == "1"]
    assert glue and all(r["tool"] == "glue_gun" and r["base"] == "glue_table" for r in glue)
    assert all(abs(float(r["base_z"]) - 5.0) < 0.05 for r in glue)
    first, last = glue[0], glue[-1]
    assert abs(float(first["base_x"]) - 55.0) < 3.0 and abs(float(first["base_y"]) - 50.0) < 0.05  # 5 mm in
    assert abs(float(last["base_x"]) - 60.0) < 3.0 and abs(float(last["base_y"]) - 250.0) < 0.05  # 10 mm before
    out = tmp_path / "cell.png"
    assert main(["plot", str(report), "-o", str(out)], Environment()) == 0
    assert out.stat().st_size > 50_000
