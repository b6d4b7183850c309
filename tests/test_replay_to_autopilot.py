"""`usv-tracker replay DIR --to URL`: a recording played into a live autopilot at the recorded pace, over real loopback
MAVLink to the simulated ArduPilot. The assertions are on what the autopilot RECEIVED."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from daemon.cli import main
from daemon.demo import free_udp_port
from daemon.mavlink_env import mavlink
from daemon.replay import recording_config, run_replay
from drivers.frames import EgoPose
from simulator.autopilot import SimAutopilot

# Real sockets and threads in real time on a 2-core machine that may be busy: a missed deadline is retried once
# (a deterministic failure still fails); the assertions themselves are not loosened.
pytestmark = pytest.mark.flaky(reruns=1)

SECONDS = 4.0
# Where the live autopilot sits on its own map: far from the recording's (59.41 N 10.49 E), so that whose map a
# position came from shows.
LIVE_ORIGIN = (43.0, 5.0, 0.0)
LIVE_NORTH_M = 50.0


def live_pose(t: float) -> EgoPose:
    """The live boat lies still 50 m north of its EKF origin, heading east."""
    return EgoPose(t, np.array([LIVE_NORTH_M, 0.0, 0.0]), np.zeros(3), 0.0, 0.0, math.pi / 2)


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("to") / "run"
    assert main(["simulate", "--scene", "crossing", "--seconds", str(SECONDS), "--write", str(d)]) == 0
    # the scene's mounts as written, and AIS_VESSEL once a second as a boat's config may ask
    (d / "ais.toml").write_text((d / "usv-tracker.toml").read_text() + "\n[output]\nais_interval_s = 1.0\n")
    return d


@pytest.fixture(scope="module")
def deterministic(recording: Path) -> list[dict]:
    out = recording / "deterministic.jsonl"
    assert run_replay(recording_config(recording, out), fast=True) == 0
    return [json.loads(line) for line in out.read_text().splitlines()]


def test_the_autopilot_receives_the_deterministic_replays_bins_at_10_hz(
    recording: Path, deterministic: list[dict], tmp_path: Path
) -> None:
    port = free_udp_port()
    with SimAutopilot(f"udpin:127.0.0.1:{port}", live_pose, origin=LIVE_ORIGIN) as ap:
        out = tmp_path / "to.jsonl"
        args = ["replay", str(recording), "--to", f"udpout:127.0.0.1:{port}", "--config", str(recording / "ais.toml")]
        assert main([*args, "--tracks-out", str(out), "--quiet"]) == 0
        received = ap.obstacle_distances()
        heartbeats = ap.heartbeats()
        ais = ap.ais_vessels()
        requests = ap.interval_requests()
    sent_rows = [r for r in deterministic if r["obstacle_distance_cm"] is not None]
    assert len(sent_rows) >= 38  # 4 s of ticks, bins withheld on none but the first ticks
    assert any(min(r["obstacle_distance_cm"]) < 65535 for r in sent_rows)  # obstacles in them, not only "unknown"
    # One OBSTACLE_DISTANCE per tick that sent bins, with exactly those bins (tolerance 0 cm: the replay is
    # deterministic on the recording's clock, whatever its pace), from the companion's ids, as live.
    assert len(received) == len(sent_rows)
    for got, row in zip(received, sent_rows, strict=True):
        assert got.distances.tolist() == row["obstacle_distance_cm"], row["t"]
    assert {(m.src_system, m.src_component, m.frame, m.increment_f) for m in received} == {
        (1, 196, mavlink.MAV_FRAME_BODY_FRD, 5.0)
    }
    # at 10 Hz, the recorded pace: median spacing 100 +- 10 ms, the whole run within 15 % of 10 Hz (a busy machine
    # delays single ticks; the replay's deadlines are absolute, so the rate holds)
    times = np.array([m.host_time for m in received])
    assert np.median(np.diff(times)) == pytest.approx(0.1, abs=0.01)
    assert (len(times) - 1) / (times[-1] - times[0]) == pytest.approx(10.0, rel=0.15)
    # the replay's own tracks-out is the deterministic one: playing into an autopilot changes nothing
    assert [json.loads(line) for line in out.read_text().splitlines()] == deterministic
    # what else the live daemon sends: its heartbeat, ACTIVE once both sensors deliver
    assert heartbeats and heartbeats[-1].system_status == mavlink.MAV_STATE_ACTIVE
    assert {(h.src_system, h.src_component) for h in heartbeats} == {(1, 196)}
    # AIS_VESSEL once a second, placed on the RECORDING's map (its autopilot's origin 59.41 N 10.49 E): the tracks
    # are in the recording's world, not the live autopilot's 43 N 5 E
    assert len(ais) >= 2
    assert all(abs(v.lat_deg - 59.41) < 0.01 and abs(v.lon_deg - 10.49) < 0.02 for v in ais), ais
    # the recording's poses are used: the autopilot is not asked to stream its own
    assert requests == []


def test_live_poses_come_from_the_live_autopilot(recording: Path, tmp_path: Path) -> None:
    port = free_udp_port()
    with SimAutopilot(f"udpin:127.0.0.1:{port}", live_pose, origin=LIVE_ORIGIN, heartbeat_hz=5.0) as ap:
        out = tmp_path / "live.jsonl"
        args = ["replay", str(recording), "--to", f"udpout:127.0.0.1:{port}", "--pose", "live"]
        assert main([*args, "--tracks-out", str(out), "--quiet"]) == 0
        received = ap.obstacle_distances()
        requested = {r.msg_id for r in ap.interval_requests()}
    assert mavlink.MAVLINK_MSG_ID_ATTITUDE in requested and mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED in requested
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(received) == sum(r["obstacle_distance_cm"] is not None for r in rows) >= 38
    # every tick's own pose is the live boat's (50 m north, heading east; float32 fields: 1 mm, 0.01 deg), on the
    # live autopilot's map
    own = [r["own"] for r in rows]
    assert all(o is not None for o in own)
    assert all(abs(o["position_ne"][0] - LIVE_NORTH_M) <= 0.001 and abs(o["position_ne"][1]) <= 0.001 for o in own)
    assert all(abs(o["yaw_deg"] - 90.0) <= 0.01 for o in own)
    lat, lon = rows[-1]["world_origin_lat_lon"]
    assert (lat, lon) == pytest.approx(LIVE_ORIGIN[:2], abs=1e-6)
