"""Structure memory: a piece of a quay wall cut off by a shadow stays structure; boats near it stay vessels."""

from __future__ import annotations

import numpy as np
import pytest

from tracker.lidar import LidarTracker, LidarTrackerConfig
from tracker.lidar.config import StructureConfig
from tracker.lidar.structure import StructureMemory

OWN = np.zeros(2)


def wall(north_from: float, north_to: float, east: float = 16.0) -> np.ndarray:
    """A vertical quay face (world NED): a return every 0.2 m along it at four heights."""
    north = np.arange(north_from, north_to, 0.2)
    return np.concatenate(
        [np.column_stack([north, np.full(north.size, east), np.full(north.size, z)]) for z in (-0.3, -0.8, -1.3, -1.8)]
    )


def boat(north: float, east: float, length: float = 8.0) -> np.ndarray:
    """The face of a hull broadside to the sensor, 0.5 m off the wall's side of it (world NED)."""
    n = np.arange(north - length / 2, north + length / 2, 0.1)
    return np.concatenate([np.column_stack([n, np.full(n.size, east), np.full(n.size, z)]) for z in (-0.4, -0.9)])


def detections_near(tracker: LidarTracker, points: np.ndarray, t: float, north: float, east: float) -> int:
    dets = tracker.detect(points, t, OWN)
    return sum(1 for d in dets if abs(d.center[0] - north) < 12.0 and abs(d.center[1] - east) < 3.0)


@pytest.mark.parametrize("memory_s, piece_is_vessel", [(120.0, False), (0.0, True)])
def test_wall_piece_after_seeing_the_whole_wall(memory_s: float, piece_is_vessel: bool) -> None:
    tracker = LidarTracker(LidarTrackerConfig(structure=StructureConfig(memory_s=memory_s)))
    # Scan 1: the whole 80 m wall (longer than max_extent 60 m: structure) and a boat 3 m off it.
    first = np.concatenate([wall(-40.0, 40.0), boat(10.0, 12.0)])
    dets = tracker.detect(first, 0.0, OWN)
    assert len(dets) == 1 and abs(dets[0].center[1] - 12.0) < 0.5  # the boat only
    assert tracker.last_structure.tolist() == [False, True]  # boat nearest, then the wall
    # Scan 2, 5 s later: a shadow leaves an 18 m piece of the wall, vessel-sized; the boat is still there.
    second = np.concatenate([wall(2.0, 20.0), boat(10.0, 12.0)])
    assert detections_near(tracker, second, 5.0, 11.0, 16.0) == (1 if piece_is_vessel else 0)
    assert detections_near(tracker, second, 5.0, 10.0, 12.0) == 1  # the boat 3 m off the wall is a vessel
    structure = tracker.last_structure
    assert structure.sum() == (0 if piece_is_vessel else 1)


def known_fraction(mem: StructureMemory, t: float, points_ne: np.ndarray) -> float:
    """Share of the points the memory knows as structure at ``t``."""
    return float(np.mean(mem.known(t, points_ne))) if len(points_ne) else 0.0


