"""Host-clock offset of a sensor's own timeline, from the message that waited least.

A sensor stamps its data on its own clock (the VLP-16's microseconds past the hour, the AWR1843's frame counter
times its frame period); the host sees each message only when a read returns, late by whatever the kernel, a
serial buffer or a busy scheduler added. The least of (host - device) over a recent window is the best estimate of
the offset between the two clocks: the message that waited least was delayed by transport alone. Device times
shifted by it keep the sensor's own spacing however the reads bunched up.
"""

from __future__ import annotations

from collections import deque


class LeastDelayOffset:
    """Least (host time - device time) over the last ``window_s`` of host time, in O(1) per sample."""

    def __init__(self, window_s: float = 2.0) -> None:
        self.window_s = window_s
        self._offsets: deque[tuple[float, float]] = deque()  # (host_time, host - device), increasing offset

    def reset(self) -> None:
        self._offsets.clear()

    def accept(self, device_time: float, host_time: float) -> None:
        offset = host_time - device_time
        # Monotone deque: the window minimum stays at the front.
        while self._offsets and self._offsets[-1][1] >= offset:
            self._offsets.pop()
        self._offsets.append((host_time, offset))
        while self._offsets[0][0] < host_time - self.window_s:
            self._offsets.popleft()

    @property
    def offset(self) -> float:
        """Host time minus device time (s) of the least-delayed sample in the window; 0 before any."""
        return self._offsets[0][1] if self._offsets else 0.0
