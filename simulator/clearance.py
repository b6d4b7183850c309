"""Clearance between moving convex solids: does a scene ever put one solid inside another (or too close to it)?

A body is a convex footprint (north, east) known at a grid of times ``t_k`` spaced at most ``step`` apart, together
with ``sweep``: an upper bound on how fast any point of it moves (m/s; speed plus yaw rate times its farthest
vertex). Between two samples every point of a body is within ``sweep * step / 2`` of where it was at the nearer
sample, so two bodies that are ``margin + (sweep_a + sweep_b) * step / 2`` apart at every sample are at least
``margin`` apart at every instant of the span, not only at the samples. That is what ``clear`` checks.

Distances between convex polygons are bounded from below by the separating-axis gap: the largest gap between the
two projections onto an edge normal of either polygon. It never exceeds the true distance (and equals it when the
nearest features are an edge and a vertex), so a gap test is conservative: it may refuse a pair that is clear, never
the other way round. Negative gaps mean overlap.

Frames: world NED, positions (north, east), m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Body:
    """A solid's footprint over the sampled span.

    ``outline`` is (T, K, 2) at the T sample times, or (1, K, 2) for a solid that never moves. ``centre`` (T, 2) or
    (1, 2) and ``radius`` give a circle holding the footprint, for a cheap first test.
    """

    outline: np.ndarray
    centre: np.ndarray
    radius: float
    sweep: float = 0.0

    @classmethod
    def fixed(cls, polygon: np.ndarray) -> Body:
        poly = np.asarray(polygon, float)
        centre = poly.mean(axis=0)
        radius = float(np.max(np.hypot(*(poly - centre).T)))
        return cls(poly[None], centre[None], radius, 0.0)

    @classmethod
    def moving(cls, outline: np.ndarray, centre: np.ndarray, sweep: float) -> Body:
        outline = np.asarray(outline, float)
        centre = np.asarray(centre, float)
        radius = float(np.max(np.hypot(*np.moveaxis(outline - centre[:, None, :], -1, 0))))
        return cls(outline, centre, radius, float(sweep))


def _unit_normals(poly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals of the edges of (..., K, 2) polygons and which edges have a length (padding repeats a vertex)."""
    edge = np.roll(poly, -1, axis=-2) - poly
    length = np.hypot(edge[..., 0], edge[..., 1])
    valid = length > 1e-9
    normal = np.stack([edge[..., 1], -edge[..., 0]], axis=-1) / np.where(valid, length, 1.0)[..., None]
    return normal, valid


def separation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Separating-axis gap between convex polygons a (..., Ka, 2) and b (..., Kb, 2), broadcast over the leading axes.

    A lower bound of their distance when positive; when they overlap, minus the smallest push that separates them.
    Written as plain products and sums (no matrix routines), so the result is the same on every machine.
    """
    return np.maximum(_axis_gaps(a, b), _axis_gaps(b, a))


def _axis_gaps(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Largest gap between the projections of a and b onto the edge normals of a."""
    n, valid = _unit_normals(a)
    nx, ny = n[..., :, None, 0], n[..., :, None, 1]  # (..., Ka, 1)
    pa = nx * a[..., None, :, 0] + ny * a[..., None, :, 1]  # (..., Ka, Ka)
    pb = nx * b[..., None, :, 0] + ny * b[..., None, :, 1]  # (..., Ka, Kb)
    gap = np.maximum(pb.min(-1) - pa.max(-1), pa.min(-1) - pb.max(-1))
    return np.where(valid, gap, -np.inf).max(-1)


