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
__all__ = ["PACE_WAIT", "TICK", "SETPOINT_PERIOD", "REPORT_PERIOD", "RECORD_PERIOD", "FLUSH_PERIOD", "FIELDBUS_POLL",
           "BRAKE_TIMEOUT", "STOP_SETTLE_TIMEOUT", "START_SETTLE_TIMEOUT"]

#: s: the trajectory generator's and the initialization's (homing) period: the servo
#: interpolates their setpoints (the two must be equal).
SETPOINT_PERIOD: float = component_params("trajectory")["period"].default  # type: ignore[assignment]
assert SETPOINT_PERIOD == component_params("initialization")["period"].default
#: s: the report's period (one logged row).
REPORT_PERIOD: float = component_params("report")["period"].default  # type: ignore[assignment]
#: s: the recording's period (joint states, the TCP and the links: one row), the report's default
#: whatever the report's own (report.period).
RECORD_PERIOD = REPORT_PERIOD
#: s of rows the report and the recording hand their writer threads at a time (runtime.loop.batches):
#: what a crash may lose of the report.
FLUSH_PERIOD = 0.1
#: s: the longest a simulated-clock server's jog session waits at once for the wall clock to
#: catch up with the robot's (runtime.loop.robotloop: a command wakes it sooner).
PACE_WAIT = 0.05
#: s: the default time between two exchanges with a PLC (runtime.hardware.fieldbus; off the loop,
#: on the exchange's own thread; a fieldbus file may choose from TICK to 1 s).
FIELDBUS_POLL = 0.01
#: s the brakes may take to release (Start Robot) or engage (Stop Robot, the safety's stops)
#: before it is a fault (the stop then goes on to torque off anyway).
BRAKE_TIMEOUT = 1.0
#: s at most Stop Robot waits for the servo to settle the axes on the last reference before
#: the brakes close.
STOP_SETTLE_TIMEOUT = 1.0
#: s after homing's move to the start position for every axis to settle there (the
#: initialization's "Go To Start").
START_SETTLE_TIMEOUT = 2.0
