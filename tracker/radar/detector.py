"""Radar detector (paper 001, sec. 2.2): one frame of returns -> clusters with a Doppler velocity each.

Order of work, and why:
1. ROI ("conditional filter"): own hull, beyond the configured range, outside the antenna's sector, bad SNR.
2. Body FRD -> world N/E with the boat's pose, lines of sight from the radar's own position.
3. Doppler made relative to the world: the radar moves with the boat, so every static return shows
   v_r = -v_radar . u. v_radar is the autopilot's velocity plus yaw rate x lever arm, or, without an autopilot
   velocity, the dominant velocity profile of the whole frame (static returns outnumber targets).
4. Multipath ghosts removed (they would otherwise become tracks of their own).
5. DBSCAN over position (sec. 3.2: 1.2 m, 20 points), then each cluster split by compensated Doppler (0.8 m/s,
   20 points): two boats side by side at different speeds become two clusters. Each gets its velocity profile
   (eq. 3-6).
6. Shore extracted from the static map as it stood before this frame; clusters on or behind it removed.
7. This frame's static returns added to the map. A boat crossing the line of sight has near-zero Doppler and would
   leave a trail that grows into a false "shore", so the tracker does this step itself after association and leaves
   out the returns of clusters that belong to moving tracks (``detect(..., update_map=False)`` + ``update_map``).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from tracker.ego import rotation_matrices
from tracker.existence import ClutterDensity
from tracker.radar.config import RadarTrackerConfig
from tracker.radar.dbscan import dbscan, dbscan_1d_grouped, kd_tree
from tracker.radar.multipath import multipath_ghosts
from tracker.radar.shore_lines import ShoreLines
from tracker.radar.static_map import StaticMap
from tracker.radar.velocity_profile import (
    ProfileFitSettings,
    VelocityEstimate,
    VelocityStatus,
    fit_velocity_profile,
    fit_velocity_profiles,
)
from tracker.types import Detection, ShapeKind

log = logging.getLogger(__name__)

SHORE_KEEP, SHORE_ON, SHORE_BEHIND = 0, 1, 2


@dataclass
class RadarCluster:
    """One detected object in one frame; arrays are per return, world frame unless named otherwise."""

    points: np.ndarray  # (n, 2) north, east, m
    points_body: np.ndarray  # (n, 3) body FRD, m
    doppler: np.ndarray  # (n,) raw, m/s, positive = receding from the radar
    doppler_world: np.ndarray  # (n,) relative to the world (ego motion removed); NaN without an ego velocity
    snr: np.ndarray  # (n,) dB
    los: np.ndarray  # (n, 2) unit line of sight radar -> return, world
    range_m: np.ndarray  # (n,) horizontal range from the radar
    index: np.ndarray  # (n,) int, rows of DetectorOutput.points
    profile: ProfileFitSettings  # the velocity-profile fit, made on first use of ``velocity``
    rng: np.random.Generator | None  # None: a generator of its own, made if the fit is ever asked for
    shore: int = SHORE_KEEP  # SHORE_KEEP, SHORE_ON or SHORE_BEHIND
    _velocity: VelocityEstimate | None = None

    @property
    def velocity(self) -> VelocityEstimate:
        """Eq. 3-6, fitted when first asked for: shore clusters (~40 % near a quay) never need one."""
        if self._velocity is None:
            rng = self.rng if self.rng is not None else np.random.default_rng(0)
            self._velocity = fit_velocity_profile(self.los, self.doppler_world, self.profile, rng)
        return self._velocity

    @property
    def fitted(self) -> bool:
        """The velocity fit is made (reading ``velocity`` costs nothing and draws nothing)."""
        return self._velocity is not None

    @property
    def n_points(self) -> int:
        return int(self.points.shape[0])

    def box(self) -> np.ndarray:
        """(4,) world-axis-aligned box: north_min, east_min, north_max, east_max."""
        return np.concatenate([self.points.min(axis=0), self.points.max(axis=0)])

    def measured_box(self, sensor_ne: np.ndarray, min_size: float) -> tuple[np.ndarray, np.ndarray, float]:
        """(centre (2,), size (2,) north and east extents with ``min_size`` as floor, range of the centre m): what the
        track filter measures, without building a Detection."""
        lo, hi = self.points.min(axis=0), self.points.max(axis=0)
        centre = (lo + hi) / 2
        rel = centre - sensor_ne
        return centre, np.maximum(hi - lo, min_size), math.hypot(float(rel[0]), float(rel[1]))

    def to_detection(self, t: float, sensor_ne: np.ndarray, min_size: float) -> Detection:
        centre, size, range_m = self.measured_box(sensor_ne, min_size)
        v = self.velocity
        known = v.status is not VelocityStatus.UNDETERMINED
        return Detection(
            t=t,
            center=centre,
            heading=0.0,  # the box is world-axis-aligned: length along north, width along east
            length=float(size[0]),
            width=float(size[1]),
            height=0.0,  # the AWR1843's elevation is too coarse to give one
            shape=ShapeKind.BOX if self.n_points >= 3 else ShapeKind.POINT,
            n_points=self.n_points,
            range_m=range_m,
            points=self.points,
            # RADIAL_ONLY: the radial component, with velocity.undetermined_var across the line of sight
            velocity=v.velocity.copy() if known else np.full(2, np.nan),
            velocity_cov=v.covariance.copy() if known else None,
            source="radar",
        )


@dataclass
class DetectorOutput:
    t: float
    sensor_ne: np.ndarray  # (2,) radar position, world
    points: np.ndarray  # (m, 2) world N/E of the returns inside the ROI
    points_body: np.ndarray  # (m, 3) the same, body FRD
    doppler: np.ndarray  # (m,) raw Doppler, m/s
    snr: np.ndarray  # (m,) dB
    los: np.ndarray  # (m, 2) unit lines of sight from the radar, world
    range_m: np.ndarray  # (m,) horizontal range from the radar
    loose: np.ndarray  # (m,) bool, in no kept cluster, no ghost, not on the shore
    doppler_world: np.ndarray  # (m,) ego-compensated Doppler (NaN without an ego velocity)
    ghost: np.ndarray  # (m,) bool, multipath ghosts
    static: np.ndarray  # (m,) bool, returns at rest over ground (candidates for the static map)
    line_static: np.ndarray  # (m,) bool, returns at rest over ground (candidates for the shore lines)
    sensor_velocity: np.ndarray  # (2,) radar velocity over ground used for compensation; NaN if none
    ego_source: str  # "autopilot", "doppler" or "none"
    ego_estimate: VelocityEstimate | None  # the Doppler ego fit, when one was made
    clusters: list[RadarCluster] = field(default_factory=list)  # all, shore verdict included
    kept_clusters: list[RadarCluster] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    min_box_size_m: float = 0.5
    _detections: list[Detection] | None = None

    @property
    def candidate(self) -> np.ndarray:
        """(m,) bool, the returns that may be a vessel's: in a kept cluster, or loose."""
        mask = self.loose.copy()
        for cl in self.kept_clusters:
            mask[cl.index] = True
        return mask

    @property
    def detections(self) -> list[Detection]:
        """The kept clusters as Detections, same order as ``kept_clusters``; built on first use (the tracker works
        on the clusters)."""
        if self._detections is None:
            self._detections = [
                cl.to_detection(self.t, self.sensor_ne, self.min_box_size_m) for cl in self.kept_clusters
            ]
        return self._detections


