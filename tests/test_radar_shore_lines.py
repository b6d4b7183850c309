"""Shore lines (static returns of the last seconds forming a long thin line) and the static map's new rules:
evidence pooled over blocks, only recently hit cells count, lone static returns stay out of the map."""

from __future__ import annotations

import numpy as np

from tests.radar_synthetic import OwnBoat, box_points, observe
from tracker.radar.config import RadarTrackerConfig
from tracker.radar.detector import SHORE_KEEP, SHORE_ON, RadarDetector
from tracker.radar.shore_lines import ShoreLines
from tracker.radar.static_map import StaticMap


def lines(interval_s: float = 0.0) -> ShoreLines:
    return ShoreLines(window_s=1.0, link_m=2.0, min_extent_m=10.0, max_thickness_m=0.5, interval_s=interval_s)


def wall_points(
    north: float, east0: float, east1: float, n: int, scatter: float, rng: np.random.Generator
) -> np.ndarray:
    """n returns evenly along a wall running east at ``north``, scattered by ``scatter`` (m, RMS) across it."""
    east = np.linspace(east0, east1, n) + rng.uniform(-0.2, 0.2, n)
    return np.column_stack([north + rng.normal(0.0, scatter, n), east])


def test_a_wall_is_a_line_a_boat_and_a_clutter_blob_are_not() -> None:
    rng = np.random.default_rng(0)
    sl = lines()
    for k in range(5):  # 0.5 s of returns: 20 a frame along a 30 m wall 25 m north, 0.2 m scatter
        sl.add(0.1 * k, wall_points(25.0, -15.0, 15.0, 20, 0.2, rng))
    wall = wall_points(25.0, -15.0, 15.0, 6, 0.2, rng)
    boat = box_points(np.array([12.0, 5.0]), (4.0, 2.0), 8, rng)
    blob = rng.uniform([2.0, -6.0], [12.0, 6.0], (40, 2))  # dense but 2-D: sea clutter near the radar
    on = sl.mark(0.5, np.concatenate([wall, boat, blob]))
    assert on[:6].all() and not on[6:].any()


def test_a_short_wall_piece_is_not_a_line_and_old_frames_expire() -> None:
    rng = np.random.default_rng(1)
    sl = lines()
    piece = wall_points(20.0, 0.0, 8.0, 30, 0.1, rng)  # 8 m < 10 m
    assert not sl.mark(0.0, piece).any()
    long_wall = wall_points(20.0, -10.0, 10.0, 30, 0.1, rng)
    sl.add(0.0, long_wall)
    assert sl.mark(0.5, long_wall[:3]).all()  # with the remembered frame: on the line
    assert not sl.mark(1.5, long_wall[:3]).any()  # the frame at t = 0 is older than the 1 s window


def test_thickness_allowance_grows_with_range() -> None:
    rng = np.random.default_rng(2)
    wall = wall_points(80.0, -15.0, 15.0, 60, 0.8, rng)  # azimuth smear at 80 m
    assert not lines().mark(0.0, wall).any()
    far = ShoreLines(1.0, 2.5, 10.0, 0.5, thickness_per_m=0.02)  # 0.5 + 0.02 * 80 = 2.1 m allowed
    assert far.mark(0.0, wall, sensor_ne=np.zeros(2)).all()


def test_between_full_searches_returns_near_known_line_returns_are_marked() -> None:
    rng = np.random.default_rng(3)
    sl = lines(interval_s=0.3)
    wall = wall_points(25.0, -15.0, 15.0, 40, 0.1, rng)
    assert sl.mark(0.0, wall).all()
    probe = np.array([[25.5, 3.0], [15.0, 3.0]])  # near the wall / far from it
    np.testing.assert_array_equal(sl.mark(0.1, probe), [True, False])  # cached: no new search at 0.1 s
    np.testing.assert_array_equal(sl.near(probe, 1.0), [True, False])
    sl.reset()
    assert not sl.near(probe, 1.0).any()


def test_a_search_due_with_the_map_extraction_waits_one_frame() -> None:
    # The static map extracts its shore every 0.3 s too; the two searches in one frame made the slowest frames.
    rng = np.random.default_rng(5)
    sl = lines(interval_s=0.3)
    assert not sl.mark(0.0, np.array([[5.0, 0.0]])).any()  # first search: nothing there yet
    wall = wall_points(25.0, -15.0, 15.0, 40, 0.1, rng)
    sl.add(0.2, wall)
    probe = wall[:3]
    assert not sl.mark(0.3, probe, defer=True).any()  # due, deferred: the old (empty) search still answers
    assert sl.mark(0.4, probe, defer=True).all()  # deferred once already this interval: searches now
    every_frame = lines(interval_s=0.0)
    every_frame.add(0.2, wall)
    assert every_frame.mark(0.3, probe, defer=True).all()  # searching every frame: never put off


def test_detector_removes_a_wall_before_the_static_map_has_it() -> None:
    # A wall seen for 0.4 s: too little evidence for the map, already a line (20 returns a frame along 30 m).
    def first_frames(window_s: float) -> list[set[int]]:
        cfg = RadarTrackerConfig().replaced(
            clustering={"min_points": 2, "velocity_min_points": 2, "radius_m": 2.0},
            shore={"update_interval_s": 0.0, "line_window_s": window_s},
        )
        rng = np.random.default_rng(4)
        det = RadarDetector(cfg)
        own = OwnBoat(position=np.zeros(2))
        verdicts = []
        for k in range(4):
            xyz, dop = observe(own, wall_points(22.0, -15.0, 15.0, 20, 0.15, rng), np.zeros(2), rng, 0.05)
            out = det.detect(xyz, dop, None, 0.1 * k, own.position, 0.0, np.zeros(2))
            verdicts.append({cl.shore for cl in out.clusters})
        assert len(det.static_map.shore_cells()) == 0  # the map has no shore yet
        return verdicts

    assert first_frames(2.0) == [{SHORE_ON}] * 4
    assert all(SHORE_KEEP in v for v in first_frames(0.0))  # without the lines the wall pieces are tracked


