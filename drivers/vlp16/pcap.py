"""Read UDP datagrams from classic pcap and pcapng captures; write classic pcap.

velodyne-decoder reads pcaps through dpkt's classic-pcap reader only, but Wireshark and dumpcap save
pcapng by default, and a capture from the boat may be either. This reader handles both formats in
both byte orders, microsecond and nanosecond (or any ``if_tsresol``) timestamps, and the link layers
seen in LiDAR captures: Ethernet (with 802.1Q tags), Linux cooked SLL/SLL2, raw IP and BSD loopback.
Only IPv4/UDP is returned; everything else is counted, never raised: a capture with a torn last record
or a stray fragment still gives all its good packets. A block too short for its own fields is counted and
skipped; a length no capture tool writes (a corrupt file) stops the reading there, the packets before it kept.
"""

from __future__ import annotations

import logging
import math
import os
import socket
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import BinaryIO, NamedTuple

log = logging.getLogger(__name__)

PCAP_MAGIC_US = 0xA1B2C3D4
PCAP_MAGIC_NS = 0xA1B23C4D
PCAPNG_SHB = 0x0A0D0D0A
PCAPNG_BYTE_ORDER_MAGIC = 0x1A2B3C4D

LINKTYPE_NULL = 0  # BSD loopback, 4-byte address family in the writer's byte order
LINKTYPE_ETHERNET = 1
LINKTYPE_RAW = 101
LINKTYPE_LOOP = 108  # OpenBSD loopback, family in network byte order
LINKTYPE_LINUX_SLL = 113
LINKTYPE_IPV4 = 228
LINKTYPE_LINUX_SLL2 = 276

ETHERTYPE_IPV4 = 0x0800
ETHERTYPE_IPV6 = 0x86DD
_VLAN_ETHERTYPES = (0x8100, 0x88A8, 0x9100)
IPPROTO_UDP = 17

# pcapng block types that carry packets.
_EPB = 0x00000006
_SPB = 0x00000003
_OPB = 0x00000002  # obsolete "packet block", still written by old tools
_IDB = 0x00000001

# libpcap's MAXIMUM_SNAPLEN: no capture tool records more of one packet. A VLP-16 packet is 1206 bytes of payload
# (1248 on the wire), so a record beyond this is a corrupt length, and it must not become a read of up to 4 GiB.
MAX_PACKET_LEN = 262_144
# One such packet in a pcapng block: block header and trailer, the enhanced packet block's fields, its options.
MAX_BLOCK_LEN = MAX_PACKET_LEN + 4096
_MIN_SHB_LEN = 28  # type, length, byte-order magic, version, section length, trailing length
_EPB_FIELDS = struct.calcsize("IIIII")  # interface, timestamp high and low, captured and original length
_IDB_FIELDS = struct.calcsize("HHI")  # link type, reserved, snap length
_SPB_FIELDS = struct.calcsize("I")  # original length
_UNKNOWN_LINK = -1  # an interface whose description block was too short: its packets count as not IPv4


class NotAPcapError(ValueError):
    """The file is not a pcap or pcapng capture (or is empty)."""


class UdpDatagram(NamedTuple):
    timestamp_s: float  # capture time, Unix seconds
    src_ip: str
    dst_port: int
    payload: bytes
    src_port: int = 0  # last, with a default: datagrams built with the first four fields keep working


@dataclass
class PcapStats:
    """What the reader saw, for the summary a user needs when a capture decodes to nothing."""

    records: int = 0  # link-layer frames in the file
    udp: int = 0  # IPv4/UDP datagrams (before the port filter)
    yielded: int = 0  # datagrams that passed the port filter
    other_port: int = 0
    not_ipv4: int = 0  # ARP, IPv6, unknown link types...
    not_udp: int = 0  # TCP, ICMP...
    fragments: int = 0  # IPv4 fragments (VLP-16 packets never fragment; reassembly is not attempted)
    truncated: int = 0  # record shorter than its headers say (snaplen or a torn file)
    no_timestamp: int = 0  # pcapng simple packet blocks
    bad_blocks: int = 0  # pcapng blocks too short for their own fields, or whose packet overruns them (skipped)
    torn_tail: bool = False  # reading stopped inside a record: the file ends there, or a length is corrupt
    stop_reason: str = ""  # why, when torn_tail


