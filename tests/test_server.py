"""End-to-end tests of ``irl serve`` and its clients: real server processes on loopback.

Every test starts its own ``irl serve`` (a subprocess of the console script) on free
ports with a state directory under tmp_path, waits until it answers ``hello``, and stops
it in a finalizer (SIGTERM, then SIGKILL after 10 s); the server's stderr is kept in a
file and printed at teardown, so a failing test shows it. Servers run on the simulated
clock (--sim-clock: as fast as the CPU allows, deterministic) except where the wall
clock is the point (pausing a move, kill -9 mid-move, a deadline fault); the first two
share one wall-clock server so that its calibration and initialization (about 9 s of
real time) are paid once, and it runs a copy of the specification with a "soft" servo
deadline policy so that a busy machine cannot fault their programs (see
soft_deadline_spec). Telemetry is on TCP loopback too, except for the stalled-subscriber
test (ipc: see there).

Two tests pin that a fault of one program (an abort, a deadline fault) does not carry
over to the next program on the same server.

Programs: programs/test.irl (the paper's three moves) and small ones in
tests/server_programs/ (short.irl one quick move, pause.irl two moves of a few seconds,
medium.irl six slow moves, long.irl a slow loop that only ends when stopped).

Time limits in these tests are only safety nets against hanging; no assertion depends
on how fast anything runs.
"""
from __future__ import annotations

import csv
import io
import json
import os
import random
import re
import signal
import socket
import subprocess
import threading
import time
from collections import Counter
from pathlib import Path

import msgpack
import pytest
import zmq

from runtime.wire import protocol
from runtime.client.client import Client, ClientError, Subscriber

