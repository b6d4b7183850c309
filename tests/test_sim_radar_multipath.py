"""Quay multipath in the simulated AWR1843: a boat seen via a quay wall appears as its mirror image behind the wall.

The radar sits at the origin, 1 m up, looking 30 deg to starboard of north; a quay wall runs north-south 20 m to the
east (land beyond it). A 6 m boat 15 m in front of the wall heads east at 1.5 m/s. Expected values are plain mirror
geometry worked out here: a wave radar -> wall -> hull -> wall -> radar travels as far as the straight line from the
radar to the hull's mirror image, which is where the radar places the echo.
"""

from __future__ import annotations

import math

import numpy as np

from drivers.mount import Mount
from simulator.radar_model import Awr1843Model, RadarDetections
from simulator.scene import LABEL_GHOST, OwnBoat, Quay, Scene, Trajectory, Vessel
from tests.radar_sim_settings import EXACT as EXACT_GEOMETRY

MOUNT = Mount(x=0.0, z=-1.0, yaw=math.radians(30.0))
RADAR = np.array([0.0, 0.0, -1.0])  # world NED: the own boat lies still at the origin, heading north
WALL_EAST = 20.0

EXACT = {**EXACT_GEOMETRY, "snr_threshold_db": -100.0}


def _boat() -> Vessel:
    return Vessel("boat", 6.0, 2.5, 1.5, Trajectory.constant_velocity((25.0, 5.0), (0.0, 1.5)))


def _scene(
    wall_north: tuple[float, float] = (-10.0, 80.0), wall_height: float = 1.5, extra: list | None = None
) -> Scene:
    quay = Quay(np.array([[wall_north[0], WALL_EAST], [wall_north[1], WALL_EAST]]), height=wall_height)  # land east
    own = OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0))
    return Scene("quay", own, [_boat(), *(extra or [])], [quay], radar_mount=MOUNT)


def _mirror_ghosts(frames: list[RadarDetections]) -> list[tuple[RadarDetections, np.ndarray]]:
    return [(f, (f.label == LABEL_GHOST) & (f.mirror_of == 0)) for f in frames]


