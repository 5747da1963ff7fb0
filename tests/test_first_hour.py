"""The first hour with the tool (issue 16, item 3): what a new user meets first."""
from __future__ import annotations

import argparse
import io
import json
import re
from pathlib import Path

from runtime.cli import Environment, build_parser, main

ROOT = Path(__file__).resolve().parents[1]


def run(*argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    code = main([str(a) for a in argv], Environment(stdout=out, stderr=err))
    return code, out.getvalue(), err.getvalue()


def test_irl_version_names_the_package_and_the_formats_a_peer_must_share(capsys):
    code, _, _ = run("--version")
    out = capsys.readouterr().out  # (argparse prints the version itself)
    assert code == 0 and re.fullmatch(r"irl \S+ \(object code format \d+, protocol \d+\)\n", out), out


def _commands():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices


def test_every_command_says_what_it_does_and_every_argument_has_help_with_its_default():
    for name, command in _commands().items():
        assert command.description, f"irl {name} --help has no description"
        text = command.format_help()
        for action in command._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            assert action.help, f"irl {name}: {action.option_strings or action.dest} has no help"
            if action.option_strings and action.default not in (None, False, argparse.SUPPRESS):
                shown = {str(action.default)} | ({f"{action.default:g}"} if isinstance(action.default, float) else set())
                assert any(form in " ".join(text.split()) for form in shown), \
                    f"irl {name} --help does not show {action.option_strings[0]}'s default {action.default!r}"


def test_the_network_commands_take_their_endpoint_from_irl_endpoint(monkeypatch):
    monkeypatch.setenv("IRL_ENDPOINT", "tcp://127.0.0.1:7777")
    args = build_parser().parse_args(["status"])
    assert args.endpoint == "tcp://127.0.0.1:7777"
    assert build_parser().parse_args(["status", "--endpoint", "tcp://127.0.0.1:1"]).endpoint == "tcp://127.0.0.1:1"
    monkeypatch.delenv("IRL_ENDPOINT")
    assert build_parser().parse_args(["status"]).endpoint == "tcp://127.0.0.1:5555"


def test_submit_json_and_wait_shows_the_programs_print_output(tmp_path, monkeypatch):
    from test_server import ServerProcess

    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=True).start()
    try:
        monkeypatch.setenv("IRL_ENDPOINT", server.endpoint)  # (no --endpoint: the environment's)
        program = tmp_path / "hello.irl"
        program.write_text(f'program hello;\nsystem_specification "{ROOT / "programs" / "lola15.spc"}";\nseq\n'
                           '  print "hello from the robot";\nendseq\nendprogram;\n', encoding="utf-8")
        code, out, err = run("submit", program, "--json")
        queued = json.loads(out)
        assert code == 0 and queued["program"] == 1 and queued["endpoint"] == server.endpoint, (out, err)
        code, out, err = run("submit", program, "--wait")
        assert code == 0 and "line 4: hello from the robot" in out, (out, err)
        code, out, err = run("submit", program, "--wait", "--json")
        final = json.loads(out)
        assert code == 0 and final["state"] == "completed"
        assert final["summary"]["log"][0]["text"] == "hello from the robot"
    finally:
        assert server.stop() == 0, server.log()
