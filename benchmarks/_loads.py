"""Loads to run beside the real-time loop (benchmarks/serve_load.py and the end-to-end
test of a status flood in tests/test_realtime.py): CPU-bound processes, and another client
flooding a server with ``status`` requests plus a telemetry subscriber. Each load is a
process of its own; on SIGTERM a client prints how many replies or messages it got."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: A client that keeps 32 ``status`` requests in flight, as fast as the server answers.
FLOOD = """
import signal, sys, zmq
from runtime.wire import protocol
signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
sock = zmq.Context().socket(zmq.DEALER)
sock.connect(sys.argv[1])
request = protocol.request("status", {}, 1)
outstanding = replies = 0
try:
    while True:
        while outstanding < 32:
            sock.send_multipart([b"", request])
            outstanding += 1
        if sock.poll(100):
            while True:
                try:
                    sock.recv_multipart(zmq.NOBLOCK)
                except zmq.Again:
                    break
                outstanding -= 1
                replies += 1
finally:
    print(replies, flush=True)
"""

#: A telemetry subscriber that reads everything.
SUBSCRIBE = """
import signal, sys, zmq
from runtime.wire import protocol
signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
sock = zmq.Context().socket(zmq.SUB)
sock.setsockopt(zmq.SUBSCRIBE, protocol.TELEMETRY_TOPIC)
sock.connect(sys.argv[1])
messages = 0
try:
    while True:
        sock.recv_multipart()
        messages += 1
finally:
    print(messages, flush=True)
"""

KINDS = ("idle", "cpu", "flood")


def start_load(kind: str, endpoint: str = "", telemetry: str = "") -> list[subprocess.Popen]:
    """``idle``: nothing; ``cpu``: two CPU-bound processes; ``flood``: FLOOD on ``endpoint``
    and SUBSCRIBE on ``telemetry``."""
    python = [sys.executable, "-c"]
    if kind == "cpu":
        return [subprocess.Popen([*python, "while True: pass"]) for _ in range(2)]
    if kind == "flood":
        return [subprocess.Popen([*python, FLOOD, endpoint], cwd=ROOT, stdout=subprocess.PIPE, text=True),
                subprocess.Popen([*python, SUBSCRIBE, telemetry], cwd=ROOT, stdout=subprocess.PIPE, text=True)]
    if kind == "idle":
        return []
    raise ValueError(f"load {kind!r}: expected one of {', '.join(KINDS)}")


def stop_load(processes: list[subprocess.Popen]) -> list[int | None]:
    """Stop the load; what each client counted (None for a CPU-bound process)."""
    counts = []
    for process in processes:
        process.terminate()
        out, _ = process.communicate(timeout=10)
        counts.append(int(out.split()[-1]) if out and out.split() else None)
    return counts
