"""The live VLP-16 source on real UDP sockets (127.0.0.1), fed by packets the test sends.

The packets come from ``sweep()`` (test_vlp16_decoder), so what arrives is known exactly. Every test runs
the source in a reader thread, as the daemon does, and stops and joins it with a timeout.
"""

from __future__ import annotations

import errno
import logging
import socket
import threading
import time
from collections.abc import Callable

import numpy as np
import pytest

from drivers.frames import LidarScan
from drivers.vlp16.packet import PPS_LOCKED, encode_position_packet
from drivers.vlp16.udp_source import LidarPortError, VelodyneUdpSource
from tests.test_vlp16_decoder import MM, PERIOD_US, sweep

GPRMC = "$GPRMC,000001,A,5955.000,N,01045.000,E,001.0,090.0,010124,,*3E"
TIMEOUT_S = 10.0


def wait_until(predicate: Callable[[], bool], timeout: float = TIMEOUT_S) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()


class Reader:
    """The source's ``scans(stop)`` in a thread, collecting what it yields."""

    def __init__(self, source: VelodyneUdpSource) -> None:
        self.source = source
        self.stop = threading.Event()
        self.scans: list[LidarScan] = []
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        try:
            for scan in self.source.scans(self.stop):
                self.scans.append(scan)
        except BaseException as exc:  # surfaced by close()
            self.error = exc

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=2.0)
        assert not self.thread.is_alive(), "reader did not honour stop"
        assert not self.source.is_open
        if self.error is not None:
            raise self.error


