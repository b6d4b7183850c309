"""Frame conventions and point packing for the live view, numpy only (no foxglove here, so it is cheap to test).

Foxglove's 3D panel is z-up, as ROS REP 103 is, so the view publishes two frames:

  "world": ENU, x east, y north, z up    from the trackers' world NED:  (x, y, z) = (east, north, -down)
  "boat":  FLU, x bow, y port, z up      from the body FRD:             (x, y, z) = (fwd, -starboard, -down)

with /tf giving "boat" in "world" from the own pose. NED published as it is would be right-handed too, but the
panel looks down its z axis from above: with z pointing down the harbour would appear mirrored (east to the left
of north) unless every viewer turned the camera upside down. A heading (0 = north, clockwise) becomes the ENU yaw
pi/2 - heading (0 = east, counter-clockwise).
"""

from __future__ import annotations

import math

import numpy as np

from tracker.lidar.preprocess import REASON_NAMES
from tracker.obstacle_map import BIN_WIDTH_RAD, N_BINS, UNKNOWN

OBSTACLE, CLEAR, UNKNOWN_STATE = 0, 1, 2  # /obstacles "state" per bin


def enu_yaw(heading: float) -> float:
    """A heading (rad, 0 = north, clockwise) as a yaw about ENU's z (0 = east, counter-clockwise)."""
    return math.pi / 2 - heading


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation by ``yaw`` about z."""
    return 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)


def _qmul(a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, float, float, float]:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


_Q_NED_IN_ENU = (math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0)  # 180 deg about (1, 1, 0): swaps x/y, flips z
_Q_FLU_IN_FRD = (1.0, 0.0, 0.0, 0.0)  # 180 deg about x


def boat_quaternion(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of the "boat" (FLU) frame in "world" (ENU), from the aerospace Z-Y-X attitude of body FRD in
    world NED (radians, as EgoPose gives it)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    q_frd_in_ned = (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )
    return _qmul(_qmul(_Q_NED_IN_ENU, q_frd_in_ned), _Q_FLU_IN_FRD)


# ---- packed point clouds --------------------------------------------------------------------------------------
# Foxglove colours a cloud by its uint8 red/green/blue/alpha fields when it has them ("RGBA (separate fields)").


def _cloud_dtype(*extra: tuple[str, str]) -> np.dtype:
    names = ["x", "y", "z", *(n for n, _ in extra), "red", "green", "blue", "alpha"]
    formats = ["<f4", "<f4", "<f4", *(f for _, f in extra), "u1", "u1", "u1", "u1"]
    return np.dtype({"names": names, "formats": formats})


LIDAR_DTYPE = _cloud_dtype(("intensity", "<f4"), ("reason", "u1"))
CLUSTER_DTYPE = _cloud_dtype(("cluster", "<u2"), ("structure", "u1"))
RADAR_DTYPE = _cloud_dtype(("doppler", "<f4"), ("snr", "<f4"))
OBSTACLE_DTYPE = _cloud_dtype(("distance_cm", "<u2"), ("bin", "u1"), ("state", "u1"))

# per REASON_NAMES: kept returns bright, each rule's drops in a colour of their own, half transparent
REASON_RGBA = np.array(
    [
        (240, 240, 240, 255),  # kept
        (128, 128, 128, 100),  # nonfinite (not drawn: no position)
        (90, 90, 90, 100),  # range
        (255, 210, 0, 160),  # own_boat
        (170, 90, 255, 160),  # height
        (40, 120, 255, 160),  # water
        (0, 220, 220, 160),  # isolated
        (255, 80, 40, 200),  # spray
    ],
    dtype=np.uint8,
)
assert REASON_RGBA.shape[0] == len(REASON_NAMES)
STATE_RGBA = np.array([(255, 40, 40, 255), (60, 220, 60, 255), (128, 128, 128, 255)], dtype=np.uint8)
CLUSTER_RGBA = np.array(
    [
        (230, 25, 75, 255),
        (60, 180, 75, 255),
        (255, 225, 25, 255),
        (0, 130, 200, 255),
        (245, 130, 48, 255),
        (145, 30, 180, 255),
        (70, 240, 240, 255),
        (240, 50, 230, 255),
        (210, 245, 60, 255),
        (250, 190, 212, 255),
        (0, 128, 128, 255),
        (170, 110, 40, 255),
    ],
    dtype=np.uint8,
)
STRUCTURE_RGBA = np.array((150, 150, 150, 200), dtype=np.uint8)
DOPPLER_STILL_MPS = 0.25  # |Doppler| below this: drawn as standing still


def _fill(cloud: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray, rgba: np.ndarray) -> None:
    cloud["x"], cloud["y"], cloud["z"] = x, y, z
    # the four colour bytes sit side by side: one copy of (n, 4) bytes, not four strided ones
    start = cloud.dtype.fields["red"][1]
    cloud.view(np.uint8).reshape(cloud.size, cloud.dtype.itemsize)[:, start : start + 4] = rgba


def lidar_cloud(xyz_frd: np.ndarray, intensity: np.ndarray, reason: np.ndarray) -> np.ndarray:
    """Every return of a revolution in "boat" (FLU), with its intensity and drop reason, coloured by reason."""
    cloud = np.empty(xyz_frd.shape[0], LIDAR_DTYPE)
    _fill(cloud, xyz_frd[:, 0], -xyz_frd[:, 1], -xyz_frd[:, 2], REASON_RGBA[reason])
    cloud["intensity"] = intensity
    cloud["reason"] = reason
    return cloud


def cluster_cloud(clusters_ned: list[np.ndarray], structure: np.ndarray) -> np.ndarray:
    """The LiDAR tracker's clusters in "world" (ENU), a colour per cluster, structure (quays, shore) grey."""
    if not clusters_ned:
        return np.empty(0, CLUSTER_DTYPE)
    k = len(clusters_ned)
    sizes = np.fromiter((len(c) for c in clusters_ned), int, k)
    is_structure = np.zeros(k, dtype=bool)
    is_structure[: min(structure.size, k)] = structure[:k]
    colour = CLUSTER_RGBA[np.arange(k) % len(CLUSTER_RGBA)]
    colour[is_structure] = STRUCTURE_RGBA
    # per cluster first, then repeated: no per-point fancy indexing
    label = np.repeat(np.arange(k, dtype=np.uint16), sizes)
    rgba = np.repeat(colour, sizes, axis=0)
    ned = np.concatenate(clusters_ned)
    cloud = np.empty(label.size, CLUSTER_DTYPE)
    _fill(cloud, ned[:, 1], ned[:, 0], -ned[:, 2], rgba)
    cloud["cluster"] = label
    cloud["structure"] = np.repeat(is_structure, sizes)
    return cloud