def _format(head: bytes) -> str:
    if len(head) < 4:
        return "empty" if not head else "short"
    if head[:2] == b"\x1f\x8b":
        return "gzip"
    (le,) = struct.unpack("<I", head[:4])
    (be,) = struct.unpack(">I", head[:4])
    if le == PCAPNG_SHB:
        return "pcapng"
    for order, value in (("<", le), (">", be)):
        if value == PCAP_MAGIC_US:
            return "pcap-us" + order
        if value == PCAP_MAGIC_NS:
            return "pcap-ns" + order
    return "unknown"


def capture_format(path: str | os.PathLike[str]) -> str:
    """'pcap' or 'pcapng'; raises ``NotAPcapError`` otherwise."""
    with open(path, "rb") as f:
        kind = _format(f.read(4))
    if kind.startswith("pcap-"):
        return "pcap"
    if kind == "pcapng":
        return "pcapng"
    raise NotAPcapError(_not_pcap_message(path, kind))


def _not_pcap_message(path: str | os.PathLike[str], kind: str) -> str:
    if kind == "empty":
        return f"{path}: empty file, not a pcap capture"
    if kind == "gzip":
        return f"{path}: gzip-compressed; decompress it first (gunzip) -- only pcap and pcapng are read"
    return f"{path}: not a pcap or pcapng capture (unrecognised magic bytes)"


