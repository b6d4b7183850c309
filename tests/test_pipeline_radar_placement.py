"""Where the radar's returns land in the obstacle array: at the boat's heading when the array is sent (as the LiDAR's
do, test_pipeline_heading_at_tick.py), and never as "clear" water where the radar returned something it has not
made an obstacle of yet."""

from __future__ import annotations

import math

import numpy as np
import pytest

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


def tilted_ego(roll_deg: float, pitch_deg: float) -> HistoryEgo:
    """The autopilot's poses at 50 Hz: at the origin facing north, heeled and trimmed as given."""
    history = PoseHistory()
    for t in np.arange(0.0, 4.0, 0.02):
        history.add(EgoPose(float(t), np.zeros(3), np.zeros(3), math.radians(roll_deg), math.radians(pitch_deg), 0.0))
    return HistoryEgo(history)


@pytest.mark.parametrize(
    ("roll_deg", "pitch_deg", "unknown_bins", "clear_bins"),
    [
        # level: the beam's lower edge, 15 deg down, meets a 0.5 m solid's top 0.5 / tan 15 = 1.9 m out, inside 2 m
        (0.0, 0.0, [], [0, 6, 11, 66]),
        # bow up 10 deg: ahead the edge is 5 deg down and meets it 5.7 m out, so 2-5.7 m ahead was never seen
        (0.0, 10.0, [0], []),
        # heeled 10 deg to starboard: 30 deg to port the edge is 10 deg down (2.8 m), to starboard 20 deg (1.4 m)
        (10.0, 0.0, [66], [0, 6]),
        # heeled 20 deg: 57 deg to starboard the beam's upper edge is 1.7 deg down and meets the water 34 m out,
        # short of the 40 m that "clear" claims
        (20.0, 0.0, [11, 66], [0]),
    ],
)
def test_the_radar_vouches_from_where_its_tilted_beam_meets_a_low_solid(
    roll_deg: float, pitch_deg: float, unknown_bins: list[int], clear_bins: list[int]
) -> None:
    # The README's PX4 setting (clear from 2 m), the radar 1 m above the water, the LiDAR silent, the radar returning
    # one point far abeam outside its field of view: it vouches in its 120 deg field of view from where its beam
    # reaches a 0.5 m solid's top. Before, the level boat's 1.9 m held at any heel or trim.
    # The radar on the body origin (x 0): its 0.5 m forward of the shipped mount narrows the wedge near the boat
    # (tests/test_coverage_sensor_offset.py), which is not what this test looks at.
    overrides = {
        "output.max_distance_m": 40.0,
        "output.clear_inner_m": 2.0,
        "radar.mount.z": -1.0,
        "radar.mount.x": 0.0,
    }
    config = load_config(None, overrides)
    pipeline = pipeline_for(config)
    ego = tilted_ego(roll_deg, pitch_deg)
    clear = int(config.output.max_distance_m * 100) + 1
    outside = np.array([[0.0, -45.0, -0.5]])  # dead abeam to port, out of the field of view
    for k, t in enumerate(np.arange(1.0, 2.0, 0.1)):
        out = pipeline.step(float(t), None, [radar_frame(float(t), k + 1, outside)], ego)
    assert [int(out.distances_cm[j]) for j in unknown_bins] == [UNKNOWN] * len(unknown_bins)
    assert [int(out.distances_cm[j]) for j in clear_bins] == [clear] * len(clear_bins)


