"""Safety Supervisor: the last word before the drives, every 1 ms, in every phase.

It sits between the servo (``out_vel``) and the robot interface (``drive_cmd``), and
trusts neither the planner, nor the servo law, nor the operator, nor the configuration
(see docs/safety.md). Every tick, with the drives powered and the brakes not holding:

* **commanded velocity** of every axis within ``max_velocity x velocity_limit_scale``
  (before an axis is referenced by homing: within ``homing_velocity_factor x
  search_velocity``);
* **commanded acceleration**: the command may change by at most ``acceleration_factor
  x max_acceleration x tick`` from one tick to the next;
* **software position limits** (referenced axes): where the axis would come to rest if a
  stop began now (``x + v reaction_time + v |v| / (2 max_acceleration)``) must lie within
  ``min - limit_tolerance .. max + limit_tolerance``, so the robot stops *before* a limit;
* **encoder plausibility**: an axis commanded ``plausibility_distance`` of recent travel
  (remembered for about ``plausibility_time``) without a single encoder count, or one whose
  encoder runs the other way over a window;
* **command watchdog**: no fresh command from the servo for two ticks;
* **following error** beyond the servo's limit (which is never off: at most 10);
* **standstill** while the robot must be at rest (held by a program, paused, brakes
  closing): each axis must come *into position* (within ``in_position_window`` counts of
  the servo's reference for ``in_position_time``, and no sooner than the servo may need to
  settle it: :func:`compiler.params.settle_time`) within ``in_position_timeout`` of the
  reference coming to rest; from then on that reference is fixed and the axis may not move
  more than ``standstill_tolerance`` counts from it;
* **stops on the path** (pause, abort) that do not reach rest within their planned time
  plus ``stop_time_margin``;
* in operating mode **T1** (manual reduced speed, :class:`ReducedSpeedMonitor`): the flange
  and the tool centre point of every 1 ms reference of the servo at most ``t1_speed``
  (250 mm/s), and every axis's commanded velocity at most ``t1_velocity_factor x
  max_velocity`` (its velocity limit in T1).

A violation is a fault, never a silent clamp: the safety itself stops the robot, with
the category of :data:`CATEGORIES` (IEC 60204-1): 0, torque off and brakes at once; 1, its
own ramp of every axis's velocity command to zero at the axis's max_acceleration, then
brakes, then torque off. A stop of any other origin (an emergency stop, a component's
fault, an abort) goes through :meth:`SafetySupervisor.stop_robot` too. The ramp needs neither
the planner nor the servo nor the encoders.

Real-time: :meth:`update` and :meth:`stop_robot` (plain floats, one tuple per tick; the per-axis
checks are :func:`runtime.kernels.safety_check` and, at rest, :func:`runtime.kernels.standstill_check`);
the rest runs between cycles.
"""
from __future__ import annotations

import math

from compiler.params import settle_time
from compiler.zones import forbidden

from runtime.accel import kernels
from runtime.loop.component import Component, DataPort
from runtime.motion.kinematics import Kinematics
from runtime.motion.reduced import point_speed
from runtime.settings import Settings
from runtime.timing import BRAKE_TIMEOUT, TICK

safety_check = kernels.safety_check
direction_check = kernels.direction_check
standstill_check = kernels.standstill_check

_D2R = math.pi / 180.0

#: Ticks without a fresh servo command before the robot stops (the command watchdog).
WATCHDOG_TICKS = 2
#: Ticks of the encoder-direction window.
DIRECTION_WINDOW = 50

