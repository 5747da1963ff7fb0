"""Jogging (operating mode T1): moving the arm by hand, an axis or the tool centre point,
continuously while the operator holds a button, or one increment at a time.

A jog is a move of the trajectory generator's motion queue, planned by the same planners
as a program's moves, in T1 (runtime/motion/reduced.py: the flange and the tool centre
point under ``[safety] t1_speed``), and guarded by the same safety supervisor:

* an **axis** jog (``A1`` .. ``A6``, and the additional axes by name) is a ptp move of
  that axis alone: continuous, to its software limit (so the limit is approached with
  deceleration and the jog ends there, saying so); incremental, by the step (deg or
  mm), refused when the step would pass a limit;
* a **Cartesian** jog (``x``, ``y``, ``z``, and ``rx``, ``ry``, ``rz``: rotations about
  those axes through the tool centre point) in the ``world`` frame, the active ``base``
  or the ``tool`` frame is a lin move: continuous, as far as :data:`REACH` (or
  :data:`TURN`) along the axis, but where the path check finds the arm cannot go on (a
  singularity, an axis limit, the end of the reach) it ends :data:`MARGIN` before that
  point and says why; incremental, by the step, refused whole when the arm cannot make it.

A continuous jog moves only while its requests keep coming: each repetition of the same
request is a heartbeat, and a jog whose last heartbeat is :data:`HEARTBEAT_TIMEOUT` old,
or that is released (``direction`` 0), stops on its path (a pause of the motion: its
decelerations), and the moves it had left are dropped. The session (a cycle of the
supervisor: the brakes released, the servo holding) ends by itself :data:`SESSION_IDLE`
after the last request once the arm is at rest.

The base and tool a jog uses are those of the last program's last move (what telemetry
shows), the world frame and the specification's tool before any program ran.

Real-time safe: :meth:`Jogger.request` and :meth:`Jogger.update` compute one target pose
(forward kinematics, a few floats) and hand it to the motion queue; planning runs on its
worker (the wall clock) or at once (the simulated clock).
"""
from __future__ import annotations

import math

from compiler.clauses import Motion
from compiler.geometry import rotation_to_rpy, rpy_to_matrix
from compiler.values import Joint, Pose, Position, Rpy

from runtime.motion.moves import MoveRequest
from runtime.wire.messages import Jog
from runtime.wire.protocol import JOG_CARTESIAN, ProtocolError

__all__ = ["HEARTBEAT_TIMEOUT", "Jogger", "MARGIN", "REACH", "SESSION_IDLE", "TURN"]

#: s without a heartbeat after which a continuous jog stops (a client repeats its request
#: at least every 0.2 s: the pendant every 0.1 s).
HEARTBEAT_TIMEOUT = 0.25
#: s at rest without a jog request after which the jog session ends (brakes on).
SESSION_IDLE = 2.0
#: How far one continuous Cartesian jog goes (mm; deg for a rotation) before it is planned
#: on from where it ended.
REACH, TURN = 500.0, 90.0
#: How far before a point the arm cannot pass (a singularity, a limit) a jog ends (mm; deg).
MARGIN = 2.0
#: s: a jog's stop on its path that would take longer is made in joint space instead, every
#: axis at this share of its max_acceleration (Jogger._stop).
STOP_TIME, STOP_DECELERATION = 0.2, 0.5
#: The shortest jog planned (mm or deg): less is refused as "cannot move on".
SHORTEST = 0.05


def _rotation(axis: tuple, angle_deg: float) -> tuple:
    """The 3x3 rotation by ``angle_deg`` about the unit vector ``axis`` (Rodrigues)."""
    x, y, z = axis
    t = math.radians(angle_deg)
    c, s, v = math.cos(t), math.sin(t), 1.0 - math.cos(t)
    return ((c + x * x * v, x * y * v - z * s, x * z * v + y * s),
            (y * x * v + z * s, c + y * y * v, y * z * v - x * s),
            (z * x * v - y * s, z * y * v + x * s, c + z * z * v))


def _mul(a: tuple, b: tuple) -> tuple:
    return tuple(tuple(sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)) for i in range(3))


def describe(jog: Jog) -> str:
    """``"x+ in the tool frame, 1 mm"``: a jog as messages say it."""
    sign = "+" if jog.direction > 0 else "-"
    where = f" in the {jog.frame} frame" if jog.axis in JOG_CARTESIAN else ""
    step = "" if jog.step is None else f", {jog.step:g} {'deg' if jog.axis.startswith('r') or jog.axis not in JOG_CARTESIAN else 'mm'}"
    return f"{jog.axis}{sign}{where}{step}"


