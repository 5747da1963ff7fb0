"""Component configurations: the runtime's static and dynamic configuration.

As in the OROCOS-based robot controller, every component's settings come from a
configuration file, and one file may define several *named* configurations. The server
loads the file once, validates every configuration in it, starts with the default one and
may switch to another at run time *between programs*; a switch to an invalid configuration
is refused with the reason and the old configuration stays in force.

File format (TOML)::

    default = "standard"            # optional; else the first configuration in the file

    [configurations.standard.servo]
    kp = 40.0
    ki = 2.0
    following_error_limit = 2.0

    [configurations.standard.report]
    period = 0.01
    columns = ["sens_pos", "desi_pos", "out_vel", "following_error"]

    [configurations.gentle]
    based_on = "standard"           # optional: start from another configuration's settings
    [configurations.gentle.servo]
    kp = 25.0

* The top level holds only ``default`` (a configuration name) and ``configurations`` (a
  table of named configurations); a file that defines none is an error.
* A configuration is a table of components (``servo``, ``robot``, ``trajectory``,
  ``initialization``, ``report``), each a table of settings, plus an optional ``based_on``
  naming another configuration of the file. ``based_on`` chains are resolved key by key
  (a configuration's own settings override the ones it is based on); cycles and unknown
  names are errors.
* The settable keys, their types and checks are the table :data:`SCHEMA` (rendered for the
  documentation by :func:`schema_markdown`). Periods are seconds, a whole multiple of the
  1 ms tick, from 0.001 to 1.0. ``trajectory.period`` must equal ``initialization.period``
  when both are given (after ``based_on`` is resolved): the servo interpolates both
  setpoint streams with one setpoint period.
* Numbers accept TOML integers and floats (not booleans; finite) and are normalized to
  ``float``; integers accept TOML integers only.

Every problem is a :class:`ConfigError` whose message names the file, the configuration
and the key, and says what was expected and what was found, e.g.
``lola15.toml: configuration 'gentle': servo.kp: expected a number > 0, got -1``.
Nothing else escapes :func:`load_configurations`, :func:`parse_configurations` or
:func:`validate_settings`, whatever the input.
"""
from __future__ import annotations

import difflib
import math
import tomllib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

__all__ = [
    "COLUMNS",
    "SCHEMA",
    "TICK",
    "ConfigError",
    "Configuration",
    "Configurations",
    "Setting",
    "load_configurations",
    "parse_configurations",
    "schema_markdown",
    "validate_settings",
]

TICK = 0.001            # s, the executive's base tick; every period is a whole multiple of it
TICK_TOLERANCE = 1e-9   # s, how far a period may be from a whole multiple of the tick
PERIOD_MIN = 0.001      # s
PERIOD_MAX = 1.0        # s
COLUMNS = ("sens_pos", "desi_pos", "out_vel", "following_error", "tcp")  # what the report component can log
TOP_LEVEL_KEYS = ("default", "configurations")
BASED_ON = "based_on"


class ConfigError(ValueError):
    """A configuration file or a configuration is unreadable or invalid; the message says why."""


class _Invalid(Exception):
    """Raised by a check: the value is invalid. ``reason`` replaces the generic "expected ..., got ..."."""

    def __init__(self, reason: str | None = None):
        super().__init__(reason)
        self.reason = reason


# ---- describing values in messages -----------------------------------------------------------

def _describe(value: object, limit: int = 60) -> str:
    """``value`` as the message shows it: TOML-like spelling, shortened."""
    try:
        text = _spell(value)
    except Exception:  # noqa: BLE001 - a message must never fail (huge ints, odd objects)
        text = f"a {type(value).__name__}"
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _spell(value: object) -> str:
    if isinstance(value, bool):
        return "true (a boolean)" if value else "false (a boolean)"
    if isinstance(value, int):
        return repr(value) if abs(value) < 10 ** 30 else "a very large integer"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, (list, tuple)):
        if not value:
            return "[]"
        return "[" + ", ".join(_describe(v, 20) for v in value[:5]) + (", ...]" if len(value) > 5 else "]")
    return f"{value} (a {type(value).__name__})"


def _suggest(word: object, known: list[str] | tuple[str, ...]) -> str:
    """' (did you mean 'x'?)' or ''."""
    if not isinstance(word, str):
        return ""
    matches = difflib.get_close_matches(word, list(known), n=1)
    return f" (did you mean {matches[0]!r}?)" if matches else ""


def _known(names) -> str:
    return ", ".join(names) if names else "(none)"


