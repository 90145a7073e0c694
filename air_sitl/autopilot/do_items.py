"""DO_* mission items: what each does when the sequencer reaches it, and what it leaves behind.

As PX4: DO_JUMP's counter is on the jump item (taken while ``count < repeat``);
DO_CHANGE_SPEED sets an airspeed, or a ground speed flown with the estimated wind; the capture
items open and close the capture window (a DO_DIGICAM_CONTROL shot keeps it open for one
camera frame). The sequencer (:mod:`air_sitl.autopilot.sequencer`) runs them in mission order.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from air_sitl.autopilot.params import GuidanceParams
from air_sitl.mission.items import MavCmd, MissionItem
from air_sitl.state import VehicleState

WIND_FILTER_GAIN = 0.02  # per 50 Hz guidance update: about a 1 s time constant


class DoItems:
    """The DO items of a mission and their state: jump counters, the speed asked for, a shot.

    ``emit`` reports an event (STATUSTEXT); ``set_capture`` opens or closes the capture window.
    """

    def __init__(self, emit: Callable[[str], None], set_capture: Callable[[bool], None]) -> None:
        self._emit = emit
        self._set_capture = set_capture
        self.jump_counts: dict[int, int] = {}  # DO_JUMP item index -> jumps taken
        self.single_frame = False  # DO_DIGICAM_CONTROL shot: the window closes after a frame
        self._speed_m_s: float | None = None  # DO_CHANGE_SPEED's, or a command's
        self._ground_speed = False  # that speed is a ground speed
        self._wind_ne = (0.0, 0.0)  # wind estimate (ground minus air velocity), low-passed

    def new_mission(self) -> None:
        """A mission was loaded: its jump counters start at zero, no shot is pending."""
        self.jump_counts = {}
        self.single_frame = False

    def set_speed(self, speed_m_s: float | None, *, ground: bool = False) -> None:
        """Fly ``speed_m_s`` (an airspeed, or a ground speed); None: the default speed."""
        self._speed_m_s = speed_m_s
        self._ground_speed = ground

    def update(self, state: VehicleState) -> None:
        """Once per guidance update, before the tasks: the wind estimate, the end of a shot."""
        if self._ground_speed:
            self._estimate_wind(state)
        if self.single_frame:
            self.single_frame = False
            self._set_capture(False)

    def airspeed(self, p: GuidanceParams, course_rad: float) -> float | None:
        """The airspeed that flies the speed asked for along ``course_rad``; None when none was."""
        if self._speed_m_s is None:
            return None
        if not self._ground_speed:
            return p.clamp_speed(self._speed_m_s)
        # Airspeed that makes the ground speed along the current course the one asked for.
        wn, we = self._wind_ne
        c, s = math.cos(course_rad), math.sin(course_rad)
        along = wn * c + we * s
        across = we * c - wn * s
        return p.clamp_speed(math.hypot(self._speed_m_s - along, across))

    def _estimate_wind(self, state: VehicleState) -> None:
        """Wind = ground velocity - air velocity (truth airspeed along the heading), low-passed."""
        if state.on_ground:
            return
        v_air = state.airspeed_m_s * math.cos(state.pitch_rad)
        wn = state.vel_ned_m_s[0] - v_air * math.cos(state.yaw_rad)
        we = state.vel_ned_m_s[1] - v_air * math.sin(state.yaw_rad)
        k = WIND_FILTER_GAIN
        self._wind_ne = (
            self._wind_ne[0] + k * (wn - self._wind_ne[0]),
            self._wind_ne[1] + k * (we - self._wind_ne[1]),
        )

    def run(self, items: Sequence[MissionItem], seq: int, *, capturing: bool) -> int:
        """Execute DO item ``seq``; return the index to continue with."""
        item = items[seq]
        cmd = item.command
        if cmd == MavCmd.DO_JUMP:
            count = self.jump_counts.get(seq, 0)
            if count < item.param2:
                self.jump_counts[seq] = count + 1
                target = int(item.param1)
                self._emit(f"Jump to item {target} ({count + 1}/{int(item.param2)})")
                return target
            return seq + 1
        if cmd == MavCmd.DO_CHANGE_SPEED:
            if item.param1 in (0.0, 1.0) and item.param2 > 0.0:
                self.set_speed(item.param2, ground=item.param1 == 1.0)
                kind = "ground" if self._ground_speed else "air"
                self._emit(f"Speed set to {item.param2:g} m/s ({kind})")
        elif cmd == MavCmd.IMAGE_START_CAPTURE:
            self._set_capture(True)
        elif cmd == MavCmd.IMAGE_STOP_CAPTURE:
            self._set_capture(False)
        elif cmd == MavCmd.DO_SET_CAM_TRIGG_DIST:
            # Frames come at the camera rate: a distance opens the window, 0 closes it.
            self.single_frame = False
            self._set_capture(item.param1 > 0.0)
        elif cmd == MavCmd.DO_DIGICAM_CONTROL and item.lat_deg == 1.0 and not capturing:
            # param5 = 1: one shot; the window stays open for one camera frame.
            self.single_frame = True
            self._set_capture(True)
        return seq + 1
