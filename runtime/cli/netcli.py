"""The ``irl`` commands that serve a robot or talk to one over the network: serve,
submit, status, pause, resume, abort, estop, override, watch, call, console, reconfigure, persistent,
control, keys. ZeroMQ is imported only when one of them runs (``irl check`` stays light).

Control (protocol 2): ``irl control take`` stores the token the server returned in a file
of the user's state directory, one per endpoint (``control_file``); every ``irl`` command
to that endpoint sends it, so it acts as the holder though each runs in a process (and a
connection) of its own. ``$IRL_CONTROL_TOKEN``, when set, is sent instead."""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

from runtime.cli import common
from runtime.places import DEFAULT_ENDPOINT, DEFAULT_TELEMETRY, default_state_dir

#: Seconds a command waits for a reply (``--timeout``), and ``irl watch`` for telemetry
#: (a server sends an idle sample every 0.5 s, so a silence this long means none is there).
REPLY_TIMEOUT = 5.0
#: ``irl control take``'s default lease (s): the irl commands after it are its requests, and
#: a person types them minutes apart (the protocol's own default, 10 s, suits programs).
CONTROL_LEASE = 300.0
#: irl watch looks at the clock at least this often (s) while it waits for telemetry, and
#: waits at least WATCH_SLACK (s) past a deadline: no period of the loop.
WATCH_POLL = 0.5
WATCH_SLACK = 0.01
TOKEN_VARIABLE = "IRL_CONTROL_TOKEN"


def client_for(args, timeout: float | None = None):
    from runtime.client.client import Client, ClientError

    try:
        return Client(args.endpoint, keys=args.keys, timeout=timeout or args.timeout, token=_token(args.endpoint))
    except ClientError as exc:
        raise common.UsageError(exc.message) from None


def call_op(client, op: str, args: dict | None = None, env=None, hints: dict | None = None):
    """A request whose failure ends the command: unreachable -> exit 2, refused -> 1
    (``hints``: error code -> what this side knows to add to the server's message)."""
    from runtime.client.client import ClientError

    try:
        return client.request(op, args)
    except ClientError as exc:
        if exc.code == "unreachable":
            raise common.UsageError(exc.message) from None
        hint = (hints or {}).get(exc.code)
        raise Refused(f"{exc.message} ({exc.code})" + (f"; {hint}" if hint else "")) from None


class Refused(Exception):
    """The server answered with an error: exit 1."""


def guarded(fn):
    def run(args, env):
        try:
            return fn(args, env)
        except Refused as exc:
            common.warn(env, f"irl {args.command}: {exc}")
            return common.EXIT_INVALID
    return run


# ---- control's token ----------------------------------------------------------------------------
def control_file(endpoint: str) -> Path:
    """Where ``irl control take`` keeps the token for ``endpoint`` (as written on the
    command line): ``STATE/control/<hash of the endpoint>.json`` (STATE: $XDG_STATE_HOME/irl,
    else ~/.local/state/irl)."""
    import hashlib


    return default_state_dir() / "control" / (hashlib.sha256(endpoint.encode()).hexdigest()[:16] + ".json")


def _token(endpoint: str) -> str | None:
    """The control token to send: $IRL_CONTROL_TOKEN, else the stored one for ``endpoint``."""
    token = os.environ.get(TOKEN_VARIABLE)
    if token:
        return token
    path = control_file(endpoint)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as exc:
        raise common.UsageError(f"{path}: not a control token file ({exc}): remove it (it is remade by "
                                "'irl control take')") from None
    token = data.get("token") if isinstance(data, dict) else None
    if not isinstance(token, str) or not 0 < len(token) <= 256 or data.get("endpoint") != endpoint:
        raise common.UsageError(f"{path}: not a control token file for {endpoint}: remove it (it is remade by "
                                "'irl control take')")
    return token


def _store_token(endpoint: str, result: dict) -> Path:
    """Write the token (mode 0600, its directory 0700; atomically) for later commands."""
    path = control_file(endpoint)
    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        json.dump({"endpoint": endpoint, "token": result["token"], "name": result["name"],
                   "lease": result["lease"], "taken": time.time()}, f)
    os.replace(tmp, path)
    return path


