"""Motion: PTP and Cartesian planning, kinematics and setpoint interpolation, in plain floats.

* :mod:`runtime.motion.trajectory` -- the one trajectory interface every motion has
  (duration, ``sample``, ``at_time``, what blending and stopping need) and the planners'
  one ``Result`` enum; every planner takes a typed input and returns ``(result,
  trajectory, message)``, never raising (Ruckig's shape).
* :mod:`runtime.motion.profiles` -- one axis: the time-optimal trapezoidal profile
  (rest to rest) and the profile of a given, longer duration.
* :mod:`runtime.motion.planner` -- all axes: ``plan_ptp(PtpInput)``, synchronised so that
  every axis starts and stops together and the slowest axis moves time-optimally.
* :mod:`runtime.motion.jerk` -- seven-phase (double-S) jerk-limited profiles and
  ``plan_ptp_jerk(PtpInput)``, the default PTP planner (``[controller] profile``).
* :mod:`runtime.motion.stops` -- controlled stops on a move's path (pause, abort).
* :mod:`runtime.motion.kinematics` -- forward and inverse kinematics of the
  specification's DH arm (spherical wrist, eight configurations).
* :mod:`runtime.motion.rotation`, :mod:`runtime.motion.paths`,
  :mod:`runtime.motion.pathcheck`, :mod:`runtime.motion.cartesian` -- lin and circ moves:
  quaternions and slerp, the paths and their timing, the whole-path check, and
  ``plan_cartesian(CartesianInput)``: the move timed within every joint's limits and
  streamed as joints every 5 ms.
* :mod:`runtime.motion.blend` -- blending a corner (``approx``): the overlap and its check.
* :mod:`runtime.motion.moves`, :mod:`runtime.motion.motionqueue` -- a program's moves
  planned into segments, and the timeline that runs them (look-ahead, blending, the
  override, pause/resume/abort), independent of components, ports and the VM.
* :mod:`runtime.motion.interpolator` -- turns the trajectory generator's 5 ms
  setpoints into the servo's 1 ms references, within every axis's limits.

Units: positions in deg (revolute axes) or mm (prismatic), velocities per second,
accelerations per second squared, times in seconds. No NumPy in what a tick runs: per-axis arithmetic
on six values is cheapest in plain Python floats, and the real-time loop must not pay
NumPy's per-call overhead (the planning-time checks of paths and blends use NumPy).
Importing this package imports nothing else.
"""
