"""The network commands' client-side parts that need no server: cell files, key files,
usage errors (the end-to-end tests with real servers are in test_server.py)."""
from __future__ import annotations


import pytest

from runtime.cli.main import UsageError
from runtime.wire.keys import KeyError_, check_server_keys, make_keys
from runtime.cli.netcli import _cell_endpoint

from conftest import ROOT, run_cli as run


def test_the_example_cell_routes_lola_15():
    assert _cell_endpoint(str(ROOT / "programs" / "cell.toml"), ("lola_15",)) == "tcp://127.0.0.1:5555"


@pytest.mark.parametrize("text, robots, message", [
    ('[robots]\nlola_15 = "tcp://127.0.0.1:1"\n', (), "names no robot"),
    ('[robots]\nlola_15 = "tcp://127.0.0.1:1"\n', ("lola_15", "kuka"), "not supported yet"),
    ('[robots]\nlola_15 = "tcp://127.0.0.1:1"\n', ("kuka",), "no endpoint for robot 'kuka'"),
    ('[robots]\nlola_15 = 5\n', ("lola_15",), "no endpoint for robot 'lola_15'"),
    ("robots = 3\n", ("lola_15",), "expected a [robots] table"),
    ("[robots\n", ("lola_15",), "not a valid cell file"),
])
def test_cell_file_problems_are_named(tmp_path, text, robots, message):
    cell = tmp_path / "cell.toml"
    cell.write_text(text, encoding="utf-8")
    with pytest.raises(UsageError, match=message.replace("[", r"\[")):
        _cell_endpoint(str(cell), robots)


def test_a_missing_cell_file_is_a_usage_error(tmp_path):
    code, out, err = run("submit", ROOT / "programs" / "test.irl", "--cell", tmp_path / "none.toml")
    assert code == 2 and "cannot read" in err and "Traceback" not in err


def test_report_needs_wait():
    code, _, err = run("submit", ROOT / "programs" / "test.irl", "--report", "x.csv")
    assert code == 2 and "--report needs --wait" in err


def test_keys_are_made_once_and_checked(tmp_path):
    code, out, err = run("keys", tmp_path / "k")
    assert code == 0, err
    names = sorted(p.name for p in (tmp_path / "k").iterdir())
    assert names == ["authorized", "client.key", "client.key_secret", "server.key", "server.key_secret"]
    assert [p.name for p in (tmp_path / "k" / "authorized").iterdir()] == ["client.key"]
    check_server_keys(tmp_path / "k")
    code, _, err = run("keys", tmp_path / "k")  # never overwrites a key
    assert code == 2 and "refusing to overwrite" in err
    code, _, err = run("keys", tmp_path / "k", "--name", "robot_cell_2")
    assert code == 0, err
    assert (tmp_path / "k" / "authorized" / "robot_cell_2.key").is_file()
    with pytest.raises(KeyError_, match="no such key file"):
        check_server_keys(tmp_path)
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "server.key_secret").write_text("garbage", encoding="utf-8")
    with pytest.raises(KeyError_, match="server.key_secret"):
        check_server_keys(tmp_path / "bad")
    with pytest.raises(KeyError_, match="letters, digits"):
        make_keys(tmp_path / "k", "no good")


def test_serve_with_a_bad_spec_or_config_is_a_usage_error(tmp_path):
    code, _, err = run("serve", "--spec", tmp_path / "none.spc")
    assert code == 2 and "Traceback" not in err
    bad = tmp_path / "bad.toml"
    bad.write_text("[configurations.x.servo]\nkp = -1\n", encoding="utf-8")
    code, _, err = run("serve", "--spec", ROOT / "programs" / "lola15.spc", "--config", bad)
    assert code == 2 and "servo.kp" in err


def test_serve_with_missing_keys_is_a_usage_error(tmp_path):
    code, _, err = run("serve", "--spec", ROOT / "programs" / "lola15.spc", "--keys", tmp_path)
    assert code == 2 and "server.key_secret" in err


