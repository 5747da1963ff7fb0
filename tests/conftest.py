"""Test-suite settings, and what the test files share: the repository's paths and the
robot's specification (ROOT, PROGRAMS, SPEC_PATH, SPEC, TEST_IRL), the in-process CLI
runner (``run_cli``), and the ``irl serve`` processes of the end-to-end tests
(``ServerProcess``, the ``start_server``, ``server`` and ``wall_server`` fixtures, and
helpers to wait on their programs). Test files import them: ``from conftest import ROOT``.

Hypothesis runs derandomized by default (profile "ci"): the examples searched are the same
on every run, so a property test that passes in CI passes again, and a counter-example, once
found, is found every time. To search new examples locally:
``IRL_HYPOTHESIS_PROFILE=explore .venv/bin/python -m pytest tests/...``; to search more of
them, ``IRL_EXAMPLES_SCALE=10`` (``examples``: the costliest tests' counts, scaled).

The README's test command runs the tests in parallel (pytest-xdist, ``-n auto --dist
worksteal``: two workers per core, see pytest_xdist_auto_num_workers; a worker that runs
out of tests takes half of another's queue). Tests marked ``long`` (the few that take seconds of CPU or of the wall clock each;
``long(first=True)``: the longest, a worker to itself) are put at the heads of the
workers' first shares, so that each worker starts on its long tests and the short ones fill in around them,
instead of one long test starting last on an otherwise idle machine, or all of them on one
worker.
"""
from __future__ import annotations

import contextlib
import fcntl
import io
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import settings

from compiler.driver import compile_file
from compiler.objcode import encode
from compiler.spec import load_spec
from runtime.cli.main import Environment, main
from runtime.client.client import Client, ClientError
from runtime.wire.protocol import TERMINAL  # noqa: F401  (the states a job ends in; tests import it from here)

# (ci: the first 25 of the derandomized examples of a property test that names no count, for
# the 5-minute run; explore: hypothesis's 100, new ones each run)
settings.register_profile("ci", derandomize=True, database=None, deadline=None, max_examples=25)
settings.register_profile("explore", deadline=None)
settings.load_profile(os.environ.get("IRL_HYPOTHESIS_PROFILE", "ci"))

#: The costliest property tests (each example a run of the robot, or seconds of planning)
#: run ``examples(n)`` examples: ``n`` times IRL_EXAMPLES_SCALE (default 0.3: what the
#: 5-minute run affords on a slow host; ``n`` is the full count). A deeper search is one
#: variable away: ``IRL_EXAMPLES_SCALE=10`` (with ``IRL_HYPOTHESIS_PROFILE=explore``: new
#: examples on every run).
EXAMPLES_SCALE = float(os.environ.get("IRL_EXAMPLES_SCALE", "0.3"))


def examples(n: int) -> int:
    """How many examples a property test whose CI count is ``n`` runs (EXAMPLES_SCALE)."""
    return max(1, round(n * EXAMPLES_SCALE))


# ---- the repository and the robot ----------------------------------------------------------------
ROOT = Path(__file__).resolve().parent.parent
PROGRAMS = ROOT / "programs"
SPEC_PATH = PROGRAMS / "lola15.spc"
SPEC = load_spec(SPEC_PATH)  # (frozen: shared by every test file)
TEST_IRL = PROGRAMS / "test.irl"
SERVER_PROGRAMS = Path(__file__).resolve().parent / "server_programs"


