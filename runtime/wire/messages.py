"""What crosses between ``irl serve``'s two processes (docs/runtime.md, "Process layout"),
declared once and used by both sides: the server (runtime/server/server.py) and the loop
(runtime/loop/robotloop.py). The model is LinuxCNC's ``emcmot_command_t`` and
``emcmot_status_t``: the commands the loop carries out and the snapshot it sends back are
typed values here, each with its msgpack-able form (``to_wire``) and back (``from_wire``);
neither side builds or reads the other's dicts by hand.

The network protocol to clients (runtime/wire/protocol.py, docs/protocol.md) is another
thing: the server answers clients from these values.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import ClassVar

#: The loop process's module, by name: the server starts it (``child``) and, for tests, builds
#: the loop in its own process (``in_process``) through this name alone, so the server's
#: process imports nothing of runtime.loop, runtime.motion or runtime.hardware
#: (tests/test_server_process.py checks its sys.modules; tests/house.py its imports).
LOOP_MODULE = "runtime.loop.robotloop"

#: How a user gets the wall clock, by command: said when a fieldbus needs it.
WALL_CLOCK_HOW = {"run": "add --realtime", "serve": "drop --sim-clock"}


def io_sources_problem(fieldbus: bool, cell: bool, wall_clock: bool, command: str = "run") -> str | None:
    """The rule of where the robot's inputs come from, once (``irl run``, ``irl serve``
    and the robot's assembly check it): a PLC (``--fieldbus``) and the simulated cell
    (``--cell-scenario``) both drive the inputs, so at most one of them; a PLC lives in
    real time, so only on the wall clock. Returns what is wrong, or None."""
    if fieldbus and cell:
        return "--fieldbus and --cell-scenario both drive the inputs: choose one"
    if fieldbus and not wall_clock:
        return f"--fieldbus needs the wall clock (the PLC lives in real time): {WALL_CLOCK_HOW[command]}"
    return None


#: s an exit waits for the robot to come to rest before an emergency stop (the loop
#: carries it out; the server waits this long, and a little more, for the loop to end).
EXIT_TIMEOUT = 15.0


@dataclass(frozen=True)
class LoopOptions:
    """How the server has the loop process build its robot (runtime.loop.system.RunOptions
    is made from it in that process): the seed, the clock, the state directory, the
    servo's deadline policy, the files of a cell scenario or a PLC (read there: the server
    process does not import the simulator or the fieldbus), and the real-time scheduling
    asked for (a runtime.scheduling.Scheduling; None: the default)."""

    seed: int = 0
    realtime: bool = False
    state_dir: str | Path | None = None
    deadline_policy: str | None = None
    cell: str | Path | None = None
    fieldbus: str | Path | None = None
    scheduling: object = None
    mode: str = "aut"  # the operating mode it starts in (runtime.wire.protocol.MODES)

    def problem(self) -> str | None:
        """What is wrong with these options (:func:`io_sources_problem`), or None."""
        return io_sources_problem(self.fieldbus is not None, self.cell is not None, self.realtime, "serve")


# ---- the commands the loop carries out (emcmot_command_t): the server sends, the loop answers each
@dataclass(frozen=True)
class Command:
    """A command to the loop. On the channel: ``{"op": OP, "ref": N, field: value...}``;
    every one is answered by a reply with the same ``ref``."""

    OP: ClassVar[str] = ""

    def to_wire(self, ref: int | None) -> dict:
        message = {"op": self.OP, "ref": ref}
        for f in fields(self):
            message[f.name] = getattr(self, f.name)
        return message


@dataclass(frozen=True)
class Start(Command):
    """Begin a cycle: a program (its verified object code; None: a reconfiguration, with
    its ``settings``), its report file, the override, its recording (an MCAP file, or None);
    in step mode (``step``) and from the move on line ``from_line`` (runtime.loop.stepping)."""

    OP: ClassVar[str] = "start"
    job: int
    object: bytes | None = None
    report: str | None = None
    settings: dict | None = None
    override: float = 100.0
    record: str | None = None
    jog: bool = False  # a jog session (no program): runtime/loop/jogging.py
    step: bool = False
    from_line: int | None = None


@dataclass(frozen=True)
class Pause(Command):
    """Pause the moving program on its path (``program``: only if it is this one)."""

    OP: ClassVar[str] = "pause"
    program: int | None = None


@dataclass(frozen=True)
class Resume(Command):
    """Resume a paused program (``program``: only if it is this one)."""

    OP: ClassVar[str] = "resume"
    program: int | None = None


@dataclass(frozen=True)
class Step(Command):
    """Step mode: the move the program waits before goes (``program``: only if it is this one)."""

    OP: ClassVar[str] = "step"
    program: int | None = None


@dataclass(frozen=True)
class Abort(Command):
    """Stop the running program (``program``: only if it is this one), saying why."""

    OP: ClassVar[str] = "abort"
    program: int | None = None
    reason: str | None = None


@dataclass(frozen=True)
class Estop(Command):
    """Emergency stop (category 1) of the running program."""

    OP: ClassVar[str] = "estop"


@dataclass(frozen=True)
class Override(Command):
    """Speed override, percent (1-100)."""

    OP: ClassVar[str] = "override"
    percent: float


@dataclass(frozen=True)
class Call(Command):
    """A scripting command (``text``), with the server's values a script may read (``front``)."""

    OP: ClassVar[str] = "call"
    text: str
    front: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Mode(Command):
    """Switch the operating mode (runtime.wire.protocol.MODES), only with no program running."""

    OP: ClassVar[str] = "mode"
    mode: str


