"""Body FRD -> world NED for points taken while the boat moves.

A VLP-16 sweep lasts 100 ms; at 3 m/s and 10 deg/s yaw rate the boat moves 0.3 m and turns 1 deg within one
revolution, which is 0.9 m of smear at 50 m. So each point is placed with the pose at its own time.
"""

from __future__ import annotations

import numpy as np


def rotation_matrices(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """(N, 3, 3) body->NED rotations, R = Rz(yaw) Ry(pitch) Rx(roll) (MAVLink/aerospace convention)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    r = np.empty((np.size(yaw), 3, 3))
    r[:, 0, 0] = cy * cp
    r[:, 0, 1] = cy * sp * sr - sy * cr
    r[:, 0, 2] = cy * sp * cr + sy * sr
    r[:, 1, 0] = sy * cp
    r[:, 1, 1] = sy * sp * sr + cy * cr
    r[:, 1, 2] = sy * sp * cr - cy * sr
    r[:, 2, 0] = -sp
    r[:, 2, 1] = cp * sr
    r[:, 2, 2] = cp * cr
    return r


def body_to_world(
    xyz_body: np.ndarray, position_ned: np.ndarray, roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray
) -> np.ndarray:
    """Points (N, 3) in body FRD -> world NED, with one pose per point (arrays of N) or one pose for all."""
    roll, pitch, yaw = (np.broadcast_to(np.asarray(a, float), (xyz_body.shape[0],)) for a in (roll, pitch, yaw))
    if np.all(roll == roll[0]) and np.all(pitch == pitch[0]) and np.all(yaw == yaw[0]):
        r = rotation_matrices(roll[:1], pitch[:1], yaw[:1])[0]
        return xyz_body @ r.T + position_ned
    r = rotation_matrices(roll, pitch, yaw)
    return np.einsum("nij,nj->ni", r, xyz_body) + position_ned


def world_to_body_2d(points_ne: np.ndarray, position_ne: np.ndarray, yaw: float) -> np.ndarray:
    """Horizontal world (north, east) -> body (forward, starboard) for a level boat at ``yaw``."""
    c, s = np.cos(yaw), np.sin(yaw)
    d = points_ne - position_ne
    return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)
