"""Scene geometry, analytic trajectories, scenarios and the truth CSV."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from simulator.clearance import separation
from simulator.scenarios import SCENARIOS, get_scenario
from simulator.scene import Leg, OwnBoat, Quay, Scene, Trajectory, Vessel, polygon_area
from simulator.truth import read_truth_csv, truth_at, write_truth_csv


def test_pointed_hull_is_a_pentagon_with_the_bow_triangles_cut_off() -> None:
    v = Vessel("fisher", 12.0, 4.0, 3.0, Trajectory.stationary((0.0, 0.0)), hull="pointed", bow_fraction=0.25)
    # rectangle 12 x 4 minus two bow triangles of 3 m x 2 m each: 48 - 6 = 42 m^2
    assert v.footprint_area() == pytest.approx(42.0, abs=1e-12)
    box = Vessel("box", 12.0, 4.0, 3.0, Trajectory.stationary((0.0, 0.0)))
    assert box.footprint_area() == pytest.approx(48.0, abs=1e-12)


def test_footprint_in_world_follows_heading_east() -> None:
    v = Vessel("b", 8.0, 2.0, 1.0, Trajectory.stationary((10.0, 5.0), math.pi / 2), hull="pointed")
    scene = Scene("t", OwnBoat(Trajectory.stationary((0.0, 0.0))), [v])
    fp = scene.footprints(0.0)[0, 0]  # (5, 2) north, east
    assert fp[:, 0].min() == pytest.approx(9.0) and fp[:, 0].max() == pytest.approx(11.0)
    assert fp[:, 1].min() == pytest.approx(1.0) and fp[:, 1].max() == pytest.approx(9.0)
    bow = fp[2]  # the pentagon's tip is vertex 2
    np.testing.assert_allclose(bow, [10.0, 9.0], atol=1e-12)
    assert polygon_area(fp) == pytest.approx(v.footprint_area(), abs=1e-9)


def test_constant_turn_stays_on_its_circle() -> None:
    speed, rate = 3.0, 0.12
    traj = Trajectory.constant_turn((0.0, -25.0), 0.0, speed, rate)
    t = np.linspace(0.0, 60.0, 241)
    s = traj.state(t)
    radius = np.hypot(s.position[:, 0], s.position[:, 1])  # centre is 25 m to starboard of the start = origin
    np.testing.assert_allclose(radius, 25.0, atol=1e-9)
    np.testing.assert_allclose(np.hypot(*s.velocity.T), speed, atol=1e-12)
    np.testing.assert_allclose(np.cos(s.heading), np.cos(rate * t), atol=1e-12)
    np.testing.assert_allclose(s.yaw_rate, rate)
    # clockwise: a quarter turn later the boat is at the north of the circle heading east
    q = traj.state(math.pi / 2 / rate)
    np.testing.assert_allclose(q.position[0], [25.0, 0.0], atol=1e-9)
    assert q.heading[0] == pytest.approx(math.pi / 2)


def test_tiny_turn_rate_is_the_straight_line_limit() -> None:
    a = Trajectory.constant_turn((1.0, 2.0), 0.3, 2.0, 1e-14).state(np.array([0.0, 7.5, 30.0]))
    b = Trajectory.constant_velocity((1.0, 2.0), (2.0 * math.cos(0.3), 2.0 * math.sin(0.3))).state(
        np.array([0.0, 7.5, 30.0])
    )
    np.testing.assert_allclose(a.position, b.position, atol=1e-9)


def test_sharp_waypoints_are_passed_on_time_and_the_boat_stops_at_the_end() -> None:
    pts = [(0.0, 0.0), (30.0, 0.0), (30.0, 40.0)]
    traj = Trajectory.waypoints(pts, 2.0)
    s = traj.state(np.array([0.0, 15.0, 35.0, 50.0]))
    np.testing.assert_allclose(s.position, [[0, 0], [30, 0], [30, 40], [30, 40]], atol=1e-9)
    mid = traj.state(25.0)  # on the second leg, heading east
    np.testing.assert_allclose(mid.position[0], [30.0, 20.0], atol=1e-9)
    assert mid.heading[0] == pytest.approx(math.pi / 2)
    np.testing.assert_allclose(traj.state(40.0).velocity[0], [0.0, 0.0])


def test_rounded_looping_waypoints_are_continuous_and_periodic() -> None:
    square = [(0.0, 0.0), (20.0, 0.0), (20.0, 20.0), (0.0, 20.0)]
    traj = Trajectory.waypoints(square, 1.5, turn_radius=3.0, loop=True)
    # perimeter 80 m minus 4 corners cut (2 * 3 m each) plus 4 quarter arcs (3 pi / 2 each)
    assert traj.period == pytest.approx((80.0 - 24.0 + 6.0 * math.pi) / 1.5)
    t = np.linspace(0.0, 2 * traj.period, 4001)
    s = traj.state(t)
    step = np.hypot(*np.diff(s.position, axis=0).T)
    assert step.max() <= 1.5 * (t[1] - t[0]) + 1e-9  # no jumps
    dh = np.abs(np.angle(np.exp(1j * np.diff(s.heading))))
    assert dh.max() <= 0.5 * (t[1] - t[0]) + 1e-9  # heading continuous, at most v/R = 0.5 rad/s
    assert set(np.round(np.unique(s.yaw_rate), 9)) == {0.0, 0.5}
    later = traj.state(t + traj.period)
    np.testing.assert_allclose(later.position, s.position, atol=1e-6)


def test_quay_blocks_lie_on_the_land_side() -> None:
    q = Quay(np.array([[0.0, 10.0], [50.0, 10.0]]), depth=4.0, land_side="starboard")
    blk = q.blocks()[0]
    assert blk[:, 1].min() == pytest.approx(10.0) and blk[:, 1].max() == pytest.approx(14.0)
    np.testing.assert_allclose(q.land_normals()[0], [0.0, 1.0])


def test_harbour_vessels_are_where_their_trajectories_say() -> None:
    scene = get_scenario("harbour")
    names = [v.name for v in scene.vessels]
    assert names == ["moored", "anchored", "crossing", "overtaking", "crew_boat", "rib"]
    truth = truth_at(scene, 10.0)
    crossing = truth.by_id(2)
    np.testing.assert_allclose(crossing.position, [62.0, -20.0], atol=1e-9)
    np.testing.assert_allclose(crossing.velocity, [0.0, -3.0], atol=1e-12)
    assert crossing.heading == pytest.approx(-math.pi / 2)
    np.testing.assert_allclose(truth.by_id(3).position, [10.0, -7.0], atol=1e-9)  # -25 + 3.5 * 10
    rib = truth.by_id(5)
    assert np.hypot(*(rib.position - [30.0, -25.0])) == pytest.approx(8.0, abs=1e-9)
    assert rib.yaw_rate == pytest.approx(3.0 / 8.0)
    np.testing.assert_allclose(truth.own.position, [20.0, 0.0, 0.0], atol=1e-12)
    moored = truth.by_id(0)
    assert 16.0 - moored.footprint[:, 1].max() == pytest.approx(3.0)  # 3 m off the quay wall
    crew = truth.by_id(4)
    assert (crew.length, crew.width) == (43.0, 10.4)


def test_every_scenario_builds_and_unknown_names_are_refused() -> None:
    for name in SCENARIOS:
        scene = get_scenario(name)
        assert scene.n_vessels >= 1 and scene.duration > 0
    assert get_scenario("radar_paper:high").name == "radar_paper:high"
    with pytest.raises(ValueError, match="unknown scenario"):
        get_scenario("lake")
    with pytest.raises(ValueError, match="speed"):
        get_scenario("radar_paper:warp")
    with pytest.raises(ValueError, match="no parameter"):
        get_scenario("harbour:fast")


def test_no_named_scene_runs_one_solid_through_another_or_the_own_boat() -> None:
    """Every hull of every named scene stays 1 m or more from every other (the separating-axis gap, a lower bound of
    the distance; 10 Hz samples of boats under 10 m/s move under 0.5 m between them) and 4 m or more from the own
    boat's centre (its box is the daemon's default 1.6 x 1.0 m) over the whole scene: a moorings lane once ran a RIB
    through a moored tender. Random scenes check themselves as they are drawn (simulator/random_scene.py)."""
    for name in SCENARIOS:
        if name == "random":
            continue
        scene = get_scenario(name)
        t = np.arange(0.0, scene.duration, 0.1)
        fp = scene.footprints(t)  # (T, V, 5, 2) world north, east
        own = scene.own.poses(t).position_ned[:, :2]
        for i in range(scene.n_vessels):
            to_own = np.hypot(fp[:, i, :, 0] - own[:, None, 0], fp[:, i, :, 1] - own[:, None, 1])
            assert to_own.min() >= 4.0, f"{name}: {scene.vessels[i].name} comes within {to_own.min():.2f} m"
            for j in range(i + 1, scene.n_vessels):
                gap = float(separation(fp[:, i], fp[:, j]).min())
                assert gap >= 1.0, f"{name}: {scene.vessels[i].name} and {scene.vessels[j].name} {gap:.2f} m apart"


def test_radar_paper_boats_stay_in_the_radar_field_of_view() -> None:
    scene = get_scenario("radar_paper", speed="high")
    sizes = [(v.name, v.length, v.width, v.height) for v in scene.vessels]
    assert sizes == [("smurf", 2.9, 1.8, 0.6), ("titan", 3.5, 2.6, 1.0), ("xi", 4.9, 2.95, 3.2)]
    t = np.arange(0.0, scene.duration, 0.5)
    s = scene.vessel_states(t)
    radar = np.array([scene.radar_mount.x, scene.radar_mount.y])
    rel = s.position - radar
    bearing = np.degrees(np.arctan2(rel[..., 1], rel[..., 0]))
    assert np.abs(bearing).max() < 55.0
    assert np.hypot(rel[..., 0], rel[..., 1]).max() < 48.0
    assert np.hypot(*s.velocity.reshape(-1, 2).T) == pytest.approx(3.0)


def test_dense_has_twenty_vessels_that_never_overlap() -> None:
    scene = get_scenario("dense", seed=3)
    assert scene.n_vessels == 20
    assert get_scenario("dense", seed=3).vessels[7].length == scene.vessels[7].length  # seed -> same scene
    for t in (0.0, 15.0, 30.0):
        s = scene.vessel_states(t)
        p = s.position[0]
        half = np.array([v.length / 2 for v in scene.vessels])
        for lane in range(10):
            a, b = 2 * lane, 2 * lane + 1
            assert abs(p[a, 1] - p[b, 1]) > half[a] + half[b]
        if t == 15.0:
            assert np.abs(p[:, 1]).max() <= 45.0


def test_truth_csv_round_trip() -> None:
    scene = get_scenario("crossing")
    buf = io.StringIO()
    rows = write_truth_csv(scene, buf, 0.0, 1.0, period=0.1)
    assert rows == 20  # 10 ticks x 2 vessels
    buf.seek(0)
    table = read_truth_csv(buf)
    assert len(table) == 20
    np.testing.assert_allclose(table["t"][::2], np.arange(10) * 0.1, atol=1e-9)
    assert list(table["name"][:2]) == ["west_to_east", "east_to_west"]
    # vessel 0 at t = 0.9: (30, -30) + 0.9 * (0, 2.5)
    np.testing.assert_allclose([table["north"][18], table["east"][18]], [30.0, -27.75], atol=1e-6)
    assert table.footprints[18].shape == (5, 2)  # pointed hull
    assert table.footprints[19].shape == (4, 2)  # box
    bad = io.StringIO(buf.getvalue().splitlines()[0] + "\n1,2,3\n")
    with pytest.raises(ValueError, match="line 2"):
        read_truth_csv(bad)


def test_bad_scene_input_is_refused_with_a_clear_error() -> None:
    still = Trajectory.stationary((0.0, 0.0))
    with pytest.raises(ValueError, match="finite and > 0"):
        Vessel("nan", float("nan"), 2.0, 1.0, still)
    with pytest.raises(ValueError, match="hull"):
        Vessel("raft", 3.0, 2.0, 1.0, still, hull="oval")
    with pytest.raises(ValueError, match="freeboard"):
        Vessel("tall", 3.0, 2.0, 1.0, still, freeboard=2.0)
    with pytest.raises(ValueError, match="must be finite"):
        Trajectory.constant_velocity((0.0, float("nan")), (1.0, 0.0))
    with pytest.raises(ValueError, match="closed path"):
        Trajectory((0.0, 0.0), 0.0, [Leg(10.0, 1.0)], loop=True)
    with pytest.raises(ValueError, match="turn_radius too large"):
        Trajectory.waypoints([(0.0, 0.0), (4.0, 0.0), (4.0, 4.0)], 1.0, turn_radius=10.0)
    with pytest.raises(ValueError, match="consecutive points"):
        Quay(np.array([[0.0, 0.0], [0.0, 0.0]]))
    scene = get_scenario("crossing")
    assert scene.vessel_index("east_to_west") == 1
    with pytest.raises(KeyError):
        scene.vessel_index("nobody")
