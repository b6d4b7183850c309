"""The VLP-16 ray caster against scenes whose answer is known in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.mount import FLU_TO_FRD, Mount
from simulator.lidar_model import ELEVATION_DEG, PACKET_PERIOD_S, VERTICAL_OFFSET_M, PacketContent, Vlp16Model
from simulator.scene import LABEL_CLUTTER, OwnBoat, Scene, Trajectory, Vessel
from tracker.ego import body_to_world

SENSOR_HEIGHT = 1.5


def _box_ahead_scene(own: OwnBoat | None = None) -> Scene:
    """A 6 m wide, 3 m high box whose near face is the plane north = 20 m, seen from a still boat at the origin."""
    own = own or OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0))
    box = Vessel("box", 4.0, 6.0, 3.0, Trajectory.stationary((22.0, 0.0), 0.0))
    return Scene("box", own, [box])


def _ideal_model(scene: Scene, mount: Mount | None = None, **kw: float) -> Vlp16Model:
    return Vlp16Model(scene, mount or Mount(z=-SENSOR_HEIGHT), range_noise_m=0.0, spray_rate=0.0, **kw)


def _decode(p: PacketContent) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Azimuth per return as vlp16.md §5 interpolates it (independent of the model), laser id, distance."""
    az = p.block_azimuth_cdeg.astype(float)
    gap = np.mod(np.diff(az), 36000.0)
    gap = np.append(gap, gap[-1])
    ch = np.arange(32)
    laser = ch % 16
    frac = (55.296 * (ch >= 16) + 2.304 * laser) / (2 * 55.296)
    az_ch = np.mod(az[:, None] + gap[:, None] * frac[None, :], 36000.0)
    return np.radians(az_ch / 100.0), np.broadcast_to(laser, (12, 32)), p.distance_m


def test_box_ahead_hits_are_on_its_face_at_the_right_range_and_bearing() -> None:
    model = _ideal_model(_box_ahead_scene())
    hits = model.revolution_points(0.0)
    on_box = hits.label == 0
    assert on_box.sum() > 100
    # every return on the face lies on the plane north = 20 (FLU x = 20 for an unrotated sensor at the origin)
    np.testing.assert_allclose(hits.xyz_world[on_box, 0], 20.0, atol=1e-9)
    np.testing.assert_allclose(hits.xyz_sensor[on_box, 0], 20.0, atol=1e-9)
    elev = np.radians(ELEVATION_DEG[hits.laser[on_box]])
    expected = 20.0 / (np.cos(elev) * np.cos(hits.azimuth[on_box]))
    np.testing.assert_allclose(hits.distance[on_box], expected, atol=1e-9)
    # heights: the face spans 0..3 m above the water; at 20 m only the -3, -1, +1, +3 deg lasers land on it
    assert set(ELEVATION_DEG[np.unique(hits.laser[on_box])]) == {-3.0, -1.0, 1.0, 3.0}
    height = -hits.xyz_world[on_box, 2]
    assert height.min() > 0 and height.max() < 3.0
    # bearing: the face's edges are at atan(3 / 20) either side of the bow
    edge = math.degrees(math.atan2(3.0, 20.0))
    bearing = np.degrees(np.angle(np.exp(1j * hits.azimuth[on_box])))
    assert bearing.max() == pytest.approx(edge, abs=0.25) and bearing.min() == pytest.approx(-edge, abs=0.25)
    # azimuth convention: clockwise seen from above, so starboard (east) hits have negative FLU y
    east = hits.xyz_world[on_box, 1] > 0.5
    assert np.all(hits.xyz_sensor[on_box][east, 1] < 0)


def test_packet_distances_decode_onto_the_face_to_the_millimetre() -> None:
    model = _ideal_model(_box_ahead_scene())
    packets = list(model.packets(0.0, 0.1))
    assert len(packets) == 76  # packets 0..75 start within the first 100 ms
    face_x = []
    for p in packets:
        az, laser, dist = _decode(p)
        sel = p.label == 0
        elev = np.radians(ELEVATION_DEG[laser[sel]])
        face_x.append(dist[sel] * np.cos(elev) * np.cos(az[sel]))
    x = np.concatenate(face_x)
    assert x.size > 100
    assert np.abs(x - 20.0).max() < 1e-3


