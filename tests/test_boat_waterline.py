"""The waterline's body z (``[boat] water_z_m``, down positive) places the water under the LiDAR.

The same boat described with its body origin on the waterline or 0.3 m above it (the sensors' mount z shifted with
it, as a crew measuring from an autopilot's origin at the IMU would) must see the same water and the same hulls.
"""

from __future__ import annotations

import numpy as np
import pytest

from daemon.config import Config, load_config
from daemon.runner import pipeline_for
from daemon.tracker_adapters import tracker_factories
from tracker.lidar.coverage import BeamGeometry, reach_from
from tracker.lidar.preprocess import preprocess
from tracker.lidar.water import WaterEstimate
from tracker.pipeline import lidar_bands

LIDAR_ABOVE_WATER_M = 1.6
RADAR_ABOVE_WATER_M = 0.9


def boat(origin_above_water_m: float) -> Config:
    """The one physical boat, its body origin ``origin_above_water_m`` above the waterline."""
    return load_config(
        None,
        {
            "boat.water_z_m": origin_above_water_m,
            "lidar.mount.z": -(LIDAR_ABOVE_WATER_M - origin_above_water_m),
            "radar.mount.z": -(RADAR_ABOVE_WATER_M - origin_above_water_m),
        },
    )


@pytest.mark.parametrize("origin_above_water_m", [0.0, 0.3, -0.2])
def test_heights_above_the_water_follow_the_waterline(origin_above_water_m: float) -> None:
    config = boat(origin_above_water_m)
    settings = pipeline_for(config).settings
    assert settings.lidar_origin_height_above_water_m == pytest.approx(origin_above_water_m, abs=1e-12)
    assert settings.radar_height_m == pytest.approx(RADAR_ABOVE_WATER_M, abs=1e-12)
    assert tracker_factories(config)[2].origin_height_above_water == pytest.approx(origin_above_water_m, abs=1e-12)
    # the sensor over a calm, level sea: 1.6 m whatever the origin
    beams = BeamGeometry.at_bins(np.zeros(72), np.zeros(72), settings.lidar_mount)
    _, height = beams.over_surface(WaterEstimate(), settings.lidar_origin_height_above_water_m)
    np.testing.assert_allclose(height, LIDAR_ABOVE_WATER_M, atol=1e-9)


def test_the_same_boat_keeps_the_same_hull_returns_and_vouches_the_same_ranges() -> None:
    kept, reach = [], []
    heights = np.linspace(0.1, 1.0, 10)  # a hull face 15 m ahead, returns 0.1 .. 1.0 m above the water
    for origin in (0.0, 0.3):
        config = boat(origin)
        cfg = tracker_factories(config)[2]
        xyz = np.column_stack([np.full(10, 15.0), np.linspace(-0.5, 0.5, 10), origin - heights])
        out = preprocess(xyz, np.zeros(3), 0.0, 0.0, 0.0, cfg)
        kept.append(np.sort(origin - out.points_world[:, 2]).round(6).tolist())  # world z = body z, level boat
        settings = pipeline_for(config).settings
        beams = BeamGeometry.at_bins(np.zeros(72), np.zeros(72), settings.lidar_mount)
        lo, hi = lidar_bands(beams, np.ones(72, bool), WaterEstimate(margin=0.2), settings)
        reach.append(reach_from(lo, hi, 2.0, 100.0))
    assert kept[0] == kept[1]
    # Returns 0.15 m (the configured margin) and more above the water are solid, lower ones water.
    assert kept[0] == pytest.approx(heights[heights >= 0.15 - 1e-9].tolist(), abs=1e-6)
    np.testing.assert_allclose(reach[0], reach[1], atol=1e-9)
    # A VLP-16 1.6 m up cannot vouch from 2 m: its lowest beam is still 1.06 m up there (coverage.py).
    assert float(reach[0].max()) == 0.0
