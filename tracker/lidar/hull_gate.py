"""Returns within the sea margin that lie on a tracked hull: solid, though a crest could reach as high.

In a sea the margin above the fitted surface hides a hull's lower strakes along with the crests, and a boat 30-60 m
off may be met only there (the VLP-16's low beams reach it close to the water while the boat pitches). One return
cannot say whether it is a crest or a hull; a confirmed track can: returns inside its footprint (grown by
``grow_m`` for the box's error) are its hull. Frames: world NED (north, east), m.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from tracker.types import Track


def on_tracked_hulls(
    points_ne: np.ndarray, tracks: Sequence[Track], grow_m: float, coast_drift_cap_m: float = 0.0
) -> np.ndarray:
    """(L,) bool: the point lies inside some confirmed track's footprint box grown by ``grow_m`` on every side, and
    for a coasting track by the distance its prediction moved since its last measurement (speed x time unseen, at
    most ``coast_drift_cap_m``): a hull that sank into the sea margin stops feeding its track, whose prediction then
    drifts off it by whatever velocity error it carried."""
    pts = np.asarray(points_ne, dtype=float).reshape(-1, 2)
    point, _, _ = _pairs_inside(pts, tracks, grow_m, coast_drift_cap_m)
    inside = np.zeros(pts.shape[0], dtype=bool)
    inside[point] = True
    return inside


def tracked_hull_of(points_ne: np.ndarray, tracks: Sequence[Track], grow_m: float) -> np.ndarray:
    """(L,) int: the index in ``tracks`` of a confirmed track whose footprint box, grown by ``grow_m`` on every
    side, holds the point (the nearest centre where several do), -1 for none."""
    pts = np.asarray(points_ne, dtype=float).reshape(-1, 2)
    point, track, dist2 = _pairs_inside(pts, tracks, grow_m)
    out = np.full(pts.shape[0], -1, dtype=np.int64)
    if point.size:
        # nearest centre per point, the lower track index among equals (the pairs come sorted by point, then
        # track, and lexsort is stable)
        order = np.lexsort((dist2, point))
        first = np.ones(order.size, dtype=bool)
        first[1:] = point[order[1:]] != point[order[:-1]]
        out[point[order[first]]] = track[order[first]]
    return out


def _pairs_inside(
    pts: np.ndarray, tracks: Sequence[Track], grow_m: float, coast_drift_cap_m: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (point, track) pair with point l of ``pts`` (L, 2) inside the grown box of confirmed track t (t indexes
    ``tracks``), as (K,) arrays of l and t sorted by l then t, and each pair's squared distance to the track's
    centre; a track without a finite size or heading counts as none.

    Work is a raster lookup per point, then (points near some box x confirmed tracks) for a square around each box
    (its half-diagonal either way), then the box test on the few pairs within it: a revolution's margin returns lie
    mostly far from any hull."""
    which = np.array([i for i, t in enumerate(tracks) if t.confirmed and _finite_box(t)], dtype=np.int64)
    if pts.shape[0] == 0 or not which.size:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, np.zeros(0)
    hull = [tracks[i] for i in which]
    centre = np.array([t.position[:2] for t in hull])  # (T, 2)
    heading = np.array([t.heading for t in hull])
    grow = grow_m + np.minimum([_coast_drift(t) for t in hull], max(coast_drift_cap_m, 0.0))
    half_len = np.array([t.length for t in hull]) / 2 + grow
    half_wid = np.array([t.width for t in hull]) / 2 + grow
    reach = np.hypot(half_len, half_wid) * (1.0 + 1e-9) + 1e-9  # a little over: never closer than the box test
    near = _near_some_square(pts, centre, reach) if pts.shape[0] * which.size >= _RASTER_FROM else None
    if near is not None:
        pts = pts[near]
    # (L, T) per coordinate: an (L, T, 2) difference array cost as much as all the rest
    dn = pts[:, 0, None] - centre[None, :, 0]
    de = pts[:, 1, None] - centre[None, :, 1]
    point, k = np.nonzero((np.abs(dn) <= reach) & (np.abs(de) <= reach))
    dn, de = dn[point, k], de[point, k]
    c, s = np.cos(heading)[k], np.sin(heading)[k]
    along = dn * c + de * s
    across = de * c - dn * s
    inside = (np.abs(along) <= half_len[k]) & (np.abs(across) <= half_wid[k])
    dn, de = dn[inside], de[inside]
    point = point[inside] if near is None else near[point[inside]]
    return point, which[k[inside]], dn * dn + de * de


_RASTER_CELL_M = 2.0
_RASTER_MAX_CELLS = 250_000  # 1 km x 1 km at 2 m: beyond, a far track's square is not worth a raster
# From this many (point, track) pairs the raster pays for its fixed cost. A rough sea's margin returns number in the
# thousands a revolution, nearly all of them far from any hull; against 20 tracks (one core), 1,000 / 1,500 / 3,000 /
# 6,000 returns took 0.27 / 0.33 / 0.87 / 1.42 ms testing every pair and 0.30 / 0.32 / 0.49 / 0.70 ms through it.
_RASTER_FROM = 30_000


def _near_some_square(pts: np.ndarray, centre: np.ndarray, reach: np.ndarray) -> np.ndarray | None:
    """Indices (ascending) of the points lying in a cell of a coarse raster that some track's square (centre +-
    reach) touches, grown by a cell each way so that rounding never drops a point the exact test keeps; None when
    the squares span too large a raster (then every point is tested). One lookup per point, one slice per track."""
    lo = np.floor((centre - reach[:, None]) / _RASTER_CELL_M).astype(np.int64) - 1
    hi = np.floor((centre + reach[:, None]) / _RASTER_CELL_M).astype(np.int64) + 1
    origin = lo.min(axis=0)
    shape = hi.max(axis=0) - origin + 1
    if shape[0] * shape[1] > _RASTER_MAX_CELLS:
        return None
    raster = np.zeros(tuple(shape), dtype=bool)
    for (a0, a1), (b0, b1) in zip(lo - origin, hi - origin, strict=True):
        raster[a0 : b0 + 1, a1 : b1 + 1] = True
    cell = np.floor(pts / _RASTER_CELL_M).astype(np.int64) - origin
    inside = np.flatnonzero(np.all((cell >= 0) & (cell < shape), axis=1))
    return inside[raster[cell[inside, 0], cell[inside, 1]]]


def _finite_box(track: Track) -> bool:
    """The track has a finite position, heading and size (scalar checks: a few tracks, no arrays needed)."""
    return all(math.isfinite(v) for v in (*track.position, track.heading, track.length, track.width))


def _coast_drift(track: Track) -> float:
    """How far the track's prediction moved since its last measurement (m); 0 when its speed is unknown."""
    if not track.speed_valid or not math.isfinite(track.time_since_update):
        return 0.0
    return float(np.hypot(*track.velocity[:2])) * max(track.time_since_update, 0.0)
