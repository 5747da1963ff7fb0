"""The robot's components, as in the paper: Robot Interface, Servo Controller,
Initialization, Trajectory Generator and Report; and the digital I/O (``io``)."""
