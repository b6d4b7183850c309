"""VLP-16 packet encoder/decoder: byte layout pinned against the spec, checks, position packets."""

from __future__ import annotations

import itertools
import struct

import numpy as np
import pytest
import velodyne_decoder as vd

from drivers.vlp16.packet import (
    DATA_PACKET_SIZE,
    LASER_RING,
    PPS_LOCKED,
    DataPacketHeader,
    PacketError,
    data_packet_problem,
    decode_data_packet,
    decode_position_packet,
    encode_data_packet,
    encode_position_packet,
    nmea_checksum_ok,
    read_data_header,
)
from drivers.vlp16.pcap import PcapReader

GPRMC = "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A"


def _fields() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    azimuth = (np.arange(12) * 20 + 35990) % 36000
    distance = np.zeros((12, 32))
    distance[0, 0] = 1.0
    distance[0, 31] = 131.07
    distance[11, 16] = 2.0011  # rounds to the nearest 2 mm: 2.002 m
    distance[5, 5] = 0.0009  # below half a unit: no return
    reflectivity = np.zeros((12, 32), dtype=np.uint8)
    reflectivity[0, 0] = 100
    reflectivity[11, 16] = 255
    return azimuth.astype(np.uint16), distance, reflectivity


def test_data_packet_bytes_follow_the_spec_layout() -> None:
    azimuth, distance, reflectivity = _fields()
    raw = encode_data_packet(azimuth, distance, reflectivity, 3_599_999_999, return_mode=0x39, product_id=0x22)
    assert len(raw) == DATA_PACKET_SIZE == 1206
    for k in range(12):
        assert raw[100 * k : 100 * k + 2] == b"\xff\xee"  # flag, as on the wire
    assert struct.unpack_from("<H", raw, 2)[0] == 35990
    assert struct.unpack_from("<H", raw, 102)[0] == 10  # wrapped past 0
    assert struct.unpack_from("<HB", raw, 4) == (500, 100)  # block 0 channel 0: 1.0 m / 2 mm
    assert struct.unpack_from("<H", raw, 4 + 3 * 31)[0] == 65535
    assert struct.unpack_from("<HB", raw, 1100 + 4 + 3 * 16) == (1001, 255)  # 2.0011 m -> 1001 units
    assert struct.unpack_from("<H", raw, 500 + 4 + 3 * 5)[0] == 0
    assert raw[1200:1206] == struct.pack("<IBB", 3_599_999_999, 0x39, 0x22)
    # velodyne-decoder's own parser reads the same fields.
    blocks, stamp, model_id, mode = vd.util.parse_packet(raw)
    assert (stamp, model_id, mode) == (3_599_999_999, 0x22, 0x39)
    assert blocks["azimuth"].tolist() == azimuth.tolist()


def test_decode_data_packet_and_header_round_trip() -> None:
    azimuth, distance, reflectivity = _fields()
    raw = encode_data_packet(azimuth, distance, reflectivity, 123_456)
    rec = decode_data_packet(raw)
    assert rec["blocks"]["azimuth"].tolist() == azimuth.tolist()
    np.testing.assert_array_equal(rec["blocks"]["channels"]["distance"] * 0.002, np.rint(distance / 0.002) * 0.002)
    np.testing.assert_array_equal(rec["blocks"]["channels"]["reflectivity"], reflectivity)
    assert read_data_header(raw) == DataPacketHeader(123_456, 0x37, 0x22, 35990, 210)
    assert read_data_header(raw).period_us == 1327.104
    assert data_packet_problem(raw) is None


def test_encoder_rejects_values_the_fields_cannot_hold() -> None:
    azimuth, distance, reflectivity = _fields()
    for bad in (np.nan, -0.1, 131.08):
        d = distance.copy()
        d[3, 3] = bad
        with pytest.raises(ValueError, match="distances"):
            encode_data_packet(azimuth, d, reflectivity, 0)
    with pytest.raises(ValueError, match="block azimuths"):
        encode_data_packet(np.full(12, 36000), distance, reflectivity, 0)
    with pytest.raises(ValueError, match="timestamp"):
        encode_data_packet(azimuth, distance, reflectivity, 3_600_000_000)
    with pytest.raises(ValueError, match="shape"):
        encode_data_packet(azimuth, distance[:, :16], reflectivity, 0)


def test_problems_are_named() -> None:
    azimuth, distance, reflectivity = _fields()
    raw = bytearray(encode_data_packet(azimuth, distance, reflectivity, 0))
    assert data_packet_problem(raw[:1205]) == "size 1205 != 1206"
    bad = bytearray(raw)
    bad[300] = 0
    assert data_packet_problem(bad) == "block 3 flag 0xEE00 != 0xEEFF"
    bad = bytearray(raw)
    bad[1204] = 0x40
    assert data_packet_problem(bad) == "unknown return mode 0x40"
    bad = bytearray(raw)
    struct.pack_into("<H", bad, 202, 36001)
    assert data_packet_problem(bad) == "azimuth > 36000"
    struct.pack_into("<H", bad, 202, 36000)  # written by 2014 firmware instead of 0
    assert data_packet_problem(bad) is None
    with pytest.raises(PacketError):
        read_data_header(raw[:100])


def test_ring_numbering_ranks_lasers_by_elevation() -> None:
    assert LASER_RING.tolist() == [0, 8, 1, 9, 2, 10, 3, 11, 4, 12, 5, 13, 6, 14, 7, 15]


def test_position_packet_round_trip_and_velodyne_decoder_agrees() -> None:
    raw = encode_position_packet(1_234_567, pps_status=PPS_LOCKED, nmea=GPRMC, temp_top_c=45, temp_bottom_c=40)
    assert len(raw) == 512
    assert raw[202] == 2 and raw[206 : 206 + len(GPRMC)] == GPRMC.encode()
    p = decode_position_packet(raw)
    assert (p.timestamp_us, p.pps_status, p.pps_locked, p.nmea) == (1_234_567, 2, True, GPRMC)
    assert (p.temp_top_c, p.temp_bottom_c, p.pps_name) == (45, 40, "locked")
    t = vd.TelemetryPacket(raw)
    assert (t.usec_since_toh, t.pps_status.name, t.nmea_sentence) == (1_234_567, "LOCKED", GPRMC)
    assert (t.temp_board_top, t.temp_board_bottom) == (45, 40)
    assert nmea_checksum_ok(GPRMC)
    assert not nmea_checksum_ok(GPRMC.replace("4807", "4808"))
    with pytest.raises(PacketError):
        decode_position_packet(raw[:511])
    with pytest.raises(ValueError, match="128"):
        encode_position_packet(0, nmea="$" + "X" * 200)


def test_position_packets_of_the_2014_capture(shared_fixtures) -> None:
    """Old firmware: no temperatures, no GPS (PPS absent, empty NMEA), device clock in the header."""
    path = shared_fixtures / "vlp16" / "veloview_vlp-16-test-90deg-1-50-frames.pcap"
    packets = [decode_position_packet(d.payload) for d in PcapReader(path, ports=[8308])]
    assert len(packets) == 367
    assert packets[0].timestamp_us == 1_378_987_175
    assert {p.pps_status for p in packets} == {0}
    assert {p.nmea for p in packets} == {""}
    assert {p.temp_top_c for p in packets} == {0}
    assert all(b.timestamp_us > a.timestamp_us for a, b in itertools.pairwise(packets))