#: Stop categories (IEC 60204-1): what stops the robot how. One declaration; docs/safety.md
#: renders it (:func:`categories_markdown`).
CATEGORIES: dict[str, tuple[int, str]] = {
    "velocity": (1, "a commanded velocity beyond the axis's limit"),
    "acceleration": (1, "a commanded velocity that changes faster than the acceleration limit allows"),
    "position limit": (1, "an axis that would come to rest beyond its software limit"),
    "encoder": (0, "an encoder that does not count, or counts the wrong way, while its axis is commanded"),
    "standstill": (0, "an axis that moves from its standstill reference while the robot must be at rest"),
    "in position": (0, "an axis that does not come into position within [safety] in_position_timeout of the "
                       "servo's reference coming to rest"),
    "watchdog": (1, "no fresh command from the servo for two ticks"),
    "following error": (1, "the servo's following error beyond its limit"),
    "stop overdue": (1, "a stop on the path (pause, abort) that does not reach rest in time"),
    "drift": (0, "a drive that drifts beyond [safety] max_drive_drift under a zero command (calibration)"),
    "brakes": (0, "brakes that do not engage within runtime.timing.BRAKE_TIMEOUT of Stop Robot closing them"),
    "emergency stop": (1, "the operator's emergency stop (irl estop)"),
    "abort": (1, "the operator's abort: a stop on the path, then brakes"),
    "fault": (1, "any other fault: a component's (homing, deadline, report, program error), a time limit, "
                 "a shutdown"),
    "pause": (2, "the operator's pause or the program's: a stop on the path, drives powered, standstill "
                 "monitored"),
    "t1 speed": (1, "in operating mode T1: the flange or the tool centre point of a 1 ms reference faster than "
                    "[safety] t1_speed"),
    "zone": (1, "the flange or the tool centre point of a 1 ms reference inside a world zone ([[zone]] of the "
                "specification; every move is planned to keep 5 mm away: a backstop)"),
    "jog released": (2, "a jog's button released or its heartbeat lost: a stop on the path, drives powered"),
}

_KINDS = {kernels.OVER_VELOCITY: "velocity", kernels.OVER_ACCELERATION: "acceleration",
          kernels.OVER_LIMIT: "position limit", kernels.NO_COUNTS: "encoder", kernels.WRONG_WAY: "encoder",
          kernels.NOT_STILL: "standstill", kernels.NOT_IN_POSITION: "in position"}


#: What each stop category does (the module docstring; docs/safety.md).
CATEGORY_TEXT = {0: "torque off and brakes at once",
                 1: "every axis ramped to rest at its max_acceleration, then brakes, then torque off",
                 2: "a stop on the path, drives powered"}


def stop_text(category: int, cause: str) -> str:
    """A stop as the recording and the report's events file say it: its category, cause
    (a key of :data:`CATEGORIES`) and what it does."""
    return f"safety stop of category {category} ({cause}): {CATEGORY_TEXT.get(category, 'a stop')}"


def categories_markdown() -> str:
    lines = ["| cause | category | what |", "|---|---|---|"]
    for cause, (category, what) in CATEGORIES.items():
        lines.append(f"| {cause} | {category} | {what} |")
    return "\n".join(lines) + "\n"


