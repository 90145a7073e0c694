"""Mission items for round-trip tests (MAVLink messages, plan params)."""

from __future__ import annotations

import math

from air_sitl.mission.items import MavCmd, MavFrame, MissionItem

# Every field given: two turns of a counter-clockwise (negative radius) circle, no heading
# (NaN), a frame other than the default, a jump id.
LOITER_TURNS = MissionItem(
    command=MavCmd.NAV_LOITER_TURNS,
    frame=MavFrame.GLOBAL,
    param1=2.0,
    param2=0.0,
    param3=-90.0,
    param4=math.nan,
    lat_deg=54.7,
    lon_deg=25.3,
    alt_m=300.0,
    do_jump_id=4,
)
