"""The obstacle array's bearings are the boat's heading when the array is sent, not at the end of the sweep it came
from: the autopilot turns the bins by its current heading, and a boat turning 50 deg/s has turned 5 deg in the
0.1 s between a sweep's end and the next tick."""

from __future__ import annotations

import math

import numpy as np

from drivers.frames import EgoPose
from drivers.mount import Mount
from tests.sea_geometry import SteadyEgo, lidar_pipeline, revolution_over_water, scan_of
from tracker.obstacle_map import bearing_bins

MOUNT = Mount(z=-1.6)
YAW = 0.3
TURN = math.radians(5.0)  # the heading gained after the sweep
POST_BEARING = math.radians(30.0)  # off the bow at the sweep: bin 6's centre


def level(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros(np.shape(t)), np.zeros(np.shape(t))


class TurnedEgo(SteadyEgo):
    """Heading YAW through the sweep (t <= 0.1 s), YAW + TURN after it."""

    def __init__(self) -> None:
        super().__init__(level, YAW)

    def at(self, t: float) -> EgoPose:
        pose = super().at(t)
        return EgoPose(t, pose.position, pose.velocity, pose.roll, pose.pitch, YAW + (TURN if t > 0.1 else 0.0))


def test_the_bins_follow_the_heading_at_the_tick() -> None:
    pipeline = lidar_pipeline(MOUNT)
    # a 0.6 m wide post 20 m off, 30 deg to starboard of the bow as the sweep ends (1.7 deg wide: inside bin 6)
    world = YAW + POST_BEARING
    centre = 20.0 * np.array([math.cos(world), math.sin(world)])
    across = 0.3 * np.array([-math.sin(world), math.cos(world)])
    post = ((tuple(centre - across), tuple(centre + across), 2.0),)
    ret = revolution_over_water(MOUNT, level, yaw=YAW, walls=post, water_returns=False)
    assert set(bearing_bins(ret.xyz_body[:, :2]).tolist()) == {6}
    obstacle_bins = []
    for tick in (0.1, 0.19):  # at the sweep's end, and 0.09 s later with the boat turned 5 deg to starboard
        out = pipeline.step(tick, scan_of(ret, 0.1), [], TurnedEgo())
        near = np.flatnonzero(out.distances_cm <= 2100)
        assert np.all(out.distances_cm[near] >= 1900)  # the post, 20 m off, within 0.1 m of range noise
        obstacle_bins.append(near.tolist())
    # 5 deg of turn to starboard moves the post 5 deg to port: bin 6 -> bin 5
    assert obstacle_bins == [[6], [5]]
