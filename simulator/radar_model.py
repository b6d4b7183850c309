"""What a TI AWR1843 (out-of-box demo point cloud) on the own boat would report, frame by frame.

This is a phenomenological model, not a ray tracer: a mmWave radar returns a handful of CFAR detections per object,
mostly from the sides that face it, so each frame samples points on the visible hull edges (more for long and near
hulls), gives each one the Doppler of the relative motion along the line of sight, an SNR that falls with R^4, and
then adds what makes radar tracking hard on the water (paper 001, §1): sea clutter near the boat, multipath ghosts
(a weaker copy further out on the same bearing) and many returns from the quay, whose Doppler is the own boat's
motion seen from a fixed wall.

Output is in TI's axes (x right, y boresight, z up), Doppler positive = moving away, as the demo firmware sends it.
Every frame's randomness depends only on ``seed`` and the frame number, so frames are reproducible in any order.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from drivers.mount import TI_TO_FRD, Mount
from simulator.scene import LABEL_CLUTTER, LABEL_GHOST, LABEL_SHORE, Prisms, Scene
from tracker.ego import rotation_matrices

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RadarDetections:
    """One radar frame's point cloud plus what each point really is (``label``, ``xyz_world``) for tests."""

    t: float  # frame time, simulation clock, s
    frame_index: int
    xyz_ti: np.ndarray  # (N, 3) m, TI axes: x right, y boresight, z up (with measurement noise)
    doppler: np.ndarray  # (N,) m/s, positive = moving away (with noise, aliased into [-v_max, v_max))
    snr_db: np.ndarray  # (N,)
    noise_db: np.ndarray  # (N,)
    label: np.ndarray  # (N,) vessel index, LABEL_CLUTTER, LABEL_GHOST or LABEL_SHORE
    xyz_world: np.ndarray  # (N, 3) NED, where the echo appears without noise (ghosts: their apparent position)
    doppler_true: np.ndarray  # (N,) noise-free, unaliased radial velocity, m/s
    ghost_of: np.ndarray  # (N,) index of the point a ghost copies, -1 for everything else

    @property
    def n_points(self) -> int:
        return int(self.doppler.shape[0])


@dataclass(frozen=True)
class _SensorPose:
    position: np.ndarray  # (3,) world NED
    rotation: np.ndarray  # (3, 3) sensor-FRD -> world
    velocity: np.ndarray  # (3,) world, including the lever arm of the own yaw rate


