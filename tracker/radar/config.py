"""Every tunable of the radar tracker, grouped by the role that reads it, with the paper's values as defaults.

Paper 001 = Xu et al. 2024, "ROTracker: a novel MMW radar-based object tracking method for unmanned surface
vehicle in offshore environments" (Front. Mar. Sci. 11:1411920). Values the paper gives cite their section;
values it leaves open say "not in the paper" and why the default was chosen.

One group per role of a frame's path (README, "Tracking"): the region of interest, the own boat's motion,
clustering, the static map and shore filter, multipath, the velocity profile, the Kalman filter, the Doppler
measurement, the visible side, occlusion, association, births, existence, the lifecycle and the motion
discriminator. In the daemon's TOML each is a table: ``[tracker.radar.clustering]`` and so on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

from tracker.config_checks import at_least_one, choice, no_nan, positive, share
from tracker.config_error import ConfigError
from tracker.lifecycle import LifecycleConfig
from tracker.radar.velocity_profile import ProfileFitSettings


@dataclass(frozen=True)
class RoiConfig:
    """Region of interest (sec. 2.2-1: "conditional filter" before clustering)."""

    min_range_m: float = 1.0  # not in the paper: returns closer than this are the own hull / radome
    max_range_m: float = 100.0  # sec. 3.1: AWR1843 configured for 100 m maximum range
    max_abs_azimuth_rad: float = math.radians(75.0)  # not in the paper: AWR1843 azimuth FoV is about +-60 deg
    min_z_m: float = -10.0  # body FRD z (down positive); radar elevation is poor, so the band is wide
    max_z_m: float = 10.0
    min_snr_db: float = -math.inf  # not in the paper; NaN SNR (TLV 7 absent) always passes

    def __post_init__(self) -> None:
        no_nan(self)
        positive(self, "max_range_m", allow_inf=True)
        positive(self, "min_range_m", allow_zero=True, allow_inf=True)
        if self.min_range_m >= self.max_range_m:
            raise ConfigError("RoiConfig: min_range_m must be below max_range_m")
        if self.min_z_m >= self.max_z_m:
            raise ConfigError("RoiConfig: min_z_m must be below max_z_m")


@dataclass(frozen=True)
class EgoMotionConfig:
    """The own boat's motion: Doppler made relative to the world."""

    inlier_threshold_mps: float = 0.3  # static returns within this of the fitted -v_sensor . u profile
    outlier_rate: float = 0.5  # RANSAC iteration count assumes this share of moving / clutter returns
    min_points: int = 6  # fewer returns: no Doppler ego estimate this frame
    static_doppler_threshold_mps: float = 0.5  # |ego-compensated Doppler| below this: a static return
    # Not in the paper: error (1 sigma, per axis) of the own boat's velocity over ground from the autopilot, m/s
    # (0.05: a GNSS-aided autopilot EKF; raise it for a poorer receiver). It is common to every return, so a cluster's
    # fit does not see it; the motion discriminator's Doppler veto adds it (the Doppler ego fit, without an autopilot,
    # brings its own).
    velocity_std_mps: float = 0.05

    def __post_init__(self) -> None:
        no_nan(self)
        positive(self, "inlier_threshold_mps", allow_inf=True)
        positive(self, "static_doppler_threshold_mps", "velocity_std_mps", allow_zero=True, allow_inf=True)
        at_least_one(self, "min_points")
        if not 0.0 <= self.outlier_rate < 1.0:
            raise ConfigError("EgoMotionConfig.outlier_rate must be in [0, 1)")


@dataclass(frozen=True)
class ClusteringConfig:
    """Clustering (sec. 2.2-1, values sec. 3.2)."""

    radius_m: float = 1.2  # sec. 3.2: DBSCAN search radius for spatial clustering
    min_points: int = 20  # sec. 3.2: minimum points, spatial clustering
    velocity_threshold_mps: float = 0.8  # sec. 3.2: velocity threshold for velocity clustering
    velocity_min_points: int = 20  # sec. 3.2: minimum points, velocity clustering
    min_box_size_m: float = 0.5  # not in the paper: floor for l, w of a sparse cluster's box

    def __post_init__(self) -> None:
        no_nan(self)
        positive(self, "radius_m", "velocity_threshold_mps", "min_box_size_m", allow_inf=True)
        at_least_one(self, "min_points", "velocity_min_points")


