"""The pieces bench/soak.py stands on: the scene chain keeps the sensor a sensor across a scene switch, and the /proc
readers read what they claim. The soak's own figures are timed and are not tested here."""

from __future__ import annotations

import os
import socket

import pytest

from bench._proc import ProcSample, rss_windows, sample, summarise, udp_socket
from bench._scene_chain import SceneChain
from bench.soak import soak_scenes
from drivers.vlp16.packet import PACKET_PERIOD_US


def test_a_scene_switch_changes_the_world_but_not_the_sensor_clock_or_rotor() -> None:
    chain = SceneChain(["random:1", "random:2"], 2.0)
    assert chain.at(1.5) == (0, 1.5) and chain.at(2.5) == (1, 0.5) and chain.at(99.0)[0] == 1
    last = list(chain.lidar_model(0).packets(1.98, 2.0))[-1]
    first = next(iter(chain.lidar_model(1).packets(0.0, 0.01)))
    # the next packet on the sensor's clock: no jump back to the start of the hour, no gap
    assert 0 < first.timestamp_us - last.timestamp_us <= PACKET_PERIOD_US + 1
    # the rotor turns on by at most one packet's sweep (12 blocks at 600 rpm: 4.8 deg)
    step = (int(first.block_azimuth_cdeg[0]) - int(last.block_azimuth_cdeg[0])) % 36000
    assert 0 < step <= 480
    assert chain.own_pose(2.0).position[0] == pytest.approx(chain.scenes[1].own.pose(0.0).position[0])


def test_a_scene_chain_wants_whole_revolutions() -> None:
    with pytest.raises(ValueError, match="whole number"):
        SceneChain(["random:1"], 60.05)


def test_the_soak_ends_on_the_scene_it_started_with() -> None:
    # the end sample and the 1-minute sample then see the same harbour: a difference is what the hour added
    assert soak_scenes(60)[:3] == ["random:1", "random:2", "random:3"]
    assert soak_scenes(60)[58:] == ["random:59", "random:1"]
    assert soak_scenes(1) == ["random:1"]
    assert soak_scenes(5) == ["random:1", "random:2", "random:3", "random:4", "random:1"]


def test_summary_counts_growth_from_the_reference_minute() -> None:
    samples = [ProcSample(float(t), 100_000 + (2048 if t >= 60 else 0) + 10 * t, 10, 6) for t in range(0, 181)]
    samples[-1] = ProcSample(180.0, samples[-1].rss_kb, 11, 7)
    s = summarise(samples, 60.0)
    assert s["rss_ref_t_s"] == 60.0
    assert s["rss_growth_mb"] == pytest.approx(120 * 10 / 1024)
    assert s["rss_slope_mb_per_h"] == pytest.approx(10 * 3600 / 1024, rel=1e-6)
    assert s["rss_ref_window_min_mb"] == pytest.approx((100_000 + 2048 + 600) / 1024)  # minute 2's floor
    assert s["rss_end_window_min_mb"] == pytest.approx((100_000 + 2048 + 1210) / 1024)  # the last minute's
    assert s["rss_end_window_median_mb"] - s["rss_ref_window_median_mb"] == pytest.approx(610 / 1024)  # 61 s apart
    assert s["fds"] == {"first": 10, "last": 11, "max": 11, "min": 10, "ref": 10}
    assert s["threads"]["last"] == 7


def test_proc_readers_see_this_process_and_a_socket_queue() -> None:
    me = sample(os.getpid())
    assert me is not None and me.rss_kb > 1000 and me.threads >= 1 and me.fds >= 3
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rx, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        rx.bind(("127.0.0.1", 0))
        port = rx.getsockname()[1]
        assert udp_socket(port) == (0, 0)
        for _ in range(3):
            tx.sendto(b"x" * 100, ("127.0.0.1", port))
        queued, drops = udp_socket(port) or (0, -1)
        assert queued >= 300 and drops == 0  # the kernel counts its bookkeeping too: at least the payloads
    assert udp_socket(port) is None


def test_rss_windows_show_the_floor_and_median_of_each_part_of_the_run() -> None:
    samples = [ProcSample(60.0 + t, 100_000 + (5000 if t % 2 else 0) + 100 * t, 10, 6) for t in range(0, 601)]
    w = rss_windows(samples, 3)
    assert [(a, b) for a, b, _, _ in w] == [(60.0, 260.0), (260.0, 460.0), (460.0, 660.0)]
    assert [lo for _, _, lo, _ in w] == pytest.approx([100_000 / 1024, 120_000 / 1024, 140_000 / 1024])
