"""A table-driven, hierarchical finite state machine, stepped once per cycle.

The engine follows the real-time FSM of OROCOS that the paper uses: states with entry,
run, handle and exit programs; ordered, guarded transitions with transition programs;
exactly one initial and one final state; at most one transition per step; automatic and
reactive modes that can be switched while running; a state may hold a sub-machine.
The cycle rules are written down in docs/fsm.md and pinned by tests/test_fsm.py.

Programs and guards are plain callables without arguments (closures over whatever they
act on). Stepping allocates nothing: the table is compiled into per-state tuples once.
Every method that runs in the real-time loop says so.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterable

Program = Callable[[], None]
Guard = Callable[[], bool]

AUTOMATIC, REACTIVE = "automatic", "reactive"


def _nothing() -> None:
    return None


@dataclass
class State:
    """A state: its programs (each optional) and, optionally, a sub-machine."""

    name: str
    entry: Program | None = None
    run: Program | None = None
    handle: Program | None = None
    exit: Program | None = None
    sub: "FSM | None" = None
    doc: str = ""


@dataclass
class Transition:
    """A row of the transition table: from ``source`` to ``target`` when the guard holds
    (and, if ``event`` is set, that event is pending). ``label`` names the guard in
    diagrams; ``program`` runs when the transition fires, before the source's exit."""

    source: str
    target: str
    guard: Guard | None = None
    program: Program | None = None
    event: str | None = None
    label: str = ""


class FSMError(Exception):
    """A malformed machine (raised when it is built, never while it steps)."""


@dataclass
class _Compiled:
    state: State
    entry: Program
    run: Program | None
    handle: Program | None
    exit: Program
    final: bool = False  # the machine's final state
    transitions: tuple = ()  # ((target, guard|None, program, event|None, compiled-target), ...)
    guarded: tuple = ()  # the transitions without an event: ((guard|None, program, compiled-target), ...)


