"""The OBSTACLE_DISTANCE array: bin geometry and the three value meanings, pinned exactly."""

from __future__ import annotations

import math

import numpy as np

from tracker.obstacle_map import (
    UNKNOWN,
    SensorCoverage,
    build_obstacle_distances,
    nearest_per_bin,
    outline_points,
)


def polar(bearing_deg: float, r: float) -> np.ndarray:
    b = math.radians(bearing_deg)
    return np.array([[r * math.cos(b), r * math.sin(b)]])


def test_bin_centres_and_edges() -> None:
    # Bin j is centred on 5j deg clockwise from the bow; 2.4 deg belongs to bin 0, 2.6 deg to bin 1, -3 deg to 71.
    pts = np.vstack([polar(2.4, 10.0), polar(2.6, 11.0), polar(-3.0, 12.0), polar(90.0, 13.0)])
    near = nearest_per_bin(pts)
    np.testing.assert_allclose(near[[0, 1, 71, 18]], [10.0, 11.0, 12.0, 13.0], atol=1e-9)
    assert np.isinf(near[[2, 17, 19, 36]]).all()
    # astern from either side is bin 36; a NaN return is skipped, not binned
    astern = np.vstack([polar(179.0, 20.0), polar(-178.0, 19.0), polar(-182.6, 18.0), [[np.nan, 1.0]]])
    near = nearest_per_bin(astern)
    np.testing.assert_allclose(near[[36, 35]], [19.0, 18.0], atol=1e-9)
    assert np.isfinite(near).sum() == 2


def test_values_obstacle_clear_unknown() -> None:
    lidar_all_round = SensorCoverage(0.0, 2 * math.pi, 100.0)
    pts = np.vstack([polar(0.0, 25.0), polar(0.0, 30.0), polar(90.0, 0.2), polar(180.0, 150.0)])
    d = build_obstacle_distances([pts], [lidar_all_round], min_distance_m=0.5, max_distance_m=100.0)
    assert d.dtype == np.uint16 and d.shape == (72,)
    assert d[0] == 2500  # nearest of two returns
    assert d[18] == 50  # closer than min_distance: clamped to min, never dropped as "0"
    assert d[36] == 10001  # beyond max range: covered and clear
    assert (d[[1, 5, 40, 71]] == 10001).all()


def test_radar_only_covers_its_wedge() -> None:
    radar_ahead = SensorCoverage(0.0, math.radians(120.0), 50.0)
    d = build_obstacle_distances([polar(30.0, 20.0)], [radar_ahead], 0.5, 100.0)
    assert d[6] == 2000
    assert d[0] == 10001 and d[12] == 10001  # 60 deg: edge of the wedge, covered
    assert d[13] == UNKNOWN and d[36] == UNKNOWN and d[59] == UNKNOWN
    assert d[60] == 10001  # -60 deg


def test_no_sensor_no_clear_bins() -> None:
    d = build_obstacle_distances([], [], 0.5, 100.0)
    assert (d == UNKNOWN).all()


def test_hull_outline_marks_every_bin_it_spans() -> None:
    # A 10 m wide hull broadside 20 m ahead spans atan(5/20) = 14 deg either side: bins 69..71, 0..3.
    corners = np.array([[20.0, -5.0], [20.0, 5.0], [24.0, 5.0], [24.0, -5.0]])
    d = build_obstacle_distances([outline_points(corners)], [SensorCoverage(0, 2 * math.pi, 100)], 0.5, 100.0)
    for j in (69, 70, 71, 0, 1, 2, 3):
        assert d[j] < 2100, j
    assert d[0] == 2000
    assert d[4] == 10001 and d[68] == 10001
