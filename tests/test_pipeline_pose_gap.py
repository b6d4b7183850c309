"""A revolution whose ego poses end partway through its sweep: the autopilot's pose messages came late (a starved
companion, a telemetry gap), so the pose history reaches only the first part of the sweep. Found by the soak
(bench/soak.py): every such cycle failed with a broadcasting error and the loop restarted all tracks."""

from __future__ import annotations

import math

import numpy as np

from drivers.mount import Mount
from tests.sea_geometry import SteadyEgo, lidar_pipeline, revolution_over_water, scan_of
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
