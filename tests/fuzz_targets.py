"""Fuzz targets: each drives one parser with one input the way the daemon does, and checks what must hold.

Shared by the property tests (``tests/test_fuzz_*.py``, hypothesis, a few hundred inputs) and ``bench/fuzz.py``
(long runs). A target catches the errors its parser documents (the counted or named outcomes of bad input) and
lets everything else out: any other exception is a crash, and an ``AssertionError`` names a broken invariant.

Inputs are bytes: random ones, and mutations (``mutate``) of real inputs (``Target.seeds``): the project's own
fixtures, and the public captures under ``shared/fixtures`` when they are there (never copied into the repo).
"""

from __future__ import annotations

import atexit
import math
import random
import shutil
import socket
import struct
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np

from daemon.autopilot_port import MAX_REMEMBERED_TYPES
from tests.conftest import OWN_FIXTURES, REPO, SHARED_FIXTURES

# --- mutation ---------------------------------------------------------------------------------------------------
_INTERESTING_32 = (0, 1, 0x7F, 0x80, 0xFF, 0x100, 0x7FFF, 0x8000, 0xFFFF, 0x10000, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF)


def mutate(seed: bytes, rnd: random.Random, others: list[bytes] | None = None, max_len: int = 1 << 16) -> bytes:
    """One to eight havoc steps on ``seed`` (AFL's kinds): bit flips, interesting bytes and words (lengths and
    counts are where parsers break), inserts, deletes, duplicated ranges, truncation, a splice with another seed."""
    data = bytearray(seed)
    for _ in range(rnd.randint(1, 8)):
        op = rnd.randrange(9)
        n = len(data)
        if op == 0 and n:
            data[rnd.randrange(n)] ^= 1 << rnd.randrange(8)
        elif op == 1 and n:
            data[rnd.randrange(n)] = rnd.choice((0, 1, 0x7F, 0x80, 0xFF, rnd.randrange(256)))
        elif op == 2 and n >= 4:
            value = rnd.choice(_INTERESTING_32)
            if rnd.random() < 0.3:
                value = (value + rnd.randint(-4, 4)) & 0xFFFFFFFF
            data[(i := rnd.randrange(n - 3)) : i + 4] = struct.pack(rnd.choice("<>") + "I", value)
        elif op == 3 and n >= 2:
            value = rnd.choice(_INTERESTING_32) & 0xFFFF
            data[(i := rnd.randrange(n - 1)) : i + 2] = struct.pack(rnd.choice("<>") + "H", value)
        elif op == 4:
            i = rnd.randrange(n + 1)
            data[i:i] = rnd.randbytes(rnd.choice((1, 2, 4, 8, rnd.randint(1, 64))))
        elif op == 5 and n:
            i = rnd.randrange(n)
            del data[i : i + rnd.randint(1, max(1, min(64, n - i)))]
        elif op == 6 and n:
            i = rnd.randrange(n)
            chunk = data[i : i + rnd.randint(1, 256)]
            j = rnd.randrange(n + 1)
            data[j:j] = chunk
        elif op == 7 and n:
            del data[rnd.randrange(n) :]
        elif op == 8 and others:
            other = rnd.choice(others)
            cut = rnd.randrange(len(data) + 1)
            data[cut:] = other[rnd.randrange(len(other) + 1) :]
    return bytes(data[:max_len])


# --- a place for the files some parsers need -----------------------------------------------------------------
@cache
def scratch_dir() -> Path:
    """A private temporary directory (in memory where /dev/shm exists), removed at exit."""
    base = "/dev/shm" if Path("/dev/shm").is_dir() else None
    path = Path(tempfile.mkdtemp(prefix="usv-fuzz-", dir=base))
    atexit.register(shutil.rmtree, path, True)
    return path


def _shared(*parts: str) -> Path | None:
    path = SHARED_FIXTURES.joinpath(*parts)
    return path if path.exists() else None


def shared_captures_present() -> bool:
    return SHARED_FIXTURES.is_dir()


