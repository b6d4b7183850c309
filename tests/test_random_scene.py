"""Scenes drawn from a seed (simulator/random_scene.py): nothing inside anything at any time, the drawn ranges hold,
the same seed gives the same scene, and the scene runs through the sensor models.

Geometry only (no sensor simulation) for the 200 seeds: the tuning seeds 1-100 and the held-out 1001-1100. The
checks here are written independently of the generator's own (exact polygon distances, not separating-axis gaps,
at times in between the generator's samples).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from simulator.lidar_model import Vlp16Model
from simulator.radar_model import Awr1843Model
from simulator.random_scene import ENCOUNTERS, HELD_OUT_SEEDS, TUNING_SEEDS, RandomScene, draw_scene
from simulator.scenarios import get_scenario
from simulator.scene import LABEL_SHORE, Quay, Scene, wrap_angle

SEEDS = [*TUNING_SEEDS, *HELD_OUT_SEEDS]
OWN_BOX = np.array([[-0.8, -0.5], [0.8, -0.5], [0.8, 0.5], [-0.8, 0.5]])  # the daemon's default box, body frame


@pytest.fixture(scope="module")
def drawn() -> dict[int, RandomScene]:
    return {seed: draw_scene(seed) for seed in SEEDS}


# -- exact geometry, independent of simulator/clearance.py ------------------------------------------------------------
def _point_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points p (..., 2) to segments a-b (..., 2)."""
    ab, ap = b - a, p - a
    len2 = np.sum(ab * ab, -1)
    u = np.clip(np.sum(ap * ab, -1) / np.where(len2 > 0, len2, 1.0), 0.0, 1.0)
    return np.linalg.norm(ap - u[..., None] * ab, axis=-1)


