"""Real-time scheduling and the host's latency (issue 15, first step): `irl latency`,
`--deadline-policy`, `--rt-priority` / `--lock-memory` / `--cpu` on `irl run` and `irl
serve`."""
from __future__ import annotations

import io
import json
import os
from array import array
from pathlib import Path

import pytest

from compiler.spec import load_spec
from runtime import realtime
from runtime.cli import Environment, main
from runtime.executive import DEADLINE_HINT, Executive, MissPolicy, SimClock
from runtime.system import RobotSystem, RunOptions
from runtime.timing import TICK

ROOT = Path(__file__).resolve().parents[1]
SPEC_FILE = ROOT / "programs" / "lola15.spc"
SPEC = load_spec(SPEC_FILE)


def run(*argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    code = main([str(a) for a in argv], Environment(stdout=out, stderr=err))
    return code, out.getvalue(), err.getvalue()


def servo_policy(system: RobotSystem) -> MissPolicy:
    return next(task.policy for task in system.executive.tasks if task.name == "servo")


# ---- the deadline policy ------------------------------------------------------------------------

def test_the_deadline_policy_is_the_specifications_unless_a_run_says_otherwise():
    assert servo_policy(RobotSystem(SPEC, RunOptions())).kind == SPEC.controller.servo_miss_policy == "firm"
    for kind in ("hard", "soft"):
        policy = servo_policy(RobotSystem(SPEC, RunOptions(deadline_policy=kind)))
        assert policy.kind == kind and policy.window == SPEC.controller.servo_miss_window


def test_the_deadline_policy_flag_is_in_the_help_with_its_default_and_refuses_anything_else(capsys):
    for command in ("run", "serve"):
        code, _, _ = run(command, "--help")
        out = " ".join(capsys.readouterr().out.split())  # (argparse prints the help itself)
        assert code == 0 and "--deadline-policy {hard,firm,soft}" in out and "(firm)" in out
        assert "--rt-priority N" in out and "--lock-memory" in out and "--cpu N" in out
    code, _, err = run("run", ROOT / "programs" / "test.irl", "--deadline-policy", "sometimes")
    err += capsys.readouterr().err
    assert code == 2 and "invalid choice: 'sometimes'" in err


def test_a_run_with_a_deadline_policy_completes_and_scheduling_needs_the_wall_clock():
    code, out, err = run("run", ROOT / "programs" / "test.irl", "--deadline-policy", "hard", "--json")
    assert code == 0 and json.loads(out)["fault"] is None
    code, _, err = run("run", ROOT / "programs" / "test.irl", "--rt-priority", "50")
    assert code == 2 and "for the wall clock: add --realtime" in err
    code, _, err = run("run", ROOT / "programs" / "test.irl", "--realtime", "--rt-priority", "120")
    assert code == 2 and "--rt-priority 120: expected 1 to 99" in err
    code, _, err = run("run", ROOT / "programs" / "test.irl", "--realtime", "--cpu", str(os.cpu_count() or 1))
    assert code == 2 and "this host's CPUs" in err
    code, _, err = run("serve", "--spec", SPEC_FILE, "--sim-clock", "--lock-memory")
    assert code == 2 and "for the wall clock: drop --sim-clock" in err


def test_a_deadline_fault_says_how_to_find_out_what_the_host_can_hold():
    clock = SimClock(TICK)
    ex = Executive(clock, TICK)
    ex.add("servo", lambda now: None, TICK, "control", policy=MissPolicy("hard"))
    ex._missed(ex.tasks[0], 0)
    assert ex.fault.startswith("deadline: servo missed its 1 ms deadline (hard)") and ex.fault.endswith(DEADLINE_HINT)
    assert "irl latency" in DEADLINE_HINT and "--deadline-policy soft" in DEADLINE_HINT


# ---- scheduling -------------------------------------------------------------------------------

def test_scheduling_says_what_it_got_and_never_raises():
    assert realtime.apply(realtime.Scheduling()) == "normal scheduling"
    before = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority, os.sched_getaffinity(0)
    try:
        got = realtime.apply(realtime.Scheduling(priority=10, cpu=0))
        if os.sched_getscheduler(0) == os.SCHED_FIFO:
            assert got.startswith("SCHED_FIFO 10") and os.sched_getparam(0).sched_priority == 10
        else:
            assert got.startswith("normal scheduling: no permission for SCHED_FIFO; grant it with ")
        assert got.endswith("CPU 0") and os.sched_getaffinity(0) == {0}
    finally:
        os.sched_setscheduler(0, before[0], os.sched_param(before[1]))
        os.sched_setaffinity(0, before[2])
    with pytest.raises(ValueError, match="expected 1 to 99"):
        realtime.Scheduling(priority=0)


# ---- latency ----------------------------------------------------------------------------------

def latency(lates, period=TICK) -> realtime.Latency:
    return realtime.Latency(period, len(lates) * period, array("d", lates))


def test_the_verdict_is_the_strictest_policy_the_wake_ups_allow():
    on_time = [0.00005] * 2000
    assert realtime.verdict(latency(on_time), 50, 1000)[0] == "hard"
    a_few = list(on_time)
    for k in (10, 500, 1500):
        a_few[k] = 0.002
    policy, why = realtime.verdict(latency(a_few), 2, 1000)
    assert policy == "firm" and "3 late wake-ups, at most 2 within 1000 ticks (firm allows 2)" in why
    bunched = list(on_time)
    for k in range(100, 104):
        bunched[k] = 0.0015
    policy, why = realtime.verdict(latency(bunched), 3, 1000)
    assert policy == "soft" and "4 within 1000 ticks" in why and "--deadline-policy soft" in why
    assert realtime.verdict(latency([0.0005, 0.00095]), 0, 10)[0] == "soft"  # (0.95 ms: no room for the work)


def test_measure_wakes_up_every_period_and_records_how_late():
    result = realtime.measure(0.002, 0.1)
    assert len(result.late) == 50 and min(result.late) >= 0.0
    assert result.percentile(0.5) <= result.percentile(0.99) <= max(result.late)
    assert sum(c for _a, _b, c in result.histogram()) == 50
    with pytest.raises(ValueError, match="positive"):
        realtime.measure(0.0, 1.0)


def test_irl_latency_prints_the_figures_and_the_policy_and_as_json():
    code, out, _ = run("latency", "--duration", "0.2", "--spec", SPEC_FILE)
    assert code == 0 and "200 wake-ups every 1 ms for 0.2 s (normal scheduling)" in out
    assert "late by: max" in out and "p99.9" in out and "this host can hold: " in out
    code, out, _ = run("latency", "--duration", "0.1", "--period", "2", "--json")
    figures = json.loads(out)
    assert code == 0 and figures["wakeups"] == 50 and figures["policy"] in ("hard", "firm", "soft")
    assert figures["max_ms"] >= figures["p99_ms"] >= figures["p50_ms"] >= 0.0
    assert sum(b["count"] for b in figures["histogram"]) == 50
    code, _, err = run("latency", "--period", "0")
    assert code == 2 and "--period 0: expected 0.05 to 1000 ms" in err


def test_irl_serve_on_the_wall_clock_says_what_scheduling_its_loop_got(tmp_path):
    """End to end: `irl serve --rt-priority 10 --deadline-policy soft` answers on loopback
    and its log says what the loop's thread got (SCHED_FIFO where permitted, else why not
    and how to grant it)."""
    from test_server import ServerProcess

    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=False,
                           extra=("--rt-priority", "10", "--deadline-policy", "soft"))
    try:
        server.start()
        assert server.client().request("hello")
        import time

        deadline = time.monotonic() + 10.0
        while "loop: " not in server.log() and time.monotonic() < deadline:
            time.sleep(0.05)
        log = server.log()
        assert "loop: SCHED_FIFO 10" in log or "loop: normal scheduling: no permission for SCHED_FIFO" in log, log
    finally:
        assert server.stop() == 0, server.log()
