"""The 72-bin polar obstacle map that becomes MAVLink OBSTACLE_DISTANCE.

Bins are in the body frame (FRD): bin j is centred on the bearing 5*j degrees clockwise from the bow and spans
+-2.5 degrees (ArduPilot takes element j's angle as j*increment + angle_offset, i.e. the bin centre).

Values follow the message's semantics, which the autopilots act on differently (see specs/mavlink-obstacles.md):
  * an obstacle: its range in cm, clamped to [max(min_distance, 1), max_distance];
  * a bearing where the live sensors vouch that any solid out to max_distance would have been returned, and none
    was: max_distance + 1 ("looked, clear"; tracker/lidar/coverage.py says how far each bearing is vouched for);
  * every other bearing: 65535 ("unknown") — never "clear" where a solid could have gone unseen; but a bin that
    would be unknown beside a solid lying within ``edge_m`` of their shared edge takes that solid's range (its
    bearing at the tick is that uncertain, and ArduPilot reads unknown as nothing there).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

N_BINS = 72
BIN_WIDTH_RAD = 2 * np.pi / N_BINS
UNKNOWN = 65535


@dataclass(frozen=True)
class SensorCoverage:
    """A horizontal wedge a sensor sees, in the body frame: centre bearing (rad, clockwise from the bow),
    full width (rad; 2*pi = all round), and the range out to which "nothing seen" means "clear"."""

    centre: float
    width: float
    max_range: float

    def bins(self) -> np.ndarray:
        """Boolean (72,) mask of bins whose centre lies inside the wedge."""
        if self.width >= 2 * np.pi - 1e-9:
            return np.ones(N_BINS, dtype=bool)
        centres = np.arange(N_BINS) * BIN_WIDTH_RAD
        off = np.angle(np.exp(1j * (centres - self.centre)))
        return np.abs(off) <= self.width / 2 + 1e-9


def bearing_bins(points_fwd_stbd: np.ndarray) -> np.ndarray:
    """Bin index of each (forward, starboard) point: bearing = atan2(starboard, forward), clockwise from the bow."""
    return _bins_of(np.arctan2(points_fwd_stbd[:, 1], points_fwd_stbd[:, 0])).astype(np.int64)


def nearest_per_bin(points_fwd_stbd: np.ndarray, edge_m: float = 0.0) -> np.ndarray:
    """(72,) nearest horizontal range in metres per bin (inf where no point); with ``edge_m``, counting also the
    points of its two neighbours that lie within ``edge_m`` of its edge, across the line of sight."""
    binned = BinnedPoints(points_fwd_stbd)
    nearest = binned.nearest()
    return np.minimum(nearest, binned.beside(edge_m, np.ones(N_BINS, dtype=bool))) if edge_m > 0.0 else nearest


def nearest_beside_edges(points_fwd_stbd: np.ndarray, edge_m: float) -> np.ndarray:
    """(72,) per bin, the nearest horizontal range (m) of the points in its two neighbours that lie within ``edge_m``
    of its edge, across the line of sight; inf where none does."""
    return BinnedPoints(points_fwd_stbd).beside(edge_m, np.ones(N_BINS, dtype=bool))


class BinnedPoints:
    """The finite points of one source (fwd, stbd, m) with their bearing (rad), bin and squared horizontal range,
    computed once: the array, the obstacle memory and its hull returns each ask a tick's solids per bin, and a
    bearing for each of a revolution's 28k returns is the costly part."""

    def __init__(self, points_fwd_stbd: np.ndarray) -> None:
        p = np.asarray(points_fwd_stbd, dtype=float).reshape(-1, 2)
        fwd, stbd, self.r2, index = _finite(p, with_index=True)
        self.points = p if index.size == p.shape[0] else p[index]
        self.angle = np.arctan2(stbd, fwd)
        self.bin = _bins_of(self.angle)

    @classmethod
    def concat(cls, parts: list[BinnedPoints]) -> BinnedPoints:
        """The points of ``parts`` in their order, as one source, without working out a bearing again."""
        out = cls.__new__(cls)
        out.points = np.concatenate([b.points for b in parts]) if parts else np.empty((0, 2))
        out.r2 = np.concatenate([b.r2 for b in parts]) if parts else np.empty(0)
        out.angle = np.concatenate([b.angle for b in parts]) if parts else np.empty(0)
        out.bin = np.concatenate([b.bin for b in parts]) if parts else np.empty(0, dtype=np.int16)
        return out

    def __len__(self) -> int:
        return int(self.r2.size)

    def nearest(self) -> np.ndarray:
        """(72,) nearest range per bin, m; inf where none."""
        out = np.full(N_BINS, np.inf)
        if self.r2.size:
            bins, least = _least_per_bin(self.bin, self.r2)
            out[bins] = np.sqrt(least)
        return out

    def beside(self, edge_m: float, wanted: np.ndarray) -> np.ndarray:
        """(72,) for the ``wanted`` bins, the nearest range of the points in their neighbours lying within ``edge_m``
        of the shared edge, across the line of sight; inf elsewhere. Only points beside a wanted bin are tested."""
        out = np.full(N_BINS, np.inf)
        if edge_m <= 0.0:
            return out
        b = self.bin.astype(np.intp)
        above, below = wanted[(b + 1) % N_BINS], wanted[(b - 1) % N_BINS]
        test = np.flatnonzero(above | below)
        if test.size == 0:
            return out
        angle, r = self.angle[test], np.sqrt(self.r2[test])
        # r * (angle to the edge) is the distance across the line of sight to within 0.03 % (sin x ~ x up to 2.5 deg)
        off = angle - np.rint(angle / BIN_WIDTH_RAD) * BIN_WIDTH_RAD  # from the bin's centre, +-half a bin
        up = above[test] & (r * (BIN_WIDTH_RAD / 2 - off) < edge_m)
        down = below[test] & (r * (BIN_WIDTH_RAD / 2 + off) < edge_m)
        if up.any() or down.any():
            bt = b[test]
            neighbour = np.concatenate([(bt[up] + 1) % N_BINS, (bt[down] - 1) % N_BINS]).astype(np.int16)
            r2 = self.r2[test]
            bins, least = _least_per_bin(neighbour, np.concatenate([r2[up], r2[down]]))
            out[bins] = np.sqrt(least)
        return out


