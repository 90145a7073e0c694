"""CSV text of the flight's 50 Hz rows compiled (:mod:`air_sitl.compiled`, group ``flight``):
``"%.Nf" % x`` of each float, byte for byte as CPython writes it, straight into a byte buffer.

CPython's ``%.Nf`` is the correctly rounded decimal of the float's exact binary value (ties
to even) with N digits after the point, a ``-`` on every negative value (``-0.0`` and those
that round to zero too). Here that value is computed exactly in integers: a finite ``x`` is
``M * 2**E`` (``M`` an integer below ``2**53``), so ``x * 10**N = M * 5**N * 2**(E + N)``, a
product of at most 74 bits shifted right and rounded to even on its remainder. Values that
are not finite or not below :data:`LIMIT` in size are left to the caller (the kernel
answers -1): it formats those rows with ``%`` itself.
"""

from __future__ import annotations

import math
import re

import numpy as np
import numpy.typing as npt

from air_sitl.compiled import compiled

Bytes = npt.NDArray[np.uint8]
Ints = npt.NDArray[np.int64]
LIMIT = 1e9  # |x| * 10**9 < 2**60: every rounded value fits an int64
MAX_DECIMALS = 9
_TWO_53 = 9007199254740992.0
_LOW32 = 0xFFFFFFFF
_ZERO, _MINUS, _POINT, _COMMA, _NEWLINE = 48, 45, 46, 44, 10


@compiled
def _scaled(ax: float, k: int) -> np.int64:
    """round(ax * 10**k), ties to even, of a positive ``ax`` below LIMIT, exactly."""
    m, e = math.frexp(ax)  # ax = m * 2**e, 0.5 <= m < 1: M = m * 2**53 is exact
    big = np.int64(m * _TWO_53)
    c = np.int64(5) ** k  # 5**k < 2**21
    s = 53 - e - k  # x * 10**k = big * c / 2**s
    if s <= 0:
        return big * c << -s  # an integer already (below 2**60)
    # big * c = hi * 2**32 + lo, in two int64 (hi < 2**42, lo < 2**32).
    pl = (big & _LOW32) * c  # < 2**53
    ph = (big >> 32) * c  # < 2**42
    hi = ph + (pl >> 32)
    lo = pl & _LOW32
    if s >= 75:
        return np.int64(0)  # big * c < 2**74 <= half of 2**s
    if s >= 32:
        t = s - 32
        q = hi >> t
        rem_hi = hi & ((np.int64(1) << t) - 1)
        # rem = rem_hi * 2**32 + lo against half = 2**(s - 1)
        if t == 0:
            above = lo > (np.int64(1) << 31)
            tie = lo == (np.int64(1) << 31)
        else:
            half_hi = np.int64(1) << (t - 1)
            above = rem_hi > half_hi or (rem_hi == half_hi and lo > 0)
            tie = rem_hi == half_hi and lo == 0
    else:
        q = (hi << (32 - s)) + (lo >> s)  # below 2**60 (the rounded value's size)
        rem = lo & ((np.int64(1) << s) - 1)
        half = np.int64(1) << (s - 1)
        above = rem > half
        tie = rem == half
    if above or (tie and q & 1):
        q += 1
    return q


@compiled
def _fixed(buf: Bytes, pos: int, x: float, k: int) -> int:
    """``"%.{k}f" % x`` written at ``pos``; the position after it, or -1 (not finite or not
    below LIMIT in size: nothing written)."""
    ax = abs(x)
    if not ax < LIMIT:  # NaN too
        return -1
    if x < 0.0 or (x == 0.0 and math.copysign(1.0, x) < 0.0):
        buf[pos] = _MINUS
        pos += 1
    q = _scaled(ax, k) if ax > 0.0 else np.int64(0)
    # q's digits, at least k + 1 of them (a zero before the point), the point before the k
    # last; written backwards into place.
    n = 1
    v = q // 10
    while v > 0:
        n += 1
        v //= 10
    n = max(n, k + 1)
    end = pos + n + (1 if k > 0 else 0)
    j = end - 1
    for d in range(n):
        if k > 0 and d == k:
            buf[j] = _POINT
            j -= 1
        buf[j] = _ZERO + q % 10
        q //= 10
        j -= 1
    return end


@compiled
def _integer(buf: Bytes, pos: int, v: int) -> int:
    """``"%d" % v`` written at ``pos``; the position after it."""
    if v < 0:
        buf[pos] = _MINUS
        pos += 1
        v = -v
    n = 1
    w = v // 10
    while w > 0:
        n += 1
        w //= 10
    for j in range(pos + n - 1, pos - 1, -1):
        buf[j] = _ZERO + v % 10
        v //= 10
    return pos + n


@compiled(
    "i8(u1[::1], i8, i8, UniTuple(f8, 17), i8[::1], u1[::1], i8, b1, UniTuple(f8, 7), i8[::1], i8)"
)
def trajectory_row(
    buf: Bytes, pos: int, time_ns: int, values: tuple[float, ...], decimals: Ints,
    mode: Bytes, seq: int, capturing: bool, extra: tuple[float, ...], extra_decimals: Ints,
    n_extra: int,
) -> int:  # fmt: skip
    """One row of trajectory.csv at ``pos``: ``time_ns``, the ``values`` (each with its
    ``decimals``), ``mode``'s text, ``seq`` and ``capturing`` as integers, then (``n_extra``
    > 0) the first ``n_extra`` of ``extra`` with theirs, or (``n_extra`` < 0) that many
    empty fields; a newline. The position after it, or -1 when a value is left to the caller
    (what was written then is not a row)."""
    pos = _integer(buf, pos, time_ns)
    for i in range(len(values)):
        buf[pos] = _COMMA
        pos = _fixed(buf, pos + 1, values[i], decimals[i])
        if pos < 0:
            return -1
    buf[pos] = _COMMA
    pos += 1
    for i in range(mode.size):
        buf[pos + i] = mode[i]
    pos += mode.size
    buf[pos] = _COMMA
    pos = _integer(buf, pos + 1, seq)
    buf[pos] = _COMMA
    pos = _integer(buf, pos + 1, 1 if capturing else 0)
    for i in range(n_extra):
        buf[pos] = _COMMA
        pos = _fixed(buf, pos + 1, extra[i], extra_decimals[i])
        if pos < 0:
            return -1
    for _ in range(-n_extra):
        buf[pos] = _COMMA
        pos += 1
    buf[pos] = _NEWLINE
    return pos + 1


def decimals(fmt: str) -> Ints:
    """The N of each ``%.Nf`` of a ``%`` format, in order (what :func:`trajectory_row`
    takes beside the values: the format stays the one home of the columns' text)."""
    found = [int(n) for n in re.findall(r"%\.(\d+)f", fmt)]
    if any(n > MAX_DECIMALS for n in found):
        msg = f"{fmt!r}: at most {MAX_DECIMALS} decimals"
        raise ValueError(msg)
    return np.array(found, dtype=np.int64)
