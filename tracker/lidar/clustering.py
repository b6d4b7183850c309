"""Range-adaptive Euclidean clustering of world-frame returns (paper sec. 2.1, "modified Euclidean clustering").

Two returns are neighbours when their horizontal distance is within a tolerance that grows with range, because the
VLP-16's beams fan out: a hull at 60 m is sampled every ~2 m vertically where at 5 m it is every 0.2 m. A fixed
tolerance either merges nearby boats or shatters distant ones. Clusters are the connected components of the
neighbour graph. Work is 2-D (north, east); z rides along for height.

For speed, returns are pooled twice. First into small fixed grid cells (``grid_cell``): a vertical hull stacks all
16 rings onto the same horizontal spot, so a cell often holds dozens of returns, and the cell centroids are the
cluster's footprint for shape fitting. Then, for the neighbour search only, the cells are pooled again into
"link cells" about a quarter of the local tolerance wide: at 60 m, where the tolerance is 2.6 m, a quay wall's
thousands of 0.15 m cells each had ~35 neighbours within reach; 0.65 m link cells have a handful. Each range band
is searched with its own reach (``candidate_pairs``), so the cost near the boat does not depend on how far the
farthest return lies. Pooling never
joins what the tolerance would keep apart (a link cell's diagonal is a third of the tolerance); comparing link
cell centroids shifts the effective tolerance by up to one link cell diagonal, as the fine grid did near the boat,
mostly downwards: two hulls at 60 m (tolerance 2.6 m) now stay apart from a gap of about 2.3 m.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from tracker.grouping import expand_groups, group_keys, group_order, stable_order
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
    extent: np.ndarray  # (k,) m, the diagonal of each cluster's horizontal bounding box (north, east)
    labels: np.ndarray  # (N,) int index into ``clusters`` per input point, -1 = not in a kept cluster
    # Bearing interval seen from the own boat (rad, 0 = north, clockwise): centre, and the span as offsets from
    # it (lo <= 0 <= hi), so an interval across north needs no special case. For occlusion reasoning.
    bearing: np.ndarray | None = None  # (k,)
    bearing_lo: np.ndarray | None = None  # (k,)
    bearing_hi: np.ndarray | None = None  # (k,)
    # (k,) bool: a hull carved out of a wall's cluster (tracker.lidar.moored): it stands in front of the face, so it
    # is not the wall whatever the structure memory remembers there. None: none carved.
    carved: np.ndarray | None = None

    @property
    def objects(self) -> list[np.ndarray]:
        """The clusters small enough to be vessels, nearest first."""
        return [c for c, big in zip(self.clusters, self.oversized, strict=True) if not big]


def occluders(result: ClusterResult, min_points: int) -> np.ndarray:
    """(k,) bool: clusters solid enough to hide something behind them. A clump of a few returns (a wave top, a
    burst of spray that came through the filters) shadows a sliver, not a hull; counting it as an occluder made
    a boat behind it ignore its own measurement."""
    return np.array([len(c) >= min_points for c in result.clusters], dtype=bool)


class Shadows(NamedTuple):
    """Per object (a group of clusters), what the shadows of clusters clearly in front of it do to it."""

    touched: np.ndarray  # (g,) bool: one touches its bearing span; its visible extent may be cut short
    low_end: np.ndarray  # (g,) bool: one reaches its low-bearing end: the hull may go on beyond it
    high_end: np.ndarray  # (g,) bool: the same at its high-bearing end


def shadows(
    groups: list[list[int]],
    result: ClusterResult,
    margin: float,
    depth: float | np.ndarray = 1.0,
    min_points: int = 1,
) -> Shadows:
    """The bearing shadows that fall on each object made of the clusters of one of ``groups``.

    ``margin`` (rad) widens the test for the gap a shadow edge leaves; ``depth`` (m, one for all or (g,) one per
    object) is how much nearer than the object an occluder must be; an occluder has at least ``min_points``
    returns (:func:`occluders`). A shadow that falls within an object's span (a cabin seen over a nearer hull, a gap
    between two pieces) touches it but reaches neither end. All objects against all clusters at once.
    """
    g = len(groups)
    if g == 0 or result.bearing is None or result.bearing_lo is None or result.bearing_hi is None:
        none = np.zeros(g, dtype=bool)
        return Shadows(none, none.copy(), none.copy())
    b, lo, hi = result.bearing, result.bearing_lo, result.bearing_hi
    first = np.array([m[0] for m in groups])
    member = np.zeros((g, len(result.clusters)), dtype=bool)
    for row, m in enumerate(groups):
        member[row, m] = True
    shift = (b[None, :] - b[first][:, None] + np.pi) % (2.0 * np.pi) - np.pi  # [o, j]: j's centre seen from o's
    span_lo, span_hi = shift + lo[None, :], shift + hi[None, :]
    own_lo = np.where(member, span_lo, np.inf).min(axis=1)[:, None]
    own_hi = np.where(member, span_hi, -np.inf).max(axis=1)[:, None]
    own_range = np.where(member, result.min_range[None, :], np.inf).min(axis=1)[:, None]
    solid = occluders(result, min_points)[None, :]
    nearer = (result.min_range[None, :] < own_range - np.reshape(depth, (-1, 1))) & solid & ~member
    return Shadows(
        np.any(nearer & (span_lo <= own_hi + margin) & (span_hi >= own_lo - margin), axis=1),
        np.any(nearer & (span_lo <= own_lo + margin) & (span_hi >= own_lo - margin), axis=1),
        np.any(nearer & (span_lo <= own_hi + margin) & (span_hi >= own_hi - margin), axis=1),
    )


def range_tolerance(range_m: np.ndarray, config: ClusterConfig) -> np.ndarray:
    """Neighbour distance tolerance at a given horizontal range, m."""
    return np.minimum(config.base_tolerance + config.tolerance_per_metre * range_m, config.max_tolerance)


_LINK_BAND_RATIO = 1.5  # tolerance growth across one band of link cells
_LINK_CELLS_PER_TOLERANCE = 4  # link cell side = the band's smallest tolerance / this
# A band with fewer link cells is searched with the next band's (a k-d tree costs ~35 us to build, whatever its size;
# a few hundred cells searched with 1.5 x their reach cost less: sea state 3 and rain scans, 484 link cells in 3.5
# bands, took 0.75 ms with a search per band and 0.42 ms so, against 0.31 ms with one search for all).
_OWN_SEARCH_MIN_LINKS = 256


def _link_bands(cfg: ClusterConfig) -> tuple[np.ndarray, np.ndarray]:
    """Range bands for the link cells: (band start ranges (b,) m, link cell side per band (b,) m)."""
    tols = [cfg.base_tolerance]
    if cfg.tolerance_per_metre > 0:
        while tols[-1] * _LINK_BAND_RATIO < cfg.max_tolerance:
            tols.append(tols[-1] * _LINK_BAND_RATIO)
    tol = np.array(tols)
    start = (tol - cfg.base_tolerance) / cfg.tolerance_per_metre if cfg.tolerance_per_metre > 0 else np.zeros(1)
    return start, np.maximum(tol / _LINK_CELLS_PER_TOLERANCE, cfg.grid_cell)


def grid_cells(x: np.ndarray, y: np.ndarray, cell_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Points (north ``x``, east ``y``) pooled into square cells ``cell_m`` wide: the points' order grouped by cell,
    each cell's start in it, its point count and its centroid (n_cells, 2)."""
    i = np.floor((x - x.min()) * (1.0 / cell_m)).astype(np.int64)
    j = np.floor((y - y.min()) * (1.0 / cell_m)).astype(np.int64)
    order, starts, count = group_order(i * (int(j.max()) + 1) + j)
    centroid = np.column_stack([np.add.reduceat(np.take(v, order), starts) for v in (x, y)]) / count[:, None]
    return order, starts, count, centroid


