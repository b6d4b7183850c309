"""Exact VLP-16 geometry over a sea surface, for tests: which firings meet the water, and where.

Independent of the simulator's ray caster, so a test built on it checks the daemon against plain geometry: the
16 lasers of vlp16.md §3 (elevations and vertical offsets) fired every 0.2 deg, from a sensor mounted on a boat
with a given roll, pitch and yaw, meeting a water plane (or a surface ``elevation(north, east)``) below.

Frames: sensor FLU -> body FRD through the mount; body FRD -> world NED with R = Rz(yaw) Ry(pitch) Rx(roll). The
body origin sits ``origin_height`` above the mean water (world z = -origin_height); world z of the water is 0.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from daemon.config import Config
from daemon.runner import pipeline_for
from drivers.frames import EgoPose, LidarScan
from drivers.mount import FLU_TO_FRD, Mount
from tracker.ego import rotation_matrices
from tracker.pipeline import PerceptionPipeline

ELEVATION_DEG = np.array([-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15], float)
VERTICAL_OFFSET_M = (
    np.array([11.2, -0.7, 9.7, -2.2, 8.1, -3.7, 6.6, -5.1, 5.1, -6.6, 3.7, -8.1, 2.2, -9.7, 0.7, -11.2]) * 1e-3
)
RING_OF_LASER = np.argsort(np.argsort(ELEVATION_DEG)).astype(np.uint8)  # 0 = lowest beam
RAIN = -2  # WaterReturns.wall of a rain drop's return


@dataclass(frozen=True)
class WaterReturns:
    xyz_body: np.ndarray  # (N, 3) body FRD, m
    t: np.ndarray  # (N,) firing time, s
    ring: np.ndarray  # (N,) uint8
    xyz_world: np.ndarray  # (N, 3) world NED, m
    wall: np.ndarray  # (N,) index of the wall hit, -1 for the water, RAIN for a rain drop


def revolution_over_water(
    mount: Mount,
    attitude: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    yaw: float = 0.3,
    origin_height: float = 0.0,
    elevation: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    max_range: float = 100.0,
    step_deg: float = 0.2,
    t0: float = 0.0,
    walls: tuple[tuple[tuple[float, float], tuple[float, float], float], ...] = (),
    water_returns: bool = True,
    rain: tuple[int, float, int] | None = None,
    water_share: tuple[float, int] | tuple[float, int, float, float] | None = None,
) -> WaterReturns:
    """Every firing of one 10 Hz revolution that meets the water within ``max_range`` returns, where it meets it.

    ``attitude(t)`` gives (roll, pitch) at the firing times; ``elevation(north, east)`` the wave height above the mean
    (up positive), solved along each ray by fixed-point iteration (it converges for the gentle slopes used here).
    ``walls`` are vertical faces from the mean water up to a top height: ((north, east), (north, east), top); a
    firing that meets one before the water returns from the wall. ``water_returns=False`` is calm water: a firing
    that meets the water returns nothing. ``rain`` = (drops, reach m, seed): that many firings, drawn at random,
    meet a drop in mid-air out to ``reach`` (horizontal range 1 + (reach - 1) u^2, u uniform: denser close in) and
    return from it when it lies before what they would otherwise meet. ``water_share`` = (share, seed): only that
    share of the firings meeting the water return from it, drawn at random (a real sea returns grazing beams
    sporadically); (share, seed, beyond, far_share): far_share of those meeting it beyond ``beyond`` m horizontal
    (the far water is met at grazing incidence and returns less).
    """
    az = np.radians(np.arange(0.0, 360.0, step_deg))
    n_az = az.size
    a, laser = np.meshgrid(az, np.arange(16), indexing="ij")
    a, laser = a.ravel(), laser.ravel()
    t = t0 + np.repeat(np.arange(n_az) / n_az * 0.1, 16) + laser * 2.304e-6
    el = np.radians(ELEVATION_DEG[laser])
    d_flu = np.stack([np.cos(el) * np.cos(a), -np.cos(el) * np.sin(a), np.sin(el)], axis=-1)
    o_flu = np.zeros_like(d_flu)
    o_flu[:, 2] = VERTICAL_OFFSET_M[laser]
    to_body = mount.rotation @ FLU_TO_FRD
    d_body = d_flu @ to_body.T
    o_body = o_flu @ to_body.T + mount.translation
    roll, pitch = attitude(t)
    r = rotation_matrices(np.broadcast_to(roll, t.shape), np.broadcast_to(pitch, t.shape), np.full(t.shape, yaw))
    d_world = np.einsum("nij,nj->ni", r, d_body)
    o_world = np.einsum("nij,nj->ni", r, o_body)
    o_world[:, 2] -= origin_height
    down = d_world[:, 2] > 1e-6
    lam = np.where(down, -o_world[:, 2] / np.where(down, d_world[:, 2], 1.0), np.inf)
    if elevation is not None:
        for _ in range(30):
            p = o_world[down] + lam[down, None] * d_world[down]
            lam[down] = (-elevation(p[:, 0], p[:, 1]) - o_world[down, 2]) / d_world[down, 2]
    wall = np.full(t.size, -1)
    for k, (p0, p1, top) in enumerate(walls):
        e = np.subtract(p1, p0, dtype=float)
        nrm = np.array([e[1], -e[0]]) / np.hypot(*e)
        den = d_world[:, :2] @ nrm
        with np.errstate(divide="ignore", invalid="ignore"):  # rays along the wall never meet it (den = 0)
            mu = ((np.asarray(p0, float) - o_world[:, :2]) @ nrm) / den
            p = o_world + mu[:, None] * d_world
        along = ((p[:, :2] - np.asarray(p0, float)) @ e) / (e @ e)
        on = (den != 0) & (mu > 0.5) & (mu < lam) & (along >= 0) & (along <= 1) & (-p[:, 2] >= 0) & (-p[:, 2] <= top)
        lam = np.where(on, mu, lam)
        wall[on] = k
    if rain is not None:
        count, reach, seed = rain
        draw = np.random.default_rng(seed)
        pick = draw.choice(t.size, size=count, replace=False)
        lam_drop = (1.0 + (reach - 1.0) * draw.random(count) ** 2) / np.hypot(d_body[pick, 0], d_body[pick, 1])
        first = lam_drop < lam[pick]
        lam[pick[first]] = lam_drop[first]
        wall[pick[first]] = RAIN
    water_hit = down & water_returns
    if water_share is not None:
        share = np.full(t.size, float(water_share[0]))
        if len(water_share) == 4:
            share[lam * np.hypot(d_body[:, 0], d_body[:, 1]) > water_share[2]] = water_share[3]
        water_hit &= np.random.default_rng(water_share[1]).random(t.size) < share
    hit = (
        (water_hit | (wall >= 0) | (wall == RAIN))
        & (lam > 0.5)
        & (lam * np.hypot(d_body[:, 0], d_body[:, 1]) <= max_range)
    )
    xyz_body = o_body[hit] + lam[hit, None] * d_body[hit]
    xyz_world = o_world[hit] + lam[hit, None] * d_world[hit]
    return WaterReturns(xyz_body, t[hit], RING_OF_LASER[laser[hit]], xyz_world, wall[hit])


G = 9.81  # m/s^2
# chop's trains: amplitude (m), wavenumber north and east (rad/m), phase (rad)
_CHOP_TRAINS = ((0.15, 0.52, 0.31, 0.4), (0.10, -0.35, 0.80, 2.0), (0.05, 1.30, -0.90, 1.1))


def chop(north: np.ndarray, east: np.ndarray) -> np.ndarray:
    """Three wave trains standing still, crests up to +-0.3 m about the mean water (the simulator's sea state 3)."""
    return travelling_chop(0.0)(north, east)


def travelling_chop(t: float) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """``chop`` at time t, its trains travelling at the deep-water phase speed sqrt(g / k) (4.0, 3.4 and 2.5 m/s) as a
    sea's do: where a beam meets a crest or a trough moves from one revolution to the next. Frozen within the
    revolution (a crest moves 0.4 m at most in its 0.1 s)."""

    def elevation(north: np.ndarray, east: np.ndarray) -> np.ndarray:
        total = np.zeros(np.broadcast(north, east).shape)
        for amplitude, k_north, k_east, phase in _CHOP_TRAINS:
            omega = math.sqrt(G * math.hypot(k_north, k_east))
            total = total + amplitude * np.sin(k_north * north + k_east * east - omega * t + phase)
        return total

    return elevation


class SteadyEgo:
    """The autopilot's pose: at the origin, heading ``yaw``, roll and pitch from ``attitude(t)``."""

    epoch = 1
    available = True

    def __init__(self, attitude: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], yaw: float) -> None:
        self.attitude = attitude
        self.yaw = yaw

    def at_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        times = np.asarray(times, float)
        roll, pitch = self.attitude(times)
        n = times.size
        return (
            np.zeros((n, 3)),
            np.broadcast_to(roll, (n,)) * 1.0,
            np.broadcast_to(pitch, (n,)) * 1.0,
            np.full(n, self.yaw),
        )

    def at(self, t: float) -> EgoPose:
        roll, pitch = self.attitude(np.array([t]))
        return EgoPose(t, np.zeros(3), np.zeros(3), float(np.ravel(roll)[0]), float(np.ravel(pitch)[0]), self.yaw)


