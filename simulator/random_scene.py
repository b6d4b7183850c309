"""Harbour scenes drawn from a seed: ``get_scenario("random:SEED")``, ``usv-tracker simulate --scene random:SEED``.

Seeds 1-100 are for tuning; seeds 1001-1100 are held out: never look at them while choosing a parameter, only to
measure the result. The generator depends on nothing that is tuned (no tracker or daemon setting): every range below
is a property of harbours, boats and sensors, fixed here, so a held-out seed is a scene nobody could have tuned to.
A scene lasts 60 s unless asked otherwise ("random:SEED:SECONDS"); it is checked over that span only.

What a scene holds (drawn uniformly within the ranges unless said otherwise; SI units, radians inside):

* the sea: WMO sea state 0-3 (``Sea.state``: crests 0, 0.05, 0.15, 0.3 m); the own boat rolls, pitches and heaves
  with it (roll up to 5 deg, pitch up to 3 deg, heave up to 0.25 m, the limits growing with the sea state; periods
  3-8 s);
* the own boat, starting at the origin on a random heading, at one speed (still 10 %, else 0.5-5 m/s) through legs
  of constant turn rate: straight 5-25 s, then turns of 15-90 deg at 0.05-0.25 rad/s, 70 % of them back towards
  the first course (as in a channel), and so on to the end;
* quays (none 20 %, one wall 45 %, a wall and one opposite 35 %): a long wall 100-300 m along the own boat's first
  course (+-5 deg), 20-60 m off it, each end bent 5-25 deg towards the land half the time; an opposite wall
  50-200 m long at 30-100 m;
* 7-20 vessels: moored boats (0-4 a wall, their hulls 0.3 m off the wall as on fenders); USVs 2-3 m long and
  0.5-0.7 m high coming no closer to the own boat than 20-60 m; boats 4-15 m (6-80 m); ships 30-50 m (0-2 a scene,
  40-100 m); and 0-3 round mooring buoys 0.8-2 m across and 0.5-1.2 m high (5-60 m). Hulls: a USV's pointed 40 %,
  box 30 %, round 30 % (an inflatable's tubes); a boat's pointed 70 %, box 15 %, round 15 % (a RIB, a tender); a
  ship's pointed. The closest approach is drawn log-uniformly, so near passes are as common as far ones; it is
  measured from the own boat's reference point to the hull every 0.25 s over the scene. Every vessel not moored
  meets the own boat around a drawn time as a crossing, overtaking or head-on encounter (relative to the own boat's
  course then), or lies at anchor (a quarter of the USVs, a fifth of the boats, every buoy, no ship); under way at
  0.5-4 m/s (USVs), 0.5-8 m/s (boats) or 1-6 m/s (ships), overtaking 1-3 m/s faster or slower than the own boat.
  Some turn 20-90 deg before or after the encounter (35 % of the USVs and boats; 20 % of the ships, 20-45 deg);
* the day: rain in 30 % of the scenes (2,000-15,000 drop returns a second out to 10-15 m, cutting the LiDAR's range
  from 100 m to as little as 40 m), bow spray growing with sea state and with the square of the own speed (30-690
  returns a second), LiDAR packet loss up to 0.05 in 30 % of the scenes, a laser or a return dropping out up to
  0.1 (more often in rain);
* the radar's conditions: drawn in ``_draw_radar_conditions`` (the radar model's defaults today).

Nothing is ever inside anything: the own boat's box (1.6 x 1.0 m, the daemon's default) keeps 3 m from every solid,
vessels keep 1 m from each other, and from quays (and out of the land behind them) 2 m under way and 0.2 m moored,
at every instant of the scene, not only at sampled times (clearance.py). A vessel that breaks this, or misses its
kind's closest approach, is placed again (its hull and role stay); after 40 failures the whole scene is drawn again.

Each part comes from a random stream of its own (``_stream``): sea, own-boat motion, weather and radar from the
seed, the solid geometry from the seed and the attempt. Changing how one part is drawn (e.g. adding radar
conditions) leaves the other parts of every seed as they were.

Frames: world NED, positions (north, east) m, headings 0 = north, clockwise. Degrees only in the description.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from simulator.clearance import Body, Occupancy, clear, point_polygon_distance, separation
from simulator.scene import (
    Leg,
    MotionState,
    OwnBoat,
    Quay,
    Scene,
    SensorConditions,
    Trajectory,
    Vessel,
    wrap_angle,
)
from simulator.sea import Sea

DEFAULT_DURATION_S = 60.0
TUNING_SEEDS = range(1, 101)
HELD_OUT_SEEDS = range(1001, 1101)

CHECK_STEP_S = 0.25  # clearance samples; the motion between samples is allowed for (clearance.py)
OWN_BOX_M = (1.6, 1.0)  # length, width: the daemon's default own-boat box
OWN_CLEARANCE_M = 3.0
VESSEL_CLEARANCE_M = 1.0
SHORE_CLEARANCE_M = 0.2  # a moored boat's hull lies FENDER_GAP_M off its wall
UNDER_WAY_SHORE_CLEARANCE_M = 2.0  # a boat under way keeps off the walls
FENDER_GAP_M = 0.3  # hull to wall of a moored boat
LAND_DEPTH_M = 2000.0  # how far behind a wall no vessel may be (the scene's solid quay is only a few m deep)
TRIES_PER_VESSEL = 40
MAX_ATTEMPTS = 200

ENCOUNTERS = ("crossing", "overtaking", "head-on")
_STREAMS = {"sea": 1, "own_motion": 2, "geometry": 3, "weather": 4, "radar": 5}


@dataclass(frozen=True)
class KindSpec:
    """What a kind of vessel may be: sizes, speeds, how close it comes to the own boat, how it manoeuvres."""

    length: tuple[float, float]  # m
    closest: tuple[float, float]  # m, own boat's reference point to the hull, over the whole scene
    speed: tuple[float, float]  # m/s when under way
    p_anchored: float
    p_manoeuvre: float
    turn_rate: tuple[float, float]  # rad/s
    max_turn: float  # rad
    encounter_p: tuple[float, float, float]  # crossing, overtaking, head-on


KINDS = {
    "usv": KindSpec(
        length=(2.0, 3.0),
        closest=(20.0, 60.0),
        speed=(0.5, 4.0),
        p_anchored=0.25,
        p_manoeuvre=0.35,
        turn_rate=(0.1, 0.4),
        max_turn=math.radians(90),
        encounter_p=(0.5, 0.25, 0.25),
    ),
    "boat": KindSpec(
        length=(4.0, 15.0),
        closest=(6.0, 80.0),
        speed=(0.5, 8.0),
        p_anchored=0.2,
        p_manoeuvre=0.35,
        turn_rate=(0.05, 0.25),
        max_turn=math.radians(90),
        encounter_p=(0.45, 0.25, 0.3),
    ),
    "buoy": KindSpec(  # mooring buoys and floats: round, low, never under way
        length=(0.8, 2.0),
        closest=(5.0, 60.0),
        speed=(0.0, 0.0),
        p_anchored=1.0,
        p_manoeuvre=0.0,
        turn_rate=(0.0, 0.0),
        max_turn=0.0,
        encounter_p=(1.0, 0.0, 0.0),
    ),
    "ship": KindSpec(  # always under way, turning slowly
        length=(30.0, 50.0),
        closest=(40.0, 100.0),
        speed=(1.0, 6.0),
        p_anchored=0.0,
        p_manoeuvre=0.2,
        turn_rate=(0.01, 0.04),
        max_turn=math.radians(45),
        encounter_p=(0.4, 0.2, 0.4),
    ),
}


@dataclass(frozen=True)
class DrawnVessel:
    """How one vessel of a drawn scene came about (the scene's vessel with the same index)."""

    kind: str  # "usv", "boat" or "ship"
    role: str  # "moored", "anchored", or one of ENCOUNTERS
    speed: float  # m/s
    closest: float  # m, nearest the hull comes to the own boat's reference point (sampled every CHECK_STEP_S)
    t_closest: float  # s
    t_encounter: float | None = None  # s, the time the encounter was drawn around (None: moored)
    relative_course: float | None = None  # rad, vessel course minus own course at t_encounter
    quay: int | None = None  # moored: index of its quay in scene.quays
    manoeuvre: str = ""


@dataclass(frozen=True)
class DrawnQuay:
    role: str  # "wall" or "opposite wall"
    length: float  # m along the wall
    offset: float  # m, the own boat's distance from the wall at t = 0
    side: str  # "port" or "starboard" of the own boat at t = 0


@dataclass(frozen=True)
class OwnPath:
    speed: float
    heading: float  # rad at t = 0
    legs: tuple[Leg, ...]


@dataclass(frozen=True)
class RandomScene:
    seed: int
    scene: Scene
    vessels: tuple[DrawnVessel, ...]
    quays: tuple[DrawnQuay, ...]
    sea_state: int
    own_path: OwnPath
    attempts: int  # geometry draws until one held (1 = the first)


def random_scene(seed: int = 0, duration: float | str = DEFAULT_DURATION_S) -> Scene:
    """The scene ``random:SEED`` (what ``get_scenario`` builds)."""
    return draw_scene(seed, float(duration)).scene


def draw_scene(seed: int, duration: float = DEFAULT_DURATION_S) -> RandomScene:
    """Draw a whole harbour scene from ``seed`` (an integer >= 0), free of collisions over ``duration`` seconds."""
    seed = int(seed)
    if seed < 0:
        raise ValueError(f"random scene seed must be >= 0, not {seed}")
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"random scene duration must be > 0 s, not {duration}")
    rng = _stream(seed, "sea")
    sea_state = int(rng.integers(0, 4))
    sea = Sea.state(sea_state, seed)
    own_motion = _draw_own_motion(_stream(seed, "own_motion"), sea_state)
    times = np.linspace(0.0, duration, math.ceil(duration / CHECK_STEP_S - 1e-9) + 1)
    for attempt in range(1, MAX_ATTEMPTS + 1):
        geometry = _draw_geometry(_stream(seed, "geometry", attempt), times)
        if geometry is not None:
            break
    else:  # pragma: no cover - never seen: each seed of 1-2000 needs at most a handful of attempts
        raise RuntimeError(f"random:{seed}: no collision-free scene in {MAX_ATTEMPTS} attempts")
    path, quays, drawn_quays, vessels, drawn_vessels = geometry
    sea, conditions = _draw_weather(_stream(seed, "weather"), sea, sea_state, path.speed)
    _draw_radar_conditions(_stream(seed, "radar"), sea_state, sea.rain_rate)
    own = OwnBoat(Trajectory((0.0, 0.0), path.heading, path.legs), **own_motion)
    scene = Scene(f"random:{seed}", own, vessels, quays, duration=float(duration), sea=sea, conditions=conditions)
    drawn = RandomScene(seed, scene, tuple(drawn_vessels), tuple(drawn_quays), sea_state, path, attempt)
    scene.description = describe(drawn)
    return drawn