def _at(x: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Rows k of a per-sample array, or its only row for a fixed solid."""
    return x[k] if x.shape[0] > 1 else np.broadcast_to(x[0], (k.size, *x.shape[1:]))


def clear(a: Body, b: Body, margin: float, step: float) -> bool:
    """True when a and b stay at least ``margin`` apart at every instant of the span sampled every ``step`` s."""
    need = margin + (a.sweep + b.sweep) * step / 2
    gap_circles = np.hypot(*(a.centre - b.centre).T) - a.radius - b.radius
    k = np.flatnonzero(gap_circles < need)  # only these samples can be too close
    if k.size == 0:
        return True
    return bool(np.all(separation(_at(a.outline, k), _at(b.outline, k)) >= need))


class Occupancy:
    """The solids placed so far, each with the clearance a newcomer must keep from it; ``admits`` tests a newcomer
    against all of them at once. Moving solids share one time grid and are screened by circles; fixed ones (quays,
    land) are too big for circles to help and are screened by their edge lines instead."""

    def __init__(self, step: float) -> None:
        self.step = float(step)
        self._moving: list[tuple[Body, float]] = []
        self._fixed: list[tuple[Body, float]] = []
        self._stacked: tuple[np.ndarray, ...] | None = None

    def add(self, body: Body, margin: float) -> None:
        (self._fixed if body.outline.shape[0] == 1 else self._moving).append((body, float(margin)))
        self._stacked = None

    def _stack(self) -> tuple[np.ndarray, ...]:
        if self._stacked is None:
            m, f = self._moving, self._fixed
            fixed = np.stack([b.outline[0] for b, _ in f]) if f else np.zeros((0, 1, 2))  # (F, K, 2)
            self._stacked = (
                np.stack([b.outline for b, _ in m], axis=1) if m else np.zeros((1, 0, 1, 2)),  # (T, N, K, 2)
                np.stack([b.centre for b, _ in m], axis=1) if m else np.zeros((1, 0, 2)),  # (T, N, 2)
                np.array([b.radius for b, _ in m]),
                np.array([b.sweep for b, _ in m]),
                np.array([g for _, g in m]),
                fixed,
                np.array([g for _, g in f]),
                *_outward_edges(fixed),
            )
        return self._stacked

    def on_fixed(self, points: np.ndarray) -> bool:
        """True when any of the points (P, 2) lies inside a fixed solid (a cheap first test for a newcomer)."""
        normals, offsets = self._stack()[7:]
        return bool(np.any(_edge_distance(points[:, None, :], normals, offsets) < 0.0))

    def admits(self, body: Body, fixed_extra: float = 0.0) -> bool:
        """True when ``body`` keeps every placed solid's clearance at every instant of the span, and ``fixed_extra``
        more from the fixed ones."""
        outlines, centres, radii, sweeps, margins, fixed, fixed_margins, normals, offsets = self._stack()
        half = self.step / 2
        if len(fixed):
            need = fixed_margins + fixed_extra + body.sweep * half  # (F,)
            d = _edge_distance(body.centre[:, None, :], normals, offsets) - body.radius  # (T, F), <= the distance
            t, j = np.nonzero(d < need)
            if t.size and np.any(separation(body.outline[t], fixed[j]) < need[j]):
                return False
        if len(radii):
            need = margins + (sweeps + body.sweep) * half  # (N,)
            d = np.hypot(*np.moveaxis(centres - body.centre[:, None, :], -1, 0)) - radii - body.radius  # (T, N)
            t, j = np.nonzero(d < need)
            if t.size and np.any(separation(body.outline[t], outlines[t, j]) < need[j]):
                return False
        return True


def _outward_edges(poly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit normals (F, K, 2) and offsets (F, K) of convex polygons (F, K, 2): n . p - offset is a point's
    signed distance to an edge's line. Padding edges get offset +inf, so they never count."""
    normal, valid = _unit_normals(poly)  # (e_east, -e_north): outward for a counter-clockwise polygon
    x, y = poly[..., 0], poly[..., 1]
    ccw = np.sum(x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y, axis=-1) > 0
    normal = np.where(ccw[..., None, None], normal, -normal)
    offset = np.where(valid, np.sum(normal * poly, axis=-1), np.inf)
    return normal, offset


def _edge_distance(points: np.ndarray, normals: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Largest signed distance of points (..., 1, 2) to the edge lines of F convex polygons: negative inside,
    and never more than the true distance outside. Shape (..., F)."""
    p = points[..., None, :]  # (..., 1, 1, 2)
    return np.max(normals[..., 0] * p[..., 0] + normals[..., 1] * p[..., 1] - offsets, axis=-1)


def point_polygon_distance(point: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance from points (..., 2) to convex polygons (..., K, 2) (counter-clockwise or not); 0 inside."""
    p = np.asarray(point, float)[..., None, :]
    a = poly
    e = np.roll(poly, -1, axis=-2) - a
    len2 = e[..., 0] ** 2 + e[..., 1] ** 2
    u = np.clip(np.sum((p - a) * e, axis=-1) / np.where(len2 > 0, len2, 1.0), 0.0, 1.0)
    near = a + u[..., None] * e
    d = np.hypot(*np.moveaxis(p - near, -1, 0)).min(-1)
    cross = e[..., 0] * (p[..., 1] - a[..., 1]) - e[..., 1] * (p[..., 0] - a[..., 0])
    real = len2 > 0  # padding edges say nothing about inside or outside
    inside = np.all(np.where(real, cross >= 0, True), -1) | np.all(np.where(real, cross <= 0, True), -1)
    return np.where(inside, 0.0, d)
