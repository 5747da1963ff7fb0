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
* The settable keys, their types and checks are the table :data:`SCHEMA`, a view of the
  components' parameters in :mod:`compiler.params` (the one declaration of every
  parameter's type, unit, range and safety relevance), rendered for the documentation
  by :func:`schema_markdown`. Periods are seconds, a whole multiple of the
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
import tomllib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from compiler.params import COMPONENTS as CONFIG_COMPONENTS
from compiler.params import REPORT_COLUMNS, TICK, Param, ParamError, component_params, markdown

__all__ = [
    "COLUMNS",
    "SCHEMA",
    "TICK",
    "ConfigError",
    "Configuration",
    "Configurations",
    "Setting",
    "load_configurations",
    "merge_settings",
    "parse_configurations",
    "schema_markdown",
    "validate_settings",
]

TICK_TOLERANCE = 1e-9   # s, how far a period may be from a whole multiple of the tick
COLUMNS = REPORT_COLUMNS  # what the report component can log
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


# ---- the schema: compiler.params, the one declaration of every parameter ------------------------

@dataclass(frozen=True)
class Setting:
    """One settable key of a component (a view of its :class:`compiler.params.Param`).

    ``type`` is the kind of TOML value; ``expected`` describes a valid value (messages say
    "expected <expected>, got ..."); ``check`` returns the normalized value or raises
    ``_Invalid``; ``unit`` and ``description`` document the key; ``safety``: whether it is
    safety-relevant.
    """

    type: str
    expected: str
    check: Callable[[object], object]
    unit: str
    description: str
    safety: bool = False


_TYPES = {"number": "number", "integer": "integer", "period": "number", "columns": "list of strings",
          "choice": "string"}


def _setting(param: Param) -> Setting:
    def check(value: object) -> object:
        try:
            return param.check(value)
        except ParamError as error:
            raise _Invalid(error.reason if error.specific else None) from None
    return Setting(_TYPES[param.kind], param.allowed(), check, param.unit, param.doc, param.safety)


SCHEMA: dict[str, dict[str, Setting]] = {
    component: {name: _setting(param) for name, param in component_params(component).items()}
    for component in CONFIG_COMPONENTS
}


def schema_markdown() -> str:
    """The components' parameters as a Markdown table for the documentation
    (:func:`compiler.params.markdown`)."""
    return markdown(CONFIG_COMPONENTS)


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


def merge_settings(base: dict, settings: dict) -> dict:
    """``base`` (component -> key -> value) with ``settings`` laid over it."""
    merged = {component: dict(values) for component, values in base.items()}
    for component, values in settings.items():
        merged.setdefault(component, {}).update(values)
    return merged


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
    return _build(toml_tables(text, source, ConfigError), source, path)


def toml_tables(text: str, source: str, error: type[Exception]) -> dict:
    """The tables of TOML ``text``, or ``error`` saying where and why it is not TOML
    (also for what makes tomllib raise other than TOMLDecodeError on untrusted text)."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{source}: invalid TOML: {exc}") from None
    except RecursionError:
        raise error(f"{source}: invalid TOML: nested too deeply") from None
    except ValueError as exc:  # e.g. an integer literal with more digits than Python converts
        raise error(f"{source}: invalid TOML: {exc}") from None


def read_toml(path: str | Path, error: type[Exception]) -> dict:
    """A TOML file's tables (a cell scenario, a fieldbus file), or ``error`` saying why not:
    unreadable, not UTF-8 text, not TOML."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise error(f"cannot read {path}: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not UTF-8 text (byte {exc.start}): {exc.reason}") from None
    return toml_tables(text, str(path), error)


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