@dataclass(frozen=True)
class ShoreConfig:
    """Static map and shore filter (sec. 2.2-2, values sec. 3.2)."""

    enabled: bool = True  # ablation switch
    map_resolution_m: float = 0.25  # sec. 3.2
    submap_cells: int = 400  # sec. 3.2: 400 x 400 cells per sub-map
    # Not in the paper: 3 x 3 sub-maps around the boat, so at least one sub-map (100 m) lies between the boat and the
    # window's edge; returns farther than that from the boat are not mapped.
    submaps_across: int = 3
    decay_time_s: float = 30.0  # not in the paper: e-folding time of map evidence (tide, moving moorings)
    occupied_hits: float = 3.0  # not in the paper: decayed hits that make a cell occupied
    # Not in the paper: hits are pooled over squares of this side before the occupancy test (0: per cell). At 1 deg
    # azimuth noise a wall 40 m away smears over ~1.4 m, so per 0.25 m cell it took ~15 s to show up as shore.
    evidence_pool_m: float = 0.75
    # Not in the paper: a static return enters the map only with this many other static returns within
    # ClusteringConfig.radius_m in the same frame (0: all do). Keeps scattered sea clutter from building a "shore".
    map_min_neighbours: int = 1
    # Not in the paper: only cells hit within this many seconds count toward the shore (the evidence itself decays
    # with decay_time_s). inf: every occupied cell counts.
    recent_s: float = 2.0
    # Not in the paper: returns of a track moving faster than this (and than twice its speed's std), whose velocity
    # explains their Doppler within the tolerance, stay out of the map (see RadarTracker._moving).
    map_exclude_min_speed_mps: float = 0.25
    map_exclude_doppler_tolerance_mps: float = 0.15
    link_radius_m: float = 0.75  # not in the paper: gaps up to 2x this join one structure (sparse wall)
    min_extent_m: float = 10.0  # not in the paper: a static structure this long is shore, not a moored boat
    margin_m: float = 1.0  # not in the paper: a cluster this close to the shore is "on" it
    on_fraction: float = 0.5  # share of a cluster's points on the shore that removes it
    # Not in the paper: a track left without a cluster whose centre now lies on the shore is deleted at once instead
    # of coasting (a quay piece tracked in the first frames, before the wall was known as shore).
    drop_tracks_on_shore: bool = True
    horizon_bin_rad: float = math.radians(1.0)  # bearing bins of the "what lies behind the shore" test
    # Not in the paper: seconds between shore extractions (map and lines); in between the last shore is used. At
    # 0.3 s a wall is found at most three frames later, for a third of the cost of extracting every frame.
    update_interval_s: float = 0.3
    # Not in the paper (tracker.radar.shore_lines): static returns of the last line_window_s linked at line_link_m
    # into a line at least min_extent_m long and at most line_max_thickness_m thick (RMS) are shore at once, before
    # the static map has caught up. line_window_s = 0 disables.
    line_window_s: float = 2.0
    line_link_m: float = 2.0
    line_max_thickness_m: float = 1.0
    # Not in the paper: a structure as long as a line but too thick for one (walls linked by a rough sea's clutter)
    # is searched again, only its returns at least line_recheck_min_range_m from the radar in places (line_link_m / 4
    # cells) that returned in line_min_frames frames of the window or more (ShoreLines._recurring): sea clutter
    # lands somewhere new each frame, except near the boat, where it is dense enough to recur (at 15 m a ring of it
    # drew false lines: tuning seed 30). line_min_frames = 1: no second search.
    line_min_frames: int = 2
    line_recheck_min_range_m: float = 25.0

    def __post_init__(self) -> None:
        no_nan(self)
        positive(
            self,
            "map_resolution_m",
            "decay_time_s",
            "occupied_hits",
            "min_extent_m",
            "horizon_bin_rad",
            "line_max_thickness_m",
            allow_inf=True,
        )
        positive(
            self,
            "evidence_pool_m",
            "recent_s",
            "map_exclude_min_speed_mps",
            "map_exclude_doppler_tolerance_mps",
            "link_radius_m",
            "margin_m",
            "update_interval_s",
            "line_window_s",
            "line_link_m",
            "line_recheck_min_range_m",
            allow_zero=True,
            allow_inf=True,
        )
        at_least_one(self, "submap_cells", "line_min_frames")
        share(self, "on_fraction")
        if self.submaps_across < 1 or self.submaps_across % 2 == 0:
            raise ConfigError("ShoreConfig.submaps_across must be odd (the boat's sub-map in the middle)")