class SafetyLimits:
    """The limits the safety derives from the specification and the robot's settings:
    each axis's speed (``max_velocity x robot.velocity_limit_scale``, or homing's before
    the axis is referenced), its change per tick, its software limits and stopping
    distance; and the servo's ``following_error_limit``, read from the settings every tick
    (the servo's own fault reads the same value)."""

    def __init__(self, spec, settings: Settings, tick: float):
        axes = spec.axes
        self.axes = axes
        self.tick = tick
        safety = spec.safety  # validated (compiler.params), every key present
        self.reaction = safety.stop_reaction_time
        self.tolerance = safety.limit_tolerance
        self.deceleration = tuple(a.max_acceleration for a in axes)
        self.braking = tuple(1.0 / (2.0 * a.max_acceleration) for a in axes)
        self.step_limits = tuple(safety.acceleration_factor * a.max_acceleration * tick for a in axes)
        self.homing_limits = tuple(safety.homing_velocity_factor * a.search_velocity for a in axes)
        self.referenced = [False] * len(axes)  # per axis: its encoder's zero is known (limits apply)
        self.servo_settings = settings.servo  # following_error_limit (the servo's; read every tick)
        self.t1_factor = spec.safety.t1_velocity_factor
        self.t1 = False
        self.scale = settings.robot.velocity_limit_scale
        self.set_velocity_limit_scale(self.scale)
        settings.watch("robot", "velocity_limit_scale", self.set_velocity_limit_scale)

    def set_velocity_limit_scale(self, scale: float) -> None:
        """Not real-time (told by the settings): robot.velocity_limit_scale changed."""
        self.scale = scale
        if self.t1:
            scale = min(scale, self.t1_factor)
        self.velocity_limits = tuple(a.max_velocity * scale for a in self.axes)
        self.refresh()

    def set_t1(self, t1: bool) -> None:
        """Not real-time (between cycles): operating mode T1 (each axis's velocity limit is
        then its reduced speed) or not."""
        self.t1 = t1
        self.set_velocity_limit_scale(self.scale)

    def set_referenced(self, axis: int | None, referenced: bool = True) -> None:
        """Real-time safe: ``axis`` (None: every axis) is referenced (its limits apply and
        it may move at full speed) or not."""
        for i in range(len(self.axes)) if axis is None else (axis,):
            self.referenced[i] = referenced
        self.refresh()

    def refresh(self) -> None:
        inf = math.inf
        lows, highs, speeds = [], [], []
        for i, a in enumerate(self.axes):
            if self.referenced[i]:
                lows.append(a.min - self.tolerance)
                highs.append(a.max + self.tolerance)
                speeds.append(self.velocity_limits[i])
            else:
                lows.append(-inf)
                highs.append(inf)
                speeds.append(min(self.velocity_limits[i], self.homing_limits[i]))
        self.low, self.high, self.speed_limits = tuple(lows), tuple(highs), tuple(speeds)

    def describe(self, kind: int, i: int, command, previous, x: float) -> str:
        """Real-time safe: what the violation ``kind`` of axis ``i`` is (a velocity, an
        acceleration or a position limit), ``x`` its position."""
        a = self.axes[i]
        unit = a.unit
        if kind == kernels.OVER_VELOCITY:
            why = "velocity_limit_scale" if self.referenced[i] else "not referenced yet: homing speed"
            return (f"{a.name} commanded at {command[i]:.3f} {unit}/s, beyond its limit {self.speed_limits[i]:g} "
                    f"{unit}/s ({why})")
        if kind == kernels.OVER_ACCELERATION:
            change = (command[i] - previous[i]) / self.tick
            return (f"{a.name} command changes at {change:.0f} {unit}/s^2, beyond "
                    f"{self.step_limits[i] / self.tick:g} {unit}/s^2 ([safety] acceleration_factor x "
                    "max_acceleration)")
        rest = x + command[i] * self.reaction + command[i] * abs(command[i]) * self.braking[i]
        return (f"{a.name} at {x:.3f} {unit}, commanded at {command[i]:.3f} {unit}/s, would come to rest at "
                f"{rest:.3f} {unit}, beyond its software limits {a.min:g}..{a.max:g} {unit}")


class EncoderPlausibility:
    """The encoders watched against the commands: commanded travel without a single count
    (remembered for about ``plausibility_time``: it leaks away), and encoders that count
    against the commanded direction over a window of :data:`DIRECTION_WINDOW` ticks."""

    def __init__(self, spec, tick: float):
        self.axes = spec.axes
        self.plausible = tuple(spec.safety.plausibility_distance for _ in spec.axes)
        self.leak = 1.0 - tick / spec.safety.plausibility_time
        self.counts_per_unit = tuple(a.counts_per_unit for a in spec.axes)
        self.reset()

    def reset(self) -> None:
        """Not real-time: a new cycle."""
        n = len(self.axes)
        self.last_counts = [0] * n  # the counts of the last tick
        self.travel = [0.0] * n  # per axis: commanded travel since its last count (leaking)
        self.window = [0.0] * n  # per axis: commanded travel over the direction window
        self.window_counts = [0] * n  # the counts as the window began
        self.window_ticks = 0

    def arm(self, counts) -> None:
        """Real-time: the brakes have just released: watch from these counts on (the
        direction window runs on)."""
        self.last_counts[:] = counts
        self.window_counts[:] = counts
        for i in range(len(self.travel)):
            self.travel[i] = 0.0
            self.window[i] = 0.0

    def window_end(self, counts) -> int:
        """Real-time: the direction window (``window_ticks``, counted up by the guard every
        tick: no call per tick) is full: the check's code (0: every encoder counted the
        commanded way), and a new window."""
        self.window_ticks = 0
        return direction_check(self.window, counts, self.window_counts, self.counts_per_unit, self.plausible)

    def describe(self, kind: int, i: int) -> str:
        a = self.axes[i]
        if kind == kernels.NO_COUNTS:
            return (f"{a.name} commanded {self.travel[i]:+.3f} {a.unit} of travel without a single encoder count "
                    "(encoder frozen, drive not responding, or the axis blocked)")
        return f"the encoder of {a.name} counts against the commanded direction (encoder or drive wired wrong)"


