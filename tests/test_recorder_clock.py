"""A recording's stamps run on one clock: the host's wall clock stepping back (NTP correcting a fake-hwclock boot)
mid-recording must not send the sensors back in time in the files."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from daemon.recorder import Recorder, steady_wall_clock
from drivers.vlp16.pcap import read_udp


def test_the_recording_clock_reads_the_wall_once_and_runs_on(monkeypatch: pytest.MonkeyPatch) -> None:
    start = time.time()
    clock = steady_wall_clock()
    monkeypatch.setattr(time, "time", lambda: start - 600.0)  # NTP steps the host clock back 10 minutes
    time.sleep(0.01)
    assert 0.009 < clock() - start < 1.0


def test_a_wall_clock_step_back_leaves_the_stamps_in_order(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    recorder = Recorder(tmp_path)
    recorder.attach(type("Lidar", (), {"raw_sink": None})(), None, None)
    sender = ("192.168.1.201", 2368)
    recorder.on_lidar(2368, b"\x00" * 1206, sender)
    stepped = time.time() - 600.0
    monkeypatch.setattr(time, "time", lambda: stepped)  # the host clock stepped back 10 minutes
    time.sleep(0.01)
    recorder.on_lidar(2368, b"\x00" * 1206, sender)
    recorder.close()
    stamps = [d.timestamp_s for d in read_udp(tmp_path / "lidar.pcap")]
    assert len(stamps) == 2
    assert 0.009 < stamps[1] - stamps[0] < 1.0  # the monotonic time between them, not -600 s
