"""Request latency of `irl serve` over loopback, against a bare pyzmq echo measured in the
same run.

Figures:
  status round trip, p50 and p99, against a bare ROUTER echo process (same sockets, same
  machine, interleaved blocks): goal ratio <= 2x;
  submit of the paper's program (already compiled) until the reply that it is verified and
  queued: goal p99 <= 20 ms. The server runs on the wall clock (its default), so the
  submitted programs really run while the later submits are measured;
  telemetry replay (protocol 2): a request for the last 2,000 messages, p50 and p99.
Run: .venv/bin/python benchmarks/service_latency.py [--blocks N] [--per-block N]
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import zmq

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from compiler.driver import compile_file  # noqa: E402
from compiler.objcode import encode  # noqa: E402
from runtime.wire import protocol  # noqa: E402
from _stats import free_port, percentile  # noqa: E402

ECHO = """
import sys, zmq
ctx = zmq.Context()
s = ctx.socket(zmq.ROUTER)
s.bind(sys.argv[1])
while True:
    s.send_multipart(s.recv_multipart())
"""




def round_trips(sock, payload: bytes, n: int) -> list[float]:
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        sock.send(payload)
        sock.recv()
        out.append(time.perf_counter() - t0)
    return out


def compare(srv, bare, payload: bytes, args, when: str) -> None:
    served, echoed = [], []
    for _ in range(args.blocks):  # interleaved blocks: both see the same host noise
        echoed += round_trips(bare, payload, args.per_block)
        served += round_trips(srv, payload, args.per_block)
    print(f"status round trip over loopback, {when}: {len(served)} requests each, interleaved blocks of "
          f"{args.per_block}")
    for name, q in (("p50", 0.5), ("p99", 0.99)):
        s, e = percentile(served, q), percentile(echoed, q)
        print(f"  {name}: irl serve {s * 1e6:7.1f} us   bare pyzmq echo {e * 1e6:7.1f} us   "
              f"ratio {s / e:4.2f}x  (goal <= 2x)")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=20)
    ap.add_argument("--per-block", type=int, default=200)
    ap.add_argument("--submits", type=int, default=90, help=f"at most {protocol.MAX_QUEUED} (the queue's bound)")
    args = ap.parse_args()
    ports = [free_port() for _ in range(3)]
    state = tempfile.mkdtemp(prefix="irl-bench-")
    server = subprocess.Popen([sys.executable, "-m", "runtime.cli.main", "serve", "--spec", str(ROOT / "programs" / "lola15.spc"),
                               "--state-dir", state, "--endpoint", f"tcp://127.0.0.1:{ports[0]}",
                               "--telemetry", f"tcp://127.0.0.1:{ports[1]}"],
                              cwd=ROOT, stderr=subprocess.DEVNULL)
    echo = subprocess.Popen([sys.executable, "-c", ECHO, f"tcp://127.0.0.1:{ports[2]}"])
    ctx = zmq.Context()
    try:
        srv = ctx.socket(zmq.DEALER)
        srv.connect(f"tcp://127.0.0.1:{ports[0]}")
        bare = ctx.socket(zmq.DEALER)
        bare.connect(f"tcp://127.0.0.1:{ports[2]}")
        status = protocol.request("status", {}, 1)
        for sock in (srv, bare):  # wait until both answer
            sock.send(status)
            if not sock.poll(15000):
                raise SystemExit("a process did not answer within 15 s")
            sock.recv()
        compare(srv, bare, status, args, "robot idle")

        data = encode(compile_file(ROOT / "programs" / "test.irl").program)
        times = []
        for i in range(args.submits):
            payload = protocol.request("submit", {"object": data, "name": "test.irl"}, 1000 + i)
            t0 = time.perf_counter()
            srv.send(payload)
            reply = protocol.decode_reply(srv.recv())
            times.append(time.perf_counter() - t0)
            if not reply["ok"]:
                raise SystemExit(f"submit refused: {reply['error']}")
        print(f"submit of the paper's program ({len(data)} bytes) until verified and queued, {len(times)} submits "
              f"(programs running meanwhile):")
        print(f"  p50 {percentile(times, 0.5) * 1e3:.2f} ms, p99 {percentile(times, 0.99) * 1e3:.2f} ms, "
              f"max {max(times) * 1e3:.2f} ms  (goal p99 <= 20 ms); mean {statistics.mean(times) * 1e3:.2f} ms")
        compare(srv, bare, status, args, "a program running (wall clock)")
        replay_times, sizes, counts = [], [], []
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline:  # 2,000 messages in the history first (20 s of a running program)
            srv.send(protocol.request("telemetry", {}, 4999))
            if protocol.decode_reply(srv.recv())["result"]["seq"] > 2100:
                break
            time.sleep(0.5)
        for i in range(50):  # what a subscriber that lost 2,000 messages (20 s) pays to catch up
            srv.send(protocol.request("telemetry", {}, 5000 + 2 * i))
            seq = protocol.decode_reply(srv.recv())["result"]["seq"]
            t0 = time.perf_counter()
            srv.send(protocol.request("telemetry", {"since": max(0, seq - 2000)}, 5001 + 2 * i))
            payload = srv.recv()
            replay_times.append(time.perf_counter() - t0)
            sizes.append(len(payload))
            counts.append(len(protocol.decode_reply(payload)["result"]["messages"]))
        print(f"telemetry replay (protocol 2) of the last {min(counts)}-{max(counts)} messages, "
              f"{statistics.mean(sizes) / 1024:.0f} KiB per reply, 50 requests:")
        print(f"  p50 {percentile(replay_times, 0.5) * 1e3:.2f} ms, p99 {percentile(replay_times, 0.99) * 1e3:.2f} ms")
    finally:
        server.terminate()
        echo.kill()
        try:
            server.wait(20)
        except subprocess.TimeoutExpired:
            server.kill()
        ctx.destroy(linger=0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