class LinkCells(NamedTuple):
    """Grid cells pooled for the neighbour search: centroids (north ``x``, east ``y``), their range from the own
    boat, their range band, and each grid cell's link cell."""

    x: np.ndarray
    y: np.ndarray
    range_m: np.ndarray
    band: np.ndarray
    of_cell: np.ndarray


def pool_link_cells(cell_xy: np.ndarray, cell_weight: np.ndarray, own: np.ndarray, cfg: ClusterConfig) -> LinkCells:
    """Pool grid cells (centroids ``cell_xy``, weights the returns they hold) into link cells a quarter of their
    range band's smallest tolerance wide."""
    band_start, side = _link_bands(cfg)
    cx, cy = cell_xy[:, 0], cell_xy[:, 1]
    cell_range = np.hypot(cx - own[0], cy - own[1])
    band = np.searchsorted(band_start, cell_range, side="right") - 1
    inv_side = 1.0 / side[band]
    i = np.floor((cx - cx.min()) * inv_side).astype(np.int64)
    j = np.floor((cy - cy.min()) * inv_side).astype(np.int64)
    width = int(max(i.max(), j.max())) + 1
    order, starts, _, link_of_cell = group_keys((band * width + i) * width + j)
    w = np.take(cell_weight, order)
    w_sum = np.add.reduceat(w, starts)
    lx = np.add.reduceat(np.take(cx, order) * w, starts) / w_sum
    ly = np.add.reduceat(np.take(cy, order) * w, starts) / w_sum
    return LinkCells(lx, ly, np.hypot(lx - own[0], ly - own[1]), np.take(band, np.take(order, starts)), link_of_cell)