@guarded
def cmd_control(args, env) -> int:
    """``irl control take|release``: take control of the robot (the token stored for the
    commands after it) or give it back."""
    client = client_for(args)
    try:
        if args.action == "take":
            request = {"take": True, "lease": args.lease, **({"name": args.name} if args.name else {})}
            result = call_op(client, "control", request)
            try:
                path = _store_token(args.endpoint, result)
            except OSError as exc:
                raise common.UsageError(f"cannot store the control token: {exc.strerror or exc} (give it to the "
                                     f"commands in ${TOKEN_VARIABLE} instead: 'irl control take --json' prints "
                                     "it)") from None
            if args.json:
                common.say(env, json.dumps({**result, "file": str(path)}))
            else:
                common.say(env, f"control of {args.endpoint} taken as {result['name']!r} (lease {result['lease']:g} s: "
                                "it ends that long after the last irl command to this server)")
                common.say(env, f"token stored in {path}: the irl commands to this endpoint act as the holder "
                                f"until 'irl control release' (or set ${TOKEN_VARIABLE})")
            return common.EXIT_OK
        if args.name is not None:
            raise common.UsageError("--name is for 'irl control take'")
        call_op(client, "control", {"take": False})
        control_file(args.endpoint).unlink(missing_ok=True)
        if args.json:
            common.say(env, json.dumps({"control": False}))
        else:
            common.say(env, f"control of {args.endpoint} given back (or nobody held it)")
        return common.EXIT_OK
    finally:
        client.close()


# ---- serve ----------------------------------------------------------------------------------
def cmd_serve(args, env) -> int:
    from compiler.spec import SpecError, load_spec
    from runtime.scheduling import given, scheduling
    from runtime.server.server import InsecureEndpoint, LoopRefused, ServeOptions, check_endpoints, serve
    from runtime.wire.messages import io_sources_problem

    try:
        wanted = scheduling(args)  # (by default SCHED_FIFO, memory locked, where the host permits it)
    except ValueError as exc:
        raise common.UsageError(str(exc)) from None
    if given(args) and args.sim_clock:
        raise common.UsageError(f"{' and '.join(given(args))} {'is' if len(given(args)) == 1 else 'are'} for the wall "
                             "clock: drop --sim-clock")
    options = ServeOptions(endpoint=args.endpoint, telemetry=args.telemetry, state_dir=args.state_dir,
                           sim_clock=args.sim_clock, seed=args.seed, keys=args.keys, mode=args.mode,
                           allow_insecure_remote=args.insecure_allow_remote_without_encryption,
                           deadline_policy=args.deadline_policy, scheduling=wanted)
    try:
        check_endpoints(options)  # before anything is loaded or bound
    except InsecureEndpoint as exc:
        raise common.UsageError(str(exc)) from None
    try:
        spec = load_spec(args.spec)
    except SpecError as exc:
        raise common.UsageError(str(exc)) from None
    problem = io_sources_problem(bool(args.fieldbus), bool(args.cell_scenario), not args.sim_clock, "serve")
    if problem is not None:
        raise common.UsageError(problem)
    # (the cell scenario's and the PLC's files are read by the loop process: the server's imports no simulator)
    options.cell, options.fieldbus = args.cell_scenario, args.fieldbus
    if args.record:
        from runtime.recording import missing

        if missing():
            raise common.UsageError(f"--record: {missing()}")
        options.record = args.record
    configurations = None
    if args.config:
        from runtime.config import ConfigError, load_configurations

        try:
            configurations = load_configurations(args.config)
        except ConfigError as exc:
            raise common.UsageError(str(exc)) from None
    if args.keys:
        from runtime.wire.keys import KeyError_, check_server_keys

        try:
            check_server_keys(args.keys)
        except KeyError_ as exc:
            raise common.UsageError(str(exc)) from None
    try:
        return serve(spec, options, configurations, stderr=env.stderr)
    except LoopRefused as exc:  # the loop read the cell scenario's or the PLC's file: what is wrong with it
        raise common.UsageError(str(exc)) from None


# ---- submit ---------------------------------------------------------------------------------
def _object_code(args, env) -> tuple[bytes, str, tuple, str | None, str | None, object] | None:
    """(bytes, name, robots, the specification file it was compiled for where known, the
    source text where known, the program) of FILE.irlo (as is: the server verifies; its
    source file when it is there) or FILE.irl (compiled)."""
    from compiler.objcode import ObjectCodeError, decode, encode
    from runtime.client.client import source_text

    if args.file.endswith(".irlo"):
        data = common.read_object(args.file)
        try:
            program = decode(data)
        except ObjectCodeError as exc:
            common.warn(env, f"{args.file}: invalid object code: {exc}")
            return None
        return (data, Path(args.file).name, program.robots, common.spec_compiled_for(program, Path(args.file))[0],
                source_text(Path(args.file).parent / program.source), program)
    result = common.compile_source(args.file, args.spec)
    common.report_diagnostics(env, result, False)
    if not result.ok:
        return None
    return (encode(result.program), Path(args.file).name, result.program.robots, result.spec.file,
            source_text(Path(args.file)), result.program)


