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
* :mod:`runtime.motion.stops` -- controlled stops on a move's path (pause, abort): the
  joint-space ones (a lin or circ move's, :class:`runtime.motion.cartesian.PathStop`,
  is beside the move's stream).
* :mod:`runtime.motion.kinematics` -- forward and inverse kinematics of the
  specification's DH arm (spherical wrist, eight configurations); :mod:`runtime.motion.teach`
  -- the L-IRL literals that name where the arm is (``irl pose``, ``irl where``, the
  pendant); :mod:`runtime.motion.urdf` -- the arm as URDF (``irl urdf``) and its links'
  transforms at given joint values.
* :mod:`runtime.motion.rotation`, :mod:`runtime.motion.paths`,
  :mod:`runtime.motion.pathcheck`, :mod:`runtime.motion.cartesian` -- lin and circ moves:
  quaternions and slerp, the paths and their timing, the whole-path check, and
  ``plan_cartesian(CartesianInput)``: the move timed within every joint's limits and
  streamed as joints every 5 ms (:mod:`runtime.motion.pathtiming`: its timing).
* :mod:`runtime.motion.reduced` -- operating mode T1 (manual reduced speed): the flange's
  and the tool centre point's speed measured along a move, the reduced limits moves and
  homing are planned under.
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

The modules form layers, declared once in :data:`MODULES` (lowest first): each imports
only from the ones before it (tests/test_motion.py checks it), so there is no circle and
each can be read knowing only what comes before it. No module imports another's private
(``_name``) names: what two modules share is public in the lower one.
"""

#: The package's modules, lowest first: each imports only from the ones before it.
MODULES = (
    "trajectory",  # the one Trajectory interface and the planners' Result
    "profiles",  # one axis, trapezoidal
    "stops",  # the joint-space stops (StopRamp, JerkStop, LineStop)
    "planner",  # PtpInput, the trapezoidal PTP planner
    "jerk",  # jerk-limited profiles and the jerk-limited PTP planner
    "kinematics",  # forward and inverse kinematics
    "zonecheck",  # a planned move against the world zones
    "tcp",  # the tool centre point of joint values with any tool and base (the arm per tool, cached)
    "teach",  # the literals that name where the arm is (irl pose, irl where, the pendant)
    "urdf",  # the arm as URDF, and its links' transforms
    "rotation",  # quaternions, slerp
    "pathtiming",  # a path's timing within the joints' limits
    "reachability",  # its near time-optimal timing (TOPP-RA, averaged for the jerk) and its stop
    "interpolator",  # 5 ms setpoints to 1 ms references
    "paths",  # lines and arcs, and their timing
    "pathcheck",  # the whole-path check
    "reduced",  # operating mode T1: the reduced speeds as the planners keep them
    "cartesian",  # lin and circ moves: JointStream, PathStop, plan_cartesian
    "blend",  # the blend's overlap and its check
    "moves",  # a program's move request planned into a segment
    "motionqueue",  # the timeline
)