def _stream(seed: int, part: str, attempt: int = 0) -> np.random.Generator:
    return np.random.default_rng([seed, _STREAMS[part], attempt])


# -- the sea and the own boat's motion in it ------------------------------------------------------------------------
def _draw_own_motion(rng: np.random.Generator, sea_state: int) -> dict[str, float]:
    """Roll, pitch and heave of the own boat: a calm sea still rocks it a little (wakes), a slight sea up to the
    brief's limits (5 deg, 3 deg, 0.25 m)."""
    rough = sea_state / 3.0
    u = rng.uniform(0.2, 1.0, 3)
    return {
        "roll_amplitude": math.radians(u[0] * (1.5 + 3.5 * rough)),
        "roll_period": float(rng.uniform(3.0, 8.0)),
        "pitch_amplitude": math.radians(u[1] * (1.0 + 2.0 * rough)),
        "pitch_period": float(rng.uniform(3.0, 8.0)),
        "heave_amplitude": float(u[2] * (0.05 + 0.2 * rough)),
        "heave_period": float(rng.uniform(3.0, 8.0)),
        "wave_phase": float(rng.uniform(0.0, 2 * math.pi)),
    }


def _draw_weather(rng: np.random.Generator, sea: Sea, sea_state: int, own_speed: float) -> tuple[Sea, SensorConditions]:
    """Rain, spray and LiDAR faults. Every value is drawn whether it is used or not, so the stream stays aligned."""
    raining = rng.random() < 0.3
    rate, rain_range = rng.uniform(2000.0, 15000.0), rng.uniform(10.0, 15.0)
    spray_gain = rng.uniform(200.0, 600.0)
    loss_on, loss = rng.random() < 0.3, rng.uniform(0.0, 0.05)
    laser_on, laser = rng.random(), rng.uniform(0.0, 0.1)
    drop_on, drop = rng.random(), rng.uniform(0.0, 0.1)
    if raining:
        sea = dataclasses.replace(sea, rain_rate=float(rate), rain_max_range=float(rain_range))
    # A VLP-16 in heavy rain reaches about 40 m; scale the cut with the rain's density.
    max_range = 100.0 - 60.0 * (rate / 15000.0) if raining else 100.0
    conditions = SensorConditions(
        lidar_max_range=float(max_range),
        lidar_dropout=float(drop) if drop_on < (0.6 if raining else 0.3) else 0.0,
        lidar_laser_dropout=float(laser) if laser_on < (0.6 if raining else 0.2) else 0.0,
        lidar_packet_loss=float(loss) if loss_on else 0.0,
        # spray off the bow: some from the sea itself, most from speed (the square of it, like the bow wave)
        lidar_spray_rate=float(30.0 + 20.0 * sea_state + spray_gain * (own_speed / 5.0) ** 2),
    )
    return sea, conditions