@dataclass(frozen=True)
class MultipathConfig:
    """Multipath ghosts (sec. 3.2)."""

    enabled: bool = True
    search_angle_rad: float = math.radians(10.0)  # sec. 3.2: search angle (used as +- half-width)
    range_orders: tuple[int, ...] = (2, 3)  # not in the paper: a k-bounce ghost sits at k x range
    range_tolerance_m: float = 0.75  # not in the paper; ~5 range bins of the sec. 3.1 configuration
    range_tolerance_rel: float = 0.03
    doppler_tolerance_mps: float = 0.5  # a k-bounce ghost also has k x the raw Doppler; <0 disables
    # Not in the paper: a k-bounce ghost is weaker than its source by at least the extra round trip's path loss
    # (40 log10 2 = 12 dB at k = 2) and the extra reflections; a real boat at twice the range of a smaller one is
    # not (a 3 m high hull at 35 m returns within ~6 dB of a 0.6 m one at 17 m). 0 = any weaker return qualifies.
    min_snr_drop_db: float = 10.0
    # Not in the paper (it drops ghost returns before clustering). With both boats at rest the Doppler test cannot tell
    # a ghost from a real boat at twice the range of another within the search angle: in the simulated paper scene
    # a third of the far boat's returns were called ghosts of the near one. Clustered with everything, a cluster is
    # dropped only when at least this share of its returns are ghosts; ghost returns never reach the static map.
    per_cluster: bool = True
    cluster_ghost_share: float = 0.5

    def __post_init__(self) -> None:
        no_nan(self)
        positive(self, "search_angle_rad", allow_inf=True)
        positive(self, "range_tolerance_m", "range_tolerance_rel", "min_snr_drop_db", allow_zero=True, allow_inf=True)
        share(self, "cluster_ghost_share")
        if any(int(k) < 2 for k in self.range_orders):
            raise ConfigError("MultipathConfig.range_orders must all be >= 2")


@dataclass(frozen=True)
class VelocityProfileConfig:
    """A cluster's velocity from its Doppler velocity profile (eq. 3-6)."""

    inlier_threshold_mps: float = 0.25  # not in the paper; ~2 Doppler bins of a typical AWR1843 profile
    ransac_outlier_rate: float = 0.3  # RANSAC iterations n0 = log(1 - p) / log(1 - (1 - e)^2)
    ransac_confidence: float = 0.99
    ransac_max_iterations: int = 100
    min_points: int = 3  # fewer Doppler points: velocity "not determined"
    min_inlier_fraction: float = 0.5  # RANSAC consensus below this: velocity "not determined"
    noise_std_mps: float = 0.1  # floor on the residual std used for the velocity covariance
    max_tangential_std_mps: float = 0.5  # worse than this along the weak direction: radial component only
    undetermined_var: float = 1.0e4  # (m/s)^2 given to a direction the cluster does not determine
    heading_min_snr: float = 3.0  # speed / its std below this: course not determined

    def __post_init__(self) -> None:
        no_nan(self)
        positive(self, "inlier_threshold_mps", "noise_std_mps", "max_tangential_std_mps", allow_inf=True)
        positive(self, "undetermined_var", allow_inf=True)
        share(self, "ransac_confidence", "min_inlier_fraction")
        if not 0.0 <= self.ransac_outlier_rate < 1.0:
            raise ConfigError("VelocityProfileConfig.ransac_outlier_rate must be in [0, 1)")

    def settings(self) -> ProfileFitSettings:
        """Settings of the per-cluster velocity-profile fit (eq. 3-6)."""
        return ProfileFitSettings(
            inlier_threshold=self.inlier_threshold_mps,
            outlier_rate=self.ransac_outlier_rate,
            confidence=self.ransac_confidence,
            max_iterations=self.ransac_max_iterations,
            min_points=self.min_points,
            min_inlier_fraction=self.min_inlier_fraction,
            noise_std=self.noise_std_mps,
            max_tangential_std=self.max_tangential_std_mps,
            undetermined_var=self.undetermined_var,
            heading_min_snr=self.heading_min_snr,
        )

    def ego_settings(self, ego: EgoMotionConfig) -> ProfileFitSettings:
        """The same fit over a whole frame, where the static returns are the model and targets the outliers."""
        return ProfileFitSettings(
            inlier_threshold=ego.inlier_threshold_mps,
            outlier_rate=ego.outlier_rate,
            confidence=self.ransac_confidence,
            max_iterations=max(self.ransac_max_iterations, 50),
            min_points=ego.min_points,
            min_inlier_fraction=0.3,
            noise_std=self.noise_std_mps,
            max_tangential_std=self.max_tangential_std_mps,
            undetermined_var=self.undetermined_var,
            heading_min_snr=self.heading_min_snr,
        )


