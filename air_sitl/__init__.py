"""air-sitl: software-in-the-loop harness for fixed-wing UAV localization research."""

__version__ = "0.1.0"
