"""Protocol version 2 (issue 16, item 2), from docs/protocol.md alone: version 1 clients
are still served; `wait` answers when a program ends; `telemetry` replays what a
subscriber missed; pause and resume name the program they mean."""
from __future__ import annotations

import time
from pathlib import Path

import msgpack
import zmq

from test_server import PROGRAMS, ServerProcess, objcode

ROOT = Path(__file__).resolve().parents[1]


class RawClient:
    """A client written from docs/protocol.md: a DEALER socket, msgpack maps, an empty
    delimiter frame (the envelope), replies matched by id."""

    def __init__(self, endpoint: str, version: int):
        self.sock = zmq.Context.instance().socket(zmq.DEALER)
        self.sock.connect(endpoint)
        self.version = version
        self.next_id = 0
        self.early: dict = {}

    def send(self, op: str, **args) -> int:
        self.next_id += 1
        self.sock.send_multipart([b"", msgpack.packb({"v": self.version, "id": self.next_id, "op": op,
                                                     "args": args})])
        return self.next_id

    def reply(self, request_id: int, timeout: float = 30.0) -> dict:
        deadline = time.monotonic() + timeout
        while request_id not in self.early:
            left = deadline - time.monotonic()
            assert left > 0 and self.sock.poll(int(left * 1000)), f"no reply to {request_id}"
            message = msgpack.unpackb(self.sock.recv_multipart()[-1], raw=False)
            self.early[message["id"]] = message
        return self.early.pop(request_id)

    def call(self, op: str, **args) -> dict:
        return self.reply(self.send(op, **args))

    def close(self):
        self.sock.close(linger=0)


def test_version_1_and_2_clients_on_one_server_and_wait_and_replay(tmp_path):
    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=True).start()
    old, new = RawClient(server.endpoint, 1), RawClient(server.endpoint, 2)
    try:
        hello = old.call("hello")
        assert hello["v"] == 1 and hello["ok"] and hello["result"]["protocols"] == [1, 2]
        refused = old.call("wait", program=1)
        assert refused["v"] == 1 and refused["error"]["code"] == "unknown_op" and "version 2" in \
            refused["error"]["message"]

        # wait: one request, answered when the program has ended, others answered meanwhile
        job = new.call("submit", object=objcode(PROGRAMS / "short.irl"))["result"]["program"]
        waiting = new.send("wait", program=job, timeout=120)
        status = new.call("status")
        assert status["ok"] and status["v"] == 2
        ended = new.reply(waiting, timeout=120)
        assert ended["ok"] and ended["result"]["state"] == "completed" and "summary" in ended["result"]
        again = new.call("wait", program=job, timeout=0.1)  # (ended already: answered at once)
        assert again["result"]["state"] == "completed" and "timed_out" not in again["result"]
        queued_job = new.call("submit", object=objcode(PROGRAMS / "short.irl"))["result"]["program"]
        early = new.call("wait", program=queued_job, timeout=0.05)
        assert early["ok"] and (early["result"].get("timed_out") or early["result"]["state"] == "completed")
        assert new.call("wait", program=10**6)["error"]["code"] == "not_found"
        assert new.call("wait", program=job, timeout=0)["error"]["code"] == "bad_request"
        new.reply(new.send("wait", program=queued_job, timeout=120), timeout=120)

        # telemetry replay after a deliberate gap: nothing subscribed at all, everything recovered
        latest = new.call("telemetry")["result"]
        assert latest["seq"] > 100 and latest["sample"]["kind"] == "sample"
        replay = new.call("telemetry", since=0)["result"]
        seqs = [m["seq"] for m in replay["messages"]]
        assert seqs == list(range(1 + replay["missing"], 1 + replay["missing"] + len(seqs)))
        got, since = list(replay["messages"]), seqs[-1]
        while replay["more"]:
            replay = new.call("telemetry", since=since)["result"]
            got += replay["messages"]
            since = got[-1]["seq"]
        events = [m for m in got if m["kind"] == "event" and m["event"] == "program"]
        assert [e["state"] for e in events if e["program"] == job] == ["running", "completed"]
        assert new.call("telemetry", since=latest["seq"] + 10**6)["error"]["code"] == "bad_request"
    finally:
        old.close()
        new.close()
        assert server.stop() == 0, server.log()