class StandstillMonitor:
    """While the robot must be at rest (held by a program, paused, brakes closing): each
    axis must come into position (within ``in_position_window`` counts of the servo's
    reference for ``in_position_time``, not before its :attr:`settle_times`) within
    ``in_position_timeout`` of the reference coming to rest, and from then on stay within
    ``standstill_tolerance`` counts of that reference. And a stop on the path must reach
    rest within its planned time plus ``stop_time_margin``."""

    def __init__(self, spec, clock):
        safety = spec.safety
        self.axes = spec.axes
        self.clock = clock
        self.standstill_tolerance = safety.standstill_tolerance
        self.in_position_window = safety.in_position_window
        self.in_position_time = safety.in_position_time
        self.in_position_timeout = safety.in_position_timeout
        self.stop_time_margin = safety.stop_time_margin
        self.window, self.tolerance = float(self.in_position_window), float(self.standstill_tolerance)
        self.counts_per_unit = tuple(a.counts_per_unit for a in spec.axes)
        # per axis: how long after its reference comes to rest the servo may still swing it through the
        # window (compiler.params.settle_time): an axis is not in position before
        controller, lag = spec.controller, spec.simulation.drive_time_constant
        self.settle_times = tuple(settle_time(a, lag, controller.kp, controller.ki, self.in_position_window)
                                  for a in spec.axes)
        self.reset()

    def reset(self) -> None:
        n, nan = len(self.axes), math.nan
        self.expected = False  # someone who knows says the robot must be at rest
        self.position_deadline = nan  # the time every axis must be in position by (NaN: not at rest)
        self.reference_rest = nan  # the time the servo's reference came to rest
        self.since = [nan] * n  # per axis: within the window since (NaN: not within)
        self.fixed = [nan] * n  # per axis: its standstill reference (NaN: not in position yet)
        self.away = [0.0] * n  # per axis: counts from that reference (or the servo's), last tick
        self.rest_deadline: float | None = None  # a stop on the path must reach rest by then

    def check(self, now: float, positions, servo) -> int:
        """Real-time: the robot must be at rest: the check's code (0: every axis in
        position or on its way within the time)."""
        if self.position_deadline != self.position_deadline:  # rest has just begun: the servo's
            self.reference_rest = now + servo.setpoint_period  # reference stops a setpoint period later
            self.position_deadline = self.reference_rest + self.in_position_timeout
        segments, s, _ = servo.reference_segments
        return standstill_check(positions, segments, s, self.counts_per_unit, self.window, self.tolerance,
                                self.in_position_time, self.settle_times, self.reference_rest, now,
                                self.position_deadline, self.since, self.fixed, self.away)

    def not_at_rest(self) -> None:
        """Real-time: the robot may move again: every axis's in-position state is forgotten."""
        nan = math.nan
        self.position_deadline = nan
        for i in range(len(self.axes)):
            self.since[i] = nan
            self.fixed[i] = nan

    @property
    def in_position(self) -> tuple[bool, ...]:
        return tuple([f == f for f in self.fixed])

    def expect_standstill(self, expected: bool) -> None:
        if expected:
            self.rest_deadline = None
        self.expected = expected

    def expect_rest_within(self, seconds: float) -> None:
        deadline = self.clock.tick_time + seconds + self.stop_time_margin
        if self.rest_deadline is None or deadline < self.rest_deadline:
            self.rest_deadline = deadline

    def describe(self, kind: int, i: int) -> str:
        a = self.axes[i]
        away = self.away[i]
        if kind == kernels.NOT_STILL:
            return (f"{a.name} moved {abs(away):.0f} encoder counts from the reference it came into position "
                    f"at, while the robot must be at rest (allowed: {self.standstill_tolerance})")
        within = abs(away) <= self.in_position_window
        return (f"{a.name} not in position {self.in_position_timeout:g} s after its reference came to rest: "
                f"{away:+.0f} encoder counts ({away / a.counts_per_unit:+.4f} {a.unit}) from the servo's reference"
                f"{', within the window for less than in_position_time' if within else ''} (in position: within "
                f"{self.in_position_window} counts for {self.in_position_time:g} s; [safety] in_position_window, "
                f"in_position_time, in_position_timeout)")