def nearest_and_edge_points_per_bin(points_fwd_stbd: np.ndarray | BinnedPoints, wanted: np.ndarray) -> np.ndarray:
    """(K, 2) for each ``wanted`` (72,) bin that holds a point: its nearest point and its two points nearest its
    edges (least and greatest bearing within it), forward/starboard; the three may be one point. What a bin showed,
    without the thousands of returns behind it: its range and how far across the bin its solid reached."""
    binned = points_fwd_stbd if isinstance(points_fwd_stbd, BinnedPoints) else BinnedPoints(points_fwd_stbd)
    take = wanted[binned.bin]
    if not take.any():
        return np.empty((0, 2))
    index = np.flatnonzero(take)
    b, r2 = binned.bin[index], binned.r2[index]
    # bearing within the bin, from its centre: continuous across the -pi/pi seam of the bin astern
    off = np.remainder(binned.angle[index] - b * BIN_WIDTH_RAD + np.pi, 2 * np.pi) - np.pi
    runs = _BinRuns(b)
    r2_sorted, off_sorted = r2[runs.order], off[runs.order]
    picked = np.concatenate(
        [
            runs.first_at(r2_sorted, np.minimum.reduceat(r2_sorted, runs.starts)),
            runs.first_at(off_sorted, np.minimum.reduceat(off_sorted, runs.starts)),
            runs.first_at(off_sorted, np.maximum.reduceat(off_sorted, runs.starts)),
        ]
    )
    return binned.points[index[runs.order[picked]]]


