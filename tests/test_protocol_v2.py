"""Protocol version 2 (issue 16, item 2), from docs/protocol.md alone: version 1 clients
are still served; `wait` answers when a program ends; `telemetry` replays what a
subscriber missed; pause and resume name the program they mean."""
from __future__ import annotations

import time
from pathlib import Path

import msgpack
import zmq

from runtime.wire import protocol
from conftest import SERVER_PROGRAMS as PROGRAMS, ServerProcess, objcode

from conftest import ROOT, examples


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
    from conftest import moving, soft_deadline_spec, wait_for

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
        assert taken == {"control": True, "name": "cell PLC gateway", "lease": 1.0, "token": taken["token"]}
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
        from runtime.wire.protocol import SAMPLE_FIELDS  # every field a sample has is declared (and documented)

        samples = [m for m in replay["messages"] if m["kind"] == "sample"]
        assert any("line" in m for m in samples)
        assert set().union(*samples) - {"v", "seq", "t", "kind"} <= set(SAMPLE_FIELDS)
        ended = client.call("abort", program=first)["error"]
        assert ended["code"] == "refused" and f"program {first} has already ended (completed)" in ended["message"]
        assert client.call("abort", program=999)["error"]["code"] == "not_found"
    finally:
        client.close()
        assert server.stop() == 0, server.log()


def _dealer(endpoint: str, routing_id: bytes | None = None):
    sock = zmq.Context.instance().socket(zmq.DEALER)
    if routing_id is not None:
        sock.setsockopt(zmq.ROUTING_ID, routing_id)
    sock.connect(endpoint)
    return sock


def _ask(sock, request_id, op: str, wait: float = 10.0, **extra) -> dict | None:
    """One request on a raw DEALER (``extra``: more fields of the request map); the reply,
    or None when none came within ``wait`` seconds."""
    sock.send(msgpack.packb({"v": 2, "id": request_id, "op": op, **extra}))
    while sock.poll(int(wait * 1000)):
        reply = msgpack.unpackb(sock.recv(), raw=False)
        if reply["id"] == request_id:
            return reply
    return None


def test_control_is_bound_to_the_connection_and_its_token_not_to_a_routing_id_a_client_can_copy(tmp_path):
    """Issue 26, fault 3: a client that copies the holder's ZeroMQ routing id onto its own
    socket does not become the holder; status shows no id or token; the token that
    ``take`` returned makes a request the holder's from any connection."""
    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=True).start()
    observer = RawClient(server.endpoint, 2)
    holder = _dealer(server.endpoint, b"hmi-1")
    thieves = []
    try:
        taken = _ask(holder, 1, "control", args={"take": True, "lease": 60})["result"]
        token = taken["token"]
        assert taken["control"] and isinstance(token, str) and len(token) >= 32
        shown = observer.call("status")["result"]
        text = repr(shown)
        assert shown["control"] and token not in text and "hmi-1" not in text and b"hmi-1".hex() not in text

        # the holder still connected: a thief on the holder's routing id takes the id over
        # (ZeroMQ's handover: the holder's socket is disconnected and reconnects), not control
        thief = _dealer(server.endpoint, b"hmi-1")
        thieves.append(thief)
        stolen = _ask(thief, 100, "override", args={"percent": 5})
        assert stolen["error"]["code"] == "refused" and "client #1 holds control" in stolen["error"]["message"]
        keeper = _dealer(server.endpoint)  # the holder's token, from anywhere: control is intact
        thieves.append(keeper)
        assert _ask(keeper, 2, "override", args={"percent": 90}, token=token)["result"] == {"override": 90.0}

        # the holder gone (a CLI process that took control and exited): its id copied again
        holder.close(linger=0)
        thief2 = _dealer(server.endpoint, b"hmi-1")
        thieves.append(thief2)
        copied = _ask(thief2, 200, "override", args={"percent": 5})
        assert copied["error"]["code"] == "refused" and "client #1 holds control" in copied["error"]["message"]
        assert observer.call("status")["result"]["override"] == 90.0

        # the token makes any connection's request the holder's; a wrong one does not
        other = _dealer(server.endpoint)
        thieves.append(other)
        bad = _ask(other, 1, "override", args={"percent": 10}, token="x" * 32)
        assert bad["error"]["code"] == "refused" and "token" in bad["error"]["message"]
        assert _ask(other, 2, "override", args={"percent": 80}, token=token)["result"] == {"override": 80.0}
        assert _ask(other, 3, "control", args={"take": False}, token=token)["result"] == {"control": False}
        assert observer.call("status")["result"]["control"] is None
    finally:
        for sock in thieves:
            sock.close(linger=0)
        holder.close(linger=0)
        observer.close()
        assert server.stop() == 0, server.log()


