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


def on_tracked_hulls(points_ne: np.ndarray, tracks: Sequence[Track], grow_m: float) -> np.ndarray:
    """(L,) bool: the point lies inside some confirmed track's footprint box grown by ``grow_m`` on every side."""
    return _inside_grown_boxes(points_ne, tracks, grow_m)[0].any(axis=1)


def tracked_hull_of(points_ne: np.ndarray, tracks: Sequence[Track], grow_m: float) -> np.ndarray:
    """(L,) int: the index in ``tracks`` of a confirmed track whose footprint box, grown by ``grow_m`` on every
    side, holds the point (the nearest centre where several do), -1 for none."""
    inside, which, dist2 = _inside_grown_boxes(points_ne, tracks, grow_m)
    if not which.size:
        return np.full(inside.shape[0], -1, dtype=np.int64)
    best = np.argmin(np.where(inside, dist2, np.inf), axis=1)
    return np.where(inside.any(axis=1), which[best], -1)


def _inside_grown_boxes(
    points_ne: np.ndarray, tracks: Sequence[Track], grow_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(L, T) bool: point l inside the grown box of confirmed track ``which[t]``; ``which`` (T,) their indices in
    ``tracks``; (L, T) squared distances to their centres.

    Work is (points x confirmed tracks) array operations; a track without a finite size or heading counts as
    none."""
    pts = np.asarray(points_ne, dtype=float).reshape(-1, 2)
    which = np.array([i for i, t in enumerate(tracks) if t.confirmed and _finite_box(t)], dtype=np.int64)
    if pts.shape[0] == 0 or not which.size:
        empty = np.zeros((pts.shape[0], 0))
        return empty.astype(bool), which, empty
    hull = [tracks[i] for i in which]
    centre = np.array([t.position[:2] for t in hull])  # (T, 2)
    heading = np.array([t.heading for t in hull])
    half_len = np.array([t.length for t in hull]) / 2 + grow_m
    half_wid = np.array([t.width for t in hull]) / 2 + grow_m
    # (L, T) per coordinate: an (L, T, 2) difference array cost as much as all the rest
    dn = pts[:, 0, None] - centre[None, :, 0]
    de = pts[:, 1, None] - centre[None, :, 1]
    c, s = np.cos(heading), np.sin(heading)
    along = dn * c + de * s
    across = de * c - dn * s
    return (np.abs(along) <= half_len) & (np.abs(across) <= half_wid), which, dn * dn + de * de


def _finite_box(track: Track) -> bool:
    """The track has a finite position, heading and size (scalar checks: a few tracks, no arrays needed)."""
    return all(math.isfinite(v) for v in (*track.position, track.heading, track.length, track.width))
