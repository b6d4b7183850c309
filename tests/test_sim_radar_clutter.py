"""Sea clutter in the simulated AWR1843: everywhere it looks, thicker near and on a rough sea, moving with the water.

The expected values are worked out here from the model's stated law (an areal density proportional to range^-2,
scaled so that 1-50 m and +-60 deg hold ``clutter_calm + clutter_sea_state_3 crest / 0.3 m`` a frame) and from
linear deep-water wave theory, not from the model's code.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from drivers.mount import Mount
from simulator.radar_model import Awr1843Model, RadarDetections
from simulator.scene import LABEL_CLUTTER, OwnBoat, Quay, Scene, SensorConditions, Trajectory, Vessel
from simulator.sea import Sea, WaveTrain

MOUNT = Mount(x=1.2, z=-0.9)  # the scenes' default radar mount: 0.9 m above the water, looking along the bow
QUIET = {"range_noise_m": 0.0, "azimuth_noise_deg": 0.0, "elevation_noise_deg": 0.0, "doppler_noise": 0.0}
G = 9.81


def _still() -> OwnBoat:
    return OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0))


def _clutter(frames: list[RadarDetections]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World positions, true Doppler and SNR of every clutter point of the frames."""
    sel = [f.label == LABEL_CLUTTER for f in frames]
    return (
        np.concatenate([f.xyz_world[s] for f, s in zip(frames, sel, strict=True)]),
        np.concatenate([f.doppler_true[s] for f, s in zip(frames, sel, strict=True)]),
        np.concatenate([f.snr_db[s] for f, s in zip(frames, sel, strict=True)]),
    )


def _horizontal_range(xyz: np.ndarray) -> np.ndarray:
    return np.hypot(xyz[:, 0] - MOUNT.x, xyz[:, 1] - MOUNT.y)


def _expected_per_frame(rate: float, r0: float, r1: float) -> float:
    """Clutter a frame between horizontal ranges r0 and r1 in the +-60 deg field of view: density ~ r^-2 puts a
    share ln(r1 / r0) / ln(50 / 1) of the reference window's ``rate`` there."""
    return rate * math.log(r1 / r0) / math.log(50.0)


def test_clutter_fills_the_field_of_view_with_a_density_falling_as_range_squared() -> None:
    scene = Scene("sea", _still(), [], [], radar_mount=MOUNT, sea=Sea.state(3, seed=4))
    model = Awr1843Model(scene, seed=2, **QUIET)
    assert model.clutter_rate == pytest.approx(3.0 + 150.0)
    frames = list(model.frames(0.0, 20.0))
    xyz, _, snr = _clutter(frames)
    r = _horizontal_range(xyz)
    bearing = np.arctan2(xyz[:, 1] - MOUNT.y, xyz[:, 0] - MOUNT.x)
    assert np.all(np.abs(bearing) <= math.radians(60.0) + 1e-9)
    assert r.max() > 49.0 and r.max() <= 50.0
    # near the radar the water lies below the 20 deg elevation field of view: none within 0.9 / tan(20 deg) = 2.5 m
    # of a flat sea, nor within (0.9 - 0.3) / tan(20 deg) = 1.65 m on a 0.3 m crest
    assert 1.6 < r.min() < 2.5
    # on the water surface, where the sea stands at that place and time
    t = np.concatenate([np.full(int(np.sum(f.label == LABEL_CLUTTER)), f.t) for f in frames])
    np.testing.assert_allclose(-xyz[:, 2], scene.sea.elevation(xyz[:, 0], xyz[:, 1], t), atol=1e-9)
    # Counts per octave of range are equal for a density ~ r^-2 (the areas grow as r^2): 5-10 m, 10-20 m, 20-40 m
    # each hold 153 ln 2 / ln 50 = 27.1 a frame, though the area grows 16-fold from the first to the last.
    n_frames = len(frames)
    for lo, hi in ((5.0, 10.0), (10.0, 20.0), (20.0, 40.0)):
        per_frame = np.sum((r >= lo) & (r < hi)) / n_frames
        assert per_frame == pytest.approx(_expected_per_frame(153.0, lo, hi), rel=0.08), (lo, hi)
    assert np.sum(r >= 40.0) / n_frames == pytest.approx(_expected_per_frame(153.0, 40.0, 50.0), rel=0.1)
    # the SNR sits just over the 15 dB CFAR threshold: exponential excess of mean 2 dB (median 1.4 dB, 95 % 6.0 dB)
    assert snr.min() >= 15.0
    assert np.median(snr) == pytest.approx(15.0 + 2.0 * math.log(2.0), abs=0.15)
    assert np.quantile(snr, 0.95) == pytest.approx(15.0 + 2.0 * math.log(20.0), abs=0.5)


