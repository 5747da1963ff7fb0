"""The ``irl`` command. A thin entry point: ``main(argv, env) -> exit status``.

Exit status: 0 success, 1 the program or object file is wrong, 2 usage or file errors.
Each command imports what it needs when it runs, and only the command that runs has its
arguments declared, so ``irl check`` starts without the runtime, NumPy or ZeroMQ
(:data:`NOT_FOR_CHECKING`).
"""
from __future__ import annotations

import argparse
import os
import shlex
import sys
from pathlib import Path

from runtime.cli.common import (EXIT_INTERNAL, EXIT_INVALID, EXIT_OK, EXIT_USAGE, Environment, UsageError, add_cell_scenario, add_deadline_policy, compile_source, joint_values, log_line, read_object, report_diagnostics, say, spec_compiled_for, warn)
from runtime.timing import TICK


#: What ``irl check`` does not need, so does not import (each name with its submodules):
#: the runtime (its loop, scheduling, simulated arm, network), NumPy, ZeroMQ, the object
#: code's encoding (msgpack), the code generator, plotting, and the package metadata
#: behind ``--version``. tests/test_cli.py and benchmarks/check_startup.py look for them.
NOT_FOR_CHECKING = ("numpy", "zmq", "msgpack", "matplotlib", "ctypes", "importlib.metadata", "email",
                    "compiler.codegen", "runtime.wire.protocol", "runtime.loop.realtime", "runtime.loop.executive",
                    "runtime.loop.system", "runtime.client.client", "runtime.server.server", "runtime.hardware.sim")


class _Formatter(argparse.HelpFormatter):
    """Help that shows each option's default (when it has one worth showing)."""

    def _get_help_string(self, action):
        text = action.help or ""
        if "default" not in text and action.default not in (None, False, argparse.SUPPRESS) \
                and (action.option_strings or action.nargs in ("?", "*")):
            text += " (default: %(default)s)"
        return text


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", _Formatter)
        super().__init__(*args, **kwargs)

    def error(self, message):  # argparse would print and sys.exit(2)
        raise UsageError(f"{message}\n{self.format_usage().strip()}")


def cmd_check(args, env: Environment) -> int:
    from runtime.cli.checking import report

    motion = not args.no_motion
    if args.cell_scenario is not None and not motion:
        raise UsageError("--cell-scenario is for the motion check: leave out --no-motion")
    if args.max_moves < 1:
        raise UsageError(f"--max-moves {args.max_moves}: expected a whole number of moves >= 1")
    result = compile_source(args.file, args.spec, generate_code=motion)
    check = None
    if motion and result.ok:  # (a program with errors does not run)
        from runtime.cli.checking import MotionCheck

        check = MotionCheck(result, args.cell_scenario, args.max_moves)
        check.run()
    return report(env, result, check, args.json)


