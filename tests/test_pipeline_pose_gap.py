"""A revolution whose ego poses end partway through its sweep: the autopilot's pose messages came late (a starved
companion, a telemetry gap), so the pose history reaches only the first part of the sweep. Found by the soak
(bench/soak.py): every such cycle failed with a broadcasting error and the loop restarted all tracks."""

from __future__ import annotations

import math

import numpy as np

from daemon.config import Config
from daemon.runner import pipeline_for
from drivers.mount import Mount
from tests.sea_geometry import (
    SteadyEgo,
    clear_to_11_m_config,
    lidar_pipeline,
    revolution_over_water,
    scan_of,
    wall_ring,
)
from tracker.obstacle_map import UNKNOWN, bearing_bins

MOUNT = Mount(z=-1.6)
YAW = 0.3


def level(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros(np.shape(t)), np.zeros(np.shape(t))


class LateEgo(SteadyEgo):
    """Poses known up to ``until`` only; later times are out of the history's reach (NaN), as PoseHistory gives them."""

    def __init__(self, until: float) -> None:
        super().__init__(level, YAW)
        self.until = until

    def at_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        pos, roll, pitch, yaw = (np.array(a, float) for a in super().at_many(times))
        late = np.asarray(times, float) > self.until
        for a in (pos, roll, pitch, yaw):
            a[late] = np.nan
        return pos, roll, pitch, yaw


def test_a_sweep_whose_poses_end_halfway_still_gives_its_obstacles_and_the_cycle_does_not_fail() -> None:
    pipeline = lidar_pipeline(MOUNT)
    wall = (((20.0, -15.0), (20.0, 15.0), 2.0),)  # 20 m north of the boat, world frame
    ret = revolution_over_water(MOUNT, level, yaw=YAW, walls=wall, water_returns=False)
    assert ret.t.size > 1000
    out = pipeline.step(0.1, scan_of(ret, 0.1), [], LateEgo(until=0.05))
    # the obstacle array comes from the body frame, which needs no pose: the wall's bins, seen ahead to port of a
    # boat heading 0.3 rad east of north
    obstacle = np.flatnonzero(out.distances_cm <= 10000)
    assert obstacle.size > 0 and set(obstacle.tolist()) <= set(bearing_bins(ret.xyz_body[:, :2]).tolist())
    assert np.all(out.distances_cm[obstacle] >= 1900)  # the wall is 20 m off, 17 m+ along any bearing to it
    assert pipeline.skipped_no_pose == 1  # tracking waits for a whole pose
    assert out.tracks == [] and np.any(out.distances_cm == UNKNOWN)
    assert math.isfinite(out.timings_ms["lidar"])


class PoseUntil:
    """The scene's own-boat pose up to ``until``; later, none (the autopilot went silent), as PoseHistory gives it."""

    epoch = 0
    available = True

    def __init__(self, scene: object, until: float) -> None:
        from bench.cycle import SceneEgo

        self.inner = SceneEgo(scene)  # type: ignore[arg-type]
        self.until = until

    def at_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        pos, roll, pitch, yaw = (np.array(a, float) for a in self.inner.at_many(times))
        late = np.asarray(times, float) > self.until
        for a in (pos, roll, pitch, yaw):
            a[late] = np.nan
        return pos, roll, pitch, yaw

    def at(self, t: float) -> object:
        return None if t > self.until else self.inner.at(t)


def test_with_the_pose_lost_the_radar_puts_no_raw_return_in_the_bins_and_its_tracks_are_not_news() -> None:
    """Found replaying a recording whose .tlog was cut: once the pose was lost the radar's raw returns, mostly sea
    clutter, went into the bins as obstacles (4 % of the obstacle bins false), and the tracks stayed confirmed where
    they were last seen for 15 s."""
    from daemon.runner import pipeline_for
    from drivers.awr1843.parser import RadarFrameParser, encode_frame
    from simulator.radar_model import Awr1843Model
    from simulator.scenarios import get_scenario
    from simulator.sea import Sea

    scene = get_scenario("harbour", seed=0)
    scene.sea = Sea.state(3, seed=2)  # clutter at every range the radar sees
    config = Config()
    config.lidar.enabled = False
    config.radar.mount.x, config.radar.mount.z = scene.radar_mount.x, scene.radar_mount.z
    pipeline = pipeline_for(config)
    model = Awr1843Model(scene, scene.radar_mount, seed=1)
    parser = RadarFrameParser(None, scene.radar_mount)
    ego = PoseUntil(scene, until=8.0)
    out = None
    confirmed_before = 0
    for k in range(100):  # 10 s: the pose ends at 8 s
        t = 0.1 * (k + 1)
        d = model.frame(t, k)
        frames = parser.feed(encode_frame(k + 1, d.xyz_ti, d.doppler, d.snr_db, d.noise_db), t)
        out = pipeline.step(t + 0.01, None, frames, ego)
        if t < 7.95:
            confirmed_before = sum(tr.confirmed for tr in out.tracks)
    assert out is not None
    assert confirmed_before >= 2  # the harbour's vessels in the radar's view were tracked while the pose lasted
    assert pipeline.skipped_no_pose >= 15  # the radar kept delivering frames after the pose was lost
    assert np.all(out.distances_cm == UNKNOWN)  # no raw return as an obstacle
    assert not out.pose_known  # so the daemon's loop withholds the array (tests/test_change_notices.py)
    assert out.tracks and not any(tr.confirmed for tr in out.tracks)


def test_with_the_pose_lost_over_a_calm_sea_the_lidar_vouches_for_nothing() -> None:
    """Found in review: with the attitude unknown, the beams were placed for a level boat. Heeled 5 deg to
    starboard, the starboard beams meet the water sooner than that; with clear sent out to 11 m from 4.2 m (beyond
    the lowest beam's gap), the level bands vouched all 72 bearings. Over a calm sea (no water returns, so no
    surface fit to stand in for the attitude) nothing may be vouched until a pose is back."""
    config = clear_to_11_m_config(MOUNT)
    walls = wall_ring(0.0, 361.0, 7.5)

    def heeled(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.full(np.shape(t), math.radians(5.0)), np.zeros(np.shape(t))

    ret = revolution_over_water(MOUNT, heeled, yaw=YAW, walls=walls, water_returns=False)
    assert set(bearing_bins(ret.xyz_body[:, :2]).tolist()) == set(range(72))  # every bearing returned: live
    known = pipeline_for(config).step(0.1, scan_of(ret, 0.1), [], SteadyEgo(heeled, YAW))
    assert np.count_nonzero(known.clear_to_m > 0) >= 30  # with its attitude the LiDAR does vouch, on the high side
    lost = pipeline_for(config).step(0.1, scan_of(ret, 0.1), [], LateEgo(until=-1.0))
    assert lost.clear_to_m.max() == 0.0
    assert np.all(lost.distances_cm != 1101)  # no bin sent as clear
