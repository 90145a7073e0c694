"""Autopilot: mission executor and guidance (what to fly) and control (how to fly it)."""