def membership(s, cut_cdeg: int = 18000) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Revolution index of each expected return (spec azimuths; revolution 0 = before the first cut)."""
    return np.floor((s.azimuth_unwrapped_cdeg - cut_cdeg) / 36000).astype(int) + 1


# ------------------------------------------------------------------------------------------------------------
def test_live_packets_decoded_with_wrong_sizes_and_foreign_senders_dropped(sender, caplog) -> None:  # type: ignore[no-untyped-def]
    caplog.set_level(logging.INFO, logger="drivers.vlp16")
    source = VelodyneUdpSource(host="127.0.0.1", port=0, position_port=0, accept_ip="127.0.0.1", poll_s=0.02)
    source.open()
    assert source.rcvbuf_granted > 0
    assert f"receive buffer {source.rcvbuf_granted} bytes" in caplog.text
    data_port, position_port = source.bound_port, source.bound_position_port
    reader = Reader(source)
    try:
        good, foreign = sender("127.0.0.1"), sender("127.0.0.2")
        good.sendto(encode_position_packet(999_000, PPS_LOCKED, GPRMC), ("127.0.0.1", position_port))
        foreign.sendto(encode_position_packet(999_000, 0, ""), ("127.0.0.1", position_port))
        s = sweep(200, start_azimuth_cdeg=104)
        for i, payload in enumerate(s.payloads):
            if i % 50 == 10:
                good.sendto(payload[:1205], ("127.0.0.1", data_port))  # truncated
                good.sendto(payload + b"\0", ("127.0.0.1", data_port))  # one byte too many
                good.sendto(payload * 2, ("127.0.0.1", data_port))  # two merged
                foreign.sendto(payload, ("127.0.0.1", data_port))  # another Velodyne on the network
            good.sendto(payload, ("127.0.0.1", data_port))
        # Three revolutions close on their cut; the fourth is flushed when the stream stalls (0.3 s).
        assert wait_until(lambda: len(reader.scans) == 4)
    finally:
        reader.close()
    scans = reader.scans
    expected = np.bincount(membership(s))
    assert [sc.n_points for sc in scans] == expected.tolist() == [13018, 26182, 26182, 4436]
    assert [sc.packets for sc in scans] == [38, 75, 75, 12]
    sel = membership(s) == 1
    i, j = np.argsort(scans[1].t), np.argsort(s.device_time[sel])
    np.testing.assert_allclose(scans[1].xyz[i], s.xyz_sensor_frd[sel][j], atol=MM)
    # Device clock spacing survives the trip: point times differ exactly as the firings do.
    np.testing.assert_allclose(np.diff(scans[1].t[i]), np.diff(s.device_time[sel][j]), atol=1e-6)
    st = source.stats
    assert (st.packets, st.wrong_size, st.foreign_source, st.missing, st.scans) == (200, 12, 5, 0, 4)
    assert st.bytes == 200 * 1206 and st.last_foreign_ip == "127.0.0.2"
    assert (st.position_packets, st.pps_status, st.nmea) == (1, PPS_LOCKED, GPRMC)
    assert all(sc.pps_locked for sc in scans)


def test_burst_of_two_revolutions_at_twice_the_sensor_rate_loses_nothing(sender) -> None:  # type: ignore[no-untyped-def]
    source = VelodyneUdpSource(host="127.0.0.1", port=0, position_port=None, poll_s=0.02)
    source.open()
    port = source.bound_port
    reader = Reader(source)
    try:
        # From 181 deg, just past the cut: packets 0-74 and 75-149 are whole revolutions, 150 starts a third.
        s = sweep(151, start_azimuth_cdeg=18100)
        out = sender("127.0.0.1")
        interval = PERIOD_US * 1e-6 / 2  # 1507 packets/s
        start = time.perf_counter()
        for n, payload in enumerate(s.payloads):
            delay = start + n * interval - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            out.sendto(payload, ("127.0.0.1", port))
        assert wait_until(lambda: len(reader.scans) >= 3)
    finally:
        reader.close()
    full = reader.scans[:2]
    rev = membership(s)
    assert [sc.packets for sc in full] == [75, 75]
    assert [sc.packets_missing for sc in full] == [0, 0]
    assert [sc.n_points for sc in full] == [int((rev == 1).sum()), int((rev == 2).sum())] == [26110, 26182]
    assert source.stats.packets == 151 and source.stats.missing == 0


def test_a_multicast_group_is_joined_and_only_its_packets_are_taken(sender) -> None:  # type: ignore[no-untyped-def]
    # Newer firmware can send to a multicast group; bound to the group without joining it, the socket got nothing.
    group = "239.255.77.16"
    source = VelodyneUdpSource(host=group, port=0, position_port=None, poll_s=0.02)
    source.open()
    port = source.bound_port
    reader = Reader(source)
    try:
        out = sender("127.0.0.1")
        out.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
        out.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
        s = sweep(80, start_azimuth_cdeg=18100)  # one revolution (packets 0-74) and the start of the next
        for n, payload in enumerate(s.payloads):
            out.sendto(payload, (group, port))
            if n == 40:
                out.sendto(payload, ("127.0.0.1", port))  # unicast to the same port: not the group, not taken
            if n % 20 == 19:
                time.sleep(0.01)  # paced, so the loopback queue never overflows on a busy machine
        assert wait_until(lambda: source.stats.packets >= 80 and len(reader.scans) >= 1)
    finally:
        reader.close()
    assert source.stats.packets == 80 and source.stats.missing == 0
    assert reader.scans[0].packets == 75 and reader.scans[0].n_points == int((membership(s) == 1).sum())


def test_data_port_in_use_is_a_clear_error_naming_the_port() -> None:
    blocker = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    blocker.bind(("127.0.0.1", 0))
    port = blocker.getsockname()[1]
    try:
        source = VelodyneUdpSource(host="127.0.0.1", port=port, position_port=None)
        with pytest.raises(LidarPortError, match=rf"UDP 127\.0\.0\.1:{port} is already in use") as info:
            source.open()
        assert info.value.errno == errno.EADDRINUSE
        # The same error out of the iterator a reader thread runs (the daemon retries it).
        with pytest.raises(LidarPortError, match=str(port)):
            next(iter(source.scans(threading.Event())))
        assert not source.is_open
        # Binding all addresses collides with the blocker too.
        with pytest.raises(LidarPortError, match=rf"0\.0\.0\.0:{port}"):
            VelodyneUdpSource(host="0.0.0.0", port=port, position_port=None).open()
    finally:
        blocker.close()


def test_position_port_in_use_is_logged_and_data_still_flows(sender, caplog) -> None:  # type: ignore[no-untyped-def]
    blocker = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    blocker.bind(("127.0.0.1", 0))
    taken = blocker.getsockname()[1]
    try:
        source = VelodyneUdpSource(host="127.0.0.1", port=0, position_port=taken, poll_s=0.02)
        source.open()
        assert source.bound_position_port is None
        assert f"UDP 127.0.0.1:{taken} is already in use" in caplog.text
        reader = Reader(source)
        try:
            s = sweep(10)
            out = sender("127.0.0.1")
            for payload in s.payloads:
                out.sendto(payload, ("127.0.0.1", source.bound_port))
            assert wait_until(lambda: len(reader.scans) == 1)  # flushed by the stall
        finally:
            reader.close()
        assert reader.scans[0].n_points == len(s.device_time)
        assert source.stats.pps_name == "unknown" and not reader.scans[0].pps_locked
    finally:
        blocker.close()


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_silence_is_logged_at_most_once_per_timeout_and_listening_continues(sender, caplog) -> None:  # type: ignore[no-untyped-def]
    caplog.set_level(logging.INFO, logger="drivers.vlp16")
    clock = FakeClock()
    source = VelodyneUdpSource(
        host="127.0.0.1",
        port=0,
        position_port=None,
        accept_ip="127.0.0.1",
        silence_timeout_s=1.0,
        poll_s=0.01,
        clock=clock,
    )
    source.open()
    port = source.bound_port
    reader = Reader(source)

    def step_to(t: float) -> None:
        clock.now = t
        polls = source.polls
        assert wait_until(lambda: source.polls >= polls + 2)

    def silence_errors() -> list[str]:
        return [r.getMessage() for r in caplog.records if r.levelno == logging.ERROR and "no VLP-16 data" in r.msg]

    try:
        step_to(0.5)
        assert silence_errors() == [] and not source.stats.silent
        step_to(1.2)
        assert source.stats.silent
        (message,) = silence_errors()
        assert f"UDP 127.0.0.1:{port}" in message and "from 127.0.0.1" in message
        step_to(2.3)  # within SILENCE_REPEAT_S (30 s) of the last report: no repeat
        assert len(silence_errors()) == 1
        step_to(31.3)
        assert len(silence_errors()) == 2
        assert "for 31.3 s" in silence_errors()[1]
        # The cable comes back: data is decoded and the flag clears.
        s = sweep(3)
        out = sender("127.0.0.1")
        for payload in s.payloads:
            out.sendto(payload, ("127.0.0.1", port))
        assert wait_until(lambda: source.stats.packets == 3)
        assert wait_until(lambda: not source.stats.silent)
        assert "resumed" in caplog.text
        step_to(31.8)  # stall (0.5 s on the injected clock) flushes the partial revolution
        assert wait_until(lambda: len(reader.scans) == 1)
        assert reader.scans[0].n_points == len(s.device_time)
    finally:
        reader.close()
