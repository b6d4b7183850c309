"""What a Velodyne VLP-16 on the own boat would measure in a simulated scene, packet by packet.

Every one of the 16 lasers fires every 55.296 us (vlp16.md §4); each firing is cast as its own ray, at its own time,
from the own boat's pose at that instant, so the motion smear a real sensor produces (the boat moves and rolls
during a 100 ms sweep) is in the data and the tracker's per-point de-skewing is exercised. Vessels are placed once
per packet (1.3 ms; a 5 m/s boat moves 7 mm in that time).

The rays are cast from each laser's own origin (the vertical offset of vlp16.md §3) along the true, continuous
rotor angle, so a decoder that applies the spec's offsets places a noise-free return exactly on the surface it hit;
what is left is the 2 mm distance unit and the 0.01 deg block-azimuth rounding of the packet format (<= 0.005 deg of
interpolation error for sequence B and later lasers).

Geometry: every solid is a vertical convex prism (scene.Prisms); a ray meets it where it enters the intersection of
the prism's half-spaces (Cyrus-Beck clipping), which covers side walls, the top (decks, the quay's land) and the water
plane (rays that reach the water end there: calm water returns nothing). Prisms outside a packet's azimuth sector are
culled first, so the cost follows what is in view, not the size of the scene.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from drivers.mount import FLU_TO_FRD, Mount
from simulator.scene import LABEL_CLUTTER, LABEL_RAIN, LABEL_WATER, Scene, wrap_angle

log = logging.getLogger(__name__)

ELEVATION_DEG = np.array([-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15], float)
VERTICAL_OFFSET_M = (
    np.array([11.2, -0.7, 9.7, -2.2, 8.1, -3.7, 6.6, -5.1, 5.1, -6.6, 3.7, -8.1, 2.2, -9.7, 0.7, -11.2]) * 1e-3
)
LASER_PERIOD_S = 2.304e-6
SEQUENCE_PERIOD_S = 55.296e-6
SEQUENCES_PER_PACKET = 24
PACKET_PERIOD_S = SEQUENCES_PER_PACKET * SEQUENCE_PERIOD_S  # 1327.104 us
RAYS_PER_PACKET = SEQUENCES_PER_PACKET * 16
HOUR_US = 3_600_000_000
LABEL_NONE = -99  # no return

_ELEV = np.radians(ELEVATION_DEG)
# Firing time of (sequence s, laser id) relative to the packet's first firing (vlp16.md §4).
_RAY_OFFSET_S = (
    np.arange(SEQUENCES_PER_PACKET)[:, None] * SEQUENCE_PERIOD_S + np.arange(16)[None, :] * LASER_PERIOD_S
).ravel()
_RAY_LASER = np.tile(np.arange(16), SEQUENCES_PER_PACKET)


@dataclass(frozen=True)
class PacketContent:
    """Everything ``drivers.vlp16.packet.encode_data_packet`` needs for one single-return data packet.

    Channel c of block k: laser c % 16, sequence 2k + (c >= 16). ``label`` is not in the packet; it tells tests and
    benchmarks what each return hit (vessel index, LABEL_SHORE, LABEL_CLUTTER, LABEL_NONE).
    """

    t: float  # time of the packet's first firing, simulation (host) clock, s
    block_azimuth_cdeg: np.ndarray  # (12,) uint16, 0..35999
    distance_m: np.ndarray  # (12, 32) float64, 0 = no return
    reflectivity: np.ndarray  # (12, 32) uint8
    timestamp_us: int  # microseconds past the hour on the sensor clock
    index: int = 0  # packet number on the simulation's packet grid (t = index * 1327.104 us)
    label: np.ndarray | None = None  # (12, 32) int


@dataclass(frozen=True)
class LidarHits:
    """Ideal (noise-free) returns of a stretch of firings, one row per return."""

    t: np.ndarray  # (N,) firing time, s
    laser: np.ndarray  # (N,) laser id 0..15 (vlp16.md §3 order, not ring)
    azimuth: np.ndarray  # (N,) rotor angle, rad, clockwise from the sensor's forward axis
    distance: np.ndarray  # (N,) m, from the laser's origin
    xyz_sensor: np.ndarray  # (N, 3) sensor native FLU, m (vertical offset included)
    xyz_body: np.ndarray  # (N, 3) own-boat body FRD, m
    xyz_world: np.ndarray  # (N, 3) world NED, m
    label: np.ndarray  # (N,) vessel index or LABEL_SHORE

    @property
    def n_points(self) -> int:
        return int(self.t.shape[0])


@dataclass(frozen=True)
class _Firings:
    """Ideal result of casting every ray of ``n`` consecutive packets; per-ray arrays are (n * 384,)."""

    first_packet: int
    packet_t: np.ndarray  # (n,)
    t: np.ndarray
    laser: np.ndarray
    azimuth: np.ndarray
    origin_world: np.ndarray  # (R, 3)
    direction_world: np.ndarray  # (R, 3)
    distance: np.ndarray  # (R,) inf = no hit
    label: np.ndarray  # (R,)
    reflectivity: np.ndarray  # (R,) base reflectivity of what was hit, after the incidence falloff
    water: np.ndarray  # (R,) distance to the sea surface where it comes before any solid, else inf
    grazing: np.ndarray  # (R,) rad below the horizon the ray meets the water at (0 for rays that do not)


class Vlp16Model:
    """Ray-casting VLP-16 (single return, strongest) mounted on the scene's own boat.

    ``spray_rate`` is the mean number of spurious water/spray returns per second (a few per revolution at 600 rpm),
    placed 0.8..``spray_max_range`` m out on downward beams. ``dropout`` is the probability that a genuine return is
    lost (dark or wet surfaces); ``laser_dropout`` that one laser returns nothing for a whole batch of packets
    (0.1 s: a wet or fouled window); ``packet_loss`` that a data packet never arrives. Each of these not given
    is taken from ``scene.conditions``. The scene's sea
    (simulator/sea.py) decides what the water and the rain return: a firing that meets the water before any solid
    ends there, returning from it with the sea's probability for its grazing angle. Packet times are on a fixed grid,
    t = k * 1327.104 us of the simulation clock, and the randomness of a packet depends only on ``seed`` and its
    number, so the stream is reproducible however the caller slices ``packets()``.
    """

    def __init__(
        self,
        scene: Scene,
        mount: Mount | None = None,
        rpm: float = 600.0,
        range_noise_m: float = 0.02,
        seed: int = 0,
        spray_rate: float | None = None,
        spray_max_range: float = 5.0,
        max_range: float | None = None,
        min_range: float = 0.5,
        dropout: float | None = None,
        azimuth0_deg: float = 0.0,
        device_clock_offset_s: float = 0.0,
        batch_packets: int = 76,
        laser_dropout: float | None = None,
        packet_loss: float | None = None,
    ) -> None:
        c = scene.conditions  # a value not given is the scene's own
        spray_rate = c.lidar_spray_rate if spray_rate is None else spray_rate
        max_range = c.lidar_max_range if max_range is None else max_range
        dropout = c.lidar_dropout if dropout is None else dropout
        laser_dropout = c.lidar_laser_dropout if laser_dropout is None else laser_dropout
        packet_loss = c.lidar_packet_loss if packet_loss is None else packet_loss
        if not 300 <= rpm <= 1200:
            raise ValueError(f"VLP-16 rpm must be 300..1200, got {rpm}")
        if not (0 <= dropout < 1 and 0 <= laser_dropout < 1 and 0 <= packet_loss < 1):
            raise ValueError("dropout, laser_dropout and packet_loss must be in [0, 1)")
        self.laser_dropout = float(laser_dropout)
        self.packet_loss = float(packet_loss)
        self.scene = scene
        self.mount = mount if mount is not None else scene.lidar_mount
        self.rpm = float(rpm)
        self.range_noise_m = float(range_noise_m)
        self.seed = int(seed)
        self.spray_rate = float(spray_rate)
        self.spray_max_range = float(spray_max_range)
        self.max_range = float(max_range)
        self.min_range = float(min_range)
        self.dropout = float(dropout)
        self.azimuth0 = math.radians(azimuth0_deg)
        self.device_clock_offset_s = float(device_clock_offset_s)
        self.batch_packets = int(batch_packets)
        self._omega = 2 * math.pi * self.rpm / 60.0  # rad/s, clockwise seen from above
        # sensor FLU -> body FRD, for directions and for each laser's origin
        self._flu_to_body = self.mount.rotation @ FLU_TO_FRD
        origin_flu = np.zeros((16, 3))
        origin_flu[:, 2] = VERTICAL_OFFSET_M
        self._origin_body = origin_flu @ self._flu_to_body.T + self.mount.translation
        self._cache: tuple[int, dict[str, np.ndarray]] | None = None
        log.debug(
            "VLP-16 model on %r: %.0f rpm, noise %.3f m, spray %.0f/s, %d prisms",
            scene.name,
            self.rpm,
            self.range_noise_m,
            self.spray_rate,
            scene.prisms_at(0.0).label.size,
        )

    @property
    def revolution_period(self) -> float:
        return 60.0 / self.rpm

    def azimuth_at(self, t: np.ndarray | float) -> np.ndarray:
        """Rotor angle (rad, [0, 2 pi), clockwise from sensor forward) at time ``t``."""
        return np.mod(self.azimuth0 + self._omega * np.asarray(t, float), 2 * math.pi)

    # -- public API ------------------------------------------------------------------------------------------------
    def packets(self, t0: float, t1: float) -> Iterator[PacketContent]:
        """Data packets whose first firing lies in [t0, t1), in order."""
        _check_times(t0, t1)
        k_lo = math.ceil(t0 / PACKET_PERIOD_S - 1e-9)
        k_hi = math.ceil(t1 / PACKET_PERIOD_S - 1e-9)
        for k in range(k_lo, k_hi):
            batch, i = divmod(k, self.batch_packets)
            data = self._batch(batch)
            if data["lost"][i]:
                continue
            yield PacketContent(
                t=float(data["t"][i]),
                block_azimuth_cdeg=data["azimuth"][i].copy(),
                distance_m=data["distance"][i].copy(),
                reflectivity=data["reflectivity"][i].copy(),
                timestamp_us=int(data["timestamp"][i]),
                index=k,
                label=data["label"][i].copy(),
            )

    def revolution_points(self, t: float) -> LidarHits:
        """Noise-free returns of the firings in [t, t + one revolution): no range noise, spray or dropout."""
        _check_times(t)
        t_end = t + self.revolution_period
        k_lo = math.floor(t / PACKET_PERIOD_S)
        k_hi = math.ceil(t_end / PACKET_PERIOD_S)
        f = self._fire(k_lo, k_hi - k_lo)
        keep = (f.t >= t) & (f.t < t_end) & np.isfinite(f.distance)
        return self._hits(f, keep)

    def hits_between(self, t0: float, t1: float) -> LidarHits:
        """Noise-free returns of the firings in [t0, t1) (any span; revolution_points is the one-turn case)."""
        _check_times(t0, t1)
        k_lo = math.floor(t0 / PACKET_PERIOD_S)
        k_hi = math.ceil(t1 / PACKET_PERIOD_S)
        f = self._fire(k_lo, max(k_hi - k_lo, 0))
        keep = (f.t >= t0) & (f.t < t1) & np.isfinite(f.distance)
        return self._hits(f, keep)

    # -- internals --------------------------------------------------------------------------------------------------
    def _hits(self, f: _Firings, keep: np.ndarray) -> LidarHits:
        keep = keep & (f.distance >= self.min_range) & (f.distance <= self.max_range)
        d = f.distance[keep]
        laser = f.laser[keep]
        az = f.azimuth[keep]
        cos_e = np.cos(_ELEV[laser])
        xyz_sensor = np.stack(
            [d * cos_e * np.cos(az), -d * cos_e * np.sin(az), d * np.sin(_ELEV[laser]) + VERTICAL_OFFSET_M[laser]],
            axis=-1,
        )
        xyz_body = (xyz_sensor @ FLU_TO_FRD.T) @ self.mount.rotation.T + self.mount.translation
        xyz_world = f.origin_world[keep] + d[:, None] * f.direction_world[keep]
        return LidarHits(f.t[keep], laser, az, d, xyz_sensor, xyz_body, xyz_world, f.label[keep])

    def _batch(self, batch: int) -> dict[str, np.ndarray]:
        """Noisy packet contents of one aligned batch of packets, cached because callers walk forward in time."""
        if self._cache is not None and self._cache[0] == batch:
            return self._cache[1]
        n = self.batch_packets
        f = self._fire(batch * n, n)
        rng = np.random.default_rng([self.seed, batch % (1 << 62), 0x1D4A])
        rays = n * RAYS_PER_PACKET
        distance = f.distance.copy()
        label = f.label.copy()
        refl = f.reflectivity.copy()
        hit = np.isfinite(distance)
        if self.range_noise_m > 0:
            distance[hit] += rng.normal(0.0, self.range_noise_m, int(hit.sum()))
        if self.dropout > 0:
            lost = hit & (rng.random(rays) < self.dropout)
            distance[lost] = np.inf
            label[lost] = LABEL_NONE
        refl = np.where(hit, refl + rng.normal(0.0, 2.0, rays), refl)
        # water and spray: a few weak returns close to the boat on the downward beams
        n_spray = rng.poisson(self.spray_rate * n * PACKET_PERIOD_S) if self.spray_rate > 0 else 0
        if n_spray:
            down = np.flatnonzero(ELEVATION_DEG[f.laser] < 0)
            idx = rng.choice(down, size=min(n_spray, len(down)), replace=False)
            r = rng.uniform(0.8, self.spray_max_range, len(idx))
            closer = r < distance[idx]
            idx, r = idx[closer], r[closer]
            distance[idx] = r
            label[idx] = LABEL_CLUTTER
            refl[idx] = rng.uniform(1.0, 8.0, len(idx))
        lost = self._sea_and_faults(batch, f, distance, label, refl)
        valid = np.isfinite(distance) & (distance >= self.min_range) & (distance <= self.max_range)
        distance = np.where(valid, distance, 0.0)
        label = np.where(valid, label, LABEL_NONE)
        refl = np.where(valid, np.clip(np.rint(refl), 1, 255), 0).astype(np.uint8)

        # (packet, sequence 24, laser 16) -> (packet, block 12, channel 32): channel = 16 * (sequence odd) + laser
        block_t = f.packet_t[:, None] + np.arange(12)[None, :] * 2 * SEQUENCE_PERIOD_S
        az_cdeg = np.rint(np.degrees(self.azimuth_at(block_t)) * 100).astype(np.int64) % 36000
        device_us = np.rint((f.packet_t + self.device_clock_offset_s) * 1e6).astype(np.int64) % HOUR_US
        data = {
            "t": f.packet_t,
            "azimuth": az_cdeg.astype(np.uint16),
            "distance": distance.reshape(n, 12, 32),
            "reflectivity": refl.reshape(n, 12, 32),
            "label": label.reshape(n, 12, 32),
            "timestamp": device_us,
            "lost": lost,
        }
        self._cache = (batch, data)
        return data

    def _sea_and_faults(
        self, batch: int, f: _Firings, distance: np.ndarray, label: np.ndarray, refl: np.ndarray
    ) -> np.ndarray:
        """Water and rain returns, dead lasers (in place); returns which packets of the batch are lost.

        Drawn from a stream of their own, so a calm, dry, faultless scene keeps the packets it always had."""
        sea = self.scene.sea
        n = self.batch_packets
        rng = np.random.default_rng([self.seed, batch % (1 << 62), 0x5EA])
        water = np.isfinite(f.water)
        if water.any() and sea.water_return_at_10deg > 0:
            back = water & (rng.random(water.size) < sea.water_return_probability(f.grazing))
            distance[back] = f.water[back] + rng.normal(0.0, self.range_noise_m, int(back.sum()))
            label[back] = LABEL_WATER
            refl[back] = rng.uniform(1.0, 12.0, int(back.sum()))
        if sea.rain_rate > 0:
            n_rain = rng.poisson(sea.rain_rate * n * PACKET_PERIOD_S)
            ray = rng.integers(0, distance.size, n_rain)
            # density falling as r^-0.5 from 1 m out: r = (1 + u (sqrt(R) - 1))^2
            r = (1.0 + rng.random(n_rain) * (math.sqrt(sea.rain_max_range) - 1.0)) ** 2
            nearer = r < distance[ray]
            ray, r = ray[nearer], r[nearer]
            distance[ray] = r
            label[ray] = LABEL_RAIN
            refl[ray] = rng.uniform(0.0, 8.0, ray.size)
        if self.laser_dropout > 0:
            dead = rng.random(16) < self.laser_dropout
            off = dead[f.laser]
            distance[off] = np.inf
            label[off] = LABEL_NONE
        return rng.random(n) < self.packet_loss if self.packet_loss > 0 else np.zeros(n, dtype=bool)

    def _fire(self, first_packet: int, n_packets: int) -> _Firings:
        """Cast every ray of packets first_packet .. first_packet + n_packets - 1 against the scene (no noise)."""
        packet_t = (first_packet + np.arange(n_packets)) * PACKET_PERIOD_S
        t = (packet_t[:, None] + _RAY_OFFSET_S[None, :]).ravel()
        laser = np.tile(_RAY_LASER, n_packets)
        azimuth = self.azimuth_at(t)
        n_rays = t.shape[0]

        # ray directions in sensor FLU (vlp16.md §3), then body FRD, then world NED with the pose at each firing
        cos_e = np.cos(_ELEV[laser])
        d_flu = np.stack([cos_e * np.cos(azimuth), -cos_e * np.sin(azimuth), np.sin(_ELEV[laser])], axis=-1)
        d_body = d_flu @ self._flu_to_body.T
        o_body = self._origin_body[laser]
        poses = self.scene.own.poses(t)
        d_world = _rotate_body_to_world(d_body, poses.roll, poses.pitch, poses.yaw)
        o_world = _rotate_body_to_world(o_body, poses.roll, poses.pitch, poses.yaw)
        o_world[:, :2] += poses.position
        o_world[:, 2] += poses.down

        distance = np.full(n_rays, np.inf)
        label = np.full(n_rays, LABEL_NONE, dtype=np.int64)
        refl = np.zeros(n_rays)
        if n_rays:
            self._cast(packet_t, o_world, d_world, distance, label, refl)
        # The sea: a firing that meets the water before any solid ends there (a crest hides a low hull behind it).
        water = self.scene.sea.water_distance(o_world, d_world, t) if n_rays else np.zeros(0)
        first = water < distance
        distance[first] = np.inf
        label[first] = LABEL_NONE
        water = np.where(first, water, np.inf)
        grazing = np.where(first, np.arcsin(np.clip(d_world[:, 2], 0.0, 1.0)), 0.0)
        return _Firings(
            first_packet, packet_t, t, laser, azimuth, o_world, d_world, distance, label, refl, water, grazing
        )

    def _cast(
        self,
        packet_t: np.ndarray,
        o_world: np.ndarray,
        d_world: np.ndarray,
        distance: np.ndarray,
        label: np.ndarray,
        refl: np.ndarray,
    ) -> None:
        """Nearest prism entry along each ray (in place into distance/label/refl).

        Work is organised in groups of 24 rays (one laser across one packet), and a group is only tested against a
        prism when both the group's bearings and its elevations can reach the prism: a 1.5 m quay wall 30 m away is
        within reach of two or three lasers, not sixteen.
        """
        prisms = self.scene.prisms_at(packet_t + PACKET_PERIOD_S / 2)
        n_pkt, n_prism = prisms.vertices.shape[:2]
        if n_prism == 0:
            return
        verts = prisms.vertices  # (B, P, 5, 2)
        seq = SEQUENCES_PER_PACKET
        # (B, laser, sequence, 3): a group = one laser over one packet
        o = o_world.reshape(n_pkt, seq, 16, 3).transpose(0, 2, 1, 3)
        d = d_world.reshape(n_pkt, seq, 16, 3).transpose(0, 2, 1, 3)

        # bearing cull, per packet
        sensor = o[:, 14, seq // 2, :2]  # (B, 2) the -1 deg laser mid-packet
        bearing = np.arctan2(d[..., 1], d[..., 0]).reshape(n_pkt, -1)
        centre_b = bearing[:, bearing.shape[1] // 2]
        half_b = np.max(np.abs(wrap_angle(bearing - centre_b[:, None])), axis=1)
        rel = verts - sensor[:, None, None, :]
        centroid = rel.mean(axis=2)  # (B, P, 2): inside the convex prism (the padded vertex only shifts it)
        dist_c = np.hypot(centroid[..., 0], centroid[..., 1])
        radius = np.max(np.hypot(*np.moveaxis(rel - centroid[:, :, None, :], -1, 0)), axis=2)
        centre_p = np.arctan2(centroid[..., 1], centroid[..., 0])
        vb = np.arctan2(rel[..., 1], rel[..., 0])
        half_p = np.max(np.abs(wrap_angle(vb - centre_p[..., None])), axis=2)
        near = dist_c <= radius + 0.5  # sensor next to or inside the prism's circle: bearings say nothing
        overlap = np.abs(wrap_angle(centre_p - centre_b[:, None])) <= half_p + half_b[:, None] + 1e-6
        cand = (overlap | near) & (dist_c - radius <= self.max_range)
        pb, pp = np.nonzero(cand)
        if pb.size == 0:
            return

        # elevation cull, per (packet, prism) pair and laser: world elevation span of each group vs the prism's
        height = -o[:, :, :, 2]  # (B, 16, 24) height of each ray origin above the water
        elev = np.arcsin(np.clip(-d[..., 2], -1.0, 1.0))
        el_lo, el_hi = elev.min(axis=2)[pb], elev.max(axis=2)[pb]  # (Q, 16)
        h_s = height[pb].mean(axis=(1, 2))[:, None]  # (Q, 1); the spread (mm) is covered by the margin
        d_near = np.maximum(dist_c[pb, pp] - radius[pb, pp], 1e-3)[:, None]
        d_far = (dist_c[pb, pp] + radius[pb, pp])[:, None]
        dz_top = prisms.top[pp][:, None] - h_s
        dz_bot = prisms.bottom[pp][:, None] - h_s
        reach_hi = np.arctan2(dz_top, np.where(dz_top > 0, d_near, d_far))
        reach_lo = np.arctan2(dz_bot, np.where(dz_bot < 0, d_near, d_far))
        margin = 1e-3
        gq, gl = np.nonzero((el_hi >= reach_lo - margin) & (el_lo <= reach_hi + margin))
        if gq.size == 0:
            return
        gb, gp = pb[gq], pp[gq]

        # half-spaces of each prism: 5 side planes n.x <= c, top (-z <= top), water/bottom (z <= -bottom)
        edge = np.roll(verts, -1, axis=2) - verts
        length = np.hypot(edge[..., 0], edge[..., 1])
        normal = np.stack([edge[..., 1], -edge[..., 0]], axis=-1) / np.where(length > 0, length, 1.0)[..., None]
        offset = np.sum(normal * verts, axis=-1)  # (B, P, 5)
        nx, ny = normal[gb, gp, None, :, 0], normal[gb, gp, None, :, 1]  # (G, 1, 5)
        og, dg = o[gb, gl], d[gb, gl]  # (G, 24, 3)
        den = np.empty((*og.shape[:2], 7))
        num = np.empty_like(den)
        den[..., :5] = dg[..., 0:1] * nx + dg[..., 1:2] * ny
        num[..., :5] = offset[gb, gp, None, :] - og[..., 0:1] * nx - og[..., 1:2] * ny
        den[..., 5] = -dg[..., 2]
        num[..., 5] = prisms.top[gp][:, None] + og[..., 2]
        den[..., 6] = dg[..., 2]
        num[..., 6] = -prisms.bottom[gp][:, None] - og[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = num / den
        lam_in_all = np.where(den < 0, ratio, -np.inf)
        plane = np.argmax(lam_in_all, axis=-1)
        lam_in = np.take_along_axis(lam_in_all, plane[..., None], -1)[..., 0]
        lam_out = np.min(np.where(den > 0, ratio, np.inf), axis=-1)
        parallel_out = np.any((den == 0) & (num < 0), axis=-1)
        hit = (lam_in <= lam_out) & (lam_in > 0) & ~parallel_out
        if not hit.any():
            return
        g_idx, s_idx = np.nonzero(hit)
        ray = gb[g_idx] * RAYS_PER_PACKET + s_idx * 16 + gl[g_idx]
        lam = lam_in[g_idx, s_idx]
        cos_inc = -den[g_idx, s_idx, plane[g_idx, s_idx]]  # |n . d| of the entry face, both unit vectors
        order = np.lexsort((lam, ray))
        ray, lam, cos_inc, g_first = ray[order], lam[order], cos_inc[order], g_idx[order]
        first = np.ones(ray.shape[0], bool)
        first[1:] = ray[1:] != ray[:-1]
        ray, lam, cos_inc, g_first = ray[first], lam[first], cos_inc[first], g_first[first]
        prism = gp[g_first]
        distance[ray] = lam
        label[ray] = prisms.label[prism]
        # Lambertian-ish: grazing hits return less light
        refl[ray] = prisms.reflectivity[prism] * (0.4 + 0.6 * np.clip(cos_inc, 0.0, 1.0))


def _check_times(*times: float) -> None:
    if not all(math.isfinite(t) for t in times):
        raise ValueError(f"simulation times must be finite, got {times}")


def _rotate_body_to_world(v: np.ndarray, roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """(N, 3) body FRD vectors -> world NED with one attitude per row: R = Rz(yaw) Ry(pitch) Rx(roll), applied as
    three plane rotations (cheaper than building N matrices)."""
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    if np.any(roll):
        cr, sr = np.cos(roll), np.sin(roll)
        y, z = cr * y - sr * z, sr * y + cr * z
    if np.any(pitch):
        cp, sp = np.cos(pitch), np.sin(pitch)
        x, z = cp * x + sp * z, -sp * x + cp * z
    cy, sy = np.cos(yaw), np.sin(yaw)
    x, y = cy * x - sy * y, sy * x + cy * y
    return np.stack([x, y, np.broadcast_to(z, x.shape)], axis=-1)