def test_a_client_with_missing_keys_is_a_usage_error_not_a_crash(tmp_path):
    for command in (["status"], ["watch", "--count", "1"]):
        code, _, err = run(*command, "--keys", tmp_path / "none")
        assert code == 2 and "client.key_secret: no such key file" in err and "internal" not in err, err


def test_keys_that_others_may_write_or_read_are_refused_with_the_fix(tmp_path):
    import os

    spec = ROOT / "programs" / "lola15.spc"
    d = tmp_path / "k"
    assert run("keys", d)[0] == 0
    check_server_keys(d)
    os.chmod(d / "authorized", 0o777)  # anyone could authorize a client of their own
    code, _, err = run("serve", "--spec", spec, "--keys", d)
    assert code == 2 and "writable by others (mode 0777)" in err and f"chmod go-w {d / 'authorized'}" in err, err
    os.chmod(d / "authorized", 0o700)
    os.chmod(d, 0o757)
    code, _, err = run("status", "--keys", d)
    assert code == 2 and "writable by others" in err, err
    code, _, err = run("keys", d, "--name", "second")
    assert code == 2 and "writable by others" in err, err
    assert not (d / "second.key_secret").exists()
    os.chmod(d, 0o700)
    os.chmod(d / "server.key_secret", 0o644)  # a secret key readable by everyone
    code, _, err = run("serve", "--spec", spec, "--keys", d)
    assert code == 2 and "a secret key readable by others (mode 0644)" in err and "chmod 600" in err, err
    os.chmod(d / "server.key_secret", 0o600)
    check_server_keys(d)
    assert run("keys", d, "--name", "second")[0] == 0


from hypothesis import given, strategies as st  # noqa: E402

_STATUS = st.fixed_dictionaries(
    {"id": st.integers(1, 10**6), "name": st.text(max_size=10), "state": st.sampled_from(["queued", "running"])},
    optional={"fsm": st.sampled_from(["Start Robot", "Move Robot", "Initialization Sequence/Find Index"]),
              "line": st.none() | st.integers(1, 10**5), "moves_done": st.integers(0, 99),
              "moves_total": st.none() | st.integers(0, 99), "paused": st.booleans()})


@given(_STATUS)
def test_a_progress_line_never_says_none(status):
    """``irl submit --wait`` and ``irl status``: a program that has started but whose line
    the server does not know yet (its first snapshot not in) is shown without a line, not
    as 'line None'."""
    from runtime.cli.netcli import _job_line, _progress_line, _telemetry_line

    texts = [_job_line(status), _progress_line(status["id"], status)]
    sample = {"seq": 1, "t": 0.0, "kind": "sample", "state": status.get("fsm", "Idle"), "program": status["id"],
              "position": [0.0] * 6, **{k: status[k] for k in ("line", "moves_done", "moves_total") if k in status}}
    texts.append(_telemetry_line(sample))
    for text in texts:
        assert "None" not in text, text
        if status["state"] == "running" and status.get("line") is not None:
            assert f"line {status['line']}" in text, text


def test_watch_with_no_server_says_so_and_exits_2(monkeypatch):
    """Issue 26, first hour: ``irl watch`` with nothing at the endpoint no longer waits in
    silence: no telemetry within the reply timeout (5 s; shortened here) is exit 2."""
    import socket

    from runtime.cli import netcli

    monkeypatch.setattr(netcli, "REPLY_TIMEOUT", 0.3)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        unused = f"tcp://127.0.0.1:{s.getsockname()[1]}"
    code, out, err = run("watch", "--telemetry", unused, "--timeout", "3")
    assert code == 2 and f"no telemetry from {unused} within 0.3 s" in err and "Traceback" not in err, (code, err)


