"""Range-adaptive Euclidean clustering."""

from __future__ import annotations

import numpy as np
import pytest

from tracker.lidar.clustering import cluster_points, range_tolerance
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
