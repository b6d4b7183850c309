"""One perception cycle: newest LiDAR revolution + radar frames + ego pose -> tracks and the obstacle array.

Pure computation (no sockets, threads or clocks): the daemon's loop, the replay and the benchmarks all call
``PerceptionPipeline.step`` with the same inputs, so what is measured is what runs on the boat.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from drivers.frames import LidarScan, RadarFrame
from tracker.ego import body_to_world, rotation_matrices, world_to_body_2d
from tracker.obstacle_map import SensorCoverage, build_obstacle_distances, outline_points
from tracker.types import Track

log = logging.getLogger(__name__)


class PoseLookup(Protocol):
    """Ego pose in the world frame (NED) at host times; None where the pose is not known."""

    def at_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """(positions (N,3), roll (N,), pitch (N,), yaw (N,))."""
        ...


@dataclass(frozen=True)
class OwnBoatBox:
    """Returns inside this box (body FRD, metres) are the boat itself."""

    bow: float = 0.8
    stern: float = -0.8
    port: float = -0.5
    starboard: float = 0.5
    water_z: float = 0.0  # body z (down positive) of the water line


@dataclass(frozen=True)
class PipelineSettings:
    min_distance_m: float = 0.5
    max_distance_m: float = 100.0
    lidar_min_range_m: float = 0.5
    lidar_max_range_m: float = 100.0
    min_height_above_water_m: float = 0.15
    radar_fov_rad: float = np.radians(120.0)
    radar_yaw_rad: float = 0.0
    radar_max_range_m: float = 50.0
    boat: OwnBoatBox = field(default_factory=OwnBoatBox)


@dataclass
class PerceptionOutput:
    t: float
    tracks: list[Track]
    distances_cm: np.ndarray  # (72,) uint16, ready for OBSTACLE_DISTANCE
    lidar_fresh: bool
    radar_fresh: bool
    n_lidar_points: int = 0
    n_radar_points: int = 0
    timings_ms: dict[str, float] = field(default_factory=dict)
    solid_points_body: np.ndarray | None = None  # (M, 2) fwd/stbd, for pictures


class SensorTracker(Protocol):
    """What a tracker plugged into the pipeline provides (the LiDAR and radar trackers of issues 4 and 5)."""

    def step_pipeline(self, inputs: Any) -> list[Track]: ...


def _timed(timings: dict[str, float], key: str, fn: Callable[[], Any]) -> Any:
    t0 = time.perf_counter()
    out = fn()
    timings[key] = timings.get(key, 0.0) + (time.perf_counter() - t0) * 1e3
    return out


def level_points(xyz_body: np.ndarray, roll: float, pitch: float) -> np.ndarray:
    """Body FRD -> a yaw-free level frame (forward, starboard, gravity-down): heights on a rolling boat."""
    if roll == 0.0 and pitch == 0.0:
        return xyz_body
    r = rotation_matrices(np.array([roll]), np.array([pitch]), np.array([0.0]))[0]
    return xyz_body @ r.T


def lidar_solid_mask(xyz_body: np.ndarray, level_z: np.ndarray, s: PipelineSettings) -> np.ndarray:
    """Points that are real obstacles: within range, above the water, not the own boat, finite."""
    x, y = xyz_body[:, 0], xyz_body[:, 1]
    rng = np.hypot(x, y)
    b = s.boat
    own = (x <= b.bow) & (x >= b.stern) & (y >= b.port) & (y <= b.starboard)
    above_water = level_z < b.water_z - s.min_height_above_water_m
    return np.isfinite(rng) & (rng >= s.lidar_min_range_m) & (rng <= s.lidar_max_range_m) & above_water & ~own


@dataclass
class PerceptionPipeline:
    settings: PipelineSettings = field(default_factory=PipelineSettings)
    lidar_tracker: Any | None = None
    radar_tracker: Any | None = None
    freshness_s: float = 0.5

    _last_lidar_t: float = -np.inf
    _last_radar_t: float = -np.inf

    def step(
        self,
        t: float,
        scan: LidarScan | None,
        radar_frames: Sequence[RadarFrame],
        poses: PoseLookup | None,
    ) -> PerceptionOutput:
        timings: dict[str, float] = {}
        s = self.settings
        solid: list[np.ndarray] = []
        tracks: list[Track] = []
        n_lidar = n_radar = 0

        own = _pose_at(poses, t)
        if scan is not None and scan.n_points:
            self._last_lidar_t = max(self._last_lidar_t, scan.stamp)
            pts = _timed(timings, "lidar_pre", lambda: self._lidar_solid_points(scan, poses))
            n_lidar = int(pts.shape[0])
            solid.append(pts[:, :2])
            if self.lidar_tracker is not None:
                world = _timed(timings, "lidar_world", lambda: _to_world(pts, scan.t[self._last_mask], poses))
                tracks += _timed(timings, "lidar_track", lambda: self.lidar_tracker.step(world, scan.stamp, own))
        elif scan is not None:
            self._last_lidar_t = max(self._last_lidar_t, scan.stamp)
        for frame in radar_frames:
            self._last_radar_t = max(self._last_radar_t, frame.stamp)
            fin = np.all(np.isfinite(frame.xyz), axis=1)
            pts = frame.xyz[fin]
            n_radar += int(pts.shape[0])
            solid.append(pts[:, :2])
            if self.radar_tracker is not None:
                frame_pose = _pose_at(poses, frame.stamp)
                tracks_r = _timed(timings, "radar_track", lambda f=frame, p=frame_pose: self.radar_tracker.step(f, p))
                if frame is radar_frames[-1]:
                    tracks += tracks_r
        if own is not None and tracks:
            for tr in tracks:
                if tr.confirmed:
                    solid.append(world_to_body_2d(outline_points(tr.footprint()), own[0][:2], own[3]))

        lidar_fresh = t - self._last_lidar_t <= self.freshness_s
        radar_fresh = t - self._last_radar_t <= self.freshness_s
        coverages = []
        if lidar_fresh:
            coverages.append(SensorCoverage(0.0, 2 * np.pi, s.lidar_max_range_m))
        if radar_fresh:
            coverages.append(SensorCoverage(s.radar_yaw_rad, s.radar_fov_rad, s.radar_max_range_m))
        distances = _timed(
            timings,
            "obstacle_map",
            lambda: build_obstacle_distances(solid, coverages, s.min_distance_m, s.max_distance_m),
        )
        return PerceptionOutput(
            t=t,
            tracks=tracks,
            distances_cm=distances,
            lidar_fresh=lidar_fresh,
            radar_fresh=radar_fresh,
            n_lidar_points=n_lidar,
            n_radar_points=n_radar,
            timings_ms=timings,
            solid_points_body=np.concatenate(solid) if solid else np.empty((0, 2)),
        )

    _last_mask: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))

    def _lidar_solid_points(self, scan: LidarScan, poses: PoseLookup | None) -> np.ndarray:
        roll = pitch = 0.0
        p = _pose_at(poses, scan.stamp)
        if p is not None:
            roll, pitch = float(p[1]), float(p[2])
        level = level_points(scan.xyz, roll, pitch)
        mask = lidar_solid_mask(scan.xyz, level[:, 2], self.settings)
        self._last_mask = mask
        return scan.xyz[mask]


def _pose_at(poses: PoseLookup | None, t: float) -> tuple[np.ndarray, float, float, float] | None:
    if poses is None:
        return None
    got = poses.at_many(np.array([t]))
    if got is None:
        return None
    pos, roll, pitch, yaw = got
    if not np.all(np.isfinite(pos[0])):
        return None
    return pos[0], float(roll[0]), float(pitch[0]), float(yaw[0])


def _to_world(xyz_body: np.ndarray, times: np.ndarray, poses: PoseLookup | None) -> np.ndarray:
    """Each point with the pose at its own firing time; without a pose the body frame at start is the world."""
    if poses is None:
        return xyz_body
    got = poses.at_many(times)
    if got is None:
        return xyz_body
    pos, roll, pitch, yaw = got
    return body_to_world(xyz_body, pos, roll, pitch, yaw)
