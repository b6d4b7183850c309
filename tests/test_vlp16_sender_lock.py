"""The live VLP-16 source locks onto one sender: real UDP sockets on 127.0.0.1, senders bound to 127.0.0.2/.3.

Every Velodyne sends to port 2368; the field found a second LiDAR-like source mixed into the revolutions. Here two
senders share the port and the assertions are on exact counts and on the points: every decoded point must be one the
locked sender sent (``sweep()`` knows them to the millimetre), none of the other's.

Timing: packets are paced at the sensor's 753.5/s (pairs interleaved), but nothing asserted depends on the pace or
on when the reader wakes: the lock judges cadence on the sensors' own clocks (the stamps in the packets), loopback
keeps each socket pair's order, and the points are compared as one set over all revolutions, so a partial revolution
flushed because the sending thread was descheduled for > 0.3 s changes nothing. The one assumption is that the
socket buffer holds a burst (the source asks for 4 MB; 400 datagrams need about 1 MB). The lock-moving test steps an
injected clock instead of waiting for real seconds.
"""

from __future__ import annotations

import logging
import struct
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from daemon.recorder import Recorder
from drivers.frames import LidarScan
from drivers.vlp16.packet import PPS_ABSENT, PPS_LOCKED, encode_position_packet
from drivers.vlp16.pcap_source import VelodynePcapSource
from drivers.vlp16.udp_source import VelodyneUdpSource
from tests.test_vlp16_decoder import MM, PERIOD_US, Sweep, sweep
from tests.test_vlp16_udp import GPRMC, FakeClock, Reader, wait_until

HDL32E_PERIOD_US = 552.96  # spec section 11


def restamp(payload: bytes, timestamp_us: int) -> bytes:
    return payload[:1200] + struct.pack("<I", timestamp_us) + payload[1204:]


def paced(pairs: list[tuple[Callable[[bytes], object], bytes]], rate: float = 1e6 / PERIOD_US) -> None:
    """Send (send, payload) in order, ``rate`` items per second (one item: one datagram)."""
    start = time.perf_counter()
    for n, (send, payload) in enumerate(pairs):
        delay = start + n / rate - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        send(payload)


def assert_points_are(scans: list[LidarScan], expected: Sweep) -> None:
    """The revolutions together hold exactly the sweep's returns in firing order, nothing else.

    Revolutions follow each other in time, but each maps the device clock onto the host's with the offset known when
    it closed, so firing order is taken within each revolution, not across them."""
    order = [np.argsort(s.t) for s in scans]
    xyz = np.concatenate([s.xyz[o] for s, o in zip(scans, order, strict=True)])
    assert len(xyz) == len(expected.device_time)
    j = np.argsort(expected.device_time)
    np.testing.assert_allclose(xyz, expected.xyz_sensor_frd[j], atol=MM)
    # same firings: the time differences survive within a revolution
    start = 0
    for s, o in zip(scans, order, strict=True):
        n = len(o)
        np.testing.assert_allclose(np.diff(s.t[o]), np.diff(expected.device_time[j][start : start + n]), atol=1e-6)
        start += n


def live_source(**kwargs) -> VelodyneUdpSource:  # type: ignore[no-untyped-def]
    source = VelodyneUdpSource(host="127.0.0.1", port=0, position_port=0, poll_s=0.02, **kwargs)
    source.open()
    return source


