"""The delayed fusion horizon: IMU delta buffer, per-source measurement buffers, output predictor.

As in PX4 EKF2, the filter itself runs ``fusion_horizon`` behind the newest IMU sample, so a
measurement that arrives late (up to the horizon) is fused at the time it refers to. The
estimate of *now* comes from an output predictor: the same strapdown integration run ahead
over the IMU deltas that the delayed filter has not reached yet. Each correction of the
delayed state is carried forward to the output state to first order (position by the
velocity correction times the window, velocity by the attitude correction crossed with the
specific-force increment of the window); once a second the output is recomputed exactly by
replaying the buffered deltas from the delayed state.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Generic, TypeVar

from air_sitl.nav.ekf import integrate, rotate_global, rotation_matrix

T = TypeVar("T")
NEVER = 2**63  # the due time of an empty buffer: after any simulated time


@dataclass(slots=True)
class ImuDelta:
    """IMU samples summed over one filter period, and the output predictor's running sums."""

    t_ns: int  # end of the period
    dang: tuple[float, float, float]  # raw delta angle, body FRD, rad
    dvel: tuple[float, float, float]  # raw delta velocity, body FRD, m/s
    dt: float
    # Running sums of the NED specific-force delta velocity (and its integral) at t_ns.
    cv: tuple[float, float, float]
    cp: tuple[float, float, float]


class TimedBuffer(Generic[T]):
    """Measurements in time order, popped once the delayed horizon reaches them.

    ``due_ns`` is the time of the oldest one (:data:`NEVER` when empty): the filter asks a
    source to fuse only once its horizon has reached it.
    """

    __slots__ = ("_items", "due_ns", "maxlen")

    def __init__(self, maxlen: int) -> None:
        self._items: deque[tuple[int, T]] = deque()
        self.maxlen = maxlen
        self.due_ns = NEVER

    def __len__(self) -> int:
        return len(self._items)

    def push(self, t_ns: int, item: T) -> bool:
        """Append (times must not go back); False when full or out of order."""
        items = self._items
        if len(items) >= self.maxlen:
            return False
        if items and t_ns < items[-1][0]:
            return False
        if not items:
            self.due_ns = t_ns
        items.append((t_ns, item))
        return True

    def newest_time(self) -> int | None:
        return self._items[-1][0] if self._items else None

    def pop_due(self, t_ns: int) -> list[tuple[int, T]]:
        """All items stamped at or before ``t_ns``, oldest first."""
        out: list[tuple[int, T]] = []
        items = self._items
        while items and items[0][0] <= t_ns:
            out.append(items.popleft())
        self.due_ns = items[0][0] if items else NEVER
        return out

    def clear(self) -> None:
        self._items.clear()
        self.due_ns = NEVER