# ---- checks ------------------------------------------------------------------------------------

def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _finite_float(value: object) -> float:
    """``value`` as a finite float, or _Invalid."""
    if not _is_number(value):
        raise _Invalid()
    try:
        result = float(value)
    except OverflowError:
        raise _Invalid(f"expected a finite number, got {_describe(value)}") from None
    if not math.isfinite(result):
        raise _Invalid(f"expected a finite number, got {_describe(value)}")
    return result


def _number(accept: Callable[[float], bool]) -> Callable[[object], object]:
    def check(value: object) -> float:
        result = _finite_float(value)
        if not accept(result):
            raise _Invalid()
        return result
    return check


def _integer(low: int, high: int) -> Callable[[object], object]:
    def check(value: object) -> int:
        if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
            raise _Invalid()
        return int(value)
    return check


def _period(value: object) -> float:
    seconds = _finite_float(value)
    if not PERIOD_MIN - TICK_TOLERANCE <= seconds <= PERIOD_MAX + TICK_TOLERANCE:
        raise _Invalid(f"expected a period between {PERIOD_MIN} and {PERIOD_MAX} s, got {_describe(value)}")
    ticks = round(seconds / TICK)
    if abs(seconds - ticks * TICK) > TICK_TOLERANCE:
        below, above = math.floor(seconds / TICK), math.ceil(seconds / TICK)
        raise _Invalid(f"expected a whole multiple of the {TICK * 1000:g} ms tick, got {_describe(value)} "
                       f"(nearest: {below * TICK:g} or {above * TICK:g})")
    return ticks / round(1 / TICK)  # the float nearest to the whole number of ticks


def _columns(value: object) -> list[str]:
    if not isinstance(value, (list, tuple)) or not value:
        raise _Invalid()
    seen: list[str] = []
    for index, column in enumerate(value):
        if not isinstance(column, str):
            raise _Invalid(f"expected column names (strings), got {_describe(column)} at index {index}")
        if column not in COLUMNS:
            raise _Invalid(f"unknown column {column!r}{_suggest(column, COLUMNS)}; known: {_known(COLUMNS)}")
        if column in seen:
            raise _Invalid(f"duplicate column {column!r}")
        seen.append(column)
    return seen


# ---- the schema --------------------------------------------------------------------------------

@dataclass(frozen=True)
class Setting:
    """One settable key of a component.

    ``type`` is the kind of TOML value; ``expected`` describes a valid value (messages say
    "expected <expected>, got ..."); ``check`` returns the normalized value or raises
    ``_Invalid``; ``unit`` and ``description`` document the key.
    """

    type: str
    expected: str
    check: Callable[[object], object]
    unit: str
    description: str


_PERIOD_TEXT = f"a number of seconds, a whole multiple of the 1 ms tick, {PERIOD_MIN} to {PERIOD_MAX}"


def _period_setting(description: str) -> Setting:
    return Setting("number", _PERIOD_TEXT, _period, "s", description)


SCHEMA: dict[str, dict[str, Setting]] = {
    "servo": {
        "kp": Setting("number", "a number > 0", _number(lambda x: x > 0), "1/s", "position loop gain"),
        "ki": Setting("number", "a number >= 0", _number(lambda x: x >= 0), "1/s^2", "integral gain"),
        "following_error_limit": Setting(
            "number", "a number > 0", _number(lambda x: x > 0), "deg",
            "largest allowed difference between reference and measured position; beyond it the servo faults"),
    },
    "robot": {
        "velocity_limit_scale": Setting(
            "number", "a number > 0 and <= 1", _number(lambda x: 0 < x <= 1), "",
            "fraction of each axis' max_velocity the drives accept"),
    },
    "trajectory": {
        "budget": Setting("integer", "an integer from 1 to 100000", _integer(1, 100_000), "instructions per update",
                          "largest number of object-code instructions the interpreter executes in one update"),
        "period": _period_setting("time between trajectory updates (setpoints); must equal initialization.period "
                                  "when both are given"),
    },
    "initialization": {
        "period": _period_setting("time between updates of the move to the start position; must equal "
                                  "trajectory.period when both are given"),
    },
    "report": {
        "period": _period_setting("time between two logged rows"),
        "columns": Setting("list of strings", "a non-empty list of unique column names from " + ", ".join(COLUMNS),
                           _columns, "", "signals logged in each row, in this order"),
    },
}


