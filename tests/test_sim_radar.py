"""The AWR1843 point-cloud model: Doppler signs, TI axes, shore returns, ghosts, limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.mount import TI_TO_FRD, Mount
from simulator.radar_model import Awr1843Model, RadarDetections
from simulator.scene import LABEL_GHOST, LABEL_SHORE, OwnBoat, Quay, Scene, Trajectory, Vessel
from tests.radar_sim_settings import EXACT
from tracker.ego import rotation_matrices

MOUNT = Mount(x=1.0, z=-1.0)


def _still() -> OwnBoat:
    return OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0))


def _frames(model: Awr1843Model, n: int = 10) -> list[RadarDetections]:
    return list(model.frames(0.0, n * model.frame_period))


def _sensor(own: OwnBoat, mount: Mount, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Radar position (world), sensor-FRD -> world rotation and velocity, computed independently of the model."""
    p = own.poses(t)
    r_wb = rotation_matrices(p.roll, p.pitch, p.yaw)[0]
    lever = r_wb @ mount.translation
    w = p.yaw_rate[0]
    v = np.array([p.velocity[0, 0] - w * lever[1], p.velocity[0, 1] + w * lever[0], 0.0])
    return p.position_ned[0] + lever, r_wb @ mount.rotation, v


def test_approaching_vessel_has_negative_doppler_and_receding_positive() -> None:
    for v_north, sign in ((-3.0, -1.0), (3.0, 1.0)):
        boat = Vessel("b", 6.0, 3.0, 1.5, Trajectory.constant_velocity((30.0, 0.0), (v_north, 0.0)))
        model = Awr1843Model(Scene("s", _still(), [boat]), MOUNT, **EXACT)
        frames = _frames(model)
        dop = np.concatenate([f.doppler[f.label == 0] for f in frames])
        assert dop.size >= 10
        assert np.all(np.sign(dop) == sign)
        for f in frames:
            sel = f.label == 0
            pos, _, _ = _sensor(model.scene.own, MOUNT, f.t)
            los = f.xyz_world[sel] - pos
            los /= np.linalg.norm(los, axis=1, keepdims=True)
            np.testing.assert_allclose(f.doppler[sel], los @ [v_north, 0.0, 0.0], atol=1e-9)
        assert np.abs(dop).max() <= 3.0 + 1e-9 and np.abs(dop).min() > 2.9  # nearly head-on


def test_ti_axes_x_right_y_boresight_z_up() -> None:
    bearing = math.radians(30.0)
    centre = (1.0 + 25.0 * math.cos(bearing), 25.0 * math.sin(bearing))
    boat = Vessel("b", 3.0, 3.0, 2.0, Trajectory.stationary(centre, 0.0))
    model = Awr1843Model(Scene("s", _still(), [boat]), MOUNT, **EXACT)
    f = _frames(model, 5)
    xyz = np.concatenate([x.xyz_ti[x.label == 0] for x in f])
    assert xyz.shape[0] > 5
    assert np.all(xyz[:, 0] > 0) and np.all(xyz[:, 1] > 0)
    az = np.degrees(np.arctan2(xyz[:, 0], xyz[:, 1]))
    assert np.all(np.abs(az - 30.0) < 5.0)
    # points on the hull between 15 % and 90 % of its 2 m height; the radar sits 1 m up: z in (-0.7, 0.8)
    assert np.all(xyz[:, 2] > -0.7) and np.all(xyz[:, 2] < 0.8)
    # the same point through TI -> sensor FRD -> body equals the world point for a still, level boat at the origin
    body = MOUNT.sensor_frd_to_body(xyz @ TI_TO_FRD.T)
    world = np.concatenate([x.xyz_world[x.label == 0] for x in f])
    np.testing.assert_allclose(body, world, atol=1e-9)


def test_shore_doppler_is_the_own_motion_seen_from_a_fixed_wall() -> None:
    # own boat turning (so the mount's lever arm matters), radar looking to starboard at a quay
    own = OwnBoat(Trajectory.constant_turn((0.0, 0.0), 0.0, 2.0, 0.05))
    mount = Mount(x=2.0, y=0.3, z=-1.0, yaw=math.pi / 2)
    quay = Quay(np.array([[-40.0, 12.0], [60.0, 12.0]]), height=1.5)
    model = Awr1843Model(Scene("q", own, [], [quay]), mount, **{**EXACT, "shore_keep": 1.0})
    frames = _frames(model, 20)
    ahead = behind = 0
    for f in frames:
        sel = f.label == LABEL_SHORE
        assert sel.sum() > 10
        pos, _, vel = _sensor(own, mount, f.t)
        los = f.xyz_world[sel] - pos
        los /= np.linalg.norm(los, axis=1, keepdims=True)
        np.testing.assert_allclose(f.doppler[sel], -(los @ vel), atol=1e-9)
        ahead += int(np.sum(f.xyz_world[sel, 0] > pos[0] + 1.0))
        behind += int(np.sum(f.xyz_world[sel, 0] < pos[0] - 1.0))
        assert np.all(np.sign(f.doppler[sel][f.xyz_world[sel, 0] > pos[0] + 1.0]) == -1)  # wall ahead closes in
    assert ahead > 0 and behind > 0
    # the lever arm: sensor velocity differs from the boat's by omega x r (0.05 rad/s x ~2 m = 0.1 m/s)
    _, _, vel = _sensor(own, mount, 1.0)
    assert np.linalg.norm(vel[:2] - own.poses(1.0).velocity[0]) == pytest.approx(0.05 * math.hypot(2.0, 0.3))


