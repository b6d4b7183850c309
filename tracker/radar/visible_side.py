"""Where the hull's centre lies, given returns from the sides that face the radar only (not in paper 001).

A millimetre-wave radar sees the hull sides that face it, so the box around one frame's returns sits on the near
side of the boat: in the simulated paper scenes the box centre was 0.5 m (2.9 m boat) to 1.5 m (4.9 m boat) short of
the hull centre along the line of sight, which alone is the paper's whole MOTP budget. Range is precise (centimetres)
and azimuth is not (1 deg is 0.5 m at 30 m), so the correction works along the line of sight u:

* the nearest return of the frame marks the hull's nearest corner (range noise is small);
* the hull centre lies behind it by about half the visible depth plus a share of the silhouette width (the hidden
  short side): centre_r = min r_i + depth_gain * M + width_gain * S, where M and S are the extents, along and across
  u, of the track's returns over the last second (``shape`` relative to the track centre), which fill in the visible
  outline that one frame of 3-8 returns does not; each extent is the 5-95 % spread / 0.9, robust to stray returns;
* across u the box centre stays (the silhouette is symmetric about the centre).

For a rectangle seen corner-on the centre is the midpoint of the two silhouette corners, at depth (a + b) / 2 behind
the nearest corner, where a and b are the depths of those corners; M measures max(a, b) and S the silhouette width,
which with boat-like proportions carries the hidden min(a, b). The gains were fitted on the simulated AWR1843 returns
of the paper's three boats; with extents (not spreads) the static scene's bias along u is -0.01 / -0.18 / -0.52 m
(Smurf / Titan / Xi, the Xi seen corner-on at 34 m), moving boats within +-0.25 m. They are config values to be
checked on real returns.
"""

from __future__ import annotations

import numpy as np


def spreads(columns: np.ndarray, quantile: float) -> np.ndarray:
    """(m,) width between the ``quantile`` and ``1 - quantile`` quantiles of each column of ``columns`` (n, m):
    np.quantile's linear interpolation without its overhead, one sort for all columns (this runs every frame)."""
    n = columns.shape[0]
    if n < 2:
        return np.zeros(columns.shape[1])
    v = np.sort(columns, axis=0)
    pos = np.array([quantile, 1.0 - quantile]) * (n - 1)
    lo = np.floor(pos).astype(np.int64)
    hi = np.minimum(lo + 1, n - 1)
    q = v[lo] + (pos - lo)[:, None] * (v[hi] - v[lo])
    return q[1] - q[0]


def spread(values: np.ndarray, quantile: float) -> float:
    """Width between the ``quantile`` and ``1 - quantile`` quantiles (robust extent of a sparse outline):
    :func:`spreads` of one column."""
    return float(spreads(np.asarray(values, dtype=float).reshape(-1, 1), quantile)[0])


def visible_side_centre(
    points: np.ndarray,
    sensor_ne: np.ndarray,
    shape: np.ndarray,
    depth_gain: float,
    width_gain: float,
    quantile: float = 0.05,
) -> np.ndarray:
    """(2,) estimated hull centre, world N/E.

    ``points`` (n, 2) this frame's returns of the object, world; ``sensor_ne`` (2,) radar position; ``shape`` (k, 2)
    the object's recent returns relative to its centre (world axes), this frame's included.
    """
    pts = np.asarray(points, float).reshape(-1, 2)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    box_centre = (lo + hi) / 2
    rel = box_centre - np.asarray(sensor_ne, float)
    dist = float(np.hypot(*rel))
    if dist < 1e-6:
        return box_centre
    u = rel / dist
    n = np.array([-u[1], u[0]])
    near = float(((pts - sensor_ne) @ u).min())
    shp = np.asarray(shape, float).reshape(-1, 2)
    # Spreads between the quantiles are (1 - 2 quantile) of the extent of evenly spread returns: extents, not spreads,
    # are what the geometry below is written in.
    depth, width = spreads(shp @ np.column_stack([u, n]), quantile) / (1.0 - 2.0 * quantile)
    centre_r = near + depth_gain * depth + width_gain * width
    return np.asarray(sensor_ne, float) + u * max(centre_r, near)