def _rot(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])  # body (fwd, stbd) -> world (north, east)


class RadarDetector:
    def __init__(self, config: RadarTrackerConfig, rng: np.random.Generator | None = None) -> None:
        self.cfg = config
        self.rng = rng if rng is not None else np.random.default_rng(config.seed)
        self.static_map = StaticMap(config)
        self.shore_lines = ShoreLines(
            config.shore.line_window_s,
            config.shore.line_link_m,
            config.shore.min_extent_m,
            config.shore.line_max_thickness_m,
            config.shore.update_interval_s,
            config.kalman.position_std_per_m,
            min_frames=config.shore.line_min_frames,
            recheck_min_range_m=config.shore.line_recheck_min_range_m,
        )
        self.multipath = config.multipath
        self.profile = config.velocity.settings()
        self.ego_profile = config.velocity.ego_settings(config.ego)
        self.totals: dict[str, int] = {}
        self.clutter = self.new_clutter()
        self.static_map.clutter_per_m2 = lambda range_m: self.clutter_expected(range_m, 1.0)

    def new_clutter(self) -> ClutterDensity:
        """The sea clutter's density around the radar, measured from the frames' returns (tracker.existence)."""
        c = self.cfg
        return ClutterDensity(
            max(c.roi.min_range_m, 0.5),
            c.roi.max_range_m,
            2 * c.roi.max_abs_azimuth_rad,
            c.existence.clutter_time_constant_s,
        )

    def measure_clutter(self, out: DetectorOutput, use: np.ndarray) -> None:
        """The frame's returns flagged in ``use`` (m,) bool (its candidates, less those of established tracks) into the
        clutter density; the tracker calls this once per frame, after counting its tracks' returns."""
        rel = out.points_body[use, :2] - np.asarray(self.cfg.sensor_position_body)
        az = np.angle(np.exp(1j * (np.arctan2(rel[:, 1], rel[:, 0]) - self.cfg.sensor_yaw_body_rad)))
        self.clutter.update(out.t, out.range_m[use], az)

    def clutter_expected(self, range_m: np.ndarray, area_m2: np.ndarray | float) -> np.ndarray:
        """(n,) clutter returns a frame expected over ``area_m2`` at ``range_m`` from the radar: the measured density
        times its peak on the crests (``existence.clutter_peak``)."""
        return self.clutter.at(range_m) * area_m2 * self.cfg.existence.clutter_peak

    def _count(self, counts: dict[str, int], key: str, n: int) -> None:
        counts[key] = counts.get(key, 0) + int(n)
        self.totals[key] = self.totals.get(key, 0) + int(n)

    def roi_mask(self, xyz_body: np.ndarray, snr: np.ndarray) -> np.ndarray:
        c = self.cfg
        rel = xyz_body[:, :2] - np.asarray(c.sensor_position_body)
        rng = np.hypot(rel[:, 0], rel[:, 1])
        az = (np.arctan2(rel[:, 1], rel[:, 0]) - c.sensor_yaw_body_rad + np.pi) % (2.0 * np.pi) - np.pi
        z = xyz_body[:, 2]
        with np.errstate(invalid="ignore"):
            return (
                (rng >= c.roi.min_range_m)
                & (rng <= c.roi.max_range_m)
                & (np.abs(az) <= c.roi.max_abs_azimuth_rad)
                & (z >= c.roi.min_z_m)
                & (z <= c.roi.max_z_m)
                & ~(snr < c.roi.min_snr_db)  # NaN SNR passes
            )

    def detect(
        self,
        points_body: np.ndarray,
        doppler: np.ndarray,
        snr: np.ndarray | None,
        t: float,
        position: np.ndarray,
        yaw: float,
        velocity: np.ndarray | None = None,
        yaw_rate: float = 0.0,
        update_map: bool = True,
        roll: float = 0.0,
        pitch: float = 0.0,
    ) -> DetectorOutput:
        """One frame. ``position`` (2,) world N/E and ``yaw`` (rad) of the boat; ``velocity`` (2,) world N/E over
        ground from the autopilot, or None to estimate it from the static returns' Doppler. With ``update_map``
        False the caller adds the frame to the static map itself (``update_map``)."""
        c = self.cfg
        counts: dict[str, int] = {}
        xyz = np.asarray(points_body, float)
        if xyz.ndim != 2 or xyz.shape[1] not in (2, 3):
            raise ValueError(f"radar points must be (n, 2) or (n, 3) body FRD, got shape {xyz.shape}")
        if xyz.shape[1] == 2:
            xyz = np.column_stack([xyz, np.zeros(len(xyz))])
        n_in = xyz.shape[0]
        dop = np.asarray(doppler, float).reshape(-1)
        snr_a = np.full(n_in, np.nan) if snr is None else np.asarray(snr, float).reshape(-1)
        if dop.size != n_in or snr_a.size != n_in:
            raise ValueError(f"radar frame: {n_in} points but {dop.size} Doppler and {snr_a.size} SNR values")
        finite = np.all(np.isfinite(xyz), axis=1)
        if not finite.all():
            self._count(counts, "nonfinite_points", n_in - int(finite.sum()))
            log.debug("radar: %d of %d returns with non-finite coordinates dropped", n_in - finite.sum(), n_in)
        # 1. ROI
        keep = finite.copy()
        keep[finite] = self.roi_mask(xyz[finite], snr_a[finite])
        self._count(counts, "outside_roi", int(finite.sum() - keep.sum()))
        xyz, dop, snr_a = xyz[keep], dop[keep], snr_a[keep]
        self._count(counts, "roi_points", len(xyz))
        self._count(counts, "nonfinite_doppler", int((~np.isfinite(dop)).sum()))  # kept: position is still good

        # 2. body FRD -> world N/E, lines of sight from the radar
        pos = np.asarray(position, float).reshape(2)
        rot = _rot(float(yaw))
        sensor_body = np.asarray(c.sensor_position_body, float)
        sensor_ne = pos + rot @ sensor_body
        # Body FRD -> world N/E with the full attitude: on a boat rolled 5 deg a return 2 m above or below the body
        # origin moves 0.17 m sideways, and one 20 m abeam 0.08 m nearer. Level, yaw alone does it.
        if roll or pitch:
            r_bw = rotation_matrices(np.array([roll]), np.array([pitch]), np.array([float(yaw)]))[0]
            world = xyz @ r_bw[:2].T + pos
        else:
            world = xyz[:, :2] @ rot.T + pos
        rel = world - sensor_ne
        rng = np.hypot(rel[:, 0], rel[:, 1])
        los = rel / np.maximum(rng, 1e-9)[:, None]

        # 3. ego motion
        ego_est: VelocityEstimate | None = None
        v_sensor = np.full(2, np.nan)
        source = "none"
        if velocity is not None and np.all(np.isfinite(velocity)):
            lever = float(yaw_rate) * np.array([-sensor_body[1], sensor_body[0]])  # omega x r, FRD, yaw rate about z
            v_sensor = np.asarray(velocity, float).reshape(2) + rot @ lever
            source = "autopilot"
        elif len(xyz) >= c.ego.min_points:
            ego_est = fit_velocity_profile(los, dop, self.ego_profile, self.rng)
            if ego_est.status is VelocityStatus.FULL:
                v_sensor = -ego_est.velocity  # static returns: v_r = -v_radar . u
                source = "doppler"
            else:
                log.debug("radar: no Doppler ego velocity this frame (%s)", ego_est.reason)
        dop_world = dop + los @ v_sensor if source != "none" else np.full(len(dop), np.nan)
        v_max = c.max_radial_speed_mps
        if v_max > 0 and source == "autopilot":
            # The radar measures the Doppler modulo 2 v_max: a boat closing at 11 m/s while the own boat makes 4.5
            # is reported receding at 4.7, and compensated, at 9.2 m/s over ground instead of -6.8: its track then
            # runs away from its returns and is never confirmed, head-on, where it matters most. Speeds over ground
            # of vessels in a harbour lie within v_max (8.3 m/s, 16 kn, with the shipped profile), so the
            # compensated Doppler is taken in [-v_max, v_max): right whatever the own boat's speed. (Estimated from
            # the static returns' own Doppler, the ego velocity is as aliased as they are: left as it is.)
            dop_world = np.mod(dop_world + v_max, 2.0 * v_max) - v_max

        # 4. multipath
        ghost = np.zeros(len(xyz), bool)
        if c.multipath.enabled and len(xyz) > 1:
            az_body = np.arctan2(xyz[:, 1] - sensor_body[1], xyz[:, 0] - sensor_body[0])
            ghost = multipath_ghosts(rng, az_body, dop, snr_a, self.multipath)
            self._count(counts, "multipath_ghosts", int(ghost.sum()))

        # Only returns at rest over ground go to the static map, so a boat passing the quay leaves no trail in it.
        if source != "none":
            static = (np.abs(dop_world) <= c.ego.static_doppler_threshold_mps) & ~ghost
        else:
            static = ~ghost
        on_line = np.zeros(len(xyz), bool)
        line_static = static.copy()
        map_extracted = False
        if c.shore.enabled:
            # 6a. the shore as known before this frame (used in 6b, after clustering)
            self.static_map.advance_time(t)
            self.static_map.follow(pos)
            map_extracted = self.static_map.update_shore(t, pos, c.roi.max_range_m)
        if c.shore.enabled and c.shore.line_window_s > 0:
            on_line[static] = self.shore_lines.mark(t, world[static], sensor_ne, defer=map_extracted)
        if c.shore.map_min_neighbours > 0 and static.any():
            # Sea clutter is static-looking but scattered: over minutes it would fill the water near the boat with
            # "occupied" cells. A wall or a hull gives returns with neighbours in the same frame; lone ones are left
            # out. (The map's extraction then asks more of a cell than the clutter there leaves: StaticMap.)
            idx = np.flatnonzero(static)
            pairs = kd_tree(world[idx]).query_pairs(c.clustering.radius_m, output_type="ndarray")
            nbrs = np.bincount(pairs.reshape(-1), minlength=idx.size)
            static[idx[nbrs < c.shore.map_min_neighbours]] = False

        # 5. clustering over the non-ghost returns (paper), or over all returns with the ghost verdict per cluster
        per_cluster = c.multipath.enabled and c.multipath.per_cluster
        real = np.arange(len(xyz)) if per_cluster else np.flatnonzero(~ghost)
        labels = np.full(len(xyz), -1, np.int64)
        if real.size:
            spatial = dbscan(world[real], c.clustering.radius_m, c.clustering.min_points)
            labels[real] = self.split_by_doppler(spatial, dop_world[real] if source != "none" else dop[real])
        n_clusters = int(labels.max()) + 1 if labels.size else 0
        self._count(counts, "clustered_points", int((labels >= 0).sum()))

        clusters: list[RadarCluster] = []
        for k in range(n_clusters):  # one iteration per cluster (a handful), each vectorised
            idx = np.flatnonzero(labels == k)
            if per_cluster and np.count_nonzero(ghost[idx]) / idx.size >= c.multipath.cluster_ghost_share:
                self._count(counts, "ghost_clusters", 1)
                continue
            clusters.append(self._make_cluster(idx, world, xyz, dop, dop_world, snr_a, los, rng))

        # 6b. shore filter, with the shore as known before this frame
        if c.shore.enabled and clusters:
            verdict = self.static_map.shore_verdict(sensor_ne, [cl.points for cl in clusters])
            line_share = np.array([np.count_nonzero(on_line[cl.index]) / cl.n_points for cl in clusters])
            verdict[(verdict == SHORE_KEEP) & (line_share >= c.shore.on_fraction)] = SHORE_ON
            for cl, v in zip(clusters, verdict, strict=True):
                cl.shore = int(v)
            self._count(counts, "shore_clusters", int((verdict != SHORE_KEEP).sum()))
        kept = [cl for cl in clusters if cl.shore == SHORE_KEEP]
        # The kept clusters' velocity fits are left to the tracker (RadarTracker.step), which fits those its tracks
        # and births use in one batch and gives the rest generators of their own; a shore cluster's fit, made only if
        # someone asks, draws from a generator of its own. So reading velocities outside the tracker cannot change
        # the random draws, and a replay gives the same tracks.
        for cl in clusters:
            if cl.shore != SHORE_KEEP:
                cl.rng = None
        # Returns in no kept cluster, no ghost and not on the shore: too few to start a track, but a track that finds
        # no cluster this frame may take them (RadarTracker, association.update_min_points).
        loose = np.ones(len(xyz), bool)
        for cl in kept:
            loose[cl.index] = False
        loose &= ~ghost & ~on_line & (labels < 0)
        if c.shore.enabled and loose.any():
            loose[loose] = ~self.static_map.on_shore(world[loose])
        out = DetectorOutput(
            t=t,
            sensor_ne=sensor_ne,
            points=world,
            points_body=xyz,
            doppler=dop,
            snr=snr_a,
            los=los,
            range_m=rng,
            loose=loose,
            doppler_world=dop_world,
            ghost=ghost,
            static=static,
            line_static=line_static,
            sensor_velocity=v_sensor,
            ego_source=source,
            ego_estimate=ego_est,
            clusters=clusters,
            kept_clusters=kept,
            counts=counts,
            min_box_size_m=c.clustering.min_box_size_m,
        )
        if update_map:
            self.update_map(out)
        return out

    def _make_cluster(
        self,
        idx: np.ndarray,
        world: np.ndarray,
        xyz: np.ndarray,
        dop: np.ndarray,
        dop_world: np.ndarray,
        snr: np.ndarray,
        los: np.ndarray,
        rng: np.ndarray,
    ) -> RadarCluster:
        return RadarCluster(
            points=world[idx],
            points_body=xyz[idx],
            doppler=dop[idx],
            doppler_world=dop_world[idx],  # NaN without an ego velocity: the fit then finds nothing
            snr=snr[idx],
            los=los[idx],
            range_m=rng[idx],
            index=idx,
            profile=self.profile,
            rng=self.rng,
        )

    def cluster_of(self, out: DetectorOutput, idx: np.ndarray) -> RadarCluster:
        """A cluster made of rows ``idx`` of a frame's output (loose returns a track gathers)."""
        return self._make_cluster(
            np.asarray(idx, np.int64),
            out.points,
            out.points_body,
            out.doppler,
            out.doppler_world,
            out.snr,
            out.los,
            out.range_m,
        )

    def fit_clusters(self, clusters: list[RadarCluster]) -> None:
        """The velocity fits of those ``clusters`` not fitted yet, in one batch
        (velocity_profile.fit_velocity_profiles), drawing from the tracker's RNG in their order (a shore cluster's, on a
        generator of its own, is left to ``RadarCluster.velocity``)."""
        todo = [cl for cl in clusters if not cl.fitted and cl.rng is self.rng]
        if not todo:
            return
        fits = fit_velocity_profiles([cl.los for cl in todo], [cl.doppler_world for cl in todo], self.profile, self.rng)
        for cl, fit in zip(todo, fits, strict=True):
            cl._velocity = fit

    def merge_clusters(self, parts: list[RadarCluster]) -> RadarCluster:
        """One cluster from pieces a track claims together (a sparse hull that DBSCAN split); velocity refitted."""
        if len(parts) == 1:
            return parts[0]

        def cat(name: str) -> np.ndarray:
            return np.concatenate([getattr(p, name) for p in parts])

        return RadarCluster(
            points=cat("points"),
            points_body=cat("points_body"),
            doppler=cat("doppler"),
            doppler_world=cat("doppler_world"),
            snr=cat("snr"),
            los=cat("los"),
            range_m=cat("range_m"),
            index=cat("index"),
            profile=self.profile,
            rng=self.rng,
        )

    def update_map(self, out: DetectorOutput, exclude: np.ndarray | None = None) -> None:
        """7. Add the frame's static returns to the static map, except rows flagged in ``exclude`` (m,) bool."""
        if not self.cfg.shore.enabled:
            return
        use = out.static if exclude is None else out.static & ~exclude
        self.static_map.add_points(out.points[use], out.t)
        if self.cfg.shore.line_window_s > 0:
            line = out.line_static if exclude is None else out.line_static & ~exclude
            self.shore_lines.add(out.t, out.points[line])

    def split_by_doppler(self, spatial: np.ndarray, dop: np.ndarray) -> np.ndarray:
        """Split each spatial cluster by 1-D DBSCAN over Doppler; one call for all clusters, points of different
        spatial clusters never linking. Returns with unknown Doppler join the largest part.
        """
        c = self.cfg
        out = np.full(spatial.size, -1, np.int64)
        inside = spatial >= 0
        if not inside.any():
            return out
        known = inside & np.isfinite(dop)
        if known.any():
            out[known] = dbscan_1d_grouped(
                dop[known], spatial[known], c.clustering.velocity_threshold_mps, c.clustering.velocity_min_points
            )
        unknown = np.flatnonzero(inside & ~np.isfinite(dop))
        if unknown.size:
            for lab in np.unique(spatial[unknown]):
                members = spatial == lab
                parts = out[members & known]
                parts = parts[parts >= 0]
                if parts.size:
                    target = np.bincount(parts).argmax()
                elif not (members & known).any():  # no Doppler at all: keep the spatial cluster whole
                    target = out.max() + 1
                else:
                    continue
                out[unknown[spatial[unknown] == lab]] = target
        # Renumber 0..k-1 in order of first appearance so labels stay compact.
        valid = out >= 0
        if valid.any():
            _, first, inv = np.unique(out[valid], return_index=True, return_inverse=True)
            rank = np.empty(first.size, np.int64)
            rank[np.argsort(first)] = np.arange(first.size)
            out[valid] = rank[inv]
        return out