def run_cli(*argv) -> tuple[int, str, str]:
    """``irl ARGV`` in-process (``runtime.cli.main.main(argv, env)``): (status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    code = main([str(a) for a in argv], Environment(stdout=out, stderr=err))
    return code, out.getvalue(), err.getvalue()


def pytest_xdist_auto_num_workers(config):
    """``-n auto``: two workers per core this process may run on. A fifth of the suite's
    time is spent waiting on the wall clock (servers, the fieldbus, real-time runs) with
    a core idle; a second worker per core keeps it busy."""
    return 2 * len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 2 * (os.cpu_count() or 1)


def pytest_configure(config):
    """Without bytecode caches (``PYTHONDONTWRITEBYTECODE``, as on CI's machine), every
    process of a run would compile the runtime and rewrite the test files' asserts for
    itself: each xdist worker about 12 s of CPU before its first test, each ``irl``
    subprocess a fraction of a second. The first process (the xdist controller, or the only
    one) compiles them once into the ``__pycache__`` directories the others read (not a
    PYTHONPYCACHEPREFIX: that would hide the standard library's and the packages' caches),
    and removes the directories it made at the end."""
    if hasattr(config, "workerinput") or not sys.dont_write_bytecode:
        return
    import compileall
    import shutil

    here = Path(__file__).resolve().parent
    sources = [path for package in ("compiler", "runtime") for path in (ROOT / package).rglob("*.py")]
    sources += [path for path in here.glob("*.py") if not path.name.startswith("test_") and path.name != "conftest.py"]
    made = sorted({path.parent / "__pycache__" for path in sources} | {here / "__pycache__"})
    made = [directory for directory in made if not directory.exists()]
    config.add_cleanup(lambda: [shutil.rmtree(directory, ignore_errors=True) for directory in made])
    for path in sources:
        compileall.compile_file(path, quiet=2)
    written = _rewrite_tests(config, here)
    config.add_cleanup(lambda: [path.unlink(missing_ok=True) for path in written])


def _rewrite_tests(config, here: Path) -> list[Path]:
    """The test files' asserts rewritten as pytest's import hook does, into its cache, by
    as many processes as there are cores; and the plugins' modules this process has
    rewritten already (hypothesis's), beside their packages: those files are returned, to
    be removed at the end. (Best effort: pytest's own functions, not public; without them
    each process rewrites what it imports.)"""
    import multiprocessing

    try:
        from _pytest.assertion.rewrite import PYC_TAIL, _read_pyc, assertstate_key, get_cache_dir

        rewritten = getattr(config.stash[assertstate_key].hook, "_rewritten_names", {})
    except Exception:
        return []

    def pyc(path: Path) -> Path:
        return get_cache_dir(path) / (path.name[:-3] + PYC_TAIL)

    plugins = [Path(path) for path in rewritten.values() if Path(path).parent != here]
    written = [pyc(path) for path in plugins if not pyc(path).exists()]
    tests = [path for path in sorted(here.glob("test_*.py")) if _read_pyc(path, pyc(path)) is None]  # (a run in a run)
    paths = tests + [path for path in plugins if pyc(path) in written]
    processes = min(len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1, 4)
    if processes > 1 and "fork" in multiprocessing.get_all_start_methods():
        children = []
        for k in range(processes):
            child = multiprocessing.get_context("fork").Process(target=_rewrite, args=(config, paths[k::processes]))
            child.start()
            children.append(child)
        for child in children:
            child.join()
    else:
        _rewrite(config, paths)
    return written


def _rewrite(config, paths: list[Path]) -> None:
    try:
        from _pytest.assertion.rewrite import PYC_TAIL, _rewrite_test, _write_pyc, assertstate_key, get_cache_dir

        state = config.stash[assertstate_key]
        for path in paths:
            cache = get_cache_dir(path)
            cache.mkdir(parents=True, exist_ok=True)
            source_hash, code = _rewrite_test(path, config)
            _write_pyc(state, code, source_hash, cache / (path.name[:-3] + PYC_TAIL))
    except Exception:  # (another pytest: each process rewrites them itself)
        pass


def pytest_collection_modifyitems(config, items):
    """The ``long`` tests dealt in turn to the heads of the shares that xdist's worksteal
    scheduler first gives each worker (contiguous: worker i gets len(pending) //
    (workers - i) of the tests left): the ``first=True`` ones to workers of their own, the
    others to the rest; the other tests in their files' order. Without xdist: the long
    tests first."""
    workers = max(1, int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")))

    def rank(item) -> int:
        mark = item.get_closest_marker("long")
        return 2 if mark is None else 0 if mark.kwargs.get("first") else 1

    ranked = sorted(items, key=rank)  # (stable)
    longs = [item for item in ranked if rank(item) < 2]
    rest = ranked[len(longs):]
    firsts = [item for item in longs if rank(item) == 0]
    shares: list[list] = [[] for _ in range(workers)]
    for k, item in enumerate(firsts):
        shares[k % workers].append(item)
    others = list(range(len(firsts), workers)) or list(range(workers))  # (the workers with no first one)
    for k, item in enumerate(longs[len(firsts):]):
        shares[others[k % len(others)]].append(item)
    left = len(items)
    for i, share in enumerate(shares):
        size = left // (workers - i)
        take = max(0, size - len(share))
        share.extend(rest[:take])
        rest = rest[take:]
        left -= len(share)
    items[:] = [item for share in shares for item in share] + rest


# ---- irl serve, end to end (tests/test_server.py and others) -----------------------------------------
_SCRIPT = Path(sys.executable).with_name("irl")
IRL = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "runtime.cli.main"]

START, CALIBRATE, INITIALIZE, MOVE, STOP = (
    "Start Robot", "Calibrate Offsets", "Initialization Sequence", "Move Robot", "Stop Robot")
ALL_PHASES = (START, CALIBRATE, INITIALIZE, MOVE, STOP)
SAFETY = 120.0  # s: a wait that takes longer than this has hung (not a timing assertion)


# ---- helpers ---------------------------------------------------------------------------------------
def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


_OBJECTS: dict[tuple, bytes] = {}


def objcode(path: Path, spec: Path | None = None) -> bytes:
    """The object code of a program, for ``spec`` if given (compiled once per session)."""
    key = (path, spec)
    if key not in _OBJECTS:
        result = compile_file(path, spec)
        assert result.ok, f"{path} does not compile: {result.diagnostics}"
        _OBJECTS[key] = encode(result.program)
    return _OBJECTS[key]


def soft_deadline_spec(directory: Path) -> Path:
    """A copy of the Lola 15 specification whose servo deadline policy is "soft".

    A wall-clock server on a busy two-core machine (other test runs, the test process
    itself) can miss more than the firm policy's 50 deadlines in a second, and the
    program then faults: the tests that need the wall clock for something else (pausing
    a move, kill -9 mid-move) use this copy so that their outcome does not depend on
    the machine's load. Programs sent to such a server are compiled for this spec."""
    text = SPEC_PATH.read_text(encoding="utf-8")
    assert 'servo_miss_policy = "firm"' in text
    path = directory / "lola15_soft.spc"
    path.write_text(text.replace('servo_miss_policy = "firm"', 'servo_miss_policy = "soft"'), encoding="utf-8")
    return path


def run_irl(*args, timeout: float = 60.0, stdin: str | None = None) -> subprocess.CompletedProcess:
    """Run an ``irl`` command to its end; the output is text. A client command runs
    in-process (``runtime.cli.main.main(argv, env)``: the same code without a new interpreter's
    imports, about 0.4 s of CPU each); ``irl serve`` is a process of its own."""
    argv = [str(a) for a in args]
    if argv[0] == "serve":
        return subprocess.run([*IRL, *argv], cwd=ROOT, capture_output=True, text=True, timeout=timeout,
                              input=stdin, stdin=None if stdin is not None else subprocess.DEVNULL)
    out, err = io.StringIO(), io.StringIO()
    code = main(argv, Environment(stdout=out, stderr=err, stdin=io.StringIO(stdin or "")))
    return subprocess.CompletedProcess([*IRL, *argv], code, out.getvalue(), err.getvalue())


def no_traceback(proc: subprocess.CompletedProcess) -> None:
    assert "Traceback" not in proc.stderr and "Traceback" not in proc.stdout, proc.stderr
    assert "internal error" not in proc.stderr, proc.stderr


#: The lock of the machine's real-time capacity (every worker of a run, every run of this user).
_REALTIME_LOCK = Path(os.environ.get("TMPDIR", "/tmp")) / f"irl-tests-realtime-{os.getuid()}.lock"


_SHARES_HELD = [0]  # the shares this process holds (a module's wall-clock server keeps one)


@contextlib.contextmanager
def realtime_share(whole: bool = False, wait: float = 120.0):
    """The machine's real-time capacity, which the tests that run a SCHED_FIFO loop share (a
    wall-clock server, ``irl run --realtime``: taken shared, they may run together); a test
    that asserts a firm 1 ms loop holds under its own load takes it ``whole``: no other
    test's real-time loop then competes with it for the cores (two SCHED_FIFO loops and a
    probe on two cores made its loop miss deadlines its probe did not: a failure that was the
    suite's, not the server's). Never a deadlock: a process that holds a share itself does
    not wait for the whole, and no one waits longer than ``wait`` s (then it goes on
    without, as before the lock)."""
    if whole and _SHARES_HELD[0]:
        yield
        return
    with open(_REALTIME_LOCK, "a+") as f:
        deadline, got = time.monotonic() + wait, False
        while not got:
            try:
                fcntl.flock(f, (fcntl.LOCK_EX if whole else fcntl.LOCK_SH) | fcntl.LOCK_NB)
                got = True
            except BlockingIOError:
                if time.monotonic() > deadline:
                    break
                time.sleep(0.05)
        _SHARES_HELD[0] += got and not whole
        try:
            yield
        finally:
            if got:
                _SHARES_HELD[0] -= not whole
                fcntl.flock(f, fcntl.LOCK_UN)


class ServerProcess:
    """One ``irl serve`` subprocess on free loopback ports; on the wall clock (a SCHED_FIFO
    loop), holding its share of the machine's real-time capacity (:func:`realtime_share`;
    ``whole``: all of it) while it runs."""

    def __init__(self, directory: Path, state_dir: Path, sim_clock: bool = True, keys: Path | None = None,
                 telemetry: str | None = None, spec: Path | None = None, extra: tuple = (), whole: bool = False):
        self.spec = spec  # None: programs/lola15.spc
        self.extra = tuple(extra)  # more arguments of irl serve
        self.directory = directory
        self.state_dir = state_dir
        self.sim_clock = sim_clock
        self.keys = keys
        self.endpoint = f"tcp://127.0.0.1:{free_port()}"
        self.telemetry = telemetry or f"tcp://127.0.0.1:{free_port()}"
        directory.mkdir(parents=True, exist_ok=True)
        self.log_path = directory / f"serve-{self.endpoint.rsplit(':', 1)[1]}.log"
        self.proc: subprocess.Popen | None = None
        self.clients: list[Client] = []
        self.whole = whole
        self._share: contextlib.AbstractContextManager | None = None  # held while a wall-clock server runs

    def start(self) -> "ServerProcess":
        if not self.sim_clock and self._share is None:
            self._share = realtime_share(self.whole)
            self._share.__enter__()
        cmd = [*IRL, "serve", "--spec", self.spec or SPEC_PATH, "--state-dir", self.state_dir,
               "--endpoint", self.endpoint, "--telemetry", self.telemetry]
        if self.sim_clock:
            cmd.append("--sim-clock")
        if self.keys is not None:
            cmd += ["--keys", self.keys]
        cmd += list(self.extra)
        with open(self.log_path, "wb") as log:
            self.proc = subprocess.Popen(list(map(str, cmd)), cwd=ROOT, stdin=subprocess.DEVNULL,
                                         stdout=log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + 10.0
        probe = Client(self.endpoint, keys=self.keys, timeout=0.2)
        try:
            while True:
                if self.proc.poll() is not None:
                    pytest.fail(f"irl serve exited with {self.proc.returncode} at start:\n{self.log()}")
                try:
                    probe.request("hello")
                    return self
                except ClientError:
                    if time.monotonic() > deadline:
                        self.stop()  # (not left running: a test that fails here may never stop it)
                        pytest.fail(f"irl serve did not answer hello within 10 s:\n{self.log()}")
        finally:
            probe.close()

    def log(self) -> str:
        try:
            return self.log_path.read_text(errors="replace")
        except OSError:
            return "(no log)"

    def client(self, timeout: float = 10.0, keys: Path | None = None) -> Client:
        c = Client(self.endpoint, keys=keys if keys is not None else self.keys, timeout=timeout)
        self.clients.append(c)
        return c

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def stop(self) -> int | None:
        """SIGTERM, then SIGKILL after 10 s; returns the exit status."""
        for c in self.clients:
            c.close()
        self.clients = []
        try:
            if self.proc is None:
                return None
            if self.proc.poll() is None:
                self.proc.send_signal(signal.SIGTERM)
                try:
                    self.proc.wait(10)
                except subprocess.TimeoutExpired:
                    self.proc.kill()
                    self.proc.wait()
            return self.proc.returncode
        finally:
            if self._share is not None:
                share, self._share = self._share, None
                share.__exit__(None, None, None)

    def kill9(self) -> None:
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait()


def _finish(servers: list[ServerProcess]) -> None:
    for server in servers:
        code = server.stop()
        print(f"---- irl serve {server.endpoint} ({'sim' if server.sim_clock else 'wall'} clock), "
              f"exit status {code} ----\n{server.log()}")


@pytest.fixture
def start_server(tmp_path):
    """``start_server(sim_clock=True, keys=None, state_dir=None, telemetry=None, spec=None)``
    -> a running server."""
    servers: list[ServerProcess] = []

    def start(sim_clock: bool = True, keys: Path | None = None, state_dir: Path | None = None,
              telemetry: str | None = None, spec: Path | None = None, whole: bool = False) -> ServerProcess:
        server = ServerProcess(tmp_path / f"server{len(servers)}", state_dir or tmp_path / f"state{len(servers)}",
                               sim_clock, keys, telemetry, spec, whole=whole)
        servers.append(server)
        return server.start()

    yield start
    _finish(servers)


@pytest.fixture
def server(start_server) -> ServerProcess:
    return start_server()


@pytest.fixture(scope="module")
def wall_server(tmp_path_factory):
    """One wall-clock server shared by the tests that need real time (the last one kills
    it), with the soft-deadline specification (see soft_deadline_spec)."""
    base = tmp_path_factory.mktemp("wall")
    server = ServerProcess(base / "server", base / "state", sim_clock=False, spec=soft_deadline_spec(base))
    server.start()
    yield server
    _finish([server])


def status(client: Client, program: int) -> dict:
    return client.request("status", {"program": program})


def wait_for(client: Client, program: int, predicate, what: str, server: ServerProcess | None = None,
             poll: float = 0.02) -> dict:
    """Poll a program's status until ``predicate(status)``; fails if it ends first."""
    deadline = time.monotonic() + SAFETY
    while True:
        s = status(client, program)
        if predicate(s):
            return s
        if s["state"] in TERMINAL:
            pytest.fail(f"program {program} ended ({s['state']}: {s.get('fault')}) before {what}"
                        + (f"\n{server.log()}" if server else ""))
        if time.monotonic() > deadline:
            pytest.fail(f"program {program} not {what} after {SAFETY} s: {s}"
                        + (f"\n{server.log()}" if server else ""))
        time.sleep(poll)


def wait_end(client: Client, program: int, server: ServerProcess | None = None) -> dict:
    deadline = time.monotonic() + SAFETY
    while True:
        s = status(client, program)
        if s["state"] in TERMINAL:
            return s
        if time.monotonic() > deadline:
            pytest.fail(f"program {program} did not end within {SAFETY} s: {s}"
                        + (f"\n{server.log()}" if server else ""))
        time.sleep(0.05)


def moving(s: dict) -> bool:
    return s["state"] == "running" and s.get("fsm") == MOVE


def phases(final: dict) -> list[str]:
    return [st["name"] for st in final["summary"]["states"]]


def submit(client: Client, path: Path, server: ServerProcess | None = None) -> int:
    """Queue a program (compiled for ``server``'s specification if it has its own)."""
    data = objcode(path, server.spec if server is not None else None)
    return client.request("submit", {"object": data, "name": path.name})["program"]


# ---- where the suite's CPU goes (opt-in: IRL_TEST_CPU=1) --------------------------------------------
# Each test's CPU time (user + system, this process and the children it waited for, e.g. the
# irl serve processes it stopped), setup and teardown included, from resource.getrusage deltas.
# Each process (an xdist worker, or the only one) writes its figures to
# .cpu-report/<worker>.tsv at the end; the controller (or the only process) sums the files
# and prints the 40 costliest tests and the total. Wall time is no measure on a loaded
# machine; CPU is what the suite costs everyone else.
_CPU = os.environ.get("IRL_TEST_CPU") == "1"
_CPU_DIR = ROOT / ".cpu-report"
_cpu_used: dict[str, float] = {}


def _cpu_now() -> float:
    import resource
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


if _CPU:
    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(item, nextitem):
        start = _cpu_now()
        yield
        _cpu_used[item.nodeid] = _cpu_used.get(item.nodeid, 0.0) + _cpu_now() - start

    def pytest_sessionstart(session):
        if not hasattr(session.config, "workerinput"):  # (the controller, or the only process)
            _CPU_DIR.mkdir(exist_ok=True)
            for old in _CPU_DIR.glob("*.tsv"):
                old.unlink()

    def pytest_sessionfinish(session):
        worker = getattr(session.config, "workerinput", {}).get("workerid", "main")
        if _cpu_used:
            _CPU_DIR.mkdir(exist_ok=True)
            with open(_CPU_DIR / f"{worker}.tsv", "w", encoding="utf-8") as f:
                for nodeid, cpu in _cpu_used.items():
                    f.write(f"{cpu:.3f}\t{nodeid}\n")

    def pytest_terminal_summary(terminalreporter):
        totals: dict[str, float] = {}
        for path in sorted(_CPU_DIR.glob("*.tsv")):
            for line in path.read_text(encoding="utf-8").splitlines():
                cpu, nodeid = line.split("\t", 1)
                totals[nodeid] = totals.get(nodeid, 0.0) + float(cpu)
        if not totals:
            return
        write = terminalreporter.write_line
        write(f"---- CPU per test (IRL_TEST_CPU=1): {len(totals)} tests, {sum(totals.values()):.1f} s in all; "
              f"the 40 costliest ----")
        for nodeid, cpu in sorted(totals.items(), key=lambda kv: -kv[1])[:40]:
            write(f"{cpu:8.2f} s  {nodeid}")
        per_file: dict[str, float] = {}
        for nodeid, cpu in totals.items():
            per_file[nodeid.split("::", 1)[0]] = per_file.get(nodeid.split("::", 1)[0], 0.0) + cpu
        write("---- CPU per file, the 15 costliest ----")
        for name, cpu in sorted(per_file.items(), key=lambda kv: -kv[1])[:15]:
            write(f"{cpu:8.2f} s  {name}")