@dataclass(frozen=True)
class KalmanConfig:
    """Kalman filter (sec. 2.3-1, eq. 1-2): the transition model and the position and size measurement noise.

    ``motion_model`` "ca": constant acceleration driven by white jerk (jerk_std); "cv": constant velocity driven by
    white acceleration (accel_std); "ct": "cv" plus a turn rate (see below). Not in the paper, which names a Kalman
    filter without its motion model."""

    motion_model: str = "ca"
    jerk_std: float = 0.1  # m/s^3, white-noise jerk: boats change acceleration slowly; not in the paper
    accel_std: float = 2.0  # m/s^2, white-noise acceleration of the "cv" model (a 3 m/s boat turning on 2.5 m: 3.6)
    size_std_rate: float = 0.2  # m/sqrt(s), random walk of l and w
    position_std_m: float = 0.5  # radar cluster centre noise at short range
    position_std_per_m: float = 0.02  # plus this per metre of range (azimuth resolution)
    size_std_m: float = 1.0  # measured l, w of sparse clusters are poor
    init_velocity_std_mps: float = 3.0
    init_accel_std_mps2: float = 0.3
    # "ct": the "cv" model plus a turn-rate state (EKF, coordinated turn). Not in the paper. A boat on a tight turn
    # (3 m/s on 2.5 m: 1.2 rad/s) turns its velocity 7 deg per frame; a straight-line model lags it and the hull's
    # rotation makes its returns' Doppler differ by yaw rate x lever arm (the track knows the rate to undo it).
    turn_rate_std: float = 1.5  # rad/s/sqrt(s), random walk of the turn rate: ~0.5 rad/s per 0.1 s frame
    init_turn_rate_std: float = 0.5  # rad/s at birth
    max_turn_rate: float = 2.0  # rad/s, clamp: small boats do not turn faster
    # Beyond this range the turn rate is held at zero (the track predicts as "cv"): 1 deg of azimuth noise is 1 m
    # at 60 m, as much as a small boat's turning radius, and a turn rate fitted to such positions swings wildly.
    turn_model_max_range_m: float = 60.0  # inf: everywhere; 0: nowhere (the "ct" track then predicts as "cv")
    # With "ct": the Doppler velocity's measurement row reads the turn rate too (the fit over a turning hull's
    # returns gives v + M omega, RadarTracker._turn_gain), and the merge test allows the rotation Doppler of any turn
    # rate within AssociationConfig.merge_turn_rate_sigmas of the track's (RadarTracker._doppler_agrees). Not in the
    # paper.
    turn_doppler_compensation: bool = True

    def __post_init__(self) -> None:
        no_nan(self)
        choice(self, "motion_model", ("ca", "cv", "ct"))
        positive(self, "position_std_m", "size_std_m", "init_velocity_std_mps", "init_accel_std_mps2", allow_inf=True)
        positive(
            self,
            "jerk_std",
            "accel_std",
            "size_std_rate",
            "position_std_per_m",
            "turn_rate_std",
            "init_turn_rate_std",
            "max_turn_rate",
            "turn_model_max_range_m",
            allow_zero=True,
            allow_inf=True,
        )


@dataclass(frozen=True)
class DopplerMeasurementConfig:
    """The fused measurement's Doppler velocity (eq. 7, gamma sec. 3.2)."""

    enabled: bool = True  # ablation switch ("Remove Velocity Measurement", Table 4)
    gamma: float = 0.8  # sec. 3.2: weight of the Doppler velocity measurement
    reference_distance_m: float = 10.0  # not in the paper: eq. 7's 1/d weight is capped at 1 inside this
    # Not in the paper: when the position innovation's NIS exceeds maneuver_nis (0: off), this much velocity variance
    # is added before the update (see kalman.fused_update).
    maneuver_nis: float = 9.21  # 99 % of chi2(2)
    maneuver_velocity_std_mps: float = 1.5
    maneuver_skip_doppler: bool = True  # the Doppler velocity is not fused in a frame flagged as a manoeuvre
    # Not in the paper: added to the Doppler velocity's variance along the directions it determines (turning hulls,
    # near-side returns); 0 trusts the profile fit's own covariance.
    model_std_mps: float = 0.3
    gate_chi2: float = 13.8  # not in the paper: 99.9 % of chi2(2); a Doppler velocity beyond it is not fused

    def __post_init__(self) -> None:
        no_nan(self)
        positive(self, "reference_distance_m", "gate_chi2", allow_inf=True)
        positive(self, "maneuver_nis", "maneuver_velocity_std_mps", "model_std_mps", allow_zero=True, allow_inf=True)
        if not 0.0 <= self.gamma <= 1.0:
            raise ConfigError("DopplerMeasurementConfig.gamma must be in [0, 1]")