def test_map_pools_evidence_and_counts_only_recent_cells() -> None:
    cfg = RadarTrackerConfig().replaced(shore={"occupied_hits": 3.0, "evidence_pool_m": 0.75, "recent_s": 2.0})
    m = StaticMap(cfg)
    m.advance_time(0.0)
    m.follow(np.zeros(2))
    # Three hits in three different 0.25 m cells of one 0.75 m block: occupied only when pooled.
    wall = np.column_stack([np.full(60, 30.1), np.linspace(-8.0, 8.0, 60)])  # a 16 m line of single hits
    for k, dx in enumerate((0.0, 0.3, 0.55)):
        m.add_points(wall + np.array([dx, 0.0]), 0.1 * k)
    m.update_shore(0.3, np.zeros(2), 100.0)
    assert len(m.shore_cells()) > 0
    per_cell = cfg.replaced(shore={"evidence_pool_m": 0.0})
    m2 = StaticMap(per_cell)
    m2.advance_time(0.0)
    m2.follow(np.zeros(2))
    for k, dx in enumerate((0.0, 0.3, 0.55)):
        m2.add_points(wall + np.array([dx, 0.0]), 0.1 * k)
    m2.update_shore(0.3, np.zeros(2), 100.0)
    assert len(m2.shore_cells()) == 0
    # Not hit for longer than shore.recent_s: no longer shore, though its evidence has hardly decayed.
    m.update_shore(2.5, np.zeros(2), 100.0)
    assert len(m.shore_cells()) == 0
    assert m.evidence_at(np.array([[30.1, 0.0]]), 2.5)[0] > 0.9


def test_lone_static_returns_stay_out_of_the_map() -> None:
    cfg = RadarTrackerConfig().replaced(
        clustering={"min_points": 3, "velocity_min_points": 3}, shore={"map_min_neighbours": 1}
    )
    det = RadarDetector(cfg)
    own = OwnBoat(position=np.zeros(2))
    pts = np.array([[10.0, 0.0], [10.5, 0.3], [20.0, -8.0]])  # a pair and a loner (sea clutter)
    xyz, dop = observe(own, pts, np.zeros(2))
    out = det.detect(xyz, dop, None, 0.0, own.position, 0.0, np.zeros(2))
    np.testing.assert_array_equal(out.static, [True, True, False])
    np.testing.assert_array_equal(out.line_static, [True, True, True])
    off = RadarDetector(cfg.replaced(shore={"map_min_neighbours": 0}))
    assert off.detect(xyz, dop, None, 0.0, own.position, 0.0, np.zeros(2)).static.all()


def _rough_sea_window(sl: ShoreLines, rng: np.random.Generator, with_wall: bool) -> tuple[np.ndarray, np.ndarray]:
    """2 s of frames (10 Hz): 150 clutter returns a frame over 70 x 70 m round the radar (a rough sea's, enough to
    link everything within 2 m into one blob), and with ``with_wall`` a 20 m wall 35 m north whose scatterers, every
    0.5 m, each return in a third of the frames (0.3 m scatter). Adds 19 frames; returns the 20th's wall and
    clutter."""
    places = np.column_stack([np.full(41, 35.0), np.linspace(-10.0, 10.0, 41)])

    def frame() -> tuple[np.ndarray, np.ndarray]:
        wall = places[rng.random(len(places)) < 1 / 3] if with_wall else np.empty((0, 2))
        return wall + rng.normal(0.0, 0.3, wall.shape), rng.uniform(-35.0, 35.0, (150, 2))

    for k in range(19):
        sl.add(0.1 * k, np.concatenate(frame()))
    return frame()


def test_in_a_rough_sea_a_wall_linked_into_the_clutter_is_found_from_its_recurring_returns() -> None:
    rng = np.random.default_rng(4)

    def shore_lines(min_frames: int) -> ShoreLines:
        return ShoreLines(2.0, 2.0, 10.0, 1.0, sensor_ne=np.zeros(2), min_frames=min_frames, recheck_min_range_m=15.0)

    plain, recheck = shore_lines(1), shore_lines(2)
    for sl in (plain, recheck):
        wall, clutter = _rough_sea_window(sl, np.random.default_rng(5), with_wall=True)
        on = sl.mark(1.9, np.concatenate([wall, clutter]))
        if sl is plain:  # the window's 3,000 clutter returns swallow the wall: one blob, no line
            assert not on.any()
        else:
            assert on[: len(wall)].all()
            # clutter returns count only where they fall within the 2 m link of the wall
            near_wall = (np.abs(clutter[:, 0] - 35.0) < 2.5) & (np.abs(clutter[:, 1]) < 12.5)
            assert not on[len(wall) :][~near_wall].any()
    sea_only = shore_lines(2)
    wall, clutter = _rough_sea_window(sea_only, rng, with_wall=False)
    assert not sea_only.mark(1.9, clutter).any()  # clutter alone recurs too seldom to draw a line
