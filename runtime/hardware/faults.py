"""The hardware faults the simulated robot can be made to have (``irl run --inject
FAULT:AXIS``, the fault-matrix tests): declared once, read by the simulated robot and the
command line. Imports nothing (the command line reads it before anything heavy)."""
from __future__ import annotations

#: ``sensor_dead``: the homing sensor never switches; ``encoder_frozen``: the encoder's
#: counts stop; ``drive_dead``: the drive stops answering its command.
FAULTS = ("sensor_dead", "encoder_frozen", "drive_dead")
