"""The frame conversions every driver relies on, pinned with exact numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.mount import FLU_TO_FRD, TI_TO_FRD, Mount


def test_identity_mount_keeps_points() -> None:
    pts = np.array([[1.0, 2.0, 3.0]])
    np.testing.assert_allclose(Mount().sensor_frd_to_body(pts), pts)


def test_yaw_90_deg_mount_points_sensor_forward_to_starboard() -> None:
    # A sensor turned 90 deg clockwise (seen from above) looks to starboard: its forward is body +y.
    m = Mount.from_degrees(x=1.0, z=-2.0, yaw=90.0)
    out = m.sensor_frd_to_body(np.array([[10.0, 0.0, 0.0]]))
    np.testing.assert_allclose(out, [[1.0, 10.0, -2.0]], atol=1e-12)


def test_pitch_up_mount_raises_forward_points() -> None:
    # Pitch +10 deg (nose up): a point straight ahead of the sensor is above the bow line (negative z in FRD).
    m = Mount(pitch=math.radians(10.0))
    out = m.sensor_frd_to_body(np.array([[10.0, 0.0, 0.0]]))
    np.testing.assert_allclose(out, [[10 * math.cos(math.radians(10)), 0.0, -10 * math.sin(math.radians(10))]])


def test_native_axis_maps_are_rotations() -> None:
    for r in (FLU_TO_FRD, TI_TO_FRD):
        np.testing.assert_allclose(r @ r.T, np.eye(3))
        assert math.isclose(np.linalg.det(r), 1.0)
    # TI: boresight (y) is forward, x (right) is starboard, z up is -down.
    np.testing.assert_allclose(TI_TO_FRD @ [0.5, 4.0, 1.0], [4.0, 0.5, -1.0])
    np.testing.assert_allclose(FLU_TO_FRD @ [3.0, 2.0, 1.0], [3.0, -2.0, -1.0])


@pytest.mark.parametrize(
    ("roll", "pitch", "yaw"),
    [(0.0, 0.0, 0.0), (0.0, 0.0, 30.0), (180.0, 0.0, 0.0), (180.0, 0.0, -40.0), (3.0, -2.0, 90.0)],
)
def test_body_bearings_are_where_the_sensor_points(roll: float, pitch: float, yaw: float) -> None:
    mount = Mount.from_degrees(roll=roll, pitch=pitch, yaw=yaw)
    az = np.radians(np.arange(-175.0, 180.0, 5.0))
    d = mount.rotate_sensor_frd_to_body(np.stack([np.cos(az), np.sin(az), np.zeros(az.size)], axis=1))
    want = np.arctan2(d[:, 1], d[:, 0])
    got = mount.body_bearings(az)
    np.testing.assert_allclose(np.angle(np.exp(1j * (got - want))), 0.0, atol=1e-12)
    back = mount.sensor_azimuths(got)
    # exact for level and upside-down mounts; a 3 deg tilt moves the projected azimuth by under 0.2 deg (its square)
    np.testing.assert_allclose(np.angle(np.exp(1j * (back - az))), 0.0, atol=1e-12 if pitch == 0 else 3.5e-3)
    assert mount.mirrored == (roll == 180.0)
