"""Track-level fusion: a radar track joins the nearest LiDAR track that reaches it, not the first listed."""

from __future__ import annotations

import numpy as np

from tracker.fusion import fuse_tracks
from tracker.types import Track


def track(tid: int, north: float, east: float, source: str, length: float = 8.0, width: float = 3.0) -> Track:
    return Track(
        tid, 0.0, np.array([north, east]), np.zeros(2), 0.0, 0.0, length, width, 1.5, confirmed=True, source=source
    )


def test_a_radar_track_joins_the_nearest_lidar_track_that_reaches_it() -> None:
    # Two boats moored 6 m apart (centres east 0 and 6); a radar track at east 4.5 lies on the second. Both LiDAR
    # tracks reach it (4 + 3 m of gate), the first listed is the farther.
    lidar = [track(1, 20.0, 0.0, "lidar"), track(2, 20.0, 6.0, "lidar")]
    radar = [track(7, 20.0, 4.5, "radar")]
    out = fuse_tracks(lidar, radar, gate_m=3.0)
    assert [(t.id, t.source) for t in out] == [(1, "lidar"), (2, "fused")]


def test_each_lidar_track_takes_its_own_radar_tracks_and_the_rest_stay() -> None:
    lidar = [track(1, 20.0, 0.0, "lidar"), track(2, 20.0, 6.0, "lidar")]
    radar = [track(7, 20.0, 5.5, "radar"), track(8, 20.5, 0.5, "radar"), track(9, 60.0, 0.0, "radar")]
    out = fuse_tracks(lidar, radar, gate_m=3.0)
    assert [(t.id, t.source) for t in out] == [(1, "fused"), (2, "fused"), (9, "radar")]
