"""Does a telemetry subscriber that stops reading slow the real-time loop?

A wall-clock `irl serve` runs the paper's program (after one warm-up run that calibrates
and initializes) alternately with and without a subscriber that connects and never reads
(its receive queue limited to one message); per run, the deadline statistics from the
program's summary. Goal: the same statistics with the stalled subscriber as without (the
host's noise sets how "same" looks: compare the spread within each group).
Run: .venv/bin/python benchmarks/telemetry_stall.py [--pairs N]
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import zmq

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from compiler.driver import compile_file  # noqa: E402
from compiler.objcode import encode  # noqa: E402
from runtime.client.client import Client  # noqa: E402
from _stats import free_port  # noqa: E402



def run_once(client: Client, data: bytes) -> dict:
    job = client.request("submit", {"object": data, "name": "test.irl"})["program"]
    while True:
        status = client.request("status", {"program": job}, timeout=30)
        if status["state"] not in ("queued", "running"):
            break
        zmq.select([], [], [], 0.2)
    if status["state"] != "completed":
        raise SystemExit(f"program {job} {status['state']}: {status['fault']}")
    return status["summary"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=3)
    args = ap.parse_args()
    ports = [free_port(), free_port()]
    endpoint, telemetry = (f"tcp://127.0.0.1:{p}" for p in ports)
    # The servo's deadline policy "soft" (counted only): a burst of host noise must not end
    # a run, since the misses themselves are what is compared.
    work = Path(tempfile.mkdtemp(prefix="irl-stall-"))
    spec = work / "lola15.spc"
    spec.write_text((ROOT / "programs" / "lola15.spc").read_text(encoding="utf-8")
                    .replace('servo_miss_policy = "firm"', 'servo_miss_policy = "soft"'), encoding="utf-8")
    server = subprocess.Popen([sys.executable, "-m", "runtime.cli.main", "serve", "--spec",
                               str(spec), "--state-dir", str(work),
                               "--endpoint", endpoint, "--telemetry", telemetry], cwd=ROOT, stderr=subprocess.DEVNULL)
    ctx = zmq.Context.instance()
    client = Client(endpoint, timeout=15)
    data = encode(compile_file(ROOT / "programs" / "test.irl", spec).program)
    groups: dict[str, list[dict]] = {"without": [], "stalled": []}
    try:
        client.request("hello")
        run_once(client, data)  # warm-up: calibration and initialization
        for _ in range(args.pairs):
            for mode in ("without", "stalled"):
                sub = None
                if mode == "stalled":
                    sub = ctx.socket(zmq.SUB)
                    sub.setsockopt(zmq.RCVHWM, 1)
                    sub.setsockopt(zmq.RCVBUF, 4096)
                    sub.setsockopt(zmq.SUBSCRIBE, b"")
                    sub.connect(telemetry)
                groups[mode].append(run_once(client, data))
                if sub is not None:
                    sub.close(linger=0)
    finally:
        client.close()
        server.terminate()
        server.wait(30)
    print(f"paper's program on a wall-clock server, {args.pairs} runs each, alternating")
    for mode, runs in groups.items():
        misses = [r["deadline_misses"] for r in runs]
        servo_p99 = [r["deadlines"]["servo"]["late_p99_us"] for r in runs]
        servo_max = [r["deadlines"]["servo"]["late_max_us"] for r in runs]
        print(f"  {mode:8s} subscriber: misses {misses}, servo lateness p99 {[round(x) for x in servo_p99]} us "
              f"(median {statistics.median(servo_p99):.0f}), max {[round(x) for x in servo_max]} us")
    return 0


if __name__ == "__main__":
    sys.exit(main())
