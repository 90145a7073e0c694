"""PX4 parameters the simulation serves for ground stations without flying by them.

QGroundControl and MAVProxy read these at connect for a PX4 fixed wing (airframe, identity,
failsafes, RTL, geofence, sensor calibration ids, estimator switches); a vehicle without them
looks misconfigured. Values are PX4 v1.14 defaults for a standard plane (SITL where PX4 SITL
differs); types are PX4's (INT32 or REAL32). The battery ones (BAT*, COM_LOW_BAT_ACT) are read
by :mod:`air_sitl.battery`.

Each entry: (name, default, is_int, unit, description).
"""

from __future__ import annotations

PX4_CONNECT_PARAMS: tuple[tuple[str, float, bool, str, str], ...] = (
    ("SYS_AUTOSTART", 2100, True, "", "airframe: 2100 standard plane"),
    ("SYS_AUTOCONFIG", 0, True, "", "airframe reset on next boot (0: keep)"),
    ("SYS_HITL", 0, True, "", "hardware in the loop (0: off)"),
    ("SYS_HAS_MAG", 1, True, "", "magnetometers present"),
    ("SYS_HAS_BARO", 1, True, "", "barometers present"),
    ("MAV_SYS_ID", 1, True, "", "MAVLink system id"),
    ("MAV_COMP_ID", 1, True, "", "MAVLink component id"),
    ("MAV_TYPE", 1, True, "", "MAV_TYPE: 1 fixed wing"),
    ("MAV_PROTO_VER", 0, True, "", "MAVLink protocol version (0: auto, 2 once heard)"),
    ("CAL_ACC0_ID", 1310988, True, "", "accelerometer 0 calibrated (device id)"),
    ("CAL_GYRO0_ID", 1310988, True, "", "gyroscope 0 calibrated (device id)"),
    ("CAL_MAG0_ID", 197388, True, "", "magnetometer 0 calibrated (device id)"),
    ("CAL_BARO0_ID", 6620172, True, "", "barometer 0 (device id)"),
    ("SENS_BOARD_ROT", 0, True, "", "board rotation (0: none)"),
    ("CBRK_SUPPLY_CHK", 894281, True, "", "circuit breaker: power supply check off"),
    ("CBRK_USB_CHK", 197848, True, "", "circuit breaker: USB check off"),
    ("CBRK_IO_SAFETY", 22027, True, "", "circuit breaker: safety switch off"),
    ("COM_RC_IN_MODE", 1, True, "", "manual control input: 1 joystick only (no RC)"),
    ("COM_RC_LOSS_T", 0.5, False, "s", "manual control loss timeout"),
    ("COM_DL_LOSS_T", 10, True, "s", "data link loss timeout"),
    ("COM_ARM_WO_GPS", 1, True, "", "arming without GPS: 1 allowed"),
    ("COM_DISARM_LAND", 2.0, False, "s", "disarm after landing"),
    ("COM_DISARM_PRFLT", 10.0, False, "s", "disarm when not taking off after arming"),
    ("COM_FLTMODE1", -1, True, "", "flight mode slot 1 (-1: unassigned)"),
    ("COM_LOW_BAT_ACT", 0, True, "", "low battery: 0 warn, 1 return, 2 land, 3 return then land"),
    ("NAV_DLL_ACT", 0, True, "", "data link loss action (0: disabled)"),
    ("NAV_RCL_ACT", 2, True, "", "manual control loss action (2: hold)"),
    ("NAV_FW_ALTL_RAD", 5.0, False, "m", "altitude acceptance radius before landing"),
    ("RTL_DESCEND_ALT", 30.0, False, "m", "RTL loiter altitude above home"),
    ("RTL_LAND_DELAY", -1.0, False, "s", "RTL: loiter before landing (-1: loiter, no landing)"),
    ("RTL_TYPE", 0, True, "", "RTL: 0 straight home"),
    ("MIS_DIST_1WP", 900.0, False, "m", "first waypoint farther than this: warning"),
    ("GF_ACTION", 3, True, "", "geofence breach: 3 return (what the vehicle does)"),
    ("GF_MAX_HOR_DIST", 0.0, False, "m", "geofence horizontal distance from home (0: off)"),
    ("GF_MAX_VER_DIST", 0.0, False, "m", "geofence altitude above home (0: off)"),
    ("EKF2_HGT_REF", 1, True, "", "height reference: 0 baro, 1 GNSS"),
    ("EKF2_BARO_CTRL", 1, True, "", "barometer fusion"),
    ("EKF2_MAG_TYPE", 0, True, "", "magnetometer fusion: 0 automatic"),
    ("EKF2_EV_DELAY", 0.0, False, "ms", "vision measurement delay"),
    ("BAT1_SOURCE", 0, True, "", "battery 1 source: 0 power module"),
    ("BAT1_N_CELLS", 4, True, "", "battery cells in series"),
    ("BAT1_CAPACITY", 5000.0, False, "mAh", "battery capacity"),
    ("BAT1_V_CHARGED", 4.05, False, "V", "cell voltage full (no load)"),
    ("BAT1_V_EMPTY", 3.5, False, "V", "cell voltage empty (no load)"),
    ("BAT1_R_INTERNAL", 0.02, False, "Ohm", "pack internal resistance (voltage sag)"),
    ("BAT_LOW_THR", 0.15, False, "", "low battery threshold (remaining fraction)"),
    ("BAT_CRIT_THR", 0.07, False, "", "critical battery threshold"),
    ("BAT_EMERGEN_THR", 0.05, False, "", "emergency battery threshold"),
)
