"""A boat rolling and pitching over the sea: water returns never become obstacles or clusters.

The daemon's pipeline is built exactly as `usv-tracker run` builds it (`pipeline_for` on the shipped defaults), and
the revolution comes from plain geometry (tests/sea_geometry.py), not from the simulator: every firing of a VLP-16
1.6 m above the water that meets the water returns from it, the worst case of a choppy surface.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

import tracker.lidar.preprocess as preprocess_module
from drivers.mount import Mount
from tests.sea_geometry import SteadyEgo, chop, lidar_pipeline, revolution_over_water, scan_of, travelling_chop
from tracker.lidar.preprocess import REASON_NAMES
from tracker.obstacle_map import UNKNOWN
from tracker.pipeline import PerceptionOutput, PerceptionPipeline

ROLL, PITCH, YAW = math.radians(5.0), math.radians(3.0), 0.3
MOUNT = Mount(z=-1.6)


def steady(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.full(np.shape(t), ROLL), np.full(np.shape(t), PITCH)


def rolling(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """5 deg of roll over a 4 s period, 3 deg of pitch over 3 s: the attitude turns 0.8 deg within one sweep."""
    t = np.asarray(t, float)
    return ROLL * np.sin(2 * math.pi * t / 4.0 + 0.3), PITCH * np.sin(2 * math.pi * t / 3.0 + 1.0)


@pytest.mark.parametrize("attitude", [steady, rolling], ids=["rolled-5-pitched-3", "rolling"])
def test_flat_sea_under_a_tilted_boat_gives_no_obstacle_and_no_cluster(attitude) -> None:
    pipeline = lidar_pipeline(MOUNT)
    ego = SteadyEgo(attitude, YAW)
    for k in range(3):  # three revolutions: the tracker would confirm a track on the third
        ret = revolution_over_water(MOUNT, attitude, yaw=YAW, t0=0.1 * k)
        # the geometry is the worst case the issue describes: thousands of water returns between 6 and 30 m
        assert ret.t.size > 5000
        horizontal = np.hypot(ret.xyz_body[:, 0], ret.xyz_body[:, 1])
        assert np.count_nonzero((horizontal > 6) & (horizontal < 30)) > 1000
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
        obstacle = out.distances_cm <= 10000
        assert not obstacle.any(), f"revolution {k}: obstacle bins {np.flatnonzero(obstacle).tolist()}"
        assert pipeline.lidar_tracker.last_clusters == []
        assert out.tracks == []
    assert np.all((out.distances_cm == 10001) | (out.distances_cm == UNKNOWN))


def test_choppy_heaving_sea_gives_no_obstacle_and_a_low_hull_in_it_still_does() -> None:
    """Crests +-0.3 m, the boat heaved 0.2 m up (which the autopilot does not report) and rolling: the water is
    found from its own returns, and a hull 0.8 m high at 20 m on the 45 deg bearing stays an obstacle."""
    pipeline = lidar_pipeline(MOUNT)
    ego = SteadyEgo(rolling, YAW)
    bearing = math.radians(45.0) + YAW  # world bearing of the body's 45 deg
    centre = 20.0 * np.array([math.cos(bearing), math.sin(bearing)])
    along = np.array([-math.sin(bearing), math.cos(bearing)])
    wall = (tuple(centre - 1.5 * along), tuple(centre + 1.5 * along), 0.8)
    for k in range(4):
        water_only = k < 3
        ret = revolution_over_water(
            MOUNT, rolling, yaw=YAW, origin_height=0.2, elevation=chop, t0=0.1 * k, walls=() if water_only else (wall,)
        )
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
        pre = pipeline.last_preprocess
        obstacle = np.flatnonzero(out.distances_cm <= 10000)
        if water_only:
            assert obstacle.tolist() == [], f"revolution {k}"
            assert pipeline.lidar_tracker.last_clusters == []
            assert out.tracks == []
        else:
            # the sea state was measured: the margin covers the 0.3 m crests, and 3 sigmas of the sea (0.13 m) plus
            # the 5 cm pad by at most 3 cm
            assert pre.water.measured and 0.3 <= pre.water.margin <= 0.48
            assert pre.water.offset == pytest.approx(-0.2, abs=0.05)  # the mean water, 0.2 m below the waterline
            # the hull's face spans bearings 40.7-49.3 deg, bins 8-10, at 20.0-20.1 m
            assert obstacle.tolist() == [8, 9, 10]
            np.testing.assert_allclose(out.distances_cm[obstacle] / 100.0, 20.05, atol=0.1)
            assert len(pipeline.lidar_tracker.last_clusters) == 1


def _face_in_chop(
    range_m: float, grow_m: float = 0.5, **preprocess: float
) -> tuple[PerceptionPipeline, PerceptionOutput, np.ndarray, np.ndarray]:
    """Eight revolutions of a 6 m hull face 1.2 m high, ``range_m`` off on the 45 deg bearing, in the chop of the
    test above (hull gate grown by ``grow_m``; ``preprocess`` overrides the shipped PreprocessConfig). Returns the
    pipeline, the last output, and each within-margin return's (radial, along) offset from the face's centre."""
    pipeline = lidar_pipeline(MOUNT)
    pipeline.settings = replace(pipeline.settings, hull_margin_grow_m=grow_m)
    pipeline.lidar_preprocess_config = replace(pipeline.lidar_preprocess_config, **preprocess)
    ego = SteadyEgo(rolling, YAW)
    bearing = math.radians(45.0) + YAW
    radial = np.array([math.cos(bearing), math.sin(bearing)])
    along = np.array([-math.sin(bearing), math.cos(bearing)])
    centre = range_m * radial
    wall = (tuple(centre - 3.0 * along), tuple(centre + 3.0 * along), 1.2)
    for k in range(8):
        ret = revolution_over_water(
            MOUNT, rolling, yaw=YAW, origin_height=0.2, elevation=chop, t0=0.1 * k, walls=(wall,)
        )
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
    rel = pipeline.last_preprocess.within_margin_world[:, :2] - centre
    return pipeline, out, np.abs(rel @ radial), np.abs(rel @ along)


def _hull_in_chop(grow_m: float) -> tuple[int, int, int, int]:
    """The face of ``_face_in_chop`` 25 m off; of the last revolution: solid returns, within-margin returns on the
    face (within 0.3 m of it), those on it or at its foot (0.5 m in front of it, or its ends), and those
    elsewhere."""
    _, out, radial, along = _face_in_chop(25.0, grow_m)
    on_face = (radial <= 0.3) & (along <= 3.0)
    at_foot = (radial <= 0.5) & (along <= 3.5)
    assert [t.confirmed for t in out.tracks] == [True]
    n_face, n_foot = int(np.count_nonzero(on_face)), int(np.count_nonzero(at_foot))
    return out.n_lidar_points, n_face, n_foot, int(np.count_nonzero(~at_foot))


def test_a_tracked_hulls_returns_within_the_sea_margin_are_obstacles_and_the_crests_around_it_are_not() -> None:
    """The margin over the crests (0.3-0.48 m) hides the face's foot; once the face is a confirmed track, its own
    returns in that band (and the crests at its foot, within 0.5 m in front of it) are solid again
    (tracker/lidar/hull_gate.py), and the crests beyond its box stay water."""
    gated, on_face, at_foot, off_face = _hull_in_chop(0.5)
    plain, on_face_plain, _, _ = _hull_in_chop(-1.0)
    assert on_face == on_face_plain and on_face >= 10  # the face's foot, met by the low beams
    assert off_face > 100  # crests in the band everywhere else
    assert on_face <= gated - plain <= at_foot


def _face_margin_heights(range_m: float, **preprocess: float) -> np.ndarray:
    """Heights above the fitted sea of the within-margin returns on the face of ``_face_in_chop`` at ``range_m``."""
    pipeline, _, radial, along = _face_in_chop(range_m, **preprocess)
    pre = pipeline.last_preprocess
    low = pre.within_margin_world
    origin_height = pipeline.lidar_preprocess_config.origin_height_above_water
    height = origin_height - low[:, 2] - pre.water.surface(low[:, 0], low[:, 1])
    return height[(radial <= 0.3) & (along <= 3.0)]


def test_a_hulls_waterline_below_the_calm_floor_is_offered_to_the_hull_gate_beyond_20_m_only() -> None:
    """35 m off the -3 deg beam meets the face 0-10 cm above the sea, as low as a crest's top and below the calm
    floor (0.15 m): beyond waterline_gate_range (20 m) such returns go to the hull gate (within_margin_world), which
    makes those inside a tracked hull's box obstacles. 14 m off the face is met above the floor, and nothing nearer
    than 20 m below the floor is offered: there it was crests beside false tracks."""
    floor = lidar_pipeline(MOUNT).lidar_preprocess_config.water.margin_floor
    far = _face_margin_heights(35.0)
    assert np.count_nonzero(far <= floor) >= 5 and np.all(far >= -0.05)  # the waterline, not the sea below it
    far_off = _face_margin_heights(35.0, waterline_gate_range=100.0)
    assert np.all(far_off > floor) and far_off.size == np.count_nonzero(far > floor)
    near = _face_margin_heights(14.0)
    assert near.size >= 20 and np.all(near > floor)


def _assert_no_obstacle_over(
    attitude: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    elevation_at: Callable[[float], Callable[[np.ndarray, np.ndarray], np.ndarray]],
    share: float,
    revolutions: int,
    first_seed: int = 0,
) -> None:
    """Revolutions from the boat 0.2 m over the sea ``elevation_at(t)``, ``share`` of the firings meeting it
    returning (drawn afresh each revolution): the water is fitted every revolution, and no bin holds an obstacle and
    no track forms in any of them."""
    pipeline = lidar_pipeline(MOUNT)
    ego = SteadyEgo(attitude, YAW)
    for k in range(revolutions):
        ret = revolution_over_water(
            MOUNT,
            attitude,
            yaw=YAW,
            origin_height=0.2,
            elevation=elevation_at(0.1 * k),
            t0=0.1 * k,
            water_share=(share, first_seed + k),
        )
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
        assert pipeline.last_preprocess.water.measured
        assert np.flatnonzero(out.distances_cm <= 10000).tolist() == [], f"revolution {k}"
        assert out.tracks == []


@pytest.mark.parametrize(
    ("attitude", "share"),
    [(steady, 0.3), (steady, 0.6), (rolling, 0.3), (rolling, 0.6)],
    ids=["listing-30%", "listing-60%", "rolling-30%", "rolling-60%"],
)
def test_a_sea_returning_part_of_its_firings_gives_no_obstacle_over_ten_revolutions(attitude, share: float) -> None:
    """The chop above returning a share of the firings that meet it, drawn afresh each revolution, under a boat
    heeled steadily (5 deg roll, 3 deg pitch) or rolling. Listing, the -11 deg laser meets the mean water at 19-20 m
    on the high side and reaches beyond 20 m in the troughs of 4 bins; its far end (a trough as deep as the sea
    margin) lay beyond 20 m in 15 bins, and counted against all of those the trough returns looked sporadic: once in
    three revolutions five of them in a row were a "line", an obstacle at 22 m in bins 61-62. This chop stands
    still, so its returns recur at one place: the rule that makes margin returns recurring in one cell obstacles
    (PipelineSettings.lidar_margin_persistence), applied on every laser, put obstacles at 14-39 m here from the
    fourth revolution; it applies on lasers whose sea is sparse only."""
    _assert_no_obstacle_over(attitude, lambda t: chop, share, 10)


@pytest.mark.parametrize(("attitude", "revolutions"), [(steady, 15), (rolling, 35)], ids=["listing", "rolling"])
def test_a_travelling_sea_returning_a_third_of_its_firings_gives_no_obstacle(attitude, revolutions: int) -> None:
    """The chop travelling as a sea does (tests/sea_geometry.py travelling_chop), 30 % of the firings meeting it
    returning. Listing, the -11 deg laser comes down through the margin at 14-25 m on the high side, and only the
    troughs take it beyond 20 m: its 7-27 returns a revolution there were counted against all the firings of every
    bin they lay in, a rate of a few per cent, "sparse", and five trough returns in a row at 20.3-20.5 m were a
    line, an obstacle in bins 61-62 from revolution 8, held for ten revolutions; rolling, in bins 12-13 from
    revolution 29. A bin's firings now count as met beyond 20 m in the share of its water returns lying there."""
    _assert_no_obstacle_over(attitude, travelling_chop, 0.3, revolutions)