from hypothesis import example, given, settings, strategies as st  # noqa: E402


@given(st.lists(st.binary(min_size=1, max_size=4), max_size=24), st.booleans())
@example([b"hop"] * 15, True)
@example([b"hop"] * 16, True)
def test_an_envelope_of_at_most_16_frames_is_a_request_and_a_longer_one_is_not(hops, delimited):
    """docs/protocol.md, Framing: a request frame alone, or after an envelope of at most
    MAX_ENVELOPE_FRAMES frames whose last is the empty delimiter; the reply goes back with
    that envelope. Anything else is not a request."""
    from runtime.wire.protocol import MAX_ENVELOPE_FRAMES
    from runtime.server.server import envelope

    assert MAX_ENVELOPE_FRAMES == 16
    frames = [b"peer", *hops, *([b""] if delimited else []), b"request"]
    count = len(hops) + 1 if delimited else len(hops)  # the envelope's frames
    head, payload = envelope(frames)
    if count == 0 or (delimited and count <= MAX_ENVELOPE_FRAMES):
        assert payload == b"request" and head == frames[:-1]
    else:
        assert payload is None and head == [b"peer"]


def test_every_answer_the_protocol_document_gives_is_the_running_servers(tmp_path):
    """Issue 26, fault 9: what docs/protocol.md says a client gets, checked against a
    running server: ids signed and unsigned, the envelope's limit, the range of ``since``,
    the feed topic format, a non-holder's ``take: false``, ``estop`` and control, the
    ``v`` of a ``bad_version`` reply, a version-1 request for a version-2 operation."""
    import re

    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=True).start()
    sock = _dealer(server.endpoint)
    holder, other = RawClient(server.endpoint, 2), RawClient(server.endpoint, 2)

    def exchange(*frames):
        sock.send_multipart(list(frames))
        assert sock.poll(10_000), f"no reply to {frames!r}"
        reply = sock.recv_multipart()
        return reply[:-1], msgpack.unpackb(reply[-1], raw=False)

    try:
        # ids: any msgpack integer, signed or unsigned 64-bit, echoed as sent
        for rid in (-(1 << 63), -1, 0, (1 << 63), (1 << 64) - 1):
            _, reply = exchange(msgpack.packb({"v": 2, "id": rid, "op": "hello"}))
            assert reply["ok"] and reply["id"] == rid, reply
        # an envelope of 16 frames (the delimiter its last) is one; 17 is not
        request = msgpack.packb({"v": 2, "id": 5, "op": "status"})
        head, reply = exchange(*[b"hop"] * 15, b"", request)
        assert reply["ok"] and reply["id"] == 5 and head == [b"hop"] * 15 + [b""]
        _, reply = exchange(*[b"hop"] * 16, b"", request)
        assert reply["error"]["code"] == "bad_message" and reply["id"] is None
        # v of an error reply: the request's when it is 1 or 2, else 2; bad_version: 2
        for v, code, shown in ((9, "bad_version", 2), ("2", "bad_version", 2), (1, "bad_request", 1)):
            _, reply = exchange(msgpack.packb({"v": v, "id": 1.5 if code == "bad_request" else 1, "op": "status"}))
            assert reply["error"]["code"] == code and reply["v"] == shown, (v, reply)
        # a version-1 request for a version-2 operation: unknown_op, naming the version
        v1 = RawClient(server.endpoint, 1)
        for op in ("wait", "telemetry", "control", "feed"):
            reply = v1.call(op)
            assert reply["v"] == 1 and reply["error"]["code"] == "unknown_op" and "version 2" in \
                reply["error"]["message"], reply
        v1.close()
        # since: 0 (everything held) to the latest seq; beyond or negative is bad_request
        latest = holder.call("telemetry")["result"]["seq"]
        assert holder.call("telemetry", since=0)["ok"] and holder.call("telemetry", since=latest)["ok"]
        for since in (-1, latest + 1000):
            bad = holder.call("telemetry", since=since)["error"]
            assert bad["code"] == "bad_request" and "from 0 to the latest" in bad["message"], bad
        # a feed's topic: "feed:" and 16 lowercase hexadecimal digits
        topic = holder.call("feed", fields=["position"])["result"]["topic"]
        assert re.fullmatch(r"feed:[0-9a-f]{16}", topic), topic
        # take: false from a client that does not hold control is refused, naming the holder;
        # while nobody holds it, it answers control false
        assert other.call("control", take=False)["result"] == {"control": False}
        assert holder.call("control", take=True, name="pendant", lease=60)["ok"]
        refused = other.call("control", take=False)["error"]
        assert refused["code"] == "refused" and "pendant" in refused["message"]
        # estop is open to every client and does not end control
        assert other.call("estop")["ok"]
        assert other.call("status")["result"]["control"] == "pendant"
        assert holder.call("control", take=False)["result"] == {"control": False}
    finally:
        sock.close(linger=0)
        holder.close()
        other.close()
        assert server.stop() == 0, server.log()


