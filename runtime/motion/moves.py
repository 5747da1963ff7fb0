"""Moves: what a program hands over (:class:`MoveRequest`), how one is planned into a
trajectory (:class:`MovePlanner`), and what the timeline holds (:class:`Segment`,
:class:`MoveRecord`).

:meth:`MovePlanner.plan` is pure (it reads the robot's axes, kinematics and the
previous segment's plan, and changes nothing), so it may run on the planning worker:

* ``ptp`` -- to a joint value, to a pose (the inverse kinematics' configuration nearest
  the start, or the one the pose names: its groups and turns, compiler.configs), or to the positions of every axis (the rest of an interrupted move), with
  the axes' limits times the move's ``speed_ptp`` / ``acc_ptp`` (and the jerk limits
  times ``acc_ptp`` for the jerk-limited profile): :func:`runtime.motion.jerk.plan_ptp_jerk`
  or :func:`runtime.motion.planner.plan_ptp`;
* ``lin`` / ``circ`` -- to poses (joint values are turned into poses by the forward
  kinematics): :func:`runtime.motion.cartesian.plan_cartesian`, timed within every
  joint's limits; a target (or via pose) that names another configuration than the one
  the move starts in is refused before it, and one that names turns must end in them;
* a move after one with ``approx`` gets its blend offset
  (:func:`runtime.motion.blend.blend_offset`), checked within every axis's limits.

A move that cannot be planned gives ``(None, problem)``: the problem says what and why,
and the program stops at the move's line.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

from compiler.clauses import Motion
from compiler.configs import TURN_AXES, format_config, group_problem, in_turn, turn_of
from compiler.frames import IDENTITY
from compiler.triggers import PLACES, UNITS
from compiler.values import Joint, Pose

from runtime.motion.blend import Limits, blend_offset
from runtime.motion.cartesian import CartesianInput, plan_cartesian
from runtime.motion.jerk import plan_ptp_jerk
from runtime.motion.kinematics import Kinematics, KinematicsError, configuration_name
from runtime.motion.pathcheck import JointLimits
from runtime.motion.planner import PtpInput, plan_ptp, scaled_limits
from runtime.motion.reduced import Reduced, cartesian_peak, path_speed
from runtime.motion.trajectory import Refusal, Trajectory
from runtime.motion.zonecheck import zone_problem

__all__ = ["CACHE_SIZE", "Frames", "MovePlanner", "MoveRecord", "MoveRequest", "Segment"]

#: The most moves and blends :attr:`MovePlanner.cache` keeps (the oldest goes first).
CACHE_SIZE = 1024


class Frames(NamedTuple):
    """The base and tool a move was handed with (``use base``, ``use tool``;
    compiler.frames): each one's name and its x, y, z (mm), roll, pitch, yaw (deg), the
    base in the world frame, the tool in the flange frame. The move's pose targets are
    already in the world frame; the tool is the TCP its path and targets are of."""

    base_name: str
    base: tuple
    tool_name: str
    tool: tuple

    @classmethod
    def default(cls, spec) -> "Frames":
        """What a program starts with: the world frame and the specification's tool."""
        return cls("world", IDENTITY, "default_tool", tuple(float(v) for v in spec.tool))

    def using(self, keyword: str, name: str, values: tuple) -> "Frames":
        """These frames with ``keyword``'s (``"base"`` or ``"tool"``) replaced."""
        if keyword == "base":
            return self._replace(base_name=name, base=values)
        return self._replace(tool_name=name, tool=values)


@dataclass
class MoveRecord:
    """A move as it ran, for the run's summary: its line, kind and target, its planned
    duration (at the override of its start) and when its first and last setpoints were."""

    line: int
    kind: str
    target: tuple
    planned_duration: float
    t_start: float
    t_end: float | None = None
    blended: bool = False  # the move blended into the next one (it did not stop at its target)
    frames: Frames | None = None  # its base and tool (None: the specification's tool in the world frame)
    approach: bool = False  # the approach of a start from a line (runtime.loop.stepping), not a program's move

    @property
    def actual_duration(self) -> float | None:
        return None if self.t_end is None else self.t_end - self.t_start


