"""Static map of radar returns and the shore filter (paper 001, sec. 2.2-2).

One radar frame shows a quay wall as a handful of points, too few to tell from a boat. Accumulated in a world-frame
grid over many frames the wall becomes a long line of occupied cells while a moored boat stays a small blob. Large
structures are the shore: clusters on them, or behind them as seen from the radar (multipath through the wall, cars on
the quay), are not tracked. The shore cells are kept for the obstacle map: a wall is an obstacle even if not a vessel.

Layout: ``submaps_across`` x ``submaps_across`` sub-maps of ``submap_cells``^2 cells (sec. 3.2: 0.25 m, 400 x 400)
aligned to a world lattice, the boat always in the middle one. When the boat crosses into another sub-map the window
shifts by whole sub-maps: overlapping evidence is copied by index arithmetic, the new sub-maps start empty.

Decay without touching the whole grid every frame: evidence is stored scaled by exp((t - t_ref) / tau) and read back
scaled by exp(-(t - t_ref) / tau); the stored values are rebased once the factor gets large.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from tracker.existence import clutter_tail
from tracker.grid_shift import shift_in_place
from tracker.radar.config import RadarTrackerConfig
from tracker.radar.dbscan import kd_tree

log = logging.getLogger(__name__)

_REBASE_FACTOR = 1.0e6  # rebase stored evidence once the write scale exceeds this


def _keys(cells_rc: np.ndarray) -> np.ndarray:
    """One int64 per (row, col) world cell; rows and cols within +-2^30 cells (+-268 000 km at 0.25 m)."""
    rc = np.asarray(cells_rc, np.int64).reshape(-1, 2)
    return (rc[:, 0] + (1 << 30)) * (1 << 31) + (rc[:, 1] + (1 << 30))


def _dilate_3x3(mask: np.ndarray) -> np.ndarray:
    """ndimage.binary_dilation of a 2-D bool array by a 3 x 3 square (outside counts as empty), as two shifted ORs
    per axis: a tenth of ndimage's call overhead on the ~100 x 100 block rasters of a shore extraction."""
    rows = mask.copy()
    rows[1:] |= mask[:-1]
    rows[:-1] |= mask[1:]
    out = rows.copy()
    out[:, 1:] |= rows[:, :-1]
    out[:, :-1] |= rows[:, 1:]
    return out