@dataclass(frozen=True)
class VisibleSideConfig:
    """Visible-side compensation (not in the paper; see tracker.radar.visible_side). The paper measures the box centre
    of the returns, which sits on the near side of the hull. On: the centre measurement is moved behind the nearest
    return by these shares of the track's recent outline depth and width."""

    enabled: bool = True
    depth_gain: float = 0.4  # fitted on the simulated paper boats; check on real returns
    width_gain: float = 0.2
    shape_window_s: float = 1.0  # the outline is the track's returns of this long, relative to its centre
    # Not in the paper: the size measurement is the larger of the frame's box and the outline's quantile spread (this
    # quantile to 1 - it, over 1 - 2 x it) (RadarTracker._outline_size). A far hull's 1-3 returns a frame span a
    # fraction of it, and the track shrank to the 0.5 m floor. 0: the frame's box, as the paper; the outline is kept
    # with the visible-side centre only, so with enabled False this is off too.
    outline_size_quantile: float = 0.05

    def __post_init__(self) -> None:
        no_nan(self)
        positive(self, "depth_gain", "width_gain", "shape_window_s", allow_zero=True, allow_inf=True)
        if not 0.0 <= self.outline_size_quantile < 0.5:
            raise ConfigError("VisibleSideConfig.outline_size_quantile must be in [0, 0.5)")


@dataclass(frozen=True)
class OcclusionConfig:
    """A track in a nearer object's shadow (not in the paper; its coasting time is the lifecycle's
    max_unseen_time_occluded)."""

    # A confirmed track coasts max_unseen_time_occluded while at least min_share of its bearing span lies in a nearer
    # cluster's shadow (a boat wholly behind a taller one is still there), its velocity relaxing toward zero with
    # velocity_decay_s (hidden, its course is not known to be kept; 0: no relaxing).
    min_share: float = 0.5
    velocity_decay_s: float = 2.0
    # The LiDAR paper's visibility factor, for the radar: a track whose bearing span is partly shadowed by a nearer
    # cluster (margin_m nearer) has this much variance, m^2, times the shadowed share squared added to its position
    # measurement (RadarTracker._shadow). 0 disables.
    position_var_m2: float = 4.0
    margin_m: float = 1.0
    # With one end of its bearing span in such a shadow, a track's centre across the line of sight is measured half
    # its silhouette in from the lit edge of its returns (tracker.radar.occlusion.lit_edge_centre). Off by default:
    # the shadow test is 2-D, and a radar mounted above a low hull sees over it (0.9 m up, a 0.6 m dinghy 15 m out
    # hides nothing of a boat at 37 m), so the shift moved fully seen tracks by half a hull. It pays where the nearer
    # hulls are taller than the radar mount (a radar at the water line among moored boats).
    lit_edge: bool = False

    def __post_init__(self) -> None:
        no_nan(self)
        positive(self, "velocity_decay_s", "position_var_m2", "margin_m", allow_zero=True, allow_inf=True)
        share(self, "min_share")