@guarded
def cmd_submit(args, env) -> int:
    if args.report and not args.wait:
        raise common.UsageError("--report needs --wait (the report is fetched when the program has ended)")
    compiled = _object_code(args, env)
    if compiled is None:
        return common.EXIT_INVALID
    data, name, robots, compiled_for, source, program = compiled
    if args.from_line is not None:
        from compiler.objcode import from_line_problem

        problem = from_line_problem(program, args.from_line)
        if problem is not None:
            raise common.UsageError(f"--from-line {args.from_line}: {problem}")
    hints = {"wrong_robot": f"{name} was compiled here for {compiled_for}"} if compiled_for else None
    if args.cell:
        args.endpoint = _cell_endpoint(args.cell, robots)
    client = client_for(args)
    try:
        since = call_op(client, "telemetry")["seq"] if args.wait else 0  # the program's print output: after this
        request = {"object": data, "name": name, **({"source": source} if source is not None else {}),
                   **({"step": True} if args.step else {}),
                   **({"from_line": args.from_line} if args.from_line is not None else {})}
        reply = call_op(client, "submit", request, hints=hints)
        job = reply["program"]
        if not args.json:
            common.say(env, f"program {job} queued on {args.endpoint} ({name})")
        if not args.wait:
            if args.json:
                common.say(env, json.dumps({"program": job, "queued": reply["queued"], "endpoint": args.endpoint}))
            return common.EXIT_OK
        final, shown = _wait(client, job, env, since, quiet=args.json)
        from runtime.wire.protocol import REPORT_FILES, JobState
        if args.report:
            out = Path(args.report)
            client.download(job, "report", out)
            for which in REPORT_FILES[1:]:  # (OUT.states.csv, OUT.events.csv: irl plot reads them)
                client.download(job, which, out.with_suffix(f".{which}.csv"))
            common.warn(env, f"report written to {out}")
        if args.json:
            common.say(env, json.dumps(final, default=str))
            return common.EXIT_OK if final["state"] == JobState.COMPLETED else common.EXIT_INVALID
        for entry in (final.get("summary") or {}).get("log", [])[shown:]:  # print output telemetry had lost
            common.say(env, common.log_line(entry["time"], entry["line"], entry["text"]))
        if final["state"] == JobState.COMPLETED:
            summary = final.get("summary") or {}
            common.say(env, f"program {job} completed: {len(summary.get('moves', []))} moves, final position "
                            + common.joint_values(summary.get("final_position", [])))
            return common.EXIT_OK
        common.say(env, f"program {job} {final['state']}: {final.get('fault')}")
        return common.EXIT_INVALID
    finally:
        client.close()


def _wait(client, job: int, env, since: int, quiet: bool = False) -> tuple[dict, int]:
    """Poll the program's status, showing one progress line and the program's ``print``
    output as it comes (from the telemetry after ``since``; unless ``quiet``), until it
    has ended. Returns its final status and how many print lines were shown."""
    from runtime.wire.protocol import TERMINAL

    tty = hasattr(env.stdout, "isatty") and env.stdout.isatty() and not quiet
    last = None
    shown = 0
    while True:
        status = call_op(client, "status", {"program": job})
        more = not quiet
        while more:  # the print output so far (telemetry keeps it; a long gap loses the oldest)
            replay = call_op(client, "telemetry", {"since": since})
            more = replay.get("more", False)
            for m in replay["messages"]:
                since = m["seq"]
                if m["kind"] == "event" and m.get("event") == "log" and m.get("program") == job:
                    if tty and last:
                        env.stdout.write("\r\x1b[K")
                        last = None
                    common.say(env, common.log_line(m["at"], m["line"], m["text"]))
                    shown += 1
        if status["state"] in TERMINAL:
            if tty and last:
                env.stdout.write("\n")
            return status, shown
        line = _progress_line(job, status)
        if line != last and not quiet:
            if tty:
                env.stdout.write("\r\x1b[K" + line)
                env.stdout.flush()
            else:
                common.say(env, line)
            last = line
        time.sleep(0.1)


def _progress_line(job: int, status: dict) -> str:
    """``irl submit --wait``'s line: where the program is (without a line while the
    server does not know it yet: the program has just started)."""
    from runtime.wire.protocol import JobState

    if status["state"] == JobState.QUEUED:
        return f"program {job}: queued"
    total = status.get("moves_total")
    moves = f"{status.get('moves_done') or 0}/{total if total is not None else '?'}"
    paused = " (paused)" if status.get("paused") else ""
    if status.get("waiting_for_step"):
        paused += " (waiting for a step: irl step)"
    if status.get("approach"):
        paused += " (approach)"
    at = f"  line {status['line']}" if status.get("line") is not None else ""
    return f"program {job}: {status.get('fsm') or ''}{at}  moves {moves}{paused}"