class StaticMap:
    """World-frame (north, east) evidence grid that follows the boat, with the shore extracted from it."""

    def __init__(self, config: RadarTrackerConfig) -> None:
        self.cfg = config
        self.res = float(config.shore.map_resolution_m)
        self.sub = int(config.shore.submap_cells)
        self.size = self.sub * int(config.shore.submaps_across)
        self.grid = np.zeros((self.size, self.size))
        self.last_hit = np.full((self.size, self.size), -np.inf)  # time of each cell's latest hit
        self.origin: tuple[int, int] | None = None  # world cell (i, j) of grid[0, 0]
        self.t_ref = 0.0
        self.t_last = -math.inf
        self.shifts = 0
        self.frames = 0.0  # frames added, decayed as the evidence is (same scale): how many a cell could have been hit
        # Clutter returns a frame expected per m^2 at given ranges from the boat (RadarDetector.clutter_expected);
        # None: the fixed shore.occupied_hits alone decides
        self.clutter_per_m2: Callable[[np.ndarray], np.ndarray] | None = None
        # Flat indices of the cells holding evidence: the shore scan visits only these, not 1200 x 1200 cells.
        self._touched = np.empty(0, np.int64)
        self._touched_new: list[np.ndarray] = []  # cells hit since the last shore extraction, merged there
        self._is_touched = np.zeros(self.size * self.size, bool)  # membership of _touched, so merging needs no sort
        self._clear_shore()

    # --- bookkeeping -------------------------------------------------------------------------------------------------

    def reset(self) -> None:
        self.grid[:] = 0.0
        self.last_hit[:] = -np.inf
        self._touched = np.empty(0, np.int64)
        self._touched_new = []
        self._is_touched[:] = False
        self.origin = None
        self.t_last = -math.inf
        self.frames = 0.0
        self._clear_shore()

    def _clear_shore(self) -> None:
        self._shore_rc = np.empty((0, 2), np.int64)  # world cells (row, col) of shore-sized structures
        self._shore_keys = np.empty(0, np.int64)  # the same as sorted keys, for membership tests
        self._edge_rc = np.empty((0, 2), np.int64)  # their contour
        self._tree: cKDTree | None = None  # shore cell centres, for "within the margin" tests
        self._t_shore = -math.inf
        self._horizon: tuple[tuple[float, float], np.ndarray] | None = None  # (sensor N/E, shore_horizon there)

    def cells(self, points_ne: np.ndarray) -> np.ndarray:
        """(n, 2) world cell indices (row = north, col = east)."""
        return np.floor(np.asarray(points_ne, float) / self.res).astype(np.int64)

    def _scale(self, t: float) -> float:
        return math.exp(min((t - self.t_ref) / self.cfg.shore.decay_time_s, 700.0))

    def advance_time(self, t: float) -> None:
        """Move the map's clock to t (every write and shore update does this); going back in time clears the map."""
        if t < self.t_last:
            log.warning("static map: time went back from %.3f to %.3f s; map cleared", self.t_last, t)
            self.reset()
        if self.t_last == -math.inf:
            self.t_ref = t
        self.t_last = t
        if self._scale(t) > _REBASE_FACTOR:
            self.frames *= 1.0 / self._scale(t)
            self.grid *= 1.0 / self._scale(t)
            self.t_ref = t

    def follow(self, position_ne: np.ndarray) -> None:
        """Keep the boat in the middle sub-map; shift the window by whole sub-maps when it leaves it."""
        boat = self.cells(np.asarray(position_ne, float).reshape(1, 2))[0]
        half = self.cfg.shore.submaps_across // 2
        want = tuple(int((b // self.sub - half) * self.sub) for b in boat)
        if self.origin is None:
            self.origin = want  # type: ignore[assignment]
            return
        if want == self.origin:
            return
        di, dj = want[0] - self.origin[0], want[1] - self.origin[1]
        # In place: two new 11 MB grids per shift kept glibc's heap large (tracker/grid_shift.py)
        shift_in_place(self.grid, di, dj, 0.0)
        shift_in_place(self.last_hit, di, dj, -np.inf)
        self._touched = np.flatnonzero(self.grid)  # a rare event: one full scan
        self._touched_new = []
        self._is_touched[:] = False
        self._is_touched[self._touched] = True
        self.origin = want  # type: ignore[assignment]
        self.shifts += 1

    # --- evidence ----------------------------------------------------------------------------------------------------

    def add_points(self, points_ne: np.ndarray, t: float) -> int:
        """One hit per occupied cell per frame (a dense reflector does not outvote persistence). Returns cells hit."""
        self.advance_time(t)
        self.frames += self._scale(t)
        if self.origin is None or len(points_ne) == 0:
            return 0
        rc = self.cells(points_ne) - np.asarray(self.origin)
        inside = np.all((rc >= 0) & (rc < self.size), axis=1)
        flat = np.unique(rc[inside, 0] * self.size + rc[inside, 1])
        self.grid.flat[flat] += self._scale(t)
        self.last_hit.flat[flat] = t
        self._touched_new.append(flat)
        return int(flat.size)

    def evidence(self, t: float) -> np.ndarray:
        """Decayed hits per cell at time t, (size, size); a copy."""
        return self.grid * (1.0 / self._scale(t))

    def evidence_at(self, points_ne: np.ndarray, t: float) -> np.ndarray:
        out = np.zeros(len(points_ne))
        if self.origin is None or len(points_ne) == 0:
            return out
        rc = self.cells(points_ne) - np.asarray(self.origin)
        inside = np.all((rc >= 0) & (rc < self.size), axis=1)
        out[inside] = self.grid[rc[inside, 0], rc[inside, 1]] / self._scale(t)
        return out

    # --- shore -------------------------------------------------------------------------------------------------------

    def update_shore(self, t: float, position_ne: np.ndarray, max_range_m: float) -> bool:
        """Extract shore structures within ``max_range_m`` of the boat; True if an extraction ran (it runs every
        ``shore.update_interval_s``).

        Cost follows the number of occupied cells, not the map's area (a harbour window is 800 x 800 cells): the
        occupied cells are OR-ed into blocks of the link radius, blocks are grown by one and labelled (ndimage), so
        structures with gaps up to about twice the link radius are one; a structure's extent is measured on its fine
        cells. Shore cells are then kept as a sorted key list, a k-d tree (distance to the shore) and their contour.
        """
        self.advance_time(t)
        if self.origin is None or t - self._t_shore < self.cfg.shore.update_interval_s:
            return False
        self._clear_shore()
        self._t_shore = t
        scale = self._scale(t)
        if self._touched_new:
            fresh = np.unique(np.concatenate(self._touched_new))
            fresh = fresh[~self._is_touched[fresh]]
            self._is_touched[fresh] = True
            self._touched = np.concatenate([self._touched, fresh])
            self._touched_new = []
        value = self.grid.flat[self._touched]
        keep = value >= 1e-3 * scale  # evidence decayed to nothing: forget the cell until it is hit again
        self._is_touched[self._touched[~keep]] = False
        self._touched, value = self._touched[keep], value[keep]
        recent = self.last_hit.flat[self._touched] >= t - self.cfg.shore.recent_s
        pool = max(1, round(self.cfg.shore.evidence_pool_m / self.res))
        if pool > 1:
            # Evidence pooled over pool x pool cells: a wall seen through 1 deg of azimuth noise spreads its returns
            # over a metre, so single 0.25 m cells fill up far slower than the wall is really seen.
            # Block numbers straight from the flat index (no sort): bincount sums each block's cells in the same
            # order as over np.unique's labels.
            row, col = np.divmod(self._touched, self.size)
            block = (row // pool) * (self.size // pool + 1) + col // pool
            pooled = np.bincount(block, weights=value)[block]
            recent = np.bincount(block, weights=recent)[block] > 0
        else:
            pooled = value
        # Occupied: enough evidence, and seen lately. A structure is judged by what is there now: the returns a slow
        # boat leaves behind (its Doppler looks static) fall out after shore.recent_s instead of adding up to a
        # "shore" as long as its track.
        occupied = (pooled >= self.cfg.shore.occupied_hits * scale) & recent
        boat = self.cells(np.asarray(position_ne, float).reshape(1, 2))[0] - np.asarray(self.origin)
        if self.clutter_per_m2 is not None and occupied.any():
            occupied[occupied] = self._beyond_clutter(self._touched[occupied], pooled[occupied] / scale, boat, pool)
        occ = self._touched[occupied]
        rc = np.stack(np.divmod(occ, self.size), axis=1)
        rc = rc[np.all(np.abs(rc - boat) <= math.ceil(max_range_m / self.res) + 1, axis=1)]
        if rc.size == 0:
            return True
        block = max(1, round(self.cfg.shore.link_radius_m / self.res))
        coarse = rc // block
        lo = coarse.min(axis=0) - 1
        coarse -= lo
        blocks = np.zeros(tuple(coarse.max(axis=0) + 2), bool)
        blocks[coarse[:, 0], coarse[:, 1]] = True
        grown = _dilate_3x3(blocks)
        labels, n_lab = ndimage.label(grown, structure=np.ones((3, 3), bool))
        lab = labels[coarse[:, 0], coarse[:, 1]]
        big = np.zeros(n_lab + 1, bool)
        lo_r, hi_r = np.full(n_lab + 1, np.iinfo(np.int64).max), np.full(n_lab + 1, np.iinfo(np.int64).min)
        lo_c, hi_c = lo_r.copy(), hi_r.copy()
        np.minimum.at(lo_r, lab, rc[:, 0])
        np.maximum.at(hi_r, lab, rc[:, 0])
        np.minimum.at(lo_c, lab, rc[:, 1])
        np.maximum.at(hi_c, lab, rc[:, 1])
        seen = hi_r >= lo_r
        extent = np.hypot(hi_r[seen] - lo_r[seen] + 1, hi_c[seen] - lo_c[seen] + 1) * self.res
        big[np.flatnonzero(seen)] = extent >= self.cfg.shore.min_extent_m
        shore = rc[big[lab]] + np.asarray(self.origin)  # world cell indices
        if shore.size == 0:
            return True
        self._shore_rc = shore
        self._shore_keys = np.sort(_keys(shore))
        self._tree = kd_tree((shore + 0.5) * self.res)
        # Contour: shore cells with at least one of their four neighbours not shore (on a raster of their bounds).
        r, c = (shore - shore.min(axis=0) + 1).T
        raster = np.zeros((r.max() + 2, c.max() + 2), bool)
        raster[r, c] = True
        inner = raster[r + 1, c] & raster[r - 1, c] & raster[r, c + 1] & raster[r, c - 1]
        self._edge_rc = shore[~inner]
        return True

    def _beyond_clutter(self, flat: np.ndarray, hits: np.ndarray, boat_rc: np.ndarray, pool: int) -> np.ndarray:
        """(n,) bool: the pooled hits of these cells are more than the sea's clutter would have left there over the
        map's decayed frames (Poisson tail at most ``existence.confirm_tail``). Rough water leaves static-looking
        returns everywhere near the boat; a wall leaves them in the same place frame after frame."""
        assert self.clutter_per_m2 is not None
        rc = np.stack(np.divmod(flat, self.size), axis=1)
        range_m = np.hypot(*((rc - boat_rc) * self.res).T)
        block_area = (pool * self.res) ** 2
        expected = self.clutter_per_m2(range_m) * block_area * (self.frames / self._scale(self.t_last))
        return clutter_tail(hits, expected) <= self.cfg.existence.confirm_tail

    def _contains(self, cells_rc: np.ndarray) -> np.ndarray:
        keys = _keys(cells_rc)
        pos = np.searchsorted(self._shore_keys, keys)
        pos = np.minimum(pos, max(len(self._shore_keys) - 1, 0))
        return (self._shore_keys[pos] == keys) if len(self._shore_keys) else np.zeros(len(keys), bool)

    def on_shore(self, points_ne: np.ndarray) -> np.ndarray:
        """(n,) bool: within shore.margin_m of a shore cell (its centre, plus half a cell diagonal)."""
        pts = np.asarray(points_ne, float).reshape(-1, 2)
        if self._tree is None or len(pts) == 0:
            return np.zeros(len(pts), bool)
        reach = self.cfg.shore.margin_m + self.res * math.sqrt(0.5)
        dist, _ = self._tree.query(pts, k=1, distance_upper_bound=reach)
        return np.isfinite(dist)

    def is_shore(self, points_ne: np.ndarray) -> np.ndarray:
        """(n,) bool: the point's cell is a shore cell."""
        pts = np.asarray(points_ne, float).reshape(-1, 2)
        return self._contains(self.cells(pts))

    def shore_points(self) -> np.ndarray:
        """(k, 2) world north/east centres of the shore's contour cells, for the obstacle map."""
        return (self._edge_rc + 0.5) * self.res

    def shore_cells(self) -> np.ndarray:
        """(k, 2) world north/east centres of every shore cell."""
        return (self._shore_rc + 0.5) * self.res

    def _bearing_bin(self, rel: np.ndarray) -> np.ndarray:
        n_bins = round(2 * math.pi / self.cfg.shore.horizon_bin_rad)
        az = np.arctan2(rel[:, 1], rel[:, 0])
        return np.floor((az + math.pi) / (2 * math.pi) * n_bins).astype(np.int64) % n_bins

    def shore_horizon(self, sensor_ne: np.ndarray) -> np.ndarray:
        """Range of the nearest shore cell per bearing bin as seen from the radar (inf where no shore).

        A bin also takes its neighbours' minimum, so a wall with a missing cell or two still hides what is behind
        it. Shore cells within shore.margin_m of the radar are ignored: the own boat may lie alongside the quay.
        """
        key = (float(sensor_ne[0]), float(sensor_ne[1]))
        if self._horizon is not None and self._horizon[0] == key:
            return self._horizon[1]  # same shore, radar not moved (a moored boat): same horizon
        n_bins = round(2 * math.pi / self.cfg.shore.horizon_bin_rad)
        horizon = np.full(n_bins, np.inf)
        rel = self.shore_cells() - np.asarray(sensor_ne, float).reshape(2)
        rng = np.hypot(rel[:, 0], rel[:, 1])
        far = rng > self.cfg.shore.margin_m
        np.minimum.at(horizon, self._bearing_bin(rel[far]), rng[far])
        horizon = ndimage.minimum_filter1d(horizon, size=3, mode="wrap")
        horizon.flags.writeable = False  # cached and shared between calls
        self._horizon = (key, horizon)
        return horizon

    def shore_verdict(self, sensor_ne: np.ndarray, clusters: list[np.ndarray]) -> np.ndarray:
        """(k,) int per cluster of (n_i, 2) world points: 0 keep, 1 on the shore, 2 behind it (seen from the radar).

        On: at least shore.on_fraction of its points within shore.margin_m of shore cells. Behind: its centre is
        farther than the shore horizon on its bearing, plus shore.margin_m.
        """
        k = len(clusters)
        verdict = np.zeros(k, np.int8)
        if k == 0 or self._tree is None:
            return verdict
        sizes = np.array([len(c) for c in clusters])
        pts = np.concatenate(clusters) if sizes.sum() else np.empty((0, 2))
        on = self.on_shore(pts).astype(float)
        owner = np.repeat(np.arange(k), sizes)
        frac = np.bincount(owner, weights=on, minlength=k) / np.maximum(sizes, 1)
        verdict[frac >= self.cfg.shore.on_fraction] = 1
        # Behind: farther than the shore seen from the radar on the same bearing (polar "shore horizon").
        horizon = self.shore_horizon(sensor_ne)
        centres = np.stack([np.bincount(owner, weights=pts[:, a], minlength=k) for a in (0, 1)], axis=1)
        rel = centres / np.maximum(sizes, 1)[:, None] - np.asarray(sensor_ne, float).reshape(2)
        b = self._bearing_bin(rel)
        behind = (np.hypot(rel[:, 0], rel[:, 1]) > horizon[b] + self.cfg.shore.margin_m) & (sizes > 0)
        verdict[behind & (verdict == 0)] = 2
        return verdict
