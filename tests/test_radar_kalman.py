"""The radar track filter's motion models and its manoeuvre rule (tracker.radar.kalman)."""

from __future__ import annotations

import numpy as np
import pytest

from tracker.radar import kalman
from tracker.radar.config import RadarTrackerConfig
from tracker.radar.velocity_profile import VelocityEstimate, VelocityStatus

CV = RadarTrackerConfig().replaced(kalman={"motion_model": "cv", "accel_std": 2.0})


def test_constant_velocity_model_matrices() -> None:
    dt = 0.1
    f = kalman.transition(dt, CV)
    want = np.eye(8)
    want[0, 2] = want[1, 3] = dt
    np.testing.assert_array_equal(f, want)  # no acceleration terms
    q = kalman.process_noise(dt, CV)
    a2 = 4.0
    np.testing.assert_allclose(q[np.ix_([0, 2], [0, 2])], a2 * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]]))
    np.testing.assert_allclose(q[np.ix_([1, 3], [1, 3])], q[np.ix_([0, 2], [0, 2])])
    assert not q[4:6].any() and not q[:, 4:6].any()  # the acceleration state stays at zero
    ca = kalman.transition(dt, RadarTrackerConfig())
    assert ca[0, 4] == pytest.approx(dt * dt / 2) and ca[2, 4] == pytest.approx(dt)
    with pytest.raises(ValueError, match="motion_model"):
        RadarTrackerConfig().replaced(kalman={"motion_model": "imm"})


def test_velocity_follows_positions_under_the_cv_model() -> None:
    kf = kalman.new_filter(np.array([10.0, 0.0]), np.ones(2), 10.0, None, CV)
    for k in range(1, 31):
        kalman.predict(kf, 0.1, CV)
        kalman.fused_update(kf, np.array([10.0 + 0.2 * k, 0.0]), np.ones(2), 10.0, None, CV)
    np.testing.assert_allclose(kf.x[kalman.VEL, 0], [2.0, 0.0], atol=0.1)
    np.testing.assert_array_equal(kf.x[kalman.ACC, 0], [0.0, 0.0])


def radial(speed: float, direction: np.ndarray, var: float = 1e-4) -> VelocityEstimate:
    e = direction / np.linalg.norm(direction)
    across = np.array([-e[1], e[0]])
    return VelocityEstimate(
        status=VelocityStatus.RADIAL_ONLY,
        velocity=speed * e,
        covariance=var * np.outer(e, e) + 1e4 * np.outer(across, across),
        radial_direction=e,
        radial_speed=speed,
        tangential_speed=float("nan"),
        heading_determined=False,
        inliers=np.ones(3, bool),
        residual_std=0.01,
    )


def settled(cfg: RadarTrackerConfig) -> object:
    kf = kalman.new_filter(np.array([20.0, 0.0]), np.ones(2), 20.0, None, cfg)
    for _ in range(30):  # at rest for 3 s
        kalman.predict(kf, 0.1, cfg)
        kalman.fused_update(kf, np.array([20.0, 0.0]), np.ones(2), 20.0, None, cfg)
    kalman.predict(kf, 0.1, cfg)
    return kf


def test_manoeuvre_opens_the_velocity_and_skips_the_doppler() -> None:
    jump = np.array([20.0, 4.0])  # 4 m off a settled prediction: NIS ~19, above 9.21
    wild = radial(5.0, np.array([1.0, 0.0]))  # a Doppler speed no boat here has (a turning hull's returns)
    kf = settled(CV)
    kalman.fused_update(kf, jump, np.ones(2), 20.0, wild, CV)
    turned = kf.x[kalman.VEL, 0].copy()
    assert turned[1] > 1.5  # this very update turns the velocity toward the jump
    assert turned[0] == pytest.approx(0.0, abs=1e-9)  # and leaves the Doppler out
    off = CV.replaced(doppler={"maneuver_nis": 0.0})
    kf2 = settled(off)
    kalman.fused_update(kf2, jump, np.ones(2), 20.0, None, off)
    assert kf2.x[3, 0] < turned[1] / 2  # without the rule the settled filter turns half as much
    keep = CV.replaced(doppler={"maneuver_skip_doppler": False})
    kf3 = settled(keep)
    kalman.fused_update(kf3, jump, np.ones(2), 20.0, wild, keep)
    assert kf3.x[2, 0] > 4.0  # the opened-up velocity takes the Doppler whole


