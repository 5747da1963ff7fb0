"""``irl view``: the robot in 3D in the browser (runtime.view): a program's paths, a
report or recording replayed, or a served robot live. It serves the page on 127.0.0.1,
prints its URL, and serves until interrupted (Ctrl-C, SIGTERM: exit 0)."""
from __future__ import annotations

import contextlib
import importlib.util
import os
import signal
import threading
from pathlib import Path

from runtime.cli import common

#: The files ``irl view`` shows, by suffix.
KINDS = {".irl": "program", ".csv": "report", ".mcap": "recording"}


def add_arguments(p) -> None:
    from runtime.client.client import DEFAULT_ENDPOINT, DEFAULT_TELEMETRY
    from runtime.view.stage import DEFAULT_PORT

    p.add_argument("file", nargs="?", metavar="PROG.irl|REPORT.csv|FILE.mcap",
                   help="a program (its paths), a report or a recording (replayed); none: live from --endpoint")
    p.add_argument("--spec", metavar="FILE.spc", help="the robot's specification (a program's own by default; a "
                                                       "served robot's by default when live)")
    p.add_argument("--endpoint", metavar="E", help=f"live: the server's request endpoint (e.g. {DEFAULT_ENDPOINT})")
    p.add_argument("--telemetry", metavar="E", help="live: the server's telemetry endpoint (default: the "
                                                    f"endpoint's host with the next port, e.g. {DEFAULT_TELEMETRY})")
    p.add_argument("--keys", metavar="DIR", help="live: CURVE keys (made by 'irl keys DIR')")
    p.add_argument("--port", type=int, default=DEFAULT_PORT, metavar="P",
                   help="the page's port on 127.0.0.1 (default %(default)s; the next free one when taken); live, "
                        "the pendant's page is on the next free one after it")
    p.add_argument("--programs", metavar="DIR", help="live: the directory whose .irl files the pendant offers to "
                                                     "start (default: none)")
    common.add_cell_scenario(p, "the program's paths")


def cmd_view(args, env: common.Environment) -> int:
    if (args.file is None) == (args.endpoint is None):
        raise common.UsageError("give a file (PROG.irl, REPORT.csv, FILE.mcap) or --endpoint E (live), "
                                "one of the two")
    if not 1 <= args.port <= 65535:
        raise common.UsageError(f"--port {args.port}: expected 1 to 65535")
    if args.file is not None:
        kind = KINDS.get(Path(args.file).suffix.lower())
        if kind is None:
            also = " (the program's source: its lines are shown with its paths)" if args.file.endswith(".irlo") else ""
            raise common.UsageError(f"irl view {args.file}: expected a program (.irl){also}, a report (.csv) or a "
                                    "recording (.mcap)")
        if not Path(args.file).is_file():
            raise common.UsageError(f"cannot read {args.file}: no such file")
    elif args.cell_scenario:
        raise common.UsageError("--cell-scenario is for a program's paths, not a live view")
    if args.programs is not None:
        if args.endpoint is None:
            raise common.UsageError("--programs is for the pendant of a live view (--endpoint E)")
        if not Path(args.programs).is_dir():
            raise common.UsageError(f"--programs {args.programs}: no such directory")
    if importlib.util.find_spec("viser") is None or importlib.util.find_spec("yourdfpy") is None:
        raise common.UsageError("irl view needs viser and yourdfpy: pip install -e '.[view]'")
    if args.endpoint is not None:
        view, stage = _live(args, env)  # (its URLs said: the 3D view's and the pendant's)
    elif kind == "program":
        view, stage = _program(args, env)
        if view is None:
            return common.EXIT_INVALID
    else:
        view, stage = _replay(args, env)
    if not stage.announced:
        _announce(env, stage)
    _serve_until_stopped()
    view.close()
    stage.close()
    return common.EXIT_OK


def _announce(env, stage) -> None:
    """Say where the page is (as soon as it serves the arm)."""
    common.say(env, f"irl view: {stage.url}")
    env.stdout.flush()
    stage.announced = True


def _serve_until_stopped() -> None:
    done = threading.Event()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *_: done.set())
    try:
        while not done.wait(0.5):
            pass
    except KeyboardInterrupt:
        pass


def _stage(spec, args, title: str):
    from runtime.view.stage import Stage

    try:
        return Stage(spec, args.port, title)
    except OSError as exc:
        raise common.UsageError(f"cannot serve on 127.0.0.1:{args.port}: {exc.strerror or exc}") from None
    except ValueError as exc:  # (the specification's kinematics: no URDF of it)
        raise common.UsageError(f"{spec.file}: {exc}") from None


def _load_spec(path: str):
    from compiler.spec import SpecError, load_spec

    try:
        return load_spec(path)
    except SpecError as exc:
        raise common.UsageError(str(exc)) from None


