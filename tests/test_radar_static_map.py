"""Static map and shore filter: a quay wall is removed from tracking, a boat moored 3 m off it is kept."""

from __future__ import annotations

import numpy as np
import pytest

from tests.radar_synthetic import OwnBoat, box_points, observe, segment_points
from tracker.radar.config import RadarTrackerConfig
from tracker.radar.detector import SHORE_BEHIND, SHORE_KEEP, SHORE_ON, RadarDetector
from tracker.radar.static_map import StaticMap

CFG = RadarTrackerConfig().replaced(clustering={"min_points": 4, "velocity_min_points": 4})
WALL_A, WALL_B = np.array([20.0, -30.0]), np.array([20.0, 30.0])  # quay face along east, 20 m north
MOORED = np.array([16.0, 5.0])  # 2 m (north) x 4 m boat: its side toward the quay is at 17 m, 3 m off the wall
BEHIND = np.array([26.0, -10.0])  # a parked van on the quay, behind the wall seen from the water


def on_moored_boat(p: np.ndarray) -> bool:
    return bool(np.all(np.abs(p - MOORED) <= [1.0 + 0.3, 2.0 + 0.3]))


def quay_frames(cfg: RadarTrackerConfig, n_frames: int, seed: int = 0) -> tuple[RadarDetector, list]:
    """Own boat creeping north at 0.3 m/s toward the quay, 10 Hz, autopilot velocity known."""
    rng = np.random.default_rng(seed)
    det = RadarDetector(cfg)
    outs = []
    for k in range(n_frames):
        t = 0.1 * k
        own = OwnBoat(position=np.array([0.3 * t, 0.0]), yaw=0.0, velocity=np.array([0.3, 0.0]))
        wall = segment_points(WALL_A, WALL_B, 45, 0.1, rng)
        boat = box_points(MOORED, (2.0, 4.0), 12, rng)
        van = box_points(BEHIND, (2.0, 2.0), 8, rng)
        pts = np.concatenate([wall, boat, van])
        xyz, dop = observe(own, pts, np.zeros(2), rng, doppler_noise=0.05)
        outs.append(det.detect(xyz, dop, None, t, own.position, own.yaw, own.velocity))
    return det, outs


def test_wall_removed_moored_boat_kept() -> None:
    det, outs = quay_frames(CFG, 60)
    verdicts = {"wall": set(), "van": set(), "boat": set()}
    boat_frames = 0
    for out in outs[40:]:  # four seconds in: the wall has built up in the map, ends included
        # Nothing but the moored boat (sometimes split in two sparse halves) is left for tracking.
        assert all(on_moored_boat(d.center) for d in out.detections)
        boat_frames += len(out.detections) > 0
        for cl in out.clusters:
            centre = cl.points.mean(axis=0)
            if abs(centre[0] - WALL_A[0]) < 1.0:
                verdicts["wall"].add(cl.shore)
            elif np.linalg.norm(centre - BEHIND) < 2.0:
                verdicts["van"].add(cl.shore)
            else:
                assert on_moored_boat(centre)
                verdicts["boat"].add(cl.shore)
    assert verdicts == {"wall": {SHORE_ON}, "van": {SHORE_BEHIND}, "boat": {SHORE_KEEP}}
    assert boat_frames >= 18
    last = outs[-1]
    # The shore the daemon gets for the obstacle map lies on the wall and covers most of its 60 m.
    shore = det.static_map.shore_points()
    assert len(shore) > 200
    assert np.all(np.abs(shore[:, 0] - 20.0) < 0.8)
    assert shore[:, 1].min() < -25.0 and shore[:, 1].max() > 25.0
    # The moored boat and the van are in the map but not shore (too small).
    assert not det.static_map.is_shore(box_points(MOORED, (2.0, 4.0), 50, np.random.default_rng(9))).any()
    g = np.stack(np.meshgrid(np.arange(15.1, 17.0, 0.25), np.arange(3.1, 7.0, 0.25), indexing="ij"), -1).reshape(-1, 2)
    assert det.static_map.evidence_at(g, last.t).max() >= CFG.shore.occupied_hits  # it is in the map, as static


def test_first_frames_have_no_shore_and_the_ablation_switch_keeps_the_wall() -> None:
    _, outs = quay_frames(CFG, 2)
    assert len(outs[0].detections) >= 3  # one frame of evidence is not a shore yet
    _, outs = quay_frames(CFG.replaced(shore={"enabled": False}), 40)
    wall_dets = [d for d in outs[-1].detections if abs(d.center[0] - 20.0) < 1.0]
    assert len(wall_dets) >= 2


