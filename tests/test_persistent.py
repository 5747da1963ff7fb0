"""Persistent variables (compiler/persistent.py, runtime/loop/persistence.py; issue 33 item
5): the VM takes kept values back and keeps every change, the store writes atomically (a
kill -9 of a process keeping values as fast as it can never leaves a torn file), irl run
--state-dir keeps them across runs, and a server shows, sets and resets them for the client
in control."""
from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from compiler.values import Joint, Pose, Position, Rpy
from runtime.loop.persistence import PersistentStore, plain_of, value_of
from runtime.loop.vm import VMStatus

from conftest import ROOT, SPEC_PATH, ServerProcess, examples, objcode, run_cli
from test_protocol_v2 import RawClient
from test_vm import DISPATCHES, FakeHost, compile_text, program_text, run

DECLS = """var persistent
  parts : integer := 10;
  heights : array[1..3] of real;
  where : joint;
var n : integer;
procedure bump(var k : integer);
seq
  k := k + 1;
endseq
endprocedure;"""
BODY = """  print "start ", parts, " ", heights[2], " ", where;
  parts := parts + 1;
  heights[2] := heights[2] + 0.5;
  call bump(parts);
  where := joint(mainjoint(1, 2, 3, 4, 5, 6));"""


class Keeping(FakeHost):
    """A host that keeps values as the runtime does: (name, type) -> value."""

    def __init__(self, kept=None, **kw):
        super().__init__(**kw)
        self.store = dict(kept or {})
        self.stores = []

    def kept(self, name, type_):
        return self.store.get((name, type_))

    def keep(self, name, type_, value):
        self.stores.append(name)
        self.store[(name, type_)] = value_of(plain_of(value))  # (a copy, as the store's plain data is)


@pytest.fixture(params=DISPATCHES)
def dispatch(request):
    return request.param


def test_a_run_starts_from_what_the_last_one_kept(tmp_path, dispatch):
    program = compile_text(tmp_path, program_text(BODY, DECLS))
    host = Keeping()
    machine, host = run(program, host, dispatch=dispatch)
    assert machine.status is VMStatus.DONE, machine.error
    assert host.texts == ["start 10 0 joint(mainjoint(0, 0, 0, 0, 0, 0))"]
    assert host.stores == ["parts", "heights", "parts", "where"]  # each assignment, the var parameter's too
    again = Keeping(host.store)
    machine, again = run(program, again, dispatch=dispatch)
    assert again.texts == ["start 12 0.5 joint(mainjoint(1, 2, 3, 4, 5, 6))"]


def test_a_kept_value_that_no_longer_fits_is_not_taken(tmp_path, dispatch):
    """Another type is not even asked for; an array of other bounds, a joint of other axes
    are not taken: the log says so and the initial value stays."""
    program = compile_text(tmp_path, program_text(BODY, DECLS))
    host = Keeping({("parts", "real"): 3.5, ("heights", "array[1..3] of real"): [1.0, 2.0],
                    ("where", "joint"): Joint((1.0, 2.0), ())})
    machine, host = run(program, host, dispatch=dispatch)
    assert machine.status is VMStatus.DONE, machine.error
    assert host.texts[-1] == "start 10 0 joint(mainjoint(0, 0, 0, 0, 0, 0))"
    assert sum("does not fit its declaration now" in t for t in host.texts) == 2


@settings(max_examples=examples(60), deadline=None)
@given(st.recursive(
    st.one_of(st.integers(-2**63, 2**63 - 1), st.floats(allow_nan=False, allow_infinity=False), st.booleans(),
              st.text(max_size=20),
              st.builds(lambda x, y, z: Pose(Position(x, y, z), Rpy(0.0, 90.0, z)), *[st.floats(-1e6, 1e6)] * 3)),
    lambda inner: st.lists(inner, max_size=4), max_leaves=12))