def test_packet_clock_azimuth_and_timestamps() -> None:
    model = _ideal_model(_box_ahead_scene(), device_clock_offset_s=3599.9)
    packets = list(model.packets(0.0, 0.2))
    times = np.array([p.t for p in packets])
    np.testing.assert_allclose(np.diff(times), PACKET_PERIOD_S, atol=1e-12)
    az = np.concatenate([p.block_azimuth_cdeg for p in packets]).astype(int)
    steps = np.mod(np.diff(az), 36000)
    assert set(steps) <= {39, 40}  # 0.398 deg per two firing sequences at 600 rpm
    stamps = np.array([p.timestamp_us for p in packets])
    assert stamps[0] == 3_599_900_000
    assert stamps.max() < 3_600_000_000 and stamps.min() >= 0  # wrapped at the hour
    assert all(p.distance_m.shape == (12, 32) and p.reflectivity.dtype == np.uint8 for p in packets)


def test_yawed_offset_mount_on_a_yawed_boat() -> None:
    own_yaw = math.radians(30.0)
    own = OwnBoat(Trajectory.stationary((5.0, -3.0), own_yaw))
    mount = Mount(x=2.0, y=0.5, z=-1.2, yaw=math.pi / 2)  # looking to starboard
    look = own_yaw + math.pi / 2  # sensor forward axis in the world: bearing 120 deg
    c, s = math.cos(own_yaw), math.sin(own_yaw)
    sensor = np.array([5.0 + c * 2.0 - s * 0.5, -3.0 + s * 2.0 + c * 0.5])
    u = np.array([math.cos(look), math.sin(look)])
    # a box broadside to the line of sight, its near face 23.5 m in front of the sensor
    box = Vessel("box", 10.0, 3.0, 2.5, Trajectory.stationary(sensor + 25.0 * u, look + math.pi / 2))
    model = _ideal_model(Scene("mount", own, [box]), mount)
    hits = model.revolution_points(0.0)
    sel = hits.label == 0
    assert sel.sum() > 50
    np.testing.assert_allclose(hits.xyz_sensor[sel, 0], 23.5, atol=1e-9)
    assert np.abs(hits.xyz_sensor[sel, 1]).max() <= 5.0 + 1e-9
    np.testing.assert_allclose((hits.xyz_world[sel, :2] - sensor) @ u, 23.5, atol=1e-9)
    # the same points through the body frame and the tracker's body -> world transform
    body = mount.sensor_frd_to_body(hits.xyz_sensor[sel] @ FLU_TO_FRD.T)
    np.testing.assert_allclose(body, hits.xyz_body[sel], atol=1e-12)
    world = body_to_world(body, np.array([5.0, -3.0, 0.0]), 0.0, 0.0, own_yaw)
    np.testing.assert_allclose(world, hits.xyz_world[sel], atol=1e-9)


def test_rolling_moving_boat_places_each_firing_with_its_own_pose() -> None:
    own = OwnBoat(
        Trajectory.constant_velocity((0.0, 0.0), (3.0, 0.0)),
        roll_amplitude=math.radians(4.0),
        roll_period=1.3,
        pitch_amplitude=math.radians(2.0),
        pitch_period=0.9,
    )
    model = _ideal_model(_box_ahead_scene(own))
    hits = model.revolution_points(0.5)
    sel = hits.label == 0
    assert sel.sum() > 50
    # the face is still the plane north = 20 in the world, whatever the boat did during the sweep
    np.testing.assert_allclose(hits.xyz_world[sel, 0], 20.0, atol=1e-9)
    p = own.poses(hits.t[sel])
    world = body_to_world(hits.xyz_body[sel], p.position_ned, p.roll, p.pitch, p.yaw)
    np.testing.assert_allclose(world, hits.xyz_world[sel], atol=1e-9)
    # and in the sensor frame the face is no longer a plane x = const (the boat moved 0.3 m and rolled)
    assert np.ptp(hits.xyz_sensor[sel, 0]) > 0.1


def test_a_vessel_hides_the_one_behind_it() -> None:
    own = OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0))
    near = Vessel("near", 4.0, 4.0, 3.0, Trajectory.stationary((15.0, 0.0), 0.0))  # front face 13 m, +-2 m
    far = Vessel("far", 4.0, 12.0, 2.0, Trajectory.stationary((27.0, 0.0), 0.0))
    shadow = math.atan2(2.0, 13.0)  # the near box's silhouette half-angle (its front corners)
    hits = _ideal_model(Scene("occ", own, [near, far])).revolution_points(0.0)
    az = np.angle(np.exp(1j * hits.azimuth))
    assert np.any(hits.label == 0)
    assert np.any(hits.label == 1)
    assert np.abs(az[hits.label == 1]).min() >= shadow - 1e-9
    # without the near boat the far one is seen straight ahead: the gap above was occlusion, not a miss
    alone = _ideal_model(Scene("alone", own, [far])).revolution_points(0.0)
    az_alone = np.angle(np.exp(1j * alone.azimuth))
    assert np.sum(np.abs(az_alone[alone.label == 0]) < shadow) > 20


