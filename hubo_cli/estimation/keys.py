"""The estimate's keys in the per-period store: one home for each estimated quantity.

Frames: ``world`` (z up, the floor at z = 0 where the robot started), ``torso`` (the neck frame
N of the kinematics, the IMU's body), the soles (``right_sole``, ``left_sole``: the sole's
middle on the floor, x forward), the force-torque sensors' own frames (``state.FT_SENSORS``).
Feet are always ordered (right, left).
"""

from __future__ import annotations

import numpy as np

from hubo_cli.dataflow import Key

CONTACT = Key("contact_feet", tuple,
              "(right, left): the sole carries load (one filter, one debounce)")
WRENCHES = Key("wrenches_compensated", dict,
               "sensor name -> [fx fy fz mx my mz] (N, N m) in the sensor's frame, the links' "
               "and the held tool's weight removed (at the wrists their inertia too); components a "
               "sensor lacks are 0")
QUAT_WORLD_TORSO = Key("quat_world_torso_wxyz", np.ndarray,
                       "torso attitude in the world (unit quaternion w x y z), estimated")
GYRO_BIAS = Key("gyro_bias_torso_rad_s", np.ndarray,
                "the gyro's estimated bias in the torso frame (rad/s)")
OMEGA_TORSO = Key("omega_torso_rad_s", np.ndarray,
                  "torso angular rate in the torso frame, bias removed (rad/s)")
IMU_REJECTED = Key("imu_rejected", tuple,
                   "(gyro, accelerometer): this period's reading was not used (not finite or "
                   "beyond the sensor's range; a rejected gyro holds the attitude), or the "
                   "gyro's estimated bias is beyond any working gyro's")
T_WORLD_TORSO = Key("T_world_torso", np.ndarray,
                    "torso pose in the world (4x4, m), from the legs anchored at the loaded "
                    "sole and the estimated attitude")
T_WORLD_SOLES = Key("T_world_soles", np.ndarray,
                    "(2, 4, 4): right and left sole poses in the world (m)")
T_TORSO_SOLES = Key("T_torso_soles", np.ndarray,
                    "(2, 4, 4): right and left sole poses in the torso frame (m), the legs' "
                    "forward kinematics of this period's joints (None when they are not "
                    "finite): worked out once a period for the layer's observers")
SOLES_FLAT = Key("soles_flat", tuple,
                 "(right, left): the sole lies flat on the floor, as the attitude's legs "
                 "measurement judges it (in contact, pressing legs_min_fz_n with its centre of "
                 "pressure legs_cop_margin_m inside its outline; the last period's contact and "
                 "wrenches)")
COM_WORLD = Key("com_world_m", np.ndarray, "centre of mass in the world (3, m)")
COM_VELOCITY_WORLD = Key("com_velocity_world_m_s", np.ndarray,
                         "centre-of-mass velocity in the world (3, m/s), filtered")
CAPTURE_POINT_WORLD = Key("capture_point_world_m", np.ndarray,
                          "instantaneous capture point on the floor (x, y; m)")
ZMP_WORLD = Key("zmp_world_m", np.ndarray,
                "ZMP of the soles in contact on the floor (x, y; m); NaN with no contact")

ESTIMATE_KEYS = (CONTACT, WRENCHES, QUAT_WORLD_TORSO, GYRO_BIAS, OMEGA_TORSO, IMU_REJECTED,
                 T_WORLD_TORSO, T_WORLD_SOLES, COM_WORLD, COM_VELOCITY_WORLD,
                 CAPTURE_POINT_WORLD, ZMP_WORLD)
