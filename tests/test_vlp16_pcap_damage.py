"""Damaged pcapng files: a block too short for its fields is counted and skipped, a corrupt length stops the
reading with the packets before it kept, and ``usv-tracker decode`` prints a summary, never a traceback.

The files under ``tests/fixtures/fuzz/`` are what ``damaged_pcapngs()`` makes (a test checks it). Regenerate with
``python -c "from tests.test_vlp16_pcap_damage import write_fixtures; write_fixtures()"``.
"""

from __future__ import annotations

import json
import resource
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from drivers.vlp16.pcap import MAX_BLOCK_LEN, NotAPcapError, PcapReader
from tests.conftest import OWN_FIXTURES
from tests.test_vlp16_decoder import sweep
from tests.test_vlp16_pcap import SENSOR, epb, ethernet, idb, ipv4_udp, shb

FUZZ = OWN_FIXTURES / "fuzz"
LE = "<"


def _raw_block(block_type: int, body: bytes) -> bytes:
    """A block whose length fields agree but whose body is as short as given (no padding to the fields)."""
    total = 12 + len(body)
    return struct.pack("<II", block_type, total) + body + struct.pack("<I", total)


def _data(i: int) -> bytes:
    return ethernet(ipv4_udp(SENSOR, 2368, 2368, sweep(3).payloads[i]))


def _t(i: int) -> int:
    return round(sweep(3).host_times[i] * 1e6)


def damaged_pcapngs() -> dict[str, bytes]:
    head = shb(LE) + idb(LE, 1)
    return {
        # an enhanced packet block of 16 bytes: too short for its 20 bytes of fields
        "pcapng_short_epb.pcapng": head
        + epb(LE, 0, _t(0), _data(0))
        + _raw_block(6, bytes(16))
        + epb(LE, 0, _t(1), _data(1))
        + epb(LE, 0, _t(2), _data(2)),
        # an interface description block of 4 bytes (needs 8): interface 0 is unknown, interface 1 still Ethernet
        "pcapng_short_idb.pcapng": shb(LE)
        + _raw_block(1, bytes(4))
        + idb(LE, 1)
        + epb(LE, 1, _t(0), _data(0))
        + epb(LE, 0, _t(1), _data(1))
        + epb(LE, 1, _t(2), _data(2)),
        # a simple packet block without its 4-byte length field
        "pcapng_short_spb.pcapng": head
        + epb(LE, 0, _t(0), _data(0))
        + _raw_block(3, b"")
        + epb(LE, 0, _t(1), _data(1)),
        # a second section header claiming 4 GiB: the reader once asked for all of it in one read
        "pcapng_corrupt_shb_length.pcapng": head
        + epb(LE, 0, _t(0), _data(0))
        + epb(LE, 0, _t(1), _data(1))
        + struct.pack("<III", 0x0A0D0D0A, 0xFFFFFFF0, 0x1A2B3C4D)
        + bytes(20),
    }


def write_fixtures() -> None:
    for name, data in damaged_pcapngs().items():
        (FUZZ / name).write_bytes(data)


def test_committed_fixtures_are_what_the_generator_makes() -> None:
    for name, data in damaged_pcapngs().items():
        assert (FUZZ / name).read_bytes() == data, name
        assert len(data) < 5000


@pytest.mark.parametrize(
    ("name", "payloads", "bad_blocks", "not_ipv4", "stop_reason"),
    [
        ("pcapng_short_epb.pcapng", [0, 1, 2], 1, 0, ""),
        ("pcapng_short_idb.pcapng", [0, 2], 1, 1, ""),
        ("pcapng_short_spb.pcapng", [0, 1], 1, 0, ""),
        ("pcapng_corrupt_shb_length.pcapng", [0, 1], 0, 0, "corrupt section header (length 4294967280)"),
    ],
)
def test_damaged_blocks_are_counted_and_the_good_packets_kept(
    name: str, payloads: list[int], bad_blocks: int, not_ipv4: int, stop_reason: str
) -> None:
    reader = PcapReader(FUZZ / name)
    assert [d.payload for d in reader] == [sweep(3).payloads[i] for i in payloads]
    st = reader.stats
    assert (st.bad_blocks, st.not_ipv4, st.torn_tail, st.stop_reason) == (
        bad_blocks,
        not_ipv4,
        bool(stop_reason),
        stop_reason,
    )


