"""Issue 13, item 7: the smaller failures an adversarial user found, each through the CLI
(``runtime.cli.main.main`` in-process) or the network protocol (a real ``irl serve`` on
loopback, simulated clock):

1. an integer literal of 4,301+ digits ended ``irl check`` with an internal error;
2. rendering diagnostics as text was quadratic (the source split once per diagnostic);
3. ``irl keys`` wrote secret keys readable by everyone;
4. a ``report`` request with an offset beyond the file answered ``internal``;
5. the program queue of ``irl serve`` was unbounded;
6. ``irl serve`` bound endpoints other machines can reach without CURVE keys.
"""
from __future__ import annotations

import io
import json
import os
import re
import shutil
import signal
import socket
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

from compiler.objcode import decode
from compiler.semantics import INT_MAX, INT_MIN

from conftest import ROOT, SPEC_PATH as SPEC, run_cli as run
CONFIG = ROOT / "programs" / "lola15.toml"
SERVER_PROGRAMS = Path(__file__).resolve().parent / "server_programs"
DIAG = re.compile(r"^(?P<file>\S+):(?P<line>\d+):(?P<col>\d+): error: (?P<msg>.+)$")
HEAD = 'program p;\nsystem_specification "lola15.spc";\nvar x : integer; r : real;\nseq\n'
TAIL = "endseq\nendprogram;\n"


def no_crash(text: str) -> None:
    assert "Traceback" not in text and "internal error" not in text, text[:2000]


@pytest.fixture
def work(tmp_path: Path) -> Path:
    shutil.copy(SPEC, tmp_path / "lola15.spc")
    return tmp_path


def program(work: Path, body: str, name: str = "p.irl") -> Path:
    path = work / name
    path.write_text(HEAD + body + TAIL, encoding="utf-8")
    return path


# ---- 1. huge number literals ------------------------------------------------------------------
@pytest.mark.parametrize("digits", [4301, 5000, 100_000])
def test_an_integer_literal_of_thousands_of_digits_is_a_diagnostic(work, digits):
    path = program(work, "  x := " + "9" * digits + ";\n")
    for argv in (("check", path), ("compile", path, "-o", work / "p.irlo")):
        code, out, err = run(*argv)
        no_crash(out + err)
        assert code == 1, err[:2000]
        m = DIAG.match(err.splitlines()[0])
        assert m and (int(m["line"]), int(m["col"])) == (5, 8), err[:500]
        assert "too large" in m["msg"] and f"({digits} digits)" in m["msg"]
        assert f"from {INT_MIN} to {INT_MAX}" in m["msg"]
        assert len(m["msg"]) < 200  # the digits are not all repeated in the message
        assert not (work / "p.irlo").exists()
    code, out, err = run("check", "--json", path)
    assert code == 1
    [d] = json.loads(out)["diagnostics"]
    assert (d["line"], d["column"], d["end"]["column"]) == (5, 8, 8 + digits)
    assert "too large" in d["message"] and str(INT_MAX) in d["message"]


def test_an_integer_literal_just_out_of_range_shows_its_digits(work):
    path = program(work, "  x := 9223372036854775808;\n  x := 99999999999999999999;\n  x := 9223372036854775807;\n")
    code, _, err = run("check", path)
    assert code == 1
    found = [DIAG.match(line) for line in err.splitlines() if DIAG.match(line)]
    assert [(int(m["line"]), int(m["col"])) for m in found] == [(5, 8), (6, 8)]
    assert "the integer 9223372036854775808 is too large" in found[0]["msg"]
    assert "the integer 99999999999999999999 is too large" in found[1]["msg"]
    assert "hint: write it as a real" in err


def test_leading_zeros_do_not_make_a_literal_long(work):
    """5,000 zeros and a 7 is the integer 7 (not an error, and not converted digit by digit)."""
    path = program(work, "  x := " + "0" * 5000 + "7;\n")
    code, out, err = run("compile", path, "-o", work / "p.irlo")
    assert code == 0, err[:2000]
    assert 7 in decode((work / "p.irlo").read_bytes()).constants


@pytest.mark.parametrize("literal, ok", [
    ("9" * 5000 + ".5", False),           # beyond the largest real
    ("0." + "1" * 5000, True),            # many digits, a small value
    ("1" + "0" * 300 + ".0", True),       # 1e300
    ("1e999999", False),
    ("1e-999999", True),                  # underflows to 0.0
    ("1e" + "9" * 5000, False),
    ("9." + "9" * 5000 + "e308", False),    # 1e309
    ("." + "9" * 5000 + "e308", True),      # 1e308, in range
])
def test_long_real_literals_and_huge_exponents(work, literal, ok):
    path = program(work, "  r := " + literal + ";\n")
    code, out, err = run("check", path)
    no_crash(out + err)
    if ok:
        assert code == 0, err[:2000]
        return
    assert code == 1
    m = DIAG.match(err.splitlines()[0])
    assert m and (int(m["line"]), int(m["col"])) == (5, 8)
    assert "too large for a real" in m["msg"]


