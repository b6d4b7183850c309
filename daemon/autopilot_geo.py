"""Latitude/longitude <-> a local NED tangent plane, for the autopilot link's GLOBAL_POSITION_INT fallback.

When the autopilot sends no LOCAL_POSITION_NED (ArduPilot does not before its EKF has an origin), the world
frame is a NED plane tangent to the WGS-84 ellipsoid at the first fix. The projection is the local
"flat earth" one with the ellipsoid's meridian and prime-vertical radii at the origin: within 10 km of the
origin its error is below 1 m horizontally, far inside what a boat's tracker cares about, and it is exact
to invert, so lat/lon -> NED -> lat/lon round trips to the float precision.
"""

from __future__ import annotations

import math

import numpy as np

WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)


class LocalTangentPlane:
    """NED plane at (lat0, lon0, alt0): degrees, degrees, metres above MSL (the autopilot's altitude datum)."""

    def __init__(self, lat0_deg: float, lon0_deg: float, alt0_m: float = 0.0) -> None:
        if not (-90.0 <= lat0_deg <= 90.0 and -180.0 <= lon0_deg <= 180.0 and math.isfinite(alt0_m)):
            raise ValueError(f"bad origin lat={lat0_deg} lon={lon0_deg} alt={alt0_m}")
        self.lat0_deg = float(lat0_deg)
        self.lon0_deg = float(lon0_deg)
        self.alt0_m = float(alt0_m)
        s = math.sin(math.radians(lat0_deg))
        w = 1.0 - WGS84_E2 * s * s
        # metres per radian of latitude (meridian radius) and of longitude (parallel circle radius)
        self._m_per_rad_lat = WGS84_A * (1.0 - WGS84_E2) / w**1.5 + alt0_m
        self._m_per_rad_lon = (WGS84_A / math.sqrt(w) + alt0_m) * math.cos(math.radians(lat0_deg))

    def to_ned(self, lat_deg: np.ndarray | float, lon_deg: np.ndarray | float, alt_m: np.ndarray | float) -> np.ndarray:
        """(..., 3) north, east, down in metres."""
        lat = np.asarray(lat_deg, dtype=float)
        dlon = (np.asarray(lon_deg, dtype=float) - self.lon0_deg + 180.0) % 360.0 - 180.0  # across the antimeridian
        north = np.radians(lat - self.lat0_deg) * self._m_per_rad_lat
        east = np.radians(dlon) * self._m_per_rad_lon
        down = self.alt0_m - np.asarray(alt_m, dtype=float)
        return np.stack(np.broadcast_arrays(north, east, down), axis=-1)

    def to_geodetic(self, ned: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Inverse of ``to_ned``: (lat deg, lon deg in [-180, 180), alt m) for (..., 3) NED points."""
        ned = np.asarray(ned, dtype=float)
        lat = self.lat0_deg + np.degrees(ned[..., 0] / self._m_per_rad_lat)
        lon = (self.lon0_deg + np.degrees(ned[..., 1] / self._m_per_rad_lon) + 180.0) % 360.0 - 180.0
        alt = self.alt0_m - ned[..., 2]
        return lat, lon, alt
