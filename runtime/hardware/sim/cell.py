"""The simulated cell around the robot: what its digital inputs do, from a scenario file.

A robot program talks to its cell (``wait for in[2]``, ``out[1] := true``). On the
simulated robot nothing else sets an input, so a scenario file (TOML) says how the cell
behaves; ``irl run --cell-scenario FILE`` runs a program against it:

.. code-block:: toml

    [inputs]            # initial values (every other input starts false)
    1 = true            # a part waits at the feeder

    [[latch]]           # the gripper's "closed" sensor: set 0.3 s after out[1] rises,
    input = 2           # reset 0.3 s after out[2] rises
    set = 1
    reset = 2
    delay = 0.3

    [[follow]]          # a sensor that copies an output after a delay
    input = 5
    output = 3
    delay = 0.1

    [[timeline]]        # parts arriving: in[6] toggles at these times (s since the
    input = 6           # program started: its first step), the list repeating every 10 s
    at = [2.0, 2.5]
    every = 10.0

    [[contact]]         # a touch sensor on the tool: in[7] is true while the tool centre
    input = 7           # point is at or below the stack's top, 120 mm up, which rises by
    z = 120.0           # 20 mm each time out[2] rises (a part put on the stack)
    step = 20.0
    output = 2

Each rule kind and its fields are declared once (:data:`RULES`); the loader, its error
messages and docs/runtime.md read the table. The cell is a driver of the simulated
robot's I/O, run by the io component's task (runtime/loop/components/io.py: every 1 ms tick,
first in the tick, as the world is, before the inputs are read into its port); on the
simulated clock it is deterministic: the same program, seed and scenario give the same
report bytes.
"""
from __future__ import annotations

import bisect
import difflib
import math
from dataclasses import dataclass
from pathlib import Path

__all__ = ["RULES", "Cell", "Rule", "Scenario", "ScenarioError", "load_scenario"]

#: The longest delay or time a scenario may give (s).
MAX_SECONDS = 86_400.0
#: The largest count a rule takes (a latch's misses).
MAX_COUNT = 1_000_000


class ScenarioError(ValueError):
    """A scenario file that cannot be used: says where, what, and what is allowed."""


@dataclass(frozen=True)
class Field:
    kind: str  # "input", "output", "seconds", "bool", "times", "count"
    doc: str
    default: object = None  # None: required

    def allowed(self, spec) -> str:
        return {"input": f"an input number 1..{spec.inputs}", "output": f"an output number 1..{spec.outputs}",
                "seconds": f"a number of seconds 0..{MAX_SECONDS:g}", "bool": "true or false",
                "times": f"a list of increasing times in seconds, 0..{MAX_SECONDS:g}",
                "count": f"a whole number 0..{MAX_COUNT}",
                "output or none": f"an output number 1..{spec.outputs}, or 0 (none)",
                "analog": (f"an analog input number 1..{len(spec.analog_inputs)}" if spec.analog_inputs else
                           "an analog input number (the specification declares none: [[analog_input]])"),
                "number": "a finite number", "numbers": "a list of finite numbers"}[self.kind]


