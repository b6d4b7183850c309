"""The coverage behind "clear" is judged from the body origin, where the array's bins start, for sensors mounted
elsewhere on the deck: the LiDAR's beam bands move along each bearing with the mount, and the radar's field of view
is drawn from the radar, beginning at its detector's nearest range."""

from __future__ import annotations

import math

import numpy as np
import pytest

from daemon.config import Config
from daemon.runner import pipeline_for
from drivers.frames import RadarFrame
from tests.sea_geometry import SteadyEgo, revolution_over_water, scan_of
from tracker.lidar.coverage import SUB_BEARINGS, bin_bearings
from tracker.obstacle_map import UNKNOWN
from tracker.pipeline import _fov_entry, bands_in_body


def _judged(deg: float) -> int:
    return int(np.argmin(np.abs(np.angle(np.exp(1j * (bin_bearings() - math.radians(deg)))))))


def test_a_bearings_bands_move_with_the_sensors_place() -> None:
    n = bin_bearings().size
    lo = np.tile([9.5, 28.6, 0.0, 5.0], (n, 1))
    hi = np.tile([16.2, 46.7, -3.0, math.inf], (n, 1))  # the third is empty (start > end)
    body_lo, body_hi = bands_in_body(lo, hi, (2.0, 0.0))  # the sensor 2 m forward of the body origin
    ahead, astern, abeam = _judged(0.0), _judged(180.0), _judged(90.0)
    np.testing.assert_allclose(body_lo[ahead, :2], [11.5, 30.6], atol=1e-9)
    np.testing.assert_allclose(body_hi[ahead, :2], [18.2, 48.7], atol=1e-9)
    np.testing.assert_allclose(body_lo[astern, :2], [7.5, 26.6], atol=1e-9)
    np.testing.assert_allclose(body_hi[astern, :2], [14.2, 44.7], atol=1e-9)
    np.testing.assert_allclose(body_lo[abeam, :2], np.sqrt(np.array([9.5, 28.6]) ** 2 - 4.0), atol=1e-9)
    assert (body_lo[:, 2] == math.inf).all() and (body_hi[:, 2] == -math.inf).all()  # still empty
    assert (body_hi[:, 3] == math.inf).all()
    same_lo, same_hi = bands_in_body(lo, hi, (0.0, 0.0))
    np.testing.assert_array_equal(same_lo, lo)
    np.testing.assert_array_equal(same_hi, hi)


def test_the_field_of_view_drawn_from_the_radar_begins_where_the_ray_crosses_its_edge() -> None:
    bearings = np.radians([57.0, -57.0, 0.0, 30.0])
    entry = _fov_entry(bearings, 0.0, math.radians(120.0), (0.5, 0.0))
    # on the 57 deg ray, R (cos 57, sin 57) is seen from (0.5, 0) at 60 deg when R sin 57 = tan 60 (R cos 57 - 0.5)
    at_edge = (
        0.5
        * math.tan(math.radians(60.0))
        / (math.tan(math.radians(60.0)) * math.cos(math.radians(57.0)) - math.sin(math.radians(57.0)))
    )
    # the 30 deg ray starts behind the radar's beam too: it crosses the 60 deg edge at 0.5 sin 60 / sin 30 (the law of
    # sines in the triangle origin, radar, crossing); the boresight never leaves it
    np.testing.assert_allclose(entry, [at_edge, at_edge, 0.0, 0.5 * math.sqrt(3.0) / 2 / 0.5], atol=1e-9)
    assert at_edge == pytest.approx(8.28, abs=0.01)


def _level(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros(np.shape(t)), np.zeros(np.shape(t))


def test_a_lidar_forward_of_the_origin_does_not_vouch_astern_beyond_its_reach() -> None:
    """A LiDAR 1 m above the water, 2 m forward of the body origin; "clear" asked from 3 m to 15 m. A post 0.5 m tall
    14.6 m astern of the origin is 16.6 m from the sensor, past the band where a beam meets 0.5 m of it above the
    water's margin: its returns are water-low and it is not seen. The bin must not go out clear, as it did when the
    band's sensor ranges were taken for body ranges."""
    outcome = {}
    for forward in (0.0, 2.0):
        config = Config()
        config.lidar.mount.x, config.lidar.mount.z = forward, -1.0
        config.radar.enabled = False
        config.output.clear_inner_m, config.output.max_distance_m = 3.0, 15.0
        pipeline = pipeline_for(config)
        post = (((-14.6, -0.3), (-14.6, 0.3), 0.5),)
        ret = revolution_over_water(config.lidar.mount.to_mount(), _level, yaw=0.0, walls=post)
        out = pipeline.step(0.1, scan_of(ret, 0.1), [], SteadyEgo(_level, 0.0))
        outcome[forward] = (int(out.distances_cm[36]), float(out.clear_to_m[36]), int(out.distances_cm[0]))
    assert outcome[0.0][0] == 1460  # from the origin the post's top is met: an obstacle at 14.6 m
    distance, clear_to, ahead = outcome[2.0]
    assert distance == UNKNOWN and clear_to < 15.0 - 0.5
    # ahead, the inner 3 m from the origin is 1 m from the sensor, under its steepest beam for a 0.5 m solid
    assert ahead == UNKNOWN


def test_the_radar_alone_sends_no_clear_where_its_beam_does_not_reach_near_the_boat() -> None:
    """The shipped radar (0.5 m forward of the origin, +-60 deg), the LiDAR off, clear asked out to 15 m: a body point
    1.2 m off at 57 deg lies at 81 deg from the radar, outside its beam; the bin was sent clear."""
    config = Config()
    config.lidar.enabled = False
    config.output.max_distance_m = 15.0
    pipeline = pipeline_for(config)
    assert pipeline.settings.radar_offset_fwd_stbd_m == (config.radar.mount.x, config.radar.mount.y) == (0.5, 0.0)
    assert pipeline.settings.radar_min_range_m == 1.0
    frame = RadarFrame(1.0, 1, np.array([[40.0, 0.0, 0.0]]), np.zeros(1), np.full(1, 20.0), np.full(1, 5.0))
    out = pipeline.step(1.0, None, [frame], None)
    assert (out.clear_to_m[9:14] < 15.0).all()
    assert (out.distances_cm[9:14] == UNKNOWN).all()
    assert SUB_BEARINGS.size == 3
