"""LiDAR preprocessing: range, height and own-boat filters, spray rejection, body FRD -> world NED."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracker.lidar.config import PreprocessConfig
from tracker.lidar.preprocess import preprocess

CFG = PreprocessConfig(
    min_range=1.0,
    max_range=100.0,
    min_height=-0.3,
    max_height=15.0,
    origin_height_above_water=0.5,
    own_box=(-2.5, 1.0, -1.0, 1.0, -2.0, 1.0),
    spray_max_height=0.6,
    spray_radius=0.5,
    spray_min_neighbours=3,
)
POS = np.array([100.0, 50.0, 0.0])  # body origin in world NED; the water is 0.5 m below it (z = +0.5)


def test_single_pose_transform_and_height_limits() -> None:
    # Level boat heading east (yaw 90 deg): body x (bow) -> world east, body y (starboard) -> world south.
    body = np.array(
        [
            [20.0, 5.0, -1.0],  # 1.5 m above water: kept
            [20.0, 5.0, -16.0],  # 16.5 m above water: too high
            [20.0, 5.0, 1.0],  # 0.5 m below water: a mirror image
            [0.5, 0.2, 0.0],  # closer than min_range
            [150.0, 0.0, -1.0],  # beyond max_range
            [-2.0, 0.5, -1.0],  # on the own boat
            [np.nan, 1.0, 1.0],
        ]
    )
    res = preprocess(body, POS, 0.0, 0.0, math.pi / 2, CFG)
    assert res.keep.tolist() == [True, False, False, False, False, False, False]
    assert res.points_world == pytest.approx(np.array([[95.0, 70.0, -1.0]]))
    assert (res.n_height, res.n_range, res.n_own_boat, res.n_nonfinite, res.n_spray) == (2, 2, 1, 1, 0)


def test_per_point_pose() -> None:
    body = np.array([[10.0, 0.0, -2.0], [10.0, 0.0, -2.0]])
    yaw = np.array([0.0, math.pi / 2])
    pos = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 0.0]])
    res = preprocess(body, pos, np.zeros(2), np.zeros(2), yaw, CFG)
    assert res.points_world == pytest.approx(np.array([[10.0, 0.0, -2.0], [1.0, 12.0, -2.0]]), abs=1e-12)


def test_roll_moves_points_in_height() -> None:
    # Rolled 10 deg to starboard: body (0, 10, -3) -> world (0, 10 cos + 3 sin, 10 sin - 3 cos).
    roll = math.radians(10.0)
    res = preprocess(np.array([[0.0, 10.0, -3.0]]), np.zeros(3), roll, 0.0, 0.0, CFG)
    expected = [0.0, 10.0 * math.cos(roll) + 3.0 * math.sin(roll), 10.0 * math.sin(roll) - 3.0 * math.cos(roll)]
    assert res.points_world == pytest.approx(np.array([expected]))


def test_spray_is_removed_but_low_hulls_are_kept() -> None:
    rng = np.random.default_rng(4)
    # A dinghy's gunwale 0.3 m above the water: 40 returns along 3 m (body z = 0.5 - 0.3 = 0.2).
    gunwale = np.stack([np.linspace(15.0, 18.0, 40), np.full(40, 3.0), np.full(40, 0.2)], axis=1)
    # Spray: 30 isolated returns 0.3 m above the water (above the 0.15 m sea margin), metres apart.
    clutter = np.stack([rng.uniform(5, 60, 30), rng.uniform(-30, 30, 30), np.full(30, 0.2)], axis=1)
    # A hull at 30 m: three rings 1 m apart, the lowest 0.2 m above the water, returns 0.1 m apart along each.
    ring = np.linspace(-6.0, -4.0, 20)
    hull = np.concatenate([np.stack([np.full(20, 30.0), ring, np.full(20, z)], axis=1) for z in (0.3, -0.7, -1.7)])
    res = preprocess(np.concatenate([gunwale, clutter, hull]), POS, 0.0, 0.0, 0.0, CFG)
    assert res.keep[:40].all()
    assert not res.keep[40:70].any()
    assert res.keep[70:].all()
    assert res.n_spray == 30
    assert res.points_world.shape == (100, 3)


def test_empty_and_all_bad_input() -> None:
    res = preprocess(np.zeros((0, 3)), POS, 0.0, 0.0, 0.0, CFG)
    assert res.points_world.shape == (0, 3) and res.keep.shape == (0,)
    res = preprocess(np.full((4, 3), np.nan), POS, 0.0, 0.0, 0.0, CFG)
    assert res.points_world.shape == (0, 3) and res.n_nonfinite == 4


def test_pose_index_picks_each_points_pose_from_a_table() -> None:
    # Three poses, four points: points 0 and 3 at pose 0 (heading north; all beyond the spray check),
    # 1 at pose 2 (east), 2 at pose 1.
    body = np.array([[10.0, 0.0, -2.0], [10.0, 0.0, -2.0], [0.0, 10.0, -2.0], [15.0, 5.0, -2.0]])
    pos = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [2.0, -3.0, 0.0]])
    yaw = np.array([0.0, math.pi, math.pi / 2])
    res = preprocess(body, pos, np.zeros(3), np.zeros(3), yaw, CFG, pose_index=np.array([0, 2, 1, 0]))
    expected = np.array([[10.0, 0.0, -2.0], [2.0, 7.0, -2.0], [1.0, -9.0, -2.0], [15.0, 5.0, -2.0]])
    assert res.points_world == pytest.approx(expected, abs=1e-12)


def test_a_point_whose_pose_is_unknown_is_dropped_as_nonfinite() -> None:
    body = np.array([[10.0, 0.0, -2.0], [12.0, 0.0, -2.0]])
    pos = np.array([[0.0, 0.0, 0.0], [np.nan, np.nan, np.nan]])
    res = preprocess(body, pos, np.zeros(2), np.zeros(2), np.zeros(2), CFG, pose_index=np.array([0, 1]))
    assert res.keep.tolist() == [True, False] and res.n_nonfinite == 1


def test_cube_grid_counts_match_a_ball_query_and_bound_it() -> None:
    from scipy.spatial import cKDTree

    from tracker.lidar.preprocess import CubeGrid

    rng = np.random.default_rng(4)
    pts = np.concatenate([rng.uniform(0.0, 3.0, (400, 3)), rng.normal(10.0, 0.2, (50, 3))])
    query = np.array([0, 7, 100, 399, 400, 449])
    grid = CubeGrid(pts, 0.5)
    exact = cKDTree(pts).query_ball_point(pts[query], r=0.5, return_length=True) - 1
    assert grid.exact_counts(query).tolist() == exact.tolist()
    upper = grid.upper_counts(query)
    assert np.all(upper >= exact) and np.all(upper <= len(pts) - 1)
    # a lone point has no neighbours either way
    lone = CubeGrid(np.array([[0.0, 0.0, 0.0], [5.0, 5.0, 5.0]]), 0.5)
    assert lone.exact_counts(np.array([0, 1])).tolist() == [0, 0]
    assert lone.upper_counts(np.array([0, 1])).tolist() == [0, 0]


def test_empty_scan_and_a_bad_pose_index() -> None:
    res = preprocess(np.zeros((0, 3)), np.zeros((0, 3)), 0.0, 0.0, 0.0, CFG)
    assert res.points_world.shape == (0, 3) and res.keep.shape == (0,)
    body = np.array([[10.0, 0.0, -2.0], [12.0, 0.0, -2.0]])
    with pytest.raises(ValueError, match="pose index"):
        preprocess(body, np.zeros((2, 3)), np.zeros(2), np.zeros(2), np.zeros(2), CFG, pose_index=np.array([0, 2]))


def test_reasons_name_each_points_rule_and_add_up_to_the_counts() -> None:
    from tracker.lidar.preprocess import HEIGHT, KEPT, NONFINITE, OWN_BOAT, RANGE, SPRAY

    body = np.array(
        [
            [20.0, 5.0, -1.0],  # kept
            [20.0, 5.0, -16.0],  # too high
            [0.5, 0.2, 0.0],  # closer than min_range
            [-2.0, 0.5, -1.0],  # on the own boat
            [np.nan, 1.0, 1.0],
            [30.0, -8.0, 0.1],  # a lone low return in mid-sea: spray
        ]
    )
    res = preprocess(body, POS, 0.0, 0.0, math.pi / 2, CFG, reasons=True)
    assert res.reason is not None and res.reason.dtype == np.int8
    assert res.reason.tolist() == [KEPT, HEIGHT, RANGE, OWN_BOAT, NONFINITE, SPRAY]
    assert np.bincount(res.reason, minlength=8).tolist() == list(res.counts().values())
    assert preprocess(body, POS, 0.0, 0.0, math.pi / 2, CFG).reason is None  # not asked for: not built


def test_ring_runs_count_consecutive_firings_at_one_range() -> None:
    from tracker.lidar.range_image import FIRING_S, LASER_OF_RING, SEQUENCE_S, RangeImage

    # ring 6: firings 0-4 at 25 m (a run of 5), firing 5 silent, 6-7 at 25 m (2); firing 8 at 30 m (1, a jump);
    # ring 7: firing 0 at 25 m alone
    seq = np.array([0, 1, 2, 3, 4, 6, 7, 8, 0])
    ring = np.array([6, 6, 6, 6, 6, 6, 6, 6, 7])
    r = np.array([25.0, 25.05, 25.1, 25.1, 25.2, 25.0, 25.0, 30.0, 25.0])
    t = seq * SEQUENCE_S + LASER_OF_RING[ring] * FIRING_S
    image = RangeImage.build(t, ring, r)
    assert image is not None
    members = np.arange(seq.size)
    assert image.ring_runs(members, r, 0.1, 0.02).tolist() == [5, 5, 5, 5, 5, 2, 2, 1, 1]
    # only the members count: without firing 2 the first run splits in two
    some = np.array([0, 1, 3, 4])
    assert image.ring_runs(some, r[some], 0.1, 0.02).tolist() == [2, 2, 2, 2]


def test_returns_under_the_band_do_not_break_a_solid_lines_run_of_feet() -> None:
    """One laser (ring 7) along a hull 40 m ahead: six firings on its side 0.6 m up (solid), then five along its
    waterline in the troughs, 0.05 m under the surface (within the band and the sea margin) and, where the fitted
    surface stands above the trough, 0.4 m under it (below min_height). The margin's returns are the hull's feet
    only in a run holding its solid ones; the two under the band broke that run after the sixth firing, and the
    waterline went unknown. They count in the run now, and all five are feet (obstacle array only, not the tracker's
    points). (Just under the surface, not above it, so that the calm-water rule, which keeps a line's returns above
    the surface, does not take them first.)"""
    from tracker.lidar.range_image import FIRING_S, LASER_OF_RING, SEQUENCE_S

    cfg = PreprocessConfig(origin_height_above_water=0.5)
    seq = np.arange(11)
    height = np.array([0.6] * 6 + [-0.4, -0.05, -0.4, -0.05, -0.05])
    bearing = np.radians(0.2) * seq  # one firing every 0.2 deg
    body = np.column_stack([40.0 * np.cos(bearing), 40.0 * np.sin(bearing), 0.5 - height])  # FRD: z down
    ring = np.full(seq.size, 7)
    point_t = seq * SEQUENCE_S + LASER_OF_RING[ring] * FIRING_S
    res = preprocess(body, POS, 0.0, 0.0, 0.0, cfg, ring=ring, point_t=point_t)
    assert res.points_world.shape[0] == 6  # the side: the tracker's
    feet_north_east = res.feet_world[:, :2] - POS[:2]
    expected = (body[6:, :2])[np.argsort(body[6:, 1])]
    np.testing.assert_allclose(feet_north_east[np.argsort(feet_north_east[:, 1])], expected, atol=1e-9)
