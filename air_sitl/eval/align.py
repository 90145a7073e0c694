"""Alignment of an estimated trajectory onto the truth before scoring.

- ``none``: absolute, georeferenced localizers are scored as they are;
- ``se3`` / ``sim3``: Umeyama's least squares rigid (with scale for monocular VO), evo's
  :func:`evo.core.geometry.umeyama_alignment`;
- ``posyaw``: 4-DoF for VIO (translation and a rotation about the vertical only), the closed
  form of rpg_trajectory_evaluation (``align_trajectory.py``, ``alignPositionYaw``).

Every alignment maps estimate positions ``p`` to ``s * R @ p + t``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from air_sitl.eval.trajectory import F64

ALIGNMENTS = ("none", "posyaw", "se3", "sim3")


@dataclass(frozen=True, slots=True, kw_only=True)
class Alignment:
    """A similarity transform ``p -> scale * rotation @ p + translation``."""

    rotation: F64  # (3, 3)
    translation: F64  # (3,)
    scale: float

    def apply(self, points_m: F64) -> F64:
        """The transform applied to (K, 3) points."""
        out: F64 = self.scale * points_m @ self.rotation.T + self.translation
        return out


IDENTITY = Alignment(rotation=np.eye(3), translation=np.zeros(3), scale=1.0)


def rot_z(yaw_rad: float) -> F64:
    """Rotation by ``yaw_rad`` about the vertical (z up)."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def posyaw(est_m: F64, truth_m: F64) -> Alignment:
    """Translation and yaw minimising the squared distances (rpg ``alignPositionYaw``).

    With centred positions d (estimate) and m (truth), trace(Rz(yaw) C) with C = sum d m^T is
    largest at yaw = atan2(sum d x m (vertical component), sum d . m (horizontal)).
    """
    mu_est = est_m.mean(axis=0)
    mu_truth = truth_m.mean(axis=0)
    d = est_m[:, :2] - mu_est[:2]
    m = truth_m[:, :2] - mu_truth[:2]
    cross = float(np.sum(d[:, 0] * m[:, 1] - d[:, 1] * m[:, 0]))
    dot = float(np.sum(d[:, 0] * m[:, 0] + d[:, 1] * m[:, 1]))
    rotation = rot_z(np.arctan2(cross, dot))
    return Alignment(rotation=rotation, translation=mu_truth - rotation @ mu_est, scale=1.0)


def umeyama(est_m: F64, truth_m: F64, *, with_scale: bool) -> Alignment | None:
    """evo's Umeyama alignment; None when it is not possible (too few or collinear points)."""
    from evo.core.geometry import GeometryException, umeyama_alignment  # evo: slow import

    if est_m.shape[0] < 3:
        return None
    try:
        r, t, c = umeyama_alignment(est_m.T, truth_m.T, with_scale)
    except GeometryException:
        return None
    return Alignment(rotation=np.asarray(r), translation=np.asarray(t), scale=float(c))


def fit(method: str, est_m: F64, truth_m: F64) -> Alignment | None:
    """The alignment ``method`` of the estimate onto the truth; None when not computable."""
    if method == "none" or est_m.shape[0] == 0:
        return IDENTITY  # nothing estimated: nothing to move, every frame is a miss
    if method == "posyaw":
        return posyaw(est_m, truth_m)
    if method in ("se3", "sim3"):
        return umeyama(est_m, truth_m, with_scale=method == "sim3")
    msg = f"unknown alignment {method!r} (expected one of {', '.join(ALIGNMENTS)})"
    raise ValueError(msg)