# ---- 2. rendering diagnostics is linear ---------------------------------------------------------
class _CountingSource(str):
    """A source text that counts the characters its whole-text operations scan while
    ``counting`` is on: each split/splitlines/find/count/index/partition/iteration/encode
    of the whole source costs its length, each slice the length of the slice."""

    counting = False
    scanned = 0

    def _scan(self, n: int) -> None:
        if _CountingSource.counting:
            _CountingSource.scanned += n

    def __getitem__(self, key):
        result = str.__getitem__(self, key)
        self._scan(len(result))
        return result

    def __iter__(self):
        self._scan(len(self))
        return str.__iter__(self)


def _whole_scan(name):
    method = getattr(str, name)

    def scanning(self, *args, **kwargs):
        self._scan(len(self))
        return method(self, *args, **kwargs)
    return scanning


for _name in ("split", "rsplit", "splitlines", "find", "rfind", "index", "rindex", "count", "partition",
              "rpartition", "encode", "replace", "strip", "lstrip", "rstrip", "expandtabs", "startswith",
              "endswith", "lower", "upper", "casefold", "translate", "join", "__contains__", "__add__",
              "__mod__", "format", "__str__"):
    setattr(_CountingSource, _name, _whole_scan(_name))


def test_rendering_20000_diagnostics_scans_the_source_a_bounded_number_of_times(work, monkeypatch):
    """`irl check` of a 20,000-line program with 20,000 errors: while the diagnostics are
    rendered as text, the source is scanned at most twice over in all (it used to be
    split into lines once per diagnostic: 20,000 times). Work is counted, not timed."""
    import compiler.diagnostics
    import compiler.driver

    n = 20_000
    path = program(work, "  x := y;\n" * n)
    text = path.read_text(encoding="utf-8")
    monkeypatch.setattr(compiler.driver, "read_source", lambda p: _CountingSource(text))
    original = compiler.diagnostics.render_all
    rendered = []

    def counted(diagnostics, source, others=None):
        assert isinstance(source, _CountingSource)  # the CLI renders the text it compiled
        _CountingSource.scanned, _CountingSource.counting = 0, True
        try:
            rendered.append(len(diagnostics))
            return original(diagnostics, source, others)
        finally:
            _CountingSource.counting = False

    monkeypatch.setattr(compiler.diagnostics, "render_all", counted)
    code, _, err = run("check", path)
    assert code == 1 and rendered == [n]
    assert _CountingSource.scanned <= 2 * len(text), (
        f"rendering {n} diagnostics scanned {_CountingSource.scanned} characters of a {len(text)}-character "
        f"source ({_CountingSource.scanned / len(text):.0f} times over)")
    lines = err.splitlines()
    assert lines[-1] == f"{n} errors in {path}"
    for i in (0, 3 * (n - 1)):  # the first and the last diagnostic, with their source line and caret
        m = DIAG.match(lines[i])
        assert m and int(m["line"]) in (5, 4 + n) and int(m["col"]) == 8
        assert lines[i + 1] == "    x := y;" and lines[i + 2] == "         ^"
    assert DIAG.match(lines[3 * (n - 1)])["line"] == str(4 + n)


# ---- 3. key file modes --------------------------------------------------------------------------
def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def test_keys_secret_files_are_0600_from_the_start_and_a_new_directory_0700(tmp_path, monkeypatch):
    created = {}  # path -> (flags, mode) of the os.open that created it
    real_open = os.open

    def recording_open(path, flags, mode=0o777, *args, **kwargs):
        if flags & os.O_CREAT:
            created[str(path)] = (flags, mode)
        return real_open(path, flags, mode, *args, **kwargs)

    monkeypatch.setattr(os, "open", recording_open)
    old_umask = os.umask(0)  # a file made with the default mode would be world-readable (0666)
    try:
        d = tmp_path / "new" / "keys"
        code, out, err = run("keys", d)
        assert code == 0, err
        code2, _, err2 = run("keys", d, "--name", "operator")
        assert code2 == 0, err2
    finally:
        os.umask(old_umask)
    for name in ("server", "client", "operator"):
        secret = d / f"{name}.key_secret"
        assert _mode(secret) == 0o600, (secret, oct(_mode(secret)))
        assert _mode(d / f"{name}.key") == 0o644
        flags, mode = created[str(secret)]
        assert mode == 0o600 and flags & os.O_EXCL, "the secret key file was not created 0600 in one step"
    assert _mode(d) == 0o700 and _mode(d / "authorized") == 0o700
    assert sorted(p.name for p in (d / "authorized").iterdir()) == ["client.key", "operator.key"]
    assert f"wrote {d / 'server.key_secret'}" in out

    import zmq.auth

    from runtime.wire.keys import check_server_keys

    check_server_keys(d)
    public, secret = zmq.auth.load_certificate(d / "client.key_secret")
    assert secret is not None and zmq.auth.load_certificate(d / "authorized" / "client.key") == (public, None)

    code, _, err = run("keys", d, "--name", "operator")  # a secret key is never overwritten
    assert code == 2 and "exists already" in err


