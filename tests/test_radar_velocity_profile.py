"""Doppler velocity profile (paper 001, eq. 3-6): exact recovery, outliers, and what a cluster cannot determine."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracker.radar.config import RadarTrackerConfig
from tracker.radar.velocity_profile import (
    VelocityStatus,
    batch_size_limit,
    fit_velocity_profile,
    fit_velocity_profiles,
    ransac_iterations,
)

SETTINGS = RadarTrackerConfig().velocity.settings()


def lines_of_sight(azimuth_deg: np.ndarray) -> np.ndarray:
    a = np.radians(azimuth_deg)
    return np.column_stack([np.cos(a), np.sin(a)])


def profile(speed: float, alpha_deg: float, azimuth_deg: np.ndarray) -> np.ndarray:
    """Eq. 4: v_r = v cos(theta - alpha)."""
    return speed * np.cos(np.radians(azimuth_deg - alpha_deg))


def test_ransac_iterations_from_outlier_rate() -> None:
    # log(1 - 0.99) / log(1 - 0.7^2) = 6.84 -> 7 pairs; no outliers -> 1; capped by the maximum
    assert ransac_iterations(0.3, 0.99, 2, 100) == 7
    assert ransac_iterations(0.0, 0.99, 2, 100) == 1
    assert ransac_iterations(0.9, 0.999, 2, 50) == 50


def test_exact_profile_with_gross_outliers_recovers_speed_and_orientation() -> None:
    az = np.linspace(10.0, 50.0, 16)  # a boat spanning 40 deg: both components well determined
    v_r = profile(2.0, 30.0, az)
    outliers = np.array([2, 7, 11, 14])
    v_r[outliers] += np.array([1.7, -2.4, 3.1, -0.9])  # multipath / sea clutter Doppler
    est = fit_velocity_profile(lines_of_sight(az), v_r, SETTINGS, np.random.default_rng(0))
    assert est.status is VelocityStatus.FULL
    np.testing.assert_allclose(
        est.velocity, [2.0 * math.cos(math.radians(30)), 2.0 * math.sin(math.radians(30))], atol=1e-9
    )
    assert est.speed == pytest.approx(2.0, abs=1e-9)
    assert math.degrees(est.course) == pytest.approx(30.0, abs=1e-7)
    expected_inliers = np.ones(16, bool)
    expected_inliers[outliers] = False
    np.testing.assert_array_equal(est.inliers, expected_inliers)
    assert est.heading_determined


def test_noisy_large_cluster_uses_random_pairs_and_stays_within_tolerance() -> None:
    rng = np.random.default_rng(7)
    az = rng.uniform(-30.0, 30.0, 80)
    v_r = profile(1.2, -120.0, az) + rng.normal(0.0, 0.05, 80)
    bad = rng.choice(80, 24, replace=False)  # 30 % outliers, the configured rate
    v_r[bad] += rng.uniform(0.8, 3.0, 24) * rng.choice([-1, 1], 24)
    est = fit_velocity_profile(lines_of_sight(az), v_r, SETTINGS, np.random.default_rng(3))
    assert est.status is VelocityStatus.FULL
    assert est.speed == pytest.approx(1.2, abs=0.08)
    assert math.degrees(est.course) == pytest.approx(-120.0, abs=5.0)
    assert not est.inliers[bad].any()
    # the covariance is the LS one: a few cm/s along the line of sight
    assert math.sqrt(est.radial_direction @ est.covariance @ est.radial_direction) < 0.03


def test_narrow_cluster_gives_radial_component_only() -> None:
    az = np.linspace(43.5, 46.5, 8)  # 3 deg: a small boat far away
    v_r = profile(3.0, 0.0, az)  # moving north, line of sight about 45 deg
    est = fit_velocity_profile(lines_of_sight(az), v_r, SETTINGS, np.random.default_rng(0))
    assert est.status is VelocityStatus.RADIAL_ONLY
    assert not est.determined and not est.heading_determined
    assert math.isnan(est.tangential_speed) and math.isnan(est.speed) and math.isnan(est.course)
    los = lines_of_sight(np.array([45.0]))[0]
    np.testing.assert_allclose(est.radial_direction, los, atol=1e-9)
    assert est.radial_speed == pytest.approx(3.0 * math.cos(math.radians(45)), abs=2e-3)
    across = np.array([-los[1], los[0]])
    assert est.velocity @ across == pytest.approx(0.0, abs=1e-12)  # nothing invented across the line of sight
    assert across @ est.covariance @ across == pytest.approx(SETTINGS.undetermined_var, rel=1e-6)
    assert los @ est.covariance @ los < 0.01


def test_single_point_is_not_determined() -> None:
    est = fit_velocity_profile(lines_of_sight(np.array([10.0])), np.array([1.0]), SETTINGS, np.random.default_rng(0))
    assert est.status is VelocityStatus.UNDETERMINED
    assert np.isnan(est.velocity).all() and np.isnan(est.covariance).all()
    assert "1 Doppler points" in est.reason


def test_all_returns_at_one_azimuth_do_not_determine_the_tangential_component() -> None:
    az = np.full(6, 20.0)
    v_r = np.array([0.8, 0.82, 0.79, 0.81, 0.8, -2.0])  # one Doppler outlier
    est = fit_velocity_profile(lines_of_sight(az), v_r, SETTINGS, np.random.default_rng(0))
    assert est.status is VelocityStatus.RADIAL_ONLY
    assert math.isnan(est.tangential_speed)
    assert est.radial_speed == pytest.approx(0.804, abs=1e-3)
    np.testing.assert_array_equal(est.inliers, [True] * 5 + [False])


def test_zero_doppler_spread_cluster_is_at_rest_with_unknown_course() -> None:
    az = np.linspace(-20.0, 20.0, 9)
    est = fit_velocity_profile(lines_of_sight(az), np.zeros(9), SETTINGS, np.random.default_rng(0))
    assert est.status is VelocityStatus.FULL
    np.testing.assert_allclose(est.velocity, [0.0, 0.0], atol=1e-12)
    assert not est.heading_determined
    assert math.isnan(est.course)  # no made-up direction for a boat at rest


def test_no_consensus_is_not_determined() -> None:
    az = np.linspace(-20.0, 20.0, 8)
    u = lines_of_sight(az)
    v_r = np.array([0.5, -3.0, 4.0, -1.0, 6.0, -5.0, 2.5, -7.0])  # sea clutter: no common profile
    # brute force over every two-point model: at most 3 of 8 returns agree, below the 50 % consensus
    pairs = [(i, j) for i in range(8) for j in range(i + 1, 8)]
    best = max(
        int((np.abs(u @ np.linalg.solve(u[[i, j]], v_r[[i, j]]) - v_r) <= SETTINGS.inlier_threshold).sum())
        for i, j in pairs
    )
    assert best == 3
    est = fit_velocity_profile(u, v_r, SETTINGS, np.random.default_rng(0))
    assert est.status is VelocityStatus.UNDETERMINED
    assert "consensus 3 of 8" in est.reason


def test_nan_doppler_is_ignored_and_length_mismatch_rejected() -> None:
    az = np.linspace(0.0, 40.0, 10)
    v_r = profile(1.0, 90.0, az)
    v_r[[1, 4]] = np.nan
    est = fit_velocity_profile(lines_of_sight(az), v_r, SETTINGS, np.random.default_rng(0))
    assert est.status is VelocityStatus.FULL
    np.testing.assert_allclose(est.velocity, [0.0, 1.0], atol=1e-9)
    assert not est.inliers[[1, 4]].any()
    with pytest.raises(ValueError, match="lines of sight"):
        fit_velocity_profile(lines_of_sight(az), v_r[:5], SETTINGS, np.random.default_rng(0))


def _mixed_clusters() -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Clusters taking every branch of the fit: wide and narrow, with outliers, at one azimuth, too few, no
    consensus, NaN Doppler, and larger than the batch (random pairs)."""
    rng = np.random.default_rng(11)
    los, v_r = [], []
    for n in [3, 4, 5, 6, 8, 10, 12, 14, 20, 45]:
        for span in [0.5, 3.0, 25.0, 60.0]:
            az = rng.uniform(-span / 2, span / 2, n) + rng.uniform(-180, 180)
            z = profile(rng.uniform(0.0, 4.0), rng.uniform(-180, 180), az) + rng.normal(0.0, 0.05, n)
            z[rng.random(n) < 0.25] += rng.uniform(-3.0, 3.0)
            los.append(lines_of_sight(az))
            v_r.append(z)
    los += [lines_of_sight(np.full(5, 40.0)), lines_of_sight(np.array([0.0, 180.0, 0.0, 180.0]))]
    v_r += [np.array([1.0, 1.0, 1.1, 0.9, 1.0]), np.array([1.0, -1.0, 1.0, -1.0])]
    los.append(lines_of_sight(np.array([0.0, 40.0, 80.0, 120.0, 160.0, 200.0])))
    v_r.append(np.array([3.0, -2.0, 0.5, 4.0, -3.5, 1.5]))  # no two-point model explains three returns
    los += [lines_of_sight(np.array([0.0, 30.0])), lines_of_sight(np.array([0.0, 20.0, 40.0, 60.0]))]
    v_r += [np.array([1.0, 0.8]), np.array([1.0, np.nan, 0.9, 0.7])]
    return los, v_r