#: The rule kinds: name -> (what it models, its fields).
RULES: dict[str, tuple[str, dict[str, Field]]] = {
    "follow": ("an input that copies an output after a delay (a sensor that follows a valve)", {
        "input": Field("input", "the input set"),
        "output": Field("output", "the output it copies"),
        "delay": Field("seconds", "how long after the output changes", 0.0),
        "invert": Field("bool", "copy the output's opposite", False),
    }),
    "latch": ("an input set when one output rises and reset when another rises, after a delay (a gripper's jaw "
              "sensor)", {
        "input": Field("input", "the input set"),
        "set": Field("output", "the output whose rising edge sets the input"),
        "reset": Field("output", "the output whose rising edge resets the input"),
        "delay": Field("seconds", "how long after the edge", 0.0),
        "initial": Field("bool", "the input's value before any edge", False),
        "misses": Field("count", "how many of the first rising edges of `set` do nothing (a grip that misses: "
                                 "for a program's error handler to retry)", 0),
    }),
    "analog": ("an analog input's reading, changed at given times since the program started (a sensor's "
               "values: the height of each part)", {
        "input": Field("analog", "the analog input (the specification's [[analog_input]] N)"),
        "value": Field("number", "what it reads at the start (within the input's range)"),
        "at": Field("times", "when its reading changes (s since the program started)", ()),
        "values": Field("numbers", "what it reads from each of those times on (one per time, within its range)", ()),
    }),
    "contact": ("an input true while the tool centre point is at or below a height (a touch sensor on the tool "
                "finding a stack's top: a search move's input), the height changing at each rising edge of an "
                "output (a part put on the stack, or taken off)", {
        "input": Field("input", "the input set"),
        "z": Field("number", "the height (mm, in the world frame) at and below which the input is true"),
        "step": Field("number", "how much the height changes at each rising edge of `output` (mm; negative: it "
                                "falls)", 0.0),
        "output": Field("output or none", "the output whose rising edge changes the height (0: none)", 0),
    }),
    "timeline": ("an input toggled at given times since the program started (parts arriving)", {
        "input": Field("input", "the input toggled"),
        "at": Field("times", "when it toggles (s since the program started: its first 5 ms step in Move "
                             "Robot, after any calibration and homing)"),
        "every": Field("seconds", "repeat the list with this period (0: once)", 0.0),
    }),
}


@dataclass(frozen=True)
class Rule:
    kind: str
    values: dict  # field -> checked value

    def __getitem__(self, name: str):
        return self.values[name]


@dataclass(frozen=True)
class Scenario:
    path: Path | None
    initial: dict[int, bool]  # input -> value at the program's start
    rules: tuple[Rule, ...]


def _check(value, field: Field, spec, where: str):
    def bad(what: str = "") -> ScenarioError:
        return ScenarioError(f"{where}: expected {field.allowed(spec)}, got {value!r}{what}")

    if field.kind in ("input", "output", "output or none"):
        count = spec.inputs if field.kind == "input" else spec.outputs
        low = 0 if field.kind == "output or none" else 1
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= count:
            raise bad()
        return value
    if field.kind == "bool":
        if not isinstance(value, bool):
            raise bad()
        return value
    if field.kind == "analog":
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= len(spec.analog_inputs):
            raise bad()
        return value
    if field.kind in ("number", "numbers"):
        items = value if field.kind == "numbers" else [value]
        if not isinstance(items, list) or not all(not isinstance(v, bool) and isinstance(v, (int, float))
                                                  and math.isfinite(v) for v in items):
            raise bad()
        return tuple(float(v) for v in items) if field.kind == "numbers" else float(value)
    if field.kind == "count":
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_COUNT:
            raise bad()
        return value
    if field.kind == "seconds":
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                or not 0.0 <= value <= MAX_SECONDS:
            raise bad()
        return float(value)
    times = value
    if not isinstance(times, list) or not times:
        raise bad()
    out = []
    for t in times:
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t) \
                or not 0.0 <= t <= MAX_SECONDS or (out and t <= out[-1]):
            raise bad(f" (at {t!r})")
        out.append(float(t))
    return tuple(out)


def _check_analog(rule: Rule, spec, where: str) -> None:
    """An analog rule's readings: one per time, each within the input's range."""
    if len(rule["values"]) != len(rule["at"]):
        raise ScenarioError(f"{where}: {len(rule['at'])} times in at and {len(rule['values'])} readings in values: "
                            "one reading per time")
    channel = spec.analog_inputs[rule["input"] - 1]
    for value in (rule["value"], *rule["values"]):
        problem = channel.problem(rule["input"], value)
        if problem is not None:
            raise ScenarioError(f"{where}: {problem}")


