"""The adaptive EKF bank: motion model, eq. 10-12 noise, heading aliases, convergence on a constant turn."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracker.lidar.config import EkfConfig
from tracker.lidar.ekf import (
    LEN,
    OMEGA,
    PSI,
    VE,
    VN,
    WID,
    EkfBank,
    Measurement,
    measurement_noises,
    visibility,
    wrap_angle,
)
from tracker.types import ShapeKind

CFG = EkfConfig()
R_FULL = np.diag(np.square(CFG.r_full_std))  # eq. 12


def test_eq12_full_visibility_noise_and_eq11_inflation() -> None:
    assert np.sqrt(np.diag(R_FULL)) == pytest.approx([0.1, 0.1, 0.05, 0.5, 0.5, 0.5])
    p = np.array([1.0, 1.0, 0.5, 0.5, 0.0, 1.0])
    diag = measurement_noises(p[None], CFG)[0]
    assert np.diag(diag - R_FULL) == pytest.approx(CFG.r_inflation * np.array([0, 0, 0.25, 0.25, 1.0, 0]))
    assert diag - np.diag(np.diag(diag)) == pytest.approx(np.zeros((6, 6)))
    outer = measurement_noises(p[None], EkfConfig(inflation_form="outer"))[0]
    assert outer - R_FULL == pytest.approx(CFG.r_inflation * np.outer(1 - p, 1 - p))
    assert measurement_noises(p[None], EkfConfig(adaptive_r=False))[0] == pytest.approx(R_FULL)


@pytest.mark.parametrize(
    "config", [CFG, EkfConfig(inflation_form="outer"), EkfConfig(adaptive_r=False)], ids=["diag", "outer", "fixed"]
)
def test_stacked_noise_is_each_rows_own(config: EkfConfig) -> None:
    """A measurement's R does not depend on the others stacked with it (eq. 11 row by row, to the bit)."""
    p = np.random.default_rng(0).uniform(-0.2, 1.2, (50, 6))
    stacked = measurement_noises(p, config)
    for k in (0, 17, 49):
        assert stacked[k].tobytes() == measurement_noises(p[k : k + 1], config)[0].tobytes()


def test_eq10_visibility_falls_with_range_mse_and_end_on_views() -> None:
    good = visibility(5.0, 0.0, math.radians(45.0), CFG)
    assert np.all(good > 0.98)
    far = visibility(80.0, 0.0, math.radians(45.0), CFG)
    assert far[0] == pytest.approx(1.0 / (1.0 + 4.0))  # 80 m = 2 x the 40 m half range
    assert np.all(far < good)
    bad_fit = visibility(5.0, 0.2, math.radians(45.0), CFG)
    assert np.all(bad_fit[:5] < good[:5])
    assert bad_fit[5] == pytest.approx(good[5])  # height comes from the z extent, not from the 2-D fit
    end_on = visibility(5.0, 0.0, 0.0, CFG)
    broadside = visibility(5.0, 0.0, math.radians(90.0), CFG)
    for v in (end_on, broadside):
        assert v[3:5] == pytest.approx(np.full(2, CFG.visibility_aspect_floor * good[5]))  # length, width
        assert v[0] == pytest.approx(0.5 * (1.0 + CFG.visibility_aspect_floor) * good[5])  # centre: half
        assert v[[2, 5]] == pytest.approx(good[[2, 5]])  # a visible side still gives the heading; height as ever
    occluded = visibility(5.0, 0.0, math.radians(45.0), EkfConfig(occluded_visibility=0.1), occluded=True)
    assert occluded == pytest.approx(good * np.array([0.1, 0.1, 1.0, 0.1, 0.1, 1.0]))


def box(
    center: tuple[float, float], heading: float, length: float, width: float, kind: ShapeKind = ShapeKind.BOX
) -> Measurement:
    return Measurement(np.array(center, float), heading, length, width, 2.0, kind, R_FULL)


def test_quarter_turn_alias_keeps_the_heading() -> None:
    bank = EkfBank(CFG)
    bank.add(box((0.0, 0.0), math.radians(10.0), 8.0, 3.0))
    # Only the stern is visible: the fitter reports a 3 m side at 100 deg, which is the same box turned 90 deg.
    chosen = bank.choose_aliases([(0, box((0.0, 0.0), math.radians(100.0), 3.0, 0.1))], [(True, True)])[0]
    assert chosen.heading == pytest.approx(math.radians(10.0))
    assert (chosen.length, chosen.width) == (0.1, 3.0)
    # And 180 deg: a box fit in [0, pi) near 190 deg is reported as 10 deg; the track near 190 keeps 190.
    bank.filters[0].x[PSI] = wrap_angle(math.radians(190.0))
    chosen = bank.choose_aliases([(0, box((0.0, 0.0), math.radians(12.0), 8.0, 3.0))], [(True, True)])[0]
    assert wrap_angle(chosen.heading - math.radians(192.0)) == pytest.approx(0.0, abs=1e-12)