def _one_gib_address_space() -> None:
    # The unfixed reader asked for 4 GiB in one read: under this limit that fails at once.
    resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))


@pytest.mark.parametrize(
    ("name", "bad_blocks", "stopped_at"),
    [
        ("pcapng_short_epb.pcapng", 1, ""),
        ("pcapng_short_idb.pcapng", 1, ""),
        ("pcapng_short_spb.pcapng", 1, ""),
        ("pcapng_corrupt_shb_length.pcapng", 0, "corrupt section header (length 4294967280)"),
    ],
)
def test_decode_summarises_a_damaged_capture(name: str, bad_blocks: int, stopped_at: str) -> None:
    res = subprocess.run(
        [sys.executable, "-m", "daemon.cli", "decode", str(FUZZ / name), "--json"],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=_one_gib_address_space,
    )
    assert res.returncode == 0, res.stderr
    summary = json.loads(res.stdout.splitlines()[-1])
    assert (summary["bad_blocks"], summary["stopped_at"], summary["format"]) == (bad_blocks, stopped_at, "pcapng")


def test_lengths_no_capture_tool_writes_stop_the_reading(tmp_path: Path) -> None:
    good = shb(LE) + idb(LE, 1) + epb(LE, 0, _t(0), _data(0))
    cases = {
        "over the cap": struct.pack("<II", 6, MAX_BLOCK_LEN + 4) + bytes(64),
        "not a multiple of 4": struct.pack("<II", 6, 42) + bytes(64),
        "shorter than a block": struct.pack("<II", 6, 8) + bytes(64),
        "length fields differ": struct.pack("<II", 6, 16) + bytes(4) + struct.pack("<I", 20),
    }
    reasons = {
        "over the cap": f"corrupt block (length {MAX_BLOCK_LEN + 4})",
        "not a multiple of 4": "corrupt block (length 42)",
        "shorter than a block": "corrupt block (length 8)",
        "length fields differ": "corrupt block (its two length fields differ)",
    }
    for case, tail in cases.items():
        path = tmp_path / "c.pcapng"
        path.write_bytes(good + tail)
        reader = PcapReader(path)
        assert [d.payload for d in reader] == [sweep(3).payloads[0]], case
        assert (reader.stats.torn_tail, reader.stats.stop_reason) == (True, reasons[case])
    # an enhanced packet block whose captured length overruns the block: skipped, the next one read
    overrun = struct.pack("<IIIII", 0, 0, 0, 5000, 5000) + bytes(8)
    path.write_bytes(good + _raw_block(6, overrun) + epb(LE, 0, _t(1), _data(1)))
    reader = PcapReader(path)
    assert [d.payload for d in reader] == sweep(3).payloads[:2]
    assert (reader.stats.bad_blocks, reader.stats.torn_tail) == (1, False)
    # an obsolete packet block (type 2) too short for its 20 bytes of fields: skipped like the enhanced one
    path.write_bytes(good + _raw_block(2, bytes(12)) + epb(LE, 0, _t(1), _data(1)))
    reader = PcapReader(path)
    assert [d.payload for d in reader] == sweep(3).payloads[:2]
    assert (reader.stats.bad_blocks, reader.stats.torn_tail) == (1, False)
    # a bad byte-order magic in the first section header is no capture at all
    path.write_bytes(struct.pack("<III", 0x0A0D0D0A, 28, 0x12345678) + bytes(16))
    with pytest.raises(NotAPcapError, match="bad byte-order magic"):
        list(PcapReader(path))


def test_classic_pcap_record_beyond_any_snaplen_stops_the_reading(tmp_path: Path) -> None:
    frame = _data(0)
    head = struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 1)
    record = struct.pack("<IIII", 1, 0, len(frame), len(frame)) + frame
    path = tmp_path / "c.pcap"
    path.write_bytes(head + record + struct.pack("<IIII", 2, 0, 0x3FFFFFF, 0x3FFFFFF) + bytes(100))
    reader = PcapReader(path)
    assert [d.payload for d in reader] == [sweep(3).payloads[0]]
    assert reader.stats.stop_reason == f"corrupt record (length {0x3FFFFFF})"