def _cell_endpoint(path: str, robots: tuple) -> str:
    """The endpoint of the robot the program moves, from a cell file."""
    import tomllib

    try:
        cell = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise common.UsageError(f"cannot read {path}: {exc.strerror or exc}") from None
    except (ValueError, RecursionError) as exc:  # TOMLDecodeError, UnicodeDecodeError, an integer too long
        raise common.UsageError(f"{path}: not a valid cell file: {exc}") from None
    table = cell.get("robots")
    if not isinstance(table, dict) or not table:
        raise common.UsageError(f"{path}: expected a [robots] table: robot name = endpoint, "
                             'e.g. lola_15 = "tcp://127.0.0.1:5555"')
    if not robots:
        raise common.UsageError("the program names no robot (act_rob): --cell cannot choose one; use --endpoint")
    if len(robots) > 1:
        raise common.UsageError(f"the program moves {len(robots)} robots ({', '.join(robots)}); a program for "
                             "several robots of a cell is not supported yet")
    endpoint = table.get(robots[0])
    if not isinstance(endpoint, str):
        raise common.UsageError(f"{path}: no endpoint for robot {robots[0]!r} (the cell has: {', '.join(table)})")
    return endpoint


# ---- status and control ---------------------------------------------------------------------------
@guarded
def cmd_status(args, env) -> int:
    client = client_for(args)
    try:
        status = call_op(client, "status", {"program": args.program} if args.program is not None else {})
    finally:
        client.close()
    if args.json:
        common.say(env, json.dumps(status, indent=2, default=str))
        return common.EXIT_OK
    if args.program is not None:
        common.say(env, _job_line(status))
        if status.get("fault"):
            common.say(env, f"  fault: {status['fault']}")
        return common.EXIT_OK
    common.say(env, f"robot: {status['state']}  ({str(status.get('mode', 'aut')).upper()}, override {status['override']:g} %, "
                    f"{'calibrated' if status['calibrated'] else 'not calibrated'}, "
                    f"{'initialized' if status['initialized'] else 'not initialized'})")
    for key in ("calibration", "initialization"):  # why each is (or is not) remembered
        if status.get(key):
            common.say(env, f"  {status[key]}")
    if status.get("control"):
        common.say(env, f"control: held by {status['control']} (other clients may only read and estop)")
    if status["running"]:
        common.say(env, "running: " + _job_line(status["running"]))
    common.say(env, "queue: " + (", ".join(map(str, status["queue"])) or "empty"))
    for job in status["programs"]:
        common.say(env, "  " + _job_line(job))
    return common.EXIT_OK


@guarded
def cmd_persistent(args, env) -> int:
    """The kept values of persistent variables: shown, one set (``--set NAME=VALUE``, the
    value as JSON: 3, 2.5, true, "text", or the plain form ``irl persistent --json`` shows),
    or forgotten (``--reset``, one or all of a program's)."""
    if (args.set or args.reset is not None) and not args.program:
        raise common.UsageError("--set and --reset need the program's name: irl persistent PROGRAM --set NAME=VALUE")
    if args.set:
        name, _, text = args.set.partition("=")
        try:
            value = json.loads(text)
        except ValueError:
            raise common.UsageError(f"--set {args.set}: the value must be JSON (3, 2.5, true, \"text\", or the plain "
                                    "form irl persistent --json shows)") from None
        op, request = "persistent_set", {"program": args.program, "name": name.strip().lower(), "value": value}
    elif args.reset is not None:
        op, request = "persistent_reset", {"program": args.program} | ({"name": args.reset.lower()} if args.reset else {})
    else:
        op, request = "persistent", {"program": args.program} if args.program else {}
    client = client_for(args)
    try:
        result = call_op(client, op, request)
    finally:
        client.close()
    if args.json:
        common.say(env, json.dumps(result, indent=2))
    elif op == "persistent_set":
        common.say(env, f"{args.program}.{result['name']} := {result['value']} (kept for its next run)")
    elif op == "persistent_reset":
        common.say(env, f"{args.program}: {result['forgotten']} kept value{'s' if result['forgotten'] != 1 else ''} "
                        "forgotten (its next run starts from the initial values)")
    else:
        common.say(env, f"store: {result['store'] or 'none (no state directory)'}: {result['found']}")
        for program, names in result["programs"].items():
            for name, entry in names.items():
                common.say(env, f"  {program}.{name} : {entry['type']} = {entry['value']}")
    return common.EXIT_OK


def current_position(args) -> tuple[str, list]:
    """(the specification hash, the axis positions) of the robot the server at
    ``args.endpoint`` drives: hello's ``spec_hash`` and status's ``position`` (irl pose).
    Unreachable: a usage error (exit 2); refused: a ValueError (exit 1)."""
    client = client_for(args)
    try:
        hello = call_op(client, "hello")
        status = call_op(client, "status")
    except Refused as exc:
        raise ValueError(f"the server at {args.endpoint} refused: {exc}") from None
    finally:
        client.close()
    return hello.get("spec_hash", ""), list(status.get("position") or [])


