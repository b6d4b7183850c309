"""Range-adaptive Euclidean clustering of world-frame returns (paper sec. 2.1, "modified Euclidean clustering").

Two returns are neighbours when their horizontal distance is within a tolerance that grows with range, because the
VLP-16's beams fan out: a hull at 60 m is sampled every ~2 m vertically where at 5 m it is every 0.2 m. A fixed
tolerance either merges nearby boats or shatters distant ones. Clusters are the connected components of the
neighbour graph.

For speed, returns are first pooled into small 2-D grid cells (a vertical hull stacks all 16 rings onto the same
horizontal spot, so a cell often holds dozens of returns); the neighbour search runs over cell centroids, which
shifts the effective tolerance by at most one cell diagonal. Work is 2-D (north, east); z rides along for height.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from tracker.lidar.config import ClusterConfig


@dataclass
class ClusterResult:
    clusters: list[np.ndarray]  # each (n, 3) world NED points, nearest cluster first
    # Each cluster's horizontal footprint: the centroids of its occupied grid cells, (m, 2) north, east. The 16
    # rings of a vertical hull stack onto the same spot; fitting shapes to the footprint instead of the points
    # costs a fraction and weighs every part of the outline once, however many rings hit it.
    footprints: list[np.ndarray]
    min_range: np.ndarray  # (k,) m, horizontal distance of each cluster's nearest return from the own boat
    oversized: np.ndarray  # (k,) bool: extent above max_extent (shore, quay): structure, not a vessel
    labels: np.ndarray  # (N,) int index into ``clusters`` per input point, -1 = not in a kept cluster
    # Bearing interval seen from the own boat (rad, 0 = north, clockwise): centre, and the span as offsets from
    # it (lo <= 0 <= hi), so an interval across north needs no special case. For occlusion reasoning.
    bearing: np.ndarray | None = None  # (k,)
    bearing_lo: np.ndarray | None = None  # (k,)
    bearing_hi: np.ndarray | None = None  # (k,)

    @property
    def objects(self) -> list[np.ndarray]:
        """The clusters small enough to be vessels, nearest first."""
        return [c for c, big in zip(self.clusters, self.oversized, strict=True) if not big]


def occluded_by_nearer(members: list[int], result: ClusterResult, margin: float, depth: float = 1.0) -> bool:
    """Whether the object made of clusters ``members`` touches, in bearing, a cluster clearly in front of it.

    Such an object may extend into the nearer one's shadow: its visible extent, and so its fitted centre and size,
    are cut short. ``margin`` (rad) widens the test for the gap the shadow edge leaves; ``depth`` (m) is how much
    nearer an occluder must be.
    """
    if result.bearing is None or result.bearing_lo is None or result.bearing_hi is None:
        return False
    ref = float(result.bearing[members[0]])

    def span(idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        shift = (result.bearing[idx] - ref + np.pi) % (2.0 * np.pi) - np.pi
        return shift + result.bearing_lo[idx], shift + result.bearing_hi[idx]

    own_lo, own_hi = span(np.asarray(members))
    lo, hi = float(own_lo.min()), float(own_hi.max())
    r = float(result.min_range[members].min())
    others = np.setdiff1d(np.flatnonzero(result.min_range < r - depth), members)
    if others.size == 0:
        return False
    o_lo, o_hi = span(others)
    return bool(np.any((o_lo <= hi + margin) & (o_hi >= lo - margin)))


def occluded_clusters(result: ClusterResult, margin: float, depth: float = 1.0) -> np.ndarray:
    """:func:`occluded_by_nearer` for every single cluster at once: (k,) bool."""
    k = len(result.clusters)
    if k == 0 or result.bearing is None or result.bearing_lo is None or result.bearing_hi is None:
        return np.zeros(k, dtype=bool)
    b, lo, hi = result.bearing, result.bearing_lo, result.bearing_hi
    shift = (b[None, :] - b[:, None] + np.pi) % (2.0 * np.pi) - np.pi  # [i, j]: j's centre seen from i's
    nearer = result.min_range[None, :] < result.min_range[:, None] - depth
    touch = (shift + lo[None, :] <= hi[:, None] + margin) & (shift + hi[None, :] >= lo[:, None] - margin)
    return np.any(nearer & touch, axis=1)


def range_tolerance(range_m: np.ndarray, config: ClusterConfig) -> np.ndarray:
    """Neighbour distance tolerance at a given horizontal range, m."""
    return np.minimum(config.base_tolerance + config.tolerance_per_metre * range_m, config.max_tolerance)


def cluster_points(
    points_world: np.ndarray, own_position: np.ndarray, config: ClusterConfig | None = None
) -> ClusterResult:
    """Cluster (N, 3) world NED points; ``own_position`` is the own boat's (north, east), m."""
    cfg = config or ClusterConfig()
    all_pts = np.asarray(points_world, dtype=float).reshape(-1, 3)
    finite_idx = np.flatnonzero(np.isfinite(all_pts).all(axis=1))
    pts = all_pts[finite_idx]
    n = pts.shape[0]
    empty = ClusterResult(
        [],
        np.zeros(0),
        np.zeros(0, bool),
        np.full(all_pts.shape[0], -1, dtype=int),
        np.zeros(0),
        np.zeros(0),
        np.zeros(0),
    )
    if n == 0:
        return empty
    own = np.asarray(own_position, dtype=float)[:2]
    xy = pts[:, :2]

    # Pool points into grid cells; a cell's centroid stands in for its points in the neighbour search.
    ij = np.floor((xy - xy.min(axis=0)) / cfg.grid_cell).astype(np.int64)
    key = ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1]
    _, cell_of_point, cell_count = np.unique(key, return_inverse=True, return_counts=True)
    cell_of_point = cell_of_point.ravel()
    n_cells = cell_count.size
    cell_xy = np.stack(
        [np.bincount(cell_of_point, weights=xy[:, k], minlength=n_cells) / cell_count for k in (0, 1)], axis=1
    )
    cell_range = np.hypot(cell_xy[:, 0] - own[0], cell_xy[:, 1] - own[1])

    tree = cKDTree(cell_xy)
    search = float(range_tolerance(np.array(cell_range.max()), cfg))
    pairs = tree.query_pairs(r=search, output_type="ndarray")
    if pairs.size:
        a, b = pairs[:, 0], pairs[:, 1]
        d = np.hypot(*(cell_xy[a] - cell_xy[b]).T)
        ok = d <= range_tolerance(0.5 * (cell_range[a] + cell_range[b]), cfg)
        a, b = a[ok], b[ok]
    else:
        a = b = np.zeros(0, dtype=np.int64)
    graph = coo_matrix((np.ones(a.size, dtype=np.int8), (a, b)), shape=(n_cells, n_cells))
    _, cell_label = connected_components(graph, directed=False)
    label = cell_label[cell_of_point]

    # Group points by label once; per-cluster statistics come from reduceat over the sorted order.
    order = np.argsort(label, kind="stable")
    sorted_label = label[order]
    starts = np.flatnonzero(np.r_[True, sorted_label[1:] != sorted_label[:-1]])
    sizes = np.diff(np.r_[starts, n])
    r_pts = np.hypot(xy[order, 0] - own[0], xy[order, 1] - own[1])
    nearest = np.minimum.reduceat(r_pts, starts)
    lo = np.minimum.reduceat(xy[order], starts, axis=0)
    hi = np.maximum.reduceat(xy[order], starts, axis=0)
    extent = np.hypot(*(hi - lo).T)

    candidates = np.flatnonzero(sizes >= cfg.min_points)
    candidates = candidates[np.argsort(nearest[candidates], kind="stable")][: cfg.max_clusters]
    if candidates.size == 0:
        return empty
    cell_order = np.argsort(cell_label, kind="stable")
    cell_starts = np.searchsorted(cell_label[cell_order], np.arange(cell_label.max() + 2))
    out_labels = np.full(all_pts.shape[0], -1, dtype=int)
    clusters, footprints = [], []
    for k, c in enumerate(candidates):
        members = order[starts[c] : starts[c] + sizes[c]]
        out_labels[finite_idx[members]] = k
        clusters.append(pts[members])
        label_c = sorted_label[starts[c]]
        footprints.append(cell_xy[cell_order[cell_starts[label_c] : cell_starts[label_c + 1]]])

    # Bearing spans: each point's bearing relative to its cluster's mean direction, reduced per cluster.
    rel = xy[order] - own
    mean_dir = np.add.reduceat(rel, starts, axis=0)
    centre = np.arctan2(mean_dir[:, 1], mean_dir[:, 0])
    offset = np.arctan2(rel[:, 1], rel[:, 0]) - np.repeat(centre, sizes)
    offset = (offset + np.pi) % (2.0 * np.pi) - np.pi
    lo_b, hi_b = np.minimum.reduceat(offset, starts), np.maximum.reduceat(offset, starts)
    return ClusterResult(
        clusters,
        footprints,
        nearest[candidates],
        extent[candidates] > cfg.max_extent,
        out_labels,
        centre[candidates],
        lo_b[candidates],
        hi_b[candidates],
    )
