"""How a hull returns to the simulated AWR1843: a few persistent strong scatterers plus weaker diffuse points.

Each vessel spins on the spot in front of a still radar, so every side faces it once a turn. Expected values come
from the model's stated law: 2 + length / 10 m scatterers (2..6) at hull corners (80 % of the freeboard up) and cabin
corners (60 % up the cabin, a third of them when there is a cabin), each 6 +- 2 dB over a face-on metre of side;
chi-square fluctuation with 4 degrees of freedom for them (Swerling IV) and 2 for the diffuse points (Swerling II).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from drivers.mount import Mount
from simulator.radar_model import Awr1843Model, RadarDetections
from simulator.scene import OwnBoat, Scene, Trajectory, Vessel
from tests.radar_sim_settings import EXACT as EXACT_GEOMETRY

MOUNT = Mount(x=0.0, z=-1.0)

EXACT = {**EXACT_GEOMETRY, "snr_threshold_db": -100.0, "max_range": 100.0}
SPIN = 0.3  # rad/s: a full turn in 21 s


def _spinning(vessel: Vessel, distance: float) -> Scene:
    spinning = dataclasses.replace(vessel, trajectory=Trajectory.constant_turn((distance, 0.0), 0.2, 0.0, SPIN))
    return Scene("spin", OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0)), [spinning], [], radar_mount=MOUNT)


USV = Vessel("usv", 2.5, 1.5, 0.8, Trajectory.stationary((0.0, 0.0)))
FISHER = Vessel("fisher", 12.0, 4.0, 3.5, Trajectory.stationary((0.0, 0.0)), hull="pointed", freeboard=1.4)
CREW = Vessel("crew", 43.0, 10.4, 7.5, Trajectory.stationary((0.0, 0.0)), hull="pointed", freeboard=2.8, rcs_scale=3.0)


def _body(scene: Scene, f: RadarDetections, sel: np.ndarray) -> np.ndarray:
    """World NED points of the vessel -> its body frame (forward, starboard, height above the water)."""
    s = scene.vessel_states(f.t)
    d = f.xyz_world[sel, :2] - s.position[0, 0]
    c, sn = math.cos(s.heading[0, 0]), math.sin(s.heading[0, 0])
    return np.stack([c * d[:, 0] + sn * d[:, 1], -sn * d[:, 0] + c * d[:, 1], -f.xyz_world[sel, 2]], axis=1)


def _corners(v: Vessel) -> tuple[np.ndarray, np.ndarray]:
    """Hull corners at 80 % of the freeboard, cabin corners 60 % up the cabin: (K, 3) body (fwd, stbd, height)."""
    hull = np.unique(v.outline_body(), axis=0)
    hull_sites = np.column_stack([hull, np.full(len(hull), 0.8 * v.hull_top)])
    if not v.has_cabin:
        return hull_sites, np.zeros((0, 3))
    cabin = np.unique(v.cabin_body(), axis=0)
    return hull_sites, np.column_stack([cabin, np.full(len(cabin), v.hull_top + 0.6 * (v.height - v.hull_top))])


@pytest.mark.parametrize(
    ("vessel", "distance", "n_strong", "n_cabin"), [(USV, 20.0, 2, 0), (FISHER, 30.0, 3, 1), (CREW, 60.0, 6, 2)]
)
def test_a_hull_returns_from_a_few_persistent_scatterers_at_its_corners_and_cabin(
    vessel: Vessel, distance: float, n_strong: int, n_cabin: int
) -> None:
    scene = _spinning(vessel, distance)
    model = Awr1843Model(scene, **EXACT)
    frames = list(model.frames(0.0, 21.0))  # one full turn
    hull_sites, cabin_sites = _corners(vessel)
    # a face-on metre of this hull's side at 10 m: 45 dB + 10 log10(height x rcs_scale)
    side_db = 45.0 + 10 * math.log10(vessel.height * vessel.rcs_scale)
    where: dict[int, list[np.ndarray]] = {}
    strength: dict[int, list[float]] = {}
    diffuse_strength = []
    for f in frames:
        sel = f.label == 0
        body = _body(scene, f, sel)
        r = np.linalg.norm(f.xyz_world[sel] - [0.0, 0.0, -1.0], axis=1)
        at_10m = f.snr_db[sel] + 40 * np.log10(r / 10)  # the echo's strength at 10 m
        ids = f.scatterer[sel]
        assert np.unique(ids[ids >= 0]).size == np.sum(ids >= 0)  # each scatterer once a frame
        for i, b, s in zip(ids, body, at_10m, strict=True):
            if i >= 0:
                where.setdefault(int(i), []).append(b)
                strength.setdefault(int(i), []).append(float(s))
        diffuse_strength.extend(at_10m[ids == -1])
    assert sorted(where) == list(range(n_strong))  # 2 + length / 10 m of them (2..6)
    on_cabin = 0
    for i, pts in where.items():
        pts_arr = np.array(pts)
        # fixed in the body frame, frame after frame, on a corner of the hull or of the cabin
        assert np.ptp(pts_arr, axis=0).max() < 1e-9
        d_hull = np.abs(hull_sites - pts_arr[0]).max(axis=1).min()
        d_cabin = np.abs(cabin_sites - pts_arr[0]).max(axis=1).min() if len(cabin_sites) else math.inf
        assert min(d_hull, d_cabin) < 1e-9
        on_cabin += int(d_cabin < 1e-9)
        # seen face on once a turn: then 6 +- 2 dB over a face-on metre of side
        assert side_db + 4.0 - 1e-3 <= max(strength[i]) <= side_db + 8.0
    assert on_cabin == n_cabin
    # the diffuse points are weaker: at most a face-on metre of side, never over it
    assert max(diffuse_strength) <= side_db + 1e-9
    assert len(diffuse_strength) > 2 * len(frames)


def test_scatterers_fluctuate_frame_to_frame_like_swerling_iv_and_the_sides_like_swerling_ii() -> None:
    """Same seed with and without fluctuation: the points are the same, and the ratio of their powers is the
    fluctuation. Chi-square with 4 degrees of freedom (mean 1, variance 1/2, 1.75 % below 0.1) for the corners,
    exponential (mean 1, variance 1, 9.5 % below 0.1) for the diffuse points, new every frame."""
    scene = _spinning(FISHER, 30.0)
    steady = Awr1843Model(scene, seed=4, **EXACT)
    fading = Awr1843Model(scene, seed=4, **{**EXACT, "fluctuation": True})
    strong, diffuse = [], []
    by_scatterer: dict[int, list[float]] = {}
    for a, b in zip(steady.frames(0.0, 42.0), fading.frames(0.0, 42.0), strict=True):
        np.testing.assert_array_equal(a.xyz_world, b.xyz_world)
        ratio = 10 ** ((b.snr_db - a.snr_db) / 10)
        strong.extend(ratio[a.scatterer >= 0])
        diffuse.extend(ratio[(a.label == 0) & (a.scatterer == -1)])
        for i in range(3):  # the scatterer seen in consecutive frames, for their correlation
            by_scatterer.setdefault(i, []).append(
                float(ratio[a.scatterer == i][0]) if np.any(a.scatterer == i) else np.nan
            )
    s, d = np.array(strong), np.array(diffuse)
    assert s.size > 500 and d.size > 2000
    assert s.mean() == pytest.approx(1.0, abs=3 * math.sqrt(0.5 / s.size))
    assert s.var() == pytest.approx(0.5, rel=0.2)
    assert np.mean(s < 0.1) == pytest.approx(1 - math.exp(-0.2) * 1.2, abs=0.015)
    assert d.mean() == pytest.approx(1.0, abs=3 * math.sqrt(1.0 / d.size))
    assert d.var() == pytest.approx(1.0, rel=0.2)
    assert np.mean(d < 0.1) == pytest.approx(1 - math.exp(-0.1), abs=0.02)
    for series in by_scatterer.values():
        x = np.array(series)
        pair = ~np.isnan(x[:-1]) & ~np.isnan(x[1:])
        assert pair.sum() > 100
        assert abs(np.corrcoef(x[:-1][pair], x[1:][pair])[0, 1]) < 0.2  # independent from frame to frame


def test_a_43_m_ship_returns_many_times_what_a_2_5_m_usv_does() -> None:
    """Broadside at 30 m, with the default fading and detection: the USV gives about 3 points a frame (2 or 3 on its
    side, its one corner on that side), the crew boat about 30 (its 43 m side, its corners and cabin)."""
    means = {}
    for v in (USV, CREW):
        boat = dataclasses.replace(v, trajectory=Trajectory.stationary((31.0, 0.0), math.pi / 2))
        scene = Scene("side", OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0)), [boat], [], radar_mount=MOUNT)
        model = Awr1843Model(scene, seed=1, clutter_calm=0.0, ghost_probability=0.0)
        means[v.name] = np.mean([np.sum(f.label == 0) for f in model.frames(0.0, 10.0)])
    assert 1.5 <= means["usv"] <= 5.0
    assert means["crew"] >= 8 * means["usv"]
