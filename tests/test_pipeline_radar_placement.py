"""Where the radar's returns land in the obstacle array: at the boat's heading when the array is sent (as the LiDAR's
do, test_pipeline_heading_at_tick.py), and never as "clear" water where the radar returned something it has not
made an obstacle of yet."""

from __future__ import annotations

import math

import numpy as np

from daemon.config import load_config
from daemon.ego import HistoryEgo
from daemon.pose_history import PoseHistory
from daemon.runner import pipeline_for
from drivers.frames import EgoPose, RadarFrame
from tracker.obstacle_map import UNKNOWN
from tracker.pipeline import PerceptionPipeline, PipelineSettings


def turning_ego(rate_rad_s: float, until_s: float = 4.0) -> HistoryEgo:
    """The autopilot's poses at 50 Hz: at the origin, heading rate_rad_s * t."""
    history = PoseHistory()
    for t in np.arange(0.0, until_s, 0.02):
        history.add(EgoPose(float(t), np.zeros(3), np.zeros(3), 0.0, 0.0, rate_rad_s * t, yaw_rate=rate_rad_s))
    return HistoryEgo(history)


def radar_frame(t: float, number: int, xyz_body: np.ndarray) -> RadarFrame:
    n = len(xyz_body)
    return RadarFrame(t, number, xyz_body, np.zeros(n), np.full(n, 25.0), np.full(n, 5.0))


def test_the_radar_returns_follow_the_heading_at_the_tick() -> None:
    # A return 20 m off, 30 deg to starboard (bin 6) in a frame at t = 1 s; the boat turns 30 deg/s to starboard.
    # Ticks after it with no new frame (the radar still fresh) must move it to port with the turn: 0.1 s -> 3 deg,
    # 0.3 s -> 9 deg. Before, it stayed in bin 6 until the radar went stale.
    pipeline = PerceptionPipeline(PipelineSettings())  # no radar tracker: the frame's returns are the solids
    ego = turning_ego(math.radians(30.0))
    bearing = math.radians(30.0)
    ret = np.array([[20.0 * math.cos(bearing), 20.0 * math.sin(bearing), 0.0]])
    seen = []
    for tick in (1.0, 1.3):
        out = pipeline.step(tick, None, [radar_frame(1.0, 1, ret)] if tick == 1.0 else [], ego)
        near = np.flatnonzero(out.distances_cm <= 2100)
        assert np.all(out.distances_cm[near] >= 1990)
        seen.append(near.tolist())
    # 30 deg -> bin 6; 30 - 9 = 21 deg -> bin 4 (its centre 20 deg: 1 deg off, 0.35 m from its edge at 20 m)
    assert seen == [[6], [4]]


def test_the_radar_vouches_only_out_to_what_it_returned() -> None:
    # The README's PX4 setting (clear sent out to 40 m from 2 m), the LiDAR silent: the radar alone vouches in its
    # 120 deg field of view. A small hull 20 m dead ahead gives 2 returns a frame, too few to confirm a track:
    # bin 0 was sent as clear water (4001) every tick. It must be unknown, or the hull's range, never clear.
    config = load_config(None, {"output.max_distance_m": 40.0, "output.clear_inner_m": 2.0})
    pipeline = pipeline_for(config)
    ego = turning_ego(0.0)
    clear = int(config.output.max_distance_m * 100) + 1
    hull = np.array([[20.0, -0.3, -0.5], [20.2, 0.3, -0.5]])
    rng = np.random.default_rng(5)
    for k, t in enumerate(np.arange(1.0, 3.0, 0.1)):
        frame = radar_frame(float(t), k + 1, hull + rng.normal(0.0, 0.05, hull.shape))
        out = pipeline.step(float(t), None, [frame], ego)
        assert out.distances_cm[0] in (UNKNOWN, *range(1900, 2100)), (t, out.distances_cm[0])
        assert out.clear_to_m[0] <= 20.3  # vouched only up to the nearest return
        # Where it returned nothing, it still vouches: 30 deg to either side (bins 6 and 66) are clear.
        assert out.distances_cm[6] == clear and out.distances_cm[66] == clear
        # Outside its field of view (abeam) nothing vouches: unknown.
        assert out.distances_cm[18] == UNKNOWN