def _edge_distance(p: np.ndarray, poly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance of 2-D points (N, 2) to a polygon's boundary, and the unit normal of the nearest side."""
    a, b = poly, np.roll(poly, -1, axis=0)
    d = b - a
    seg = np.sum(d * d, axis=1) > 0
    a, d = a[seg], d[seg]
    f = np.clip(np.sum((p[:, None, :] - a[None]) * d[None], axis=2) / np.sum(d * d, axis=1)[None], 0.0, 1.0)
    dist = np.linalg.norm(a[None] + f[..., None] * d[None] - p[:, None, :], axis=2)
    nearest = dist.argmin(axis=1)
    side = d[nearest] / np.linalg.norm(d[nearest], axis=1, keepdims=True)
    return dist.min(axis=1), np.stack([side[:, 1], -side[:, 0]], axis=1)


def test_a_boat_seen_via_a_quay_wall_appears_mirrored_behind_it_at_the_bounce_path_length() -> None:
    scene = _scene()
    frames = list(Awr1843Model(scene, **EXACT).frames(0.0, 2.0))
    n_ghosts = n_corner_ghosts = 0
    for f, g in _mirror_ghosts(frames):
        p = f.xyz_world[g]
        assert np.all(p[:, 1] > WALL_EAST)  # behind the wall, on the land side
        real = p.copy()
        real[:, 1] = 2 * WALL_EAST - p[:, 1]  # folded back across the wall
        hull = scene.footprints(f.t)[0, 0]
        dist, _ = _edge_distance(real[:, :2], hull)
        assert dist.max() < 1e-9  # ... it lies on the boat's hull
        assert np.all((-real[:, 2] > 0) & (-real[:, 2] <= 1.5))
        # the bounce: where the straight radar -> image line crosses the wall, within the wall and below its top
        frac = (WALL_EAST - RADAR[1]) / (p[:, 1] - RADAR[1])
        wall_point = RADAR + frac[:, None] * (p - RADAR)
        assert np.all((wall_point[:, 0] >= -10.0) & (wall_point[:, 0] <= 80.0))
        assert np.all((-wall_point[:, 2] >= 0.0) & (-wall_point[:, 2] <= 1.5))
        # its range is the path radar -> wall -> hull (and the same way back)
        path = np.linalg.norm(wall_point - RADAR, axis=1) + np.linalg.norm(real - wall_point, axis=1)
        np.testing.assert_allclose(np.linalg.norm(f.xyz_ti[g], axis=1), path, atol=1e-9)
        # Doppler of the image: the boat heads east (away, positive), its image west (towards the radar, negative)
        los = (p - RADAR) / np.linalg.norm(p - RADAR, axis=1, keepdims=True)
        np.testing.assert_allclose(f.doppler_true[g], los @ [0.0, -1.5, 0.0], atol=1e-9)
        assert np.all(f.doppler_true[g] < 0) and np.all(f.doppler_true[f.label == 0] > 0)
        n_ghosts += int(g.sum())
        n_corner_ghosts += int(np.sum(f.scatterer[g] >= 0))
    assert n_ghosts > 40 and n_corner_ghosts > 10


def test_the_mirror_image_is_weaker_by_the_two_reflections_and_the_longer_path() -> None:
    """A side's echo seen via the wall: 45 dB + 10 log10(1.5 m) at 10 m, the incidence cosine as the radar's image
    (behind the wall) sees that side, less 8 dB for the two reflections and 40 log10 of the whole path."""
    scene = _scene()
    image = np.array([0.0, 2 * WALL_EAST, -1.0])  # the radar mirrored behind the wall
    frames = list(Awr1843Model(scene, **EXACT).frames(0.0, 2.0))
    checked = 0
    for f, g in _mirror_ghosts(frames):
        diffuse = g & (f.scatterer == -1)
        p = f.xyz_world[diffuse]
        real = p * [1.0, -1.0, 1.0] + [0.0, 2 * WALL_EAST, 0.0]
        _, normal = _edge_distance(real[:, :2], scene.footprints(f.t)[0, 0])
        to_image = image[:2] - real[:, :2]
        cos_inc = np.abs(np.sum(normal * to_image, axis=1)) / np.linalg.norm(to_image, axis=1)
        path = np.linalg.norm(p - RADAR, axis=1)
        expected = (
            45.0 + 10 * math.log10(1.5) + 10 * np.log10(np.maximum(cos_inc, 0.1)) - 8.0 - 40 * np.log10(path / 10)
        )
        np.testing.assert_allclose(f.snr_db[diffuse], expected, atol=1e-9)
        checked += int(diffuse.sum())
    assert checked > 20
    # with the real threshold and fading some images are still detected, all weaker than the boat's own returns
    model = Awr1843Model(scene, seed=2, clutter_calm=0.0, ghost_probability=0.0)
    frames = list(model.frames(0.0, 10.0))
    ghost_snr = np.concatenate([f.snr_db[g] for f, g in _mirror_ghosts(frames)])
    direct_snr = np.concatenate([f.snr_db[f.label == 0] for f in frames])
    assert ghost_snr.size > 20 and ghost_snr.min() >= 15.0
    assert np.median(ghost_snr) < np.median(direct_snr) - 8.0


def test_no_mirror_image_without_a_wall_where_the_wave_would_bounce() -> None:
    def n_images(scene: Scene) -> int:
        frames = list(Awr1843Model(scene, **EXACT).frames(0.0, 2.0))
        return sum(int(g.sum()) for _, g in _mirror_ghosts(frames))

    assert n_images(_scene()) > 40
    assert n_images(_scene(wall_north=(40.0, 80.0))) == 0  # the wall ends before the bounce point (north 13-17 m)
    # a 0.25 m wall: the bounce lies 0.55-1.2 m up (between the radar's 1 m and the hull's points), over its top
    assert n_images(_scene(wall_height=0.25)) == 0
    # a 3 m high boat between the radar and the bounce point blocks the way there (not the direct view)
    blocker = Vessel("blocker", 4.0, 4.0, 3.0, Trajectory.stationary((7.0, 10.0), 0.0))
    scene = _scene(extra=[blocker])
    assert n_images(scene) == 0
    frames = list(Awr1843Model(scene, **EXACT).frames(0.0, 2.0))
    assert all(np.sum(f.label == 0) > 3 for f in frames)
