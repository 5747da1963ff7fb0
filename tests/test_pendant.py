"""The pendant's Python side without a browser (tests/test_pendant_browser.py drives the page):
which jog messages go on (JogGate), the page server's refusals, and every action against a
served robot on the simulated clock, each a protocol-2 request under control.
"""
from __future__ import annotations

import json
import time
import urllib.error
import urllib.request

import pytest

from runtime.view.pagehttp import MAX_BODY
from runtime.view.pendant import ACTIONS, STALE, JogGate, Pendant
from tests.conftest import SPEC, SPEC_PATH, ServerProcess, free_port, no_traceback, run_irl


# ---- which jog messages go on ------------------------------------------------------------------
def _gate(*messages) -> list:
    """Each (seq, page ms, release, our ms), received then admitted in the order given:
    None (sent on) or why it was dropped."""
    gate = JogGate()
    out = []
    for seq, page, release, now in messages:
        gate.receive(seq, page, now)
        out.append(gate.admit(seq, page, release, now))
    return out


def test_the_gate_sends_each_new_message_on():
    assert _gate((1, 0.0, False, 1000.0), (2, 100.0, False, 1102.0), (3, 200.0, True, 1201.0)) == [None] * 3


def test_the_gate_drops_what_a_later_message_overtook_but_never_a_release():
    gate = JogGate()
    for seq, page in ((1, 0.0), (2, 100.0), (3, 200.0)):  # three came, 3 a release
        gate.receive(seq, page, 1000.0 + page)
    assert gate.admit(2, 100.0, False, 1300.0) == "a later message came"
    assert gate.admit(3, 200.0, True, 1300.0) is None
    assert gate.admit(1, 0.0, False, 1300.0) == "a later message was sent on already"
    assert gate.admit(4, 300.0, True, 1301.0) is None  # (a release after the last: goes)


def test_the_gate_drops_a_heartbeat_that_came_late():
    late = STALE * 1000.0 + 50.0
    assert _gate((1, 0.0, False, 5000.0), (2, 100.0, False, 5100.0 + late)) == \
        [None, f"it came {late:.0f} ms later than the page's quickest"]
    assert _gate((1, 0.0, False, 5000.0), (2, 100.0, True, 5100.0 + late)) == [None, None]  # a release goes


# ---- the page server ----------------------------------------------------------------------------
class Page:
    """Requests to a pendant as its page makes them (urllib: the status and the JSON)."""

    def __init__(self, pendant: Pendant):
        self.url = pendant.url
        self.page = self.post("session", {})[1]["page"]

    def request(self, path: str, data: bytes | None = None, headers: dict | None = None) -> tuple[int, dict]:
        req = urllib.request.Request(self.url + path, data=data, headers=headers or {})
        try:
            with urllib.request.urlopen(req, timeout=10) as reply:
                return reply.status, json.loads(reply.read())
        except urllib.error.HTTPError as exc:
            return exc.code, json.loads(exc.read())

    def post(self, path: str, body: dict) -> tuple[int, dict]:
        return self.request(path, json.dumps(body).encode(), {"Content-Type": "application/json"})

    def act(self, action: str, **args) -> dict:
        status, reply = self.post("act", {"page": self.page, "action": action, "args": args})
        assert status == 200, reply
        return reply

    def state(self) -> dict:
        return self.request(f"state?page={self.page}")[1]


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    """A server on the simulated clock in T1, and a pendant of it in this process."""
    base = tmp_path_factory.mktemp("pendant")
    programs = base / "programs"
    programs.mkdir()
    (programs / "short.irl").write_text("program short;\nseq\n  print(\"hello from the pendant\");\n"
                                        "  move ptp joint(mainjoint(5, 0, 0, 0, 30, 0));\nendseq\nendprogram;\n",
                                        encoding="utf-8")
    (programs / "broken.irl").write_text("program broken;\nseq\n  move ptp jiont(1);\nendseq\nendprogram;\n",
                                         encoding="utf-8")
    (programs / "notes.txt").write_text("not a program", encoding="utf-8")
    server = ServerProcess(base / "server", base / "state", extra=("--mode", "t1")).start()
    client = server.client()
    hello = client.request("hello")
    pendant = Pendant(server.endpoint, None, SPEC, str(SPEC_PATH), hello, programs, "http://127.0.0.1:1/",
                      free_port())
    pendant.start()
    yield server, pendant, client
    pendant.close()
    server.stop()