def _draw_radar_conditions(rng: np.random.Generator, sea_state: int, rain_rate: float) -> None:
    """The radar's day: sea clutter density and reach from the sea state, rain clutter, multipath off a calm sea.

    The radar model takes its own defaults today; when Scene carries radar clutter fields, draw them here from
    ``rng`` (a stream of its own: drawing more here changes no other quantity of any seed) and pass them to Scene.
    """
    del rng, sea_state, rain_rate


# -- geometry: own path, quays, vessels, all checked together ---------------------------------------------------------
_Geometry = tuple[OwnPath, list[Quay], list[DrawnQuay], list[Vessel], list[DrawnVessel]]


def _draw_geometry(rng: np.random.Generator, times: np.ndarray) -> _Geometry | None:
    """One attempt at the solid part of a scene; None when some vessel could not be placed."""
    duration = float(times[-1])
    path = _draw_own_path(rng, duration)
    own_traj = Trajectory((0.0, 0.0), path.heading, path.legs)
    own_state = own_traj.state(times)
    own_body = _own_body(own_state.position, own_state.heading, path)
    quays, drawn_quays = _draw_quays(rng, path.heading)
    deep = [dataclasses.replace(q, depth=LAND_DEPTH_M).blocks() for q in quays]
    if len(deep) == 2 and np.any(separation(deep[0][:, None], deep[1][None]) <= 0.0):
        return None  # the two walls would cross somewhere: no such harbour
    land = [Body.fixed(b) for blocks in deep for b in blocks]
    if not all(clear(own_body, b, OWN_CLEARANCE_M, CHECK_STEP_S) for b in land):
        return None

    n_total = int(rng.integers(7, 21))
    n_ship = int(rng.choice(3, p=[0.35, 0.45, 0.2]))
    n_usv = int(rng.integers(1, 5))
    n_buoy = int(rng.integers(0, 4))  # beside the 7-20 vessels
    wanted_moored = [int(rng.integers(0, 5)) for _ in quays]
    room = max(n_total - n_ship - n_usv - 2, 0)  # keep at least two boats under way or anchored
    moored_per_quay = []
    for w in wanted_moored:
        moored_per_quay.append(min(w, room))
        room -= moored_per_quay[-1]
    n_boat = n_total - n_ship - n_usv - sum(moored_per_quay)

    vessels: list[Vessel] = []
    drawn: list[DrawnVessel] = []
    placed = Occupancy(CHECK_STEP_S)
    placed.add(own_body, OWN_CLEARANCE_M)
    for b in land:
        placed.add(b, SHORE_CLEARANCE_M)

    def place(make: Callable[[], tuple[Vessel, DrawnVessel, float] | None]) -> bool:
        for _ in range(TRIES_PER_VESSEL):
            drawn_one = make()
            if drawn_one is None:
                continue
            vessel, info, sweep = drawn_one
            state = vessel.trajectory.state(times)
            if placed.on_fixed(state.position[::8]):  # a quick no: its centre crosses the land
                continue
            outline = _to_world(vessel.outline_body(), state.position, state.heading)
            body = Body.moving(outline, state.position, sweep)
            extra = UNDER_WAY_SHORE_CLEARANCE_M - SHORE_CLEARANCE_M if info.speed > 0 else 0.0
            if not placed.admits(body, fixed_extra=extra):
                continue
            dist = point_polygon_distance(own_state.position, outline)
            k = int(np.argmin(dist))
            info = dataclasses.replace(info, closest=float(dist[k]), t_closest=float(times[k]))
            if info.role != "moored":
                lo, hi = KINDS[info.kind].closest
                if not lo <= info.closest <= hi:
                    continue
            vessels.append(dataclasses.replace(vessel, name=f"{len(vessels):02d}-{info.kind}-{info.role}"))
            drawn.append(info)
            placed.add(body, VESSEL_CLEARANCE_M)
            return True
        return False

    # A vessel's hull and role are drawn once; only where and how it sails is drawn again when it does not fit, so
    # the refusals do not thin out the big hulls or the vessels under way.
    for qi, (quay, count) in enumerate(zip(quays, moored_per_quay, strict=True)):
        for _ in range(count):
            hull = _draw_hull(rng, "boat")
            if not place(lambda q=quay, i=qi, h=hull: _draw_moored(rng, h, q, i)):
                return None
    # biggest first: they are hardest to fit
    kinds = ["ship"] * n_ship + ["usv"] * n_usv + ["boat"] * n_boat + ["buoy"] * n_buoy
    for kind in kinds:
        hull, role = _draw_hull(rng, kind), _draw_role(rng, kind)
        if not place(lambda k=kind, h=hull, r=role: _draw_traffic(rng, k, h, r, own_state, placed.on_fixed)):
            return None
    return path, quays, drawn_quays, vessels, drawn


