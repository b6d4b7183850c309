"""The 50-vessel crowd bench/load.py runs against (no named scenario has 50): every boat in range and apart."""

from __future__ import annotations

import itertools

import numpy as np

from bench.load import crowd_scene


def test_the_crowd_has_50_vessels_in_range_and_apart_for_its_120_s() -> None:
    scene = crowd_scene()
    assert len(scene.vessels) == 50
    for t in np.arange(0.0, 120.1, 5.0):
        states = [(v, v.trajectory.state(float(t)).position.reshape(2)) for v in scene.vessels]
        for v, p in states:
            assert np.hypot(*p) + v.length / 2 < 100.0  # within the VLP-16's 100 m
            assert abs(p[0]) - v.width / 2 > 5.0  # clear of the own boat (lanes run east-west)
        for (a, pa), (b, pb) in itertools.combinations(states, 2):
            north, east = abs(pa[0] - pb[0]), abs(pa[1] - pb[1])
            assert north >= (a.width + b.width) / 2 + 1.0 or east >= (a.length + b.length) / 2 + 1.0, (a.name, b.name)


def test_a_looped_capture_carries_the_device_clock_on_across_passes(tmp_path) -> None:
    """bench/load.py --worst plays 60 s of LiDAR over again: the second pass must reach the port with the same
    returns and a device clock that went on (first stamp + one pass), not one that jumped back."""
    import queue
    import socket
    import time

    from bench._udp_senders import replay_capture
    from drivers.vlp16.packet import DATA_PACKET_DTYPE, encode_data_packet
    from drivers.vlp16.pcap import PcapWriter
    from simulator.truth import T0_UNIX

    azimuth = np.arange(12, dtype=np.int64) * 40  # cdeg per block
    distance = np.full((12, 32), 10.0)
    reflectivity = np.full((12, 32), 50, dtype=np.uint8)
    period_s = 0.001327  # a VLP-16 data packet period
    stamps_us = [3_599_999_000, 3_599_999_000 + 1327, 3_599_999_000 + 2654]  # the last pass wraps the hour
    pcap = tmp_path / "three.pcap"
    with PcapWriter(pcap) as w:
        for k, us in enumerate(stamps_us):
            w.write_udp(
                T0_UNIX + k * period_s, encode_data_packet(azimuth + k, distance, reflectivity, us % 3_600_000_000)
            )
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rx:
        rx.bind(("127.0.0.1", 0))
        rx.settimeout(5.0)
        results: queue.Queue = queue.Queue()
        # 3 packets a pass, a pass lasts 3 periods: 6 packets within 5.5 periods, at the recorded pace
        replay_capture(str(pcap), rx.getsockname()[1], 9, 1.0, time.monotonic(), results, seconds=5.5 * period_s)
        got = [rx.recv(2048) for _ in range(6)]
    assert results.get_nowait()["lidar"]["data"] == 6
    offset = DATA_PACKET_DTYPE.fields["timestamp"][1]
    stamps = [int.from_bytes(g[offset : offset + 4], "little") for g in got]
    span_us = 3 * 1327
    assert stamps[:3] == [s % 3_600_000_000 for s in stamps_us]
    assert stamps[3:] == [(s + span_us) % 3_600_000_000 for s in stamps_us]  # on across the hour's wrap
    for first, second in zip(got[:3], got[3:], strict=True):
        assert first[:offset] == second[:offset] and first[offset + 4 :] == second[offset + 4 :]
