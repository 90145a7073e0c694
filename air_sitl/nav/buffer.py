"""The per-source measurement buffers of the delayed fusion horizon.

As in PX4 EKF2, the filter runs ``fusion_horizon`` behind the newest IMU sample, so a
measurement that arrives late (up to the horizon) is fused at the time it refers to: each
source keeps its measurements here until the delayed filter reaches their time (the IMU
deltas and the output predictor are in :mod:`air_sitl.nav.strapdown`).
"""

from __future__ import annotations

from collections import deque
from typing import Generic, TypeVar

T = TypeVar("T")
NEVER = 2**63  # the due time of an empty buffer: after any simulated time


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