def _finite(points_fwd_stbd: np.ndarray, with_index: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The forward, starboard and squared horizontal range of the points with a finite position, and (with
    ``with_index``) their indices among all."""
    p = np.asarray(points_fwd_stbd, dtype=float).reshape(-1, 2)
    fwd, stbd = p[:, 0], p[:, 1]
    r2 = fwd * fwd + stbd * stbd
    ok = np.isfinite(r2)
    if ok.all():
        return fwd, stbd, r2, np.arange(r2.size) if with_index else np.empty(0, np.int64)
    index = np.flatnonzero(ok)
    return fwd[index], stbd[index], r2[index], index


def _bins_of(angle: np.ndarray) -> np.ndarray:
    """Bin (0..71, int16) of each bearing (rad, clockwise from the bow, -pi..pi); a NaN bearing's is meaningless
    (the cast's, 0 on x86-64 and arm64): callers that may hold points without a position drop those themselves."""
    with np.errstate(invalid="ignore"):
        b = np.rint(angle / BIN_WIDTH_RAD).astype(np.int16)
    return np.where(b < 0, b + np.int16(N_BINS), b)  # a masked in-place add cost twice as much


class _BinRuns:
    """Points grouped by bin: a stable sort of their 16-bit bin numbers (a radix sort), then reduceat over each bin's
    run, 4x faster than np.minimum.at on a revolution's 29k returns."""

    def __init__(self, b: np.ndarray) -> None:
        self.order = np.argsort(b, kind="stable")
        self.sorted_bins = b[self.order]
        self.starts = np.flatnonzero(np.r_[True, self.sorted_bins[1:] != self.sorted_bins[:-1]])

    def first_at(self, sorted_values: np.ndarray, per_run: np.ndarray) -> np.ndarray:
        """Each run's first place (in the sorted order) holding its run's value ``per_run`` (its minimum, say)."""
        at = np.flatnonzero(sorted_values == np.repeat(per_run, np.diff(np.r_[self.starts, sorted_values.size])))
        return at[np.r_[True, self.sorted_bins[at[1:]] != self.sorted_bins[at[:-1]]]]


def _least_per_bin(b: np.ndarray, r2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The bins holding a point and the least squared horizontal range in each."""
    runs = _BinRuns(b)
    least = np.minimum.reduceat(r2[runs.order], runs.starts)
    return runs.sorted_bins[runs.starts].astype(np.int64), least


# Outline points lie no more than a quarter bin apart as seen from the own boat, so that each bin a hull's side
# overlaps gets a point of that side: at 0.25 m apart, a side 1.5 m off skipped bins, which then took the far side
# of the hull, 2 m further. Never closer than this (a hull over the sensor itself would ask for endless points).
_OUTLINE_MIN_SPACING_M = 0.01


def outline_points(corners_fwd_stbd: np.ndarray, spacing: float = 0.25) -> np.ndarray:
    """Points along a closed polygon (body frame, m), so a hull marks every bin its extent overlaps with its nearest
    side: every ``spacing`` metres, closer on a side near the own boat (a quarter bin's arc at the side's least
    distance from the body origin)."""
    a = corners_fwd_stbd
    b = np.roll(a, -1, axis=0)
    d = b - a
    lengths = np.hypot(*d.T)
    # each side's least distance from the body origin: the foot of the perpendicular, clipped to the side
    along = np.clip(-np.einsum("ij,ij->i", a, d) / np.maximum(lengths**2, 1e-12), 0.0, 1.0)
    least = np.hypot(*(a + d * along[:, None]).T)
    step = np.clip(least * (BIN_WIDTH_RAD / 4.0), _OUTLINE_MIN_SPACING_M, spacing)
    n = np.maximum(np.ceil(lengths / step).astype(int), 1)
    seg = np.repeat(np.arange(len(a)), n)
    frac = np.concatenate([np.arange(k) / k for k in n])
    return a[seg] + (b[seg] - a[seg]) * frac[:, None]


def to_distances_cm(
    nearest_m: np.ndarray, covered: np.ndarray, min_distance_m: float, max_distance_m: float
) -> np.ndarray:
    """Metres per bin + the bins vouched clear -> the uint16 array OBSTACLE_DISTANCE carries: an obstacle wherever
    one was returned within max_distance, else clear where vouched, else unknown."""
    max_cm = round(max_distance_m * 100)
    min_cm = max(round(min_distance_m * 100), 1)
    out = np.full(N_BINS, UNKNOWN, dtype=np.uint16)
    out[covered] = max_cm + 1
    hit = nearest_m <= max_distance_m
    out[hit] = np.clip(np.rint(nearest_m[hit] * 100), min_cm, max_cm).astype(np.uint16)
    return out


def build_obstacle_distances(
    solid_points_fwd_stbd: list[np.ndarray] | list[BinnedPoints],
    clear_to_m: np.ndarray,
    min_distance_m: float,
    max_distance_m: float,
    edge_m: float = 0.0,
) -> np.ndarray:
    """Fuse every source of solid returns (LiDAR points, radar points, track hull outlines, shore) into one array.

    ``clear_to_m`` (72,) says per bin how far out the live sensors vouch that a solid would have been returned; a
    bin with no solid is "clear" (max_distance + 1) only when that reaches max_distance, else "unknown" (65535).
    One message carries everything: ArduPilot resets its whole proximity boundary on each OBSTACLE_DISTANCE, so
    separate partial arrays per sensor would overwrite each other. Each source an (N, 2) array or its
    :class:`BinnedPoints`.
    """
    sources = [
        pts if isinstance(pts, BinnedPoints) else BinnedPoints(np.asarray(pts, float)[:, :2])
        for pts in solid_points_fwd_stbd
        if pts is not None and len(pts)
    ]
    nearest = np.full(N_BINS, np.inf)
    for source in sources:
        nearest = np.minimum(nearest, source.nearest())
    # A returned solid is an obstacle wherever it is, whatever the coverage model says the sensor should see.
    vouched = np.asarray(clear_to_m, float) >= max_distance_m - 1e-6
    fill = ~vouched & ~np.isfinite(nearest)  # the bins that would go out unknown
    if edge_m > 0.0 and sources and fill.any():  # a bin to fill holds no solid of its own: the nearest beside it
        beside = np.min([source.beside(edge_m, fill) for source in sources], axis=0)
        nearest = np.where(fill, beside, nearest)
    return to_distances_cm(nearest, vouched, min_distance_m, max_distance_m)