class PcapReader:
    """Iterate the IPv4/UDP datagrams of a capture, optionally only those to ``ports``.

    The file is checked when the reader is made, so a wrong file fails with ``NotAPcapError`` at once
    rather than on first iteration. Counters are in ``stats``.
    """

    def __init__(self, path: str | os.PathLike[str], ports: Iterable[int] | None = None) -> None:
        self.path = os.fspath(path)
        self.ports = None if ports is None else frozenset(int(p) for p in ports)
        self.stats = PcapStats()
        with open(self.path, "rb") as f:
            self.format = _format(f.read(4))
        if not (self.format.startswith("pcap-") or self.format == "pcapng"):
            raise NotAPcapError(_not_pcap_message(self.path, self.format))
        self.link_types: set[int] = set()

    def __iter__(self) -> Iterator[UdpDatagram]:
        with open(self.path, "rb", buffering=1 << 20) as f:
            frames = self._classic(f) if self.format.startswith("pcap-") else self._pcapng(f)
            for timestamp, link_type, frame in frames:
                self.stats.records += 1
                datagram = self._udp(timestamp, link_type, frame)
                if datagram is None:
                    continue
                if self.ports is not None and datagram.dst_port not in self.ports:
                    self.stats.other_port += 1
                    continue
                self.stats.yielded += 1
                yield datagram

    def last_time(self) -> float | None:
        """Capture time of the file's last record (of any kind), None for a capture without one: where a replay
        ends, for its progress bar. Reads only the containers, not the datagrams (about 0.1 s per minute of VLP-16
        data)."""
        last = None
        with open(self.path, "rb", buffering=1 << 20) as f:
            frames = self._classic(f) if self.format.startswith("pcap-") else self._pcapng(f)
            for timestamp, _link_type, _frame in frames:
                last = timestamp
        return last

    # --- containers ------------------------------------------------------------------------------------
    def _torn(self, what: str) -> None:
        self.stats.torn_tail = True
        self.stats.stop_reason = what
        log.warning("%s: reading stopped at a %s; the packets before it are kept", self.path, what)

    def _bad_block(self, what: str) -> None:
        self.stats.bad_blocks += 1
        log.debug("%s: skipped %s", self.path, what)

    def _classic(self, f: BinaryIO) -> Iterator[tuple[float, int, bytes]]:
        head = f.read(24)
        if len(head) < 24:
            raise NotAPcapError(f"{self.path}: pcap global header is truncated")
        order = self.format[-1]
        scale = 1e-9 if self.format.startswith("pcap-ns") else 1e-6
        (network,) = struct.unpack_from(order + "I", head, 20)
        link_type = network & 0x0FFFFFFF  # the top bits may carry an FCS length
        self.link_types.add(link_type)
        record = struct.Struct(order + "IIII")
        while True:
            rh = f.read(16)
            if not rh:
                return
            if len(rh) < 16:
                self._torn("torn record header")
                return
            seconds, fraction, incl_len, _orig_len = record.unpack(rh)
            if incl_len > MAX_PACKET_LEN:
                self._torn(f"corrupt record (length {incl_len})")
                return
            frame = f.read(incl_len)
            if len(frame) < incl_len:
                self._torn("torn record")
                return
            yield seconds + fraction * scale, link_type, frame

    def _pcapng(self, f: BinaryIO) -> Iterator[tuple[float, int, bytes]]:
        order = "<"
        interfaces: list[tuple[int, int, float]] = []  # (link type, ticks per second, offset s)
        first = True
        while True:
            bh = f.read(8)
            if not bh:
                return
            if len(bh) < 8:
                self._torn("torn block header")
                return
            (block_type,) = struct.unpack("<I", bh[:4])
            if block_type == PCAPNG_SHB:
                bom = f.read(4)
                if len(bom) < 4:
                    self._torn("torn section header")
                    return
                order = "<" if struct.unpack("<I", bom)[0] == PCAPNG_BYTE_ORDER_MAGIC else ">"
                if struct.unpack(order + "I", bom)[0] != PCAPNG_BYTE_ORDER_MAGIC:
                    if first:
                        raise NotAPcapError(f"{self.path}: pcapng section header has a bad byte-order magic")
                    self._torn("corrupt section header (bad byte-order magic)")
                    return
                (length,) = struct.unpack(order + "I", bh[4:])
                if length < _MIN_SHB_LEN or length % 4 or length > MAX_BLOCK_LEN:
                    self._torn(f"corrupt section header (length {length})")
                    return
                rest = f.read(length - 12)
                if len(rest) < length - 12:
                    self._torn("torn section header")
                    return
                if rest[-4:] != bh[4:]:
                    self._torn("corrupt section header (its two length fields differ)")
                    return
                first = False
                interfaces = []  # interface ids are per section
                continue
            (block_type,) = struct.unpack(order + "I", bh[:4])
            (length,) = struct.unpack(order + "I", bh[4:])
            if length < 12 or length % 4 or length > MAX_BLOCK_LEN:
                self._torn(f"corrupt block (length {length})")
                return
            body = f.read(length - 8)
            if len(body) < length - 8:
                self._torn("torn block")
                return
            if body[-4:] != bh[4:]:
                self._torn("corrupt block (its two length fields differ)")
                return
            body = body[:-4]
            if block_type == _IDB:
                if len(body) < _IDB_FIELDS:
                    self._bad_block(f"interface description block of {len(body)} bytes")
                    interfaces.append((_UNKNOWN_LINK, 1_000_000, 0.0))  # keeps the later interfaces' ids
                else:
                    interfaces.append(self._interface(body, order))
            elif block_type in (_EPB, _OPB):
                if len(body) < _EPB_FIELDS:
                    self._bad_block(f"packet block of {len(body)} bytes")
                    continue
                if block_type == _EPB:
                    interface, ts_hi, ts_lo, cap_len, _orig = struct.unpack_from(order + "IIIII", body, 0)
                else:
                    interface, _drops, ts_hi, ts_lo, cap_len, _orig = struct.unpack_from(order + "HHIIII", body, 0)
                if cap_len > len(body) - _EPB_FIELDS:
                    self._bad_block(f"packet block whose {cap_len}-byte packet overruns it")
                    continue
                yield self._packet(interfaces, interface, ts_hi, ts_lo, body[_EPB_FIELDS : _EPB_FIELDS + cap_len])
            elif block_type == _SPB:
                if len(body) < _SPB_FIELDS:
                    self._bad_block(f"simple packet block of {len(body)} bytes")
                    continue
                self.stats.no_timestamp += 1  # no timestamp: useless for replay

    def _packet(
        self, interfaces: list[tuple[int, int, float]], interface: int, ts_hi: int, ts_lo: int, frame: bytes
    ) -> tuple[float, int, bytes]:
        if interface >= len(interfaces):
            return 0.0, -1, frame  # block refers to an undeclared interface: counted as not IPv4
        link_type, per_second, offset = interfaces[interface]
        # Whole seconds and the fraction apart: 1.7e18 ns in one float would lose the sub-microsecond part.
        seconds, fraction = divmod((ts_hi << 32) | ts_lo, per_second)
        return seconds + offset + fraction / per_second, link_type, frame

    def _interface(self, body: bytes, order: str) -> tuple[int, int, float]:
        link_type, _reserved, _snaplen = struct.unpack_from(order + "HHI", body, 0)
        self.link_types.add(link_type)
        per_second, offset = 1_000_000, 0.0
        pos = 8
        while pos + 4 <= len(body):
            code, length = struct.unpack_from(order + "HH", body, pos)
            value = body[pos + 4 : pos + 4 + length]
            if code == 0:
                break
            if code == 9 and length >= 1:  # if_tsresol
                exponent = value[0] & 0x7F
                per_second = 2**exponent if value[0] & 0x80 else 10**exponent
            elif code == 14 and length >= 8:  # if_tsoffset, seconds
                (offset,) = struct.unpack(order + "q", value[:8])
            pos += 4 + ((length + 3) & ~3)
        return link_type, per_second, float(offset)

    # --- link, network, transport ------------------------------------------------------------------------
    def _udp(self, timestamp: float, link_type: int, frame: bytes) -> UdpDatagram | None:
        ip_start = self._ip_start(link_type, frame)
        if ip_start is None:
            self.stats.not_ipv4 += 1
            return None
        if len(frame) < ip_start + 20:
            self.stats.truncated += 1
            return None
        version_ihl = frame[ip_start]
        if version_ihl >> 4 != 4:
            self.stats.not_ipv4 += 1
            return None
        ihl = (version_ihl & 0x0F) * 4
        (flags_fragment,) = struct.unpack_from("!H", frame, ip_start + 6)
        protocol = frame[ip_start + 9]
        if protocol != IPPROTO_UDP:
            self.stats.not_udp += 1
            return None
        if flags_fragment & 0x3FFF:  # more-fragments flag or a non-zero offset
            self.stats.fragments += 1
            return None
        udp_start = ip_start + ihl
        if ihl < 20 or len(frame) < udp_start + 8:
            self.stats.truncated += 1
            return None
        src_port, dst_port, udp_length = struct.unpack_from("!HHH", frame, udp_start)
        # Trust the UDP length: Ethernet pads short frames and may carry an FCS after the payload, and
        # captures taken with segmentation offload can hold a zero IPv4 total length.
        end = udp_start + udp_length
        if udp_length < 8 or end > len(frame):
            self.stats.truncated += 1
            return None
        self.stats.udp += 1
        src_ip = socket.inet_ntoa(frame[ip_start + 12 : ip_start + 16])
        return UdpDatagram(timestamp, src_ip, dst_port, frame[udp_start + 8 : end], src_port)

    @staticmethod
    def _ip_start(link_type: int, frame: bytes) -> int | None:
        if link_type == LINKTYPE_ETHERNET:
            pos = 12
            while len(frame) >= pos + 2:
                (ethertype,) = struct.unpack_from("!H", frame, pos)
                if ethertype in _VLAN_ETHERTYPES:
                    pos += 4
                    continue
                return pos + 2 if ethertype == ETHERTYPE_IPV4 else None
            return None
        if link_type == LINKTYPE_LINUX_SLL:
            return 16 if frame[14:16] == b"\x08\x00" else None
        if link_type == LINKTYPE_LINUX_SLL2:
            return 20 if frame[0:2] == b"\x08\x00" else None
        if link_type in (LINKTYPE_RAW, LINKTYPE_IPV4):
            return 0
        if link_type == LINKTYPE_NULL:
            family = frame[0:4]
            return 4 if family in (b"\x02\x00\x00\x00", b"\x00\x00\x00\x02") else None
        if link_type == LINKTYPE_LOOP:
            return 4 if frame[0:4] == b"\x00\x00\x00\x02" else None
        return None