class ZoneMonitor:
    """The world zones (compiler.zones): the flange and the tool centre point (of the tool
    ``tool_of()`` gives: the move's) of every 1 ms reference of the servo outside each,
    once every main axis is referenced. The planners keep every move
    :data:`compiler.zones.MARGIN` away, so this is the backstop of what no plan covers.

    Real-time: :meth:`check`, plain floats, nothing without zones. A tick whose reference
    cannot have brought either point to a zone is not computed: no point moves further
    than the joints' motion (rad) times the longest lever any axis has on it (``lever``:
    every link's length plus the tool's), so while the sum of the axes' motion since the
    last computed tick, times that lever, is less than the points' clearance then, both
    are still outside. Far from the zones, or at rest, that is most ticks."""

    def __init__(self, spec, limits: "SafetyLimits"):
        self.spec = spec
        self.main = len(spec.main_axes)
        self.limits = limits
        self.kinematics: Kinematics | None = None
        self.zones: tuple = ()
        self.use(forbidden(spec.zones))
        self.links = sum(math.hypot(a.dh.a, a.dh.d) for a in spec.main_axes if a.dh is not None)
        self.default_tool = tuple(float(v) for v in spec.tool[:3])
        self.tool_of = None  # () -> the move's tool, set by the system
        self.forget()

    def use(self, zones: tuple) -> None:
        """Not real-time (between cycles): the forbidden zones to keep the robot out of (the
        specification's, and a program's own: compiler.zones); none without kinematics."""
        if zones and self.kinematics is None:
            try:
                self.kinematics = Kinematics(self.spec)
            except ValueError:
                zones = ()
        self.zones = tuple(zones)
        self.forget()

    def forget(self) -> None:
        """Real-time safe: the next reference is computed (a new cycle, a jump)."""
        self.last: tuple | None = None  # the joints (deg) of the last computed reference
        self.last_tool: tuple | None = None
        self.clearance = 0.0  # how far both points were from every zone then (mm)

    def check(self, reference) -> str | None:
        """Real-time: why the reference is inside a zone, or None."""
        if not self.zones or not all(self.limits.referenced[:self.main]):
            return None
        tool = self.tool_of()[:3] if self.tool_of is not None else self.default_tool
        q = reference[:self.main]
        last = self.last
        if last is not None and tool == self.last_tool:
            moved = 0.0
            for a, b in zip(q, last):
                moved += abs(a - b)
            lever = self.links + math.sqrt(tool[0] * tool[0] + tool[1] * tool[1] + tool[2] * tool[2])
            if moved * _D2R * lever < self.clearance:
                return None
        flange, tcp = self.kinematics.flange_and_tcp(q, tool)
        clearance = math.inf
        for zone in self.zones:
            for name, (x, y, z) in (("the tool centre point", tcp), ("the flange", flange)):
                depth = zone.depth(x, y, z)
                if depth > 0.0:
                    self.last = None
                    return (f"{name} entered zone '{zone.name}' ({depth:.1f} mm inside it, at ({x:.1f}, {y:.1f}, "
                            f"{z:.1f}))")
                if -depth < clearance:
                    clearance = -depth
        self.last, self.last_tool, self.clearance = tuple(q), tool, clearance
        return None