# ------------------------------------------------------------------------------------------------------------
def test_two_senders_interleaved_with_the_foreign_one_first(sender, caplog, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    caplog.set_level(logging.INFO, logger="drivers.vlp16")
    source = live_source()
    data_port, position_port = source.bound_port, source.bound_position_port
    assert position_port is not None
    recorder = Recorder(tmp_path)
    recorder.attach(source, None, None)
    reader = Reader(source)
    try:
        foreign, vlp = sender("127.0.0.3"), sender("127.0.0.2")
        # Position packets first: the foreign sensor claims a GPS lock, ours has none. Only ours may count.
        foreign.sendto(encode_position_packet(999_000, PPS_LOCKED, GPRMC), ("127.0.0.1", position_port))
        vlp.sendto(encode_position_packet(999_000, PPS_ABSENT, ""), ("127.0.0.1", position_port))
        ours = sweep(200, start_azimuth_cdeg=104)
        # A VLP-32C (product 0x28) with another scene, at its own cadence, sending first in every pair.
        theirs = sweep(200, start_azimuth_cdeg=20_000, start_us=7_000_000, product_id=0x28)
        items = []
        for k in range(200):
            items.append((lambda p: foreign.sendto(p, ("127.0.0.1", data_port)), theirs.payloads[k]))
            items.append((lambda p: vlp.sendto(p, ("127.0.0.1", data_port)), ours.payloads[k]))
        paced(items, rate=2e6 / PERIOD_US)
        assert wait_until(lambda: sum(s.packets for s in reader.scans) == 200)
    finally:
        reader.close()
        recorder.close()
    st = source.stats
    assert st.sender == f"127.0.0.2:{vlp.getsockname()[1]}"
    assert (st.packets, st.wrong_size, st.malformed, st.missing) == (200, 0, 0, 0)
    assert st.foreign_source == 200 + 1  # every foreign data packet and its position packet
    assert source.lock.pending == 0
    assert (st.other_senders, st.lock_moves, st.last_foreign_ip) == (1, 0, "127.0.0.3")
    assert (st.position_packets, st.pps_name, st.nmea) == (1, "absent", "")
    assert not any(s.pps_locked for s in reader.scans)
    assert_points_are(reader.scans, ours)
    assert caplog.text.count(f"locked onto 127.0.0.2:{vlp.getsockname()[1]}") == 1
    assert caplog.text.count(f"another sender, 127.0.0.3:{foreign.getsockname()[1]}, is ignored") == 1

    # The recording holds both senders with their ports; its replay locks onto the same one, with the same result.
    replay = VelodynePcapSource(tmp_path / "lidar.pcap", speed=None)
    scans = list(replay.scans())
    rs = replay.stats
    assert (rs.sender, rs.packets, rs.foreign_source, rs.position_packets) == (st.sender, 200, 201, 1)
    assert_points_are(scans, ours)


def test_a_foreign_sender_switching_to_the_vlp16_product_byte_after_the_lock_stays_dropped(sender) -> None:  # type: ignore[no-untyped-def]
    source = live_source()
    port = source.bound_port
    reader = Reader(source)
    try:
        foreign, vlp = sender("127.0.0.3"), sender("127.0.0.2")
        ours = sweep(150, start_azimuth_cdeg=104)
        before = sweep(20, start_azimuth_cdeg=20_000, start_us=7_000_000, product_id=0x28)
        # After the lock: perfect VLP-16 packets (product 0x22, VLP-16 cadence) of another scene.
        after = sweep(130, start_azimuth_cdeg=20_000, start_us=9_000_000)
        items = []
        for k in range(20):
            items.append((lambda p: foreign.sendto(p, ("127.0.0.1", port)), before.payloads[k]))
            items.append((lambda p: vlp.sendto(p, ("127.0.0.1", port)), ours.payloads[k]))
        paced(items, rate=2e6 / PERIOD_US)
        assert wait_until(lambda: source.lock.locked)
        items = []
        for k in range(130):
            items.append((lambda p: foreign.sendto(p, ("127.0.0.1", port)), after.payloads[k]))
            items.append((lambda p: vlp.sendto(p, ("127.0.0.1", port)), ours.payloads[20 + k]))
        paced(items, rate=2e6 / PERIOD_US)
        assert wait_until(lambda: sum(s.packets for s in reader.scans) == 150)
    finally:
        reader.close()
    st = source.stats
    assert st.sender == f"127.0.0.2:{vlp.getsockname()[1]}"
    assert (st.packets, st.foreign_source, st.other_senders, st.lock_moves) == (150, 150, 1, 0)
    assert_points_are(reader.scans, ours)


def test_senders_of_other_velodyne_packets_never_take_the_lock(sender, caplog) -> None:  # type: ignore[no-untyped-def]
    caplog.set_level(logging.INFO, logger="drivers.vlp16")
    source = live_source()
    port = source.bound_port
    reader = Reader(source)
    try:
        hdl, vlp32, noise = sender("127.0.0.2"), sender("127.0.0.3"), sender("127.0.0.1")
        # An HDL-32E: the product byte 0x21 that early VLP-16 firmware also sends (so it passes that check), but a
        # packet every 552.96 us of its clock, not 1327.104. A VLP-32C: VLP-16-like cadence, product 0x28.
        hdl_packets = [
            restamp(p, 5_000_000 + round(k * HDL32E_PERIOD_US))
            for k, p in enumerate(sweep(150, product_id=0x21).payloads)
        ]
        vlp32_packets = sweep(150, start_us=8_000_000, product_id=0x28).payloads
        # 1206 bytes of something else: flags wrong.
        junk = [bytes([k % 256]) * 1206 for k in range(20)]
        items = []
        for k in range(150):
            items.append((lambda p: hdl.sendto(p, ("127.0.0.1", port)), hdl_packets[k]))
            items.append((lambda p: vlp32.sendto(p, ("127.0.0.1", port)), vlp32_packets[k]))
            if k < 20:
                items.append((lambda p: noise.sendto(p, ("127.0.0.1", port)), junk[k]))
        paced(items, rate=2e6 / PERIOD_US)
        # Each HDL-32E packet ends the streak of the one before and starts its own: the last one is held.
        assert wait_until(lambda: source.stats.foreign_source == 150 + 150 + 20 - 1)
        time.sleep(0.2)  # the reader has read everything (the count above); nothing may turn up late
    finally:
        reader.close()
    st = source.stats
    assert (st.sender, st.packets, st.foreign_source, source.lock.pending) == ("", 0, 319, 1)
    assert (st.scans, st.other_senders) == (0, 0)
    assert reader.scans == []
    assert "locked onto" not in caplog.text


def test_the_lock_moves_when_its_sender_falls_silent(sender, caplog) -> None:  # type: ignore[no-untyped-def]
    caplog.set_level(logging.INFO, logger="drivers.vlp16")
    clock = FakeClock()
    source = live_source(clock=clock, lock_timeout_s=2.0, silence_timeout_s=10.0)
    port = source.bound_port
    reader = Reader(source)

    def step_to(t: float) -> None:
        clock.now = t
        polls = source.polls
        assert wait_until(lambda: source.polls >= polls + 2)

    def send(sock, payloads) -> None:  # type: ignore[no-untyped-def]
        for p in payloads:
            sock.sendto(p, ("127.0.0.1", port))

    try:
        a, b = sender("127.0.0.2"), sender("127.0.0.3")
        a_name, b_name = f"127.0.0.2:{a.getsockname()[1]}", f"127.0.0.3:{b.getsockname()[1]}"
        first = sweep(30, start_azimuth_cdeg=104)
        second = sweep(30, start_azimuth_cdeg=20_000, start_us=9_000_000)
        send(a, first.payloads[:20])  # at t = 0
        assert wait_until(lambda: source.stats.packets == 20)
        assert source.stats.sender == a_name
        step_to(1.0)  # A silent for 1 s: the lock holds, B is dropped
        send(b, second.payloads[:10])
        assert wait_until(lambda: source.stats.foreign_source == 10)
        assert source.stats.sender == a_name
        step_to(2.5)  # A silent for 2.5 s > 2 s: released at the next wake-up with the socket read empty
        assert wait_until(lambda: source.stats.sender == "")
        send(b, second.payloads[10:30])  # all of it taken: the 5 that won the lock are not lost
        assert wait_until(lambda: source.stats.packets == 40)
        assert source.stats.sender == b_name
        send(a, first.payloads[20:30])  # A is back, but B has the lock now
        assert wait_until(lambda: source.stats.foreign_source == 20)
        step_to(3.0)  # B's partial revolution is flushed by the stall (0.3 s on the injected clock)
        assert wait_until(lambda: len(reader.scans) == 2)
    finally:
        reader.close()
    st = source.stats
    assert (st.packets, st.foreign_source, st.lock_moves, st.sender) == (40, 20, 1, b_name)
    a_scan, b_scan = reader.scans
    assert (a_scan.packets, b_scan.packets) == (20, 20)
    assert_points_are([a_scan], sweep(20, start_azimuth_cdeg=104))
    b_expected = second.device_time
    keep = second.packet >= 10
    assert len(b_scan.t) == int(keep.sum())
    i, j = np.argsort(b_scan.t), np.argsort(b_expected[keep])
    np.testing.assert_allclose(b_scan.xyz[i], second.xyz_sensor_frd[keep][j], atol=MM)
    assert f"{a_name} silent for 2.5 s: lock released" in caplog.text
    assert f"lock moved from {a_name} to {b_name}" in caplog.text


def test_a_configured_accept_ip_wins_and_never_moves(sender) -> None:  # type: ignore[no-untyped-def]
    # A lock timeout of 0.2 s, so that a release would happen within the test if accept_ip allowed one.
    source = live_source(accept_ip="127.0.0.3", lock_timeout_s=0.2)
    port = source.bound_port
    reader = Reader(source)
    try:
        a, b = sender("127.0.0.2"), sender("127.0.0.3")
        first = sweep(40, start_azimuth_cdeg=104)
        second = sweep(40, start_azimuth_cdeg=20_000, start_us=9_000_000, product_id=0x28)  # content does not matter
        for p in first.payloads[:20]:  # A would qualify first
            a.sendto(p, ("127.0.0.1", port))
        for p in second.payloads:
            b.sendto(p, ("127.0.0.1", port))
        assert wait_until(lambda: source.stats.packets == 40 and source.stats.foreign_source == 20)
        time.sleep(0.6)  # B silent for three lock timeouts
        for p in first.payloads[20:]:
            a.sendto(p, ("127.0.0.1", port))
        assert wait_until(lambda: source.stats.foreign_source == 40)
    finally:
        reader.close()
    st = source.stats
    assert (st.sender, st.packets, st.foreign_source, st.lock_moves) == ("127.0.0.3", 40, 40, 0)
    assert source.lock.locked


def test_drops_are_summed_up_once_a_minute_not_logged_per_packet(sender, caplog) -> None:  # type: ignore[no-untyped-def]
    caplog.set_level(logging.INFO, logger="drivers.vlp16")
    clock = FakeClock()
    # lock timeout and silence beyond the test's minute: only the summary is under test
    source = live_source(clock=clock, lock_timeout_s=1000.0, silence_timeout_s=1000.0)
    port = source.bound_port
    reader = Reader(source)

    def step_to(t: float) -> None:
        clock.now = t
        polls = source.polls
        assert wait_until(lambda: source.polls >= polls + 2)

    def summaries() -> list[str]:
        return [r.getMessage() for r in caplog.records if "datagrams from other senders dropped" in r.getMessage()]

    try:
        a, b = sender("127.0.0.2"), sender("127.0.0.3")
        for p in sweep(10).payloads:
            a.sendto(p, ("127.0.0.1", port))
        assert wait_until(lambda: source.stats.packets == 10)
        for p in sweep(7, start_us=9_000_000).payloads:
            b.sendto(p, ("127.0.0.1", port))
        assert wait_until(lambda: source.stats.foreign_source == 7)
        step_to(59.0)
        assert summaries() == []
        step_to(61.0)
        step_to(125.0)  # nothing dropped in the second minute: nothing to say
    finally:
        reader.close()
    a_name, b_name = f"127.0.0.2:{a.getsockname()[1]}", f"127.0.0.3:{b.getsockname()[1]}"
    assert summaries() == [
        f"VLP-16 port {port}: 7 datagrams from other senders dropped in the last 61 s (1 sender(s), last {b_name}); "
        f"data taken from {a_name}"
    ]
    assert [r.levelname for r in caplog.records if "dropped in the last" in r.getMessage()] == ["WARNING"]
    assert caplog.text.count("is ignored") == 1
