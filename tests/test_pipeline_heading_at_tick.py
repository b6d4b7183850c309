"""The obstacle array's bearings are the boat's heading when the array is sent, not at the end of the sweep it came
from: the autopilot turns the bins by its current heading, and a boat turning 50 deg/s has turned 5 deg in the
0.1 s between a sweep's end and the next tick."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from drivers.frames import EgoPose
from drivers.mount import Mount
from tests.sea_geometry import SteadyEgo, lidar_pipeline, revolution_over_water, scan_of
from tracker.obstacle_map import SensorCoverage, bearing_bins
from tracker.pipeline import swept_at_tick

MOUNT = Mount(z=-1.6)
YAW = 0.3
TURN = math.radians(5.0)  # the heading gained after the sweep
POST_BEARING = math.radians(30.0)  # off the bow at the sweep: bin 6's centre


def level(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros(np.shape(t)), np.zeros(np.shape(t))


class TurnedEgo(SteadyEgo):
    """Heading YAW through the sweep (t <= 0.1 s), YAW + ``turn`` after it."""

    def __init__(self, turn: float = TURN) -> None:
        super().__init__(level, YAW)
        self.turn = turn

    def at(self, t: float) -> EgoPose:
        pose = super().at(t)
        return EgoPose(t, pose.position, pose.velocity, pose.roll, pose.pitch, YAW + (self.turn if t > 0.1 else 0.0))


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


def test_the_radar_speaks_where_the_turned_lidar_did_not_look() -> None:
    """Where the radar alone may put an obstacle is judged against the LiDAR's beams as the tick's body frame sees
    them: a revolution whose bins 10-14 returned nothing (a fouled window), the boat turned 10 deg (two bins) to
    starboard before the tick."""
    ret = revolution_over_water(MOUNT, level, yaw=YAW)
    keep = ~np.isin(bearing_bins(ret.xyz_body[:, :2]), [10, 11, 12, 13, 14])
    ret = dataclasses.replace(
        ret,
        xyz_body=ret.xyz_body[keep],
        t=ret.t[keep],
        ring=ret.ring[keep],
        xyz_world=ret.xyz_world[keep],
        wall=ret.wall[keep],
    )
    pipeline = lidar_pipeline(MOUNT)
    pipeline.step(0.2, scan_of(ret, 0.1), [], TurnedEgo(math.radians(10.0)))
    bins = np.arange(4, 17)
    at_14m = 14.0 * np.column_stack([np.cos(np.radians(5.0 * bins)), np.sin(np.radians(5.0 * bins))])
    speaks = pipeline._radar_speaks_at(at_14m, lidar_fresh=True)
    # the dead bins 10-14 of the revolution are bins 8-12 at the tick; judged in the revolution's frame, 13-14
    # spoke (where the LiDAR vouched) and 8-9 were muted (where it never looked)
    assert bins[speaks].tolist() == [8, 9, 10, 11, 12]


def test_a_partial_sweeps_wedge_turns_with_the_boat() -> None:
    """A sweep of the bow's 90 deg (bins 63-71 and 0-9 hold their centres), then 10 deg of turn to starboard: at the
    tick the same water lies 10 deg further to port, bins 61-71 and 0-7. A LiDAR track's outline is added where the
    sweep did not reach it, judged at the tick's heading."""
    wedge = SensorCoverage(0.0, math.radians(90.0), 100.0)
    assert np.flatnonzero(swept_at_tick(wedge, 0.0)).tolist() == [*range(0, 10), *range(63, 72)]
    assert np.flatnonzero(swept_at_tick(wedge, math.radians(10.0))).tolist() == [*range(0, 8), *range(61, 72)]
