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
``min_length_m``. Boats moored end to end can hide more of a wall than is left in view: their near sides, in one
strip parallel to the face, are then left out of that share (on tuning seed 27 two boats 27 m long hid a low quay
seen 80 m off, 98 of the 219 cells were its face, and both boats went untracked for 40 s). Land behind the face
lies away from the sensor and is never carved; a cluster with no straight face (a corner, rough shore) is left
whole; a convex hull has no cells in front of its own face, so a vessel alone is never carved. The work is a few
array passes per long cluster, over at most a thousand of its cells.

A wall need not be straight from end to end: a quay's end bent towards the land by some degrees carries boats too,
and they lie behind the main face's line (on tuning seed 78 a 12.6 m boat on a bent end stood 4.6 m behind it to
1.3 m in front, and was never tracked). So the search goes on beyond each outer end of the main face's runs of wall
(unbroken runs at least BEND_MIN_RUN_M long: a boat's shadow breaks a face into runs, and the quay's top seen in
such a gap is land, not the start of a bent face), along a bent face: the line through that end (the kink), turned
BEND_MIN_DEG to BEND_MAX_DEG either way, that holds the most of the cells beyond it which the sensor met first on
their bearing (a low quay's top, seen behind its face, holds more cells on a line turned into the land than the face
does). Cells standing ``min_offset_m`` in front of it, in runs as above whose front runs along the bent face, are
hulls. The kink ties the bent face to the wall, so a boat's own side, parallel to the wall but a beam off it, is
not taken for it; a pier or an arm turns by more than BEND_MAX_DEG; and a stretch of wall left in front of a bent
face that was turned into the land where the face itself went unreturned runs at the turn's angle to it, not along
it, as a moored hull's side does. The bounds are ours, from the geometry above; held out (random:1001-1050, fused)
against the main face alone: MOTA 0.9381 -> 0.9393, worst scene 0.601 -> 0.608, moored box hulls tracked 0.855 ->
0.874 of their vessel-ticks, 8 scenes better and 1 worse (random:1010, by 0.010).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker.lidar.clustering import ClusterResult, with_pieces

FACE_HALF_WIDTH_M = 0.5  # m each side of the face line: a wall's face with the VLP-16's range noise
COARSE_CELLS = 256  # cells the coarse direction search looks at (evenly strided)
FINE_CELLS = 1024  # and the fine one
BEND_MIN_DEG = 3.0  # a bent face turns at least this much from the main one (less is the same face, within its strip)
BEND_MAX_DEG = 45.0  # and at most this much: a pier or an arm off a quay stands at right angles to it
BEND_STEP_DEG = 0.5  # the bent face's search step: 0.5 deg is 0.17 m across at 20 m from the kink
BEND_MIN_RUN_M = 5.0  # m: an unbroken run of the main face this long is wall (a boat crossing its line makes less)
FIRST_SEEN_BIN_DEG = 0.25  # the bent face is searched among the cells first seen in each this much of bearing
BEND_MIN_CELLS = 5  # cells on a bent face (0.75 m of 0.15 m cells) for it to be a face at all
# Boats moored along a wall show their near sides in one strip parallel to its face: when at least this share of the
# cells in front of the face lie in one such strip, they are hulls and do not count against the face's share.
HULL_SIDES_MIN_SHARE = 0.5
# m: and that strip lies within a beam of the face: a 50 m ship is 8.5 m wide. Farther on, a strip parallel to the
# face is something else (seen from beyond a quay's end, with its end face taken for the face, the long face itself
# runs away in front of it and a boat 18 m off stands parallel: tuning seed 94). Ours, from the geometry; tuning
# seeds 1-100 (fused) against none: MOTA 0.9646 -> 0.9654, worst scene 0.798 -> 0.881. Held out (random:1001-1050,
# fused), with tracker.lidar.structure's wall-line test, against neither: MOTA 0.9501 -> 0.9534, worst scene 0.674
# -> 0.721, moored box hulls tracked 0.847 -> 0.894 of their vessel-ticks.
HULL_SIDES_MAX_M = 10.0


@dataclass(frozen=True)
class Face:
    """A straight stretch of a wall's face in a footprint's frame (north/east, relative to the footprint's mean):
    ``origin`` on the face, ``axis`` along it (unit), ``normal`` towards the sensor (unit). A cell's distance in
    front of the face is ``(cell - origin) @ normal``, its place along it ``(cell - origin) @ axis``."""

    origin: np.ndarray
    axis: np.ndarray
    normal: np.ndarray


