"""Seamless, deterministic noise on the absolute pixel lattice: a tile needs no neighbours.

Values come from hashing integer coordinates with the seed, so any tile of an unbounded world
is generated alone and two tiles always agree on their shared edge.
"""

from __future__ import annotations

import functools

import numpy as np
import numpy.typing as npt

FloatImage = npt.NDArray[np.float32]

_M1 = np.uint64(0x9E3779B97F4A7C15)
_M2 = np.uint64(0xC2B2AE3D27D4EB4F)
_M3 = np.uint64(0xBF58476D1CE4E5B9)
_M4 = np.uint64(0x94D049BB133111EB)
_MASK = 2**64 - 1


def hash2(ix: npt.NDArray[np.int64], iy: npt.NDArray[np.int64], key: int) -> npt.NDArray[np.uint64]:
    """A 64-bit hash of integer lattice coordinates (splitmix64 finaliser); wraps silently."""
    h = ix.astype(np.uint64) * _M1 ^ iy.astype(np.uint64) * _M2 ^ np.uint64(key & _MASK)
    h ^= h >> np.uint64(30)
    h *= _M3
    h ^= h >> np.uint64(27)
    h *= _M4
    h ^= h >> np.uint64(31)
    return h


def hash_int(*parts: int) -> int:
    """The same kind of hash for a few Python integers (no numpy overhead)."""
    h = 0x243F6A8885A308D3
    for p in parts:
        h = (h ^ ((p & _MASK) * 0x9E3779B97F4A7C15)) & _MASK
        h ^= h >> 30
        h = (h * 0xBF58476D1CE4E5B9) & _MASK
        h ^= h >> 27
        h = (h * 0x94D049BB133111EB) & _MASK
        h ^= h >> 31
    return h


def unit_of(*parts: int) -> float:
    """A uniform value in [0, 1) from a few integers."""
    return (hash_int(*parts) >> 11) * (1.0 / 2**53)


def unit2(
    ix: npt.NDArray[np.int64], iy: npt.NDArray[np.int64], key: int
) -> npt.NDArray[np.float64]:
    """Uniform values in [0, 1) from lattice coordinates."""
    return (hash2(ix, iy, key) >> np.uint64(11)).astype(np.float64) * (1.0 / 2**53)


def key_of(*parts: int) -> int:
    """Mix several integers (seed, salt, indices) into one hash key."""
    return hash_int(*parts)


def rng_for(*parts: int) -> np.random.Generator:
    """A numpy generator seeded by several integers (one world cell, one purpose)."""
    return np.random.default_rng(key_of(*parts))


@functools.lru_cache(maxsize=1024)
def _weights(
    start: float, size: int, cell: float
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.float32], int, int]:
    """Cubic B-spline taps from lattice nodes to pixel centres start..start+size-1.

    Returns (first tap index per pixel relative to the first node, 4 weights per pixel,
    first node index, node count).
    """
    q = (start + np.arange(size, dtype=np.float64)) / cell
    fl = np.floor(q)
    f = q - fl
    w = np.empty((size, 4), dtype=np.float32)
    w[:, 0] = (1 - f) ** 3 / 6.0
    w[:, 1] = (4.0 - 6.0 * f**2 + 3.0 * f**3) / 6.0
    w[:, 2] = (1.0 + 3.0 * f + 3.0 * f**2 - 3.0 * f**3) / 6.0
    w[:, 3] = f**3 / 6.0
    i0 = int(fl[0]) - 1
    idx = (fl.astype(np.intp) - 1) - i0
    return idx, w, i0, int(idx[-1]) + 4


def value_noise(key: int, x0: float, y0: float, size: int, cell_px: float) -> FloatImage:
    """Smooth noise (cubic B-spline over a hashed lattice), about zero mean and unit std.

    ``(x0, y0)`` is the absolute position of the tile's first pixel centre in pixels;
    ``cell_px`` the lattice spacing (feature size) in pixels. Separable: 4 taps per axis.
    """
    idx_x, wx, ix0, nx = _weights(float(x0), size, float(cell_px))
    idx_y, wy, iy0, ny = _weights(float(y0), size, float(cell_px))
    iy = np.arange(iy0, iy0 + ny, dtype=np.int64)
    ix = np.arange(ix0, ix0 + nx, dtype=np.int64)
    lattice = unit2(ix[None, :], iy[:, None], key).astype(np.float32) * 2.0 - 1.0
    rows = lattice[:, idx_x] * wx[:, 0]
    for k in range(1, 4):
        rows += lattice[:, idx_x + k] * wx[:, k]
    out = rows[idx_y] * wy[:, 0:1]
    for k in range(1, 4):
        out += rows[idx_y + k] * wy[:, k : k + 1]
    # B-spline smoothing shrinks the std of uniform [-1, 1] (0.577) to about 0.16.
    result: FloatImage = out * np.float32(1.0 / 0.16)
    return result


def fractal_noise(
    key: int, x0: float, y0: float, size: int, cell_px: float, octaves: int, gain: float = 0.5
) -> FloatImage:
    """Sum of ``octaves`` value noises halving the cell each time, normalised to unit std."""
    total = np.zeros((size, size), dtype=np.float32)
    amp = 1.0
    norm = 0.0
    cell = cell_px
    for o in range(octaves):
        if cell < 0.75:
            break
        total += np.float32(amp) * value_noise(key + 7919 * o, x0, y0, size, cell)
        norm += amp * amp
        amp *= gain
        cell /= 2.0
    return total * np.float32(1.0 / np.sqrt(max(norm, 1e-9)))


def white_noise(key: int, x0: int, y0: int, size: int) -> FloatImage:
    """Per-pixel uniform noise in [-1, 1) on the absolute lattice (film grain, gravel)."""
    iy = np.arange(y0, y0 + size, dtype=np.int64)[:, None]
    ix = np.arange(x0, x0 + size, dtype=np.int64)[None, :]
    return (unit2(ix, iy, key) * 2.0 - 1.0).astype(np.float32)