def radar_cloud(xyz_frd: np.ndarray, doppler: np.ndarray, snr: np.ndarray) -> np.ndarray:
    """Radar returns in "boat" (FLU) with their raw Doppler (m/s, + receding) and SNR: approaching red, receding
    blue, still white."""
    rgba = np.full((xyz_frd.shape[0], 4), 255, dtype=np.uint8)
    rgba[doppler < -DOPPLER_STILL_MPS, 1:3] = 60
    rgba[doppler > DOPPLER_STILL_MPS, 0:2] = 60
    cloud = np.empty(xyz_frd.shape[0], RADAR_DTYPE)
    _fill(cloud, xyz_frd[:, 0], -xyz_frd[:, 1], -xyz_frd[:, 2], rgba)
    cloud["doppler"] = doppler
    cloud["snr"] = snr
    return cloud


def bin_states(distances_cm: np.ndarray, max_cm: int) -> np.ndarray:
    """(72,) OBSTACLE, CLEAR or UNKNOWN_STATE, as OBSTACLE_DISTANCE's values mean them."""
    d = np.asarray(distances_cm)
    return np.where(d == UNKNOWN, UNKNOWN_STATE, np.where(d > max_cm, CLEAR, OBSTACLE)).astype(np.uint8)


def bin_radii(distances_cm: np.ndarray, max_cm: int) -> np.ndarray:
    """(72,) m at which each bin is drawn: an obstacle at its range, clear and unknown at the maximum distance."""
    d = np.asarray(distances_cm, dtype=float)
    return np.where(bin_states(distances_cm, max_cm) == OBSTACLE, d, max_cm) / 100.0


def obstacle_cloud(distances_cm: np.ndarray, max_cm: int) -> np.ndarray:
    """The 72 bins as 72 points in "boat" (FLU) at each bin's centre bearing (bin 0 the bow, 5 deg each, clockwise),
    with the value sent, the bin and its state; obstacle red, clear green, unknown grey."""
    state = bin_states(distances_cm, max_cm)
    r = bin_radii(distances_cm, max_cm)
    bearing = np.arange(N_BINS) * BIN_WIDTH_RAD
    cloud = np.empty(N_BINS, OBSTACLE_DTYPE)
    _fill(cloud, r * np.cos(bearing), -r * np.sin(bearing), np.zeros(N_BINS), STATE_RGBA[state])
    cloud["distance_cm"] = distances_cm
    cloud["bin"] = np.arange(N_BINS)
    cloud["state"] = state
    return cloud


def obstacle_chords(distances_cm: np.ndarray, max_cm: int) -> tuple[np.ndarray, np.ndarray]:
    """(144, 3) FLU segment ends, each bin's +-2.5 deg drawn at its radius (a line list), and (144,) state per end."""
    r = np.repeat(bin_radii(distances_cm, max_cm), 2)
    bearing = (np.arange(N_BINS)[:, None] + np.array([-0.5, 0.5])).ravel() * BIN_WIDTH_RAD
    xyz = np.stack([r * np.cos(bearing), -r * np.sin(bearing), np.zeros(r.size)], axis=1)
    return xyz, np.repeat(bin_states(distances_cm, max_cm), 2)