from conftest import (  # (the server helpers and fixtures: start_server, server, wall_server)
    ROOT, TEST_IRL, SPEC_PATH as SPEC, SERVER_PROGRAMS as PROGRAMS, IRL, START, CALIBRATE, INITIALIZE, MOVE, STOP, ALL_PHASES, TERMINAL, SAFETY, free_port, objcode, run_irl, no_traceback, ServerProcess, status, wait_for, wait_end, moving, phases, submit,
)
# ---- 1. submit --wait through the CLI --------------------------------------------------------------
def test_submit_wait_report_and_second_program_skips_calibration(server, tmp_path):
    out = tmp_path / "first.csv"
    proc = run_irl("submit", TEST_IRL, "--endpoint", server.endpoint, "--wait", "--report", out)
    assert proc.returncode == 0, proc.stdout + proc.stderr + server.log()
    no_traceback(proc)
    assert "program 1 queued" in proc.stdout
    assert "program 1 completed" in proc.stdout

    with open(out, newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    assert header[:2] == ["time", "state"] and "sens_pos_A1" in header
    assert len(rows) - 1 > 1000
    assert all(len(r) == len(header) for r in rows)
    states = out.with_suffix(".states.csv").read_text()
    assert states.startswith("time,from,to\n")
    visited = [line.split(",")[2] for line in states.splitlines()[1:]]
    assert visited == list(ALL_PHASES)

    out2 = tmp_path / "second.csv"
    proc = run_irl("submit", TEST_IRL, "--endpoint", server.endpoint, "--wait", "--report", out2)
    assert proc.returncode == 0, proc.stdout + proc.stderr + server.log()
    assert "program 2 queued" in proc.stdout and "program 2 completed" in proc.stdout
    visited = [line.split(",")[2] for line in out2.with_suffix(".states.csv").read_text().splitlines()[1:]]
    assert CALIBRATE not in visited and INITIALIZE not in visited
    assert visited == [START, MOVE, STOP]


def test_submit_of_a_program_for_another_specification_names_both_files_and_the_fix(server, tmp_path,
                                                                                    monkeypatch):
    """`irl submit` of a program compiled for other.spc (the same robot, another file) to a
    server that drives programs/lola15.spc: refused with both files named (the server's
    own, the client's) and the commands that fix it; the recompiled program is queued."""
    import shlex

    from compiler.spec import load_spec
    from runtime.cli.main import Environment, main

    def irl(*argv) -> tuple[int, str, str]:
        out, err = io.StringIO(), io.StringIO()
        code = main([str(a) for a in argv], Environment(stdout=out, stderr=err))
        return code, out.getvalue(), err.getvalue()

    other = tmp_path / "other.spc"
    other.write_text(SPEC.read_text(encoding="utf-8").replace("max_velocity = 156.0", "max_velocity = 150.0", 1),
                     encoding="utf-8")
    source = tmp_path / "test.irl"
    source.write_text(TEST_IRL.read_text(encoding="utf-8"), encoding="utf-8")
    obj = tmp_path / "test.irlo"
    assert irl("compile", source, "--spec", other, "-o", obj)[0] == 0
    theirs, ours = load_spec(other), load_spec(SPEC)
    for sent in (obj, source):  # the object file (its spec found beside it), the source compiled for it
        extra = ("--spec", other) if sent == source else ()
        code, out, err = irl("submit", sent, *extra, "--endpoint", server.endpoint)
        assert code == 1 and "Traceback" not in err, err
        assert (f"the program was compiled for specification 'lola_15' ({theirs.hash[:12]}: its file is not known "
                f"to this runtime), but this runtime drives 'lola_15' ({ours.hash[:12]}, {SPEC}): ") in err, err
        assert f"(irl compile test.irl --spec {SPEC})" in err
        assert "submit it to a runtime started with the specification it was compiled for (irl serve --spec " in err
        assert err.rstrip().endswith(f"(wrong_robot); test.irl{'o' if sent == obj else ''} was compiled here "
                                     f"for {other}"), err
    command = shlex.split(re.search(r"\((irl compile [^)]*)\)", err).group(1))
    monkeypatch.chdir(tmp_path)  # (where the source is: the object code names its file, not its folder)
    code, _out, err = irl(*command[1:], "-o", obj)
    assert code == 0, err
    code, out, err = irl("submit", obj, "--endpoint", server.endpoint)
    assert code == 0 and "queued" in out, err


# ---- 2. malformed requests -------------------------------------------------------------------------
def _malformed_requests(rng: random.Random, count: int, good_object: bytes):
    """``count`` malformed requests: (frames, expected reply id, expected error code or None
    when several codes are right)."""
    v = protocol.VERSION
    pack = protocol.pack
    big = protocol.MAX_REQUEST_BYTES
    out = []
    for i in range(count):
        rid = f"m{i}" if i % 2 else i + 1_000_000  # string and integer ids, never reused
        kind = rng.randrange(14)
        if i % 500 == 499:  # 20 over-size messages (the id cannot be read from them)
            oversize = b"\0" * (big + rng.randrange(1, 4096))
            payload = pack({"v": v, "id": rid, "op": "submit", "args": {"object": oversize}})
            out.append(([payload], None, "too_large"))
            continue
        if i % 250 == 7:  # a few that go to the real-time loop and are refused there
            op, args, code = rng.choice([("pause", {}, "refused"), ("resume", {}, "refused"),
                                         ("abort", {}, "refused"), ("abort", {"program": 10**9}, "not_found")])
            out.append(([pack({"v": v, "id": rid, "op": op, "args": args})], rid, code))
            continue
        if kind == 0:  # random bytes
            payload = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 64)))
            try:
                decoded = msgpack.unpackb(payload, raw=False, strict_map_key=True)
            except Exception:
                decoded = None
            if isinstance(decoded, dict):  # valid msgpack by chance: whatever its id says
                candidate = decoded.get("id")
                ok_id = candidate is None or (isinstance(candidate, (int, str))
                                              and not isinstance(candidate, bool))
                out.append(([payload], candidate if ok_id else None, None))
            else:
                out.append(([payload], None, "bad_message"))
        elif kind == 1:  # valid msgpack, not a map
            value = rng.choice([[1, 2, 3], [{"v": v, "op": "hello"}], 7, -1, "hello", None, 3.5, True, b"bin",
                                [], list(range(rng.randrange(50)))])
            out.append(([pack(value)], None, "bad_message"))
        elif kind == 2:  # map without "v"
            out.append(([pack({"id": rid, "op": "hello", "args": {}})], rid, "bad_version"))
        elif kind == 3:  # map without "op"
            out.append(([pack({"v": v, "id": rid, "args": {}})], rid, "bad_request"))
        elif kind == 4:  # wrong version
            bad_v = rng.choice([0, max(protocol.VERSIONS) + 1, -1, "1", True, None, [1], 2**40, "v1"])
            out.append(([pack({"v": bad_v, "id": rid, "op": "hello"})], rid, "bad_version"))
        elif kind == 5:  # unknown op, sometimes huge
            op = rng.choice(["helo", "STATUS", "", "submit ", "op_hello", "__init__",
                             "x" * rng.randrange(1000, 100_000)])
            out.append(([pack({"v": v, "id": rid, "op": op})], rid, "unknown_op"))
        elif kind == 6:  # op of the wrong type
            out.append(([pack({"v": v, "id": rid, "op": rng.choice([1, None, True, ["hello"], b"hello"])})],
                        rid, "bad_request"))
        elif kind == 7:  # arguments of the wrong type (bool where int expected, etc.)
            op, args = rng.choice([
                ("status", {"program": True}), ("status", {"program": "1"}), ("status", {"program": 1.0}),
                ("status", {"program": None}), ("status", {"program": [1]}),
                ("report", {"program": False}), ("report", {"program": 1, "offset": True}),
                ("report", {"program": 1, "offset": "0"}), ("report", {"program": 1, "file": 5}),
                ("report", {}), ("submit", {}), ("submit", {"object": "text, not bin"}),
                ("submit", {"object": 12}), ("submit", {"object": True}),
                ("submit", {"object": good_object, "name": 5}),
                ("override", {"percent": True}), ("override", {"percent": "50"}),
                ("override", {"percent": float("nan")}), ("override", {"percent": float("inf")}),
                ("override", {}), ("override", {"percent": 0}), ("override", {"percent": 100.5}),
                ("call", {"text": 5}), ("call", {"text": b"servo.kp"}), ("call", {"text": None}),
                ("reconfigure", {"name": 3}), ("hello", {"extra": 1}), ("pause", {"now": True}),
                ("abort", {"program": "1"}), ("abort", {"program": True}),
            ])
            out.append(([pack({"v": v, "id": rid, "op": op, "args": args})], rid, "bad_request"))
        elif kind == 8:  # "args" not a map
            out.append(([pack({"v": v, "id": rid, "op": "status", "args": rng.choice([[1], 1, "x", True])})],
                        rid, "bad_request"))
        elif kind == 9:  # huge strings
            n = rng.randrange(10_001, 120_000)
            choice = rng.randrange(3)
            if choice == 0:  # a huge id is not a valid id: no id in the reply
                out.append(([pack({"v": v, "id": "i" * n, "op": "hello"})], None, "bad_request"))
            elif choice == 1:
                out.append(([pack({"v": v, "id": rid, "op": "call", "args": {"text": "servo." + "k" * n}})],
                            rid, "script_error"))
            else:
                out.append(([pack({"v": v, "id": rid, "op": "submit",
                                   "args": {"object": b"IRLO" + b"\x07" * n, "name": "n" * n}})],
                            rid, "invalid_program"))
        elif kind == 10:  # mutated object code
            data = bytearray(good_object)
            for _ in range(rng.randrange(1, 5)):
                pos = rng.randrange(len(data))
                data[pos] = (data[pos] + rng.randrange(1, 256)) % 256
            out.append(([pack({"v": v, "id": rid, "op": "submit", "args": {"object": bytes(data)}})],
                        rid, "invalid_program"))
        elif kind == 11:  # truncated object code
            data = good_object[:rng.randrange(len(good_object))]
            out.append(([pack({"v": v, "id": rid, "op": "submit", "args": {"object": data}})],
                        rid, "invalid_program"))
        elif kind == 12:  # ids of the wrong type
            bad_id = rng.choice([1.5, True, False, [1], {"a": 1}, b"id", "i" * 257])
            out.append(([pack({"v": v, "id": bad_id, "op": "hello"})], None, "bad_request"))
        else:  # extra frames (more than one frame after the envelope), or a valid map truncated
            if rng.randrange(2):
                frames = [b"x", b"y", pack({"v": v, "id": rid, "op": "hello"})]
                out.append((frames, None, "bad_message"))
            else:
                payload = pack({"v": v, "id": rid, "op": "status", "args": {"program": 1}})
                out.append(([payload[:rng.randrange(1, len(payload))]], None, None))
    return out


