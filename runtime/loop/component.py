"""Components: one lifecycle vocabulary, properties, operations and data ports.

As in OROCOS (the paper's framework): a component is configured, started, updated
periodically by the executive, stopped and cleaned up; a failure puts it in ERROR.
Components exchange data through latest-value data ports (``sens_pos``, ``desi_pos``,
``init_pos``, ``out_vel``...): one writer, any number of readers, sharing one port object.
Properties (settings) and operations (whitelisted methods) are declared per class so the
scripting interface can list and reach them without ``eval``.
"""
from __future__ import annotations

import enum


class Lifecycle(enum.Enum):
    UNCONFIGURED = "unconfigured"
    STOPPED = "stopped"
    RUNNING = "running"
    ERROR = "error"


class DataPort:
    """A latest-value data port: the last value written, and when (real-time safe)."""

    __slots__ = ("name", "value", "stamp", "writes")

    def __init__(self, name: str, initial=None):
        self.name = name
        self.value = initial
        self.stamp = -1.0
        self.writes = 0

    def write(self, value, stamp: float = 0.0) -> None:
        """Real-time: store the value (no copy: writers pass immutable tuples)."""
        self.value = value
        self.stamp = stamp
        self.writes += 1

    def read(self):
        """Real-time: the last value written (or the initial value)."""
        return self.value


class Component:
    """Base class. Subclasses override the ``on_*`` hooks and ``update``.

    ``PROPERTIES`` maps a property name to its declaration (:class:`compiler.params.Param`:
    type, unit, range, safety relevance, when it may change); the value is the setting of
    the same name in the component's section of the robot's settings
    (:class:`runtime.settings.Settings`, ``settings``: one object for all components).
    ``OPERATIONS`` names the methods the scripting interface may call.
    """

    PROPERTIES: dict = {}  # name -> compiler.params.Param
    OPERATIONS: tuple[str, ...] = ("configure", "start", "stop", "cleanup")

    def __init__(self, name: str, period: float, settings=None):
        self.name = name
        self.period = period  # seconds between updates
        self.settings = settings  # the robot's settings (runtime.settings.Settings): its section is self.name
        self.lifecycle = Lifecycle.UNCONFIGURED
        self.error_message: str | None = None
        self._watchers: list = []  # called after every change of lifecycle (see watch)

    def watch(self, callback) -> None:
        """Not real-time: call ``callback()`` after every change of the lifecycle state
        (the executive keeps its list of runnable tasks up to date this way)."""
        self._watchers.append(callback)

    def _set_lifecycle(self, state: Lifecycle) -> None:
        if state is not self.lifecycle:
            self.lifecycle = state
            for callback in self._watchers:
                callback()

    @property
    def running(self) -> bool:
        return self.lifecycle is Lifecycle.RUNNING

    # -- lifecycle (not real-time: called on transitions, never per tick) --
    def configure(self) -> bool:
        """UNCONFIGURED/STOPPED -> STOPPED, if ``on_configure`` accepts the settings."""
        if self.lifecycle is Lifecycle.RUNNING:
            return False
        if not self.on_configure():
            return False
        self._set_lifecycle(Lifecycle.STOPPED)
        self.error_message = None
        return True

    def start(self) -> bool:
        """STOPPED -> RUNNING (configures first if needed)."""
        if self.lifecycle is Lifecycle.RUNNING:
            return True
        if self.lifecycle is not Lifecycle.STOPPED and not self.configure():
            return False
        if not self.on_start():
            return False
        self._set_lifecycle(Lifecycle.RUNNING)
        return True

    def stop(self) -> bool:
        """RUNNING -> STOPPED."""
        if self.lifecycle is not Lifecycle.RUNNING:
            return False
        self.on_stop()
        self._set_lifecycle(Lifecycle.STOPPED)
        return True

    def cleanup(self) -> bool:
        """STOPPED/ERROR -> UNCONFIGURED."""
        if self.lifecycle is Lifecycle.RUNNING:
            return False
        self.on_cleanup()
        self._set_lifecycle(Lifecycle.UNCONFIGURED)
        return True

    def recover(self) -> None:
        """Not real-time: forget a failure (ERROR -> STOPPED), e.g. before a new cycle."""
        if self.lifecycle is Lifecycle.ERROR:
            self._set_lifecycle(Lifecycle.STOPPED)
        self.error_message = None

    def error(self, message: str) -> None:
        """Real-time safe: stop updating and remember why (the supervisor reads it)."""
        self._set_lifecycle(Lifecycle.ERROR)
        self.error_message = message

    # -- hooks --
    def on_configure(self) -> bool:
        return True

    def on_start(self) -> bool:
        return True

    def on_stop(self) -> None:
        pass

    def on_cleanup(self) -> None:
        pass

    def update(self, now: float) -> None:
        """Real-time: one period's work. No blocking, no I/O, no waiting loops."""

    # -- properties (not real-time) --
    def get_property(self, name: str):
        if name not in self.PROPERTIES:
            raise KeyError(f"{self.name} has no property {name!r}")
        return self.settings.get(self.name, name)

    def set_property(self, name: str, value) -> None:
        """Not real-time: set a property to a value its declaration accepts (a
        ``compiler.params.ParamError``, a ValueError, otherwise; nothing changes)."""
        if name not in self.PROPERTIES:
            raise KeyError(f"{self.name} has no property {name!r}")
        self.settings.set(self.name, name, value)
