# System specification of the KUKA KR 6 R900 sixx (KR AGILUS): six-axis arm, 6 kg payload,
# 901 mm reach.
#
# Sources
#   Geometry, joint directions and the flange: ROS-Industrial,
#     github.com/ros-industrial/kuka_experimental, kuka_kr6_support/urdf/kr6r900sixx_macro.xacro
#     (commit 652600d, 2021-09-28). Its joint values are the controller's A1..A6.
#   Joint ranges and speeds: the KUKA KR AGILUS sixx data sheet (range of motion and speed
#     with rated payload per axis), as the URDF's <limit> tags carry them (in rad, rad/s).
#     Reach and payload: the data sheet.
#   Everything marked "# assumed" is not published (accelerations, jerks, gear ratios,
#   encoders, the simulated drives): plausible values, to be replaced by measured ones.
#
# Convention: standard Denavit-Hartenberg (runtime/motion/kinematics.py): link i is
#   Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i), theta_i = direction_i * q_i + theta_offset_i,
#   q_i the joint value. Frame 0 is the URDF's base_link (= "base", KUKA's $ROBROOT: z up,
#   x forward); frame 6 is the URDF's tool0 (KUKA's $FLANGE: z out of the flange, x down at
#   A2 = A3 = A5 = 0). Each z_{i-1} points along its axis to +x, +y or +z at the zero
#   position; direction = -1 where the URDF's <axis> points the other way (A1, A4, A6: so
#   A1 = +30 turns the arm clockwise seen from above, as on the real robot). From the URDF (mm):
#     joint_a1  origin 0 0 400    axis -z   z0 = +z, direction -1; d1 = 400
#     joint_a2  origin 25 0 0     axis +y   a1 = 25; z1 = +y: alpha1 = -90
#     joint_a3  origin 455 0 0    axis +y   the upper arm is horizontal at A2 = 0: a2 = 455,
#                                           theta_offset2 = 0; z2 = +y (alpha2 = 0)
#     joint_a4  origin 0 0 35     axis -x   the common normal of axes 3 and 4 points up, 35
#                                           long: a3 = 35, theta_offset3 = -90 (frame 2's x is
#                                           forward); z3 = +x: alpha3 = -90, direction -1
#     joint_a5  origin 420 0 0    axis +y   on axis 4, 420 along it: d4 = 420; z4 = +y: alpha4 = 90
#     joint_a6  origin 80 0 0     axis -x   through the wrist centre: a5 = d5 = 0; z5 = +x:
#                                           alpha5 = -90, direction -1
#     tool0     link_6 (flange) + rpy(0, 90 deg, 0): 80 beyond the wrist centre: d6 = 80; its
#                                           x is down (frame 5's x is up): theta_offset6 = 180
#   tests/test_real_arms.py checks this table against the URDF's chain.
# Units: deg, deg/s, deg/s^2, deg/s^3; mm, mm/s, mm/s^2.

[robot]
name = "kuka_kr6_r900_sixx"
description = "KUKA KR 6 R900 sixx (KR AGILUS), 6 kg, 901 mm reach (data sheet and ROS-Industrial URDF)"
max_speed = 2000.0            # mm/s, tool centre point  # assumed (not in the data sheet)
max_acceleration = 10000.0    # mm/s^2                   # assumed

[kinematics]
# The default tool is the flange itself ($FLANGE, $TOOL with no tool): frame 6 of the chain
# below is that frame, so a tool measured on the real robot ($TOOL data) is a [[tool]] as it is.
tool = { x = 0.0, y = 0.0, z = 0.0, roll = 0.0, pitch = 0.0, yaw = 0.0 }

[simulation]
drive_time_constant = 0.002   # s  # assumed (a small arm's drives: a 2 ms lag)

# Home: KUKA's usual home position ($H_POS: A2 = -90, A3 = 90, the others 0; upper arm
# vertical, forearm horizontal).
# Accelerations: each axis reaches its maximum speed in 0.25 s; jerks: that acceleration in
# 0.1 s.  # assumed (KUKA publishes neither)
# Gears and encoders: 100:1 and 4096 counts per motor revolution.  # assumed

[[axis]]
name = "A1"
kind = "revolute"
min = -170.0                  # data sheet: +-170
max = 170.0
max_velocity = 360.0          # data sheet
max_acceleration = 1440.0     # assumed
max_jerk = 14400.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
direction = -1
dh = { a = 25.0, alpha = -90.0, d = 400.0 }

[[axis]]
name = "A2"
kind = "revolute"
min = -190.0                  # data sheet: +45 / -190
max = 45.0
home = -90.0
max_velocity = 300.0          # data sheet
max_acceleration = 1200.0     # assumed
max_jerk = 12000.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 455.0, alpha = 0.0, d = 0.0 }

[[axis]]
name = "A3"
kind = "revolute"
min = -120.0                  # data sheet: +156 / -120
max = 156.0
home = 90.0
max_velocity = 360.0          # data sheet
max_acceleration = 1440.0     # assumed
max_jerk = 14400.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 35.0, alpha = -90.0, d = 0.0, theta_offset = -90.0 }

[[axis]]
name = "A4"
kind = "revolute"
min = -185.0                  # data sheet: +-185
max = 185.0
max_velocity = 381.0          # data sheet
max_acceleration = 1524.0     # assumed
max_jerk = 15240.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
direction = -1
dh = { a = 0.0, alpha = 90.0, d = 420.0 }

[[axis]]
name = "A5"
kind = "revolute"
min = -120.0                  # data sheet: +-120
max = 120.0
max_velocity = 388.0          # data sheet
max_acceleration = 1552.0     # assumed
max_jerk = 15520.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 0.0, alpha = -90.0, d = 0.0 }

[[axis]]
name = "A6"
kind = "revolute"
min = -350.0                  # data sheet: +-350
max = 350.0
max_velocity = 615.0          # data sheet
max_acceleration = 2460.0     # assumed
max_jerk = 24600.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
direction = -1
dh = { a = 0.0, alpha = 0.0, d = 80.0, theta_offset = 180.0 }
