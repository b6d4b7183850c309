"""The simulated harbour: vessels, quay walls and the own boat, all with analytic motion.

Every trajectory is a chain of legs of constant speed and constant turn rate, so position, heading, velocity and yaw
rate at any time follow in closed form. That makes the ground truth exact (no integration drift) and lets every query
be vectorised over time, which the sensor models need (one own-boat pose per LiDAR firing).

Frames
------
* world: local NED, metres; 2-D positions are (north, east). Headings are radians, 0 = north, clockwise positive.
* vessel body: (forward, starboard) in the horizontal plane; the own boat's body frame is FRD with its origin at the
  water line (so a sensor 1.5 m above the water has mount z = -1.5).

Solids are vertical prisms over convex footprints: a vessel hull from the water line (z = 0) up to its freeboard, an
optional superstructure above that, and quay blocks (the wall plus a strip of land behind it). The sensor models only
need these prisms, so ``Scene.prisms_at`` is the one geometric interface between scene and sensors.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from drivers.frames import EgoPose
from drivers.mount import Mount
from simulator.sea import Sea

MAX_VERTICES = 5  # pentagon hull; boxes are padded with a repeated vertex (a zero-length, inert edge)
HULLS = ("box", "pointed", "round", "buoy")
CURVE_POINTS = 9  # vertices on a curved hull's half-round: 22.5 deg apart, within 2 % of the radius of the curve

# Labels shared by the sensor models for points that do not come from a vessel (vessels are labelled 0..V-1).
LABEL_CLUTTER = -1  # LiDAR water/spray returns, radar sea clutter
LABEL_GHOST = -2  # radar multipath
LABEL_SHORE = -3  # quay walls and the land behind them
LABEL_WATER = -4  # LiDAR returns from the sea surface
LABEL_RAIN = -5  # LiDAR returns from rain drops


def wrap_angle(a: np.ndarray | float) -> np.ndarray | float:
    """Wrap to [-pi, pi)."""
    return (np.asarray(a) + math.pi) % (2 * math.pi) - math.pi


@dataclass(frozen=True)
class MotionState:
    """Kinematic state of one rigid body at one or more times (leading axis = time when ``t`` was an array)."""

    t: np.ndarray  # (T,) s
    position: np.ndarray  # (T, 2) north, east, m
    velocity: np.ndarray  # (T, 2) m/s
    heading: np.ndarray  # (T,) rad, 0 = north, clockwise
    yaw_rate: np.ndarray  # (T,) rad/s, clockwise positive


@dataclass(frozen=True)
class Leg:
    """A stretch of constant speed (along the heading) and constant turn rate, lasting ``duration`` seconds."""

    duration: float
    speed: float
    yaw_rate: float = 0.0


class Trajectory:
    """Chain of legs starting at ``start`` (north, east) with ``heading`` at time ``t0``.

    Before ``t0`` the first leg is extrapolated backwards; after the last leg the last leg continues (give a final
    zero-speed leg to stop). With ``loop=True`` the chain repeats with its total duration as period; that only makes
    sense for a closed path, which is checked.
    """

    def __init__(
        self,
        start: Sequence[float],
        heading: float,
        legs: Sequence[Leg],
        t0: float = 0.0,
        loop: bool = False,
        heading_jumps: Sequence[float] | None = None,
    ) -> None:
        if not legs:
            raise ValueError("a trajectory needs at least one leg")
        if not (np.all(np.isfinite(start)) and math.isfinite(heading) and math.isfinite(t0)):
            raise ValueError(f"trajectory start {start!r}, heading {heading!r} and t0 {t0!r} must be finite")
        if not all(math.isfinite(leg.speed) and math.isfinite(leg.yaw_rate) for leg in legs):
            raise ValueError("leg speeds and yaw rates must be finite")
        if any(leg.duration < 0 or not math.isfinite(leg.duration) for leg in legs[:-1]):
            raise ValueError("leg durations must be finite and >= 0")
        self.t0 = float(t0)
        self.loop = loop
        n = len(legs)
        jumps = np.zeros(n) if heading_jumps is None else np.asarray(heading_jumps, float)
        if jumps.shape != (n,):
            raise ValueError("heading_jumps needs one value per leg (applied at the leg's start)")
        self._speed = np.array([leg.speed for leg in legs], float)
        self._rate = np.array([leg.yaw_rate for leg in legs], float)
        durations = np.array([leg.duration for leg in legs], float)
        self._t_start = np.empty(n)
        self._p_start = np.empty((n, 2))
        self._h_start = np.empty(n)
        t, p, h = self.t0, np.asarray(start, float).copy(), float(heading)
        for i in range(n):
            h += jumps[i]
            self._t_start[i], self._p_start[i], self._h_start[i] = t, p, h
            dp, dh = _leg_displacement(self._speed[i], self._rate[i], h, durations[i])
            p, h, t = p + dp, h + dh, t + durations[i]
        self.end_time = t  # end of the last leg's nominal duration
        self.period = t - self.t0
        if loop:
            if not 0 < self.period < math.inf:
                raise ValueError("a looping trajectory needs a positive total duration")
            if np.hypot(*(p - self._p_start[0])) > 1e-6:
                raise ValueError("loop=True needs a closed path (it ends where it starts)")

    # -- constructors for the usual kinds ------------------------------------------------------------------------
    @classmethod
    def stationary(cls, position: Sequence[float], heading: float = 0.0) -> Trajectory:
        return cls(position, heading, [Leg(math.inf, 0.0)])

    @classmethod
    def constant_velocity(
        cls, start: Sequence[float], velocity: Sequence[float], t0: float = 0.0, heading: float | None = None
    ) -> Trajectory:
        """Straight line; heading = course over ground unless the body is still (then ``heading`` or 0)."""
        vn, ve = float(velocity[0]), float(velocity[1])
        speed = math.hypot(vn, ve)
        if speed > 0:
            return cls(start, math.atan2(ve, vn), [Leg(math.inf, speed)], t0)
        return cls(start, heading or 0.0, [Leg(math.inf, 0.0)], t0)

    @classmethod
    def constant_turn(
        cls, start: Sequence[float], heading: float, speed: float, yaw_rate: float, t0: float = 0.0
    ) -> Trajectory:
        """Circle of radius speed / |yaw_rate|; positive yaw rate turns clockwise (to starboard)."""
        return cls(start, heading, [Leg(math.inf, speed, yaw_rate)], t0)

    @classmethod
    def waypoints(
        cls,
        points: Sequence[Sequence[float]],
        speed: float,
        t0: float = 0.0,
        turn_radius: float = 0.0,
        loop: bool = False,
        stop_at_end: bool = True,
    ) -> Trajectory:
        """Straight legs through ``points`` (north, east) at constant ``speed``.

        With ``turn_radius > 0`` each corner is cut by a circular arc tangent to both legs (so heading and velocity
        are continuous and the yaw rate is speed / radius during the turn); the path then passes within
        ``turn_radius * (1/cos(turn/2) - 1)`` of the corner instead of through it. With ``loop=True`` the first
        point is appended to close the path and the corner at the start is rounded as well.
        """
        pts = np.asarray(points, float)
        if loop and np.hypot(*(pts[0] - pts[-1])) > 1e-9:
            pts = np.vstack([pts, pts[:1]])
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
            raise ValueError("waypoints need at least two (north, east) points")
        if speed <= 0:
            raise ValueError("waypoint speed must be > 0")
        seg = np.diff(pts, axis=0)
        seg_len = np.hypot(seg[:, 0], seg[:, 1])
        if np.any(seg_len <= 0):
            raise ValueError("consecutive waypoints must differ")
        course = np.arctan2(seg[:, 1], seg[:, 0])
        n_seg = len(seg)
        # turn at the end of segment i (into segment i+1); for loops also from the last back into the first
        n_corner = n_seg if loop else n_seg - 1
        turn = np.array([float(wrap_angle(course[(i + 1) % n_seg] - course[i])) for i in range(n_corner)])
        cut = turn_radius * np.tan(np.abs(turn) / 2) if turn_radius > 0 else np.zeros(n_corner)
        cut_before = np.zeros(n_seg)  # length removed at a segment's start by the previous corner's arc
        cut_after = np.zeros(n_seg)  # ... and at its end by the next corner's arc
        cut_after[:n_corner] = cut
        if loop:
            cut_before[0] = cut[-1]
        cut_before[1:] = cut[: n_seg - 1]
        straight = seg_len - cut_before - cut_after
        if np.any(straight < -1e-9):
            raise ValueError("turn_radius too large for these waypoints (arcs would overlap)")
        legs: list[Leg] = []
        jumps: list[float] = []
        for i in range(n_seg):
            legs.append(Leg(max(straight[i], 0.0) / speed, speed, 0.0))
            jumps.append(0.0 if (i == 0 or turn_radius > 0) else float(turn[i - 1]))
            if i < n_corner and turn_radius > 0 and abs(turn[i]) > 1e-12:
                rate = math.copysign(speed / turn_radius, turn[i])
                legs.append(Leg(abs(turn[i]) * turn_radius / speed, speed, rate))
                jumps.append(0.0)
        start = pts[0] + cut_before[0] * np.array([math.cos(course[0]), math.sin(course[0])])
        if not loop and stop_at_end:
            legs.append(Leg(math.inf, 0.0))
            jumps.append(0.0)
        return cls(start, float(course[0]), legs, t0, loop=loop, heading_jumps=jumps)

    # -- evaluation -----------------------------------------------------------------------------------------------
    def state(self, t: np.ndarray | float) -> MotionState:
        """State at time(s) ``t`` (scalar or (T,) array); always returns arrays with a leading time axis."""
        t = np.atleast_1d(np.asarray(t, float))
        local = t
        if self.loop:
            local = self.t0 + np.mod(t - self.t0, self.period)
        i = np.clip(np.searchsorted(self._t_start, local, side="right") - 1, 0, len(self._t_start) - 1)
        tau = local - self._t_start[i]
        v, w, h0 = self._speed[i], self._rate[i], self._h_start[i]
        dp, dh = _leg_displacement(v, w, h0, tau)
        heading = h0 + dh
        position = self._p_start[i] + dp
        velocity = np.stack([v * np.cos(heading), v * np.sin(heading)], axis=-1)
        return MotionState(t, position, velocity, np.asarray(wrap_angle(heading)), w.copy())


def _leg_displacement(
    speed: np.ndarray | float, rate: np.ndarray | float, h0: np.ndarray | float, tau: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray]:
    """Displacement (north, east) and heading change after ``tau`` s on a constant-speed, constant-rate arc.

    Written with sinc so that a zero turn rate is the straight-line limit, not a division by zero:
    sin(h0 + x) - sin(h0) = 2 cos(h0 + x/2) sin(x/2), likewise for cos.
    """
    speed, rate, h0, tau = np.broadcast_arrays(*(np.asarray(a, float) for a in (speed, rate, h0, tau)))
    tau = np.where(np.isinf(tau), 0.0, tau)  # a zero-speed infinite leg moves nowhere; never evaluated otherwise
    x = rate * tau
    dist = speed * tau * np.sinc(x / (2 * math.pi))  # np.sinc(y) = sin(pi y) / (pi y)
    mid = h0 + x / 2
    return np.stack([dist * np.cos(mid), dist * np.sin(mid)], axis=-1), x


# ---------------------------------------------------------------------------------------------------------------
# Solids


@dataclass
class Vessel:
    """A boat: a prism from the water line to ``freeboard``, plus a superstructure up to ``height`` if higher.

    ``hull`` "box" is a rectangle, "pointed" a rectangle whose front ``bow_fraction`` of the length narrows to a point
    on the centre line (a pentagon), "round" a rectangle with a half-round bow and stern (a RIB's tubes, a tender),
    "buoy" an elliptic cylinder (a buoy, a round float when length = width). ``height`` is the top of the highest
    part above the water, which is what the truth reports and what a sensor can see.
    """

    name: str
    length: float
    width: float
    height: float
    trajectory: Trajectory
    hull: str = "box"
    freeboard: float | None = None  # None: the hull reaches ``height`` (no superstructure)
    bow_fraction: float = 0.25
    cabin_length_fraction: float = 0.4
    cabin_width_fraction: float = 0.8
    cabin_offset_fraction: float = -0.1  # cabin centre, along the length from amidships (negative = aft)
    reflectivity: int = 40  # LiDAR calibrated reflectivity of the paint, 0..100
    rcs_scale: float = 1.0  # radar: multiplies the echo strength of the visible sides

    def __post_init__(self) -> None:
        if self.hull not in HULLS:
            raise ValueError(f"vessel {self.name!r}: hull must be one of {', '.join(HULLS)}, not {self.hull!r}")
        if not all(math.isfinite(x) and x > 0 for x in (self.length, self.width, self.height)):
            raise ValueError(f"vessel {self.name!r}: length, width and height must be finite and > 0")
        if not 0 <= self.bow_fraction < 1:
            raise ValueError(f"vessel {self.name!r}: bow_fraction must be in [0, 1)")
        if self.freeboard is not None and not 0 < self.freeboard <= self.height:
            raise ValueError(f"vessel {self.name!r}: freeboard must be in (0, height]")

    @property
    def hull_top(self) -> float:
        return self.height if self.freeboard is None else self.freeboard

    @property
    def has_cabin(self) -> bool:
        return self.freeboard is not None and self.freeboard < self.height

    def outline_body(self) -> np.ndarray:
        """(5, 2) hull footprint in (forward, starboard), counter-clockwise in that plane, padded to 5 vertices. A
        curved hull's is a pentagon on its outline (the truth's footprint and the radar's corners): its sides lie
        inside the curve by at most 0.19 x the radius for a buoy, 0.29 x the beam's half for a round bow's quarter."""
        L, W = self.length / 2, self.width / 2
        if self.hull == "box":
            return np.array([[-L, -W], [L, -W], [L, W], [-L, W], [-L, W]])
        if self.hull == "buoy":
            a = np.pi + 2.0 * np.pi * np.arange(5) / 5
            return np.column_stack([L * np.cos(a), W * np.sin(a)])
        if self.hull == "round":
            r = min(L, W)
            d = r * math.sqrt(0.5)
            return np.array([[-L + r - d, -d], [L - r, -W], [L, 0.0], [L - r, W], [-L + r - d, d]])
        b = self.length * self.bow_fraction
        return np.array([[-L, -W], [L - b, -W], [L, 0.0], [L - b, W], [-L, W]])

    def hull_polygon_body(self) -> np.ndarray:
        """(K, 2) the hull's whole outline in (forward, starboard), counter-clockwise: the outline's own vertices for
        box and pointed hulls, CURVE_POINTS on each half-round of a curved one."""
        if self.hull == "box":
            return self.outline_body()[:4]
        if self.hull == "pointed":
            return self.outline_body()
        L, W = self.length / 2, self.width / 2
        if self.hull == "buoy":
            a = np.pi + 2.0 * np.pi * np.arange(2 * CURVE_POINTS) / (2 * CURVE_POINTS)
            return np.column_stack([L * np.cos(a), W * np.sin(a)])
        r = min(L, W)
        a = np.linspace(-0.5 * np.pi, 0.5 * np.pi, CURVE_POINTS)  # the bow's half-round, port to starboard
        bow = np.column_stack([L - r + r * np.cos(a), r * np.sin(a)])
        stern = np.column_stack([-L + r - r * np.cos(a), -r * np.sin(a)])  # starboard to port
        return np.concatenate([stern[-1:], bow, stern[:-1]])  # from the stern's port end

    def hull_parts_body(self) -> list[np.ndarray]:
        """The hull as convex prisms of at most 5 vertices each, (5, 2) in (forward, starboard): the outline itself
        for box and pointed hulls; a curved hull's polygon cut into a fan of pentagons that share their chords. The
        ray casters take the nearest entry over all parts, so the chords inside the hull never show."""
        if self.hull in ("box", "pointed"):
            return [self.outline_body()]
        poly = self.hull_polygon_body()
        parts = []
        for i in range(1, poly.shape[0] - 1, MAX_VERTICES - 2):
            idx = [0, *range(i, min(i + MAX_VERTICES - 1, poly.shape[0]))]
            idx += [idx[-1]] * (MAX_VERTICES - len(idx))  # padded with a repeated vertex, an inert edge
            parts.append(poly[idx])
        return parts

    def cabin_body(self) -> np.ndarray:
        L = self.length * self.cabin_length_fraction / 2
        W = self.width * self.cabin_width_fraction / 2
        c = self.length * self.cabin_offset_fraction
        return np.array([[c - L, -W], [c + L, -W], [c + L, W], [c - L, W], [c - L, W]])

    def footprint_area(self) -> float:
        return polygon_area(self.outline_body())


@dataclass
class Quay:
    """A quay wall along a polyline (north, east), ``height`` above the water, land on one side.

    ``land_side`` is "starboard" or "port" of someone walking along the polyline from its first point. Each segment
    becomes a convex block ``depth`` metres deep into the land, so the top of the quay returns points too.
    """

    points: np.ndarray
    height: float = 1.5
    land_side: str = "starboard"
    depth: float = 4.0
    name: str = "quay"
    reflectivity: int = 25

    def __post_init__(self) -> None:
        self.points = np.asarray(self.points, float)
        if self.points.ndim != 2 or self.points.shape[1] != 2 or len(self.points) < 2:
            raise ValueError("a quay needs a polyline of at least two (north, east) points")
        if not np.all(np.isfinite(self.points)) or np.any(np.hypot(*np.diff(self.points, axis=0).T) <= 0):
            raise ValueError(f"quay {self.name!r}: points must be finite and consecutive points must differ")
        if not (self.height > 0 and self.depth > 0):
            raise ValueError(f"quay {self.name!r}: height and depth must be > 0")
        if self.land_side not in ("starboard", "port"):
            raise ValueError("land_side must be 'starboard' or 'port'")

    def land_normals(self) -> np.ndarray:
        """(S, 2) unit normals of each wall segment pointing into the land."""
        d = np.diff(self.points, axis=0)
        d /= np.hypot(d[:, 0], d[:, 1])[:, None]
        starboard = np.stack([-d[:, 1], d[:, 0]], axis=-1)  # course rotated 90 deg clockwise (NED)
        return starboard if self.land_side == "starboard" else -starboard

    def blocks(self) -> np.ndarray:
        """(S, 5, 2) convex blocks (wall face + land strip), counter-clockwise, padded to 5 vertices."""
        a, b = self.points[:-1], self.points[1:]
        n = self.land_normals() * self.depth
        quad = np.stack([a, b, b + n, a + n], axis=1)
        ccw = _signed_area(quad) > 0
        quad = np.where(ccw[:, None, None], quad, quad[:, ::-1])
        return np.concatenate([quad, quad[:, -1:]], axis=1)

    def wall_segments(self) -> tuple[np.ndarray, np.ndarray]:
        """The water-facing wall: segment starts (S, 2), ends (S, 2)."""
        return self.points[:-1].copy(), self.points[1:].copy()


@dataclass
class OwnBoat:
    """The boat carrying the sensors; roll and pitch are optional sinusoidal wave motion (radians, seconds)."""

    trajectory: Trajectory
    roll_amplitude: float = 0.0
    roll_period: float = 5.0
    pitch_amplitude: float = 0.0
    pitch_period: float = 3.7
    wave_phase: float = 0.0
    heave_amplitude: float = 0.0  # m, body origin up and down with the waves
    heave_period: float = 4.0

    def attitude(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        roll = self.roll_amplitude * np.sin(2 * math.pi * t / self.roll_period + self.wave_phase)
        pitch = self.pitch_amplitude * np.sin(2 * math.pi * t / self.pitch_period + 0.5 * self.wave_phase)
        return roll, pitch

    def attitude_rates(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """d(roll)/dt, d(pitch)/dt, rad/s: what a real autopilot's gyros report (as body rates) while rolling."""
        w_roll, w_pitch = 2 * math.pi / self.roll_period, 2 * math.pi / self.pitch_period
        roll_rate = self.roll_amplitude * w_roll * np.cos(w_roll * t + self.wave_phase)
        pitch_rate = self.pitch_amplitude * w_pitch * np.cos(w_pitch * t + 0.5 * self.wave_phase)
        return roll_rate, pitch_rate

    def poses(self, t: np.ndarray | float) -> OwnPoses:
        t = np.atleast_1d(np.asarray(t, float))
        s = self.trajectory.state(t)
        roll, pitch = self.attitude(t)
        down = -self.heave_amplitude * np.sin(2 * math.pi * t / self.heave_period + 0.7)
        return OwnPoses(t, s.position, s.velocity, roll, pitch, s.heading, s.yaw_rate, down)

    def pose(self, t: float) -> EgoPose:
        p = self.poses(t)
        roll_rate, pitch_rate = self.attitude_rates(np.array([float(t)]))
        return EgoPose(
            t=float(t),
            position=np.array([p.position[0, 0], p.position[0, 1], float(p.down[0])]),
            velocity=np.array([p.velocity[0, 0], p.velocity[0, 1], 0.0]),
            roll=float(p.roll[0]),
            pitch=float(p.pitch[0]),
            yaw=float(p.yaw[0]),
            yaw_rate=float(p.yaw_rate[0]),
            roll_rate=float(roll_rate[0]),
            pitch_rate=float(pitch_rate[0]),
        )


@dataclass(frozen=True)
class OwnPoses:
    """Own-boat poses at many times; the body origin sits on the water line, heaved to world z = ``down``."""

    t: np.ndarray  # (T,)
    position: np.ndarray  # (T, 2) north, east
    velocity: np.ndarray  # (T, 2)
    roll: np.ndarray  # (T,)
    pitch: np.ndarray
    yaw: np.ndarray
    yaw_rate: np.ndarray
    down: np.ndarray  # (T,) world z of the body origin, m (negative: heaved up)

    @property
    def position_ned(self) -> np.ndarray:
        return np.concatenate([self.position, self.down[:, None]], axis=1)


@dataclass(frozen=True)
class Prisms:
    """Vertical convex prisms at a batch of times, the only geometry the sensor models see.

    ``vertices`` is (B, P, 5, 2) world (north, east), counter-clockwise; a prism spans heights ``bottom``..``top``
    above the water. ``label`` is the vessel index or LABEL_SHORE.
    """

    vertices: np.ndarray  # (B, P, 5, 2)
    bottom: np.ndarray  # (P,) m above water
    top: np.ndarray  # (P,) m above water
    label: np.ndarray  # (P,) int
    reflectivity: np.ndarray  # (P,) LiDAR reflectivity 0..255


@dataclass(frozen=True)
class SensorConditions:
    """What the day does to the sensors, beyond the sea (sea.py): the sensor models take these as their defaults,
    so a scene carries its own weather and faults into every place that simulates it."""

    lidar_max_range: float = 100.0  # m; rain and fog cut it (a VLP-16 in heavy rain: about 40 m)
    lidar_dropout: float = 0.0  # chance a genuine return is lost (wet, dark surfaces)
    lidar_laser_dropout: float = 0.0  # chance a laser returns nothing for 0.1 s (a wet or fouled window)
    lidar_packet_loss: float = 0.0  # chance a data packet never arrives
    lidar_spray_rate: float = 30.0  # spurious low returns per second close to the boat
    # Radar (simulator/radar_model.py). The defaults keep the calm harbour of the earlier simulator.
    # Sea-clutter detections a frame in 1-50 m and +-60 deg of the radar; the model spreads them with a density that
    # falls with range. Calm water (ripples, wakes) gives the first; a sea adds the second times crest / 0.3 m, so
    # sea state 1 (0.05 m crests) adds a sixth of it, sea state 2 (0.15 m) half, sea state 3 (0.3 m) all.
    radar_clutter_calm: float = 3.0
    radar_clutter_sea_state_3: float = 150.0
    radar_ghost_probability: float = 0.1  # chance a detected hull return also comes back k times as far (multipath)
    radar_mirror_loss_db: float = 8.0  # a boat seen via a quay wall: its two reflections off the wall cost this much
    radar_snr_loss_db: float = 0.0  # two-way loss on every echo: rain, spray or a film of water on the radome


@dataclass
class Scene:
    """Everything in the harbour, plus the sensor mounts a scenario suggests for its own boat."""

    name: str
    own: OwnBoat
    vessels: list[Vessel] = field(default_factory=list)
    quays: list[Quay] = field(default_factory=list)
    duration: float = 30.0
    lidar_mount: Mount = field(default_factory=lambda: Mount(x=0.0, z=-1.6))
    radar_mount: Mount = field(default_factory=lambda: Mount(x=1.2, z=-0.9))
    description: str = ""
    sea: Sea = field(default_factory=Sea)
    conditions: SensorConditions = field(default_factory=SensorConditions)

    @property
    def n_vessels(self) -> int:
        return len(self.vessels)

    def vessel_index(self, name: str) -> int:
        """Id (index, also the sensor models' label) of the vessel called ``name``."""
        for i, v in enumerate(self.vessels):
            if v.name == name:
                return i
        raise KeyError(name)

    def vessel_states(self, t: np.ndarray | float) -> MotionState:
        """States of all vessels at times ``t``: arrays shaped (T, V, ...) (T = 1 for a scalar time)."""
        t = np.atleast_1d(np.asarray(t, float))
        v = len(self.vessels)
        pos, vel = np.zeros((len(t), v, 2)), np.zeros((len(t), v, 2))
        hdg, rate = np.zeros((len(t), v)), np.zeros((len(t), v))
        for j, vessel in enumerate(self.vessels):  # per vessel, vectorised over time
            s = vessel.trajectory.state(t)
            pos[:, j], vel[:, j], hdg[:, j], rate[:, j] = s.position, s.velocity, s.heading, s.yaw_rate
        return MotionState(t, pos, vel, hdg, rate)

    def footprints(self, t: np.ndarray | float) -> np.ndarray:
        """Hull footprints in world (north, east): (T, V, 5, 2), counter-clockwise, boxes padded to 5 vertices."""
        s = self.vessel_states(t)
        outline = np.array([v.outline_body() for v in self.vessels]).reshape(len(self.vessels), MAX_VERTICES, 2)
        return _place(outline[None], s.position, s.heading)

    def prisms_at(self, t: np.ndarray | float) -> Prisms:
        t = np.atleast_1d(np.asarray(t, float))
        s = self.vessel_states(t)
        outlines, bottoms, tops, labels, refl, owner = [], [], [], [], [], []
        for j, v in enumerate(self.vessels):
            for part in v.hull_parts_body():
                outlines.append(part)
                bottoms.append(0.0)
                tops.append(v.hull_top)
                labels.append(j)
                refl.append(v.reflectivity)
                owner.append(j)
            if v.has_cabin:
                outlines.append(v.cabin_body())
                bottoms.append(v.hull_top)
                tops.append(v.height)
                labels.append(j)
                refl.append(v.reflectivity)
                owner.append(j)
        parts = []
        if outlines:
            body = np.array(outlines)[None]  # (1, Pv, 5, 2)
            own_idx = np.array(owner)
            parts.append(_place(body, s.position[:, own_idx], s.heading[:, own_idx]))
        for q in self.quays:
            blocks = q.blocks()
            parts.append(np.broadcast_to(blocks[None], (len(t), *blocks.shape)))
            n = len(blocks)
            bottoms += [0.0] * n
            tops += [q.height] * n
            labels += [LABEL_SHORE] * n
            refl += [q.reflectivity] * n
        verts = np.concatenate(parts, axis=1) if parts else np.zeros((len(t), 0, MAX_VERTICES, 2))
        return Prisms(
            verts,
            np.array(bottoms, float),
            np.array(tops, float),
            np.array(labels, int),
            np.array(refl, float),
        )

    def quay_wall_segments(self) -> tuple[np.ndarray, np.ndarray]:
        """All water-facing quay wall segments: starts (S, 2), ends (S, 2), in world (north, east)."""
        if not self.quays:
            return np.zeros((0, 2)), np.zeros((0, 2))
        segs = [q.wall_segments() for q in self.quays]
        return np.concatenate([s[0] for s in segs]), np.concatenate([s[1] for s in segs])

    def quay_heights(self) -> np.ndarray:
        """(S,) wall height per segment, in the order of ``quay_wall_segments``."""
        return np.concatenate([np.full(len(q.points) - 1, q.height) for q in self.quays]) if self.quays else np.zeros(0)


def _place(outline_body: np.ndarray, position: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Body (forward, starboard) outlines (..., P, K, 2) -> world (north, east) at (T, P, 2), headings (T, P)."""
    c, s = np.cos(heading)[..., None], np.sin(heading)[..., None]
    x, y = outline_body[..., 0], outline_body[..., 1]
    north = position[..., None, 0] + c * x - s * y
    east = position[..., None, 1] + s * x + c * y
    return np.stack([north, east], axis=-1)


def _signed_area(poly: np.ndarray) -> np.ndarray:
    """Signed area of (..., K, 2) polygons; positive = counter-clockwise in the (first, second) coordinate plane."""
    x, y = poly[..., 0], poly[..., 1]
    return 0.5 * np.sum(x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y, axis=-1)


def polygon_area(poly: np.ndarray) -> float:
    """Area of a simple polygon given as (K, 2) vertices (repeated vertices are harmless)."""
    return float(abs(_signed_area(np.asarray(poly, float))))