def test_ten_thousand_malformed_requests(server):
    rng = random.Random(20240607)
    requests = _malformed_requests(rng, 10_000, objcode(TEST_IRL))
    expected_ids = Counter(rid for _frames, rid, _code in requests)
    expected_code = {rid: code for _f, rid, code in requests if rid is not None}
    ctx = zmq.Context.instance()
    sock = ctx.socket(zmq.DEALER)
    sock.setsockopt(zmq.LINGER, 0)
    sock.setsockopt(zmq.RCVHWM, 0)
    sock.setsockopt(zmq.SNDHWM, 0)
    sock.connect(server.endpoint)
    replies = []
    try:
        sent = 0
        for start in range(0, len(requests), 200):
            for frames, _rid, _code in requests[start:start + 200]:
                sock.send_multipart(frames)
                sent += 1
            while len(replies) < sent:
                if not sock.poll(30_000, zmq.POLLIN):
                    pytest.fail(f"{sent - len(replies)} requests of {sent} got no reply\n{server.log()}")
                replies.append(sock.recv_multipart()[-1])
        assert not sock.poll(500, zmq.POLLIN), "more replies than requests"
    finally:
        sock.close(linger=0)

    got_ids = Counter()
    internal = []
    for payload in replies:
        reply = protocol.decode_reply(payload)
        assert reply["ok"] is False, reply
        assert reply["v"] == protocol.VERSION
        code = reply["error"]["code"]
        assert code in protocol.ERRORS, reply
        assert isinstance(reply["error"]["message"], str) and reply["error"]["message"]
        if code == "internal":
            internal.append(reply["error"]["message"])
        rid = reply["id"]
        got_ids[rid] += 1
        if rid is not None and expected_code.get(rid) is not None:
            assert code == expected_code[rid], (rid, reply)
    assert not internal, f"internal errors (server bugs): {internal[:5]}"
    assert len(replies) == len(requests)
    assert got_ids == expected_ids  # every request with an id got exactly one reply, by id
    assert all(count == 1 for rid, count in got_ids.items() if rid is not None)

    assert server.alive(), server.log()
    client = server.client()
    assert client.request("hello")["robot"] == "lola_15"
    program = submit(client, PROGRAMS / "short.irl")
    final = wait_end(client, program, server)
    assert final["state"] == "completed", final
    assert not client.request("status")["queue"]