@dataclass(frozen=True)
class AssociationConfig:
    """Association (sec. 2.3-1): box IoU, a distance fallback, and the merges of a hull's pieces."""

    min_iou: float = 0.01  # below: the IoU cost gives way to the distance fallback
    distance_gate_m: float = 3.0  # centre distance for sparse clusters whose boxes do not overlap
    # Not in the paper: a sparse hull often comes as two or three clusters. A cluster left over after the one-to-one
    # assignment joins the track whose predicted box is within this gap (and whose velocity explains its Doppler)
    # instead of starting a second track on the same boat. 0 disables.
    merge_gap_m: float = 2.0
    merge_doppler_tolerance_mps: float = 0.8  # = ClusteringConfig.velocity_threshold_mps: what the split would tell
    # Not in the paper: with "ct", a cluster's Doppler agrees with a track if some turn rate within this many of the
    # track's standard deviations explains it (RadarTracker._doppler_agrees). 0: the track's own rate only.
    merge_turn_rate_sigmas: float = 3.0
    # Not in the paper: a confirmed track left without a cluster takes a would-be new track's cluster within this
    # distance of its prediction (a hard turn leaves the predicted box). 0 disables.
    recovery_gate_m: float = 5.0
    # Not in the paper: a track that gets no cluster takes this many loose returns (in no cluster) within
    # merge_gap_m of its predicted box as its measurement. 0 disables.
    update_min_points: int = 2
    # Not in the paper: beyond this range from the radar a track takes a single loose return (with agreeing
    # Doppler). A 3 m boat at 75 m gives about one return a frame; sea clutter that far out is sparse, while near
    # the radar it is dense and a single return there is as likely clutter as boat. inf: never.
    update_single_return_range_m: float = 40.0  # the return must have a finite Doppler that agrees
    # Not in the paper: tracks born from pieces of one hull before either was established are duplicates when their
    # boxes overlap this much or their centres are this close while moving alike; the younger is dropped.
    # duplicate_distance_m = 0 disables.
    duplicate_iou: float = 0.1
    duplicate_distance_m: float = 2.5
    duplicate_velocity_mps: float = 1.0
    duplicate_velocity_chi2: float = 9.21  # or their difference within 99 % of chi2(2) of the two filters' covariance
    # Not in the paper: a hull's strong scatterers (bow, cabin, stern) 5-10 m apart come back as clusters of their
    # own, each holding a confirmed track. A confirmed track moving alike with a better one (their velocities within
    # duplicate_velocity_mps, or not told apart within duplicate_velocity_chi2 of the filters' covariance), both at
    # piece_min_speed_mps or more, within piece_along_m of it along their common course and piece_across_m across
    # it, is a piece of that hull (tracker.radar.pieces): its outline still goes to the obstacle array, it is no
    # vessel of its own. Held out, radar alone: MOTA 0.350 -> 0.483 (44 scenes better, none worse), false
    # track-frames 57.1 -> 38.5 % of matches; fused unchanged. 3.5 m across was chosen on tuning seeds 1-32 (MOTA
    # 0.5416 / 0.5549 / 0.5650 at 2.5 / 3.5 / 5 m; 5 m took a boat abreast in). piece_along_m = 0 disables.
    piece_along_m: float = 12.0
    piece_across_m: float = 3.5
    # 0.5 m/s rather than 1 (stop 89): of the second tracks left on hulls another track matched (seeds 101-140,
    # radar alone), a third were on boats making 0.3-1 m/s. Tuning seeds 1-100 (radar alone) against 1 m/s: MOTA
    # 0.5997 -> 0.6117 (64 scenes better, 8 worse by 0.005 at most), false positives 5,248 -> 4,371, matches 50,651
    # -> 50,566; 0.3 m/s: 0.6135, 4,142 and 50,457, 16 scenes worse than at 0.5 (by up to 0.010). Held out
    # (random:1001-1050), radar alone: MOTA 0.561 -> 0.572 (34 better, 2 worse by 0.0043 at most), false
    # track-frames 16.2 -> 14.5 % of matches; the LiDAR alone and fused identical. Boats at anchor swing slower;
    # the duplicate test judges them.
    piece_min_speed_mps: float = 0.5
    # The common course is the sum of the two velocities, and the radar knows their direction poorly: on seeds
    # 101-140 (radar alone), of the second tracks moving with a hull another track matched, the course lay 22 deg off
    # the hull's heading at the median (38 deg at the 3rd quartile), and two thirds of them were more than 3.5 m
    # "across" it while lying within 1.8 m of the true keel line at the median. So piece_across_m grows by
    # tan(this) a metre along; two boats abreast (nothing along) are judged as before. Ours. Tuning seeds 1-100
    # (radar alone) against 0: MOTA 0.5914 -> 0.5997 (56 scenes better, 7 worse by 0.012 at most), false positives
    # 5,808 -> 5,248, matches 50,707 -> 50,651; 40 deg: 0.6004, 5,145 and 50,604, 10 worse by up to 0.027. Held out
    # (random:1001-1050), radar alone: MOTA 0.553 -> 0.561 (31 better, 5 worse by 0.0035 at most), worst scene
    # -0.451 -> -0.423, false track-frames 17.5 -> 16.2 % of matches; the LiDAR alone and fused identical.
    piece_course_tolerance_deg: float = 25.0

    def __post_init__(self) -> None:
        no_nan(self)
        positive(self, "distance_gate_m", allow_inf=True)
        positive(self, "piece_along_m", "piece_across_m", "piece_min_speed_mps", allow_zero=True)
        if not 0.0 <= self.piece_course_tolerance_deg < 90.0:
            raise ConfigError(
                "AssociationConfig.piece_course_tolerance_deg: must be within [0, 90), "
                f"got {self.piece_course_tolerance_deg!r}"
            )
        positive(
            self,
            "merge_gap_m",
            "merge_doppler_tolerance_mps",
            "merge_turn_rate_sigmas",
            "recovery_gate_m",
            "update_single_return_range_m",
            "duplicate_distance_m",
            "duplicate_velocity_mps",
            "duplicate_velocity_chi2",
            allow_zero=True,
            allow_inf=True,
        )
        share(self, "duplicate_iou")