def test_plain_data_round_trips(value):
    assert value_of(json.loads(json.dumps(plain_of(value)))) == value


def test_a_store_that_cannot_be_read_counts_as_empty_and_says_why(tmp_path):
    path = tmp_path / "persistent.json"
    for content, why in ((b"{nope", "not JSON"), (b'{"format": 99, "programs": {}}', "of format 1"),
                         (b"\xff\xfe", "not JSON")):
        path.write_bytes(content)
        store = PersistentStore(tmp_path)
        store.load()
        assert store.values == {} and why in store.why, store.why
        assert store.kept("p", "x", "integer") is None


def test_reset_forgets_and_set_keeps(tmp_path):
    store = PersistentStore(tmp_path)
    store.start()
    store.keep("p", "a", "integer", 1)
    store.keep("p", "b", "real", 2.5)
    store.keep("q", "a", "integer", 7)
    assert store.flush()
    assert json.loads((tmp_path / "persistent.json").read_text())["programs"]["p"] == {"a": ["integer", 1],
                                                                                      "b": ["real", 2.5]}
    assert store.reset("p", "a") == 1 and store.kept("p", "a", "integer") is None
    assert store.reset("p") == 1 and store.reset("p") == 0
    again = PersistentStore(tmp_path)
    again.load()
    assert again.entries() == {"q": {"a": ["integer", 7]}}


KEEPER = """
import sys
from runtime.loop.persistence import PersistentStore
store = PersistentStore(sys.argv[1])
store.load()
store.start()
start = (store.kept("p", "n", "integer") or 0) + 1
store.keep("p", "n", "integer", start)
store.keep("p", "squares", "array[1..2] of integer", [start, start * start])
store.flush()  # (on disk before the test kills it: the kill then lands among the later writes)
print(start, flush=True)
for i in range(start + 1, start + 10_000_000):
    store.keep("p", "n", "integer", i)
    store.keep("p", "squares", "array[1..2] of integer", [i, i * i])
"""


@settings(max_examples=examples(6), deadline=None)
@given(st.floats(0.05, 0.4))
def test_a_kill_9_never_leaves_a_torn_store_and_the_next_run_goes_on_from_it(tmp_path_factory, delay):
    """A process keeping two values as fast as it can (after its first values are on disk),
    killed with SIGKILL at a random moment, twice: the store always reads back whole, its
    two values are of the same moment (i, i * i), never older than what was on disk, and
    the next process goes on from them."""
    directory = tmp_path_factory.mktemp("kept")
    seen = []
    for _ in range(2):
        proc = subprocess.Popen([sys.executable, "-c", KEEPER, str(directory)], cwd=ROOT, stdout=subprocess.PIPE,
                                text=True)
        seen.append(int(proc.stdout.readline()))
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        store = PersistentStore(directory)
        store.load()
        n = store.kept("p", "n", "integer")
        squares = store.kept("p", "squares", "array[1..2] of integer")
        assert n is not None and n >= seen[-1] and squares[1] == squares[0] ** 2 and abs(squares[0] - n) <= 1, \
            (store.why, n, squares)
    assert seen[1] > seen[0]  # (the second process went on from what the first one left)


COUNTER = """program counter;
system_specification "lola15.spc";
var persistent
  parts : integer := 0;
seq
  parts := parts + 1;
  print "part ", parts;
endseq
endprogram;
"""


def test_irl_run_with_a_state_dir_keeps_them_across_runs(tmp_path):
    source = tmp_path / "counter.irl"
    source.write_text(COUNTER, encoding="utf-8")
    (tmp_path / "lola15.spc").write_bytes(SPEC_PATH.read_bytes())
    for expected in ("part 1", "part 2"):
        code, out, err = run_cli("run", source, "--state-dir", tmp_path / "state")
        assert code == 0 and expected in out, err
    code, out, err = run_cli("run", source)
    assert code == 0 and "part 1" in out and "kept for this run only" in out, out


