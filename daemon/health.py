"""Cycle timing, deadline misses and the one-line health summary the crew reads in the journal."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class CycleStats:
    period_s: float
    window: int = 600  # the last minute at 10 Hz
    cycles: int = 0
    deadline_misses: int = 0
    _durations_ms: deque[float] = field(default_factory=deque)
    stage_ms: dict[str, deque[float]] = field(default_factory=dict)

    def record(self, duration_ms: float, stages: dict[str, float]) -> None:
        self.cycles += 1
        if duration_ms > self.period_s * 1e3:
            self.deadline_misses += 1
        self._push(self._durations_ms, duration_ms)
        for k, v in stages.items():
            self._push(self.stage_ms.setdefault(k, deque()), v)

    def _push(self, d: deque[float], v: float) -> None:
        d.append(v)
        if len(d) > self.window:
            d.popleft()

    def percentiles(self) -> tuple[float, float]:
        if not self._durations_ms:
            return float("nan"), float("nan")
        a = np.fromiter(self._durations_ms, float)
        return float(np.percentile(a, 50)), float(np.percentile(a, 99))

    def stage_p50(self) -> dict[str, float]:
        return {k: float(np.median(np.fromiter(v, float))) for k, v in self.stage_ms.items() if v}


@dataclass
class RateCounter:
    """Items per second over the interval between two summaries."""

    last_count: int = 0
    last_t: float = 0.0

    def rate(self, count: int, t: float) -> float:
        dt = t - self.last_t
        r = (count - self.last_count) / dt if dt > 0 else 0.0
        self.last_count, self.last_t = count, t
        return r


def source_status(lidar: Any, radar: Any, link: Any) -> str:
    """The drivers' and the autopilot link's part of the health line.

    ``lidar_from`` names the sender the LiDAR data is taken from (none: no VLP-16 heard yet, or the one locked fell
    silent); ``lidar_rejected`` appears once anything else was heard on the LiDAR ports: a second Velodyne on the
    network shows up here. ``radar_rejected`` counts frames of another configuration than the one sent to the radar.
    """
    parts = []
    st = getattr(lidar, "stats", None)
    if st is not None:
        parts.append(f"lidar_wrong_size {getattr(st, 'wrong_size', 0)} lidar_missing {getattr(st, 'missing', 0)}")
        if hasattr(st, "sender"):
            parts.append(f"lidar_from {st.sender or 'none'}")
        if getattr(st, "foreign_source", 0):
            parts.append(
                f"lidar_rejected {st.foreign_source} (other senders {st.other_senders}, last {st.last_foreign})"
            )
    ps = getattr(getattr(radar, "stats", None), "parser", None)
    if ps is not None:
        parts.append(
            f"radar_skipped_bytes {getattr(ps, 'bytes_skipped', 0)} radar_gaps {getattr(ps, 'frames_lost', 0)}"
        )
        if getattr(ps, "frames_rejected", 0):
            parts.append(f"radar_rejected {ps.frames_rejected} ({ps.last_rejection})")
    parts.append(_autopilot_status(link))
    return " ".join(parts)


def _autopilot_status(link: Any) -> str:
    """``autopilot up``, with ``no pose`` (or how old it is) when it sends none the daemon can use, and
    ``pose_rejected N`` once any of its ATTITUDE or LOCAL_POSITION_NED messages carried a non-finite field (counted
    and skipped, never used)."""
    if not getattr(link, "connected", False):
        return "autopilot absent (no ego pose)"
    text = "autopilot up"
    age = getattr(link, "pose_age", None)
    if age is None:
        text += ", no pose"
    elif age > 1.0:
        text += f", pose {age:.0f} s old"
    counters = getattr(link, "counters", {})
    rejected = counters.get("pose_rejected", 0) + counters.get("pose_local_rejected", 0)
    return text + (f", pose_rejected {rejected}" if rejected else "")
