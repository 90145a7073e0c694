"""The map-matcher's score map depends on its inputs only, not on where they sit in memory.

``cv2.magnitude`` rounded with the alignment of its output buffer (IPP), which numpy places
after whatever was allocated before; the online map-matcher then gave a few ppm different
answers from run to run. Here the same patch and reference are put at every offset of a
64-byte line (which moves every later allocation too): one score map.
"""

from __future__ import annotations

import hashlib

import numpy as np
import numpy.typing as npt

from air_sitl.localize.mapmatch_core import Rectified, orientation_correlation


def at(a: npt.NDArray[np.uint8], offset: int) -> npt.NDArray[np.uint8]:
    """A copy of ``a`` starting ``offset`` bytes into a fresh buffer."""
    buf = np.empty(a.nbytes + 64, np.uint8)
    out = buf[offset : offset + a.nbytes].reshape(a.shape)
    out[:] = a
    return out


def test_orientation_correlation_is_the_same_at_any_alignment() -> None:
    rng = np.random.default_rng(0)
    ph, pw, margin = 150, 170, 60
    patch = rng.integers(0, 255, (ph, pw), dtype=np.uint8)
    patch_mask = np.zeros((ph, pw), np.uint8)
    patch_mask[5:-5, 8:-8] = 255
    reference = rng.integers(0, 255, (ph + 2 * margin, pw + 2 * margin), dtype=np.uint8)
    reference_mask = np.full(reference.shape, 255, np.uint8)
    digests = set()
    for offset in range(0, 64, 3):
        rect = Rectified(
            patch=at(patch, offset),
            patch_mask=at(patch_mask, (offset * 7) % 64),
            reference=at(reference, (offset * 13) % 64),
            reference_mask=at(reference_mask, (offset * 5) % 64),
            margin_px=margin,
            level=0,
            gsd_m=1.0,
            height_m=100.0,
            prior_east_m=0.0,
            prior_north_m=0.0,
        )
        score, _ = orientation_correlation(rect)
        digests.add(hashlib.sha256(score.tobytes()).hexdigest())
    assert len(digests) == 1