def test_memory_expires_and_follows_the_boat() -> None:
    mem = StructureMemory(StructureConfig(memory_s=60.0, cell_m=0.5, half_size_m=100.0, range_m=40.0))
    mem.follow(np.array([0.0, 0.0]))
    face = np.column_stack([np.arange(10.0, 30.0, 0.2), np.full(100, 16.0)])
    mem.remember(0.0, face)
    assert known_fraction(mem, 10.0, face) == 1.0
    assert known_fraction(mem, 10.0, face + np.array([0.0, 0.6])) == 1.0  # within a cell of it
    assert known_fraction(mem, 10.0, face + np.array([0.0, 3.0])) == 0.0  # a boat 3 m off it
    assert known_fraction(mem, 61.0, face) == 0.0  # not seen as structure for over memory_s
    # Off the grid nothing is known, even beside a remembered cell on its edge.
    edge = np.column_stack([np.full(10, 99.8), np.arange(0.0, 5.0, 0.5)])  # the grid's north edge is at 100 m
    mem.remember(0.0, edge)
    assert known_fraction(mem, 10.0, edge) == 1.0
    assert known_fraction(mem, 10.0, edge + np.array([1.0, 0.0])) == 0.0  # 0.2-0.7 m past the edge
    assert known_fraction(mem, 10.0, np.array([[5000.0, 16.0]])) == 0.0
    # The boat moves 55 m north: still within half_size - range_m of the centre, the grid stays.
    mem.follow(np.array([55.0, 0.0]))
    assert mem.origin is not None and mem.origin.tolist() == [-100.0, -100.0]
    # The boat moves 70 m north: the grid recentres and keeps what lies within it.
    mem.follow(np.array([70.0, 0.0]))
    assert mem.origin is not None and mem.origin.tolist() == [-30.0, -100.0]  # was (-100, -100)
    assert known_fraction(mem, 10.0, face) == 1.0
    mem.follow(np.array([400.0, 0.0]))  # far away: nothing of it is left
    assert known_fraction(mem, 10.0, face) == 0.0


def cabin_boat(north: float, east: float, length: float = 10.0) -> np.ndarray:
    """A hull 1.4 m high with a cabin to 3.4 m over its middle 40 %, broadside to the sensor (world NED)."""
    n = np.arange(north - length / 2, north + length / 2, 0.1)
    cabin = n[np.abs(n - north) <= 0.2 * length]
    hull = [np.column_stack([n, np.full(n.size, east), np.full(n.size, z)]) for z in (-0.4, -0.9, -1.4)]
    top = [np.column_stack([cabin, np.full(cabin.size, east + 0.2), np.full(cabin.size, z)]) for z in (-2.2, -3.4)]
    return np.concatenate(hull + top)


@pytest.mark.parametrize("taller_margin_m, boat_is_vessel", [(0.3, True), (-1.0, False)])
def test_a_boat_taller_than_its_quay_stays_a_vessel(taller_margin_m: float, boat_is_vessel: bool) -> None:
    tracker = LidarTracker(LidarTrackerConfig(structure=StructureConfig(taller_margin_m=taller_margin_m)))
    # Scan 1: the boat lies 0.5 m off an 80 m wall 1.8 m high (too close to be carved off it): one cluster, too big
    # for a vessel, so structure, boat cells and all.
    assert tracker.detect(np.concatenate([wall(-40.0, 40.0), cabin_boat(10.0, 15.5)]), 0.0, OWN) == []
    # The wall's lid there: its top 1.8 m, raised to where the next beam up passed at ~16-30 m; not the cabin's.
    lid = tracker.structure.lids_at(5.0, np.array([[10.0, 16.0]]))[0]
    assert -3.0 < lid < -2.3
    # Scan 2: the boat alone where the wall's cells are remembered. Its cabin stands 1 m above the lid.
    assert detections_near(tracker, cabin_boat(10.0, 15.5), 5.0, 10.0, 15.5) == (1 if boat_is_vessel else 0)
    # A piece of the same wall alone, no higher than the wall, stays structure either way.
    assert detections_near(tracker, wall(-30.0, -12.0), 6.0, -21.0, 16.0) == 0


def quay_top(north_from: float, north_to: float, east_from: float = 16.0, depth: float = 8.0) -> np.ndarray:
    """The quay's top behind its face, 1.8 m up, a return every 0.5 m (world NED)."""
    n, e = np.meshgrid(np.arange(north_from, north_to, 0.5), np.arange(east_from, east_from + depth, 0.5))
    return np.column_stack([n.ravel(), e.ravel(), np.full(n.size, -1.8)])