class Awr1843Model:
    """Simulated AWR1843 point cloud. Angles in degrees only in the constructor (like a cfg file); radians inside.

    ``snr_at_10m_db`` is the SNR of a 1 m high, face-on hull side at 10 m; it falls with 40 log10(range) and with the
    cosine of the incidence angle. Points below ``snr_threshold_db`` (the CFAR threshold) are not reported, which is
    what limits the range on small boats. ``points_per_metre`` of visible hull side at <= 20 m (fewer further out),
    1..``max_points_per_vessel`` per vessel.
    """

    def __init__(
        self,
        scene: Scene,
        mount: Mount | None = None,
        fov_deg: float = 60.0,
        elevation_fov_deg: float = 20.0,
        max_range: float = 50.0,
        min_range: float = 0.3,
        range_noise_m: float = 0.05,
        azimuth_noise_deg: float = 1.0,
        elevation_noise_deg: float = 2.0,
        doppler_noise: float = 0.05,
        v_max: float = 8.0,
        alias: bool = True,
        seed: int = 0,
        frame_period: float = 0.1,
        snr_threshold_db: float = 15.0,
        snr_at_10m_db: float = 45.0,
        snr_fading_db: float = 2.0,
        detect_probability: float = 0.9,
        points_per_metre: float = 1.5,
        max_points_per_vessel: int = 10,
        clutter_per_frame: float = 3.0,
        clutter_range: float = 8.0,
        ghost_probability: float = 0.1,
        ghost_loss_db: float = 9.0,
        shore_spacing: float = 0.5,
        shore_keep: float = 0.35,
        report_elevation: bool = True,
    ) -> None:
        if frame_period <= 0 or max_range <= min_range or v_max <= 0:
            raise ValueError("need frame_period > 0, max_range > min_range and v_max > 0")
        self.scene = scene
        self.mount = mount if mount is not None else scene.radar_mount
        self.fov = math.radians(fov_deg)
        self.elevation_fov = math.radians(elevation_fov_deg)
        self.max_range, self.min_range = float(max_range), float(min_range)
        self.range_noise_m = float(range_noise_m)
        self.azimuth_noise = math.radians(azimuth_noise_deg)
        self.elevation_noise = math.radians(elevation_noise_deg)
        self.doppler_noise = float(doppler_noise)
        self.v_max, self.alias = float(v_max), alias
        self.seed = int(seed)
        self.frame_period = float(frame_period)
        self.snr_threshold_db = float(snr_threshold_db)
        self.snr_at_10m_db = float(snr_at_10m_db)
        self.snr_fading_db = float(snr_fading_db)
        self.detect_probability = float(detect_probability)
        self.points_per_metre = float(points_per_metre)
        self.max_points_per_vessel = int(max_points_per_vessel)
        self.clutter_per_frame = float(clutter_per_frame)
        self.clutter_range = float(clutter_range)
        self.ghost_probability = float(ghost_probability)
        self.ghost_loss_db = float(ghost_loss_db)
        self.report_elevation = report_elevation
        self.shore_keep = float(shore_keep)
        self._shore = _sample_quay(scene, shore_spacing)
        self._vessel_height = np.array([v.height for v in scene.vessels], float)
        self._vessel_rcs = np.array([v.rcs_scale for v in scene.vessels], float)
        log.debug(
            "AWR1843 model on %r: +-%.0f deg, %.0f m, %d shore scatterers",
            scene.name,
            fov_deg,
            max_range,
            self._shore[0].shape[0],
        )

    # -- public API ------------------------------------------------------------------------------------------------
    def frames(self, t0: float, t1: float) -> Iterator[RadarDetections]:
        """Frames on the grid t = k * frame_period with t in [t0, t1)."""
        if not (math.isfinite(t0) and math.isfinite(t1)):
            raise ValueError(f"radar frame times must be finite, got {t0}, {t1}")
        k_lo = math.ceil(t0 / self.frame_period - 1e-9)
        k_hi = math.ceil(t1 / self.frame_period - 1e-9)
        for k in range(k_lo, k_hi):
            yield self.frame(k * self.frame_period, k)

    def frame(self, t: float, frame_index: int | None = None) -> RadarDetections:
        """The frame at time ``t``; its randomness is keyed on ``frame_index`` (default: round(t / frame_period))."""
        if not math.isfinite(t):
            raise ValueError(f"radar frame time must be finite, got {t}")
        k = round(t / self.frame_period) if frame_index is None else int(frame_index)
        rng = np.random.default_rng([self.seed, k % (1 << 62), 0xA18])
        pose = self._sensor_pose(t)
        verts = self.scene.footprints(t)[0] if self.scene.vessels else np.zeros((0, 5, 2))
        parts = [
            self._vessel_points(t, verts, pose, rng),
            self._shore_points(pose, rng),
            self._clutter_points(pose, rng),
        ]
        pw = np.concatenate([p[0] for p in parts])  # world scatter positions (N, 3)
        vw = np.concatenate([p[1] for p in parts])  # their world velocities (N, 3)
        snr_extra = np.concatenate([p[2] for p in parts])  # dB relative to the 10 m reference, before range loss
        label = np.concatenate([p[3] for p in parts]).astype(np.int64)
        blocked = self._occluded(pose.position, pw, label, self.scene.prisms_at(t))

        frd = (pw - pose.position) @ pose.rotation  # world -> sensor FRD (rotation is orthonormal)
        ti = frd @ TI_TO_FRD  # sensor FRD -> TI (the axis map is its own inverse)
        rng_m, az, el = _spherical(ti)
        with np.errstate(divide="ignore"):
            los = (pw - pose.position) / rng_m[:, None]
        doppler = np.sum((vw - pose.velocity) * los, axis=1)
        snr = snr_extra - 40.0 * np.log10(np.maximum(rng_m, 0.1) / 10.0)
        snr += rng.normal(0.0, self.snr_fading_db, snr.shape)
        clutter = label == LABEL_CLUTTER
        snr[clutter] = rng.uniform(self.snr_threshold_db, self.snr_threshold_db + 8.0, int(clutter.sum()))
        seen = (
            ~blocked
            & (rng_m >= self.min_range)
            & (rng_m <= self.max_range)
            & (np.abs(az) <= self.fov)
            & (np.abs(el) <= self.elevation_fov)
            & (snr >= self.snr_threshold_db)
            & ((rng.random(snr.shape) < self.detect_probability) | clutter)
        )
        pw, label, rng_m, az, el, doppler, snr = (a[seen] for a in (pw, label, rng_m, az, el, doppler, snr))
        ghost_of = np.full(label.shape, -1, dtype=np.int64)

        # multipath: a weaker echo of a vessel point further out on the same bearing, same Doppler
        src = np.flatnonzero((label >= 0) & (rng.random(label.shape) < self.ghost_probability))
        if src.size:
            g_range = rng_m[src] * rng.uniform(1.25, 1.9, src.size)
            g_snr = snr[src] - self.ghost_loss_db - 40.0 * np.log10(g_range / rng_m[src]) / 2
            ok = (g_range <= self.max_range) & (g_snr >= self.snr_threshold_db)
            src, g_range, g_snr = src[ok], g_range[ok], g_snr[ok]
            g_pw = pose.position + (pw[src] - pose.position) * (g_range / rng_m[src])[:, None]
            pw = np.concatenate([pw, g_pw])
            label = np.concatenate([label, np.full(src.size, LABEL_GHOST)])
            rng_m = np.concatenate([rng_m, g_range])
            az, el = np.concatenate([az, az[src]]), np.concatenate([el, el[src]])
            doppler = np.concatenate([doppler, doppler[src]])
            snr = np.concatenate([snr, g_snr])
            ghost_of = np.concatenate([ghost_of, src])

        # measurement noise and the radar's own limits
        n = label.shape[0]
        m_range = rng_m + rng.normal(0.0, self.range_noise_m, n)
        m_az = az + rng.normal(0.0, self.azimuth_noise, n)
        m_el = el + rng.normal(0.0, self.elevation_noise, n) if self.report_elevation else np.zeros(n)
        xyz_ti = np.stack(
            [m_range * np.cos(m_el) * np.sin(m_az), m_range * np.cos(m_el) * np.cos(m_az), m_range * np.sin(m_el)],
            axis=-1,
        )
        m_doppler = doppler + rng.normal(0.0, self.doppler_noise, n)
        if self.alias:
            m_doppler = np.mod(m_doppler + self.v_max, 2 * self.v_max) - self.v_max
        noise_db = 64.0 + 14.0 * np.exp(-rng_m / 4.0) + rng.normal(0.0, 1.5, n)
        return RadarDetections(
            t=float(t),
            frame_index=k,
            xyz_ti=xyz_ti,
            doppler=m_doppler,
            snr_db=snr,
            noise_db=noise_db,
            label=label,
            xyz_world=pw,
            doppler_true=doppler,
            ghost_of=ghost_of,
        )

    # -- point sources ----------------------------------------------------------------------------------------------
    def _sensor_pose(self, t: float) -> _SensorPose:
        own = self.scene.own.poses(t)
        r_wb = rotation_matrices(own.roll, own.pitch, own.yaw)[0]
        lever = r_wb @ self.mount.translation
        position = np.array([own.position[0, 0], own.position[0, 1], 0.0]) + lever
        w = own.yaw_rate[0]
        velocity = np.array([own.velocity[0, 0] - w * lever[1], own.velocity[0, 1] + w * lever[0], 0.0])
        return _SensorPose(position, r_wb @ self.mount.rotation, velocity)

    def _vessel_points(
        self, t: float, verts: np.ndarray, pose: _SensorPose, rng: np.random.Generator
    ) -> tuple[np.ndarray, ...]:
        """Points on the hull sides that face the radar: (world xyz, world velocity, snr offset, label)."""
        if not self.scene.vessels:
            return _empty()
        state = self.scene.vessel_states(t)
        a, b = verts, np.roll(verts, -1, axis=1)
        edge = b - a
        length = np.hypot(edge[..., 0], edge[..., 1])
        normal = np.stack([edge[..., 1], -edge[..., 0]], -1) / np.where(length > 0, length, 1.0)[..., None]
        to_sensor = pose.position[:2] - (a + b) / 2
        facing = (length > 0) & (np.sum(normal * to_sensor, axis=-1) > 0)
        facing_len = np.where(facing, length, 0.0)
        total = facing_len.sum(axis=1)  # (V,)
        centre = state.position[0]
        dist = np.hypot(*(centre - pose.position[:2]).T)
        count = np.rint(self.points_per_metre * total * np.minimum(1.0, 20.0 / np.maximum(dist, 1e-3)))
        count = np.where(total > 0, np.clip(count, 1, self.max_points_per_vessel), 0).astype(np.int64)
        n = int(count.sum())
        if n == 0:
            return _empty()
        # draw positions uniformly along each vessel's facing sides laid end to end
        owner = np.repeat(np.arange(len(count)), count)
        flat_len = facing_len.ravel()
        cum_end = np.cumsum(flat_len)
        vessel_start = np.concatenate([[0.0], np.cumsum(total)[:-1]])
        g = vessel_start[owner] + rng.random(n) * total[owner]
        e = np.minimum(np.searchsorted(cum_end, g, side="right"), flat_len.size - 1)
        e = np.where(flat_len[e] > 0, e, np.maximum(e - 1, 0))
        frac = np.clip((g - (cum_end[e] - flat_len[e])) / np.where(flat_len[e] > 0, flat_len[e], 1.0), 0.0, 1.0)
        p2 = a.reshape(-1, 2)[e] + frac[:, None] * edge.reshape(-1, 2)[e]
        height = self._vessel_height[owner] * rng.uniform(0.15, 0.9, n)
        pw = np.concatenate([p2, -height[:, None]], axis=1)
        # rigid-body velocity of the scatterer: v + omega x r, omega = yaw_rate about the down axis
        r = p2 - centre[owner]
        w = state.yaw_rate[0][owner]
        vel = state.velocity[0][owner] + np.stack([-w * r[:, 1], w * r[:, 0]], -1)
        vw = np.concatenate([vel, np.zeros((n, 1))], axis=1)
        los2 = p2 - pose.position[:2]
        cos_inc = np.abs(np.sum(normal.reshape(-1, 2)[e] * los2, axis=1)) / np.maximum(np.hypot(*los2.T), 1e-6)
        snr = (
            self.snr_at_10m_db
            + 10 * np.log10(np.maximum(self._vessel_height[owner], 0.3) * self._vessel_rcs[owner])
            + 10 * np.log10(np.maximum(cos_inc, 0.1))
        )
        return pw, vw, snr, owner

    def _shore_points(self, pose: _SensorPose, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
        """Echoes off the quay walls facing the radar; a fixed wall has no Doppler of its own."""
        pts, normals, heights = self._shore
        if pts.shape[0] == 0:
            return _empty()
        to_sensor = pose.position[:2] - pts
        dist = np.hypot(*to_sensor.T)
        cos_inc = np.sum(normals * to_sensor, axis=1) / np.maximum(dist, 1e-6)
        keep = (cos_inc > 0) & (dist <= self.max_range + 1.0) & (rng.random(dist.shape) < self.shore_keep)
        p2, h, cos_inc = pts[keep], heights[keep], cos_inc[keep]
        n = p2.shape[0]
        pw = np.concatenate([p2, -(h * rng.uniform(0.1, 0.95, n))[:, None]], axis=1)
        snr = self.snr_at_10m_db + 10 * np.log10(np.maximum(h, 0.3)) + 10 * np.log10(np.maximum(cos_inc, 0.1))
        return pw, np.zeros((n, 3)), snr, np.full(n, LABEL_SHORE)

    def _clutter_points(self, pose: _SensorPose, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
        """Sea clutter: a few near-range echoes off the water, moving slowly with the waves."""
        n = rng.poisson(self.clutter_per_frame) if self.clutter_per_frame > 0 else 0
        if n == 0:
            return _empty()
        az = rng.uniform(-self.fov, self.fov, n)
        r = rng.uniform(1.0, self.clutter_range, n)
        d = np.stack([np.cos(az), np.sin(az), np.zeros(n)], -1) @ pose.rotation.T  # sensor FRD -> world
        d2 = d[:, :2] / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)[:, None]
        pw = np.concatenate([pose.position[:2] + r[:, None] * d2, np.zeros((n, 1))], axis=1)
        vw = np.concatenate([rng.normal(0.0, 0.2, (n, 2)), np.zeros((n, 1))], axis=1)
        return pw, vw, np.zeros(n), np.full(n, LABEL_CLUTTER)

    @staticmethod
    def _occluded(sensor: np.ndarray, points: np.ndarray, owner: np.ndarray, prisms: Prisms) -> np.ndarray:
        """True where the sight line sensor->point passes through a prism (hull, cabin, quay block) of another owner.

        In 3-D: the line crosses a prism's side where its footprint edge is cut, and is blocked only if its height
        there lies between the prism's bottom and top. A radar 0.9 m up sees a 3 m cabin over a 0.6 m dinghy, and
        only the low returns of a boat behind a 1 m hull are lost. Sea clutter (a water return) is never blocked.
        """
        n = points.shape[0]
        verts = prisms.vertices[0]  # (P, K, 2) world (north, east)
        if n == 0 or verts.shape[0] == 0:
            return np.zeros(n, bool)
        a = verts.reshape(-1, 2)
        s = np.roll(verts, -1, axis=1).reshape(-1, 2) - a  # (S, 2) edge vectors
        k = verts.shape[1]
        seg_owner, seg_bottom, seg_top = (np.repeat(x, k) for x in (prisms.label, prisms.bottom, prisms.top))
        r = points[:, :2] - sensor[:2]  # (N, 2)
        denom = r[:, None, 0] * s[None, :, 1] - r[:, None, 1] * s[None, :, 0]  # cross(r, s)
        qp = a[None, :, :] - sensor[:2]  # (1, S, 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            t_ray = (qp[..., 0] * s[None, :, 1] - qp[..., 1] * s[None, :, 0]) / denom
            u_seg = (qp[..., 0] * r[:, None, 1] - qp[..., 1] * r[:, None, 0]) / denom
        crosses = (np.abs(denom) > 1e-12) & (t_ray > 0) & (t_ray < 1 - 1e-6) & (u_seg >= 0) & (u_seg <= 1)
        crosses &= (seg_owner[None, :] != owner[:, None]) & (owner[:, None] != LABEL_CLUTTER)
        # world z is down: heights above the water are -z
        h_sensor, h_point = -sensor[2], -points[:, 2]
        h_cross = h_sensor + np.where(crosses, t_ray, 0.0) * (h_point - h_sensor)[:, None]
        crosses &= (h_cross >= seg_bottom[None, :]) & (h_cross <= seg_top[None, :])
        return np.any(crosses, axis=1)


def _empty() -> tuple[np.ndarray, ...]:
    return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64)


def _spherical(ti: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """TI (x right, y boresight, z up) -> range, azimuth (atan2(x, y), positive to the right), elevation."""
    rng_m = np.linalg.norm(ti, axis=1)
    az = np.arctan2(ti[:, 0], ti[:, 1])
    el = np.arcsin(np.clip(ti[:, 2] / np.maximum(rng_m, 1e-9), -1.0, 1.0))
    return rng_m, az, el


def _sample_quay(scene: Scene, spacing: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fixed candidate scatterers along every quay wall: positions (M, 2), water-side normals (M, 2), heights (M,)."""
    pts, normals, heights = [], [], []
    for q in scene.quays:
        a, b = q.wall_segments()
        water = -q.land_normals()
        for i in range(a.shape[0]):  # per wall segment (a few), not per point
            length = float(np.hypot(*(b[i] - a[i])))
            k = max(int(length // spacing), 1)
            f = (np.arange(k) + 0.5) / k
            pts.append(a[i] + f[:, None] * (b[i] - a[i]))
            normals.append(np.broadcast_to(water[i], (k, 2)))
            heights.append(np.full(k, q.height))
    if not pts:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0)
    return np.concatenate(pts), np.concatenate(normals), np.concatenate(heights)
