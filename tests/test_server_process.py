"""The shape of ``irl serve`` (issue 28): every operation of the protocol has its handler
and every handler its operation; the rule of the I/O sources is the same for ``irl run``
and ``irl serve``."""
from __future__ import annotations

import io

import pytest

from runtime.cli.main import Environment, main
from runtime.server.server import Server
from runtime.wire import protocol
from runtime.wire.messages import io_sources_problem

from conftest import ROOT, SPEC, SPEC_PATH


def irl(*argv) -> tuple[int, str]:
    """An irl command in this process (it is refused before anything starts): its exit
    status and what it said on stderr."""
    err = io.StringIO()
    code = main([str(a) for a in argv], Environment(stdout=io.StringIO(), stderr=err, stdin=io.StringIO()))
    return code, err.getvalue()


def test_every_operation_of_the_protocol_has_its_handler_and_every_handler_its_operation():
    handlers = {name[len("op_"):] for name in dir(Server) if name.startswith("op_")}
    assert handlers - set(protocol.OPS) == set(), "handlers of operations the protocol does not declare"
    assert set(protocol.OPS) - handlers == set(), "operations of the protocol without a handler in the server"


@pytest.mark.parametrize("command, flags, wall_clock", [
    ("run", ["--realtime"], True), ("run", [], False), ("serve", [], True), ("serve", ["--sim-clock"], False)])
def test_a_fieldbus_with_a_cell_or_on_the_simulated_clock_is_refused_by_one_rule(tmp_path, command, flags,
                                                                                 wall_clock):
    scenario = tmp_path / "cell.toml"
    fieldbus = tmp_path / "plc.toml"
    for path in (scenario, fieldbus):
        path.write_text("", encoding="utf-8")
    program = [ROOT / "programs" / "test.irl"] if command == "run" else []
    code, err = irl(command, *program, "--spec", SPEC_PATH, *flags, "--fieldbus", fieldbus, "--cell-scenario", scenario)
    assert code == 2 and err == f"irl: {io_sources_problem(True, True, wall_clock, command)}\n", err
    if not wall_clock:
        code, err = irl(command, *program, "--spec", SPEC_PATH, *flags, "--fieldbus", fieldbus)
        assert code == 2 and err == f"irl: {io_sources_problem(True, False, False, command)}\n", err


def test_the_servers_own_operation_runs_in_the_server_and_the_others_in_the_loop(tmp_path):
    from runtime.server.server import ServeOptions
    from runtime.wire.protocol import ProtocolError

    server = Server(SPEC, ServeOptions(sim_clock=True, loop_process=False, state_dir=tmp_path / "state"))
    try:
        for text, code, message in (
                ("server.reconfigure(1)", "script_error", "server.reconfigure: reconfigure() takes the configuration's "
                                                          "name, a string"),
                ("server.nope()", "script_error", "server has no operation 'nope' (operations: reconfigure)"),
                ('server.reconfigure("a")', "refused", "this server has no configuration file (start it with --config "
                                                       "FILE.toml)")):
            with pytest.raises(ProtocolError) as caught:
                server.request("call", {"text": text})
            assert (caught.value.code, caught.value.message) == (code, message)
        assert server.request("call", {"text": "server.override"})["value"] == 100.0  # (read in the loop)
        assert "server" in server.request("call", {"text": "components"})["value"]
    finally:
        server.close()


SERVE_AND_LIST_MODULES = """
import os, signal, sys, threading
from runtime.cli.main import main
from runtime.client.client import Client

endpoint, telemetry, spec, state = sys.argv[1:5]
answers = []

def one_request():
    client = Client(endpoint, timeout=60.0)
    try:
        answers.append(client.request("status")["state"])
    finally:
        client.close()
        os.kill(os.getpid(), signal.SIGINT)  # (irl serve stops on it, the robot at rest)

threading.Thread(target=one_request, daemon=True).start()
code = main(["serve", "--spec", spec, "--sim-clock", "--endpoint", endpoint, "--telemetry", telemetry,
             "--state-dir", state])
print(code, answers)
print(" ".join(sorted(sys.modules)))
"""


def test_the_server_process_imports_nothing_of_the_loop_the_motion_or_the_hardware(tmp_path):
    """``irl serve`` for real, on loopback: its process answers a request and ends having
    imported no module of runtime.loop, runtime.motion or runtime.hardware (the loop's
    process has them)."""
    import subprocess
    import sys

    from conftest import free_port

    endpoint, telemetry = f"tcp://127.0.0.1:{free_port()}", f"tcp://127.0.0.1:{free_port()}"
    proc = subprocess.run([sys.executable, "-c", SERVE_AND_LIST_MODULES, endpoint, telemetry, str(SPEC_PATH),
                           str(tmp_path / "state")], cwd=ROOT, capture_output=True, text=True, timeout=120)
    first, modules = proc.stdout.splitlines()[-2:]
    assert first == "0 ['Idle']", proc.stdout + proc.stderr
    loaded = modules.split()
    assert "runtime.server.server" in loaded and "runtime.wire.messages" in loaded
    assert [m for m in loaded if m.startswith(("runtime.loop", "runtime.motion", "runtime.hardware"))] == []


def test_every_command_to_the_loop_has_its_handler_there_and_round_trips():
    from runtime.loop.robotloop import COMMANDS as HANDLERS
    from runtime.wire import messages

    assert set(HANDLERS) == set(messages.COMMANDS)
    start = messages.Start(3, b"\x01", "r.csv", None, 50.0)
    assert messages.command_of(start.to_wire(7)) == (7, start)
