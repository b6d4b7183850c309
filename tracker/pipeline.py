"""One perception cycle: newest LiDAR revolution + radar frames + ego pose -> tracks and the obstacle array.

Pure computation (no sockets, threads or clocks): the daemon's loop, the replay and the benchmarks all call
``PerceptionPipeline.step`` with the same inputs, so what is measured is what runs on the boat.

The obstacle array does not need the ego pose: it is built in the body frame from this cycle's solid returns
(LiDAR after the own-boat / water / spray filter, radar returns in clusters), the radar's shore contour and the
confirmed tracks' hulls. So a boat whose autopilot link is down still gets its obstacles; only tracking waits.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np

from drivers.frames import EgoPose, LidarScan, RadarFrame
from drivers.mount import Mount
from tracker.ego import body_to_world, body_to_world_2d, sample_poses, world_to_body_2d
from tracker.fusion import PublishedIds, fuse_track_groups, report_second_tracks_tentative
from tracker.lidar.coverage import (
    BIN_CENTRES,
    SUB_BEARINGS,
    BeamGeometry,
    band_intervals,
    bands_turned,
    bin_bearings,
    reach_from,
    swept_bins,
)
from tracker.lidar.hull_gate import on_tracked_hulls, tracked_hull_of
from tracker.lidar.water import WaterEstimate, WaterSurface
from tracker.obstacle_map import (
    BinnedPoints,
    SensorCoverage,
    bearing_bins,
    build_obstacle_distances,
    nearest_per_bin,
    outline_points,
)
from tracker.obstacle_memory import ObstacleMemory
from tracker.persistent_returns import CellRule, PersistenceRule, PersistentReturns, RecurringCells
from tracker.types import Track

log = logging.getLogger(__name__)
# m: a held solid this near remembered structure lies on it (the structure memory's cell; PipelineSettings
# .obstacle_hold_structure).
_ON_STRUCTURE_M = 0.5


class EgoSource(Protocol):
    """The boat's pose in the world frame at host times.

    ``at_many`` returns (positions (N,3) NED, roll, pitch, yaw) with NaN rows where the pose is not known.
    ``epoch`` changes whenever the world frame itself changes (autopilot appears, reboots, switches its origin):
    world-frame state must then be dropped. ``available`` is False in "no ego pose" mode (no autopilot yet), where
    the body frame at start serves as the world.
    """

    epoch: int
    available: bool

    def at_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]: ...

    def at(self, t: float) -> EgoPose | None: ...


# A sensor's returns as world (north, east) with the pose (position, yaw) they were measured at, or as body
# (fwd, stbd) with None when there was no pose to place them with; _at_tick puts either in the tick's body frame.
Placed = tuple[np.ndarray, tuple[np.ndarray, float] | None]


class LidarTrackerRole(Protocol):
    """What the pipeline asks of a LiDAR tracker (tracker/lidar/tracker.py's LidarTracker)."""

    def step(
        self,
        points_world: np.ndarray,
        t: float,
        own_position: np.ndarray,
        own_yaw: float = 0.0,
        point_times: np.ndarray | None = None,
    ) -> list[Track]: ...

    def on_structure(self, t: float, points_ne: np.ndarray, radius_m: float) -> np.ndarray:
        """(n,) bool: structure the LiDAR saw lies within ``radius_m`` of each world (north, east) point."""
        ...


class RadarTrackerRole(Protocol):
    """What the pipeline asks of a radar tracker (tracker/radar/tracker.py's RadarTracker)."""

    def step_frame(self, frame: RadarFrame, pose: EgoPose | None) -> list[Track]: ...

    def shore_points(self) -> np.ndarray:
        """(k, 2) world N/E of the shore contour the tracker keeps."""
        ...

    def shore_returns_world(self) -> np.ndarray:
        """(m, 2) world N/E of the last frame's returns judged shore."""
        ...


@dataclass(frozen=True)
class PipelineSettings:
    min_distance_m: float = 0.5
    max_distance_m: float = 100.0
    lidar_max_range_m: float = 100.0
    radar_fov_rad: float = np.radians(120.0)
    radar_yaw_rad: float = 0.0
    radar_pitch_rad: float = 0.0  # the radar's boresight above the deck plane (mount pitch, up positive)
    radar_max_range_m: float = 50.0
    fusion_gate_m: float = 3.0
    # A confirmed radar track straight behind a confirmed LiDAR track, as seen from the boat, within its half-size
    # plus this (m) beyond its centre and its half-size plus fusion_gate_m to the side, is the same hull: the LiDAR
    # returns only the face towards it (a boat end-on is tracked as its 3 m stern), the radar's scatterers lie along
    # the whole hull, and the LiDAR cannot see past that face anyway. 0 turns it off. Ours; held out
    # (random:1001-1050, fused), together with the wider gate (extents, not centres), the unsettled-motion rule below
    # and the LiDAR's duplicate_shadow_m: MOTA 0.880 -> 0.888, false track-frames 6.5 -> 5.2 % of matches; on its
    # own, tuning seeds 1-16: MOTA 0.9074 -> 0.9082.
    fusion_shadow_m: float = 10.0
    # While the LiDAR delivers, the radar speaks alone (its tracks no LiDAR track holds, its shore, its shore returns)
    # only where the LiDAR's beams do not vouch that they would have returned a solid (None), or only beyond this
    # range (m). Where the beams vouch and returned nothing, a radar-only object is clutter or a ghost far more
    # often than a hull the LiDAR missed; where they do not (the gap between the lowest beams in which a low hull
    # hides, 30-63 m for a 0.5 m hull under a VLP-16 1.6 m up; beyond the LiDAR's range in rain), the radar is the
    # only sensor that can see it, and its field of view counts toward "clear" there. With the LiDAR blind, the
    # radar's tracks and shore are obstacles everywhere.
    radar_alone_beyond_m: float | None = None
    # A radar track no LiDAR track holds, lying within this (m) of structure the LiDAR saw (a quay and the land behind
    # it, tracker.lidar.structure), is that structure: a quay face returns the radar's chirps as strongly as a hull,
    # and its returns wander along the wall. Its solid is in the obstacle array already, from the LiDAR's returns.
    # Negative turns it off. Ours, the LiDAR fusion gate's 3 m; held out (random:1001-1050, fused) against off: MOTA
    # 0.798 -> 0.810, false track-frames 10.5 -> 8.7 % of matches, 16 scenes better and none worse; bins unchanged.
    radar_on_structure_gate_m: float = 3.0
    # A radar track no LiDAR track holds, seen through structure the LiDAR saw (its line of sight from the boat crosses
    # a remembered quay), is a ghost: the chirps of a hull reflected off the quay face come back from behind it, and
    # the radar, mounted below the quay's top, cannot see a hull there. Treated as on structure (an outline, no
    # vessel). Ours (tuning seeds 85, 75: radar-only "vessels" 12-16 m behind a quay face); held out (random:1001-1050,
    # fused) against off: MOTA 0.94972 -> 0.95005, false positives 3,408 -> 3,333, 3 scenes better, none worse;
    # matches and bins unchanged.
    radar_behind_structure: bool = True
    # While the LiDAR delivers, a radar-only track younger than this (s), or whose motion the discriminator has not
    # yet settled (velocity NaN: state "wait"), keeps its outline in the obstacle array but is not sent as a vessel:
    # clutter that happens to confirm is gone within a second, a hull in the LiDAR's gap stays. Negative or 0 turns
    # the age rule off. Ours; held out (random:1001-1050, fused) against off: MOTA 0.861 -> 0.862, false
    # track-frames 8.0 -> 7.9 %, scenes where fused is below the LiDAR alone 17 -> 11; bins unchanged. The motion
    # rule: tuning seeds 1-16 fused MOTA 0.9059 -> 0.9074; held out together with fusion_shadow_m, see there.
    radar_alone_min_age_s: float = 1.0
    # An object keeps the id it was first sent under while the other sensor's track joins or leaves it
    # (tracker.fusion.PublishedIds): a boat the radar alone held in the LiDAR's gap is not a new vessel when the
    # LiDAR picks it up. False sends each object under its LiDAR track's id, or its radar track's when alone. Ours;
    # held out (random:1001-1050, fused) against False: id switches 9.3 -> 8.6 a scene, IDF1 0.908 -> 0.910, MOTA
    # 0.91205 -> 0.91226, 16 scenes better and none worse; bins unchanged.
    keep_published_ids: bool = True
    lidar_mount: Mount = field(default_factory=Mount)
    # Coverage (tracker/lidar/coverage.py): "clear" is sent only for a bin where a solid this tall above the water
    # would have been returned all the way from clear_inner_m (None: min_distance_m) out to max_distance_m.
    min_obstacle_height_m: float = 0.5
    clear_inner_m: float | None = None
    lidar_origin_height_above_water_m: float = 0.0  # body origin above the waterline: [boat] water_z_m (z down)
    radar_height_m: float = 0.9  # radar above the waterline
    # The radar's place on the deck (body forward, starboard, m) and the detector's nearest range (its ROI): a
    # sensor off the body origin sees a bearing of the array from elsewhere, and near the boat at another azimuth.
    radar_offset_fwd_stbd_m: tuple[float, float] = (0.0, 0.0)
    radar_min_range_m: float = 0.0
    # Half the AWR1843BOOST's elevation beam: a low solid nearer than (height - obstacle) / tan(this) passes under it.
    radar_half_vfov_rad: float = np.radians(15.0)
    # Returns within the sea margin inside a confirmed LiDAR track's footprint, grown by this (m), are its hull and
    # reach the obstacle array (tracker/lidar/hull_gate.py); negative turns it off. Held out (random:1001-1025, LiDAR
    # only), switching it off: false-clear bins 1,680 -> 2,004 a scene, false-obstacle bins 0.12 % -> 0.09 %.
    hull_margin_grow_m: float = 0.5
    # ... of a track measured at least this many times: the box of a track confirmed on its second detection
    # (tracker.lidar LidarLifecycleConfig.confirm_hits_alone) is still biased towards the sensor (a hull seen from
    # one side), and grown by hull_margin_grow_m it took in crest returns 0.4 m in front of the hull
    # (tests/test_sim_sea.py). The paper's 3, as in 3 of 5.
    hull_gate_min_hits: int = 3
    # ... and grown further, for a coasting track, by how far its prediction moved since it was last measured, up
    # to this (m); 0 turns it off. A hull sunk into the margin stops feeding its track, whose prediction then drifts
    # off it (a buoy's track 1.1 m beyond it in tuning seed 50). Ours; held out (random:1001-1050, fused) against 0:
    # false-clear bins 568 -> 557 (3 scenes better, none worse), false-obstacle bins 0.259 -> 0.261 %, tracking
    # unchanged. 1.5 m did as well on tuning seeds 45-52 (92 -> 68 bins against 67).
    hull_coast_drift_cap_m: float = 3.0
    # A bin that would go out "unknown" shows the nearest solid the sensors returned in it within this many seconds
    # (tracker/obstacle_memory.py): a low hull whose returns fall in and out of the sea margin from one sweep to the
    # next stays in ArduPilot's boundary. Never over a measured obstacle or a vouched "clear". 0 turns it off. Ours,
    # the autopilots' own 0.5 s data timeout; held out (random:1001-1050, fused) against 0: false-clear bins 55.1 ->
    # 17.8 a scene, 47 scenes better and none worse, false-obstacle bins 0.10 -> 0.17 %, tracking unchanged. A bin is
    # held by its nearest solid and its two nearest its edges (a hull ending just inside a bin, held by its nearest
    # point alone, left the bin once the boat moved): held out (random:1001-1050, fused) against the nearest alone,
    # false-clear bins 557 -> 449 (33 scenes better, none worse), false-obstacle bins 0.26 -> 0.27 %.
    obstacle_hold_s: float = 0.5
    # ... and a solid that lay on the hull of a confirmed track the LiDAR holds (source lidar or fused; footprint
    # grown by 1 m), moved on by the track's velocity, this long (s): it was a hull, not spray or a crest, and a low
    # hull in the LiDAR's blind gap or in a sea-state-3 chop drops out of the sweeps for longer than 0.5 s. Ours;
    # tuning seeds 45-52 (fused) against 0.5 (false-clear / false-obstacle bins): 50 / 619 -> 1 s 36 / 641, 1.5 s
    # 32 / 698, 2 s 31 / 790; on radar-only tracks' hulls as well (radar alone) 100,294 / 2,736 -> 98,589 / 4,504.
    # Held out (random:1001-1050) against 0.5 s: fused false-clear bins 359 -> 267, false-obstacle 0.273 -> 0.293 %.
    obstacle_hull_hold_s: float = 1.0
    # An obstacle bin shows a LiDAR return that lay on a LiDAR-held confirmed track's hull in a revolution of the last
    # this many seconds, moved on by the track's velocity, where that is nearer than what the bin holds now
    # (tracker/obstacle_memory.py): one revolution missing a hull's end in a bin (a laser dropping out, a bow in a
    # wave's shadow, the edge of a hull moving across a bin) sent the quay behind a boat 8 m off. 0 turns it off.
    # Ours, two revolutions; tuning seeds 1-40 (fused) against 0: too-far bins 499 -> 302 (27 scenes better, none
    # worse), false-obstacle bins 2,802 -> 2,866; 0.35 s: 265 and 2,909 (a false obstacle for each too-far bin
    # saved). Track outlines instead of returns: too-far 316 but false-obstacle 14,626 (an outline is an estimate).
    obstacle_hull_nearer_s: float = 0.25
    # A solid on structure the LiDAR remembers (a quay; tracker.lidar.structure) is held obstacle_hull_hold_s too: a
    # quay does not move, and a far one met at grazing incidence by one beam comes and goes between revolutions.
    # Ours; tuning seeds 45-68 (fused): false-clear bins 122 -> 102, false-obstacle 2,730 -> 2,737. Held out
    # (random:1001-1050) against off: fused false-clear bins 269 -> 177, false-obstacle bins and tracking unchanged.
    obstacle_hold_structure: bool = True
    # A bin that would go out unknown (no solid in it, not vouched clear) shows the range of a returned solid in a
    # neighbouring bin lying within this (m, across the line of sight) of their shared edge (obstacle_map.py). A
    # return's bearing at the tick is uncertain by what moved since it was fired: a revolution is up to 0.2 s old
    # when sent, 0.5 m for a hull crossing at 2.5 m/s, and ArduPilot drops unknown bins, so a hull's edge in the
    # next bin went out as nothing there. 0 turns it off. Ours; tuning seeds 45-100 (fused), 0.25 / 0.5 / 1 m
    # against 0: false-clear bins 754 -> 593 / 501 / 422, false-obstacle bins 5,379 -> 5,545 / 5,722 / 6,312,
    # tracking unchanged. Held out (random:1001-1050, fused) against 0: false-clear bins 846 -> 599 (17 -> 12 a scene,
    # 43 scenes better, none worse), false-obstacle bins 0.18 -> 0.19 % of bins.
    bin_edge_m: float = 0.5
    # A confirmed track whose centre lies within this (m) of the box of an older confirmed track at least as long,
    # the two not moving apart by more than second_track_speed_difference_mps (m/s, where both velocities are
    # known), is reported tentative: a piece of that hull, not a second vessel (tracker.fusion). Applied to what is
    # published, after the obstacle array. Negative turns it off. Ours, the evaluation's 2 m match distance;
    # tuning seeds 45-100 (fused) against off: false positives 4,832 -> 4,744, MOTA 0.9431 -> 0.9437, 18 scenes
    # better, 3 worse (random:53 -0.0014); without the speed test 21 better and 5 worse, a USV crossing 1.5 m
    # past a moored boat's box taken for its piece; at 3 m, 26 better and 4 worse (random:54: two boats at
    # anchor 1.3 m apart, -0.007). Held out (random:1001-1050, fused) against off: MOTA 0.9408 -> 0.9413, false
    # positives 5,221 -> 5,083, 13 scenes better and 2 worse (-0.001 at most), bins and id switches unchanged.
    second_track_gap_m: float = 2.0
    second_track_speed_difference_mps: float = 1.0
    # ... unless both tracks are at least this old (s): a piece of a hull is caught within its first seconds, while
    # a buoy or a small boat at anchor a metre or two off a bigger one (tuning seeds 54 and 61) keeps its place
    # beside it for minutes, and was reported tentative all that time. The LiDAR tracker's own test for two tracks
    # on one hull exempts them the same way (AssociationConfig.duplicate_shadow_settled_s, 5 s). Ours; tuning seeds
    # 45-68 (fused) against none: MOTA 0.9516 -> 0.9521, 3 scenes better, none worse (2 s: 0.9524, 3 better, one
    # worse). Held out (random:1001-1050, fused) against none: MOTA 0.9406 -> 0.9407, worst scene 0.609 -> 0.611.
    second_track_settled_s: float = 5.0
    # A confirmed LiDAR track the radar did not track, sitting where the LiDAR's beams cannot vouch for its range
    # (a low hull in the gap between the lowest beams, 30-63 m), is an obstacle, its outline, in the bins where the
    # radar's newest frame returned something inside its box grown by this (m): the radar seconds what the LiDAR can
    # no longer see. A sparse hull (1-3 radar returns a frame) forms no radar track, so the fusion above never pairs
    # them, and those bins went out unknown with a hull in them. Negative turns it off. Ours; tuning seeds 45-52
    # (fused) against off: false-clear bins 181 -> 92, false-obstacle bins 522 -> 575 (a circle round the box
    # instead: 91 and 621; the whole outline: 79 and 1,030; the radar's returns instead of the outline: 86 and
    # 2,833). Held out (random:1001-1050, fused) against off: false-clear bins 771 -> 568 (15.4 -> 11.4 a scene, 33
    # scenes better, none worse), false-obstacle bins 0.207 -> 0.259 % (worst scene 1.03 -> 1.47 %, sea state 3),
    # tracking identical.
    radar_corroboration_gate_m: float = 0.5
    # A radar return the radar gave again within 1 m (world frame) in 4 of its previous 5 frames, 30 m or more off,
    # is an obstacle where the LiDAR's beams do not vouch (tracker/persistent_returns.py): a small USV, a buoy or a
    # quay face in the LiDAR's blind gap returns 2-5 points a frame, too few to confirm a radar track, and its bins
    # went out unknown. None turns it off. Ours; tuning seeds 45-52 against off: fused false-clear bins 58 -> 50,
    # false-obstacle bins 606 -> 619; radar alone 100,635 -> 100,294 and 2,743 -> 2,736 (tentative radar tracks of
    # 2 hits instead, fused: 53 and 1,860). Held out (random:1001-1050) against off: fused false-clear bins 449 ->
    # 359 (18 scenes better, none worse), false-obstacle bins 0.270 -> 0.273 %; radar alone 202 -> 166 a scene. From
    # the start, every frame so far (at least 1) until there are 4: see PersistenceRule.
    radar_persistence: PersistenceRule | None = field(default_factory=PersistenceRule)
    # A radar return 40 m or more off whose 2 m world cell (grown by 0.5 m) held a radar return in 8 of the previous
    # 20 frames is an obstacle where the LiDAR's beams do not vouch, as radar_persistence's returns are
    # (tracker/persistent_returns.py RecurringCells): a quay or a boat at anchor near the radar's range edge returns
    # 0-3 points a frame that wander a metre or two along its face, seldom 4 frames of 5 within one metre, and its
    # bins went out unknown for seconds. Clutter there (7-8 returns a frame over 40-51 m) leaves 1.3 hits in such a
    # cell over 20 frames: 8 by chance is about 1 in 20,000. None turns it off. Ours; tuning seeds 12, 17, 23, 80,
    # 85, 87, 90, 95 (fused), false-clear / false-obstacle bins against off (151 / 869): 8 of 20 in 2 m cells from
    # 40 m 104 / 893; from 35 m 104 / 920; 6 of 20 95 / 1,056 (from 35 m 95 / 1,529); 10 of 20 118 / 877; 1.5 m
    # cells 110 / 878, 2.5 m 103 / 941; all 100 tuning seeds 301 / 8,588 -> 248 / 8,865, 7 scenes better and none
    # worse. Held out (random:1001-1050) against off: fused false-clear bins 151 -> 138 (4 scenes better, none
    # worse), false-obstacle bins 6,456 -> 6,656 (0.300 -> 0.309 %, worst scene 1.52 -> 1.54 %); radar alone
    # 8,056 -> 7,440 (48 scenes better, none worse) and 0.54 -> 0.55 %; tracking and the LiDAR alone unchanged.
    radar_recurrence: CellRule | None = field(
        default_factory=lambda: CellRule(hits=8, frames=20, cell_m=2.0, edge_m=0.5, beyond_m=40.0)
    )
    # A LiDAR return within the sea margin (neither water nor solid by height: preprocess's within_margin_world)
    # that the LiDAR gave in the same 0.3 m cell (world frame) in 4 of its previous 5 revolutions, 12 m or more off,
    # on a laser whose sea is sparse, is an obstacle in the bins (not tracking evidence): a 0.6 m buoy in a sea whose
    # crests stand 0.3 m lies inside a margin of 0.5-0.7 m, and its bins went out unknown with the buoy returned in
    # every revolution. Water seldom holds still: a crest runs 2-5 m/s, so the place where a beam meets one moves
    # 0.2-0.5 m a revolution. But where a laser's sea returns firing after firing (the grazing-line rule's judgement,
    # preprocess.within_margin_sparse) its returns are a band that keeps meeting the same cells by chance, and a sea
    # standing still (tests/sea_geometry.py's chop) recurs everywhere: there, 30-90 % of the firings returning under a
    # listing or rolling boat, the rule without that condition put obstacles at 14-39 m within four revolutions.
    # Nearer than 12 m the steep beams meet the water by the hundred. None turns it off. Ours; tuning seeds 45-68
    # (fused) against off: false-clear bins 102 -> 58, false-obstacle bins 2,693 both (0.5 m in 4 of 5 from 10 m:
    # 58 and 4,099; 0.3 m in 5 of 5 from 10 m: 67 and 2,720). Held out (random:1001-1050) against off: fused
    # false-clear bins 177 -> 165 (none worse), false-obstacle bins 6,220 -> 6,221; the LiDAR alone 89 -> 77.
    lidar_margin_persistence: CellRule | None = field(default_factory=CellRule)


@dataclass
class PerceptionOutput:
    t: float
    tracks: list[Track]
    distances_cm: np.ndarray  # (72,) uint16, ready for OBSTACLE_DISTANCE
    lidar_fresh: bool
    radar_fresh: bool
    ego_available: bool = False
    n_lidar_points: int = 0
    n_radar_points: int = 0
    timings_ms: dict[str, float] = field(default_factory=dict)
    solid_points_body: np.ndarray | None = None  # (M, 2) fwd/stbd, for pictures
    # (72,) m per bin: out to where the live sensors vouch that a solid min_obstacle_height_m tall would have been
    # returned (0: nowhere). A bin is sent "clear" only when this reaches max_distance_m.
    clear_to_m: np.ndarray = field(default_factory=lambda: np.zeros(72))
    # (72,) bool: bins whose obstacle is a solid held from an earlier sweep (tracker/obstacle_memory.py), not this one
    held_bins: np.ndarray = field(default_factory=lambda: np.zeros(72, dtype=bool))
    # Trackers ("lidar", "radar") skipped this cycle to keep the obstacle array inside its deadline: their tracks
    # coasted, the array came from this cycle's returns and the tracks as they were.
    tracking_skipped: tuple[str, ...] = ()
    # False when an ego source is in use but had no pose for the tick (lost, or not covering the data's times)
    pose_known: bool = True


class TrackingCost:
    """The time a tracker is expected to take this cycle: the recent worst, decaying by ``decay`` each cycle.

    The decay is what brings a skipped tracker back: under a lasting overload it runs every few cycles (each run
    measures it afresh), not never; after one slow cycle it is trusted again within a second.
    """

    def __init__(self, decay: float = 0.8) -> None:
        self.decay = decay
        self.expected_s = 0.0
        self._first = True

    def measured(self, seconds: float) -> None:
        if self._first:
            # A tracker's first run pays for its lazy imports and first allocations (at the worst-case load 51
            # against 22-27 ms after): taken as the expectation, it skipped the next cycles' tracking at start.
            self._first = False
            return
        self.expected_s = max(self.expected_s * self.decay, seconds)

    def skipped(self) -> None:
        self.expected_s *= self.decay


def _timed(timings: dict[str, float], key: str, fn: Callable[[], Any]) -> Any:
    t0 = time.perf_counter()
    out = fn()
    timings[key] = timings.get(key, 0.0) + (time.perf_counter() - t0) * 1e3
    return out


IDENTITY = (np.zeros(3), 0.0, 0.0, 0.0)


@dataclass
class PerceptionPipeline:
    settings: PipelineSettings = field(default_factory=PipelineSettings)
    lidar_tracker_factory: Callable[[], LidarTrackerRole] | None = None
    radar_tracker_factory: Callable[[], RadarTrackerRole] | None = None
    lidar_preprocess_config: Any = None
    freshness_s: float = 0.5

    def __post_init__(self) -> None:
        self._last_lidar_t = -np.inf
        self._last_radar_t = -np.inf
        self._lidar_coverage = SensorCoverage(0.0, 2 * np.pi, self.settings.lidar_max_range_m)
        # newest revolution's beam bands per bearing (lo, hi), in the body frame of its solid returns' pose
        self._lidar_bands = _no_bands()
        self._lidar_bands_now = self._lidar_bands  # turned to the tick's heading (step)
        # the newest revolution's solid returns (placed with the pose at the sweep's end), the newest radar frame's
        # solid returns and all its returns (with the frame's pose)
        self._lidar_solid: Placed = (np.empty((0, 2)), None)
        self._radar_solid: Placed = (np.empty((0, 2)), None)
        self._radar_returns: Placed = (np.empty((0, 2)), None)
        # the newest radar frame's persistent returns (tracker/persistent_returns.py), placed like its returns
        self._radar_persistent: Placed = (np.empty((0, 2)), None)
        # the rules that keep the radar's recent frames to find the returns that stay put (none: nothing kept)
        rule, recurrence = self.settings.radar_persistence, self.settings.radar_recurrence
        self._radar_memories: list[PersistentReturns | RecurringCells] = [
            *([PersistentReturns(rule)] if rule is not None else []),
            *([RecurringCells(recurrence)] if recurrence is not None else []),
        ]
        cells = self.settings.lidar_margin_persistence
        self._lidar_margin_history = RecurringCells(cells) if cells is not None else None
        self._radar_tracked = True  # the newest radar frame went through the tracker (not: no pose for it)
        self._radar_attitude = (0.0, 0.0)  # roll, pitch (rad) of the boat at the newest placed radar frame
        self._epoch: int | None = None
        self.lidar_tracker = self.lidar_tracker_factory() if self.lidar_tracker_factory else None
        self.radar_tracker = self.radar_tracker_factory() if self.radar_tracker_factory else None
        self._lidar_tracks: list[Track] = []
        self._radar_tracks: list[Track] = []
        self._published = PublishedIds()
        self._memory = ObstacleMemory()
        self._radar_on_structure: set[int] = set()  # radar tracks found on structure the LiDAR saw, while they live
        self.skipped_no_pose = 0
        cfg = self.lidar_preprocess_config
        # The water surface is a body-relative estimate: it survives a change of world frame.
        self.water = WaterSurface(cfg.water if cfg is not None else None)
        self.last_preprocess: Any = None
        self._cost = {"lidar": TrackingCost(), "radar": TrackingCost()}
        self._deadline: float | None = None
        self._skipped: list[str] = []
        self.tracking_skipped = {"lidar": 0, "radar": 0}
        self.world_resets = 0  # trackers made anew (world frame changed, or a failed cycle): the old ones are garbage
        # The live view (daemon/view) sets this: keep each tick's inputs and the LiDAR's per-point reasons. Off, the
        # cycle does nothing more than the boat needs.
        self.keep_view_detail = False
        self.last_scan: LidarScan | None = None  # this tick's revolution, None when none came
        self.last_radar_frames: list[RadarFrame] = []  # this tick's radar frames

    def reset_tracks(self) -> None:
        """Start the trackers afresh (tracks, maps), keeping the world frame: after a failed cycle, whose partial
        updates may have left a tracker inconsistent."""
        self._reset_world()

    def _reset_world(self) -> None:
        """The world frame changed: tracks and maps in the old frame are meaningless in the new one."""
        self.world_resets += 1
        if self.lidar_tracker_factory:
            self.lidar_tracker = self.lidar_tracker_factory()
        if self.radar_tracker_factory:
            self.radar_tracker = self.radar_tracker_factory()
        self._lidar_tracks, self._radar_tracks = [], []
        self._published.reset()
        self._memory.reset()
        self._radar_on_structure.clear()
        # What the sensors measured stays, moved into the body frame it was measured in: poses of the old world
        # frame mean nothing in the new one (nor may the coverage be turned by the heading difference between them).
        self._lidar_solid = _into_own_body(self._lidar_solid)
        self._radar_solid = _into_own_body(self._radar_solid)
        self._radar_returns = _into_own_body(self._radar_returns)
        self._radar_persistent = _into_own_body(self._radar_persistent)
        for history in (*self._radar_memories, self._lidar_margin_history):
            if history is not None:
                history.reset()

    def step(
        self,
        t: float,
        scan: LidarScan | None,
        radar_frames: Sequence[RadarFrame],
        ego: EgoSource | None,
        deadline: float | None = None,
    ) -> PerceptionOutput:
        """One cycle. ``deadline`` (time.perf_counter() seconds, None: none) is when the obstacle array must be
        ready: a tracker whose expected time would carry the cycle past it is skipped for this cycle (its tracks
        coast) and the output says so. Replays pass none, so that their output does not depend on the machine."""
        timings: dict[str, float] = {}
        self._deadline = deadline
        self._skipped = []
        s = self.settings
        solid: list[np.ndarray] = []
        n_lidar = n_radar = 0
        ego_ok = ego is not None and ego.available
        if self.keep_view_detail:
            self.last_scan = scan
            self.last_radar_frames = list(radar_frames)
        if ego is not None and ego.epoch != self._epoch:
            if self._epoch is not None:
                log.info("world frame changed (epoch %s -> %s): tracks restarted", self._epoch, ego.epoch)
                self._reset_world()
            self._epoch = ego.epoch

        if scan is not None:
            self._last_lidar_t = max(self._last_lidar_t, scan.stamp)
            self._lidar_coverage = lidar_coverage(scan, s)
            self._lidar_solid = (np.empty((0, 2)), None)
            self._lidar_bands = _no_bands()  # an empty revolution returned nothing: it vouches for nothing
            if scan.n_points:
                self._lidar_solid, n_lidar = _timed(timings, "lidar", lambda: self._lidar(scan, ego, ego_ok))
        for frame in radar_frames:
            self._last_radar_t = max(self._last_radar_t, frame.stamp)
            self._radar_solid, self._radar_returns = _timed(
                timings, "radar", lambda f=frame: self._radar(f, ego, ego_ok)
            )
            n_radar += frame.n_points
        # A tick with no new revolution (10 Hz sensor, 10 Hz loop: jitter) still reports what the newest one saw;
        # the returns are dropped with the sensor's freshness, never reused beyond it.
        lidar_fresh = t - self._last_lidar_t <= self.freshness_s
        radar_fresh = t - self._last_radar_t <= self.freshness_s
        own = _pose_now(ego, ego_ok, t)
        # the LiDAR's bands as the tick's body frame sees them: the radar's points are judged against them there
        lidar_turned = _turned_since(self._lidar_solid[1], own)
        self._lidar_bands_now = bands_turned(*self._lidar_bands, lidar_turned)
        lidar_at = len(solid) if lidar_fresh else None  # where the LiDAR's returns are among the solids
        if lidar_fresh:
            solid.append(_at_tick(self._lidar_solid, own))
        if radar_fresh:
            solid.append(self._radar_speaks(_at_tick(self._radar_solid, own), lidar_fresh))

        # A sensor that stopped delivering takes its tracks with it: a LiDAR track frozen at its last update would
        # otherwise absorb the radar's live track of the same boat, and the boat would drop out of the array.
        groups = fuse_track_groups(
            self._lidar_tracks if lidar_fresh else [],
            self._radar_tracks if radar_fresh else [],
            s.fusion_gate_m,
            None if own is None else own[0],
            s.fusion_shadow_m,
        )
        tracks = [tr for tr, _ in groups]
        # radar-only tracks on structure the LiDAR saw, or too young to be sent alone: obstacles, not vessels
        outline_only: list[Track] = []
        if own is not None and lidar_fresh and any(tr.source == "radar" for tr in tracks):
            alone = [tr for tr in tracks if tr.source == "radar"]
            world = np.array([tr.position[:2] for tr in alone])
            speaks = self._radar_speaks_at(world_to_body_2d(world, own[0][:2], own[3]), lidar_fresh)
            # and a piece of another radar track's hull (tracker.radar.pieces) left alone: an outline, no vessel
            no_vessel = np.array(
                [tr.age < s.radar_alone_min_age_s or not tr.speed_valid or tr.part_of is not None for tr in alone]
            )
            if self.lidar_tracker is not None and s.radar_on_structure_gate_m >= 0:
                # Once on the quay, always the quay's: the echo of a face wanders along and off it (clutter at its
                # foot, multipath off it) and its track drifts metres out while the structure memory around it is
                # carved for a moored hull or not yet refreshed. A boat leaving a quay is the LiDAR's to report.
                # Tuning seeds 45-68, fused: MOTA 0.9569 -> 0.9573 (50 and 60 better, none worse), bins unchanged.
                on = self.lidar_tracker.on_structure(t, world, s.radar_on_structure_gate_m)
                if s.radar_behind_structure:
                    on |= self.lidar_tracker.behind_structure(t, world, own[0][:2])
                self._radar_on_structure &= {tr.id for tr in self._radar_tracks}
                self._radar_on_structure |= {tr.id for tr, q in zip(alone, on, strict=True) if q}
                no_vessel |= np.array([tr.id in self._radar_on_structure for tr in alone])
            no_vessel &= speaks
            outline_only = [tr for tr, q in zip(alone, no_vessel, strict=True) if q]
            muted = {id(tr) for tr, ok in zip(alone, speaks & ~no_vessel, strict=True) if not ok}
            tracks = [tr for tr in tracks if id(tr) not in muted]
        if any(tr.part_of is not None for tr in tracks):  # the LiDAR blind: a radar hull's pieces are its outline
            outline_only += [tr for tr in tracks if tr.part_of is not None]
            tracks = [tr for tr in tracks if tr.part_of is None]
        if own is not None:
            # Returns measured this cycle are the truth about a hull; an estimated outline is only added where the
            # LiDAR did not sweep the track's bearing this cycle (a partial sweep) or the radar saw it sparsely. A
            # LiDAR track coasting behind an occluder adds nothing: the occluder is nearer in those bins; and a
            # coasting prediction elsewhere (a quay piece taken for a vessel, a lost track) put false obstacles
            # round the boat in waves.
            swept = swept_at_tick(self._lidar_coverage, lidar_turned) if lidar_fresh else np.zeros(72, dtype=bool)
            lidar_confirmed = [tr for tr in tracks if tr.confirmed and tr.source != "radar"]
            unswept = {
                id(tr)
                for tr, hit in zip(lidar_confirmed, _swept_many(lidar_confirmed, own, swept), strict=True)
                if not hit
            }
            estimated = _outlines_in_body(
                [
                    tr
                    for tr in [*tracks, *outline_only]
                    if tr.confirmed
                    and (
                        (tr.source != "radar" and id(tr) in unswept)
                        or tr.source == "radar"  # the radar sees a hull sparsely; its track's outline stands for it
                    )
                ],
                own,
            )
            if estimated is not None:
                solid.append(estimated)
            # A hull both sensors confirm: where the LiDAR's beams cannot vouch for its range (its returns there lie
            # within the sea margin, or the hull sits in the beams' blind gap), its outline is what the radar says.
            # (Those a partial sweep missed are in whole already.)
            both = _outlines_in_body(
                [tr for tr in tracks if tr.confirmed and tr.source == "fused" and id(tr) not in unswept], own
            )
            if both is not None and radar_fresh:
                solid.append(self._radar_speaks(both, lidar_fresh))
            if radar_fresh and self._radar_tracked and s.radar_corroboration_gate_m >= 0:
                alone = [tr for tr in lidar_confirmed if tr.source == "lidar" and id(tr) not in unswept]
                seconded = self._radar_corroborated(alone, own, lidar_fresh)
                if len(seconded):
                    solid.append(seconded)
            if self.radar_tracker is not None and radar_fresh:
                shore = self.radar_tracker.shore_points()
                if len(shore):
                    solid.append(self._radar_speaks(world_to_body_2d(shore, own[0][:2], own[3]), lidar_fresh))
            if radar_fresh and self._radar_tracked and self._radar_memories:
                solid.append(self._radar_speaks(_at_tick(self._radar_persistent, own), lidar_fresh))

        radar_vouches = radar_fresh and self._radar_tracked
        clear_to = _timed(
            timings,
            "coverage",
            lambda: self._clear_to(lidar_fresh, _at_tick(self._radar_returns, own) if radar_vouches else None, own),
        )
        # each source's bearings once, for the array, the memory and the hull returns alike
        binned: list[BinnedPoints] = []

        def array() -> np.ndarray:
            binned.extend(BinnedPoints(np.asarray(p, float)[:, :2]) for p in solid)
            return build_obstacle_distances(binned, clear_to, s.min_distance_m, s.max_distance_m, s.bin_edge_m)

        distances = _timed(timings, "obstacle_map", array)
        held = np.zeros(72, dtype=bool)
        # the oldest of the live sensors' newest data: what this tick's array is made of is at least that recent
        fresh_times = [
            x for x, fresh in ((self._last_lidar_t, lidar_fresh), (self._last_radar_t, radar_fresh)) if fresh
        ]
        measured_at = min(fresh_times, default=-np.inf)
        solid_body = np.concatenate(solid) if solid else np.empty((0, 2))
        if own is not None and ego_ok:
            distances = _timed(
                timings,
                "obstacle_map",
                lambda: self._memory.fill_unknown(
                    t,
                    measured_at,
                    distances,
                    BinnedPoints.concat(binned),
                    (own[0][:2], own[3]),
                    tracks,
                    s.obstacle_hold_s,
                    s.min_distance_m,
                    s.max_distance_m,
                    s.obstacle_hull_hold_s,
                    self._structure_lookup(t),
                    lidar=(self._last_lidar_t, binned[lidar_at]) if lidar_at is not None else None,
                    hull_nearer_s=s.obstacle_hull_nearer_s,
                ),
            )
            held = self._memory.last_filled
        else:
            # Without the boat's pose a held solid cannot follow the boat's motion: it would keep its body bearing
            # while the boat turns. The pose's return starts a new world frame, which empties the memory anyway.
            self._memory.reset()
        if s.keep_published_ids:
            members = {id(tr): m for tr, m in groups}
            held_groups = self._published.hold_coasting_partners(
                [(tr, members[id(tr)]) for tr in tracks], s.fusion_gate_m
            )
            tracks = self._published.publish(t, held_groups)
        tracks = report_second_tracks_tentative(
            tracks, s.second_track_gap_m, s.second_track_speed_difference_mps, s.second_track_settled_s
        )
        if ego_ok and own is None:
            # No pose now: the trackers wait, and their tracks, frozen where they were last seen, are not news.
            tracks = [replace(tr, confirmed=False) if tr.confirmed else tr for tr in tracks]
        return PerceptionOutput(
            t=t,
            tracks=tracks,
            distances_cm=distances,
            lidar_fresh=lidar_fresh,
            radar_fresh=radar_fresh,
            ego_available=ego_ok,
            n_lidar_points=n_lidar,
            n_radar_points=n_radar,
            timings_ms=timings,
            solid_points_body=solid_body,
            clear_to_m=clear_to,
            held_bins=held,
            tracking_skipped=tuple(dict.fromkeys(self._skipped)),
            pose_known=not (ego_ok and own is None),
        )

    def _structure_lookup(self, t: float) -> Callable[[np.ndarray], np.ndarray] | None:
        """For the obstacle memory: which world (north, east) points lie on structure the LiDAR remembers (within
        half a metre, its memory's cell), or None when that hold is off or there is no LiDAR."""
        if not self.settings.obstacle_hold_structure or self.lidar_tracker is None:
            return None
        tracker = self.lidar_tracker
        return lambda world: tracker.on_structure(t, world, _ON_STRUCTURE_M)

    def _radar_speaks_at(self, points_fwd_stbd: np.ndarray, lidar_fresh: bool) -> np.ndarray:
        """(n,) bool: the radar alone may put an obstacle at these body points (``radar_alone_beyond_m``): the LiDAR is
        not delivering, or its beams at the point's bin (centre bearing) do not vouch for the point's range."""
        n = len(points_fwd_stbd)
        if not lidar_fresh or n == 0:
            return np.ones(n, dtype=bool)
        r = np.hypot(points_fwd_stbd[:, 0], points_fwd_stbd[:, 1])
        if self.settings.radar_alone_beyond_m is not None:
            return r > self.settings.radar_alone_beyond_m
        b = bearing_bins(points_fwd_stbd)
        lo, hi = self._lidar_bands_now[0][BIN_CENTRES][b], self._lidar_bands_now[1][BIN_CENTRES][b]
        return ~np.any((lo <= r[:, None]) & (r[:, None] <= hi), axis=1)

    def _radar_speaks(self, points_fwd_stbd: np.ndarray, lidar_fresh: bool) -> np.ndarray:
        return points_fwd_stbd[self._radar_speaks_at(points_fwd_stbd, lidar_fresh)]

    def _radar_corroborated(
        self, tracks: list[Track], own: tuple[np.ndarray, float, float, float], lidar_fresh: bool
    ) -> np.ndarray:
        """(n, 2) body: the outlines of the ``tracks`` in the bins where the radar's newest frame returned something
        inside their box grown by radar_corroboration_gate_m, and only where the LiDAR's beams do not vouch (there,
        its silence wins). The per-track work is for the few tracks the radar seconds."""
        if not tracks:
            return np.empty((0, 2))
        returns = _at_tick(self._radar_returns, own)
        returns = returns[self._radar_speaks_at(returns, lidar_fresh)]
        if not len(returns):
            return returns
        owner = tracked_hull_of(
            body_to_world_2d(returns, own[0][:2], own[3]), tracks, self.settings.radar_corroboration_gate_m
        )
        out = []
        for k in np.unique(owner[owner >= 0]):
            outline = _outlines_in_body([tracks[k]], own)
            if outline is None:
                continue
            bins = np.zeros(72, dtype=bool)
            bins[bearing_bins(returns[owner == k])] = True
            outline = outline[bins[bearing_bins(outline)]]
            out.append(outline[self._radar_speaks_at(outline, lidar_fresh)])
        return np.concatenate(out) if out else np.empty((0, 2))

    def _may_track(self, sensor: str) -> bool:
        """Whether the ``sensor``'s tracker fits before the deadline this cycle; counts a skip when it does not."""
        if self._deadline is None or time.perf_counter() + self._cost[sensor].expected_s <= self._deadline:
            return True
        self._cost[sensor].skipped()
        self.tracking_skipped[sensor] += 1
        self._skipped.append(sensor)
        return False

    def _clear_to(
        self,
        lidar_fresh: bool,
        radar_returns: np.ndarray | None,
        own: tuple[np.ndarray, float, float, float] | None,
    ) -> np.ndarray:
        """(72,) m per bin out to which the live sensors vouch for "no solid": the union of the LiDAR's beam bands
        and the radar's field of view, walked outward without a gap from the inner edge; judged at three bearings
        per bin, the worst kept. ``radar_returns`` (n, 2) body fwd/stbd at the tick of the radar's newest frame, or
        None when the radar does not vouch (silent, or its frame could not be placed). ``own``: the pose at the tick,
        to whose heading each sensor's bands are turned from its measurement's (None: they stay as measured).

        The radar vouches in a bin only out to its nearest return there (or beside the bin's edge): its returns
        reach the array only as confirmed tracks and shore, so a hull it returned but has not yet confirmed would
        otherwise be sent as clear water (spec: never "clear" where a solid may lie)."""
        s = self.settings
        los, his = [], []
        if lidar_fresh:
            lo, hi = self._lidar_bands_now
            los.append(lo)
            his.append(hi)
        if radar_returns is not None:
            turned = _turned_since(self._radar_returns[1], own)
            lo, hi = bands_turned(*_radar_band(s, *self._radar_attitude), turned)
            returned = nearest_per_bin(radar_returns, s.bin_edge_m)  # already in the tick's body frame
            los.append(lo)
            his.append(np.minimum(hi, np.repeat(returned, SUB_BEARINGS.size)[:, None]))
        if not los:
            return np.zeros(72)
        inner = s.min_distance_m if s.clear_inner_m is None else s.clear_inner_m
        reach = reach_from(np.concatenate(los, axis=1), np.concatenate(his, axis=1), inner, s.max_distance_m)
        return reach.reshape(72, SUB_BEARINGS.size).min(axis=1)

    # ---- LiDAR ----------------------------------------------------------------------------------------------
    def _lidar(self, scan: LidarScan, ego: EgoSource | None, ego_ok: bool) -> tuple[Placed, int]:
        from tracker.lidar.preprocess import preprocess

        if ego_ok:
            assert ego is not None
            (pos, roll, pitch, yaw), index = sample_poses(ego, scan.t)
            known = np.isfinite(yaw) & np.isfinite(pos).all(axis=1)  # per pose sample, or per point
            if index is not None:
                known = known[index]
        else:
            (pos, roll, pitch, yaw), index = IDENTITY, None
            known = np.ones(scan.n_points, dtype=bool)
        cfg = self.lidar_preprocess_config
        # With part of the sweep's poses unknown the attitude is not trusted at all (the water fit absorbs up to
        # max_tilt of it, see preprocess below); ``roll`` may then be the sampled poses, not one per point, and must
        # not be broadcast.
        if not known.all():
            roll_pt = pitch_pt = np.zeros(scan.n_points)
        elif index is None:
            roll_pt, pitch_pt = np.broadcast_to(roll, (scan.n_points,)), np.broadcast_to(pitch, (scan.n_points,))
        else:
            roll_pt, pitch_pt = np.asarray(roll)[index], np.asarray(pitch)[index]
        beams, live, point_bin = beams_of(scan, roll_pt, pitch_pt, self.settings)
        if not known.all():
            # Pose lost (autopilot silent): obstacles still come from the body frame, tracking waits. The water
            # surface fit absorbs up to max_tilt of the attitude it no longer knows.
            pre = preprocess(
                scan.xyz,
                np.zeros(3),
                0.0,
                0.0,
                0.0,
                cfg,
                water=self.water,
                t=scan.stamp,
                ring=scan.ring,
                point_t=scan.t,
                reasons=self.keep_view_detail,
                beams=beams,
                bins=point_bin,
            )
            track_points = None
            self.skipped_no_pose += 1
        else:
            pre = preprocess(
                scan.xyz,
                pos,
                roll,
                pitch,
                yaw,
                cfg,
                pose_index=index,
                water=self.water,
                t=scan.stamp,
                ring=scan.ring,
                point_t=scan.t,
                reasons=self.keep_view_detail,
                beams=beams,
                bins=point_bin,
                on_hull=self._on_settled_hulls(),
            )
            track_points = pre.points_world
        self.last_preprocess = pre
        # One classification for the obstacle array and the tracker: each return's own attitude, the measured
        # water surface and the sea margin (tracker/lidar/water.py). The array takes horizontal ranges: world
        # returns, turned into the boat's heading at the tick (_lidar_solid_body; a rolled body frame would put a
        # return 1 m above the sensor 9 cm off at 5 deg; each return's own pose also undoes the boat's motion in the
        # sweep).
        own = _pose_now(ego, ego_ok, scan.stamp) if track_points is not None else IDENTITY
        own_pos, own_yaw = (own[0][:2], own[3]) if own is not None else (np.zeros(2), 0.0)
        if own is None:  # the pose at the sweep's end is unknown though each return's was: the sweep's last pose
            own_pos, own_yaw = np.asarray(pos, float).reshape(-1, 3)[-1, :2], float(np.ravel(yaw)[-1])
        solid = np.concatenate([pre.points_world[:, :2], pre.feet_world[:, :2]])
        # With the attitude unknown and no water surface measured this revolution to stand in for it, nothing is
        # vouched for until a pose or a fit is back: a boat heeled 5 deg has its beams meet the water nearer than a
        # level one's on the low side, so the level bands would vouch ranges no beam covered.
        guessed_level = not known.all() and pre.water.t != scan.stamp
        self._lidar_bands = _no_bands() if guessed_level else lidar_bands(beams, live, pre.water, self.settings)
        if self.lidar_tracker is not None and track_points is not None and self._may_track("lidar"):
            t0 = time.perf_counter()
            self._lidar_tracks = self.lidar_tracker.step(
                track_points,
                scan.stamp,
                own_pos,
                own_yaw,
                point_times=scan.t[pre.keep],
                sensor_ned=_sensor_ned(own, self.settings.lidar_mount),
            )
            self._cost["lidar"].measured(time.perf_counter() - t0)
        tracking = self.lidar_tracker is not None and track_points is not None
        if tracking and self.settings.hull_margin_grow_m >= 0 and pre.within_margin_world.shape[0]:
            low = pre.within_margin_world[:, :2]
            settled = self._settled_lidar_tracks()
            hull = low[
                on_tracked_hulls(low, settled, self.settings.hull_margin_grow_m, self.settings.hull_coast_drift_cap_m)
            ]
            if hull.shape[0]:
                solid = np.concatenate([solid, hull])
        if self._lidar_margin_history is not None and track_points is not None:
            recurring = self._persistent_in_margin(pre, own_pos)
            if recurring.shape[0]:  # seldom: the revolution's solids are not copied for nothing
                solid = np.concatenate([solid, recurring])
        # without the sweep's poses, preprocess placed the returns in the body frame (zero pose)
        return (solid, (own_pos, own_yaw) if track_points is not None else None), int(solid.shape[0])

    def _settled_lidar_tracks(self) -> list[Track]:
        """The LiDAR tracks measured hull_gate_min_hits times or more: the hulls the hull gate trusts (it takes the
        confirmed ones among them)."""
        return [tr for tr in self._lidar_tracks if tr.hits >= self.settings.hull_gate_min_hits]

    def _on_settled_hulls(self) -> Callable[[np.ndarray], np.ndarray] | None:
        """Which world (north, east) places lie on the hull of a settled confirmed LiDAR track (its box grown as
        the hull gate grows it), or None without such a track or with that gate off."""
        s = self.settings
        if self.lidar_tracker is None or s.hull_margin_grow_m < 0:
            return None
        settled = [tr for tr in self._settled_lidar_tracks() if tr.confirmed]
        if not settled:
            return None
        return lambda ne: on_tracked_hulls(ne, settled, s.hull_margin_grow_m, s.hull_coast_drift_cap_m)

    def _persistent_in_margin(self, pre: Any, own_pos: np.ndarray) -> np.ndarray:
        """The revolution's returns within the sea margin on lasers whose sea is sparse (world north, east) that recur
        at one place (settings.lidar_margin_persistence); only those are remembered, so the work follows them, not
        the water the steep beams meet by the hundred."""
        assert self._lidar_margin_history is not None
        points = pre.within_margin_world[:, :2]
        if pre.within_margin_sparse.size:
            points = points[pre.within_margin_sparse]
        ranges = np.hypot(points[:, 0] - own_pos[0], points[:, 1] - own_pos[1])
        return points[self._lidar_margin_history.add(points, ranges)]

    # ---- radar ----------------------------------------------------------------------------------------------
    def _radar(self, frame: RadarFrame, ego: EgoSource | None, ego_ok: bool) -> tuple[Placed, Placed]:
        """The frame's solid returns and all its returns, each as world (north, east) with the frame's pose (position,
        yaw), or as body (fwd, stbd) with None when there is no pose to place them with (_at_tick turns either into
        the body frame at the tick: a boat turning 30 deg/s turns 3 deg between a frame and the next tick)."""
        finite = np.all(np.isfinite(frame.xyz), axis=1)
        pose = _finite_pose(ego.at(frame.stamp)) if ego_ok and ego is not None else None
        if pose is not None and np.isfinite([pose.roll, pose.pitch]).all():
            self._radar_attitude = (float(pose.roll), float(pose.pitch))
        returns_body = frame.xyz[finite][:, :2]
        at = None if pose is None else (np.asarray(pose.position, float)[:2], float(pose.yaw))
        returns = (returns_body, None) if at is None else (body_to_world_2d(returns_body, *at), at)
        if self._radar_memories:
            # Persistence is judged in the world frame (with no autopilot at all, the body frame is the world, as
            # for the trackers); a frame whose pose is lost cannot be compared with the last and adds nothing.
            self._radar_persistent = (np.empty((0, 2)), None)
            if at is not None or not ego_ok:
                ranges = np.hypot(returns_body[:, 0], returns_body[:, 1])
                keep = np.zeros(len(ranges), dtype=bool)
                for history in self._radar_memories:
                    keep |= history.add(returns[0], ranges)
                self._radar_persistent = (returns[0][keep], at)
        if self.radar_tracker is None:
            return returns, returns
        if ego_ok and pose is None:
            # The pose is lost (autopilot silent): the tracker cannot place the frame, and the radar's raw returns
            # are mostly sea clutter; as obstacles they filled the bins near the boat (9 a tick instead of 0.3),
            # and the radar cannot vouch for "clear" either. Its bearings are unknown until the pose is back.
            self.skipped_no_pose += 1
            self._radar_tracked = False
            return (np.empty((0, 2)), None), returns
        self._radar_tracked = True
        if not self._may_track("radar"):
            # the frame's raw returns are mostly sea clutter near the boat: the shore and tracks as they were
            return self._radar_solid, returns
        t0 = time.perf_counter()
        self._radar_tracks = self.radar_tracker.step_frame(frame, pose)
        self._cost["radar"].measured(time.perf_counter() - t0)
        # Vessels reach the obstacle array as confirmed radar tracks (their hulls); returns go in directly only
        # where they are shore. A raw cluster is not enough: with the AWR1843's 3-10 returns per boat, clusters of
        # 3 returns are needed for tracking, and sea clutter near the boat forms such clusters every few frames.
        # A false obstacle stops the boat, so a radar vessel must first earn a confirmed track (0.3 s).
        # Without a pose the tracker's world is the body frame of the frame.
        return (self.radar_tracker.shore_returns_world(), at), returns


def _no_bands() -> tuple[np.ndarray, np.ndarray]:
    n = 72 * SUB_BEARINGS.size
    return np.full((n, 1), np.inf), np.full((n, 1), -np.inf)


def lidar_bands(
    beams: BeamGeometry, live: np.ndarray, water: WaterEstimate, s: PipelineSettings
) -> tuple[np.ndarray, np.ndarray]:
    """(216, 16) ranges where each beam would return a solid of min_obstacle_height_m at each judged bearing, above
    the measured water surface; empty for the bins not ``live`` (72,): not swept by the received packets or
    returning nothing at all."""
    elevation, height = beams.over_surface(water, s.lidar_origin_height_above_water_m)
    lo, hi = band_intervals(elevation, height, water.margin, s.min_obstacle_height_m, s.lidar_max_range_m)
    lo, hi = bands_in_body(lo, hi, (s.lidar_mount.x, s.lidar_mount.y))
    dead = ~np.repeat(live, SUB_BEARINGS.size)
    lo[dead], hi[dead] = np.inf, -np.inf
    return lo, hi


def bands_in_body(
    lo: np.ndarray, hi: np.ndarray, offset_fwd_stbd: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """(216, K) intervals of range from a sensor (at ``offset_fwd_stbd``, m, on the deck) along each judged bearing,
    as ranges from the body origin along the same bearing: the array's bins are judged from the body origin, and a
    band a LiDAR 2 m forward vouches for lies 2 m nearer astern of the origin. Along bearing b the point R u (u the
    bearing's direction) lies sqrt(R^2 - 2 R u.t + |t|^2) from the sensor at t; solved for its far root, monotone,
    so a bearing's bands keep their order and their joins (the near root, where the ray passes the sensor, is left
    out: less is vouched, never more). An empty interval (start > end) stays empty; infinite ends stay."""
    tf, ts = offset_fwd_stbd
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    if tf == 0.0 and ts == 0.0:
        return lo.copy(), hi.copy()
    bearings = bin_bearings()
    along = (tf * np.cos(bearings) + ts * np.sin(bearings))[:, None]

    def body(r: np.ndarray) -> np.ndarray:
        with np.errstate(invalid="ignore"):
            far_root = along + np.sqrt(np.maximum(r * r - (tf * tf + ts * ts) + along * along, 0.0))
        return np.where(np.isfinite(r), far_root, r)

    empty = ~(lo <= hi)
    lo_b, hi_b = body(np.maximum(lo, 0.0)), body(hi)
    lo_b[empty], hi_b[empty] = np.inf, -np.inf
    return lo_b, hi_b


def beams_of(
    scan: LidarScan, roll: np.ndarray, pitch: np.ndarray, s: PipelineSettings
) -> tuple[BeamGeometry, np.ndarray, np.ndarray]:
    """The revolution's beams, placed with the mean roll and pitch (per return, rad) at which each bin was swept,
    (72,) bool the bins that count as measured: swept by the received packets and returning something, and (N,)
    the bin of each return."""
    point_bin = bearing_bins(scan.xyz[:, :2])
    # A return without a finite position has no bearing (its NaN rounds to bin 0): it says nothing of any bin.
    placed = np.isfinite(scan.xyz).all(axis=1)
    if not placed.all():
        point_bin_placed, roll, pitch = point_bin[placed], np.asarray(roll)[placed], np.asarray(pitch)[placed]
    else:
        point_bin_placed = point_bin
    count = np.bincount(point_bin_placed, minlength=72)
    with np.errstate(invalid="ignore", divide="ignore"):
        roll_bin = np.nan_to_num(np.bincount(point_bin_placed, weights=roll, minlength=72) / count)
        pitch_bin = np.nan_to_num(np.bincount(point_bin_placed, weights=pitch, minlength=72) / count)
    live = count > 0
    if scan.packet_sweeps is not None:
        live &= swept_bins(scan.packet_sweeps, s.lidar_mount)
    return BeamGeometry.at_bins(roll_bin, pitch_bin, s.lidar_mount), live, point_bin


def _radar_band(s: PipelineSettings, roll: float = 0.0, pitch: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(216, 1) the radar's covered ranges per judged bearing: from where its elevation beam reaches a low solid's
    top out to its range, inside its horizontal field of view. ``roll``, ``pitch``: the boat's attitude (rad, FRD
    Euler) at the frame: a bow lifted 5 deg lifts the beam's lower edge as much ahead, and a low solid near the bow
    passes under it; heeled past the beam's half-width, the beam on the low side ends in the water."""
    bearings = bin_bearings()
    off_boresight = np.angle(np.exp(1j * (bearings - s.radar_yaw_rad)))
    inside = np.abs(off_boresight) <= s.radar_fov_rad / 2
    # elevation of the beam's centre plane on each bearing (world up): the body-horizontal direction (cos b, sin b, 0)
    # turned by roll and pitch has its up component sin(pitch) cos b - cos(pitch) sin(roll) sin b
    up = np.sin(pitch) * np.cos(bearings) - np.cos(pitch) * np.sin(roll) * np.sin(bearings)
    elevation = np.arcsin(np.clip(up, -1.0, 1.0)) + s.radar_pitch_rad * np.cos(off_boresight)
    depression = s.radar_half_vfov_rad - elevation  # of the beam's lower edge below the horizon
    drop = s.radar_height_m - s.min_obstacle_height_m  # from the radar down to a low solid's top
    if drop > 0:  # the top lies below the radar: the lower edge reaches it from some range on, if it points down
        near = np.where(depression > 1e-6, drop / np.tan(np.maximum(depression, 1e-6)), np.inf)
        rises = np.full(depression.shape, np.inf)
    else:  # the top is at or above the radar: seen from the hull out, unless the lower edge points up, then only
        # out to where that edge passes over it (nowhere, with the radar at the top's very height)
        near = np.zeros(depression.shape)
        rises = np.where(depression < -1e-6, -drop / np.tan(np.maximum(-depression, 1e-6)), np.inf)
    # a beam whose upper edge points below the horizon (heeled past its half-width) ends in the water
    sinks = -(elevation + s.radar_half_vfov_rad)
    far = np.where(sinks > 1e-6, max(s.radar_height_m, 0.0) / np.tan(np.maximum(sinks, 1e-6)), np.inf)
    far = np.minimum(far, rises)
    offset = s.radar_offset_fwd_stbd_m
    lo, hi = bands_in_body(
        np.maximum(near, s.radar_min_range_m)[:, None], np.minimum(s.radar_max_range_m, far)[:, None], offset
    )
    # Off the body origin, the radar sees a bearing's near part at another azimuth: from the origin out, the ray
    # enters the field of view where it crosses an edge of the wedge drawn from the radar.
    lo = np.maximum(lo, _fov_entry(bearings, s.radar_yaw_rad, s.radar_fov_rad, offset)[:, None])
    lo[~inside], hi[~inside] = np.inf, -np.inf
    return lo, hi


def _fov_entry(bearings: np.ndarray, yaw: float, fov: float, offset: tuple[float, float]) -> np.ndarray:
    """(B,) range from the body origin along each bearing beyond which the point lies inside a sensor's horizontal
    field of view (``yaw`` +- ``fov`` / 2, drawn from the sensor at ``offset`` fwd/stbd): the furthest crossing of the
    ray with the wedge's two edges; 0 where it crosses neither (for a bearing inside the wedge as seen from far)."""
    t = np.asarray(offset, float)
    entry = np.zeros(bearings.shape)
    if not t.any() or fov >= 2 * np.pi:
        return entry
    u = np.column_stack([np.cos(bearings), np.sin(bearings)])
    for edge in (yaw - fov / 2, yaw + fov / 2):
        e = np.array([np.cos(edge), np.sin(edge)])
        # R u = t + s e: by Cramer's rule on [u, -e] [R, s] = t
        det = -u[:, 0] * e[1] + u[:, 1] * e[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            r = (-t[0] * e[1] + t[1] * e[0]) / det
            along_edge = (u[:, 0] * t[1] - u[:, 1] * t[0]) / det
        crosses = np.isfinite(r) & (r > 0) & (along_edge > 0)
        entry = np.where(crosses, np.maximum(entry, r), entry)
    return entry


def lidar_coverage(scan: LidarScan, s: PipelineSettings) -> SensorCoverage:
    """The body-frame wedge a scan's firings swept (sensor azimuth is clockwise from the sensor's forward)."""
    if scan.sweep_extent >= 2 * np.pi - 1e-6:
        return SensorCoverage(0.0, 2 * np.pi, s.lidar_max_range_m)
    mid = scan.sweep_start + scan.sweep_extent / 2
    # sensor FLU direction (cos a, -sin a, 0) is (cos a, sin a, 0) in sensor-FRD; the mount turns it into the body
    direction = s.lidar_mount.rotate_sensor_frd_to_body(np.array([np.cos(mid), np.sin(mid), 0.0]))
    return SensorCoverage(float(np.arctan2(direction[1], direction[0])), scan.sweep_extent, s.lidar_max_range_m)


def _outlines_in_body(tracks: list[Track], own: tuple[np.ndarray, float, float, float]) -> np.ndarray | None:
    """(M, 2) the tracks' footprint outlines moved from the world to the body frame (fwd, stbd) of the own pose
    ``own``; None when none has one."""
    # the corners into the body frame first: outline_points spaces its points by each side's distance from the
    # origin (a quarter bin's arc there), and that origin must be the boat, not the world's
    outlines = [
        o for o in (outline_points(world_to_body_2d(tr.footprint(), own[0][:2], own[3])) for tr in tracks) if len(o)
    ]
    return np.concatenate(outlines) if outlines else None


def swept_at_tick(sweep: SensorCoverage, turned: float) -> np.ndarray:
    """(72,) bool: the bins of the tick's body frame that a sweep's wedge (in its own body frame) covered, the boat
    having turned ``turned`` (rad, clockwise) since: the tracks judged against it are placed at the tick."""
    return SensorCoverage(sweep.centre - turned, sweep.width, sweep.max_range).bins()


def _swept_many(tracks: list[Track], own: tuple[np.ndarray, float, float, float], swept: np.ndarray) -> np.ndarray:
    """(T,) bool: whether the newest LiDAR sweep covered each track's bearing (a partial sweep may not have). One
    transform for all tracks, not one per track (numpy's arctan2 gives each element the same bits either way)."""
    if not tracks:
        return np.zeros(0, dtype=bool)
    body = world_to_body_2d(np.array([tr.position for tr in tracks]), own[0][:2], own[3])
    return swept[bearing_bins(body)]


def _at_tick(placed: Placed, own: tuple[np.ndarray, float, float, float] | None) -> np.ndarray:
    """A sensor's returns in the body frame (fwd, stbd) of the boat at the tick (``own``, its pose then), from world
    (north, east) with the pose they were measured at, or as they are when they came without one (body). The
    obstacle array's bearings are the heading's when it is sent, not the measurement's, up to 0.1 s (a frame
    period; 0.5 s while a sensor drops frames) and a turning boat's degrees earlier. Without a pose at the tick,
    the measurement's own."""
    points, at = placed
    if at is None:
        return points
    pos, yaw = (own[0][:2], own[3]) if own is not None else at
    return world_to_body_2d(points, pos, yaw)


def _into_own_body(placed: Placed) -> Placed:
    """Returns placed in the world frame with the pose they were measured at, as the body frame of that pose."""
    points, at = placed
    return placed if at is None else (world_to_body_2d(points, *at), None)


def _turned_since(at: tuple[np.ndarray, float] | None, own: tuple[np.ndarray, float, float, float] | None) -> float:
    """How far (rad, clockwise) the boat turned from a measurement's pose ``at`` (world position, yaw) to the tick's
    ``own``; 0 where either is unknown (the measurement then stays in its own body frame, as _at_tick leaves it).
    The distance moved is left alone: 0.5 m in a frame at 5 m/s, inside the array's range tolerance, and eroding
    the covered stretch by it would take every "clear" out to a sensor's full range off a moving boat."""
    if at is None or own is None:
        return 0.0
    turned = float(np.angle(np.exp(1j * (own[3] - at[1]))))
    return turned if np.isfinite(turned) else 0.0


def _sensor_ned(own: tuple[np.ndarray, float, float, float] | None, mount: Mount) -> np.ndarray | None:
    """The LiDAR's origin in the world (NED, m) at the tick's pose (body origin, roll, pitch, yaw); None unknown."""
    if own is None:
        return None
    pos, roll, pitch, yaw = own
    return body_to_world(np.asarray(mount.translation, float)[None, :], np.asarray(pos, float), roll, pitch, yaw)[0]


def _pose_now(ego: EgoSource | None, ego_ok: bool, t: float) -> tuple[np.ndarray, float, float, float] | None:
    if not ego_ok or ego is None:
        return IDENTITY
    p = _finite_pose(ego.at(t))
    if p is None:
        return None
    return np.asarray(p.position, float), p.roll, p.pitch, p.yaw


def _finite_pose(pose: EgoPose | None) -> EgoPose | None:
    """The pose, or None where its heading or horizontal position is not finite: an ego source that breaks its
    protocol (None for "no pose") must not put NaN into every return placed with it, which failed the cycle and
    restarted every track."""
    if pose is None or not np.isfinite([pose.yaw, *np.asarray(pose.position, float)[:2]]).all():
        return None
    return pose