def test_keys_in_an_existing_directory_keep_its_mode(tmp_path):
    d = tmp_path / "existing"
    d.mkdir()
    d.chmod(0o750)
    code, _, err = run("keys", d)
    assert code == 0, err
    assert _mode(d) == 0o750
    assert _mode(d / "server.key_secret") == 0o600 and _mode(d / "client.key_secret") == 0o600


# ---- a real server ------------------------------------------------------------------------------
def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class _Served:
    """``irl serve --sim-clock`` on free loopback ports (a subprocess), with a client."""

    def __init__(self, tmp_path: Path, *extra: str):
        from runtime.client.client import Client, ClientError

        self.endpoint = f"tcp://127.0.0.1:{_free_port()}"
        tmp_path.mkdir(parents=True, exist_ok=True)
        self.log_path = tmp_path / "serve.log"
        cmd = [sys.executable, "-m", "runtime.cli.main", "serve", "--spec", str(SPEC), "--sim-clock",
               "--state-dir", str(tmp_path / "state"), "--endpoint", self.endpoint,
               "--telemetry", f"tcp://127.0.0.1:{_free_port()}", *extra]
        with open(self.log_path, "wb") as log:
            self.proc = subprocess.Popen(cmd, cwd=ROOT, stdin=subprocess.DEVNULL, stdout=log,
                                         stderr=subprocess.STDOUT)
        self.client = Client(self.endpoint, timeout=10.0)
        deadline = time.monotonic() + 20.0
        while True:
            if self.proc.poll() is not None:
                pytest.fail(f"irl serve exited with {self.proc.returncode}:\n{self.log()}")
            try:
                self.client.request("hello", timeout=0.2)
                break
            except ClientError:
                if time.monotonic() > deadline:
                    self.stop()
                    pytest.fail(f"irl serve did not answer hello:\n{self.log()}")

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def request(self, op: str, args: dict | None = None):
        return self.client.request(op, args)

    def error(self, op: str, args: dict | None = None):
        from runtime.client.client import ClientError

        with pytest.raises(ClientError) as err:
            self.request(op, args)
        return err.value

    def wait(self, program: int, predicate, what: str) -> dict:
        deadline = time.monotonic() + 120.0
        while True:
            s = self.request("status", {"program": program})
            if predicate(s):
                return s
            if time.monotonic() > deadline:
                pytest.fail(f"program {program} not {what}: {s}\n{self.log()}")
            time.sleep(0.02)

    def stop(self) -> None:
        self.client.close()
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        print(f"---- irl serve {self.endpoint}: exit {self.proc.returncode} ----\n{self.log()}")


@pytest.fixture
def serve(tmp_path):
    servers = []

    def start(*extra: str) -> _Served:
        servers.append(_Served(tmp_path / f"s{len(servers)}", *extra))
        return servers[-1]

    yield start
    for s in servers:
        s.stop()


def _object(path: Path) -> bytes:
    from compiler.driver import compile_file
    from compiler.objcode import encode

    result = compile_file(path)
    assert result.ok, result.diagnostics
    return encode(result.program)