def test_pause_names_its_program_and_a_second_pause_is_refused(tmp_path):
    from test_server import moving, soft_deadline_spec, wait_for

    spec = soft_deadline_spec(tmp_path)
    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=False, spec=spec).start()
    client = RawClient(server.endpoint, 2)
    try:
        job = client.call("submit", object=objcode(PROGRAMS / "long.irl", spec))["result"]["program"]
        wait_for(server.client(), job, moving, "moving", server)
        other = client.call("pause", program=job + 1)
        assert other["error"]["code"] == "refused" and f"program {job + 1} is not the running program" in \
            other["error"]["message"]
        assert client.call("pause", program=job)["ok"]
        again = client.call("pause", program=job)
        assert again["error"]["code"] == "refused" and "already paused" in again["error"]["message"]
        assert client.call("resume", program=job)["ok"]
        aborted = client.call("abort", program=job)
        assert aborted["ok"]
        final = client.call("wait", program=job, timeout=60)["result"]
        assert final["state"] == "aborted" and final["fault"].startswith("Move Robot: aborted by the operator at "
                                                                         "line "), final
    finally:
        client.close()
        assert server.stop() == 0, server.log()


def test_one_controlling_client_at_a_time_observers_read_and_estop_and_the_lease_ends_control(tmp_path):
    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=True).start()
    owner, other = RawClient(server.endpoint, 2), RawClient(server.endpoint, 2)
    try:
        taken = owner.call("control", take=True, name="cell PLC gateway", lease=1.0)["result"]
        assert taken == {"control": True, "name": "cell PLC gateway", "lease": 1.0}
        assert other.call("status")["result"]["control"] == "cell PLC gateway"
        for op, args in (("submit", {"object": objcode(PROGRAMS / "short.irl")}), ("pause", {}),
                         ("override", {"percent": 50}), ("call", {"text": "trajectory.budget = 500"}),
                         ("control", {"take": True})):
            refused = other.call(op, **args)
            assert refused["error"]["code"] == "refused" and "cell PLC gateway" in refused["error"]["message"], op
        assert other.call("call", text="trajectory.budget")["ok"]  # a read
        assert other.call("estop")["ok"]  # open to everyone
        job = owner.call("submit", object=objcode(PROGRAMS / "short.irl"))["result"]["program"]
        assert owner.call("wait", program=job, timeout=120)["result"]["state"] == "completed"
        assert owner.call("control", take=False)["result"] == {"control": False}
        assert other.call("override", percent=80)["ok"]  # nobody holds it: everyone controls

        assert owner.call("control", take=True, lease=0.5)["ok"]
        assert other.call("override", percent=70)["error"]["code"] == "refused"
        time.sleep(0.8)  # the holder sends nothing: its lease ends
        assert other.call("override", percent=60)["ok"]
        assert other.call("status")["result"]["control"] is None
        assert owner.call("control", take=True, lease=0.1)["error"]["code"] == "bad_request"
        v1 = RawClient(server.endpoint, 1)
        assert v1.call("control", take=True)["error"]["code"] == "unknown_op"
        v1.close()
    finally:
        owner.close()
        other.close()
        assert server.stop() == 0, server.log()


def test_framing_the_envelope_and_malformed_ids_are_answered_unambiguously(tmp_path):
    """docs/protocol.md, Transport and Replies: a request is the last frame, alone or after
    an envelope that ends with an empty frame; the reply comes back with that envelope; any
    other framing, and an id the server cannot echo, get an error whose id is nil."""
    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=True).start()
    sock = zmq.Context.instance().socket(zmq.DEALER)
    sock.connect(server.endpoint)

    def exchange(*frames):
        sock.send_multipart(list(frames))
        assert sock.poll(10_000), f"no reply to {frames!r}"
        reply = sock.recv_multipart()
        return reply[:-1], msgpack.unpackb(reply[-1], raw=False)

    def status(request_id=1, **extra):
        return msgpack.packb({"v": 2, "id": request_id, "op": "status", **extra})

    try:
        envelope, reply = exchange(status(1))  # a DEALER: the request alone
        assert envelope == [] and reply["ok"] and reply["id"] == 1
        envelope, reply = exchange(b"", status(2))  # a REQ's delimiter
        assert envelope == [b""] and reply["ok"] and reply["id"] == 2
        envelope, reply = exchange(b"proxy-7", b"", status(3))  # a client behind a proxy
        assert envelope == [b"proxy-7", b""] and reply["ok"] and reply["id"] == 3
        envelope, reply = exchange(b"not-a-delimiter", status(4))  # not one request
        assert envelope == [] and reply["id"] is None and reply["error"]["code"] == "bad_message"
        assert "got 2 frames" in reply["error"]["message"]
        for bad_id, shown in ((1.5, "float 1.5"), ([1], "list [1]"), (True, "bool True"), ("x" * 300, "300")):
            envelope, reply = exchange(msgpack.packb({"v": 2, "id": bad_id, "op": "status"}))
            assert reply["id"] is None and reply["error"]["code"] == "bad_request", reply
            assert shown in reply["error"]["message"] and "id is nil" in reply["error"]["message"]
        _, reply = exchange(msgpack.packb({"v": 9, "id": "mine", "op": "status"}))  # the id read: echoed
        assert reply["id"] == "mine" and reply["error"]["code"] == "bad_version" and reply["v"] == 2
        _, reply = exchange(b"\xc1")  # not msgpack: nothing could be read
        assert reply["id"] is None and reply["error"]["code"] == "bad_message"
        assert server.client().request("status")["state"] == "Idle"  # and it keeps serving
    finally:
        sock.close(linger=0)
        assert server.stop() == 0, server.log()


