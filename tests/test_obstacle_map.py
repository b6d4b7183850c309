"""The OBSTACLE_DISTANCE array: bin geometry and the three value meanings, pinned exactly."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracker.obstacle_map import (
    UNKNOWN,
    build_obstacle_distances,
    nearest_beside_edges,
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
    pts = np.vstack([polar(0.0, 25.0), polar(0.0, 30.0), polar(90.0, 0.2), polar(180.0, 150.0), polar(270.0, 60.0)])
    clear_to = np.full(72, 100.0)  # vouched out to max_distance all round ...
    clear_to[50:60] = 99.0  # ... except bins 50-59, vouched only to 99 m
    d = build_obstacle_distances([pts], clear_to, min_distance_m=0.5, max_distance_m=100.0)
    assert d.dtype == np.uint16 and d.shape == (72,)
    assert d[0] == 2500  # nearest of two returns
    assert d[18] == 50  # closer than min_distance: clamped to min, never dropped as "0"
    assert d[36] == 10001  # beyond max range: vouched and clear
    assert (d[[1, 5, 40, 71]] == 10001).all()
    assert (d[[50, 53, 59]] == UNKNOWN).all()  # not vouched to max_distance: unknown, never clear
    assert d[54] == 6000  # a returned solid is an obstacle whatever the coverage says


def test_clear_only_where_vouched_to_max_distance() -> None:
    # the radar's wedge (bins 60..71, 0..12) vouched to 40 m, the rest nowhere
    clear_to = np.zeros(72)
    clear_to[np.r_[60:72, 0:13]] = 40.0
    d = build_obstacle_distances([polar(30.0, 20.0)], clear_to, 0.5, 40.0)
    assert d[6] == 2000
    assert d[0] == 4001 and d[12] == 4001 and d[60] == 4001
    assert d[13] == UNKNOWN and d[36] == UNKNOWN and d[59] == UNKNOWN
    d = build_obstacle_distances([polar(30.0, 20.0)], clear_to, 0.5, 100.0)  # vouched to 40 of 100 m
    assert d[6] == 2000 and np.count_nonzero(d == UNKNOWN) == 71


def test_no_sensor_no_clear_bins() -> None:
    d = build_obstacle_distances([], np.zeros(72), 0.5, 100.0)
    assert (d == UNKNOWN).all()


def test_hull_outline_marks_every_bin_it_spans() -> None:
    # A 10 m wide hull broadside 20 m ahead spans atan(5/20) = 14 deg either side: bins 69..71, 0..3.
    corners = np.array([[20.0, -5.0], [20.0, 5.0], [24.0, 5.0], [24.0, -5.0]])
    d = build_obstacle_distances([outline_points(corners)], np.full(72, 100.0), 0.5, 100.0)
    for j in (69, 70, 71, 0, 1, 2, 3):
        assert d[j] < 2100, j
    assert d[0] == 2000
    assert d[4] == 10001 and d[68] == 10001


def test_a_hull_beside_the_boat_marks_each_bin_with_its_near_side() -> None:
    """A 4 m x 2 m hull whose near side runs 1.5 m off the starboard beam spans bins 7-29. Each bin must hold the
    near side at its nearest within the bin (1.5 m / sin of the bin's angle nearest the beam), not the far side
    2 m further out, which 0.25 m between outline points gave in bins 12, 15, 17, 19, 21 and 24 (3.5-3.8 m)."""
    corners = np.array([[2.0, 1.5], [2.0, 3.5], [-2.0, 3.5], [-2.0, 1.5]])  # body forward, starboard
    d = build_obstacle_distances([outline_points(corners)], np.zeros(72), 0.5, 20.0).astype(float) / 100.0
    for j in range(8, 29):  # wholly within the near side's angular span (36.9-143.1 deg)
        lo, hi = np.radians(5.0 * j - 2.5), np.radians(5.0 * j + 2.5)
        exact = 1.5 / np.sin(np.clip(np.pi / 2, lo, hi))
        # points a quarter bin (1.25 deg) apart: the nearest sampled lies at most that far from the exact angle,
        # 1.5 m x d(1/sin)/d(angle) x 0.022 rad = 6 cm at the span's ends (40 deg)
        assert d[j] == pytest.approx(exact, abs=0.07), j
    assert d[7] == pytest.approx(2.5, abs=0.07) and d[29] == pytest.approx(2.5, abs=0.07)  # the near corners


def test_a_return_beside_a_bins_edge_counts_in_the_neighbour_too() -> None:
    # Bin 1 spans 2.5-7.5 deg. At 20 m, 7.0 deg is 0.17 m (20 sin 0.5 deg) across the line of sight from its upper
    # edge, 3.5 deg is 0.35 m from its lower edge, 5.0 deg 0.87 m from both.
    near = nearest_beside_edges(np.vstack([polar(7.0, 20.0), polar(3.5, 21.0), polar(5.0, 19.0)]), edge_m=0.25)
    assert near[2] == pytest.approx(20.0, abs=1e-9)  # 0.17 m < 0.25 m
    assert np.isinf(near[0])  # 0.35 m > 0.25 m
    assert np.count_nonzero(np.isfinite(near)) == 1
    # nearer in, the same angle is nearer across: 3.5 deg at 10 m is 0.17 m from the edge
    assert nearest_beside_edges(polar(3.5, 10.0), edge_m=0.25)[0] == pytest.approx(10.0, abs=1e-9)
    # either side of the bow and of astern: -2.8 deg (bin 71) is 0.16 m from bin 0, 177.2 deg (bin 35) from bin 36
    assert nearest_beside_edges(polar(-2.8, 30.0), edge_m=0.25)[0] == pytest.approx(30.0, abs=1e-9)
    assert nearest_beside_edges(polar(177.2, 30.0), edge_m=0.25)[36] == pytest.approx(30.0, abs=1e-9)


def test_an_edge_return_fills_only_a_neighbour_that_would_go_out_unknown() -> None:
    pts = np.vstack([polar(7.0, 20.0), polar(-7.0, 25.0)])  # bin 1 near bin 2's edge, bin 71 near bin 70's
    clear_to = np.full(72, 100.0)
    clear_to[2] = 40.0  # bin 2 vouched only to 40 m: unknown without the return beside it
    d = build_obstacle_distances([pts], clear_to, 0.5, 100.0, edge_m=0.5)
    assert d[1] == 2000 and d[71] == 2500
    assert d[2] == 2000  # an obstacle where it would have been unknown
    assert d[70] == 10001  # vouched clear all the way: the beams saw the bin and nothing in it
    d = build_obstacle_distances([pts], clear_to, 0.5, 100.0)  # edge_m 0: off
    assert d[2] == UNKNOWN
    # a bin with an obstacle of its own keeps its range, however near the one beside its edge
    clear_to[9:11] = 40.0
    pts = np.vstack([polar(50.0, 60.0), polar(47.2, 20.0)])  # bin 10 at 60 m; bin 9, 0.1 m from bin 10's edge
    d = build_obstacle_distances([pts], clear_to, 0.5, 100.0, edge_m=0.5)
    assert d[10] == 6000 and d[9] == 2000 and d[8] == 10001
