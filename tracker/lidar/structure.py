"""Where the LiDAR has seen structure: quay walls and shore remembered in the world frame (ours, not in paper 000).

A quay wall is structure while the sensor sees it whole: its cluster is longer than any vessel
(``ClusterConfig.max_extent``). But boats moored along it and the own boat's passage cut it into pieces by their
shadows, and a 15-50 m piece of wall is the size of a vessel: tracked, it becomes a "vessel" with a speed made of
its changing ends. Paper 001 answers the same problem for radar with a static map; here the memory is simpler,
because the LiDAR tells structure apart by size whenever it sees it whole: every world cell covered by a
structure-sized cluster is remembered for ``memory_s``, and a later cluster lying mostly on remembered cells is
structure too. Its returns still reach the obstacle map; it just gets no track.

A boat moored on fenders merges with its wall in any scan where the wall's face is not straight enough to carve
it from (tracker.lidar.moored), and such a scan put the boat's cells in the memory: every later scan of the boat
alone, or carved, then lay on "wall" and the boat went untracked for ``memory_s`` (on the tuning scenes, fused,
moored boats were 29 % of the vessel-ticks missed). So the cells under a carved hull, and the cells next to them,
are no structure for ``memory_s`` after the carving, whatever a merged scan remembers there.

A scan can also merge a moored boat with its wall, or two boats moored end to end into one quay-sized "vessel"
(tracker.LidarTracker._static_structure), and remember the boat as wall. A quay's top is level, and the memory
keeps for each cell a lid: the wall's top, raised to where the VLP-16's next beam up passed over it. A cluster
later found on remembered structure that stands clearly above the lid there (a cabin) is a vessel again.

The cost of the rule: a vessel larger than ``max_extent`` that moves leaves structure behind it for ``memory_s``;
a small boat following in its track within that time is not tracked (its returns remain obstacles).

Frames: world NED (north, east), metres; the grid follows the own boat.
"""

from __future__ import annotations

import math

import numpy as np

from tracker.grid_shift import shift_in_place
from tracker.grouping import component_labels
from tracker.lidar.config import StructureConfig

_NEIGHBOURS = np.array([(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)], dtype=np.int64)
# The VLP-16's beams are 2 deg apart: a solid whose top return came from one beam stands no higher than where the
# next beam up passed at its range, or that beam would have returned too.
_NEXT_BEAM_TAN = math.tan(math.radians(2.0))
# Pieces of one straight wall: their axes within this of each other and each one's centre this close to the
# other's line (a thin piece's axis is good to a degree or two over 1.5 m or more; boats moored along a wall show
# sides offset from it and from each other by their differing beams).
_RUN_MAX_ANGLE_RAD = math.radians(5.0)
_RUN_MAX_OFFSET_M = 1.0
# Where a piece's line meets remembered structure (StructureMemory._wall_line_holds): the cells this far around the
# meeting show the wall's own line when they spread across it by at most _WALL_THIN_M (a face one or two 0.5 m cells
# thick); a piece more than _WALL_FRONT_MIN_M in front of that line, on the own boat's side, is on it only within
# _RUN_MAX_ANGLE_RAD and _WALL_MAX_OFFSET_M. Ours, from the geometry: a boat's near side stands its beam plus the
# fender gap in front (at least 1.3 m for a 1 m USV); on tuning seeds 1-30 the accepted pieces on boats met the
# face at a median 11 deg and stood a median 3.7 m in front of it, those on quays 1.7 deg and 0.7 m. Held out
# (random:1001-1050, fused), with tracker.lidar.moored's hull sides, against neither: MOTA 0.9501 -> 0.9534, worst
# scene 0.674 -> 0.721, moored hulls tracked 0.887 -> 0.918 of their vessel-ticks (pointed).
_WALL_WINDOW_M = 3.0
_WALL_THIN_M = 0.3
_WALL_FRONT_MIN_M = 0.5
_WALL_MAX_OFFSET_M = 2.0
_OWN_CELL = np.zeros((1, 2), dtype=np.int64)
# A line followed along a wall: on its emptier flank at most this share of what lies on the line itself.
_FLANK_MAX_RATIO = 0.5
# A wall's end met end-on by a thin piece (StructureMemory.wall_ends): past the corner, at most this share of what
# lies along the wall.
_CORNER_FAR_MAX_RATIO = 0.25