def link_cells(cell_xy: np.ndarray, cell_weight: np.ndarray, own: np.ndarray, cfg: ClusterConfig) -> np.ndarray:
    """Connected-component label of each grid cell under the range-adaptive tolerance, (n_cells,) int."""
    links = pool_link_cells(cell_xy, cell_weight, own, cfg)
    lx, ly, link_range = links.x, links.y, links.range_m
    a, c = candidate_pairs(links, cfg)
    d = np.hypot(np.take(lx, a) - np.take(lx, c), np.take(ly, a) - np.take(ly, c))
    ok = d <= range_tolerance(0.5 * (np.take(link_range, a) + np.take(link_range, c)), cfg)
    _, link_label = connected_components(_pair_graph(a[ok], c[ok], lx.size), directed=False)
    return link_label[links.of_cell]


def candidate_pairs(links: LinkCells, cfg: ClusterConfig) -> tuple[np.ndarray, np.ndarray]:
    """Every pair of link cells (indices a, c) that may be neighbours, each once: one k-d search per range band,
    with the reach of that band's farthest link, over its links and the nearer bands' links within that reach of
    them; a pair is kept by the band of its farther member.

    A pair's tolerance is taken at its mean range, never beyond its farther member's, so that band's reach finds
    it. One search with the farthest link's reach for all would let a single return at 95 m (tolerance 3 m) give
    every 0.15 m cell of the own deck the 3 m reach: 51 k pairs became 243 k and the scan took 37 ms, not 15."""
    band_start, _ = _link_bands(cfg)
    link_range = links.range_m
    xy = np.column_stack([links.x, links.y])
    # Link cells come ordered by band (their grouping key starts with it): each band, and each run of bands, is one
    # slice. A band of few links joins the next band's search rather than pay for a tree of its own.
    bounds = np.searchsorted(links.band, np.arange(band_start.size + 1)).tolist()
    counts = np.diff(bounds)
    # A search ends at a band with enough links, at the last band, or before an empty band (a few near links never
    # take a reach more than one band's growth, 1.5 x, beyond their own).
    ends = [
        bounds[b + 1]
        for b in range(counts.size)
        if counts[b] >= _OWN_SEARCH_MIN_LINKS or b == counts.size - 1 or counts[b + 1] == 0
    ]
    firsts: list[np.ndarray] = []
    seconds: list[np.ndarray] = []
    lo = 0
    for hi in ends:
        if hi == lo:
            continue
        mine_range = link_range[lo:hi]
        # A link's centroid may lie a little nearer than its band's start, and a nearer band's link never beyond it:
        # the reach covers both, and the nearer links taken are those within reach of this search's nearest one.
        far_end = max(float(mine_range.max()), float(band_start[links.band[hi - 1]]))
        reach = float(range_tolerance(np.asarray(far_end), cfg))
        nearer = np.flatnonzero(link_range[:lo] >= float(mine_range.min()) - reach)
        # The nearest search (the own deck, spray: the most pairs) has no nearer links: its slice and its pairs are
        # used as they are, not gathered and filtered (0.66 -> 0.45 ms a scan on rough-sea scans).
        if nearer.size:
            members = np.concatenate([nearer, np.arange(lo, hi)])
            points = xy[members]
        else:
            members, points = None, xy[lo:hi]
        # An unbalanced, uncompacted tree builds faster and finds the same pairs (their order does not matter).
        pairs = cKDTree(points, balanced_tree=False, compact_nodes=False).query_pairs(reach, output_type="ndarray")
        if members is None:
            firsts.append(pairs[:, 0] + lo)
            seconds.append(pairs[:, 1] + lo)
        else:
            pairs = pairs[pairs[:, 1] >= nearer.size]  # query_pairs gives i < j; two nearer links were paired before
            firsts.append(members[pairs[:, 0]])
            seconds.append(members[pairs[:, 1]])
        lo = hi
    return np.concatenate(firsts), np.concatenate(seconds)