# ---- 3. clients that go away ----------------------------------------------------------------------
def test_disconnecting_clients_do_not_stop_programs(server):
    medium = PROGRAMS / "medium.irl"
    first_client = Client(server.endpoint, timeout=10)
    first = submit(first_client, PROGRAMS / "short.irl")
    first_client.close()  # gone right after the submit reply

    proc = subprocess.Popen([*IRL, "submit", str(medium), "--endpoint", server.endpoint, "--wait"], cwd=ROOT,
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert " queued on " in line, line + proc.stderr.read()
        second = int(line.split()[1])
        observer = server.client()
        # the CLI client is waiting on a program that is under way when it is killed
        wait_for(observer, second, lambda s: s["state"] == "running", "running", server)
        proc.kill()
        proc.wait()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        proc.stderr.close()

    fresh = server.client()
    for program, moves in ((first, 1), (second, 6)):
        final = wait_end(fresh, program, server)
        assert final["state"] == "completed", final
        assert final["summary"]["fault"] is None
        assert len(final["summary"]["moves"]) == moves


# ---- 6a. pause on the wall clock --------------------------------------------------------------------
@pytest.mark.long  # (a long wall-clock test: started first, not left for the run's tail)
def test_pause_stops_the_robot_and_resume_completes(wall_server):
    client = wall_server.client()
    program = submit(client, PROGRAMS / "pause.irl", wall_server)
    wait_for(client, program, moving, "moving", wall_server, poll=0.05)
    time.sleep(0.5)  # into the first move (about 3 s long)
    assert client.request("pause") == {"program": program, "paused": True}
    s = status(client, program)
    assert s["state"] == "running" and s["paused"] is True
    running = client.request("status")["running"]
    assert running["id"] == program and running["paused"] is True

    def position():
        return client.request("status")["position"]

    def still(a, b) -> bool:  # within a few encoder counts (the readings jitter by one count)
        return max(abs(x - y) for x, y in zip(a, b)) < 0.01

    previous = position()
    deadline = time.monotonic() + 10
    while True:  # the stop ramp: wait until the robot has come to rest on its path
        time.sleep(0.1)
        current = position()
        if still(previous, current):
            break
        assert time.monotonic() < deadline, "the robot did not come to rest after the pause"
        previous = current
    first = position()
    time.sleep(0.3)
    second = position()
    assert still(first, second), (first, second)
    s = status(client, program)
    assert s["state"] == "running" and s["paused"] is True and s["moves_done"] < 2

    assert client.request("resume") == {"program": program, "paused": False}
    final = wait_end(client, program, wall_server)
    assert final["state"] == "completed", final
    assert [m["actual_duration"] is not None for m in final["summary"]["moves"]] == [True, True]
    assert not still(second, final["summary"]["final_position"])


# ---- 4. kill -9, and a deadline fault ------------------------------------------------------------------
def test_kill9_leaves_complete_report_and_state_file(wall_server, start_server):
    client = wall_server.client()
    program = submit(client, PROGRAMS / "long.irl", wall_server)
    s = wait_for(client, program, moving, "moving", wall_server, poll=0.05)
    report = Path(s["report"])
    deadline = time.monotonic() + SAFETY
    while f",{MOVE}," not in report.read_text(encoding="utf-8"):  # rows of the move written
        assert time.monotonic() < deadline, "no Move Robot rows in the report"
        time.sleep(0.05)
    s = status(client, program)
    assert moving(s) and s["moves_done"] < 2, s
    wall_server.kill9()
    assert wall_server.proc.returncode == -signal.SIGKILL

    text = report.read_text(encoding="utf-8")
    assert text.endswith("\n"), "the report ends in a partial row"
    lines = text.splitlines()
    header = lines[0].split(",")
    assert header[:2] == ["time", "state"]
    assert len(lines) >= 2
    for row in csv.reader(io.StringIO(text)):
        assert len(row) == len(header), row
    assert any(row.split(",")[1] == MOVE for row in lines[1:])
    # the state transitions too, written as the program runs (whole lines, up to Move Robot)
    states = report.with_suffix(".states.csv").read_text(encoding="utf-8")
    assert states.endswith("\n"), "the states file ends in a partial row"
    rows = list(csv.reader(io.StringIO(states)))
    assert rows[0] == ["time", "from", "to"] and all(len(row) == 3 for row in rows)
    assert rows[-1][2] == MOVE, rows
    state_file = wall_server.state_dir / "calibration.json"
    data = json.loads(state_file.read_text(encoding="utf-8"))
    assert isinstance(data, dict) and data.get("compensation")

    restarted = start_server(state_dir=wall_server.state_dir, spec=wall_server.spec)
    fresh = restarted.client()
    hello = fresh.request("hello")
    assert hello["pid"] == restarted.proc.pid
    final = wait_end(fresh, submit(fresh, PROGRAMS / "short.irl", restarted), restarted)
    assert final["state"] == "completed", final
    assert phases(final) == [START, INITIALIZE, MOVE, STOP]


def test_program_after_a_deadline_fault_runs(start_server):
    server = start_server(sim_clock=False, whole=True)  # the firm deadline policy of programs/lola15.spc
    client = server.client()
    first = submit(client, PROGRAMS / "long.irl")
    deadline = time.monotonic() + SAFETY
    while True:
        s = status(client, first)
        if s["state"] in TERMINAL or (s["state"] == "running" and s.get("fsm", "").startswith(INITIALIZE)):
            break
        assert time.monotonic() < deadline, s
        time.sleep(0.02)
    if s["state"] == "running":  # stop the loop's process for 0.3 s: 300 deadlines missed
        loop_pid = client.request("hello")["loop_pid"]
        os.kill(loop_pid, signal.SIGSTOP)
        time.sleep(0.3)
        os.kill(loop_pid, signal.SIGCONT)
    final = wait_end(client, first, server)
    assert final["state"] == "faulted" and "deadline" in final["fault"], final

    second = submit(client, PROGRAMS / "short.irl")
    deadline = time.monotonic() + SAFETY
    while True:  # until it is under way past Start Robot, or has ended
        s = status(client, second)
        if s["state"] in TERMINAL or (s["state"] == "running" and s.get("fsm") not in (START, STOP)):
            break
        assert time.monotonic() < deadline, s
        time.sleep(0.01)
    # Start Robot lasts 50 ms: a deadline fault there can only be the previous program's
    assert not (s["state"] == "faulted" and s["fault"].startswith(f"{START}: deadline")), s
    if s["state"] == "running":
        client.request("estop")


# ---- 5. concurrent clients ----------------------------------------------------------------------------
def test_ten_concurrent_clients(server):
    n = 10
    barrier = threading.Barrier(n)
    results: list[dict | BaseException] = [None] * n
    data = objcode(PROGRAMS / "short.irl")

    def worker(k: int) -> None:
        client = Client(server.endpoint, timeout=20)
        try:
            barrier.wait(timeout=30)
            program = client.request("submit", {"object": data, "name": f"client-{k}"})["program"]
            results[k] = wait_end(client, program)
        except BaseException as exc:  # reported by the main thread
            results[k] = exc
        finally:
            client.close()

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(SAFETY)
    assert not any(t.is_alive() for t in threads)
    errors = [r for r in results if isinstance(r, BaseException)]
    assert not errors, errors
    ids = [r["id"] for r in results]
    assert sorted(ids) == list(range(1, n + 1))  # unique
    assert sorted(r["name"] for r in results) == sorted(f"client-{k}" for k in range(n))
    assert all(r["state"] == "completed" for r in results), results
    ordered = sorted(results, key=lambda r: r["id"])
    for before, after in zip(ordered, ordered[1:]):
        assert after["started"] >= before["ended"], (before, after)
    overview = server.client().request("status")
    listed = Counter(p["id"] for p in overview["programs"])
    assert listed == Counter(range(1, n + 1))  # each program ended once
    assert overview["running"] is None and overview["queue"] == []


# ---- 6. control -----------------------------------------------------------------------------------
def test_abort_running_and_queued_programs(server):
    client = server.client()
    running = submit(client, PROGRAMS / "long.irl")
    queued = submit(client, PROGRAMS / "long.irl")
    wait_for(client, running, moving, "moving", server)
    assert status(client, queued)["state"] == "queued"

    assert client.request("abort", {"program": queued}) == {"program": queued, "state": "cancelled"}
    assert status(client, queued)["state"] == "cancelled"
    with pytest.raises(ClientError) as err:
        client.request("abort", {"program": 10_000})
    assert err.value.code == "not_found"

    assert client.request("abort") == {"program": running, "state": "aborting"}
    final = wait_end(client, running, server)
    assert final["state"] == "aborted", final
    assert "aborted by the operator" in final["fault"]
    assert client.request("status")["queue"] == []


def test_program_after_an_abort_completes(server):
    client = server.client()
    program = submit(client, PROGRAMS / "long.irl")
    wait_for(client, program, moving, "moving", server)
    client.request("abort")
    assert wait_end(client, program, server)["state"] == "aborted"
    final = wait_end(client, submit(client, PROGRAMS / "short.irl"), server)
    assert final["state"] == "completed", final


def test_estop_ends_the_program_and_cancels_the_queue(server):
    client = server.client()
    running = submit(client, PROGRAMS / "long.irl")
    queued = [submit(client, PROGRAMS / "short.irl"), submit(client, PROGRAMS / "long.irl")]
    wait_for(client, running, moving, "moving", server)
    assert client.request("estop") == {"program": running, "cancelled": queued}
    final = wait_end(client, running, server)
    assert final["state"] != "completed" and final["state"] in TERMINAL, final
    assert "emergency stop" in final["fault"]
    for program in queued:
        s = status(client, program)
        assert s["state"] == "cancelled" and "emergency stop" in s["fault"], s
    overview = client.request("status")
    assert overview["running"] is None and overview["queue"] == []


def test_override_and_refusals(server):
    client = server.client()
    assert client.request("override", {"percent": 50}) == {"override": 50.0}
    assert client.request("status")["override"] == 50.0
    for bad in (0, 150, -5, 100.01):
        with pytest.raises(ClientError) as err:
            client.request("override", {"percent": bad})
        assert err.value.code == "bad_request", bad
    assert client.request("status")["override"] == 50.0
    for op in ("pause", "resume", "abort"):
        with pytest.raises(ClientError) as err:
            client.request(op)
        assert err.value.code == "refused", op
    proc = run_irl("pause", "--endpoint", server.endpoint)
    assert proc.returncode == 1 and "refused" in proc.stderr, proc.stderr
    no_traceback(proc)
    proc = run_irl("override", "150", "--endpoint", server.endpoint)
    assert proc.returncode == 1 and "bad_request" in proc.stderr, proc.stderr
    proc = run_irl("override", "75", "--endpoint", server.endpoint)
    assert proc.returncode == 0 and "override 75 %" in proc.stdout, proc.stdout + proc.stderr


# ---- 7. scripting ---------------------------------------------------------------------------------
def test_scripting_call_and_console(server):
    e = ("--endpoint", server.endpoint)
    proc = run_irl("call", "servo.kp", *e)
    assert proc.returncode == 0 and proc.stdout.strip() == "servo.kp = 40.0", proc.stdout + proc.stderr
    proc = run_irl("call", "servo.kp = 30", *e)  # safety-relevant: only by a whole configuration
    assert proc.returncode == 1 and "refused" in proc.stderr and "safety-relevant" in proc.stderr, proc.stderr
    assert "irl reconfigure" in proc.stderr
    proc = run_irl("call", "servo.kp", *e)
    assert proc.returncode == 0 and proc.stdout.strip() == "servo.kp = 40.0", proc.stdout + proc.stderr
    proc = run_irl("call", "trajectory.budget = 500", *e)  # a live parameter
    assert proc.returncode == 0 and proc.stdout.strip() == "trajectory.budget = 500", proc.stdout + proc.stderr
    proc = run_irl("call", "trajectory.budget = 0", *e)  # out of its range: refused, nothing stored
    assert proc.returncode == 1 and "bad_request" in proc.stderr, proc.stderr
    assert "trajectory.budget: expected an integer 1 <= x <= 10000 (instructions), got 0" in proc.stderr
    proc = run_irl("call", "trajectory.budget", *e)
    assert proc.returncode == 0 and proc.stdout.strip() == "trajectory.budget = 500", proc.stdout + proc.stderr
    proc = run_irl("call", "trajectory.budget = 200", *e)
    assert proc.returncode == 0

    proc = run_irl("call", "servo.nope", *e)
    assert proc.returncode == 1
    assert "servo has no property 'nope'" in proc.stderr and "kp" in proc.stderr, proc.stderr
    no_traceback(proc)
    proc = run_irl("call", "servo.kp = ", *e)
    assert proc.returncode == 1
    assert "column" in proc.stderr and "script_error" in proc.stderr, proc.stderr
    no_traceback(proc)

    proc = run_irl("console", *e, stdin="components\nhelp servo\nservo.ki\nquit\n")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    no_traceback(proc)
    out = proc.stdout
    listed = [line.split()[0] for line in out.splitlines() if line and not line.startswith(("connected", " "))]
    for name in ("robot", "servo", "initialization", "trajectory", "report", "fsm"):
        assert name in listed, out
    assert "kp = 40.0" in out and "ki = 2.0" in out  # help servo
    assert "servo.ki = 2.0" in out.splitlines()


# ---- 8. telemetry ---------------------------------------------------------------------------------
def test_telemetry_watch(server):
    # long.irl only ends when stopped: it is still moving however long the watch takes to start
    client = server.client()
    program = submit(client, PROGRAMS / "long.irl")
    wait_for(client, program, moving, "moving", server, poll=0.01)
    proc = run_irl("watch", "--json", "--count", 20, "--timeout", 20, "--telemetry", server.telemetry)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    no_traceback(proc)
    messages = [json.loads(line) for line in proc.stdout.splitlines()]
    assert len(messages) == 20
    seqs = [m["seq"] for m in messages]
    assert all(b > a for a, b in zip(seqs, seqs[1:])), seqs
    assert {m["kind"] for m in messages} <= {"sample", "event"}
    assert all(m["v"] == protocol.VERSION and isinstance(m["t"], (int, float)) for m in messages)
    samples = [m for m in messages if m["kind"] == "sample"]
    assert samples and all(len(m["position"]) == 6 for m in samples)
    assert any(m["program"] == program for m in samples), messages
    client.request("abort", {"program": program})
    assert wait_end(client, program, server)["state"] == "aborted"


def test_subscriber_that_never_reads_does_not_stop_a_program(start_server, tmp_path):
    # Telemetry on an ipc endpoint: over TCP loopback the kernel's autotuned buffers
    # (~3.4 MB here, ~14,000 messages) would swallow a whole program's telemetry, and the
    # server's PUB queue would never fill; a Unix socket's buffers are small, so it does.
    server = start_server(telemetry=f"ipc://{tmp_path}/telemetry")
    ctx = zmq.Context.instance()
    stalled = ctx.socket(zmq.SUB)
    stalled.setsockopt(zmq.LINGER, 0)
    stalled.setsockopt(zmq.RCVHWM, 1)
    stalled.setsockopt(zmq.SUBSCRIBE, protocol.TELEMETRY_TOPIC)
    stalled.connect(server.telemetry)
    try:
        # subscribed once a message waits (idle samples come every 0.5 s); then never read
        assert stalled.poll(10_000, zmq.POLLIN), "no telemetry at all"
        client = server.client()
        program = submit(client, PROGRAMS / "medium.irl")
        final = wait_end(client, program, server)
        assert final["state"] == "completed", final
        assert server.alive()

        second = Subscriber(server.telemetry)
        try:
            got = [second.receive(5.0) for _ in range(2)]
        finally:
            second.close()
        assert all(m is not None for m in got), got
        last = got[-1]["seq"]

        # the stalled subscriber's queue did fill: the server dropped messages for it
        # (a gap in its sequence numbers) instead of waiting for it
        # (drained to the first message sent after the second subscriber's: what was
        # queued for it, then idle samples; no time limit on the draining but SAFETY, which
        # a busy machine could otherwise cut short before the gap)
        seqs: list[int] = []
        while not seqs or seqs[-1] <= last:
            assert stalled.poll(int(SAFETY * 1000), zmq.POLLIN), \
                f"the drained subscriber gets no new telemetry after {seqs[-3:]} (last seq {last})"
            seqs.append(protocol.decode_telemetry(stalled.recv_multipart()[1])["seq"])
        assert seqs == sorted(seqs)
        assert any(b > a + 1 for a, b in zip(seqs, seqs[1:])), \
            f"no messages were dropped: the subscriber did not stall ({len(seqs)} received, last seq {last})"
        assert len(seqs) < last < seqs[-1]
    finally:
        stalled.close(linger=0)


# ---- 9. CURVE -------------------------------------------------------------------------------------
def test_curve_keys(start_server, tmp_path):
    keys, other = tmp_path / "keys", tmp_path / "other"
    for d in (keys, other):
        proc = run_irl("keys", d)
        assert proc.returncode == 0, proc.stderr
        assert (d / "server.key_secret").is_file() and (d / "client.key_secret").is_file()
        assert list((d / "authorized").glob("*.key"))
    server = start_server(keys=keys)
    good = server.client(keys=keys)
    assert good.request("hello")["robot"] == "lola_15"

    plain = Client(server.endpoint, timeout=1.0)
    try:
        with pytest.raises(ClientError) as err:
            plain.request("hello")
        assert err.value.code == "unreachable"
    finally:
        plain.close()
    stranger = Client(server.endpoint, keys=other, timeout=1.0)
    try:
        with pytest.raises(ClientError) as err:
            stranger.request("hello")
        assert err.value.code == "unreachable"
    finally:
        stranger.close()

    proc = run_irl("status", "--endpoint", server.endpoint, "--keys", keys, "--json")
    assert proc.returncode == 0 and json.loads(proc.stdout)["state"] == "Idle", proc.stderr
    assert good.request("hello")["robot"] == "lola_15"  # still serving the keyed client
    assert server.alive()

    # the server's own handshake handler (runtime.server.connections) guards the telemetry too
    subscribers = [Subscriber(server.telemetry, keys=keys), Subscriber(server.telemetry, keys=other),
                   Subscriber(server.telemetry)]
    try:
        assert subscribers[0].receive(10.0) is not None
        assert subscribers[1].receive(1.0) is None and subscribers[2].receive(0.1) is None
    finally:
        for sub in subscribers:
            sub.close()
    # control is the connection's, not the key's: another connection with the same key is
    # refused, unless it sends the token
    token = good.request("control", {"take": True, "lease": 60})["token"]
    same_key = server.client(keys=keys)
    with pytest.raises(ClientError) as err:
        same_key.request("override", {"percent": 50})
    assert err.value.code == "refused"
    same_key.token = token
    assert same_key.request("override", {"percent": 50}) == {"override": 50.0}


# ---- 10. bad input from the CLI ---------------------------------------------------------------------
def test_cli_bad_inputs_without_tracebacks(tmp_path):
    unused = f"tcp://127.0.0.1:{free_port()}"
    proc = run_irl("submit", PROGRAMS / "syntax_error.irl", "--endpoint", unused, "--wait")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "syntax_error.irl:4:46: error: unexpected 'speed_ptp'" in proc.stderr, proc.stderr
    no_traceback(proc)

    proc = run_irl("status", "--endpoint", unused, "--timeout", "0.5")
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "no reply" in proc.stderr
    no_traceback(proc)

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        proc = run_irl("serve", "--spec", SPEC, "--sim-clock", "--state-dir", tmp_path / "state",
                       "--endpoint", f"tcp://127.0.0.1:{port}", "--telemetry", f"tcp://127.0.0.1:{free_port()}",
                       timeout=30)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "cannot bind" in proc.stderr
    no_traceback(proc)


# ---- SIGTERM / SIGINT while a program runs ---------------------------------------------------------
class Events:
    """Every telemetry event, collected by a thread of its own (a subscriber that keeps up)."""

    def __init__(self, endpoint: str):
        from runtime.client.client import Subscriber

        self.subscriber = Subscriber(endpoint)
        self.events: list[dict] = []
        self.subscribed = threading.Event()  # set by the first message: the subscription has reached the server
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._collect, daemon=True)
        self.thread.start()

    def _collect(self) -> None:
        while not self.stop.is_set():
            message = self.subscriber.receive(0.05)
            if message is not None:
                self.subscribed.set()
            if message is not None and message["kind"] == "event":
                self.events.append(message)

    def until(self, predicate, seconds: float = 10.0) -> list[dict]:
        """The events once ``predicate(events)`` holds (or after ``seconds``: a safety net)."""
        deadline = time.monotonic() + seconds
        while not predicate(self.events) and time.monotonic() < deadline:
            time.sleep(0.02)
        self.stop.set()
        self.thread.join(5)
        self.subscriber.close()
        return self.events