def _draw_own_path(rng: np.random.Generator, duration: float) -> OwnPath:
    still = rng.random() < 0.1
    speed = 0.0 if still else float(rng.uniform(0.5, 5.0))
    heading = float(rng.uniform(-math.pi, math.pi))
    legs = [Leg(float(rng.uniform(5.0, 25.0)), speed, 0.0)]
    t, turned = legs[0].duration, 0.0
    while t < duration:
        change = float(rng.uniform(math.radians(15), math.radians(90)))
        rate = float(rng.uniform(0.05, 0.25))
        back = rng.random() < 0.7  # mostly back towards the first course, as a boat keeping to a channel does
        sign = -math.copysign(1.0, turned) if (back and turned != 0.0) else float(rng.choice([-1.0, 1.0]))
        straight = float(rng.uniform(5.0, 25.0))
        legs += [Leg(change / rate, speed, sign * rate), Leg(straight, speed, 0.0)]
        t += change / rate + straight
        turned += sign * change
    legs[-1] = Leg(math.inf, speed, 0.0)  # the last straight goes on past the end of the scene
    return OwnPath(speed, heading, tuple(legs))


def _own_body(position: np.ndarray, heading: np.ndarray, path: OwnPath) -> Body:
    length, width = OWN_BOX_M
    x, y = length / 2, width / 2
    box = np.array([[-x, -y], [x, -y], [x, y], [-x, y], [-x, y]])  # padded to 5 vertices like the hulls
    outline = _to_world(box, position, heading)
    max_rate = max(abs(leg.yaw_rate) for leg in path.legs)
    return Body.moving(outline, position, path.speed + max_rate * math.hypot(length, width) / 2)


