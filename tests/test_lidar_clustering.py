"""Range-adaptive Euclidean clustering."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from tracker.lidar.clustering import (
    candidate_pairs,
    cluster_points,
    grid_cells,
    link_cells,
    pool_link_cells,
    range_tolerance,
)
from tracker.lidar.config import ClusterConfig

CFG = ClusterConfig(base_tolerance=0.5, tolerance_per_metre=0.035, max_tolerance=3.0, grid_cell=0.15)
OWN = np.array([0.0, 0.0])


def blob(center: tuple[float, float], n: int = 20, size: float = 0.6, z: float = -1.0) -> np.ndarray:
    """n points on a line across ``size`` m (east), stacked at two heights."""
    east = np.linspace(-size / 2, size / 2, n)
    pts = np.stack([np.full(n, center[0]), center[1] + east, np.full(n, z)], axis=1)
    pts[::2, 2] = z - 1.0
    return pts


def test_tolerance_grows_with_range_and_is_capped() -> None:
    assert range_tolerance(np.array([0.0, 10.0, 60.0, 1000.0]), CFG) == pytest.approx([0.5, 0.85, 2.6, 3.0])


def test_gap_splits_near_objects_but_not_far_ones() -> None:
    # Two objects 1.0 m apart at 5 m (tolerance 0.68 m): two clusters.
    near = np.concatenate([blob((5.0, 0.0)), blob((5.0, 1.6))])  # edges 0.6 m wide: gap 1.0 m
    res = cluster_points(near, OWN, CFG)
    assert len(res.clusters) == 2
    # The same gap at 60 m (tolerance 2.6 m): one cluster, since the beams there are too sparse to resolve it.
    far = np.concatenate([blob((60.0, 0.0)), blob((60.0, 1.6))])
    res = cluster_points(far, OWN, CFG)
    assert len(res.clusters) == 1 and len(res.clusters[0]) == 40


def test_sparse_far_hull_stays_one_cluster() -> None:
    # A hull at 80 m sampled every 1.8 m (beam spread), tolerance there 3.0 m.
    east = np.arange(0.0, 18.0, 1.8)
    hull = np.stack([np.full(east.size, 80.0), east, np.full(east.size, -1.0)], axis=1)
    res = cluster_points(hull, OWN, CFG)
    assert len(res.clusters) == 1 and res.clusters[0].shape == (10, 3)
    # The same spacing at 5 m would be ten separate returns, each below min_points: nothing.
    assert len(cluster_points(hull - [75.0, 0.0, 0.0], OWN, CFG).clusters) == 0


def test_footprint_is_one_centroid_per_grid_cell() -> None:
    # 16 rings stacked on 4 spots 1 m apart: 64 points, a footprint of 4.
    spots = np.array([[20.0, 0.0], [20.0, 1.0], [20.0, 2.0], [20.0, 3.0]])
    pts = np.concatenate([np.column_stack([spots, np.full(4, -0.2 * k)]) for k in range(16)])
    pts[:, :2] += 0.01  # keep the spots off the cell boundaries
    res = cluster_points(pts, OWN, ClusterConfig(base_tolerance=1.1))
    assert len(res.clusters) == 1 and len(res.clusters[0]) == 64
    assert sorted(map(tuple, res.footprints[0].round(6))) == sorted(map(tuple, (spots + 0.01).round(6)))


def test_min_points_labels_and_nan_rows() -> None:
    pts = np.concatenate([blob((10.0, 0.0), n=10), blob((10.0, 8.0), n=2), [[np.nan, 0.0, 0.0]]])
    res = cluster_points(pts, OWN, CFG)
    assert len(res.clusters) == 1
    assert res.labels.tolist() == [0] * 10 + [-1, -1, -1]
    assert res.clusters[0] == pytest.approx(pts[:10])


def test_cap_keeps_the_nearest_clusters_in_order() -> None:
    ranges = [50.0, 10.0, 40.0, 20.0, 30.0]
    pts = np.concatenate([blob((r, 0.0)) for r in ranges])
    res = cluster_points(pts, OWN, ClusterConfig(max_clusters=3))
    assert len(res.clusters) == 3
    assert res.min_range == pytest.approx([10.0, 20.0, 30.0], abs=0.05)
    assert [float(c[:, 0].mean()) for c in res.clusters] == pytest.approx([10.0, 20.0, 30.0])
    assert (res.labels == -1).sum() == 40  # the clusters at 40 and 50 m


def test_quay_wall_is_oversized_structure() -> None:
    east = np.arange(-50.0, 50.0, 0.2)
    wall = np.stack([np.full(east.size, 30.0), east, np.full(east.size, -2.0)], axis=1)
    boat = blob((15.0, 5.0))
    res = cluster_points(np.concatenate([wall, boat]), OWN, CFG)
    assert len(res.clusters) == 2
    assert res.oversized.tolist() == [False, True]  # boat nearest
    assert len(res.objects) == 1 and res.objects[0].shape == (20, 3)


def test_own_position_sets_the_range() -> None:
    # Seen from far away the 1.0 m gap merges; from close by it splits.
    pts = np.concatenate([blob((100.0, 0.0)), blob((100.0, 1.6))])
    assert len(cluster_points(pts, np.array([0.0, 0.0]), CFG).clusters) == 1
    assert len(cluster_points(pts, np.array([95.0, 0.0]), CFG).clusters) == 2


def test_empty_input() -> None:
    res = cluster_points(np.zeros((0, 3)), OWN, CFG)
    assert res.clusters == [] and res.labels.shape == (0,)


def _cells(points_ne: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Grid-cell centroids (north, east) and return counts of ``points_ne``, as cluster_points pools them."""
    _, _, counts, centroids = grid_cells(points_ne[:, 0], points_ne[:, 1], CFG.grid_cell)
    return centroids, counts.astype(float)


