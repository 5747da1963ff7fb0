"""Every parameter of the robot, declared once: type, unit, range, default, whether it is
safety-relevant and when it may change.

The specification loader (``[controller]``, ``[simulation]`` and ``[safety]`` of a
``.spc``), the TOML configurations (``runtime.config``), the components' properties and
the scripting interface's writes all validate through this table; the documentation's
parameter tables are rendered from it (:func:`markdown`). Nothing else declares a range.

A parameter lives in a *section*: a table of the specification (``controller``,
``simulation``, ``safety``) or a component (``servo``, ``robot``, ``trajectory``,
``initialization``, ``report``), whose parameters are keys of the TOML configurations
and properties of the component. A component parameter may take its start value from the
specification (``spec_key``, e.g. ``servo.kp`` from ``[controller] kp``).

When a parameter may change (``change``):

* ``specification``: only by editing the specification (the robot's data; calibration
  and object code depend on its hash);
* ``configuration``: only with a whole configuration applied in Robot Reconfiguration,
  between programs (``irl reconfigure NAME``), never by a single network write;
* ``live``: also by a scripting write (``irl call 'trajectory.budget = 500'``).

Every safety-relevant parameter changes at most by configuration. NaN, infinities, values
out of range and values of the wrong type are refused with the name, the value and the
allowed range (:class:`ParamError`).

Imports nothing from Lark, NumPy or ZeroMQ.
"""
from __future__ import annotations

import dataclasses
import difflib
import math
from dataclasses import dataclass

from . import geometry

__all__ = ["COMPONENTS", "PARAMS", "SETTINGS", "SPEC_SECTIONS", "Param", "ParamError", "component_params",
           "describe", "markdown", "section_params", "settings", "spec_section"]

#: The specification's tables whose keys are parameters (``axis``, each ``[[axis]]``
#: table's limits and encoder, is read by compiler.spec per axis).
SPEC_SECTIONS = ("controller", "simulation", "safety")
#: The components whose settings are parameters (TOML configurations, scripting).
COMPONENTS = ("servo", "robot", "trajectory", "initialization", "report")
CHANGES = ("specification", "configuration", "live")

TICK = 0.001  # s: every period is a whole multiple of the executive's tick
#: The finest encoder resolution an axis may have: counts per deg (or mm) of axis motion,
#: encoder_counts x gear_ratio / 360 (revolute) or x gear_ratio (prismatic). Coarser counts
#: cannot be servoed within the safety's acceleration check, settled on nor homed.
MIN_COUNTS_PER_UNIT = 50.0
#: The finest encoder resolution (counts per deg or mm).
MAX_COUNTS_PER_UNIT = 20_000.0
#: One encoder count steps the servo's command by kp / counts_per_unit within a tick (its
#: proportional term on the quantised position), and an axis drifting at v under a held
#: position ramps the command at kp x v (calibration ends with the drives still drifting):
#: each is at most this share of what the safety's acceleration check allows
#: ([safety] acceleration_factor x max_acceleration), at the largest kp a configuration may
#: set (servo.kp), so that no accepted configuration faults a healthy arm
#: (:func:`least_counts_per_unit`, :func:`greatest_drive_offset`).
SERVO_STEP_SHARE = 0.5
#: How far (deg or mm) above an axis's min homing's index search must end: the search goes
#: down from the sensor's upper edge until an index pulse comes, at most one index spacing
#: (one motor revolution, 360 / gear_ratio deg), and must stop with room before the limit.
INDEX_SEARCH_MARGIN = 10.0
PERIOD_MIN, PERIOD_MAX = 0.001, 1.0
#: The least [robot] max_speed (mm/s) and max_acceleration (mm/s^2): the lower bounds of the
#: speed and acc clauses (compiler.clauses), which those keys bound from above.
MIN_TOOL_SPEED = 0.1
MIN_TOOL_ACCELERATION = 1.0
#: How finely calibration tells a drive's drift (deg/s or mm/s): its 0.25 s of measurement
#: see a few counts of the coarsest encoder. The least [safety] max_drive_drift, and the
#: margin the simulated drives' offset keeps below it.
DRIFT_RESOLUTION = 0.1
#: The most [controller] kp x [simulation] drive_time_constant: the position loop around
#: the lagging drive damped enough (damping ratio 1 / (2 sqrt(kp tau)) >= 0.7) that the
#: servo's command does not overshoot homing's speed limit.
MAX_KP_LAG = 0.5
#: The keys of a pose table (``[kinematics] tool``, ``mounting``, ``[[tool]]``, ``[[frame]]``):
#: x, y, z (mm) and the orientation as roll, pitch, yaw (deg) or as a unit quaternion.
POSE_KEYS = ("x", "y", "z", "roll", "pitch", "yaw")
QUAT_KEYS = ("qw", "qx", "qy", "qz")
#: How far a pose table's quaternion may be from unit norm (a datasheet's five or six
#: digits); it is normalised. Farther, it is a typing error, refused.
QUAT_NORM_TOLERANCE = 1e-3
REPORT_COLUMNS = ("sens_pos", "desi_pos", "out_vel", "following_error", "tcp")
#: Columns a report may also have (not by default): io, every digital input then output (0/1);
#: move, the number and source line of the program's move under way (runtime.loop.components.report).
#: frame, the names of the active tool and base and the tool centre point in that base;
#: analog, every analog input then output, in its unit (the specification's [[analog_input]], [[analog_output]]).
REPORT_COLUMNS_OPTIONAL = ("io", "move", "frame", "analog")


class ParamError(ValueError):
    """A value a parameter does not accept. ``reason`` is the message without the
    parameter's name ("expected ..., got ..."); ``specific`` when it says more than the
    allowed range (a period off the tick, an unknown column)."""

    def __init__(self, name: str, reason: str, specific: bool = False, field: str | None = None):
        if field is not None:
            name = f"{name}.{field}"
        super().__init__(f"{name}: {reason}")
        self.name = name
        self.reason = reason
        self.specific = specific
        self.field = field  # the key within a table value (a pose's "x") the reason is about