def hull_cells(
    footprint: np.ndarray,
    own: np.ndarray,
    min_offset_m: float,
    min_length_m: float,
    gap_m: float,
    face_min_share: float,
) -> list[tuple[np.ndarray, Face]]:
    """Groups of footprint cells standing in front of the footprint's straight face, or of a face bent off one of
    its ends, as index arrays, each with the face it stands in front of (so that the caller can place the
    cluster's points the same way). No groups when the footprint has no straight face."""
    fp = np.asarray(footprint, dtype=float).reshape(-1, 2)
    if fp.shape[0] < 3:
        return []
    mean = fp.mean(axis=0)
    rel = fp - mean
    # The face's direction: the one whose densest 1 m-wide strip holds the most cells (a Hough search, 2 deg then
    # 0.2 deg), not the principal axis, which a hull or the wall's end faces tilt by degrees (metres at 60 m).
    sample = rel[:: max(1, rel.shape[0] // COARSE_CELLS)]  # the coarse search on a few hundred cells: a long wall has
    coarse = _densest_strip(sample, np.radians(np.arange(0.0, 180.0, 2.0)))  # thousands, and this runs every scan
    fine = rel[:: max(1, rel.shape[0] // FINE_CELLS)]
    angle, face, held = _densest_strip(fine, coarse[0] + np.radians(np.arange(-2.0, 2.05, 0.2)))
    axis = np.array([np.cos(angle), np.sin(angle)])
    normal = np.array([-axis[1], axis[0]])
    if float((own - mean) @ normal) < 0.0:
        normal, face = -normal, -face
    if held < face_min_share * (fine.shape[0] - _hull_sides(fine @ normal - face, min_offset_m)):
        return []
    across = rel @ normal
    along = rel @ axis
    face = float(np.median(across[np.abs(across - face) <= FACE_HALF_WIDTH_M]))
    main = Face(face * normal, axis, normal)
    front = np.flatnonzero(across - face >= min_offset_m)
    found = [(g, main) for g in _runs_along(front, along, min_length_m, gap_m)]
    # The bent ends: beyond the outer ends of the face's unbroken runs of wall (a boat's shadow breaks a face into
    # runs; a boat lying across the face's line beyond a kink makes a short one), off the cells already hulls.
    on_face = np.flatnonzero(np.abs(across - face) <= FACE_HALF_WIDTH_M)
    on_face = on_face[np.argsort(along[on_face], kind="stable")]
    runs = np.split(on_face, np.flatnonzero(np.diff(along[on_face]) > gap_m) + 1)
    walls = [r for r in runs if np.ptp(along[r]) >= BEND_MIN_RUN_M]
    if not walls:
        return found
    free = np.ones(fp.shape[0], dtype=bool)
    free[on_face] = False
    for g, _ in found:
        free[g] = False
    ends = (float(min(along[r].min() for r in walls)), float(max(along[r].max() for r in walls)))
    for sign, end in zip((-1.0, 1.0), ends, strict=True):
        beyond = np.flatnonzero(free & (sign * (along - end) > 0.0))
        if beyond.size < BEND_MIN_CELLS:
            continue
        bent = _bent_face(_first_seen(rel[beyond], own - mean), end * axis + face * normal, sign * axis, own - mean)
        if bent is None:
            continue
        d = rel - bent.origin
        along_bent, across_bent = d @ bent.axis, d @ bent.normal
        ahead = beyond[(across_bent[beyond] >= min_offset_m) & (along_bent[beyond] >= 0.0)]
        for g in _runs_along(ahead, along_bent, min_length_m, gap_m):
            if _parallel(along_bent[g], across_bent[g]):
                found.append((g, bent))
    return found


def _hull_sides(in_front: np.ndarray, min_offset_m: float) -> int:
    """How many cells (their distances ``in_front`` of a face, m) stand ``min_offset_m`` or more in front of it
    as the near sides of hulls moored along it: all of those cells when at least HULL_SIDES_MIN_SHARE of them lie in
    one 2 * FACE_HALF_WIDTH_M strip parallel to the face and nearer to it than HULL_SIDES_MAX_M, else none. A
    quay's top seen from beyond its end lies "in front" of the face too, but spread over its depth."""
    ahead = in_front[in_front >= min_offset_m]
    beam = ahead[ahead < HULL_SIDES_MAX_M]
    if beam.size == 0:
        return 0
    bins = np.bincount(((beam - min_offset_m) * (1.0 / FACE_HALF_WIDTH_M)).astype(np.int64))
    strip = int((bins[:-1] + bins[1:]).max()) if bins.size > 1 else int(bins[0])
    return int(ahead.size) if strip >= HULL_SIDES_MIN_SHARE * ahead.size else 0


def _runs_along(cells: np.ndarray, along: np.ndarray, min_length_m: float, gap_m: float) -> list[np.ndarray]:
    """``cells`` (indices) split where they are more than ``gap_m`` apart along a face, the runs of at least three
    cells and ``min_length_m`` kept."""
    if cells.size < 3:
        return []
    order = cells[np.argsort(along[cells], kind="stable")]
    breaks = np.flatnonzero(np.diff(along[order]) > gap_m) + 1
    return [g for g in np.split(order, breaks) if g.size >= 3 and np.ptp(along[g]) >= min_length_m]


def _parallel(along: np.ndarray, across: np.ndarray) -> bool:
    """Whether cells (their places along and in front of a face) show a side running along the face, as a moored
    hull's does, within BEND_MIN_DEG: the frontmost cell of each metre along, fitted with a line. A stretch of
    wall that a mis-fitted bent face (one turned into the quay's top, where its face was not returned) left in front
    runs at the turn's angle to it."""
    bins = np.floor(along).astype(np.int64)
    order = np.lexsort((-across, bins))
    first = order[np.concatenate([[True], np.diff(bins[order]) != 0])]
    if first.size < 3:
        return True
    slope = np.polyfit(along[first], across[first], 1)[0]
    return bool(abs(slope) <= np.tan(np.radians(BEND_MIN_DEG)))


def _first_seen(cells: np.ndarray, own: np.ndarray) -> np.ndarray:
    """Of ``cells``, the nearest to ``own`` in each FIRST_SEEN_BIN_DEG of bearing from it: the surfaces the sensor
    met first, a wall's face or a hull, not the quay's top or the land seen over them."""
    d = cells - own
    bins = np.floor(np.degrees(np.arctan2(d[:, 1], d[:, 0])) / FIRST_SEEN_BIN_DEG).astype(np.int64)
    order = np.lexsort((np.hypot(d[:, 0], d[:, 1]), bins))
    first = np.concatenate([[True], np.diff(bins[order]) != 0])
    return cells[order[first]]


def _bent_face(cells: np.ndarray, kink: np.ndarray, outward: np.ndarray, own: np.ndarray) -> Face | None:
    """The face through ``kink`` that holds the most of ``cells`` (beyond the kink, all relative to one origin)
    within FACE_HALF_WIDTH_M, turned BEND_MIN_DEG to BEND_MAX_DEG either way from ``outward`` (unit, along the
    main face away from it); None when it holds fewer than BEND_MIN_CELLS."""
    cells = cells[:: max(1, cells.shape[0] // FINE_CELLS)]
    turns = np.radians(np.arange(BEND_MIN_DEG, BEND_MAX_DEG + 0.5 * BEND_STEP_DEG, BEND_STEP_DEG))
    turns = np.concatenate([-turns, turns])
    c, s = np.cos(turns), np.sin(turns)
    axes = np.stack([c * outward[0] - s * outward[1], s * outward[0] + c * outward[1]], axis=1)  # (T, 2)
    d = cells - kink
    along = d @ axes.T  # (N, T)
    across = d @ np.stack([-axes[:, 1], axes[:, 0]], axis=1).T
    held = np.count_nonzero((np.abs(across) <= FACE_HALF_WIDTH_M) & (along >= 0.0), axis=0)
    best = int(np.argmax(held))
    if held[best] < BEND_MIN_CELLS:
        return None
    axis = axes[best]
    normal = np.array([-axis[1], axis[0]])
    if float((own - kink) @ normal) < 0.0:
        normal = -normal
    return Face(kink, axis, normal)


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
    kept: dict[int, tuple[np.ndarray, np.ndarray, bool]] = {}
    pieces: list[tuple[np.ndarray, np.ndarray]] = []
    for k in big.tolist():
        fp = result.footprints[k]
        groups = hull_cells(fp, own, min_offset_m, min_length_m, gap_m, face_min_share)
        if not groups:
            continue
        members = np.flatnonzero(result.labels == k)
        mean = fp.mean(axis=0)
        rel = pts[members, :2] - mean
        taken = np.zeros(members.size, dtype=bool)
        taken_cells = np.zeros(fp.shape[0], dtype=bool)
        found: list[tuple[np.ndarray, np.ndarray]] = []  # (point indices, footprint cells) per hull
        for g, face in groups:
            # the hull's points: in front of its face (by half a cell less than its cells, which are centroids)
            # and along its cells' stretch
            fp_along = (fp[g] - mean - face.origin) @ face.axis
            a0, a1 = float(fp_along.min()) - cell_m, float(fp_along.max()) + cell_m
            d = rel - face.origin
            across, along = d @ face.normal, d @ face.axis
            mine = ~taken & (across >= min_offset_m - 0.5 * cell_m) & (along >= a0) & (along <= a1)
            if np.count_nonzero(mine) < 3:
                continue
            taken |= mine
            taken_cells[g] = True
            found.append((members[mine], fp[g]))
        if not found or taken.all():  # nothing carved, or nothing left of a "wall" that was hulls' sides
            continue
        kept[k] = (members[~taken], fp[~taken_cells], bool(result.oversized[k]))
        pieces += found
    return with_pieces(result, pts, own, kept, pieces, pieces_carved=True)


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
