"""The --tracks-out record carries the own pose each tick used and the world origin's latitude/longitude."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from daemon.loop import tick_record
from daemon.replay import recording_config, run_replay
from drivers.frames import EgoPose
from simulator.capture import write_captures
from simulator.scene import OwnBoat, Scene, Trajectory, Vessel
from simulator.truth import T0_UNIX
from tracker.pipeline import PerceptionOutput

OLD_KEYS = {"t", "tracks", "obstacle_distance_cm", "lidar_fresh", "radar_fresh"}


def output() -> PerceptionOutput:
    clear_to = np.zeros(72)
    clear_to[:3] = [11.81, 50.0, 0.04]
    return PerceptionOutput(
        t=12.5,
        tracks=[],
        distances_cm=np.full(72, 10001, np.uint16),
        lidar_fresh=True,
        radar_fresh=False,
        clear_to_m=clear_to,
        held_bins=np.isin(np.arange(72), [5, 6]),
    )


def test_record_with_and_without_a_pose() -> None:
    pose = EgoPose(12.5, np.array([3.14159, -2.5, 0.1]), np.zeros(3), 0.01, 0.02, math.radians(-30.0), 0.0)
    rec = tick_record(output(), sent=True, own=pose, world_origin=(59.4100000123, 10.49))
    assert set(rec) == OLD_KEYS | {"own", "world_origin_lat_lon", "clear_to_m", "held_bins"}
    assert rec["held_bins"] == [5, 6]
    assert rec["clear_to_m"][:4] == [11.8, 50.0, 0.0, 0.0] and len(rec["clear_to_m"]) == 72
    assert rec["own"] == {"position_ne": [3.142, -2.5], "yaw_deg": -30.0}
    assert rec["world_origin_lat_lon"] == [59.41000001, 10.49]
    bare = tick_record(output(), sent=False)
    assert bare["own"] is None and bare["world_origin_lat_lon"] is None and bare["obstacle_distance_cm"] is None
    assert "max_distance_m" not in bare
    assert tick_record(output(), sent=True, max_distance_m=60.0)["max_distance_m"] == 60.0


def test_replayed_ticks_carry_the_autopilots_pose(tmp_path: Path) -> None:
    """A replay of simulated captures: the own pose in each record is the scene's at the tick's time, and the
    world origin is the capture's tangent-plane anchor (the local NED origin seen through GLOBAL_POSITION_INT)."""
    own = OwnBoat(Trajectory.constant_turn((5.0, -3.0), math.radians(40.0), 2.0, 0.2))
    scene = Scene("turning", own, [Vessel("buoy", 2.0, 2.0, 1.0, Trajectory.stationary((15.0, 0.0)))], duration=5.0)
    write_captures("turning", tmp_path, 1.5, scene=scene)
    config = recording_config(tmp_path, tmp_path / "tracks.jsonl")
    assert run_replay(config) == 0
    rows = [json.loads(line) for line in (tmp_path / "tracks.jsonl").read_text().splitlines()]
    assert len(rows) >= 14
    for r in rows:
        truth = scene.own.pose(r["t"] - T0_UNIX)
        assert r["own"]["position_ne"] == pytest.approx(truth.position[:2].tolist(), abs=0.01)
        yaw_err = (r["own"]["yaw_deg"] - math.degrees(truth.yaw) + 180.0) % 360.0 - 180.0
        assert abs(yaw_err) < 0.05
        assert r["world_origin_lat_lon"] == pytest.approx([59.41, 10.49], abs=2e-7)  # 1e-7 deg: GLOBAL_POSITION_INT
        # what "clear" (max + 1 cm) meant in this run, for the evaluator to judge the bins by
        assert r["max_distance_m"] == config.output.max_distance_m == 100.0
