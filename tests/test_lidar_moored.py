"""Hulls moored against a wall are carved out of the wall's cluster (tracker.lidar.moored) and tracked as vessels."""

from __future__ import annotations

import numpy as np
import pytest

from tests.lidar_synthetic import SyntheticObject, scan_objects
from tracker.lidar import LidarTracker, LidarTrackerConfig
from tracker.lidar.moored import hull_cells

ORIGIN = np.zeros(2)
DT = 0.1
# A quay face running north-south 30 m east of the sensor, 120 m of it, 5 m deep; a 10 x 3.5 m boat on 0.3 m fenders.
WALL = SyntheticObject((0.0, 32.5), 0.0, 120.0, 5.0, 1.5)
BOAT = SyntheticObject((8.0, 30.0 - 0.3 - 1.75), 0.0, 10.0, 3.5, 2.0)


def run(objects: list[SyntheticObject], offset_m: float, scans: int = 20) -> list:
    cfg = LidarTrackerConfig()
    cfg.structure.moored_min_offset_m = offset_m
    tracker = LidarTracker(cfg)
    rng = np.random.default_rng(1)
    tracks = []
    for k in range(scans):
        tracks = tracker.step(scan_objects(objects, ORIGIN, range_noise=0.03, rng=rng), k * DT, ORIGIN, 0.0)
    return [t for t in tracks if t.confirmed]


def test_a_boat_moored_against_a_quay_is_a_track_and_the_quay_is_not() -> None:
    tracks = run([WALL, BOAT], 0.8)
    assert len(tracks) == 1
    # its side towards the sensor is seen, its beam only in part: the centre within 1 m, the length within 0.5 m
    assert tracks[0].position == pytest.approx(BOAT.center, abs=1.0)
    assert tracks[0].length == pytest.approx(BOAT.length, abs=0.5)


def test_without_the_carving_the_moored_boat_is_part_of_the_quay() -> None:
    assert run([WALL, BOAT], 0.0) == []


def test_a_quay_alone_gives_no_track() -> None:
    assert run([WALL], 0.8) == []


def wall_cells(length: float = 60.0, east: float = 30.0, step: float = 0.3) -> np.ndarray:
    north = np.arange(-0.5 * length, 0.5 * length, step)
    return np.column_stack([north, np.full_like(north, east)])


def test_cells_in_front_of_the_face_are_one_hull_and_land_behind_it_is_none() -> None:
    wall = wall_cells()
    hull = np.column_stack([np.arange(5.0, 14.0, 0.3), np.full(30, 26.5)])  # 9 m long, 3.5 m in front
    land = np.column_stack([np.arange(-20.0, 0.0, 0.5), np.full(40, 35.0)])  # behind the face, away from the sensor
    fp = np.concatenate([wall, hull, land])
    groups = hull_cells(fp, ORIGIN, 0.8, 1.5, 1.5, 0.5)
    assert len(groups) == 1
    cells, face = groups[0]
    assert sorted(cells.tolist()) == list(range(len(wall), len(wall) + len(hull)))
    assert abs(face.axis[0]) == pytest.approx(1.0, abs=1e-3)  # the face runs north-south
    assert face.normal[1] == pytest.approx(-1.0, abs=1e-3)  # towards the sensor, west


def test_a_perpendicular_arm_or_a_shapeless_cluster_is_no_hull() -> None:
    wall = wall_cells()
    arm = np.column_stack([np.full(40, -10.0), np.arange(18.0, 30.0, 0.3)])  # a pier towards the sensor: thin along
    assert hull_cells(np.concatenate([wall, arm]), ORIGIN, 0.8, 1.5, 1.5, 0.5) == []
    blob = np.random.default_rng(2).uniform(-10.0, 10.0, (400, 2)) + np.array([0.0, 40.0])  # rough shore: no face
    assert hull_cells(blob, ORIGIN, 0.8, 1.5, 1.5, 0.5) == []


def run_with(objects: list[SyntheticObject], confirmed_only: bool = True, **structure: float) -> list:
    cfg = LidarTrackerConfig()
    for k, v in structure.items():
        setattr(cfg.structure, k, v)
    tracker = LidarTracker(cfg)
    rng = np.random.default_rng(1)
    tracks = []
    for k in range(20):
        tracks = tracker.step(scan_objects(objects, ORIGIN, range_noise=0.03, rng=rng), k * DT, ORIGIN, 0.0)
    return [t for t in tracks if t.confirmed or not confirmed_only]


