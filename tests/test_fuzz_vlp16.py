"""Property tests of the VLP-16 packet decoders and the pcap/pcapng reader: random and mutated inputs never raise
anything but the documented errors, and what comes out is sound (see ``tests/fuzz_targets.py`` for each property)."""

from __future__ import annotations

import random
import struct

from hypothesis import given
from hypothesis import strategies as st

from drivers.vlp16.packet import BLOCK_FLAG, DATA_PACKET_SIZE, POSITION_PACKET_SIZE
from tests.fuzz_strategies import EDGE_INTS, FUZZ, mutated, needs_public_captures, randoms
from tests.fuzz_targets import TARGETS, run_pcap, run_vlp16_data, run_vlp16_position
from tests.test_vlp16_pcap import SENSOR, epb, ethernet, idb, ipv4_udp, shb

DATA, POSITION, PCAP = TARGETS["vlp16_data"], TARGETS["vlp16_position"], TARGETS["pcap"]


@st.composite
def plausible_packets(draw: st.DrawFn) -> bytes:
    """1206 bytes that pass the block-flag check, so the random azimuths, distances, stamps and bytes of mode and
    product reach the decoder (random bytes alone almost never get past the flags)."""
    raw = bytearray(draw(st.binary(min_size=DATA_PACKET_SIZE, max_size=DATA_PACKET_SIZE)))
    for block in range(12):
        struct.pack_into("<HH", raw, 100 * block, BLOCK_FLAG, draw(st.integers(0, 36000)))
    struct.pack_into("<I", raw, 1200, draw(st.integers(0, 3_599_999_999)))
    raw[1204] = draw(st.sampled_from([0x37, 0x38, 0x39, draw(st.integers(0, 255))]))
    raw[1205] = draw(st.sampled_from([0x21, 0x22, 0x28, draw(st.integers(0, 255))]))
    return bytes(raw)


@FUZZ
@given(st.binary(max_size=3 * DATA_PACKET_SIZE), randoms())
def test_data_decoder_random_bytes(data: bytes, rnd: random.Random) -> None:
    run_vlp16_data(data, rnd)


@FUZZ
@given(st.lists(plausible_packets(), min_size=1, max_size=8).map(b"".join), randoms())
def test_data_decoder_plausible_packets(data: bytes, rnd: random.Random) -> None:
    run_vlp16_data(data, rnd)


@FUZZ
@given(mutated(DATA, "own"), randoms())
def test_data_decoder_mutated_synthetic_capture(data: bytes, rnd: random.Random) -> None:
    run_vlp16_data(data, rnd)


@needs_public_captures
@FUZZ
@given(mutated(DATA, "public"), randoms())
def test_data_decoder_mutated_public_captures(data: bytes, rnd: random.Random) -> None:
    run_vlp16_data(data, rnd)


@FUZZ
@given(
    st.one_of(
        st.binary(max_size=600),
        st.binary(min_size=POSITION_PACKET_SIZE, max_size=POSITION_PACKET_SIZE),
        mutated(POSITION, "own"),
    ),
    randoms(),
)
def test_position_decoder(data: bytes, rnd: random.Random) -> None:
    run_vlp16_position(data, rnd)


@needs_public_captures
@FUZZ
@given(mutated(POSITION, "public"), randoms())
def test_position_decoder_mutated_public_captures(data: bytes, rnd: random.Random) -> None:
    run_vlp16_position(data, rnd)


_MAGICS = [b"\xd4\xc3\xb2\xa1", b"\xa1\xb2\xc3\xd4", b"\x4d\x3c\xb2\xa1", b"\x0a\x0d\x0d\x0a", b"\x1f\x8b", b""]


@FUZZ
@given(st.sampled_from(_MAGICS), st.binary(max_size=600), randoms())
def test_pcap_reader_random_bytes_behind_a_magic(magic: bytes, tail: bytes, rnd: random.Random) -> None:
    run_pcap(magic + tail, rnd)


@st.composite
def pcapng_files(draw: st.DrawFn) -> bytes:
    """Section and interface headers and packet blocks of any type, with true or random length fields and bodies
    that may be too short for the block's fields: the shapes that once crashed the reader."""
    order = draw(st.sampled_from("<>"))
    out = [shb(order), idb(order, draw(st.sampled_from([1, 101, 113, 276, 0, 108, 228, 9999])))]
    frame = ethernet(ipv4_udp(SENSOR, 2368, 2368, draw(st.binary(max_size=64))))
    for _ in range(draw(st.integers(0, 6))):
        kind = draw(st.sampled_from(["epb", "raw", "shb"]))
        if kind == "epb":
            out.append(epb(order, draw(st.integers(0, 3)), draw(st.integers(0, 2**64 - 1)), frame))
            continue
        block_type = draw(st.sampled_from([1, 2, 3, 5, 6, 0x0A0D0D0A, 0xDEADBEEF]))
        body = draw(st.binary(max_size=48))
        true_length = 12 + len(body)
        length = draw(st.one_of(st.just(true_length), EDGE_INTS.map(lambda v: v & 0xFFFFFFFF)))
        head = struct.pack(order + "II", block_type, length)
        if kind == "shb":
            head += struct.pack(order + "I", 0x1A2B3C4D)
        out.append(head + body + struct.pack(order + "I", length))
    return b"".join(out)


@FUZZ
@given(pcapng_files(), randoms())
def test_pcapng_reader_damaged_blocks(data: bytes, rnd: random.Random) -> None:
    run_pcap(data, rnd)


@FUZZ
@given(mutated(PCAP, "own"), randoms())
def test_pcap_reader_mutated_own_captures(data: bytes, rnd: random.Random) -> None:
    run_pcap(data, rnd)


@needs_public_captures
@FUZZ
@given(mutated(PCAP, "public"), randoms())
def test_pcap_reader_mutated_public_captures(data: bytes, rnd: random.Random) -> None:
    run_pcap(data, rnd)