def _draw_quays(rng: np.random.Generator, own_heading: float) -> tuple[list[Quay], list[DrawnQuay]]:
    u = rng.random()
    n = 0 if u < 0.2 else 1 if u < 0.65 else 2
    side = float(rng.choice([-1.0, 1.0]))  # +1: the wall is to starboard of the own boat's first course
    draws = [
        # role, side, offset, length, where the own boat's foot lies along it (fraction), bend the ends?
        ("wall", side, rng.uniform(20.0, 60.0), rng.uniform(100.0, 300.0), rng.uniform(0.05, 0.6), True),
        ("opposite wall", -side, rng.uniform(30.0, 100.0), rng.uniform(50.0, 200.0), rng.uniform(0.05, 0.95), False),
    ]
    angles = rng.uniform(math.radians(-5), math.radians(5), 2)
    bends = rng.uniform(math.radians(5), math.radians(25), (2, 2))
    bend_on = rng.random((2, 2)) < 0.5
    bend_len = rng.uniform(0.1, 0.4, (2, 2))
    heights, depths = rng.uniform(0.8, 2.5, 2), rng.uniform(3.0, 8.0, 2)
    refl = rng.integers(15, 46, 2)
    quays, drawn = [], []
    for i in range(n):
        role, s, offset, length, foot, bendable = draws[i]
        course = own_heading + angles[i]
        along = np.array([math.cos(course), math.sin(course)])
        out = s * np.array([-along[1], along[0]])  # from the own boat towards the wall (starboard normal times s)
        foot_point = offset * out
        start, end = foot_point - foot * length * along, foot_point + (1 - foot) * length * along
        points = [start, end]
        if bendable:
            # Bend the ends towards the land about a kink at least 10 m from the foot point, keeping the length:
            # the wall nearest the own boat at t = 0 stays straight, so its distance then is ``offset``.
            head = min(bend_len[i, 0] * length, foot * length - 10.0)
            tail = min(bend_len[i, 1] * length, (1 - foot) * length - 10.0)
            if bend_on[i, 0] and head > 1.0:
                kink = start + head * along
                points[0] = kink - head * _rotate(along, -s * bends[i, 0])
                points.insert(1, kink)
            if bend_on[i, 1] and tail > 1.0:
                kink = end - tail * along
                points[-1] = kink + tail * _rotate(along, s * bends[i, 1])
                points.insert(len(points) - 1, kink)
        land_side = "starboard" if s > 0 else "port"
        quays.append(
            Quay(
                np.array(points),
                height=float(heights[i]),
                land_side=land_side,
                depth=float(depths[i]),
                name=f"quay{i}",
                reflectivity=int(refl[i]),
            )
        )
        drawn.append(DrawnQuay(role, float(length), float(offset), land_side))
    return quays, drawn


