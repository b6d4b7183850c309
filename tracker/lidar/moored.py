"""Hulls moored against a wall: carved out of the wall's cluster as clusters of their own.

A boat on fenders lies 0.3 m off a quay, closer than any clustering tolerance, so its returns join the quay's
cluster; the cluster is too big to be a vessel and the whole of it, boat included, became structure: never tracked,
and remembered, so that later scans of the boat were structure too. On the tuning scenes the moored boats were most
of the vessels missed (random:4: 570 of its 588 missed vessel-ticks).

What tells the boat from the wall is where it lies: a wall seen from the water shows one straight face, and a hull
moored against it stands in front of that face, towards the sensor, by its beam plus the fender gap. So, in the
footprint (occupied grid cells, world north/east) of a cluster too big for a vessel or at least ``min_extent_m``
across: the face is the densest 1 m strip over all directions (a Hough search; a vertical face stacks every ring's
returns onto one line); when at least ``face_min_share`` of the cells lie in it, the cells standing
``min_offset_m`` or more in front of it, grouped along the face with gaps under ``gap_m``, are hulls of at least
``min_length_m``. Land behind the face lies away from the sensor and is never carved; a cluster with no straight
face (a corner, rough shore) is left whole; a convex hull has no cells in front of its own face, so a vessel alone
is never carved. The work is a few array passes per long cluster, over at most a thousand of its cells.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tracker.lidar.clustering import ClusterResult

FACE_HALF_WIDTH_M = 0.5  # m each side of the face line: a wall's face with the VLP-16's range noise
COARSE_CELLS = 256  # cells the coarse direction search looks at (evenly strided)
FINE_CELLS = 1024  # and the fine one


def hull_cells(
    footprint: np.ndarray,
    own: np.ndarray,
    min_offset_m: float,
    min_length_m: float,
    gap_m: float,
    face_min_share: float,
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray, float]:
    """Groups of footprint cells standing in front of the footprint's straight face, as index arrays.

    Also returns the axis (unit, north/east), the normal towards ``own`` and the face's offset along that normal
    from the footprint's mean, so that the caller can place the cluster's points the same way. No groups when the
    footprint has no straight face."""
    fp = np.asarray(footprint, dtype=float).reshape(-1, 2)
    none: tuple[list[np.ndarray], np.ndarray, np.ndarray, float] = ([], np.zeros(2), np.zeros(2), 0.0)
    if fp.shape[0] < 3:
        return none
    mean = fp.mean(axis=0)
    rel = fp - mean
    # The face's direction: the one whose densest 1 m-wide strip holds the most cells (a Hough search, 2 deg then
    # 0.2 deg), not the principal axis, which a hull or the wall's end faces tilt by degrees (metres at 60 m).
    sample = rel[:: max(1, rel.shape[0] // COARSE_CELLS)]  # the coarse search on a few hundred cells: a long wall has
    coarse = _densest_strip(sample, np.radians(np.arange(0.0, 180.0, 2.0)))  # thousands, and this runs every scan
    fine = rel[:: max(1, rel.shape[0] // FINE_CELLS)]
    angle, face, held = _densest_strip(fine, coarse[0] + np.radians(np.arange(-2.0, 2.05, 0.2)))
    if held < face_min_share * fine.shape[0]:
        return none
    axis = np.array([np.cos(angle), np.sin(angle)])
    normal = np.array([-axis[1], axis[0]])
    if float((own - mean) @ normal) < 0.0:
        normal, face = -normal, -face
    across = rel @ normal
    along = rel @ axis
    face = float(np.median(across[np.abs(across - face) <= FACE_HALF_WIDTH_M]))
    front = np.flatnonzero(across - face >= min_offset_m)
    if front.size < 3:
        return ([], axis, normal, face)
    order = front[np.argsort(along[front], kind="stable")]
    a = along[order]
    breaks = np.flatnonzero(np.diff(a) > gap_m) + 1
    groups = [g for g in np.split(order, breaks) if g.size >= 3 and np.ptp(along[g]) >= min_length_m]
    return (groups, axis, normal, face)


def carve_moored_hulls(
    result: ClusterResult,
    points_world: np.ndarray,
    own: np.ndarray,
    min_offset_m: float,
    min_length_m: float,
    gap_m: float,
    face_min_share: float,
    cell_m: float,
    min_extent_m: float = np.inf,
) -> ClusterResult:
    """``result`` with every hull found in front of the face (:func:`hull_cells`) of a cluster too big for a vessel
    or at least ``min_extent_m`` across made a cluster of its own (not oversized); the wall keeps the rest. Clusters
    stay nearest first and ``labels`` follows them. ``points_world`` (N, 3) are the points ``result`` was clustered
    from; ``cell_m`` the footprint's grid cell."""
    if min_offset_m <= 0.0 or not result.clusters:
        return result
    big = np.flatnonzero(result.oversized | (result.extent >= min_extent_m))
    if big.size == 0:
        return result
    pts = np.asarray(points_world, dtype=float).reshape(-1, 3)
    labels = result.labels.copy()
    clusters, footprints = list(result.clusters), list(result.footprints)
    oversized = list(result.oversized)
    new_points: list[np.ndarray] = []
    for k in big:
        fp = footprints[k]
        groups, axis, normal, face = hull_cells(fp, own, min_offset_m, min_length_m, gap_m, face_min_share)
        if not groups:
            continue
        members = np.flatnonzero(labels == k)
        mean = fp.mean(axis=0)
        rel = pts[members, :2] - mean
        across, along = rel @ normal, rel @ axis
        fp_along = (fp - mean) @ axis
        taken = np.zeros(members.size, dtype=bool)
        taken_cells = np.zeros(fp.shape[0], dtype=bool)
        found: list[tuple[np.ndarray, np.ndarray]] = []  # (point indices, footprint cells) per hull
        for g in groups:
            # the hull's points: in front of the face (by half a cell less than its cells, which are centroids)
            # and along its cells' stretch
            a0, a1 = float(fp_along[g].min()) - cell_m, float(fp_along[g].max()) + cell_m
            mine = ~taken & (across - face >= min_offset_m - 0.5 * cell_m) & (along >= a0) & (along <= a1)
            if np.count_nonzero(mine) < 3:
                continue
            taken |= mine
            taken_cells[g] = True
            found.append((members[mine], fp[g]))
        if not found or taken.all():  # nothing carved, or nothing left of a "wall" that was hulls' sides
            continue
        clusters[k] = pts[members[~taken]]
        footprints[k] = fp[~taken_cells]
        for idx, cells in found:
            new_points.append(idx)
            clusters.append(pts[idx])
            footprints.append(cells)
            oversized.append(False)
    if not new_points:
        return result
    first_new = len(result.clusters)
    for j, idx in enumerate(new_points):
        labels[idx] = first_new + j
    changed = sorted({int(k) for k in big} | set(range(first_new, len(clusters))))
    carved = np.arange(len(clusters)) >= first_new
    if result.carved is not None:
        carved[:first_new] |= result.carved
    return _nearest_first(result, clusters, footprints, np.array(oversized, dtype=bool), labels, own, changed, carved)