def read_udp(path: str | os.PathLike[str], ports: Iterable[int] | None = None) -> Iterator[UdpDatagram]:
    """Shorthand for ``iter(PcapReader(path, ports))`` when the counters are not needed."""
    return iter(PcapReader(path, ports))


# --- writer --------------------------------------------------------------------------------------------------
_SRC_MAC = bytes.fromhex("607688000001")  # 60:76:88 is Velodyne's OUI
_BROADCAST_MAC = b"\xff" * 6
_HOST_MAC = bytes.fromhex("020000000001")  # locally administered


def _ipv4_checksum(header: bytes) -> int:
    total = sum(struct.unpack(f"!{len(header) // 2}H", header))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return ~total & 0xFFFF


class PcapWriter:
    """Write UDP datagrams as a classic little-endian pcap (Ethernet/IPv4/UDP) that every tool reads.

    Timestamps are microseconds by default (what velodyne-decoder, VeloView and tcpdump all expect);
    ``nanosecond=True`` writes the nanosecond variant.
    """

    def __init__(self, path: str | os.PathLike[str], nanosecond: bool = False, snaplen: int = 65535) -> None:
        self.path = os.fspath(path)
        self.nanosecond = nanosecond
        self._scale = 1_000_000_000 if nanosecond else 1_000_000
        self._f: BinaryIO | None = open(self.path, "wb")  # noqa: SIM115 -- closed by close()/__exit__
        self._ident = 0
        self.records = 0
        magic = PCAP_MAGIC_NS if nanosecond else PCAP_MAGIC_US
        self._f.write(struct.pack("<IHHiIII", magic, 2, 4, 0, 0, snaplen, LINKTYPE_ETHERNET))

    def write_frame(self, t_s: float, frame: bytes) -> None:
        """One link-layer (Ethernet) frame at Unix time ``t_s``."""
        if self._f is None:
            raise ValueError(f"{self.path}: writer is closed")
        if not math.isfinite(t_s) or t_s < 0:
            raise ValueError(f"pcap timestamp must be a finite non-negative Unix time, got {t_s}")
        seconds = math.floor(t_s)
        fraction = round((t_s - seconds) * self._scale)
        if fraction >= self._scale:
            seconds, fraction = seconds + 1, fraction - self._scale
        self._f.write(struct.pack("<IIII", seconds, fraction, len(frame), len(frame)))
        self._f.write(frame)
        self.records += 1

    def write_udp(
        self,
        t_s: float,
        payload: bytes,
        src_ip: str = "192.168.1.201",
        dst_port: int = 2368,
        src_port: int = 2368,
        dst_ip: str = "255.255.255.255",
    ) -> None:
        """One UDP datagram wrapped in Ethernet/IPv4/UDP headers (IPv4 checksum set, UDP checksum 0)."""
        if len(payload) > 65507:
            raise ValueError(f"UDP payload of {len(payload)} bytes does not fit in one IPv4 datagram")
        udp = struct.pack("!HHHH", src_port, dst_port, 8 + len(payload), 0)
        self._ident = (self._ident + 1) & 0xFFFF
        ip = struct.pack(
            "!BBHHHBBH4s4s",
            0x45,
            0,
            20 + len(udp) + len(payload),
            self._ident,
            0x4000,  # don't fragment
            64,
            IPPROTO_UDP,
            0,
            socket.inet_aton(src_ip),
            socket.inet_aton(dst_ip),
        )
        ip = ip[:10] + struct.pack("!H", _ipv4_checksum(ip)) + ip[12:]
        dst_mac = _BROADCAST_MAC if dst_ip == "255.255.255.255" else _HOST_MAC
        ethernet = dst_mac + _SRC_MAC + struct.pack("!H", ETHERTYPE_IPV4)
        self.write_frame(t_s, ethernet + ip + udp + bytes(payload))

    def flush(self) -> None:
        if self._f is not None:
            self._f.flush()

    def close(self) -> None:
        if self._f is not None:
            self._f.close()
            self._f = None

    def __enter__(self) -> PcapWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