class MoveRequest:
    """A move the program handed over, not planned yet: ``kind`` (a
    :class:`compiler.clauses.Motion`), ``targets`` (one target; a circ move's via pose first), ``speed`` and
    ``acc`` (fractions for ptp, mm/s and mm/s^2 for lin/circ), ``approx``, the source
    ``line``; ``rest_of``: the interrupted segment whose rest this is (planned from where
    it stopped); ``frames``: its base and tool (:class:`Frames`; None: the
    specification's tool; its pose targets are in the world frame either way);
    ``approach``: the approach of a start from a line (runtime.loop.stepping), which is
    not one of the program's moves (its record says so)."""

    __slots__ = ("kind", "targets", "speed", "acc", "approx", "line", "rest_of", "frames", "triggers", "carried",
                 "approach", "tag")

    def __init__(self, kind: str, targets: tuple, speed: float, acc: float, approx: float, line: int,
                 rest_of: "Segment | None" = None, frames: Frames | None = None, triggers: tuple = (),
                 approach: bool = False, tag: int | None = None):
        self.kind, self.targets, self.speed, self.acc, self.approx, self.line = kind, targets, speed, acc, approx, line
        self.tag = tag  # the program's name for it (runtime.loop.vm: a failure found later is reported with it)
        self.rest_of = rest_of
        self.frames = frames
        self.approach = approach
        self.triggers = triggers  # (place, unit, amount, action) each: compiler.triggers
        self.carried: tuple = ()  # the triggers not reached when it was stopped on its path: the rest's

    def __repr__(self) -> str:
        return (f"MoveRequest({self.kind!r}, {self.targets!r}, {self.speed!r}, {self.acc!r}, {self.approx!r}, "
                f"{self.line!r})")


class Segment:
    """A planned move on the timeline: ``trajectory`` from the previous move's end to
    ``end``; ``offset``: when it starts after the previous segment's start if it is
    blended into it (None: after the previous one has stopped); ``start``: its start on
    the timeline once scheduled."""

    __slots__ = ("request", "trajectory", "duration", "end", "limits", "offset", "start", "record",
                 "blendable", "previous", "stop", "triggers")

    def __init__(self, request: MoveRequest, trajectory: Trajectory, end, limits: Limits):
        self.request = request
        self.trajectory = trajectory
        self.duration = trajectory.duration
        self.end = tuple(end)
        self.limits = limits
        self.offset: float | None = None
        self.start: float | None = None
        self.record: MoveRecord | None = None
        self.blendable = True  # cleared when the move is interrupted (its blend is off)
        self.previous: Segment | None = None  # the segment it was planned after (its blend partner)
        self.stop: Trajectory | None = None  # the controlled stop that interrupted it
        self.triggers: list = []  # (time after its start, action, trigger) of its triggers, in time order

    @property
    def kind(self) -> str:
        return self.request.kind


def place_triggers(segment: Segment) -> str | None:
    """Each of the move's triggers (compiler.triggers) as a time of its own trajectory
    (``segment.triggers``), or the problem (a distance beyond its path)."""
    trajectory, duration = segment.trajectory, segment.duration
    rest = segment.request.rest_of is not None  # carried over a stop: a place passed fires as the rest starts
    placed = []
    for trigger in segment.request.triggers:
        place, unit, amount, action = trigger
        words, name = PLACES[place].words, UNITS[unit].name
        if name == "mm":
            length = trajectory.tool_path_length()
            if length is None:  # (the checker allows mm for lin and circ only)
                return f"a trigger in mm is for lin and circ moves, not {segment.kind}"
            if amount > length + 1e-9 and not rest:
                return (f"trigger when {amount:.10g} mm {words}: the tool's path of this move is only {length:.10g} mm "
                        "long")
            amount = min(amount, length)
            at = trajectory.path_time(amount, words == "before end")
            t = duration - at if words == "before end" else at
        else:
            seconds = amount / 1000.0
            if words != "after end" and seconds > duration + 1e-9 and not rest:
                return f"trigger when {amount:.10g} ms {words}: the move takes only {duration * 1000.0:.10g} ms"
            t = seconds if words == "after start" else duration - seconds if words == "before end" \
                else duration + seconds
        placed.append((min(max(t, 0.0), duration) if words != "after end" else t, action, trigger))
    placed.sort(key=lambda x: x[0])
    segment.triggers = placed
    return None


class _Blended:
    """Two segments blended (the second ``offset`` s after the first starts), over their
    overlap, as a trajectory (``position_at``, ``duration``) for the zone check."""

    def __init__(self, first: Segment, second: Segment, offset: float):
        self.first, self.second, self.offset = first.trajectory, second.trajectory, offset
        self.corner = first.end
        self.duration = max(first.duration - offset, 0.0)

    def position_at(self, t: float) -> tuple:
        a = self.first.position_at(self.offset + t)
        b = self.second.position_at(t)
        return tuple([x + y - c for x, y, c in zip(a, b, self.corner)])


