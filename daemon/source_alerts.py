"""STATUSTEXT for what the drivers find about who is sending: a second LiDAR on the data port, the LiDAR lock going
over to another sender, radar frames of another configuration than the one sent.

The drivers count in their reader threads; the loop polls the counters once a tick, in its own thread, which is the
one that talks to the autopilot. At most one message per kind a minute: a noisy network must not flood a telemetry
radio (the journal and the health line carry the details). News within the minute is held, not dropped, and sent
when the minute is over, as it stands then: a second takeover of the LiDAR soon after a first one is still heard.
"""

from __future__ import annotations

import math
from typing import Any

ALERT_INTERVAL_S = 60.0
MAV_SEVERITY_WARNING = 4


class SourceAlerts:
    """``poll(t)`` -> [(severity, text)] to send now; texts fit one 50-character STATUSTEXT."""

    def __init__(self, lidar: Any, radar: Any) -> None:
        self._lidar_stats = getattr(lidar, "stats", None)
        self._parser_stats = getattr(getattr(radar, "stats", None), "parser", None)
        self._seen: dict[str, int] = {}
        self._sent: dict[str, float] = {}
        self._held: set[str] = set()  # kinds with news not sent yet (within ALERT_INTERVAL_S of the last)

    def poll(self, t: float) -> list[tuple[int, str]]:
        out: list[tuple[int, str]] = []
        st = self._lidar_stats
        if st is not None:
            if self._news("lidar_other", getattr(st, "other_senders", 0), t):
                out.append((MAV_SEVERITY_WARNING, f"usv-tracker: other LiDAR {st.last_foreign_ip} ignored"))
            if self._news("lidar_moved", getattr(st, "lock_moves", 0), t):
                out.append((MAV_SEVERITY_WARNING, f"usv-tracker: LiDAR now from {st.sender.rpartition(':')[0]}"))
        ps = self._parser_stats
        if ps is not None and self._news("radar_rejected", getattr(ps, "frames_rejected", 0), t):
            out.append((MAV_SEVERITY_WARNING, "usv-tracker: radar frames of other config dropped"))
        return out

    def _news(self, kind: str, count: int, t: float) -> bool:
        """The counter rose since this kind was last sent, and it was not sent within ALERT_INTERVAL_S."""
        if count > self._seen.get(kind, 0):
            self._held.add(kind)
        self._seen[kind] = count
        if kind not in self._held or t - self._sent.get(kind, -math.inf) < ALERT_INTERVAL_S:
            return False
        self._held.discard(kind)
        self._sent[kind] = t
        return True
