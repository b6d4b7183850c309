"""The water-surface estimate: found from water returns, never from hulls or a quay, forgotten when stale."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracker.lidar.config import WaterConfig
from tracker.lidar.water import WaterSurface


def ring_of_water(rng: np.random.Generator, n: int, offset: float, amplitude: float) -> tuple[np.ndarray, ...]:
    """Water returns 6-30 m out on a tilted plane, with three wave trains whose crests sum to ``amplitude``."""
    bearing = rng.uniform(-math.pi, math.pi, n)
    r = rng.uniform(6.0, 30.0, n)
    x, y = r * np.cos(bearing), r * np.sin(bearing)
    waves = 0.5 * np.sin(0.6 * x + 0.3 * y) + 0.33 * np.sin(-0.4 * x + 0.9 * y + 1.0) + 0.17 * np.sin(1.7 * x + 2.1)
    h = offset + 0.01 * x - 0.005 * y + amplitude * waves
    return x, y, h


def test_plane_offset_tilt_and_margin_from_water_returns() -> None:
    rng = np.random.default_rng(1)
    x, y, h = ring_of_water(rng, 4000, offset=-0.2, amplitude=0.25)
    est = WaterSurface().update(x, y, h, t=5.0)
    assert est.measured and est.t == 5.0
    assert est.offset == pytest.approx(-0.2, abs=0.03)
    assert est.slope_x == pytest.approx(0.01, abs=0.003) and est.slope_y == pytest.approx(-0.005, abs=0.003)
    # crests of 0.25 m: the margin covers them and the 5 cm pad, by at most 3 robust sigmas of the sea (0.11 m)
    assert 0.30 <= est.margin <= 0.42
    assert est.spread == pytest.approx(0.11, abs=0.02)


def test_a_quay_and_hulls_are_not_taken_for_water() -> None:
    rng = np.random.default_rng(2)
    surface = WaterSurface()
    # A quay face along 40 m at 20 m to starboard: 3000 returns from 0 to 1 m, in 4 sectors of 10 deg.
    x = rng.uniform(-5.0, 5.0, 3000)
    quay = (x, np.full(3000, 20.0), rng.uniform(0.0, 1.0, 3000))
    assert not surface.update(*quay, t=1.0).measured
    # Hull sides all round at 15 m, 0-1.3 m high: many sectors, but spread over a metre, not a thin layer.
    b = rng.uniform(-math.pi, math.pi, 3000)
    hulls = (15.0 * np.cos(b), 15.0 * np.sin(b), rng.uniform(0.0, 1.3, 3000))
    assert not surface.update(*hulls, t=1.1).measured
    assert surface.refused == 1 and surface.accepted == 0
    assert surface.current(1.1).margin == WaterConfig().margin_floor


def test_an_estimate_holds_for_its_memory_then_the_waterline_returns() -> None:
    rng = np.random.default_rng(3)
    surface = WaterSurface(WaterConfig(memory_s=2.0))
    x, y, h = ring_of_water(rng, 3000, offset=0.3, amplitude=0.1)
    surface.update(x, y, h, t=10.0)
    empty = np.zeros(0)
    assert surface.update(empty, empty, empty, t=11.9).offset == pytest.approx(0.3, abs=0.03)
    after = surface.update(empty, empty, empty, t=12.1)
    assert not after.measured and after.offset == 0.0 and after.margin == 0.15


def test_the_floor_is_not_raised_beyond_the_water_the_fit_saw() -> None:
    """A tilt measured on water 6-30 m out is not carried on to 63 m where it would rise: there a 0.5 m hull, met
    by the -1 deg beam, stood under the plane plus the sea margin and its bin was reported clear."""
    rng = np.random.default_rng(4)
    bearing = rng.uniform(-math.pi, math.pi, 4000)
    r = rng.uniform(6.0, 30.0, 4000)
    x, y = r * np.cos(bearing), r * np.sin(bearing)
    h = 0.05 + 0.007 * x + 0.03 * np.sin(1.3 * x + 0.7 * y)  # 0.4 deg up towards the bow, a 3 cm chop
    est = WaterSurface().update(x, y, h, t=1.0)
    assert est.measured and est.slope_x == pytest.approx(0.007, abs=0.001)
    # uniform in range over 6-30 m: 95 % of the water lies within 28.8 m
    assert est.reach == pytest.approx(28.8, abs=0.5)
    ahead, astern = np.array([63.0, -63.0]), np.zeros(2)
    floor = est.floor(ahead, astern)
    plane = est.surface(ahead, astern)
    # ahead the plane rises to 0.49 m; the floor stays where the fit's water ended (0.25 m)
    assert plane[0] == pytest.approx(0.05 + 0.007 * 63, abs=0.07)
    assert floor[0] == pytest.approx(est.surface(np.array([est.reach]), np.zeros(1))[0], abs=1e-9)
    assert floor[0] < plane[0] - 0.2
    # astern it falls: followed, since a lower floor only keeps more returns solid
    assert floor[1] == pytest.approx(plane[1], abs=1e-12)
    hull_top = 0.05 + 0.5  # above the level water at the boat
    assert hull_top - floor[0] > est.margin > hull_top - plane[0]
    # within the reach the floor is the plane
    near = np.array([10.0, -3.0]), np.array([4.0, 20.0])
    assert np.allclose(est.floor(*near), est.surface(*near))


def test_the_fits_quantile_is_numpys_to_the_bit() -> None:
    """The water fit's crest and reach quantiles (water._quantile) are np.quantile's linear interpolation exactly,
    at the fit's sizes and the quantiles it takes, ties and the ends included."""
    from tracker.lidar.water import _quantile

    rng = np.random.default_rng(7)
    for n in (1, 2, 3, 10, 99, 2500):
        for q in (0.0, 0.05, 0.5, 0.95, 0.995, 1.0):
            values = np.abs(rng.normal(0.0, 0.2, n))
            assert _quantile(values.copy(), q) == float(np.quantile(values, q))
            rounded = np.round(values, 2)  # ties
            assert _quantile(rounded.copy(), q) == float(np.quantile(rounded, q))