def test_multipath_copies_lie_k_times_as_far_on_the_same_bearing_with_k_times_the_doppler() -> None:
    """Radar -> hull -> own boat -> hull -> radar: the path is twice (three times) the direct one and changes twice
    (three times) as fast, so the copy sits at k x the range on the same bearing with k x the Doppler; it is
    (k - 1) x 9 dB + 20 log10(k) weaker (15.0 dB for k = 2, 27.5 dB for k = 3)."""
    boat = Vessel("b", 8.0, 3.0, 2.0, Trajectory.constant_velocity((15.0, 3.0), (0.0, -1.0)))
    model = Awr1843Model(Scene("g", _still(), [boat]), MOUNT, **{**EXACT, "ghost_probability": 1.0})
    orders = []
    for f in _frames(model, 20):
        ghosts = np.flatnonzero(f.label == LABEL_GHOST)
        src = f.ghost_of[ghosts]
        assert np.all(f.label[src] == 0)
        r_g = np.linalg.norm(f.xyz_ti[ghosts], axis=1)
        r_s = np.linalg.norm(f.xyz_ti[src], axis=1)
        k = np.rint(r_g / r_s)
        np.testing.assert_allclose(r_g / r_s, k, atol=1e-9)
        np.testing.assert_allclose(f.xyz_ti[ghosts] / r_g[:, None], f.xyz_ti[src] / r_s[:, None], atol=1e-12)
        np.testing.assert_allclose(f.doppler_true[ghosts], k * f.doppler_true[src], atol=1e-9)
        np.testing.assert_allclose(f.snr_db[src] - f.snr_db[ghosts], (k - 1) * 9.0 + 20 * np.log10(k), atol=1e-9)
        assert np.all(f.ghost_of[f.label != LABEL_GHOST] == -1)
        assert np.all(f.mirror_of == -1)  # no quay here
        orders.extend(k)
    assert set(orders) == {2.0, 3.0} and len(orders) > 50


def test_field_of_view_range_limit_and_occlusion() -> None:
    wide = Vessel("wide", 3.0, 8.0, 2.0, Trajectory.stationary((12.0, 0.0), 0.0))
    hidden = Vessel("hidden", 3.0, 2.0, 2.0, Trajectory.stationary((25.0, 0.0), 0.0))
    abeam = Vessel("abeam", 3.0, 2.0, 2.0, Trajectory.stationary((1.0 + 10.0 * math.cos(1.3), 10.0 * math.sin(1.3))))
    far = Vessel("far", 3.0, 6.0, 3.0, Trajectory.stationary((56.0, -20.0), 0.0))
    model = Awr1843Model(Scene("l", _still(), [wide, hidden, abeam, far]), MOUNT, **EXACT)
    labels = np.concatenate([f.label for f in _frames(model, 20)])
    assert np.sum(labels == 0) >= 20
    assert not np.any(np.isin(labels, [1, 2, 3]))  # behind the wide boat, 74 deg off boresight, ~59 m out
    # the far boat is only out of range: with a 100 m configuration it shows up
    far_ok = Awr1843Model(Scene("l", _still(), [far]), MOUNT, **{**EXACT, "max_range": 100.0})
    assert sum(int(np.sum(f.label == 0)) for f in _frames(far_ok, 5)) > 0


def test_occlusion_is_three_dimensional_a_low_hull_hides_only_what_lies_below_the_sight_line() -> None:
    """Radar 0.9 m up: a 0.6 m dinghy hides nothing of a 3.2 m boat behind it; a 1.0 m hull hides its low returns."""
    mount = Mount(x=0.0, z=-0.9)
    tall = Vessel("tall", 4.9, 2.95, 3.2, Trajectory.stationary((25.0, 0.0), 0.0), freeboard=1.2)
    for front_height, hidden in ((0.6, False), (1.0, True)):
        front = Vessel("front", 3.0, 8.0, front_height, Trajectory.stationary((12.0, 0.0), 0.0))
        model = Awr1843Model(Scene("o", _still(), [front, tall]), mount, **EXACT)
        frames = _frames(model, 20)
        height = np.concatenate([-f.xyz_world[f.label == 1, 2] for f in frames])  # the tall boat's seen returns
        assert height.size >= 20
        # the front hull spans every bearing to the tall boat: without height, nothing of it would be seen
        if not hidden:
            assert height.min() < 0.6  # seen over the dinghy, below the dinghy's own top
        else:
            # the sight line rises from 0.9 m and must clear the 1.0 m gunwale at the near face (10.5 m): a return
            # on the tall boat's near face (22.55 m) is seen only above 0.9 + 0.1 * 22.55 / 10.5 = 1.115 m
            assert height.min() > 1.11
            assert np.sum(height < 1.3) > 0  # and the cut is at the geometry, not at some coarse threshold


