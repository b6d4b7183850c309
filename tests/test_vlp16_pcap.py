"""pcap/pcapng reading and pcap writing, on the public captures and on captures built here byte by byte.

``make_synthetic_pcapng()`` builds ``tests/fixtures/vlp16_synthetic.pcapng`` (committed; a test checks
the file is exactly what this code makes). Regenerate with
``python -c "from tests.test_vlp16_pcap import write_fixture; write_fixture()"``.
"""

from __future__ import annotations

import gzip
import socket
import struct
from pathlib import Path

import dpkt
import pytest

from drivers.vlp16.packet import PPS_LOCKED, encode_position_packet
from drivers.vlp16.pcap import NotAPcapError, PcapReader, PcapWriter, capture_format, read_udp
from tests.conftest import OWN_FIXTURES
from tests.test_vlp16_decoder import sweep

FIXTURE = OWN_FIXTURES / "vlp16_synthetic.pcapng"
GPRMC = "$GPRMC,000001,A,5955.000,N,01045.000,E,001.0,090.0,010124,,*3E"
SENSOR = "192.168.1.201"


# --- frame builders (independent of the writer under test) ------------------------------------------------
def ipv4_udp(src: str, sport: int, dport: int, payload: bytes, flags_fragment: int = 0x4000, proto: int = 17) -> bytes:
    udp = struct.pack("!HHHH", sport, dport, 8 + len(payload), 0) + payload
    return (
        struct.pack(
            "!BBHHHBBH4s4s",
            0x45,
            0,
            20 + len(udp),
            7,
            flags_fragment,
            64,
            proto,
            0,
            socket.inet_aton(src),
            socket.inet_aton("255.255.255.255"),
        )
        + udp
    )


def ethernet(ip: bytes, vlan: int | None = None, ethertype: int = 0x0800) -> bytes:
    head = b"\xff" * 6 + bytes.fromhex("607688000002")
    if vlan is not None:
        head += struct.pack("!HH", 0x8100, vlan)
    return head + struct.pack("!H", ethertype) + ip


def linux_sll(ip: bytes) -> bytes:
    return struct.pack("!HHH8sH", 0, 1, 6, bytes.fromhex("6076880000020000"), 0x0800) + ip


def _block(order: str, block_type: int, body: bytes) -> bytes:
    body += b"\0" * (-len(body) % 4)
    total = 12 + len(body)
    return struct.pack(order + "II", block_type, total) + body + struct.pack(order + "I", total)


def shb(order: str) -> bytes:
    return _block(order, 0x0A0D0D0A, struct.pack(order + "IHHq", 0x1A2B3C4D, 1, 0, -1))


def idb(order: str, link_type: int, tsresol: int | None = None, tsoffset: int | None = None) -> bytes:
    options = b""
    if tsresol is not None:
        options += struct.pack(order + "HHB3x", 9, 1, tsresol)
    if tsoffset is not None:
        options += struct.pack(order + "HHq", 14, 8, tsoffset)
    if options:
        options += struct.pack(order + "HH", 0, 0)
    return _block(order, 1, struct.pack(order + "HHI", link_type, 0, 65535) + options)


def epb(order: str, interface: int, ticks: int, frame: bytes) -> bytes:
    head = struct.pack(order + "IIIII", interface, ticks >> 32, ticks & 0xFFFFFFFF, len(frame), len(frame))
    return _block(order, 6, head + frame)


def spb(order: str, frame: bytes) -> bytes:
    return _block(order, 3, struct.pack(order + "I", len(frame)) + frame)


def make_synthetic_pcapng(order: str = "<") -> bytes:
    """Eight VLP-16 data packets (sweep(8)) among the clutter a real capture holds.

    Interface 0: Ethernet, microsecond ticks. Interface 1: Linux cooked (SLL), nanosecond ticks, offset
    1 s (so its tick counts are 1 s short of Unix time).
    """
    s = sweep(8)
    out = [shb(order), idb(order, 1), idb(order, 113, tsresol=9, tsoffset=1)]

    def us(t: float) -> int:
        return round(t * 1e6)

    def ns(t: float) -> int:
        return round((t - 1.0) * 1e9)

    t0 = s.host_times[0]
    out.append(epb(order, 0, us(t0 - 0.002), ethernet(b"\0" * 28, ethertype=0x0806)))  # ARP
    for i in range(6):
        frame = ethernet(ipv4_udp(SENSOR, 2368, 2368, s.payloads[i]), vlan=5 if i == 2 else None)
        out.append(epb(order, 0, us(s.host_times[i]), frame))
        if i == 1:
            position = encode_position_packet(1_000_000 + 2000, PPS_LOCKED, GPRMC)
            out.append(epb(order, 0, us(s.host_times[i] + 0.0005), ethernet(ipv4_udp(SENSOR, 8308, 8308, position))))
            out.append(epb(order, 0, us(s.host_times[i] + 0.0006), ethernet(ipv4_udp(SENSOR, 2368, 2368, b"x" * 600))))
        if i == 3:
            tcp = ethernet(ipv4_udp("192.168.1.77", 22, 2368, b"ssh", proto=6))
            fragment = ethernet(ipv4_udp(SENSOR, 2368, 2368, s.payloads[i][:400], flags_fragment=0x2000))
            other = ethernet(ipv4_udp("192.168.1.77", 5000, 9999, b"hello"))
            out += [epb(order, 0, us(s.host_times[i] + 0.0002), f) for f in (tcp, fragment, other)]
            out.append(spb(order, ethernet(ipv4_udp(SENSOR, 2368, 2368, s.payloads[i]))))
    for i in (6, 7):
        out.append(epb(order, 1, ns(s.host_times[i]), linux_sll(ipv4_udp(SENSOR, 2368, 2368, s.payloads[i]))))
    return b"".join(out)