def test_a_feed_sends_the_fields_asked_for_at_the_rate_asked_for(tmp_path):
    """docs/protocol.md, ``feed``: a subscriber chooses sample fields and a rate (as RTDE
    does), subscribes to the topic the reply names, and gets those fields only, at that
    rate of the robot's clock, numbered so that a loss shows."""
    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=True).start()
    client = RawClient(server.endpoint, 2)
    sub = zmq.Context.instance().socket(zmq.SUB)
    try:
        old = RawClient(server.endpoint, 1).call("feed", fields=["position"])
        assert old["error"]["code"] == "unknown_op"
        bad = client.call("feed", fields=["postion"])["error"]
        assert bad["code"] == "bad_request" and "did you mean 'position'" in bad["message"]
        assert client.call("feed", fields=["line"], rate=1000)["error"]["code"] == "bad_request"
        assert client.call("feed", fields=[])["error"]["code"] == "bad_request"
        feed = client.call("feed", fields=["line", "position"], rate=10, events=True)["result"]
        assert feed["fields"] == ["position", "line"] and feed["rate"] == 10 and feed["topic"].startswith("feed:")
        same = client.call("feed", fields=["position", "line"], rate=10.0, events=True)["result"]
        assert same["topic"] == feed["topic"]  # the same feed, shared
        other = client.call("feed", fields=["position"], rate=10)["result"]
        assert other["topic"] != feed["topic"]
        sub.connect(server.telemetry)
        sub.subscribe(feed["topic"].encode())
        time.sleep(0.5)  # (the subscription reaches the server)
        job = client.call("submit", object=objcode(PROGRAMS / "short.irl"))["result"]["program"]
        messages = []
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if not sub.poll(1000):
                continue
            topic, payload = sub.recv_multipart()
            assert topic == feed["topic"].encode()
            message = msgpack.unpackb(payload, raw=False)
            messages.append(message)
            if message.get("event") == "program" and message["state"] == "completed":
                break
        assert [m["feed_seq"] for m in messages] == list(range(messages[0]["feed_seq"],
                                                               messages[0]["feed_seq"] + len(messages)))
        running = [m for m in messages if m["kind"] == "sample" and m.get("line") is not None]
        assert len(running) > 5, messages[:5]
        for m in running:
            assert set(m) == {"v", "seq", "feed_seq", "t", "kind", "position", "line"}, m
        gaps = [b["t"] - a["t"] for a, b in zip(running, running[1:])]
        assert all(0.095 <= g <= 0.105 for g in gaps), gaps  # 10 per second of the robot's clock
        events = [m for m in messages if m["kind"] == "event" and m["event"] == "program"]
        assert [e["state"] for e in events if e["program"] == job][-1] == "completed"
    finally:
        sub.close(linger=0)
        client.close()
        assert server.stop() == 0, server.log()


def test_a_cancelled_program_is_said_on_telemetry(tmp_path):
    """Every program that will not run any more has its ``program`` event: a queued one
    removed by abort is ``cancelled``; aborting one that has ended is refused, saying so."""
    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=True).start()
    client = RawClient(server.endpoint, 2)
    try:
        first = client.call("submit", object=objcode(PROGRAMS / "medium.irl"))["result"]["program"]
        second = client.call("submit", object=objcode(PROGRAMS / "short.irl"))["result"]["program"]
        assert client.call("abort", program=second)["result"] == {"program": second, "state": "cancelled"}
        client.call("wait", program=first, timeout=120)
        replay = client.call("telemetry", since=0)["result"]
        events = [m for m in replay["messages"] if m["kind"] == "event" and m["event"] == "program"
                  and m["program"] == second]
        assert [(e["state"], e["fault"]) for e in events] == [("cancelled", "removed from the queue by the operator")]
        from runtime.protocol import SAMPLE_FIELDS  # every field a sample has is declared (and documented)

        samples = [m for m in replay["messages"] if m["kind"] == "sample"]
        assert any("line" in m for m in samples)
        assert set().union(*samples) - {"v", "seq", "t", "kind"} <= set(SAMPLE_FIELDS)
        ended = client.call("abort", program=first)["error"]
        assert ended["code"] == "refused" and f"program {first} has already ended (completed)" in ended["message"]
        assert client.call("abort", program=999)["error"]["code"] == "not_found"
    finally:
        client.close()
        assert server.stop() == 0, server.log()
