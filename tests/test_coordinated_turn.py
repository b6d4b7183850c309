"""The coordinated-turn model (tracker.coordinated_turn) and the two filters built on it: the LiDAR EKF's
ctrv_predict and the radar filter's ct_transition / predict_many."""

from __future__ import annotations

import math
from decimal import Decimal, localcontext

import numpy as np
import pytest

from tracker.coordinated_turn import SERIES_BELOW, coordinated_turn
from tracker.lidar.ekf import OMEGA, PE, PN, PSI, VE, VN, ctrv_predict
from tracker.radar import kalman
from tracker.radar.config import RadarTrackerConfig

CT = RadarTrackerConfig().replaced(kalman={"motion_model": "ct", "accel_std": 0.7})


def _reference_gains(w: float, dt: float) -> tuple[float, float, float, float]:
    """(a, b, da/dw, db/dw) to 60 digits from the closed forms, with sin and cos summed as Taylor series: at that
    precision the closed forms' cancellation near w = 0 costs nothing that shows in float64."""
    with localcontext() as ctx:
        ctx.prec = 60
        w_d, dt_d = Decimal(w), Decimal(dt)
        th = w_d * dt_d
        if th == 0:
            return dt, 0.0, 0.0, dt * dt / 2
        s, c, term, k = Decimal(0), Decimal(0), Decimal(1), 0
        while k < 4 or abs(term) > Decimal(10) ** -70:
            if k % 4 == 0:
                c += term
            elif k % 4 == 1:
                s += term
            elif k % 4 == 2:
                c -= term
            else:
                s -= term
            k += 1
            term = term * th / k
        gains = (s / w_d, (1 - c) / w_d, (th * c - s) / (w_d * w_d), (th * s - (1 - c)) / (w_d * w_d))
        return tuple(float(g) for g in gains)  # type: ignore[return-value]


def _gains(w: np.ndarray, dt: float) -> np.ndarray:
    """(n, 4) a, b, da/dw, db/dw as coordinated_turn's Jacobian carries them for a unit velocity north."""
    j = coordinated_turn(1.0, 0.0, w, dt).jacobian
    return np.stack([j[:, 0, 0], j[:, 1, 0], j[:, 0, 2], j[:, 1, 2]], axis=1)


@pytest.mark.parametrize("dt", [0.05, 0.1, 0.5, 1.0])
def test_gains_are_good_to_rounding_on_both_sides_of_the_series_threshold(dt: float) -> None:
    # Turn rates up to 1 rad/s, and the series threshold approached from both sides.
    th = np.concatenate(
        [np.logspace(-9, math.log10(dt), 60), SERIES_BELOW * np.array([0.5, 0.99, 1 - 1e-12, 1.0, 1 + 1e-12, 1.01, 2])]
    )
    th = np.concatenate([th, -th])
    w = th / dt
    got = _gains(w, dt)
    want = np.array([_reference_gains(float(wi), dt) for wi in w])
    rel = np.abs(got - want) / np.abs(want)
    assert rel[:, [0, 1, 3]].max() < 1e-15  # a few rounding steps (1.1e-16 each)
    # da/dw = (theta cos - sin) / w^2 cancels above the threshold: ~1e-16 dt^2 / |theta| absolute, while the
    # Jacobian entry it enters is ~ speed dt^2 / 2 (db/dw).
    assert np.abs(got[:, 2] - want[:, 2]).max() < 5e-14 * dt * dt
    assert rel[np.abs(th) < SERIES_BELOW, 2].max() < 1e-15  # the series side itself is exact to rounding


def test_gains_at_zero_turn_rate_are_the_straight_line() -> None:
    np.testing.assert_array_equal(_gains(np.zeros(1), 0.3), [[0.3, 0.0, 0.0, 0.3 * 0.3 / 2]])


def test_ctrv_follows_the_circle() -> None:
    # Heading north at 3 m/s, turning clockwise (toward east) at 0.1 rad/s: a circle of radius 30 m centred east.
    x = np.array([[0.0, 0.0, 3.0, 0.0, 0.0, 0.1, 8.0, 3.0, 2.0]])
    out, _ = ctrv_predict(x, 2.0)
    a = 0.2
    assert out[0, :2] == pytest.approx([30.0 * math.sin(a), 30.0 * (1.0 - math.cos(a))], abs=1e-12)
    assert out[0, [VN, VE]] == pytest.approx([3.0 * math.cos(a), 3.0 * math.sin(a)], abs=1e-12)
    assert out[0, PSI] == pytest.approx(a)
    assert out[0, 6:] == pytest.approx([8.0, 3.0, 2.0])
    # No turn: a straight line.
    straight, _ = ctrv_predict(np.array([[1.0, 2.0, 3.0, -1.0, 0.3, 0.0, 1, 1, 1]]), 0.5)
    assert straight[0, :4] == pytest.approx([2.5, 1.5, 3.0, -1.0])


