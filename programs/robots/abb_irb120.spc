# System specification of the ABB IRB 120-3/0.58: six-axis arm, 3 kg payload, 580 mm reach.
#
# Sources
#   Geometry, joint directions and tool0: ROS-Industrial, github.com/ros-industrial/abb_experimental,
#     abb_irb120_support/urdf/irb120_3_58_macro.xacro (commit 0ae97e1, 2020-03-12: "Fix
#     incorrect orientation of tool0 frame"). The URDF's joint values are the controller's.
#   Joint ranges and speeds: the ABB IRB 120 product data sheet (working range and maximum
#     speed per axis), as the URDF's <limit> tags carry them (lower/upper/velocity in rad,
#     rad/s: the same numbers converted). Reach and payload: the data sheet.
#   Everything marked "# assumed" is not published (accelerations, jerks, gear ratios,
#   encoders, the simulated drives): plausible values, to be replaced by measured ones.
#
# Convention: standard Denavit-Hartenberg (runtime/motion/kinematics.py): link i is
#   Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i), theta_i = q_i + theta_offset_i, q_i the joint
#   value. Frame 0 is the URDF's base_link (= "base", ABB's base frame: the foot's centre,
#   z up, x forward); frame 6 is the URDF's tool0 (ABB's tool0: z out of the flange, x down at
#   the calibration position). Per joint, from the URDF (mm; every <axis> is positive):
#     joint_1  origin 0 0 0      axis +z   z0 = +z              d1 = 290 (joint_2's height)
#     joint_2  origin 0 0 290    axis +y   z1 = +y: alpha1 = -90; the upper arm (270) is
#                                          vertical at q2 = 0: a2 = 270, theta_offset2 = -90
#     joint_3  origin 0 0 270    axis +y   z2 = +y (alpha2 = 0)
#     joint_4  origin 0 0 70     axis +x   the common normal of axes 3 and 4 is vertical,
#                                          70 long: a3 = 70; z3 = +x: alpha3 = -90
#     joint_5  origin 302 0 0    axis +y   on axis 4, 302 along it: d4 = 302; z4 = +y: alpha4 = 90
#     joint_6  origin 72 0 0     axis +x   through the wrist centre: a5 = d5 = 0; z5 = +x: alpha5 = -90
#     tool0    link_6 + rpy(0, 90 deg, 0)  72 beyond the wrist centre: d6 = 72; its x is down
#                                          (frame 5's x is up): theta_offset6 = 180
#   tests/test_real_arms.py checks this table against the URDF's chain.
# Units: deg, deg/s, deg/s^2, deg/s^3; mm, mm/s, mm/s^2.

[robot]
name = "abb_irb120"
description = "ABB IRB 120-3/0.58, 3 kg, 580 mm reach (data sheet and ROS-Industrial URDF)"
max_speed = 2000.0            # mm/s, tool centre point  # assumed (not in the data sheet)
max_acceleration = 10000.0    # mm/s^2                   # assumed

[kinematics]
# The default tool is the flange itself (ABB's tool0): frame 6 of the chain below is tool0,
# so a tool measured on the real robot (tooldata, relative to tool0) is a [[tool]] as it is.
tool = { x = 0.0, y = 0.0, z = 0.0, roll = 0.0, pitch = 0.0, yaw = 0.0 }

[simulation]
drive_time_constant = 0.002   # s  # assumed (a small arm's drives: a 2 ms lag)

# Home: the calibration position (all axes 0: upper arm vertical, forearm horizontal).
# Accelerations: each axis reaches its maximum speed in 0.25 s; jerks: that acceleration in
# 0.1 s.  # assumed (ABB publishes neither)
# Gears and encoders: 100:1 and 4096 counts per motor revolution.  # assumed

[[axis]]
name = "A1"
kind = "revolute"
min = -165.0                  # data sheet: +165 to -165
max = 165.0
max_velocity = 250.0          # data sheet
max_acceleration = 1000.0     # assumed
max_jerk = 10000.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 0.0, alpha = -90.0, d = 290.0 }

[[axis]]
name = "A2"
kind = "revolute"
min = -110.0                  # data sheet: +110 to -110
max = 110.0
max_velocity = 250.0          # data sheet
max_acceleration = 1000.0     # assumed
max_jerk = 10000.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 270.0, alpha = 0.0, d = 0.0, theta_offset = -90.0 }

[[axis]]
name = "A3"
kind = "revolute"
min = -110.0                  # data sheet: +70 to -110
max = 70.0
max_velocity = 250.0          # data sheet
max_acceleration = 1000.0     # assumed
max_jerk = 10000.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 70.0, alpha = -90.0, d = 0.0 }

[[axis]]
name = "A4"
kind = "revolute"
min = -160.0                  # data sheet: +160 to -160
max = 160.0
max_velocity = 320.0          # data sheet
max_acceleration = 1280.0     # assumed
max_jerk = 12800.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 0.0, alpha = 90.0, d = 302.0 }

[[axis]]
name = "A5"
kind = "revolute"
min = -120.0                  # data sheet: +120 to -120
max = 120.0
max_velocity = 320.0          # data sheet
max_acceleration = 1280.0     # assumed
max_jerk = 12800.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 0.0, alpha = -90.0, d = 0.0 }

[[axis]]
name = "A6"
kind = "revolute"
min = -400.0                  # data sheet: +400 to -400 (default; more turns as an option)
max = 400.0
max_velocity = 420.0          # data sheet
max_acceleration = 1680.0     # assumed
max_jerk = 16800.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 0.0, alpha = 0.0, d = 72.0, theta_offset = 180.0 }
