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
