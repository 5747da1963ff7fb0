"""The network commands' client-side parts that need no server: cell files, key files,
usage errors (the end-to-end tests with real servers are in test_server.py)."""
from __future__ import annotations

import io
from pathlib import Path

import pytest

from runtime.cli import Environment, UsageError, main
from runtime.keys import KeyError_, check_server_keys, make_keys
from runtime.netcli import _cell_endpoint

ROOT = Path(__file__).resolve().parent.parent


def run(*argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    code = main([str(a) for a in argv], Environment(stdout=out, stderr=err))
    return code, out.getvalue(), err.getvalue()


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