@pytest.mark.parametrize(("sea_state", "crest"), [(0, 0.0), (1, 0.05), (2, 0.15), (3, 0.3)])
def test_clutter_rises_with_the_sea_state(sea_state: int, crest: float) -> None:
    scene = Scene("sea", _still(), [], [], radar_mount=MOUNT, sea=Sea.state(sea_state, seed=1))
    assert scene.sea.crest == pytest.approx(crest)
    frames = list(Awr1843Model(scene, seed=5, **QUIET).frames(0.0, 20.0))
    r = _horizontal_range(_clutter(frames)[0])
    per_frame = np.sum(r >= 3.0) / len(frames)  # beyond 3 m the elevation field of view cuts nothing
    rate = 3.0 + 150.0 * crest / 0.3  # calm 3, sea state 1: 28, 2: 78, 3: 153
    expected = _expected_per_frame(rate, 3.0, 50.0)
    assert abs(per_frame - expected) < 4 * math.sqrt(expected / len(frames)) + 0.05 * expected
    if sea_state == 0:
        assert per_frame < 3.0  # a calm sea clutters little
    if sea_state == 3:
        assert per_frame > 100.0  # sea state 3 a lot


def test_the_scene_sets_the_clutter_level() -> None:
    quiet = SensorConditions(radar_clutter_calm=0.0, radar_clutter_sea_state_3=0.0)
    assert Awr1843Model(Scene("q", _still(), sea=Sea.state(3), conditions=quiet)).frame(0.0).n_points == 0
    heavy = SensorConditions(radar_clutter_calm=40.0)
    model = Awr1843Model(Scene("h", _still(), radar_mount=MOUNT, conditions=heavy), seed=3, **QUIET)
    assert model.clutter_rate == 40.0
    frames = list(model.frames(0.0, 10.0))
    per_frame = np.sum(_horizontal_range(_clutter(frames)[0]) >= 3.0) / len(frames)
    assert per_frame == pytest.approx(_expected_per_frame(40.0, 3.0, 50.0), rel=0.1)
    # a wet radome (2 dB) sinks clutter whose exponential excess (mean 2 dB) is under 2 dB: exp(-1) = 37 % remain
    wet = SensorConditions(radar_clutter_calm=40.0, radar_snr_loss_db=2.0)
    frames = list(
        Awr1843Model(Scene("w", _still(), radar_mount=MOUNT, conditions=wet), seed=3, **QUIET).frames(0.0, 10.0)
    )
    wet_per_frame = np.sum(_horizontal_range(_clutter(frames)[0]) >= 3.0) / len(frames)
    assert wet_per_frame == pytest.approx(math.exp(-1.0) * _expected_per_frame(40.0, 3.0, 50.0), rel=0.12)