class ReducedSpeedMonitor:
    """Operating mode T1: the flange and the tool centre point (of the tool ``tool_of()``
    gives: the move's) of every 1 ms reference of the servo at most ``[safety] t1_speed``;
    a prismatic additional axis (a track) adds its own speed. Off in AUT. Real-time:
    :meth:`check` (one flange frame per tick, plain floats)."""

    def __init__(self, spec, tick: float):
        self.limit = spec.safety.t1_speed
        self.tick = tick
        self.main = len(spec.main_axes)
        try:
            self.kinematics: Kinematics | None = Kinematics(spec)
        except ValueError:
            self.kinematics = None
        self.tracks = tuple(i for i, a in enumerate(spec.axes) if i >= self.main and a.kind == "prismatic")
        self.default_tool = tuple(float(v) for v in spec.tool[:3])
        self.tool_of = None  # () -> the move's tool (x, y, z, roll, pitch, yaw in the flange), set by the system
        self.on = False
        self.epoch = -1
        self.peak = 0.0  # the largest speed seen since the mode was set (mm/s)
        self.speed = 0.0  # the last tick's
        self.forget()

    def forget(self) -> None:
        """Real-time safe: the next reference is the first (the reference jumped: an
        encoder reset by homing, a new cycle)."""
        self.last = None
        self.last_tool = None
        self.last_tracks = None

    def check(self, reference, epoch: int) -> float:
        """Real-time: the speed (mm/s) of this reference against the last one (``epoch``: the
        servo's count of the times its reference started anew, from where the robot is: a
        new baseline then, as after :meth:`forget`)."""
        kinematics = self.kinematics
        if kinematics is None:
            return 0.0
        if epoch != self.epoch:
            self.epoch = epoch
            self.forget()
        columns = kinematics.flange_columns(reference[:self.main])
        tool = self.tool_of()[:3] if self.tool_of is not None else self.default_tool
        tracks = tuple([reference[i] for i in self.tracks]) if self.tracks else ()
        last, self.last = self.last, columns
        last_tool, self.last_tool = self.last_tool, tool
        last_tracks, self.last_tracks = self.last_tracks, tracks
        if last is None or last_tool != tool:  # a tool changed (at rest): a new baseline
            return 0.0
        speed = point_speed(last, columns, tool, self.tick)
        for a, b in zip(last_tracks, tracks):
            speed += abs(b - a) / self.tick
        self.speed = speed
        if speed > self.peak:
            self.peak = speed
        return speed


class StopRamp:
    """The safety's own stop (IEC 60204-1): category 1 ramps every axis's command from the
    last one passed to the drives to zero at the axis's max_acceleration, then applies the
    brakes, then takes the torque off (after :data:`runtime.timing.BRAKE_TIMEOUT` at most);
    category 0 does both at once. Needs neither the planner nor the servo nor the encoders."""

    def __init__(self, spec, robot, drive_cmd: DataPort, tick: float):
        self.robot, self.drive_cmd, self.tick = robot, drive_cmd, tick
        self.deceleration = tuple(a.max_acceleration for a in spec.axes)
        self.zeros = (0.0,) * len(spec.axes)
        self.reset()

    def reset(self) -> None:
        self.category: int | None = None  # the stop under way (None: none)
        self.reason: str | None = None
        self.at_rest = False  # the stop has ended: brakes applied, torque off
        self.ramp_from = self.zeros
        self.ramp_t = 0.0
        self.ramp_end = 0.0
        self.phase = ""
        self.since = 0.0  # when the phase began

    def start(self, category: int, reason: str, now: float, previous) -> bool:
        """Real-time safe: begin (or make stricter) a stop from the command ``previous``;
        False if a stop at least as strict is under way."""
        if self.category is not None and self.category <= category:
            return False
        if self.category is None:
            self.reason = reason
        self.category = category
        self.at_rest = False
        self.since = now
        if category == 0:
            self.robot.disable_drives()
            self.robot.apply_brakes()
            self.phase = "brakes"
            self.drive_cmd.write(self.zeros, now)
            return True
        self.ramp_from = previous
        self.ramp_t = 0.0
        self.ramp_end = max((abs(v) / a for v, a in zip(previous, self.deceleration)), default=0.0)
        self.phase = "ramp"
        return True

    def step(self, now: float) -> None:
        """Real-time: one tick of the stop under way."""
        phase = self.phase
        robot = self.robot
        if phase == "ramp":
            self.ramp_t += self.tick
            t = self.ramp_t
            command = tuple([v - a * t if v > a * t else v + a * t if v < -a * t else 0.0
                             for v, a in zip(self.ramp_from, self.deceleration)])
            self.drive_cmd.write(command, now)
            if t >= self.ramp_end:
                robot.apply_brakes()
                self.phase = "brakes"
                self.since = now
            return
        self.drive_cmd.write(self.zeros, now)
        if phase == "brakes":
            if robot.brakes_applied() or now - self.since > BRAKE_TIMEOUT:
                robot.disable_drives()
                self.phase = "done"
                self.at_rest = True