def test_batch_fit_gives_each_clusters_single_fit() -> None:
    """fit_velocity_profiles (one padded batch for clusters of up to 14 returns) against fit_velocity_profile one
    by one on the same generator state: the same status, reason, inliers and heading flag, the numbers to 1e-12 (the
    batch solves its least squares by normal equations, the single fit by lstsq); the large clusters' random pairs
    drawn in the same order."""
    los, v_r = _mixed_clusters()
    batch = fit_velocity_profiles(los, v_r, SETTINGS, np.random.default_rng(5))
    rng = np.random.default_rng(5)
    single = [fit_velocity_profile(u, z, SETTINGS, rng) for u, z in zip(los, v_r, strict=True)]
    statuses = {est.status for est in single}
    assert statuses == set(VelocityStatus)  # every branch is exercised
    assert sum(est.reason == "azimuth spread too small for the tangential component" for est in single) >= 10
    for b, s in zip(batch, single, strict=True):
        assert (b.status, b.reason, b.heading_determined) == (s.status, s.reason, s.heading_determined)
        np.testing.assert_array_equal(b.inliers, s.inliers)
        for name in ("velocity", "covariance", "radial_direction"):
            np.testing.assert_allclose(getattr(b, name), getattr(s, name), rtol=1e-12, atol=1e-12, equal_nan=True)
        for name in ("radial_speed", "tangential_speed", "residual_std"):
            assert getattr(b, name) == pytest.approx(getattr(s, name), rel=1e-12, abs=1e-12, nan_ok=True)


def test_batch_takes_clusters_up_to_the_all_pairs_size() -> None:
    # 100 iterations at most: every pair of up to 14 returns (91 pairs) is tried, 15 returns (105) are sampled
    assert batch_size_limit(SETTINGS) == 14