def write_fixture() -> None:
    FIXTURE.write_bytes(make_synthetic_pcapng())


# ------------------------------------------------------------------------------------------------------------
def test_committed_pcapng_fixture_is_what_the_generator_makes() -> None:
    assert FIXTURE.read_bytes() == make_synthetic_pcapng()
    assert FIXTURE.stat().st_size < 20_000


@pytest.mark.parametrize("order", ["<", ">"])
def test_pcapng_both_byte_orders_link_types_and_clutter(order: str, tmp_path: Path) -> None:
    path = tmp_path / "capture.pcapng"
    path.write_bytes(make_synthetic_pcapng(order))
    s = sweep(8)
    reader = PcapReader(path, ports=[2368, 8308])
    got = list(reader)
    data = [d for d in got if d.dst_port == 2368 and len(d.payload) == 1206]
    assert [d.payload for d in data] == s.payloads
    assert [d.src_ip for d in data] == [SENSOR] * 8
    for d, t in zip(data[:6], s.host_times[:6], strict=True):
        assert d.timestamp_s == pytest.approx(t, abs=0.5e-6)  # microsecond interface
    for d, t in zip(data[6:], s.host_times[6:], strict=True):
        assert d.timestamp_s == pytest.approx(t, abs=2.5e-7)  # ns interface + 1 s offset; float64 ulp 2.4e-7
    assert [len(d.payload) for d in got if len(d.payload) != 1206] == [512, 600]
    st = reader.stats
    assert (st.records, st.yielded, st.other_port) == (14, 10, 1)  # ARP, 8 data, 5 more UDP/TCP
    assert (st.not_ipv4, st.not_udp, st.fragments, st.no_timestamp, st.truncated) == (1, 1, 1, 1, 0)
    assert reader.link_types == {1, 113}
    assert capture_format(path) == "pcapng"


def test_public_captures_are_read_completely(shared_fixtures: Path) -> None:
    folder = shared_fixtures / "vlp16"
    expected = {
        "rlu_velodyne_example.pcap": (84, 0, "192.168.1.200", 1525347606.362040),
        "veloview_vlp-16-test-90deg-1-50-frames.pcap": (1902, 367, "192.168.1.200", 1415069209.556942),
        # 2019-07-30 12:00:00 UTC + the first packet's own microseconds past the hour (SOURCES.md).
        "einride_recording_converted.pcap": (1000, 0, "192.168.1.201", 1564488000.0 + 2666.163099),
    }
    for name, (n_data, n_position, src, first_t) in expected.items():
        reader = PcapReader(folder / name)
        got = list(reader)
        data = [d for d in got if d.dst_port == 2368 and len(d.payload) == 1206]
        position = [d for d in got if d.dst_port == 8308 and len(d.payload) == 512]
        assert (len(data), len(position), len(got)) == (n_data, n_position, n_data + n_position), name
        assert {d.src_ip for d in got} == {src}
        assert got[0].timestamp_s == pytest.approx(first_t, abs=1e-6), name
        assert not reader.stats.torn_tail and reader.link_types == {1}