def _unknown(name: str, known, where: str) -> ScenarioError:
    close = difflib.get_close_matches(name, list(known), n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return ScenarioError(f"{where}: unknown {name!r}{hint}; known: {', '.join(known)}")


def parse_scenario(data: dict, spec, name: str = "scenario", path: Path | None = None) -> Scenario:
    """A checked scenario from a TOML document's tables (ScenarioError when it cannot be used)."""
    initial: dict[int, bool] = {}
    rules: list[Rule] = []
    driven: dict[int, str] = {}
    for key, value in data.items():
        if key == "inputs":
            if not isinstance(value, dict):
                raise ScenarioError(f"{name}: [inputs] must be a table of input = true/false")
            for number, state in value.items():
                where = f"{name}: [inputs] {number}"
                if not number.isdigit() or not 1 <= int(number) <= spec.inputs:
                    raise ScenarioError(f"{where}: expected an input number 1..{spec.inputs}")
                if not isinstance(state, bool):
                    raise ScenarioError(f"{where}: expected true or false, got {state!r}")
                initial[int(number)] = state
            continue
        if key not in RULES:
            raise _unknown(key, ["inputs", *RULES], name)
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise ScenarioError(f"{name}: {key} rules are written [[{key}]]")
        fields = RULES[key][1]
        for index, table in enumerate(value, 1):
            where = f"{name}: [[{key}]] #{index}"
            for field_name in table:
                if field_name not in fields:
                    raise _unknown(field_name, fields, where)
            checked = {}
            for field_name, field in fields.items():
                if field_name not in table:
                    if field.default is None:
                        raise ScenarioError(f"{where}: {field_name} is missing ({field.doc}: {field.allowed(spec)})")
                    checked[field_name] = field.default
                else:
                    checked[field_name] = _check(table[field_name], field, spec, f"{where} {field_name}")
            rule = Rule(key, checked)
            if key == "analog":
                _check_analog(rule, spec, where)
            driver = ("analog", rule["input"]) if key == "analog" else rule["input"]
            if driver in driven:
                raise ScenarioError(f"{where}: {'analog ' if key == 'analog' else ''}input {rule['input']} is "
                                    f"already driven by {driven[driver]}: one rule per input")
            driven[driver] = f"[[{key}]] #{index}"
            if key == "timeline" and rule["every"] and rule["every"] <= rule["at"][-1] - rule["at"][0]:
                raise ScenarioError(f"{where} every: the period must be longer than the list's span "
                                    f"({rule['at'][-1] - rule['at'][0]:g} s), got {rule['every']:g}")
            rules.append(rule)
    for rule in rules:
        if rule.kind in ("follow", "latch", "contact") and rule["input"] in initial:
            raise ScenarioError(f"{name}: [inputs] {rule['input']}: the input is driven by a [[{rule.kind}]] rule "
                                "(give a latch its 'initial'; a follower starts as its output)")
        if rule.kind == "latch":
            initial[rule["input"]] = rule["initial"]
    return Scenario(path, initial, tuple(rules))


def markdown() -> str:
    """The rule kinds and their fields, for docs/runtime.md (``python -m runtime.cli.docgen``)."""
    kinds = {"input": "input number", "output": "output number", "output or none": "output number or 0", "seconds": "s", "bool": "true/false",
             "times": "list of s", "count": "whole number", "analog": "analog input number", "number": "number",
             "numbers": "list of numbers"}
    lines = ["| rule | field | type | default | meaning |", "|---|---|---|---|---|"]
    for name, (doc, fields) in RULES.items():
        first = True
        for field_name, field in fields.items():
            default = "required" if field.default is None else str(field.default).lower()
            lines.append(f"| {f'`[[{name}]]`: {doc}' if first else ''} | `{field_name}` | {kinds[field.kind]} | "
                         f"{default} | {field.doc} |")
            first = False
    return "\n".join(lines) + "\n"


def load_scenario(path: str | Path, spec) -> Scenario:
    from runtime.config import read_toml

    return parse_scenario(read_toml(path, ScenarioError), spec, str(path), Path(path))


class Cell:
    """The scenario at work on the simulated robot's I/O (``backend``: set_input, outputs).
    ``tcp``: where the tool centre point is in the world (x, y, z, mm; real-time), for the
    ``contact`` rules (ScenarioError when they have none: an arm without kinematics)."""

    def __init__(self, scenario: Scenario, backend, tcp=None):
        self.scenario = scenario
        self.backend = backend
        self.tcp = tcp
        self._contacts = [rule for rule in scenario.rules if rule.kind == "contact"]
        if self._contacts and tcp is None:
            raise ScenarioError(f"{scenario.path or 'scenario'}: a [[contact]] rule needs the tool centre point, "
                                "and this robot's specification gives no usable kinematics")
        self._heights: list[float] = []  # per contact rule: the height now
        self._t0 = math.inf  # when the program started (its first step): the timelines count from it
        self._last: tuple = ()
        self._events: list[tuple[float, int, int, bool]] = []  # (time, order, input, value), sorted
        self._order = 0
        self._timeline: list[list] = []  # per timeline rule: [rule, next index, cycle]
        self._missed: dict[int, int] = {}  # per latch with misses (by id): the set edges it has missed
        self._analog: list[list] = []  # per analog rule: [rule, its next reading's index]

    def reset(self, now: float) -> None:
        """Not real-time: a cycle begins (power-up): the initial inputs, no pending change;
        the timelines wait for the program's start (:meth:`start_program`)."""
        self._t0 = math.inf
        outputs = self.backend.outputs
        for n in range(1, len(self.backend.inputs) + 1):
            self.backend.set_input(n, self.scenario.initial.get(n, False))
        for rule in self.scenario.rules:  # a follower starts where its output is
            if rule.kind == "follow":
                self.backend.set_input(rule["input"], outputs[rule["output"] - 1] != rule["invert"])
        self._last = outputs
        self._events = []
        self._missed = {}
        self._analog = [[rule, 0] for rule in self.scenario.rules if rule.kind == "analog"]
        for rule in self.scenario.rules:
            if rule.kind == "analog":
                self.backend.set_analog_input(rule["input"], rule["value"])
        self._timeline = [[rule, 0, 0] for rule in self.scenario.rules if rule.kind == "timeline"]
        self._heights = [rule["z"] for rule in self._contacts]

    def start_program(self, now: float) -> None:
        """Real-time: the program starts (its first step in Move Robot, the trajectory
        generator's first 5 ms update at tick ``now``, after calibration and homing, which
        take a varying time): the timelines' times count from here. From the program's own
        first step, not from the tick Move Robot was entered: a time is the same instant of
        the program's 5 ms steps after any homing, and in irl check's offline run."""
        self._t0 = now

    def _schedule(self, at: float, n: int, value: bool) -> None:
        self._order += 1
        bisect.insort(self._events, (at, self._order, n, value))

    def update(self, now: float) -> None:
        """Real-time (every tick, before anything reads an input)."""
        outputs = self.backend.outputs
        last = self._last
        if outputs != last:
            for rule in self.scenario.rules:
                kind = rule.kind
                if kind == "follow":
                    k = rule["output"] - 1
                    if outputs[k] != last[k]:
                        self._schedule(now + rule["delay"], rule["input"], outputs[k] != rule["invert"])
                elif kind == "latch":
                    for field, value in (("set", True), ("reset", False)):
                        k = rule[field] - 1
                        if outputs[k] and not last[k]:
                            if value and self._missed.get(id(rule), 0) < rule["misses"]:
                                self._missed[id(rule)] = self._missed.get(id(rule), 0) + 1
                                continue
                            self._schedule(now + rule["delay"], rule["input"], value)
            for i, rule in enumerate(self._contacts):  # (a part put on the stack: its top rises)
                k = rule["output"] - 1
                if k >= 0 and outputs[k] and not last[k]:
                    self._heights[i] += rule["step"]
            self._last = outputs
        if self._contacts:
            z = self.tcp()[2]
            for rule, height in zip(self._contacts, self._heights):
                touching = z <= height
                if self.backend.input(rule["input"]) != touching:
                    self.backend.set_input(rule["input"], touching)
        for entry in self._timeline:
            rule, index, cycle = entry
            at = rule["at"]
            due = self._t0 + cycle * rule["every"] + at[index]
            if now + 1e-9 >= due and (cycle == 0 or rule["every"]):
                n = rule["input"]
                self.backend.set_input(n, not self.backend.input(n))
                index += 1
                if index == len(at):
                    index = 0
                    cycle += 1
                    if not rule["every"]:
                        cycle = -1  # (once: never again)
                entry[1], entry[2] = index, cycle
        for entry in self._analog:
            rule, index = entry
            at = rule["at"]
            while index < len(at) and now + 1e-9 >= self._t0 + at[index]:
                self.backend.set_analog_input(rule["input"], rule["values"][index])
                index += 1
            entry[1] = index
        events = self._events
        while events and events[0][0] <= now + 1e-9:
            _at, _order, n, value = events.pop(0)
            self.backend.set_input(n, value)
