"""Shore seen as a line of static returns over the last half second (not in paper 001; helps its static map).

The static map (``static_map``) calls a structure shore once enough evidence has piled up in its cells. A quay wall
40 m away gives 7-14 returns a frame spread along 25-40 m with a metre of azimuth scatter, and in the simulated paper
scenes the map took 5-10 s to see it; until then wall pieces were tracked as boats. Over half a second the same wall
gives 50-100 returns that link into one long, thin line: at least ``shore.min_extent_m`` along its main axis and at
most ``shore.line_max_thickness_m`` plus ``kalman.position_std_per_m`` per metre of range (azimuth scatter) RMS across
it. Boats are shorter than the extent; sea clutter near the radar links into blobs, not lines; a slow boat's returns in
half a second are a boat-sized patch. Returns on such a line are shore now, whatever the map says yet.

In a rough sea the window's thousands of clutter returns link the walls round the boat into one blob, as long as a
line and far too thick for one. Such a blob is searched again using only its returns away from the boat in places
that returned in more than one frame: a wall returns from the same places frame after frame, clutter lands somewhere
new.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from scipy.spatial import cKDTree

from tracker.grouping import component_labels, group_keys, lowest_to_ranks
from tracker.radar.dbscan import kd_tree


class ShoreLines:
    """Keeps the static returns of the last ``window_s`` and finds the long thin structures among them.

    ``mark`` a frame's static returns first (the detector), ``add`` them once the tracker has left out the returns of
    tracks known to move (a fast boat crossing the line of sight has static-looking Doppler and, over a second or
    two, draws a line of its own)."""

    def __init__(
        self,
        window_s: float,
        link_m: float,
        min_extent_m: float,
        max_thickness_m: float,
        interval_s: float = 0.0,
        thickness_per_m: float = 0.0,
        sensor_ne: np.ndarray | None = None,
        min_frames: int = 1,
        recheck_min_range_m: float = 0.0,
    ) -> None:
        self.window_s = float(window_s)
        self.thickness_per_m = float(thickness_per_m)
        self.sensor_ne = np.zeros(2) if sensor_ne is None else np.asarray(sensor_ne, float)
        self.link_m = float(link_m)
        self.min_extent_m = float(min_extent_m)
        self.max_thickness_m = float(max_thickness_m)
        self.interval_s = float(interval_s)
        self.min_frames = int(min_frames)
        self.recheck_min_range_m = float(recheck_min_range_m)
        self._frames: deque[tuple[float, np.ndarray]] = deque()
        self._t_lines = -np.inf
        self._line_tree: cKDTree | None = None  # returns found on lines at the last full search
        self._deferred = False  # the search due now was put off by a frame already

    def reset(self) -> None:
        self._frames.clear()
        self._t_lines = -np.inf
        self._line_tree = None
        self._deferred = False

    def add(self, t: float, static_ne: np.ndarray) -> None:
        """Remember a frame's static returns (k, 2) world N/E (the tracker leaves out those of moving tracks)."""
        self._frames.append((t, np.asarray(static_ne, float).reshape(-1, 2)))

    def mark(
        self, t: float, static_ne: np.ndarray, sensor_ne: np.ndarray | None = None, defer: bool = False
    ) -> np.ndarray:
        """(k,) bool: which of this frame's static returns (k, 2) lie on a shore line, with the remembered frames.
        ``sensor_ne``: the radar's position now (for the range-dependent thickness). ``defer``: a full search due
        now waits one frame, once (the static map extracted its shore this frame; the two together made the
        slowest frames)."""
        pts = np.asarray(static_ne, float).reshape(-1, 2)
        if sensor_ne is not None:
            self.sensor_ne = np.asarray(sensor_ne, float).reshape(2)
        while self._frames and self._frames[-1][0] > t:  # time went back (a replay restarted)
            self._frames.pop()
        while self._frames and self._frames[0][0] <= t - self.window_s:
            self._frames.popleft()
        on = np.zeros(pts.shape[0], bool)
        if pts.shape[0] == 0:
            return on
        due = not 0 <= t - self._t_lines < self.interval_s
        wait = due and defer and self.interval_s > 0 and not self._deferred
        self._deferred = wait
        if not due or wait:
            # Between full searches: a return within the link distance of a known line return is on the line.
            if self._line_tree is not None:
                dist, _ = self._line_tree.query(pts, k=1, distance_upper_bound=self.link_m)
                on = np.isfinite(dist)
            return on
        self._t_lines = t
        allp = np.concatenate([p for _, p in self._frames] + [pts])
        n = allp.shape[0]
        if n < 3:
            self._line_tree = None
            return on
        on_all, blob = self._on_lines(allp)
        if self.min_frames > 1 and blob.any():
            # In a rough sea the window's thousands of clutter returns can link the walls round the boat into one
            # blob far too thick for a line: its returns in places that recurred are looked at again, away from the
            # boat (where the clutter is dense enough to recur, and its patch drawn out along the course looks long).
            frame = np.repeat(np.arange(len(self._frames) + 1), [len(p) for _, p in self._frames] + [len(pts)])
            far = np.hypot(allp[:, 0] - self.sensor_ne[0], allp[:, 1] - self.sensor_ne[1]) >= self.recheck_min_range_m
            idx = np.flatnonzero(blob & far)
            if idx.size:
                idx = idx[self._recurring(allp[idx], frame[idx])]
            if idx.size >= 3:
                found = idx[self._on_lines(allp[idx])[0]]
                on_all[found] = True
                if found.size:
                    # this frame's returns beside them as between searches (its own cell may not have recurred yet)
                    dist, _ = kd_tree(allp[found]).query(pts, k=1, distance_upper_bound=self.link_m)
                    on_all[n - pts.shape[0] :] |= np.isfinite(dist)
        self._line_tree = kd_tree(allp[on_all]) if on_all.any() else None
        return on_all[n - pts.shape[0] :]

    def _on_lines(self, allp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n,) bool each: the return lies on a line, and on a structure as long as a line but too thick for one."""
        comp = self._components(allp)
        count = np.bincount(comp)
        # Principal axes of every component at once from its first and second moments.
        w = count.astype(float)
        mx = np.bincount(comp, allp[:, 0]) / w
        my = np.bincount(comp, allp[:, 1]) / w
        dx, dy = allp[:, 0] - mx[comp], allp[:, 1] - my[comp]
        sxx = np.bincount(comp, dx * dx) / w
        syy = np.bincount(comp, dy * dy) / w
        sxy = np.bincount(comp, dx * dy) / w
        half_tr, diff = (sxx + syy) / 2, np.hypot((sxx - syy) / 2, sxy)
        minor = np.maximum(half_tr - diff, 0.0)  # variance across the main axis
        theta = 0.5 * np.arctan2(2 * sxy, sxx - syy)  # main axis direction
        along = dx * np.cos(theta[comp]) + dy * np.sin(theta[comp])
        lo = np.full(count.size, np.inf)
        hi = np.full(count.size, -np.inf)
        np.minimum.at(lo, comp, along)
        np.maximum.at(hi, comp, along)
        # Azimuth noise smears a far wall across the line of sight: the allowed thickness grows with range.
        rng = np.hypot(mx - self.sensor_ne[0], my - self.sensor_ne[1])
        thick = self.max_thickness_m + self.thickness_per_m * rng
        long = (count >= 3) & (hi - lo >= self.min_extent_m)
        thin = np.sqrt(minor) <= thick
        return (long & thin)[comp], (long & ~thin)[comp]

    def _recurring(self, pts: np.ndarray, frame: np.ndarray) -> np.ndarray:
        """(n,) bool: the return's link cell (a quarter of the link wide) holds returns of ``min_frames`` frames of the
        window or more. A wall returns from the same places frame after frame; sea clutter lands somewhere new each
        frame."""
        if self.link_m <= 0:
            return np.ones(pts.shape[0], bool)
        of_point = self._link_cells(pts)
        seen = np.unique(of_point * (int(frame.max()) + 1) + frame) // (int(frame.max()) + 1)
        return np.bincount(seen, minlength=int(of_point.max()) + 1)[of_point] >= self.min_frames

    def _components(self, pts: np.ndarray) -> np.ndarray:
        """(n,) component label 0..k-1 of each point, linked at ``link_m``, through "link cells" a quarter of the
        link wide: returns of a wall seen for seconds pile up in the same places, so a few hundred cells stand for
        the window's ~600 returns and their ~7000 linked pairs. Cells link when their centroids are within
        ``link_m`` (the effective link shifts by up to a cell diagonal, 0.35 x link)."""
        if self.link_m <= 0:  # nothing links: every return is its own component
            return np.arange(pts.shape[0])
        of_point = self._link_cells(pts)
        w = np.bincount(of_point).astype(float)
        centroid = np.column_stack([np.bincount(of_point, pts[:, 0]), np.bincount(of_point, pts[:, 1])]) / w[:, None]
        pairs = kd_tree(centroid).query_pairs(self.link_m, output_type="ndarray")
        # numpy component labels, not scipy's sparse connected_components: a few hundred cells and ~2000 pairs cost
        # it less than building the sparse matrix does (same labels, numbered by their lowest cell).
        lowest = component_labels(centroid.shape[0], pairs[:, 0], pairs[:, 1])
        return lowest_to_ranks(lowest)[of_point]

    def _link_cells(self, pts: np.ndarray) -> np.ndarray:
        """(n,) each return's link cell (a quarter of the link wide), numbered 0..k-1 in key order (as np.unique's
        inverse)."""
        cell = np.floor(pts / (self.link_m / 4.0)).astype(np.int64)
        cell -= cell.min(axis=0)
        return group_keys(cell[:, 0] * (int(cell[:, 1].max()) + 1) + cell[:, 1])[3]

    def near(self, points_ne: np.ndarray, margin_m: float) -> np.ndarray:
        """(n,) bool: within ``margin_m`` of a return found on a line at the last full search."""
        pts = np.asarray(points_ne, float).reshape(-1, 2)
        if self._line_tree is None or len(pts) == 0:
            return np.zeros(len(pts), bool)
        dist, _ = self._line_tree.query(pts, k=1, distance_upper_bound=margin_m)
        return np.isfinite(dist)
