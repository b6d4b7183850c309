"""Which part of a track a nearer object hides, seen from the radar, and what that means for its measurement (not in
paper 001; the LiDAR paper's visibility factor, eq. 10-11, carried over to the radar).

A radar sees nothing behind a hull. A boat partly behind another returns from its lit part only, so the box around
its returns sits toward the lit side; a boat wholly behind another returns nothing, though it is still there. The
tracker uses the shadow share three ways: the position measurement's variance grows with it, the centre across the
line of sight is measured from the lit edge, and a wholly hidden track may coast longer.

Frames: world N/E, bearings from north toward east (rad), everything relative to the radar's position.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SHADOW_BINS = 16  # resolution of a track's bearing span


def wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@dataclass
class ShadowCasters:
    """Returns that may hide a track this frame, world N/E, seen from the radar."""

    points: np.ndarray  # (n, 2)
    bearing: np.ndarray  # (n,) rad
    range_m: np.ndarray  # (n,)
    owner: np.ndarray  # (n,) which caster (cluster) each belongs to

    @classmethod
    def of(cls, parts: list[np.ndarray], sensor_ne: np.ndarray) -> ShadowCasters:
        """From the (k_i, 2) returns of each caster."""
        if not parts:
            e = np.empty(0)
            return cls(np.empty((0, 2)), e, e, e.astype(np.int64))
        pts = np.concatenate(parts)
        rel = pts - sensor_ne
        return cls(
            points=pts,
            bearing=np.arctan2(rel[:, 1], rel[:, 0]),
            range_m=np.hypot(rel[:, 0], rel[:, 1]),
            owner=np.repeat(np.arange(len(parts)), [len(p) for p in parts]),
        )


def shadow(
    box: np.ndarray,
    casters: ShadowCasters,
    sensor_ne: np.ndarray,
    margin_m: float,
    own_gap_m: float,
    point_pad_m: float,
) -> np.ndarray | None:
    """(SHADOW_BINS,) bool over the bearing span of a track's ``box`` (north_min, east_min, north_max, east_max),
    from its counter-clockwise to its clockwise edge (toward increasing bearing): which parts a nearer caster
    shadows. None when nothing does.

    A caster return must lie ``margin_m`` nearer than the box centre and outside the box grown by ``own_gap_m`` (a
    piece of the track's own hull does not hide it). Each caster shadows the bearing span of its returns, each return
    taken ``point_pad_m`` wide.
    """
    return shadows(np.asarray(box, float).reshape(1, 4), casters, sensor_ne, margin_m, own_gap_m, point_pad_m)[0]


def shadows(
    boxes: np.ndarray,
    casters: ShadowCasters,
    sensor_ne: np.ndarray,
    margin_m: float,
    own_gap_m: float,
    point_pad_m: float,
) -> list[np.ndarray | None]:
    """``shadow`` of each of the (k, 4) ``boxes``, all tracks of a frame in one pass over the casters (per-track
    calls were dozens of tiny numpy operations each)."""
    out: list[np.ndarray | None] = [None] * len(boxes)
    if len(boxes) == 0 or casters.range_m.size == 0:
        return out
    centres = (boxes[:, :2] + boxes[:, 2:]) / 2 - sensor_ne
    # Python's hypot and atan2 per box, as a scalar call gives them (numpy's may differ in the last bit)
    r_track = np.array([math.hypot(c[0], c[1]) for c in centres.tolist()])
    front = casters.range_m[None, :] < (r_track - margin_m)[:, None]
    rows = np.flatnonzero(front.any(axis=1))
    if rows.size == 0:  # nothing nearer than any track: the usual case, decided before any trigonometry
        return out
    box, front = boxes[rows], front[rows]
    b_track = np.array([math.atan2(centres[i, 1], centres[i, 0]) for i in rows.tolist()])
    px, py = casters.points[:, 0], casters.points[:, 1]
    grown = np.concatenate([box[:, :2] - own_gap_m, box[:, 2:] + own_gap_m], axis=1)
    own = (px >= grown[:, 0, None]) & (py >= grown[:, 1, None]) & (px <= grown[:, 2, None]) & (py <= grown[:, 3, None])
    d = wrap(casters.bearing[None, :] - b_track[:, None])
    front &= ~own & (np.abs(d) < math.pi / 2)
    corners = np.stack([box[:, [0, 1]], box[:, [0, 3]], box[:, [2, 1]], box[:, [2, 3]]], axis=1) - sensor_ne
    half = np.abs(wrap(np.arctan2(corners[..., 1], corners[..., 0]) - b_track[:, None])).max(axis=1)
    live = front.any(axis=1) & (half > 0)
    if not live.any():
        return out
    rows, front, d, half = rows[live], front[live], d[live], half[live]
    # Each row's casters' bearing spans, as (row, caster) slots of one flat array.
    n_casters = int(casters.owner.max()) + 1
    r, c = np.nonzero(front)
    slot = r * n_casters + casters.owner[c]
    pad = (point_pad_m / np.maximum(casters.range_m, 1e-3))[c]
    lo = np.full(rows.size * n_casters, np.inf)
    hi = np.full(rows.size * n_casters, -np.inf)
    np.minimum.at(lo, slot, d[r, c] - pad)
    np.maximum.at(hi, slot, d[r, c] + pad)
    lo, hi = lo.reshape(rows.size, 1, n_casters), hi.reshape(rows.size, 1, n_casters)
    bins = _bins(half)[:, :, None]
    shadowed = ((bins >= lo) & (bins <= hi)).any(axis=2)
    for k, row in enumerate(rows.tolist()):
        if shadowed[k].any():
            out[row] = shadowed[k]
    return out


def _bins(half: np.ndarray) -> np.ndarray:
    """(k, SHADOW_BINS) np.linspace(-h, h, SHADOW_BINS) for each h of ``half`` (> 0), computed as linspace does
    (i * step + start, the last one set to the end) without its per-call overhead, ~80 us."""
    step = (half - -half) / (SHADOW_BINS - 1)
    bins = np.arange(SHADOW_BINS, dtype=float)[None, :] * step[:, None] + (-half)[:, None]
    bins[:, -1] = half
    return bins


def lit_edge_centre(
    centre: np.ndarray,
    returns: np.ndarray,
    track_centre: np.ndarray,
    track_size: np.ndarray,
    shadowed: np.ndarray | None,
    sensor_ne: np.ndarray,
) -> np.ndarray:
    """The centre measurement with its across-the-line-of-sight part taken from the lit edge.

    When one end of the track's bearing span lies in a nearer object's shadow and the other end does not, the
    ``returns`` (k, 2) come from the lit part only: their box centre is off toward the lit side by up to half the
    hidden width. The lit edge is still an edge of the hull, so the centre lies half the track's silhouette width
    (its box of ``track_size`` north/east extents, projected across the line of sight) in from it.
    """
    if shadowed is None:
        return centre
    m = shadowed.size // 2
    hidden_ccw, hidden_cw = bool(shadowed[:m].any()), bool(shadowed[m:].any())
    if hidden_ccw == hidden_cw:  # both ends, or neither: no lit edge to hold on to
        return centre
    rel = track_centre - sensor_ne
    u = rel / max(float(np.hypot(*rel)), 1e-9)
    n = np.array([-u[1], u[0]])  # toward increasing bearing (clockwise seen from above)
    width = float(track_size[0] * abs(n[0]) + track_size[1] * abs(n[1]))
    across = (returns - sensor_ne) @ n
    if float(across.max() - across.min()) >= width:
        return centre  # the returns already span the hull
    lit = across.max() - width / 2 if hidden_ccw else across.min() + width / 2
    return centre + n * (lit - float((centre - sensor_ne) @ n))
