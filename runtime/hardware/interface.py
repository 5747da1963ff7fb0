"""The interfaces the loop's components use of a backend (the hardware side of the robot, as
ros2_control's hardware interfaces are): a backend derives from them, and nothing above
``runtime.hardware`` asks which backend it has.
"""
from __future__ import annotations

from typing import Sequence


class IoBackend:
    """What the I/O component needs of a backend; a backend derives from it. Real-time:
    ``inputs``, ``outputs``, ``input``, ``set_output`` and ``lost`` (plain reads and
    assignments, never a wait). Not real-time: ``start`` (begin exchanging: a fieldbus's
    thread), ``close`` and ``wait_connected``. The defaults: never lost, nothing to start
    or close, always connected."""

    @property
    def inputs(self) -> Sequence[bool]:
        raise NotImplementedError

    @property
    def outputs(self) -> Sequence[bool]:
        raise NotImplementedError

    def input(self, n: int) -> bool:
        raise NotImplementedError

    def set_output(self, n: int, value: bool) -> None:
        raise NotImplementedError

    def lost(self) -> str | None:
        """Why the backend counts as lost now (a PLC not heard from), or None."""
        return None

    def start(self) -> None:
        pass

    def close(self) -> None:
        pass

    def wait_connected(self, timeout: float) -> bool:
        return True

    #: whether an input can be set from outside (:meth:`set_input`): the simulated robot's can,
    #: a real cell's are set by the cell
    forcible = False

    def set_input(self, n: int, value: bool) -> None:
        """Between ticks, on a forcible backend: set input ``n`` (1-based)."""
        raise PermissionError("an input is forced on the simulated robot only")


class NoIo(IoBackend):
    """A robot without digital I/O (a hardware backend that does not derive from
    IoBackend): no inputs, no outputs."""

    inputs = outputs = ()

    def input(self, n: int) -> bool:
        raise IndexError(f"digital input {n} does not exist: this robot has no digital I/O")

    def set_output(self, n: int, value: bool) -> None:
        raise IndexError(f"digital output {n} does not exist: this robot has no digital I/O")