def test_clutter_doppler_is_the_orbital_motion_of_the_waves_under_it() -> None:
    """One train of 12 m waves, 0.25 m high: the water moves at a omega = 0.57 m/s, forward on the crests, back in
    the troughs, up and down in between. The clutter's Doppler follows that field (coherent through each wave
    period at each place) to within the model's 0.1 m/s spread, and the crests, where it prefers to sit, move
    forward."""
    wave = WaveTrain(amplitude=0.25, wavelength=12.0, direction=0.4, phase=1.0)
    scene = Scene("swell", _still(), [], [], radar_mount=MOUNT, sea=Sea(waves=(wave,)))
    model = Awr1843Model(scene, seed=8, clutter_calm=0.0, clutter_sea_state_3=300.0, **QUIET)
    frames = list(model.frames(0.0, 10.0))
    xyz, dop, _ = _clutter(frames)
    t = np.concatenate([np.full(int(np.sum(f.label == LABEL_CLUTTER)), f.t) for f in frames])
    k = 2 * math.pi / 12.0
    omega = math.sqrt(G * k)
    theta = k * (xyz[:, 0] * math.cos(0.4) + xyz[:, 1] * math.sin(0.4)) - omega * t + 1.0
    speed = 0.25 * omega
    v_ned = np.stack(
        [speed * np.sin(theta) * math.cos(0.4), speed * np.sin(theta) * math.sin(0.4), speed * np.cos(theta)], axis=1
    )
    los = xyz - np.array([MOUNT.x, MOUNT.y, MOUNT.z])
    los /= np.linalg.norm(los, axis=1, keepdims=True)
    orbital = np.sum(v_ned * los, axis=1)  # the own boat is at rest
    residual = dop - orbital
    assert dop.size > 2000
    assert abs(residual.mean()) < 0.01
    assert 0.09 < residual.std() < 0.105  # the 0.1 m/s horizontal spread, seen along a nearly level line of sight
    # the correlation a 0.1 m/s spread leaves to an orbital Doppler of this spread (0.2 m/s): about 0.9
    expected_corr = orbital.std() / math.sqrt(orbital.var() + 0.1**2)
    assert np.corrcoef(dop, orbital)[0, 1] == pytest.approx(expected_corr, abs=0.02)
    assert np.quantile(np.abs(dop), 0.99) < 0.9  # a few tenths of a m/s, never a boat's speed
    # Kept with w = ((sin(theta) + 1) / 2)^2, the points' mean sin(theta) is E[w sin] / E[w] = 0.25 / 0.375 = 2/3
    assert np.sin(theta).mean() == pytest.approx(2 / 3, abs=0.03)


def test_clutter_does_not_stay_where_it_was() -> None:
    """Fresh places every frame: few points of one frame have a point of the frame before within 10 cm (about 2.5 %
    for independent places at this density; a clutter patch that persisted would score near 100 %)."""
    scene = Scene("sea", _still(), [], [], radar_mount=MOUNT, sea=Sea.state(3, seed=4))
    frames = list(Awr1843Model(scene, seed=6, **QUIET).frames(0.0, 5.0))
    matched = total = 0
    for prev, cur in itertools.pairwise(frames):
        a = prev.xyz_world[prev.label == LABEL_CLUTTER, :2]
        b = cur.xyz_world[cur.label == LABEL_CLUTTER, :2]
        d = np.hypot(b[:, None, 0] - a[None, :, 0], b[:, None, 1] - a[None, :, 1]).min(axis=1)
        matched += int(np.sum(d < 0.1))
        total += b.shape[0]
    assert total > 4000
    assert matched / total < 0.05


def test_no_clutter_on_land_or_in_a_hulls_shadow() -> None:
    """A quay 30 m ahead (land beyond it) and a long hull 15 m ahead: no water returns on the land, none in the
    hull's radar shadow, while the same bearings beside the shadow have plenty."""
    quay = Quay(np.array([[31.2, -60.0], [31.2, 60.0]]), height=1.5, land_side="port")  # walking east: port = north
    hull = Vessel("barge", 3.0, 8.0, 1.5, Trajectory.stationary((16.2, 0.0), 0.0))  # 8 m across the line of sight
    scene = Scene("basin", _still(), [hull], [quay], radar_mount=MOUNT, sea=Sea.state(3, seed=2))
    frames = list(Awr1843Model(scene, seed=9, max_range=50.0, **QUIET).frames(0.0, 20.0))
    xyz = _clutter(frames)[0]
    north, east = xyz[:, 0] - MOUNT.x, xyz[:, 1]
    assert np.all(north < 30.0 + 1e-9)  # nothing beyond the wall
    bearing = np.arctan2(east, north)
    half_shadow = math.atan2(4.0, 13.5)  # the barge's near face: 8 m wide at 13.5 m from the radar
    beyond = north > 16.5  # beyond its far face
    in_shadow = beyond & (np.abs(bearing) < half_shadow - 0.01)
    beside = beyond & (np.abs(bearing) > half_shadow + 0.01) & (np.abs(bearing) < 2 * half_shadow)
    assert np.sum(in_shadow) == 0
    assert np.sum(beside) > 100
    # and none inside the hull itself
    assert not np.any((np.abs(north - 15.0) <= 1.5) & (np.abs(east) <= 4.0))