def test_a_boat_against_a_stretch_of_quay_shorter_than_a_ship_is_carved_too() -> None:
    """30 m of quay with the boat: one cluster a vessel could be. Searched from moored_min_extent_m (15 m) up."""
    quay = SyntheticObject((0.0, 32.5), 0.0, 30.0, 5.0, 1.5)
    near_boat = [t for t in run_with([quay, BOAT]) if np.hypot(*(t.position - BOAT.center)) <= 1.0]
    assert len(near_boat) == 1 and near_boat[0].length == pytest.approx(BOAT.length, abs=0.5)
    whole = run_with([quay, BOAT], moored_min_extent_m=1000.0)  # only clusters too big for a vessel searched
    assert [t for t in whole if np.hypot(*(t.position - BOAT.center)) <= 1.0] == []


def test_a_ship_alone_is_never_carved() -> None:
    """A convex hull has no cells in front of its own face: a 45 m ship seen from its quarter stays one track (a
    tentative one: lying still, it is structure-sized and has not shown a speed)."""
    ship = SyntheticObject((25.0, 30.0), np.radians(20.0), 45.0, 9.0, 6.0)
    tracks = run_with([ship], confirmed_only=False)
    assert len(tracks) == 1
    assert tracks[0].position == pytest.approx(ship.center, abs=2.0)


def test_a_carved_hull_where_the_memory_has_wall_is_still_a_vessel() -> None:
    """The wall and the boat seen merged once (carving off, as when a bend hid the face's line): their cells are
    remembered as structure. Carved afterwards, the boat stands in front of the face: a vessel, not remembered wall."""
    cfg = LidarTrackerConfig()
    tracker = LidarTracker(cfg)
    rng = np.random.default_rng(1)
    cfg.structure.moored_min_offset_m = 0.0
    tracker.step(scan_objects([WALL, BOAT], ORIGIN, range_noise=0.03, rng=rng), 0.0, ORIGIN, 0.0)
    assert tracker.structure.known(0.0, np.array([BOAT.center + np.array([0.0, -1.75])])).all()  # its near side
    cfg.structure.moored_min_offset_m = 0.8
    tracks = []
    for k in range(1, 20):
        tracks = tracker.step(scan_objects([WALL, BOAT], ORIGIN, range_noise=0.03, rng=rng), k * DT, ORIGIN, 0.0)
    confirmed = [t for t in tracks if t.confirmed]
    assert len(confirmed) == 1 and confirmed[0].position == pytest.approx(BOAT.center, abs=1.0)


def boat_track_after_a_merged_scan(carved_first: bool) -> list:
    """The boat tracked (carved off the wall) for a second or not, then one scan where it and the wall merge (the
    carving off, as when a bend hid the face's line), then 4 s of the boat alone as its own small cluster (the
    wall's near stretch not returned). Returns the confirmed tracks updated in the last scan."""
    cfg = LidarTrackerConfig()
    tracker = LidarTracker(cfg)
    rng = np.random.default_rng(1)
    k = 0
    if carved_first:
        for k in range(10):
            tracker.step(scan_objects([WALL, BOAT], ORIGIN, range_noise=0.03, rng=rng), k * DT, ORIGIN, 0.0)
    cfg.structure.moored_min_offset_m = 0.0
    k += 1
    tracker.step(scan_objects([WALL, BOAT], ORIGIN, range_noise=0.03, rng=rng), k * DT, ORIGIN, 0.0)
    assert tracker.last_structure.all()  # the merged scan: all of it wall, remembered
    cfg.structure.moored_min_offset_m = 0.8
    tracks = []
    for j in range(k + 1, k + 41):
        tracks = tracker.step(scan_objects([BOAT], ORIGIN, range_noise=0.03, rng=rng), j * DT, ORIGIN, 0.0)
    return [t for t in tracks if t.confirmed and t.time_since_update == 0.0]


def test_a_hull_once_carved_off_its_wall_stays_a_vessel_after_a_scan_where_they_merged() -> None:
    """Where a hull was carved off a wall, the structure memory holds no wall for memory_s (StructureMemory.
    remember_hull), so a scan where boat and wall merge cannot turn the boat into remembered quay."""
    tracks = boat_track_after_a_merged_scan(carved_first=True)
    assert len(tracks) == 1 and tracks[0].position == pytest.approx(BOAT.center, abs=1.0)


def test_a_boat_only_ever_seen_merged_with_its_wall_stays_structure() -> None:
    """The other side of the rule: never carved, the boat's cells are remembered wall, and the boat alone on them
    is structure (an obstacle, no track): the hull memory, not the boat's own look, made the difference above."""
    assert boat_track_after_a_merged_scan(carved_first=False) == []


