"""Bounded hand-over between reader threads and the 10 Hz loop: the loop never blocks on I/O.

LiDAR: only the newest complete revolution matters (an older one is stale the moment a newer one exists), so a
single slot; a revolution replaced before the loop took it is counted as dropped. Radar: every frame since the last
tick matters (sparse points, Doppler history), so a bounded queue; overflow drops the oldest and counts it.
"""

from __future__ import annotations

import threading
from collections import deque
from dataclasses import dataclass
from typing import Generic, TypeVar

T = TypeVar("T")


@dataclass
class BufferStats:
    received: int = 0
    taken: int = 0
    dropped: int = 0
    last_put: float = float("-inf")  # host time of the newest item


class LatestSlot(Generic[T]):
    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._item: T | None = None
        self.stats = BufferStats()

    def put(self, item: T, t: float) -> None:
        with self._lock:
            if self._item is not None:
                self.stats.dropped += 1
            self._item = item
            self.stats.received += 1
            self.stats.last_put = t

    def take(self) -> T | None:
        with self._lock:
            item, self._item = self._item, None
            if item is not None:
                self.stats.taken += 1
            return item


class BoundedQueue(Generic[T]):
    def __init__(self, maxlen: int = 64) -> None:
        self._lock = threading.Lock()
        self._items: deque[T] = deque()
        self._maxlen = maxlen
        self.stats = BufferStats()

    def put(self, item: T, t: float) -> None:
        with self._lock:
            if len(self._items) >= self._maxlen:
                self._items.popleft()
                self.stats.dropped += 1
            self._items.append(item)
            self.stats.received += 1
            self.stats.last_put = t

    def take_all(self) -> list[T]:
        with self._lock:
            items = list(self._items)
            self._items.clear()
            self.stats.taken += len(items)
            return items