def _nearest_first(
    result: ClusterResult,
    clusters: list[np.ndarray],
    footprints: list[np.ndarray],
    oversized: np.ndarray,
    labels: np.ndarray,
    own: np.ndarray,
    changed: list[int],
    carved: np.ndarray,
) -> ClusterResult:
    """The ``changed`` clusters' ranges, extents and bearing spans recomputed (a handful a scan), all sorted nearest
    first."""
    n = len(clusters)
    pad = n - len(result.clusters)
    nearest = np.concatenate([result.min_range, np.zeros(pad)])
    extent = np.concatenate([result.extent, np.zeros(pad)])
    spans = [
        np.concatenate([b if b is not None else np.zeros(len(result.clusters)), np.zeros(pad)])
        for b in (result.bearing, result.bearing_lo, result.bearing_hi)
    ]
    centre, lo, hi = spans
    for k in changed:
        c = clusters[k]
        dn, de = c[:, 0] - own[0], c[:, 1] - own[1]
        nearest[k] = float(np.sqrt(np.min(dn * dn + de * de)))
        extent[k] = float(np.hypot(np.ptp(c[:, 0]), np.ptp(c[:, 1])))
        centre[k] = float(np.arctan2(de.sum(), dn.sum()))
        off = np.arctan2(de, dn) - centre[k]
        off -= (2.0 * np.pi) * np.floor((off + np.pi) * (0.5 / np.pi))
        lo[k], hi[k] = float(off.min()), float(off.max())
    order = np.argsort(nearest, kind="stable")
    rank = np.empty(n, dtype=np.int64)
    rank[order] = np.arange(n)
    new_labels = np.where(labels >= 0, rank[np.maximum(labels, 0)], -1)
    return replace(
        result,
        clusters=[clusters[k] for k in order],
        footprints=[footprints[k] for k in order],
        min_range=nearest[order],
        oversized=oversized[order],
        extent=extent[order],
        labels=new_labels,
        bearing=centre[order],
        bearing_lo=lo[order],
        bearing_hi=hi[order],
        carved=carved[order],
    )


def _densest_strip(rel: np.ndarray, angles: np.ndarray) -> tuple[float, float, int]:
    """Among axis ``angles`` (rad, from north), the one with the most cells in a strip 2 * FACE_HALF_WIDTH_M wide
    along it: (angle, the strip's centre across the axis, its cell count). One bincount for every angle; the strip
    is two neighbouring bins of FACE_HALF_WIDTH_M."""
    normals = np.stack([-np.sin(angles), np.cos(angles)], axis=1)  # (A, 2)
    across = rel @ normals.T  # (N, A)
    lo = across.min(axis=0)
    bins = ((across - lo) * (1.0 / FACE_HALF_WIDTH_M)).astype(np.int64)
    nb = int(bins.max()) + 2
    counts = np.bincount((bins + nb * np.arange(angles.size)).ravel(), minlength=nb * angles.size)
    counts = counts.reshape(angles.size, nb)
    window = counts[:, :-1] + counts[:, 1:]
    a, b = np.unravel_index(int(np.argmax(window)), window.shape)
    return float(angles[a]), float(lo[a] + (int(b) + 1) * FACE_HALF_WIDTH_M), int(window[a, b])