@pytest.mark.parametrize("moments", [
    [(MOVE, signal.SIGTERM), (INITIALIZE, signal.SIGINT), (None, signal.SIGTERM), (MOVE, signal.SIGINT)]])
def test_sigterm_or_sigint_while_a_program_runs_exits_0_cancels_the_queue_and_keeps_the_calibration(tmp_path,
                                                                                                    moments):
    """Issue 26, fault 4: a signal at several moments of a running program (in Move Robot,
    during homing, at once after the submission), with programs queued: `irl serve` exits
    0; each queued program gets its `cancelled` event; the running one's report and states
    file are complete to the end of Stop Robot; and the next server on the same state
    directory says from the start that it is calibrated (the first run's calibration)."""
    state = tmp_path / "state"
    for k, (moment, sig) in enumerate(moments):
        server = ServerProcess(tmp_path / f"server{k}", state).start()
        try:
            client = server.client()
            if k > 0:  # a restart on the same state directory
                overview = client.request("status")
                assert overview["calibrated"] is True and overview["calibration"].startswith("calibrated: loaded"), \
                    overview
            events = Events(server.telemetry)
            assert events.subscribed.wait(SAFETY), "no telemetry (an idle sample comes every 0.5 s)"
            running = submit(client, PROGRAMS / "long.irl")
            queued = [submit(client, PROGRAMS / "short.irl"), submit(client, PROGRAMS / "medium.irl")]
            if moment is not None:
                wait_for(client, running, lambda s: s.get("fsm", "").startswith(moment), f"in {moment}", server,
                         poll=0.005)
            report = Path(status(client, running)["report"])
            server.proc.send_signal(sig)
            try:
                code = server.proc.wait(60)
            except subprocess.TimeoutExpired:
                pytest.fail(f"irl serve did not end within 60 s of {sig.name}:\n{server.log()}")
            assert code == 0, f"{sig.name} at {moment}: exit {code}\n{server.log()}"
            assert "Traceback" not in server.log() and "internal error" not in server.log(), server.log()
            seen = events.until(lambda evs: any(e["event"] == "shutdown" for e in evs))
            ended = {e["program"]: e for e in seen if e["event"] == "program" and e["state"] != "running"}
            for program in queued:
                assert ended.get(program, {}).get("state") == "cancelled", (program, seen)
                assert "shutting down" in ended[program]["fault"], ended[program]
            if report.exists():  # (a signal before the program started: it had no cycle)
                rows = list(csv.reader(io.StringIO(report.read_text(encoding="utf-8"))))
                header = rows[0]
                assert all(len(row) == len(header) for row in rows), "a partial row"
                velocities = [i for i, name in enumerate(header) if name.startswith("out_vel_")]
                transitions = list(csv.reader(io.StringIO(report.with_suffix(".states.csv").read_text())))
                assert transitions[-1][2] == STOP, (k, moment, transitions, server.log())
                if len(rows) == 1:  # the report starts in Calibrate Offsets: a cycle stopped before has no rows
                    assert moment is None and [t[2] for t in transitions[1:]] == ["Start Robot", STOP], \
                        (k, transitions, server.log())
                    continue
                last = rows[-1]
                assert last[1] == STOP and all(float(last[i]) == 0.0 for i in velocities), (k, moment, last, server.log())
                assert float(last[0]) >= float(transitions[-1][0]), transitions
            else:
                assert moment is None, f"no report of program {running}"
        finally:
            server.stop()
    restarted = ServerProcess(tmp_path / "last", state).start()
    try:
        overview = restarted.client().request("status")
        assert overview["calibrated"] is True, overview
    finally:
        assert restarted.stop() == 0, restarted.log()
