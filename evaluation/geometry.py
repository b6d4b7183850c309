"""Plane geometry the matching needs, in world (north, east) metres."""

from __future__ import annotations

import numpy as np


def distance_to_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """(N,) distance from each (N, 2) point to a simple polygon's area (K, 2 vertices, either orientation):
    0 inside or on the outline, else the distance to the nearest edge."""
    p = np.asarray(points, float).reshape(-1, 2)
    a = np.asarray(polygon, float).reshape(-1, 2)
    if a.shape[0] == 0:
        return np.full(p.shape[0], np.inf)
    b = np.roll(a, -1, axis=0)
    ab = b - a  # (K, 2)
    ap = p[:, None, :] - a[None, :, :]  # (N, K, 2)
    len2 = np.sum(ab * ab, axis=1)
    u = np.clip(np.sum(ap * ab[None], axis=2) / np.where(len2 > 0, len2, 1.0), 0.0, 1.0)
    nearest = a[None] + u[..., None] * ab[None]
    edge_dist = np.min(np.hypot(*np.moveaxis(p[:, None, :] - nearest, -1, 0)), axis=1)
    # crossing number: a ray from the point towards +east crosses the outline an odd number of times when inside
    an, ae, bn, be = a[:, 0], a[:, 1], b[:, 0], b[:, 1]
    pn, pe = p[:, 0:1], p[:, 1:2]
    straddles = (an <= pn) != (bn <= pn)
    with np.errstate(divide="ignore", invalid="ignore"):
        e_cross = ae + (pn - an) * (be - ae) / (bn - an)
    inside = (np.sum(straddles & (e_cross > pe), axis=1) % 2) == 1
    return np.where(inside, 0.0, edge_dist)


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Wrap to [-pi, pi)."""
    return (np.asarray(a, float) + np.pi) % (2 * np.pi) - np.pi


def rotation_ne(heading: float) -> np.ndarray:
    """2x2 rotation taking body (forward, starboard) to world (north, east) for a heading clockwise from north."""
    c, s = np.cos(heading), np.sin(heading)
    return np.array([[c, -s], [s, c]])
