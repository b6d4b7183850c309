"""Coverage: how far out each bearing is vouched for, from the VLP-16's beams, the mount, the attitude and the sea;
and the low, sparse, grazing returns of real solids reaching the bins."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from daemon.runner import pipeline_for
from drivers.mount import Mount
from tests.sea_geometry import (
    RAIN,
    SteadyEgo,
    clear_to_11_m_config,
    lidar_pipeline,
    revolution_over_water,
    scan_of,
    wall_ring,
)
from tracker.lidar.coverage import (
    band_intervals,
    bands_turned,
    beam_elevations_level,
    bin_bearings,
    reach_from,
    swept_bins,
)
from tracker.obstacle_map import UNKNOWN

MOUNT = Mount(z=-1.6)


def vouched_range(
    elevation: np.ndarray,
    sensor_height: np.ndarray,
    margin: float,
    obstacle_height: float,
    inner: float,
    max_range: float,
) -> np.ndarray:
    """(B,) range out to which a solid ``obstacle_height`` tall would have been returned, per bearing: how the
    coverage model chains the beams' bands from ``inner`` outward."""
    lo, hi = band_intervals(elevation, sensor_height, margin, obstacle_height, max_range)
    return reach_from(lo, hi, inner, max_range)


def level_elevations(n: int = 1) -> tuple[np.ndarray, np.ndarray]:
    return beam_elevations_level(np.zeros(n), np.zeros(n), np.zeros(n), MOUNT)


def test_the_beams_bands_for_a_half_metre_solid_from_1_6_m() -> None:
    el, up = level_elevations()
    assert up[0] == pytest.approx(1.6)
    lo, hi = band_intervals(el, up, margin=0.15, obstacle_height=0.5, max_range=100.0)
    deg = np.round(np.degrees(el[0])).astype(int)
    band = {int(d): (float(a), float(b)) for d, a, b in zip(deg, lo[0], hi[0], strict=True)}
    # beam at -e deg: between (1.6 - 0.5) / tan e and (1.6 - 0.15) / tan e
    for e in (1, 3, 5, 7, 15):
        t = math.tan(math.radians(e))
        assert band[-e] == pytest.approx((1.1 / t, 1.45 / t), abs=1e-6)
    # the -3 deg beam leaves the band at 27.7 m and the -1 deg beam enters it at 63.0 m: the blind 30-63 m
    assert band[-3][1] == pytest.approx(27.67, abs=0.01) and band[-1][0] == pytest.approx(63.02, abs=0.01)
    assert band[1][0] > band[1][1]  # upward beams never come down to a 0.5 m solid


def test_vouched_only_without_a_gap_from_the_inner_edge() -> None:
    el, up = level_elevations()
    # below 4.1 m the lowest beam passes over a 0.5 m solid: nothing is vouched from 0.5 m
    assert vouched_range(el, up, 0.15, 0.5, inner=0.5, max_range=100.0)[0] == 0.0
    # from 4.2 m the -15 .. -7 deg bands overlap up to 11.81 m, where the -7 and -5 deg bands leave a gap
    assert vouched_range(el, up, 0.15, 0.5, inner=4.2, max_range=100.0)[0] == pytest.approx(
        1.45 / math.tan(math.radians(7))
    )
    # a sea margin of 0.5 m leaves no band at all
    assert vouched_range(el, up, 0.5, 0.5, inner=4.2, max_range=100.0)[0] == 0.0


def test_roll_tilts_the_bands_bearing_by_bearing() -> None:
    bearings = np.radians([0.0, 90.0, 270.0])
    roll = np.full(3, math.radians(5.0))  # rolled to starboard: the starboard beams dip 5 deg, the port ones rise
    el, up = beam_elevations_level(bearings, roll, np.zeros(3), MOUNT)
    np.testing.assert_allclose(
        np.degrees(el[1]),
        np.degrees(np.radians([-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15])) - 5.0,
        atol=0.02,
    )
    np.testing.assert_allclose(np.degrees(el[2]) - np.degrees(el[1]), 10.0, atol=0.05)
    v = vouched_range(el, up, 0.15, 0.5, inner=4.2, max_range=100.0)
    # to starboard every beam dips 5 deg: the chain of bands from 4.2 m runs down the beams to the -3 deg one (at
    # -8 deg), which leaves the band at (1.6 cos 5 deg - 0.15) / tan 8 deg before the -1 deg one (at -6) enters it
    assert v[1] == pytest.approx((1.6 * math.cos(math.radians(5)) - 0.15) / math.tan(math.radians(8)), rel=0.005)
    assert v[2] == 0.0  # to port the lowest beam is at -10 deg: over a 0.5 m solid until 6.2 m


def test_a_lost_packet_leaves_its_bins_unswept() -> None:
    step = math.radians(360.0 / 75.4)  # 600 rpm: a packet sweeps 4.77 deg
    starts = np.arange(76) * step
    sweeps = np.stack([starts, np.full(76, step)], axis=1)
    assert swept_bins(sweeps, Mount()).all()
    lost = np.delete(sweeps, 10, axis=0)  # the packet from 47.7 to 52.5 deg
    swept = swept_bins(lost, Mount())
    assert np.flatnonzero(~swept).tolist() == [10]  # bin 10 spans 47.5-52.5 deg


