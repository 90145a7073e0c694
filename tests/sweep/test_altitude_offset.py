"""``fly --altitude-offset M``: flown altitudes shifted, landing and capture items unchanged."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
import short_plans

from air_sitl.builder import load_setup
from air_sitl.errors import OptionError
from air_sitl.mission.geometry import shift_altitudes
from air_sitl.mission.items import MavCmd, Mission, MissionItem
from air_sitl.options import FlightOptions, add_flight_arguments, flight_options_from_args
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=38.54, lon_deg=-121.49, alt_amsl_m=10.0)


def test_every_flown_altitude_moves_and_nothing_else(tmp_path: Path) -> None:
    plan = short_plans.write_short_plan(tmp_path / "UT-200.plan", HOME, leg_m=30.0)
    plain = load_setup(plan, FlightOptions())
    high = load_setup(plan, FlightOptions(altitude_offset_m=800.0))
    for a, b in zip(plain.mission.items, high.mission.items, strict=True):
        flown = a.command in (MavCmd.NAV_TAKEOFF, MavCmd.NAV_WAYPOINT)
        assert b.alt_m == (a.alt_m + 800.0 if flown else a.alt_m)
        assert (b.command, b.lat_deg, b.lon_deg, b.param2) == (
            a.command, a.lat_deg, a.lon_deg, a.param2,
        )  # fmt: skip
    assert high.home == plain.home


def test_land_keeps_its_altitude_and_amsl_items_stay_above_home() -> None:
    land = MissionItem(command=MavCmd.NAV_LAND, lat_deg=38.54, lon_deg=-121.49, alt_m=0.0)
    wp_amsl = MissionItem(command=MavCmd.NAV_WAYPOINT, frame=0, lat_deg=38.541,
                          lon_deg=-121.49, alt_m=110.0)  # fmt: skip
    mission = Mission(items=(wp_amsl, land), planned_home=HOME)
    shifted = shift_altitudes(mission, -50.0, HOME)
    assert [i.alt_m for i in shifted.items] == [60.0, 0.0]
    with pytest.raises(OptionError, match=r"item 0: altitude 110 m would be -10 m above home"):
        shift_altitudes(mission, -110.0, HOME)


def test_the_option_is_a_number_of_metres() -> None:
    parser = argparse.ArgumentParser()
    add_flight_arguments(parser, default_speed=0.0)
    args = parser.parse_args(["--altitude-offset", "-100"])
    assert flight_options_from_args(args).altitude_offset_m == -100.0
    with pytest.raises(OptionError, match="--altitude-offset: 'high'"):
        flight_options_from_args(parser.parse_args(["--altitude-offset", "high"]))
