"""Turn vs straight: a frame is in a turn where the truth yaw rate exceeds 3 deg/s.

The yaw rate is the derivative of the unwrapped truth heading, smoothed by a centred moving
average over 1 s (SPEC section 5).
"""

from __future__ import annotations

import numpy as np

from air_sitl.eval.trajectory import F64, I64, Bools

TURN_RATE_DEG_S = 3.0
SMOOTH_S = 1.0


def yaw_rate_rad_s(t_ns: I64, yaw_rad: F64, smooth_s: float = SMOOTH_S) -> F64:
    """Smoothed yaw rate at each sample (centred moving average over ``smooth_s``)."""
    n = t_ns.shape[0]
    if n < 2:
        return np.zeros(n)
    t_s = (t_ns - t_ns[0]).astype(np.float64) / 1e9
    rate = np.gradient(np.unwrap(yaw_rad), t_s)
    period_s = float(np.median(np.diff(t_s)))
    half = max(round(smooth_s / period_s / 2.0), 0) if period_s > 0 else 0
    if half == 0:
        return rate
    # centred window of 2*half+1 samples, shortened at both ends
    c = np.concatenate(([0.0], np.cumsum(rate)))
    k = np.arange(n)
    lo = np.maximum(k - half, 0)
    hi = np.minimum(k + half + 1, n)
    smoothed: F64 = (c[hi] - c[lo]) / (hi - lo)
    return smoothed


def turn_mask(t_ns: I64, yaw_rad: F64, threshold_deg_s: float = TURN_RATE_DEG_S) -> Bools:
    """True for frames in a turn."""
    rate = yaw_rate_rad_s(t_ns, yaw_rad)
    mask: Bools = np.abs(rate) > np.radians(threshold_deg_s)
    return mask
