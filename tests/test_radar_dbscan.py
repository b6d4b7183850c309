"""Vectorised DBSCAN against a plain brute-force DBSCAN written from the definition."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest

from tracker.radar.dbscan import dbscan, dbscan_1d_grouped


def brute_force_dbscan(x: np.ndarray, eps: float, min_points: int) -> np.ndarray:
    """Textbook DBSCAN: full distance matrix, breadth-first expansion from core points in index order.

    Border points reachable from two clusters go to their nearest core point (ties: lower index), the rule
    tracker.radar.dbscan documents, so that labels can be compared exactly.
    """
    n = len(x)
    d = np.sqrt(((x[:, None, :] - x[None, :, :]) ** 2).sum(axis=2))
    neigh = [np.flatnonzero(d[i] <= eps) for i in range(n)]
    core = np.array([len(nb) >= min_points for nb in neigh])
    labels = np.full(n, -1)
    cluster = 0
    for i in range(n):
        if not core[i] or labels[i] >= 0:
            continue
        labels[i] = cluster
        queue = deque([i])
        while queue:
            p = queue.popleft()
            for q in neigh[p]:
                if core[q] and labels[q] < 0:
                    labels[q] = cluster
                    queue.append(q)
        cluster += 1
    for i in range(n):
        if core[i]:
            continue
        cores = [q for q in neigh[i] if core[q]]
        if cores:
            best = min(cores, key=lambda q: (d[i, q], q))
            labels[i] = labels[best]
    return labels


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_equals_brute_force_on_random_sets(seed: int) -> None:
    rng = np.random.default_rng(seed)
    blobs = [rng.normal(c, 0.6, (25, 2)) for c in ([0, 0], [4, 1], [1, 5])]
    x = np.concatenate([*blobs, rng.uniform(-4, 8, (30, 2))])
    for eps, min_pts in ((0.5, 3), (0.8, 5), (1.2, 4)):
        got = dbscan(x, eps, min_pts)
        want = brute_force_dbscan(x, eps, min_pts)
        np.testing.assert_array_equal(got, want)
        assert got.max() >= 1  # the parameters really produce several clusters and the case is not trivial


def test_hand_made_case_core_border_noise() -> None:
    # Five points in a row 1 m apart plus a far point; eps 1.0 with min 3: the inner three are core,
    # the ends are border, the far point is noise.
    x = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [4.0, 0.0], [10.0, 0.0]])
    np.testing.assert_array_equal(dbscan(x, 1.0, 3), [0, 0, 0, 0, 0, -1])
    # With min 4 nobody has enough neighbours: all noise.
    np.testing.assert_array_equal(dbscan(x, 1.0, 4), [-1] * 6)


def test_border_point_between_two_clusters_goes_to_nearest_core() -> None:
    left = np.array([[0.0, 0.0], [-0.2, 0.0], [-0.4, 0.0], [-0.6, 0.0]])
    right = np.array([[2.0, 0.0], [2.2, 0.0], [2.4, 0.0], [2.6, 0.0]])
    border = np.array([[1.1, 0.0]])  # 1.1 from the left core (0, 0), 0.9 from the right core (2, 0); 3 neighbours
    x = np.concatenate([left, right, border])
    np.testing.assert_array_equal(dbscan(x, 1.2, 5), [0, 0, 0, 0, 1, 1, 1, 1, 1])
    np.testing.assert_array_equal(brute_force_dbscan(x, 1.2, 5), [0, 0, 0, 0, 1, 1, 1, 1, 1])


def test_one_dimensional_input_and_empty_and_bad_input() -> None:
    np.testing.assert_array_equal(dbscan(np.array([0.0, 0.1, 0.2, 5.0]), 0.15, 2), [0, 0, 0, -1])
    assert dbscan(np.empty((0, 2)), 1.0, 2).shape == (0,)
    with pytest.raises(ValueError, match="finite"):
        dbscan(np.array([[0.0, np.nan]]), 1.0, 1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_component_labels_match_scipy_connected_components(seed: int) -> None:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from tracker.grouping import component_labels

    rng = np.random.default_rng(seed)
    n = 300
    a = rng.integers(0, n, 250)
    b = rng.integers(0, n, 250)
    lab = component_labels(n, a, b)
    _, ref = connected_components(coo_matrix((np.ones(a.size), (a, b)), shape=(n, n)), directed=False)
    # Same partition, and each label is the lowest node index of its component.
    assert len(np.unique(lab)) == len(np.unique(ref))
    for c in np.unique(ref):
        members = np.flatnonzero(ref == c)
        assert (lab[members] == members.min()).all()
    np.testing.assert_array_equal(component_labels(4, np.empty(0, int), np.empty(0, int)), [0, 1, 2, 3])


def test_grouped_1d_dbscan_matches_dbscan_on_separated_lines() -> None:
    # The Doppler split's sort-based 1-D DBSCAN against the k-d tree one with each group on its own far line.
    rng = np.random.default_rng(11)
    for _ in range(500):
        n = int(rng.integers(1, 40))
        groups = rng.integers(0, int(rng.integers(1, 5)), n)
        values = rng.normal(0.0, 1.5, n)
        values[: n // 4] = np.round(values[: n // 4], 1)  # some exactly equal values
        eps, m = 0.75, int(rng.integers(1, 5))
        offset = 10.0 * (np.abs(values).max() + eps + 1.0)
        want = dbscan(np.column_stack([groups * offset, values]), eps, m)
        np.testing.assert_array_equal(dbscan_1d_grouped(values, groups, eps, m), want)
    assert dbscan_1d_grouped(np.empty(0), np.empty(0, int), 0.8, 3).size == 0
    np.testing.assert_array_equal(dbscan_1d_grouped(np.array([0.0, 0.5, 5.0]), np.zeros(3, int), 0.8, 2), [0, 0, -1])
