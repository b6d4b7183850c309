"""Which radar tracks become obstacles: a radar-only track where the LiDAR's beams vouch and saw nothing is clutter;
in the gap between its beams, or with the LiDAR blind, the radar speaks alone."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.frames import EgoPose, LidarScan, RadarFrame
from drivers.mount import Mount
from tracker.obstacle_map import UNKNOWN
from tracker.pipeline import PerceptionPipeline, PipelineSettings
from tracker.types import Track


class FixedRadarTracks:
    """Stands in for the radar tracker (not under test here): returns given confirmed tracks every frame."""

    def __init__(self, tracks: list[Track]) -> None:
        self.tracks = tracks

    def step_frame(self, frame: RadarFrame, pose: object) -> list[Track]:
        return self.tracks

    def shore_points(self) -> np.ndarray:
        return np.empty((0, 2))

    def shore_returns_world(self) -> np.ndarray:
        return np.empty((0, 2))


def radar_track(north: float, east: float, age: float = 5.0) -> Track:
    """A confirmed radar track (2 x 2 m), ``age`` s old: by default long past radar_alone_min_age_s."""
    return Track(
        1, 0.0, np.array([north, east]), np.zeros(2), 0.0, 0.0, 2.0, 2.0, 1.0, confirmed=True, source="radar", age=age
    )


def empty_scan(t: float) -> LidarScan:
    z = np.zeros((0, 3))
    return LidarScan(t, t, z, np.zeros(0, np.float32), np.zeros(0, np.uint8), np.zeros(0))


def frame(t: float) -> RadarFrame:
    return RadarFrame(t, 1, np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros(0))


# The shipped mount: a VLP-16 1.6 m above the water. Its beams vouch for a 0.5 m solid at 4.1-11.8 m (the lowest
# five lasers' bands overlap), 12.6-16.6 m, 21-27.7 m (-3 deg) and 63-83 m (-1 deg); between them a low hull hides.
MOUNTED = PipelineSettings(lidar_mount=Mount(z=-1.6))  # the body origin at the waterline


def water_scan(t: float) -> LidarScan:
    """A revolution whose only returns are one water return 8 m off in each bin: every bin measured, nothing solid."""
    b = np.radians(5.0 * np.arange(72))
    xyz = np.column_stack([8.0 * np.cos(b), 8.0 * np.sin(b), np.zeros(72)])
    return LidarScan(t, t, xyz, np.zeros(72, np.float32), np.zeros(72, np.uint8), np.full(72, t))


def run(tracks: list[Track], lidar: bool, settings: PipelineSettings = MOUNTED) -> tuple[np.ndarray, list[Track]]:
    p = PerceptionPipeline(settings, radar_tracker_factory=lambda: FixedRadarTracks(tracks))
    out = p.step(1.0, water_scan(0.95) if lidar else None, [frame(0.95)], None)
    return out.distances_cm, out.tracks


def test_near_radar_only_track_is_not_an_obstacle_while_the_lidar_sees() -> None:
    d, tracks = run([radar_track(6.0, 0.0)], lidar=True)
    assert d[0] == UNKNOWN and tracks == []  # the LiDAR looked there and saw nothing: clutter, not a hull


def test_radar_only_track_where_the_lidars_beams_vouch_is_neither_obstacle_nor_track() -> None:
    d, tracks = run([radar_track(24.0, 0.0)], lidar=True)  # in the -3 deg beam's band
    assert d[0] == UNKNOWN and tracks == []


def test_radar_only_track_in_the_gap_between_the_lidars_beams_is_an_obstacle_and_a_track() -> None:
    """A low hull 40 m off passes between the -3 and -1 deg beams: only the radar can see it, so it speaks there."""
    d, tracks = run([radar_track(40.0, 0.0)], lidar=True)
    assert d[0] == 3900 and [tr.source for tr in tracks] == ["radar"]


def test_a_young_radar_only_track_in_the_gap_is_an_obstacle_but_not_yet_a_vessel() -> None:
    """Clutter that happens to confirm lasts under a second; until a radar-only track has lasted
    radar_alone_min_age_s (1 s) its outline is an obstacle, but it is not sent as a vessel."""
    d, tracks = run([radar_track(40.0, 0.0, age=0.5)], lidar=True)
    assert d[0] == 3900 and tracks == []
    d, tracks = run([radar_track(40.0, 0.0, age=1.0)], lidar=True)
    assert d[0] == 3900 and [tr.source for tr in tracks] == ["radar"]


def test_a_young_radar_only_track_is_a_vessel_when_the_lidar_is_blind() -> None:
    _, tracks = run([radar_track(40.0, 0.0, age=0.2)], lidar=False)
    assert [tr.source for tr in tracks] == ["radar"]


def test_radar_only_track_within_a_fixed_range_is_muted_when_one_is_set() -> None:
    fixed = PipelineSettings(
        max_distance_m=200.0,
        lidar_mount=Mount(z=-1.6),
        lidar_origin_height_above_water_m=1.6,
        radar_alone_beyond_m=100.0,
    )
    d, tracks = run([radar_track(40.0, 0.0)], lidar=True, settings=fixed)
    assert d[0] == UNKNOWN and tracks == []
    d, tracks = run([radar_track(120.0, 0.0)], lidar=True, settings=fixed)  # beyond it the radar speaks alone
    assert d[0] == 11900 and [tr.source for tr in tracks] == ["radar"]


def test_near_radar_only_track_counts_when_the_lidar_is_blind() -> None:
    d, _ = run([radar_track(6.0, 0.0)], lidar=False)
    assert d[0] == 500  # the near face of the 2 x 2 m box 6 m ahead


def test_far_radar_only_track_is_an_obstacle_when_the_lidar_is_blind() -> None:
    d, _ = run([radar_track(30.0, 0.0)], lidar=False)
    assert d[0] == 2900


class FixedLidarTracks:
    """Stands in for the LiDAR tracker: a confirmed track on the same boat the radar tracks."""

    def __init__(self, tracks: list[Track]) -> None:
        self.tracks = tracks

    def step(self, *args: object, **kwargs: object) -> list[Track]:
        return self.tracks

    def on_structure(self, t: float, points_ne: np.ndarray, radius_m: float) -> np.ndarray:
        return np.zeros(len(points_ne), dtype=bool)  # no quay in these scenes

    def behind_structure(self, t: float, points_ne: np.ndarray, sensor_ne: np.ndarray) -> np.ndarray:
        return np.zeros(len(points_ne), dtype=bool)


def test_a_boat_stays_an_obstacle_when_the_lidar_goes_silent() -> None:
    lidar_track = Track(7, 0.0, np.array([30.0, 0.0]), np.zeros(2), 0.0, 0.0, 2.0, 2.0, 1.0, confirmed=True)
    scan = LidarScan(
        0.95, 0.95, np.array([[29.0, 0.0, -1.0]] * 5), np.zeros(5, np.float32), np.zeros(5, np.uint8), np.full(5, 0.95)
    )
    p = PerceptionPipeline(
        lidar_tracker_factory=lambda: FixedLidarTracks([lidar_track]),
        radar_tracker_factory=lambda: FixedRadarTracks([radar_track(30.0, 0.0)]),
    )
    out = p.step(1.0, scan, [frame(0.95)], None)
    assert [tr.source for tr in out.tracks] == ["fused"]
    # two seconds later the LiDAR is silent, the radar still sees the boat: its own track carries the obstacle
    out = p.step(3.0, None, [frame(2.95)], None)
    assert [tr.source for tr in out.tracks] == ["radar"]
    assert out.distances_cm[0] == 2900


def boat_both_sensors_track(north: float) -> tuple[np.ndarray, list[Track]]:
    """A 4 x 2 m boat ``north`` m dead ahead, confirmed by both trackers, while the LiDAR's revolution holds only
    water returns (its hull's returns lay within the sea margin): the bins and the tracks sent."""
    lidar_track = Track(7, 0.0, np.array([north, 0.0]), np.zeros(2), 0.0, 0.0, 4.0, 2.0, 1.0, confirmed=True)
    p = PerceptionPipeline(
        MOUNTED,
        lidar_tracker_factory=lambda: FixedLidarTracks([lidar_track]),
        radar_tracker_factory=lambda: FixedRadarTracks([radar_track(north, 0.0)]),
    )
    out = p.step(1.0, water_scan(0.95), [frame(0.95)], None)
    return out.distances_cm, out.tracks


def test_a_boat_both_sensors_confirm_is_an_obstacle_where_the_lidars_beams_cannot_vouch() -> None:
    """40 m off the boat lies between the -3 and -1 deg beams: the LiDAR could not have returned its hull above the
    sea margin, so the fused track's outline (its near end at 38 m) stands for it, as a radar-only track's would."""
    d, tracks = boat_both_sensors_track(40.0)
    assert [tr.source for tr in tracks] == ["fused"]
    assert d[0] == 3800


def test_a_boat_both_sensors_confirm_adds_no_outline_where_the_lidars_beams_vouch() -> None:
    """24 m off the -3 deg beam vouches for a 0.5 m solid and returned none: its revolution, not an estimated
    outline, says what is there."""
    d, tracks = boat_both_sensors_track(24.0)
    assert [tr.source for tr in tracks] == ["fused"]
    assert d[0] == UNKNOWN


def test_a_radar_only_track_whose_motion_is_not_settled_is_an_obstacle_but_not_yet_a_vessel() -> None:
    """The motion discriminator's "wait" (velocity NaN): clutter that confirms rarely settles a motion; the outline
    stays an obstacle in the LiDAR's gap, the track is not sent until the radar knows how it moves."""
    waiting = radar_track(40.0, 0.0)
    waiting.velocity = np.full(2, np.nan)
    d, tracks = run([waiting], lidar=True)
    assert d[0] == 3900 and tracks == []
    _, tracks = run([waiting], lidar=False)  # with the LiDAR blind the radar speaks alone, settled or not
    assert [tr.source for tr in tracks] == ["radar"]


def hull_piece(north: float, east: float, host: int) -> Track:
    """A confirmed radar track (2 x 2 m) on a piece of track ``host``'s hull (tracker.radar.pieces)."""
    piece = radar_track(north, east)
    piece.id, piece.part_of = 2, host
    return piece


def test_a_piece_of_a_radar_hull_is_an_obstacle_but_no_vessel_when_the_lidar_is_blind() -> None:
    """A hull's track 30 m dead ahead and a piece of it 38 m off, 5 deg to starboard (bin 1): one vessel sent, both
    outlines in the bins."""
    d, tracks = run([radar_track(30.0, 0.0), hull_piece(37.9, 3.3, host=1)], lidar=False)
    assert [tr.id for tr in tracks] == [1]
    assert d[0] == 2900
    assert d[1] == pytest.approx(3697, abs=2)  # the piece's 2 x 2 m box, its near corner 36.97 m off


def test_a_piece_is_an_obstacle_only_where_the_radar_speaks_for_the_lidar() -> None:
    """As a radar track alone: in the gap between the LiDAR's beams (40-45 m) the piece's outline is an obstacle; at
    24 m, in the -3 deg beam's band, the revolution returned no solid there and the piece is none. Never a vessel."""
    d, tracks = run([radar_track(40.0, 0.0), hull_piece(44.8, 3.9, host=1)], lidar=True)
    assert [tr.id for tr in tracks] == [1]
    assert d[0] == 3900
    assert d[1] == pytest.approx(4390, abs=2)  # the piece's 2 x 2 m box, its near corner 43.9 m off
    d, tracks = run([radar_track(40.0, 0.0), hull_piece(24.0, 0.0, host=1)], lidar=True)
    assert [tr.id for tr in tracks] == [1]
    assert d[0] == 3900


def boat_only_the_lidar_tracks(north: float, radar_returns: list[tuple[float, float]]) -> np.ndarray:
    """A 4 x 2 m boat ``north`` m dead ahead, a confirmed LiDAR track, while its revolution holds only water returns
    and the radar's frame holds ``radar_returns`` (fwd, stbd) but no track (a sparse hull): the bins sent."""
    lidar_track = Track(7, 0.0, np.array([north, 0.0]), np.zeros(2), 0.0, 0.0, 4.0, 2.0, 1.0, confirmed=True)
    p = PerceptionPipeline(
        MOUNTED,
        lidar_tracker_factory=lambda: FixedLidarTracks([lidar_track]),
        radar_tracker_factory=lambda: FixedRadarTracks([]),
    )
    xyz = np.array([[f, s, -0.5] for f, s in radar_returns]).reshape(-1, 3)
    n = len(xyz)
    radar = RadarFrame(0.95, 1, xyz, np.zeros(n), np.full(n, 20.0), np.full(n, 5.0))
    return p.step(1.0, water_scan(0.95), [radar], None).distances_cm


def test_a_lidar_track_in_the_beams_gap_that_the_radar_returned_is_an_obstacle() -> None:
    """40 m off lies between the -3 and -1 deg beams: the LiDAR cannot return the hull there, and the radar returned
    it once this frame (too few returns for a radar track). The LiDAR track's outline in that bin (its near end at
    38 m) stands for it; before, the bin went out unknown with a hull in it."""
    assert boat_only_the_lidar_tracks(40.0, [(40.6, 0.3)])[0] == 3800


def test_without_a_radar_return_by_it_a_lidar_track_in_the_gap_adds_nothing() -> None:
    """The LiDAR track may be stale there (a quay piece taken for a vessel, a lost track): nothing seconds it, or the
    radar's return lies beyond its box and 0.5 m (6 m further out), so the bin stays unknown."""
    assert boat_only_the_lidar_tracks(40.0, [])[0] == UNKNOWN
    assert boat_only_the_lidar_tracks(40.0, [(46.0, 0.0)])[0] == UNKNOWN


def test_where_the_lidars_beams_vouch_a_radar_return_does_not_second_its_track() -> None:
    """24 m off the -3 deg beam vouches for a 0.5 m solid and returned none: its silence wins over the radar."""
    assert boat_only_the_lidar_tracks(24.0, [(24.5, 0.0)])[0] == UNKNOWN


class PoseFarFromOrigin:
    """The autopilot's pose: level, heading north, 500 m north and 300 m east of the world origin (EKF origin)."""

    epoch = 1
    available = True
    position = np.array([500.0, 300.0, 0.0])

    def at_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        n = np.asarray(times, float).size
        return np.tile(self.position, (n, 1)), np.zeros(n), np.zeros(n), np.zeros(n)

    def at(self, t: float) -> EgoPose:
        return EgoPose(t, self.position.copy(), np.zeros(3), 0.0, 0.0, 0.0)


def test_a_near_outline_fills_every_bin_it_spans_wherever_the_world_origin_is() -> None:
    """A radar-only hull 2 m ahead, 6 m wide across the bow (its near side 1.5 m off, spanning 63 deg either side),
    with the LiDAR blind: each bin within 57.5 deg either side holds its near side. Its outline was spaced by the
    sides' distance from the world origin (580 m here), 0.25 m: at 1.5 m a point every 9.5 deg, and a bin between
    two of them showed the far side, 1 m farther, or a neighbour's near side."""
    boat = Track(
        1, 0.0, np.array([502.0, 300.0]), np.zeros(2), 0.0, 0.0, 1.0, 6.0, 1.0, confirmed=True, source="radar", age=5.0
    )
    p = PerceptionPipeline(MOUNTED, radar_tracker_factory=lambda: FixedRadarTracks([boat]))
    d = p.step(1.0, None, [frame(0.95)], PoseFarFromOrigin()).distances_cm
    bins = np.arange(-11, 12)
    # within a bin, no farther than the near side at the bin's outer edge
    near_side_cm = 150.0 / np.cos(np.radians(np.abs(5.0 * bins) + 2.5))
    assert np.all(d[bins % 72] <= np.ceil(near_side_cm)), d[bins % 72] - near_side_cm
    assert d[16] == UNKNOWN and d[56] == UNKNOWN