@pytest.mark.parametrize(
    "short_length_m, short_share, flank_m, piece_is_wall, face_is_wall",
    [
        (1.5, 0.5, 1.5, True, False),
        (4.0, 0.5, 1.5, False, False),
        (1.5, 0.25, 1.5, True, False),  # the flank test alone keeps the face a vessel
        (1.5, 0.5, 0.0, True, False),  # and so does the short pieces' share alone
        (1.5, 0.25, 0.0, True, True),
    ],
)
def test_a_short_piece_on_a_walls_line_is_wall_and_a_face_across_it_is_not(
    short_length_m: float, short_share: float, flank_m: float, piece_is_wall: bool, face_is_wall: bool
) -> None:
    cfg = StructureConfig(
        short_line_min_length_m=short_length_m, short_line_min_share=short_share, line_flank_m=flank_m
    )
    tracker = LidarTracker(LidarTrackerConfig(structure=cfg))
    assert tracker.detect(np.concatenate([wall(-40.0, 40.0), quay_top(-40.0, 40.0)]), 0.0, OWN) == []
    # 5 s later: a 2 m piece of the same wall 5 m past the remembered end (a far quay seen by one beam), and a
    # boat's 2 m end face 4 m off the wall, pointing at it: its line crosses the wall and the quay's top behind it
    # (8 m of its 30 m reach) instead of running along them.
    face = np.concatenate(
        [np.column_stack([np.full(20, 30.0), np.arange(10.0, 12.0, 0.1), np.full(20, z)]) for z in (-0.4, -0.9)]
    )
    dets = tracker.detect(np.concatenate([wall(45.0, 47.0), face]), 5.0, OWN)
    assert sum(1 for d in dets if abs(d.center[1] - 16.0) < 1.0) == (0 if piece_is_wall else 1)
    assert sum(1 for d in dets if abs(d.center[0] - 30.0) < 1.0 and abs(d.center[1] - 11.0) < 1.5) == (
        0 if face_is_wall else 1
    )


def line_of_returns(start: np.ndarray, direction: np.ndarray, length: float) -> np.ndarray:
    """One laser's returns every 0.1 m along a straight line 0.5 m above the water (world NED): a quay's face met
    by one beam, or a hull's side seen so."""
    s = np.arange(0.0, length, 0.1)
    xy = start[None, :] + s[:, None] * direction[None, :]
    return np.column_stack([xy, np.full(s.size, -0.5)])


@pytest.mark.parametrize(
    "speed_mps, beams, thin_max_width_m, reported",
    [(0.0, 1, 0.3, False), (0.0, 1, 0.0, True), (2.0, 2, 0.3, True), (2.0, 1, 0.3, False)],
)
def test_a_line_with_its_ends_in_view_is_no_vessel_until_it_moves(
    speed_mps: float, beams: int, thin_max_width_m: float, reported: bool
) -> None:
    """A 6 m line of returns seen obliquely from 25 m (its near end in view, so a hull of any beam would have shown
    an end face) keeps a track a few centimetres wide: a piece of quay, reported tentative; the rule off, or the
    line moving at 2 m/s (a hull's side) met by two beams 1.2 m apart in height, it is a vessel. Met by one beam
    (under flat_max_height_m), a moving line 5 m or longer stays tentative (flat_thin_min_length_m)."""
    tracker = LidarTracker(LidarTrackerConfig(structure=StructureConfig(thin_max_width_m=thin_max_width_m)))
    direction = np.array([6.0, 2.0]) / np.hypot(6.0, 2.0)
    start = np.array([20.0, 10.0])
    for k in range(40):  # 4 s at 10 Hz
        t = 0.1 * k
        line = line_of_returns(start + speed_mps * t * direction, direction, 6.0)
        lines = [line + np.array([0.0, 0.0, -1.2 * b]) for b in range(beams)]
        tracks = tracker.step(np.concatenate(lines), t, OWN)
    assert len(tracks) == 1
    track = tracks[0]
    assert track.width < 0.05  # no beam prior: the near end was in view
    assert abs(track.length - 6.0) < 0.3
    assert track.confirmed == reported


