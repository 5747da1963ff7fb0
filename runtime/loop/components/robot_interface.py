"""Robot Interface: the sensors and actuators of the arm behind one component.

Sense (every 1 ms): read the incremental encoders, turn counts into axis positions
(relative to power-up until the initialization resets the encoders), estimate each
axis's velocity with an alpha-beta filter, and write ``sens_pos``. Act (every 1 ms):
apply ``drive_cmd`` (the safety supervisor's, made from the servo's ``out_vel``; plus the
calibrated offset compensation) to the drives; a command the safety did not write this
tick is never applied: the interface then takes the torque off and applies the brakes
itself. The hardware is a backend; the simulated robot is the default, real hardware
plugs in behind the same methods (encoders, drives with a velocity command and a torque
enable, brakes). The digital I/O is a component of its own (runtime/loop/components/io.py),
with the backend's I/O (or a PLC's) behind it.
"""
from __future__ import annotations

from compiler.params import component_params

from runtime.accel import kernels
from runtime.hardware.interface import RobotBackend
from runtime.loop.component import Component, DataPort
from runtime.settings import Settings
from runtime.timing import TICK

clamp_commands = kernels.clamp_commands


class RobotInterface(Component):
    PROPERTIES = component_params("robot")
    OPERATIONS = Component.OPERATIONS + ("release_brakes", "apply_brakes")

    def __init__(self, spec, backend: RobotBackend, sens_pos: DataPort, drive_cmd: DataPort, estimator,
                 tick: float = TICK, settings: Settings | None = None):
        # robot.velocity_limit_scale (reduced speed) is the robot's setting; the planners, the
        # servo and the safety supervisor read it there
        super().__init__("robot", tick, settings if settings is not None else Settings(spec))
        self.spec = spec
        self.backend = backend
        self.sens_pos = sens_pos
        self.drive_cmd = drive_cmd
        self.estimator = estimator
        self.tick = tick
        self.axes = spec.axes
        self.n = len(spec.axes)
        self.scale = tuple(1.0 / a.counts_per_unit for a in spec.axes)
        self.offset = [0.0] * self.n  # position = counts / counts_per_unit + offset
        self.zeroed = [False] * self.n  # per axis: its encoder was reset by a homing (positions absolute)
        self.compensation = [0.0] * self.n  # added to every velocity command (calibration)
        self.max_velocity = tuple(a.max_velocity for a in spec.axes)
        self.unguarded: str | None = None  # why the interface stopped the drives itself
        self.counts = (0,) * self.n
        self.index_events = (0,) * self.n
        self.latched = (0,) * self.n
        self.sensors = (False,) * self.n
        self.positions = (0.0,) * self.n
        self.last_command = (0.0,) * self.n
        self.homing = True  # read sensors and index pulses (the initialization needs them)
        self._zeros = (0.0,) * self.n

    # -- lifecycle --
    def on_start(self) -> bool:
        self.read(0.0)
        self.estimator.reset(self.positions)
        return True

    # -- real-time --
    def read(self, now: float) -> None:
        """Real-time (sense): encoders -> positions, velocity estimate -> ``sens_pos``.
        Homing sensors and index pulses are taken only while ``homing`` is set (the
        index counters only grow, so nothing is missed between reads)."""
        if self.homing:
            counts, self.index_events, self.latched, self.sensors = self.backend.read()
        else:
            counts = self.backend.read_counts()
        self.counts = counts
        positions = self.estimator.update_counts(counts, self.scale, self.offset)
        self.positions = positions
        self.sens_pos.write(positions, now)

    @property
    def velocities(self) -> tuple[float, ...]:
        """Each axis's estimated velocity (the alpha-beta filter's, at the last read)."""
        return self.estimator.velocities

    def write(self, now: float) -> None:
        """Real-time (act): ``drive_cmd`` (within each axis's max_velocity) + the calibrated
        compensation to the drives: the drive then runs at the command, also at
        max_velocity when its offset works against the motion (clamped after the
        compensation, such an axis fell behind for as long as it ran at max_velocity). A
        command not written by the safety supervisor for this very tick is not applied:
        zero, torque off, brakes on."""
        port = self.drive_cmd
        if port.stamp != now or port.value is None:
            command = self._zeros
            if self.backend.brakes_released() and self.unguarded is None:
                self.unguarded = (f"the drives got no command from the safety supervisor at {now:.3f} s: "
                                  "torque off, brakes applied")
                self.backend.disable_drives()
                self.backend.apply_brakes()
        else:
            command = port.value
        out = clamp_commands(command, self.compensation, self.max_velocity)
        self.last_command = out
        self.backend.step(self.tick, out)

    # -- operations (called by the supervisor between ticks) --
    def release_brakes(self) -> None:
        self.backend.release_brakes()

    def apply_brakes(self) -> None:
        self.backend.apply_brakes()

    def disable_drives(self) -> None:
        """Safe torque off (real-time safe)."""
        self.backend.disable_drives()

    def enable_drives(self) -> None:
        self.unguarded = None
        self.backend.enable_drives()

    def drives_enabled(self) -> bool:
        return self.backend.drives_enabled()

    def brakes_released(self) -> bool:
        return self.backend.brakes_released()

    def brakes_applied(self) -> bool:
        return self.backend.brakes_applied()

    def reset_encoder(self, axis: int, counts_at: int, position_at: float) -> None:
        """From now on, ``counts_at`` encoder counts read as ``position_at`` on ``axis``."""
        new = position_at - counts_at * self.scale[axis]
        delta = new - self.offset[axis]
        self.offset[axis] = new
        self.zeroed[axis] = True
        positions = list(self.estimator.positions)
        positions[axis] += delta
        self.estimator.reset(positions, self.estimator.velocities)
        shifted = list(self.positions)
        shifted[axis] += delta
        self.positions = tuple(shifted)
        self.sens_pos.write(self.positions, self.sens_pos.stamp)  # readers this tick see the new zero
