"""Clusters whose top is a horizontal surface met by one descending beam: a quay's deck, not a hull (ours).

A quay 40-80 m off is reached by the VLP-16's lowest beam alone. Where that beam passes over the wall's edge it meets
the deck behind it, and the deck's returns join the face's into one cluster the size of a boat, centred metres
behind the face on wall the memory never saw whole (tracker.lidar.structure): on the tuning seeds 45-68 (LiDAR
alone) two thirds of the false track-frames were tracks 0-4 m behind a quay's face. One return cannot tell a deck
from a side; a beam's returns together can:

- a beam descending at ``e`` that meets a vertical face changes height by ``tan(e)`` per metre of range along it; on
  a horizontal surface its returns stay at one height over any range (the boat's roll, turning the beam's elevation
  with bearing, draws the deck's line out in range). So the cluster's top returns (within ``height_tolerance_m``
  of its highest) spanning ``min_range_span_m`` of range or more, over which a face would have changed height by
  ``face_change_ratio`` times that tolerance, lie on a horizontal surface;
- with the boat level the beam meets a flat deck along an arc of one range round the sensor, where a straight face
  as long spreads in range by at least its sagitta (length^2 / 8 range): top returns whose range spreads at most
  ``arc_max_ratio`` of that sagitta (which must be ``arc_min_sagitta_m`` or more to be measured) lie on an arc.

Both only for a cluster of one beam (its returns within ``max_elevation_spread_rad`` of elevation seen from the
sensor; the lasers are 2 deg apart) whose top lies ``min_depression_rad`` or more below the sensor (a beam at 0 deg
draws a level line on any face). A cluster of several beams is a hull's side with its deck on top, and is left to
the other rules: the simulator's flat-topped hulls, met by one beam along their decks, were taken for quays when
that was not required (tuning seeds 45-68: 5,000 vessel-ticks lost). The deck cluster is structure: no track, its
returns still obstacles; it is not remembered (a moored boat's deck met so would be structure for the memory's two
minutes). Frames: world NED, m; the sensor's position in the same frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LevelRule:
    height_tolerance_m: float = 0.02
    min_depression_rad: float = math.radians(0.3)
    min_range_span_m: float = 6.0
    face_change_ratio: float = 2.5
    arc_max_ratio: float = 0.4
    arc_min_sagitta_m: float = 0.15
    max_elevation_spread_rad: float = math.radians(1.6)
    min_points: int = 8
    min_share: float = 0.1


def horizontal_tops(clusters: list[np.ndarray], sensor_ned: np.ndarray, rule: LevelRule) -> np.ndarray:
    """(k,) bool: each cluster ((n, 3) world NED points) whose top is a horizontal surface met by one descending
    beam (see the module). ``sensor_ned``: the LiDAR's origin, world NED. All clusters in one pass."""
    k = len(clusters)
    out = np.zeros(k, dtype=bool)
    if k == 0:
        return out
    sizes = np.array([len(c) for c in clusters])
    if not (sizes > 0).all():
        keep = np.flatnonzero(sizes > 0)
        out[keep] = horizontal_tops([clusters[i] for i in keep], sensor_ned, rule)
        return out
    pts = np.concatenate(clusters)[:, :3]
    starts = np.cumsum(sizes) - sizes
    owner = np.repeat(np.arange(k), sizes)
    s = np.asarray(sensor_ned, dtype=float)
    rng = np.hypot(pts[:, 0] - s[0], pts[:, 1] - s[1])
    down = pts[:, 2]
    top = np.minimum.reduceat(down, starts)  # down: the least is the highest
    level = down <= top[owner] + rule.height_tolerance_m
    n_level = np.bincount(owner[level], minlength=k)
    enough = (n_level >= rule.min_points) & (n_level >= rule.min_share * sizes)
    if not enough.any():
        return out
    r_lo = np.minimum.reduceat(np.where(level, rng, np.inf), starts)
    r_hi = np.maximum.reduceat(np.where(level, rng, -np.inf), starts)
    r_mid = 0.5 * (r_lo + r_hi)
    depression = np.arctan2(top - s[2], np.maximum(r_mid, 1e-6))
    # one beam's returns: the VLP-16's lasers are 2 deg apart, a hull's side returns several
    elevation = np.arctan2(s[2] - down, np.maximum(rng, 1e-6))
    one_beam = (
        np.maximum.reduceat(elevation, starts) - np.minimum.reduceat(elevation, starts)
    ) <= rule.max_elevation_spread_rad
    below = depression >= rule.min_depression_rad
    span = r_hi - r_lo
    # what a vertical face met by the same beam would have changed in height over that range: several bands
    level_line = (span >= rule.min_range_span_m) & (
        span * np.tan(np.maximum(depression, 0.0)) >= rule.face_change_ratio * rule.height_tolerance_m
    )
    n_lo = np.minimum.reduceat(np.where(level, pts[:, 0], np.inf), starts)
    n_hi = np.maximum.reduceat(np.where(level, pts[:, 0], -np.inf), starts)
    e_lo = np.minimum.reduceat(np.where(level, pts[:, 1], np.inf), starts)
    e_hi = np.maximum.reduceat(np.where(level, pts[:, 1], -np.inf), starts)
    # The level returns' chord: the diagonal of their box is within a factor sqrt(2) of it, enough for a threshold.
    chord = np.hypot(n_hi - n_lo, e_hi - e_lo)
    sagitta = chord**2 / (8.0 * np.maximum(r_mid, 1e-6))
    arc = (sagitta >= rule.arc_min_sagitta_m) & (span <= rule.arc_max_ratio * sagitta)
    return enough & below & one_beam & (level_line | arc)