def test_doppler_is_fused_without_a_manoeuvre_with_its_model_floor() -> None:
    kf = settled(CV)
    v = radial(0.4, np.array([1.0, 0.0]))
    r = kalman.velocity_noise(v, 20.0, CV)
    w = kalman.doppler_weight(CV, 20.0)
    assert r[0, 0] == pytest.approx((1e-4 + 0.3**2) / w)
    kalman.fused_update(kf, np.array([20.0, 0.0]), np.ones(2), 20.0, v, CV)
    assert 0.05 < kf.x[2, 0] < 0.4  # pulled toward the radial 0.4 m/s, not all the way


CT = RadarTrackerConfig().replaced(kalman={"motion_model": "ct", "accel_std": 0.7})


def test_turn_rate_state_follows_a_tight_turn_that_cv_lags() -> None:
    """3 m/s on a 2.5 m radius, positions only: the ct filter learns the rate and stays on the hull."""
    w, r, dt = 1.2, 2.5, 0.1
    err = {}
    for cfg in (CV, CT):
        kf = kalman.new_filter(np.array([20.0, 0.0]), np.ones(2), 20.0, None, cfg)
        for k in range(1, 21):  # 2 s straight north
            kalman.predict(kf, dt, cfg)
            kalman.fused_update(kf, np.array([20.0 + 0.3 * k, 0.0]), np.ones(2), 20.0, None, cfg)
        lag = []
        for k in range(1, 16):  # 1.5 s of turn toward east, centre 2.5 m east of the turn's start
            th = w * dt * k
            kalman.predict(kf, dt, cfg)
            lag.append(np.hypot(*(kf.x[kalman.POS, 0] - [26.0 + r * np.sin(th), r * (1 - np.cos(th))])))
            kalman.fused_update(
                kf, np.array([26.0 + r * np.sin(th), r * (1 - np.cos(th))]), np.ones(2), 20.0, None, cfg
            )
        err[cfg.kalman.motion_model] = np.mean(lag[5:])
    assert kalman.turn_rate(kf)[0] == pytest.approx(w, abs=0.3)
    assert err["ct"] < 0.6 * err["cv"]


def test_doppler_turn_row_explains_a_turning_hulls_velocity_profile() -> None:
    """A hull turning at omega reads v + M omega in its profile fit; with the row for omega that is no contradiction."""
    kf = kalman.new_filter(np.array([20.0, 0.0]), np.ones(2), 20.0, None, CT)
    kf.x[kalman.VEL, 0] = [0.0, 3.0]
    kf.x[kalman.TURN, 0] = 1.2
    kf.P[kalman.VEL, kalman.VEL] = np.eye(2) * 0.01
    kf.P[kalman.TURN, kalman.TURN] = 0.01
    gain = np.array([2.0, 0.0])  # returns 2 m across the line of sight from the centre: 2.4 m/s more radial
    v = radial(2.4, np.array([1.0, 0.0]))
    assert kalman.doppler_consistent(kf, v, 20.0, CT, gain)
    assert not kalman.doppler_consistent(kf, v, 20.0, CT)  # read as the centre's velocity it contradicts the track


def test_filters_updated_in_one_stack_end_as_each_updated_alone() -> None:
    """fused_update_many groups the filters by measurement size (with and without a Doppler row, a manoeuvre
    opening one up): every filter ends bit for bit where its own update takes it."""
    jump = np.array([26.0, 1.0])  # 6 m off a settled track: the manoeuvre rule fires
    cases = [
        (np.array([20.2, 0.1]), None, None),
        (np.array([20.1, -0.1]), radial(0.4, np.array([1.0, 0.0])), np.array([2.0, 0.0])),
        (jump, radial(0.3, np.array([1.0, 0.2])), None),
        (np.array([19.9, 0.0]), radial(-0.2, np.array([1.0, -0.3])), np.array([0.5, 1.0])),
    ]
    alone, stacked = [settled(CT) for _ in cases], [settled(CT) for _ in cases]
    for kf, (centre, vel, gain) in zip(alone, cases, strict=True):
        kalman.fused_update(kf, centre, np.array([3.0, 1.5]), 20.0, vel, CT, gain, position_var_extra=0.2)
    kalman.fused_update_many(
        stacked,
        [kalman.Measurement(c, np.array([3.0, 1.5]), 20.0, v, g, 0.2) for c, v, g in cases],
        CT,
    )
    for a, b in zip(alone, stacked, strict=True):
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.P, b.P)
    assert {
        len(kalman._measurement_rows(settled(CT), kalman.Measurement(c, np.ones(2), 20.0, v), CT)[1])
        for c, v, _ in cases
    } == {4, 6}
    assert alone[2].x[kalman.VEL, 0][0] > 1.0  # the manoeuvre opened the jump's velocity up