# ---- 4. report offsets --------------------------------------------------------------------------
def test_report_offsets_beyond_the_file_or_not_integers_are_bad_requests(serve, tmp_path):
    server = serve()
    job = server.request("submit", {"object": _object(SERVER_PROGRAMS / "short.irl"), "name": "short"})["program"]
    final = server.wait(job, lambda s: s["state"] in ("completed", "faulted", "aborted"), "ended")
    assert final["state"] == "completed", final
    first = server.request("report", {"program": job})
    size = first["size"]
    assert size > 0 and first["offset"] == 0

    for offset in (size + 1, 2 ** 62, 2 ** 63, 2 ** 64 - 1, -1, -(2 ** 63)):
        err = server.error("report", {"program": job, "offset": offset})
        assert err.code == "bad_request", (offset, err.code, err.message)
        assert f"offset must be an integer from 0 to the size of the report file ({size} bytes now)" in err.message
        assert str(offset) in err.message
    err = server.error("report", {"program": job, "file": "states", "offset": 2 ** 62})
    assert err.code == "bad_request" and "size of the states file" in err.message
    for offset in (True, False, 1.5, "0", None, [0]):
        err = server.error("report", {"program": job, "offset": offset})
        assert err.code == "bad_request", (offset, err.code, err.message)
        assert "'offset' must be an integer" in err.message

    at_end = server.request("report", {"program": job, "offset": size})
    assert at_end["data"] == b"" and at_end["eof"] and at_end["size"] == size
    last = server.request("report", {"program": job, "offset": size - 1})
    assert len(last["data"]) == 1 and last["eof"]
    assert server.request("status")["state"] == "Idle"  # still serving


# ---- 5. a bounded queue -------------------------------------------------------------------------
def test_the_queue_is_bounded_for_programs_and_reconfigurations(serve, tmp_path):
    from runtime.wire.protocol import MAX_QUEUED

    assert MAX_QUEUED == 100  # the number docs/protocol.md and README.md give
    server = serve("--config", str(CONFIG))
    running = server.request("submit", {"object": _object(SERVER_PROGRAMS / "long.irl"), "name": "long"})["program"]
    server.wait(running, lambda s: s["state"] == "running" and s.get("fsm") == "Move Robot", "moving")
    server.request("pause")  # nothing leaves the queue while the running program is held

    reconfiguration = server.request("reconfigure", {"name": "gentle"})["program"]
    err = server.error("report", {"program": reconfiguration})
    assert err.code == "not_found" and "reconfiguration" in err.message
    short = _object(SERVER_PROGRAMS / "short.irl")
    queued = [server.request("submit", {"object": short, "name": f"short {i}"}) for i in range(MAX_QUEUED - 1)]
    held = server.request("status", {"program": running})
    assert held["state"] == "running" and held["paused"], f"the held program did not stay paused: {held}"
    assert queued[-1]["queued"] == MAX_QUEUED

    err = server.error("submit", {"object": short, "name": "one too many"})
    assert err.code == "queue_full", (err.code, err.message)
    assert f"at most {MAX_QUEUED} may wait" in err.message
    err = server.error("reconfigure", {"name": "standard"})
    assert err.code == "queue_full", (err.code, err.message)

    code, out, err_text = run("submit", SERVER_PROGRAMS / "short.irl", "--endpoint", server.endpoint)
    assert code == 1, out + err_text
    assert "irl submit:" in err_text and "queue_full" in err_text and f"at most {MAX_QUEUED}" in err_text
    no_crash(out + err_text)

    status = server.request("status")
    assert len(status["queue"]) == MAX_QUEUED and status["queue"][0] == reconfiguration
    assert server.request("abort", {"program": queued[0]["program"]})["state"] == "cancelled"
    assert server.request("submit", {"object": short, "name": "room again"})["queued"] == MAX_QUEUED
    assert server.error("submit", {"object": short}).code == "queue_full"

    result = server.request("estop")
    assert len(result["cancelled"]) == MAX_QUEUED and result["program"] == running
    assert server.request("submit", {"object": short, "name": "after the estop"})["queued"] >= 1


# ---- 6. no unencrypted endpoint other machines can reach, unless asked -----------------------------
@pytest.mark.parametrize("endpoint, local", [
    ("tcp://127.0.0.1:5555", True),
    ("tcp://127.0.0.1:*", True),
    ("tcp://127.3.2.1:5555", True),
    ("tcp://localhost:5555", True),
    ("tcp://LOCALHOST:5555", True),
    ("tcp://[::1]:5555", True),
    ("tcp://[::ffff:127.0.0.1]:5555", True),
    ("ipc:///tmp/irl.sock", True),
    ("inproc://robot", True),
    ("TCP://127.0.0.1:5555", True),
    ("ws://127.0.0.1:5555/robot", True),
    ("tcp://0.0.0.0:5555", False),
    ("tcp://*:5555", False),
    ("tcp://[::]:5555", False),
    ("tcp://[::0]:5555", False),
    ("tcp://192.168.1.10:5555", False),
    ("tcp://10.0.0.1:5555", False),
    ("tcp://128.0.0.1:5555", False),
    ("tcp://eth0:5555", False),
    ("tcp://lo:5555", False),  # an interface name: not taken on trust
    ("tcp://robot.example.com:5555", False),
    ("tcp://localhost.example.com:5555", False),
    ("tcp://[fe80::1%eth0]:5555", False),
    ("tcp://:5555", False),
    ("tcp://127.0.0.1", False),  # no port: not an endpoint zmq binds; never "local" by accident
    ("udp://127.0.0.1:5555", False),
    ("pgm://eth0;239.192.1.1:5555", False),
    ("epgm://127.0.0.1;239.192.1.1:5555", False),
    ("127.0.0.1:5555", False),
    ("", False),
])
def test_endpoint_classification(endpoint, local):
    from runtime.server.server import is_local_endpoint

    assert is_local_endpoint(endpoint) is local