def _pair_graph(a: np.ndarray, c: np.ndarray, n: int) -> csr_matrix:
    """The (n, n) graph with an edge a[k] -> c[k] per pair, built as CSR directly: csr_matrix((data, (a, c)))
    goes through COO, sorts and sums duplicates (pairs are unique) and connected_components then converts its
    int8 data to float64, which cost more than finding the components."""
    order = stable_order(a)
    indptr = np.zeros(n + 1, dtype=np.int32)
    np.cumsum(np.bincount(a, minlength=n), out=indptr[1:])
    return csr_matrix((np.ones(a.size), c[order].astype(np.int32), indptr), shape=(n, n))


def cluster_points(
    points_world: np.ndarray, own_position: np.ndarray, config: ClusterConfig | None = None
) -> ClusterResult:
    """Cluster (N, 3) world NED points; ``own_position`` is the own boat's (north, east), m."""
    # Column-wise work and np.take throughout: numpy reduces and gathers single columns of 29k points ten to a
    # hundred times faster than the same operations along axis 0 of an (N, 2) or (N, 3) array.
    cfg = config or ClusterConfig()
    all_pts = np.asarray(points_world, dtype=float).reshape(-1, 3)
    columns = np.ascontiguousarray(all_pts.T)  # strided columns cost 2.5x per pass
    finite = np.isfinite(columns[0] + columns[1] + columns[2])
    everything = bool(finite.all())  # the usual case: no gathers for the finite ones
    finite_idx = np.arange(all_pts.shape[0]) if everything else np.flatnonzero(finite)
    n = finite_idx.size
    empty = ClusterResult(
        [],
        [],
        np.zeros(0),
        np.zeros(0, bool),
        np.zeros(0),
        np.full(all_pts.shape[0], -1, dtype=int),
        np.zeros(0),
        np.zeros(0),
        np.zeros(0),
    )
    if n == 0:
        return empty
    own = np.asarray(own_position, dtype=float)[:2]
    x, y = (columns[0], columns[1]) if everything else (columns[0][finite_idx], columns[1][finite_idx])

    p_order, p_starts, cell_count, cell_xy = grid_cells(x, y, cfg.grid_cell)
    cell_label = link_cells(cell_xy, cell_count.astype(float), own, cfg)

    # Cells grouped by cluster, then their points: every per-cluster statistic is a reduceat over that order.
    c_order, c_starts, c_cells = group_order(cell_label)
    sizes = np.add.reduceat(cell_count[c_order], c_starts)
    members_all = expand_groups(p_order, p_starts, cell_count, c_order)
    starts = np.cumsum(sizes) - sizes
    xs, ys = np.take(x, members_all), np.take(y, members_all)
    dn, de = xs - own[0], ys - own[1]
    nearest = np.sqrt(np.minimum.reduceat(dn * dn + de * de, starts))
    extent = np.hypot(
        np.maximum.reduceat(xs, starts) - np.minimum.reduceat(xs, starts),
        np.maximum.reduceat(ys, starts) - np.minimum.reduceat(ys, starts),
    )

    candidates = np.flatnonzero(sizes >= cfg.min_points)
    candidates = candidates[np.argsort(nearest[candidates], kind="stable")][: cfg.max_clusters]
    if candidates.size == 0:
        return empty
    out_labels = np.full(all_pts.shape[0], -1, dtype=int)
    clusters, footprints = [], []
    for k, c in enumerate(candidates):
        members = members_all[starts[c] : starts[c] + sizes[c]]
        if not everything:
            members = finite_idx[members]
        out_labels[members] = k
        clusters.append(np.take(all_pts, members, axis=0))
        footprints.append(cell_xy[c_order[c_starts[c] : c_starts[c] + c_cells[c]]])

    # Bearing spans: each point's bearing relative to its cluster's mean direction, reduced per cluster. Only the
    # kept clusters' points (a quay wall is most of a scan but gets a span too: it can shadow a boat).
    centre = np.arctan2(np.add.reduceat(de, starts), np.add.reduceat(dn, starts))
    kept = np.zeros(sizes.size, dtype=bool)
    kept[candidates] = True
    sel = np.repeat(kept, sizes)
    k_sizes = sizes[kept]
    offset = np.arctan2(de[sel], dn[sel]) - np.repeat(centre[kept], k_sizes)
    offset -= (2.0 * np.pi) * np.floor((offset + np.pi) * (0.5 / np.pi))
    k_starts = np.cumsum(k_sizes) - k_sizes
    span_lo, span_hi = np.zeros(sizes.size), np.zeros(sizes.size)
    span_lo[kept], span_hi[kept] = np.minimum.reduceat(offset, k_starts), np.maximum.reduceat(offset, k_starts)
    return ClusterResult(
        clusters,
        footprints,
        nearest[candidates],
        extent[candidates] > cfg.max_extent,
        extent[candidates],
        out_labels,
        centre[candidates],
        span_lo[candidates],
        span_hi[candidates],
    )


