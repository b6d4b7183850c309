"""A disk that fails under the --tracks-out file, and output files that cannot be made at start-up: the run's record
is lost, never the autopilot's obstacles, and start-up names the path before any sensor is opened."""

from __future__ import annotations

import logging
import socket
from pathlib import Path

import numpy as np
import pytest

from daemon.autopilot import AutopilotLink
from daemon.config import Config
from daemon.demo import free_udp_port
from daemon.loop import DaemonLoop, LoopSettings, SensorInputs
from daemon.replay import recording_config, run_replay
from daemon.runner import StartupError, start_daemon
from simulator.autopilot import SimAutopilot, wait_until
from simulator.capture import write_captures
from tracker.pipeline import PerceptionOutput, PerceptionPipeline

FULL = Path("/dev/full")  # every write fails with ENOSPC, as a full SD card does
needs_dev_full = pytest.mark.skipif(not FULL.exists(), reason="/dev/full (a device whose writes fail) is Linux-only")


@needs_dev_full
def test_a_full_disk_under_the_tracks_file_keeps_the_feed_going(
    pair: tuple[AutopilotLink, SimAutopilot], caplog: pytest.LogCaptureFixture
) -> None:
    ap_link, sim = pair
    assert wait_until(lambda: ap_link.connected, 5.0)
    with FULL.open("w", encoding="utf-8", buffering=1) as full:  # line-buffered, as `run` opens it
        loop = DaemonLoop(PerceptionPipeline(), SensorInputs(), ap_link, None, LoopSettings(), tracks_out=full)
        bins = np.full(72, 2000, dtype=np.uint16)
        with caplog.at_level(logging.ERROR, logger="daemon.loop"):
            for k in range(30):
                loop._publish(PerceptionOutput(5.0 + 0.1 * k, [], bins, lidar_fresh=True, radar_fresh=True))
        assert loop.sent == 30
        assert loop.tracks_out is None and loop.tracks_out_failed == "No space left on device"
        said = [r.getMessage() for r in caplog.records if "tracks file" in r.getMessage()]
        assert said == ["tracks file: No space left on device; no more tracks are written this run"]
        assert wait_until(lambda: len(sim.obstacle_distances()) >= 30, 5.0)
        full.close = lambda: None  # type: ignore[method-assign]  # its buffer is empty; the with would flush again


@needs_dev_full
def test_a_replay_whose_tracks_file_fills_the_disk_fails_after_the_whole_run(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    write_captures("crossing", tmp_path, 1.5)
    config = recording_config(tmp_path, FULL)
    with caplog.at_level(logging.ERROR):
        assert run_replay(config) == 2
    messages = [r.getMessage() for r in caplog.records]
    assert f"replay: the tracks file {FULL} is cut short: No space left on device" in messages


def _lidar_only(port: int, ap_port: int) -> Config:
    config = Config()
    config.lidar.source = f"udp://127.0.0.1:{port}"
    config.radar.enabled = False
    config.mavlink.url = f"udpout:127.0.0.1:{ap_port}"
    return config


def _port_is_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def test_a_tracks_file_that_cannot_be_made_stops_start_up_before_the_sensors_open(tmp_path: Path) -> None:
    port = free_udp_port()
    config = _lidar_only(port, free_udp_port())
    (tmp_path / "a_file").write_text("")
    config.output.tracks_out = str(tmp_path / "a_file" / "tracks.jsonl")  # its directory is a file
    with pytest.raises(StartupError, match=r"--tracks-out: cannot write .*a_file/tracks\.jsonl"):
        start_daemon(config)
    assert _port_is_free(port)  # the LiDAR's socket was never opened


def test_a_record_directory_that_cannot_be_made_stops_start_up(tmp_path: Path) -> None:
    port = free_udp_port()
    config = _lidar_only(port, free_udp_port())
    (tmp_path / "a_file").write_text("")
    config.output.record_dir = str(tmp_path / "a_file")
    config.output.tracks_out = str(tmp_path / "tracks.jsonl")
    with pytest.raises(StartupError, match=r"--record: cannot create .*a_file/"):
        start_daemon(config)
    assert _port_is_free(port)


def test_an_unreadable_signing_passphrase_file_stops_start_up_naming_it(tmp_path: Path) -> None:
    port = free_udp_port()
    config = _lidar_only(port, free_udp_port())
    config.mavlink.signing_passphrase_file = str(tmp_path / "missing.key")
    with pytest.raises(StartupError, match=r"signing_passphrase_file: cannot read .*missing\.key"):
        start_daemon(config)
    assert _port_is_free(port)