@pytest.mark.parametrize("thin_seen_min_scans, reported", [(10, False), (0, True)])
def test_a_line_first_seen_short_is_thin_once_its_detections_say_so(thin_seen_min_scans: int, reported: bool) -> None:
    """A still line of returns 50 m off, at 45 deg to the line of sight, first seen 1.3 m long and growing to 6 m
    (a piece of quay coming out of a moored boat's shadow): its track keeps the beam prior of that first view (a
    third of its 1.1 m fitted extent, 0.37 m, wider than thin_max_width_m), since an end face so narrow would not
    show from 50 m. A hull with a beam of a third of 6 m would have shown one, and the detections stay a few
    centimetres wide: after thin_seen_min_scans such scans the track is thin, a piece of quay, reported tentative;
    with the rule off it is a vessel."""
    tracker = LidarTracker(LidarTrackerConfig(structure=StructureConfig(thin_seen_min_scans=thin_seen_min_scans)))
    direction = np.array([-1.0, 1.0]) / np.sqrt(2.0)
    for k in range(50):  # 5 s at 10 Hz
        tracks = tracker.step(line_of_returns(np.array([50.0, 0.0]), direction, min(1.3 + 0.1 * k, 6.0)), 0.1 * k, OWN)
    assert len(tracks) == 1
    track = tracks[0]
    assert abs(track.width - 0.37) < 0.02  # the first view's prior, never measured
    assert abs(track.length - 6.0) < 0.5
    assert track.confirmed == reported


@pytest.mark.parametrize(
    "easts, run_min_pieces, vessels",
    [
        ((16.0, 16.0, 16.0), 3, 0),  # one wall in three pieces, 67 m end to end
        ((16.0, 16.0, 16.0), 0, 3),  # the rule off
        ((12.0, 13.5, 10.8), 3, 3),  # boats' sides along a wall, offset by their beams: no line
    ],
)
def test_pieces_on_one_line_longer_than_a_vessel_are_a_wall_before_any_is_remembered(
    easts: tuple[float, float, float], run_min_pieces: int, vessels: int
) -> None:
    """The first scan of a scene: a quay's face comes back in three pieces of 12-15 m (each vessel-sized) between
    the shadows of what lies in front of it, nothing remembered yet. On one line and 67 m end to end together, longer
    than any vessel, they are a wall; three faces at different offsets are not."""
    tracker = LidarTracker(LidarTrackerConfig(structure=StructureConfig(run_min_pieces=run_min_pieces)))
    spans = ((-35.0, -20.0), (-5.0, 10.0), (20.0, 32.0))
    pieces = np.concatenate([wall(a, b, east) for (a, b), east in zip(spans, easts, strict=True)])
    assert len(tracker.detect(pieces, 0.0, OWN)) == vessels
    assert int(tracker.last_structure.sum()) == 3 - vessels


def test_two_pieces_on_one_line_are_no_wall_yet() -> None:
    """Two pieces always lie on one line: they say nothing of a wall (run_min_pieces 3)."""
    tracker = LidarTracker(LidarTrackerConfig())
    assert len(tracker.detect(np.concatenate([wall(-35.0, -20.0), wall(20.0, 32.0)]), 0.0, OWN)) == 2