class OutputPredictor:
    """The estimate at the newest IMU time, run ahead of the delayed filter."""

    __slots__ = ("cp", "cv", "g", "p", "q", "t_ns", "v")

    def __init__(self, g: float) -> None:
        self.g = g
        self.t_ns = 0
        self.p: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.v: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.q: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
        self.cv: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.cp: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def advance(
        self,
        t_ns: int,
        dang: tuple[float, float, float],
        dvel: tuple[float, float, float],
        dt: float,
        bg: tuple[float, float, float],
        ba: tuple[float, float, float],
    ) -> None:
        """Integrate one summed delta with the filter's current bias estimates."""
        da = (dang[0] - bg[0] * dt, dang[1] - bg[1] * dt, dang[2] - bg[2] * dt)
        dv = (dvel[0] - ba[0] * dt, dvel[1] - ba[1] * dt, dvel[2] - ba[2] * dt)
        self.p, self.v, self.q, dv_nav = integrate(self.p, self.v, self.q, da, dv, dt, self.g)
        cv = self.cv
        cp = self.cp
        self.cp = (
            cp[0] + (cv[0] + 0.5 * dv_nav[0]) * dt,
            cp[1] + (cv[1] + 0.5 * dv_nav[1]) * dt,
            cp[2] + (cv[2] + 0.5 * dv_nav[2]) * dt,
        )
        self.cv = (cv[0] + dv_nav[0], cv[1] + dv_nav[1], cv[2] + dv_nav[2])
        self.t_ns = t_ns

    def carry(
        self,
        dx: list[float],
        window_s: float,
        cv0: tuple[float, float, float],
        cp0: tuple[float, float, float],
    ) -> None:
        """Apply a correction ``dx`` made to the delayed state ``window_s`` ago (first order).

        ``cv0``/``cp0`` are the running sums at the delayed time: the differences with the
        current sums are the specific-force delta velocity (and position) over the window.
        """
        window_s = max(window_s, 0.0)
        ex, ey, ez = dx[6], dx[7], dx[8]
        # Gyro and accelerometer bias corrections act over the window too.
        bgx, bgy, bgz = dx[9], dx[10], dx[11]
        bax, bay, baz = dx[12], dx[13], dx[14]
        if bgx or bgy or bgz or bax or bay or baz:
            r = rotation_matrix(self.q)
            w = window_s
            ex -= (r[0] * bgx + r[1] * bgy + r[2] * bgz) * w
            ey -= (r[3] * bgx + r[4] * bgy + r[5] * bgz) * w
            ez -= (r[6] * bgx + r[7] * bgy + r[8] * bgz) * w
            avx = -(r[0] * bax + r[1] * bay + r[2] * baz) * w
            avy = -(r[3] * bax + r[4] * bay + r[5] * baz) * w
            avz = -(r[6] * bax + r[7] * bay + r[8] * baz) * w
        else:
            avx = avy = avz = 0.0
        sv = (self.cv[0] - cv0[0], self.cv[1] - cv0[1], self.cv[2] - cv0[2])
        sp = (
            self.cp[0] - cp0[0] - cv0[0] * window_s,
            self.cp[1] - cp0[1] - cv0[1] * window_s,
            self.cp[2] - cp0[2] - cv0[2] * window_s,
        )
        ax, ay, az = dx[6], dx[7], dx[8]
        # d(R f) = dtheta x (R f): velocity and position pick up the rotated increments.
        v = self.v
        self.v = (
            v[0] + dx[3] + (ay * sv[2] - az * sv[1]) + avx,
            v[1] + dx[4] + (az * sv[0] - ax * sv[2]) + avy,
            v[2] + dx[5] + (ax * sv[1] - ay * sv[0]) + avz,
        )
        h = 0.5 * window_s
        p = self.p
        self.p = (
            p[0] + dx[0] + dx[3] * window_s + (ay * sp[2] - az * sp[1]) + avx * h,
            p[1] + dx[1] + dx[4] * window_s + (az * sp[0] - ax * sp[2]) + avy * h,
            p[2] + dx[2] + dx[5] * window_s + (ax * sp[1] - ay * sp[0]) + avz * h,
        )
        self.q = rotate_global(self.q, (ex, ey, ez))

    def replay(
        self,
        p: tuple[float, float, float],
        v: tuple[float, float, float],
        q: tuple[float, float, float, float],
        deltas: deque[ImuDelta],
        bg: tuple[float, float, float],
        ba: tuple[float, float, float],
    ) -> None:
        """Recompute the output exactly from the delayed state and the buffered deltas."""
        self.p, self.v, self.q = p, v, q
        g = self.g
        for d in deltas:
            dt = d.dt
            da = (d.dang[0] - bg[0] * dt, d.dang[1] - bg[1] * dt, d.dang[2] - bg[2] * dt)
            dv = (d.dvel[0] - ba[0] * dt, d.dvel[1] - ba[1] * dt, d.dvel[2] - ba[2] * dt)
            self.p, self.v, self.q, _ = integrate(self.p, self.v, self.q, da, dv, dt, g)
