"""Motion: PTP and Cartesian planning, kinematics and setpoint interpolation, in plain floats.

* :mod:`runtime.motion.profiles` -- one axis: the time-optimal trapezoidal profile
  (rest to rest) and the profile of a given, longer duration.
* :mod:`runtime.motion.planner` -- all axes: ``plan_ptp(PtpInput) -> (Result,
  PtpTrajectory | None, message)``, synchronised so that every axis starts and stops
  together and the slowest axis moves time-optimally (Ruckig's shape: input value
  object, trajectory value object, a documented result enum; it never raises).
* :mod:`runtime.motion.jerk` -- seven-phase (double-S) jerk-limited profiles and
  ``plan_ptp_jerk``, the default PTP planner (``[controller] profile``).
* :mod:`runtime.motion.kinematics` -- forward and inverse kinematics of the
  specification's DH arm (spherical wrist, eight configurations).
* :mod:`runtime.motion.cartesian` -- lin and circ paths: geometry, slerp, a jerk-limited
  profile along the path, the whole-path check, and the joint stream sampled every 5 ms.
* :mod:`runtime.motion.interpolator` -- turns the trajectory generator's 5 ms
  setpoints into the servo's 1 ms references by cubic Hermite interpolation.

Units: positions in deg (revolute axes) or mm (prismatic), velocities per second,
accelerations per second squared, times in seconds. No NumPy here: per-axis arithmetic
on six values is cheapest in plain Python floats, and the real-time loop must not pay
NumPy's per-call overhead. Importing this package imports nothing else.
"""