def _examples() -> list[str]:
    """Every example that ``irl call --help`` and the console's ``help`` give."""
    import re

    from runtime.cli.netcli import CALL_HELP
    from runtime.wire.scripting import HELP_TEXT

    found = re.findall(r"'([^']+)'", CALL_HELP)
    for line in HELP_TEXT.splitlines():
        if "e.g. " in line:
            found.append(line.split("e.g. ", 1)[1].split(" (", 1)[0].strip())
    return found


def test_control_replay_feeds_and_the_help_examples_from_the_irl_command(tmp_path, monkeypatch):
    """Issue 26, first hour: ``irl control take`` stores a token that the later irl commands
    (processes of their own) send, so an HMI's control does not lock them out once they hold
    it; ``irl watch --since`` replays, ``--feed`` chooses fields; every example of the call
    help is accepted by a server."""
    import json
    import os
    import stat

    import msgpack
    import zmq

    from runtime.cli.netcli import control_file
    from conftest import ServerProcess

    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "xdg"))
    monkeypatch.delenv("IRL_CONTROL_TOKEN", raising=False)
    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=True).start()
    e = ("--endpoint", server.endpoint)
    hmi = zmq.Context.instance().socket(zmq.DEALER)
    hmi.connect(server.endpoint)

    def hmi_call(op, **args):
        hmi.send(msgpack.packb({"v": 2, "id": 1, "op": op, "args": args}))
        assert hmi.poll(10_000)
        return msgpack.unpackb(hmi.recv(), raw=False)

    try:
        examples = _examples()
        assert "trajectory.budget = 500" in examples and not any("servo.kp =" in x for x in examples)
        for example in examples:
            code, out, err = run("call", example, *e)
            assert code == 0, (example, out, err)

        code, out, err = run("control", "take", "--name", "line 3 operator", "--lease", "60", *e)
        assert code == 0 and "taken as 'line 3 operator'" in out, (out, err)
        stored = control_file(server.endpoint)
        assert stat.S_IMODE(os.stat(stored).st_mode) == 0o600
        assert json.loads(stored.read_text())["token"] not in out  # (printed with --json only)
        refused = hmi_call("override", percent=20)["error"]
        assert refused["code"] == "refused" and "line 3 operator" in refused["message"]
        code, out, err = run("override", "40", *e)  # another process, another connection: the token
        assert code == 0 and "override 40 %" in out, err
        monkeypatch.setenv("IRL_CONTROL_TOKEN", "not-the-token")
        code, out, err = run("override", "30", *e)
        assert code == 1 and "refused" in err and "not the holder's" in err, err
        monkeypatch.delenv("IRL_CONTROL_TOKEN")
        code, out, err = run("control", "release", *e)
        assert code == 0 and not stored.exists(), err
        assert hmi_call("status")["result"]["control"] is None

        # an HMI holds control: the irl commands are refused, and say who holds it
        assert hmi_call("control", take=True, name="HMI", lease=60)["ok"]
        code, out, err = run("pause", *e)
        assert code == 1 and "HMI holds control" in err, err
        code, out, err = run("status", *e)
        assert code == 0 and "control: held by HMI" in out, out
        assert hmi_call("control", take=False)["ok"]

        code, out, err = run("watch", "--since", "0", "--count", "3", "--json", "--telemetry", server.telemetry, *e)
        assert code == 0, err
        assert [json.loads(line)["seq"] for line in out.splitlines()] == [1, 2, 3]
        code, out, err = run("watch", "--feed", "position,state", "--rate", "10", "--count", "2", "--json",
                             "--telemetry", server.telemetry, *e)
        assert code == 0, err
        for line in out.splitlines():
            assert set(json.loads(line)) == {"v", "seq", "feed_seq", "t", "kind", "position", "state"}, line
        code, out, err = run("watch", "--feed", "postion", "--telemetry", server.telemetry, *e)
        assert code == 1 and "did you mean 'position'" in err, err
    finally:
        hmi.close(linger=0)
        assert server.stop() == 0, server.log()