@dataclass(frozen=True)
class BirthConfig:
    """Where a cluster may start a track (not in the paper, which starts one from every unassigned cluster)."""

    # Loose returns of this many frames are clustered together to start tracks on far, sparse boats
    # (RadarTracker._pooled_births). 1: one frame, as the paper.
    window_frames: int = 3
    pool_min_range_m: float = 20.0  # only returns this far are pooled (clutter is dense near the radar)
    # Sea clutter is densest next to the boat, where a real hull gives the most returns. A new cluster nearer than
    # near_range_m (median range of its returns) starts a track only with near_min_points returns; 3-return clutter
    # clusters there otherwise confirm now and then on a lucky 3 of 5 and coast a second at the bow. An object giving
    # fewer returns this close (a small buoy) is left to the LiDAR, which sees best there; a boat approaching is
    # tracked from farther out. 0 disables.
    near_range_m: float = 10.0
    near_min_points: int = 5

    def __post_init__(self) -> None:
        no_nan(self)
        positive(self, "pool_min_range_m", "near_range_m", "near_min_points", allow_zero=True, allow_inf=True)
        at_least_one(self, "window_frames")


@dataclass(frozen=True)
class ExistenceConfig:
    """Existence against the measured clutter (not in the paper; tracker.existence).

    A track counts the returns in its predicted box grown by pad_m every frame; the sea's clutter density at its
    range, measured over clutter_time_constant_s and times clutter_peak (rough water gathers its clutter on the
    crests), says how many clutter alone would put there. Over its last window_frames frames (birth excluded) the
    Poisson chance of clutter giving as many must be at most confirm_tail to confirm it; a confirmed track whose
    chance rises above keep_tail is dropped. The static map's cells must beat the clutter the same way to count as
    shore. The tails at 1: off, as the paper (M of N alone); the daemon turns it on (daemon/tracker_adapters.py)."""

    confirm_tail: float = 1.0
    keep_tail: float = 1.0
    # A cluster starts a track only if clutter explains its returns with at most this chance (the same Poisson test
    # over its box grown by pad_m, one frame; births pooled over frames with the clutter of as many). Where clutter
    # is that dense no track of its returns would ever be confirmed; started, each cost an update a frame until it
    # was deleted (the worst-case load: 357 tracks in 12 s, 18 confirmed, three of four updates spent on clutter).
    # 1: off, as the paper.
    birth_tail: float = 1.0
    clutter_peak: float = 1.0
    window_frames: int = 10
    pad_m: float = 1.0
    clutter_time_constant_s: float = 3.0

    def __post_init__(self) -> None:
        no_nan(self)
        positive(self, "clutter_time_constant_s", "clutter_peak", allow_inf=True)
        positive(self, "pad_m", allow_zero=True, allow_inf=True)
        at_least_one(self, "window_frames")
        share(self, "confirm_tail", "keep_tail", "birth_tail")


@dataclass
class RadarLifecycleConfig(LifecycleConfig):
    """The shared lifecycle (tracker.lifecycle) with the radar's coasting times."""

    max_unseen_time: float = 2.0
    # Not in the paper: a confirmed track coasts this long while in a nearer object's shadow (OcclusionConfig); 0: as
    # in the open.
    max_unseen_time_occluded: float = 4.0


@dataclass(frozen=True)
class MotionDiscriminatorConfig:
    """The five-level motion discriminator (eq. 8, Table 1)."""

    enabled: bool = True  # ablation switch ("Remove Motion Discriminator", Table 4)
    # c in eq. 8, not given in the paper. Chosen on synthetic 3 m boats with 6-20 returns per frame: hull IoU at rest
    # is 0.6-0.9 over a 0.25 s group, 0.3-0.5 after 1 m of motion. Erring high reports a sparse static boat as dynamic
    # (its filter speed, near zero) rather than a slow boat as static (speed zero).
    iou_threshold: float = 0.6
    # The "point group" of eq. 8 is the track's returns of this long (0: one frame). Not in the paper.
    group_window_s: float = 0.25
    # Not in the paper: a cluster whose Doppler speed is clearly above EgoMotionConfig.static_doppler_threshold_mps
    # counts as "moved" in eq. 8 whatever its hull overlap, so a slow boat is not published at zero speed.
    doppler_veto: bool = True
    # The veto needs the cluster's Doppler speed this far above zero plus 3 sigma, sigma counting the profile fit and
    # the own boat's velocity error (EgoMotionConfig.velocity_std_mps). At 0 it is a plain 3-sigma test: a 0.5 m/s
    # boat overlaps its hull of a second ago by ~0.7 and, without the veto, was published at speed zero.
    veto_speed_mps: float = 0.0
    # Not in the paper: the same veto from the track's filter, whose velocity integrates the Doppler and the positions
    # over seconds: a boat crossing the line of sight has no Doppler to veto with, and at 0.5 m/s its hull of a
    # second ago still overlaps. Speed above filter_veto_speed_mps and this many sigmas (a vote, not a verdict: the
    # counter needs many of them, and a moored boat's filter speed rarely clears 0.2 m/s); 0: off. Independent of
    # doppler_veto.
    filter_veto_sigmas: float = 1.5
    filter_veto_speed_mps: float = 0.2
    # The paper compares consecutive frames (set 0 for that). At 10 Hz a 2 m/s boat moves 0.2 m per frame, less than
    # the frame-to-frame jitter of a sparse radar hull, so by default a hull is compared with the one >= 1 s older.
    hull_baseline_s: float = 1.0
    absolutely_static_max: int = -6  # Table 1: D <= -6
    static_max: int = -3  # Table 1: -6 < D <= -3
    dynamic_min: int = 3  # Table 1: 3 <= D < 6
    absolutely_dynamic_min: int = 6  # Table 1: D >= 6
    counter_limit: int = 6  # |D| is clamped here so a long-moored boat that casts off is seen leaving
    hull_point_pad_m: float = 0.15  # each point is a square of this half-size: hulls of 1-2 points stay areas
    # The hulls of eq. 8 as qhull's convex hulls (True, the paper's) or as support polygons in 16 directions along the
    # reference group's principal axes (False: the IoU within a few hundredths of qhull's on radar point groups, a
    # quarter of the cost; tracker.radar.hull).
    hull_exact: bool = False

    def __post_init__(self) -> None:
        no_nan(self)
        positive(
            self,
            "group_window_s",
            "veto_speed_mps",
            "filter_veto_sigmas",
            "filter_veto_speed_mps",
            "hull_baseline_s",
            "hull_point_pad_m",
            allow_zero=True,
            allow_inf=True,
        )
        share(self, "iou_threshold")
        if not self.absolutely_static_max < self.static_max < self.dynamic_min < self.absolutely_dynamic_min:
            raise ConfigError("MotionDiscriminatorConfig: motion thresholds must increase (Table 1)")
        if self.counter_limit < max(-self.absolutely_static_max, self.absolutely_dynamic_min):
            raise ConfigError("MotionDiscriminatorConfig.counter_limit must reach both 'absolute' levels")


