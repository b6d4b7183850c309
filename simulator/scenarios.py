"""Named scenes for the demo, the tests and the benchmarks.

Sizes come from the two papers where they name them: the container (8.6 x 3.6 m), crew boat (43 x 10.4 m) and
fisher boat of the LiDAR shape-fitting paper (000), and the Smurf, Titan and Xi boats of the ROTracker radar paper
(001, Fig. 8), whose sequences are "static", "low", "mid" and "high" speed. Positions and speeds are the
simulator's own choice, picked so that each scene exercises one thing (see each builder's docstring).

``get_scenario("radar_paper:high")`` and ``get_scenario("radar_paper", speed="high")`` are the same scene.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from simulator.random_scene import random_scene
from simulator.scene import OwnBoat, Quay, Scene, Trajectory, Vessel

RADAR_PAPER_SPEEDS = {"static": 0.0, "low": 0.5, "mid": 1.5, "high": 3.0}  # m/s; the paper gives no numbers


def _still_own() -> OwnBoat:
    return OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0))


def harbour(seed: int = 0) -> Scene:
    """The built-in demo: the own boat runs north at 2 m/s along a quay (to starboard) through harbour traffic.

    Vessel ids: 0 moored 3 m off the quay, 1 anchored, 2 crossing ahead from the quay side, 3 overtaking to port,
    4 a crew boat far out, 5 a RIB circling. The own boat rolls and pitches gently (1.5 deg / 0.7 deg).
    """
    del seed  # the demo is the same every time
    quay = Quay(np.array([[-30.0, 16.0], [60.0, 16.0], [75.0, 22.0], [160.0, 22.0]]), height=1.5)
    own = OwnBoat(
        Trajectory.constant_velocity((0.0, 0.0), (2.0, 0.0)),
        roll_amplitude=math.radians(1.5),
        pitch_amplitude=math.radians(0.7),
    )
    vessels = [
        Vessel("moored", 10.0, 3.5, 1.8, Trajectory.stationary((35.0, 16.0 - 3.0 - 1.75), 0.0), freeboard=1.1),
        Vessel("anchored", 7.0, 2.5, 2.0, Trajectory.stationary((55.0, -22.0), math.radians(200)), hull="pointed"),
        Vessel("crossing", 6.5, 2.4, 1.6, Trajectory.constant_velocity((62.0, 10.0), (0.0, -3.0)), hull="pointed"),
        Vessel("overtaking", 5.5, 2.2, 1.3, Trajectory.constant_velocity((-25.0, -7.0), (3.5, 0.0))),
        Vessel(
            "crew_boat",
            43.0,
            10.4,
            7.5,
            Trajectory.constant_velocity((85.0, -35.0), (0.0, -1.2)),
            hull="pointed",
            freeboard=2.8,
            reflectivity=55,
            rcs_scale=3.0,
        ),
        Vessel("rib", 4.5, 2.0, 1.2, Trajectory.constant_turn((30.0, -33.0), 0.0, 3.0, 3.0 / 8.0), hull="pointed"),
    ]
    return Scene("harbour", own, vessels, [quay], duration=40.0, description=harbour.__doc__ or "")


def crossing(seed: int = 0) -> Scene:
    """Two boats cross each other 30 and 33.5 m ahead of a still own boat; at t = 12 s the far one (id 1) is hidden
    behind the near one (id 0), which is what breaks track ids in a naive tracker."""
    del seed
    vessels = [
        Vessel("west_to_east", 7.0, 2.5, 1.8, Trajectory.constant_velocity((30.0, -30.0), (0.0, 2.5)), hull="pointed"),
        Vessel("east_to_west", 6.0, 2.4, 1.5, Trajectory.constant_velocity((33.5, 30.0), (0.0, -2.5))),
    ]
    return Scene("crossing", _still_own(), vessels, [], duration=24.0, description=crossing.__doc__ or "")


def moorings(seed: int = 0) -> Scene:
    """Curved hulls: the own boat runs north at 1.5 m/s through a mooring field of round buoys (1.2 and 2 m), round-
    ended tenders and RIBs at their moorings, a box-hulled workboat among them, and a RIB crossing at 3 m/s: the
    LiDAR's adaptive fit (paper 000's Algorithm 4) meets hulls an ellipse fits better than a box."""
    del seed
    own = OwnBoat(Trajectory.constant_velocity((0.0, 0.0), (1.5, 0.0)))
    still = Trajectory.stationary
    vessels = [
        Vessel("buoy-1", 2.0, 2.0, 1.2, still((20.0, 12.0), 0.0), hull="buoy"),
        Vessel("buoy-2", 1.2, 1.2, 0.8, still((35.0, -10.0), 0.0), hull="buoy"),
        Vessel("buoy-3", 2.0, 2.0, 1.2, still((50.0, 14.0), 0.0), hull="buoy"),
        Vessel("tender-1", 4.0, 1.8, 0.8, still((28.0, 18.0), math.radians(200.0)), hull="round"),
        Vessel("tender-2", 5.0, 2.0, 0.9, still((42.0, -16.0), math.radians(170.0)), hull="round"),
        Vessel("rib-1", 8.0, 3.0, 1.2, still((60.0, 20.0), math.radians(190.0)), hull="round"),
        Vessel("workboat", 9.0, 3.5, 1.6, still((55.0, -20.0), math.radians(180.0)), hull="box", freeboard=1.0),
        Vessel("rib-crossing", 7.0, 2.6, 1.2, Trajectory.constant_velocity((68.0, -40.0), (0.0, 3.0)), hull="round"),
    ]
    return Scene("moorings", own, vessels, [], duration=30.0, description=moorings.__doc__ or "")


def container(seed: int = 0) -> Scene:
    """Paper 000's floating container (8.6 x 3.6 m, box) lying still; the own boat passes it at 2 m/s, 45 -> 20 m."""
    del seed
    own = OwnBoat(Trajectory.constant_velocity((0.0, 0.0), (2.0, 0.0)))
    vessels = [Vessel("container", 8.6, 3.6, 2.6, Trajectory.stationary((40.0, 20.0), math.radians(30)))]
    return Scene("container", own, vessels, [], duration=30.0, description=container.__doc__ or "")


