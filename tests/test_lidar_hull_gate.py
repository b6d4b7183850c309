"""Returns within the sea margin count as solid only on a confirmed track's hull (tracker/lidar/hull_gate.py)."""

from __future__ import annotations

import math

import numpy as np

from tracker.lidar.hull_gate import on_tracked_hulls
from tracker.types import Track


def _track(north: float, east: float, heading_deg: float, length: float, width: float, confirmed: bool) -> Track:
    return Track(
        id=1,
        t=0.0,
        position=np.array([north, east]),
        velocity=np.zeros(2),
        heading=math.radians(heading_deg),
        yaw_rate=0.0,
        length=length,
        width=width,
        height=1.0,
        confirmed=confirmed,
    )


def test_points_on_a_turned_hull_and_its_grown_edge_count_and_others_do_not() -> None:
    # A 10 x 3 m hull 40 m north heading east (090): it spans east -5..5 and north 38.5..41.5.
    hull = _track(40.0, 0.0, 90.0, 10.0, 3.0, True)
    points = np.array(
        [
            [40.0, 0.0],  # centre
            [38.6, 4.9],  # inside, by a corner
            [38.1, 0.0],  # 0.4 m off the near side: inside the 0.5 m growth
            [37.9, 0.0],  # 0.6 m off: outside
            [40.0, 5.6],  # 0.6 m past the stern: outside
            [40.0, -5.4],  # 0.4 m past the bow: inside
        ]
    )
    assert on_tracked_hulls(points, [hull], 0.5).tolist() == [True, True, True, False, False, True]


def test_a_tentative_track_or_one_without_a_size_vouches_for_nothing() -> None:
    points = np.array([[40.0, 0.0]])
    assert on_tracked_hulls(points, [_track(40.0, 0.0, 90.0, 10.0, 3.0, False)], 0.5).tolist() == [False]
    assert on_tracked_hulls(points, [_track(40.0, 0.0, 90.0, math.nan, 3.0, True)], 0.5).tolist() == [False]
    assert on_tracked_hulls(np.zeros((0, 2)), [_track(40.0, 0.0, 90.0, 10.0, 3.0, True)], 0.5).shape == (0,)


def test_a_coasting_track_reaches_back_to_where_it_was_last_measured() -> None:
    # A 1.5 x 1.5 m buoy whose returns sank into the sea margin: its track, unseen for 2 s, carried 0.55 m/s of
    # velocity error north and its prediction lies 1.1 m beyond the buoy. A return on the buoy's far side from the
    # prediction (1.1 + 0.75 = 1.85 m south of it) lies outside the box grown 0.5 m (1.25 m), inside it grown by the
    # 1.1 m drifted as well (2.35 m); capped at 0.5 m of drift it is outside again (1.75 m).
    buoy = _track(16.0 + 1.1, 0.0, 0.0, 1.5, 1.5, True)
    buoy.velocity = np.array([0.55, 0.0])
    buoy.time_since_update = 2.0
    far_side = np.array([[16.0 - 0.75, 0.0], [16.0 - 1.5, 0.0]])  # the buoy's south edge; 0.75 m beyond it
    assert on_tracked_hulls(far_side, [buoy], 0.5).tolist() == [False, False]
    assert on_tracked_hulls(far_side, [buoy], 0.5, coast_drift_cap_m=3.0).tolist() == [True, False]
    assert on_tracked_hulls(far_side, [buoy], 0.5, coast_drift_cap_m=0.5).tolist() == [False, False]
    # measured this frame, or its speed unknown: no drift to reach back over
    buoy.time_since_update = 0.0
    assert on_tracked_hulls(far_side, [buoy], 0.5, coast_drift_cap_m=3.0).tolist() == [False, False]
    buoy.time_since_update, buoy.velocity = 2.0, np.full(2, math.nan)
    assert on_tracked_hulls(far_side, [buoy], 0.5, coast_drift_cap_m=3.0).tolist() == [False, False]
