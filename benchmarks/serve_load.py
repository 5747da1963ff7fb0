"""`irl serve`'s loop under three loads, each against a bare loop measured in the same run.

For each load the host's own wake-up latency is measured first (``irl latency`` in a
process of its own, at the same scheduling class: the bare sleep-then-spin loop), then
the paper's program runs on the wall clock under ``irl serve`` (its loop in its own
process, soft deadline policy so that it runs to the end and is counted), and the loop's
figures are read from the program's summary: the ticks' wake-up lateness (``wakeups``,
what the host gave the loop) and the servo's deadline misses (its work finished more than
1 ms after the tick's start). Loads:

* ``idle``: nothing else;
* ``cpu``: two CPU-bound processes;
* ``flood``: a client process sending ``status`` requests as fast as the server answers
  (32 in flight) and a subscriber process reading the telemetry.

Goal (issue 15): the loop's misses and p99 lateness within 1.2x of the bare loop's under
each load; with SCHED_FIFO granted (the default: SCHED_FIFO 50, memory locked), the ``cpu`` load
at most a tenth of its misses at normal priority (``--rt-priority 0``). The bare loop's "misses" are wake-ups
later than 0.9 ms (irl latency's rule: too late for a tick's work).
One run of the program swings by 2-3x on a shared host (a stall of the host hits either
loop): each load is measured ``--rounds`` times, misses summed, p99 ratios' median.
Run: .venv/bin/python benchmarks/serve_load.py [--rounds N] [--seconds S] [--loads idle,cpu,flood]
     [--rt-priority N|0] [--[no-]lock-memory] [--cpu N]
"""
from __future__ import annotations

import argparse
import json
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from compiler.driver import compile_file  # noqa: E402
from compiler.objcode import encode  # noqa: E402
from runtime.loop import realtime  # noqa: E402
from runtime.client.client import Client  # noqa: E402
from runtime.wire.protocol import TERMINAL  # noqa: E402

sys.path.insert(0, str(ROOT / "benchmarks"))
from _loads import start_load, stop_load  # noqa: E402

IRL = [sys.executable, "-m", "runtime.cli.main"]

def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def flags(args) -> list[str]:
    """The scheduling flags given (none: both commands' default, SCHED_FIFO 50 with memory locked)."""
    out = []
    if args.rt_priority is not None:
        out += ["--rt-priority", str(args.rt_priority)]
    if args.lock_memory is not None:
        out.append("--lock-memory" if args.lock_memory else "--no-lock-memory")
    if args.cpu is not None:
        out += ["--cpu", str(args.cpu)]
    return out


def bare(seconds: float, args) -> dict:
    out = subprocess.run([*IRL, "latency", "--duration", str(seconds), "--json", *flags(args)], cwd=ROOT,
                         capture_output=True, text=True, check=True).stdout
    figures = json.loads(out)
    return {"misses": figures["misses"], "p99_us": figures["p99_ms"] * 1000, "max_us": figures["max_ms"] * 1000,
            "scheduling": figures["scheduling"]}


def program(client: Client, data: bytes) -> dict:
    job = client.request("submit", {"object": data, "name": "test.irl"})["program"]
    while True:
        s = client.request("status", {"program": job})
        if s["state"] in TERMINAL:
            break
        time.sleep(0.2)
    summary = s["summary"]
    servo = summary["deadlines"]["servo"]
    return {"state": s["state"], "fault": s["fault"], "misses": servo["misses"],
            "p99_us": summary["wakeups"]["late_p99_us"], "max_us": summary["wakeups"]["late_max_us"],
            "servo_p99_us": servo["late_p99_us"], "ticks": summary["ticks"], "wall": summary["wall_time"]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=0.0,
                    help="the bare loop's duration per load (default: the program's wall time)")
    ap.add_argument("--loads", default="idle,cpu,flood")
    ap.add_argument("--rounds", type=int, default=3, help="each load this many times (the host is noisy)")
    realtime.add_arguments(ap)
    args = ap.parse_args()
    result = compile_file(ROOT / "programs" / "test.irl")
    data = encode(result.program)
    endpoint, telemetry = f"tcp://127.0.0.1:{free_port()}", f"tcp://127.0.0.1:{free_port()}"
    with tempfile.TemporaryDirectory() as state:
        server = subprocess.Popen([*IRL, "serve", "--spec", str(ROOT / "programs" / "lola15.spc"), "--state-dir",
                                   state, "--endpoint", endpoint, "--telemetry", telemetry, "--deadline-policy",
                                   "soft", *flags(args)], cwd=ROOT, stderr=subprocess.PIPE, text=True)
        client = Client(endpoint, timeout=30.0)
        try:
            hello = client.request("hello")
            print(f"irl serve: loop process {hello['loop_pid']}, {hello['loop_scheduling']}")
            program(client, data)  # calibration and homing, remembered: every measured run is the same
            rows = {kind: [] for kind in args.loads.split(",")}
            for r in range(args.rounds):
                for kind in rows:
                    load = start_load(kind, endpoint, telemetry)
                    try:
                        time.sleep(0.5)
                        ours = program(client, data)
                        theirs = bare(args.seconds or ours["wall"], args)
                    finally:
                        stop_load(load)
                    rows[kind].append((theirs, ours))
                    print(f"round {r + 1}, load {kind}: bare loop ({theirs['scheduling']}) misses {theirs['misses']}, "
                          f"p99 {theirs['p99_us']:.0f} us, max {theirs['max_us']:.0f} us | irl serve's loop: "
                          f"{ours['state']}, misses {ours['misses']} in {ours['ticks']} ticks, wake-up p99 "
                          f"{ours['p99_us']:.0f} us, max {ours['max_us']:.0f} us (servo done p99 "
                          f"{ours['servo_p99_us']:.0f} us)", flush=True)
            print(f"loop / bare, summed over {args.rounds} rounds (misses) and median of the rounds (p99):")
            for kind, pairs in rows.items():
                misses_o = sum(o["misses"] for _t, o in pairs)
                misses_b = sum(t["misses"] for t, _o in pairs)
                p99 = statistics.median(o["p99_us"] / max(t["p99_us"], 1) for t, o in pairs)
                print(f"  {kind:6s} misses {misses_o:5d} / {misses_b:5d} = {misses_o / max(misses_b, 1):.2f}x   "
                      f"p99 {p99:.2f}x  (goal <= 1.2x)")
        finally:
            client.close()
            server.terminate()
            server.wait(30)
    return 0


if __name__ == "__main__":
    sys.exit(main())
