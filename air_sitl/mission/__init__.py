"""Missions: one MissionItem type for QGC plan files and MAVLink uploads, plan I/O, validation."""