def _pair_set(a: np.ndarray, c: np.ndarray) -> set[tuple[int, int]]:
    return set(zip(np.minimum(a, c).tolist(), np.maximum(a, c).tolist(), strict=True))


def test_one_far_return_does_not_widen_the_search_near_the_boat() -> None:
    # 6 x 5 m of deck and spray 1-7 m off (tolerance up to 0.75 m) and one return at 95 m (tolerance 3 m). One
    # search with the far return's reach for every link cell found 3-4 times the deck's pairs (issue 12); each
    # range band now searches with its own reach, so the deck's candidate pairs are the same with it or without.
    rng = np.random.default_rng(3)
    deck = np.column_stack([rng.uniform(1.0, 7.0, 20000), rng.uniform(-2.5, 2.5, 20000)])
    alone = pool_link_cells(*_cells(deck), OWN, CFG)
    with_far = pool_link_cells(*_cells(np.vstack([deck, [[95.0, 0.0]]])), OWN, CFG)
    assert with_far.x.size == alone.x.size + 1
    a0, c0 = candidate_pairs(alone, CFG)
    a1, c1 = candidate_pairs(with_far, CFG)
    assert a0.size > 10_000  # a dense deck: the search has work to do
    far = int(np.argmax(with_far.range_m))
    assert with_far.range_m[far] == pytest.approx(95.0, abs=0.1)
    deck_index = np.delete(np.arange(with_far.x.size), far)  # deck link k of the first pooling is deck_index[k]
    assert _pair_set(a1, c1) == _pair_set(deck_index[a0], deck_index[c0])


def test_banded_search_finds_every_neighbour_pair() -> None:
    # Returns scattered from the deck out to 100 m: the labels must be those of the exact rule applied to every pair
    # of link cells (tolerance at the pair's mean range), whatever band each cell fell into.
    rng = np.random.default_rng(11)
    r = np.concatenate([rng.uniform(0.5, 100.0, 3000), rng.uniform(5.0, 9.0, 1500), rng.uniform(33.0, 36.0, 1500)])
    az = rng.uniform(-np.pi, np.pi, r.size)
    points = np.column_stack([r * np.cos(az), r * np.sin(az)])
    cell_xy, weight = _cells(points)
    links = pool_link_cells(cell_xy, weight, OWN, CFG)
    d = np.hypot(links.x[:, None] - links.x[None, :], links.y[:, None] - links.y[None, :])
    tol = range_tolerance(0.5 * (links.range_m[:, None] + links.range_m[None, :]), CFG)
    n_ref, ref = connected_components(csr_matrix(d <= tol), directed=False)
    labels = link_cells(cell_xy, weight, OWN, CFG)
    assert np.unique(labels).size == n_ref
    assert np.unique(np.column_stack([labels, ref[links.of_cell]]), axis=0).shape[0] == n_ref  # same partition