def _job_line(job: dict) -> str:
    from runtime.wire.protocol import JobState

    text = f"program {job['id']} ({job['name']}): {job['state']}"
    if job["state"] == JobState.RUNNING:
        total = job.get("moves_total")
        at = f", line {job['line']}" if job.get("line") is not None else ""
        text += (f", {job.get('fsm') or ''}{at}, moves {job.get('moves_done') or 0}/"
                 f"{total if total is not None else '?'}" + (" (paused)" if job.get("paused") else "")
                 + ((" (step mode: waiting for a step)" if job.get("waiting_for_step") else " (step mode)")
                    if job.get("step") else "")
                 + (f" (approach to line {job.get('from_line')})" if job.get("approach") else ""))
    elif job.get("fault") and job["state"] != JobState.RUNNING:
        text += f": {job['fault']}"
    return text


def _simple(op: str, describe, arguments=lambda args: {}):
    """A control command: one request built by ``arguments`` from the command line, one
    line of output made by ``describe`` from the result."""
    @guarded
    def run(args, env) -> int:
        client = client_for(args)
        try:
            result = call_op(client, op, arguments(args))
        finally:
            client.close()
        common.say(env, describe(result))
        return common.EXIT_OK
    return run


cmd_pause = _simple("pause", lambda r: f"program {r['program']} paused")
cmd_resume = _simple("resume", lambda r: f"program {r['program']} resumed")
cmd_step = _simple("step", lambda r: f"program {r['program']}: " + (
    f"the approach to the start of the move at line {r['line']} goes" if r.get("approach")
    else f"the move at line {r['line']} goes"))
cmd_abort = _simple("abort", lambda r: f"program {r['program']}: {r['state']}",
                    lambda a: {"program": a.program} if a.program is not None else {})
cmd_estop = _simple("estop", lambda r: "emergency stop" + (f": program {r['program']} stopped" if r["program"] else "")
                    + (f"; cancelled {', '.join(map(str, r['cancelled']))}" if r["cancelled"] else ""))
cmd_override = _simple("override", lambda r: f"override {r['override']:g} %", lambda a: {"percent": a.percent})
cmd_reconfigure = _simple("reconfigure", lambda r: f"reconfiguration to {r['requested']!r} requested",
                          lambda a: {"name": a.name})


# ---- watch ---------------------------------------------------------------------------------------
def cmd_watch(args, env) -> int:
    """Print the telemetry (or a feed of some fields, ``--feed``), after replaying what the
    server still holds since a ``seq`` (``--since``). A server sends a message at least
    every 0.5 s: no message for REPLY_TIMEOUT seconds (plus a slow feed's period) means no
    server there, or it went away: exit 2."""
    from runtime.wire import protocol
    from runtime.client.client import ClientError, Subscriber

    if args.since is not None and args.feed:
        raise common.UsageError("--since replays the full telemetry: it does not combine with --feed")
    if args.since is not None and args.since < 0:
        raise common.UsageError(f"--since must be a telemetry seq, 0 or more, got {args.since}")
    if (args.rate is not None or args.events) and not args.feed:
        raise common.UsageError("--rate and --events are for a feed: give --feed FIELDS")
    topic, fields, silence = protocol.TELEMETRY_TOPIC, None, REPLY_TIMEOUT
    client = None
    try:
        if args.feed or args.since is not None:
            client = client_for(args, REPLY_TIMEOUT)
        if args.feed:
            request = {"fields": [f.strip() for f in args.feed.split(",") if f.strip()]}
            if args.rate is not None:
                request["rate"] = args.rate
            if args.events:
                request["events"] = True
            feed = call_op(client, "feed", request)
            topic, fields = feed["topic"].encode(), feed["fields"]
            silence += 1.0 / feed["rate"]
        try:
            sub = Subscriber(args.telemetry, keys=args.keys, topic=topic)
        except ClientError as exc:
            raise common.UsageError(exc.message) from None
        try:
            return _watch(args, env, sub, client, fields, silence)
        finally:
            sub.close()
    except Refused as exc:
        common.warn(env, f"irl watch: {exc}")
        return common.EXIT_INVALID
    finally:
        if client is not None:
            client.close()