@dataclass
class FSM:
    """The machine. Build it with states and a transition table, then ``start()`` it."""

    name: str
    states: list[State]
    transitions: list[Transition]
    initial: str
    final: str
    mode: str = AUTOMATIC
    clock: Callable[[], float] = lambda: 0.0
    on_transition: Callable[[str, str, float], None] | None = None
    _by_name: dict = field(default_factory=dict, repr=False)
    _current: _Compiled | None = field(default=None, repr=False)
    _events: set = field(default_factory=set, repr=False)
    _requested: str | None = field(default=None, repr=False)
    history: list = field(default_factory=list, repr=False)

    def __post_init__(self) -> None:
        names = [s.name for s in self.states]
        if len(set(names)) != len(names):
            raise FSMError(f"{self.name}: two states have the same name")
        if self.initial not in names or self.final not in names:
            raise FSMError(f"{self.name}: the initial ({self.initial!r}) and final ({self.final!r}) "
                           "states must be among the states")
        if self.initial == self.final:
            raise FSMError(f"{self.name}: the initial and the final state must differ")
        if self.mode not in (AUTOMATIC, REACTIVE):
            raise FSMError(f"{self.name}: mode must be {AUTOMATIC!r} or {REACTIVE!r}")
        for s in self.states:
            # run and handle stay None when absent: the step skips them (it runs every cycle)
            self._by_name[s.name] = _Compiled(s, s.entry or _nothing, s.run, s.handle, s.exit or _nothing,
                                              s.name == self.final)
        rows: dict[str, list] = {n: [] for n in names}
        for t in self.transitions:
            if t.source not in rows or t.target not in rows:
                raise FSMError(f"{self.name}: transition {t.source!r} -> {t.target!r} names an unknown state")
            rows[t.source].append((t.target, t.guard, t.program or _nothing, t.event, self._by_name[t.target]))
        for n in names:
            compiled = self._by_name[n]
            compiled.transitions = tuple(rows[n])
            compiled.guarded = tuple([(guard, program, target) for _name, guard, program, event, target in rows[n]
                                      if event is None])

    # ---- inspection ----
    @property
    def state(self) -> str | None:
        """The current state's name (None before ``start``)."""
        return self._current.state.name if self._current is not None else None

    @property
    def active(self) -> bool:
        return self._current is not None

    @property
    def finished(self) -> bool:
        """True once the final state has been entered."""
        return self._current is not None and self._current.state.name == self.final

    def path(self) -> str:
        """The current state, with the sub-machine's state: "Init/Find Sensor A1"."""
        if self._current is None:
            return ""
        sub = self._current.state.sub
        if sub is not None and sub.active and not sub.finished:
            return f"{self.state}/{sub.path()}"
        return self.state

    # ---- control (not real-time: called between steps, from the loop or an operator) ----
    def start(self) -> None:
        """Activate the machine: enter the initial state (its entry program runs now).
        A machine already active first leaves its current state (exit program, and its
        sub-machine is stopped), as a re-entered parent restarts its sub-machine."""
        if self._current is not None:
            self._leave(self._current)
        self._events = set()
        self._requested = None
        self._enter(self._by_name[self.initial], None)

    def set_mode(self, mode: str) -> None:
        if mode not in (AUTOMATIC, REACTIVE):
            raise ValueError(f"mode must be {AUTOMATIC!r} or {REACTIVE!r}, not {mode!r}")
        self.mode = mode

    def post(self, event: str) -> None:
        """Make ``event`` pending for the next step (real-time safe)."""
        self._events.add(event)

    def request_state(self, name: str) -> bool:
        """Ask for a transition to ``name`` at the next step. False (nothing pending) when
        the table has no transition from the current state to it."""
        if self._current is None or name not in self._by_name:
            return False
        if not any(row[0] == name for row in self._current.transitions):
            return False
        self._requested = name
        return True

    def stop(self) -> None:
        """Go to the final state from wherever the machine is (exit, then the final's entry).
        Pending requests and events are dropped."""
        self._requested = None
        self._events = set()
        if self._current is None or self.finished:
            return
        self._leave(self._current)
        self._enter(self._by_name[self.final], self._current.state.name)

    # ---- the step (real-time) ----
    def step(self) -> bool:
        """One cycle (real-time): sub-machine, run, at most one transition or else handle.
        Returns True when a transition fired. Events pending at the start are consumed."""
        current = self._current
        if current is None:
            return False
        pending = self._events
        if pending:  # events posted during this step stay pending for the next one
            self._events = set()
        sub = current.state.sub
        if sub is not None and sub._current is not None and not sub._current.final:  # active, not finished
            sub.step()
        if current.run is not None:
            current.run()
        requested = self._requested
        if requested is None and not pending and self.mode == AUTOMATIC:
            # the usual step: the guarded transitions in table order (event rows wait for their event)
            for guard, program, compiled in current.guarded:
                if guard is None or guard():
                    self._fire(current, program, compiled)
                    return True
        else:
            self._requested = None
            automatic = self.mode == AUTOMATIC
            for target, guard, program, event, compiled in current.transitions:
                if requested is not None:
                    if target != requested:
                        continue
                elif event is not None:
                    if event not in pending:
                        continue
                elif not automatic:
                    continue
                if guard is not None and not guard():
                    continue
                self._fire(current, program, compiled)
                return True
        if current.handle is not None:
            current.handle()
        return False

    def _fire(self, current: _Compiled, program: Program, target: _Compiled) -> None:
        """A transition fires: its program, then the source's exit, then the target's entry."""
        program()
        self._leave(current)
        self._enter(target, current.state.name)

    def _leave(self, compiled: _Compiled) -> None:
        sub = compiled.state.sub
        if sub is not None and sub.active and not sub.finished:
            sub.stop()
        compiled.exit()

    def _enter(self, compiled: _Compiled, source: str | None) -> None:
        self._current = compiled
        now = self.clock()
        self.history.append((now, source, compiled.state.name))
        if self.on_transition is not None:
            self.on_transition(source, compiled.state.name, now)
        compiled.entry()
        sub = compiled.state.sub
        if sub is not None:
            sub.start()

    # ---- diagrams ----
    def to_mermaid(self) -> str:
        lines = ["stateDiagram-v2", f"    [*] --> {_mid(self.initial)}"]
        lines += self._diagram_lines(_mermaid_state, _mermaid_edge, "    ")
        lines.append(f"    {_mid(self.final)} --> [*]")
        return "\n".join(lines) + "\n"

    def _diagram_lines(self, state_fmt, edge_fmt, indent: str) -> list[str]:
        out = []
        for s in self.states:
            out.extend(indent + line for line in state_fmt(s))
        for t in self.transitions:
            out.append(indent + edge_fmt(t.source, t.target, _label(t)))
        return out

    def to_dot(self) -> str:
        lines = [f'digraph "{self.name}" {{', "    rankdir=LR;", '    node [shape=box, style=rounded];',
                 '    __start [shape=point];', f'    __start -> "{self.initial}";',
                 f'    "{self.final}" [peripheries=2];']
        for s in self.states:
            if s.sub is not None:
                subs = "\\n".join(x.name for x in s.sub.states)
                lines.append(f'    "{s.name}" [label="{s.name}\\n[{subs}]"];')
            else:
                lines.append(f'    "{s.name}";')
        for t in self.transitions:
            lines.append(f'    "{t.source}" -> "{t.target}" [label="{_label(t)}"];')
        lines.append("}")
        return "\n".join(lines) + "\n"


def _mid(name: str) -> str:
    return name.replace(" ", "_")


def _label(t: Transition) -> str:
    """A transition's label in diagrams: its own, else its event, else its guard's name."""
    if t.label:
        return t.label
    if t.event:
        return f"on {t.event}"
    return t.guard.__name__ if t.guard is not None else ""


def _mermaid_state(s: State) -> Iterable[str]:
    yield f"{_mid(s.name)} : {s.name}"
    if s.sub is not None:
        yield f"state {_mid(s.name)} {{"
        yield f"    [*] --> {_mid(s.sub.initial)}"
        for child in s.sub.states:
            yield f"    {_mid(child.name)} : {child.name}"
        for t in s.sub.transitions:
            label = _label(t)
            yield f"    {_mid(t.source)} --> {_mid(t.target)}" + (f" : {label}" if label else "")
        yield f"    {_mid(s.sub.final)} --> [*]"
        yield "}"


def _mermaid_edge(source: str, target: str, label: str) -> str:
    return f"{_mid(source)} --> {_mid(target)}" + (f" : {label}" if label else "")
