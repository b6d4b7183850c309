"""A still vessel's hull cut out of a cluster that grew around it.

A moored boat tracked for seconds lies still at its size. When a scan's cluster joins it to its neighbours (the
quay's face, seen through the gap between two moored hulls, links them), the joined cluster is the size of a quay
stretch: the track took that size and the static-structure rule (``LidarTracker._static_structure``) ended it and
remembered the boat's hull as quay, untracked for as long as the memory lasts (tuning seed 27: a 14.7 m boat moored
6 m from another went untracked for 30 s). A vessel that has lain still does not grow, so before the structure tests
the returns within such a track's predicted box, grown by a margin, are cut out as a cluster of their own, and the
rest of the cluster is judged alone.
"""

from __future__ import annotations

import numpy as np

from tracker.lidar.clustering import ClusterResult, with_pieces

_MIN_CELLS = 3  # footprint cells on each side of a cut: the fits need three


def box_depths(points_ne: np.ndarray, boxes: np.ndarray, margin_m: float, min_half_m: float = 0.0) -> np.ndarray:
    """(P, B): how deep each of the (P, 2) points (north, east) lies in each box (rows north, east, heading rad,
    length, width; m) grown by ``margin_m``: max(|along| / half-length, |across| / half-width), at most 1 inside.
    A grown half-size under ``min_half_m`` is taken as that, so that a degenerate box has a depth scale."""
    rel = points_ne[:, None, :2] - boxes[None, :, :2]
    c, s = np.cos(boxes[:, 2])[None, :], np.sin(boxes[:, 2])[None, :]
    along = np.abs(rel[..., 0] * c + rel[..., 1] * s) / np.maximum(0.5 * boxes[None, :, 3] + margin_m, min_half_m)
    across = np.abs(rel[..., 1] * c - rel[..., 0] * s) / np.maximum(0.5 * boxes[None, :, 4] + margin_m, min_half_m)
    return np.maximum(along, across)


def _owners(depth: np.ndarray) -> np.ndarray:
    """(P,) the box each point lies deepest in, -1 where it lies in none."""
    owner = np.argmin(depth, axis=1)
    return np.where(np.take_along_axis(depth, owner[:, None], axis=1)[:, 0] <= 1.0, owner, -1)


def cut_settled_hulls(
    result: ClusterResult,
    points_world: np.ndarray,
    own: np.ndarray,
    boxes: np.ndarray,
    margin_m: float,
    min_extent_m: float,
    min_points: int,
) -> ClusterResult:
    """``result`` with the returns of every cluster at least ``min_extent_m`` across that lie in one of ``boxes``
    (still, settled tracks' predicted boxes: north, east, heading, length, width) grown by ``margin_m`` made a
    cluster per box; the cluster keeps the rest. A cut needs ``min_points`` returns and three footprint cells on
    each side; clusters stay nearest first and ``labels`` follows them. ``points_world`` (N, 3) are the points
    ``result`` was clustered from. ``margin_m`` < 0 cuts nothing."""
    if margin_m < 0.0 or len(boxes) == 0 or not result.clusters:
        return result
    grown = np.flatnonzero(result.extent >= min_extent_m)
    if grown.size == 0:
        return result
    boxes = np.asarray(boxes, dtype=float).reshape(-1, 5)
    pts = np.asarray(points_world, dtype=float).reshape(-1, 3)
    kept: dict[int, tuple[np.ndarray, np.ndarray, bool]] = {}
    pieces: list[tuple[np.ndarray, np.ndarray]] = []
    for k in grown.tolist():  # few: clusters the size of a quay stretch
        fp = result.footprints[k]
        cell_depth = box_depths(fp[:, :2], boxes, margin_m)
        cell_owner = _owners(cell_depth)
        if not (cell_owner >= 0).any():
            continue
        members = np.flatnonzero(result.labels == k)
        point_depth = box_depths(pts[members, :2], boxes, margin_m)
        point_owner = _owners(point_depth)
        owners = [
            o
            for o in np.unique(cell_owner[cell_owner >= 0]).tolist()
            if np.count_nonzero(cell_owner == o) >= _MIN_CELLS and np.count_nonzero(point_owner == o) >= min_points
        ]
        if not owners:
            continue
        rest_cells = ~np.isin(cell_owner, owners)
        rest_points = ~np.isin(point_owner, owners)
        if np.count_nonzero(rest_cells) < _MIN_CELLS or not rest_points.any():
            if len(owners) == 1:  # the cluster is that hull: nothing to judge apart
                continue
            # the cluster is these hulls: what is left goes to the box it lies nearest
            cell_owner[rest_cells] = np.array(owners)[np.argmin(cell_depth[rest_cells][:, owners], axis=1)]
            point_owner[rest_points] = np.array(owners)[np.argmin(point_depth[rest_points][:, owners], axis=1)]
            rest_cells[:] = False
            rest_points[:] = False
        cuts = [(members[point_owner == o], fp[cell_owner == o]) for o in owners]
        if rest_points.any():
            kept[k] = (members[rest_points], fp[rest_cells], bool(result.oversized[k]))
        else:  # the first hull takes the cluster's place
            kept[k] = (*cuts[0], False)
            cuts = cuts[1:]
        pieces += cuts
    return with_pieces(result, pts, own, kept, pieces, pieces_carved=False)