@pytest.mark.parametrize("omega", [0.0, 1e-6, 0.2, -0.5])
def test_ctrv_jacobian_matches_finite_differences(omega: float) -> None:
    x = np.array([5.0, -3.0, 2.0, -1.5, 0.7, omega, 8.0, 3.0, 2.0])
    _, f = ctrv_predict(x[None], 0.3)
    num = np.empty((9, 9))
    h = 1e-6
    for j in range(9):
        dx = np.zeros(9)
        dx[j] = h
        hi, _ = ctrv_predict((x + dx)[None], 0.3)
        lo, _ = ctrv_predict((x - dx)[None], 0.3)
        num[:, j] = (hi[0] - lo[0]) / (2 * h)
    assert f[0] == pytest.approx(num, abs=1e-6)


def test_coordinated_turn_prediction_follows_the_circle_with_its_jacobian() -> None:
    x = np.array([0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.2])  # 3 m/s north, turning toward east at 1.2 rad/s
    y, j = kalman.ct_transition(x, 2 * np.pi / 1.2)  # one full turn: back at the start, same velocity
    np.testing.assert_allclose(y[0, :4], x[:4], atol=1e-9)
    y, _ = kalman.ct_transition(x, np.pi / 1.2)  # half a turn: 2 r = 5 m east, heading south
    np.testing.assert_allclose(y[0, :4], [0.0, 5.0, -3.0, 0.0], atol=1e-9)
    for w in (1.2, 1e-7):  # the Jacobian, also on the small-angle branch
        x[kalman.TURN] = w
        _, j = kalman.ct_transition(x, 0.1)
        num = np.zeros_like(j[0])
        for i in range(x.size):
            e = np.zeros(x.size)
            e[i] = 1e-6
            num[:, i] = (kalman.ct_transition(x + e, 0.1)[0][0] - kalman.ct_transition(x - e, 0.1)[0][0]) / 2e-6
        np.testing.assert_allclose(j[0], num, atol=1e-6)


def test_both_filters_predict_the_same_turn() -> None:
    rng = np.random.default_rng(5)
    vel, w = rng.uniform(-10, 10, (50, 2)), rng.uniform(-1, 1, 50)
    w[:5] = [0.0, 1e-9, -1e-6, SERIES_BELOW / 0.1, -SERIES_BELOW / 0.1]
    lidar = np.zeros((50, 9))
    lidar[:, [VN, VE]], lidar[:, OMEGA] = vel, w
    radar = np.zeros((50, 9))
    radar[:, kalman.VEL], radar[:, kalman.TURN] = vel, w
    xl, fl = ctrv_predict(lidar, 0.1)
    xr, jr = kalman.ct_transition(radar, 0.1)
    np.testing.assert_array_equal(xl[:, [PN, PE, VN, VE]], xr[:, :4])
    np.testing.assert_array_equal(fl[:, [PN, PE, VN, VE]][:, :, [VN, VE, OMEGA]], jr[:, :4][:, :, [2, 3, kalman.TURN]])


@pytest.mark.parametrize("model", ["ct", "ca", "cv"])
def test_predict_many_is_predict_per_filter(model: str) -> None:
    """The radar tracker predicts all its tracks in one stack: the same numbers as one at a time, each its own dt."""
    cfg = CT.replaced(kalman={"motion_model": model})
    rng = np.random.default_rng(7)
    n = kalman.dim_x(cfg)
    one, many = [], []
    for _ in range(6):
        x = rng.normal(size=(n, 1)) * 5.0
        if model == "ct":
            x[kalman.TURN, 0] = rng.uniform(-3.0, 3.0)  # beyond max_turn_rate too: clamped
        a = rng.normal(size=(n, n))
        for bank in (one, many):
            kf = kalman.new_filter(np.zeros(2), np.ones(2), 30.0, None, cfg)
            kf.x, kf.P = x.copy(), a @ a.T + np.eye(n)
            bank.append(kf)
    dts = [0.1, 0.1, 0.25, 0.0, -0.1, 0.1]  # a track that does not move for dt <= 0
    before = [kf.x.copy() for kf in many]
    kalman.predict_many(many, dts, cfg)
    for kf, dt in zip(one, dts, strict=True):
        kalman.predict(kf, dt, cfg)
    for k, (a_kf, b_kf) in enumerate(zip(one, many, strict=True)):
        np.testing.assert_allclose(b_kf.x, a_kf.x, rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(b_kf.P, a_kf.P, rtol=1e-14, atol=1e-14)
        if dts[k] <= 0:
            np.testing.assert_array_equal(b_kf.x, before[k])
        else:
            assert b_kf.last_dt == dts[k]
            if model == "ct":
                assert abs(b_kf.x[kalman.TURN, 0]) <= cfg.kalman.max_turn_rate