class SafetySupervisor(Component):
    """The guard every tick: the command watchdog, and the checks of :class:`SafetyLimits`,
    :class:`EncoderPlausibility` and :class:`StandstillMonitor` on the servo's command
    before it goes to the drives; a violation is a stop by :class:`StopRamp`."""

    PROPERTIES: dict = {}
    OPERATIONS: tuple[str, ...] = ()

    def __init__(self, spec, robot, servo, out_vel: DataPort, drive_cmd: DataPort, clock, tick: float = TICK,
                 settings: Settings | None = None):
        settings = settings if settings is not None else Settings(spec)
        super().__init__("safety", tick, settings)
        self.spec, self.robot, self.servo = spec, robot, servo
        self.out_vel, self.drive_cmd = out_vel, drive_cmd
        self.clock = clock
        self.tick = tick
        self.axes = spec.axes
        self.limits = SafetyLimits(spec, settings, tick)
        self.encoders = EncoderPlausibility(spec, tick)
        self.standstill = StandstillMonitor(spec, clock)
        self.reduced = ReducedSpeedMonitor(spec, tick)
        self.zones = ZoneMonitor(spec, self.limits)
        self.ramp = StopRamp(spec, robot, drive_cmd, tick)
        self._zeros = (0.0,) * len(spec.axes)
        self.fault: str | None = None
        self.reset()

    # -- set-up (not real-time) --
    def set_referenced(self, axis: int | None, referenced: bool = True) -> None:
        """Real-time safe: ``axis`` (None: every axis) is referenced (its limits apply and
        it may move at full speed) or not (its reference jumps: the T1 check starts anew)."""
        self.limits.set_referenced(axis, referenced)
        self.reduced.forget()
        self.zones.forget()

    def use_tool_of(self, tool_of) -> None:
        """Not real-time: ``tool_of()`` gives the tool of the move under way (x, y, z, roll,
        pitch, yaw in the flange), for the T1 speed check and the zones."""
        self.reduced.tool_of = self.zones.tool_of = tool_of

    def set_t1(self, t1: bool) -> None:
        """Not real-time (between cycles): operating mode T1 (checked every tick) or AUT."""
        self.reduced.on = t1
        self.reduced.peak = 0.0
        self.reduced.forget()
        self.limits.set_t1(t1)

    def reset(self) -> None:
        """Not real-time: a new cycle (the drives are enabled again by Start Robot)."""
        self.fault = None
        self.stops: list[tuple[float, int, str]] = []  # (time, category, cause) of each stop begun or made stricter
        self.ramp.reset()
        self.reduced.forget()
        self.zones.forget()
        self.reduced.peak = 0.0
        self.encoders.reset()
        self.standstill.reset()
        self.previous = self._zeros  # the last command passed to the drives
        self._writes = -1
        self._stale = 0
        self._armed = False  # the drives may move (brakes released or releasing); checks run

    def on_start(self) -> bool:
        self.reset()
        return True

    # -- what the supervisor and the tests read --
    @property
    def category(self) -> int | None:
        """The stop under way (None: none)."""
        return self.ramp.category

    @property
    def stop_reason(self) -> str | None:
        return self.ramp.reason

    @property
    def at_rest(self) -> bool:
        """The stop has ended: brakes applied, torque off."""
        return self.ramp.at_rest

    @property
    def stopping(self) -> bool:
        return self.ramp.category is not None

    @property
    def standstill_expected(self) -> bool:
        return self.standstill.expected

    @property
    def in_position(self) -> tuple[bool, ...]:
        """Per axis: in position, its standstill monitored against a fixed reference."""
        return self.standstill.in_position

    # -- the 1 ms guard (real-time) --
    def update(self, now: float) -> None:
        """Real-time (guard): check the servo's command and pass it to the drives, or
        carry out a stop."""
        ramp = self.ramp
        if ramp.category is not None:
            ramp.step(now)
            return
        robot = self.robot
        if not robot.brakes_released():  # the brakes hold: nothing can move
            self._armed = False
            self.drive_cmd.write(self._zeros, now)
            self.previous = self._zeros
            return
        port = self.out_vel
        counts = robot.counts
        encoders = self.encoders
        if not self._armed:  # the brakes have just released: start watching from here
            self._armed = True
            self._writes = port.writes
            encoders.arm(counts)
        limits = self.limits
        if port.writes == self._writes:
            self._stale += 1
            if self._stale >= WATCHDOG_TICKS:
                self._violation("watchdog", f"no fresh command from the servo for {self._stale} ms "
                                            "while the brakes are released (the servo stopped or stalled)", now)
                return
            command = self.previous  # one tick late: repeat the last command (checked before)
        else:
            self._stale = 0
            self._writes = port.writes
            command = port.value
            code = safety_check(command, self.previous, limits.speed_limits, limits.step_limits, robot.positions,
                                limits.low, limits.high, limits.reaction, limits.braking, counts,
                                encoders.last_counts, encoders.travel, encoders.window, encoders.plausible,
                                self.tick, encoders.leak)
            if code:
                self._axis_violation(code, command, now)
                return
        encoders.window_ticks += 1
        if encoders.window_ticks >= DIRECTION_WINDOW:
            code = encoders.window_end(counts)
            if code:
                self._axis_violation(code, command, now)
                return
        reduced = self.reduced
        if reduced.on and reduced.check(self.servo.reference, self.servo.epoch) > reduced.limit:
            self._violation("t1 speed", f"in T1 the flange or the tool centre point moved at {reduced.speed:.1f} "
                                        f"mm/s, beyond [safety] t1_speed {reduced.limit:g} mm/s", now)
            return
        zones = self.zones
        if zones.zones:
            inside = zones.check(self.servo.reference)
            if inside is not None:
                self._violation("zone", inside, now)
                return
        limit = limits.servo_settings.following_error_limit
        if self.servo.worst_error > limit:
            self._violation("following error", f"following error {self.servo.worst_error:.3f} beyond the limit "
                                                f"{limit:g} (the servo did not stop)", now)
            return
        standstill = self.standstill
        if standstill.expected:
            code = standstill.check(now, robot.positions, self.servo)
            if code:
                self._axis_violation(code, command, now)
                return
        elif standstill.position_deadline == standstill.position_deadline:
            standstill.not_at_rest()
        if standstill.rest_deadline is not None and now > standstill.rest_deadline:
            self._violation("stop overdue", "the stop on the path did not reach rest within its planned time "
                                            f"and {standstill.stop_time_margin:g} s", now)
            return
        self.previous = command
        self.drive_cmd.write(command, now)

    def expect_standstill(self, expected: bool) -> None:
        """Real-time safe: the robot must (or may no longer) be at rest (see
        :class:`StandstillMonitor`). Reaching rest also ends a :meth:`expect_rest_within`."""
        self.standstill.expect_standstill(expected)

    def expect_rest_within(self, seconds: float) -> None:
        """Real-time safe: a stop on the path began; it must reach rest (see
        :meth:`expect_standstill`) within ``seconds`` plus ``stop_time_margin``."""
        self.standstill.expect_rest_within(seconds)

    def rest_not_expected(self) -> None:
        """Real-time safe: the stop on the path was called off before it reached rest (a
        resume): its deadline no longer applies."""
        self.standstill.rest_deadline = None

    # -- violations and stops (real-time) --
    def _axis_violation(self, code: int, command, now: float) -> None:
        kind, i = divmod(code, 256)
        if kind in (kernels.OVER_VELOCITY, kernels.OVER_ACCELERATION, kernels.OVER_LIMIT):
            text = self.limits.describe(kind, i, command, self.previous, self.robot.positions[i])
        elif kind in (kernels.NO_COUNTS, kernels.WRONG_WAY):
            text = self.encoders.describe(kind, i)
        else:
            text = self.standstill.describe(kind, i)
        self._violation(_KINDS[kind], text, now)

    def _violation(self, cause: str, text: str, now: float) -> None:
        self.fault = f"safety: {text} (stop category {CATEGORIES[cause][0]})"
        self.stop_robot(cause, self.fault, now)

    def stop_robot(self, cause: str, reason: str, now: float | None = None) -> None:
        """Real-time safe: stop the robot now for ``cause`` (a key of :data:`CATEGORIES`),
        by its category (0 or 1; a stop already under way only ever gets stricter): see
        :class:`StopRamp`."""
        now = self.clock.tick_time if now is None else now
        category = CATEGORIES[cause][0]
        if self.ramp.start(category, reason, now, self.previous):
            self.stops.append((now, category, cause))  # (the recording's and the events file's stop)
            if category == 0:
                self.previous = self._zeros