def test_the_page_server_answers_only_its_own_page(cell):
    _server, pendant, _client = cell
    page = Page(pendant)
    root = pendant.url.rsplit("/", 2)[0] + "/"
    for url, headers, data, status in (
            (root, {}, None, 404),  # (no key)
            (root + "nokey/state", {}, None, 404),
            (pendant.url + "state", {"Host": "evil.example:80"}, None, 403),  # (a rebound name)
            (pendant.url + "act", {"Content-Type": "text/plain"}, b"{}", 415),  # (another site's form)
            (pendant.url + "act", {"Content-Type": "application/json", "Origin": "http://evil.example"}, b"{}", 403),
            (pendant.url + "act", {"Content-Type": "application/json"}, b"x" * (MAX_BODY + 1), 413),
            (pendant.url + "act", {"Content-Type": "application/json"}, b"{nope", 400),
            (pendant.url + "act", {"Content-Type": "application/json"}, b"[1]", 400),
            (pendant.url + "act", {"Content-Type": "application/json"}, b'{"page": "gone", "action": "take"}', 410),
            (pendant.url + "state?page=gone", {}, None, 410),
            (pendant.url + "nothing", {}, None, 404)):
        req = urllib.request.Request(url, data=data, headers=headers)
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(req, timeout=10)
        assert refused.value.code == status, url
        assert json.loads(refused.value.read())["ok"] is False
    with urllib.request.urlopen(pendant.url, timeout=10) as reply:
        assert b"hold to move" in reply.read().lower()
    assert page.act("fly")["error"] == "no action 'fly'"
    assert page.act("take", name="bad input")["ok"]
    for args in ({"axis": "A9", "direction": 1}, {"axis": "A1", "direction": 2}, {"axis": "A1", "direction": True},
                 {"axis": "A1", "direction": 1, "frame": "moon"}, {"axis": "A1", "direction": 1, "step": 1000},
                 {"axis": "A1", "direction": 1, "step": "1"}, {"axis": "A1", "direction": 1, "t": "now"}):
        reply = page.act("jog", **{"frame": "world", "press": 1, "seq": 1, "t": 0.0, **args})
        assert not reply["ok"] and reply["code"] == "bad_request", reply
    page.act("release")


def test_every_action_but_taking_and_teaching_needs_control(cell):
    _server, pendant, client = cell
    page = Page(pendant)
    assert {name for name, needs in ACTIONS.items() if not needs} == {"take", "release", "teach"}
    for action in ACTIONS:
        if ACTIONS[action]:
            assert page.act(action)["error"] == "this page does not hold control: take it first"
    state = page.state()
    assert state["connected"] and state["mode"] == "t1" and state["control"] is None and not state["you"]
    assert state["programs"] == ["broken.irl", "short.irl"]


def test_control_mode_programs_and_inputs_from_the_page(cell):
    server, pendant, client = cell
    page, other = Page(pendant), Page(pendant)
    assert page.act("take", name="  ")["error"].startswith("a name of 1 to 64")
    assert page.act("take", name="anna") == {"ok": True, "name": "anna"}
    assert page.state()["you"] and page.state()["control"] == "anna"
    assert other.act("take", name="bob")["error"].startswith("anna holds control of the robot")  # (the server's words)
    assert not other.state()["you"] and other.state()["control"] == "anna"
    # a program that does not compile: its diagnostics, as irl check says them
    broken = page.act("start", program="broken.irl")
    assert broken["code"] == "compile" and "broken.irl:3:" in broken["error"] and "1 error" in broken["error"]
    assert page.act("start", program="../etc/passwd")["code"] == "bad_request"  # (only the files offered)
    started = page.act("start", program="short.irl")
    assert started["ok"], started
    job = started["program"]
    assert client.request("source", {"program": job})["source"].startswith("program short;")
    assert client.request("wait", {"program": job, "timeout": 60})["state"] == "completed"
    assert page.act("step")["error"] == "no program is running"  # (the server's words)
    # in step mode, each move waits for Step
    stepped = page.act("start", program="short.irl", step=True)["program"]
    deadline = time.monotonic() + 60
    while not (client.request("status")["running"] or {}).get("waiting_for_step"):
        assert time.monotonic() < deadline, client.request("status")
        time.sleep(0.05)
    assert page.state()["running"]["waiting_for_step"] is True
    assert page.act("step", program=stepped)["line"] == 4
    assert client.request("wait", {"program": stepped, "timeout": 60})["state"] == "completed"
    assert page.act("start", program="short.irl", step="yes")["code"] == "bad_request"
    assert page.act("pause")["error"]  # (nothing to pause)
    assert page.act("override", percent=0)["code"] == "bad_request"
    assert page.act("override", percent=35.5)["override"] == 35.5
    assert page.act("input", input=3, value=True)["ok"]
    assert page.state()["inputs"][2] is True
    assert page.act("input", input=17, value=True)["code"] == "bad_request"
    assert page.act("mode", mode="aut")["mode"] == "aut"
    # a press refused starts nothing later by itself, held on as it may be: it is pressed again
    jog = {"axis": "A1", "direction": 1, "frame": "world", "press": 7}
    assert "needs operating mode T1" in page.act("jog", **jog, seq=100, t=0.0)["error"]
    assert page.act("mode", mode="t1")["mode"] == "t1"
    assert page.act("jog", **jog, seq=101, t=100.0)["error"].endswith("release the button and press it again")
    assert page.act("jog", **{**jog, "direction": 0}, seq=102, t=200.0)["ok"]  # (the release: nothing to stop)
    assert "control taken by anna (the pendant)" in [m["text"] for m in page.state()["messages"]]
    # the emergency stop needs no control; giving control back ends it for the page
    assert other.post("estop", {"page": other.page}) == (200, {"ok": True, "program": None, "cancelled": []})
    assert page.act("release") == {"ok": True}
    assert client.request("status")["control"] is None
    assert page.act("release")["error"] == "this page does not hold control"