@pytest.mark.parametrize(
    ("roll_deg", "pitch_deg", "unknown_bins", "clear_bins"), [(0.0, 0.0, [], [0, 66]), (0.0, 18.0, [0], [])]
)
def test_a_radar_at_a_low_solids_height_sees_none_once_its_beam_points_up(
    roll_deg: float, pitch_deg: float, unknown_bins: list[int], clear_bins: list[int]
) -> None:
    # The shipped geometry: the radar 0.5 m above the water, a low solid's top at its very height. Level, the beam's
    # lower edge (15 deg down) meets that top from the hull out; bow up 18 deg, that edge points 3 deg up ahead and
    # passes over every such solid there. Before, the level boat's coverage held at any trim.
    config = load_config(None, {"output.max_distance_m": 40.0, "output.clear_inner_m": 2.0})
    pipeline = pipeline_for(config)
    assert pipeline.settings.radar_height_m == pytest.approx(pipeline.settings.min_obstacle_height_m)
    ego = tilted_ego(roll_deg, pitch_deg)
    clear = int(config.output.max_distance_m * 100) + 1
    outside = np.array([[0.0, -45.0, -0.5]])
    for k, t in enumerate(np.arange(1.0, 2.0, 0.1)):
        out = pipeline.step(float(t), None, [radar_frame(float(t), k + 1, outside)], ego)
    assert [int(out.distances_cm[j]) for j in unknown_bins] == [UNKNOWN] * len(unknown_bins)
    assert [int(out.distances_cm[j]) for j in clear_bins] == [clear] * len(clear_bins)


def test_the_radar_field_of_view_follows_the_heading_at_the_tick() -> None:
    # Its returns turn with the boat between a frame and the tick (above); so must the field of view it vouches in.
    # A frame at t = 1 s sees +-60 deg about the bow; the boat turns 30 deg/s to starboard, so at the tick 0.3 s
    # later (no new frame, the radar still fresh) that field lies at -69..+51 deg: bin 11 (53-57 deg) has left it
    # and bin 59 (-67..-63 deg) has come into it. Before, the field stayed at +-60 deg about the new heading.
    config = load_config(
        None, {"output.max_distance_m": 40.0, "output.clear_inner_m": 2.0, "radar.mount.x": 0.0}
    )  # the radar on the body origin, as above
    pipeline = pipeline_for(config)
    ego = turning_ego(math.radians(30.0))
    clear = int(config.output.max_distance_m * 100) + 1
    outside = np.array([[0.0, -45.0, -0.5]])  # dead abeam to port, out of the field of view
    first = pipeline.step(1.0, None, [radar_frame(1.0, 1, outside)], ego)
    assert (int(first.distances_cm[11]), int(first.distances_cm[59])) == (clear, UNKNOWN)
    later = pipeline.step(1.3, None, [], ego)
    assert (int(later.distances_cm[11]), int(later.distances_cm[59])) == (UNKNOWN, clear)


def test_a_new_world_frame_leaves_the_field_of_view_where_the_radar_looked() -> None:
    # A frame at heading 180 deg, then the autopilot's world frame changes (its poses cleared) before the next frame:
    # the frame's field of view stays about the bow of the body frame it was measured in. Before, it was turned by
    # the heading between the old world's pose (180 deg) and the pose-less tick's (0): "clear" astern, where the
    # radar does not look.
    config = load_config(
        None, {"output.max_distance_m": 40.0, "output.clear_inner_m": 2.0, "radar.mount.x": 0.0}
    )  # the radar on the body origin, as above
    pipeline = pipeline_for(config)
    clear = int(config.output.max_distance_m * 100) + 1
    history, epoch = PoseHistory(), [0]
    ego = HistoryEgo(history, lambda: epoch[0])
    for t in np.arange(0.0, 1.05, 0.02):
        history.add(EgoPose(float(t), np.zeros(3), np.zeros(3), 0.0, 0.0, math.pi))
    outside = np.array([[0.0, -45.0, -0.5]])  # dead abeam to port, out of the field of view
    ahead = [*range(0, 12), *range(61, 72)]
    first = pipeline.step(1.0, None, [radar_frame(1.0, 1, outside)], ego)
    assert np.flatnonzero(first.distances_cm == clear).tolist() == ahead
    history.clear()
    epoch[0] += 1
    later = pipeline.step(1.1, None, [], ego)
    assert np.flatnonzero(later.distances_cm == clear).tolist() == ahead
