"""The simulated AWR1843 on a boat that rolls, pitches and heaves: where its points land, their Doppler, the bytes.

The expected values come from the frames' definitions written out here (world NED -> body FRD with
R = Rz(yaw) Ry(pitch) Rx(roll) about the heaved body origin, body FRD -> sensor FRD through the mount, sensor FRD ->
TI axes), not from the model's code.
"""

from __future__ import annotations

import math

import numpy as np

from drivers.awr1843.parser import RadarFrameParser, encode_frame
from drivers.mount import TI_TO_FRD, Mount
from simulator.radar_model import Awr1843Model, RadarDetections
from simulator.scene import OwnBoat, Quay, Scene, SensorConditions, Trajectory, Vessel
from tests.radar_sim_settings import EXACT
from tracker.ego import rotation_matrices

MOUNT = Mount(x=1.2, y=0.2, z=-0.9, yaw=math.radians(10.0))
HEADING = 0.3
ROLL = math.radians(5.0)


def _rolling(heave: float = 0.3) -> OwnBoat:
    """Still, heading 0.3 rad, rolling 5 deg every 5 s (starboard down at t = 0, 5, 10 ...), pitching and heaving."""
    return OwnBoat(
        Trajectory.stationary((0.0, 0.0), HEADING),
        roll_amplitude=ROLL,
        roll_period=5.0,
        pitch_amplitude=math.radians(2.0),
        pitch_period=3.7,
        wave_phase=math.pi / 2,
        heave_amplitude=heave,
        heave_period=4.0,
    )


def _buoy_scene(own: OwnBoat) -> Scene:
    """A 0.4 m post 20 m from the radar, 45 deg to starboard of the bow: a near point scatterer."""
    bearing = HEADING + math.pi / 4
    centre = (1.2 * math.cos(HEADING) + 20.0 * math.cos(bearing), 1.2 * math.sin(HEADING) + 20.0 * math.sin(bearing))
    post = Vessel("post", 0.4, 0.4, 1.6, Trajectory.stationary(centre, 0.0))
    return Scene("post", own, [post], [], radar_mount=MOUNT)


def _world_to_body(own: OwnBoat, t: float, xyz_world: np.ndarray, level: bool = False) -> np.ndarray:
    """World NED -> body FRD at time t (``level``: as if the boat neither rolled, pitched nor heaved)."""
    p = own.poses(t)
    if level:
        r_wb = rotation_matrices(np.zeros(1), np.zeros(1), p.yaw)[0]
        origin = np.array([p.position[0, 0], p.position[0, 1], 0.0])
    else:
        r_wb = rotation_matrices(p.roll, p.pitch, p.yaw)[0]
        origin = p.position_ned[0]
    return (xyz_world - origin) @ r_wb  # r_wb maps body -> world; its transpose world -> body


def _world_to_ti(own: OwnBoat, t: float, xyz_world: np.ndarray, level: bool = False) -> np.ndarray:
    body = _world_to_body(own, t, xyz_world, level)
    sensor_frd = (body - MOUNT.translation) @ MOUNT.rotation  # body FRD -> sensor FRD
    return sensor_frd @ TI_TO_FRD  # sensor FRD -> TI (x right, y boresight, z up); the map is its own inverse