def test_an_upside_down_lidar_sweeps_and_fires_the_other_way_round() -> None:
    # Hung under an arch (roll 180 deg), the sensor's azimuth 50 deg points 50 deg to port: the lost packet's bin
    # is bin 62 (-50 deg), and the beams judged toward a bearing fire along it. Before, both used the sensor's
    # azimuth as the bearing (bin 10, and beams toward -b).
    mount = Mount.from_degrees(z=-1.6, roll=180.0)
    step = math.radians(360.0 / 75.4)
    sweeps = np.stack([np.arange(76) * step, np.full(76, step)], axis=1)
    assert np.flatnonzero(~swept_bins(np.delete(sweeps, 10, axis=0), mount)).tolist() == [62]
    bearings = np.radians([0.0, 30.0, -85.0, 170.0])
    _, origin_up = beam_elevations_level(bearings, np.zeros(4), np.zeros(4), mount)
    np.testing.assert_allclose(origin_up, 1.6, atol=1e-12)
    from tracker.lidar.coverage import _beam_directions_body

    d = _beam_directions_body(np.ascontiguousarray(bearings).tobytes(), mount)
    fired = np.arctan2(d[..., 1], d[..., 0])
    np.testing.assert_allclose(np.angle(np.exp(1j * (fired - bearings[:, None]))), 0.0, atol=1e-9)


def _one_revolution(walls, pitch_deg: float = 0.0, rain: tuple[int, float, int] | None = None):
    pitch = math.radians(pitch_deg)

    def attitude(t):
        return np.zeros(np.shape(t)), np.full(np.shape(t), pitch)

    pipeline = lidar_pipeline(MOUNT)
    ret = revolution_over_water(MOUNT, attitude, yaw=0.0, walls=walls, water_returns=False, rain=rain)
    out = pipeline.step(0.1, scan_of(ret, 0.1, intensity=30.0), [], SteadyEgo(attitude, 0.0))
    return out, ret, pipeline


def test_a_quay_at_80_m_seen_only_by_the_lowest_beam_at_grazing_incidence_is_an_obstacle() -> None:
    # A quay 1 m high across the bow at 80 m: only the -1 deg beam meets it, 0.2 m above the water ahead and down to
    # the water itself at 92 m (30 deg off the bow): inside the 0.15 m sea margin from 83 m out, but a line of
    # returns at 1 deg of grazing, which calm water does not give.
    out, ret, pipeline = _one_revolution((((80.0, -50.0), (80.0, 50.0), 1.0),))
    assert set(np.unique(ret.ring[ret.wall >= 0]).tolist()) == {7}  # ring 7 = the -1 deg beam
    assert pipeline.last_preprocess.n_grazing > 100
    d = out.distances_cm
    bins = np.r_[66:72, 0:7]  # bearings within 32.5 deg of the bow: where the beam meets the quay before the water
    for j in bins:
        off = abs(5.0 * (j if j < 36 else j - 72))
        expect = 80.0 / math.cos(math.radians(max(off - 2.5, 0.0)))  # the bin's nearest edge
        assert abs(int(d[j]) - expect * 100) <= 0.01 * expect * 100 + 30, (j, int(d[j]), expect)
    others = np.setdiff1d(np.arange(72), bins)
    assert np.all(d[others] == UNKNOWN)  # nothing returned and nothing vouched


def test_rain_over_a_glassy_sea_does_not_hide_a_quay_seen_at_grazing_incidence() -> None:
    # The quay above with 1,500 drops a revolution within 12 m. The drops are alone in the range image, not water:
    # counted as water returns they made the glassy sea look rough, and the quay's foot in the sea margin was lost.
    out, ret, pipeline = _one_revolution((((80.0, -50.0), (80.0, 50.0), 1.0),), rain=(1500, 12.0, 5))
    drops = ret.wall == RAIN
    assert 1400 <= np.count_nonzero(drops) <= 1500  # a few firings would have met nothing before their drop anyway
    pre = pipeline.last_preprocess
    assert not pre.water.measured and pre.n_grazing > 100
    assert pre.n_isolated >= 0.9 * np.count_nonzero(drops)
    d = out.distances_cm
    for j in np.r_[69:72, 0:4]:  # within 17.5 deg of the bow
        off = abs(5.0 * (j if j < 36 else j - 72))
        expect = 80.0 / math.cos(math.radians(max(off - 2.5, 0.0)))
        assert abs(int(d[j]) - expect * 100) <= 0.01 * expect * 100 + 30, (j, int(d[j]), expect)


def test_a_low_hull_at_50_m_caught_by_one_beam_is_an_obstacle() -> None:
    # A 0.5 m hull 50 m ahead, 4 m wide; the bow pitched 0.5 deg down puts the -1 deg beam at 0.29 m on its side.
    out, ret, pipeline = _one_revolution((((50.0, -2.0), (50.0, 2.0), 0.5),), pitch_deg=-0.5)
    assert 5 <= np.count_nonzero(ret.wall >= 0) <= 30  # a sparse line of returns from one beam
    assert pipeline.last_preprocess.n_isolated == 0
    d = out.distances_cm
    assert abs(int(d[0]) - 5000) <= 30, int(d[0])