def _write_atomically(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise UsageError(f"cannot write {path}: {exc.strerror or exc}") from None


def cmd_compile(args, env: Environment) -> int:
    from compiler.objcode import encode

    result = compile_source(args.file, args.spec)
    report_diagnostics(env, result, args.json)
    if not result.ok:
        return EXIT_INVALID
    out = Path(args.output) if args.output else Path(args.file).with_suffix(".irlo")
    if out.resolve() == Path(args.file).resolve():
        raise UsageError(f"refusing to write the object code over its source {args.file}")
    data = encode(result.program)
    _write_atomically(out, data)
    if not args.json:
        say(env, f"{args.file} -> {out} ({len(data)} bytes, {len(result.program.code)} instructions)")
    return EXIT_OK


def cmd_dis(args, env: Environment) -> int:
    from compiler.disasm import format_json, format_text
    from compiler.objcode import ObjectCodeError, decode, encode, verify

    source = modules = None
    if args.file.endswith(".irl"):
        result = compile_source(args.file, args.spec)
        report_diagnostics(env, result, False)
        if not result.ok:
            return EXIT_INVALID
        program, source, modules = result.program, result.source, result.modules
        data = encode(program)
    else:
        data = read_object(args.file)
        try:
            program = decode(data)
            verify(program)
        except ObjectCodeError as exc:
            warn(env, f"{args.file}: invalid object code: {exc}")
            return EXIT_INVALID
    if args.json:
        import json

        say(env, json.dumps(format_json(program, data), indent=2))
    else:
        env.stdout.write(format_text(program, data, source, modules))
    return EXIT_OK


def _load_program(path: str, spec_path: str | None, env: Environment):
    """FILE.irl (compiled now) or FILE.irlo (decoded and verified): (program, spec) or None."""
    from compiler.objcode import ObjectCodeError, decode, spec_mismatch, verify
    from compiler.spec import SpecError, load_spec

    if not path.endswith(".irlo"):
        result = compile_source(path, spec_path)
        report_diagnostics(env, result, False)
        return (result.program, result.spec) if result.ok else None
    data = read_object(path)
    try:
        program = decode(data)
    except ObjectCodeError as exc:
        warn(env, f"{path}: invalid object code: {exc}")
        return None
    if spec_path is None:
        guess = Path(path).with_name(program.source).with_suffix(".irl")
        raise UsageError(f"{path}: give the robot's specification with --spec FILE.spc "
                         f"(the object code names {program.spec_name!r}; its source was {guess.name})")
    try:
        spec = load_spec(spec_path)
    except SpecError as exc:
        raise UsageError(str(exc)) from None
    if program.spec_hash != spec.hash:
        compiled_for, source = spec_compiled_for(program, Path(path))
        warn(env, f"{path}: " + spec_mismatch(
            program, spec, compiled_for=compiled_for, source=source,
            unknown="no .spc file beside the object file has this hash", instead=f"run it with the specification it was compiled for (irl run {shlex.quote(path)} --spec {{}})"))
        return None
    try:
        verify(program, spec.hash)
    except ObjectCodeError as exc:
        warn(env, f"{path}: {exc}")
        return None
    return program, spec


def _print_summary(env: Environment, s: dict) -> None:
    say(env, f"program {s['program']} on {s['robot']}: "
                f"{'FAULT: ' + s['fault'] if s['fault'] else 'completed'}")
    say(env, "")
    say(env, "  state                      enter      time")
    for st in s["states"]:
        say(env, f"  {st['name']:24s} {st['t_enter']:8.3f} s {st['t_exit'] - st['t_enter']:8.3f} s")
    if s["moves"]:
        say(env, "")
        say(env, "  move  line   planned    actual")
        for i, m in enumerate(s["moves"], 1):
            actual = f"{m['actual_duration']:8.3f} s" if m["actual_duration"] is not None else "     (unfinished)"
            blended = "  blended into the next" if m.get("blended") else ""
            say(env, f"  {i:4d}  {m['line']:4d}  {m['planned_duration']:7.3f} s {actual}{blended}")
    say(env, "")
    if s.get("step"):
        say(env, "  step mode: every move waited for a step")
    start = s.get("from_line")
    if start is not None:
        skipped = ", ".join(f"{n} {what if n != 1 else what.rstrip('s')}" for what, n in start["skipped"].items() if n)
        approach = start["approach"]
        went = ("no approach (its move is the program's first)" if approach is None else
                f"approach to the target of line {approach['to_line']}: " +
                (f"{approach['actual_duration']:.3f} s" if approach["actual_duration"] is not None else "unfinished"))
        say(env, f"  started from line {start['line']}" + ("" if start["reached"] else " (not reached)") +
            f": skipped {skipped or 'nothing'}; {went}")
    if s.get("stop"):
        say(env, f"  stopped: category {s['stop']['category']} (docs/safety.md)")
    say(env, "  final position: " + joint_values(s["final_position"]))
    say(env, f"  largest following error: {s['max_following_error']:.4f}")
    servo = s["deadlines"].get("servo", {}).get("misses", 0)
    say(env, f"  deadline misses: {s['deadline_misses']} of {s['ticks']} ticks late (the servo's: {servo})")
    ratio = s["sim_time"] / s["wall_time"] if s["wall_time"] > 0 else float("inf")
    say(env, f"  simulated {s['sim_time']:.3f} s in {s['wall_time']:.3f} s wall ({ratio:.1f}x; "
                f"kernels: {s['kernels']})")


def _flush(env: Environment) -> None:
    flush = getattr(env.stdout, "flush", None)
    if flush is not None:
        flush()


#: What holds a program for the operator under irl run (RobotSystem.run's ``on_pause``
#: kinds): what it is, the prompt's Enter, and what going on is called.
_HOLDS = {"pause": ("paused by the program", "Enter resumes", "resumed"),
          "step": ("step mode: the move waits", "Enter moves it", "it goes"),
          "approach": ("step mode: the approach to this move's start waits", "Enter makes it", "it goes")}


def _on_pause(args, env: Environment):
    """What a ``pause;`` of the program, and in step mode each move, leads to under irl
    run: on a terminal, ask (Enter resumes or goes on, 'abort' aborts); else, or with
    --on-pause, resume (go on) or abort at once, saying so."""
    stdin = env.stdin
    choice = args.on_pause or ("ask" if stdin is not None and stdin.isatty() else "resume")

    why = f"--on-pause {choice}" if args.on_pause else "not a terminal; --on-pause ask|resume|abort chooses"

    def decide(line: int, kind: str = "pause") -> str:
        what, enter, went = _HOLDS[kind]
        if choice != "ask":
            warn(env, f"irl run: line {line}: {what}: {went if choice == 'resume' else 'aborted'} ({why})")
            return choice
        env.stderr.write(f"irl run: line {line}: {what}. {enter}, 'abort' Enter aborts: ")
        env.stderr.flush()
        answer = stdin.readline()
        return "abort" if answer.strip().lower() == "abort" or not answer else "resume"
    return decide


def cmd_run(args, env: Environment) -> int:
    if args.plot and not args.report:
        raise UsageError("--plot needs --report (the plot is drawn from the report)")
    if args.report_columns is not None and not args.report:
        raise UsageError("--report-columns needs --report (it chooses the report's columns)")
    if args.record:
        from runtime.recording import missing

        if missing():
            raise UsageError(f"--record: {missing()}")
    loaded = _load_program(args.file, args.spec, env)
    if loaded is None:
        return EXIT_INVALID
    program, spec = loaded
    if args.from_line is not None:
        from compiler.objcode import from_line_problem

        problem = from_line_problem(program, args.from_line)
        if problem is not None:
            raise UsageError(f"--from-line {args.from_line}: {problem}")
    from runtime.hardware.backends import DEFAULT_ROBOT, ROBOTS
    from runtime.loop.system import RobotSystem, RunOptions
    from runtime.wire.messages import io_sources_problem

    faults = []
    injectable = ROBOTS[DEFAULT_ROBOT].faults
    for item in args.inject or []:
        fault, _, axis = item.partition(":")
        names = [a.name.lower() for a in spec.axes]
        if fault not in injectable or axis.lower() not in names:
            raise UsageError(f"--inject {item}: expected FAULT:AXIS with FAULT one of {', '.join(injectable)} "
                             f"and AXIS one of {', '.join(a.name for a in spec.axes)}")
        faults.append((fault, names.index(axis.lower())))
    if not 1.0 <= args.override <= 100.0:
        raise UsageError(f"--override {args.override:g}: expected a percentage from 1 to 100")
    from runtime.loop import realtime

    try:
        wanted = realtime.scheduling(args)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    given = realtime.given(args)
    if given and not args.realtime:
        raise UsageError(f"{' and '.join(given)} {'is' if len(given) == 1 else 'are'} for the wall clock: "
                         "add --realtime")
    problem = io_sources_problem(bool(args.fieldbus), bool(args.cell_scenario), args.realtime, "run")
    if problem is not None:
        raise UsageError(problem)
    from runtime.hardware.backends import load_io_files

    try:
        cell, fieldbus = load_io_files(args.cell_scenario, args.fieldbus, spec)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    columns = _report_columns(args.report_columns, spec) if args.report_columns is not None else None
    settings = _run_settings(args)
    options = RunOptions(seed=args.seed, realtime=args.realtime, report=args.report, record=args.record,
                         state_dir=args.state_dir, max_time=args.max_time, faults=faults, override=args.override,
                         deadline_policy=args.deadline_policy, cell=cell, fieldbus=fieldbus, mode=args.mode)
    on_pause = _on_pause(args, env)

    def on_log(at: float, line: int, text: str) -> None:  # the program's print output, as it comes
        say(env, log_line(at, line, text))
        _flush(env)

    # the loop's thread is this one: on the wall clock it asks for real-time scheduling (by
    # default SCHED_FIFO, memory locked; says what it got) and gives it back when the run ends
    from contextlib import nullcontext

    with realtime.Applied(wanted) if args.realtime else nullcontext() as got:
        if got is not None:
            warn(env, f"irl run: {got.text}")
        try:
            system = RobotSystem(spec, options)
            if settings:
                _apply_settings(system, settings, args)
            if columns is not None:
                add, names = columns
                system.report.columns = [*system.report.columns,
                                         *(n for n in names if n not in system.report.columns)] if add else names
            summary = system.run(program, on_pause, None if args.json else on_log, step=args.step,
                                 from_line=args.from_line)
        except ValueError as exc:  # refused at load time (e.g. a move kind not supported yet)
            warn(env, f"{args.file}: {exc}")
            return EXIT_INVALID
    plot_status = _plot(args.report, args.plot, env) if args.plot else EXIT_OK  # files first, then words
    if args.json:
        import json

        say(env, json.dumps(summary, indent=2))
    else:
        _print_summary(env, summary)
    if plot_status:
        return plot_status
    return EXIT_INVALID if summary["fault"] else EXIT_OK


def _run_settings(args) -> dict:
    """The component settings ``--config`` (the file's default configuration) and
    ``--report-period`` ask for, each checked as a configuration's are (compiler.params)."""
    settings: dict = {}
    if args.config:
        from runtime.config import ConfigError, load_configurations

        try:
            configurations = load_configurations(args.config)
        except ConfigError as exc:
            raise UsageError(str(exc)) from None
        settings = {component: dict(values)
                    for component, values in configurations.default_configuration.settings.items()}
    if args.report_period is not None:
        from compiler.params import ParamError, component_params

        seconds = args.report_period / 1000.0
        try:
            seconds = component_params("report")["period"].check(seconds)
        except ParamError as exc:
            raise UsageError(f"--report-period {args.report_period:g} (ms): report.period would be {seconds:g} s: "
                             f"{exc.reason}") from None
        settings.setdefault("report", {})["period"] = seconds
    return settings


def _apply_settings(system, settings: dict, args) -> None:
    """Lay ``settings`` over the system's own and apply them (before the run starts)."""
    from runtime.config import ConfigError, merge_settings, validate_settings

    where = " and ".join(x for x in (f"{args.config}: configuration" if args.config else "",
                                      "--report-period" if args.report_period is not None else "") if x)
    try:
        merged = validate_settings(merge_settings(system.settings(), settings), where)
    except ConfigError as exc:
        raise UsageError(str(exc)) from None
    system.apply_settings(merged)


def _report_columns(text: str, spec) -> tuple[bool, list[str]]:
    """``--report-columns``: (whether they add to the report's own, the column groups),
    checked as a configuration's ``report.columns`` is."""
    from compiler.params import ParamError, component_params

    add = text.startswith("+")
    names = [name.strip() for name in (text[1:] if add else text).split(",") if name.strip()]
    try:
        names = component_params("report")["columns"].check(names)
    except ParamError as exc:
        raise UsageError(f"--report-columns {text}: {exc.reason}") from None
    if "tcp" in names:
        from runtime.motion.tcp import tcp_of

        if tcp_of(spec) is None:
            raise UsageError(f"--report-columns {text}: this robot's kinematics give no tool centre point (tcp)")
    return add, names


def _plot(report: str, out: str, env: Environment) -> int:
    from runtime.cli.plot import PlotError, plot_report

    try:
        plot_report(report, out)
    except PlotError as exc:
        warn(env, f"irl plot: {exc}")
        return EXIT_USAGE
    if env is not None:
        warn(env, f"plot written to {out}")
    return EXIT_OK


def cmd_plot(args, env: Environment) -> int:
    return _plot(args.report, args.output, env)


def cmd_latency(args, env: Environment) -> int:
    import json

    from compiler.params import section_params
    from runtime.loop import realtime

    try:
        wanted = realtime.scheduling(args)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if not (0.05 <= args.period <= 1000.0):
        raise UsageError(f"--period {args.period:g}: expected 0.05 to 1000 ms")
    if not (0.0 < args.duration <= 3600.0):
        raise UsageError(f"--duration {args.duration:g}: expected more than 0 and at most 3600 s")
    controller = section_params("controller")
    limit, window = controller["servo_miss_limit"].default, controller["servo_miss_window"].default
    if args.spec:
        from compiler.spec import SpecError, load_spec

        try:
            spec = load_spec(args.spec)
        except SpecError as exc:
            raise UsageError(str(exc)) from None
        limit, window = spec.controller.servo_miss_limit, spec.controller.servo_miss_window
    with realtime.Applied(wanted) as applied:  # (given back afterwards: a test runs it in-process)
        got = applied.text
        result = realtime.measure(args.period / 1000.0, args.duration)
    policy, why = realtime.verdict(result, limit, window)
    ms = 1000.0
    figures = {"period_ms": args.period, "duration_s": args.duration, "scheduling": got,
               "wakeups": len(result.late), "max_ms": max(result.late) * ms, "p50_ms": result.percentile(0.5) * ms,
               "p99_ms": result.percentile(0.99) * ms, "p999_ms": result.percentile(0.999) * ms,
               "misses": len(result.misses), "policy": policy, "why": why,
               "histogram": [{"from_ms": a * ms, "to_ms": b * ms, "count": c} for a, b, c in result.histogram()]}
    if args.json:
        say(env, json.dumps(figures, indent=2))
        return EXIT_OK
    say(env, f"{len(result.late)} wake-ups every {args.period:g} ms for {args.duration:g} s ({got})")
    say(env, f"  late by: max {figures['max_ms']:.3f} ms, p50 {figures['p50_ms']:.3f}, p99 "
                f"{figures['p99_ms']:.3f}, p99.9 {figures['p999_ms']:.3f}; {figures['misses']} too late for a tick's "
                f"work (more than {(1 - realtime.WORK_SHARE) * args.period:g} ms)")
    top = max((c for _a, _b, c in result.histogram()), default=1) or 1
    for a, b, c in result.histogram():
        say(env, f"  {a * ms:7.3f}-{b * ms:7.3f} ms {c:8d} {'#' * max(1 if c else 0, round(40 * c / top))}")
    say(env, f"this host can hold: {policy} ({why})")
    return EXIT_OK


def cmd_fsm(args, env: Environment) -> int:
    from runtime.cli.diagram import supervisor_diagram

    env.stdout.write(supervisor_diagram(args.format))
    return EXIT_OK


def cmd_urdf(args, env: Environment) -> int:
    from compiler.spec import SpecError, load_spec
    from runtime.motion.urdf import urdf_text

    path = Path(args.spec)
    if not path.is_file():
        raise UsageError(f"cannot read {args.spec}: {'no such file' if not path.exists() else 'not a file'}")
    try:
        spec = load_spec(path)
    except SpecError as exc:
        warn(env, f"irl urdf: {exc}")
        return EXIT_INVALID
    try:
        text = urdf_text(spec)
    except ValueError as exc:  # no arm the kinematics can take, or names a URDF cannot carry
        warn(env, f"irl urdf: {spec.file}: no URDF of this arm: {exc}")
        return EXIT_INVALID
    if args.output is None:
        env.stdout.write(text)
        return EXIT_OK
    _write_atomically(Path(args.output), text.encode("utf-8"))
    say(env, f"{spec.file} -> {args.output} (robot {spec.name}, joints {', '.join(a.name for a in spec.main_axes)})")
    return EXIT_OK


def version_text() -> str:
    """``irl --version``: the package, and the formats a peer must share with it."""
    from importlib import metadata

    from compiler.objcode import FORMAT_VERSION
    from runtime.wire.protocol import VERSION

    try:
        version = metadata.version("irl")
    except metadata.PackageNotFoundError:  # (run from a source tree that is not installed)
        version = "unknown (not installed)"
    return f"irl {version} (object code format {FORMAT_VERSION}, protocol {VERSION})"


class _Version(argparse.Action):
    """``--version``, worked out only when asked for: it reads the package metadata and the
    object-code and protocol modules, which no other command (``irl check`` above all) needs."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, help=None):
        super().__init__(option_strings, dest=dest, default=default, nargs=0,
                         help=help or "print the package's version and the object-code and protocol versions")

    def __call__(self, parser, namespace, values, option_string=None):
        parser._print_message(version_text() + "\n", sys.stdout)  # (as argparse's own version action)
        parser.exit()


class Commands:
    """Names each command (with its help) on ``irl``'s subparsers; ``__call__`` gives the
    command's parser to declare its arguments on, or None when only another command is
    wanted (``build_parser(command)``)."""

    def __init__(self, sub, only: str | None):
        self.sub, self.only = sub, only

    def __call__(self, name: str, help: str):
        parser = self.sub.add_parser(name, help=help)
        return parser if self.only in (None, name) else None


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """``irl``'s parser. Every command is named with its help (``irl --help`` lists them all);
    the arguments are declared for every command, or for ``command`` alone (the one
    :func:`main` runs): declaring another command's arguments can import what that command
    needs (the runtime's scheduling flags, the network commands), and ``irl check`` starts
    with no more than checking needs."""
    parser = _Parser(prog="irl", description="L-IRL robot programs: compile, inspect, run.")
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    declare = Commands(sub, command)

    if (p := declare("check", help="check a program; print every diagnostic")) is not None:
        _check_arguments(p)
    if (p := declare("compile", help="compile a program to object code (.irlo)")) is not None:
        _compile_arguments(p)
    if (p := declare("dis", help="disassemble object code (or compile a program and disassemble it)")) is not None:
        _dis_arguments(p)
    if (p := declare("run", help="run a program on the simulated robot, through every phase")) is not None:
        _run_arguments(p)
    if (p := declare("latency", help="measure this host's wake-up latency: which deadline policy a 1 ms servo "
                                     "can hold here")) is not None:
        _latency_arguments(p)
    if (p := declare("plot", help="draw a report: position over time per axis, phases shaded")) is not None:
        _plot_arguments(p)
    if (p := declare("fsm", help="print the supervisor's state machine as a diagram")) is not None:
        _fsm_arguments(p)
    if (p := declare("pose", help="the pose literal, with its configuration, that reaches given joint values (or "
                                  "the robot's current ones): teach a point")) is not None:
        from runtime.cli.teach import add_arguments as pose_arguments

        pose_arguments(p)
    if (p := declare("view", help="the robot in 3D in the browser: a program's paths, a report or recording "
                                  "replayed, or a served robot live")) is not None:
        from runtime.cli.viewing import add_arguments as view_arguments, cmd_view

        view_arguments(p)
        p.set_defaults(run=cmd_view)
    if (p := declare("urdf", help="the arm as URDF (links, joints named after the axes, tools and frames): for 3D "
                                  "viewers and ROS tools")) is not None:
        _urdf_arguments(p)
    if command is None or command not in sub.choices:  # (naming the network commands imports their module)
        from runtime.cli.netcli import add_commands  # light: ZeroMQ is imported when a command runs
        from runtime.cli.operate import add_commands as operator_commands

        add_commands(declare)
        operator_commands(declare)
    helps = {choice.dest: choice.help for choice in sub._choices_actions}
    for name, command_parser in sub.choices.items():  # each command's own help starts with what it does
        command_parser.description = command_parser.description or helps.get(name)
    return parser


#: the most moves ``irl check`` plans by default (runtime.loop.offline.MAX_MOVES: a test
#: checks they agree; not imported here, so that ``--no-motion`` imports nothing of the runtime)
MAX_CHECKED_MOVES = 2000

#: what --spec means to a command that compiles the program it is given
OTHER_SPEC = "use this system specification instead of the program's"


def _program_arguments(p, metavar: str, what: str, spec: str) -> None:
    """The program (or object code) a command reads, and the specification for it."""
    p.add_argument("file", metavar=metavar, help=what)
    p.add_argument("--spec", metavar="FILE.spc", help=spec)


def _check_arguments(p) -> None:
    _program_arguments(p, "FILE.irl", "the program", OTHER_SPEC)
    p.add_argument("--json", action="store_true",
                   help="one JSON object (for editors): the diagnostics (motion ones marked), and the motion check's "
                        "cycle time, moves and assumptions")
    p.add_argument("--no-motion", action="store_true",
                   help="only the compiler's checks: do not run the program's moves offline through the runtime's "
                        "planners")
    add_cell_scenario(p, "the cell the motion check runs the program in, as irl run --cell-scenario (default: the "
                         "assumed cell, see docs/language.md)")
    p.add_argument("--max-moves", type=int, default=MAX_CHECKED_MOVES, metavar="N",
                   help="the most moves the motion check plans, all runs together")
    p.set_defaults(run=cmd_check)


def _compile_arguments(p) -> None:
    _program_arguments(p, "FILE.irl", "the program", OTHER_SPEC)
    p.add_argument("-o", "--output", metavar="OUT.irlo", help="default: beside the source, suffix .irlo")
    p.add_argument("--json", action="store_true", help="diagnostics as a JSON list")
    p.set_defaults(run=cmd_compile)


def _dis_arguments(p) -> None:
    _program_arguments(p, "FILE.irlo|FILE.irl", "the object code, or a program to compile first",
                       "for FILE.irl: the system specification to use")
    p.add_argument("--json", action="store_true", help="the listing as JSON")
    p.set_defaults(run=cmd_dis)


def _run_arguments(p) -> None:
    from runtime.hardware.backends import DEFAULT_ROBOT, ROBOTS
    from runtime.loop.realtime import add_arguments

    _program_arguments(p, "FILE.irl|FILE.irlo", "the program, or its object code (then --spec)",
                       "the robot's specification (needed for FILE.irlo)")
    p.add_argument("--report", metavar="OUT.csv", help="write the report (and OUT.states.csv)")
    p.add_argument("--plot", metavar="OUT.png", help="draw the report (needs --report and matplotlib)")
    p.add_argument("--record", metavar="FILE.mcap",
                   help="record the run: joints, TCP, every link, phases, lines, I/O, prints and faults, in an MCAP "
                        "file that Foxglove opens (see docs/runtime.md)")
    p.add_argument("--report-columns", metavar="LIST",
                   help="the report's column groups, comma-separated, in order (default: sens_pos,desi_pos,out_vel,"
                        "following_error,tcp, and io with a cell or fieldbus); +LIST adds to them: +move records "
                        "each move's number and line, which irl plot marks")
    p.add_argument("--report-period", type=float, metavar="MS",
                   help="time between two report rows, ms: report.period's range, a whole number of 1 ms ticks "
                        "(default: the configuration's, 10; 1 records every tick, e.g. to check triggers)")
    p.add_argument("--config", metavar="FILE.toml",
                   help="component configurations (as irl serve --config): the run uses the file's default "
                        "configuration (see docs/runtime.md); --report-period and --report-columns apply over it")
    p.add_argument("--realtime", action="store_true", help="run on the wall clock (default: simulated clock)")
    add_cell_scenario(p, "what the simulated cell does with the digital I/O: inputs that follow outputs, latch or "
                         "toggle on a timeline (see docs/runtime.md); the report gains the io columns")
    p.add_argument("--fieldbus", metavar="FILE.toml",
                   help="the digital I/O on a PLC over Modbus TCP (see docs/runtime.md); needs --realtime")
    p.add_argument("--on-pause", choices=("ask", "resume", "abort"),
                   help="what the program's 'pause;' (and with --step each move) leads to (default: ask on a "
                        "terminal: Enter resumes, or moves; else resume, or go on, saying so)")
    p.add_argument("--step", action="store_true",
                   help="step mode: the program stops before each of its moves, which goes when you press Enter "
                        "(--on-pause); no look-ahead, no blending: the robot stops at every target")
    p.add_argument("--from-line", type=int, metavar="N",
                   help="start at the move on line N: the program runs to it without moving (no waits, outputs or "
                        "prints), the robot goes to that move's start with a ptp move at 10 %% speed, then the program "
                        "runs on from there (docs/runtime.md)")
    p.add_argument("--seed", type=int, default=0, help="the simulated robot's seed (power-up position, offsets)")
    p.add_argument("--state-dir", metavar="DIR", help="remember the calibration in DIR across runs")
    p.add_argument("--max-time", type=float, default=3600.0, metavar="S", help="stop the run after S seconds")
    p.add_argument("--override", type=float, default=100.0, metavar="PCT",
                   help="speed override, percent (1-100): velocities x p, accelerations x p^2")
    p.add_argument("--inject", action="append", metavar="FAULT:AXIS",
                   help=f"break the simulated robot: {', '.join(ROBOTS[DEFAULT_ROBOT].faults)} on an axis (e.g. sensor_dead:A3)")
    p.add_argument("--mode", choices=("aut", "t1"), default="aut",
                   help="the operating mode (docs/safety.md): aut (default), or t1, a test run at manual reduced "
                        "speed: the tool centre point and the flange at most [safety] t1_speed (250 mm/s), checked "
                        "every 1 ms")
    p.add_argument("--json", action="store_true", help="the summary as one JSON object")
    add_deadline_policy(p)
    add_arguments(p)
    p.set_defaults(run=cmd_run)


def _latency_arguments(p) -> None:
    from runtime.loop.realtime import add_arguments

    p.add_argument("--period", type=float, default=TICK * 1000.0, metavar="MS",
                   help="the period to wake up at, ms (default: the servo's, %(default)g)")
    p.add_argument("--duration", type=float, default=10.0, metavar="S", help="how long to measure (default %(default)g s)")
    p.add_argument("--spec", metavar="FILE.spc",
                   help="take the firm policy's limit and window from this specification (default: the defaults)")
    p.add_argument("--json", action="store_true", help="the figures as one JSON object")
    add_arguments(p)
    p.set_defaults(run=cmd_latency)


def _plot_arguments(p) -> None:
    p.add_argument("report", metavar="REPORT.csv", help="a report written by irl run --report or irl submit --report")
    p.add_argument("-o", "--output", metavar="FIG.png", required=True, help="where to draw it (PNG, PDF or SVG)")
    p.set_defaults(run=cmd_plot)


def _fsm_arguments(p) -> None:
    p.add_argument("--format", choices=("mermaid", "dot"), default="mermaid", help="the diagram's language")
    p.set_defaults(run=cmd_fsm)


def _urdf_arguments(p) -> None:
    p.add_argument("spec", metavar="SPEC.spc", help="the robot's specification")
    p.add_argument("-o", "--output", metavar="FILE.urdf", help="write it there (default: to standard output)")
    p.set_defaults(run=cmd_urdf)


def main(argv: list[str] | None = None, env: Environment | None = None) -> int:
    env = env or Environment()
    try:
        words = sys.argv[1:] if argv is None else argv
        command = next((w for w in words if not w.startswith("-")), None)  # (irl's own options take no value)
        args = build_parser(command).parse_args(argv)
        return args.run(args, env)
    except UsageError as exc:
        warn(env, f"irl: {exc}")
        return EXIT_USAGE
    except SystemExit as exc:  # --help
        return exc.code if isinstance(exc.code, int) else EXIT_OK
    except KeyboardInterrupt:
        warn(env, "irl: interrupted")
        return 130
    except BrokenPipeError:  # the reader went away (e.g. `| head`): nothing more to say
        return EXIT_OK
    except Exception as exc:  # the last guard: a user never sees a traceback
        warn(env, f"irl: internal error: {type(exc).__name__}: {exc}\n"
                  "This is a bug in irl; please report it with the input that caused it.")
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