def test_writer_output_is_read_back_by_dpkt_and_by_the_reader(tmp_path: Path) -> None:
    s = sweep(3)
    position = encode_position_packet(1_000_500, 0)
    path = tmp_path / "out.pcap"
    with PcapWriter(path) as w:
        for t, p in zip(s.host_times, s.payloads, strict=True):
            w.write_udp(t, p, "192.168.1.201", 2368, 2368)
        w.write_udp(1_704_067_201.9999996, position, "192.168.1.201", 8308, 8308)  # rounds up to next second
    # dpkt is an independent implementation (velodyne-decoder reads pcaps through it).
    with open(path, "rb") as f:
        records = list(dpkt.pcap.Reader(f))
    assert len(records) == 4
    for (ts, buf), t, p in zip(records, s.host_times, s.payloads, strict=False):
        ip = dpkt.ethernet.Ethernet(buf).data
        assert ts == pytest.approx(t, abs=0.5e-6)
        assert (socket.inet_ntoa(ip.src), ip.data.dport, bytes(ip.data.data)) == ("192.168.1.201", 2368, p)
        header = bytes(buf[14:34])
        assert sum(struct.unpack("!10H", header)) % 0xFFFF == 0  # valid IPv4 header checksum
    assert records[3][0] == pytest.approx(1_704_067_202.0, abs=1e-9)
    got = list(read_udp(path))
    assert [d.payload for d in got] == [*s.payloads, position]
    assert [d.dst_port for d in got] == [2368, 2368, 2368, 8308]


def test_nanosecond_writer_and_big_endian_classic_pcap(tmp_path: Path) -> None:
    path = tmp_path / "ns.pcap"
    with PcapWriter(path, nanosecond=True) as w:
        w.write_udp(1_700_000_000.123456789, b"abc", "10.0.0.1", 2368, 1234)
    (d,) = list(PcapReader(path))
    assert d.timestamp_s == pytest.approx(1_700_000_000.123456789, abs=2.5e-7)
    assert (d.src_ip, d.dst_port, d.payload) == ("10.0.0.1", 2368, b"abc")

    # Big-endian microsecond pcap, as written on a big-endian host, raw-IP link type (101).
    frame = ipv4_udp("10.0.0.2", 2368, 2368, b"xyz")
    big = struct.pack(">IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 101)
    big += struct.pack(">IIII", 1_700_000_001, 250_000, len(frame), len(frame)) + frame
    path = tmp_path / "big.pcap"
    path.write_bytes(big)
    (d,) = list(PcapReader(path))
    assert (d.timestamp_s, d.src_ip, d.payload) == (1_700_000_001.25, "10.0.0.2", b"xyz")


def test_torn_last_record_keeps_the_packets_before_it(tmp_path: Path) -> None:
    s = sweep(4)
    path = tmp_path / "torn.pcap"
    with PcapWriter(path) as w:
        for t, p in zip(s.host_times, s.payloads, strict=True):
            w.write_udp(t, p)
    path.write_bytes(path.read_bytes()[:-500])
    reader = PcapReader(path)
    assert [d.payload for d in reader] == s.payloads[:3]
    assert reader.stats.torn_tail

    ng = tmp_path / "torn.pcapng"
    ng.write_bytes(make_synthetic_pcapng()[:-700])
    reader = PcapReader(ng, ports=[2368])
    assert len([d for d in reader if len(d.payload) == 1206]) == 7
    assert reader.stats.torn_tail


def test_files_that_are_not_captures_raise_a_clear_error(tmp_path: Path) -> None:
    text = tmp_path / "notes.txt"
    text.write_text("VLP-16 notes\n")
    with pytest.raises(NotAPcapError, match=r"notes\.txt: not a pcap or pcapng"):
        PcapReader(text)
    empty = tmp_path / "empty.pcap"
    empty.write_bytes(b"")
    with pytest.raises(NotAPcapError, match="empty file"):
        PcapReader(empty)
    zipped = tmp_path / "run.pcap.gz"
    zipped.write_bytes(gzip.compress(make_synthetic_pcapng()))
    with pytest.raises(NotAPcapError, match="gunzip"):
        capture_format(zipped)
    short = tmp_path / "short.pcap"
    short.write_bytes(struct.pack("<I", 0xA1B2C3D4) + b"\0" * 10)
    with pytest.raises(NotAPcapError, match="truncated"):
        list(PcapReader(short))


def test_last_time_is_the_last_record_of_either_container(tmp_path: Path) -> None:
    s = sweep(4)
    path = tmp_path / "end.pcap"
    with PcapWriter(path) as w:
        for t, p in zip(s.host_times, s.payloads, strict=True):
            w.write_udp(t, p)
        w.write_udp(s.host_times[-1] + 0.25, encode_position_packet(0, 0), dst_port=8308, src_port=8308)
    assert PcapReader(path, ports=[2368]).last_time() == pytest.approx(s.host_times[-1] + 0.25, abs=0.5e-6)
    ng = tmp_path / "end.pcapng"
    ng.write_bytes(make_synthetic_pcapng())
    # its last record: the eighth data packet, on the nanosecond interface with the 1 s offset
    assert PcapReader(ng).last_time() == pytest.approx(sweep(8).host_times[7], abs=2.5e-7)
    empty = tmp_path / "empty.pcap"
    with PcapWriter(empty):
        pass
    assert PcapReader(empty).last_time() is None
