"""Body FRD -> world NED for points taken while the boat moves.

A VLP-16 sweep lasts 100 ms; at 3 m/s and 10 deg/s yaw rate the boat moves 0.3 m and turns 1 deg within one
revolution, which is 0.9 m of smear at 50 m. So each point is placed with the pose at its own time (to within
half a millisecond: see sample_poses).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

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
    xyz = np.asarray(xyz_body, dtype=float).reshape(-1, 3)
    n = xyz.shape[0]
    return PoseTable.of(position_ned, roll, pitch, yaw, n).body_to_world(xyz, np.arange(n))[0]


def world_to_body_2d(points_ne: np.ndarray, position_ne: np.ndarray, yaw: float) -> np.ndarray:
    """Horizontal world (north, east) -> body (forward, starboard) for a level boat at ``yaw``."""
    c, s = np.cos(yaw), np.sin(yaw)
    d = points_ne - position_ne
    return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)


def body_to_world_2d(points_fs: np.ndarray, position_ne: np.ndarray, yaw: float) -> np.ndarray:
    """Body (forward, starboard) of a level boat at ``yaw`` -> horizontal world (north, east); inverts
    world_to_body_2d."""
    c, s = np.cos(yaw), np.sin(yaw)
    f, st = points_fs[..., 0], points_fs[..., 1]
    return np.stack([position_ne[0] + c * f - s * st, position_ne[1] + s * f + c * st], axis=-1)


@dataclass
class PoseTable:
    """K body->NED poses (world NED position m, roll/pitch/yaw rad) and which one each of N points was taken at.

    A revolution's points need not each get their own pose: sampled every 1 ms, the boat's pose moves by
    millimetres between samples, and computing 100 rotations instead of 29k saves a millisecond a cycle.
    """

    position: np.ndarray  # (K, 3)
    roll: np.ndarray  # (K,)
    pitch: np.ndarray  # (K,)
    yaw: np.ndarray  # (K,)
    index: np.ndarray  # (N,) int: point i's pose

    @classmethod
    def of(
        cls,
        position: np.ndarray,
        roll: np.ndarray | float,
        pitch: np.ndarray | float,
        yaw: np.ndarray | float,
        n: int,
        index: np.ndarray | None = None,
    ) -> PoseTable:
        """Poses given as one for all, one per point (K = N, no ``index``), or K with a per-point ``index``."""
        pos = np.asarray(position, dtype=float).reshape(-1, 3)
        att = [np.asarray(a, dtype=float).reshape(-1) for a in (roll, pitch, yaw)]
        if n == 0:  # an empty scan: no point takes any pose
            return cls(np.zeros((1, 3)), np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(0, dtype=np.intp))
        k = max(pos.shape[0], *(a.size for a in att))
        pos = np.broadcast_to(pos, (k, 3))
        att = [np.broadcast_to(a, (k,)) for a in att]
        if index is None:
            if k not in (1, n):
                raise ValueError(f"{k} poses for {n} points and no index saying which point takes which")
            index = np.zeros(n, dtype=np.intp) if k == 1 else np.arange(n)
        index = np.asarray(index, dtype=np.intp)
        if index.shape != (n,) or (n and (index.min() < 0 or index.max() >= k)):
            raise ValueError(f"pose index: need {n} entries within [0, {k}), got shape {index.shape}")
        return cls(pos, att[0], att[1], att[2], index)

    def all_finite(self) -> bool:
        """Every pose of the table is known (then so is every point's)."""
        return bool(np.isfinite(self.position).all() and np.isfinite(self.roll + self.pitch + self.yaw).all())

    def finite_per_point(self) -> np.ndarray:
        """(N,) bool: the point's pose is known."""
        ok = np.isfinite(self.position[:, 0] + self.position[:, 1] + self.position[:, 2])
        ok &= np.isfinite(self.roll + self.pitch + self.yaw)
        return ok[self.index]

    def body_to_world(self, xyz_body: np.ndarray, point_idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points (M, 3) body FRD, which are the table's points ``point_idx``, -> (world NED (M, 3), the body
        origin's world down coordinate at each point (M,)), m."""
        sel = self.index[np.asarray(point_idx, dtype=np.intp)]
        m = sel.size
        if m == 0:
            return np.zeros((0, 3)), np.zeros(0)
        if self.position.shape[0] == 1:
            r = rotation_matrices(self.roll, self.pitch, self.yaw)[0]
            return xyz_body @ r.T + self.position[0], np.full(m, self.position[0, 2])
        north, east, down, pos_down = self.columns_to_world(xyz_body[:, 0], xyz_body[:, 1], xyz_body[:, 2], point_idx)
        return np.column_stack([north, east, down]), pos_down

    def columns_to_world(
        self, x: np.ndarray, y: np.ndarray, z: np.ndarray, point_idx: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`body_to_world` for body FRD columns, each point with its own pose (as K > 1 poses place them):
        (north, east, down, the body origin's down coordinate) columns, m."""
        sel = np.take(self.index, np.asarray(point_idx, dtype=np.intp))
        r = rotation_matrices(self.roll, self.pitch, self.yaw)
        # Column by column with 1-D gathers: several times faster than einsum over an (M, 3, 3) gather.
        rows = [
            np.take(r[:, row, 0], sel) * x
            + np.take(r[:, row, 1], sel) * y
            + np.take(r[:, row, 2], sel) * z
            + np.take(self.position[:, row], sel)
            for row in range(3)
        ]
        return rows[0], rows[1], rows[2], np.take(self.position[:, 2], sel)


class PoseSource(Protocol):
    def at_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]: ...


POSE_SAMPLE_S = 0.001  # s between the ego poses a revolution's points are placed with
MAX_SAMPLED_SPAN_S = 1.0  # s; a scan whose times spread wider (a bad timestamp) gets a pose per point instead


def sample_poses(
    ego: PoseSource, t: np.ndarray, step: float = POSE_SAMPLE_S
) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray | None]:
    """Ego poses every ``step`` s across the points' times ``t`` (``ego.at_many`` at those instants), and the
    nearest sample for each point: ((positions (K, 3), roll, pitch, yaw (K,)), index (N,)).

    Within half a step (0.5 ms) a boat at 5 m/s turning 20 deg/s moves 2.5 mm and turns 0.01 deg (0.9 cm at
    50 m), below the VLP-16's 3 cm range noise; interpolating 29k poses instead cost about 1.5 ms a cycle. With any
    time missing every point gets its own pose (index None), so a point without a time gets no pose.
    """
    t = np.asarray(t, dtype=float).ravel()
    if t.size and np.isfinite(t).all():
        t0, t1 = float(t.min()), float(t.max())
        if t1 - t0 <= MAX_SAMPLED_SPAN_S:
            knots = t0 + step * np.arange(int((t1 - t0) / step) + 2)
            index = np.clip(np.rint((t - t0) * (1.0 / step)).astype(np.intp), 0, knots.size - 1)
            return ego.at_many(knots), index
    return ego.at_many(t), None
