"""What a TI AWR1843 (out-of-box demo point cloud) on the own boat would report, frame by frame.

This is a phenomenological model, not a ray tracer: a mmWave radar returns a handful of CFAR detections per object,
mostly from a few strong scatterers (a hull's corners, bow, stern, superstructure) and more weakly from the sides
that face it, so each frame takes a hull's persistent scatterers that are in view and samples points on its
visible sides (more for long and near hulls), gives each one the Doppler of the relative motion along the line of
sight, an SNR that falls with R^4 and fades from frame to frame, and then adds what makes radar tracking hard on
the water (paper 001, §1): sea clutter at every range it sees, thicker
near the boat and on a rougher sea, moving with the waves' orbital motion; multipath ghosts (a boat's mirror image
behind a quay wall that reflects it, and weaker copies at k times the range of a hull return that bounced between
the hull and the own boat); and many returns from the quay, whose Doppler is the own boat's motion seen from a fixed
wall.

Frames: every echo is placed in the world (NED) first; the radar sits where the own boat's full pose puts it (track,
yaw, roll, pitch and heave, then the mount's lever arm), and its velocity includes the lever arm swinging with the
roll, pitch and yaw rates and the heave rate. World -> sensor FRD -> TI axes (x right, y boresight, z up) is the
last step, so a rolling boat's points are placed by the sensor's tilt, exactly as a real sensor reports them.
Doppler positive = moving away, as the demo firmware sends it. Each value not given to the constructor that the
scene's ``conditions`` carries (scene.SensorConditions) is taken from there. Every frame's randomness depends only
on ``seed`` and the frame number, so frames are reproducible in any order.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import math
from collections.abc import Iterator
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from drivers.awr1843.profile import load_profile
from drivers.mount import TI_TO_FRD, Mount
from simulator.scene import LABEL_CLUTTER, LABEL_GHOST, LABEL_SHORE, MAX_VERTICES, Scene
from simulator.sea import Sea
from tracker.ego import rotation_matrices

log = logging.getLogger(__name__)

SHIPPED_PROFILE = Path(__file__).resolve().parent.parent / "daemon" / "profiles" / "awr1843_50m.cfg"


@functools.lru_cache(maxsize=1)
def shipped_max_velocity() -> float:
    """The shipped chirp profile's unambiguous radial speed (m/s): the simulated radar wraps its Doppler there, as
    the radar configured with that profile (the one the simulator's captures and demo name) does."""
    return float(load_profile(SHIPPED_PROFILE).max_velocity_mps)


_RATE_STEP_S = 1e-3  # half-step of the central differences that give the roll, pitch and heave rates
# The window in which SensorConditions states its clutter rates: 1-50 m and +-60 deg (the shipped 50 m profile).
CLUTTER_REF_RANGES = (1.0, 50.0)
CLUTTER_REF_HALF_FOV = math.radians(60.0)
SEA_STATE_3_CREST = 0.3  # m, simulator/sea.py's crest for sea state 3
_CLUTTER_FOV_MARGIN = 0.15  # rad drawn beyond the field of view, so that a rolled sensor's view is filled too
# Fluctuation of an echo's power from frame to frame (chi-square with 2 x dof degrees of freedom, mean 1): at 3.9 mm
# wavelength any motion of a hull decorrelates it between frames (Swerling II / IV).
DOF_MANY = 1  # many comparable scatterers in the cell (a stretch of hull side or wall): exponential, Swerling II
DOF_DOMINANT = 2  # one dominant scatterer and small ones (a corner): chi-square with 4 degrees of freedom, Swerling IV


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
    ghost_of: np.ndarray  # (N,) index of the point a k-bounce ghost copies, -1 for everything else
    # (N,) which persistent scatterer of its vessel a hull point (or its mirror image) is, else -1; None: all -1
    scatterer: np.ndarray | None = None
    mirror_of: np.ndarray | None = None  # (N,) vessel a quay-mirror ghost images, -1 for the rest; None: all -1

    def __post_init__(self) -> None:
        # frames built by hand (tests of what consumes them) may leave out what only the model knows
        for name in ("scatterer", "mirror_of"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, np.full(self.n_points, -1, np.int64))

    @property
    def n_points(self) -> int:
        return int(self.doppler.shape[0])


@dataclass(frozen=True)
class SensorPose:
    """Where the radar is at one time, and how it moves."""

    position: np.ndarray  # (3,) world NED
    rotation: np.ndarray  # (3, 3) sensor-FRD -> world
    velocity: np.ndarray  # (3,) world NED: the boat's, its heave rate, and the lever arm turning with roll, pitch, yaw


@dataclass(frozen=True)
class _SceneAt:
    """The vessels at one frame time, evaluated once and shared by every echo source."""

    position: np.ndarray  # (V, 2) world (north, east)
    velocity: np.ndarray  # (V, 2) world
    heading: np.ndarray  # (V,) rad
    yaw_rate: np.ndarray  # (V,) rad/s, clockwise positive
    hulls: np.ndarray  # (V, 5, 2) hull footprints, world (north, east)
    solids: _Solids  # every prism that can block a sight line


@dataclass(frozen=True)
class _Solids:
    """Vertical convex prisms in the world: (P, 5, 2) footprints (north, east), heights above the water, owner."""

    vertices: np.ndarray
    bottom: np.ndarray
    top: np.ndarray
    owner: np.ndarray  # vessel index or LABEL_SHORE


@dataclass(frozen=True)
class _Echoes:
    """Candidate echoes of one frame, before the radar has decided which it detects. World NED."""

    position: np.ndarray  # (N, 3) where the echo appears (a ghost: its apparent position)
    velocity: np.ndarray  # (N, 3) of that apparent position
    snr: np.ndarray  # (N,) dB, range loss and fluctuation included
    label: np.ndarray  # (N,) int
    scatterer: np.ndarray  # (N,) int, persistent scatterer index within its vessel, -1 for the rest
    mirror_of: np.ndarray  # (N,) int, the vessel a quay-mirror ghost images, -1 for the rest

    @property
    def size(self) -> int:
        return int(self.snr.shape[0])

    def take(self, keep: np.ndarray) -> _Echoes:
        return _Echoes(*(getattr(self, f.name)[keep] for f in fields(self)))

    def replace(self, **changes: np.ndarray) -> _Echoes:
        return dataclasses.replace(self, **changes)

    @staticmethod
    def join(parts: list[_Echoes]) -> _Echoes:
        return _Echoes(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(_Echoes)))

    @staticmethod
    def of(
        position: np.ndarray,
        velocity: np.ndarray,
        snr: np.ndarray,
        label: np.ndarray | int,
        scatterer: np.ndarray | None = None,
    ) -> _Echoes:
        """Echoes that are no mirror image (and no persistent hull scatterer unless ``scatterer`` says so)."""
        n = snr.shape[0]
        labels = np.broadcast_to(np.asarray(label, np.int64), (n,)).copy()
        none = np.full(n, -1, np.int64)
        return _Echoes(position, velocity, snr, labels, none if scatterer is None else scatterer, none.copy())

    @staticmethod
    def empty() -> _Echoes:
        return _Echoes.of(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64))