def crew_boat(seed: int = 0) -> Scene:
    """Paper 000's 43 x 10.4 m crew boat crossing east at 2 m/s, 45 m ahead (nearest side ~40 m)."""
    del seed
    vessels = [
        Vessel(
            "crew_boat",
            43.0,
            10.4,
            7.5,
            Trajectory.constant_velocity((45.0, -50.0), (0.0, 2.0)),
            hull="pointed",
            freeboard=2.8,
            reflectivity=55,
            rcs_scale=3.0,
        )
    ]
    return Scene("crew_boat", _still_own(), vessels, [], duration=40.0, description=crew_boat.__doc__ or "")


def fisher(seed: int = 0) -> Scene:
    """A 12 x 4 m fisher boat circling the still own boat at 25 m radius and 3 m/s (yaw rate 0.12 rad/s)."""
    del seed
    traj = Trajectory.constant_turn((0.0, -25.0), 0.0, 3.0, 3.0 / 25.0)
    vessels = [Vessel("fisher", 12.0, 4.0, 3.5, traj, hull="pointed", freeboard=1.4)]
    return Scene("fisher", _still_own(), vessels, [], duration=40.0, description=fisher.__doc__ or "")


def radar_paper(seed: int = 0, speed: str = "low") -> Scene:
    """Paper 001's three boats in front of a still own boat, with a shore 28 m to starboard.

    ``speed`` is "static", "low" (0.5 m/s), "mid" (1.5 m/s) or "high" (3 m/s); moving boats run closed laps with
    rounded corners so they stay inside the radar's field of view. Ids: 0 Smurf, 1 Titan, 2 Xi.
    """
    del seed
    if speed not in RADAR_PAPER_SPEEDS:
        raise ValueError(f"radar_paper speed must be one of {sorted(RADAR_PAPER_SPEEDS)}, not {speed!r}")
    v = RADAR_PAPER_SPEEDS[speed]
    laps = {
        "smurf": [(12.0, -10.0), (24.0, -10.0), (24.0, -2.0), (12.0, -2.0)],
        "titan": [(18.0, 14.0), (18.0, 3.0), (34.0, 3.0), (34.0, 14.0)],
        "xi": [(30.0, -15.0), (45.0, -15.0), (45.0, 15.0), (30.0, 15.0)],
    }

    def path(points: list[tuple[float, float]]) -> Trajectory:
        if v == 0:
            (n0, e0), (n1, e1) = points[0], points[1]
            return Trajectory.stationary(points[0], math.atan2(e1 - e0, n1 - n0))
        return Trajectory.waypoints(points, v, turn_radius=2.5, loop=True)

    vessels = [
        Vessel("smurf", 2.9, 1.8, 0.6, path(laps["smurf"])),
        Vessel("titan", 3.5, 2.6, 1.0, path(laps["titan"])),
        Vessel("xi", 4.9, 2.95, 3.2, path(laps["xi"]), hull="pointed", freeboard=1.2),
    ]
    shore = Quay(np.array([[-10.0, 28.0], [80.0, 28.0]]), height=1.2, name="shore")
    return Scene(
        f"radar_paper:{speed}", _still_own(), vessels, [shore], duration=60.0, description=radar_paper.__doc__ or ""
    )