class Jogger:
    """The jog session's state: the jog under way (``active``), the one waiting for the
    arm to come to rest (``pending``), the last heartbeat, why the last jog ended
    (``reason``). ``host``: the trajectory generator (its motion queue, planner, frames)."""

    def __init__(self, host, now: float):
        self.host = host
        self.motion = host.motion
        self.axes = host.axes
        self.names = [a.name.lower() for a in host.axes]
        self.active: Jog | None = None
        self.pending: Jog | None = None
        self.heartbeat = now
        self.last_request = now
        self.stopping = False
        self.reason: str | None = None
        self.length = 0.0  # the continuous Cartesian jog's planned length (mm or deg)
        #: a continuous jog that ended at the end of its travel while held: its heartbeats go
        #: on without starting it again (the operator releases, and presses again)
        self.held_at_end: Jog | None = None
        self.jogs = 0  # jogs started in this session

    # ---- what the loop asks (real-time safe) -------------------------------------------------
    def request(self, jog: Jog, now: float) -> dict:
        """One ``jog`` request: start it, make it the heartbeat of the one under way, release
        (``direction`` 0), or stop the one under way and start it at rest. ProtocolError:
        a jog that cannot start (its reason)."""
        if self.held_at_end is not None and (jog != self.held_at_end or now - self.heartbeat > HEARTBEAT_TIMEOUT):
            self.held_at_end = None
        self.last_request = now
        if jog.direction == 0:
            self.pending = None
            if self.active is not None:
                self._stop("released")
            return self.state()
        if jog.step is None and (self.active == jog and not self.stopping or self.held_at_end == jog):
            self.heartbeat = now
            return self.state()
        self.heartbeat = now
        if self.active is not None or self.stopping:
            self.pending = jog
            if not self.stopping:
                self._stop("another jog asked for")
            return self.state()
        problem = self._start(jog)
        if problem is not None:
            raise ProtocolError("refused", f"jog {describe(jog)}: {problem}")
        return self.state()

    def update(self, now: float) -> None:
        """Every 5 ms: the heartbeat watched, a stop finished, the next jog started."""
        motion = self.motion
        if self.stopping:
            if motion.hold.stop is None and not motion.hold.on_timeline:
                motion.clear()  # the rest of the stopped jog is dropped
                self.stopping = False
                self.active = None
        elif self.active is not None:
            if self.active.step is None and now - self.heartbeat > HEARTBEAT_TIMEOUT:
                self._stop(f"no heartbeat for {HEARTBEAT_TIMEOUT:g} s")
            elif motion.done(triggers=False):
                self._ended()
        if self.active is None and not self.stopping and self.pending is not None:
            jog, self.pending = self.pending, None
            if now - self.heartbeat <= HEARTBEAT_TIMEOUT or jog.step is not None:
                problem = self._start(jog)
                if problem is not None:
                    self.reason = f"jog {describe(jog)}: {problem}"

    def failed(self, problem: str) -> None:
        """The motion queue could not plan the jog on its worker: see :meth:`_retry`."""
        jog = self.active
        problem = self._retry(problem)
        if problem is not None and jog is not None:
            self.reason = f"jog {describe(jog)}: {problem}"

    def _retry(self, problem: str) -> str | None:
        """A jog's move could not be planned: a continuous Cartesian jog is planned again
        shorter, ending MARGIN before where its path fails (None: handed over); else the
        jog ends, and the problem is returned."""
        jog = self.active
        self.motion.clear()
        if jog is None:
            return problem
        fraction = getattr(problem, "fraction", None)
        if jog.step is None and jog.axis in JOG_CARTESIAN and fraction is not None:
            length = fraction * self.length - MARGIN
            if length >= SHORTEST:
                self.length = length
                request, _ = self._cartesian(jog, length)
                again = self.motion.add(request)
                if again is None:
                    why = str(problem).split("refused: ", 1)[-1]
                    unit = "deg" if jog.axis.startswith("r") else "mm"
                    self.reason = f"jog {describe(jog)} ends {MARGIN:g} {unit} before the arm cannot go on: {why}"
                    return None
                problem = again
        self.active = None
        return problem

    def end(self, why: str) -> None:
        """End the session: the jog under way stops on its path, nothing waits."""
        self.pending = None
        self.last_request = -math.inf
        if self.active is not None and not self.stopping:
            self._stop(why)

    @property
    def finished(self) -> bool:
        """The session is over: nothing moves or waits, and no request for SESSION_IDLE s."""
        return (self.active is None and self.pending is None and not self.stopping
                and self.host.clock.tick_time - self.last_request > SESSION_IDLE)

    def state(self) -> dict:
        """What ``status`` and the replies say of jogging."""
        return {"active": describe(self.active) if self.active is not None else None,
                "stopping": self.stopping, "reason": self.reason, "jogs": self.jogs}

    # ---- the moves ---------------------------------------------------------------------------
    def _stop(self, why: str) -> None:
        """Stop the jog on its path (the motion's pause); a stop on a Cartesian path that
        would take longer than STOP_TIME (it may run on to the move's end where no sooner
        one keeps the joints' limits) is replaced by every axis ramped to rest at
        STOP_DECELERATION of its max_acceleration: at T1's speeds the tool leaves its
        line by a fraction of a millimetre."""
        self.stopping = True
        self.reason = f"jog {describe(self.active)} stopped: {why}" if self.active is not None else why
        within = self.motion.pause()
        if within is not None and within > STOP_TIME:
            within = self.motion.stop_in_joint_space(tuple(a.max_acceleration * STOP_DECELERATION
                                                           for a in self.axes))
        self.host.expect_rest(within)

    def _ended(self) -> None:
        """The jog's move reached its end: an increment is done; a continuous jog ends at a
        limit (said), or goes on from here while held."""
        jog, self.active = self.active, None
        self.motion.clear()
        if jog.step is not None:
            self.reason = f"jog {describe(jog)} done"
            return
        if jog.axis in JOG_CARTESIAN and self.reason is None and \
                self.host.clock.tick_time - self.heartbeat <= HEARTBEAT_TIMEOUT:
            if self._start(jog) is None:  # the full reach went: plan the next stretch
                return
        if self.reason is None:
            self.reason = f"jog {describe(jog)}: reached the end of its travel"
        self.held_at_end = jog

    def _start(self, jog: Jog) -> str | None:
        """Plan ``jog`` from where the arm is: the problem, else None."""
        self.reason = None
        self.active = jog
        self.jogs += 1
        if jog.axis in JOG_CARTESIAN:
            self.length = jog.step if jog.step is not None else (TURN if jog.axis.startswith("r") else REACH)
        else:
            self.length = 0.0
        problem = self._add(jog, self.length)
        if problem is not None and self.active is jog:
            self.active = None
        return problem

    def _add(self, jog: Jog, length: float) -> str | None:
        """Hand the jog's move (``length`` mm or deg along a Cartesian axis) to the motion
        queue: the problem when it cannot be made (planned at once without a worker; with
        one, a refusal comes back through :meth:`failed`)."""
        request, problem = (self._cartesian(jog, length) if jog.axis in JOG_CARTESIAN else self._axis(jog))
        if problem is not None:
            return problem
        problem = self.motion.add(request)
        return None if problem is None else self._retry(problem)

    def _axis(self, jog: Jog) -> tuple[MoveRequest | None, str | None]:
        i = self.names.index(jog.axis.lower())
        axis = self.axes[i]
        now = tuple(self.motion.positions)
        if jog.step is None:
            target = axis.max if jog.direction > 0 else axis.min
            if abs(target - now[i]) < SHORTEST:
                return None, f"{axis.name} is at its {'upper' if jog.direction > 0 else 'lower'} limit {target:g} {axis.unit}"
        else:
            target = now[i] + jog.direction * jog.step
            if not axis.min <= target <= axis.max:
                return None, (f"{axis.name} would go to {target:.3f} {axis.unit}, beyond its software limits "
                              f"{axis.min:g}..{axis.max:g} {axis.unit}")
        values = list(now)
        values[i] = target
        main = len(self.host.spec.main_axes)
        return MoveRequest(Motion.PTP, (Joint(tuple(values[:main]), tuple(values[main:])),), 1.0, 1.0, 0.0, 0,
                           frames=self.host.jog_frames), None

    def _cartesian(self, jog: Jog, length: float) -> tuple[MoveRequest | None, str | None]:
        host = self.host
        frames = host.jog_frames
        kinematics = host.planner.kinematics_for(frames)
        if kinematics is None:
            return None, host.planner.kinematics_problem
        main = len(host.spec.main_axes)
        matrix = kinematics.forward_matrix(self.motion.positions[:main])
        rotation = tuple(tuple(row[:3]) for row in matrix[:3])
        position = tuple(row[3] for row in matrix[:3])
        if jog.frame == "tool":
            frame = rotation
        elif jog.frame == "base":
            frame = rpy_to_matrix(*frames.base[3:])
        else:
            frame = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
        k = "xyz".index(jog.axis[-1])
        direction = tuple(frame[r][k] * jog.direction for r in range(3))
        if jog.axis.startswith("r"):
            rotation = _mul(_rotation(direction, length), rotation)
        else:
            position = tuple(p + d * length for p, d in zip(position, direction))
        roll, pitch, yaw = rotation_to_rpy(*rotation[0], *rotation[1], *rotation[2])
        target = Pose(Position(*position), Rpy(roll, pitch, yaw))
        return MoveRequest(Motion.LIN, (target,), host.spec.max_speed, host.spec.max_acceleration,
                           0.0, 0, frames=frames), None