def bent_quay(bend_deg: float, boat_from_kink_m: float) -> tuple[list[SyntheticObject], SyntheticObject]:
    """The quay face running north at 30 m east up to a kink at 20 m north, then bent ``bend_deg`` towards the land
    (east) for 40 m; a 10 x 3.5 m boat on 0.3 m fenders along the bent end, its centre ``boat_from_kink_m`` along."""
    h = np.radians(bend_deg)
    u, land = np.array([np.cos(h), np.sin(h)]), np.array([-np.sin(h), np.cos(h)])
    kink = np.array([20.0, 30.0])
    main = SyntheticObject((-20.0, 32.5), 0.0, 80.0, 5.0, 1.5)
    bent = SyntheticObject(tuple(kink + 20.0 * u + 2.5 * land), h, 40.0, 5.0, 1.5)
    boat = SyntheticObject(tuple(kink + boat_from_kink_m * u - (0.3 + 1.75) * land), h, 10.0, 3.5, 2.0)
    return [main, bent], boat


def test_a_boat_moored_on_a_bent_end_of_the_quay_is_a_track() -> None:
    """A boat on a quay's end bent 20 deg towards the land stands behind the main face's line (up to 4.5 m here):
    only the face bent off the main one's end shows it in front of its wall (tuning seed 78's missed boat)."""
    walls, boat = bent_quay(20.0, 20.0)
    tracks = run_with([*walls, boat])
    assert len(tracks) == 1
    assert tracks[0].position == pytest.approx(boat.center, abs=1.0)
    assert tracks[0].length == pytest.approx(boat.length, abs=1.0)


def test_a_bent_quay_alone_and_land_behind_a_broken_face_give_no_hull() -> None:
    walls, _ = bent_quay(20.0, 20.0)
    assert run_with(walls, confirmed_only=False) == []
    # A straight face broken by the shadow of a boat in front of it, the quay's top seen behind it: the boat is
    # the one hull; no face bent off the broken run's ends makes one of the land.
    wall = wall_cells()
    broken = wall[(wall[:, 0] < 4.0) | (wall[:, 0] > 15.0)]
    hull = np.column_stack([np.arange(5.0, 14.0, 0.3), np.full(30, 26.5)])
    top = np.array([(n, e) for n in np.arange(-30.0, 30.0, 1.5) for e in (32.0, 34.0)])
    groups = hull_cells(np.concatenate([broken, hull, top]), ORIGIN, 0.8, 1.5, 1.5, 0.5)
    assert [sorted(cells.tolist()) for cells, _ in groups] == [list(range(len(broken), len(broken) + len(hull)))]


def test_boats_end_to_end_hiding_most_of_the_wall_are_carved() -> None:
    """Boats moored end to end along a low quay, 27 m of hulls in front of 20 m of face left in view: fewer than
    half the cells are face, but most of those in front of it (the hulls' near sides) lie in one strip parallel to
    it, so they are left out of the share (tuning seed 27, 80 m off: both boats untracked for 40 s while their
    cluster was structure)."""
    wall = wall_cells(20.0)  # north -10..10 at east 30: 67 cells
    sides = np.column_stack([np.arange(12.0, 39.0, 0.45), np.full(60, 25.5)])  # 4.5 m in front
    cabins = np.column_stack([np.arange(14.0, 21.0, 0.5), np.full(14, 27.0)])  # returns off a cabin, 3 m in front
    fp = np.concatenate([wall, sides, cabins])
    assert len(wall) < 0.5 * len(fp)
    groups = hull_cells(fp, ORIGIN, 0.8, 1.5, 1.5, 0.5)
    assert [sorted(g.tolist()) for g, _ in groups] == [list(range(len(wall), len(fp)))]


def test_a_quays_top_seen_from_beyond_its_end_is_no_hull() -> None:
    """From beyond a quay's end, across the line of its face, the top of the quay lies "in front" of the face, spread
    over its depth rather than in one strip: it still counts against the face's share, and nothing is carved
    (tuning seed 38: pieces of a quay's top carved as hulls tracked as vessels at its end)."""
    wall = wall_cells(20.0)
    north, east = np.meshgrid(np.arange(-10.0, 10.0, 0.5), np.arange(25.5, 29.4, 0.5))
    top = np.column_stack([north.ravel(), east.ravel()])  # 4 m of top, on the sensor's side of the face's line
    fp = np.concatenate([wall, top])
    assert hull_cells(fp, ORIGIN, 0.8, 1.5, 1.5, 0.5) == []