def describe(value: object, limit: int = 60) -> str:
    """``value`` as a message shows it (shortened; never fails)."""
    try:
        if isinstance(value, bool):
            text = "true" if value else "false"
        elif isinstance(value, int):
            text = repr(value) if abs(value) < 10 ** 30 else "a very large integer"
        elif isinstance(value, (float, str)):
            text = repr(value)
        elif isinstance(value, (list, tuple)):
            text = "[" + ", ".join(describe(v, 20) for v in value[:5]) + (", ...]" if len(value) > 5 else "]")
        elif isinstance(value, dict):
            text = "a table"
        else:
            text = f"a {type(value).__name__}"
    except Exception:  # noqa: BLE001 - a message must never fail
        text = f"a {type(value).__name__}"
    return text if len(text) <= limit else text[:limit - 3] + "..."


def is_number(value: object) -> bool:
    """A finite number a specification may hold (not a bool, below 1e300 in size: a TOML
    integer too large for a float is not one)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(value) and abs(value) < 1e300
    except OverflowError:
        return False


def _number(x: float) -> str:
    return f"{x:g}"


@dataclass(frozen=True)
class Param:
    """One parameter. ``kind``: "number" (a finite float), "integer", "choice" (one of
    ``choices``), "period" (seconds, a whole multiple of the 1 ms tick) or "columns" (a
    non-empty list of distinct names from ``choices``). Numbers lie in ``low``..``high``,
    each end excluded where ``low_open``/``high_open``."""

    section: str
    name: str
    kind: str
    default: object
    unit: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple = ()
    safety: bool = False
    change: str = "specification"
    spec_key: str | None = None  # "controller.kp": the specification gives the start value
    doc: str = ""

    @property
    def key(self) -> str:
        return f"{self.section}.{self.name}"

    def allowed(self) -> str:
        """What the parameter accepts, as messages and the documentation say it."""
        unit = f" ({self.unit})" if self.unit else ""
        if self.kind == "sign":
            return "1 or -1"
        if self.kind == "text":
            return "a non-empty string"
        if self.kind == "pose":
            return (f"a table {{x, y, z}} (mm, at most {_number(self.high)} mm from the origin) with the orientation "
                    "as roll, pitch, yaw (deg) or as a unit quaternion qw, qx, qy, qz (each key optional: 0; "
                    "not both kinds)")
        if self.kind == "coupling":
            return (f"a table {{axis = NAME, factor = F}}: NAME an earlier main axis, F a number "
                    f"{_number(self.low)} <= F <= {_number(self.high)}, not 0")
        if self.kind == "choice":
            return "one of " + ", ".join(f'"{c}"' for c in self.choices)
        if self.kind == "columns":
            return "a non-empty list of distinct names from " + ", ".join(self.choices)
        if self.kind == "period":
            return f"a period of {PERIOD_MIN:g} to {PERIOD_MAX:g} s, a whole multiple of the {TICK * 1000:g} ms tick"
        what = "an integer" if self.kind == "integer" else "a number"
        if self.low is not None and self.high is not None:
            lo = "<" if self.low_open else "<="
            hi = "<" if self.high_open else "<="
            return f"{what} {_number(self.low)} {lo} x {hi} {_number(self.high)}{unit}"
        if self.low is not None:
            return f"{what} {'>' if self.low_open else '>='} {_number(self.low)}{unit}"
        return what + unit

    def check(self, value: object) -> object:
        """The value normalized (numbers as float, integers as int), or ParamError."""
        kind = self.kind
        if kind == "text":
            if not isinstance(value, str) or not value:
                raise self._error(value)
            return value
        if kind == "choice":
            if not isinstance(value, str) or value not in self.choices:
                raise self._error(value)
            return value
        if kind == "columns":
            return self._columns(value)
        if kind == "pose":
            return self._pose(value)
        if kind == "coupling":
            return self._coupling(value)
        if kind == "sign":
            if isinstance(value, bool) or value not in (1, -1) or not float(value).is_integer():
                raise self._error(value)
            return int(value)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self._error(value)
        if kind == "integer":
            if not isinstance(value, int):
                raise self._error(value)
            x: float | int = value
        else:
            try:
                x = float(value)
            except OverflowError:
                raise self._error(value) from None
            if not math.isfinite(x):
                raise self._error(value)
        if kind == "period":
            return self._period(x, value)
        low, high = self.low, self.high
        if low is not None and (x < low or (self.low_open and x == low)):
            raise self._error(value)
        if high is not None and (x > high or (self.high_open and x == high)):
            raise self._error(value)
        return x

    def _error(self, value: object, reason: str | None = None) -> ParamError:
        return ParamError(self.key, reason or f"expected {self.allowed()}, got {describe(value)}", reason is not None)

    def _period(self, seconds: float, value: object) -> float:
        if not PERIOD_MIN - 1e-9 <= seconds <= PERIOD_MAX + 1e-9:
            raise self._error(value)
        ticks = round(seconds / TICK)
        if abs(seconds - ticks * TICK) > 1e-9:
            below, above = math.floor(seconds / TICK), math.ceil(seconds / TICK)
            raise self._error(value, f"expected a whole multiple of the {TICK * 1000:g} ms tick, got "
                                     f"{describe(value)} (nearest: {below * TICK:g} or {above * TICK:g})")
        return ticks / round(1 / TICK)

    def _pose(self, value: object) -> tuple[float, ...]:
        """x, y, z, roll, pitch, yaw of a pose table (a quaternion's as roll, pitch, yaw)."""
        if not isinstance(value, dict):
            raise self._error(value)
        unknown = [k for k in value if k not in POSE_KEYS + QUAT_KEYS]
        if unknown:
            close = difflib.get_close_matches(str(unknown[0]), list(POSE_KEYS + QUAT_KEYS), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise self._error(value, f"unknown key {unknown[0]!r}{hint}; expected x, y, z and either roll, pitch, "
                                     "yaw or qw, qx, qy, qz")
        numbers = {}
        for key, v in value.items():
            if not is_number(v):
                unit = "mm" if key in "xyz" else "deg" if key in POSE_KEYS else "a quaternion's component"
                raise ParamError(self.key, f"expected a number ({unit}), got {describe(v)}", True, key)
            numbers[key] = float(v)
        x, y, z = (numbers.get(k, 0.0) for k in "xyz")
        offset = math.sqrt(x * x + y * y + z * z)
        if self.high is not None and offset > self.high:
            raise self._error(value, f"expected the origin at most {_number(self.high)} mm from its frame's, got "
                                     f"{offset:.6g} mm")
        given = [k for k in QUAT_KEYS if k in numbers]
        if not given:
            return (x, y, z, *(numbers.get(k, 0.0) for k in POSE_KEYS[3:]))
        rpy = [k for k in POSE_KEYS[3:] if k in numbers]
        if rpy:
            raise self._error(value, f"expected the orientation as roll, pitch, yaw or as qw, qx, qy, qz, not both "
                                     f"(got {rpy[0]} and {given[0]})")
        q = tuple(numbers.get(k, 0.0) for k in QUAT_KEYS)
        norm = math.sqrt(sum(c * c for c in q))
        if abs(norm - 1.0) > QUAT_NORM_TOLERANCE:
            raise self._error(value, f"expected a unit quaternion (qw^2 + qx^2 + qy^2 + qz^2 = 1 within "
                                     f"{QUAT_NORM_TOLERANCE:g}), got one of norm {norm:.6g}: check its values")
        return (x, y, z, *geometry.quat_to_rpy(q))

    def _coupling(self, value: object) -> tuple[str, float]:
        if not isinstance(value, dict) or set(value) != {"axis", "factor"}:
            raise self._error(value)
        name, factor = value["axis"], value["factor"]
        if not isinstance(name, str) or not name:
            raise self._error(value, f"expected axis, the name of an earlier main axis, got {describe(name)}")
        if isinstance(factor, bool) or not isinstance(factor, (int, float)) or not math.isfinite(factor) \
                or factor == 0 or not self.low <= factor <= self.high:
            raise self._error(value, f"expected factor a number {_number(self.low)} <= F <= {_number(self.high)}, "
                                     f"not 0, got {describe(factor)}")
        return (name, float(factor))

    def _columns(self, value: object) -> list:
        if not isinstance(value, (list, tuple)) or not value:
            raise self._error(value)
        seen: list[str] = []
        for index, column in enumerate(value):
            if not isinstance(column, str):
                raise self._error(value, f"expected column names (strings), got {describe(column)} at index {index}")
            if column not in self.choices:
                close = difflib.get_close_matches(column, list(self.choices), n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise self._error(value, f"unknown column {column!r}{hint}; known: {', '.join(self.choices)}")
            if column in seen:
                raise self._error(value, f"duplicate column {column!r}")
            seen.append(column)
        return seen


def _p(section, name, kind, default, unit="", low=None, high=None, **kw) -> Param:
    return Param(section, name, kind, default, unit, low, high, **kw)


#: THE table. Order: as the documentation lists them.
PARAMS: tuple[Param, ...] = (
    # ---- the servo (1 ms position loop); start values from [controller] ----
    _p("servo", "kp", "number", 40.0, "1/s", 10.0, 100.0, safety=True, change="configuration",
       spec_key="controller.kp", doc="position loop gain (below 10, with a small ki and a slow drive, the axes did not settle at the start position within homing's 2 s)"),
    _p("servo", "ki", "number", 2.0, "1/s^2", 0.0, 100.0, safety=True, change="configuration",
       spec_key="controller.ki", doc="integral gain"),
    _p("servo", "following_error_limit", "number", 2.0, "deg or mm", 0.1, 10.0, safety=True,
       change="configuration", spec_key="controller.following_error_limit",
       doc="largest allowed |reference - measured position| of any axis; beyond it the robot stops "
           "(category 1). It cannot be switched off: at most 10; at least 0.1, and for each axis at least "
           "[simulation] drive_time_constant x max_acceleration / kp (least_following_error_limit: what the "
           "servo lags behind a move at max_acceleration)"),
    # ---- [controller]: the loop's policies ----
    _p("controller", "servo_miss_policy", "choice", "firm", choices=("hard", "firm", "soft"), safety=True,
       doc="deadline policy of the 1 ms servo task on the wall clock: hard (one miss faults), firm (more than "
           "servo_miss_limit misses within servo_miss_window ticks fault) or soft (counted only)"),
    _p("controller", "servo_miss_limit", "integer", 50, "misses", 0, 10_000, safety=True,
       doc="firm policy: misses allowed within the window (must be below servo_miss_window)"),
    _p("controller", "servo_miss_window", "integer", 1000, "ticks", 1, 100_000, safety=True,
       doc="firm policy: the window of ticks the misses are counted in"),
    _p("controller", "profile", "choice", "jerk", choices=("jerk", "trapezoid"),
       doc="PTP velocity profile: seven-phase jerk-limited, or trapezoidal (velocity and acceleration only)"),
    _p("controller", "lookahead", "integer", 4, "moves", 0, 16,
       doc="moves planned ahead of the robot (0: each move is planned when the one before has ended)"),
    # ---- [safety]: the safety supervisor (docs/safety.md) ----
    _p("safety", "max_drive_drift", "number", 2.0, "deg/s or mm/s", DRIFT_RESOLUTION, 100.0, safety=True,
       doc=f"largest drift of a drive under a zero command that calibration accepts (measured or loaded); at "
           f"least {DRIFT_RESOLUTION:g}, what calibration's 0.25 s measurement resolves with the coarsest encoder, "
           f"and at least [simulation] max_drive_offset + {DRIFT_RESOLUTION:g} (the simulated drives' own drift)"),
    _p("safety", "standstill_tolerance", "integer", 10, "counts", 1, 10_000, safety=True,
       doc="standstill monitoring: how far (encoder counts) an axis may move from its standstill reference, "
           "once it is in position, while the robot must be at rest"),
    _p("safety", "in_position_window", "integer", 5, "counts", 2, 10_000, safety=True,
       doc="standstill monitoring: an axis is in position when its encoder stays within this many counts of "
           "the servo's reference for in_position_time (the servo's reference then becomes its standstill "
           "reference); at most standstill_tolerance, and at least 2 (one count of the encoder's quantisation "
           "and one for the servo's hold)"),
    _p("safety", "in_position_time", "number", 0.02, "s", 0.001, 1.0, safety=True,
       doc="standstill monitoring: how long an axis must stay within in_position_window to be in position"),
    _p("safety", "in_position_timeout", "number", 1.0, "s", 0.01, 60.0, safety=True,
       doc="standstill monitoring: an axis that is not in position this long after the servo's reference came "
           "to rest is a fault (category 0); at least in_position_time + what the servo needs to settle each "
           "axis into the window after a move at its limits (least_in_position_timeout: from [controller] kp "
           "and ki, [simulation] drive_time_constant and the axis's limits and encoder)"),
    _p("safety", "plausibility_distance", "number", 0.1, "deg or mm", 0.05, 10.0, safety=True,
       doc="encoder plausibility: commanded travel of an axis without a single encoder count (or against the "
           "counts' direction) that is a fault; at least 0.05, and for each axis at least one count plus "
           "[simulation] drive_time_constant x how fast a move from rest at max_acceleration "
           "goes at the first count (the travel commanded before the lagging drive gives a count: "
           "least_plausibility_distance)"),
    _p("safety", "plausibility_time", "number", 0.2, "s", 0.01, 2.0, safety=True,
       doc="encoder plausibility: how long commanded travel is remembered while no count comes (a command "
           "below plausibility_distance / plausibility_time, 0.5 deg/s by default, never adds up to a fault: "
           "it may only hold the axis against a drift)"),
    _p("safety", "stop_reaction_time", "number", 0.01, "s", 0.001, 0.1, safety=True,
       doc="software position limits: the time from a stop command until the drives decelerate (their lag "
           "and one tick), added to the stopping distance"),
    _p("safety", "limit_tolerance", "number", 0.05, "deg or mm", 0.0, 5.0, safety=True,
       doc="software position limits: how far beyond min/max the predicted rest position may lie before the "
           "robot stops (covers settling on a target at the limit)"),
    _p("safety", "acceleration_factor", "number", 2.0, "x max_acceleration", 1.0, 10.0, safety=True,
       doc="a commanded velocity that changes faster than this multiple of the axis's max_acceleration is a "
           "fault (the servo's corrections and the interpolation add up to 5/3 of the planned acceleration)"),
    _p("safety", "homing_velocity_factor", "number", 2.0, "x search_velocity", 1.0, 10.0, safety=True,
       doc="before an axis is referenced (homing), its commanded velocity may not exceed this multiple of its "
           "search_velocity"),
    _p("safety", "stop_time_margin", "number", 0.5, "s", 0.05, 5.0, safety=True,
       doc="a controlled stop (pause, abort, a stop on the path) that has not brought the robot to rest this "
           "long after its planned duration is taken over by the safety's own ramp"),
    _p("safety", "t1_speed", "number", 250.0, "mm/s", 10.0, 250.0, safety=True,
       doc="operating mode T1 (manual reduced speed, ISO 10218-1): the tool centre point and the flange never "
           "move faster; the safety supervisor checks every 1 ms reference and stops the robot (category 1) "
           "beyond it; moves, jogs and homing are planned under it"),
    _p("safety", "t1_velocity_factor", "number", 0.25, "x max_velocity", 0.01, 1.0, safety=True,
       doc="operating mode T1: each axis's reduced speed, this fraction of its max_velocity (planned under and "
           "enforced by the safety supervisor as its velocity limit)"),
    # ---- [robot]: the robot's name and its tool's limits (the specification's own keys:
    # a configuration's robot.* keys are the component's, below) ----
    _p("robot", "name", "text", None, doc="the robot's name (what a program's act_rob names)"),
    _p("robot", "description", "text", "", doc="what the robot is (optional)"),
    _p("robot", "max_speed", "number", 2000.0, "mm/s", MIN_TOOL_SPEED, 20_000.0,
       doc="the tool centre point's speed limit: the speed clause's upper bound (compiler.clauses)"),
    _p("robot", "max_acceleration", "number", 10_000.0, "mm/s^2", MIN_TOOL_ACCELERATION, 500_000.0,
       doc="the tool centre point's acceleration limit: the acc clause's upper bound (compiler.clauses)"),
    # ---- [[axis]]: what each axis is (the position keys are checked against each other in
    # compiler/spec.py: min < max, home and sensor_position within them) ----
    _p("axis", "name", "text", None, doc="the axis's name (unique; what reports and messages call it)"),
    _p("axis", "kind", "choice", None, choices=("revolute", "prismatic"),
       doc="revolute (its positions in deg) or prismatic (in mm)"),
    _p("axis", "min", "number", None, "deg or mm", doc="the lower software limit"),
    _p("axis", "max", "number", None, "deg or mm", doc="the upper software limit (greater than min)"),
    _p("axis", "group", "choice", "main", choices=("main", "additional"),
       doc="an axis of the arm (main) or an additional one (a track, a positioner); main axes come first"),
    _p("axis", "home", "number", 0.0, "deg or mm",
       doc="the start position the initialization sequence drives to, within min..max (the default 0 only "
           "where it lies within them)"),
    _p("axis", "sensor_position", "number", -5.0, "deg or mm",
       doc="the centre of the homing sensor's window, within min..max; by default this far from home "
           "(home - 5, where that lies within min..max)"),
    # ---- [[axis]]: each axis's data (the position keys min, max, home and sensor_position
    # are checked against each other in compiler/spec.py). The lower bounds are what the
    # runtime can use: a smaller limit plans moves no run ends (or nan positions), a coarser
    # encoder cannot be servoed or homed, and the servo's own corrections on a healthy arm
    # would be a fault beside a smaller max_acceleration ----
    _p("axis", "max_velocity", "number", None, "deg/s or mm/s", 1.0, 3600.0, safety=True,
       doc="the axis's velocity limit (moves, the servo's commands and the safety supervisor); fast wrists "
           "of small arms turn at up to about 1500 deg/s"),
    _p("axis", "max_acceleration", "number", None, "deg/s^2 or mm/s^2", 50.0, 10_000.0, safety=True,
       doc="the axis's acceleration limit"),
    _p("axis", "max_jerk", "number", None, "deg/s^3 or mm/s^3", 10.0, 1_000_000.0, safety=True,
       doc="the axis's jerk limit (jerk-limited PTP moves, blends, lin and circ paths)"),
    _p("axis", "gear_ratio", "number", 100.0, "", 1.0, 1000.0,
       doc="motor revolutions per axis revolution (revolute) or per mm (prismatic); with encoder_counts at most "
           f"{MAX_COUNTS_PER_UNIT:g} counts per deg or mm and at least {MIN_COUNTS_PER_UNIT:g} and KP_MAX / "
           f"({SERVO_STEP_SHARE:g} x [safety] acceleration_factor x max_acceleration x the tick), KP_MAX the largest servo.kp "
           "(least_counts_per_unit); at least 360 / (sensor_position + sensor_window - min - "
           f"{INDEX_SEARCH_MARGIN:g}) (least_gear_ratio: homing's index search ends above min)"),
    _p("axis", "encoder_counts", "integer", 4096, "counts", 16, 1 << 20,
       doc="encoder counts per motor revolution (after quadrature)"),
    _p("axis", "direction", "sign", 1,
       doc="which way the joint value turns the link: 1, about +z of the axis's DH frame (theta = q + "
           "theta_offset); -1, about -z (theta = -q + theta_offset), so that joint values are the vendor's "
           "(KUKA's A1, A4 and A6 turn about -z of a right-handed DH chain)"),
    _p("axis", "coupling", "coupling", None, "", -1.0, 1.0,
       doc="a coupled axis (FANUC's J3, measured from the horizontal: its DH angle is J3 - J2): theta = "
           "direction x q + theta_offset + factor x the value of axis NAME. Only axes 2 and 3 of the arm may be "
           "coupled, each to an earlier main axis; the joint limits stay each axis's own (a J2/J3 interference "
           "limit that depends on both is not expressed)"),
    # ---- [kinematics]: where the arm stands and its tool ----
    _p("kinematics", "tool", "pose", (0.0,) * 6, "mm, deg", None, 5_000.0,
       doc="the tool centre point in the flange frame (the last DH frame): what a pose target puts in place "
           "when no 'use tool' says otherwise (default_tool)"),
    _p("kinematics", "mounting", "pose", (0.0,) * 6, "mm, deg", None, 100_000.0,
       doc="the robot's base (the first DH frame) in the cell's world frame: floor (the default, the identity), "
           "a riser (z), a wall (roll or pitch 90) or the ceiling (roll 180). Pose targets, frames and the "
           "reported tool centre point are in the world frame"),
    _p("axis", "sensor_window", "number", 0.5, "deg or mm", 0.01, 10.0,
       doc="half-width of the homing sensor's window"),
    _p("axis", "search_velocity", "number", 5.0, "deg/s or mm/s", 0.1, 1000.0,
       doc="speed of the initialization's searches (at most max_velocity; default: 5, or max_velocity if smaller)"),
    # ---- [simulation]: the simulated arm ----
    _p("simulation", "drive_time_constant", "number", 0.005, "s", 0.0001, 0.01,
       doc=f"first-order lag of each velocity-commanded drive: a lag below a tenth of the 1 ms tick is not seen; "
           f"with a longer one, or kp x drive_time_constant above {MAX_KP_LAG:g}, the servo overshoots homing's "
           f"speed limit or does not settle"),
    _p("simulation", "max_drive_offset", "number", 0.5, "deg/s or mm/s", 0.0, 100.0,
       doc="largest constant velocity offset of a drive (seeded per axis); for every axis at most "
           f"{SERVO_STEP_SHARE:g} x [safety] acceleration_factor x max_acceleration / KP_MAX "
           "(greatest_drive_offset, KP_MAX the largest servo.kp: the servo holding the drift within the safety's "
           "acceleration check)"),
    _p("simulation", "park_spread", "number", 3.0, "deg or mm", 0.0, 90.0,
       doc="power-up position: home +- this (seeded per axis)"),
    _p("simulation", "brake_time", "number", 0.05, "s", 0.0, 5.0, doc="time the brakes take to engage or release"),
    _p("simulation", "drive_saturation", "number", 1.5, "x max_velocity", 1.0, 10.0,
       doc="the drives' own velocity limit"),
    _p("simulation", "end_stop_margin", "number", 5.0, "deg or mm", 0.1, 90.0,
       doc="the mechanical end stops lie this far beyond each axis's min and max (the software limits); "
           "more than [safety] limit_tolerance, how far beyond a limit the safety lets the arm come to rest"),
    # ---- the other components (TOML configurations; scripting for 'live' ones) ----
    _p("robot", "velocity_limit_scale", "number", 1.0, "", 0.01, 1.0, safety=True,
       change="configuration",
       doc="reduced speed: the fraction of each axis's max_velocity that moves are planned with and that the "
           "safety supervisor enforces (homing's searches too: below 0.01 they take many minutes)"),
    _p("initialization", "home_speed", "number", 0.2, "", 0.01, 1.0, safety=True,
       change="configuration",
       doc="fraction of each axis's max_velocity and max_acceleration used by homing (searches ramp with this "
           "fraction of max_acceleration; the move to the start position uses both; below 0.01 it takes "
           "many minutes)"),
    _p("initialization", "period", "period", 0.005, "s", change="configuration",
       doc="time between setpoints of the homing sequence; must equal trajectory.period"),
    _p("trajectory", "budget", "integer", 200, "instructions", 1, 10_000, change="live",
       doc="object-code instructions the interpreter runs per update at most (on the wall clock each "
           "update is also bounded in time: runtime.loop.vm.TIME_SLICE)"),
    _p("trajectory", "period", "period", 0.005, "s", change="configuration",
       doc="time between setpoints of the program's motion; must equal initialization.period"),
    _p("report", "period", "period", 0.01, "s", change="configuration", doc="time between two logged rows"),
    _p("report", "columns", "columns", list(REPORT_COLUMNS), choices=REPORT_COLUMNS + REPORT_COLUMNS_OPTIONAL,
       change="configuration",
       doc="signals logged in each row, in this order (tcp: x, y, z, roll, pitch, yaw of the tool; io: every "
           "digital input, then output, 0 or 1; added by a cell scenario; move: move, the number of the program's "
           "move under way or last started (from 1; 0 before the first), and line, the source line of the move "
           "under way (0 when none is); frame: tool and base, the names of the tool and base of the move under way "
           "or last started (use tool, use base), and base_x ... base_yaw, the tool centre point in that base)"),
)

_BY_SECTION: dict[str, dict[str, Param]] = {}
for _param in PARAMS:
    assert _param.change in CHANGES, _param
    assert not (_param.safety and _param.change == "live"), f"{_param.key}: safety-relevant parameters are not live"
    _BY_SECTION.setdefault(_param.section, {})[_param.name] = _param


def section_params(section: str) -> dict[str, Param]:
    """The parameters of one section (a specification table or a component), by name."""
    return dict(_BY_SECTION.get(section, {}))


def component_params(component: str) -> dict[str, Param]:
    """A component's settings (``robot.velocity_limit_scale``; not the specification's
    ``[robot]`` keys, which share the section's name)."""
    return {name: p for name, p in _BY_SECTION.get(component, {}).items() if p.change != "specification"}


def spec_section(section: str) -> dict[str, Param]:
    """What a specification table accepts: its own parameters, and the component
    parameters whose start value it gives (``[controller] kp`` -> ``servo.kp``)."""
    result = {name: p for name, p in _BY_SECTION.get(section, {}).items() if p.change == "specification"}
    for param in PARAMS:
        if param.spec_key is not None and param.spec_key.split(".", 1)[0] == section:
            result[param.spec_key.split(".", 1)[1]] = param
    return result


#: The Python type of each kind of parameter (the settings' field types).
_TYPES = {"number": float, "integer": int, "choice": str, "text": str, "period": float, "columns": list, "sign": int,
          "pose": tuple, "coupling": tuple}


def _settings_class(section: str) -> type:
    """The typed settings of a specification table: a frozen dataclass with one field per
    parameter the table accepts (:func:`spec_section`), its type from the parameter's kind
    and its documentation from the table."""
    accepted = spec_section(section)
    cls = dataclasses.make_dataclass(
        f"{section.title()}Settings", [(name, _TYPES[param.kind]) for name, param in accepted.items()],
        frozen=True, slots=True)
    cls.__module__ = __name__
    cls.__doc__ = (f"The specification's [{section}], validated (compiler.params); one attribute per "
                   "parameter:\n\n" + "\n".join(f"* ``{name}`` ({p.unit or p.kind}) -- {p.doc}"
                                                   for name, p in accepted.items()))
    return cls


#: The typed settings of each specification table: ``spec.controller.kp``,
#: ``spec.simulation.brake_time``, ``spec.safety.stop_time_margin``.
SETTINGS: dict[str, type] = {section: _settings_class(section) for section in SPEC_SECTIONS}
ControllerSettings, SimulationSettings, SafetySettings = (SETTINGS[s] for s in ("controller", "simulation", "safety"))


def settings(section: str, values: dict):
    """The typed settings of the table ``section`` from its validated ``values`` (every
    parameter present; see :func:`spec_section`)."""
    return SETTINGS[section](**values)


def check_spec_rules(values: dict[str, dict[str, object]]) -> tuple[str, str] | None:
    """Rules across keys of the specification's tables (validated values, defaults
    filled in): ``(key, reason)`` of the first broken one, or None."""
    controller, safety, simulation = values["controller"], values["safety"], values["simulation"]
    if controller["servo_miss_limit"] >= controller["servo_miss_window"]:
        return ("controller.servo_miss_limit",
                f"expected fewer misses than the window ({controller['servo_miss_window']} ticks), "
                f"got {controller['servo_miss_limit']}")
    lag = controller["kp"] * simulation["drive_time_constant"]
    if lag > MAX_KP_LAG + 1e-12:
        return ("simulation.drive_time_constant",
                f"expected at most {MAX_KP_LAG:g} / [controller] kp ({MAX_KP_LAG / controller['kp']:.4g} s: a longer "
                f"lag makes the servo overshoot), got {simulation['drive_time_constant']:g}")
    if simulation["max_drive_offset"] + DRIFT_RESOLUTION > safety["max_drive_drift"] + 1e-9:
        return ("safety.max_drive_drift",
                f"expected at least [simulation] max_drive_offset + {DRIFT_RESOLUTION:g} "
                f"({simulation['max_drive_offset'] + DRIFT_RESOLUTION:g}: the simulated drives drift up to "
                f"max_drive_offset, which calibration must accept), got {safety['max_drive_drift']:g}")
    if safety["in_position_window"] > safety["standstill_tolerance"]:
        return ("safety.in_position_window",
                f"expected at most [safety] standstill_tolerance ({safety['standstill_tolerance']} counts: an axis in "
                f"position must already be within the tolerance of its standstill reference), got "
                f"{safety['in_position_window']}")
    if safety["in_position_time"] >= safety["in_position_timeout"]:
        return ("safety.in_position_timeout",
                f"expected more than [safety] in_position_time ({safety['in_position_time']:g} s: an axis must be "
                f"able to stay in the window that long before the timeout), got {safety['in_position_timeout']:g}")
    if simulation["end_stop_margin"] <= safety["limit_tolerance"]:
        return ("simulation.end_stop_margin",
                f"expected more than [safety] limit_tolerance ({safety['limit_tolerance']:g}: the arm may come to "
                f"rest that far beyond a limit), got {simulation['end_stop_margin']:g}")
    return None


#: The largest position-loop gain any configuration may set (servo.kp's upper bound).
KP_MAX = _BY_SECTION["servo"]["kp"].high


def least_counts_per_unit(max_acceleration: float, acceleration_factor: float) -> float:
    """The coarsest encoder an axis may have (counts per deg or mm): MIN_COUNTS_PER_UNIT,
    and fine enough that one count's step of the servo's command (KP_MAX / counts per unit
    in a tick) is at most SERVO_STEP_SHARE of the safety's acceleration limit."""
    return max(MIN_COUNTS_PER_UNIT, KP_MAX / (SERVO_STEP_SHARE * acceleration_factor * max_acceleration * TICK))


def greatest_drive_offset(max_acceleration: float, acceleration_factor: float) -> float:
    """The largest [simulation] max_drive_offset an axis allows (deg/s or mm/s): the servo
    holding a drive that drifts that fast ramps its command at KP_MAX x the drift, at most
    SERVO_STEP_SHARE of the safety's acceleration limit."""
    return SERVO_STEP_SHARE * acceleration_factor * max_acceleration / KP_MAX


def least_gear_ratio(axis) -> float:
    """The smallest gear_ratio ``axis`` allows: its index pulses close enough together
    that homing's index search below the sensor ends INDEX_SEARCH_MARGIN above min."""
    room = axis.sensor_position + axis.sensor_window - axis.min - INDEX_SEARCH_MARGIN
    full = 360.0 if axis.kind == "revolute" else 1.0
    return math.inf if room <= 0 else full / room


def first_count_velocity(axis, drive_time_constant: float) -> float:
    """The fastest the reference of ``axis`` moves (deg/s or mm/s) when its encoder gives the
    first count of a motion from rest: accelerating at max_acceleration ``a`` (at most),
    the lagging drive has moved at least a (t^2 / 2 - tau t), one count ``c`` by
    t = tau + sqrt(tau^2 + 2 c / a); the reference then moves at a t, at most max_velocity."""
    a, tau, c = axis.max_acceleration, drive_time_constant, 1.0 / axis.counts_per_unit
    return min(axis.max_velocity, a * (tau + math.sqrt(tau * tau + 2.0 * c / a)))


def least_plausibility_distance(axis, drive_time_constant: float) -> float:
    """The smallest [safety] plausibility_distance ``axis`` allows (deg or mm): the travel
    the servo may command before the encoder's first count of a motion from rest (a
    homing search, the move to the start position, a program's move): one count (the axis
    may rest just below the next) and what the lagging drive has not yet followed. Under a
    first-order lag (tau v' = u - v) the commanded travel leads the axis's by exactly
    drive_time_constant x the axis's velocity, at most the reference's then
    (:func:`first_count_velocity`)."""
    lead = drive_time_constant * first_count_velocity(axis, drive_time_constant)
    return 1.0 / axis.counts_per_unit + lead


def least_following_error_limit(axis, drive_time_constant: float, kp: float) -> float:
    """The smallest [controller] following_error_limit ``axis`` allows (deg or mm): the
    servo's following error while the reference accelerates at the axis's
    max_acceleration, drive_time_constant x max_acceleration / kp (the lagging drive's
    velocity deficit, tau x acceleration, made up by the proportional term)."""
    return drive_time_constant * axis.max_acceleration / kp


#: Encoder counts an axis that has settled on its reference may still read away from it: one
#: of the encoder's quantisation, and up to half a count more from the servo's hold (a drive's
#: offset left after calibration, which the integral takes out only slowly). The settling must
#: reach in_position_window less this.
IN_POSITION_SLACK = 1.5
#: Two modes of the position loop closer than this share of their size are bounded as if they
#: were this far apart: a double root's t e^(rt) is below the bound of the pair that far apart.
MODE_SEPARATION = 0.01


def loop_modes(drive_time_constant: float, kp: float, ki: float) -> tuple[complex, ...]:
    """The modes of the servo's position loop around the lagging drive: the roots of
    ``D(s) = tau s^3 + s^2 + kp s + ki`` (the reference's velocity fed forward, PI on the
    error ``e``, the drive a first-order lag ``tau``), under which ``e = tau J / D(s)`` of
    the reference's jerk ``J``. Roots closer than MODE_SEPARATION of their size are moved
    that far apart (see :func:`settle_time`)."""
    tau = drive_time_constant

    def d(s: float) -> float:
        return ((tau * s + 1.0) * s + kp) * s + ki

    low, high = -(1.0 + max(1.0, kp, ki) / tau), 0.0  # d(low) < 0 <= d(0) = ki: a real root between
    for _ in range(200):
        middle = 0.5 * (low + high)
        if d(middle) < 0.0:
            low = middle
        else:
            high = middle
    r0 = high if ki > 0.0 else 0.0
    b = 1.0 + tau * r0  # d(s) = (s - r0) (tau s^2 + b s + c)
    c = kp + b * r0
    root = (complex(b * b - 4.0 * tau * c)) ** 0.5
    roots = [complex(r0), (-b + root) / (2.0 * tau), (-b - root) / (2.0 * tau)]
    for i in range(3):
        for j in range(i + 1, 3):
            size = max(abs(roots[i]), abs(roots[j]))
            if abs(roots[i] - roots[j]) < MODE_SEPARATION * size:
                middle = 0.5 * (roots[i] + roots[j])
                apart = 0.5 * MODE_SEPARATION * size
                roots[i], roots[j] = middle + apart, middle - apart
    return tuple(roots)


def settle_time(axis, drive_time_constant: float, kp: float, ki: float, window: float) -> float:
    """How long (s) after its reference comes to rest the servo may need to bring ``axis``
    within ``window`` encoder counts of it, after any motion within the axis's limits
    (``max - min``, max_velocity, max_acceleration) that started from rest on the reference:
    0 if never outside, ``inf`` if it may never come there.

    The following error ``e = tau J / D(s)`` (:func:`loop_modes`) is, once the reference
    rests, a sum of modes ``tau / D'(r) x the integral of e^(r (t - u)) dA(u)`` over the
    reference's acceleration ``A``. Integrating by parts (A and the velocity are 0 at rest,
    the weight is monotone for a real ``r``: the second mean value theorem), a real mode is
    at most ``tau / |D'(r)| x min(max_acceleration, |r| max_velocity, r^2 (max - min))``, a
    complex one ``tau / |D'(r)| x min(|r| max_acceleration, |r|^2 max_velocity) / |Re r|``,
    and each decays as ``e^(Re r t)``. The slow mode of the integral (about -ki / kp) starts
    small (its ``r^2 (max - min)``) but decays slowly. The time is where their sum falls to
    ``window`` (less IN_POSITION_SLACK). The loop runs every tick on a position measured at
    the tick and holds its command over the tick: ``tau`` is the drive's lag and that tick
    (which the lag of a slow drive hides, and which a fast one makes the larger part)."""
    tau = drive_time_constant + TICK
    target = window - IN_POSITION_SLACK
    span = axis.max - axis.min
    amax, vmax, cpu = axis.max_acceleration, axis.max_velocity, axis.counts_per_unit
    roots = loop_modes(tau, kp, ki)
    modes = []
    for i, r in enumerate(roots):
        derivative = tau
        for j, other in enumerate(roots):
            if j != i:
                derivative *= r - other
        size, rate = abs(r), -r.real
        if r.imag == 0.0:
            bound = min(amax, size * vmax, size * size * span)
        else:
            bound = min(size * amax, size * size * vmax) / rate
        amplitude = tau * bound / abs(derivative) * cpu if bound > 0.0 else 0.0
        if amplitude > 0.0:
            modes.append((amplitude, rate))
    if sum(a for a, _ in modes) <= target:
        return 0.0
    if target <= 0.0 or any(rate <= 0.0 for _, rate in modes):
        return math.inf
    low, high = 0.0, max(math.log(len(modes) * a / target) / rate for a, rate in modes)
    for _ in range(60):  # the sum falls monotonically: bisection
        middle = 0.5 * (low + high)
        if sum(a * math.exp(-rate * middle) for a, rate in modes) > target:
            low = middle
        else:
            high = middle
    return high


def least_in_position_timeout(axis, drive_time_constant: float, kp: float, ki: float, window: float,
                              time: float) -> float:
    """The smallest [safety] in_position_timeout ``axis`` allows (s): in_position_time, what
    the servo may need to settle the axis into the window (:func:`settle_time`) and a tick."""
    return time + settle_time(axis, drive_time_constant, kp, ki, window) + TICK


def check_axis_rules(values: dict[str, dict[str, object]], axes) -> tuple[str, str] | None:
    """Rules between each axis's data and the specification's tables (validated values,
    defaults filled in): ``(key, reason)`` of the first broken one, or None."""
    safety, simulation, controller = values["safety"], values["simulation"], values["controller"]
    factor, offset = safety["acceleration_factor"], simulation["max_drive_offset"]
    tau, kp = simulation["drive_time_constant"], controller["kp"]
    for i, a in enumerate(axes):
        least = least_counts_per_unit(a.max_acceleration, factor)
        if a.counts_per_unit < least:
            per = "/ 360 " if a.kind == "revolute" else ""
            return (f"axis[{i + 1}].encoder_counts",
                    f"encoder_counts x gear_ratio {per}gives {a.counts_per_unit:.4g} counts per {a.unit}: expected at "
                    f"least {least:.4g} (servo.kp at most {KP_MAX:g} / ({SERVO_STEP_SHARE:g} x [safety] "
                    f"acceleration_factor {factor:g} x max_acceleration {a.max_acceleration:g} x the {TICK * 1000:g} "
                    f"ms tick): one count must not step the servo's command beyond the safety's acceleration check)")
        gear = least_gear_ratio(a)
        if a.gear_ratio < gear:
            return (f"axis[{i + 1}].gear_ratio",
                    f"expected at least {gear:.4g} (an index pulse every 360 / gear_ratio {a.unit}; homing searches "
                    f"for one below the sensor's upper edge, sensor_position + sensor_window = "
                    f"{a.sensor_position + a.sensor_window:g}, and must end {INDEX_SEARCH_MARGIN:g} {a.unit} above "
                    f"min {a.min:g}), got {a.gear_ratio:g}")
        plausible = least_plausibility_distance(a, tau)
        if safety["plausibility_distance"] < plausible:
            return ("safety.plausibility_distance",
                    f"expected at least {plausible:.4g} {a.unit} for {a.name} (one count, 1 / {a.counts_per_unit:.4g}, "
                    f"+ [simulation] drive_time_constant {tau:g} x "
                    f"{first_count_velocity(a, tau):.4g} {a.unit}/s, how fast a move from rest at its max_acceleration "
                    f"{a.max_acceleration:g} goes when the lagging drive gives its first count), got "
                    f"{safety['plausibility_distance']:g}")
        following = least_following_error_limit(a, tau, kp)
        if controller["following_error_limit"] < following:
            return ("controller.following_error_limit",
                    f"expected at least {following:.4g} {a.unit} for {a.name} ([simulation] drive_time_constant "
                    f"{tau:g} x its max_acceleration {a.max_acceleration:g} / [controller] kp {kp:g}: the servo's "
                    f"following error while a move accelerates at max_acceleration), got "
                    f"{controller['following_error_limit']:g}")
        window, time = safety["in_position_window"], safety["in_position_time"]
        timeout = least_in_position_timeout(a, tau, kp, controller["ki"], window, time)
        if safety["in_position_timeout"] < timeout:
            settle = timeout - time - TICK
            return ("safety.in_position_timeout",
                    f"expected at least {timeout:.3g} s for {a.name} (in_position_time {time:g} s + {settle:.3g} s, "
                    f"what the servo may need to settle it within in_position_window {window} counts (less "
                    f"{IN_POSITION_SLACK:g}) of its reference after a move at its limits, with [controller] kp {kp:g} "
                    f"and ki {controller['ki']:g}, [simulation] drive_time_constant {tau:g} and "
                    f"{a.counts_per_unit:.4g} counts per {a.unit} (least_in_position_timeout) + a tick; a larger "
                    f"in_position_window, with standstill_tolerance, or a smaller ki shortens it), got "
                    f"{safety['in_position_timeout']:g}")
        most = greatest_drive_offset(a.max_acceleration, factor)
        if offset > most:
            return ("simulation.max_drive_offset",
                    f"expected at most {most:.4g} deg/s or mm/s for {a.name} ({SERVO_STEP_SHARE:g} x [safety] "
                    f"acceleration_factor {factor:g} x its max_acceleration {a.max_acceleration:g} / servo.kp at "
                    f"most {KP_MAX:g}: the servo holding a drive that drifts faster changes its command beyond the "
                    f"safety's acceleration check), got {offset:g}")
    return None


def markdown(sections=None) -> str:
    """The table of parameters (all, or those of ``sections``) for the documentation."""
    def cell(text: str) -> str:
        return str(text).replace("|", "\\|")

    lines = ["| parameter | allowed | default | safety | changes by | meaning |", "|---|---|---|---|---|---|"]
    for p in PARAMS:
        if sections is not None and (p.section not in sections
                                     or (p.section in COMPONENTS and p.change == "specification")):
            continue
        where = f"`{p.key}`" + (f" (from `[{p.spec_key.split('.')[0]}] {p.spec_key.split('.')[1]}`)"
                                if p.spec_key else "")
        default = describe(p.default, 80) if not isinstance(p.default, str) else f'"{p.default}"'
        if p.kind == "pose":
            default = "the identity"
        elif p.default is None:
            default = "none" if p.kind == "coupling" else "required"
        lines.append(f"| {where} | {cell(p.allowed())} | {cell(default)} | {'yes' if p.safety else ''} "
                     f"| {p.change} | {cell(p.doc)} |")
    return "\n".join(lines) + "\n"
