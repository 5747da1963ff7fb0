# System specification of the Staubli TX2-60: six-axis arm, 3.5 kg nominal payload (4.5 kg
# maximum), 670 mm reach.
#
# Sources
#   Geometry, joint directions and the flange: ROS-Industrial,
#     github.com/ros-industrial/staubli_experimental, staubli_tx2_60_support/urdf/tx2_60_macro.xacro
#     (commit f3c3ae1, 2020-02-25). Its joint values are the controller's J1..J6.
#   Joint ranges and speeds: the Staubli TX2-60 data sheet (amplitude and nominal speed per
#     axis), as the URDF's <limit> tags carry them (in rad, rad/s; "nominal velocity limits
#     are used", says the file). Reach and payload: the data sheet.
#   Everything marked "# assumed" is not published (accelerations, jerks, gear ratios,
#   encoders, the simulated drives): plausible values, to be replaced by measured ones.
#
# Convention: standard Denavit-Hartenberg (runtime/motion/kinematics.py): link i is
#   Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i), theta_i = q_i + theta_offset_i, q_i the joint
#   value. Frame 0 is the URDF's "base" (Staubli's world frame: on axis 1 at the height of
#   axis 2, 375 mm above the foot's base_link; z up, x forward); frame 6 is the URDF's tool0
#   (= link_6: flange, then back by the same rotation: z out of the flange, which points up
#   at the zero position, the arm upright). Every <axis> is positive. From the URDF (mm):
#     joint_1  origin 0 0 375     axis +z   z0 = +z; axis 2 crosses axis 1 at the base: d1 = a1 = 0
#     joint_2  origin 0 0 0       axis +y   z1 = +y: alpha1 = -90
#     joint_3  origin 0 20 290    axis +y   the upper arm is vertical at J2 = 0: a2 = 290,
#                                           theta_offset2 = -90; 20 to the side: d2 = 20
#                                           (a lateral shoulder offset); z2 = +y (alpha2 = 0)
#     joint_4  origin 0 0 0       axis +z   crosses axis 3: a3 = 0; its x points back (-x):
#                                           theta_offset3 = -90; z3 = +z: alpha3 = -90
#     joint_5  origin 0 0 310     axis +y   on axis 4, 310 along it: d4 = 310; z4 = +y: alpha4 = 90
#     joint_6  origin 0 0 70      axis +z   through the wrist centre: a5 = d5 = 0; z5 = +z: alpha5 = -90
#     tool0     link_6 (flange: rpy(0, -90 deg, 0); tool0: rpy(0, 90 deg, 0) from the flange):
#                                           70 beyond the wrist centre: d6 = 70; its x is
#                                           forward (frame 5's x is back): theta_offset6 = 180
#   tests/test_real_arms.py checks this table against the URDF's chain.
# Units: deg, deg/s, deg/s^2, deg/s^3; mm, mm/s, mm/s^2.

[robot]
name = "staubli_tx2_60"
description = "Staubli TX2-60, 3.5 kg, 670 mm reach (data sheet and ROS-Industrial URDF)"
max_speed = 2000.0            # mm/s, tool centre point  # assumed (not in the data sheet)
max_acceleration = 10000.0    # mm/s^2                   # assumed

[kinematics]
# The default tool is the flange itself (tool0): frame 6 of the chain below is that frame,
# so a tool measured on the real robot is a [[tool]] as it is.
tool = { x = 0.0, y = 0.0, z = 0.0, roll = 0.0, pitch = 0.0, yaw = 0.0 }

[simulation]
drive_time_constant = 0.002   # s  # assumed (a small arm's drives: a 2 ms lag)

# Home: a ready position, upper arm vertical, forearm horizontal and the flange pointing down
# (J3 = 90, J5 = 90; the zero position, the arm upright, is stretched and singular).
# Accelerations: each axis reaches its nominal speed in 0.25 s; jerks: that acceleration in
# 0.1 s.  # assumed (Staubli publishes neither)
# Gears and encoders: 100:1 and 4096 counts per motor revolution.  # assumed

[[axis]]
name = "J1"
kind = "revolute"
min = -180.0                  # data sheet: +-180
max = 180.0
max_velocity = 435.0          # data sheet (nominal)
max_acceleration = 1740.0     # assumed
max_jerk = 17400.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 0.0, alpha = -90.0, d = 0.0 }

[[axis]]
name = "J2"
kind = "revolute"
min = -127.5                  # data sheet: +-127.5
max = 127.5
max_velocity = 385.0          # data sheet (nominal)
max_acceleration = 1540.0     # assumed
max_jerk = 15400.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 290.0, alpha = 0.0, d = 20.0, theta_offset = -90.0 }

[[axis]]
name = "J3"
kind = "revolute"
min = -152.5                  # data sheet: +-152.5
max = 152.5
home = 90.0
max_velocity = 500.0          # data sheet (nominal)
max_acceleration = 2000.0     # assumed
max_jerk = 20000.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 0.0, alpha = -90.0, d = 0.0, theta_offset = -90.0 }

[[axis]]
name = "J4"
kind = "revolute"
min = -270.0                  # data sheet: +-270
max = 270.0
max_velocity = 995.0          # data sheet (nominal)
max_acceleration = 3980.0     # assumed
max_jerk = 39800.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 0.0, alpha = 90.0, d = 310.0 }

[[axis]]
name = "J5"
kind = "revolute"
min = -121.0                  # data sheet: +132.5 / -121
max = 132.5
home = 90.0
max_velocity = 1065.0         # data sheet (nominal)
max_acceleration = 4260.0     # assumed
max_jerk = 42600.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 0.0, alpha = -90.0, d = 0.0 }

[[axis]]
name = "J6"
kind = "revolute"
min = -270.0                  # data sheet: +-270
max = 270.0
max_velocity = 1445.0         # data sheet (nominal)
max_acceleration = 5780.0     # assumed
max_jerk = 57800.0            # assumed
gear_ratio = 100.0            # assumed
encoder_counts = 4096         # assumed
dh = { a = 0.0, alpha = 0.0, d = 70.0, theta_offset = 180.0 }