def schema_markdown() -> str:
    """The schema as a Markdown table (component, key, type/check with unit, description) for the documentation."""
    def cell(text: str) -> str:
        return text.replace("|", "\\|")

    lines = ["| Component | Key | Type / check | Description |", "|---|---|---|---|"]
    for component, keys in SCHEMA.items():
        for key, setting in keys.items():
            unit = f" (unit: {setting.unit})" if setting.unit else ""
            lines.append(f"| `{cell(component)}` | `{cell(key)}` | {cell(setting.expected + unit)} "
                         f"| {cell(setting.description)} |")
    return "\n".join(lines) + "\n"


# ---- validation --------------------------------------------------------------------------------

def _check_values(settings: object, where: str) -> dict[str, dict[str, object]]:
    """Type and range checks of one component -> key -> value mapping; returns it normalized."""
    if not isinstance(settings, dict):
        raise ConfigError(f"{where}: expected a table of components, got {_describe(settings)}")
    result: dict[str, dict[str, object]] = {}
    components = list(SCHEMA)
    for component, values in settings.items():
        if not isinstance(component, str) or component not in SCHEMA:
            raise ConfigError(f"{where}: unknown component {_describe(component)}{_suggest(component, components)}; "
                              f"known: {_known(components)}")
        if not isinstance(values, dict):
            raise ConfigError(f"{where}: {component}: expected a table of settings, got {_describe(values)}")
        schema = SCHEMA[component]
        keys = list(schema)
        normalized: dict[str, object] = {}
        for key, value in values.items():
            if not isinstance(key, str) or key not in schema:
                raise ConfigError(f"{where}: {component}.{key if isinstance(key, str) else _describe(key)}: unknown key"
                                  f"{_suggest(key, keys)}; known keys of {component}: {_known(keys)}")
            setting = schema[key]
            try:
                normalized[key] = setting.check(value)
            except _Invalid as invalid:
                reason = invalid.reason or f"expected {setting.expected}, got {_describe(value)}"
                raise ConfigError(f"{where}: {component}.{key}: {reason}") from None
        result[component] = normalized
    return result


def _check_rules(settings: dict[str, dict[str, object]], where: str) -> None:
    """Rules across keys, on fully resolved settings."""
    trajectory = settings.get("trajectory", {}).get("period")
    initialization = settings.get("initialization", {}).get("period")
    if trajectory is not None and initialization is not None and abs(trajectory - initialization) > TICK_TOLERANCE:
        raise ConfigError(f"{where}: trajectory.period: expected the same period as initialization.period "
                          f"({initialization:g} s; the servo interpolates both setpoint streams with one period), "
                          f"got {trajectory:g}")


def validate_settings(settings: dict, where: str) -> dict:
    """Validate one configuration's component -> key -> value mapping; return it normalized.

    Used for a single configuration that arrives over the network. ``where`` starts every
    message (e.g. ``"client: configuration 'fast'"``). Numbers become ``float``; periods
    are rounded to the exact whole millisecond. Raises :class:`ConfigError`.
    """
    result = _check_values(settings, where)
    _check_rules(result, where)
    return result


# ---- configurations ----------------------------------------------------------------------------

@dataclass(frozen=True)
class Configuration:
    """One named configuration, ``based_on`` resolved: component -> key -> value.

    Only keys that the configuration or one it is based on gives are present.
    """

    name: str
    settings: dict[str, dict[str, object]]

    def get(self, component: str, key: str, default: object = None) -> object:
        """The value of ``component.key``, or ``default`` when no configuration in the chain gives it."""
        return self.settings.get(component, {}).get(key, default)


@dataclass(frozen=True)
class Configurations:
    """The named configurations of one file. ``source`` is how messages name the file."""

    path: Path | None
    default: str
    by_name: dict[str, Configuration]
    source: str = field(default="<config>", compare=False)

    def names(self) -> list[str]:
        """The configuration names, in file order."""
        return list(self.by_name)

    def __getitem__(self, name: str) -> Configuration:
        try:
            return self.by_name[name]
        except (KeyError, TypeError):
            names = self.names()
            raise ConfigError(f"no configuration {_describe(name)} in {self.source}{_suggest(name, names)}; "
                              f"known: {_known(names)}") from None

    def __contains__(self, name: object) -> bool:
        try:
            return name in self.by_name
        except TypeError:
            return False

    def __iter__(self) -> Iterator[str]:
        return iter(self.by_name)

    def __len__(self) -> int:
        return len(self.by_name)

    @property
    def default_configuration(self) -> Configuration:
        return self.by_name[self.default]


