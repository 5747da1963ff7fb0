# System specification of the Yaskawa Motoman GP8: six-axis arm, 8 kg payload, 727 mm reach.
#
# Sources
#   Geometry, joint directions and the flange: ROS-Industrial, github.com/ros-industrial/motoman,
#     motoman_gp8_support/urdf/gp8_macro.xacro (commit 3a9f58e, 2021-05-15). Its joint
#     values are the controller's S, L, U, R, B, T (as MotoROS reports them).
#   Joint ranges and speeds: the Motoman GP8 data sheet (maximum motion range and maximum
#     speed per axis). The URDF's <limit> tags carry them converted to rad and rad/s, three of
#     them rounded up past the data sheet's numbers: L 6.7495 rad/s (386.7 deg/s, data sheet
#     385), T 17.4845 rad/s (1001.8 deg/s, data sheet 1000) and T +-6.2944 rad (+-360.6 deg,
#     data sheet +-360): the data sheet's are used. Reach and payload: the data sheet.
#   Everything marked "# assumed" is not published (accelerations, jerks, gear ratios,
#   encoders, the simulated drives): plausible values, to be replaced by measured ones.
#
# Convention: standard Denavit-Hartenberg (runtime/motion/kinematics.py): link i is
#   Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i), theta_i = direction_i * q_i + theta_offset_i,
#   q_i the joint value. Frame 0 is the URDF's "base" (Yaskawa's robot frame: on the S axis
#   at the height of the L axis, 330 mm above the foot's base_link; z up, x forward); frame 6
#   is the URDF's tool0 (the flange: z out of it, x up at the zero position). Each z_{i-1}
#   points along its axis to +x, +y or +z at the zero position; direction = -1 where the
#   URDF's <axis> points the other way (U, R, B, T). From the URDF (mm):
#     joint_1_s  origin 0 0 330      axis +z   z0 = +z; axis 2 at the base's height: d1 = 0
#     joint_2_l  origin 40 0 0       axis +y   a1 = 40; z1 = +y: alpha1 = -90
#     joint_3_u  origin 0 0 345      axis -y   the lower arm is vertical at L = 0: a2 = 345,
#                                              theta_offset2 = -90; z2 = +y (alpha2 = 0),
#                                              direction -1
#     joint_4_r  origin 340 0 40     axis -x   axis 4 is 40 above axis 3: a3 = 40 (frame 2's x
#                                              is up: theta_offset3 = 0); z3 = +x: alpha3 = -90,
#                                              direction -1
#     joint_5_b  origin 0 0 0        axis -y   on axis 4, 340 along it: d4 = 340; z4 = +y:
#                                              alpha4 = 90, direction -1
#     joint_6_t  origin 0 0 0        axis -x   through the wrist centre: a5 = d5 = 0; z5 = +x:
#                                              alpha5 = -90, direction -1
#     tool0      link_6_t + xyz(80, 0, 0) rpy(3.1415926, -1.570796, 0) (pi and -pi/2, rounded
#                                              in the file): 80 beyond the wrist centre:
#                                              d6 = 80; its x is up, as frame 5's: theta_offset6 = 0
#   tests/test_real_arms.py checks this table against the URDF's chain.
# Units: deg, deg/s, deg/s^2, deg/s^3; mm, mm/s, mm/s^2.

[robot]
name = "yaskawa_gp8"
description = "Yaskawa Motoman GP8, 8 kg, 727 mm reach (data sheet and ROS-Industrial URDF)"
max_speed = 2000.0            # mm/s, tool centre point  # assumed (not in the data sheet)
max_acceleration = 10000.0    # mm/s^2                   # assumed

[kinematics]
# The default tool is the flange itself (tool0): frame 6 of the chain below is that frame,
# so a tool measured on the real robot is a [[tool]] as it is.
tool = { x = 0.0, y = 0.0, z = 0.0, roll = 0.0, pitch = 0.0, yaw = 0.0 }

[simulation]
drive_time_constant = 0.002   # s  # assumed (a small arm's drives: a 2 ms lag)

# Home: the zero position, where the controller's axes are calibrated (lower arm vertical,
# upper arm horizontal, the flange forward).
# Accelerations: each axis reaches its maximum speed in 0.25 s; jerks: that acceleration in
# 0.1 s.  # assumed (Yaskawa publishes neither)
# Gears and encoders: 100:1 and 4096 counts per motor revolution.  # assumed

[[axis]]
name = "S"
kind = "revolute"
min = -170.0                  # data sheet: +-170
max = 170.0
max_velocity = 455.0          # data sheet
max_acceleration = 1820.0     # assumed
max_jerk = 18200.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 40.0, alpha = -90.0, d = 0.0 }

[[axis]]
name = "L"
kind = "revolute"
min = -65.0                   # data sheet: +145 / -65
max = 145.0
max_velocity = 385.0          # data sheet
max_acceleration = 1540.0     # assumed
max_jerk = 15400.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 345.0, alpha = 0.0, d = 0.0, theta_offset = -90.0 }

[[axis]]
name = "U"
kind = "revolute"
min = -70.0                   # data sheet: +190 / -70
max = 190.0
max_velocity = 520.0          # data sheet
max_acceleration = 2080.0     # assumed
max_jerk = 20800.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
direction = -1
dh = { a = 40.0, alpha = -90.0, d = 0.0 }

[[axis]]
name = "R"
kind = "revolute"
min = -190.0                  # data sheet: +-190
max = 190.0
max_velocity = 550.0          # data sheet
max_acceleration = 2200.0     # assumed
max_jerk = 22000.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
direction = -1
dh = { a = 0.0, alpha = 90.0, d = 340.0 }

[[axis]]
name = "B"
kind = "revolute"
min = -135.0                  # data sheet: +-135
max = 135.0
max_velocity = 550.0          # data sheet
max_acceleration = 2200.0     # assumed
max_jerk = 22000.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
direction = -1
dh = { a = 0.0, alpha = -90.0, d = 0.0 }

[[axis]]
name = "T"
kind = "revolute"
min = -360.0                  # data sheet: +-360
max = 360.0
max_velocity = 1000.0         # data sheet
max_acceleration = 4000.0     # assumed
max_jerk = 40000.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
direction = -1
dh = { a = 0.0, alpha = 0.0, d = 80.0 }