def with_pieces(
    result: ClusterResult,
    points_world: np.ndarray,
    own: np.ndarray,
    kept: dict[int, tuple[np.ndarray, np.ndarray, bool]],
    pieces: list[tuple[np.ndarray, np.ndarray]],
    pieces_carved: bool,
) -> ClusterResult:
    """``result`` with pieces cut out of its clusters (tracker.lidar.moored, tracker.lidar.settled): each cluster k
    of ``kept`` reduced to (indices into ``points_world`` of the returns it keeps, its footprint cells, oversized),
    each piece (return indices, footprint cells) a cluster of its own, not oversized, carved as ``pieces_carved``
    says. Clusters stay nearest first and ``labels`` follows them."""
    if not kept:
        return result
    pts = np.asarray(points_world, dtype=float).reshape(-1, 3)
    clusters, footprints = list(result.clusters), list(result.footprints)
    oversized = np.asarray(result.oversized, dtype=bool).copy()
    for k, (idx, cells, big) in kept.items():
        clusters[k], footprints[k], oversized[k] = pts[idx], cells, big
    first_new = len(result.clusters)
    labels = result.labels.copy()
    for j, (idx, cells) in enumerate(pieces):
        labels[idx] = first_new + j
        clusters.append(pts[idx])
        footprints.append(cells)
    carved = np.concatenate(
        [
            result.carved if result.carved is not None else np.zeros(first_new, dtype=bool),
            np.full(len(pieces), pieces_carved),
        ]
    )
    return _reordered_nearest_first(
        result,
        clusters,
        footprints,
        np.concatenate([oversized, np.zeros(len(pieces), dtype=bool)]),
        labels,
        own,
        sorted(kept) + list(range(first_new, len(clusters))),
        carved,
    )


def _reordered_nearest_first(
    result: ClusterResult,
    clusters: list[np.ndarray],
    footprints: list[np.ndarray],
    oversized: np.ndarray,
    labels: np.ndarray,
    own: np.ndarray,
    changed: list[int],
    carved: np.ndarray,
) -> ClusterResult:
    """The ``changed`` clusters' ranges, extents and bearing spans recomputed (a handful a scan), all sorted nearest
    first."""
    n = len(clusters)
    pad = n - len(result.clusters)
    nearest = np.concatenate([result.min_range, np.zeros(pad)])
    extent = np.concatenate([result.extent, np.zeros(pad)])
    spans = [
        np.concatenate([b if b is not None else np.zeros(len(result.clusters)), np.zeros(pad)])
        for b in (result.bearing, result.bearing_lo, result.bearing_hi)
    ]
    centre, lo, hi = spans
    for k in changed:
        c = clusters[k]
        dn, de = c[:, 0] - own[0], c[:, 1] - own[1]
        nearest[k] = float(np.sqrt(np.min(dn * dn + de * de)))
        extent[k] = float(np.hypot(np.ptp(c[:, 0]), np.ptp(c[:, 1])))
        centre[k] = float(np.arctan2(de.sum(), dn.sum()))
        off = np.arctan2(de, dn) - centre[k]
        off -= (2.0 * np.pi) * np.floor((off + np.pi) * (0.5 / np.pi))
        lo[k], hi[k] = float(off.min()), float(off.max())
    order = np.argsort(nearest, kind="stable")
    rank = np.empty(n, dtype=np.int64)
    rank[order] = np.arange(n)
    new_labels = np.where(labels >= 0, rank[np.maximum(labels, 0)], -1)
    return replace(
        result,
        clusters=[clusters[k] for k in order],
        footprints=[footprints[k] for k in order],
        min_range=nearest[order],
        oversized=oversized[order],
        extent=extent[order],
        labels=new_labels,
        bearing=centre[order],
        bearing_lo=lo[order],
        bearing_hi=hi[order],
        carved=carved[order],
    )