def test_top_of_a_low_boat_is_seen_from_above() -> None:
    own = OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0))
    # sensor 2 m up: the -15 and -13 deg beams reach the near face (6.55 m); the -11 and -9 deg beams clear it and
    # land on the deck 0.6 m up at 7.2 and 8.8 m; the -7 deg beam would need 11.4 m and passes over the stern (9.45)
    low = Vessel("smurf", 2.9, 1.8, 0.6, Trajectory.stationary((8.0, 0.0), 0.0))
    hits = _ideal_model(Scene("deck", own, [low]), Mount(z=-2.0)).revolution_points(0.0)
    sel = hits.label == 0
    deck = np.isclose(hits.xyz_world[sel, 2], -0.6, atol=1e-9)
    face = np.isclose(hits.xyz_world[sel, 0], 8.0 - 1.45, atol=1e-9)
    assert deck.sum() > 5 and face.sum() > 5
    assert np.all(deck | face)  # every return is on the deck or on the near face, none inside the hull
    assert set(ELEVATION_DEG[np.unique(hits.laser[sel][face])]) == {-15.0, -13.0}
    assert set(ELEVATION_DEG[np.unique(hits.laser[sel][deck])]) == {-11.0, -9.0}


def test_range_limits() -> None:
    own = OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0))
    for north, expect in ((95.0, True), (106.0, False)):
        tall = Vessel("tall", 4.0, 30.0, 8.0, Trajectory.stationary((north + 2.0, 0.0), 0.0))
        packets = list(_ideal_model(Scene("far", own, [tall])).packets(0.0, 0.1))
        d = np.concatenate([p.distance_m[p.label == 0] for p in packets])
        assert (d.size > 0) == expect
        ideal = _ideal_model(Scene("far", own, [tall])).revolution_points(0.0)
        assert (ideal.n_points > 0) == expect
        if expect:
            assert d.max() <= 100.0 and ideal.distance.max() <= 100.0


def test_noise_spray_and_reproducibility() -> None:
    scene = _box_ahead_scene()
    model = Vlp16Model(scene, Mount(z=-SENSOR_HEIGHT), range_noise_m=0.02, spray_rate=2000.0, seed=7)
    ideal = _ideal_model(scene)
    whole = list(model.packets(0.0, 0.2))
    fresh = Vlp16Model(scene, Mount(z=-SENSOR_HEIGHT), range_noise_m=0.02, spray_rate=2000.0, seed=7)
    split = list(fresh.packets(0.0, 0.07)) + list(fresh.packets(0.07, 0.13)) + list(fresh.packets(0.13, 0.2))
    assert len(whole) == len(split)
    for a, b in zip(whole, split, strict=True):
        np.testing.assert_array_equal(a.distance_m, b.distance_m)
        np.testing.assert_array_equal(a.reflectivity, b.reflectivity)
    err = []
    spray = []
    for noisy, clean in zip(whole, ideal.packets(0.0, 0.2), strict=True):
        sel = (noisy.label == 0) & (clean.label == 0)
        err.append(noisy.distance_m[sel] - clean.distance_m[sel])
        laser = np.broadcast_to(np.arange(32) % 16, (12, 32))
        spray.append((noisy.distance_m[noisy.label == LABEL_CLUTTER], laser[noisy.label == LABEL_CLUTTER]))
    e = np.concatenate(err)
    assert e.size > 200
    assert np.std(e) == pytest.approx(0.02, rel=0.15)
    assert abs(np.mean(e)) < 0.005
    d = np.concatenate([s[0] for s in spray])
    lasers = np.concatenate([s[1] for s in spray])
    assert d.size > 100  # ~2000 per second asked for
    assert d.min() >= 0.8 and d.max() <= 5.0
    assert np.all(ELEVATION_DEG[lasers] < 0)
    other = list(Vlp16Model(scene, Mount(z=-SENSOR_HEIGHT), seed=8).packets(0.0, 0.01))
    assert not np.array_equal(other[0].distance_m, whole[0].distance_m)


