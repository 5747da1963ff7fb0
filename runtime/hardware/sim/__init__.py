"""The simulated robot (drives, joints, brakes, encoders, index pulses, homing sensors,
digital I/O, faults) and the alpha-beta state estimator. Pure Python: no NumPy."""
from __future__ import annotations

from runtime.hardware.sim.estimator import DEFAULT_TIME_CONSTANT, AlphaBeta, critically_damped_gains
from runtime.hardware.sim.robot import FAULTS, SimRobot

__all__ = ["FAULTS", "SimRobot", "AlphaBeta", "critically_damped_gains", "DEFAULT_TIME_CONSTANT"]