def wall_ring(start_deg: float, stop_deg: float, step_deg: float, radius: float = 30.0, height: float = 2.0) -> tuple:
    """Walls (for revolution_over_water) joining the points ``radius`` m off at bearings start..stop deg (world
    frame, every ``step_deg``): a basin all round, or with an opening."""
    ring = np.radians(np.arange(start_deg, stop_deg, step_deg))
    corners = np.column_stack([radius * np.cos(ring), radius * np.sin(ring)])
    return tuple((tuple(a), tuple(b), height) for a, b in itertools.pairwise(corners.tolist()))


def clear_to_11_m_config(mount: Mount) -> Config:
    """The shipped config, LiDAR only at ``mount``'s height, sending "clear" only where vouched from 4.2 m (past the
    lowest beam's gap near the boat) out to a max_distance of 11 m, so the beams can vouch for whole bins."""
    config = Config()
    config.lidar.mount.z = mount.z
    config.radar.enabled = False
    config.output.clear_inner_m, config.output.max_distance_m = 4.2, 11.0
    return config


def lidar_pipeline(mount: Mount) -> PerceptionPipeline:
    """The pipeline as `usv-tracker run` builds it on the shipped defaults, LiDAR only, at ``mount``'s height."""
    config = Config()
    config.lidar.mount.z = mount.z
    config.radar.enabled = False
    return pipeline_for(config)


def scan_of(ret: WaterReturns, stamp: float, intensity: float = 4.0) -> LidarScan:
    n = ret.t.size
    return LidarScan(stamp, stamp, ret.xyz_body, np.full(n, intensity, np.float32), ret.ring, ret.t)
