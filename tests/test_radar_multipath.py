"""Multipath ghosts: copies of a real target at k x its range on the same bearing are removed."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from tests.radar_synthetic import OwnBoat, box_points, observe
from tracker.radar.config import MultipathConfig, RadarTrackerConfig
from tracker.radar.detector import RadarDetector
from tracker.radar.multipath import multipath_ghosts

SETTINGS = MultipathConfig(
    search_angle_rad=math.radians(10.0),
    range_orders=(2, 3),
    range_tolerance_m=0.75,
    range_tolerance_rel=0.03,
    doppler_tolerance_mps=0.5,
    min_snr_drop_db=0.0,
)


def test_ghost_rules_point_by_point() -> None:
    #                 range  az(deg) Doppler SNR   expected
    rows = [
        (15.0, 10.0, 1.0, 20.0, False),  # 0 real target
        (15.3, 11.0, 1.1, 18.0, False),  # 1 real target, second return
        (30.4, 12.0, 2.1, 9.0, True),  # 2 double bounce of 0/1: 2x range, 2x Doppler, weaker, 2 deg off
        (45.2, 8.0, 3.0, 6.0, True),  # 3 triple bounce
        (30.2, 40.0, 2.0, 9.0, False),  # 4 same range but 30 deg away: another object
        (30.2, 11.0, -0.5, 9.0, False),  # 5 right place, Doppler of something else
        (30.2, 11.0, 2.0, 25.0, False),  # 6 right place and Doppler but stronger than the "original"
        (30.3, 21.5, 2.0, 9.0, False),  # 7 11.5 deg off the nearest real return: outside the search angle
        (30.1, 10.0, 2.0, np.nan, True),  # 8 no SNR reported (TLV 7 absent): decided on geometry and Doppler
        (22.0, 10.0, 2.0, 5.0, False),  # 9 1.5x range: not a k-bounce path
    ]
    r, az, dop, snr, want = (np.array(c) for c in zip(*rows, strict=True))
    got = multipath_ghosts(r, np.radians(az), dop, snr, SETTINGS)
    np.testing.assert_array_equal(got, want.astype(bool))


def test_doppler_test_can_be_switched_off_and_nan_doppler_never_contradicts() -> None:
    r = np.array([10.0, 20.0])
    az = np.radians([0.0, 0.0])
    snr = np.array([20.0, 10.0])
    assert not multipath_ghosts(r, az, np.array([1.0, -1.0]), snr, SETTINGS)[1]
    assert multipath_ghosts(r, az, np.array([1.0, -1.0]), snr, replace(SETTINGS, doppler_tolerance_mps=-1.0))[1]
    assert multipath_ghosts(r, az, np.array([1.0, np.nan]), snr, SETTINGS)[1]


def test_many_returns_are_processed_in_blocks() -> None:
    rng = np.random.default_rng(0)
    n = 700  # more than one block of candidates
    r = rng.uniform(5, 20, n)
    az = rng.uniform(-1, 1, n)
    dop = rng.uniform(-2, 2, n)
    snr = np.full(n, 20.0)
    ghost_r = np.concatenate([r, 2 * r[:50]])
    ghost_az = np.concatenate([az, az[:50]])
    ghost_dop = np.concatenate([dop, 2 * dop[:50]])
    ghost_snr = np.concatenate([snr, np.full(50, 5.0)])
    got = multipath_ghosts(ghost_r, ghost_az, ghost_dop, ghost_snr, SETTINGS)
    assert got[n:].all()
    # Brute-force the originals: a real return is a ghost only if some other return explains it.
    rr, aa, dd, ss = ghost_r, ghost_az, ghost_dop, ghost_snr
    ref = np.zeros(n, bool)
    for j in range(n):
        near = np.abs(np.angle(np.exp(1j * (aa[j] - aa)))) <= SETTINGS.search_angle_rad
        weaker = ~(ss[j] > ss)
        for k in SETTINGS.range_orders:
            ok = np.abs(rr[j] - k * rr) <= SETTINGS.range_tolerance_m + SETTINGS.range_tolerance_rel * k * rr
            ok &= np.abs(dd[j] - k * dd) <= SETTINGS.doppler_tolerance_mps
            ok[j] = False
            ref[j] |= bool(np.any(near & weaker & ok))
    np.testing.assert_array_equal(got[:n], ref)


def test_detector_drops_the_ghost_cluster_of_a_boat() -> None:
    rng = np.random.default_rng(2)
    own = OwnBoat(position=np.zeros(2))
    boat = box_points(np.array([14.0, 3.0]), (3.0, 2.0), 8, rng)
    boat_v = np.array([1.0, 0.0])
    xyz, dop = observe(own, boat, boat_v)
    ghost_xyz = xyz * 2.0  # the double bounce: same bearing, twice the range, twice the Doppler
    ghost_dop = dop * 2.0
    pts = np.concatenate([xyz, ghost_xyz])
    doppler = np.concatenate([dop, ghost_dop])
    snr = np.concatenate([np.full(8, 20.0), np.full(8, 8.0)])
    cfg = RadarTrackerConfig().replaced(
        clustering={"min_points": 3, "velocity_min_points": 3}, shore={"enabled": False}
    )
    out = RadarDetector(cfg).detect(pts, doppler, snr, 0.0, np.zeros(2), 0.0, np.zeros(2))
    np.testing.assert_array_equal(out.ghost, [False] * 8 + [True] * 8)
    assert len(out.detections) == 1
    vel = out.kept_clusters[0].velocity  # a 3 m boat at 14 m spans ~12 deg: only the radial speed is determined
    assert vel.status.value == "radial_only"
    assert vel.radial_speed == pytest.approx(boat_v @ vel.radial_direction, abs=0.02)
    off = cfg.replaced(multipath={"enabled": False})
    assert len(RadarDetector(off).detect(pts, doppler, snr, 0.0, np.zeros(2), 0.0, np.zeros(2)).detections) == 2


def test_a_real_boat_at_twice_the_range_of_another_is_kept_per_cluster() -> None:
    # Two boats at rest on nearly the same bearing, the far one at twice the range: with both still, the Doppler
    # test cannot tell, and the near boat explains 3 of the far boat's 8 returns as double bounces.
    own = OwnBoat(position=np.zeros(2))
    near = np.array([[14.0, -0.6], [14.1, 0.0], [14.0, 0.6], [14.3, -0.3], [14.4, 0.4], [14.2, 0.2]])
    far = np.array(
        [[29.6, 0.0], [30.0, 1.2], [30.3, 0.6], [31.0, -0.4], [31.6, 0.8], [32.2, 0.0], [32.8, 1.0], [33.4, 0.4]]
    )
    xyz, dop = observe(own, np.concatenate([near, far]), np.zeros(2))
    snr = np.concatenate([np.full(6, 30.0), np.full(8, 18.0)])
    cfg = RadarTrackerConfig().replaced(
        clustering={"min_points": 6, "velocity_min_points": 6, "radius_m": 2.5}, shore={"enabled": False}
    )
    out = RadarDetector(cfg).detect(xyz, dop, snr, 0.0, np.zeros(2), 0.0, np.zeros(2))
    np.testing.assert_array_equal(out.ghost[6:], [True] * 3 + [False] * 5)  # within 2 x 14.4 m + 1.6 m
    assert len(out.detections) == 2  # 3 of 8 is under multipath.cluster_ghost_share: the far boat is real
    paper = RadarDetector(cfg.replaced(multipath={"per_cluster": False}))
    assert len(paper.detect(xyz, dop, snr, 0.0, np.zeros(2), 0.0, np.zeros(2)).detections) == 1  # 5 left < 6


def test_a_larger_boat_at_twice_the_range_is_not_a_ghost_of_a_smaller_one() -> None:
    # Both slow (the Doppler test cannot tell): a 0.6 m high boat at 17 m (SNR 30 dB) and a 3 m high one at 34.5 m on
    # the same bearing, only 6 dB weaker. A double bounce would be 12 dB weaker or more.
    r, az = np.array([17.0, 34.5, 34.2]), np.radians([-24.0, -24.5, -23.0])
    dop, snr = np.array([-0.4, -0.45, -0.8]), np.array([30.0, 24.0, 16.0])
    strict = replace(SETTINGS, min_snr_drop_db=10.0)
    assert multipath_ghosts(r, az, dop, snr, strict).tolist() == [False, False, True]  # 14 dB down: a ghost
    assert multipath_ghosts(r, az, dop, snr, SETTINGS).tolist() == [False, True, True]  # any weaker: both


def test_bearing_windows_wrap_round_the_back() -> None:
    # returns either side of +-180 deg are 2 deg apart: a ghost pairs with its original across the wrap
    r = np.array([10.0, 20.2])
    az = np.radians([179.0, -179.0])
    got = multipath_ghosts(r, az, np.array([1.0, 2.0]), np.array([20.0, 9.0]), SETTINGS)
    np.testing.assert_array_equal(got, [False, True])