def test_moving_boat_along_the_quay_is_kept_and_does_not_become_shore() -> None:
    # A boat passing along the quay at 2 m/s, 2 m off it: its returns are not static, so they stay out of the map.
    rng = np.random.default_rng(4)
    det = RadarDetector(CFG)
    own = OwnBoat(position=np.zeros(2))
    seen = boat_static = 0
    for k in range(40):
        t = 0.1 * k
        wall = segment_points(WALL_A, WALL_B, 45, 0.1, rng)
        boat_c = np.array([17.0, -15.0 + 2.0 * t])
        xyz_w, dop_w = observe(own, wall, np.zeros(2), rng, 0.05)
        xyz_b, dop_b = observe(own, box_points(boat_c, (2.0, 4.0), 12, rng), np.array([0.0, 2.0]), rng, 0.05)
        pts, dop = np.concatenate([xyz_w, xyz_b]), np.concatenate([dop_w, dop_b])
        out = det.detect(pts, dop, None, t, own.position, 0.0, own.velocity)
        boat_static += int(out.static[len(wall) :].sum())
        seen += any(np.linalg.norm(d.center - boat_c) < 1.5 for d in out.detections)
        if k >= 20:  # the wall is shore by now; the boat must not have been removed with it
            assert all(cl.shore == SHORE_KEEP for cl in out.clusters if np.linalg.norm(cl.points.mean(0) - boat_c) < 2)
    # Only returns whose Doppler happens to look static (motion nearly across the line of sight) reach the map.
    assert boat_static <= 10
    assert seen >= 36  # clustered and kept in nearly every frame (12 sparse returns do not always cluster)
    assert det.static_map.shore_points().shape[0] > 200
    assert not det.static_map.is_shore(np.array([[17.0, -5.0], [17.0, 0.0], [17.0, 5.0]])).any()


def test_window_shifts_by_whole_submaps_and_keeps_evidence() -> None:
    cfg = CFG.replaced(shore={"submap_cells": 40})  # 10 m sub-maps, 30 m window
    m = StaticMap(cfg)
    m.follow(np.array([1.0, 1.0]))
    assert m.origin == (-40, -40)
    pts = np.array([[3.0, 4.0], [8.0, -6.0], [-9.0, 2.0]])
    m.add_points(pts, 0.0)
    m.add_points(pts, 0.0)
    np.testing.assert_allclose(m.evidence_at(pts, 0.0), [2.0, 2.0, 2.0])
    m.follow(np.array([9.9, 1.0]))  # still in the middle sub-map
    assert m.origin == (-40, -40) and m.shifts == 0
    m.follow(np.array([10.1, 1.0]))  # crossed north into the next one: shift by one sub-map
    assert m.origin == (0, -40) and m.shifts == 1
    np.testing.assert_allclose(m.evidence_at(pts, 0.0), [2.0, 2.0, 0.0])  # the southern strip fell out
    m.add_points(np.array([[25.0, 0.0]]), 0.0)  # newly covered area works
    assert m.evidence_at(np.array([[25.0, 0.0]]), 0.0)[0] == 1.0


def test_evidence_decays_and_backward_time_clears() -> None:
    cfg = CFG.replaced(shore={"decay_time_s": 2.0})
    m = StaticMap(cfg)
    m.follow(np.zeros(2))
    p = np.array([[5.0, 5.0]])
    m.add_points(p, 10.0)
    m.add_points(p, 12.0)
    assert m.evidence_at(p, 12.0)[0] == pytest.approx(1.0 + np.exp(-1.0))
    assert m.evidence_at(p, 14.0)[0] == pytest.approx((1.0 + np.exp(-1.0)) * np.exp(-1.0))
    m.add_points(p, 40.0)  # 15 time constants later: stored values get rebased, reads are unchanged
    assert m.evidence_at(p, 40.0)[0] == pytest.approx(1.0 + (1.0 + np.exp(-1.0)) * np.exp(-14.0))
    m.add_points(p, 5.0)  # replay restarted
    assert m.evidence_at(p, 5.0)[0] == 0.0  # map was cleared (origin reset, nothing counted before follow)


def test_shore_horizon_is_reused_only_for_the_same_radar_position_and_shore() -> None:
    det, _ = quay_frames(CFG, 60)
    m = det.static_map
    here, there = np.array([1.8, 0.0]), np.array([1.8, 12.0])
    h_here = m.shore_horizon(here)
    assert np.isfinite(h_here).any()
    b = m._bearing_bin(np.array([[1.0, 0.0]]))[0]  # due north: the wall at 20 m, 18.2 m from here
    assert h_here[b] == pytest.approx(18.2, abs=0.5)
    h_there = m.shore_horizon(there)
    assert not np.array_equal(h_here, h_there)  # moved 12 m east: the wall is seen at other bearings and ranges
    np.testing.assert_array_equal(m.shore_horizon(here), h_here)
    m.update_shore(100.0, np.zeros(2), 100.0)  # 100 s later every hit has decayed: no shore, no horizon
    assert np.isinf(m.shore_horizon(here)).all()


def test_block_dilation_matches_ndimage() -> None:
    from scipy import ndimage

    from tracker.radar.static_map import _dilate_3x3

    rng = np.random.default_rng(0)
    for _ in range(200):
        mask = rng.random((int(rng.integers(1, 40)), int(rng.integers(1, 40)))) < rng.uniform(0.0, 0.3)
        np.testing.assert_array_equal(_dilate_3x3(mask), ndimage.binary_dilation(mask, np.ones((3, 3), bool)))
