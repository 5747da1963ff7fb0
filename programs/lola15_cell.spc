# System specification of the Lola 15 in its palletizing cell: lola15.spc (the arm, unchanged)
# plus the cell's measured frames and the robot's tools, which every program of the cell
# uses by name (use base pallet_station; use tool gripper;). tests/test_frames.py checks that
# everything but the [[frame]] and [[tool]] tables equals lola15.spc.

#
# The real Lola 15 data are not public. These are plausible numbers for a 15 kg
# six-axis industrial arm with a spherical wrist (reach about 1.6 m), in the range of
# the public data sheets of arms of that class. Units: deg, deg/s, deg/s^2, deg/s^3
# for the revolute axes; mm, mm/s, mm/s^2 for the tool.

[robot]
name = "lola_15"
description = "Lola 15, six-axis articulated arm, 15 kg payload (plausible data, not the real robot's)"
max_speed = 2000.0            # mm/s, tool centre point
max_acceleration = 8000.0     # mm/s^2

[defaults]                    # clause values for a move that leaves them out
speed_ptp = 0.5
acc_ptp = 0.5
speed = 250.0                 # mm/s
acc = 1000.0                  # mm/s^2
approx = 0.0

[io]
inputs = 16
outputs = 16

[kinematics]
tool = { x = 0.0, y = 0.0, z = 100.0, roll = 0.0, pitch = 0.0, yaw = 0.0 }

[controller]
kp = 40.0                     # 1/s, position loop gain
ki = 2.0                      # 1/s^2
following_error_limit = 2.0   # deg
# Deadline policy of the 1 ms servo task (wall clock): "hard" (one miss faults), "firm"
# (more than servo_miss_limit misses within servo_miss_window ticks fault) or "soft".
# 50 in 1000 suits a general-purpose kernel; on a real-time kernel, tighten it.
servo_miss_policy = "firm"
servo_miss_limit = 50
servo_miss_window = 1000
# PTP velocity profile: "jerk" (seven-phase, jerk-limited by each axis's max_jerk; the
# default) or "trapezoid" (velocity and acceleration limits only).
# profile = "jerk"

[[axis]]
name = "A1"
kind = "revolute"
min = -170.0
max = 170.0
max_velocity = 156.0
max_acceleration = 400.0
max_jerk = 4000.0
gear_ratio = 160.0
encoder_counts = 4096
dh = { a = 260.0, alpha = -90.0, d = 675.0 }

[[axis]]
name = "A2"
kind = "revolute"
min = -135.0
max = 90.0
max_velocity = 156.0
max_acceleration = 400.0
max_jerk = 4000.0
gear_ratio = 160.0
encoder_counts = 4096
dh = { a = 680.0, alpha = 0.0, d = 0.0, theta_offset = -90.0 }

[[axis]]
name = "A3"
kind = "revolute"
min = -120.0
max = 156.0
max_velocity = 156.0
max_acceleration = 400.0
max_jerk = 4000.0
gear_ratio = 130.0
encoder_counts = 4096
dh = { a = 35.0, alpha = -90.0, d = 0.0 }

[[axis]]
name = "A4"
kind = "revolute"
min = -185.0
max = 185.0
max_velocity = 330.0
max_acceleration = 900.0
max_jerk = 9000.0
gear_ratio = 90.0
encoder_counts = 4096
dh = { a = 0.0, alpha = 90.0, d = 670.0 }

[[axis]]
name = "A5"
kind = "revolute"
min = -120.0
max = 120.0
max_velocity = 330.0
max_acceleration = 900.0
max_jerk = 9000.0
gear_ratio = 90.0
encoder_counts = 4096
dh = { a = 0.0, alpha = -90.0, d = 0.0 }

[[axis]]
name = "A6"
kind = "revolute"
min = -350.0
max = 350.0
max_velocity = 615.0
max_acceleration = 1500.0
max_jerk = 15000.0
gear_ratio = 60.0
encoder_counts = 4096
dh = { a = 0.0, alpha = 0.0, d = 115.0 }

# The simulated robot (`irl run` without hardware). Every axis parks at power-up within
# `park_spread` of its home, its encoder counting from zero there.
[simulation]
drive_time_constant = 0.005   # s, first-order lag of each velocity-commanded drive
max_drive_offset = 0.5        # deg/s, largest constant velocity offset of a drive
park_spread = 3.0             # deg, power-up position: home +- this

# ---- the cell: frames measured in the world (the robot's base) frame ----------------------

[[frame]]
name = "pallet_station"       # the pallet's corner, as measured when the cell was set up
x = 650.0
y = -180.0
z = 250.0
yaw = 10.0

[[frame]]
name = "glue_table"           # the gluing fixture's corner
x = 300.0
y = 600.0
z = 300.0
yaw = 90.0

# ---- the robot's tools, in the flange frame ----------------------------------------------------

[[tool]]
name = "gripper"              # vacuum gripper: 180 mm long
z = 180.0

[[tool]]
name = "glue_gun"             # glue nozzle: 150 mm out, 60 mm off the axis, tilted 20 deg
x = 60.0
z = 150.0
pitch = 20.0

# ---- the cell's analog sensors (analog_in(N) in a program) -----------------------------------------

[[analog_input]]
name = "part height"          # a laser distance sensor over the feeder: the height of the part there
unit = "mm"
min = 0.0
max = 100.0

# ---- the cell's analog outputs (call analog_out(N, VALUE) in a program) --------------------------------

[[analog_output]]
name = "glue pressure"        # the glue gun's pressure regulator
unit = "bar"
min = 0.0
max = 6.0

# The cell's world zones (docs/language.md, "World zones"): where the tool centre point and
# the flange never go. Every move is planned to keep 5 mm away, irl check finds one that does
# not, and the safety supervisor stops the robot if a 1 ms reference ever enters one.
[[zone]]
name = "fixture body"          # the machine's fixture under the part's seat (900, 300, 350)
shape = "box"
min = [830.0, 230.0, 0.0]
max = [970.0, 370.0, 320.0]

[[zone]]
name = "guard post"            # the light curtain's post beside the machine
shape = "cylinder"
centre = [1000.0, 700.0]
radius = 60.0
z = [0.0, 2200.0]
