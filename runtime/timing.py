"""The loop's periods, each declared once.

The tick and the configurable periods are declared with the parameters
(:mod:`compiler.params`: ``TICK``, and ``trajectory.period``, ``initialization.period``,
``report.period`` with their ranges); this module names their defaults for the runtime, so
that no component or planner writes 0.001, 0.005 or 0.01 of its own. A configuration
may change a period (Robot Reconfiguration); the components then take it from there.
"""
from __future__ import annotations

from compiler.params import TICK, component_params

#: TICK (s): the executive's tick: the robot interface, the supervisor, the servo and the
#: safety run every tick (declared in compiler.params, which checks periods against it).
__all__ = ["TICK", "SETPOINT_PERIOD", "REPORT_PERIOD", "FIELDBUS_POLL"]

#: s: the trajectory generator's and the initialization's (homing) period: the servo
#: interpolates their setpoints (the two must be equal).
SETPOINT_PERIOD: float = component_params("trajectory")["period"].default  # type: ignore[assignment]
assert SETPOINT_PERIOD == component_params("initialization")["period"].default
#: s: the report's period (one logged row).
REPORT_PERIOD: float = component_params("report")["period"].default  # type: ignore[assignment]
#: s: the default time between two exchanges with a PLC (runtime.hardware.fieldbus; off the loop,
#: on the exchange's own thread; a fieldbus file may choose from TICK to 1 s).
FIELDBUS_POLL = 0.01