def dense(seed: int = 0) -> Scene:
    """20 vessels on 10 east-west lanes around a still own boat (for throughput benchmarks).

    Boats on a lane share one velocity, so they never collide; lanes alternate direction. Sizes, speeds and
    spacing are drawn from ``seed``; at t = 15 s every boat is within ~45 m east or west of the own boat.
    """
    rng = np.random.default_rng(seed)
    vessels: list[Vessel] = []
    lanes = [-46.0, -36.0, -26.0, -16.0, -6.0, 6.0, 16.0, 26.0, 36.0, 46.0]
    for i, north in enumerate(lanes):
        speed = rng.uniform(0.5, 2.5) * (1 if i % 2 == 0 else -1)
        mids = [-rng.uniform(12.0, 40.0), rng.uniform(12.0, 40.0)]
        for mid in mids:
            length = rng.uniform(4.0, 12.0)
            width = min(rng.uniform(1.8, 3.6), length / 2.2)
            start = (north, mid - speed * 15.0)
            vessels.append(
                Vessel(
                    f"lane{i}_{len(vessels) % 2}",
                    length,
                    width,
                    rng.uniform(1.0, 3.0),
                    Trajectory.constant_velocity(start, (0.0, speed)),
                    hull="pointed" if rng.random() < 0.5 else "box",
                )
            )
    return Scene("dense", _still_own(), vessels, [], duration=30.0, description=dense.__doc__ or "")


SCENARIOS: dict[str, Callable[..., Scene]] = {
    "harbour": harbour,
    "crossing": crossing,
    "container": container,
    "moorings": moorings,
    "crew_boat": crew_boat,
    "fisher": fisher,
    "radar_paper": radar_paper,
    "dense": dense,
    "random": random_scene,
}


def get_scenario(name: str, seed: int = 0, **params: str) -> Scene:
    """Build a named scene. ``name`` may carry one parameter after a colon: "radar_paper:high" is speed "high",
    "random:17" the scene drawn from seed 17 (the name's seed, not ``seed``, which then only seeds the sensors of
    whoever simulates it) and "random:17:90" the same kind of draw held collision-free for 90 s instead of 60."""
    base, _, arg = name.partition(":")
    if base not in SCENARIOS:
        raise ValueError(f"unknown scenario {name!r}; known: {', '.join(sorted(SCENARIOS))}")
    if arg:
        if base == "radar_paper":
            params = {"speed": arg, **params}
        elif base == "random":
            seed_text, _, duration = arg.partition(":")
            if not seed_text.isdigit() or (duration and not _is_number(duration)):
                raise ValueError(f"random scenes are named random:SEED or random:SEED:SECONDS, not {name!r}")
            seed = int(seed_text)
            if duration:
                params = {"duration": duration, **params}
        else:
            raise ValueError(f"scenario {base!r} takes no parameter (got {arg!r})")
    return SCENARIOS[base](seed, **params)


def _is_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False
