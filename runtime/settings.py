"""The robot's settings, one object: every component parameter of :mod:`compiler.params`
(``servo``, ``robot``, ``trajectory``, ``initialization``, ``report``) with its value now.

One :class:`Settings` per robot (the system builds it from the specification): each
component gets it when it is built and reads its own section there (``settings.servo.kp``),
as ros2_control's ``on_configure`` hands a controller its parameters; a value two
components need (``robot.velocity_limit_scale``: the servo's saturation, the safety's
limits, homing's speeds, the planners' rate; ``servo.following_error_limit``: the servo's
fault and the safety's check) lives here once and both read it here. Nothing copies a
parameter from one component into another.

A change goes through :meth:`Settings.set` (a configuration applied in Robot
Reconfiguration, ``irl reconfigure``, a scripting write of a ``live`` parameter): the value
is checked against its declaration, stored, and whoever keeps something derived from it
(the servo's per-axis velocity limits, the safety's, the executive's schedule) is told at
once (:meth:`Settings.watch`). Not real-time: the loop only reads the sections' attributes.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable

from compiler.params import COMPONENTS, Param, component_params

__all__ = ["COMPONENTS", "Settings", "section_class"]


def _copy(value: object) -> object:
    return list(value) if isinstance(value, list) else value


def section_class(section: str) -> type:
    """A mutable, slotted class with one attribute per parameter of the component
    ``section`` (compiler.params); ``settings.servo`` is one."""
    params = component_params(section)
    cls = dataclasses.make_dataclass(f"{section.title()}Section", list(params), slots=True)
    cls.__module__ = __name__
    cls.__doc__ = (f"The settings of {section} (compiler.params); one attribute per parameter:\n\n"
                   + "\n".join(f"* ``{name}`` ({p.unit or p.kind}) -- {p.doc}" for name, p in params.items()))
    return cls


_SECTIONS: dict[str, type] = {section: section_class(section) for section in COMPONENTS}


def start_value(param: Param, spec) -> object:
    """A parameter's value before any configuration: the specification's where the
    parameter takes it from there (``servo.kp`` from ``[controller] kp``), else its default."""
    if param.spec_key is not None and spec is not None:
        table, key = param.spec_key.split(".", 1)
        return _copy(getattr(getattr(spec, table), key))
    return _copy(param.default)


class Settings:
    """Every component's settings; ``settings.servo``, ``settings.robot``, ... are the
    sections (one attribute per parameter). Read them anywhere; change them only through
    :meth:`set` or :meth:`apply`."""

    def __init__(self, spec=None):
        for section, cls in _SECTIONS.items():
            values = {name: start_value(param, spec) for name, param in component_params(section).items()}
            setattr(self, section, cls(**values))
        self._watchers: dict[tuple[str, str], list[Callable[[object], None]]] = {}

    servo: object
    robot: object
    trajectory: object
    initialization: object
    report: object

    @staticmethod
    def params(section: str) -> dict[str, Param]:
        """The declarations of a section's parameters (compiler.params), by name."""
        if section not in _SECTIONS:
            raise KeyError(section)
        return component_params(section)

    def section(self, section: str):
        if section not in _SECTIONS:
            raise KeyError(section)
        return getattr(self, section)

    def get(self, section: str, name: str) -> object:
        if name not in self.params(section):
            raise KeyError(f"{section} has no setting {name!r}")
        return getattr(self.section(section), name)

    def set(self, section: str, name: str, value: object) -> object:
        """Check ``value`` against the parameter's declaration (a ParamError otherwise;
        nothing changes), store it and tell the watchers of ``section.name``; returns the
        value as stored."""
        params = self.params(section)
        if name not in params:
            raise KeyError(f"{section} has no setting {name!r}")
        value = params[name].check(value)
        setattr(self.section(section), name, value)
        for callback in self._watchers.get((section, name), ()):
            callback(value)
        return value

    def apply(self, settings: dict) -> None:
        """Set every value of a component -> name -> value mapping (a configuration)."""
        for section, values in settings.items():
            for name, value in values.items():
                self.set(section, name, value)

    def values(self) -> dict:
        """Every setting: component -> name -> value (lists copied)."""
        return {section: {name: _copy(getattr(getattr(self, section), name)) for name in component_params(section)}
                for section in _SECTIONS}

    def watch(self, section: str, name: str, callback: Callable[[object], None]) -> None:
        """Not real-time: call ``callback(value)`` after every change of ``section.name``
        (who keeps something derived from it)."""
        if name not in self.params(section):
            raise KeyError(f"{section} has no setting {name!r}")
        self._watchers.setdefault((section, name), []).append(callback)