_SERVER = {}


def _in_process_server():
    """One server with its loop in this process and no sockets (requests handed to
    ``_handle`` with the connection they came on; replies read from ``outbox``)."""
    if "server" not in _SERVER:
        from compiler.spec import load_spec
        from runtime.server.server import Server, ServeOptions

        import tempfile

        state = Path(tempfile.mkdtemp(prefix="irl-control-"))
        _SERVER["server"] = Server(load_spec(ROOT / "programs" / "lola15.spc"),
                                   ServeOptions(sim_clock=True, loop_process=False, state_dir=state))
    return _SERVER["server"]


_CONNECTIONS = ("a", "b", "c", None)  # identities the server gave (None: a connection without one)
_STEPS = st.lists(st.tuples(st.sampled_from(_CONNECTIONS), st.sampled_from([b"hmi-1", b"\x00\x01\x02\x03\x04", b"x"]),
                            st.sampled_from(["none", "holder's", "wrong"]),
                            st.sampled_from(["take", "release", "override", "status", "estop"])),
                  min_size=1, max_size=25)


@settings(max_examples=examples(50))
@given(_STEPS)
def test_a_request_is_the_holders_exactly_when_it_comes_on_its_connection_or_carries_its_token(steps):
    """Issue 26, fault 3, as a property over any sequence of requests from any connection
    with any routing id (copied or not) and any token: a controlling request is accepted
    exactly when nobody holds control, or it came on the holder's connection, or it carries
    the holder's token; the routing id plays no part; no reply shows the token but take's."""
    server = _in_process_server()
    server.controls.holder = None
    server.link.commands.clear()
    server.outbox.clear()
    holder = None  # the model: (connection, token)
    for i, (connection, routing_id, token_kind, op) in enumerate(steps):
        token = {"none": None, "holder's": holder[1] if holder else "t" * 43, "wrong": "w" * 43}[token_kind]
        owns = holder is not None and ((connection is not None and connection == holder[0]) or token == holder[1])
        args = {"take": {"take": True, "lease": 3600}, "release": {"take": False},
                "override": {"percent": 50}}.get(op, {})
        wire = "control" if op in ("take", "release") else op
        server._handle([routing_id, protocol.request(wire, args, i, token=token)], connection)
        queued = bool(server.link.commands)
        server.link.commands.clear()
        reply = protocol.decode_reply(server.outbox.popleft()[1]) if server.outbox else None
        assert not server.outbox
        if op in ("override", "estop"):  # carried out by the loop (queued), or refused at once
            allowed = op == "estop" or holder is None or owns
            assert queued == allowed and (reply is None) == allowed, (op, holder, connection, token_kind, reply)
        elif op == "status":
            assert reply["ok"] and (holder is None) == (reply["result"]["control"] is None)
            assert holder is None or holder[1] not in repr(reply)
        elif op == "take":
            assert reply["ok"] == (holder is None or owns), (holder, connection, token_kind, reply)
            if holder is None:
                holder = (connection, reply["result"]["token"])
        else:  # release
            assert reply["ok"] == (holder is None or owns), (holder, connection, token_kind, reply)
            if reply["ok"]:
                holder = None
