"""The obstacle memory: a solid measured within the hold fills a bin that would go out "unknown", moved by the boat's
own motion and by its track's velocity, and never overrides a measurement, a vouched "clear", or outlives the hold."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

from drivers.frames import LidarScan
from drivers.mount import Mount
from tests.sea_geometry import SteadyEgo, lidar_pipeline, revolution_over_water, scan_of
from tracker.obstacle_map import UNKNOWN, nearest_and_edge_points_per_bin, nearest_per_bin, to_distances_cm
from tracker.obstacle_memory import ObstacleMemory
from tracker.pipeline import PerceptionOutput, PerceptionPipeline
from tracker.types import Track

MAX_M = 100.0
CLEAR = 10001
HOLD_S = 0.5


def sent(nearest: dict[int, float] | None = None, clear: tuple[int, ...] = ()) -> np.ndarray:
    """An array as build_obstacle_distances makes it: obstacles at ``nearest`` (bin: m), ``clear`` bins vouched."""
    near = np.full(72, np.inf)
    for b, r in (nearest or {}).items():
        near[b] = r
    covered = np.zeros(72, dtype=bool)
    covered[list(clear)] = True
    return to_distances_cm(near, covered, 0.5, MAX_M)


def fill(
    memory: ObstacleMemory,
    t: float,
    distances: np.ndarray,
    solid_body: np.ndarray | None = None,
    own_ne: tuple[float, float] = (0.0, 0.0),
    tracks: list[Track] | None = None,
) -> np.ndarray:
    solid = np.empty((0, 2)) if solid_body is None else np.asarray(solid_body, float)
    return memory.fill_unknown(t, t, distances, solid, (np.array(own_ne), 0.0), tracks or [], HOLD_S, 0.5, MAX_M)


def at_bearings(deg_and_range: list[tuple[float, float]]) -> np.ndarray:
    """Body (forward, starboard) points at (bearing deg clockwise from the bow, range m)."""
    a = np.radians([d for d, _ in deg_and_range])
    r = np.array([m for _, m in deg_and_range])
    return np.stack([r * np.cos(a), r * np.sin(a)], axis=1)


def test_nearest_and_edge_points_per_bin_keep_each_wanted_bins_nearest_and_its_bearing_extremes() -> None:
    """Bin 18 (87.5-92.5 deg) holds four points: its nearest (92.4 deg) is also its greatest bearing, 88.0 deg its
    least; bin 0 holds one (all three are it), bin 36 astern two across the -180/180 seam (its least bearing is
    -178 deg's neighbour 179 deg, not the seam's far side); bin 54 is not wanted; a NaN point is dropped."""
    pts = np.concatenate(
        [
            at_bearings([(91.0, 44.9), (92.4, 44.0), (88.0, 45.5), (90.0, 46.0), (0.0, 10.0)]),
            at_bearings([(179.0, 30.0), (-178.0, 31.0), (-90.0, 5.0)]),
            [[np.nan, 1.0]],
        ]
    )
    wanted = np.zeros(72, dtype=bool)
    wanted[[0, 18, 36]] = True
    got = nearest_and_edge_points_per_bin(pts, wanted)
    bearing = np.degrees(np.arctan2(got[:, 1], got[:, 0]))
    # nearest per bin first, then the least bearings, then the greatest, each in bin order
    np.testing.assert_allclose(bearing, [0.0, 92.4, 179.0, 0.0, 88.0, 179.0, 0.0, 92.4, -178.0], atol=1e-9)
    np.testing.assert_allclose(np.hypot(got[:, 0], got[:, 1]), [10, 44, 30, 10, 45.5, 30, 10, 44, 31], atol=1e-9)
    assert nearest_and_edge_points_per_bin(pts, np.zeros(72, dtype=bool)).shape == (0, 2)
    ranges = nearest_per_bin(pts)
    assert ranges[0] == pytest.approx(10.0) and ranges[18] == pytest.approx(44.0)


def test_a_hull_ending_near_a_bins_edge_still_fills_that_bin_after_the_boat_moved() -> None:
    """A hull's returns in bin 18 run from 91.0 to 92.4 deg, its nearest (44.0 m) at 92.4 deg. The boat then comes
    0.5 m ahead and the bin would be unknown: the nearest point now lies at 93.1 deg, in bin 19, but the hull still
    reaches 89.6 deg (its 91.0 deg return, 44.9 m): bin 18 shows 44.9 m (it went out unknown while only the nearest
    point was held)."""
    m = ObstacleMemory()
    hull = at_bearings([(91.0, 44.9), (91.7, 44.5), (92.4, 44.0)])
    first = fill(m, 0.0, sent({18: 44.0}), hull)
    assert first[18] == 4400
    now = fill(m, 0.1, sent(), own_ne=(0.5, 0.0))
    moved = hull - [0.5, 0.0]  # the body frame 0.5 m ahead, same heading
    assert now[18] == round(np.hypot(*moved[0]) * 100)  # 44.9 m less 0.0087 m: 4489 cm
    assert now[19] == round(np.hypot(*moved[2]) * 100)  # the nearest point, moved there: 4402 cm
    assert (np.delete(now, [18, 19]) == UNKNOWN).all()


def test_an_unknown_bin_shows_the_solid_measured_within_the_hold_where_the_boat_now_sees_it() -> None:
    """A wall point 20 m ahead measured at t = 0; at 0.2 s the boat has come 2 m north and the bin would be unknown:
    it shows 18 m. Its other bins stay unknown."""
    m = ObstacleMemory()
    first = fill(m, 0.0, sent({0: 20.0}), np.array([[20.0, 0.0]]))
    assert first[0] == 2000
    now = fill(m, 0.2, sent(), own_ne=(2.0, 0.0))
    assert now[0] == 1800
    assert (np.delete(now, 0) == UNKNOWN).all()
    assert m.bins_filled == 1 and np.flatnonzero(m.last_filled).tolist() == [0]


def test_a_measurement_or_a_vouched_clear_wins_over_the_memory() -> None:
    m = ObstacleMemory()
    fill(m, 0.0, sent({0: 20.0}), np.array([[20.0, 0.0]]))
    assert fill(m, 0.1, sent(clear=(0,)))[0] == CLEAR  # the beams vouched nothing was there: it left
    assert fill(m, 0.2, sent({0: 15.0}), np.array([[15.0, 0.0]]))[0] == 1500  # measured nearer: the truth now
    assert m.bins_filled == 0


def test_a_held_solid_is_gone_after_the_hold_and_is_never_held_again() -> None:
    """Measured at 0; filled at 0.2 and 0.4 from that measurement alone; at 0.55 it is 0.55 s old: unknown, although
    the bin was sent an obstacle 0.15 s before (a filled value is not a measurement)."""
    m = ObstacleMemory()
    fill(m, 0.0, sent({0: 20.0}), np.array([[20.0, 0.0]]))
    assert fill(m, 0.2, sent())[0] == 2000
    assert fill(m, 0.4, sent())[0] == 2000
    assert fill(m, 0.55, sent())[0] == UNKNOWN


def test_a_hold_of_zero_holds_nothing() -> None:
    m = ObstacleMemory()
    fill(m, 0.0, sent({0: 20.0}), np.array([[20.0, 0.0]]))
    out = m.fill_unknown(0.1, 0.1, sent(), np.empty((0, 2)), (np.zeros(2), 0.0), [], 0.0, 0.5, MAX_M)
    assert out[0] == UNKNOWN and not m.last_filled.any()
    assert fill(m, 0.2, sent())[0] == UNKNOWN  # and what was held before is forgotten


def test_a_solid_on_a_tracked_hull_moves_with_the_track() -> None:
    """A boat crossing at 5 m/s east, 20 m ahead: after 0.2 s its returned point is 1 m east, at 2.9 deg, in bin 1
    (centred on 5 deg, from 2.5 deg), and bin 0 is no longer held."""
    boat = Track(1, 0.0, np.array([20.5, 0.0]), np.array([0.0, 5.0]), math.pi / 2, 0.0, 6.0, 2.0, 1.0, confirmed=True)
    m = ObstacleMemory()
    fill(m, 0.0, sent({0: 20.0}), np.array([[20.0, 0.0]]), tracks=[boat])
    now = fill(m, 0.2, sent())
    assert now[0] == UNKNOWN
    assert now[1] == pytest.approx(round(math.hypot(20.0, 1.0) * 100), abs=1)


def nearer_on(tracks: list[Track], ticks: list[tuple[float, float]], hull_nearer_s: float = 0.25) -> list[int]:
    """Bin 0 at each (tick time, range of the revolution's only return dead ahead) with ``tracks``: the
    revolution of each tick is stamped 0.05 s before it, its return both the array's obstacle and the LiDAR's."""
    m = ObstacleMemory()
    out = []
    for t, r in ticks:
        solid = np.array([[r, 0.0]])
        d = m.fill_unknown(
            t,
            t - 0.05,
            sent({0: r}),
            solid,
            (np.zeros(2), 0.0),
            tracks,
            HOLD_S,
            0.5,
            MAX_M,
            lidar=(t - 0.05, solid),
            hull_nearer_s=hull_nearer_s,
        )
        out.append(int(d[0]))
    return out


def test_a_hulls_return_keeps_its_bin_for_the_revolution_that_missed_it() -> None:
    """A boat 8 m ahead (a confirmed LiDAR track, box 7.5-9.5 m ahead) returned at 8.0 m; the next revolution
    missed its end in bin 0 and returned only the quay 40 m behind: the bin stays at 8 m, not 40. Three revolutions
    on (0.3 s after the last return on the hull, beyond 0.25 s) the quay is what the sensor says."""
    boat = Track(1, 0.0, np.array([8.5, 0.0]), np.zeros(2), 0.0, 0.0, 2.0, 1.0, 1.0, confirmed=True)
    assert nearer_on([boat], [(0.1, 8.0), (0.2, 40.0), (0.3, 40.0), (0.4, 40.0)]) == [800, 800, 800, 4000]
    # nearer than the memory: the measurement is the truth
    assert nearer_on([boat], [(0.1, 8.0), (0.2, 7.6)]) == [800, 760]
    # off: the array as measured
    assert nearer_on([boat], [(0.1, 8.0), (0.2, 40.0)], hull_nearer_s=0.0) == [800, 4000]


def test_only_a_lidar_held_hull_keeps_its_bin_and_it_moves_with_its_track() -> None:
    """A return on no track, or on a tentative or radar-only track's box (sea clutter too often), does not hold an
    obstacle bin; a fused track's does. A boat closing at 2 m/s: its return at 8 m in the revolution of 0.05 s is
    0.3 m nearer at the tick of 0.2 s."""
    boat = Track(1, 0.0, np.array([8.5, 0.0]), np.zeros(2), 0.0, 0.0, 2.0, 1.0, 1.0, confirmed=True)
    ticks = [(0.1, 8.0), (0.2, 40.0)]
    assert nearer_on([], ticks) == [800, 4000]
    assert nearer_on([replace(boat, confirmed=False)], ticks) == [800, 4000]
    assert nearer_on([replace(boat, source="radar")], ticks) == [800, 4000]
    assert nearer_on([replace(boat, source="fused")], ticks) == [800, 800]
    assert nearer_on([replace(boat, velocity=np.array([-2.0, 0.0]))], ticks) == [800, 770]


def test_a_hulls_return_never_closes_a_vouched_clear_or_fills_an_unknown_bin_early() -> None:
    """The rule brings an obstacle bin in; a bin the beams vouched clear stays clear, and an unknown one is the
    ordinary hold's (0.5 s), which fills it from what the array held."""
    boat = Track(1, 0.0, np.array([8.5, 0.0]), np.zeros(2), 0.0, 0.0, 2.0, 1.0, 1.0, confirmed=True)
    m = ObstacleMemory()
    solid = np.array([[8.0, 0.0]])
    kw = {"lidar": (0.05, solid), "hull_nearer_s": 0.25}
    m.fill_unknown(0.1, 0.05, sent({0: 8.0}), solid, (np.zeros(2), 0.0), [boat], HOLD_S, 0.5, MAX_M, **kw)
    empty = np.empty((0, 2))
    kw = {"lidar": (0.15, empty), "hull_nearer_s": 0.25}
    out = m.fill_unknown(0.2, 0.15, sent(clear=(0,)), empty, (np.zeros(2), 0.0), [boat], HOLD_S, 0.5, MAX_M, **kw)
    assert out[0] == CLEAR and m.bins_hull_nearer == 0


def held_on(
    track: Track | None,
    tracks_later: list[Track],
    hull_hold_s: float = 1.0,
    on_structure: Callable[[np.ndarray], np.ndarray] | None = None,
) -> list[int]:
    """Bin 0 at 0.4, 0.8, 0.95 and 1.05 s after a solid 20 m ahead measured at 0 on ``track``'s hull (None: on
    none), the tracks at those ticks ``tracks_later``."""
    m = ObstacleMemory()
    first = [] if track is None else [track]
    m.fill_unknown(
        0.0,
        0.0,
        sent({0: 20.0}),
        np.array([[20.0, 0.0]]),
        (np.zeros(2), 0.0),
        first,
        HOLD_S,
        0.5,
        MAX_M,
        hull_hold_s,
        on_structure,
    )
    return [
        int(
            m.fill_unknown(
                t, 0.0, sent(), np.empty((0, 2)), (np.zeros(2), 0.0), tracks_later, HOLD_S, 0.5, MAX_M, hull_hold_s
            )[0]
        )
        for t in (0.4, 0.8, 0.95, 1.05)
    ]


def test_a_solid_on_a_confirmed_tracks_hull_is_held_up_to_the_hull_hold() -> None:
    """A solid on a buoy's confirmed LiDAR track was a hull, not spray: it is held 1 s, not 0.5 s; a solid on no
    track, on a tentative track's hull or on a radar-only track's (clutter too often) is gone after 0.5 s."""
    buoy = Track(4, 0.0, np.array([20.5, 0.0]), np.zeros(2), 0.0, 0.0, 1.0, 1.0, 1.0, confirmed=True)
    assert held_on(buoy, [buoy]) == [2000, 2000, 2000, UNKNOWN]
    assert held_on(None, [buoy]) == [2000, UNKNOWN, UNKNOWN, UNKNOWN]
    assert held_on(replace(buoy, confirmed=False), [buoy]) == [2000, UNKNOWN, UNKNOWN, UNKNOWN]
    assert held_on(buoy, []) == [2000, 2000, 2000, UNKNOWN]  # the track's end does not end the hull
    assert held_on(buoy, [buoy], hull_hold_s=0.5) == [2000, UNKNOWN, UNKNOWN, UNKNOWN]
    assert held_on(replace(buoy, source="fused"), []) == [2000, 2000, 2000, UNKNOWN]
    assert held_on(replace(buoy, source="radar"), []) == [2000, UNKNOWN, UNKNOWN, UNKNOWN]


def test_a_solid_on_remembered_structure_is_held_up_to_the_hull_hold() -> None:
    """A solid where the LiDAR remembers a quay is held 1 s like a tracked hull's (a quay does not move); one the
    lookup does not place on structure, 0.5 s. The lookup is asked in world (north, east) and gets the solid."""
    asked: list[np.ndarray] = []

    def quay_at_20_m_north(world: np.ndarray) -> np.ndarray:
        asked.append(world)
        return np.hypot(world[:, 0] - 20.0, world[:, 1]) < 0.5

    assert held_on(None, [], on_structure=quay_at_20_m_north) == [2000, 2000, 2000, UNKNOWN]
    assert np.allclose(asked[0], [[20.0, 0.0]])
    assert held_on(None, [], on_structure=lambda w: np.zeros(len(w), dtype=bool)) == [2000, UNKNOWN, UNKNOWN, UNKNOWN]
    assert held_on(None, [], hull_hold_s=0.5, on_structure=quay_at_20_m_north) == [2000, UNKNOWN, UNKNOWN, UNKNOWN]


MOUNT = Mount(z=-1.6)
WALL_BINS = [70, 71, 0, 1, 2]  # a wall 20 m ahead, 6 m wide, from a boat heading north


def level(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros(np.shape(t)), np.zeros(np.shape(t))


def after_a_wall(ego: SteadyEgo | None) -> tuple[PerceptionPipeline, PerceptionOutput]:
    """The daemon's pipeline on the shipped defaults, LiDAR only, after one revolution at 0.1 s with the wall."""
    pipeline = lidar_pipeline(MOUNT)
    wall = (((20.0, -3.0), (20.0, 3.0), 2.0),)
    seen = pipeline.step(0.1, scan_of(revolution_over_water(MOUNT, level, yaw=0.0, walls=wall), 0.1), [], ego)
    assert (seen.distances_cm[WALL_BINS] <= 2020).all() and (seen.distances_cm[WALL_BINS] >= 2000).all()
    assert not seen.held_bins.any()
    return pipeline, seen


def nothing_returned(t0: float) -> LidarScan:
    """A revolution in which no firing returned (the whole sensor dropped out for a sweep)."""
    ret = revolution_over_water(MOUNT, level, yaw=0.0, water_returns=False, t0=t0)
    assert ret.t.size == 0
    return scan_of(ret, t0 + 0.1)


def test_the_pipeline_holds_a_wall_through_a_revolution_that_returned_nothing() -> None:
    """A wall 20 m ahead, then a revolution in which nothing returned: the wall's bins still hold it; 0.6 s after
    its last return the memory has let it go and the bins are unknown, never clear."""
    ego = SteadyEgo(level, 0.0)
    pipeline, seen = after_a_wall(ego)
    held = pipeline.step(0.2, nothing_returned(0.1), [], ego)
    np.testing.assert_array_equal(held.distances_cm[WALL_BINS], seen.distances_cm[WALL_BINS])
    assert set(np.flatnonzero(held.held_bins).tolist()) == set(WALL_BINS)
    later = pipeline.step(0.7, nothing_returned(0.6), [], ego)
    assert (later.distances_cm[WALL_BINS] == UNKNOWN).all()


@pytest.mark.parametrize("hold_structure, bins_at_0_9_s", [(True, "held"), (False, "unknown")])
def test_the_pipeline_holds_a_quay_it_remembers_as_long_as_a_tracked_hull(
    hold_structure: bool, bins_at_0_9_s: str
) -> None:
    """A quay face 20 m ahead, 90 m long (longer than any vessel: structure the LiDAR remembers), then revolutions
    in which nothing returned: 0.8 s after its last return its bins ahead still hold it (obstacle_hold_structure,
    the hull hold of 1 s); with the rule off they are unknown after the 0.5 s hold, as for any solid."""
    ego = SteadyEgo(level, 0.0)
    pipeline = lidar_pipeline(MOUNT)
    pipeline.settings = replace(pipeline.settings, obstacle_hold_structure=hold_structure)
    quay = (((20.0, -45.0), (20.0, 45.0), 2.0),)
    seen = pipeline.step(0.1, scan_of(revolution_over_water(MOUNT, level, yaw=0.0, walls=quay), 0.1), [], ego)
    assert (seen.distances_cm[WALL_BINS] <= 2020).all() and (seen.distances_cm[WALL_BINS] >= 2000).all()
    later = pipeline.step(0.9, nothing_returned(0.8), [], ego)
    if bins_at_0_9_s == "held":
        np.testing.assert_array_equal(later.distances_cm[WALL_BINS], seen.distances_cm[WALL_BINS])
    else:
        assert (later.distances_cm[WALL_BINS] == UNKNOWN).all()


def test_without_the_boats_pose_nothing_is_held() -> None:
    """In "no ego pose" mode the body frame at start stands for the world, so a held solid could not follow the boat's
    turns: the memory is off and a revolution that returned nothing leaves the wall's bins unknown."""
    pipeline, _ = after_a_wall(None)
    after = pipeline.step(0.2, nothing_returned(0.1), [], None)
    assert (after.distances_cm[WALL_BINS] == UNKNOWN).all() and not after.held_bins.any()


def test_ticks_without_new_data_do_not_renew_the_hold() -> None:
    """One revolution with a wall at 0.1 s, then ticks with no new revolution: the array re-sends that revolution's
    returns while the LiDAR counts as fresh (0.5 s), but they are not new measurements, so the memory holds the wall
    for 0.5 s after 0.1 s, not after each tick: at 0.65 s the bins are unknown (they stayed held until 1.0 s when
    every tick renewed the hold)."""
    ego = SteadyEgo(level, 0.0)
    pipeline, _ = after_a_wall(ego)
    for k in range(2, 6):  # 0.2 .. 0.5: the revolution of 0.1 s is still fresh and still in the array
        out = pipeline.step(0.1 * k, None, [], ego)
        assert (out.distances_cm[WALL_BINS] <= 2020).all() and not out.held_bins.any()
    after = pipeline.step(0.65, None, [], ego)
    assert (after.distances_cm[WALL_BINS] == UNKNOWN).all()
