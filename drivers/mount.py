"""Sensor mounts: the rigid transform from a sensor's frame to the boat's body frame.

Frames
------
* body: FRD (x to the bow, y to starboard, z down), MAVLink's convention.
* sensor-FRD: the sensor's own axes renamed to forward/right/down. Each driver first maps the
  manufacturer's native axes to sensor-FRD (VLP-16: FLU -> FRD; AWR1843: x-right/y-boresight/z-up -> FRD),
  then applies the mount.

A mount is the sensor's pose in the body frame: its origin (x, y, z) in metres and its orientation as
roll, pitch, yaw (radians, intrinsic Z-Y-X, the aerospace convention). A sensor with all six values zero
looks along the bow with its "up" pointing up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


def rotation_zyx(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rotation matrix R = Rz(yaw) @ Ry(pitch) @ Rx(roll); maps child-frame vectors into the parent frame."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


@dataclass(frozen=True)
class Mount:
    """Pose of a sensor (in its sensor-FRD axes) in the body FRD frame. Metres and radians."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0
    _rotation: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_rotation", rotation_zyx(self.roll, self.pitch, self.yaw))

    @classmethod
    def from_degrees(
        cls,
        x: float = 0.0,
        y: float = 0.0,
        z: float = 0.0,
        roll: float = 0.0,
        pitch: float = 0.0,
        yaw: float = 0.0,
    ) -> Mount:
        """Config files give angles in degrees; everything inside is radians."""
        return cls(x, y, z, math.radians(roll), math.radians(pitch), math.radians(yaw))

    @property
    def rotation(self) -> np.ndarray:
        return self._rotation

    @property
    def translation(self) -> np.ndarray:
        return np.array([self.x, self.y, self.z])

    def sensor_frd_to_body(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) points in sensor-FRD -> (N, 3) points in body FRD."""
        return points @ self._rotation.T + self.translation

    def rotate_sensor_frd_to_body(self, vectors: np.ndarray) -> np.ndarray:
        """Directions (unit vectors, velocities) from sensor-FRD to body FRD: rotation only."""
        return vectors @ self._rotation.T

    @property
    def level(self) -> bool:
        """No roll or pitch: sensor azimuths and body bearings differ by the yaw alone."""
        return self.roll == 0.0 and self.pitch == 0.0

    @property
    def mirrored(self) -> bool:
        """Mounted upside down (the sensor's down axis points up in the body): its clockwise sweep is
        anticlockwise seen from the boat."""
        return bool(self._rotation[2, 2] < 0.0)

    def body_bearings(self, sensor_azimuth: np.ndarray) -> np.ndarray:
        """Body bearing (rad, clockwise from the bow) of the sensor's horizontal direction at each sensor-FRD azimuth
        (rad, clockwise from the sensor's forward): through the whole rotation, so an upside-down sensor's azimuth
        85 deg is the bearing -85 deg. A tilted mount's directions are projected on the body's horizontal plane."""
        az = np.asarray(sensor_azimuth, float)
        if self.level:
            return az + self.yaw
        r = self._rotation
        c, s = np.cos(az), np.sin(az)
        return np.arctan2(r[1, 0] * c + r[1, 1] * s, r[0, 0] * c + r[0, 1] * s)

    def sensor_azimuths(self, body_bearing: np.ndarray) -> np.ndarray:
        """Sensor-FRD azimuth (rad) that points along each body bearing (rad): body_bearings inverted (exactly for a
        level or upside-down mount; for a tilted one, the body direction projected on the sensor's plane)."""
        b = np.asarray(body_bearing, float)
        if self.level:
            return b - self.yaw
        r = self._rotation  # sensor -> body; its transpose takes the body direction into the sensor frame
        c, s = np.cos(b), np.sin(b)
        return np.arctan2(r[0, 1] * c + r[1, 1] * s, r[0, 0] * c + r[1, 0] * s)


# Fixed axis maps from manufacturers' native frames to sensor-FRD. Both are proper rotations.
# velodyne-decoder returns ROS FLU (x forward, y left, z up): FRD = (x, -y, -z).
FLU_TO_FRD = np.diag([1.0, -1.0, -1.0])
# TI mmWave demo: x right (in the antenna plane), y boresight, z up: FRD = (y, x, -z).
TI_TO_FRD = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
