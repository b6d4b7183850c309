"""The LiDAR multi-object tracker's cycle (paper Fig. 1): cluster, fit shapes, associate, AEKF, lifecycle.

Pure computation: the caller hands in world-frame points (already through :func:`tracker.lidar.preprocess`),
the scan's time and the own boat's pose; nothing here reads a clock or does I/O.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np
from scipy.spatial import cKDTree

from tracker.assignment import Assignment
from tracker.lidar.association import associate, footprint_covariance
from tracker.lidar.clustering import ClusterResult, cluster_points, shadows
from tracker.lidar.config import LidarTrackerConfig
from tracker.lidar.ekf import (
    HGT,
    LEN,
    OMEGA,
    PE,
    PN,
    PSI,
    VE,
    VN,
    WID,
    EkfBank,
    Measurement,
    measurement_noises,
    prior_beam_would_show,
    visibility,
)
from tracker.lidar.level_returns import LevelRule, horizontal_tops
from tracker.lidar.moored import carve_moored_hulls
from tracker.lidar.settled import box_depths, cut_settled_hulls
from tracker.lidar.shape_fit import (
    DegenerateClusterError,
    ShapeFit,
    cluster_height,
    fit_ellipses,
    fit_lshape_corners,
    fit_shape,
    guard_heading,
    prepare_all,
)
from tracker.lidar.structure import StructureMemory, collinear_runs, structure_lids
from tracker.lifecycle import IdSource, Lifecycle, TrackLife, TrackStatus
from tracker.line_of_sight import in_shadow
from tracker.types import Detection, ShapeKind, Track

# Footprint cells of a cluster the deck rule looks along, at most (LidarTracker._on_deck).
_DECK_CELLS = 32
# A shared cluster is split (LidarTracker._split_shared_detections) when each of two settled tracks' predicted boxes,
# grown by _SPLIT_BOX_GROW_M (a box's edge is good to a few tenths), holds _SPLIT_MIN_CELLS of its footprint cells
# (0.75 m of 0.15 m cells: a buoy's near face), and the two parts lie _SPLIT_MIN_GAP_M apart at their nearest (over
# three cells: water between them, not one hull's returns thinning out).
_SPLIT_BOX_GROW_M = 0.3
_SPLIT_MIN_CELLS = 5
_SPLIT_MIN_GAP_M = 0.5
_MIN_HALF_M = 0.1  # m; a box's half-size below this is taken as this, so a degenerate box has a depth scale
# A track ended in another's shadow (duplicate_shadow_m) whose place keeps starting tracks, each ended the same
# way at most _SHADOW_BIRTH_GAP_S after the last, within _SHADOW_BIRTH_RADIUS_M of it, for duplicate_shadow_settled_s
# is a hull of its own lying there, not a piece of the other (LidarTracker._note_shadow_births).
_SHADOW_BIRTH_GAP_S = 1.0
_SHADOW_BIRTH_RADIUS_M = 1.5
_IN_LINE_MAX_SPEED_DIFF = 0.5  # m/s: two pieces of one hull in line (duplicate_in_line_gap_m) move as one

log = logging.getLogger(__name__)


class LidarTracker:
    """Tracks vessels in LiDAR scans. One instance per sensor; call :meth:`step` once per revolution."""

    def __init__(self, config: LidarTrackerConfig | None = None, ids: IdSource | None = None) -> None:
        self.config = config or LidarTrackerConfig()
        self.lifecycle = Lifecycle(self.config.lifecycle, ids)
        self.bank = EkfBank(self.config.ekf)
        self._lives: list[TrackLife] = []  # parallel to self.bank.filters
        # (t deleted, life, t last seen, centre NE, velocity NE or zeros, half-size): see _remember_lost
        self._lost: list[tuple[float, TrackLife, float, np.ndarray, np.ndarray, float]] = []
        self._last_seen: dict[int, tuple[float, np.ndarray, np.ndarray, float]] = {}  # by track id, see _note_seen
        self._thin_runs: dict[int, int] = {}  # by track id: scans in a row its detection was a thin line in full view
        self._kinds: list[ShapeKind] = []
        self._t: float | None = None
        self.last_clusters: list[np.ndarray] = []  # (n, 3) world NED points per cluster, nearest first
        self.last_cluster_track: list[int | None] = []  # track id each cluster fed, None if none (or structure)
        self.last_detections: list[Detection] = []
        self.stats = {
            "scans": 0,
            "out_of_order": 0,
            "degenerate_clusters": 0,
            "duplicates": 0,
            "reacquired": 0,
            "split_detections": 0,
            "settled_cuts": 0,
        }
        self._cluster_result: ClusterResult | None = None
        self._detection_clusters: list[list[int]] = []  # cluster indices behind each detection
        self.structure = StructureMemory(self.config.structure)
        self._level_rule = LevelRule(min_range_span_m=self.config.structure.level_min_range_span_m)
        self.last_structure = np.zeros(0, dtype=bool)  # per cluster of the last scan: structure, not a vessel
        self._long_hulls: set[int] = set()  # ids of tracks that lost an in-line piece of their hull (_duplicates)
        # places where tracks ended in another's shadow: north, east, first and last time (_duplicates)
        self._shadow_births = np.zeros((0, 4))

    # -- detection ---------------------------------------------------------------------------------------------

    def detect(
        self,
        points_world: np.ndarray,
        t: float,
        own_position: np.ndarray,
        point_times: np.ndarray | None = None,
        sensor_ned: np.ndarray | None = None,
    ) -> list[Detection]:
        """Cluster and fit one scan: one :class:`Detection` per vessel-sized cluster, nearest first.

        ``points_world`` (N, 3) world NED; ``own_position`` the own boat's (north, east) (a 3rd value is ignored).
        ``point_times`` (N,) s, optional: each point's firing time; a detection's ``t`` is then the mean time its
        cluster was swept, else ``t``. Also sets :attr:`last_clusters` (every cluster, structure included) for the
        obstacle map, and :attr:`last_structure`. Does not touch the tracks; remembers where structure was seen.
        ``sensor_ned``: the LiDAR's origin (world NED) for the level-deck rule (tracker.lidar.level_returns); None
        leaves that rule out.
        """
        own = np.asarray(own_position, dtype=float)[:2]
        result = cluster_points(points_world, own, self.config.cluster)
        s = self.config.structure
        result = carve_moored_hulls(
            result,
            points_world,
            own,
            s.moored_min_offset_m,
            s.moored_min_length_m,
            s.moored_gap_m,
            s.moored_face_min_share,
            self.config.cluster.grid_cell,
            s.moored_min_extent_m,
        )
        if s.settled_cut_margin_m >= 0 and self._lives:
            cut = cut_settled_hulls(
                result,
                points_world,
                own,
                self._settled_boxes(),
                s.settled_cut_margin_m,
                s.static_min_length_m,
                self.config.cluster.min_points,
            )
            self.stats["settled_cuts"] += len(cut.clusters) - len(result.clusters)
            result = cut
        self._cluster_result = result
        self.last_clusters = result.clusters
        self.last_cluster_track = [None] * len(result.clusters)
        self._detection_clusters = []
        swept = self._sweep_times(result, point_times, t)
        self.last_structure = self._structure(result, t, own)
        if sensor_ned is not None and self.config.structure.level_min_range_span_m > 0:
            carved = result.carved if result.carved is not None else np.zeros(len(result.clusters), dtype=bool)
            rest = np.flatnonzero(~self.last_structure & ~carved)
            if rest.size:
                decks = horizontal_tops(
                    [result.clusters[k] for k in rest], np.asarray(sensor_ned, float), self._level_rule
                )
                self.last_structure[rest[decks]] = True
        vessels = np.flatnonzero(~self.last_structure)
        footprints = [result.footprints[k] for k in vessels]
        shape = self.config.shape
        # The whole scan's fits as stacked arrays where the fitter has a batch form (same results, less overhead).
        ellipses: list[ShapeFit | DegenerateClusterError | None] = [None] * len(vessels)
        boxes: list[ShapeFit | DegenerateClusterError | None] = [None] * len(vessels)
        prepared = prepare_all(footprints)
        if shape.mode in ("adaptive", "ellipse"):
            ellipses = list(fit_ellipses(footprints, prepared))
        if shape.mode == "lshape-corner" or (shape.mode == "adaptive" and shape.lshape_method == "corner"):
            boxes = list(fit_lshape_corners(footprints, shape.corner_min_offset, prepared))
        fits = self.fit_footprints(
            footprints, own, ellipses, [box if isinstance(box, ShapeFit) else None for box in boxes], prepared
        )
        heights = self._cluster_heights([result.clusters[k] for k in vessels])
        ranges = self._fit_ranges(fits, own)
        detections = []
        for j, k in enumerate(vessels):
            fit = fits[j]
            if isinstance(fit, DegenerateClusterError):
                self._degenerate(fit, int(k))
                continue
            cluster = result.clusters[k]
            detections.append(
                self._detection_of(fit, footprints[j], float(swept[k]), heights[j], ranges[j], len(cluster))
            )
            self._detection_clusters.append([k])
        self.last_detections = detections
        return detections

    @staticmethod
    def _cluster_heights(clusters: list[np.ndarray]) -> list[float]:
        """:func:`cluster_height` of each cluster, as one reduceat over their stacked heights (cluster_points keeps
        only finite points; anything else goes cluster by cluster)."""
        sizes = np.array([len(c) for c in clusters], dtype=np.int64)
        if sizes.size == 0 or not sizes.all():
            return [cluster_height(c[:, 2]) for c in clusters]
        z = np.concatenate([c[:, 2] for c in clusters])
        if not np.isfinite(z).all():
            return [cluster_height(c[:, 2]) for c in clusters]
        starts = np.cumsum(sizes) - sizes
        return (np.maximum.reduceat(z, starts) - np.minimum.reduceat(z, starts)).tolist()

    @staticmethod
    def _fit_ranges(fits: list[ShapeFit | DegenerateClusterError], own: np.ndarray) -> list[float]:
        """Each fit's centre's horizontal distance from ``own`` (NaN for a degenerate one), in one np.hypot."""
        centers = np.array([fit.center if isinstance(fit, ShapeFit) else (np.nan, np.nan) for fit in fits])
        if centers.size == 0:
            return []
        d = centers.reshape(-1, 2) - own
        return np.hypot(d[:, 0], d[:, 1]).tolist()

    def _degenerate(self, fit: DegenerateClusterError, k: int) -> None:
        self.stats["degenerate_clusters"] += 1
        log.debug("cluster %d skipped: %s", k, fit)

    @staticmethod
    def _detection_of(
        fit: ShapeFit, footprint: np.ndarray, t: float, height: float, range_m: float, n_points: int
    ) -> Detection:
        return Detection(
            t=t,
            center=fit.center,
            heading=fit.heading,
            length=fit.length,
            width=fit.width,
            height=height,
            shape=fit.kind,
            mse=fit.mse,
            n_points=n_points,
            range_m=range_m,
            points=footprint,
            source="lidar",
        )

    def _structure(self, result: ClusterResult, t: float, own: np.ndarray) -> np.ndarray:
        """(k,) bool: clusters that are structure - too big for a vessel, or lying mostly where structure was seen
        (a piece of a quay wall cut off by a shadow; tracker.lidar.structure)."""
        cfg = self.config.structure
        big = np.asarray(result.oversized, dtype=bool).copy()
        if cfg.memory_s <= 0 or big.size == 0:
            return big
        self.structure.follow(own)
        if big.any():
            self._remember_structure(t, result, np.flatnonzero(big), own)
        # A hull carved off a wall stands in front of its face: where the memory has wall there, it is from a scan
        # whose hull and wall had merged; and its side runs along the wall's line without being the wall.
        carved = result.carved if result.carved is not None else np.zeros(big.size, dtype=bool)
        if carved.any():  # a scan whose hull and wall merge must not make the hull structure for memory_s
            self.structure.remember_hull(t, np.concatenate([result.footprints[k] for k in np.flatnonzero(carved)]))
        small = np.flatnonzero(~big & ~carved)
        if small.size:  # every cluster's footprint in one lookup, the share per cluster by reduceat
            sizes = np.array([len(result.footprints[k]) for k in small])
            known = self.structure.known(t, np.concatenate([result.footprints[k] for k in small]))
            share = np.add.reduceat(known.astype(float), np.cumsum(sizes) - sizes) / np.maximum(sizes, 1)
            big[small] = (sizes > 0) & (share >= cfg.min_fraction)
            on_structure = small[big[small]]
            if on_structure.size and cfg.taller_margin_m >= 0:
                big[on_structure] = ~self._above(result, on_structure, self._lids_under(t, result, on_structure))
            big[self._on_deck(result, small[~big[small]], t, own)] = True
        # A thin piece continuing a remembered wall along its line, then one meeting a wall's end across it (a
        # quay's end face): each found wall is remembered in turn, so a wall seen piece by piece is followed.
        for wall_rule in (self.structure.continues, self.structure.wall_ends):
            rest = np.flatnonzero(~big & ~carved)
            if rest.size:
                walls, wall_lids = wall_rule(t, [result.footprints[k] for k in rest], own)
                candidates = np.flatnonzero(walls)
                if candidates.size and cfg.taller_margin_m >= 0:  # a boat's side standing above the wall is no wall
                    walls[candidates] = ~self._above(result, rest[candidates], wall_lids[candidates])
                if walls.any():
                    big[rest[walls]] = True
                    self._remember_structure(t, result, rest[walls], own, wall_lids[walls])
        rest = np.flatnonzero(~big & ~carved)
        if cfg.run_min_pieces > 0 and rest.size >= cfg.run_min_pieces:  # a wall in pieces the memory did not place
            runs = collinear_runs(
                [result.footprints[k] for k in rest],
                self.config.cluster.max_extent,
                cfg.line_max_thickness_m,
                cfg.short_line_min_length_m,
                cfg.run_min_pieces,
            )
            walls = rest[runs]
            if walls.size:  # remembered, so the wall-line rule follows the wall from here
                big[walls] = True
                self._remember_structure(t, result, walls, own)
        return big

    def _on_deck(self, result: ClusterResult, ks: np.ndarray, t: float, own: np.ndarray) -> np.ndarray:
        """The clusters of ``ks`` on a remembered quay's deck or the land behind its face: at least
        ``min_fraction`` of the footprint on remembered cells or behind them, its line of sight from the own boat
        having crossed remembered structure within ``deck_depth_m`` in front of it, and standing no higher than
        that structure's lid (``_above``). As the boat pitches, beams that pass over a quay's edge meet its deck,
        a few metres behind the face the memory holds; a hull moored in front of the face is not behind it."""
        cfg = self.config.structure
        if cfg.deck_depth_m <= 0 or ks.size == 0:
            return ks[:0]
        # Up to _DECK_CELLS cells a cluster, evenly spread: the share is what counts, and each cell's line of sight
        # is a few dozen lookups.
        picks = [result.footprints[k][:: -(-len(result.footprints[k]) // _DECK_CELLS)] for k in ks]
        sizes = np.array([len(p) for p in picks])
        starts = np.cumsum(sizes) - sizes
        cells = np.concatenate(picks)
        lid_front = self.structure.lid_in_front(t, cells, own, cfg.deck_depth_m)
        on = self.structure.known(t, cells) | np.isfinite(lid_front)
        found = np.add.reduceat(on.astype(float), starts) >= cfg.min_fraction * sizes
        decks = ks[found]
        if decks.size == 0 or cfg.taller_margin_m < 0:
            return decks
        lids = np.minimum(self._lids_under(t, result, decks), np.minimum.reduceat(lid_front, starts)[found])
        return decks[~self._above(result, decks, lids)]

    def _remember_structure(
        self, t: float, result: ClusterResult, ks: np.ndarray, own: np.ndarray, known_lids: np.ndarray | None = None
    ) -> None:
        """Remember clusters ``ks`` of ``result`` as structure seen at ``t``, each with its lid, but none higher
        than ``known_lids`` (the structure it was found to belong to; inf: none known)."""
        lids = structure_lids([result.clusters[k] for k in ks], own, self.config.structure.lid_bin_m)
        if known_lids is not None:
            lids = np.where(np.isfinite(known_lids), np.maximum(lids, known_lids), lids)
        sizes = [len(result.footprints[k]) for k in ks]
        self.structure.remember(t, np.concatenate([result.footprints[k] for k in ks]), np.repeat(lids, sizes))

    def _lids_under(self, t: float, result: ClusterResult, ks: np.ndarray) -> np.ndarray:
        """(len(ks),) the highest lid remembered on or next to each cluster's footprint (inf: none), one lookup."""
        sizes = np.array([len(result.footprints[k]) for k in ks])
        lids = self.structure.lids_at(t, np.concatenate([result.footprints[k] for k in ks]))
        return np.minimum.reduceat(lids, np.cumsum(sizes) - sizes)

    def _above(self, result: ClusterResult, ks: np.ndarray, lids: np.ndarray) -> np.ndarray:
        """(len(ks),) bool: at least ``taller_min_share`` of cluster k's returns stand more than ``taller_margin_m``
        above ``lids[k]`` (world down, m): a cabin, not a stray return or two above a quay's edge."""
        cfg = self.config.structure
        sizes = np.array([len(result.clusters[k]) for k in ks])
        z = np.concatenate([result.clusters[k][:, 2] for k in ks])
        above = (z < np.repeat(lids - cfg.taller_margin_m, sizes)).astype(float)
        return np.add.reduceat(above, np.cumsum(sizes) - sizes) >= cfg.taller_min_share * sizes

    @staticmethod
    def _sweep_times(result: ClusterResult, point_times: np.ndarray | None, t: float) -> np.ndarray:
        """Mean firing time of each cluster's points (``t`` for all without point times or on a size mismatch)."""
        k = len(result.clusters)
        if point_times is None or k == 0:
            return np.full(k, t)
        times = np.asarray(point_times, dtype=float).ravel()
        if times.shape[0] != result.labels.shape[0]:
            log.warning("point_times has %d entries for %d points: ignored", times.shape[0], result.labels.shape[0])
            return np.full(k, t)
        inside = (result.labels >= 0) & np.isfinite(times)
        counts = np.bincount(result.labels[inside], minlength=k)
        sums = np.bincount(result.labels[inside], weights=times[inside], minlength=k)
        return np.where(counts > 0, sums / np.maximum(counts, 1), t)

    def _fit_cluster(
        self,
        cluster: np.ndarray,
        footprint: np.ndarray,
        t: float,
        own: np.ndarray,
        k: int,
        ellipse: ShapeFit | DegenerateClusterError | None = None,
        box: ShapeFit | None = None,
    ) -> Detection | None:
        try:
            fit: ShapeFit | DegenerateClusterError = self.fit_footprint(footprint, own, ellipse, box)
        except DegenerateClusterError as exc:
            fit = exc
        return self._detection(cluster, footprint, fit, t, own, k)

    def _detection(
        self,
        cluster: np.ndarray,
        footprint: np.ndarray,
        fit: ShapeFit | DegenerateClusterError,
        t: float,
        own: np.ndarray,
        k: int,
    ) -> Detection | None:
        """The detection of cluster ``k`` from its ``fit`` (None, counted, for a degenerate one)."""
        if isinstance(fit, DegenerateClusterError):
            self._degenerate(fit, k)
            return None
        range_m = float(np.hypot(*(fit.center - own)))
        return self._detection_of(fit, footprint, t, cluster_height(cluster[:, 2]), range_m, len(cluster))

    def fit_footprint(
        self,
        footprint: np.ndarray,
        own: np.ndarray,
        ellipse: ShapeFit | DegenerateClusterError | None = None,
        box: ShapeFit | None = None,
    ) -> ShapeFit:
        """The shape a detection reports for one cluster's (n, 2) footprint seen from ``own`` (north, east).

        The configured fit (paper sec. 2.2-2.3), then, as configured, the heading guard. Raises
        :class:`DegenerateClusterError` for a footprint without finite points.
        """
        fit = self.fit_footprints([footprint], own, [ellipse], [box])[0]
        if isinstance(fit, DegenerateClusterError):
            raise fit
        return fit

    def fit_footprints(
        self,
        footprints: list[np.ndarray],
        own: np.ndarray,
        ellipses: list[ShapeFit | DegenerateClusterError | None],
        boxes: list[ShapeFit | None],
        prepared: list[tuple[np.ndarray, np.ndarray] | DegenerateClusterError] | None = None,
    ) -> list[ShapeFit | DegenerateClusterError]:
        """:meth:`fit_footprint` for each footprint (the error it would raise in place of a fit). ``prepared``:
        :func:`prepare_all` of the footprints."""
        fits: list[ShapeFit | DegenerateClusterError] = []
        ready = prepared if prepared is not None else [None] * len(footprints)
        for footprint, ellipse, box, prep in zip(footprints, ellipses, boxes, ready, strict=True):
            centred = prep if isinstance(prep, tuple) else None
            try:
                fits.append(self._guarded_fit(footprint, own, ellipse, box, centred))
            except DegenerateClusterError as exc:
                fits.append(exc)
        return fits

    def _guarded_fit(
        self,
        footprint: np.ndarray,
        own: np.ndarray,
        ellipse: ShapeFit | DegenerateClusterError | None,
        box: ShapeFit | None,
        prepared: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> ShapeFit:
        """The configured fit, then the heading guard if configured (on ``prepared`` points if given)."""
        cfg = self.config.shape
        fit = fit_shape(footprint, cfg, sensor_position=own, ellipse=ellipse, box=box)
        if cfg.heading_guard and fit.mse > cfg.guard_min_mse:
            fit = guard_heading(fit, footprint, prepared=prepared)
        return fit

    def _split_shared_detections(self, detections: list[Detection], own: np.ndarray) -> list[Detection]:
        """Split each detection whose footprint holds a small settled track and one bigger settled track, in parts a
        clear gap apart, into one detection per track (``AssociationConfig.split_small_max_m``).

        Each footprint cell and each return goes to the track in whose predicted box it lies deepest. A hull whose
        returns run on without a gap is never split, so two tracks on one long hull (a ship first seen as bow and
        stern) are left to the duplicate tests."""
        cfg = self.config.association
        if cfg.split_small_max_m <= 0 or not detections:
            return detections
        settled = [
            i for i, life in enumerate(self._lives) if life.confirmed and life.age >= cfg.duplicate_shadow_settled_s
        ]
        if len(settled) < 2:
            return detections
        x = self.bank.states()[settled]
        small = np.maximum(x[:, LEN], x[:, WID]) <= cfg.split_small_max_m
        if small.all() or not small.any():
            return detections
        # Only a detection reaching a small track's grown box can hold it: the rest are not looked at cell by cell.
        centres = np.array([d.center for d in detections], dtype=float).reshape(-1, 2)
        reach = 0.5 * np.hypot([d.length for d in detections], [d.width for d in detections])
        small_reach = 0.5 * np.hypot(x[small, LEN], x[small, WID]) + _SPLIT_BOX_GROW_M
        apart = centres[:, None, :] - x[None, small][..., [PN, PE]]
        near = np.flatnonzero(
            (np.hypot(apart[..., 0], apart[..., 1]) <= reach[:, None] + small_reach[None, :]).any(axis=1)
        )
        if near.size == 0:
            return detections
        nearby = [detections[j] for j in near.tolist()]
        sizes = np.array([len(d.points) for d in nearby])
        starts = np.cumsum(sizes) - sizes
        depth = box_depth(np.concatenate([d.points[:, :2] for d in nearby]), x)  # (cells, tracks)
        grown = 1.0 + _SPLIT_BOX_GROW_M / np.maximum(0.5 * np.minimum(x[:, LEN], x[:, WID]), _MIN_HALF_M)
        held = np.add.reduceat((depth <= grown).astype(np.int64), starts, axis=0) >= _SPLIT_MIN_CELLS  # (D, T)
        shared = np.flatnonzero((held.sum(axis=1) == 2) & (held & small).any(axis=1) & (held & ~small).any(axis=1))
        if shared.size == 0:
            return detections
        pieces_of: dict[int, list[Detection]] = {}
        for n in shared.tolist():  # few: a small track beside a bigger one
            j, det = int(near[n]), detections[int(near[n])]
            k = self._detection_clusters[j][0]
            owners = np.flatnonzero(held[n])
            cell_owner = np.argmin(depth[starts[n] : starts[n] + sizes[n]][:, owners], axis=1)
            point_owner = np.argmin(box_depth(self.last_clusters[k][:, :2], x[owners]), axis=1)
            cells = [det.points[cell_owner == o] for o in range(2)]
            points = [self.last_clusters[k][point_owner == o] for o in range(2)]
            if min(len(c) for c in cells) < _SPLIT_MIN_CELLS or min(len(p) for p in points) == 0:
                continue
            if _least_gap(cells[0], cells[1]) < _SPLIT_MIN_GAP_M:
                continue
            pieces = [self._fit_cluster(points[o], cells[o], det.t, own, k) for o in range(2)]
            if all(piece is not None for piece in pieces):  # never lose a detection to a bad split
                pieces_of[j] = [piece for piece in pieces if piece is not None]
        if not pieces_of:
            return detections
        self.stats["split_detections"] += len(pieces_of)
        out: list[Detection] = []
        clusters_out: list[list[int]] = []
        for j, det in enumerate(detections):
            parts = pieces_of.get(j, [det])
            out.extend(parts)
            clusters_out.extend([self._detection_clusters[j]] * len(parts))
        self._detection_clusters = clusters_out
        return out

    def _merge_split_detections(self, detections: list[Detection], t: float, own: np.ndarray) -> list[Detection]:
        """Refit as one the detections that lie inside one confirmed track's predicted footprint and no other's.

        A boat passing in front of another casts a shadow across its hull, and the far hull falls apart into two
        clusters; left alone, one piece would keep the track and the other start a new one.
        """
        confirmed = [i for i, life in enumerate(self._lives) if life.confirmed]
        if len(detections) < 2 or not confirmed:
            return detections
        x = self.bank.states()[confirmed]
        centers = np.array([d.center for d in detections])
        rel = centers[None, :, :] - x[:, None, [PN, PE]]  # (T, D, 2)
        c, s = np.cos(x[:, PSI])[:, None], np.sin(x[:, PSI])[:, None]
        along = np.abs(rel[..., 0] * c + rel[..., 1] * s)
        across = np.abs(rel[..., 1] * c - rel[..., 0] * s)
        margin = self.config.association.merge_margin
        inside = (along <= 0.5 * x[:, [LEN]] + margin) & (across <= 0.5 * x[:, [WID]] + margin)
        exclusive = inside & (inside.sum(axis=0) == 1)[None, :]
        merged_into: dict[int, list[int]] = {}
        for row in np.flatnonzero(exclusive.sum(axis=1) >= 2):
            merged_into[int(row)] = np.flatnonzero(exclusive[row]).tolist()
        if not merged_into:
            return detections
        result = self._cluster_result
        assert result is not None  # set by detect()
        used = {d for group in merged_into.values() for d in group}
        out = [d for i, d in enumerate(detections) if i not in used]
        clusters_out = [k for i, k in enumerate(self._detection_clusters) if i not in used]
        for group in merged_into.values():
            members = [k for d in group for k in self._detection_clusters[d]]
            points = np.concatenate([self.last_clusters[k] for k in members])
            footprint = np.concatenate([result.footprints[k] for k in members])
            swept = float(np.mean([detections[d].t for d in group]))
            det = self._fit_cluster(points, footprint, swept, own, members[0])
            if det is None:  # cannot happen for merged non-empty clusters, but never lose the pieces
                out.extend(detections[d] for d in group)
                clusters_out.extend(self._detection_clusters[d] for d in group)
                continue
            out.append(det)
            clusters_out.append(members)
        self._detection_clusters = clusters_out
        return out

    def measurements(
        self, detections: list[Detection], own_position: np.ndarray, own_yaw: float, occluded: list[bool]
    ) -> list[Measurement]:
        """Every detection with its eq. 11 covariance from its eq. 10 visibility, computed as one stack."""
        cfg = self.config.ekf
        own = np.asarray(own_position, dtype=float)[:2]
        p_vis = []
        for det, occ in zip(detections, occluded, strict=True):
            if cfg.aspect_reference == "sensor_heading":
                reference = own_yaw
            else:
                d = det.center - own
                reference = math.atan2(d[1], d[0])
            aspect = det.heading - reference
            p_vis.append(visibility(det.range_m, det.mse, aspect, cfg, occ, use_aspect=not cfg.view_aware))
        r = measurement_noises(np.array(p_vis), cfg) if detections else np.zeros((0, 6, 6))
        return [
            Measurement(
                det.center,
                det.heading,
                det.length,
                det.width,
                det.height,
                det.shape,
                r[j],
                own.copy(),
            )
            for j, det in enumerate(detections)
        ]

    # -- the cycle ---------------------------------------------------------------------------------------------

    def step(
        self,
        points_world: np.ndarray,
        t: float,
        own_position: np.ndarray,
        own_yaw: float = 0.0,
        point_times: np.ndarray | None = None,
        sensor_ned: np.ndarray | None = None,
    ) -> list[Track]:
        """Process one scan taken at ``t`` (s); returns every live track (``Track.confirmed`` tells which count).

        ``points_world`` (N, 3) world NED, from :func:`tracker.lidar.preprocess.preprocess`; ``own_position``
        (2,) or (3,) NED of the own boat; ``own_yaw`` rad (used only with ``EkfConfig.aspect_reference =
        "sensor_heading"``). ``point_times`` (N,) s, optional, each point's firing time (``LidarScan.t`` of the
        kept points): a moving boat's detection is then moved by its track's velocity from when it was swept to
        ``t`` (``EkfConfig.compensate_sweep``); without them the whole revolution counts as seen at ``t``, which
        puts a 5 m/s boat up to 0.5 m behind. A scan older than the previous one is ignored (counted in
        ``stats["out_of_order"]``). ``sensor_ned``: the LiDAR's origin, world NED (see :meth:`detect`).
        """
        if self._t is not None and t < self._t:
            self.stats["out_of_order"] += 1
            log.warning("lidar scan at t=%.3f is older than the last one (t=%.3f): skipped", t, self._t)
            return self.tracks()
        dt = 0.0 if self._t is None else t - self._t
        self._t = t
        self.stats["scans"] += 1
        own = np.asarray(own_position, dtype=float)[:2]

        self.bank.predict(dt)
        detections = self._split_shared_detections(self.detect(points_world, t, own, point_times, sensor_ned), own)
        detections = self._merge_split_detections(detections, t, own)
        self.last_detections = detections
        margin, result = self.config.cluster.occlusion_margin, self._cluster_result
        assert result is not None  # set by detect()
        min_points = self.config.cluster.occluder_min_points
        groups = self._detection_clusters
        occluded = shadows(groups, result, margin, min_points=min_points).touched.tolist()
        measurements = self.measurements(detections, own, own_yaw, occluded)
        if any(occluded):  # which of their ends the shadows reach (EkfBank._view_aware_plan)
            # only another hull's shadow: an occluder nearer than this one's whole depth along the line of sight
            depth = np.array([np.ptp(np.hypot(*(det.points[:, :2] - own).T)) + 1.0 for det in detections])
            ends = shadows(groups, result, margin, depth=depth, min_points=min_points)
            for j in np.flatnonzero(occluded).tolist():
                shadowed = (bool(ends.low_end[j]), bool(ends.high_end[j]))
                measurements[j] = dataclasses.replace(measurements[j], shadowed=shadowed)
        assignment = self._associate(measurements)
        alone = self._alone(t, detections, assignment)

        self.bank.update_many(
            [(int(ti), self._swept(measurements[di], t - detections[di].t)) for ti, di in assignment.matches]
        )
        # after the update: where each hit track is seen, with its velocity if known (for reacquisition)
        known = self._velocity_known(self.bank.covariances()) if self._lives else np.zeros(0, dtype=bool)
        self._note_seen(t, [int(ti) for ti, _ in assignment.matches], known)
        for ti, di in assignment.matches:
            self._lives[ti].hit(t, alone=bool(alone[di]))
            self._kinds[ti] = measurements[di].kind
            tid = self._lives[ti].id
            self._thin_runs[tid] = self._thin_runs.get(tid, 0) + 1 if self._thin_line(measurements[di]) else 0
            for k in self._detection_clusters[di]:
                self.last_cluster_track[k] = self._lives[ti].id
        for ti in assignment.unmatched_rows:
            self._lives[ti].miss(t)
        lapsed = [i for i, life in enumerate(self._lives) if not life.alive]
        self._remember_lost(t, lapsed)
        dead = lapsed + self._static_structure(t, own)
        dead += self._duplicates(set(dead), own, known)
        dead = sorted(set(dead))
        if dead:
            self.bank.remove(dead)
            dead_set = set(dead)
            for i in dead:
                self._last_seen.pop(self._lives[i].id, None)
                self._thin_runs.pop(self._lives[i].id, None)
            self._lives = [life for i, life in enumerate(self._lives) if i not in dead_set]
            self._kinds = [k for i, k in enumerate(self._kinds) if i not in dead_set]
        for di in assignment.unmatched_cols:
            self.bank.add(measurements[di])
            life = self._reacquired(t, measurements[di]) or self.lifecycle.start(t, alone=bool(alone[di]))
            self._lives.append(life)
            self._kinds.append(measurements[di].kind)
            for k in self._detection_clusters[di]:
                self.last_cluster_track[k] = life.id
        return self.tracks()

    def _alone(self, t: float, detections: list[Detection], assignment: Assignment) -> np.ndarray:
        """(D,) bool: within ``association.alone_m`` of the detection's centre lies no live track's predicted centre
        (other than the one the detection updates) and no structure remembered (tracker.lidar.structure): where
        the false tracks are born, beside a hull and along a quay (LidarLifecycleConfig.confirm_hits_alone).
        Asked only for detections that start a track or hit a tentative one (False for the rest): a confirmed
        track's lifecycle does not read it, and the structure lookup is a 10 m disc of cells per detection."""
        radius = self.config.association.alone_m
        out = np.zeros(len(detections), dtype=bool)
        if radius <= 0 or not detections or self.config.lifecycle.confirm_hits_alone <= 0:
            return out
        own_track = np.full(len(detections), -1)  # the track each detection updates, -1 for none
        for ti, di in assignment.matches:
            own_track[di] = ti
        tentative = np.array([life.status is TrackStatus.TENTATIVE for life in self._lives] + [True])
        idx = np.flatnonzero(tentative[own_track])  # index -1 (no track) reads the trailing True
        if not idx.size:
            return out
        centres = np.array([detections[i].center for i in idx], dtype=float).reshape(-1, 2)
        alone = np.ones(idx.size, dtype=bool)
        if self._lives:
            gap = centres[:, None, :] - self.bank.states()[None, :, [PN, PE]]  # (asked, T, 2)
            near = np.hypot(gap[..., 0], gap[..., 1]) <= radius
            mine = own_track[idx] >= 0  # a detection's own track is not another one near it
            near[np.flatnonzero(mine), own_track[idx][mine]] = False
            alone = ~near.any(axis=1)
        if alone.any() and self.config.structure.memory_s > 0:
            alone[alone] = ~self.structure.near(t, centres[alone], radius)
        out[idx] = alone
        return out

    def _note_seen(self, t: float, matched: list[int], known: np.ndarray) -> None:
        """Where each track of ``matched`` was seen at ``t``, its velocity then if ``known`` (T,) says it is known
        (else zeros), its half-size: what ``_reacquired`` predicts from once the track is lost."""
        if self.config.association.reacquire_s <= 0 or not matched:
            return
        x = self.bank.states()
        for i in matched:
            velocity = x[i, [VN, VE]] if known[i] else np.zeros(2)
            self._last_seen[self._lives[i].id] = (t, x[i, [PN, PE]], velocity, 0.5 * max(x[i, LEN], x[i, WID]))

    def _remember_lost(self, t: float, lapsed: list[int]) -> None:
        """Keep the confirmed tracks among ``lapsed`` (deleted by their lifecycle) for ``reacquire_s``."""
        self._lost = [lost for lost in self._lost if t - lost[0] <= self.config.association.reacquire_s]
        for i in lapsed:
            life = self._lives[i]
            seen = self._last_seen.get(life.id)
            if life.ever_confirmed and seen is not None:
                self._lost.append((t, life, *seen))

    def _reacquired(self, t: float, m: Measurement) -> TrackLife | None:
        """The lost track (``_remember_lost``) whose centre, carried on from where it was last seen at its
        velocity then, lies nearest ``m``'s, within its half-size plus ``reacquire_margin_m``; confirmed again with
        its id. None if there is none."""
        best, best_d = None, math.inf
        for k, (_, _, t_seen, centre, velocity, half) in enumerate(self._lost):
            d = float(np.hypot(*(m.center - (centre + velocity * (t - t_seen)))))
            if d <= half + self.config.association.reacquire_margin_m and d < best_d:
                best, best_d = k, d
        if best is None:
            return None
        life = self._lost.pop(best)[1]
        life.reacquire(t)
        self.stats["reacquired"] += 1
        return life

    def _static_structure(self, t: float, own: np.ndarray) -> list[int]:
        """Tracks that are quay, not vessel: confirmed, at least ``static_min_length_m`` long, at least
        ``static_min_age_s`` old and no faster than ``static_max_speed_mps`` now. Their clusters are remembered as
        structure (so the next pieces of the same wall get no track either) and the tracks end. On the tuning scenes
        a 25-45 m stretch of quay with the land behind it was tracked as a "vessel" moving at its changing ends'
        0.1-0.8 m/s, most of the false track-frames; no vessel that size lies still in a harbour's fairway, and a
        moored ship stays an obstacle in the array, built from its returns. A ship under way whose speed the track
        underestimates (its visible extent growing as it comes into view) is ended too: see Known limitations."""
        cfg = self.config.structure
        if cfg.static_min_length_m <= 0 or cfg.memory_s <= 0 or self._cluster_result is None:
            return []
        if not self._lives:
            return []
        x = self.bank.states()
        still = self._structure_sized(x) & (np.hypot(x[:, VN], x[:, VE]) <= cfg.static_max_speed_mps)
        out = []
        for i in np.flatnonzero(still).tolist():
            life = self._lives[i]
            if life.confirmed and life.age >= cfg.static_min_age_s:
                out.append(i)
                mine = [k for k, tid in enumerate(self.last_cluster_track) if tid == life.id]
                if mine:  # the track may have taken a boat moored by the quay this scan: it lends no cabin to the quay
                    ks = np.array(mine)
                    self._remember_structure(
                        t, self._cluster_result, ks, own, self._lids_under(t, self._cluster_result, ks)
                    )
        return out

    def _settled_boxes(self) -> np.ndarray:
        """(B, 5) predicted boxes (north, east, heading, length, width) of the confirmed tracks lying still
        (``static_max_speed_mps``) for ``static_min_age_s``, at least ``settled_cut_min_length_m`` and less than
        ``static_min_length_m`` long: vessels whose hull does not grow (tracker.lidar.settled)."""
        cfg = self.config.structure
        x = self.bank.states()
        still = (
            ~self._structure_sized(x)
            & (np.maximum(x[:, LEN], x[:, WID]) >= cfg.settled_cut_min_length_m)
            & (np.hypot(x[:, VN], x[:, VE]) <= cfg.static_max_speed_mps)
        )
        settled = [
            i
            for i in np.flatnonzero(still).tolist()
            if self._lives[i].confirmed and self._lives[i].age >= cfg.static_min_age_s
        ]
        return x[settled][:, [PN, PE, PSI, LEN, WID]]

    def _structure_sized(self, x: np.ndarray) -> np.ndarray:
        """(T,) bool for states ``x`` (T, DIM_X): at least ``static_min_length_m`` long or wide."""
        return np.maximum(x[:, LEN], x[:, WID]) >= self.config.structure.static_min_length_m

    def _duplicates(self, dying: set[int], own: np.ndarray, known: np.ndarray) -> list[int]:
        """Tracks that share a hull with a confirmed track: of each pair where either centre lies in the other's
        footprint or in its shadow seen from ``own`` (``duplicate_shadow_m``), where one whose velocity is not
        ``known`` lies off the other's bow or stern while that one moves (``duplicate_end_gap_m``), or where one
        no bigger than a piece (``duplicate_piece_max_half_m``) touches the other's footprint, the one with fewer
        hits.

        A hull seen end-on shows a short face, and its far end or superstructure can come back as a second cluster
        beyond it that no merge gate reaches; that cluster starts a track, and the two then share the hull's
        detections between them and both live on as two "vessels" in one place. Either can come first: a piece of
        a far hull (its end, its cabin) is often tracked before the whole hull comes back around it. A piece is
        caught within seconds of its birth, so two tracks both older than ``duplicate_shadow_settled_s`` are no
        pair by the shadow or the touch alone (two boats at anchor that the own boat's motion brings into line).
        Where tracks started at one place have kept ending in an old track's shadow for that long, the next one
        there counts as old for the shadow test: a boat at anchor beyond another."""
        cfg = self.config.association
        n = len(self._lives)
        if cfg.duplicate_margin < 0 or n < 2:
            return []
        x = self.bank.states()
        confirmed = np.array([life.confirmed for life in self._lives])
        hits = np.array([life.hits for life in self._lives])
        rel = x[None, :, [PN, PE]] - x[:, None, [PN, PE]]  # (host T, guest T, 2): guest centre from host centre
        c, s = np.cos(x[:, PSI])[:, None], np.sin(x[:, PSI])[:, None]
        along = np.abs(rel[..., 0] * c + rel[..., 1] * s)
        across = np.abs(rel[..., 1] * c - rel[..., 0] * s)
        beside = across <= 0.5 * x[:, [WID]] + cfg.duplicate_margin  # within the host's beam, plus the margin
        inside = (along <= 0.5 * x[:, [LEN]] + cfg.duplicate_margin) & beside
        overlap = inside | inside.T
        velocity = x[:, [VN, VE]]
        speed = np.hypot(velocity[:, 0], velocity[:, 1])
        moving = known & (speed >= cfg.duplicate_end_min_speed_mps)
        dv = np.linalg.norm(velocity[:, None, :] - velocity[None, :, :], axis=-1)
        half = 0.5 * np.maximum(x[:, LEN], x[:, WID])
        old = np.array([life.age >= cfg.duplicate_shadow_settled_s for life in self._lives])
        settled = old[:, None] & old[None, :] if cfg.duplicate_shadow_settled_s > 0 else np.zeros((n, n), dtype=bool)
        if cfg.duplicate_piece_max_half_m > 0:  # a piece whose footprint touches the host's, its centre outside
            touch = (along <= 0.5 * x[:, [LEN]] + half[None, :] + cfg.duplicate_margin) & (
                across <= 0.5 * x[:, [WID]] + half[None, :] + cfg.duplicate_margin
            )
            overlap |= touch & (half[None, :] <= cfg.duplicate_piece_max_half_m) & ~settled
        if cfg.duplicate_end_gap_m > 0:
            off_end = (along <= 0.5 * x[:, [LEN]] + half[None, :] + cfg.duplicate_end_gap_m) & beside
            overlap |= off_end & moving[:, None] & ~known[None, :]
        piece = np.zeros((n, n), dtype=bool)
        if cfg.duplicate_in_line_gap_m > 0:
            # Two pieces of one long hull under way: both moving alike, one ahead of the other on the same line of
            # motion, a gap between their ends that the hull's unseen middle fills.
            ux = np.where(moving, velocity[:, 0] / np.maximum(speed, 1e-9), 0.0)[:, None]
            uy = np.where(moving, velocity[:, 1] / np.maximum(speed, 1e-9), 0.0)[:, None]
            ahead = np.abs(rel[..., 0] * ux + rel[..., 1] * uy)
            aside = np.abs(rel[..., 1] * ux - rel[..., 0] * uy)
            in_line = (ahead <= half[:, None] + half[None, :] + cfg.duplicate_in_line_gap_m) & (
                aside <= 0.5 * np.minimum(x[:, [LEN]], x[:, [WID]]) + cfg.duplicate_margin
            )
            in_line &= moving[:, None]
            piece = in_line & moving[None, :] & (dv <= _IN_LINE_MAX_SPEED_DIFF)
            # Once a hull has shown a piece in line, the piece's next track (born where it was, its velocity not
            # known yet) is that piece again, not a vessel for the second or so until its velocity settles.
            self._long_hulls &= {life.id for life in self._lives}
            long_hull = np.array([life.id in self._long_hulls for life in self._lives])
            overlap |= piece | (in_line & long_hull[:, None] & ~known[None, :])
        by_other = overlap.copy()  # before the shadow test: which ends were by the shadow alone
        if cfg.duplicate_shadow_m > 0:
            centres = x[:, [PN, PE]]
            shadow = in_shadow(centres, half, centres, own, cfg.duplicate_shadow_m, cfg.duplicate_margin)
            # A boat at anchor beyond another, where every new track ended in the other's shadow at once, never grew
            # old enough for the settled exemption (tuning seed 22: a 7.2 m boat 6 m beyond a 9 m one, untracked for
            # 25 s while a track was started and ended there every other scan).
            if cfg.duplicate_shadow_settled_s > 0:
                recurring = self._recurring_shadow_births(centres, cfg.duplicate_shadow_settled_s)
                settled = settled | (old[:, None] & recurring[None, :])
            shadow &= ~settled
            overlap |= shadow | shadow.T
        same_motion = (dv <= cfg.duplicate_max_speed_diff) | ~(known[:, None] & known[None, :])
        # the guest loses to a confirmed host with more hits (ties: the younger, later-born guest loses)
        order = np.arange(n)
        stronger = (hits[:, None] > hits[None, :]) | (
            (hits[:, None] == hits[None, :]) & (order[:, None] < order[None, :])
        )
        pair = overlap & same_motion & confirmed[:, None] & stronger
        np.fill_diagonal(pair, False)
        alive_host = np.array([i not in dying for i in range(n)])
        losers = np.flatnonzero((pair & alive_host[:, None]).any(axis=0))
        hosts = np.flatnonzero((pair & piece & alive_host[:, None]).any(axis=1))
        self._long_hulls |= {self._lives[i].id for i in hosts.tolist()}
        out = [int(i) for i in losers if int(i) not in dying]
        in_shadow_only = [i for i in out if not (pair[:, i] & (by_other[:, i] | by_other[i, :])).any()]
        self._note_shadow_births(x[in_shadow_only][:, [PN, PE]])
        self.stats["duplicates"] += len(out)
        return out

    def _note_shadow_births(self, places: np.ndarray) -> None:
        """Remember ``places`` (north, east) of tracks ended in another's shadow this scan: each continues a place
        within _SHADOW_BIRTH_RADIUS_M whose last such end is at most _SHADOW_BIRTH_GAP_S old, or starts one."""
        births = self._shadow_births[self._shadow_births[:, 3] >= self._t - _SHADOW_BIRTH_GAP_S]
        for p in places:  # few: the tracks ended this scan
            d = np.hypot(births[:, 0] - p[0], births[:, 1] - p[1])
            j = int(np.argmin(d)) if d.size else -1
            if j >= 0 and d[j] <= _SHADOW_BIRTH_RADIUS_M:
                births[j, :2], births[j, 3] = p, self._t
            else:
                births = np.vstack([births, [p[0], p[1], self._t, self._t]])
        self._shadow_births = births

    def _recurring_shadow_births(self, centres: np.ndarray, settled_s: float) -> np.ndarray:
        """(T,) bool: the track lies at a place that has kept starting tracks ended in another's shadow for
        ``settled_s``; such a place stays remembered while a track lives on it."""
        births = self._shadow_births
        live = births[:, 3] >= self._t - _SHADOW_BIRTH_GAP_S
        if not live.any() or len(centres) == 0:
            return np.zeros(len(centres), dtype=bool)
        d = np.hypot(centres[:, None, 0] - births[None, :, 0], centres[:, None, 1] - births[None, :, 1])
        at = (d <= _SHADOW_BIRTH_RADIUS_M) & live[None, :]
        births[at.any(axis=0), 3] = self._t  # a track living there keeps the place
        return (at & (births[None, :, 3] - births[None, :, 2] >= settled_s)).any(axis=1)

    def _thin_line(self, m: Measurement) -> bool:
        """``m`` is a line thinner than any hull (``thin_max_width_m``, at least ``thin_min_length_m`` long) seen
        from where a hull with a beam of ``beam_ratio`` x its length would have shown an end face."""
        cfg = self.config.structure
        if cfg.thin_seen_min_scans <= 0 or m.sensor is None or m.kind is ShapeKind.POINT:
            return False
        long_side, short_side = max(m.length, m.width), min(m.length, m.width)
        if short_side >= cfg.thin_max_width_m or long_side < cfg.thin_min_length_m:
            return False
        heading = m.heading if m.length >= m.width else m.heading + 0.5 * math.pi
        return prior_beam_would_show(m.center, heading, long_side, m.sensor, self.config.ekf)

    def _unproven_structure(self, x: np.ndarray, velocities: np.ndarray) -> np.ndarray:
        """(T,) bool: tracks shaped like structure that have not shown a speed above ``static_max_speed_mps``
        (``velocities`` NaN where unknown), reported tentative until they move. Structure-sized ones
        (``static_min_length_m``) are a quay stretch, which ``_static_structure`` ends at ``static_min_age_s``; ones
        thinner than any hull (``thin_max_width_m``, at least ``thin_min_length_m`` long) are a line of returns with
        its ends in view. One that moves is a hull seen side-on. A structure-sized one, or a thin one at least
        ``flat_thin_min_length_m`` long, spanning less than ``flat_max_height_m`` of height is one beam along a quay,
        tentative however it seems to move."""
        cfg = self.config.structure
        # a line seen thin for thin_seen_min_scans scans in a row is thin whatever the width its first view gave it
        seen_thin = np.array(
            [
                cfg.thin_seen_min_scans > 0 and self._thin_runs.get(life.id, 0) >= cfg.thin_seen_min_scans
                for life in self._lives
            ],
            dtype=bool,
        )
        shaped = ((x[:, WID] < cfg.thin_max_width_m) | seen_thin) & (x[:, LEN] >= cfg.thin_min_length_m)
        long_line = (
            (cfg.flat_thin_min_length_m > 0)
            & ((np.minimum(x[:, LEN], x[:, WID]) < cfg.thin_max_width_m) | seen_thin)
            & (np.maximum(x[:, LEN], x[:, WID]) >= cfg.flat_thin_min_length_m)
        )
        if cfg.static_min_length_m > 0:
            sized = self._structure_sized(x)
            shaped |= sized
            long_line |= sized
        flat = long_line & (x[:, HGT] < cfg.flat_max_height_m)
        with np.errstate(invalid="ignore"):
            moving = np.hypot(velocities[:, 0], velocities[:, 1]) > cfg.static_max_speed_mps
        return (shaped & ~moving) | flat

    def _unseen_guess(self, velocity_known: np.ndarray) -> np.ndarray:
        """(T,) bool: tracks whose velocity is not known yet (``velocity_known`` False) or that were hit fewer than
        ``min_hits_reported_unseen`` times, unseen for longer than ``max_reported_unseen_unknown_motion``. The
        position of the first is where the vessel was, not where it is; the second may have been a wave crest that
        three revolutions confirmed: reported tentative while they coast."""
        cfg = self.config.lifecycle
        unseen = (
            np.array([life.time_since_update for life in self._lives]) > cfg.max_reported_unseen_unknown_motion + 1e-9
        )
        few_hits = np.array([life.hits for life in self._lives]) < cfg.min_hits_reported_unseen
        return unseen & (~velocity_known | few_hits)

    def _velocity_known(self, p: np.ndarray) -> np.ndarray:
        """(T,) bool for covariances ``p`` (T, DIM_X, DIM_X): the velocity is settled (both standard deviations at
        most ``velocity_valid_std``). Unsettled velocities are not published and keep a coasting track unreported
        (LifecycleConfig.max_reported_unseen_unknown_motion)."""
        return np.maximum(p[:, VN, VN], p[:, VE, VE]) <= self.config.ekf.velocity_valid_std**2

    def _swept(self, m: Measurement, lag: float) -> Measurement:
        """``m`` carrying ``lag`` s from its sweep to the scan time, for the update's measurement model."""
        if not (self.config.ekf.compensate_sweep and lag > 0.0):
            return m
        return dataclasses.replace(m, lag=lag)

    def _associate(self, measurements: list[Measurement]) -> Assignment:
        x, p = self.bank.states(), self.bank.covariances()
        track_cov = footprint_covariance(x[:, PSI], x[:, LEN], x[:, WID]) + p[:, :2, :2]
        if measurements:
            det_mean = np.array([m.center for m in measurements])
            det_cov = footprint_covariance(
                np.array([m.heading for m in measurements]),
                np.array([m.length for m in measurements]),
                np.array([m.width for m in measurements]),
            ) + np.array([m.r[:2, :2] for m in measurements])
        else:
            det_mean, det_cov = np.zeros((0, 2)), np.zeros((0, 2, 2))
        assignment, _ = associate(x[:, [PN, PE]], track_cov, det_mean, det_cov, self.config.association)
        return assignment

    # -- output ------------------------------------------------------------------------------------------------

    def on_structure(self, t: float, points_ne: np.ndarray, radius_m: float) -> np.ndarray:
        """(n,) bool: structure the LiDAR saw (a quay, the land behind it) lies within ``radius_m`` of each world
        (north, east) point, as remembered at ``t``."""
        return self.structure.near(t, points_ne, radius_m)

    def behind_structure(self, t: float, points_ne: np.ndarray, sensor_ne: np.ndarray) -> np.ndarray:
        """(n,) bool: the line of sight from ``sensor_ne`` to each world (north, east) point crosses structure the
        LiDAR saw (its own cell left out), as remembered at ``t``."""
        pts = np.asarray(points_ne, dtype=float).reshape(-1, 2)
        if not len(pts):
            return np.zeros(0, dtype=bool)
        depth = float(np.hypot(*(pts - np.asarray(sensor_ne, dtype=float)[:2]).T).max())
        return np.isfinite(self.structure.lid_in_front(t, pts, sensor_ne, depth))

    def tracks(self) -> list[Track]:
        """Every live track, from the bank's states and covariances stacked once (not read filter by filter)."""
        if not self._lives:
            return []
        x, p = self.bank.states(), self.bank.covariances()
        positions = x[:, [PN, PE]]
        velocities = x[:, [VN, VE]]
        known = self._velocity_known(p)
        velocities[~known] = np.nan
        headings = (x[:, PSI] % (2.0 * math.pi)).tolist()
        rates, lengths, widths, heights = (x[:, k].tolist() for k in (OMEGA, LEN, WID, HGT))
        position_covs = p[:, :2, :2].copy()
        tentative_now = self._unproven_structure(x, velocities) | self._unseen_guess(known)
        return [
            Track(
                id=life.id,
                t=life.t_now,
                position=positions[j],
                velocity=velocities[j],
                heading=headings[j],
                yaw_rate=rates[j],
                length=lengths[j],
                width=widths[j],
                height=heights[j],
                shape=kind,
                confirmed=life.confirmed and not tentative_now[j],
                source="lidar",
                position_cov=position_covs[j],
                hits=life.hits,
                age=life.age,
                time_since_update=life.time_since_update,
            )
            for j, (life, kind) in enumerate(zip(self._lives, self._kinds, strict=True))
        ]


def box_depth(points_ne: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(P, T): how deep each of the (P, 2) points (north, east) lies in each of the T tracks' boxes (states ``x``),
    as :func:`tracker.lidar.settled.box_depths` measures it."""
    return box_depths(points_ne, x[:, [PN, PE, PSI, LEN, WID]], 0.0, min_half_m=_MIN_HALF_M)


def _least_gap(a: np.ndarray, b: np.ndarray) -> float:
    """The least horizontal distance (m) between two sets of (n, 2+) points; inf if either is empty."""
    if len(a) == 0 or len(b) == 0:
        return math.inf
    return float(cKDTree(a[:, :2]).query(b[:, :2], k=1)[0].min())
