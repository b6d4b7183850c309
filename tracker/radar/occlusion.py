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
    centre = (box[:2] + box[2:]) / 2 - sensor_ne
    r_track = math.hypot(centre[0], centre[1])
    front = casters.range_m < r_track - margin_m
    if not front.any():  # nothing nearer: the usual case, decided before any trigonometry
        return None
    own = np.all((casters.points >= box[:2] - own_gap_m) & (casters.points <= box[2:] + own_gap_m), axis=1)
    b_track = math.atan2(centre[1], centre[0])
    d = wrap(casters.bearing - b_track)
    front &= ~own & (np.abs(d) < math.pi / 2)
    if not front.any():
        return None
    corners = np.array([[box[0], box[1]], [box[0], box[3]], [box[2], box[1]], [box[2], box[3]]]) - sensor_ne
    half = float(np.abs(wrap(np.arctan2(corners[:, 1], corners[:, 0]) - b_track)).max())
    if half <= 0:
        return None
    k = casters.owner[front]
    pad = point_pad_m / np.maximum(casters.range_m[front], 1e-3)
    lo = np.full(k.max() + 1, np.inf)
    hi = np.full(k.max() + 1, -np.inf)
    np.minimum.at(lo, k, d[front] - pad)
    np.maximum.at(hi, k, d[front] + pad)
    bins = np.linspace(-half, half, SHADOW_BINS)
    shadowed = ((bins[:, None] >= lo[None, :]) & (bins[:, None] <= hi[None, :])).any(axis=1)
    return shadowed if shadowed.any() else None


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
