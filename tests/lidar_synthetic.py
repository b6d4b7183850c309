"""A 2-D ray caster that scans boxes and ellipses the way a spinning LiDAR would: for tests and benchmarks.

Not a simulator: no waves, no ego motion within a sweep, no beam divergence. It gives what the shape fitters and
the tracker must cope with in every scan: only the sides that face the sensor, nearer hulls hiding farther ones,
sampling that thins out with range, and range noise along the beam.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tracker.types import ShapeKind


@dataclass
class SyntheticObject:
    center: tuple[float, float]  # world north, east, m
    heading: float  # rad, 0 = north, clockwise
    length: float
    width: float
    height: float = 2.0  # m above the water
    shape: ShapeKind = ShapeKind.BOX

    def outline(self, ellipse_segments: int = 72) -> np.ndarray:
        """(k, 2, 2) edges (start, end) of the footprint in world north, east."""
        if self.shape is ShapeKind.ELLIPSE:
            a = np.linspace(0.0, 2.0 * math.pi, ellipse_segments + 1)
            local = np.stack([0.5 * self.length * np.cos(a), 0.5 * self.width * np.sin(a)], axis=1)
        else:
            hl, hw = 0.5 * self.length, 0.5 * self.width
            local = np.array([[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw], [hl, hw]])
        c, s = math.cos(self.heading), math.sin(self.heading)
        world = local @ np.array([[c, s], [-s, c]]) + np.asarray(self.center, dtype=float)
        return np.stack([world[:-1], world[1:]], axis=1)


def scan_objects(
    objects: list[SyntheticObject],
    sensor: np.ndarray,
    azimuth_step: float = math.radians(0.2),
    max_range: float = 100.0,
    range_noise: float = 0.0,
    rng: np.random.Generator | None = None,
    ring_spacing: float = math.radians(2.0),
) -> np.ndarray:
    """(N, 3) world NED returns of one revolution from ``sensor`` (north, east); water at z = 0 (down positive).

    Each beam azimuth returns the nearest hull edge it meets; above each hit, returns are stacked at the heights
    where the VLP-16's rings (``ring_spacing`` apart) cross the hull, at least one per hit.
    """
    sensor = np.asarray(sensor, dtype=float)[:2]
    if not objects:
        return np.zeros((0, 3))
    edges = np.concatenate([o.outline() for o in objects])  # (S, 2, 2)
    top = np.concatenate([np.full(len(o.outline()), o.height) for o in objects])
    az = np.arange(0.0, 2.0 * math.pi, azimuth_step)
    d = np.stack([np.cos(az), np.sin(az)], axis=1)  # (R, 2)
    a = edges[:, 0] - sensor  # (S, 2)
    e = edges[:, 1] - edges[:, 0]
    denom = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]  # cross(d, e)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (a[None, :, 0] * e[None, :, 1] - a[None, :, 1] * e[None, :, 0]) / denom
        u = (a[None, :, 0] * d[:, None, 1] - a[None, :, 1] * d[:, None, 0]) / denom
    valid = np.isfinite(t) & (t > 0.0) & (u >= 0.0) & (u <= 1.0) & (t <= max_range)
    t = np.where(valid, t, np.inf)
    nearest = t.argmin(axis=1)
    rng_hit = t[np.arange(az.size), nearest]
    hit = np.isfinite(rng_hit)
    r, az_hit, h = rng_hit[hit], az[hit], top[nearest[hit]]
    if range_noise > 0.0:
        gen = rng if rng is not None else np.random.default_rng(0)
        r = r + gen.normal(0.0, range_noise, r.size)
    # Rings: heights of the beams above the water where they meet the hull, from the waterline up to the top.
    spacing = np.maximum(np.tan(ring_spacing) * r, 0.05)
    n_rings = np.maximum(np.floor(h / spacing).astype(int), 1)
    rep = np.repeat(np.arange(r.size), n_rings)
    ring = np.arange(rep.size) - np.repeat(np.cumsum(n_rings) - n_rings, n_rings)
    height = np.minimum((ring + 0.5) * spacing[rep], h[rep])
    north = sensor[0] + r[rep] * np.cos(az_hit[rep])
    east = sensor[1] + r[rep] * np.sin(az_hit[rep])
    return np.stack([north, east, -height], axis=1)