# --- targets -----------------------------------------------------------------------------------------------------
@dataclass
class Target:
    """One parser under fuzz: ``run(data, rnd)`` drives it (``rnd`` for choices besides the bytes, e.g. read
    sizes); ``own_seeds()`` are real inputs from the project's fixtures, ``public_seeds()`` from the public
    captures (empty when absent); ``max_len`` bounds a generated input."""

    name: str
    run: Callable[[bytes, random.Random], None]
    own_seeds: Callable[[], list[bytes]]
    public_seeds: Callable[[], list[bytes]] = list
    max_len: int = 1 << 16
    stateful: bool = False  # the parser keeps state across inputs (a stream), as it does in the daemon
    _cache: dict[str, list[bytes]] = field(default_factory=dict, repr=False)

    def seeds(self, which: str = "all") -> list[bytes]:
        """'own', 'public' or 'all' seeds, each cut to ``max_len``."""
        if which not in self._cache:
            if which == "all":
                found = self.seeds("own") + self.seeds("public")
            else:
                found = [s[: self.max_len] for s in (self.own_seeds() if which == "own" else self.public_seeds())]
            self._cache[which] = found
        return self._cache[which]


# ---- VLP-16 data packets: ScanAssembler, the path every data datagram takes --------------------------------------
def _pcap_payloads(path: Path, port: int, size: int, limit: int) -> list[bytes]:
    from drivers.vlp16.pcap import PcapReader

    out = []
    for d in PcapReader(path, [port]):
        if len(d.payload) == size:
            out.append(d.payload)
            if len(out) >= limit:
                break
    return out


def _in_sixes(packets: list[bytes]) -> list[bytes]:
    return [b"".join(packets[i : i + 6]) for i in range(0, len(packets), 6)]


def _vlp16_own() -> list[bytes]:
    from drivers.vlp16.packet import DATA_PACKET_SIZE, DATA_PORT

    return _in_sixes(_pcap_payloads(OWN_FIXTURES / "vlp16_synthetic.pcapng", DATA_PORT, DATA_PACKET_SIZE, 100))


def _vlp16_public() -> list[bytes]:
    from drivers.vlp16.packet import DATA_PACKET_SIZE, DATA_PORT

    out: list[bytes] = []
    for name in ("rlu_velodyne_example.pcap", "veloview_vlp-16-test-90deg-1-50-frames.pcap"):
        if (path := _shared("vlp16", name)) is not None:
            out += _in_sixes(_pcap_payloads(path, DATA_PORT, DATA_PACKET_SIZE, 60))
    return out


def run_vlp16_data(data: bytes, rnd: random.Random) -> None:
    """The bytes as a stream of 1206-byte datagrams (the last one short) into one ScanAssembler, on host times
    that mostly follow the sensor's cadence and sometimes jump (a stall, a clock reset, a reordered packet)."""
    from drivers.vlp16.decoder import ScanAssembler
    from drivers.vlp16.packet import DATA_PACKET_SIZE, PacketError, data_packet_problem, decode_data_packet

    asm = ScanAssembler(cut_angle=rnd.choice((math.pi, 0.0, None)), model=rnd.choice(("VLP16", None)))
    datagrams = [data[i : i + DATA_PACKET_SIZE] for i in range(0, len(data), DATA_PACKET_SIZE)]
    t = 1_700_000_000.0
    scans = []
    for payload in datagrams:
        t += 1.327104e-3 if rnd.random() < 0.8 else rnd.choice((-1e-3, 0.0, 0.5, -5.0, 3600.0, rnd.uniform(-2, 2)))
        if len(payload) == DATA_PACKET_SIZE:
            decode_data_packet(payload)  # the raw fields of any 1206 bytes, damaged or not
        else:
            assert data_packet_problem(payload) is not None
            try:
                decode_data_packet(payload)
            except PacketError:
                pass
            else:
                raise AssertionError(f"a {len(payload)}-byte payload decoded as a data packet")
        scans += asm.push(t, payload)
    scans += asm.flush()
    st = asm.stats
    accounted = st.packets + st.wrong_size + st.malformed + st.wrong_product + st.out_of_order
    assert accounted == len(datagrams), f"{len(datagrams)} datagrams pushed, {accounted} accounted for"
    assert st.points == sum(s.n_points for s in scans) and st.scans == len(scans)
    # each accepted packet is counted in one scan (a straddler in the one it closed), unless its batch would not decode
    assert sum(s.packets for s in scans) == st.packets or st.decode_errors, (st, [s.packets for s in scans])
    for s in scans:
        n = s.n_points
        assert s.xyz.shape == (n, 3) and s.t.shape == (n,) and s.ring.shape == (n,) and s.intensity.shape == (n,)
        assert np.isfinite(s.xyz).all() and np.isfinite(s.t).all() and math.isfinite(s.stamp)
        assert (np.linalg.norm(s.xyz, axis=1) <= 200.0 + 1.0).all(), "a point beyond the decoder's max range"
        assert 0 < s.sweep_extent <= 2 * math.pi + 1e-9 and 0 <= s.sweep_start < 2 * math.pi + 1e-9