@pytest.mark.parametrize("deck_depth_m, deck_is_vessel", [(10.0, False), (0.0, True)])
def test_a_quays_deck_behind_its_remembered_face_is_structure(deck_depth_m: float, deck_is_vessel: bool) -> None:
    """The boat pitches down and its beams pass over the quay's edge to meet the deck 1-7 m behind the face: a
    7 x 6 m patch of returns at the wall's top, never under the remembered face's cells. Seen over the face it
    remembers, no higher than that face's lid, it is structure. A boat 4 m in front of the face, and a cabin 3 m
    behind it standing 1.6 m above the quay (a boat in the basin beyond a pier), stay vessels."""
    tracker = LidarTracker(LidarTrackerConfig(structure=StructureConfig(deck_depth_m=deck_depth_m)))
    assert tracker.detect(wall(-40.0, 40.0), 0.0, OWN) == []  # 80 m of face, 1.8 m high: remembered
    deck = quay_top(5.0, 12.0, east_from=17.0, depth=6.0)
    in_front = boat(-10.0, 12.0)
    cabin = np.concatenate(
        [np.column_stack([np.arange(-25.0, -22.0, 0.1), np.full(30, 19.0), np.full(30, z)]) for z in (-3.4, -3.9)]
    )
    dets = tracker.detect(np.concatenate([deck, in_front, cabin]), 5.0, OWN)
    assert sum(1 for d in dets if abs(d.center[0] - 8.5) < 2.0 and abs(d.center[1] - 20.0) < 2.0) == int(deck_is_vessel)
    assert sum(1 for d in dets if abs(d.center[0] + 10.0) < 1.0 and abs(d.center[1] - 12.0) < 1.0) == 1
    assert sum(1 for d in dets if abs(d.center[0] + 23.5) < 1.0 and abs(d.center[1] - 19.0) < 1.0) == 1
    assert len(dets) == 2 + int(deck_is_vessel)


def test_lid_in_front_looks_back_along_the_line_of_sight_only_as_deep_as_asked() -> None:
    """From the own boat at the origin, a face remembered along east 16 m with its lid 2.5 m up: a point 3 m behind
    it meets it; one 12 m behind does not within 10 m; one in front of it, or beside the face's end, never."""
    mem = StructureMemory(StructureConfig(memory_s=60.0))
    mem.follow(OWN)
    face = np.column_stack([np.arange(-20.0, 20.0, 0.2), np.full(200, 16.0)])
    mem.remember(0.0, face, np.full(len(face), -2.5))
    points = np.array([[5.0, 19.0], [5.0, 28.0], [5.0, 13.0], [30.0, 22.0]])
    lid = mem.lid_in_front(1.0, points, OWN, 10.0)
    assert lid[0] == -2.5
    assert np.isinf(lid[1:]).all()
    assert mem.lid_in_front(1.0, points[1:2], OWN, 15.0)[0] == -2.5
    assert np.isinf(mem.lid_in_front(61.0, points, OWN, 10.0)).all()  # forgotten after memory_s


@pytest.mark.parametrize("flank_m, piece_is_vessel", [(1.5, True), (0.0, False)])
def test_a_boats_side_pointing_across_a_quay_is_no_piece_of_it(flank_m: float, piece_is_vessel: bool) -> None:
    """A boat's 4.3 m side 20 m west of a remembered quay, its axis 60 deg off the quay's line: followed on, that
    line crosses the face and 9 m of the quay's top (over line_min_share of its 30 m reach), but so do the lines
    1.5 m either side of it (line_flank_m), so it runs across the quay, not along it: a vessel. Without the flank
    test the wall-line rule made such a crossing boat structure, and the memory then followed its own path (tuning
    seed 60's boat 07: 225 ticks missed)."""
    tracker = LidarTracker(LidarTrackerConfig(structure=StructureConfig(line_flank_m=flank_m)))
    assert tracker.detect(np.concatenate([wall(-40.0, 40.0), quay_top(-40.0, 40.0)]), 0.0, OWN) == []
    axis = np.array([0.5, np.sqrt(3.0) / 2.0])  # (north, east)
    along = np.arange(-2.15, 2.15, 0.1)
    side = np.array([-20.0, 3.0]) + along[:, None] * axis
    points = np.concatenate([np.column_stack([side, np.full(along.size, z)]) for z in (-0.4, -0.9)])
    assert detections_near(tracker, points, 5.0, -20.0, 3.0) == (1 if piece_is_vessel else 0)
    # A piece further along the quay's own line, water on one flank, stays wall with the flank test.
    assert detections_near(tracker, wall(45.0, 47.0), 6.0, 46.0, 16.0) == 0


