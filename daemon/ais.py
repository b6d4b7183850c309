"""Confirmed tracks as AIS_VESSEL messages, for the operator's map in the ground station.

Not for avoidance: neither autopilot acts on AIS_VESSEL from a companion computer (specs/mavlink-obstacles.md
§2.4); OBSTACLE_DISTANCE is what keeps the boat off things. A track becomes a vessel with a made-up MMSI (a base
plus the track id), its position, course and speed over ground when the tracker knows them, its heading, and its
length and beam split evenly about the position. Units at this edge are the message's: degE7, centidegrees, cm/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from daemon.config import AIS_MMSI_BASE as MMSI_BASE
from daemon.mavlink_env import mavlink
from tracker.types import Track

_UNKNOWN_ANGLE = 65535  # cdeg
_UNKNOWN_TURN = 127  # INT8_MAX


@dataclass(frozen=True)
class AisVessel:
    """The AIS_VESSEL fields, in the message's units."""

    mmsi: int
    lat_e7: int
    lon_e7: int
    cog_cdeg: int
    heading_cdeg: int
    velocity_cms: int
    dimension_bow: int
    dimension_stern: int
    dimension_port: int
    dimension_starboard: int
    name: bytes
    flags: int
    navigational_status: int = mavlink.AIS_NAV_STATUS_UNKNOWN
    turn_rate: int = _UNKNOWN_TURN
    vessel_type: int = 0  # AIS_TYPE_UNKNOWN
    tslc: int = 0  # s since the last "communication": since the track was last measured


def _cdeg(angle_rad: float) -> int:
    return round(math.degrees(angle_rad) % 360.0 * 100) % 36000


def ais_vessel(track: Track, lat_deg: float, lon_deg: float, mmsi_base: int = MMSI_BASE) -> AisVessel:
    """One confirmed track (world NED, SI) at the given latitude/longitude as AIS_VESSEL fields."""
    flags = mavlink.AIS_FLAGS_VALID_NAME
    v = np.asarray(track.velocity, dtype=float)
    cog, velocity = _UNKNOWN_ANGLE, 0
    if np.all(np.isfinite(v)):  # NaN: the tracker does not know the velocity (a newborn track, radar "wait")
        speed = float(np.hypot(v[0], v[1]))
        velocity = min(round(speed * 100), 65534)
        flags |= mavlink.AIS_FLAGS_VALID_VELOCITY
        if speed >= 0.2:  # slower, the course is noise
            cog = _cdeg(math.atan2(v[1], v[0]))
            flags |= mavlink.AIS_FLAGS_VALID_COG
    heading = _cdeg(track.heading) if math.isfinite(track.heading) else _UNKNOWN_ANGLE
    half_len = max(round(track.length / 2), 1) if math.isfinite(track.length) else 0
    half_beam = max(round(track.width / 2), 1) if math.isfinite(track.width) else 0
    if half_len and half_beam:
        flags |= mavlink.AIS_FLAGS_VALID_DIMENSIONS
    return AisVessel(
        mmsi=int(mmsi_base) + int(track.id) % 1_000_000,
        lat_e7=round(lat_deg * 1e7),
        lon_e7=round(lon_deg * 1e7),
        cog_cdeg=cog,
        heading_cdeg=heading,
        velocity_cms=velocity,
        dimension_bow=min(half_len, 511),
        dimension_stern=min(half_len, 511),
        dimension_port=min(half_beam, 63),
        dimension_starboard=min(half_beam, 63),
        name=f"USV-TRK {track.id} {track.source.upper()}"[:20].encode("ascii"),
        flags=flags,
        tslc=min(max(round(track.time_since_update), 0), 65535) if math.isfinite(track.time_since_update) else 0,
    )