def test_chance_runs_in_a_sparse_travelling_sea_are_not_lines() -> None:
    """The travelling chop returning 10 % of the firings under the listing boat: sparse by the grazing-line rule's
    rates, yet over some thousand firings a run of 5 comes by chance (n p**5), and in revolution 32 five trough
    returns in a row 23.4-23.7 m off were a line, an obstacle in bins 20-21 and a track. The run a line needs grows
    with the laser's sporadic rate until chance gives one in a thousand revolutions (grazing_line_chance)."""
    _assert_no_obstacle_over(steady, travelling_chop, 0.1, 40, first_seed=100)


def higher_chop(north: np.ndarray, east: np.ndarray) -> np.ndarray:
    """The chop above with crests 1.5 times as high: +-0.45 m, still within sea state 3."""
    return 1.5 * chop(north, east)


def rolling_8(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return math.radians(8.0) * np.sin(2 * math.pi * np.asarray(t, float) / 3.0), np.zeros(np.shape(t))


def test_a_sea_the_surface_fit_refuses_is_unknown_not_obstacles() -> None:
    """Crests of +-0.45 m under a boat heeled 5 deg and 3 deg: the lasers' median heights disagree by 0.21 m (the
    steep ones see troughs, the grazing ones crests' faces), more than the fit takes from water (0.2 m; a quay's
    lasers disagree by 0.5), so no surface is fitted. With the calm floor (0.15 m) as the margin the crests were
    obstacles in 69 of 72 bins and 56 confirmed tracks by the third revolution. A sea returning by the hundred
    within 15 m with no surface fitted has nothing up to margin_max (1 m) taken for a solid, and the bins are
    unknown: the beams vouch for nothing below that."""
    pipeline = lidar_pipeline(MOUNT)
    ego = SteadyEgo(steady, 1.2)
    for k in range(3):
        ret = revolution_over_water(MOUNT, steady, yaw=1.2, elevation=higher_chop, t0=0.1 * k, water_share=(0.9, k))
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
        water = pipeline.last_preprocess.water
        assert not water.measured and water.margin == 1.0
        assert np.all(out.distances_cm == UNKNOWN), f"revolution {k}"
        assert out.tracks == []


def test_crest_faces_paired_by_two_lasers_in_a_higher_sea_are_not_feet() -> None:
    """The same crests under a boat rolling 8 deg: the fit takes this sea (margin 0.6 m). Two adjacent lasers,
    0.035 m apart per metre of range, meet one crest's face at the same range out to 2 x 0.45 / tan(2 deg) = 26 m,
    and from 20 m such pairs were taken for a face's foot: obstacles at 20-23 m, now and then, all round."""
    pipeline = lidar_pipeline(MOUNT)
    ego = SteadyEgo(rolling_8, 1.2)
    for k in range(10):
        ret = revolution_over_water(
            MOUNT, rolling_8, yaw=1.2, elevation=higher_chop, t0=0.1 * k, water_share=(0.6, 40 + k)
        )
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
        assert pipeline.last_preprocess.water.measured
        assert np.flatnonzero(out.distances_cm <= 10000).tolist() == [], f"revolution {k}"


def _low_hull_in_chop(water_share: tuple[float, int] | None) -> tuple[np.ndarray, object]:
    """Four revolutions from a level boat of a hull 0.5 m high and 3 m wide, 25 m dead ahead, in the chop above; the
    sea returns ``water_share`` of the firings meeting it (None: every one). The -3 deg beam meets the hull 0.29 m
    above the mean water, under the crests' margin; the -1 deg beam passes 1.16 m up, over it."""

    def level(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(np.shape(t)), np.zeros(np.shape(t))

    pipeline = lidar_pipeline(MOUNT)
    ego = SteadyEgo(level, 0.0)
    hull = (((25.0, -1.5), (25.0, 1.5), 0.5),)
    for k in range(4):
        share = None if water_share is None else (water_share[0], water_share[1] + k)
        ret = revolution_over_water(MOUNT, level, yaw=0.0, elevation=chop, t0=0.1 * k, walls=hull, water_share=share)
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
    return out.distances_cm, pipeline.last_preprocess


def test_a_low_hull_under_the_crests_margin_is_an_obstacle_where_the_sea_returns_sporadically() -> None:
    d, pre = _low_hull_in_chop((0.05, 7))
    assert pre.water.measured and pre.water.margin > 0.29  # the hull's line lies inside the sea margin
    assert pre.n_grazing >= 20  # its run of firings along the -3 deg ring
    obstacle = np.flatnonzero(d <= 10000)
    assert 0 in obstacle.tolist() and set(obstacle.tolist()) <= {71, 0, 1}  # the hull spans -3.4..3.4 deg
    assert abs(int(d[0]) - 2500) <= 30


def test_the_same_hull_in_a_sea_returning_every_firing_is_not_told_from_a_crest() -> None:
    # every grazing firing returns: the crests draw lines too, the -3 deg ring's far margin returns fill every bin,
    # and no line on it is trusted - the hull's bins stay unknown rather than the crests becoming obstacles
    d, pre = _low_hull_in_chop(None)
    assert pre.n_grazing == 0
    assert np.all(d[d <= 10000] >= 2400)  # nothing nearer than the hull: no crest became an obstacle


def test_low_hulls_filling_most_of_a_grazing_beams_margin_returns_are_obstacles_where_its_sea_is_sparse() -> None:
    """Two boats 12 m long and 0.5 m high lie broadside 25 m ahead and astern in the chop above. The -3 deg beam
    meets each 0.29 m up, under the crests' margin, across 27 deg; the sea returns 80 % of the firings meeting it
    close in (the steep beams) but 0.1 % of the grazing ones beyond 20 m. So the boats fill most of the bins in
    which that beam returned anything in the margin: judged by those bins alone its water looked full, none of its
    lines was trusted, and both boats were unknown. Judged by all its firings that met the water (every bin), its
    sea is sparse: the boats are obstacles at their ranges, and no crest is."""

    def level(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(np.shape(t)), np.zeros(np.shape(t))

    pipeline = lidar_pipeline(MOUNT)
    ego = SteadyEgo(level, 0.0)
    boats = (((25.0, -6.0), (25.0, 6.0), 0.5), ((-25.0, -6.0), (-25.0, 6.0), 0.5))
    for k in range(3):
        ret = revolution_over_water(
            MOUNT, level, yaw=0.0, elevation=chop, t0=0.1 * k, walls=boats, water_share=(0.8, 20 + k, 20.0, 0.001)
        )
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
        pre = pipeline.last_preprocess
        assert pre.water.measured and pre.water.margin > 0.29  # the boats' lines lie inside the sea margin
        # each boat spans -13.5..13.5 deg about its beam: bins -3..3 of it; a bin's nearest return is at the bearing
        # nearest the beam, 25 m / cos(that bearing)
        offsets = np.arange(-3, 4)
        expected = 25.0 / np.cos(np.radians(np.maximum(np.abs(offsets) * 5.0 - 2.5, 0.0)))
        d = out.distances_cm
        for beam in (0, 36):
            np.testing.assert_allclose(d[(beam + offsets) % 72] / 100.0, expected, atol=0.05)
        assert np.count_nonzero(d <= 10000) == 2 * offsets.size  # and no crest anywhere else


@pytest.mark.parametrize(
    ("east_end", "far_share", "firings", "expected_cm"),
    [(0.9, 0.001, 4, 7700), (0.65, 0.001, 3, None), (0.9, 0.06, 4, None)],
    ids=["four-in-a-sparse-sea", "three-in-a-sparse-sea", "four-in-a-sea-returning-6-percent"],
)
def test_a_short_run_of_the_minus_1_deg_laser_far_out_is_an_obstacle_where_its_sea_is_sparse(
    east_end: float, far_share: float, firings: int, expected_cm: int | None
) -> None:
    """A quay corner 77 m dead ahead, 0.5 m high, in the chop above: only the -1 deg laser meets it, 0.26 m above
    the mean water (inside the sea margin), at one range, in four firings when it reaches 0.9 m to starboard of
    the bow line (azimuths 0-0.6 deg; the next, 0.8 deg, passes 1.08 m off) and three when it reaches 0.65 m. A
    line the tracker takes needs five (grazing_line_min_run, on a laser whose far sea returns at most 10 % of its
    firings); where it returns at most 3 % (grazing_line_array_max_sporadic) four are a face for the obstacle
    array (grazing_line_array_run), and bin 0 carries it. Three stay water, and so do four where the far sea
    returns 6 % (a rough sea's crests draw runs of four there): the bin is unknown."""

    def level(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(np.shape(t)), np.zeros(np.shape(t))

    pipeline = lidar_pipeline(MOUNT)
    ego = SteadyEgo(level, 0.0)
    corner = (((77.0, -0.1), (77.0, east_end), 0.5),)
    for k in range(3):
        ret = revolution_over_water(
            MOUNT, level, yaw=0.0, elevation=chop, t0=0.1 * k, walls=corner, water_share=(0.8, 30 + k, 20.0, far_share)
        )
        assert np.count_nonzero(ret.wall == 0) == firings  # all of the -1 deg laser, nothing else
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
        pre = pipeline.last_preprocess
        assert pre.water.measured and pre.water.margin > 0.26  # the corner's returns lie inside the sea margin
        obstacles = np.flatnonzero(out.distances_cm <= 10000).tolist()
        if expected_cm is None:
            assert out.distances_cm[0] == UNKNOWN and obstacles == []
        else:
            assert obstacles == [0] and abs(int(out.distances_cm[0]) - expected_cm) <= 5
            assert len(pre.feet_world) == firings  # the obstacle array's
            assert not np.any(np.hypot(*pre.points_world[:, :2].T) > 70.0)  # not the tracker's
        assert out.tracks == []


def test_a_low_pontoon_met_by_one_beam_stays_out_of_the_water_fit_and_is_an_obstacle() -> None:
    """A pontoon 0.45 m high and 60 m long lies 24 m off to starboard in the chop above; the sea returns 10 % of
    the firings meeting it. Only the -3 deg beam meets the pontoon, 0.34 m above the mean water abeam: a line of
    returns within the fit's search window. Fitted as water, that line tilted the surface 0.0055 up to starboard
    (0.13 m under the pontoon) and widened the margin to 0.55 m, so the pontoon's face measured 0.2 m up and its
    ends were lost in the margin: bins 14 and 21-22 unknown. Lines far out stay out of the fit, as far water never
    draws them: the surface stays level and the pontoon is an obstacle in every bin the beam meets it in. Beyond
    bins 14-22 the beam meets it under the calm margin (0.15 m): a line there in a sea this sparse is solid too
    (preprocess._grazing_lines), so the obstacle runs on to bins 10-26, where the pontoon ends 30 m off."""

    def level(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(np.shape(t)), np.zeros(np.shape(t))

    pipeline = lidar_pipeline(MOUNT)
    ego = SteadyEgo(level, 0.0)
    pontoon = (((-30.0, 24.0), (30.0, 24.0), 0.45),)
    for k in range(3):
        ret = revolution_over_water(
            MOUNT, level, yaw=0.0, elevation=chop, t0=0.1 * k, walls=pontoon, water_share=(0.1, 20 + k)
        )
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
        water = pipeline.last_preprocess.water
        assert water.measured and abs(water.slope_y) < 0.002 and abs(water.offset) < 0.03
        assert water.margin < 0.5
        # each bin the pontoon 24 m / cos(the bin's bearing nearest abeam) off: bins 14-22 (67.5-112.5 deg) above
        # the calm margin, 10-13 and 23-26 below it, where a crest in front may break the line at the bin's edge
        abeam = np.arange(10, 27)
        expected = 24.0 / np.cos(np.radians(np.maximum(np.abs(abeam - 18) * 5.0 - 2.5, 0.0)))
        tolerance = np.where(np.abs(abeam - 18) <= 4, 0.05, 0.6)
        assert np.all(np.abs(out.distances_cm[abeam] / 100.0 - expected) <= tolerance)
        assert np.all(out.distances_cm[abeam] / 100.0 >= expected - 0.05)  # never nearer: no crest in front of it
        assert set(np.flatnonzero(out.distances_cm <= 10000).tolist()) == set(abeam.tolist())


@pytest.mark.parametrize("below", [True, False], ids=["judged-by-the-steeper-lasers", "judged-alone"])
def test_a_low_pier_met_at_its_foot_by_the_one_laser_the_heel_brings_down_is_an_obstacle(
    below: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A pier 0.6 m high and 240 m long lies 22 m off to starboard in the chop above, the boat heeled 2.5 deg to
    starboard; the sea returns 10 % of the firings meeting it within 20 m and 1 % beyond. The -1 deg laser comes
    down to the water only on the heeled side (in 40 of the 72 bins) and meets the pier 0.1-0.3 m above the mean
    water, inside the sea margin (0.49 m); the lasers above pass over it, those below meet the water first. So the
    pier's foot is more than half of that laser's returns in the margin: judged alone, its sea looked full, none of
    its lines was trusted and the pier was unknown in all 23 of its bins. The lasers below it return a tenth of
    their firings from the water, and a laser grazing the sea 2 deg more flatly cannot return more of it."""
    roll = math.radians(2.5)

    def heeled(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.full(np.shape(t), roll), np.zeros(np.shape(t))

    pipeline = lidar_pipeline(MOUNT)
    ego = SteadyEgo(heeled, 0.0)
    pier = (((-120.0, 22.0), (120.0, 22.0), 0.6),)
    if not below:  # each laser's fill its own, as before the steeper lasers were asked
        monkeypatch.setattr(preprocess_module, "_fill_below", lambda fill, wet_bins: fill)
    for k in range(3):
        ret = revolution_over_water(
            MOUNT, heeled, yaw=0.0, elevation=chop, t0=0.1 * k, walls=pier, water_share=(0.1, 20 + k, 20.0, 0.01)
        )
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
    pre = pipeline.last_preprocess
    assert pre.water.measured and pre.water.margin > 0.4  # the pier's foot lies inside the sea margin
    d = out.distances_cm
    abeam = np.arange(7, 30)
    if not below:
        assert pre.n_grazing == 0 and np.all(d == UNKNOWN)
        return
    # each bin 22 m / cos(the bin's bearing nearest abeam) off, never nearer: no crest in front of it
    expected = 22.0 / np.cos(np.radians(np.maximum(np.abs(abeam - 18) * 5.0 - 2.5, 0.0)))
    assert np.all(d[abeam] / 100.0 >= expected - 0.05)
    assert np.all(d[abeam] / 100.0 <= expected + 0.3)
    assert set(np.flatnonzero(d <= 10000).tolist()) == set(abeam.tolist())


def _level_boat_in_chop(walls: tuple, **preprocess: float) -> tuple[np.ndarray, object, object]:
    """Three revolutions from a level boat of ``walls`` in the chop above, every firing returning, with these
    preprocess settings: the third revolution's bins, preprocess result (with per-point reasons) and returns."""

    def level(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(np.shape(t)), np.zeros(np.shape(t))

    pipeline = lidar_pipeline(MOUNT)
    pipeline.lidar_preprocess_config = replace(pipeline.lidar_preprocess_config, **preprocess)
    ego = SteadyEgo(level, 0.0)
    for k in range(3):
        ret = revolution_over_water(MOUNT, level, yaw=0.0, elevation=chop, t0=0.1 * k, walls=walls)
        pipeline.keep_view_detail = k == 2
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
    return out.distances_cm, pipeline.last_preprocess, ret


def _wall_in_chop(foot_min_range: float) -> tuple[np.ndarray, object, object]:
    """A quay face 3 m high and 6 m wide, 25 m dead ahead. The -3 deg beam meets the face 0.29 m up, within the
    crests' margin; the -1 deg beam meets it 1.16 m up, above."""
    return _level_boat_in_chop((((25.0, -3.0), (25.0, 3.0), 3.0),), vertical_foot_min_range=foot_min_range)


def test_a_faces_foot_within_the_sea_margin_is_solid_and_the_crests_are_not() -> None:
    d, pre, ret = _wall_in_chop(20.0)
    assert pre.water.measured and pre.water.margin > 0.29  # the foot lies within the sea margin
    foot = (ret.wall == 0) & (ret.ring == 6)  # the -3 deg ring on the face
    assert np.count_nonzero(foot) >= 20
    assert np.all(
        pre.reason[foot] == REASON_NAMES.index("kept")
    )  # kept: the -1 deg ring returned at the same range above it
    assert pre.n_grazing >= np.count_nonzero(foot)
    # the crests, returning every firing out to 30 m, stay water: no obstacle off the face's bins, none nearer. The
    # face spans +-6.8 deg (bins 71, 0, 1); its ends lie 0.3 m across the line of sight from bins 70 and 2, which
    # show its range too (PipelineSettings.bin_edge_m)
    obstacle = np.flatnonzero(d <= 10000)
    assert set(obstacle.tolist()) == {70, 71, 0, 1, 2}
    assert np.all(d[obstacle] >= 2450)
    assert np.all(d[[70, 2]] <= 2540)
    # with the rule off (beyond the LiDAR's range) the foot is water
    _, plain, _ = _wall_in_chop(1000.0)
    assert np.all(plain.reason[foot] == REASON_NAMES.index("water"))


def _low_oblique_wall_in_chop(solid_line_min_run: int) -> tuple[np.ndarray, object, object]:
    """A low wall (0.6 m) running from 20 m off on the 20 deg bearing to 30 m off on the 36 deg bearing (clear of the
    sweep's start at the bow, which a run along a beam does not cross). Only the -3 deg beam meets it, 0.55 m up at
    its near end (above the crests' margin), 0.03 m up at its far end (within it)."""
    wall = (((18.79, 6.84), (24.27, 17.63), 0.6),)
    return _level_boat_in_chop(wall, solid_line_min_run=solid_line_min_run)


def test_a_line_along_one_beam_that_rises_out_of_the_sea_margin_is_an_obstacle_along_its_length() -> None:
    d, pre, ret = _low_oblique_wall_in_chop(5)
    d_plain, plain, _ = _low_oblique_wall_in_chop(0)
    on_wall = ret.wall == 0
    assert set(ret.ring[on_wall].tolist()) == {6}  # the -3 deg beam alone
    kept, water = REASON_NAMES.index("kept"), REASON_NAMES.index("water")
    # the far part, within the margin, is water to the tracker either way; with the rule it is the wall's foot in the
    # obstacle array, to within a few firings of its far end (where a crest in front of the wall breaks the run)
    far_part = on_wall & (plain.reason == water)
    assert np.count_nonzero(far_part) >= 20 and plain.feet_world.shape[0] == 0
    assert np.all(pre.reason[on_wall] == plain.reason[on_wall])
    assert pre.feet_world.shape[0] >= np.count_nonzero(far_part) - 5
    assert np.count_nonzero(pre.reason[on_wall] == kept) >= 20
    # the crests, returning every firing, stay water: obstacles only on the wall's bearings, none nearer than it
    obstacle = np.flatnonzero(d <= 10000)
    assert set(obstacle.tolist()) <= {3, 4, 5, 6, 7, 8}
    assert np.all(d[obstacle] >= 1950)
    # bins 6 and 7 (27.5-36 deg): the wall 24-30 m off, within the margin; unknown without the rule
    assert 2300 <= d[6] <= 2800 and 2650 <= d[7] <= 3050
    assert d_plain[6] == d_plain[7] == UNKNOWN


def test_a_low_buoy_beside_the_boat_keeps_its_bins_once_tracked() -> None:
    """A buoy 1.2 m wide 6.5 m off on the 45 deg bearing, in the chop: 0.7 m of it stands over the water, the margin
    (0.45-0.55 m) leaves its top standing and it is tracked; then it rides 0.25 m lower in the swell and all of it
    lies under the margin. Its side is offered to the hull gate like any hull's, within the spray range (8 m) too:
    its bins stay 6.5 m. Before, the returns under the margin there never reached the gate and the bins went out
    unknown, or with what lay behind the buoy (tuning scene 8: a buoy 6.7 m off sent at 68 m). Only returns on a
    face (the laser above or below returned at their range) are offered that near: the crests there are many."""
    pipeline = lidar_pipeline(MOUNT)
    ego = SteadyEgo(rolling, YAW)
    bearing = math.radians(45.0) + YAW
    radial = np.array([math.cos(bearing), math.sin(bearing)])
    along = np.array([-math.sin(bearing), math.cos(bearing)])
    centre = 6.5 * radial
    for k in range(8):
        buoy = (tuple(centre - 0.6 * along), tuple(centre + 0.6 * along), 0.7 if k < 6 else 0.45)
        ret = revolution_over_water(
            MOUNT, rolling, yaw=YAW, origin_height=0.2, elevation=chop, t0=0.1 * k, walls=(buoy,)
        )
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
        if k == 5:
            assert [t.confirmed for t in out.tracks] == [True]
    pre = pipeline.last_preprocess
    assert pre.points_world.shape[0] == 0  # nothing over the margin in the last revolution
    rel = pre.within_margin_world[:, :2] - centre
    on_side = (np.abs(rel @ radial) <= 0.3) & (np.abs(rel @ along) <= 0.6)
    assert np.count_nonzero(on_side) >= 10  # the side under the margin, met by the low beams
    # the buoy spans 39.7-50.3 deg: bins 8-10, 6.5 m off (bins 7 and 11 take it across their edge: bin_edge_m)
    np.testing.assert_allclose(out.distances_cm[7:12] / 100.0, 6.5, atol=0.2)
    assert np.all(out.distances_cm[np.r_[0:7, 12:72]] > 10000)