def _watch(args, env, sub, client, fields, silence: float) -> int:
    received = 0
    start = time.monotonic()
    deadline = start + args.timeout if args.timeout else None
    last_heard = start
    shown = -1  # the last seq printed (replayed messages are not printed twice)

    def show(message: dict) -> None:
        nonlocal received
        received += 1
        if args.json:
            common.say(env, json.dumps(message, default=_bytes_hex))
        elif fields is not None and message.get("kind") == "sample":
            common.say(env, _feed_line(message, fields))
        else:
            common.say(env, _telemetry_line(message))
        env.stdout.flush()

    if args.since is not None:  # subscribed first: nothing between the replay and the live stream is lost
        since, more = args.since, True
        while more and (args.count is None or received < args.count):
            replay = call_op(client, "telemetry", {"since": since})
            if replay.get("missing"):
                common.warn(env, f"irl watch: {replay['missing']} telemetry messages after {since} are no longer held "
                              "by the server")
            for message in replay["messages"]:
                if args.count is not None and received >= args.count:
                    break
                show(message)
                since = shown = message["seq"]
            more = replay.get("more", False)
        last_heard = time.monotonic()
    while args.count is None or received < args.count:
        now = time.monotonic()
        if deadline is not None and now >= deadline:
            break
        if now - last_heard > silence:
            what = "no telemetry" if not received and args.since is None else "no more telemetry"
            raise common.UsageError(f"{what} from {args.telemetry} within {silence:g} s (is 'irl serve' running "
                                 "there, with the same --keys?)")
        wait = min(WATCH_POLL, silence - (now - last_heard) + WATCH_SLACK)
        message = sub.receive(max(WATCH_SLACK, wait if deadline is None else min(wait, deadline - now)))
        if message is None:
            continue
        last_heard = time.monotonic()
        if message["seq"] <= shown:
            continue
        show(message)
        if message.get("kind") == "event" and message.get("event") == "shutdown":
            break  # the server said it is going
    if sub.missed:
        common.warn(env, f"irl watch: {sub.missed} telemetry messages were missed (sequence gaps)")
    return common.EXIT_OK


def _feed_line(m: dict, fields: list) -> str:
    """A feed's sample: its fields as ``name=value``."""
    values = " ".join(f"{name}={_shown_value(m[name])}" for name in fields if name in m)
    return f"#{m.get('seq')} t={m.get('t', 0):.3f} {values}".rstrip()


def _shown_value(value) -> str:
    if isinstance(value, float):
        return f"{value:.3f}"
    if isinstance(value, list):
        return "[" + " ".join(_shown_value(v) for v in value) + "]"
    return str(value)


def _bytes_hex(value):
    return value.hex() if isinstance(value, bytes) else str(value)


def _telemetry_line(m: dict) -> str:
    head = f"#{m.get('seq')} t={m.get('t', 0):.3f}"
    if m.get("kind") == "event":
        event = m.get("event")
        if event == "state":
            return f"{head} state {m.get('from') or '-'} -> {m.get('to')}"
        if event == "program":
            fault = f": {m['fault']}" if m.get("fault") else ""
            return f"{head} program {m.get('program')} {m.get('state')}{fault}"
        if event == "log":
            return f"{head} line {m.get('line')}: {m.get('text')}"
        return f"{head} {event} {m.get('reason') or ''}".rstrip()
    position = " ".join(f"{x:8.3f}" for x in m.get("position", []))
    text = f"{head} {m.get('state')}"
    if m.get("program") is not None:
        total = m.get("moves_total")
        at = f" line {m['line']}" if m.get("line") is not None else ""
        text += (f" program {m['program']}{at} moves {m.get('moves_done') or 0}/"
                 f"{total if total is not None else '?'}" + (" paused" if m.get("paused") else "")
                 + (" waiting for a step" if m.get("waiting_for_step") else "")
                 + (" approach" if m.get("approach") else ""))
    return f"{text} override {m.get('override', 100):g}% pos [{position}]"


# ---- scripting ------------------------------------------------------------------------------------
#: ``irl call``'s help: its examples are sent to a server by tests/test_netcli.py (each is accepted).
CALL_HELP = "one scripting command, e.g. 'servo.kp', 'trajectory.budget = 500' or 'help servo'"

@guarded
def cmd_call(args, env) -> int:
    client = client_for(args)
    try:
        result = call_op(client, "call", {"text": args.text})
    finally:
        client.close()
    common.say(env, result["output"])
    return common.EXIT_OK


def cmd_console(args, env) -> int:
    """An interactive scripting session (reads lines from stdin until EOF or 'quit')."""
    from runtime.client.client import ClientError

    client = client_for(args)
    stdin = env.stdin
    interactive = hasattr(stdin, "isatty") and stdin.isatty()
    try:
        hello = call_op(client, "hello")
        common.say(env, f"connected to {hello['robot']} at {args.endpoint}; 'help' lists the commands, "
                        "'quit' ends the session")
        while True:
            if interactive:
                env.stdout.write("irl> ")
                env.stdout.flush()
            line = stdin.readline()
            if not line:
                break
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            if text in ("quit", "exit"):
                break
            try:
                common.say(env, client.request("call", {"text": text})["output"])
            except ClientError as exc:
                if exc.code == "unreachable":
                    raise common.UsageError(exc.message) from None
                common.say(env, f"error: {exc.message}")
    except Refused as exc:
        common.warn(env, f"irl console: {exc}")
        return common.EXIT_INVALID
    finally:
        client.close()
    return common.EXIT_OK