def _inside(p: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Points p (..., M, 2) strictly inside convex polygons poly (..., K, 2) of either orientation: (..., M)."""
    a = poly[..., None, :, :]
    e = np.roll(poly, -1, axis=-2)[..., None, :, :] - a
    w = p[..., :, None, :] - a
    cross = e[..., 0] * w[..., 1] - e[..., 1] * w[..., 0]
    real = np.sum(e * e, -1) > 0
    return np.all(np.where(real, cross > 0, True), -1) | np.all(np.where(real, cross < 0, True), -1)


def _distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Exact distance between convex polygons a (P, Ka, 2) and b (P, Kb, 2); 0 where they touch or overlap."""
    ea, eb = np.roll(a, -1, axis=1), np.roll(b, -1, axis=1)
    d_ab = _point_segment(a[:, :, None], b[:, None], eb[:, None]).min((1, 2))
    d_ba = _point_segment(b[:, :, None], a[:, None], ea[:, None]).min((1, 2))

    def orient(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
        return np.sign(
            (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
        )

    p1, p2 = a[:, :, None], ea[:, :, None]
    q1, q2 = b[:, None], eb[:, None]
    cross = (orient(p1, p2, q1) * orient(p1, p2, q2) < 0) & (orient(q1, q2, p1) * orient(q1, q2, p2) < 0)
    overlap = cross.any((1, 2)) | _inside(a, b).any(1) | _inside(b, a).any(1)
    return np.where(overlap, 0.0, np.minimum(d_ab, d_ba))


def _screen(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A lower bound of the distance between polygons a (..., Ka, 2) and b (..., Kb, 2): from the centre of a to
    b, less a's radius about that centre."""
    lead = np.broadcast_shapes(a.shape[:-2], b.shape[:-2])
    c = a.mean(-2)
    r = np.broadcast_to(np.linalg.norm(a - c[..., None, :], axis=-1).max(-1), lead)
    c = np.broadcast_to(c, (*lead, 2))
    to_edges = _point_segment(c[..., None, :], b, np.roll(b, -1, axis=-2)).min(-1)
    inside = _inside(c[..., None, :], b)[..., 0]
    return np.where(inside, 0.0, to_edges) - r


def _min_distance(a: np.ndarray, b: np.ndarray, margin: float) -> float:
    """Smallest distance between every polygon of a (T, A, Ka, 2) and every one of b (T, B, Kb, 2) over time (only
    pairs that can come within ``margin`` are measured exactly); inf when none can."""
    t, i, j = np.nonzero(_screen(a[:, :, None], b[:, None]) < margin + 1e-6)
    return float(_distance(a[t, i], b[t, j]).min()) if t.size else math.inf


def _min_distance_within(a: np.ndarray, margin: float) -> float:
    """Smallest distance between any two different polygons of a (T, A, K, 2) over time."""
    i, j = np.triu_indices(a.shape[1], 1)
    c = a.mean(-2)
    r = np.linalg.norm(a - c[..., None, :], axis=-1).max(-1)  # circles are enough between hulls of <= 50 m
    t, p = np.nonzero(np.linalg.norm(c[:, i] - c[:, j], axis=-1) - r[:, i] - r[:, j] < margin + 1e-6)
    return float(_distance(a[t, i[p]], a[t, j[p]]).min()) if t.size else math.inf


def _own_box(scene: Scene, t: np.ndarray) -> np.ndarray:
    p = scene.own.poses(t)
    c, s = np.cos(p.yaw)[:, None], np.sin(p.yaw)[:, None]
    x, y = OWN_BOX[:, 0], OWN_BOX[:, 1]
    return np.stack([p.position[:, :1] + c * x - s * y, p.position[:, 1:] + s * x + c * y], -1)[:, None]


def _static(blocks: list[np.ndarray], t: np.ndarray) -> np.ndarray:
    b = np.concatenate(blocks) if blocks else np.zeros((0, 5, 2))
    return np.broadcast_to(b[None], (len(t), *b.shape))


def _land(q: Quay) -> np.ndarray:
    """The water-side wall with the land behind it, 2 km deep: no vessel belongs in there."""
    deep = Quay(q.points, q.height, q.land_side, 2000.0)
    return deep.blocks()


# -- nothing inside anything, ever -------------------------------------------------------------------------------------
def test_no_solid_comes_near_the_own_boat_or_into_another_over_200_seeds(drawn: dict[int, RandomScene]) -> None:
    worst = dict.fromkeys(("own", "vessels", "moored", "under way"), math.inf)
    for seed, d in drawn.items():
        scene = d.scene
        # between the generator's 0.25 s samples, and both ends
        t = np.concatenate([[0.0], np.arange(0.1, scene.duration, 0.5), [scene.duration]])
        own = _own_box(scene, t)
        hulls = scene.footprints(t)
        quays = _static([q.blocks() for q in scene.quays], t)
        land = _static([_land(q) for q in scene.quays], t)
        # measured out to a little beyond each margin, so that the worst cases are known, not only bounded
        to_own = min(_min_distance(own, hulls, 8.0), _min_distance(own, quays, 8.0), _min_distance(own, land, 8.0))
        between = _min_distance_within(hulls, 2.0)
        moored = np.array([v.role == "moored" for v in d.vessels], bool)
        to_quay = min(_min_distance(hulls[:, moored], quays, 1.0), _min_distance(hulls[:, moored], land, 1.0))
        under_way = np.array([v.speed > 0 for v in d.vessels], bool)
        off_walls = min(_min_distance(hulls[:, under_way], quays, 3.0), _min_distance(hulls[:, under_way], land, 3.0))
        assert to_own >= 3.0, f"random:{seed}: a solid {to_own:.2f} m from the own boat's box"
        assert between >= 1.0, f"random:{seed}: two hulls {between:.2f} m apart"
        assert to_quay >= 0.2, f"random:{seed}: a moored hull {to_quay:.2f} m from a quay or on its land"
        assert off_walls >= 2.0, f"random:{seed}: a boat under way {off_walls:.2f} m from a quay or on its land"
        worst = {k: min(worst[k], x) for k, x in zip(worst, (to_own, between, to_quay, off_walls), strict=True)}
    # the margins are reached, not only respected from afar: the checks above bite
    assert worst["own"] < 4.5 and worst["vessels"] < 1.5 and worst["under way"] < 2.5
    assert worst["moored"] == pytest.approx(0.3, abs=1e-6)


# -- the drawn ranges -------------------------------------------------------------------------------------------------
def test_vessels_have_their_kinds_sizes_speeds_and_closest_approaches(drawn: dict[int, RandomScene]) -> None:
    for seed, d in drawn.items():
        scene = d.scene
        n_buoys = sum(info.kind == "buoy" for info in d.vessels)
        assert 7 <= scene.n_vessels - n_buoys <= 20 and n_buoys <= 3, f"random:{seed}"
        times = np.linspace(0.0, scene.duration, 241)  # the generator's 0.25 s grid, on which "closest" is defined
        own = scene.own.trajectory.state(times).position
        states = scene.vessel_states(times)
        hulls = scene.footprints(times)
        for i, (v, info) in enumerate(zip(scene.vessels, d.vessels, strict=True)):
            where = f"random:{seed} vessel {i} ({info.kind}, {info.role})"
            speed = np.hypot(*states.velocity[:, i].T)
            np.testing.assert_allclose(speed, info.speed, atol=1e-9, err_msg=where)
            assert 0.0 <= info.speed <= 8.0, where
            assert (info.speed == 0.0) == (info.role in ("moored", "anchored")), where
            # nearest the hull comes to the own boat's reference point, measured here on the same grid
            closest = np.min([_point_segment(own, hulls[:, i, k], hulls[:, i, (k + 1) % 5]) for k in range(5)])
            assert info.closest == pytest.approx(closest, abs=1e-9), where
            if info.kind == "buoy":
                assert v.hull == "buoy" and 0.8 <= v.length <= 2.0 and v.width == v.length, where
                assert 0.5 <= v.height <= 1.2 and info.role == "anchored" and 5.0 <= closest <= 60.0, where
                continue
            if info.kind == "ship":
                assert 30.0 <= v.length <= 50.0 and 40.0 <= closest <= 100.0, where
                assert v.hull == "pointed", where
                assert v.height > v.hull_top >= 2.5, where  # a superstructure on a high hull
            elif info.kind == "usv":
                assert 2.0 <= v.length <= 3.0 and 0.5 <= v.height <= 0.7 and not v.has_cabin, where
                assert 20.0 <= closest <= 60.0, where
            else:
                assert info.kind == "boat" and 4.0 <= v.length <= 15.0, where
                assert info.role == "moored" or 6.0 <= closest <= 80.0, where
            assert v.width < v.length, where


def test_moored_boats_lie_on_fenders_0_3_m_off_their_wall(drawn: dict[int, RandomScene]) -> None:
    n = 0
    for seed, d in drawn.items():
        for v, info in zip(d.scene.vessels, d.vessels, strict=True):
            if info.role != "moored":
                continue
            quay = d.scene.quays[info.quay]
            a, b = quay.wall_segments()
            hull = d.scene.footprints(0.0)[0, d.vessels.index(info)]
            gap = _point_segment(hull[:, None], a[None], b[None]).min()
            assert gap == pytest.approx(0.3, abs=0.01), f"random:{seed} {v.name}: {gap:.3f} m off its wall"
            # on the water side: the centre is off the land normal's side of the nearest segment
            centre = v.trajectory.state(0.0).position[0]
            seg = int(np.argmin(_point_segment(centre[None], a, b)))
            assert float((centre - a[seg]) @ quay.land_normals()[seg]) < 0, f"random:{seed} {v.name} on land"
            np.testing.assert_array_equal(d.scene.footprints(d.scene.duration)[0, d.vessels.index(info)], hull)
            n += 1
    assert n > 100  # moored boats are common, so this tested something


def test_encounters_are_crossing_overtaking_or_head_on_relative_to_the_own_course(
    drawn: dict[int, RandomScene],
) -> None:
    seen = dict.fromkeys(ENCOUNTERS, 0)
    for seed, d in drawn.items():
        for i, info in enumerate(d.vessels):
            if info.role not in ENCOUNTERS:
                continue
            t = info.t_encounter
            own = d.scene.own.trajectory.state(t)
            mine = d.scene.vessels[i].trajectory.state(t)
            rel = abs(math.degrees(float(wrap_angle(mine.heading[0] - own.heading[0]))))
            own_speed = float(np.hypot(*own.velocity[0]))
            where = f"random:{seed} vessel {i}: {info.role} at {rel:.1f} deg"
            if info.role == "head-on":
                assert rel >= 160.0 - 1e-9, where
            elif info.role == "crossing":
                assert 45.0 - 1e-9 <= rel <= 135.0 + 1e-9, where
            else:
                assert rel <= 15.0 + 1e-9 and abs(info.speed - own_speed) >= 1.0 - 1e-9, where
            seen[info.role] += 1
    assert min(seen.values()) > 200, seen


def test_own_boat_sea_and_day_stay_in_their_ranges(drawn: dict[int, RandomScene]) -> None:
    crest = {0: 0.0, 1: 0.05, 2: 0.15, 3: 0.3}
    for seed, d in drawn.items():
        own, sea, c = d.scene.own, d.scene.sea, d.scene.conditions
        where = f"random:{seed}"
        assert math.degrees(own.roll_amplitude) <= 5.0 and math.degrees(own.pitch_amplitude) <= 3.0, where
        assert all(3.0 <= p <= 8.0 for p in (own.roll_period, own.pitch_period, own.heave_period)), where
        assert 0.0 < own.heave_amplitude <= 0.25, where
        assert sea.crest == pytest.approx(crest[d.sea_state], abs=1e-12), where
        assert d.own_path.speed == 0.0 or 0.5 <= d.own_path.speed <= 5.0, where
        turns = [leg for leg in d.own_path.legs if leg.yaw_rate != 0.0]
        assert turns and all(0.05 <= abs(leg.yaw_rate) <= 0.25 for leg in turns), where
        if sea.rain_rate > 0:
            assert 2000.0 <= sea.rain_rate <= 15000.0 and 10.0 <= sea.rain_max_range <= 15.0, where
            assert c.lidar_max_range == pytest.approx(100.0 - 60.0 * sea.rain_rate / 15000.0), where
        else:
            assert c.lidar_max_range == 100.0, where
        assert 40.0 <= c.lidar_max_range <= 100.0, where
        assert 0.0 <= c.lidar_packet_loss <= 0.05 and 0.0 <= c.lidar_laser_dropout <= 0.1, where
        assert 0.0 <= c.lidar_dropout <= 0.1, where
    # bow spray grows with speed: every fast scene sprays more than every slow one in the same sea
    for state in range(4):
        fast = [
            d.scene.conditions.lidar_spray_rate for d in drawn.values() if d.sea_state == state and d.own_path.speed > 4
        ]
        slow = [
            d.scene.conditions.lidar_spray_rate
            for d in drawn.values()
            if d.sea_state == state and d.own_path.speed < 1.5
        ]
        assert fast and slow and min(fast) > max(slow), state


def test_quays_are_long_walls_alongside_the_own_boat(drawn: dict[int, RandomScene]) -> None:
    for seed, d in drawn.items():
        for q, info in zip(d.scene.quays, d.quays, strict=True):
            a, b = q.wall_segments()
            length = float(np.sum(np.hypot(*(b - a).T)))
            assert length == pytest.approx(info.length, abs=1e-9), f"random:{seed}"
            offset = float(_point_segment(np.zeros(2), a, b).min())  # the own boat starts at the origin
            assert offset == pytest.approx(info.offset, abs=1e-9), f"random:{seed}"
            if info.role == "wall":
                assert 100.0 <= length <= 300.0 and 20.0 <= offset <= 60.0, f"random:{seed}"
                assert len(a) <= 3, f"random:{seed}"  # a block per segment: a 300 m wall stays a few prisms
            else:
                assert 50.0 <= length <= 200.0 and 30.0 <= offset <= 100.0 and len(a) == 1, f"random:{seed}"
        # the sensor models' cost follows the prism count: a hull (six pentagons when curved), a cabin, a block per
        # wall segment
        parts = sum(len(v.hull_parts_body()) + v.has_cabin for v in d.scene.vessels)
        blocks = sum(len(q.blocks()) for q in d.scene.quays)
        assert d.scene.prisms_at(0.0).label.size == parts + blocks <= 80, f"random:{seed}"


def test_the_200_scenes_cover_every_kind_of_harbour(drawn: dict[int, RandomScene]) -> None:
    scenes = list(drawn.values())
    quays = [len(d.quays) for d in scenes]
    assert all(quays.count(n) >= 30 for n in (0, 1, 2)), quays
    assert {d.sea_state for d in scenes} == {0, 1, 2, 3}
    raining = sum(d.scene.sea.rain_rate > 0 for d in scenes)
    assert 30 <= raining <= 90, raining  # 30 % of the scenes
    assert sum(any(v.kind == "ship" for v in d.vessels) for d in scenes) >= 80
    assert sum(d.own_path.speed == 0.0 for d in scenes) >= 5
    assert sum(d.scene.conditions.lidar_packet_loss > 0 for d in scenes) >= 30
    # every count of vessels from 7 to 20, and of buoys from 0 to 3, beside them
    assert len({sum(v.kind != "buoy" for v in d.vessels) for d in scenes}) == 14
    assert {sum(v.kind == "buoy" for v in d.vessels) for d in scenes} == {0, 1, 2, 3}
    hulls = [v.hull for d in scenes for v, info in zip(d.scene.vessels, d.vessels, strict=True) if info.kind != "buoy"]
    shares = {h: hulls.count(h) / len(hulls) for h in ("pointed", "box", "round")}
    # a USV's hull round 30 %, a boat's 15 %; boats outnumber USVs about 4 to 1 (drawn: 0.16)
    assert 0.12 <= shares["round"] <= 0.22 and shares["pointed"] >= 0.6, shares


# -- the same seed, the same scene ------------------------------------------------------------------------------------
def _fingerprint(scene: Scene) -> tuple:
    t = np.linspace(0.0, scene.duration, 61)
    s = scene.vessel_states(t)
    own = scene.own.poses(t)
    return (
        scene.name,
        scene.description,
        [(v.name, v.length, v.width, v.height, v.freeboard, v.hull, v.reflectivity) for v in scene.vessels],
        s.position.tobytes(),
        s.heading.tobytes(),
        own.position.tobytes(),
        own.roll.tobytes(),
        own.down.tobytes(),
        [q.points.tobytes() for q in scene.quays],
        scene.sea,
        scene.conditions,
    )


def test_a_seed_always_draws_the_same_scene_and_seeds_differ(drawn: dict[int, RandomScene]) -> None:
    for seed in (1, 57, 1001):
        assert _fingerprint(draw_scene(seed).scene) == _fingerprint(drawn[seed].scene)
        assert _fingerprint(get_scenario(f"random:{seed}")) == _fingerprint(drawn[seed].scene)
    assert len({d.scene.description for d in drawn.values()}) == len(drawn)
    assert len({d.own_path.heading for d in drawn.values()}) == len(drawn)


def test_get_scenario_names_random_scenes_by_seed_and_duration() -> None:
    scene = get_scenario("random:17")
    assert scene.name == "random:17" and scene.duration == 60.0
    assert scene.description.startswith("random:17, 60 s")
    assert _fingerprint(get_scenario("random:17", seed=5)) == _fingerprint(scene)  # the name's seed wins
    assert _fingerprint(get_scenario("random", seed=17)) == _fingerprint(scene)
    longer = get_scenario("random:17:90")
    assert longer.duration == 90.0 and longer.name == "random:17"
    for bad in ("random:x", "random:-3", "random:17:soon", "random:17:inf"):
        with pytest.raises(ValueError, match="random"):
            get_scenario(bad)


def test_a_longer_scene_is_clear_for_its_whole_duration() -> None:
    d = draw_scene(23, duration=120.0)
    scene = d.scene
    t = np.arange(0.0, 120.0 + 1e-9, 0.5)
    hulls = scene.footprints(t)
    assert _min_distance(_own_box(scene, t), hulls, 3.0) >= 3.0
    assert _min_distance_within(hulls, 1.0) >= 1.0
    assert max(i.t_encounter for i in d.vessels if i.t_encounter is not None) > 60.0  # the second minute is used


def test_description_names_what_was_drawn() -> None:
    d = draw_scene(4)
    lines = d.scene.description.splitlines()
    assert lines[0] == "random:4, 60 s (tuning seeds 1-100, held out 1001-1100)"
    assert lines[1].startswith(f"day: sea state {d.sea_state} ")
    assert lines[2].startswith(f"own boat: {d.own_path.speed:.1f} m/s")
    counts = {k: sum(v.kind == k for v in d.vessels) for k in ("usv", "boat", "buoy", "ship")}
    assert (
        f"vessels {len(d.vessels)}: {counts['usv']} usv, {counts['boat']} boat, {counts['buoy']} buoy, "
        f"{counts['ship']} ship" in lines[4]
    )
    assert len(lines) == 5 + len(d.vessels)  # one line a vessel


# -- the scene runs through the sensor models ------------------------------------------------------------------------
def test_a_drawn_scene_runs_through_the_lidar_and_radar_models() -> None:
    d = draw_scene(2)
    scene = d.scene
    near = min(range(len(d.vessels)), key=lambda i: d.vessels[i].closest)
    t = d.vessels[near].t_closest
    lidar = Vlp16Model(scene, seed=1)
    assert lidar.max_range == scene.conditions.lidar_max_range  # the scene's day reaches the sensor
    hits = lidar.revolution_points(t)
    assert np.count_nonzero(hits.label == near) > 20, d.vessels[near]
    assert set(np.unique(hits.label)) <= {*range(scene.n_vessels), LABEL_SHORE}
    radar = Awr1843Model(scene, seed=1)
    frame = radar.frame(t, 0)
    assert frame.n_points > 0 and np.all(np.isfinite(frame.xyz_ti))