# ---- VLP-16 position packets -----------------------------------------------------------------------------------
def _position_own() -> list[bytes]:
    from drivers.vlp16.packet import POSITION_PACKET_SIZE, POSITION_PORT, encode_position_packet

    seeds = _pcap_payloads(OWN_FIXTURES / "vlp16_synthetic.pcapng", POSITION_PORT, POSITION_PACKET_SIZE, 5)
    return [*seeds, encode_position_packet(3_599_999_999, 0, "")]


def _position_public() -> list[bytes]:
    from drivers.vlp16.packet import POSITION_PACKET_SIZE, POSITION_PORT

    if (path := _shared("vlp16", "veloview_vlp-16-test-90deg-1-50-frames.pcap")) is None:
        return []
    return _pcap_payloads(path, POSITION_PORT, POSITION_PACKET_SIZE, 20)


def run_vlp16_position(data: bytes, rnd: random.Random) -> None:
    """A position datagram: decoded, then taken by the sources' shared statistics as a live source does."""
    from drivers.vlp16.decoder import ScanAssembler
    from drivers.vlp16.packet import POSITION_PACKET_SIZE, PacketError, decode_position_packet
    from drivers.vlp16.source_stats import LidarSourceStats

    try:
        p = decode_position_packet(data)
    except PacketError:
        assert len(data) != POSITION_PACKET_SIZE
    else:
        assert 0 <= p.timestamp_us < 1 << 32 and 0 <= p.pps_status <= 255
        assert "\0" not in p.nmea and isinstance(p.pps_name, str)
    stats, asm = LidarSourceStats(), ScanAssembler()
    stats.take_position(1.0, data, asm)
    assert stats.position_packets + stats.position_wrong_size == 1
    assert asm.pps_locked == (stats.pps_status == 2)


# ---- pcap / pcapng ---------------------------------------------------------------------------------------------
def _pcap_own() -> list[bytes]:
    seeds = [(OWN_FIXTURES / "vlp16_synthetic.pcapng").read_bytes()]
    return seeds + [p.read_bytes() for p in sorted((OWN_FIXTURES / "fuzz").glob("*.pcapng"))]


def _pcap_public() -> list[bytes]:
    seeds = []
    for path in sorted(SHARED_FIXTURES.joinpath("vlp16").glob("*.pcap")) if shared_captures_present() else []:
        with path.open("rb") as f:
            seeds.append(f.read(24 + 3 * (16 + 1248) + 2 * (16 + 554)))  # global header and the first records
    return seeds


def run_pcap(data: bytes, rnd: random.Random) -> None:
    """The bytes as a capture file, read by PcapReader, then summarised as ``usv-tracker decode`` does."""
    from drivers.vlp16.inspect import NoLidarDataError, summarise_pcap
    from drivers.vlp16.pcap import MAX_PACKET_LEN, NotAPcapError, PcapReader

    path = scratch_dir() / "input.pcap"
    path.write_bytes(data)
    try:
        reader = PcapReader(path, rnd.choice((None, [2368, 8308])))
        got = list(reader)
    except NotAPcapError:
        return
    st = reader.stats
    assert st.records == st.udp + st.not_ipv4 + st.not_udp + st.fragments + st.truncated, st
    assert st.udp == st.yielded + st.other_port and len(got) == st.yielded, st
    assert st.torn_tail == bool(st.stop_reason)
    for d in got:
        assert math.isfinite(d.timestamp_s) and 0 <= d.dst_port <= 0xFFFF and len(d.payload) <= MAX_PACKET_LEN
    try:
        summary = summarise_pcap(path)
        revolutions = list(summary)
    except NoLidarDataError:
        return
    totals = summary.totals
    assert totals is not None and totals["revolutions"] == len(revolutions)
    assert totals["points"] == sum(r["points"] for r in revolutions)


