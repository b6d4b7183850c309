"""Non-finite values in the autopilot's pose messages: counted and skipped where they are, the good fields kept, and
a replay of a .tlog holding them runs to its end."""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path

import numpy as np
import pytest

from daemon.autopilot_pose import PoseAssembler
from daemon.config import Config
from daemon.mavlink_env import mavlink, mavutil
from daemon.pose_history import PoseHistory
from daemon.replay import recording_config, run_replay
from daemon.runner import pipeline_for
from drivers.frames import EgoPose, RadarFrame
from simulator.capture import write_captures


def _assembler() -> PoseAssembler:
    return PoseAssembler(PoseHistory(), position_timeout=1.0, global_grace=1.0)


def test_an_infinite_or_nan_attitude_is_counted_and_skipped() -> None:
    a = _assembler()
    a.on_local_position(0.0, np.array([1.0, 2.0, 0.0]), np.array([1.0, 0.0, 0.0]))
    assert a.on_attitude(0.02, math.inf, 0.0, 0.1, 0.0, 0.0, 0.0) is None
    assert a.on_attitude(0.04, 0.0, 0.0, 0.1, 0.0, math.nan, 0.0) is None
    assert a.rejected == 2 and a.samples == 0
    pose = a.on_attitude(0.06, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0)
    assert pose is not None and a.samples == 1
    np.testing.assert_allclose(pose.position, [1.06, 2.0, 0.0], atol=1e-12)


def test_a_local_position_without_a_finite_velocity_keeps_its_position_and_the_last_velocity() -> None:
    a = _assembler()
    nan_v = np.array([1.0, 0.0, math.nan])
    a.on_local_position(0.0, np.array([1.0, 2.0, 0.0]), nan_v)  # nothing earlier to hold: no position from it
    assert a.local_rejected == 1 and a.on_attitude(0.01, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0) is None
    a.on_local_position(0.1, np.array([1.0, 2.0, 0.0]), np.array([0.5, -0.5, 0.0]))
    a.on_local_position(0.15, np.array([5.0, 6.0, 0.0]), nan_v)
    assert a.velocity_held == 1
    pose = a.on_attitude(0.15, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert pose is not None
    np.testing.assert_allclose(pose.position, [5.0, 6.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(pose.velocity, [0.5, -0.5, 0.0], atol=1e-12)
    a.on_local_position(0.2, np.array([math.nan, 6.0, 0.0]), np.array([0.5, -0.5, 0.0]))
    assert a.local_rejected == 2


def _spoil_tlog(path: Path) -> int:
    """Rewrites the .tlog with its 20th ATTITUDE's roll infinite and its 20th LOCAL_POSITION_NED's vz NaN; returns
    how many messages it holds."""
    conn = mavutil.mavlink_connection(str(path))
    records, seen = [], {"ATTITUDE": 0, "LOCAL_POSITION_NED": 0}
    enc = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    while (m := conn.recv_msg()) is not None:
        buf = bytes(m.get_msgbuf())
        kind = m.get_type()
        if kind in seen:
            seen[kind] += 1
            if seen[kind] == 20:
                fields = {k: getattr(m, k) for k in m.get_fieldnames()}
                if kind == "ATTITUDE":
                    fields["roll"] = math.inf
                    buf = bytes(mavlink.MAVLink_attitude_message(**fields).pack(enc))
                else:
                    fields["vz"] = math.nan
                    buf = bytes(mavlink.MAVLink_local_position_ned_message(**fields).pack(enc))
        records.append(struct.pack(">Q", int(m._timestamp * 1e6)) + buf)
    conn.close()
    path.write_bytes(b"".join(records))
    return len(records)


def test_a_replay_through_a_spoilt_attitude_and_position_runs_to_its_end(tmp_path: Path) -> None:
    write_captures("crossing", tmp_path, 2.0)
    clean = recording_config(tmp_path, tmp_path / "clean.jsonl")
    assert run_replay(clean) == 0
    assert _spoil_tlog(tmp_path / "autopilot.tlog") > 100
    spoilt = recording_config(tmp_path, tmp_path / "spoilt.jsonl")
    assert run_replay(spoilt) == 0
    rows = [json.loads(line) for line in (tmp_path / "spoilt.jsonl").read_text().splitlines()]
    expected = [json.loads(line) for line in (tmp_path / "clean.jsonl").read_text().splitlines()]
    assert len(rows) == len(expected) >= 18
    # one ATTITUDE of 50 a second missing changes no pose by more than its interpolation does
    assert [r["t"] for r in rows] == pytest.approx([r["t"] for r in expected], abs=1e-9)
    assert sum(r["obstacle_distance_cm"] is not None for r in rows) == sum(
        r["obstacle_distance_cm"] is not None for r in expected
    )


class _EgoWithOneBadHeading:
    """An ego source that breaks its protocol once: a NaN heading at one instant instead of None."""

    epoch = 0
    available = True

    def __init__(self, bad_from: float, bad_to: float) -> None:
        self.bad = (bad_from, bad_to)

    def _yaw(self, t: float) -> float:
        return math.nan if self.bad[0] <= t <= self.bad[1] else 0.0

    def at(self, t: float) -> EgoPose:
        return EgoPose(t, np.zeros(3), np.zeros(3), 0.0, 0.0, self._yaw(t))

    def at_many(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        n = np.size(t)
        return np.zeros((n, 3)), np.zeros(n), np.zeros(n), np.array([self._yaw(float(x)) for x in np.ravel(t)])


def test_a_nan_heading_from_the_ego_source_is_no_pose_not_a_failed_cycle() -> None:
    pipeline = pipeline_for(Config())
    ego = _EgoWithOneBadHeading(0.45, 0.55)
    xyz = np.array([[20.0, 0.0, 0.0], [20.3, 0.4, 0.0], [20.1, -0.4, 0.0]])
    for k in range(8):
        frame = RadarFrame(0.1 * k, k + 1, xyz, np.zeros(3), np.full(3, 20.0), np.full(3, 5.0))
        out = pipeline.step(0.1 * k + 0.01, None, [frame], ego)  # raised ValueError (data must be finite) at k = 5
        assert np.isfinite(out.clear_to_m).all()
    assert pipeline.skipped_no_pose == 1