def test_vertical_offset_is_the_beam_origin() -> None:
    hits = _ideal_model(_box_ahead_scene()).revolution_points(0.0)
    sel = hits.label == 0
    laser = hits.laser[sel]
    z_expected = hits.distance[sel] * np.sin(np.radians(ELEVATION_DEG[laser])) + VERTICAL_OFFSET_M[laser]
    np.testing.assert_allclose(hits.xyz_sensor[sel, 2], z_expected, atol=1e-12)
    np.testing.assert_allclose(hits.xyz_world[sel, 2], -(SENSOR_HEIGHT + z_expected), atol=1e-9)


def test_nan_times_are_refused() -> None:
    model = _ideal_model(_box_ahead_scene())
    with pytest.raises(ValueError, match="finite"):
        list(model.packets(0.0, float("nan")))
    with pytest.raises(ValueError, match="finite"):
        model.revolution_points(float("inf"))


def test_packets_survive_the_real_encoder_and_velodyne_decoder() -> None:
    """Simulated packets -> 1206-byte payloads -> velodyne-decoder: the points land where the caster put them."""
    vd = pytest.importorskip("velodyne_decoder")
    from drivers.vlp16.packet import encode_data_packet

    model = _ideal_model(_box_ahead_scene())
    packets = list(model.packets(0.0, 0.1))
    vector = vd.PacketVector()
    for p in packets:
        payload = encode_data_packet(p.block_azimuth_cdeg, p.distance_m, p.reflectivity, p.timestamp_us)
        vector.append(vd.VelodynePacket(p.t, payload))
    decoder = vd.ScanDecoder(vd.Config(model=vd.Model.VLP16, min_range=0.1, max_range=200.0))
    _stamp, points = decoder.decode(vector)
    xyz = points[:, [vd.PointField.x, vd.PointField.y, vd.PointField.z]].astype(np.float64)
    assert xyz.shape[0] == sum(int(np.sum(p.label == 0)) for p in packets)
    assert np.abs(xyz[:, 0] - 20.0).max() < 2e-3  # 2 mm distance unit, float32 points
    ideal = model.hits_between(0.0, packets[-1].t + PACKET_PERIOD_S).xyz_sensor
    nearest = np.min(np.linalg.norm(xyz[:, None, :] - ideal[None, :, :], axis=2), axis=1)
    assert nearest.max() < 5e-3  # and y, z (vertical beam offsets included) agree too


def _off_curve(hull: str, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Signed distance (m, + outside) of body points from the outline of a 2 m buoy or a 6 x 2.4 m round hull."""
    if hull == "buoy":
        return np.hypot(x, y) - 1.0
    r, straight = 1.2, 3.0 - 1.2  # half-rounds of the beam's radius at either end of a straight midbody
    return np.where(np.abs(x) > straight, np.hypot(np.abs(x) - straight, y) - r, np.abs(y) - r)


@pytest.mark.parametrize(("hull", "length", "width"), [("buoy", 2.0, 2.0), ("round", 6.0, 2.4)])
def test_a_curved_hull_returns_points_on_its_curve(hull: str, length: float, width: float) -> None:
    """A buoy (a cylinder) and a round-ended tender 20 m ahead: every return lies on the true curved outline, not
    beyond it, and within the 16-gon's sagitta inside it; the outline's pentagon (the truth's footprint and the radar's
    corners) has its vertices on the curve; the prisms' areas add up to the curved hull's."""
    v = Vessel("v", length, width, 1.0, Trajectory.stationary((20.0, 0.0), 0.0), hull=hull)
    scene = Scene("curved", OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0)), [v])
    hits = _ideal_model(scene).revolution_points(0.0)
    on = hits.label == 0
    assert on.sum() >= 25  # at 20 m only the -3 deg laser meets a 1 m freeboard: 5.7 deg of it for the buoy
    off = _off_curve(hull, hits.xyz_world[on, 0] - 20.0, hits.xyz_world[on, 1])
    # a polygon of 16 vertices per circle lies within r (1 - cos 11.25 deg), 2 % of the radius, inside it
    assert off.max() <= 1e-9 and off.min() >= -0.02 * min(length, width) / 2
    pentagon = v.outline_body()
    np.testing.assert_allclose(_off_curve(hull, pentagon[:, 0], pentagon[:, 1]), 0.0, atol=1e-12)
    areas = [0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]) for p in v.hull_parts_body()]
    assert min(areas) > 0  # every part counter-clockwise, none inside out
    exact = math.pi * length * width / 4 if hull == "buoy" else (length - width) * width + math.pi * width**2 / 4
    assert sum(areas) == pytest.approx(exact, rel=0.03)  # a 16-gon holds 97.4 % of its circle's area
