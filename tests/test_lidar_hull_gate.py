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


def test_a_rough_seas_thousands_of_returns_pair_with_the_hulls_exactly_as_every_pair_tested_does(monkeypatch) -> None:
    """5,000 margin returns over 200 x 200 m (hulls on their edges and corners among them) and 20 hulls: the pairs
    found through the raster of the hulls' squares are those of testing every point against every hull, in the
    same order, with the same distances; and a hull 7 km off (too large a raster) leaves every point tested."""
    import tracker.lidar.hull_gate as gate

    rng = np.random.default_rng(12)
    hulls = [
        _track(*rng.uniform(-100, 100, 2), rng.uniform(0, 360), rng.uniform(2, 30), rng.uniform(1, 8), True)
        for _ in range(20)
    ]
    corners = np.concatenate(
        [h.position[:2] + rng.normal(0.0, (h.length + h.width) / 2, (40, 2)) for h in hulls]  # near every box
    )
    points = np.concatenate([rng.uniform(-100, 100, (5000 - len(corners), 2)), corners])
    far = [*hulls, _track(5000.0, 5000.0, 0.0, 10.0, 3.0, True)]
    for tracks in (hulls, far):
        fast = gate._pairs_inside(points, tracks, 0.5)
        monkeypatch.setattr(gate, "_RASTER_FROM", 10**12)
        every = gate._pairs_inside(points, tracks, 0.5)
        monkeypatch.undo()
        assert fast[0].size > 250  # the test pairs plenty of points with hulls (318)
        for a, b in zip(fast, every, strict=True):
            np.testing.assert_array_equal(a, b)
    assert gate._near_some_square(points, np.array([[0.0, 0.0], [5000.0, 5000.0]]), np.array([10.0, 10.0])) is None
    assert gate._near_some_square(points, np.array([[0.0, 0.0]]), np.array([10.0])).size < 200  # of 5,000