def _spy_server(monkeypatch) -> list:
    """Replace the server so that the CLI can be run without binding anything: returns
    the list of ServeOptions it was asked to serve with."""
    import runtime.server.server

    served = []

    class NoServer:
        def __init__(self, *args, **kwargs):
            raise AssertionError("a Server was made: the endpoint check came too late")

    def fake_serve(spec, options, configurations=None, stderr=None):
        runtime.server.server.check_endpoints(options)
        served.append(options)
        return 0

    monkeypatch.setattr(runtime.server.server, "Server", NoServer)
    monkeypatch.setattr(runtime.server.server, "serve", fake_serve)
    return served


@pytest.mark.parametrize("option, endpoint, what", [
    ("--endpoint", "tcp://0.0.0.0:{port}", "request"),
    ("--endpoint", "tcp://*:{port}", "request"),
    ("--telemetry", "tcp://0.0.0.0:{port}", "telemetry"),
    ("--telemetry", "tcp://[::]:{port}", "telemetry"),
])
def test_serve_refuses_a_remote_endpoint_without_keys(tmp_path, monkeypatch, option, endpoint, what):
    served = _spy_server(monkeypatch)
    port = _free_port()
    endpoint = endpoint.format(port=port)
    state = tmp_path / "state"
    code, out, err = run("serve", "--spec", SPEC, "--sim-clock", "--state-dir", state, option, endpoint)
    no_crash(out + err)
    assert code == 2, out + err
    assert f"refusing to bind the {what} endpoint {endpoint} without CURVE keys" in err
    assert "anyone on the network" in err
    assert "--keys DIR" in err and "--insecure-allow-remote-without-encryption" in err
    assert served == [] and not state.exists()
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:  # nothing holds the port
        s.bind(("127.0.0.1", port))


def test_serve_allows_a_remote_endpoint_with_the_flag_or_with_keys(tmp_path, monkeypatch):
    served = _spy_server(monkeypatch)
    remote = f"tcp://0.0.0.0:{_free_port()}"
    code, out, err = run("serve", "--spec", SPEC, "--sim-clock", "--state-dir", tmp_path / "state",
                         "--endpoint", remote, "--insecure-allow-remote-without-encryption")
    assert code == 0, err
    assert served[-1].endpoint == remote and served[-1].allow_insecure_remote

    keys = tmp_path / "keys"
    assert run("keys", keys)[0] == 0
    code, out, err = run("serve", "--spec", SPEC, "--sim-clock", "--state-dir", tmp_path / "state",
                         "--endpoint", remote, "--telemetry", f"tcp://*:{_free_port()}", "--keys", keys)
    assert code == 0, err
    assert len(served) == 2 and not served[-1].allow_insecure_remote and served[-1].keys == str(keys)

    code, out, err = run("serve", "--spec", SPEC, "--sim-clock", "--state-dir", tmp_path / "state")
    assert code == 0, err  # the defaults are loopback
    assert len(served) == 3


def test_the_server_itself_refuses_to_bind_a_remote_endpoint_without_keys(tmp_path):
    """The same check guards ``serve()`` and ``Server.bind()`` for callers other than the CLI."""
    from compiler.spec import load_spec
    from runtime.server.server import InsecureEndpoint, Server, ServeOptions, serve

    spec = load_spec(SPEC)
    options = ServeOptions(endpoint=f"tcp://0.0.0.0:{_free_port()}", telemetry=f"tcp://127.0.0.1:{_free_port()}",
                           state_dir=tmp_path / "state", sim_clock=True)
    err = io.StringIO()
    assert serve(spec, options, stderr=err) == 2
    assert "refusing to bind the request endpoint" in err.getvalue()
    server = Server(spec, options)
    try:
        with pytest.raises(InsecureEndpoint, match="--insecure-allow-remote-without-encryption"):
            server.bind()
        assert server.router is None and server.telemetry.pub is None
    finally:
        server.close()
