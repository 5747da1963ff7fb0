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

from conftest import ROOT, SPEC_PATH


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