@dataclass(frozen=True)
class Jog(Command):
    """One jog request (runtime.wire.protocol.OPS ``jog``): ``axis`` (an axis's name, or one
    of JOG_CARTESIAN), ``direction`` (+1, -1; 0 releases), ``frame`` (JOG_FRAMES) and
    ``step`` (None: continuous)."""

    OP: ClassVar[str] = "jog"
    axis: str
    direction: int
    frame: str = "world"
    step: float | None = None


@dataclass(frozen=True)
class Settings(Command):
    """Apply validated settings between programs."""

    OP: ClassVar[str] = "settings"
    settings: dict


@dataclass(frozen=True)
class Exit(Command):
    """Bring the robot to rest and end the loop, saying why."""

    OP: ClassVar[str] = "exit"
    reason: str | None = None


#: Every command, by its name on the channel.
@dataclass(frozen=True)
class Persistent(Command):
    """The persistent variables' store (runtime.loop.persistence): ``action`` "show" (every
    program's, or ``program``'s), "set" (``program``'s ``name`` to ``value``, plain data) or
    "reset" (``program``'s ``name``, or all of its values with ``name`` "")."""

    OP: ClassVar[str] = "persistent"
    action: str
    program: str = ""
    name: str = ""
    value: object = None


COMMANDS: dict[str, type[Command]] = {c.OP: c for c in (Start, Pause, Resume, Abort, Estop, Override, Call, Settings,
                                                        Exit, Mode, Jog, Step, Persistent)}


def command_of(message: dict) -> tuple[object, Command]:
    """``(ref, command)`` of a message to the loop (KeyError: no such command; TypeError:
    its fields are not the command's)."""
    kind = COMMANDS[message["op"]]
    return message.get("ref"), kind(**{k: v for k, v in message.items() if k not in ("op", "ref")})


# ---- what the loop says of the robot (emcmot_status_t) ---------------------------------------------
@dataclass(frozen=True)
class Progress:
    """Where the running program is: its source line, the moves done, whether it is
    paused, the largest absolute following error (deg); whether it runs in step mode,
    waits for a step, and whether its next move (or the one under way) is the approach of
    a start from a line (runtime.loop.stepping)."""

    line: int | None
    moves_done: int
    paused: bool
    following_error: float
    step: bool = False
    waiting_for_step: bool = False
    approach: bool = False


@dataclass(frozen=True)
class Snapshot:
    """The robot as the loop sees it: every 10 ms while a cycle runs, every 0.5 s while
    idle, and after every command. The server answers ``status`` and publishes telemetry
    samples from it. ``state``: the supervisor's state path (``"Idle"`` when no cycle
    runs); ``tool``, ``base``: the names of the move's frames; ``tcp``, ``tcp_base``: the
    tool centre point of the measured position in the world and in that base (None when
    the robot's kinematics give none); the calibration and homing memory; ``progress``
    while a program runs."""

    KIND: ClassVar[str] = "snapshot"
    t: float
    job: int | None
    state: str
    position: list
    inputs: list
    outputs: list
    tool: str
    base: str
    tcp: list | None
    tcp_base: list | None
    calibrated: bool
    initialized: bool
    calibration: str | None
    initialization: str | None
    progress: Progress | None = None
    mode: str = "aut"
    jog: dict | None = None

    def to_wire(self) -> dict:
        message = {"kind": self.KIND, "t": self.t, "job": self.job, "state": self.state, "position": self.position,
                   "inputs": self.inputs, "outputs": self.outputs, "tool": self.tool, "base": self.base,
                   "tcp": self.tcp, "tcp_base": self.tcp_base, "calibrated": self.calibrated,
                   "initialized": self.initialized, "calibration": self.calibration,
                   "initialization": self.initialization, "progress": None, "mode": self.mode, "jog": self.jog}
        p = self.progress
        if p is not None:
            message["progress"] = {"line": p.line, "moves_done": p.moves_done, "paused": p.paused,
                                   "following_error": p.following_error, "step": p.step,
                                   "waiting_for_step": p.waiting_for_step, "approach": p.approach}
        return message

    @classmethod
    def from_wire(cls, message: dict) -> "Snapshot":
        p = message["progress"]
        return cls(message["t"], message["job"], message["state"], message["position"], message["inputs"],
                   message["outputs"], message["tool"], message["base"], message["tcp"], message["tcp_base"],
                   message["calibrated"], message["initialized"], message["calibration"], message["initialization"],
                   None if p is None else Progress(**p), message["mode"], message["jog"])
