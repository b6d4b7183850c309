"""A hull's strong scatterers each holding a radar track: one vessel, the others its pieces (tracker.radar.pieces).

The simulated AWR1843 returns a 12 m boat from a few persistent scatterers (bow, cabin, stern) 5-10 m apart; each
comes back as its own cluster and, before this rule, held a confirmed track of its own: one boat crossing at 30 m
was reported as two vessels in every frame from 3 s on.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from daemon.config import Config
from daemon.tracker_adapters import tracker_factories
from drivers.awr1843.parser import RadarFrameParser, encode_frame
from simulator.radar_model import SHIPPED_PROFILE, Awr1843Model
from simulator.scene import OwnBoat, Scene, Trajectory, Vessel
from tracker.radar.config import AssociationConfig
from tracker.radar.kalman import mahalanobis2_many
from tracker.radar.pieces import hull_pieces
from tracker.types import Track

ALONG, ACROSS, MIN_SPEED, SPEED_DIFF, CHI2 = 12.0, 3.5, 0.5, 1.0, 9.21  # the shipped AssociationConfig's
COURSE_TOLERANCE_DEG = 25.0  # the shipped piece_course_tolerance_deg
SMALL_COV = np.eye(2) * 0.01  # (m/s)^2: a settled velocity


def _track(
    track_id: int, north: float, east: float, v: tuple[float, float], hits: int, confirmed: bool = True
) -> Track:
    return Track(
        id=track_id,
        t=0.0,
        position=np.array([north, east]),
        velocity=np.array(v),
        heading=0.0,
        yaw_rate=0.0,
        length=4.0,
        width=3.0,
        height=0.0,
        confirmed=confirmed,
        source="radar",
        hits=hits,
    )


def _pieces(
    tracks: list[Track],
    covs: np.ndarray | None = None,
    apart: set[tuple[int, int]] | None = None,
    course_tolerance_deg: float = COURSE_TOLERANCE_DEG,
) -> list[int | None]:
    velocities = np.array([tr.velocity for tr in tracks])
    covs = np.repeat(SMALL_COV[None], len(tracks), axis=0) if covs is None else covs
    hull_pieces(
        tracks,
        velocities,
        covs,
        ALONG,
        ACROSS,
        MIN_SPEED,
        SPEED_DIFF,
        CHI2,
        set() if apart is None else apart,
        math.radians(course_tolerance_deg),
    )
    return [tr.part_of for tr in tracks]


def test_a_track_ahead_of_a_better_one_moving_alike_is_its_piece() -> None:
    """Bow and stern of a boat making 4 m/s north, 8 m apart along its course: the one with fewer hits is the piece."""
    assert _pieces([_track(7, 8.0, 0.5, (4.0, 0.0), hits=20), _track(3, 0.0, 0.0, (4.2, 0.1), hits=30)]) == [3, None]


def test_ties_go_to_the_older_track_and_a_piece_hosts_no_piece() -> None:
    """Bow, cabin and stern 0, 6 and 12 m along: the cabin's track hosts both ends, equal hits, the lowest id wins."""
    tracks = [
        _track(9, 12.0, 0.0, (0.0, 0.0), 10),
        _track(4, 6.0, 0.0, (0.0, 0.0), 10),
        _track(5, 0.0, 0.0, (0.0, 0.0), 10),
    ]
    for tr in tracks:
        tr.velocity = np.array([3.0, 0.0])
    assert _pieces(tracks) == [4, None, 4]
    ends_only = [
        _track(2, 0.0, 0.0, (3.0, 0.0), 10),
        _track(8, 11.0, 0.0, (3.0, 0.0), 9),
        _track(6, 23.0, 0.0, (3.0, 0.0), 8),
    ]
    # 6 lies within 12 m of 8 only, and 8 is a piece of 2: 6 stays a vessel
    assert _pieces(ends_only) == [None, 2, None]


@pytest.mark.parametrize(
    ("second", "why"),
    [
        (_track(2, 0.0, 4.0, (4.0, 0.0), 5), "abreast, 4 m apart across the course (beyond 3.5 m)"),
        (_track(2, 13.0, 0.0, (4.0, 0.0), 5), "13 m ahead (beyond 12 m)"),
        (_track(2, 6.0, 0.0, (4.0, 2.0), 5), "moving 2 m/s apart, each velocity settled"),
        (_track(2, 6.0, 0.0, (4.0, 0.0), 5, confirmed=False), "not confirmed: no vessel yet, nor a piece"),
    ],
)
def test_two_boats_that_do_not_move_as_one_hull_stay_two(second: Track, why: str) -> None:
    assert _pieces([_track(1, 0.0, 0.0, (4.0, 0.0), 20), second]) == [None, None], why


def test_a_piece_off_a_course_the_radar_got_wrong_by_30_deg() -> None:
    """Bow and stern 9 m apart on a boat heading north, both filters' course 30 deg off it (the radar measures the
    radial speed only): 7.8 m along their course, 4.5 m across it. With 25 deg of course tolerance 3.5 m across
    grows to 3.5 + 7.8 tan(25 deg) = 7.1 m: a piece. Without it, two vessels."""
    v = (4.0 * math.cos(math.radians(30.0)), 4.0 * math.sin(math.radians(30.0)))
    pair = [_track(1, 0.0, 0.0, v, 20), _track(2, 9.0, 0.0, v, 5)]
    assert _pieces(pair, course_tolerance_deg=0.0) == [None, None]
    pair = [_track(1, 0.0, 0.0, v, 20), _track(2, 9.0, 0.0, v, 5)]
    assert _pieces(pair, course_tolerance_deg=25.0) == [None, 1]


