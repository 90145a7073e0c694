"""The camera's default settings and effect names: plain values, no imports, so that the
command-line parsers can show them without loading the renderer (numpy, OpenCV)."""

from __future__ import annotations

# Gazebo's camera sensors (as PX4 SITL used for AIR) add Gaussian noise of stddev 0.007 of
# full scale: 1.8 grey levels of 255.
DEFAULT_NOISE_SIGMA = 1.8
DEFAULT_JPEG_QUALITY = 90

# The camera effects that can be switched on (air_sitl.camera.effects), in their order.
EFFECT_NAMES = ("blur", "rolling-shutter", "vignette", "exposure", "haze", "distortion")