def test_a_boats_side_whose_line_runs_into_a_quay_at_a_slant_is_no_piece_of_it() -> None:
    """A moored boat's near side 4 m in front of a remembered quay face and 15 m past the end of what is remembered
    of it, its measured axis 11 deg off the face's (a line through a few metres of returns is good to a few
    degrees): followed on, the line meets the face about 20 m away, and on one flank it runs past the face's end, so
    the flank test lets it through. The face met runs at a slant to the piece and the piece stands a beam in front
    of it: a vessel (tuning seed 98: a 12 m boat made structure this way and untracked for 20 s). A piece on the
    face's own line beyond its end is still wall."""
    tracker = LidarTracker(LidarTrackerConfig())
    assert tracker.detect(wall(-40.0, 32.0), 0.0, OWN) == []
    centre = np.array([47.0, 12.0])
    axis = (centre - np.array([26.0, 16.0])) / np.linalg.norm(centre - np.array([26.0, 16.0]))
    along = np.arange(-3.5, 3.5, 0.1)
    side = centre + along[:, None] * axis
    points = np.concatenate([np.column_stack([side, np.full(along.size, z)]) for z in (-0.4, -0.9)])
    assert detections_near(tracker, points, 5.0, 47.0, 12.0) == 1
    assert detections_near(tracker, wall(36.0, 40.0), 6.0, 38.0, 16.0) == 0


@pytest.mark.parametrize("corner_reach_m, end_is_vessel", [(5.0, False), (0.0, True)])
def test_a_quays_end_face_seen_from_beyond_the_end_is_structure(corner_reach_m: float, end_is_vessel: bool) -> None:
    """The end face of a quay, seen from out beyond its end, runs from the remembered front face's last corner
    into the land: 6 m of thin wall beside the memory, not on it nor on its line. Tracked, it was a "vessel" at the
    quay's end for the rest of the run (tuning seed 38: 220 false track-frames)."""
    tracker = LidarTracker(LidarTrackerConfig(structure=StructureConfig(corner_reach_m=corner_reach_m)))
    assert tracker.detect(wall(-40.0, 40.0), 0.0, OWN) == []
    beyond = np.array([52.0, 14.5])  # 12 m past the end, 1.5 m off the face's line on the water side
    end_face = line_of_returns(np.array([40.0, 16.0]), np.array([0.0, 1.0]), 6.0)
    dets = tracker.detect(end_face, 5.0, beyond)
    assert sum(1 for d in dets if abs(d.center[0] - 40.0) < 1.0 and abs(d.center[1] - 19.0) < 1.5) == (
        1 if end_is_vessel else 0
    )


@pytest.mark.parametrize("side_margin_m, stern_is_vessel", [(2.0, True), (100.0, False)])
def test_a_moored_boats_stern_against_the_end_of_the_wall_seen_is_a_vessel(
    side_margin_m: float, stern_is_vessel: bool
) -> None:
    """A boat moored alongside hides the wall behind it, so the memory's wall ends at its stern, and the stern
    meets it end-on just as a quay's end face does; but it stands in front of the wall, on the own boat's side."""
    cfg = StructureConfig(corner_side_margin_m=side_margin_m)
    tracker = LidarTracker(LidarTrackerConfig(structure=cfg))
    assert tracker.detect(wall(-50.0, 20.0), 0.0, OWN) == []
    stern = line_of_returns(np.array([20.0, 12.0]), np.array([0.0, 1.0]), 3.7)  # a 3.7 m beam, 0.3 m fenders
    dets = tracker.detect(stern, 5.0, np.array([5.0, 5.0]))
    assert sum(1 for d in dets if abs(d.center[0] - 20.0) < 1.0 and abs(d.center[1] - 13.85) < 1.0) == (
        1 if stern_is_vessel else 0
    )