def test_a_low_wall_met_by_one_beam_at_grazing_incidence_is_an_obstacle_though_its_returns_are_alone() -> None:
    # A wall 1 m high along the bow's line 5 m to starboard, 50-80 m ahead: only the -1 deg beam meets it, at 3.6-5.7
    # deg of grazing, so its range steps 1.5-3.5 m between firings and no return has a neighbour at its range (the
    # rain rule's test); three firings in a row on a straight line are a face, not drops. It goes to the obstacle
    # array (not to the tracker), in bin 1 (2.5-7.5 deg) at the nearest firing that met it.
    out, ret, pipeline = _one_revolution((((50.0, 5.0), (80.0, 5.0), 1.0),))
    on_wall = ret.wall >= 0
    assert set(np.unique(ret.ring[on_wall]).tolist()) == {7} and np.count_nonzero(on_wall) >= 10
    pre = pipeline.last_preprocess
    assert pre.n_isolated >= 0.8 * np.count_nonzero(on_wall)  # alone in the range image, as drops are
    assert pre.points_world.shape[0] == 0  # nothing of it reaches the tracker
    nearest = np.hypot(*ret.xyz_body[on_wall, :2].T).min()
    assert 50.0 <= nearest <= 52.0  # the first firing past the wall's end
    d = out.distances_cm
    assert abs(int(d[1]) - nearest * 100) <= 5, (int(d[1]), nearest)
    assert np.all(d[np.r_[0, 2:72]] > 10000)  # clear or unknown elsewhere: nothing else returned


def test_bands_turned_with_the_boat_carry_no_coverage_into_a_bearing_that_had_none() -> None:
    # Measured: 10-40 m vouched on the bearings 0..30 deg (bins 0-6 less bin 0's -2 deg), nothing elsewhere. The boat
    # has since turned 3 deg to starboard: its bearing b looked along b + 3 deg, so -3..27 deg is vouched now. A
    # bearing between two judged ones takes what both vouched for: 27 deg (30 - 3, judged) keeps 10-40 m, 28 deg
    # (31 deg between 30 and 32, the latter not vouched) has nothing.
    deg = np.degrees(np.mod(bin_bearings() + np.pi, 2 * np.pi) - np.pi)
    inside = (deg >= -1e-9) & (deg <= 30 + 1e-9)
    lo = np.where(inside, 10.0, np.inf)[:, None]
    hi = np.where(inside, 40.0, -np.inf)[:, None]
    turned_lo, turned_hi = bands_turned(lo, hi, math.radians(3.0))
    now = {round(float(d)): (float(a), float(b)) for d, a, b in zip(deg, turned_lo[:, 0], turned_hi[:, 0], strict=True)}
    assert now[27] == (10.0, 40.0) and now[0] == (10.0, 40.0)
    assert now[28] == (np.inf, -np.inf) and now[-2] == (10.0, 40.0)
    assert now[-3] == (10.0, 40.0)  # it looked along 0 deg
    assert now[30] == (np.inf, -np.inf) and now[-5] == (np.inf, -np.inf)
    # not turned: as measured, to the bit
    same_lo, same_hi = bands_turned(lo, hi, 0.0)
    assert np.array_equal(same_lo, lo) and np.array_equal(same_hi, hi)


def test_a_bearing_that_returned_nothing_is_not_vouched_for_by_points_without_a_position() -> None:
    """Walls 30 m off all round but ahead (340-20 deg), a calm sea: the bins ahead returned nothing, so they vouch
    for nothing and go out unknown. A revolution also carrying returns without a finite position (a decoder's NaN)
    once counted those in bin 0 (a NaN bearing rounds to bin 0), which then counted as having returned something,
    and was sent "clear"."""
    config = clear_to_11_m_config(MOUNT)
    walls = wall_ring(20.0, 341.0, 5.0)

    def level(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(np.shape(t)), np.zeros(np.shape(t))

    ret = revolution_over_water(MOUNT, level, yaw=0.0, walls=walls, water_returns=False)
    scan = scan_of(ret, 0.1)
    nan = np.full((5, 3), np.nan)
    with_nan = dataclasses.replace(
        scan,
        xyz=np.r_[scan.xyz, nan],
        intensity=np.r_[scan.intensity, np.full(5, 4.0, np.float32)],
        ring=np.r_[scan.ring, np.full(5, 3, np.uint8)],
        t=np.r_[scan.t, np.full(5, scan.t[-1])],
    )
    for s in (scan, with_nan):
        out = pipeline_for(config).step(0.1, s, [], SteadyEgo(level, 0.0))
        ahead = [70, 71, 0, 1, 2]
        assert out.clear_to_m[ahead].tolist() == [0.0] * 5
        assert out.distances_cm[ahead].tolist() == [UNKNOWN] * 5
        assert np.all(out.distances_cm[10:60] == 1101)  # the walls are beyond 11 m: clear where the beams looked