# ---- keys -------------------------------------------------------------------------------------------
def cmd_keys(args, env) -> int:
    from runtime.wire.keys import KeyError_, make_keys

    try:
        made = make_keys(args.directory, args.name)
    except KeyError_ as exc:
        raise common.UsageError(str(exc)) from None
    for path in made:
        common.say(env, f"wrote {path}")
    return common.EXIT_OK


# ---- the parsers ----------------------------------------------------------------------------------
def add_connection(p, telemetry: bool = False, reply_timeout: bool = True) -> None:
    """The arguments every network command has: --endpoint, --keys, --timeout (and
    --telemetry), their defaults from $IRL_ENDPOINT and $IRL_TELEMETRY."""
    endpoint = os.environ.get("IRL_ENDPOINT") or DEFAULT_ENDPOINT
    telemetry_endpoint = os.environ.get("IRL_TELEMETRY") or DEFAULT_TELEMETRY
    p.add_argument("--endpoint", default=endpoint, metavar="E",
                   help=f"the server's request endpoint (default: $IRL_ENDPOINT, else {DEFAULT_ENDPOINT}; "
                        f"now {endpoint})")
    if telemetry:
        p.add_argument("--telemetry", default=telemetry_endpoint, metavar="E",
                       help=f"the server's telemetry endpoint (default: $IRL_TELEMETRY, else "
                            f"{DEFAULT_TELEMETRY}; now {telemetry_endpoint})")
    p.add_argument("--keys", metavar="DIR", help="CURVE keys (made by 'irl keys DIR')")
    if reply_timeout:
        p.add_argument("--timeout", type=float, default=REPLY_TIMEOUT, metavar="S",
                       help="seconds to wait for a reply")


