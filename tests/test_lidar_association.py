"""Bhattacharyya distance, footprint Gaussians and the gated optimal assignment (tracker/assignment.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracker.assignment import gated_assignment
from tracker.lidar.association import associate, bhattacharyya_distance, footprint_covariance
from tracker.lidar.config import AssociationConfig


def test_bhattacharyya_by_hand() -> None:
    # a: N((0, 0), diag(1, 4)), b: N((2, 0), diag(3, 4)).  S = diag(2, 4).
    # 1/8 d^T S^-1 d = 1/8 * 4/2 = 0.25;  1/2 ln(det S / sqrt(det a det b)) = 1/2 ln(8 / sqrt(48)).
    expected = 0.25 + 0.5 * math.log(8.0 / math.sqrt(48.0))
    d = bhattacharyya_distance(
        np.array([[0.0, 0.0]]), np.diag([1.0, 4.0])[None], np.array([[2.0, 0.0]]), np.diag([3.0, 4.0])[None]
    )
    assert d.shape == (1, 1)
    assert d[0, 0] == pytest.approx(expected, rel=1e-12)


def test_bhattacharyya_full_covariance_matches_the_textbook_formula() -> None:
    rng = np.random.default_rng(5)
    ma, mb = rng.normal(size=(3, 2)), rng.normal(size=(4, 2))
    ca = np.array([(lambda m: m @ m.T + 0.1 * np.eye(2))(rng.normal(size=(2, 2))) for _ in range(3)])
    cb = np.array([(lambda m: m @ m.T + 0.1 * np.eye(2))(rng.normal(size=(2, 2))) for _ in range(4)])
    got = bhattacharyya_distance(ma, ca, mb, cb)
    for i in range(3):
        for j in range(4):
            s = 0.5 * (ca[i] + cb[j])
            d = ma[i] - mb[j]
            ref = d @ np.linalg.solve(s, d) / 8 + 0.5 * math.log(
                np.linalg.det(s) / math.sqrt(np.linalg.det(ca[i]) * np.linalg.det(cb[j]))
            )
            assert got[i, j] == pytest.approx(ref, rel=1e-10)
    # Identical Gaussians are at distance 0; the distance is symmetric.
    assert bhattacharyya_distance(ma, ca, ma, ca).diagonal() == pytest.approx(np.zeros(3), abs=1e-12)
    assert bhattacharyya_distance(mb, cb, ma, ca) == pytest.approx(got.T)


def test_footprint_covariance_is_the_rectangle_second_moment() -> None:
    # A 12 m x 6 m rectangle heading east (90 deg): variance 12^2/12 = 12 along east, 6^2/12 = 3 along north.
    cov = footprint_covariance(np.array([math.pi / 2]), np.array([12.0]), np.array([6.0]))
    assert cov[0] == pytest.approx(np.array([[3.0, 0.0], [0.0, 12.0]]), abs=1e-12)
    cov45 = footprint_covariance(np.array([math.pi / 4]), np.array([12.0]), np.array([6.0]))[0]
    assert cov45 == pytest.approx(np.array([[7.5, 4.5], [4.5, 7.5]]))


def test_gated_assignment_is_optimal_not_greedy() -> None:
    # Greedy would take (0, 0) = 1 and leave row 1 with 10; optimal is (0, 1) + (1, 0) = 2 + 2.
    cost = np.array([[1.0, 2.0], [2.0, 10.0]])
    a = gated_assignment(cost, gate=20.0)
    assert a.matches.tolist() == [[0, 1], [1, 0]]
    assert a.unmatched_rows.size == 0 and a.unmatched_cols.size == 0


def test_gated_assignment_respects_the_gate_and_non_finite_entries() -> None:
    cost = np.array([[0.5, 9.0, np.nan], [np.inf, 4.0, 1.0], [7.0, 8.0, 9.0]])
    a = gated_assignment(cost, gate=3.0)
    assert a.matches.tolist() == [[0, 0], [1, 2]]
    assert a.unmatched_rows.tolist() == [2]
    assert a.unmatched_cols.tolist() == [1]
    # A forbidden pair never becomes a match just because the matrix is square.
    b = gated_assignment(np.array([[1.0, 50.0], [50.0, 50.0]]), gate=3.0)
    assert b.matches.tolist() == [[0, 0]]


def test_gated_assignment_empty_and_rectangular() -> None:
    a = gated_assignment(np.zeros((0, 3)), gate=1.0)
    assert a.matches.shape == (0, 2) and a.unmatched_cols.tolist() == [0, 1, 2]
    b = gated_assignment(np.array([[5.0, 0.1, 3.0]]), gate=np.inf)
    assert b.matches.tolist() == [[0, 1]] and b.unmatched_cols.tolist() == [0, 2]
    with pytest.raises(ValueError, match="2-D"):
        gated_assignment(np.zeros(3), gate=1.0)


def test_associate_prefers_the_right_size_over_the_nearest_centre() -> None:
    # A dinghy track (3 m x 1.5 m). Detections: a ferry-sized shape 0.8 m away, a dinghy-sized one 1.0 m away.
    small_pos = 0.05 * np.eye(2)
    t_mean = np.array([[0.0, 0.0]])
    t_cov = footprint_covariance(np.zeros(1), np.array([3.0]), np.array([1.5])) + small_pos
    d_mean = np.array([[0.8, 0.0], [0.0, 1.0]])
    d_cov = footprint_covariance(np.zeros(2), np.array([38.0, 3.2]), np.array([9.0, 1.4])) + small_pos
    assignment, cost = associate(t_mean, t_cov, d_mean, d_cov, AssociationConfig(gate=5.0, max_distance=10.0))
    assert assignment.matches.tolist() == [[0, 1]]
    assert cost[0, 1] < cost[0, 0]


def test_associate_hard_distance_gate() -> None:
    cov = np.eye(2)[None] * 400.0  # huge Gaussians would overlap across any distance
    assignment, cost = associate(
        np.array([[0.0, 0.0]]), cov, np.array([[0.0, 15.0]]), cov, AssociationConfig(gate=5.0, max_distance=10.0)
    )
    assert assignment.matches.shape == (0, 2)
    assert np.isinf(cost[0, 0])