def test_ellipse_alias_uses_size_when_heading_is_uncertain() -> None:
    bank = EkfBank(CFG)
    bank.add(box((0.0, 0.0), math.radians(30.0), 8.0, 3.0, ShapeKind.ELLIPSE))
    bank.filters[0].P[PSI, PSI] = math.pi**2  # heading unknown: size decides
    chosen = bank.choose_aliases(
        [(0, box((0.0, 0.0), math.radians(120.0), 3.0, 8.0, ShapeKind.ELLIPSE))], [(True, True)]
    )[0]
    assert (chosen.length, chosen.width) == (8.0, 3.0)


def test_update_never_turns_the_heading_across_an_alias() -> None:
    bank = EkfBank(CFG)
    bank.add(box((0.0, 0.0), math.radians(5.0), 8.0, 3.0))
    for k in range(1, 20):
        bank.predict(0.1)
        # Alternating views: the L (heading 5 deg) and the stern only (a 3 m side across the hull).
        m = box((0.0, 0.0), math.radians(5.0), 8.0, 3.0) if k % 2 else box((0.0, 0.0), math.radians(95.0), 3.0, 0.2)
        bank.update(0, m)
        x = bank.filters[0].x
        assert abs(math.degrees(wrap_angle(x[PSI] - math.radians(5.0)))) < 1.0
        assert x[LEN] > x[WID]


def test_converges_on_a_constant_turn() -> None:
    """3 m/s, 0.1 rad/s clockwise for 30 s (heading sweeps 172 deg), measurements at 10 Hz with eq. 12 noise."""
    rng = np.random.default_rng(0)
    bank = EkfBank(CFG)
    speed, omega, dt = 3.0, 0.1, 0.1
    errors = []
    for k in range(300):
        t = k * dt
        pos = np.array([speed / omega * math.sin(omega * t), speed / omega * (1.0 - math.cos(omega * t))])
        heading = omega * t
        # The fitted shape only knows its heading modulo pi.
        m = Measurement(
            pos + rng.normal(0.0, 0.1, 2),
            (heading + rng.normal(0.0, 0.05)) % math.pi,
            8.0 + rng.normal(0.0, 0.5),
            3.0 + rng.normal(0.0, 0.5),
            2.0 + rng.normal(0.0, 0.5),
            ShapeKind.BOX,
            R_FULL,
        )
        if k == 0:
            bank.add(m)
            continue
        bank.predict(dt)
        bank.update(0, m)
        x = bank.filters[0].x
        vel = speed * np.array([math.cos(heading), math.sin(heading)])
        errors.append(
            (
                t,
                np.hypot(*(x[:2] - pos)),
                np.hypot(*(x[[VN, VE]] - vel)),
                x[OMEGA] - omega,
                wrap_angle(x[PSI] - heading),
            )
        )
    e = np.array(errors)
    late = e[e[:, 0] > 10.0]  # after convergence
    assert np.sqrt(np.mean(late[:, 1] ** 2)) < 0.1  # m, RMS: better than the 0.1 m per-scan noise
    assert late[:, 1].max() < 0.25  # m
    assert late[:, 2].max() < 0.35  # m/s
    assert np.abs(late[:, 3]).max() < 0.06  # rad/s
    assert np.degrees(np.abs(late[:, 4])).max() < 5.0  # full-circle heading: no 180 deg flip either


def test_heading_aligned_once_with_the_course() -> None:
    bank = EkfBank(CFG)
    for k in range(40):  # moving south at 2 m/s, the box fit says heading 0 (its [0, pi) convention)
        m = box((-0.2 * k, 0.0), 0.0, 6.0, 2.0)
        if k == 0:
            bank.add(m)
        else:
            bank.predict(0.1)
            bank.update(0, m)
    x = bank.filters[0].x
    assert bank.aligned == [True]
    assert abs(wrap_angle(x[PSI] - math.pi)) < math.radians(2.0)
    assert x[VN] == pytest.approx(-2.0, abs=0.1)


def test_point_measurement_updates_position_only() -> None:
    bank = EkfBank(CFG)
    bank.add(box((0.0, 0.0), 0.5, 6.0, 2.0))
    before = bank.filters[0].x.copy()
    bank.predict(0.1)
    bank.update(0, box((0.3, 0.0), 2.0, 0.0, 0.0, ShapeKind.POINT))
    after = bank.filters[0].x
    assert after[0] > before[0] + 0.1
    assert after[[PSI, LEN, WID]] == pytest.approx(before[[PSI, LEN, WID]])


def test_predict_batches_and_removes() -> None:
    bank = EkfBank(CFG)
    for k in range(3):
        bank.add(box((10.0 * k, 0.0), 0.0, 5.0, 2.0))
    bank.filters[1].x[[VN, VE]] = [1.0, 2.0]
    bank.predict(0.5)
    assert bank.states()[:, :2] == pytest.approx(np.array([[0.0, 0.0], [10.5, 1.0], [20.0, 0.0]]))
    bank.remove([0, 2])
    assert len(bank) == 1 and bank.states()[0, 0] == pytest.approx(10.5)
    bank.predict(0.0)  # no time passed: nothing changes
    bank.predict(-1.0)
    assert bank.states()[0, 0] == pytest.approx(10.5)