def load_configurations(path: str | Path) -> Configurations:
    """Read and validate a configuration file. Raises :class:`ConfigError` (unreadable, not TOML, invalid)."""
    try:
        path = Path(path)
        data = path.read_bytes()
    except (OSError, ValueError) as error:
        reason = error.strerror if isinstance(error, OSError) and error.strerror else str(error)
        raise ConfigError(f"{path}: cannot read the configuration file: {reason}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ConfigError(f"{path}: not UTF-8 text (byte {error.start}): {error.reason}") from None
    return _parse(text, str(path), path)


def parse_configurations(text: str, name: str = "<config>") -> Configurations:
    """Parse and validate configurations from TOML text; ``name`` names the source in messages."""
    return _parse(text, name, None)


def _parse(text: str, source: str, path: Path | None) -> Configurations:
    if not isinstance(text, str):
        raise ConfigError(f"{source}: expected TOML text, got {_describe(text)}")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ConfigError(f"{source}: invalid TOML: {error}") from None
    except RecursionError:
        raise ConfigError(f"{source}: invalid TOML: nested too deeply") from None
    except ValueError as error:  # e.g. an integer literal with more digits than Python converts
        raise ConfigError(f"{source}: invalid TOML: {error}") from None
    return _build(data, source, path)


def _build(data: dict, source: str, path: Path | None) -> Configurations:
    for key in data:
        if key not in TOP_LEVEL_KEYS:
            raise ConfigError(f"{source}: unknown top-level key {key!r}{_suggest(key, TOP_LEVEL_KEYS)}; "
                              f"known: {_known(TOP_LEVEL_KEYS)}")
    tables = data.get("configurations")
    if tables is None or tables == {}:
        raise ConfigError(f"{source}: defines no configurations (expected [configurations.NAME.COMPONENT] tables)")
    if not isinstance(tables, dict):
        raise ConfigError(f"{source}: configurations: expected a table of named configurations, "
                          f"got {_describe(tables)}")
    names = list(tables)

    own: dict[str, dict[str, dict[str, object]]] = {}
    bases: dict[str, str] = {}
    for name, table in tables.items():
        where = f"{source}: configuration {name!r}"
        if not isinstance(table, dict):
            raise ConfigError(f"{where}: expected a table of components, got {_describe(table)}")
        settings = dict(table)
        if BASED_ON in settings:
            base = settings.pop(BASED_ON)
            if not isinstance(base, str):
                raise ConfigError(f"{where}: {BASED_ON}: expected the name of another configuration, "
                                  f"got {_describe(base)}")
            if base not in tables:
                raise ConfigError(f"{where}: {BASED_ON}: no configuration {base!r}{_suggest(base, names)}; "
                                  f"known: {_known(names)}")
            bases[name] = base
        own[name] = _check_values(settings, where)

    resolved: dict[str, dict[str, dict[str, object]]] = {}
    for name in names:
        chain = [name]  # name, its base, the base's base, ... up to a resolved one or the root
        while chain[-1] in bases and chain[-1] not in resolved:
            base = bases[chain[-1]]
            if base in chain:
                cycle = chain[chain.index(base):] + [base]
                raise ConfigError(f"{source}: configuration {chain[-1]!r}: {BASED_ON} cycle: {' -> '.join(cycle)}")
            chain.append(base)
        for member in reversed(chain):
            if member in resolved:
                continue
            base = bases.get(member)
            resolved[member] = _merge(resolved[base] if base is not None else {}, own[member])

    by_name: dict[str, Configuration] = {}
    for name in names:
        _check_rules(resolved[name], f"{source}: configuration {name!r}")
        by_name[name] = Configuration(name, resolved[name])

    default = data.get("default", names[0])
    if not isinstance(default, str):
        raise ConfigError(f"{source}: default: expected the name of a configuration, got {_describe(default)}")
    if default not in by_name:
        raise ConfigError(f"{source}: default: no configuration {default!r}{_suggest(default, names)}; "
                          f"known: {_known(names)}")
    return Configurations(path, default, by_name, source)


def _merge(base: dict[str, dict[str, object]], own: dict[str, dict[str, object]]) -> dict[str, dict[str, object]]:
    """``own`` over a copy of ``base``, key by key."""
    result = {component: {key: _copy(value) for key, value in values.items()} for component, values in base.items()}
    for component, values in own.items():
        target = result.setdefault(component, {})
        for key, value in values.items():
            target[key] = _copy(value)
    return result


def _copy(value: object) -> object:
    return list(value) if isinstance(value, list) else value