def test_teaching_is_irl_where(cell):
    server, pendant, client = cell
    page = Page(pendant)
    taught = page.act("teach", tool="default_tool", base="world")
    where = run_irl("where", "--endpoint", server.endpoint)
    assert where.returncode == 0, where.stderr
    lines = where.stdout.splitlines()
    assert taught["joint"] == lines[0]
    if taught["pose"] is None:
        assert lines[1] == f"-- {taught['note']}"
    else:
        assert [taught["pose"], f"-- {taught['note']}"] == lines[1:3]
    assert page.act("teach", tool="gripper")["code"] == "bad_request"


def test_a_page_that_says_goodbye_gives_control_back(cell):
    _server, pendant, client = cell
    page = Page(pendant)
    assert page.act("take", name="leaving")["ok"]
    assert client.request("status")["control"] == "leaving"
    assert page.post("bye", {"page": page.page}) == (200, {"ok": True})
    assert client.request("status")["control"] is None
    assert page.request(f"state?page={page.page}")[0] == 410


@pytest.mark.parametrize("args, said", [
    (["--endpoint", "tcp://127.0.0.1:9", "--programs", "nowhere"], "--programs nowhere: no such directory"),
    (["programs/test.irl", "--programs", "programs"], "--programs is for the pendant of a live view"),
])
def test_usage_errors(args, said):
    done = run_irl("view", *args)
    no_traceback(done)
    assert done.returncode == 2 and said in done.stderr


def test_the_events_a_view_missed_are_replayed_from_the_servers_history(cell):
    """A view that fell behind (its sockets dropped telemetry: a gap in ``seq``) still shows
    every print and every program event: LiveView asks the server for the gap's messages."""
    from types import SimpleNamespace

    from runtime.view.live import LiveView
    _server, pendant, client = cell
    page = Page(pendant)
    before = client.request("telemetry")["seq"]
    assert page.act("take", name="replay")["ok"]
    job = page.act("start", program="short.irl")["program"]
    assert client.request("wait", {"program": job, "timeout": 60})["state"] == "completed"
    page.act("release")
    after = client.request("telemetry")["seq"] + 1
    logged: list = []
    marked: list = []

    def mark(message, _client):
        view.line = message.get("line") or 0
        marked.append(view.line)

    view = SimpleNamespace(_event=logged.append, _mark=mark, line=0)
    LiveView._recover(view, client, before, after, True)
    mine = [(m["event"], m.get("text") or m.get("state")) for m in logged if m.get("program") == job]
    assert mine[0] == ("program", "running") and mine[-1] == ("program", "completed"), mine
    assert ("log", "hello from the pendant") in mine, mine
    assert all(m["kind"] == "event" and before < m["seq"] < after for m in logged)
    assert [m["seq"] for m in logged] == sorted(m["seq"] for m in logged)
    # a page looks: the lines the missed samples passed are marked, in order, each once (the move's
    # line 4 too, however short the move and whatever samples the sockets dropped; the idle sample
    # after the program may come after the gap)
    assert 4 in marked and all(a != b for a, b in zip(marked, marked[1:])), marked
    # and nothing from outside the gap; no marks while no page looks
    logged.clear()
    marked.clear()
    LiveView._recover(view, client, after - 2, after, False)
    assert all(m["seq"] == after - 1 for m in logged) and not marked