@pytest.mark.parametrize(
    ("second", "why"),
    [
        (_track(2, 0.0, 4.0, (4.0, 0.0), 5), "abreast, 4 m apart across the course: nothing along to widen"),
        (_track(2, 3.0, 6.0, (4.0, 0.0), 5), "3 m along, 6 m across: beyond 3.5 + 3 tan(25 deg) = 4.9 m"),
    ],
)
def test_boats_abreast_stay_two_with_the_course_tolerance(second: Track, why: str) -> None:
    assert _pieces([_track(1, 0.0, 0.0, (4.0, 0.0), 20), second], course_tolerance_deg=25.0) == [None, None], why


def test_slow_tracks_are_left_to_the_duplicate_test() -> None:
    """Two boats at anchor 6 m apart move alike too; below 0.5 m/s nothing says they are one hull. At 0.6 m/s (a boat
    crossing slowly) the same pair is one hull."""
    assert _pieces([_track(1, 0.0, 0.0, (0.4, 0.0), 20), _track(2, 6.0, 0.0, (0.4, 0.0), 5)]) == [None, None]
    assert _pieces([_track(1, 0.0, 0.0, (0.6, 0.0), 20), _track(2, 6.0, 0.0, (0.6, 0.0), 5)]) == [None, 1]


def test_the_constants_here_are_the_shipped_ones() -> None:
    a = AssociationConfig()
    assert (a.piece_along_m, a.piece_across_m, a.piece_min_speed_mps) == (ALONG, ACROSS, MIN_SPEED)
    assert (a.duplicate_velocity_mps, a.duplicate_velocity_chi2) == (SPEED_DIFF, CHI2)
    assert a.piece_course_tolerance_deg == COURSE_TOLERANCE_DEG


def test_a_young_velocity_not_told_apart_counts_as_alike() -> None:
    """2 m/s apart, but the piece's filter is unsure by 1.5 m/s a side: within 99 % of chi2(2), alike."""
    covs = np.array([SMALL_COV, np.eye(2) * 1.5**2])
    assert _pieces([_track(1, 0.0, 0.0, (4.0, 0.0), 20), _track(2, 6.0, 0.0, (4.0, 2.0), 5)], covs) == [None, 1]
    assert mahalanobis2_many(np.array([0.0, 2.0]), SMALL_COV + np.eye(2) * 1.5**2) == pytest.approx(4.0 / 2.26)


def test_two_boats_once_seen_apart_stay_two_when_they_fall_in_line() -> None:
    """A convoy: 30 m apart, then one 8 m behind the other at the same speed. A hull's pieces are never further apart
    than 12 + 3.5 m, so these are two boats for good."""
    apart: set[tuple[int, int]] = set()
    assert _pieces([_track(1, 0.0, 0.0, (4.0, 0.0), 20), _track(2, -30.0, 0.0, (4.0, 0.0), 10)], apart=apart) == [
        None,
        None,
    ]
    assert apart == {(1, 2)}
    assert _pieces([_track(1, 40.0, 0.0, (4.0, 0.0), 30), _track(2, 32.0, 0.0, (4.0, 0.0), 20)], apart=apart) == [
        None,
        None,
    ]
    assert _pieces([_track(1, 40.0, 0.0, (4.0, 0.0), 30), _track(2, 32.0, 0.0, (4.0, 0.0), 20)]) == [None, 1]


def _vessel_counts(piece_along_m: float) -> list[int]:
    """Confirmed radar tracks that are vessels (no part_of), per frame after the first 3 s, of one 12 x 4 m boat
    crossing 30 m ahead at 4 m/s; the radar tracker as the daemon builds it, the simulated AWR1843's frames through
    the real parser."""
    own = OwnBoat(Trajectory.constant_velocity((0.0, 0.0), (0.0, 0.0), heading=0.0))
    boat = Vessel(
        "crossing", 12.0, 4.0, 2.5, Trajectory.constant_velocity((30.0, -15.0), (0.0, 4.0), heading=math.pi / 2)
    )
    scene = Scene("one hull", own, [boat], [])
    config = Config()
    config.radar.profile = str(SHIPPED_PROFILE)
    config.radar.mount.x, config.radar.mount.y, config.radar.mount.z = 0.0, 0.0, 0.0
    config.radar.mount.yaw = 0.0
    config.tracker.radar = {"association": {"piece_along_m": piece_along_m}}
    _, make_radar, _ = tracker_factories(config)
    assert make_radar is not None
    tracker = make_radar()
    model = Awr1843Model(scene, scene.radar_mount, seed=3)
    parser = RadarFrameParser(None, scene.radar_mount)
    counts = []
    for k, d in enumerate(model.frames(0.0, 8.0)):
        for frame in parser.feed(encode_frame(k + 1, d.xyz_ti, d.doppler, d.snr_db, d.noise_db), d.t):
            tracks = tracker.step_frame(frame, scene.own.pose(frame.stamp))
            if frame.stamp >= 3.0:
                counts.append(sum(tr.confirmed and tr.part_of is None for tr in tracks))
    return counts


def test_one_boat_is_one_radar_vessel() -> None:
    """With the rule: one vessel in at least 45 of the 50 frames, never none (measured: one in all 50)."""
    counts = np.array(_vessel_counts(12.0))
    assert len(counts) == 50
    assert np.all(counts >= 1)
    assert np.count_nonzero(counts == 1) >= 45


def test_without_the_rule_one_boat_is_several_vessels() -> None:
    """Measured: two vessels in all 50 frames."""
    counts = np.array(_vessel_counts(0.0))
    assert np.count_nonzero(counts >= 2) >= 45