def _spherical(ti: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r = np.linalg.norm(ti, axis=1)
    return r, np.arctan2(ti[:, 0], ti[:, 1]), np.arcsin(ti[:, 2] / r)


def _sensor_velocity(own: OwnBoat, t: float, step: float = 1e-5) -> np.ndarray:
    """World NED velocity of the radar's origin: a fine central difference of its position (not the model's)."""
    p = own.poses(np.array([t - step, t + step]))
    r_wb = rotation_matrices(p.roll, p.pitch, p.yaw)
    pos = p.position_ned + r_wb @ MOUNT.translation
    return (pos[1] - pos[0]) / (2 * step)


def test_points_follow_the_boats_roll_pitch_and_heave_through_a_whole_roll_cycle() -> None:
    own = _rolling()
    model = Awr1843Model(_buoy_scene(own), **EXACT)
    tilt_shift = []
    for f in model.frames(0.0, 5.0):
        assert np.all(f.label == 0) and f.n_points >= 1
        np.testing.assert_allclose(f.xyz_ti, _world_to_ti(own, f.t, f.xyz_world), atol=1e-9)
        tilt_shift.append(np.mean(f.xyz_ti[:, 2] - _world_to_ti(own, f.t, f.xyz_world, level=True)[:, 2]))
    # Starboard down by 5 deg lifts a return 45 deg to starboard at 20 m by 20 sin(45) sin(5) = 1.23 m in the sensor's
    # frame; at t = 0 the bow is also 1.4 deg up (-0.35 m) and the boat 0.19 m heaved up (-0.19 m): 0.69 m in all.
    # A model that ignored the attitude would be that far off.
    assert 0.6 < tilt_shift[0] < 0.75
    # at t = 2.5 s it leans 5 deg to port (-1.23 m), the bow is 1.9 deg down (+0.47 m), the boat 0.30 m down (+0.30 m)
    assert -0.5 < tilt_shift[25] < -0.4


def test_at_5_deg_roll_a_point_return_lands_where_the_sensor_geometry_says_within_the_stated_noise() -> None:
    own = _rolling()
    noisy = {"range_noise_m": 0.05, "azimuth_noise_deg": 1.0, "elevation_noise_deg": 2.0}
    model = Awr1843Model(_buoy_scene(own), **{**EXACT, **noisy})
    res_r, res_az, res_el, res_el_level = [], [], [], []
    for k in range(200):  # t = 0, 5, 10 ... s: the roll is exactly 5 deg to starboard each time
        t = 5.0 * k
        assert math.isclose(float(own.poses(t).roll[0]), ROLL, abs_tol=1e-12)
        f = model.frame(t, round(t / model.frame_period))
        r_m, az_m, el_m = _spherical(f.xyz_ti)
        r_t, az_t, el_t = _spherical(_world_to_ti(own, t, f.xyz_world))
        res_r.append(r_m - r_t)
        res_az.append(az_m - az_t)
        res_el.append(el_m - el_t)
        res_el_level.append(el_m - _spherical(_world_to_ti(own, t, f.xyz_world, level=True))[2])
    r, az, el, el_level = (np.concatenate(x) for x in (res_r, res_az, res_el, res_el_level))
    n = r.size
    assert n >= 180
    # each residual is the model's stated noise: zero mean (3 standard errors), standard deviation within 15 %
    for res, sigma in ((r, 0.05), (az, math.radians(1.0)), (el, math.radians(2.0))):
        assert abs(res.mean()) < 3 * sigma / math.sqrt(n)
        assert 0.85 * sigma < res.std() < 1.15 * sigma
    # ... while a level sensor would put them 3.5 deg (1.2 m at 20 m) too low: the test sees a missed attitude
    assert el_level.mean() > math.radians(3.0)


def test_doppler_includes_the_heave_and_the_mast_swinging_with_the_roll() -> None:
    """A fixed quay seen from a boat at rest that heaves 0.3 m and rolls 5 deg: every Doppler is the radar's own
    motion along the line of sight, rates included."""
    own = _rolling()
    quay = Quay(np.array([[14.0, -40.0], [14.0, 40.0]]), height=1.5, land_side="port")
    scene = Scene("quay", own, [], [quay], radar_mount=MOUNT)
    model = Awr1843Model(scene, **{**EXACT, "shore_keep": 1.0})
    largest_rate_term = 0.0
    for f in model.frames(0.0, 4.0):
        assert f.n_points > 20
        v = _sensor_velocity(own, f.t)
        p = own.poses(f.t)
        los = f.xyz_world - (p.position_ned[0] + rotation_matrices(p.roll, p.pitch, p.yaw)[0] @ MOUNT.translation)
        los /= np.linalg.norm(los, axis=1, keepdims=True)
        np.testing.assert_allclose(f.doppler_true, -(los @ v), atol=1e-6)
        largest_rate_term = max(largest_rate_term, float(np.abs(los @ v).max()))
    # the boat itself is at rest: all of that is heave and roll (0.47 m/s of heave at its fastest)
    assert largest_rate_term > 0.1


def test_the_device_bytes_decode_to_the_body_frame_points_of_the_full_pose() -> None:
    """Model -> firmware frame -> the project's parser: the tracker receives body-frame points, which lie where the
    boat's full attitude and heave put them (a tracker rotating them by yaw alone misplaces them in height)."""
    own = _rolling()
    model = Awr1843Model(_buoy_scene(own), **EXACT)
    parser = RadarFrameParser(mount=MOUNT)
    frames: list[RadarDetections] = list(model.frames(0.0, 1.0))
    data = b"".join(encode_frame(f.frame_index + 1, f.xyz_ti, f.doppler, f.snr_db, f.noise_db) for f in frames)
    decoded = parser.feed(data, host_time=0.0) + parser.finish()
    assert len(decoded) == len(frames)
    for f, d in zip(frames, decoded, strict=True):
        np.testing.assert_allclose(d.xyz, _world_to_body(own, f.t, f.xyz_world), atol=1e-4)  # float32 on the wire
        np.testing.assert_allclose(d.doppler, f.doppler, atol=1e-5)
    first = _world_to_body(own, 0.0, frames[0].xyz_world)
    level = _world_to_body(own, 0.0, frames[0].xyz_world, level=True)
    assert np.all(level[:, 2] - first[:, 2] > 0.6)  # body z (down) of the rolled boat: the post appears higher


def test_the_model_takes_its_defaults_from_the_scene_conditions() -> None:
    own = OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0))
    boat = Vessel("b", 6.0, 2.5, 1.5, Trajectory.stationary((20.0, 0.0), 0.0))
    exact = {k: v for k, v in EXACT.items() if k != "ghost_probability"}
    dry = Awr1843Model(Scene("dry", own, [boat]), snr_threshold_db=-100.0, **exact)
    wet_scene = Scene(
        "wet", own, [boat], conditions=SensorConditions(radar_snr_loss_db=6.0, radar_ghost_probability=0.0)
    )
    wet = Awr1843Model(wet_scene, snr_threshold_db=-100.0, **exact)
    assert dry.ghost_probability == SensorConditions().radar_ghost_probability == 0.1
    assert wet.ghost_probability == 0.0 and wet.snr_loss_db == 6.0
    for a, b in zip(dry.frames(0.0, 1.0), wet.frames(0.0, 1.0), strict=True):
        hull_a, hull_b = a.label == 0, b.label == 0
        np.testing.assert_allclose(b.snr_db[hull_b], a.snr_db[hull_a] - 6.0, atol=1e-9)
    # a value given to the constructor wins over the scene's
    assert Awr1843Model(wet_scene, ghost_probability=0.5).ghost_probability == 0.5


def test_an_azimuth_only_profile_reports_range_and_direction_cosine_with_z_zero() -> None:
    """The shipped profile (channelCfg 15 5 0) has no elevation antennas: its array measures x / r, which includes
    cos(elevation), and the firmware reports x = r (x / r), y = sqrt(r^2 - x^2), z = 0. At 5 deg roll the post 45 deg
    to starboard stands 1.2 m above the sensor's plane, and that is what a 2-D point loses."""
    own = _rolling()
    model = Awr1843Model(_buoy_scene(own), **{**EXACT, "report_elevation": False})
    for f in model.frames(0.0, 1.0):
        true_ti = _world_to_ti(own, f.t, f.xyz_world)
        np.testing.assert_allclose(f.xyz_ti[:, 2], 0.0)
        np.testing.assert_allclose(np.linalg.norm(f.xyz_ti, axis=1), np.linalg.norm(true_ti, axis=1), atol=1e-9)
        np.testing.assert_allclose(f.xyz_ti[:, 0], true_ti[:, 0], atol=1e-9)
        if f.frame_index == 0:
            assert np.all(true_ti[:, 2] > 0.5)  # (0.69 m at t = 0: see the roll-cycle test)