class MovePlanner:
    """Plans requests for one robot: its ``axes`` (the specification's, with ``min``,
    ``max``, ``unit``, ``name``, ``max_velocity``, ``max_acceleration``, ``max_jerk``), its
    ``main_axes`` (the arm's six, first; the rest are additional axes, held by lin/circ
    moves), the PTP ``profile`` (``"jerk"`` or ``"trapezoid"``), and the arm's
    ``kinematics`` (None: poses cannot be used, and ``kinematics_problem`` says why) and
    the world ``zones`` every move and blend keeps away from (compiler.zones)."""

    def __init__(self, axes, main_axes, profile: str, kinematics: Kinematics | None,
                 kinematics_problem: str | None = None, zones: tuple = ()):
        self.axes = tuple(axes)
        self.main_axes = tuple(main_axes)
        self.main = len(self.main_axes)
        self.joint_limits = JointLimits.of(self.main_axes)  # what a lin/circ move is timed and checked within
        self.profile = profile
        self.kinematics = kinematics
        self.kinematics_problem = kinematics_problem
        self.zones = tuple(zones) if kinematics is not None else ()
        self._tools: dict[tuple, Kinematics] = {}  # the arm with other tools (use tool), the latest 16
        jerk = profile == "jerk"
        # what a blend must keep: every axis's limits (no jerk limit for a trapezoid)
        self.limits = Limits((a.max_velocity for a in self.axes), (a.max_acceleration for a in self.axes),
                             (a.max_jerk if jerk else float("inf") for a in self.axes))
        self.cartesian_limits = Limits(self.limits.velocity, self.limits.acceleration,
                                       (a.max_jerk for a in self.axes))
        #: the moves planned so far, by what they are and where they start (None: none kept,
        #: as on the robot); an offline run keeps them, since a program's cycle repeats them
        self.cache: dict | None = None
        #: operating mode T1's limits (runtime.motion.reduced), or None (AUT): set between programs
        self.reduced: Reduced | None = None

    def plan(self, request: MoveRequest, start: tuple, previous: Segment | None,
             period: float) -> tuple[Segment | None, str | None]:
        """Plan ``request`` from the joints ``start`` (blended after ``previous`` when
        that one has ``approx``), for setpoints every ``period`` s: ``(segment, None)`` or
        ``(None, problem)``. Pure: safe on the planning worker."""
        segment, problem = self._planned(request, start, period)
        if segment is None:
            return None, problem
        if request.triggers:
            problem = place_triggers(segment)
            if problem is not None:
                return None, problem
        if previous is not None and previous.request.approx > 0.0 and previous.blendable and self.reduced is None:
            overlap_before = (previous.previous.duration - previous.offset
                              if previous.offset is not None and previous.previous is not None else 0.0)
            cap = previous.duration - overlap_before
            segment.offset = self._blend(previous, segment, period, cap)
            segment.previous = previous
        return segment, None

    def _blend(self, previous: Segment, segment: Segment, period: float, cap: float) -> float | None:
        """The blend offset of ``segment`` after ``previous`` (blend_offset), from ``cache``
        when it holds the same two trajectories blended the same way."""
        key = None
        if self.cache is not None:
            key = ("blend", previous.trajectory, previous.kind, previous.request.approx, segment.kind,
                   segment.trajectory, previous.end, previous.limits, segment.limits, period, cap)
            if key in self.cache:
                return self.cache[key]
        offset = blend_offset(previous.kind, previous.trajectory, previous.request.approx, segment.kind,
                              segment.trajectory, previous.end, previous.limits.union(segment.limits), period, cap)
        if offset is not None and self.zones and zone_problem(
                self.kinematics, _Blended(previous, segment, offset), self._tool_point(segment.request.frames),
                self.zones) is not None:
            offset = None  # (a blend that would come near a zone: the robot stops at the corner)
        if key is not None:
            self._keep(key, offset)
        return offset

    def _keep(self, key: tuple, value) -> None:
        cache = self.cache
        if len(cache) >= CACHE_SIZE:
            cache.pop(next(iter(cache)))
        cache[key] = value

    def _planned(self, request: MoveRequest, start: tuple, period: float) -> tuple[Segment | None, str | None]:
        """The move's own trajectory (no blend, no triggers), or its problem; from
        ``cache`` when it holds the same move from the same start (a new segment either way)."""
        cache = self.cache
        key = None
        if cache is not None and request.rest_of is None:
            key = ("move", request.kind, request.targets, request.speed, request.acc, request.frames, tuple(start),
                   period, self.reduced)
            known = cache.get(key)
            if known is not None:
                trajectory, end, limits, problem = known
                return (None, problem) if trajectory is None else (Segment(request, trajectory, end, limits), None)
        if request.kind == Motion.PTP:
            segment, problem = self._plan_ptp(request, start)
        else:
            segment, problem = self._plan_cartesian(request, start, period)
        if segment is not None and self.zones:
            problem = zone_problem(self.kinematics, segment.trajectory, self._tool_point(request.frames), self.zones)
            if problem is not None:
                segment = None
        if key is not None:
            self._keep(key, (None, None, None, problem) if segment is None else
                       (segment.trajectory, segment.end, segment.limits, None))
        return segment, problem

    def kinematics_for(self, frames: Frames | None) -> Kinematics | None:
        """The arm with the move's tool (built once per tool, on the planning worker where
        there is one; the latest 16 are kept)."""
        kinematics = self.kinematics
        if kinematics is None or frames is None or frames.tool == kinematics.tool:
            return kinematics
        tools = self._tools
        found = tools.get(frames.tool)
        if found is None:
            if len(tools) >= 16:
                tools.pop(next(iter(tools)))
            found = tools[frames.tool] = kinematics.with_tool(frames.tool)
        return found

    def _plan_ptp(self, request: MoveRequest, start: tuple) -> tuple[Segment | None, str | None]:
        target = request.targets[0]
        if isinstance(target, Pose):
            target, problem = self.joint_target(target, start, request.frames)
            if problem is not None:
                return None, problem
        values = target.axes if isinstance(target, Joint) else tuple(target)
        for axis, v in zip(self.axes, values):
            problem = axis.target_problem(v)
            if problem is not None:
                return None, problem
        speed, acc = request.speed, request.acc
        vmax, amax = scaled_limits(tuple(a.max_velocity for a in self.axes),
                                   tuple(a.max_acceleration for a in self.axes), speed, acc)
        jmax = tuple(a.max_jerk * acc for a in self.axes)  # (the jerk limit scales with acc_ptp)
        reduced = self.reduced
        if reduced is not None:
            vmax = tuple(min(v, r) for v, r in zip(vmax, reduced.velocities))
        result, trajectory, message = self._ptp(start, values, vmax, amax, jmax)
        if reduced is not None and result >= 0:
            result, trajectory, message = self._ptp_reduced(request, start, values, (vmax, amax, jmax), trajectory)
        if result < 0:
            return None, message
        return Segment(request, trajectory, values, self.limits), None

    def _ptp(self, start: tuple, values: tuple, vmax: tuple, amax: tuple, jmax: tuple):
        if self.profile == "jerk":
            return plan_ptp_jerk(PtpInput(start, values, vmax, amax, max_jerk=jmax))
        return plan_ptp(PtpInput(start, values, vmax, amax))

    def _ptp_reduced(self, request: MoveRequest, start: tuple, values: tuple, limits: tuple, trajectory):
        """T1 (runtime.motion.reduced): the ptp move planned again slower until its flange and
        tool centre point keep the reduced speed: its axis speeds lowered (up to three times),
        then, if that is not enough, the whole move timed slower (v x s, a x s^2, j x s^3)."""
        kinematics, tool = self.kinematics, self._tool_point(request.frames)
        if kinematics is None:
            return 0, trajectory, None
        cap = self.reduced.speed
        vmax, amax, jmax = limits
        for attempt in range(4):
            peak = cartesian_peak(kinematics, trajectory, tool)
            if peak <= cap:
                return 0, trajectory, None
            s = cap / peak * 0.98
            if attempt < 3:
                vmax = tuple(v * s for v in vmax)
            else:
                vmax = tuple(v * s for v in vmax)
                amax = tuple(a * s * s for a in amax)
                jmax = tuple(j * s * s * s for j in jmax)
            result, trajectory, message = self._ptp(start, values, vmax, amax, jmax)
            if result < 0:
                return result, None, message
        return 0, trajectory, None

    def _tool_point(self, frames: Frames | None) -> tuple:
        """The tool centre point's x, y, z in the flange (the move's tool, else the arm's)."""
        if frames is not None:
            return tuple(frames.tool[:3])
        tool = self.kinematics.tool if self.kinematics is not None else (0.0, 0.0, 0.0)
        return tuple(tool[:3])

    def _plan_cartesian(self, request: MoveRequest, start: tuple, period: float):
        kinematics = self.kinematics_for(request.frames)
        if kinematics is None:
            return None, self.kinematics_problem
        poses = tuple(kinematics.forward(t.axes[:self.main]) if isinstance(t, Joint) else t
                      for t in request.targets)
        problem = self._keeps_configuration(request, kinematics, start)
        if problem is not None:
            return None, problem
        via, target = (None, poses[0]) if request.kind == Motion.LIN else poses
        speed, limits, reduced = request.speed, self.joint_limits, self.reduced
        if reduced is not None:  # T1: a path speed that keeps the flange and the tool centre point slow
            speed = min(speed, path_speed(kinematics, start, target, via, self._tool_point(request.frames),
                                          reduced.speed))
            limits = JointLimits(limits.positions, tuple(min(v, r) for v, r in zip(limits.velocity,
                                                                                    reduced.velocities)),
                                 limits.acceleration, limits.jerk)
        result, stream, message = plan_cartesian(CartesianInput(
            kinematics, start, target, speed, request.acc, via=via, axis_limits=limits, period=period))
        if result < 0:
            prefix = f"move {request.kind} refused: "
            if isinstance(message, Refusal):
                return None, message.prefixed(prefix)
            return None, prefix + message.removeprefix(f"move {request.kind}: ")
        problem = self._ends_in_turns(request, kinematics, stream.target_position)
        if problem is not None:
            return None, problem
        return Segment(request, stream, stream.target_position, self.cartesian_limits), None

    def _keeps_configuration(self, request: MoveRequest, kinematics: Kinematics, start: tuple) -> str | None:
        """A lin or circ move keeps the configuration it starts in: the problem of a target
        (or a via pose) that names another one (compiler.configs), else None."""
        named = [(what, t.config) for what, t in zip(("via pose", "target") if request.kind == Motion.CIRC
                                                       else ("target",), request.targets)
                 if isinstance(t, Pose) and t.config is not None and t.config.mask]
        if not named:
            return None
        cid = kinematics.configuration(tuple(start[:self.main]))
        for what, config in named:
            differs = group_problem(config, cid)
            if differs is not None:
                group, value = differs
                return (f"move {request.kind} keeps the arm's configuration ({configuration_name(cid)}); its {what} "
                        f"names {group.meanings[value]} ({format_config(config)}): change the configuration with a "
                        "ptp move")
        return None

    def _ends_in_turns(self, request: MoveRequest, kinematics: Kinematics, end: tuple) -> str | None:
        """A lin or circ move to a target that names turns (compiler.configs) must end with
        A1, A4, A6 in them: the problem, else None."""
        target = request.targets[-1]
        config = target.config if isinstance(target, Pose) else None
        if config is None or config.turns is None:
            return None
        for axis, k in zip(TURN_AXES, config.turns):
            if not in_turn(end[axis], k):
                return (f"move {request.kind} would end with {kinematics.names[axis]} in turn {turn_of(end[axis])} "
                        f"({end[axis]:.1f} deg); its target names turn {k} ({format_config(config)}): reach that "
                        "turn with a ptp move")
        return None

    def joint_target(self, pose: Pose, near: tuple, frames: Frames | None = None) -> tuple[Joint | None, str | None]:
        """The joint values that put the tool (``frames``' tool) at ``pose``: the inverse
        kinematics' configuration nearest the joints ``near`` (the additional axes stay), or
        the one ``pose`` names (its ``config``: compiler.configs)."""
        kinematics = self.kinematics_for(frames)
        if kinematics is None:
            return None, self.kinematics_problem
        main = self.main
        config = pose.config
        try:
            if config is None or config.free:
                joints = kinematics.inverse(pose, near=near[:main])
            else:
                joints = kinematics.inverse_config(pose, config, near=near[:main])
        except KinematicsError as exc:
            where = "" if config is None or config.free else f" in {format_config(config)}"
            return None, f"the target pose cannot be reached{where}: {exc}"
        return Joint(tuple(joints), tuple(near[main:])), None