@dataclass(frozen=True)
class RadarTrackerConfig:
    """The radar tracker's groups, in the order a frame meets them, and the facts of the mount."""

    # Radar origin in body FRD (x fwd, y stbd), metres: line of sight and lever-arm velocity start here.
    sensor_position_body: tuple[float, float] = (0.0, 0.0)
    sensor_yaw_body_rad: float = 0.0  # radar boresight in body FRD (0 = bow, + starboard): centre of the ROI sector
    # The chirp profile's unambiguous radial speed (m/s, drivers.awr1843.profile max_velocity_mps): a Doppler beyond
    # +-this wraps round. With it, each return's speed over ground is taken in [-this, this) (see detector.py);
    # 0: the Doppler is taken as measured.
    max_radial_speed_mps: float = 0.0
    roi: RoiConfig = field(default_factory=RoiConfig)
    ego: EgoMotionConfig = field(default_factory=EgoMotionConfig)
    clustering: ClusteringConfig = field(default_factory=ClusteringConfig)
    shore: ShoreConfig = field(default_factory=ShoreConfig)
    multipath: MultipathConfig = field(default_factory=MultipathConfig)
    velocity: VelocityProfileConfig = field(default_factory=VelocityProfileConfig)
    kalman: KalmanConfig = field(default_factory=KalmanConfig)
    doppler: DopplerMeasurementConfig = field(default_factory=DopplerMeasurementConfig)
    visible_side: VisibleSideConfig = field(default_factory=VisibleSideConfig)
    occlusion: OcclusionConfig = field(default_factory=OcclusionConfig)
    association: AssociationConfig = field(default_factory=AssociationConfig)
    births: BirthConfig = field(default_factory=BirthConfig)
    existence: ExistenceConfig = field(default_factory=ExistenceConfig)
    lifecycle: RadarLifecycleConfig = field(default_factory=RadarLifecycleConfig)
    motion: MotionDiscriminatorConfig = field(default_factory=MotionDiscriminatorConfig)
    seed: int = 0  # RANSAC sampling; fixed so a replay gives the same tracks

    def __post_init__(self) -> None:
        no_nan(self)
        if len(self.sensor_position_body) != 2:
            raise ConfigError("RadarTrackerConfig.sensor_position_body must be (x, y)")
        if self.max_radial_speed_mps < 0:
            raise ConfigError("RadarTrackerConfig.max_radial_speed_mps must be >= 0 (0: Doppler not unwrapped)")

    def replaced(self, **changes: Any) -> RadarTrackerConfig:
        """A copy with ``changes``: a group's name with a dict of its fields to change
        (``replaced(association={"merge_gap_m": 0.0})``), or a top-level field with its new value."""
        out = {
            name: replace(getattr(self, name), **value) if isinstance(value, dict) else value
            for name, value in changes.items()
        }
        return replace(self, **out)