def _rotate(v: np.ndarray, angle: float) -> np.ndarray:
    """Rotate a (north, east) vector clockwise by ``angle`` (as a heading turns)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


# -- vessels ----------------------------------------------------------------------------------------------------------
def _draw_hull(rng: np.random.Generator, kind: str) -> Vessel:
    """Dimensions and looks of one vessel of ``kind``, lying still at the origin until it is placed."""
    u = rng.random(10)
    lo, hi = KINDS[kind].length
    length = lo + u[0] * (hi - lo)
    nowhere = Trajectory.stationary((0.0, 0.0))
    if kind == "buoy":  # a round mooring buoy or float
        return Vessel(
            kind,
            trajectory=nowhere,
            length=length,
            width=length,
            height=0.5 + 0.7 * u[1],
            hull="buoy",
            reflectivity=int(30 + 50 * u[2]),
        )
    if kind == "usv":  # a low, wide catamaran, dinghy-like or inflatable hull, no superstructure
        return Vessel(
            kind,
            trajectory=nowhere,
            length=length,
            width=length * (0.4 + 0.22 * u[1]),
            height=0.5 + 0.2 * u[2],
            hull="pointed" if u[3] < 0.4 else "box" if u[3] < 0.7 else "round",
            bow_fraction=0.15 + 0.1 * u[4],
            reflectivity=int(20 + 40 * u[5]),
        )
    if kind == "ship":
        freeboard = 2.5 + 2.5 * u[2]
        return Vessel(
            kind,
            trajectory=nowhere,
            length=length,
            width=length * (0.16 + 0.08 * u[1]),
            freeboard=freeboard,
            height=freeboard + 3.0 + 5.0 * u[3],
            hull="pointed",
            bow_fraction=0.12 + 0.1 * u[4],
            cabin_length_fraction=0.2 + 0.2 * u[5],
            cabin_offset_fraction=-0.3 + 0.2 * u[6],
            reflectivity=int(30 + 40 * u[7]),
            rcs_scale=3.0,
        )
    freeboard = 0.5 + 0.07 * length + 0.4 * u[2]  # 0.8-2.0 m: bigger boats stand higher
    cabin = u[3] < 0.6
    return Vessel(
        kind,
        trajectory=nowhere,
        length=length,
        width=min(length * (0.3 + 0.12 * u[1]), 4.5),
        freeboard=freeboard if cabin else None,
        height=freeboard + (0.8 + 1.7 * u[4] if cabin else 0.0),
        hull="pointed" if u[5] < 0.7 else "box" if u[5] < 0.85 else "round",  # round: a RIB or a tender
        bow_fraction=0.15 + 0.15 * u[6],
        cabin_length_fraction=0.25 + 0.25 * u[7],
        cabin_offset_fraction=-0.25 + 0.3 * u[8],
        reflectivity=int(15 + 55 * u[9]),
    )


def _sweep(vessel: Vessel, legs: Sequence[Leg]) -> float:
    """Fastest any point of the vessel moves, m/s: speed plus yaw rate times its farthest vertex."""
    reach = float(np.max(np.hypot(*vessel.outline_body().T)))
    return max(abs(leg.speed) + abs(leg.yaw_rate) * reach for leg in legs)


def _draw_moored(
    rng: np.random.Generator, hull: Vessel, quay: Quay, quay_index: int
) -> tuple[Vessel, DrawnVessel, float]:
    """``hull`` lying along a wall segment on fenders: its side FENDER_GAP_M off the wall, bow either way."""
    a, b = quay.wall_segments()
    seg_len = np.hypot(*(b - a).T)
    i = int(rng.choice(len(seg_len), p=seg_len / seg_len.sum()))
    along = (b[i] - a[i]) / seg_len[i]
    water = -quay.land_normals()[i]
    u = rng.random(2)
    room = seg_len[i] - hull.length - 2.0  # 1 m clear of either end of the segment
    s_along = hull.length / 2 + 1.0 + u[0] * room if room > 0 else seg_len[i] / 2  # (too long: refused later)
    centre = a[i] + s_along * along + (FENDER_GAP_M + hull.width / 2) * water
    heading = math.atan2(along[1], along[0]) + (0.0 if u[1] < 0.5 else math.pi)
    vessel = dataclasses.replace(hull, trajectory=Trajectory.stationary(centre, heading))
    return vessel, DrawnVessel("boat", "moored", 0.0, math.nan, math.nan, quay=quay_index), 0.0


def _draw_role(rng: np.random.Generator, kind: str) -> str:
    spec = KINDS[kind]
    anchored = rng.random() < spec.p_anchored
    return "anchored" if anchored else str(rng.choice(ENCOUNTERS, p=spec.encounter_p))


def _draw_traffic(
    rng: np.random.Generator,
    kind: str,
    hull: Vessel,
    role: str,
    own: MotionState,
    blocked: Callable[[np.ndarray], bool],
) -> tuple[Vessel, DrawnVessel, float] | None:
    """``hull`` meeting the own boat (``own``: its states at the check times) in ``role``: placed so that at a
    drawn time its hull is a drawn distance off the own boat, on the line of closest approach of their relative
    motion then. The time is one of the check times within the middle 70 % of the scene. None when that place is
    ``blocked`` (on land): the vessel could not be there, so nothing more is built."""
    spec = KINDS[kind]
    u = rng.random(14)  # all at once, so that an early refusal leaves the stream where a full draw would
    n_t = len(own.t) - 1
    k = math.ceil(0.15 * n_t) + int(u[0] * (math.floor(0.85 * n_t) - math.ceil(0.15 * n_t) + 1))
    t_enc = float(own.t[k])
    p_own, v_own, h_own = own.position[k], own.velocity[k], float(own.heading[k])
    own_speed = float(np.hypot(*v_own))
    # log-uniform: as many vessels pass at 6-12 m as at 40-80 m, where the sensors' points thin out anyway
    target = spec.closest[0] * (spec.closest[1] / spec.closest[0]) ** u[1]
    side = 1.0 if u[2] < 0.5 else -1.0
    speed = 0.0 if role == "anchored" else spec.speed[0] + u[3] * (spec.speed[1] - spec.speed[0])
    if role == "head-on":
        relative = math.pi + math.radians(-20 + 40 * u[4])
    elif role == "crossing":
        relative = (1.0 if u[5] < 0.5 else -1.0) * math.radians(45 + 90 * u[4])
    elif role == "overtaking":
        relative = math.radians(-15 + 30 * u[4])
        speed = _overtaking_speed(u[5], u[6], own_speed, spec.speed)
    else:
        relative = -math.pi + 2 * math.pi * u[4]
    heading = h_own + relative
    course = np.array([math.cos(heading), math.sin(heading)])
    v_rel = speed * course - v_own
    if np.hypot(*v_rel) > 0.05:
        n = side * np.array([-v_rel[1], v_rel[0]]) / np.hypot(*v_rel)
    else:  # no relative motion: anywhere around
        bearing = 2 * math.pi * u[7]
        n = np.array([math.cos(bearing), math.sin(bearing)])
    along_n = abs(float(course @ n))  # the hull's half-extent towards the own boat, so that target is hull distance
    half = hull.length / 2 * along_n + hull.width / 2 * math.sqrt(max(1 - along_n**2, 0.0))
    centre = p_own + (target + half) * n
    if blocked(centre[None]):
        return None
    before: list[Leg] = []
    after: list[Leg] = []
    manoeuvre = ""
    if speed > 0 and u[8] < spec.p_manoeuvre:
        turn = (math.radians(20) + u[9] * (spec.max_turn - math.radians(20))) * (1.0 if u[10] < 0.5 else -1.0)
        rate = spec.turn_rate[0] + u[11] * (spec.turn_rate[1] - spec.turn_rate[0])
        gap = 3.0 + 17.0 * u[12]
        turn_leg = Leg(abs(turn) / rate, speed, math.copysign(rate, turn))
        if u[13] < 0.5:
            after = [Leg(gap, speed), turn_leg]
            at = t_enc + gap
        else:
            before = [turn_leg, Leg(gap, speed)]
            at = t_enc - gap - turn_leg.duration
        direction = "starboard" if turn > 0 else "port"
        manoeuvre = f"turns {math.degrees(abs(turn)):.0f} deg to {direction} at {at:.0f} s"
    traj = _trajectory_through(centre, heading, t_enc, before, after, speed)
    vessel = dataclasses.replace(hull, trajectory=traj)
    legs = [*before, *after, Leg(math.inf, speed)]
    info = DrawnVessel(
        kind,
        role,
        float(speed),
        math.nan,
        math.nan,
        t_encounter=t_enc,
        relative_course=float(wrap_angle(relative)),
        manoeuvre=manoeuvre,
    )
    return vessel, info, _sweep(vessel, legs)


def _overtaking_speed(u_side: float, u_speed: float, own_speed: float, limits: tuple[float, float]) -> float:
    """1-3 m/s faster or slower than the own boat, within the kind's speeds: an overtaking that happens in a minute.
    Faster or slower in proportion to the room there is for each."""
    faster = (max(own_speed + 1.0, limits[0]), min(own_speed + 3.0, limits[1]))
    slower = (max(own_speed - 3.0, limits[0]), min(own_speed - 1.0, limits[1]))
    room = [max(hi - lo, 0.0) for lo, hi in (faster, slower)]
    if sum(room) == 0.0:  # the kind cannot be 1 m/s off the own boat's speed: as far off as it can
        return limits[1] if limits[1] - own_speed >= own_speed - limits[0] else limits[0]
    lo, hi = faster if u_side * sum(room) < room[0] else slower
    return lo + u_speed * (hi - lo)


def _trajectory_through(
    position: np.ndarray, heading: float, t: float, before: Sequence[Leg], after: Sequence[Leg], speed: float
) -> Trajectory:
    """A trajectory that is at ``position`` with ``heading`` at time ``t``, having sailed ``before`` up to then and
    sailing ``after`` from then, straight at ``speed`` outside those legs."""
    north, east, h = float(position[0]), float(position[1]), float(heading)
    for leg in reversed(before):  # walk back to where the first leg began
        x = leg.yaw_rate * leg.duration  # heading change over the leg
        h -= x
        # chord of the arc: length v T sin(x/2) / (x/2), along the mean heading (scene.py's closed form)
        chord = leg.speed * leg.duration * (math.sin(x / 2) / (x / 2) if abs(x) > 1e-12 else 1.0)
        north -= chord * math.cos(h + x / 2)
        east -= chord * math.sin(h + x / 2)
    t0 = t - sum(leg.duration for leg in before)
    # The zero-length straight leg first: before t0 a trajectory repeats its first leg backwards, which must be
    # a straight line, not the turn.
    legs = [Leg(0.0, speed), *before, *after, Leg(math.inf, speed)]
    return Trajectory((north, east), h, legs, t0=t0)


def _to_world(outline: np.ndarray, position: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Body (forward, starboard) outline (K, 2) -> world (north, east) (T, K, 2) at positions (T, 2), headings (T,)."""
    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
    x, y = outline[None, :, 0], outline[None, :, 1]
    return np.stack([position[:, :1] + c * x - s * y, position[:, 1:] + s * x + c * y], axis=-1)


