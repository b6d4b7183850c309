"""DBSCAN without a per-point loop: core points from neighbour counts, clusters as connected components.

Definitions (Ester et al. 1996): a point is *core* when at least ``min_points`` points (itself included) lie within
``eps``; core points within ``eps`` of each other share a cluster; a non-core point within ``eps`` of a core point is a
*border* point of that cluster; the rest is noise (-1). Classic DBSCAN gives a border point reachable from two
clusters to whichever it expands first; here it goes to its nearest core point (ties: lower index), so the result
does not depend on the processing order. Clusters are numbered by their lowest core-point index.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from tracker.grouping import component_labels, lowest_to_ranks


def kd_tree(points: np.ndarray) -> cKDTree:
    """A k-d tree split at sliding midpoints, its nodes not shrunk to their points: the same neighbours and distances
    as scipy's default (median splits, compact nodes), built in half the time for the few thousand points of a
    radar frame or shore, where building costs as much as the queries."""
    return cKDTree(points, balanced_tree=False, compact_nodes=False)


def dbscan(points: np.ndarray, eps: float, min_points: int) -> np.ndarray:
    """(n,) int labels for (n, d) points: 0, 1, ... per cluster, -1 for noise. Distances <= eps are neighbours."""
    x = np.asarray(points, float)
    if x.ndim == 1:
        x = x[:, None]
    n = x.shape[0]
    labels = np.full(n, -1, dtype=np.int64)
    if n == 0:
        return labels
    if not np.all(np.isfinite(x)):
        raise ValueError("dbscan: points must be finite (filter NaN/inf before clustering)")
    if eps <= 0 or min_points < 1:
        raise ValueError(f"dbscan: need eps > 0 and min_points >= 1, got {eps}, {min_points}")
    pairs = kd_tree(x).query_pairs(eps, output_type="ndarray")
    a, b = (pairs[:, 0], pairs[:, 1]) if pairs.size else (np.empty(0, int), np.empty(0, int))
    counts = 1 + np.bincount(a, minlength=n) + np.bincount(b, minlength=n)
    core = counts >= min_points
    if not core.any():
        return labels
    both = core[a] & core[b]
    comp = component_labels(n, a[both], b[both])
    core_idx = np.flatnonzero(core)
    # The core components numbered in order of their lowest point index.
    labels[core_idx] = lowest_to_ranks(comp, core)[core_idx]
    # Border points: both pair directions, keep (border, core) pairs, nearest core wins.
    src = np.concatenate([a, b])
    dst = np.concatenate([b, a])
    sel = ~core[src] & core[dst]
    if sel.any():
        src, dst = src[sel], dst[sel]
        dist = np.linalg.norm(x[src] - x[dst], axis=1)
        order = np.lexsort((dst, dist, src))
        src, dst = src[order], dst[order]
        first = np.ones(src.size, bool)
        first[1:] = src[1:] != src[:-1]
        labels[src[first]] = labels[dst[first]]
    return labels


def dbscan_1d_grouped(values: np.ndarray, groups: np.ndarray, eps: float, min_points: int) -> np.ndarray:
    """``dbscan`` of 1-D ``values`` run separately within each group (points of different groups never link), by
    sorting instead of a k-d tree: the same labels, numbered the same way (by lowest core-point index).

    In one dimension, with the points sorted, a point's neighbours are a contiguous run (two binary searches), two
    core points are density-connected exactly when every gap between consecutive core points between them is at
    most ``eps``, and a border point's nearest core point is the core point just before or just after it.
    """
    x = np.asarray(values, float).reshape(-1)
    g = np.asarray(groups, np.int64).reshape(-1)
    n = x.size
    labels = np.full(n, -1, np.int64)
    if n == 0:
        return labels
    if not np.all(np.isfinite(x)):
        raise ValueError("dbscan_1d_grouped: values must be finite")
    order = np.lexsort((np.arange(n), x, g))  # by group, then value, then index (ties as dbscan's lower index)
    xs, gs = x[order], g[order]
    # Within a group the searches run over [value - eps, value + eps]; groups are kept apart by searching on
    # (group, value) pairs through a composite that cannot mix them.
    span = float(xs.max() - xs.min()) + 2.0 * eps + 1.0
    key = (gs - gs.min()) * span + (xs - xs.min())
    lo = np.searchsorted(key, key - eps, side="left")
    hi = np.searchsorted(key, key + eps, side="right")
    core = (hi - lo) >= min_points
    if not core.any():
        return labels
    ci = np.flatnonzero(core)
    # Consecutive core points (sorted) in one group within eps share a cluster.
    link = (gs[ci[1:]] == gs[ci[:-1]]) & (xs[ci[1:]] - xs[ci[:-1]] <= eps)
    comp = np.concatenate([[0], np.cumsum(~link)])
    # Number clusters by their lowest original index among core points, as dbscan does.
    first = np.full(comp[-1] + 1, n, np.int64)
    np.minimum.at(first, comp, order[ci])
    rank = np.empty_like(first)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    lab_sorted = np.full(n, -1, np.int64)
    lab_sorted[ci] = rank[comp]
    # Border points: nearest core before or after (same group, within eps); a tie goes to the lower original index.
    nb = np.flatnonzero(~core)
    if nb.size:
        pos = np.searchsorted(ci, nb)
        prev = ci[np.maximum(pos - 1, 0)]
        nxt = ci[np.minimum(pos, ci.size - 1)]
        d_prev = np.where((pos > 0) & (gs[prev] == gs[nb]), xs[nb] - xs[prev], np.inf)
        d_next = np.where((pos < ci.size) & (gs[nxt] == gs[nb]), xs[nxt] - xs[nb], np.inf)
        take_next = (d_next < d_prev) | ((d_next == d_prev) & (order[nxt] < order[prev]))
        best = np.where(take_next, nxt, prev)
        ok = np.minimum(d_prev, d_next) <= eps
        lab_sorted[nb[ok]] = lab_sorted[best[ok]]
    labels[order] = lab_sorted
    return labels