def structure_lids(clusters: list[np.ndarray], own_ne: np.ndarray, bin_m: float) -> np.ndarray:
    """(k,) for each structure cluster ((n, 3) world NED points), the world down coordinate it does not rise above,
    m: along its principal axis in bins of ``bin_m``, each bin's top return raised to where the next beam up passed
    at its range, and the median over the bins. A quay's top is level along it and a boat merged with it is the
    smaller part of its cluster, so the median is the wall's and not a cabin's. All clusters in one pass."""
    n = np.array([len(c) for c in clusters])
    pts = np.concatenate([np.asarray(c, dtype=float)[:, :3] for c in clusters])
    mean, axis, lo, hi, _spread = principal_extents([np.asarray(c, dtype=float)[:, :2] for c in clusters])
    owner = np.repeat(np.arange(len(clusters)), n)
    d = pts[:, :2] - mean[owner]
    along = d[:, 0] * axis[owner, 0] + d[:, 1] * axis[owner, 1] - lo[owner]
    rng = np.hypot(pts[:, 0] - own_ne[0], pts[:, 1] - own_ne[1])
    bound = pts[:, 2] - rng * _NEXT_BEAM_TAN  # down: smaller is higher
    # Each cluster's bins side by side in one array (a dense index: np.unique over the keys cost 40 times more).
    n_bins = np.floor((hi - lo) / bin_m).astype(np.int64) + 1
    first = np.cumsum(n_bins) - n_bins
    index = first[owner] + np.clip(np.floor(along / bin_m).astype(np.int64), 0, n_bins[owner] - 1)
    top = np.full(int(n_bins.sum()), np.inf)
    np.minimum.at(top, index, bound)
    bin_owner = np.repeat(np.arange(len(clusters)), n_bins)
    seen = np.isfinite(top)
    top, bin_owner = top[seen], bin_owner[seen]
    order = np.lexsort((top, bin_owner))
    counts = np.bincount(bin_owner, minlength=len(clusters))
    return top[order][np.cumsum(counts) - counts + counts // 2]


def principal_extents(
    footprints: list[np.ndarray],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per footprint (each at least one (north, east) point), along its principal axis: the mean (k, 2), the unit
    axis (k, 2), the lowest and highest coordinate along it (k,) and the spread across it (k,, standard deviation).
    All footprints in one pass."""
    n = np.array([len(f) for f in footprints])
    pts = np.concatenate([np.asarray(f, dtype=float)[:, :2] for f in footprints])
    starts = np.cumsum(n) - n
    mean = np.add.reduceat(pts, starts, axis=0) / n[:, None]
    d = pts - np.repeat(mean, n, axis=0)
    a = np.add.reduceat(d[:, 0] * d[:, 0], starts) / n
    b = np.add.reduceat(d[:, 0] * d[:, 1], starts) / n
    c = np.add.reduceat(d[:, 1] * d[:, 1], starts) / n
    root = np.sqrt(((a - c) / 2) ** 2 + b**2)  # the 2x2 covariance's eigenvalues, closed form
    minor_std = np.sqrt(np.maximum((a + c) / 2 - root, 0.0))
    angle = 0.5 * np.arctan2(2 * b, a - c)
    axis = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    rep = np.repeat(axis, n, axis=0)
    along = d[:, 0] * rep[:, 0] + d[:, 1] * rep[:, 1]
    lo, hi = np.minimum.reduceat(along, starts), np.maximum.reduceat(along, starts)
    return mean, axis, lo, hi, minor_std


class StructureMemory:
    """A square grid of world cells centred near the own boat; each holds when it last lay under structure."""

    def __init__(self, config: StructureConfig | None = None) -> None:
        self.cfg = config or StructureConfig()
        self.cells = int(np.ceil(2 * self.cfg.half_size_m / self.cfg.cell_m))
        self.last_seen = np.full((self.cells, self.cells), -np.inf)
        # When each cell last lay under a hull carved off a wall (tracker.lidar.moored): within memory_s of that,
        # the cell is no structure whatever a scan whose hull and wall had merged left in last_seen.
        self.hull_seen = np.full((self.cells, self.cells), -np.inf)
        # The highest (least down, world NED, m) lid of the structure stamped on each cell (structure_lids): a
        # cluster standing above it by more than taller_margin_m is a boat against the wall, not the wall.
        self.lid_down = np.full((self.cells, self.cells), np.inf)
        self.origin: np.ndarray | None = None  # world (north, east) of cell (0, 0)'s corner
        self.newest = -np.inf  # no cell was last seen later than this
        self.newest_hull = -np.inf  # nor under a carved hull

    def reset(self) -> None:
        self.last_seen.fill(-np.inf)
        self.hull_seen.fill(-np.inf)
        self.lid_down.fill(np.inf)
        self.origin = None
        self.newest = -np.inf
        self.newest_hull = -np.inf

    def _remembers_any(self, t: float) -> bool:
        """Whether any cell may have been seen within ``memory_s`` of ``t``: in open water none ever was, and the
        lookups need not run."""
        return self.newest >= t - self.cfg.memory_s

    def follow(self, own_ne: np.ndarray) -> None:
        """Keep every point within ``range_m`` of the own boat on the grid: recentre (moving what it remembers
        along) once the boat is more than ``half_size_m - range_m`` from the grid's centre."""
        own = np.asarray(own_ne, dtype=float)[:2]
        half = self.cells * self.cfg.cell_m / 2
        if self.origin is None:
            self.origin = np.floor((own - half) / self.cfg.cell_m) * self.cfg.cell_m
            return
        if np.all(np.abs(own - (self.origin + half)) <= half - self.cfg.range_m - self.cfg.cell_m):
            return
        new_origin = np.floor((own - half) / self.cfg.cell_m) * self.cfg.cell_m
        shift = np.rint((new_origin - self.origin) / self.cfg.cell_m).astype(int)
        shift_in_place(self.last_seen, shift[0], shift[1], -np.inf)  # no new grid per move (tracker/grid_shift.py)
        shift_in_place(self.hull_seen, shift[0], shift[1], -np.inf)
        shift_in_place(self.lid_down, shift[0], shift[1], np.inf)
        self.origin = new_origin

    def _index(self, points_ne: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        assert self.origin is not None
        ij = np.floor((np.asarray(points_ne, dtype=float)[:, :2] - self.origin) / self.cfg.cell_m).astype(np.int64)
        i, j = ij[:, 0], ij[:, 1]
        return i, j, (i >= 0) & (i < self.cells) & (j >= 0) & (j < self.cells)

    def _stamp(
        self, grid: np.ndarray, t: float, points_ne: np.ndarray
    ) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray] | None:
        """Set ``grid``'s cells under the points to ``t``; the (i, j) of the points on the grid and a mask of them,
        None when there was nothing to stamp."""
        if self.origin is None or len(points_ne) == 0:
            return None
        i, j, inside = self._index(points_ne)
        grid[i[inside], j[inside]] = t
        return (i[inside], j[inside]), inside

    def remember(self, t: float, points_ne: np.ndarray, lid_down: np.ndarray | None = None) -> None:
        """Mark the cells under structure returns (or footprint cells) seen at time ``t``, each point with the lid
        (world down, m) of the structure it belongs to (None: not known, nothing stands above it); a cell keeps
        the highest lid stamped on it."""
        stamped = self._stamp(self.last_seen, t, points_ne)
        if stamped is not None:
            self.newest = max(self.newest, t)
            cells, inside = stamped
            lids = np.full(len(inside), -np.inf) if lid_down is None else np.asarray(lid_down, dtype=float)
            np.minimum.at(self.lid_down, cells, lids[inside])

    def remember_hull(self, t: float, points_ne: np.ndarray) -> None:
        """Mark the cells under a hull carved off a wall at time ``t``: no structure while remembered."""
        if self._stamp(self.hull_seen, t, points_ne) is not None:
            self.newest_hull = max(self.newest_hull, t)

    def lids_at(self, t: float, points_ne: np.ndarray) -> np.ndarray:
        """(n,) for each point, the highest lid (least down, m) of the structure remembered on or next to its cell
        within ``memory_s`` of ``t``; inf where none is."""
        n = len(points_ne)
        if self.origin is None or n == 0:
            return np.full(n, np.inf)
        flat, on_grid = self._neighbour_cells(points_ne, _NEIGHBOURS)
        seen = (np.take(self.last_seen.ravel(), flat) >= t - self.cfg.memory_s) & on_grid
        return np.where(seen, np.take(self.lid_down.ravel(), flat), np.inf).min(axis=1)

    def lid_in_front(self, t: float, points_ne: np.ndarray, sensor_ne: np.ndarray, depth_m: float) -> np.ndarray:
        """(n,) for each point, the highest lid (least down, m) of the structure remembered within ``memory_s`` of
        ``t`` on its line of sight from ``sensor_ne`` within ``depth_m`` in front of it (its own cell left out);
        inf where the line met none. Sampled every half cell, one cell each: a wall a cell thick is not stepped
        over. World NED (north, east), m."""
        pts = np.asarray(points_ne, dtype=float)[:, :2]
        n = len(pts)
        if self.origin is None or n == 0 or depth_m <= 0 or not self._remembers_any(t):
            return np.full(n, np.inf)
        sight = pts - np.asarray(sensor_ne, dtype=float)[:2]
        dist = np.hypot(sight[:, 0], sight[:, 1])
        unit = sight / np.maximum(dist, 1e-6)[:, None]
        step = 0.5 * self.cfg.cell_m
        back = np.arange(1, int(depth_m / step) + 1) * step  # (S,)
        samples = pts[:, None, :] - back[None, :, None] * unit[:, None, :]  # (n, S, 2)
        i, j, inside = self._index(samples.reshape(-1, 2))
        i, j, inside = i.reshape(n, -1), j.reshape(n, -1), inside.reshape(n, -1)
        flat = np.clip(i, 0, self.cells - 1) * self.cells + np.clip(j, 0, self.cells - 1)
        since = t - self.cfg.memory_s
        seen = (np.take(self.last_seen.ravel(), flat) >= since) & inside
        if self.newest_hull >= since:
            seen &= np.take(self.hull_seen.ravel(), flat) < since
        pi, pj, _ = self._index(pts)
        seen &= (i != pi[:, None]) | (j != pj[:, None])  # not the point's own cell
        seen &= back[None, :] < dist[:, None]  # nor behind the sensor
        return np.where(seen, np.take(self.lid_down.ravel(), flat), np.inf).min(axis=1)

    def known(self, t: float, points_ne: np.ndarray) -> np.ndarray:
        """(n,) bool: the point lies on, or next to, a cell seen under structure within ``memory_s`` of ``t``."""
        return self._seen_within(t, points_ne, _NEIGHBOURS)

    def near(self, t: float, points_ne: np.ndarray, radius_m: float) -> np.ndarray:
        """(n,) bool: a cell within ``radius_m`` of the point (cell centres, plus half a cell) was seen under
        structure within ``memory_s`` of ``t``. For positions measured far more coarsely than a cell (a radar
        track's centre)."""
        reach = int(np.ceil(radius_m / self.cfg.cell_m))
        di, dj = np.mgrid[-reach : reach + 1, -reach : reach + 1]
        disc = np.hypot(di, dj) * self.cfg.cell_m <= radius_m + 0.5 * self.cfg.cell_m
        return self._seen_within(t, points_ne, np.column_stack([di[disc], dj[disc]]))

    def _neighbour_cells(self, points_ne: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n, k) flat index of the cell at each of the (k, 2) cell ``offsets`` from each point's cell (clipped to
        the grid), and whether that cell lies on the grid."""
        i, j, _ = self._index(points_ne)
        ni, nj = i[:, None] + offsets[None, :, 0], j[:, None] + offsets[None, :, 1]
        on_grid = (ni >= 0) & (ni < self.cells) & (nj >= 0) & (nj < self.cells)
        flat = np.clip(ni, 0, self.cells - 1) * self.cells + np.clip(nj, 0, self.cells - 1)  # a 2-D gather costs 3x
        return flat, on_grid

    def _seen_within(self, t: float, points_ne: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """(n,) bool: a cell at one of the (k, 2) cell ``offsets`` from the point's cell was seen under structure
        within ``memory_s`` of ``t``."""
        if self.origin is None or len(points_ne) == 0 or not self._remembers_any(t):
            return np.zeros(len(points_ne), dtype=bool)
        flat, on_grid = self._neighbour_cells(points_ne, offsets)
        since = t - self.cfg.memory_s
        structure = np.any((np.take(self.last_seen.ravel(), flat) >= since) & on_grid, axis=1)  # off the grid
        if self.newest_hull < since:  # no hull carved within memory_s (most scans): the second gather is not needed
            return structure
        hull = np.any((np.take(self.hull_seen.ravel(), flat) >= since) & on_grid, axis=1)  # nothing is known
        return structure & ~hull

    def _thin_pieces_to_test(
        self, t: float, footprints: list[np.ndarray], enabled: bool
    ) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, ...] | None]:
        """For the wall rules: (k,) all False and (k,) all inf to fill in, and the thin pieces among the footprints
        (:func:`thin_pieces`), or None when there is nothing to test: the rule off, no footprint, no structure
        remembered, or no thin piece (only a thin piece can be a piece of wall; the others need no lookup)."""
        cfg = self.cfg
        k = len(footprints)
        out, lids = np.zeros(k, dtype=bool), np.full(k, np.inf)
        if not enabled or self.origin is None or k == 0 or not self._remembers_any(t):
            return out, lids, None
        pieces = thin_pieces(footprints, cfg.line_max_thickness_m, cfg.short_line_min_length_m)
        return out, lids, (pieces if pieces[0].size else None)

    def continues(
        self, t: float, footprints: list[np.ndarray], own_ne: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(k,) bool: each footprint is a thin straight piece whose own line runs on into remembered structure; and
        (k,) the highest lid of the structure its line met (inf for the others).

        A quay wall far off comes back as pieces: only the lowest beam reaches it, and boats moored along it cut it
        up with their shadows. A piece is as long as a boat, but it lies on the line of the wall already seen; a
        boat moored against the wall shows its near side, a beam's width off that line. Tested by sampling the
        piece's principal axis beyond both ends (``line_reach_m`` each way, one sample a cell) and asking whether
        at least ``line_min_share`` of one side's samples fall on remembered structure; for a piece shorter than
        ``line_min_length_m`` (down to ``short_line_min_length_m``), ``short_line_min_share``; and the wall met must
        run along the piece's line (:meth:`_wall_line_holds`, which needs ``own_ne``; None leaves it out)."""
        cfg = self.cfg
        out, lids, pieces = self._thin_pieces_to_test(t, footprints, cfg.line_reach_m > 0)
        if pieces is None:
            return out, lids
        idx, mean, axis, lo, hi = pieces
        length = hi - lo
        steps = np.arange(1, int(cfg.line_reach_m / cfg.cell_m) + 1) * cfg.cell_m + cfg.line_gap_m  # (S,)
        s_count = steps.size
        # (P, 2 sides, S, 2): samples beyond the low end and beyond the high end
        beyond_lo = mean[:, None, :] + (lo[:, None] - steps[None, :])[..., None] * axis[:, None, :]
        beyond_hi = mean[:, None, :] + (hi[:, None] + steps[None, :])[..., None] * axis[:, None, :]
        samples = np.stack([beyond_lo, beyond_hi], axis=1)  # (P, 2, S, 2)
        p_count = mean.shape[0]
        needed = np.where(length >= cfg.line_min_length_m, cfg.line_min_share, cfg.short_line_min_share)
        hit = self.known(t, samples.reshape(-1, 2)).reshape(p_count, 2, s_count)
        on_line = hit.mean(axis=2)  # (P, 2)
        along = on_line >= needed[:, None]
        piece, side = np.nonzero(along)
        if cfg.line_flank_m > 0 and piece.size:  # only the sides whose line met enough wall: few
            # A wall followed along its length has water on one flank of the line; a line that crosses remembered
            # ground (a boat's axis pointing at a quay and the land behind it) has ground on both flanks.
            normal = np.column_stack([-axis[piece, 1], axis[piece, 0]])[:, None, :]  # (C, 1, 2)
            line = samples[piece, side]  # (C, S, 2)
            flanks = np.stack([line + cfg.line_flank_m * normal, line - cfg.line_flank_m * normal], axis=1)
            on_flank = self.known(t, flanks.reshape(-1, 2)).reshape(piece.size, 2, s_count).mean(axis=2)
            along[piece, side] = on_flank.min(axis=1) <= _FLANK_MAX_RATIO * on_line[piece, side]
        piece, side = np.nonzero(along)
        if piece.size and own_ne is not None:
            along[piece, side] = self._wall_line_holds(
                t, samples[piece, side], hit[piece, side], mean[piece], axis[piece], np.asarray(own_ne, float)[:2]
            )
        out[idx] = along.any(axis=1)
        lids[idx] = self.lids_at(t, samples.reshape(-1, 2)).reshape(p_count, -1).min(axis=1)
        return out, lids

    def _wall_line_holds(
        self, t: float, samples: np.ndarray, hit: np.ndarray, mean: np.ndarray, axis: np.ndarray, own_ne: np.ndarray
    ) -> np.ndarray:
        """(C,) bool: each piece (its ``mean`` and unit ``axis``, (C, 2)) may be the wall its line met (``samples``
        (C, S, 2) along the line, ``hit`` (C, S) where they met remembered structure).

        A line drawn from a few metres of returns is good to a few degrees only, and 20 m on it crosses a wall it
        does not continue: the near side of a boat moored along a quay, a beam in front of the face, took the quay
        for its own line (tuning seed 98: a 12 m boat untracked for 20 s). So where the remembered structure met is
        a thin face (cells within _WALL_WINDOW_M of where the line met it, spread across their principal axis by at
        most _WALL_THIN_M), a piece standing more than _WALL_FRONT_MIN_M in front of that face's line, on the own
        boat's side, continues it only with its axis within _RUN_MAX_ANGLE_RAD of the face's and its centre within
        _WALL_MAX_OFFSET_M of the line. A piece behind the line (a quay bent towards the land past a kink) and
        structure too thick or too sparse to draw a line through keep the rule as it was."""
        count = hit.sum(axis=1)
        centre = (samples * hit[..., None]).sum(axis=1) / np.maximum(count, 1)[:, None]
        r = round(_WALL_WINDOW_M / self.cfg.cell_m)
        di, dj = np.mgrid[-r : r + 1, -r : r + 1]
        cells = centre[:, None, :] + np.column_stack([di.ravel(), dj.ravel()])[None, :, :] * self.cfg.cell_m
        seen = self._seen_within(t, cells.reshape(-1, 2), _OWN_CELL).reshape(cells.shape[:2])  # (C, K)
        holds = np.ones(len(samples), dtype=bool)
        fit = np.flatnonzero(seen.sum(axis=1) >= 3)
        if fit.size == 0:
            return holds
        w_mean, w_axis, _lo, _hi, spread = principal_extents([cells[c][seen[c]] for c in fit])
        normal = np.column_stack([-w_axis[:, 1], w_axis[:, 0]])
        normal *= np.where(np.einsum("ij,ij->i", own_ne - w_mean, normal) < 0.0, -1.0, 1.0)[:, None]
        in_front = np.einsum("ij,ij->i", mean[fit] - w_mean, normal)
        aligned = np.abs(np.einsum("ij,ij->i", w_axis, axis[fit])) >= math.cos(_RUN_MAX_ANGLE_RAD)
        holds[fit] = ~(
            (spread <= _WALL_THIN_M) & (in_front > _WALL_FRONT_MIN_M) & (~aligned | (in_front > _WALL_MAX_OFFSET_M))
        )
        return holds

    def wall_ends(self, t: float, footprints: list[np.ndarray], own_ne: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(k,) bool: each footprint is a thin straight piece meeting remembered structure end-on where that
        structure ends, across it; and (k,) the highest lid of the structure it met (inf for the others).

        A quay's end face, seen from beyond the end: the front face is remembered (seen from the water side before),
        the end face runs from its last corner into the land, and from out there it is all the sensor sees, a thin
        wall 4-8 m long. Its line does not run on along the wall (``continues``), its footprint lies beside the
        remembered cells rather than on them, and tracked it was a "vessel" standing at the quay's end for the rest
        of the run (the largest class of false track-frames on tuning scenes 1-100). Tested at each end of the
        piece: remembered structure within ``corner_touch_m`` beyond it, and on the line across the piece through
        that end (``corner_reach_m`` each way, from 1 m) remembered structure on one side and, at most a quarter as
        much, on the other: the wall ends there. A boat moored bow-on to a wall has the wall on both sides."""
        cfg = self.cfg
        out, lids, pieces = self._thin_pieces_to_test(t, footprints, cfg.corner_reach_m > 0)
        if pieces is None:
            return out, lids
        idx, mean, axis, lo, hi = pieces
        p_count = idx.size
        ends = np.stack([mean + lo[:, None] * axis, mean + hi[:, None] * axis], axis=1)  # (P, 2 ends, 2)
        outward = np.stack([-axis, axis], axis=1)  # (P, 2, 2)
        touch_steps = np.arange(0.0, cfg.corner_touch_m + 1e-9, cfg.cell_m)
        touch = ends[:, :, None, :] + touch_steps[None, None, :, None] * outward[:, :, None, :]
        touching = self.known(t, touch.reshape(-1, 2)).reshape(p_count, 2, -1).any(axis=2)  # (P, 2)
        piece, end = np.nonzero(touching)
        if piece.size == 0:
            return out, lids
        normal = np.column_stack([-axis[piece, 1], axis[piece, 0]])  # (C, 2)
        steps = np.arange(1.0, cfg.corner_reach_m + 1e-9, cfg.cell_m)  # (S,)
        across = np.concatenate([steps, -steps])[None, :, None] * normal[:, None, :]  # (C, 2S, 2)
        samples = ends[piece, end][:, None, :] + across
        on = self.known(t, samples.reshape(-1, 2)).reshape(piece.size, 2, steps.size).mean(axis=2)  # (C, 2 sides)
        wall, far = on.max(axis=1), on.min(axis=1)
        corner = (wall >= cfg.line_min_share) & (far <= _CORNER_FAR_MAX_RATIO * wall)
        # Behind the wall's line, not in front of it: the end or stern of a boat moored alongside meets the wall
        # end-on too, where its own shadow left the wall unseen on one side; but it stands on the water, on the own
        # boat's side of the wall. Within corner_side_margin_m of the line the own boat is beyond the wall's end
        # (short of it, it would be aground), and which side is which is not told.
        touch_pt = ends[piece, end]
        far_pt = ends[piece, 1 - end]
        own_side = np.einsum("ij,ij->i", np.asarray(own_ne, dtype=float)[:2] - touch_pt, axis[piece])
        far_side = np.einsum("ij,ij->i", far_pt - touch_pt, axis[piece])
        corner &= (own_side * far_side < 0.0) | (np.abs(own_side) <= cfg.corner_side_margin_m)
        if not corner.any():
            return out, lids
        found = idx[piece[corner]]
        out[found] = True
        met = self.lids_at(t, touch[piece[corner], end[corner]].reshape(-1, 2)).reshape(int(corner.sum()), -1)
        np.minimum.at(lids, found, met.min(axis=1))
        return out, lids


def thin_pieces(
    footprints: list[np.ndarray], max_thickness_m: float, min_length_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The footprints of at least three points that are thin straight pieces (spread across their principal axis
    at most ``max_thickness_m``, at least ``min_length_m`` along it): their indices into ``footprints`` and, as
    :func:`principal_extents` gives them, each one's mean, unit axis and lowest and highest coordinate along it."""
    sizes = np.array([len(f) for f in footprints])
    idx = np.flatnonzero(sizes >= 3)
    if idx.size == 0:
        return idx, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0)
    mean, axis, lo, hi, minor_std = principal_extents([footprints[i] for i in idx])
    thin = (minor_std <= max_thickness_m) & (hi - lo >= min_length_m)
    return idx[thin], mean[thin], axis[thin], lo[thin], hi[thin]


def collinear_runs(
    footprints: list[np.ndarray], min_span_m: float, max_thickness_m: float, min_length_m: float, min_pieces: int
) -> np.ndarray:
    """(k,) bool: the thin straight pieces (minor spread <= ``max_thickness_m``, at least ``min_length_m`` long)
    that lie on one line with other such pieces (axes within _RUN_MAX_ANGLE_RAD, each one's mean within
    _RUN_MAX_OFFSET_M of the other's line), ``min_pieces`` or more spanning ``min_span_m`` or more together: a wall
    longer than any vessel seen in pieces, by one beam or between the shadows of what lies in front of it. All
    pieces of one scan at once. World NED (north, east), m."""
    out = np.zeros(len(footprints), dtype=bool)
    if min_pieces <= 0:
        return out
    idx, mean, axis, lo, hi = thin_pieces(footprints, max_thickness_m, min_length_m)
    if idx.size < min_pieces:
        return out
    normal = np.column_stack([-axis[:, 1], axis[:, 0]])
    d = mean[None, :, :] - mean[:, None, :]  # (P, P, 2): j's mean from i's
    off = np.abs((d * normal[:, None, :]).sum(axis=2))  # j's mean off i's line
    parallel = np.abs(axis @ axis.T) >= math.cos(_RUN_MAX_ANGLE_RAD)
    first, second = np.nonzero(np.triu(parallel & (off <= _RUN_MAX_OFFSET_M) & (off.T <= _RUN_MAX_OFFSET_M), 1))
    run = component_labels(idx.size, first, second)  # each piece's run, named by its lowest piece
    for r in np.flatnonzero(np.bincount(run, minlength=idx.size) >= min_pieces):  # few: one per wall in view
        members = np.flatnonzero(run == r)
        ref = axis[members[0]]
        ends = (mean[members] @ ref)[:, None] + np.column_stack([lo[members], hi[members]]) * (axis[members] @ ref)[
            :, None
        ]
        if ends.max() - ends.min() >= min_span_m:
            out[idx[members]] = True
    return out
