"""Radar tracks that are pieces of another track's hull (not in paper 001).

The radar sees a hull as a few strong scatterers (bow, cabin, stern, a mast). On a hull of 9-15 m they lie 5-10 m
apart, beyond the clustering's reach and the duplicate test's (``duplicate_distance_m``), so each comes back as a
cluster of its own and holds a confirmed track: on the tuning scenes (radar alone, seeds 1-32) two thirds of the
false track-frames were such second tracks on a hull another track had. Two boats moving alike, one ahead of the
other within a hull's length and no further apart than a beam, are rarer than one boat seen twice; moving alike
is what tells them from two boats passing, which this leaves alone.

A piece is not deleted: its track keeps explaining its scatterer's returns (deleted, they start a new track every
few frames) and its outline still goes to the obstacle array, where the hull is. It is only no vessel of its own:
``Track.part_of`` names the host.

Two boats that come to run in line at one speed (a convoy; the radar paper's Titan and Xi for a stretch of their
laps) were seen apart before: once two confirmed tracks have been further apart than a hull's pieces can be, they
are two boats for good.
"""

from __future__ import annotations

import math

import numpy as np

from tracker.radar.kalman import mahalanobis2_many
from tracker.types import Track


def hull_pieces(
    tracks: list[Track],
    velocities: np.ndarray,
    velocity_covs: np.ndarray,
    along_m: float,
    across_m: float,
    min_speed: float,
    max_speed_diff: float,
    chi2: float,
    apart: set[tuple[int, int]],
    course_tolerance_rad: float = 0.0,
) -> None:
    """Set ``part_of`` on each confirmed track of ``tracks`` that lies within ``along_m`` of a better confirmed
    track along their common course and within ``across_m`` across it, both at ``min_speed`` or more, moving alike:
    velocities within ``max_speed_diff`` or their difference within ``chi2`` of the two covariances. The course is
    the sum of their velocities, whose direction the radar knows poorly (it measures the radial speed only), so
    ``across_m`` grows by ``tan(course_tolerance_rad)`` a metre along. Better: more hits, then older (lower id); a
    piece hosts no piece. ``apart`` holds the (lower, higher) id pairs of confirmed tracks once seen further apart
    than ``along_m + across_m``: never a hull and its piece. Updated in place.

    ``velocities`` (T, 2) m/s and ``velocity_covs`` (T, 2, 2) world north, east: the filters' own estimates, one
    row per track (a track whose motion is not judged yet publishes no velocity, but its filter knows it moves
    with the other)."""
    idx = [i for i, tr in enumerate(tracks) if tr.confirmed]
    if along_m <= 0 or len(idx) < 2:
        return
    p = np.array([tracks[i].position[:2] for i in idx], dtype=float)
    v = np.asarray(velocities, dtype=float)[idx]
    cov = np.asarray(velocity_covs, dtype=float)[idx]
    fast = np.hypot(v[:, 0], v[:, 1]) >= min_speed
    course = v[:, None, :] + v[None, :, :]
    course /= np.maximum(np.linalg.norm(course, axis=2), 1e-9)[..., None]
    rel = p[None, :, :] - p[:, None, :]
    along = np.abs(np.einsum("ijk,ijk->ij", rel, course))
    across = np.abs(rel[..., 0] * course[..., 1] - rel[..., 1] * course[..., 0])
    dv = v[:, None, :] - v[None, :, :]
    alike = (np.linalg.norm(dv, axis=2) <= max_speed_diff) | (
        mahalanobis2_many(dv, cov[:, None] + cov[None, :]) <= chi2
    )
    in_line = across <= across_m + along * math.tan(course_tolerance_rad)
    pair = (along <= along_m) & in_line & alike & fast[:, None] & fast[None, :]
    ids = np.array([tracks[i].id for i in idx])
    lo, hi = np.minimum.outer(ids, ids), np.maximum.outer(ids, ids)
    far = np.triu(np.linalg.norm(rel, axis=2) > along_m + across_m, 1)
    apart.update(zip(lo[far].tolist(), hi[far].tolist(), strict=True))
    np.fill_diagonal(pair, False)
    for a, b in zip(*np.nonzero(pair), strict=True):
        if (int(lo[a, b]), int(hi[a, b])) in apart:
            pair[a, b] = False
    if not pair.any():
        return
    rank = sorted(range(len(idx)), key=lambda k: (-tracks[idx[k]].hits, tracks[idx[k]].id))
    hosts: list[int] = []
    for k in rank:
        host = next((h for h in hosts if pair[h, k]), None)
        if host is None:
            hosts.append(k)
        else:
            tracks[idx[k]].part_of = tracks[idx[host]].id