def test_a_server_shows_sets_and_resets_them_for_the_client_in_control(tmp_path):
    source = tmp_path / "counter.irl"
    source.write_text(COUNTER, encoding="utf-8")
    (tmp_path / "lola15.spc").write_bytes(SPEC_PATH.read_bytes())
    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=True).start()
    owner, other = RawClient(server.endpoint, 2), RawClient(server.endpoint, 2)
    try:
        job = owner.call("submit", object=objcode(source))["result"]["program"]
        assert owner.call("wait", program=job, timeout=60)["result"]["state"] == "completed"
        shown = other.call("persistent")["result"]
        assert shown["programs"] == {"counter": {"parts": {"type": "integer", "value": "1", "plain": 1}}}, shown
        assert owner.call("control", take=True, name="line PLC")["ok"]
        refused = other.call("persistent_set", program="counter", name="parts", value=5)
        assert refused["error"]["code"] == "refused" and "line PLC" in refused["error"]["message"]
        assert other.call("persistent", program="counter")["ok"]  # reading is open to everyone
        wrong = owner.call("persistent_set", program="counter", name="parts", value="five")
        assert wrong["error"]["code"] == "bad_request" and "integer" in wrong["error"]["message"]
        assert owner.call("persistent_set", program="counter", name="parts", value=41)["result"]["value"] == "41"
        job = owner.call("submit", object=objcode(source))["result"]["program"]
        final = owner.call("wait", program=job, timeout=60)["result"]
        assert [e["text"] for e in final["summary"]["log"]] == ["part 42"]
        assert owner.call("persistent_reset", program="counter")["result"]["forgotten"] == 1
        job = owner.call("submit", object=objcode(source))["result"]["program"]
        final = owner.call("wait", program=job, timeout=60)["result"]
        assert [e["text"] for e in final["summary"]["log"]] == ["part 1"]
    finally:
        owner.close()
        other.close()
        assert server.stop() == 0, server.log()
    # a restarted server (the same state directory) goes on from there
    again = ServerProcess(tmp_path / "server2", tmp_path / "state", sim_clock=True).start()
    client = RawClient(again.endpoint, 2)
    try:
        assert client.call("persistent", program="counter")["result"]["programs"]["counter"]["parts"]["plain"] == 1
    finally:
        client.close()
        assert again.stop() == 0, again.log()


def test_the_store_holds_its_own_copies_of_arrays():
    """The VM changes arrays in place (a[i] := x): what the store keeps must not change with
    the program's variable, nor the variable with what the store keeps."""
    store = PersistentStore(None)
    grid = [[1.0, 2.0], [3.0, 4.0]]
    store.keep("p", "grid", "array[1..2] of array[1..2] of real", grid)
    grid[0][0] = 99.0
    loaded = store.kept("p", "grid", "array[1..2] of array[1..2] of real")
    assert loaded == [[1.0, 2.0], [3.0, 4.0]]
    loaded[1][1] = -1.0
    assert store.kept("p", "grid", "array[1..2] of array[1..2] of real") == [[1.0, 2.0], [3.0, 4.0]]


def test_a_value_fits_a_variable_of_its_type_and_shape_only():
    """One rule for a kept value (PERS_LOAD) and the operator's (persistent_set): an integer
    where a real is becomes a real at every level; other lengths, axes or types do not fit."""
    from runtime.loop.persistence import fitted

    assert fitted([[1, 2.5]], [[0.0, 0.0]]) == [[1.0, 2.5]] and type(fitted([[1, 2]], [[0.0, 0.0]])[0][0]) is float
    assert fitted([1.0], [0.0, 0.0]) is None and fitted(3, 0) == 3 and fitted(3.5, 0) is None
    assert fitted(Joint((1.0, 2.0), ()), Joint((0.0,) * 6, ())) is None
    assert fitted("a", 0.0) is None and fitted(True, 0) is None
