"""Jogging in T1, measured as an operator meets it (issue 31's figures), on a wall-clock
`irl serve --mode t1` and the Python client:

1. latency: from a continuous jog's first request (the robot's clock when the loop took it)
   to the first telemetry sample (10 ms) whose position has moved, within a jog session and
   as a new session's first jog (brakes released first), against the telemetry period;
2. released: a jog held 1 s (a heartbeat every 0.1 s), then released: the time from the
   release sent to the last sample that moved, and how far the tool centre point went in
   that time (mm);
3. lost heartbeat: the same jog held, then silence (a closed page, a lost network): from the
   last heartbeat to the last sample that moved, and the distance after it;
4. the largest speed of the tool centre point seen in the telemetry while jogging (mm/s, the
   measured position over 50 ms) and the safety supervisor's own, every 1 ms
   (`t1_peak_speed` of the jog session's summary), against T1's 250 mm/s.

Each figure is the median (and the worst) of --runs jogs, alternating directions. Run:
    .venv/bin/python benchmarks/jog.py [--runs 6]
"""
from __future__ import annotations

import argparse
import math
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
IRL = str(Path(sys.executable).with_name("irl"))
SPEC = str(ROOT / "programs" / "lola15.spc")


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Telemetry:
    """The samples of a subscriber, with the wall time each arrived."""

    def __init__(self, endpoint: str):
        from runtime.client.client import Subscriber

        self.sub = Subscriber(endpoint)

    def drain(self, seconds: float) -> list[tuple[float, dict]]:
        out, end = [], time.monotonic() + seconds
        while time.monotonic() < end:
            m = self.sub.receive(max(0.0, end - time.monotonic()))
            if m is not None and m.get("kind") == "sample":
                out.append((time.monotonic(), m))
        return out


#: deg between two 10 ms samples that is rest (the servo holds a position within a few encoder counts)
REST = 0.002


def _moved(a: dict, b: dict, tol: float = 1e-4) -> bool:
    return max(abs(x - y) for x, y in zip(a["position"], b["position"])) > tol


def _jog(client, request: dict) -> dict:
    """A jog request, sent again while the session before it ends."""
    from runtime.client.client import ClientError

    for _ in range(50):
        try:
            return client.request("jog", request)
        except ClientError as exc:
            if "session is ending" not in exc.message:
                raise
            time.sleep(0.1)
    raise RuntimeError("no jog session started")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=6)
    parser.add_argument("--deadline-policy", default="soft",
                        help="the server's (default soft: a busy shared host's missed deadlines are counted, not a "
                             "fault; the figures are the jog's, not the host's)")
    args = parser.parse_args()
    from runtime.client.client import Client

    req, tel = f"tcp://127.0.0.1:{_port()}", f"tcp://127.0.0.1:{_port()}"
    state = tempfile.mkdtemp(prefix="irl-jog-")
    server = subprocess.Popen([IRL, "serve", "--spec", SPEC, "--endpoint", req, "--telemetry", tel, "--state-dir",
                               state, "--mode", "t1", "--deadline-policy", args.deadline_policy],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        client = Client(req, timeout=10.0)
        for _ in range(100):
            try:
                client.request("hello")
                break
            except Exception:  # noqa: BLE001 (not up yet)
                time.sleep(0.1)
        telemetry = Telemetry(tel)
        _jog(client, {"axis": "A5", "direction": 1, "step": 30.0})  # homes, then off the wrist singularity
        while True:
            status = client.request("status")
            if status["running"] is not None and status["jog"] and status["jog"]["reason"]:
                break
            time.sleep(0.1)
        latency, released, released_mm, lost, lost_mm, tel_peak = [], [], [], [], [], 0.0
        for k in range(args.runs):
            for mode in ("release", "lost"):
                jog = {"axis": "y", "direction": 1 if k % 2 == 0 else -1, "frame": "world"}
                t_request = _jog(client, jog)["t"]
                t_beat = t_request
                sent = time.monotonic()
                while time.monotonic() - sent < 1.0:
                    time.sleep(0.1)
                    t_beat = _jog(client, jog)["t"]
                t_end = client.request("jog", {**jog, "direction": 0})["t"] if mode == "release" else t_beat
                time.sleep(1.0)
                samples = sorted((m for _, m in telemetry.drain(0.3)), key=lambda m: m["t"])
                samples = [m for m in samples if m["t"] >= t_request - 0.05]
                moving = [b["t"] for a, b in zip(samples, samples[1:]) if _moved(b, a, REST)]
                started = [t for t in moving if t > t_request]
                if started:
                    latency.append(started[0] - t_request)
                stopped = max(moving) if moving else t_end
                (released if mode == "release" else lost).append(max(0.0, stopped - t_end))
                at_end = min(samples, key=lambda m: abs(m["t"] - t_end))
                (released_mm if mode == "release" else lost_mm).append(math.dist(at_end["tcp"][:3], samples[-1]["tcp"][:3]))
                for a, b in zip(samples, samples[5:]):  # over 5 samples: a sample's time is when it was taken
                    if b["t"] - a["t"] >= 0.045:       # (after its tick, late by the host's jitter)
                        tel_peak = max(tel_peak, math.dist(a["tcp"][:3], b["tcp"][:3]) / (b["t"] - a["t"]))
                time.sleep(0.3)
        fresh = []  # the first jog of a new session: brakes released, Start Robot, then the jog
        for k in range(max(2, args.runs // 2)):
            time.sleep(2.6)  # the session ends (brakes on)
            jog = {"axis": "A1", "direction": 1 if k % 2 == 0 else -1, "frame": "world"}
            t_request = _jog(client, jog)["t"]
            for _ in range(5):
                time.sleep(0.1)
                _jog(client, jog)
            client.request("jog", {**jog, "direction": 0})
            time.sleep(0.5)
            samples = sorted((m for _, m in telemetry.drain(0.3)), key=lambda m: m["t"])
            samples = [m for m in samples if m["t"] >= t_request - 0.05]
            started = [b["t"] for a, b in zip(samples, samples[1:]) if _moved(b, a, REST) and b["t"] > t_request]
            if started:
                fresh.append(started[0] - t_request)
        time.sleep(2.6)  # the session ends: its summary has the supervisor's own peak
        programs = client.request("status")["programs"]
        session = [p for p in programs if p.get("kind") == "jog"][-1]
        summary = client.request("status", {"program": session["id"]}).get("summary") or {}
        peak = summary.get("t1_peak_speed")
    finally:
        server.terminate()
        server.wait(20)

    def line(name, values, unit):
        print(f"{name:<44} median {statistics.median(values):8.3f} {unit}   worst {max(values):8.3f} {unit}")

    print(f"jogging in T1 (lola15, a wall-clock server, {args.runs} jogs of each kind, y in the world frame)")
    line("latency: first request -> arm moving", latency, "s")
    line("latency, a new session's first jog", fresh, "s")
    print(f"{'  (reference: the telemetry period)':<44}        0.010 s")
    line("released: release sent -> at rest", released, "s")
    line("released: distance after the release", released_mm, "mm")
    line("lost heartbeat: last heartbeat -> at rest", lost, "s")
    line("lost heartbeat: distance after it", lost_mm, "mm")
    print(f"{'largest TCP speed, measured (50 ms)':<44} {tel_peak:8.1f} mm/s  (T1 limit 250)")
    print(f"{'largest TCP/flange speed, safety (1 ms)':<44} {peak if peak is not None else float('nan'):8.1f} mm/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