def _program(args, env):
    import time

    from runtime.loop.offline import check_motion
    from runtime.view.program import ProgramView

    result = common.compile_source(args.file, args.spec)
    if result.program is None:
        common.report_diagnostics(env, result, False)
        return None, None
    scenario = None
    if args.cell_scenario:
        from runtime.hardware.backends import load_io_files

        try:
            scenario, _fieldbus = load_io_files(args.cell_scenario, None, result.spec)
        except ValueError as exc:
            raise common.UsageError(str(exc)) from None
    started = time.perf_counter()
    stage = _stage(result.spec, args, args.file)
    _announce(env, stage)  # (the arm is there at once; its paths come when they are planned)
    waiting = stage.server.gui.add_markdown(f"planning the moves of {args.file} ...")
    outcome = check_motion(result.program, result.spec, scenario, trace=True)
    waiting.remove()
    stage.show_zones(result.program.zones)  # (the program's own, beside the specification's)
    view = ProgramView(stage, args.file, Path(args.file).read_text(encoding="utf-8"), outcome)
    refused = len(view.reasons)
    common.say(env, f"irl view: {args.file}: {len(view.records)} moves, {refused} refused, shown in "
                    f"{time.perf_counter() - started:.2f} s")
    return view, stage


def _replay(args, env):
    from runtime.view.replay import ReplayError, ReplayView, read_recorded

    spec_path = args.spec or recorded_spec(Path(args.file))
    if not spec_path:
        raise common.UsageError(f"irl view {args.file}: a report does not name its robot's specification: give "
                                "--spec FILE.spc")
    spec = _load_spec(spec_path)
    try:
        recorded = read_recorded(Path(args.file), spec)
    except ReplayError as exc:
        raise common.UsageError(str(exc)) from None
    stage = _stage(spec, args, args.file)
    return ReplayView(stage, args.file, recorded), stage


def recorded_spec(path: Path) -> str | None:
    """The specification file a recording was made with, when it is readable here."""
    if path.suffix.lower() != ".mcap":
        return None
    from runtime.recording import RecordingError, read_messages

    try:
        metadata, _messages, _complete = read_messages(path, set())
    except (RecordingError, OSError):
        return None  # (said when the file is read for its messages)
    spec_file = metadata.get("spec_file")
    return spec_file if spec_file and os.path.isfile(spec_file) else None


def _live(args, env):
    from runtime.client.client import Client, ClientError
    from runtime.view.live import LiveView
    from runtime.view.pendant import Pendant

    telemetry = args.telemetry or _telemetry_of(args.endpoint)
    try:
        client = Client(args.endpoint, keys=args.keys, timeout=3.0)
        try:
            hello = client.request("hello")
        finally:
            client.close()
    except ClientError as exc:
        raise common.UsageError(f"{exc.message}") from None
    spec_path = args.spec or hello.get("spec_file")
    if not spec_path or not os.path.isfile(spec_path):
        raise common.UsageError(f"the server's specification ({hello.get('robot')}) is not readable here: "
                                "give --spec FILE.spc")
    spec = _load_spec(spec_path)
    if spec.hash != hello.get("spec_hash"):
        raise common.UsageError(f"{spec_path} is not the served robot's specification ({hello.get('robot')},"
                                f" hash {str(hello.get('spec_hash'))[:12]}): give the one it was started with")
    stage = _stage(spec, args, f"live: {args.endpoint}")
    view = LiveView(stage, args.endpoint, telemetry, args.keys)
    try:
        # (the 3D view embedded from "localhost", another site than the pendant's 127.0.0.1: the
        # browser renders it in a process of its own, and its WebGL cannot hold up the pendant's
        # heartbeats)
        pendant = Pendant(args.endpoint, args.keys, spec, spec_path, hello,
                          Path(args.programs) if args.programs else None,
                          stage.url.replace("//127.0.0.1:", "//localhost:"), stage.server.get_port() + 1,
                          latest=lambda: view.latest)
    except (OSError, ClientError) as exc:
        stage.close()
        raise common.UsageError(f"cannot serve the pendant on 127.0.0.1: {getattr(exc, 'message', None) or exc}") \
            from None
    view.listeners.append(pendant.event)
    stage.server.gui.add_markdown("The operator's **pendant** (control, mode, programs, jogging, the emergency "
                                  "stop) is a page of its own, with this view in it: the second URL `irl view` "
                                  "printed (it holds a key: only who started irl view has it).")
    view.start()
    pendant.start()
    _announce(env, stage)
    common.say(env, f"irl view: the pendant: {pendant.url}")
    env.stdout.flush()
    both = contextlib.ExitStack()  # (its close(): the pendant's, then the live view's; the stage's after them)
    both.callback(view.close)
    both.callback(pendant.close)
    return both, stage


def _telemetry_of(endpoint: str) -> str:
    """The telemetry endpoint beside a request endpoint: the same host, the next port
    (irl serve's defaults: 5555 and 5556)."""
    head, sep, port = endpoint.rpartition(":")
    if sep and port.isdigit():
        return f"{head}:{int(port) + 1}"
    raise common.UsageError(f"--endpoint {endpoint}: give --telemetry E too (no port to count from)")