def test_snr_falls_with_range_and_small_boats_fade_out() -> None:
    for north in (11.0, 41.0):
        boat = Vessel("b", 3.0, 3.0, 1.0, Trajectory.stationary((north, 0.0), 0.0))
        model = Awr1843Model(Scene("s", _still(), [boat]), MOUNT, **{**EXACT, "snr_threshold_db": -100.0})
        for f in _frames(model, 5):
            sel = f.label == 0
            p = f.xyz_world[sel]
            np.testing.assert_allclose(p[:, 0], north - 1.5, atol=1e-9)  # all on the face-on bow side, corners too
            rel = p - [1.0, 0.0, -1.0]
            r = np.linalg.norm(rel, axis=1)
            cos_inc = rel[:, 0] / np.hypot(rel[:, 0], rel[:, 1])
            range_loss = 40 * np.log10(r / 10)
            diffuse, strong = f.scatterer[sel] == -1, f.scatterer[sel] >= 0
            assert diffuse.sum() >= 1 and strong.sum() >= 1
            # 45 dB for a 1 m high side at 10 m, face on; R^4 and the incidence cosine take it from there
            np.testing.assert_allclose(
                f.snr_db[sel][diffuse], (45.0 - range_loss + 10 * np.log10(cos_inc))[diffuse], atol=1e-9
            )
            # a corner: 6 +- 2 dB over that, with half the incidence loss (5 log10 cos)
            excess = (f.snr_db[sel] + range_loss - 5 * np.log10(cos_inc) - 45.0)[strong]
            assert np.all((excess >= 4.0 - 1e-9) & (excess <= 8.0 + 1e-9))
    # With a 100 m configuration: at 61 m the 0.6 m Smurf's sides are below the 15 dB CFAR threshold
    # (45 - 2.2 - 31.4 = 11.4 dB), only its corners reach it (+6 +- 2 dB), while the 3.2 m Xi's sides give 18.7 dB;
    # at 81 m even the Smurf's corners are gone (at most 45 - 2.2 + 8 - 38.2 = 12.6 dB).
    for name, height, north, seen in (
        ("smurf", 0.6, 61.0, "corners"),
        ("xi", 3.2, 61.0, "sides"),
        ("smurf", 0.6, 81.0, ""),
    ):
        boat = Vessel(name, 3.0, 3.0, height, Trajectory.stationary((north, 0.0), 0.0))
        model = Awr1843Model(Scene("s", _still(), [boat]), MOUNT, **{**EXACT, "max_range": 100.0})
        points = np.concatenate([f.scatterer[f.label == 0] for f in _frames(model, 5)])
        if seen == "corners":
            assert points.size >= 5 and np.all(points >= 0)
        elif seen == "sides":
            assert np.sum(points == -1) >= 5
        else:
            assert points.size == 0


def test_doppler_aliasing_and_reproducible_frames() -> None:
    boat = Vessel("b", 6.0, 3.0, 1.5, Trajectory.constant_velocity((30.0, 0.0), (-3.0, 0.0)))
    scene = Scene("a", _still(), [boat])
    model = Awr1843Model(scene, MOUNT, **{**EXACT, "v_max": 1.0})
    for f in _frames(model, 5):
        sel = f.label == 0
        assert np.all((f.doppler[sel] >= -1.0) & (f.doppler[sel] < 1.0))
        np.testing.assert_allclose(f.doppler[sel], np.mod(f.doppler_true[sel] + 1.0, 2.0) - 1.0, atol=1e-12)
    noisy = Awr1843Model(scene, MOUNT, seed=5)
    a, b = noisy.frame(0.7), noisy.frame(0.7)
    np.testing.assert_array_equal(a.xyz_ti, b.xyz_ti)
    np.testing.assert_array_equal(a.doppler, b.doppler)
    assert a.frame_index == 7
    assert a.snr_db.shape == a.noise_db.shape == a.label.shape == (a.n_points,)
    assert np.all(a.noise_db > 55.0)


def test_a_frame_built_by_hand_needs_no_scatterer_or_mirror_fields() -> None:
    n = 3
    det = RadarDetections(
        0.1, 1, np.zeros((n, 3)), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n, int), np.zeros((n, 3)),
        np.zeros(n), -np.ones(n, int),
    )  # fmt: skip
    np.testing.assert_array_equal(det.scatterer, [-1, -1, -1])
    np.testing.assert_array_equal(det.mirror_of, [-1, -1, -1])
