"""AIS_VESSEL fields from a track: units, validity flags and the made-up MMSI."""

from __future__ import annotations

import math

import numpy as np

from daemon.ais import MMSI_BASE, ais_vessel
from daemon.mavlink_env import mavlink
from tracker.types import Track


def track(velocity: tuple[float, float], heading_deg: float = 45.0) -> Track:
    return Track(
        17, 0.0, np.array([10.0, 5.0]), np.array(velocity), math.radians(heading_deg), 0.0, 6.4, 2.5, 1.5,
        confirmed=True, source="fused", time_since_update=0.2,
    )  # fmt: skip


def test_moving_track() -> None:
    v = ais_vessel(track((2.0, 2.0)), 59.4101234, -10.4907654)
    assert v.mmsi == MMSI_BASE + 17 and v.name == b"USV-TRK 17 FUSED"
    assert (v.lat_e7, v.lon_e7) == (594101234, -104907654)
    assert v.cog_cdeg == 4500 and v.heading_cdeg == 4500 and v.velocity_cms == 283
    assert (v.dimension_bow, v.dimension_stern, v.dimension_port, v.dimension_starboard) == (3, 3, 1, 1)
    want = mavlink.AIS_FLAGS_VALID_NAME | mavlink.AIS_FLAGS_VALID_VELOCITY | mavlink.AIS_FLAGS_VALID_COG
    assert v.flags == want | mavlink.AIS_FLAGS_VALID_DIMENSIONS
    assert v.tslc == 0


def test_unknown_and_slow_velocity_and_course_west() -> None:
    unknown = ais_vessel(track((math.nan, math.nan)), 0.0, 0.0)
    assert not unknown.flags & mavlink.AIS_FLAGS_VALID_VELOCITY and not unknown.flags & mavlink.AIS_FLAGS_VALID_COG
    assert unknown.cog_cdeg == 65535
    slow = ais_vessel(track((0.1, 0.0)), 0.0, 0.0)
    assert slow.flags & mavlink.AIS_FLAGS_VALID_VELOCITY and not slow.flags & mavlink.AIS_FLAGS_VALID_COG
    assert slow.velocity_cms == 10
    west = ais_vessel(track((0.0, -3.0), heading_deg=-90.0), 0.0, 0.0)
    assert west.cog_cdeg == 27000 and west.heading_cdeg == 27000