def add_commands(declare) -> None:
    """Name the network commands and declare the arguments of those ``declare`` (a
    :class:`runtime.cli.main.Commands`) gives a parser for."""
    from runtime.wire import protocol

    connection = add_connection

    if (p := declare("serve", help="serve a robot (the simulated one) on the network")) is not None:
        p.add_argument("--endpoint", default=DEFAULT_ENDPOINT, metavar="E", help="request endpoint to bind (default: "
                       "%(default)s)")
        p.add_argument("--telemetry", default=DEFAULT_TELEMETRY, metavar="E",
                       help="telemetry endpoint to bind (default: %(default)s)")
        p.add_argument("--spec", required=True, metavar="FILE.spc", help="the robot's specification")
        p.add_argument("--config", metavar="FILE.toml", help="component configurations (see docs/runtime.md)")
        p.add_argument("--state-dir", metavar="DIR", help="calibration and reports (default ~/.local/state/irl)")
        p.add_argument("--sim-clock", action="store_true", help="simulated clock (default: wall clock)")
        p.add_argument("--seed", type=int, default=0, help="the simulated robot's seed")
        common.add_cell_scenario(p, "what the simulated cell does with the digital I/O (see docs/runtime.md); reports gain "
                                    "the io columns")
        p.add_argument("--fieldbus", metavar="FILE.toml",
                       help="the digital I/O on a PLC over Modbus TCP (see docs/runtime.md; wall clock only)")
        p.add_argument("--record", metavar="DIR",
                       help="record every program in DIR: an MCAP file each, named by the server's start, the "
                            "program's id and name (opens in Foxglove; see docs/runtime.md)")
        p.add_argument("--mode", choices=tuple(protocol.MODES), default="aut",
                       help="the operating mode the robot starts in (default: aut; t1: manual reduced speed, for "
                            "jogging and test runs; docs/safety.md)")
        p.add_argument("--keys", metavar="DIR", help="require CURVE authentication with the keys in DIR")
        p.add_argument("--insecure-allow-remote-without-encryption", action="store_true",
                       help="allow endpoints other machines can reach without --keys: anyone on the network could "
                            "then move the robot (without it, such endpoints are refused)")
        from runtime.cli.common import add_deadline_policy
        from runtime.scheduling import add_arguments

        add_deadline_policy(p)
        add_arguments(p)
        p.set_defaults(run=cmd_serve)

    if (p := declare("submit", help="send a program to a server's queue")) is not None:
        p.add_argument("file", metavar="FILE.irl|FILE.irlo", help="the program (compiled here) or its object code")
        p.add_argument("--spec", metavar="FILE.spc", help="for FILE.irl: the system specification to use")
        p.add_argument("--wait", action="store_true", help="show progress until the program ends; exit 1 unless "
                                                           "it completed")
        p.add_argument("--report", metavar="OUT.csv", help="with --wait: fetch the program's report")
        p.add_argument("--cell", metavar="CELL.toml", help="send to the robot the program's act_rob names")
        p.add_argument("--step", action="store_true",
                       help="step mode: the program stops before each of its moves; each goes with 'irl step' (no "
                            "look-ahead, no blending)")
        p.add_argument("--from-line", type=int, metavar="N",
                       help="start at the move on line N, after an approach to its start at 10 %% speed (the "
                            "program runs to it without moving; docs/runtime.md)")
        p.add_argument("--json", action="store_true",
                       help="print one JSON object: the queued program (with --wait: its final status and summary)")
        connection(p)
        p.set_defaults(run=cmd_submit)

    if (p := declare("status", help="the robot, the queue and the programs (or one program)")) is not None:
        p.add_argument("program", nargs="?", type=int, metavar="ID", help="one program (default: the whole server)")
        p.add_argument("--json", action="store_true", help="the reply as one JSON object")
        connection(p)
        p.set_defaults(run=cmd_status)

    for name, fn, text in (("pause", cmd_pause, "hold the running program (a move under way comes to a controlled stop)"),
                           ("resume", cmd_resume, "continue the paused program"),
                           ("step", cmd_step, "step mode: the move the program waits before goes"),
                           ("estop", cmd_estop, "emergency stop: brakes on, drives off, queue cancelled")):
        if (p := declare(name, help=text)) is not None:
            connection(p)
            p.set_defaults(run=fn)
    for name, fn, text, arg, kind, metavar, what in (
            ("abort", cmd_abort, "stop the running program (controlled stop; or remove a queued one)", "program", int,
             "ID", "the program (default: the running one)"),
            ("override", cmd_override, "speed override (percent), also of the move under way", "percent", float,
             "PCT", "1 to 100"),
            ("reconfigure", cmd_reconfigure, "switch to another named configuration between programs", "name", str,
             "NAME", "a configuration of the server's --config file"),
            ("call", cmd_call, CALL_HELP, "text", str, "TEXT", "the command ('help' lists the forms)")):
        if (p := declare(name, help=text)) is not None:
            p.add_argument(arg, type=kind, metavar=metavar, help=what, **({"nargs": "?"} if name == "abort" else {}))
            connection(p)
            p.set_defaults(run=fn)

    if (p := declare("watch", help="print the server's telemetry (exit 2 when none comes within "
                                   f"{REPLY_TIMEOUT:g} s)")) is not None:
        p.add_argument("--json", action="store_true", help="one JSON object per line")
        p.add_argument("--count", type=int, metavar="N", help="stop after N messages")
        p.add_argument("--timeout", type=float, metavar="S", help="stop after S seconds")
        p.add_argument("--since", type=int, metavar="SEQ",
                       help="first the messages after telemetry seq SEQ that the server still holds (0: all of them), "
                            "then the live ones")
        p.add_argument("--feed", metavar="FIELDS",
                       help="only these sample fields (comma-separated, e.g. position,line; docs/protocol.md, feed)")
        p.add_argument("--rate", type=float, metavar="HZ", help=f"with --feed: samples per second, "
                       f"{protocol.MIN_FEED_RATE:g} to {protocol.MAX_FEED_RATE:g} (default: every sample)")
        p.add_argument("--events", action="store_true", help="with --feed: the events too")
        connection(p, telemetry=True, reply_timeout=False)
        p.set_defaults(run=cmd_watch)

    if (p := declare("control", help="take control of the robot (other clients may then only read and "
                                     "estop) or give it back")) is not None:
        p.add_argument("action", choices=("take", "release"), help="take: hold control (the token is stored for the "
                                                                    "irl commands after it); release: give it back")
        p.add_argument("--name", metavar="N", help="with take: the name other clients see (default: 'client #N')")
        p.add_argument("--lease", type=float, default=CONTROL_LEASE, metavar="S",
                       help=f"with take: control ends S seconds after the last irl command to the server, "
                            f"{protocol.MIN_LEASE:g} to {protocol.MAX_LEASE:g}")
        p.add_argument("--json", action="store_true", help="the reply as one JSON object (with take: the token)")
        connection(p)
        p.set_defaults(run=cmd_control)

    if (p := declare("persistent", help="the values kept of programs' persistent variables: show, set, reset")) \
            is not None:
        p.add_argument("program", nargs="?", metavar="PROGRAM", help="a program's name (default: every program's)")
        p.add_argument("--set", metavar="NAME=VALUE", help="set a kept value (JSON: 3, 2.5, true, \"text\", ...)")
        p.add_argument("--reset", nargs="?", const="", metavar="NAME", help="forget one kept value, or all of them")
        p.add_argument("--json", action="store_true", help="the reply as one JSON object")
        connection(p)
        p.set_defaults(run=cmd_persistent)

    if (p := declare("console", help="an interactive scripting session")) is not None:
        connection(p)
        p.set_defaults(run=cmd_console)

    if (p := declare("keys", help="make CURVE key pairs for a server and its clients")) is not None:
        p.add_argument("directory", metavar="DIR", help="where to make (or add) the key files")
        p.add_argument("--name", default=None, metavar="NAME",
                       help="make only a client key pair called NAME (default: the server's and a client's)")
        p.set_defaults(run=cmd_keys)