@dataclass(frozen=True)
class _HullScatterers:
    """The few strong, persistent scatterers of every vessel (corners, bow, stern, superstructure), fixed in its body
    frame. One row per scatterer, M in all."""

    vessel: np.ndarray  # (M,) vessel index
    index: np.ndarray  # (M,) scatterer number within its vessel
    body: np.ndarray  # (M, 2) (forward, starboard) from the vessel's reference point, m
    height: np.ndarray  # (M,) above the water, m
    normals: np.ndarray  # (M, 2, 2) body-frame outward normals of the two sides meeting there
    gain_db: np.ndarray  # (M,) its own strength, relative to the vessel's


class Awr1843Model:
    """Simulated AWR1843 point cloud. Angles in degrees only in the constructor (like a cfg file); radians inside.

    A hull returns from a few strong scatterers and from weaker diffuse ones along its sides. The strong ones are
    2 + length / 10 m (2..6) persistent points at its corners, bow, stern and cabin, fixed in its body frame, each
    ``scatterer_gain_db`` over a metre of side plus its own offset (uniform within +-``scatterer_spread_db``); one
    is seen while a side meeting at it faces the radar, less the further off face-on (5 log10 cos: a corner
    scatters broadly). The diffuse ones are ``points_per_metre`` of visible side at <= 20 m (fewer further out),
    1..``max_points_per_vessel`` per 10 m of length, drawn afresh along the sides every frame.
    ``snr_at_10m_db`` is the SNR of a 1 m high, face-on metre of hull side at 10 m; it falls with 40 log10(range) and
    with the cosine of the incidence angle. With ``fluctuation`` each echo's power varies from frame to frame, as
    chi-square with 4 degrees of freedom for a strong scatterer (Swerling IV) and exponentially for a diffuse one
    (Swerling II). Points below ``snr_threshold_db`` (the CFAR threshold) are not reported, which is what limits
    the range on small boats.

    Sea clutter: ``clutter_calm`` detections a frame on calm water plus ``clutter_sea_state_3`` times
    crest / 0.3 m of the scene's sea, both counted in the reference window (1-50 m, +-60 deg) and spread over the
    radar's own field of view and range with an areal density proportional to range^-``clutter_range_exponent``
    from ``clutter_min_range`` out. Each is ``clutter_snr_excess_db`` (mean, exponential) over the CFAR threshold and
    moves with the water's orbital velocity plus ``clutter_doppler_spread`` (m/s, each horizontal axis).

    Multipath: a vessel seen via a quay wall (radar -> wall -> hull -> wall -> radar) appears as its mirror image
    behind the wall, at the length of that path, ``mirror_loss_db`` weaker for the two reflections; the wall must
    reach the height where the path meets it, and neither leg may be blocked. Besides, each detected hull return
    comes back with ``ghost_probability`` as a copy that bounced between the hull and the own boat k = 2 (or, a
    quarter of the time, 3) times: k times the range on the same bearing, k times the Doppler, (k - 1) x
    ``ghost_loss_db`` + 20 log10(k) weaker.

    Reporting: with ``report_elevation`` the points carry the measured elevation (a 3-TX profile); without it they
    are what an azimuth-only profile (the shipped one) reports, z = 0. At most ``max_points`` a frame, the strongest:
    the host parser rejects a header claiming more than 512, and at 921600 baud about 450 points fill a 100 ms frame.

    ``clutter_calm``, ``clutter_sea_state_3``, ``ghost_probability``, ``mirror_loss_db`` and ``snr_loss_db`` default
    to the scene's ``conditions``.
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
        v_max: float | None = None,
        alias: bool = True,
        seed: int = 0,
        frame_period: float = 0.1,
        snr_threshold_db: float = 15.0,
        snr_at_10m_db: float = 45.0,
        fluctuation: bool = True,
        detect_probability: float = 0.9,
        scatterer_gain_db: float = 6.0,
        scatterer_spread_db: float = 2.0,
        points_per_metre: float = 1.0,
        max_points_per_vessel: int = 10,
        clutter_calm: float | None = None,
        clutter_sea_state_3: float | None = None,
        clutter_range_exponent: float = 2.0,
        clutter_min_range: float = 1.0,
        clutter_doppler_spread: float = 0.1,
        clutter_snr_excess_db: float = 2.0,
        ghost_probability: float | None = None,
        ghost_loss_db: float = 9.0,
        mirror_loss_db: float | None = None,
        shore_spacing: float = 0.5,
        shore_keep: float = 0.35,
        report_elevation: bool = True,
        max_points: int = 500,
        snr_loss_db: float | None = None,
    ) -> None:
        c = scene.conditions  # a value not given is the scene's own
        ghost_probability = c.radar_ghost_probability if ghost_probability is None else ghost_probability
        clutter_calm = c.radar_clutter_calm if clutter_calm is None else clutter_calm
        clutter_sea_state_3 = c.radar_clutter_sea_state_3 if clutter_sea_state_3 is None else clutter_sea_state_3
        snr_loss_db = c.radar_snr_loss_db if snr_loss_db is None else snr_loss_db
        mirror_loss_db = c.radar_mirror_loss_db if mirror_loss_db is None else mirror_loss_db
        v_max = shipped_max_velocity() if v_max is None else v_max
        if frame_period <= 0 or max_range <= min_range or v_max <= 0:
            raise ValueError("need frame_period > 0, max_range > min_range and v_max > 0")
        if not 0 <= ghost_probability <= 1:
            raise ValueError(f"ghost_probability must be in [0, 1], got {ghost_probability}")
        if min(clutter_calm, clutter_sea_state_3, clutter_doppler_spread, clutter_snr_excess_db) < 0:
            raise ValueError("clutter rates, Doppler spread and SNR excess must be >= 0")
        if clutter_min_range <= 0:
            raise ValueError(f"clutter_min_range must be > 0, got {clutter_min_range}")
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
        self.fluctuation = fluctuation
        self.scatterer_gain_db = float(scatterer_gain_db)
        self.snr_loss_db = float(snr_loss_db)
        self.detect_probability = float(detect_probability)
        self.points_per_metre = float(points_per_metre)
        self.max_points_per_vessel = int(max_points_per_vessel)
        self.clutter_calm = float(clutter_calm)
        self.clutter_sea_state_3 = float(clutter_sea_state_3)
        self.clutter_range_exponent = float(clutter_range_exponent)
        self.clutter_min_range = float(clutter_min_range)
        self.clutter_doppler_spread = float(clutter_doppler_spread)
        self.clutter_snr_excess_db = float(clutter_snr_excess_db)
        self.ghost_probability = float(ghost_probability)
        self.ghost_loss_db = float(ghost_loss_db)
        self.mirror_loss_db = float(mirror_loss_db)
        self.report_elevation = report_elevation
        self.max_points = int(max_points)
        self.shore_keep = float(shore_keep)
        self._shore = _sample_quay(scene, shore_spacing)
        self._vessel_height = np.array([v.height for v in scene.vessels], float)
        self._vessel_rcs = np.array([v.rcs_scale for v in scene.vessels], float)
        self._vessel_length = np.array([v.length for v in scene.vessels], float)
        # echo strength at 10 m of a face-on metre of each vessel's side (its height and paint make it)
        self._vessel_snr_db = self.snr_at_10m_db + 10 * np.log10(
            np.maximum(self._vessel_height, 0.3) * self._vessel_rcs
        )
        self._scatterers = _hull_scatterers(scene, self.seed, float(scatterer_spread_db))
        self._hull_body = np.array([v.outline_body() for v in scene.vessels], float).reshape(-1, MAX_VERTICES, 2)
        self._prism_body, self._prism_vessel, self._prism_bottom, self._prism_top = _vessel_prisms(scene)
        self._quay_blocks, self._quay_top = _quay_blocks(scene)
        self._walls = scene.quay_wall_segments()  # (starts, ends), world (north, east)
        self._wall_height = scene.quay_heights()
        self._wall_water_side = (  # unit normals of each wall segment pointing into the water, same order
            np.concatenate([-q.land_normals() for q in scene.quays]) if scene.quays else np.zeros((0, 2))
        )
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
        pose = self.sensor_pose(t)
        at = self._scene_at(t)
        sources = [
            self._vessel_echoes(at, pose, rng),
            self._shore_echoes(pose, rng),
            self._clutter_echoes(t, pose, rng),
        ]
        direct = self._detect(_Echoes.join(sources), pose, at.solids, rng)
        mirrored = self._mirror_echoes(at, pose, rng)
        ghosts, src = self._bounce_ghosts(direct, pose, rng)  # src indexes ``direct``, which comes first below
        echoes = _Echoes.join([direct, mirrored, ghosts])
        ghost_of = np.concatenate([np.full(direct.size + mirrored.size, -1, np.int64), src])
        return self._measure(t, k, echoes, pose, ghost_of, rng)

    @property
    def clutter_rate(self) -> float:
        """Sea-clutter detections a frame this scene's sea gives in the reference window (1-50 m, +-60 deg)."""
        return self.clutter_calm + self.clutter_sea_state_3 * self.scene.sea.crest / SEA_STATE_3_CREST

    def sensor_pose(self, t: float) -> SensorPose:
        """The radar's pose in the world at ``t``: the own boat's full pose (track, yaw, roll, pitch, heave) through
        the mount. Its velocity adds the heave rate and the lever arm swung by the roll, pitch and yaw rates; those
        rates are central differences (the attitude is smooth), the yaw taken along its analytic rate so that a
        heading jump at a waypoint corner does not leak into the velocity."""
        h = _RATE_STEP_S
        own = self.scene.own.poses(np.array([t - h, t, t + h]))
        yaw = own.yaw[1] + own.yaw_rate[1] * np.array([-h, 0.0, h])
        r_wb = rotation_matrices(own.roll, own.pitch, yaw)  # (3, 3, 3) body FRD -> world NED at t-h, t, t+h
        lever = r_wb @ self.mount.translation  # (3, 3) mount origin relative to the body origin, world NED
        position = own.position_ned[1] + lever[1]
        boat = np.array([own.velocity[1, 0], own.velocity[1, 1], (own.down[2] - own.down[0]) / (2 * h)])
        swing = (lever[2] - lever[0]) / (2 * h)  # the mount's lever arm turning with the attitude
        return SensorPose(position, r_wb[1] @ self.mount.rotation, boat + swing)

    # -- the scene at one time --------------------------------------------------------------------------------------
    def _scene_at(self, t: float) -> _SceneAt:
        """One evaluation of every vessel's state (the costly part of a frame) and the prisms placed from it."""
        s = self.scene.vessel_states(t)
        pos, heading = s.position[0], s.heading[0]
        hulls = _place(self._hull_body, pos, heading)
        vessel_prisms = _place(self._prism_body, pos[self._prism_vessel], heading[self._prism_vessel])
        solids = _Solids(
            np.concatenate([vessel_prisms, self._quay_blocks]),
            np.concatenate([self._prism_bottom, np.full(self._quay_top.size, -math.inf)]),  # walls stand in the water
            np.concatenate([self._prism_top, self._quay_top]),
            np.concatenate([self._prism_vessel, np.full(self._quay_top.size, LABEL_SHORE)]),
        )
        return _SceneAt(pos, s.velocity[0], heading, s.yaw_rate[0], hulls, solids)

    # -- echo sources ------------------------------------------------------------------------------------------------
    def _vessel_echoes(self, at: _SceneAt, pose: SensorPose, rng: np.random.Generator) -> _Echoes:
        """What the vessels return: their persistent strong scatterers and diffuse points along the sides facing the
        radar, with the SNR the radar receives."""
        strong = self._strong_echoes(at, pose.position[:2])
        diffuse = self._diffuse_echoes(at, pose.position[:2], rng)
        echoes = _Echoes.join([strong, diffuse])
        dof = np.concatenate([np.full(strong.size, DOF_DOMINANT), np.full(diffuse.size, DOF_MANY)])
        return echoes.replace(snr=self._received(echoes.snr, echoes.position, pose.position, dof, rng))

    def _strong_echoes(self, at: _SceneAt, sensor: np.ndarray) -> _Echoes:
        """The persistent scatterers seen from ``sensor`` (world north, east): those where a side facing it meets.
        ``snr`` is their strength at 10 m (no range loss yet)."""
        sc = self._scatterers
        if sc.vessel.size == 0:
            return _Echoes.empty()
        v = sc.vessel
        c, s = np.cos(at.heading[v]), np.sin(at.heading[v])
        # body (forward, starboard) -> world (north, east): rotate by the heading
        offset = np.stack([c * sc.body[:, 0] - s * sc.body[:, 1], s * sc.body[:, 0] + c * sc.body[:, 1]], axis=1)
        normal = np.stack(
            [
                c[:, None] * sc.normals[..., 0] - s[:, None] * sc.normals[..., 1],
                s[:, None] * sc.normals[..., 0] + c[:, None] * sc.normals[..., 1],
            ],
            axis=-1,
        )  # (M, 2, 2) world
        p2 = at.position[v] + offset
        to_sensor = sensor - p2
        dot = np.sum(normal * to_sensor[:, None, :], axis=-1)  # (M, 2)
        seen = np.any(dot > 0, axis=1)
        cos_inc = np.max(dot, axis=1) / np.maximum(np.hypot(*to_sensor.T), 1e-9)
        snr = (
            self._vessel_snr_db[v]
            + self.scatterer_gain_db
            + sc.gain_db
            + 5 * np.log10(np.maximum(cos_inc, 0.1))  # a corner scatters broadly: half the dB of a flat side
        )
        w = at.yaw_rate[v]
        vel = at.velocity[v] + np.stack([-w * offset[:, 1], w * offset[:, 0]], axis=1)  # v + omega x r
        n = int(seen.sum())
        return _Echoes.of(
            np.concatenate([p2[seen], -sc.height[seen, None]], axis=1),
            np.concatenate([vel[seen], np.zeros((n, 1))], axis=1),
            snr[seen],
            v[seen],
            sc.index[seen],
        )

    def _diffuse_echoes(self, at: _SceneAt, sensor: np.ndarray, rng: np.random.Generator) -> _Echoes:
        """Diffuse points drawn afresh each frame along the hull sides facing ``sensor`` (world north, east): more for
        long and near hulls. ``snr`` is their strength at 10 m (no range loss yet)."""
        if at.hulls.shape[0] == 0:
            return _Echoes.empty()
        verts = at.hulls
        a, b = verts, np.roll(verts, -1, axis=1)
        edge = b - a
        length = np.hypot(edge[..., 0], edge[..., 1])
        normal = np.stack([edge[..., 1], -edge[..., 0]], -1) / np.where(length > 0, length, 1.0)[..., None]
        to_sensor = sensor - (a + b) / 2
        facing = (length > 0) & (np.sum(normal * to_sensor, axis=-1) > 0)
        facing_len = np.where(facing, length, 0.0)
        total = facing_len.sum(axis=1)  # (V,)
        centre = at.position
        dist = np.hypot(*(centre - sensor).T)
        cap = self.max_points_per_vessel * np.maximum(1.0, self._vessel_length / 10.0)  # a 43 m ship: 43
        count = np.rint(self.points_per_metre * total * np.minimum(1.0, 20.0 / np.maximum(dist, 1e-3)))
        count = np.where(total > 0, np.clip(count, 1, cap), 0).astype(np.int64)
        n = int(count.sum())
        if n == 0:
            return _Echoes.empty()
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
        w = at.yaw_rate[owner]
        vel = at.velocity[owner] + np.stack([-w * r[:, 1], w * r[:, 0]], -1)
        vw = np.concatenate([vel, np.zeros((n, 1))], axis=1)
        los2 = p2 - sensor
        cos_inc = np.abs(np.sum(normal.reshape(-1, 2)[e] * los2, axis=1)) / np.maximum(np.hypot(*los2.T), 1e-6)
        snr = self._vessel_snr_db[owner] + 10 * np.log10(np.maximum(cos_inc, 0.1))
        return _Echoes.of(pw, vw, snr, owner)

    def _shore_echoes(self, pose: SensorPose, rng: np.random.Generator) -> _Echoes:
        """Echoes off the quay walls facing the radar; a fixed wall has no Doppler of its own."""
        pts, normals, heights = self._shore
        if pts.shape[0] == 0:
            return _Echoes.empty()
        to_sensor = pose.position[:2] - pts
        dist = np.hypot(*to_sensor.T)
        cos_inc = np.sum(normals * to_sensor, axis=1) / np.maximum(dist, 1e-6)
        keep = (cos_inc > 0) & (dist <= self.max_range + 1.0) & (rng.random(dist.shape) < self.shore_keep)
        p2, h, cos_inc = pts[keep], heights[keep], cos_inc[keep]
        n = p2.shape[0]
        pw = np.concatenate([p2, -(h * rng.uniform(0.1, 0.95, n))[:, None]], axis=1)
        snr = self.snr_at_10m_db + 10 * np.log10(np.maximum(h, 0.3)) + 10 * np.log10(np.maximum(cos_inc, 0.1))
        snr = self._received(snr, pw, pose.position, np.full(n, DOF_MANY), rng)
        return _Echoes.of(pw, np.zeros((n, 3)), snr, LABEL_SHORE)

    def _clutter_echoes(self, t: float, pose: SensorPose, rng: np.random.Generator) -> _Echoes:
        """Sea clutter: CFAR detections off the water at every range the radar sees, fresh places every frame.

        Their areal density falls as range^-``clutter_range_exponent`` (the grazing angle, and with it the water's
        backscatter, falls with range) and is scaled so that the reference window holds ``clutter_rate`` a frame.
        They sit preferentially on the crests (the troughs are shadowed at low grazing angles), on the surface, and
        move with the water's orbital velocity there plus a small spread (ripples, breaking): the places are new
        each frame, but the Doppler of a patch of water follows its waves through their period.
        """
        rate = self.clutter_rate
        if rate <= 0:
            return _Echoes.empty()
        gamma = self.clutter_range_exponent
        density = rate / (2 * CLUTTER_REF_HALF_FOV * _radial_integral(*CLUTTER_REF_RANGES, gamma))
        half_width = self.fov + _CLUTTER_FOV_MARGIN
        r0, r1 = self.clutter_min_range, self.max_range + 1.0
        expected = density * 2 * half_width * _radial_integral(r0, r1, gamma)
        sea = self.scene.sea
        crest = sea.crest
        # crest preference by thinning: a candidate is kept with w = ((h / crest + 1) / 2)^2, so draw 1 / E[w] times
        # as many (E[h^2] = sum a^2 / 2 over trains of independent phase)
        mean_keep = (sum(w.amplitude**2 for w in sea.waves) / 2 / crest**2 + 1) / 4 if crest > 0 else 1.0
        n = int(rng.poisson(expected / mean_keep))
        if n == 0:
            return _Echoes.empty()
        r = _draw_ranges(rng.random(n), r0, r1, gamma)  # horizontal, m
        boresight = math.atan2(pose.rotation[1, 0], pose.rotation[0, 0])  # sensor forward axis, world heading
        bearing = boresight + rng.uniform(-half_width, half_width, n)
        north = pose.position[0] + r * np.cos(bearing)
        east = pose.position[1] + r * np.sin(bearing)
        height, velocity = _sea_surface(sea, north, east, t)
        if crest > 0:
            keep = rng.random(n) < ((height / crest + 1) / 2) ** 2
            north, east, height, velocity = north[keep], east[keep], height[keep], velocity[keep]
            n = north.size
        velocity[:, :2] += rng.normal(0.0, self.clutter_doppler_spread, (n, 2))
        position = np.stack([north, east, -height], axis=1)  # world NED: z down
        # CFAR-normalised: what crosses the threshold does so by a little, with a thin tail of spikes; the day's loss
        # (a wet radome) sinks some of it below the threshold
        snr = self.snr_threshold_db + rng.exponential(self.clutter_snr_excess_db, n) - self.snr_loss_db
        return _Echoes.of(position, velocity, snr, LABEL_CLUTTER)

    def _received(
        self, snr_10m: np.ndarray, position: np.ndarray, sensor: np.ndarray, dof: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        """SNR at the radar (world NED ``sensor``) of echoes whose mean SNR at 10 m is ``snr_10m``: R^4 spreading,
        the day's losses, and with ``fluctuation`` a power drawn from chi-square with 2 ``dof`` degrees of freedom
        (mean 1) each frame."""
        rng_m = np.linalg.norm(position - sensor, axis=1)
        snr = snr_10m - 40.0 * np.log10(np.maximum(rng_m, 0.1) / 10.0) - self.snr_loss_db
        if self.fluctuation and snr.size:
            snr = snr + 10.0 * np.log10(np.maximum(rng.gamma(dof, 1.0 / dof), 1e-12))
        return snr

    # -- what the radar makes of them ------------------------------------------------------------------------------
    def _world_to_ti(self, position: np.ndarray, pose: SensorPose) -> np.ndarray:
        """World NED points -> sensor FRD (the rotation is orthonormal) -> TI axes (the axis map is its own inverse)."""
        return ((position - pose.position) @ pose.rotation) @ TI_TO_FRD

    def _in_view(self, echoes: _Echoes, pose: SensorPose, rng: np.random.Generator) -> np.ndarray:
        """Which echoes the radar would report if nothing stood in the way: in its field of view and range, over the
        CFAR threshold, and detected (clutter's rate is already a detection rate)."""
        rng_m, az, el = _spherical(self._world_to_ti(echoes.position, pose))
        clutter = echoes.label == LABEL_CLUTTER
        return (
            (rng_m >= self.min_range)
            & (rng_m <= self.max_range)
            & (np.abs(az) <= self.fov)
            & (np.abs(el) <= self.elevation_fov)
            & (echoes.snr >= self.snr_threshold_db)
            & ((rng.random(echoes.size) < self.detect_probability) | clutter)
        )

    def _detect(self, echoes: _Echoes, pose: SensorPose, solids: _Solids, rng: np.random.Generator) -> _Echoes:
        """The direct echoes the radar reports: in view, and not behind a solid; water only where no quay wall lies
        between it and the radar."""
        seen = self._in_view(echoes, pose, rng)
        idx = np.flatnonzero(seen)
        seen[idx] = ~_blocked(pose.position, echoes.position[idx], echoes.label[idx], solids)
        water = np.flatnonzero(seen & (echoes.label == LABEL_CLUTTER))
        seen[water] = ~_beyond_walls(pose.position[:2], echoes.position[water, :2], *self._walls)
        return echoes.take(seen)

    def _mirror_echoes(self, at: _SceneAt, pose: SensorPose, rng: np.random.Generator) -> _Echoes:
        """Vessels seen via a quay wall, by the image method: what the radar's mirror image behind the wall would see
        of the vessels, folded back across the wall. A detected echo appears at the vessel point's mirror image
        (behind the wall, at the length of the bounce path), moving with its mirrored velocity."""
        starts, ends = self._walls
        if starts.shape[0] == 0 or at.hulls.shape[0] == 0:
            return _Echoes.empty()
        sensor = pose.position[:2]
        off_wall = np.sum((sensor - starts) * self._wall_water_side, axis=1)  # radar's distance in front of each wall
        # a ghost lies at least twice the radar's distance from the wall away: walls beyond half the range are mute
        near = (off_wall > 0) & (_segment_distance(sensor, starts, ends) <= self.max_range / 2)
        parts = [self._mirror_echoes_in(int(j), float(off_wall[j]), at, pose, rng) for j in np.flatnonzero(near)]
        return _Echoes.join(parts) if parts else _Echoes.empty()

    def _mirror_echoes_in(
        self, j: int, off_wall: float, at: _SceneAt, pose: SensorPose, rng: np.random.Generator
    ) -> _Echoes:
        """The ghosts of every vessel in wall j, which the radar faces from ``off_wall`` metres."""
        a, b, normal = self._walls[0][j], self._walls[1][j], self._wall_water_side[j]
        image = pose.position[:2] - 2 * off_wall * normal  # the radar mirrored behind the wall (north, east)
        strong, diffuse = self._strong_echoes(at, image), self._diffuse_echoes(at, image, rng)
        real = _Echoes.join([strong, diffuse])
        dof = np.concatenate([np.full(strong.size, DOF_DOMINANT), np.full(diffuse.size, DOF_MANY)])
        p2, h_point, h_radar = real.position[:, :2], -real.position[:, 2], -pose.position[2]
        in_front = np.sum((p2 - a) * normal, axis=1)  # the vessel point's distance in front of the wall
        # the unfolded path image -> point crosses the wall at this fraction of its length: there the wave bounces
        f = off_wall / np.maximum(off_wall + in_front, 1e-9)
        bounce = image + f[:, None] * (p2 - image)
        along = np.sum((bounce - a) * (b - a), axis=1) / float(np.dot(b - a, b - a))
        h_bounce = h_radar + f * (h_point - h_radar)
        on_wall = (in_front > 0) & (along >= 0) & (along <= 1) & (h_bounce >= 0) & (h_bounce <= self._wall_height[j])
        real, dof, in_front = real.take(on_wall), dof[on_wall], in_front[on_wall]
        bounce_ned = np.concatenate([bounce[on_wall], -h_bounce[on_wall, None]], axis=1)
        # what the radar sees: the point folded back across the wall, its velocity likewise
        apparent = real.position.copy()
        apparent[:, :2] -= 2 * in_front[:, None] * normal
        velocity = real.velocity.copy()
        velocity[:, :2] -= 2 * (velocity[:, :2] @ normal)[:, None] * normal
        snr = self._received(real.snr - self.mirror_loss_db, apparent, pose.position, dof, rng)
        ghosts = _Echoes(apparent, velocity, snr, np.full(real.size, LABEL_GHOST), real.scatterer, real.label)
        seen = self._in_view(ghosts, pose, rng)
        idx = np.flatnonzero(seen)
        if idx.size:  # neither leg blocked: radar -> wall by anything but quays, wall -> hull by anything but itself
            out = _blocked(pose.position, bounce_ned[idx], np.full(idx.size, LABEL_SHORE), at.solids)
            back = _blocked(bounce_ned[idx], real.position[idx], real.label[idx], at.solids)
            seen[idx] = ~(out | back)
        return ghosts.take(seen)

    def _bounce_ghosts(self, echoes: _Echoes, pose: SensorPose, rng: np.random.Generator) -> tuple[_Echoes, np.ndarray]:
        """Multipath between a hull and the own boat (radar -> hull -> own boat -> hull -> radar, k - 1 times over):
        a copy of a detected hull return at k times its range on the same bearing, whose path length changes k times
        as fast (k times the Doppler), weaker by the extra bounces and spreading. Also the indices of the copied."""
        src = np.flatnonzero((echoes.label >= 0) & (rng.random(echoes.size) < self.ghost_probability))
        if src.size == 0:
            return _Echoes.empty(), src
        k = np.where(rng.random(src.size) < 0.25, 3.0, 2.0)
        g_snr = echoes.snr[src] - (k - 1) * self.ghost_loss_db - 20.0 * np.log10(k)
        offset = echoes.position[src] - pose.position
        ok = (k * np.linalg.norm(offset, axis=1) <= self.max_range) & (g_snr >= self.snr_threshold_db)
        src, k, g_snr, offset = src[ok], k[ok], g_snr[ok], offset[ok]
        g_pos = pose.position + k[:, None] * offset
        # an apparent velocity whose line-of-sight part relative to the radar is k times the source's
        g_vel = pose.velocity + k[:, None] * (echoes.velocity[src] - pose.velocity)
        return _Echoes.of(g_pos, g_vel, g_snr, LABEL_GHOST), src

    def _radial_velocity(self, echoes: _Echoes, pose: SensorPose) -> np.ndarray:
        """Noise-free radial velocity of each echo relative to the radar, positive = moving away, m/s."""
        los = echoes.position - pose.position
        los /= np.maximum(np.linalg.norm(los, axis=1), 1e-9)[:, None]
        return np.sum((echoes.velocity - pose.velocity) * los, axis=1)

    def _measure(
        self, t: float, k: int, echoes: _Echoes, pose: SensorPose, ghost_of: np.ndarray, rng: np.random.Generator
    ) -> RadarDetections:
        """Measurement noise and the radar's own limits; the points in TI axes, as the firmware sends them."""
        echoes, ghost_of = _strongest(echoes, ghost_of, self.max_points)
        n = echoes.size
        rng_m, az, el = _spherical(self._world_to_ti(echoes.position, pose))  # world NED -> sensor FRD -> TI
        doppler = self._radial_velocity(echoes, pose)
        m_range = rng_m + rng.normal(0.0, self.range_noise_m, n)
        m_az = az + rng.normal(0.0, self.azimuth_noise, n)
        if self.report_elevation:
            m_el = el + rng.normal(0.0, self.elevation_noise, n)
            xyz_ti = np.stack(
                [m_range * np.cos(m_el) * np.sin(m_az), m_range * np.cos(m_el) * np.cos(m_az), m_range * np.sin(m_el)],
                axis=-1,
            )
        else:
            # Azimuth-only antennas (channelCfg 15 5 0, the shipped profile) measure the direction cosine x / r, which
            # includes cos(elevation); the firmware reports x = r (x / r), y = sqrt(r^2 - x^2), z = 0.
            ux = np.clip(np.cos(el) * np.sin(m_az), -1.0, 1.0)
            xyz_ti = np.stack([m_range * ux, m_range * np.sqrt(1.0 - ux * ux), np.zeros(n)], axis=-1)
        m_doppler = doppler + rng.normal(0.0, self.doppler_noise, n)
        if self.alias:
            m_doppler = np.mod(m_doppler + self.v_max, 2 * self.v_max) - self.v_max
        noise_db = 64.0 + 14.0 * np.exp(-rng_m / 4.0) + rng.normal(0.0, 1.5, n)
        return RadarDetections(
            t=float(t),
            frame_index=k,
            xyz_ti=xyz_ti,
            doppler=m_doppler,
            snr_db=echoes.snr,
            noise_db=noise_db,
            label=echoes.label,
            xyz_world=echoes.position,
            doppler_true=doppler,
            ghost_of=ghost_of,
            scatterer=echoes.scatterer,
            mirror_of=echoes.mirror_of,
        )


def _strongest(echoes: _Echoes, ghost_of: np.ndarray, limit: int) -> tuple[_Echoes, np.ndarray]:
    """The ``limit`` strongest echoes (all when there are no more), in their order; ghost indices follow them. A
    copy is always weaker than its source, so a kept copy keeps its source."""
    if echoes.size <= limit:
        return echoes, ghost_of
    keep = np.sort(np.argsort(-echoes.snr, kind="stable")[:limit])
    new_index = np.full(echoes.size, -1, np.int64)
    new_index[keep] = np.arange(keep.size)
    g = ghost_of[keep]
    return echoes.take(keep), np.where(g >= 0, new_index[np.maximum(g, 0)], -1)


def _blocked(origin: np.ndarray, points: np.ndarray, owner: np.ndarray, solids: _Solids) -> np.ndarray:
    """True where the sight line origin->point passes through a prism (hull, cabin, quay block) of another owner.

    ``origin`` is one world NED point (3,) or one per point (N, 3). In 3-D: the line crosses a prism's side where its
    footprint edge is cut, and is blocked only if its height there lies between the prism's bottom and top. A radar
    0.9 m up sees a 3 m cabin over a 0.6 m dinghy, and only the low returns of a boat behind a 1 m hull are lost;
    the water behind a hull is in its shadow. From one origin, only the (point, prism) pairs whose bearings overlap
    are tested edge by edge.
    """
    n = points.shape[0]
    verts = solids.vertices  # (P, K, 2) world (north, east)
    if n == 0 or verts.shape[0] == 0:
        return np.zeros(n, bool)
    if origin.ndim == 1:
        pt, pr = _pairs_in_bearing(origin[:2], points[:, :2], verts)
        o = np.broadcast_to(origin, (pt.size, 3))
    else:
        pt, pr = np.repeat(np.arange(n), verts.shape[0]), np.tile(np.arange(verts.shape[0]), n)
        o = origin[pt]
    a = verts[pr]  # (M, K, 2) the candidate prisms' corners
    s = np.roll(verts, -1, axis=1)[pr] - a  # (M, K, 2) their sides
    r = points[pt, :2] - o[:, :2]  # (M, 2) sight lines
    denom = r[:, None, 0] * s[..., 1] - r[:, None, 1] * s[..., 0]  # cross(r, s)
    qp = a - o[:, None, :2]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_ray = (qp[..., 0] * s[..., 1] - qp[..., 1] * s[..., 0]) / denom
        u_seg = (qp[..., 0] * r[:, None, 1] - qp[..., 1] * r[:, None, 0]) / denom
    # not at the ends: a sight line starting on a wall face (a bounce point) does not cross that face
    crosses = (np.abs(denom) > 1e-12) & (t_ray > 1e-6) & (t_ray < 1 - 1e-6) & (u_seg >= 0) & (u_seg <= 1)
    crosses &= (solids.owner[pr] != owner[pt])[:, None]
    # world z is down: heights above the water are -z
    h_origin, h_point = -o[:, 2], -points[pt, 2]
    h_cross = h_origin[:, None] + np.where(crosses, t_ray, 0.0) * (h_point - h_origin)[:, None]
    crosses &= (h_cross >= solids.bottom[pr][:, None]) & (h_cross <= solids.top[pr][:, None])
    blocked = np.zeros(n, bool)
    blocked[pt[np.any(crosses, axis=1)]] = True
    return blocked


def _pairs_in_bearing(origin: np.ndarray, points: np.ndarray, verts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(point, prism) index pairs where the point's bearing from ``origin`` lies within the prism's angular extent
    (world north, east). A convex prism seen from outside spans less than pi; one the origin is in or at spans all."""
    rel = verts - origin  # (P, K, 2)
    centre = np.arctan2(*rel.mean(axis=1)[:, ::-1].T)  # (P,) bearing of each prism's middle
    spread = _wrap(np.arctan2(rel[..., 1], rel[..., 0]) - centre[:, None])  # (P, K)
    lo, hi = spread.min(axis=1) - 1e-9, spread.max(axis=1) + 1e-9
    everywhere = (hi - lo >= math.pi - 1e-6) | (np.min(np.hypot(rel[..., 0], rel[..., 1]), axis=1) < 1e-6)
    bearing = _wrap(np.arctan2(points[:, 1] - origin[1], points[:, 0] - origin[0])[:, None] - centre[None, :])
    return np.nonzero(((bearing >= lo) & (bearing <= hi)) | everywhere)


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles to [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def _hull_scatterers(scene: Scene, seed: int, spread_db: float) -> _HullScatterers:
    """Each vessel's persistent strong scatterers: 2 + length / 10 m of them (2..6), picked among its hull corners
    (on the hull side, at 80 % of the freeboard, where it meets the deck) and its cabin's corners (60 % up the cabin),
    spread around the hull, with a third of them on the cabin when it has one. Fixed for the model's lifetime."""
    rows: list[tuple[int, int, np.ndarray, float, np.ndarray, float]] = []
    for j, v in enumerate(scene.vessels):  # per vessel, once
        rng = np.random.default_rng([seed, j, 0x5CA7])
        hull = _polygon(v.outline_body())
        groups = [(hull, _vertex_normals(hull), 0.8 * v.hull_top)]
        if v.has_cabin:
            cabin = _polygon(v.cabin_body())
            groups.append((cabin, _vertex_normals(cabin), v.hull_top + 0.6 * (v.height - v.hull_top)))
        k_all = int(np.clip(math.floor(2.5 + v.length / 10.0), 2, 6))
        k_cabin = min(k_all // 3, groups[-1][0].shape[0]) if v.has_cabin else 0
        picks = [k_all - k_cabin, k_cabin]
        index = 0
        for (corners, normals, height), k in zip(groups, picks, strict=False):
            for i in _spread_around(corners, min(k, corners.shape[0]), rng):
                rows.append((j, index, corners[i], height, normals[i], float(rng.uniform(-spread_db, spread_db))))
                index += 1
    if not rows:
        return _HullScatterers(
            np.zeros(0, np.int64),
            np.zeros(0, np.int64),
            np.zeros((0, 2)),
            np.zeros(0),
            np.zeros((0, 2, 2)),
            np.zeros(0),
        )
    vessel, index, body, height, normals, gain = zip(*rows, strict=True)
    return _HullScatterers(
        np.array(vessel, np.int64),
        np.array(index, np.int64),
        np.array(body, float),
        np.array(height, float),
        np.array(normals, float),
        np.array(gain, float),
    )


def _polygon(outline: np.ndarray) -> np.ndarray:
    """A padded body outline (K, 2) without its repeated vertices: the polygon's corners, in their order."""
    keep = np.ones(outline.shape[0], bool)
    keep[1:] = np.any(np.abs(np.diff(outline, axis=0)) > 1e-12, axis=1)
    poly = outline[keep]
    if poly.shape[0] > 1 and np.allclose(poly[0], poly[-1]):
        poly = poly[:-1]
    return poly


def _vertex_normals(poly: np.ndarray) -> np.ndarray:
    """(K, 2, 2): at each corner of a counter-clockwise (forward, starboard) polygon, the outward unit normals of the
    side arriving at it and of the side leaving it."""
    edge = np.roll(poly, -1, axis=0) - poly  # side i runs from corner i to corner i + 1
    normal = np.stack([edge[:, 1], -edge[:, 0]], axis=1) / np.hypot(edge[:, 0], edge[:, 1])[:, None]
    return np.stack([np.roll(normal, 1, axis=0), normal], axis=1)


def _spread_around(corners: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """Indices of ``k`` corners spread evenly by their bearing from the body origin (two of a box's four are
    diagonal, so one of them faces the radar from any side), starting at a random one."""
    if k <= 0:
        return np.zeros(0, np.int64)
    order = np.argsort(np.arctan2(corners[:, 1], corners[:, 0]))
    n = order.size
    return order[np.floor((np.arange(k) + rng.random()) * n / k).astype(np.int64) % n]


def _segment_distance(point: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Distance from a 2-D point to each segment starts[i] -> ends[i]."""
    d = ends - starts
    f = np.clip(np.sum((point - starts) * d, axis=1) / np.maximum(np.sum(d * d, axis=1), 1e-12), 0.0, 1.0)
    return np.hypot(*(starts + f[:, None] * d - point).T)


def _beyond_walls(origin: np.ndarray, points: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """True where the 2-D segment origin->point (world north, east) crosses a quay wall: the point is on land."""
    if points.shape[0] == 0 or starts.shape[0] == 0:
        return np.zeros(points.shape[0], bool)
    r = points - origin  # (N, 2)
    s = ends - starts  # (W, 2)
    q = starts - origin  # (W, 2)
    denom = r[:, None, 0] * s[None, :, 1] - r[:, None, 1] * s[None, :, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_ray = (q[None, :, 0] * s[None, :, 1] - q[None, :, 1] * s[None, :, 0]) / denom
        u_wall = (q[None, :, 0] * r[:, None, 1] - q[None, :, 1] * r[:, None, 0]) / denom
    crosses = (np.abs(denom) > 1e-12) & (t_ray > 0) & (t_ray < 1) & (u_wall >= 0) & (u_wall <= 1)
    return np.any(crosses, axis=1)


def _radial_integral(r0: float, r1: float, gamma: float) -> float:
    """Integral of r^(1 - gamma) dr from r0 to r1: the clutter in a sector per radian, for a density r^-gamma."""
    a = 2.0 - gamma
    if abs(a) < 1e-9:
        return math.log(r1 / r0)
    return (r1**a - r0**a) / a


def _draw_ranges(u: np.ndarray, r0: float, r1: float, gamma: float) -> np.ndarray:
    """Ranges in [r0, r1] with probability density proportional to r^(1 - gamma), from uniforms ``u`` (inverse CDF)."""
    a = 2.0 - gamma
    if abs(a) < 1e-9:
        return r0 * (r1 / r0) ** u
    return (r0**a + u * (r1**a - r0**a)) ** (1.0 / a)


def _sea_surface(sea: Sea, north: np.ndarray, east: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """Surface height above the mean (up positive, m) and the water's orbital velocity there (world NED, m/s).

    Deep-water linear waves: for each train with phase theta = k x - omega t + phi, height a sin(theta), horizontal
    velocity a omega sin(theta) along its direction of travel, upward velocity dh/dt = -a omega cos(theta) (so NED
    down + a omega cos(theta)). Same trains and phases as Sea.elevation.
    """
    height = np.zeros(north.shape)
    velocity = np.zeros((north.size, 3))
    for w in sea.waves:  # per wave train (a few), not per point
        theta = w.wavenumber * (north * math.cos(w.direction) + east * math.sin(w.direction)) - w.omega * t + w.phase
        speed = w.amplitude * w.omega
        height += w.amplitude * np.sin(theta)
        along = speed * np.sin(theta)
        velocity[:, 0] += along * math.cos(w.direction)
        velocity[:, 1] += along * math.sin(w.direction)
        velocity[:, 2] += speed * np.cos(theta)
    return height, velocity


def _place(body: np.ndarray, position: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Vessel body (forward, starboard) outlines (P, K, 2) -> world (north, east), one position (P, 2) and heading
    (P,) each."""
    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
    x, y = body[..., 0], body[..., 1]
    return np.stack([position[:, None, 0] + c * x - s * y, position[:, None, 1] + s * x + c * y], axis=-1)


def _vessel_prisms(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each vessel's hull and, above it, its cabin: body outlines (P, 5, 2), vessel index, bottom and top heights.

    A hull reaches below the water line (bottom -inf): a sight line to the water in a trough behind it, or inside
    its footprint, passes under the mean water line and is still blocked.
    """
    outlines, owner, bottom, top = [], [], [], []
    for j, v in enumerate(scene.vessels):  # per vessel, once
        for part in v.hull_parts_body():
            outlines.append(part)
            owner.append(j)
            bottom.append(-math.inf)
            top.append(v.hull_top)
        if v.has_cabin:
            outlines.append(v.cabin_body())
            owner.append(j)
            bottom.append(v.hull_top)
            top.append(v.height)
    return (
        np.array(outlines, float).reshape(-1, MAX_VERTICES, 2),
        np.array(owner, np.int64),
        np.array(bottom, float),
        np.array(top, float),
    )


def _quay_blocks(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """The quays' fixed blocks (wall face and land strip): world footprints (Q, 5, 2) and top heights (Q,)."""
    blocks = [q.blocks() for q in scene.quays]
    if not blocks:
        return np.zeros((0, MAX_VERTICES, 2)), np.zeros(0)
    tops = np.concatenate([np.full(len(b), q.height) for b, q in zip(blocks, scene.quays, strict=True)])
    return np.concatenate(blocks), tops


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