# -- description ------------------------------------------------------------------------------------------------------
def describe(drawn: RandomScene) -> str:
    """A few lines saying what was drawn, so that a failing seed can be understood without plotting it."""
    scene, path = drawn.scene, drawn.own_path
    sea, c = scene.sea, scene.conditions
    lines = [f"random:{drawn.seed}, {scene.duration:.0f} s (tuning seeds 1-100, held out 1001-1100)"]
    rain = f"rain {sea.rain_rate:,.0f} drops/s to {sea.rain_max_range:.1f} m" if sea.rain_rate > 0 else "no rain"
    lines.append(
        f"day: sea state {drawn.sea_state} (crest {sea.crest:.2f} m), {rain}, LiDAR range {c.lidar_max_range:.0f} m, "
        f"spray {c.lidar_spray_rate:.0f}/s, packet loss {c.lidar_packet_loss:.3f}, "
        f"laser dropout {c.lidar_laser_dropout:.3f}, return dropout {c.lidar_dropout:.3f}"
    )
    own = scene.own
    legs = []
    for leg in path.legs:
        if leg.yaw_rate == 0.0:
            legs.append("straight" if math.isinf(leg.duration) else f"straight {leg.duration:.0f} s")
        else:
            turn = math.degrees(abs(leg.yaw_rate) * leg.duration)
            legs.append(f"{turn:.0f} deg {'stbd' if leg.yaw_rate > 0 else 'port'} in {leg.duration:.0f} s")
    lines.append(
        f"own boat: {path.speed:.1f} m/s from heading {math.degrees(path.heading) % 360:.0f} deg: "
        + ", ".join(legs)
        + f"; roll {math.degrees(own.roll_amplitude):.1f} deg/{own.roll_period:.1f} s, "
        f"pitch {math.degrees(own.pitch_amplitude):.1f} deg/{own.pitch_period:.1f} s, "
        f"heave {own.heave_amplitude:.2f} m/{own.heave_period:.1f} s"
    )
    quays = [f"{q.role} {q.length:.0f} m at {q.offset:.0f} m to {q.side}" for q in drawn.quays]
    lines.append("quays: " + ("; ".join(quays) if quays else "none (open water)"))
    kinds = {k: sum(v.kind == k for v in drawn.vessels) for k in KINDS}
    roles = {r: sum(v.role == r for v in drawn.vessels) for r in ("moored", "anchored", *ENCOUNTERS)}
    lines.append(
        f"vessels {len(drawn.vessels)}: "
        + ", ".join(f"{n} {k}" for k, n in kinds.items())
        + "; "
        + ", ".join(f"{n} {r}" for r, n in roles.items())
    )
    for i, (v, d) in enumerate(zip(scene.vessels, drawn.vessels, strict=True)):
        size = f"{v.length:.1f} x {v.width:.1f} x {v.height:.1f} m {v.hull}"
        if d.role == "moored":
            what = f"moored at quay{d.quay}"
        elif d.role == "anchored":
            what = "at anchor"
        else:
            what = f"{_encounter_words(d, path.speed)} at {d.speed:.1f} m/s"
        extra = f", {d.manoeuvre}" if d.manoeuvre else ""
        lines.append(f"  {i:2d} {d.kind:4s} {size}: {what}, closest {d.closest:.0f} m at {d.t_closest:.0f} s{extra}")
    return "\n".join(lines)


def _encounter_words(d: DrawnVessel, own_speed: float) -> str:
    rel = d.relative_course or 0.0
    if d.role == "crossing":  # heading to starboard of the own course: it comes from port
        return f"crossing from {'port' if rel > 0 else 'starboard'}"
    if d.role == "overtaking":
        return "overtaking the own boat" if d.speed > own_speed else "overtaken by the own boat"
    return "head-on"