# ---- AWR1843 data port ----------------------------------------------------------------------------------------
def _dat_windows(path: Path, size: int, count: int) -> list[bytes]:
    data = path.read_bytes()
    step = max(1, (len(data) - size) // max(1, count - 1))
    return [data[i : i + size] for i in range(0, max(1, len(data) - size + 1), step)][:count]


def _radar_own() -> list[bytes]:
    return [(OWN_FIXTURES / "awr1843_synthetic.dat").read_bytes()]


def _radar_public() -> list[bytes]:
    seeds = []
    for path in sorted(SHARED_FIXTURES.joinpath("awr1843").glob("*.dat")) if shared_captures_present() else []:
        seeds += _dat_windows(path, 6000, 8)
    return seeds


@cache
def _sdk2_profile() -> object:
    from drivers.awr1843.profile import load_profile

    return load_profile(REPO / "daemon" / "profiles" / "awr1843_50m.cfg")


def _frames_summary(frames: list) -> list[tuple[int, int]]:
    return [(f.frame_number, f.n_points) for f in frames]


def run_awr1843_stream(data: bytes, rnd: random.Random) -> None:
    """The bytes fed to RadarFrameParser in random read sizes (a UART hands over whatever it has), then the end of
    the stream; the same bytes in one read must give the same frames. Every byte is accounted for."""
    from drivers.awr1843.parser import HEADER_LEN, RadarFrameParser

    profile = _sdk2_profile() if rnd.random() < 0.5 else None
    chunked = RadarFrameParser(profile)
    frames = []
    pos = 0
    while pos < len(data):
        n = rnd.choice((1, 2, 7, 8, 9, 39, 40, 41, 64, 256, 4096, rnd.randint(1, 2048)))
        frames += chunked.feed(data[pos : pos + n], 0.0)
        pos += n
    frames += chunked.finish(0.0)
    whole = RadarFrameParser(profile)
    once = whole.feed(data, 0.0) + whole.finish(0.0)
    assert _frames_summary(frames) == _frames_summary(once), "frames depend on how the bytes were read"
    st = chunked.stats
    delivered = st.bytes_received - st.bytes_skipped - chunked.buffered_bytes
    assert st.bytes_received == len(data) and delivered >= 0 and delivered % 32 == 0, st
    assert delivered >= len(frames) * (HEADER_LEN + 24) and st.frames_ok == len(frames)
    for f in frames:
        n = f.n_points
        assert f.xyz.shape == (n, 3) and f.doppler.shape == f.snr.shape == f.noise.shape == (n,)
        assert np.isfinite(f.xyz).all() and (np.abs(f.xyz) <= 1000.0 + 10.0).all()
        assert (np.isnan(f.doppler) | (np.abs(f.doppler) <= 1000.0)).all()


# ---- AWR1843 CLI answers ----------------------------------------------------------------------------------------
_CLI_ANSWERS = (
    b"sensorStop\r\nIgnored: Sensor is already stopped\r\nDone\r\nmmwDemo:/>",
    b"profileCfg 0 77 7 3 39 0 0 100 1 256 7200 0 0 30\r\nDone\r\nmmwDemo:/>",
    b"cfarCfg -1 1 0 4 2 3 1 15 1\r\nError: Invalid usage of the CLI command\r\nError -1\r\nmmwDemo:/>",
    b"fancyCfg 1 2\r\n'fancyCfg' is not recognized as a CLI command\r\nmmwDemo:/>",
    b"% comment\r\nSkipped\r\nmmwDemo:/>",
    b"\r\n******************************************\r\nxWR18xx MMW Demo 03.06.00.00\r\n"
    b"******************************************\r\nmmwDemo:/>",
    b"\x00\xff\xfeprofileCfg 0 77\r\nDone\r\nmmwDemo:/> mmwDemo:/>",
)


def classify_answer(data: bytes, sent: str) -> object:
    """What ``CliSession.command`` makes of ``data`` once the prompt has come: a CliReply, or RadarConfigError."""
    from drivers.awr1843.cli import CliSession, _reply_lines

    lines = _reply_lines(data.decode("ascii", errors="replace"), sent)
    assert all(line and line == line.strip() and "\n" not in line and "\r" not in line for line in lines), lines
    return CliSession("/dev/null")._classify(sent, lines, 7)


def run_awr1843_cli(data: bytes, rnd: random.Random) -> None:
    from drivers.awr1843.cli import CliReply
    from drivers.awr1843.errors import RadarConfigError

    sent = rnd.choice(("sensorStop", "profileCfg 0 77 7 3 39 0 0 100 1 256 7200 0 0 30", "flushCfg", ""))
    try:
        reply = classify_answer(data, sent)
    except RadarConfigError as exc:
        assert exc.line == sent and exc.line_number == 7
        return
    assert isinstance(reply, CliReply) and reply.status in ("done", "ignored", "skipped", "empty", "unclassified")


# ---- TI .cfg --------------------------------------------------------------------------------------------------
def _cfg_own() -> list[bytes]:
    seeds = [(REPO / "daemon" / "profiles" / "awr1843_50m.cfg").read_bytes()]
    return seeds + [p.read_bytes() for p in sorted((OWN_FIXTURES / "fuzz").glob("*.cfg"))]


def _cfg_public() -> list[bytes]:
    if not shared_captures_present():
        return []
    return [p.read_bytes() for p in sorted(SHARED_FIXTURES.joinpath("awr1843").glob("*.cfg"))]


def run_cfg(data: bytes, rnd: random.Random) -> None:
    """cfg text, decoded as ``load_profile`` decodes a file; a profile it accepts gives a usable chirp design."""
    from drivers.awr1843.errors import RadarProfileError
    from drivers.awr1843.profile import MAX_CHIRP_INDEX, MAX_LOOPS, parse_profile

    try:
        p = parse_profile(data.decode("utf-8", errors="replace"), source="fuzz.cfg")
    except RadarProfileError:
        return
    assert 0 <= p.chirp_start <= p.chirp_end <= MAX_CHIRP_INDEX and 1 <= p.num_loops <= MAX_LOOPS
    for name in ("frame_period_s", "range_bin_m", "range_resolution_m", "max_range_m", "wavelength_m",
                 "chirp_time_s", "max_velocity_mps", "velocity_resolution_mps", "active_frame_time_s"):  # fmt: skip
        value = getattr(p, name)
        assert math.isfinite(value) and value > 0, f"{name} = {value}"
    assert p.num_range_bins <= 16384 and p.num_doppler_bins <= 256


# ---- the TOML config --------------------------------------------------------------------------------------------
def _config_seeds() -> list[bytes]:
    example = (REPO / "config" / "usv-tracker.toml").read_bytes()
    return [
        example,
        (OWN_FIXTURES / "fuzz" / "config_latin1.toml").read_bytes(),
        b"[tracker.radar.kalman]\naccel_std = 0.7\n",
    ]


def run_config(data: bytes, rnd: random.Random) -> None:
    """The bytes as a config file through load_config: a Config whose every section checks out, or ConfigError."""
    from daemon.config import load_config
    from daemon.config_schema import ConfigError

    path = scratch_dir() / "input.toml"
    path.write_bytes(data)
    try:
        config = load_config(path)
    except ConfigError as exc:
        assert exc.problems and all(isinstance(p, str) and p for p in exc.problems)
        return
    for section in (config.lidar, config.radar, config.mavlink, config.boat, config.output):
        assert section.validate() == [], section


# ---- MAVLink in -----------------------------------------------------------------------------------------------
def mavlink_messages() -> list[bytes]:
    """Encoded MAVLink 2 messages of every kind the daemon reads, from its autopilot (1/1) and from others."""
    from daemon.mavlink_env import mavlink

    out = []
    for sysid, compid in ((1, 1), (1, 191), (2, 1)):
        mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        msgs = [
            mav.heartbeat_encode(mavlink.MAV_TYPE_SURFACE_BOAT, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4),
            mav.attitude_encode(1000, 0.01, -0.02, 1.5, 0.0, 0.0, 0.1),
            mav.attitude_encode(1010, float("nan"), 0.0, 0.0, 0.0, 0.0, 0.0),
            mav.local_position_ned_encode(1020, 1.0, 2.0, 0.0, 0.5, 0.0, 0.0),
            mav.global_position_int_encode(1030, 599166667, 107500000, 10000, 0, 50, 0, 0, 9000),
            mav.system_time_encode(1_700_000_000_000_000, 1040),
            mav.timesync_encode(0, 123456789),
            mav.timesync_encode(987654321, 123456789),
            mav.command_ack_encode(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAV_RESULT_ACCEPTED, 0, 0, 1, 196),
            mav.obstacle_distance_encode(0, 0, [65535] * 72, 5, 20, 10000),
            mav.statustext_encode(6, b"PreArm: fuzz"),
        ]
        out += [bytes(m.pack(mav)) for m in msgs]
    return out


def _mavlink_seeds() -> list[bytes]:
    messages = mavlink_messages()
    return [b"".join(messages[i : i + 4]) for i in range(0, len(messages), 2)] + messages


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class MavlinkInput:
    """An AutopilotLink listening on a loopback UDP port, as the daemon's link: each input is one datagram that
    its own port reads and its own handler takes (``MavlinkPort.read``, ``recv_msg``, pymavlink's parser)."""

    def __init__(self) -> None:
        import time

        from daemon.autopilot import AutopilotLink

        port = _free_udp_port()
        self.link = AutopilotLink(f"udpin:127.0.0.1:{port}", reconnect_interval=0.05)
        deadline = time.monotonic() + 5.0
        while not self.link.port.service_open():
            assert time.monotonic() < deadline, "the UDP port did not open"
            time.sleep(0.001)
        self.sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.address = ("127.0.0.1", port)

    def feed(self, data: bytes) -> None:
        self.sender.sendto(data[:65507], self.address)
        # on loopback the datagram is queued once sendto returns; one read parses it to the last whole message
        assert self.link.port.read(self.link._handle_safely, 0.5), "the link dropped on bad input"
        counters = self.link.counters
        assert counters.get("link_failures", 0) == 0, counters
        conn = self.link.port._conn
        assert max((len(state.messages) for state in conn.sysid_state.values()), default=0) <= MAX_REMEMBERED_TYPES
        latest = self.link.poses.latest()
        if latest is not None:
            assert np.isfinite(latest.position).all() and math.isfinite(latest.yaw)

    def close(self) -> None:
        self.sender.close()
        self.link.port.close()


@cache
def mavlink_input() -> MavlinkInput:
    feeder = MavlinkInput()
    atexit.register(feeder.close)
    return feeder


def run_mavlink(data: bytes, rnd: random.Random) -> None:
    mavlink_input().feed(data)


TARGETS: dict[str, Target] = {
    t.name: t
    for t in (
        Target("vlp16_data", run_vlp16_data, _vlp16_own, _vlp16_public, max_len=12 * 1206),
        Target("vlp16_position", run_vlp16_position, _position_own, _position_public, max_len=600),
        Target("pcap", run_pcap, _pcap_own, _pcap_public, max_len=1 << 15),
        Target("awr1843_stream", run_awr1843_stream, _radar_own, _radar_public, max_len=8192),
        Target("awr1843_cli", run_awr1843_cli, lambda: list(_CLI_ANSWERS), max_len=1024),
        Target("cfg", run_cfg, _cfg_own, _cfg_public, max_len=8192),
        Target("config", run_config, _config_seeds, max_len=8192),
        Target("mavlink", run_mavlink, _mavlink_seeds, max_len=2048, stateful=True),
    )
}
