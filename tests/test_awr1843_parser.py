"""Data-port decoding: real captures with counts from SOURCES.md, damaged streams, encoder round trip.

Expected values for single points are computed here with ``struct`` at fixed byte offsets (an
independent reading of the spec), not with the parser under test.
"""

from __future__ import annotations

import logging
import math
import struct
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from drivers.awr1843.parser import MAGIC, RadarFrameParser, encode_frame
from drivers.awr1843.profile import RadarProfile, parse_profile
from drivers.frames import RadarFrame
from drivers.mount import Mount

WALK = "awr1843/xwr18xx_sdk3.6_walk_50m.dat"
NOISEPROF = "awr1843/xwr18xx_sdk3.6_profile2d_noiseprof.dat"
DOORS = "awr1843/xwr68xx_sdk3.3_ti_doors.dat"
LEGACY = "awr1843/xwr16xx_sdk2.1_legacy_qformat.dat"

# Per SOURCES.md the SDK 2.1 capture came from a Visualizer "best range resolution" cfg: 256 samples at
# 5209 ksps, 70 MHz/us, 2 TX, 16 loops, 100 ms. Its idle/ramp times are not known; these are the test's.
LEGACY_CFG = """\
profileCfg 0 77 100 6 60 0 0 70 1 256 5209 0 0 30
chirpCfg 0 0 0 0 0 0 0 1
chirpCfg 1 1 0 0 0 0 0 2
frameCfg 0 1 16 0 100 1 0
"""


def decode_file(path: Path, chunk: int = 1000, **kwargs: object) -> tuple[list[RadarFrame], RadarFrameParser]:
    data = path.read_bytes()
    parser = RadarFrameParser(**kwargs)  # type: ignore[arg-type]
    frames: list[RadarFrame] = []
    for i in range(0, len(data), chunk):
        frames += parser.feed(data[i : i + chunk], host_time=float(i))
    frames += parser.finish()
    return frames, parser


def assert_bytes_accounted(parser: RadarFrameParser, frames: list[RadarFrame], sizes: dict[int, int]) -> None:
    st = parser.stats
    assert st.bytes_received == sum(sizes[f.frame_number] for f in frames) + st.bytes_skipped + parser.buffered_bytes


# ---------------------------------------------------------------------------------------- captures
def test_walk_capture_sdk36(shared_fixtures: Path) -> None:
    frames, parser = decode_file(shared_fixtures / WALK)
    st = parser.stats
    assert len(frames) == 440
    assert [f.frame_number for f in frames] == list(range(1986, 2426))
    assert (st.frames_ok, st.frames_dropped, st.frames_lost, st.bytes_skipped) == (440, 0, 0, 0)
    assert parser.buffered_bytes == 456  # the truncated last frame
    assert Counter(t for f in frames for t in f.tlv_types) == {1: 440, 2: 440, 6: 440, 7: 244, 9: 440}
    empty = [f for f in frames if f.n_points == 0]
    assert len(empty) == 196
    assert all(f.tlv_types == (1, 2, 6, 9) for f in empty)  # zero-length TLV 1, no TLV 7
    assert all(np.isnan(f.snr).all() for f in frames if 7 not in f.tlv_types)
    assert sum(f.n_points for f in frames) == 411
    assert max(f.n_points for f in frames) == 4
    assert {f.sdk_version for f in frames} == {(3, 6, 0, 0)}
    assert {f.platform for f in frames} == {0xA1843}
    assert all(f.range_profile is not None and f.range_profile.shape == (256,) for f in frames)
    xyz = np.concatenate([f.xyz for f in frames])
    ranges = np.linalg.norm(xyz, axis=1)
    assert ranges.min() == pytest.approx(0.49, abs=0.01)
    assert ranges.max() == pytest.approx(40.1, abs=0.05)
    assert (xyz[:, 0] > 0).all()  # TI y > 0 (in front of the sensor) is body +x with the default mount
    assert (xyz[:, 2] == 0).all()
    snr = np.concatenate([f.snr for f in frames if 7 in f.tlv_types])
    assert snr.min() == pytest.approx(15.3) and snr.max() == pytest.approx(56.6)
    v = np.concatenate([f.doppler for f in frames])
    assert v.min() == pytest.approx(-0.99, abs=0.005) and v.max() == pytest.approx(0.87, abs=0.005)
    # 200 MHz cycle counter: +20,000,000 per 100 ms frame
    steps = np.diff(np.array([f.time_cpu_cycles for f in frames], dtype=np.int64)) % 2**32
    assert np.median(steps) == pytest.approx(20_000_000, rel=1e-3)


def test_walk_capture_first_point_and_side_tlvs(shared_fixtures: Path) -> None:
    raw = (shared_fixtures / WALK).read_bytes()
    frames, _ = decode_file(shared_fixtures / WALK)
    # the first frame with points: find it by walking the headers by hand
    offset = 0
    while struct.unpack_from("<I", raw, offset + 28)[0] == 0:
        offset += struct.unpack_from("<I", raw, offset + 12)[0]
    number, n = struct.unpack_from("<I", raw, offset + 20)[0], struct.unpack_from("<I", raw, offset + 28)[0]
    assert struct.unpack_from("<II", raw, offset + 40) == (1, 16 * n)
    x, y, z, v = struct.unpack_from("<4f", raw, offset + 48)
    assert struct.unpack_from("<II", raw, offset + 48 + 16 * n) == (7, 4 * n)
    snr, noise = struct.unpack_from("<2h", raw, offset + 56 + 16 * n)
    frame = next(f for f in frames if f.frame_number == number)
    assert number == 1995
    # TI (x right, y boresight, z up) -> body FRD (y, x, -z) with the identity mount
    np.testing.assert_allclose(frame.xyz[0], [y, x, -z])
    np.testing.assert_allclose(frame.xyz[0], [16.935158, 36.304604, 0.0], atol=1e-6)
    assert frame.doppler[0] == pytest.approx(v) == pytest.approx(-0.6214997)
    assert frame.snr[0] == pytest.approx(snr / 10) == pytest.approx(19.7)
    assert frame.noise[0] == pytest.approx(noise / 10) == pytest.approx(65.3)
    stats = frame.stats
    assert stats is not None
    assert stats["transmit_output_time_us"] == 7266
    assert frame.temperature is not None
    assert frame.temperature["valid"] == 1.0
    assert frame.temperature["rx0"] == 16.0


def test_noise_profile_capture_starts_mid_frame(shared_fixtures: Path) -> None:
    raw = (shared_fixtures / NOISEPROF).read_bytes()
    frames, parser = decode_file(shared_fixtures / NOISEPROF, chunk=777)
    st = parser.stats
    assert len(frames) == 196
    assert [f.frame_number for f in frames] == list(range(6955, 7151))
    assert st.bytes_skipped == 888 and frames[0].bytes_skipped == 888
    assert parser.buffered_bytes == 0
    assert (st.frames_dropped, st.frames_lost, st.headers_rejected) == (0, 0, 0)
    assert all(f.tlv_types == (1, 7, 2, 3, 6, 9) for f in frames)
    assert min(f.n_points for f in frames) == 2 and max(f.n_points for f in frames) == 10
    assert sum(f.n_points for f in frames) == 1109
    assert all(f.noise_profile is not None and f.noise_profile.shape == (256,) for f in frames)
    # first frame: header at 888, 9 points, TLV 1 payload at 888 + 48
    x, y, z, v = struct.unpack_from("<4f", raw, 888 + 48)
    snr, noise = struct.unpack_from("<2h", raw, 888 + 48 + 16 * 9 + 8)
    f0 = frames[0]
    assert f0.n_points == 9
    np.testing.assert_allclose(f0.xyz[0], [y, x, -z])
    np.testing.assert_allclose(f0.xyz[0], [0.60489017, 0.52609175, 0.0], atol=1e-7)
    assert f0.doppler[0] == v == 0.0
    assert (f0.snr[0], f0.noise[0]) == (pytest.approx(25.3), pytest.approx(87.7))
    assert (snr, noise) == (253, 877)
    rp = struct.unpack_from("<H", raw, 888 + 48 + 16 * 9 + 8 + 36 + 8)[0]
    assert f0.range_profile is not None and f0.range_profile[0] == rp / 512


def test_ti_doors_capture_sdk33_iwr6843(shared_fixtures: Path) -> None:
    frames, parser = decode_file(shared_fixtures / DOORS, chunk=4096)
    assert len(frames) == 101
    assert [f.frame_number for f in frames] == list(range(209, 310))
    assert (parser.stats.bytes_skipped, parser.buffered_bytes) == (0, 0)
    assert Counter(t for f in frames for t in f.tlv_types) == {1: 101, 2: 101, 6: 101, 7: 97}
    assert sum(f.n_points == 0 for f in frames) == 4
    assert sum(f.n_points for f in frames) == 825
    assert {f.sdk_version for f in frames} == {(3, 3, 0, 2)}
    assert {f.platform for f in frames} == {0xA6843}
    assert all(f.temperature is None for f in frames)
    np.testing.assert_allclose(frames[0].xyz[0], [0.08510004, 0.01907768, 0.0], atol=1e-7)


def test_legacy_sdk21_q_format_points(shared_fixtures: Path) -> None:
    raw = (shared_fixtures / LEGACY).read_bytes()
    profile = parse_profile(LEGACY_CFG)
    frames, parser = decode_file(shared_fixtures / LEGACY, chunk=333, profile=profile)
    assert len(frames) == 99
    assert [f.frame_number for f in frames] == list(range(167, 266))
    assert parser.stats.bytes_skipped == 216 and parser.buffered_bytes == 584
    assert all(f.tlv_types == (1, 2, 6) for f in frames)
    assert {f.sdk_version for f in frames} == {(2, 1, 0, 4)}
    assert {f.platform for f in frames} == {0xA1642}
    assert min(f.n_points for f in frames) >= 5 and max(f.n_points for f in frames) == 7
    assert sum(f.n_points for f in frames) == 551
    # first frame at 216: TLV 1 = {u16 5, u16 Q9} + 5 x {rangeIdx, dopplerIdx, peak, x, y, z}
    assert struct.unpack_from("<II", raw, 216 + 40) == (1, 64)
    assert struct.unpack_from("<HH", raw, 216 + 48) == (5, 9)
    range_idx, doppler_idx, _, xq, yq, zq = struct.unpack_from("<HhHhhh", raw, 216 + 52)
    assert (range_idx, doppler_idx, xq, yq, zq) == (15, 0, 10, 335, 0)
    f0 = frames[0]
    np.testing.assert_allclose(f0.xyz[0], [335 / 512, 10 / 512, 0.0])
    # the Q-format position agrees with rangeIdx x range bin (0.0436 m) within one bin
    assert np.linalg.norm(f0.xyz[0]) == pytest.approx(15 * profile.range_bin_m, abs=profile.range_bin_m)
    assert np.isnan(f0.snr).all()
    # velocities: dopplerIdx x velocity resolution, checked on every point of every frame
    offsets = [i for i in range(len(raw)) if raw.startswith(MAGIC, i)][:99]
    idx = []
    for off in offsets:
        n = struct.unpack_from("<I", raw, off + 28)[0]
        idx += [struct.unpack_from("<h", raw, off + 52 + 12 * k + 2)[0] for k in range(n)]
    idx_arr = np.array(idx)
    assert idx_arr.min() == -8 and idx_arr.max() == 0
    np.testing.assert_allclose(np.concatenate([f.doppler for f in frames]), idx_arr * profile.velocity_resolution_mps)


def test_legacy_without_profile_has_nan_velocity_and_says_so_once(
    shared_fixtures: Path, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.WARNING, logger="drivers.awr1843.parser"):
        frames, _ = decode_file(shared_fixtures / LEGACY)
    assert len(frames) == 99
    assert all(np.isnan(f.doppler).all() for f in frames)
    assert sum("velocity is NaN" in r.getMessage() for r in caplog.records) == 1


def test_chunking_does_not_change_the_result(shared_fixtures: Path) -> None:
    raw = (shared_fixtures / DOORS).read_bytes()
    whole, _ = decode_file(shared_fixtures / DOORS, chunk=len(raw))
    rng = np.random.default_rng(7)
    parser = RadarFrameParser()
    pieces: list[RadarFrame] = []
    i = 0
    while i < len(raw):
        step = int(rng.integers(1, 90))
        pieces += parser.feed(raw[i : i + step], 0.0)
        i += step
    assert [f.frame_number for f in pieces] == [f.frame_number for f in whole]
    for a, b in zip(pieces, whole, strict=True):
        np.testing.assert_array_equal(a.xyz, b.xyz)
        np.testing.assert_array_equal(a.snr, b.snr)


# ---------------------------------------------------------------------------------------- encoder
def test_round_trip_to_the_millimetre_and_mount_conversion() -> None:
    rng = np.random.default_rng(3)
    xyz_ti = np.column_stack([rng.uniform(-30, 30, 40), rng.uniform(0.5, 60, 40), rng.uniform(-3, 3, 40)])
    doppler = rng.uniform(-1, 1, 40)
    snr = rng.uniform(15, 50, 40).round(1)
    mount = Mount.from_degrees(x=1.5, y=0.0, z=-0.8, yaw=90.0)
    blob = encode_frame(77, xyz_ti, doppler, snr, 60.0, time_cpu_cycles=123_456, stats=(1, 2, 3, 4, 5, 6))
    assert len(blob) % 32 == 0
    parser = RadarFrameParser(mount=mount)
    (frame,) = parser.feed(blob, host_time=42.5)
    assert (frame.stamp, frame.frame_number, frame.time_cpu_cycles) == (42.5, 77, 123_456)
    # body = Rz(90 deg) @ (y_ti, x_ti, -z_ti) + (1.5, 0, -0.8) = (-x_ti + 1.5, y_ti, -z_ti - 0.8)
    expected = np.column_stack([-xyz_ti[:, 0] + 1.5, xyz_ti[:, 1], -xyz_ti[:, 2] - 0.8])
    np.testing.assert_allclose(frame.xyz, expected, atol=1e-3)
    np.testing.assert_allclose(frame.doppler, doppler, atol=1e-6)  # radial speed: mount-independent
    np.testing.assert_allclose(frame.snr, snr, atol=1e-9)
    np.testing.assert_allclose(frame.noise, 60.0)
    assert frame.stats is not None and list(frame.stats.values()) == [1, 2, 3, 4, 5, 6]


def test_single_point_through_a_pitched_mount() -> None:
    # TI (2, 10, 1): 10 m ahead, 2 m right, 1 m up. Sensor pitched 10 deg up, 3 m above the waterline.
    mount = Mount.from_degrees(z=-3.0, pitch=10.0)
    (frame,) = RadarFrameParser(mount=mount).feed(
        encode_frame(1, np.array([[2.0, 10.0, 1.0]]), np.array([0.5]), 20.0, 50.0), 0.0
    )
    c, s = math.cos(math.radians(10)), math.sin(math.radians(10))
    # sensor-FRD (10, 2, -1); pitch up: x' = c*10 + s*(-1), z' = -s*10 + c*(-1)
    np.testing.assert_allclose(frame.xyz[0], [10 * c - s, 2.0, -10 * s - c - 3.0], atol=1e-6)
    assert frame.doppler[0] == 0.5


def test_zero_object_frame_matches_firmware_layout() -> None:
    blob = encode_frame(5, np.zeros((0, 3)), np.zeros(0), 0.0, 0.0, range_profile=np.full(256, 3.0))
    assert struct.unpack_from("<II", blob, 28) == (0, 2)  # N = 0, two TLVs
    assert struct.unpack_from("<II", blob, 40) == (1, 0)  # empty TLV 1, no TLV 7
    (frame,) = RadarFrameParser().feed(blob, 0.0)
    assert frame.n_points == 0 and frame.tlv_types == (1, 2)
    assert frame.range_profile is not None and (frame.range_profile == 3.0).all()


def test_padding_is_non_zero_and_frames_are_multiples_of_32() -> None:
    blob = encode_frame(9, np.array([[1.0, 5.0, 0.0]]), np.array([0.1]), 20.0, 50.0)
    content = 40 + 8 + 16 + 8 + 4
    assert len(blob) == 96 and content == 76
    assert all(b != 0 for b in blob[content:])


def test_heat_map_tlvs_are_kept_raw() -> None:
    heat = bytes(range(256)) * 4
    blob = encode_frame(3, np.array([[0.0, 4.0, 0.0]]), np.array([0.0]), 30.0, 60.0, extra_tlvs=[(5, heat), (8, b"")])
    (frame,) = RadarFrameParser().feed(blob, 0.0)
    assert frame.tlv_types == (1, 7, 5, 8)
    assert frame.extra == {5: heat, 8: b""}


def test_legacy_encoding_round_trip() -> None:
    profile = parse_profile(LEGACY_CFG)
    xyz = np.array([[0.5, 3.25, 0.0], [-1.0, 7.5, 0.25]])
    v = np.array([-3, 2]) * profile.velocity_resolution_mps
    blob = encode_frame(
        11, xyz, v, 0, 0, version=(2, 1, 0, 4), platform=0xA1642, velocity_resolution=profile.velocity_resolution_mps
    )
    assert blob[-1] == 0x0F
    (frame,) = RadarFrameParser(profile=profile).feed(blob, 0.0)
    np.testing.assert_allclose(frame.xyz, [[3.25, 0.5, 0.0], [7.5, -1.0, -0.25]])
    np.testing.assert_allclose(frame.doppler, v)


def test_non_finite_points_are_skipped_and_counted() -> None:
    xyz = np.array([[1.0, 5.0, 0.0], [np.nan, 6.0, 0.0], [2.0, 1e9, 0.0], [0.0, 9.0, 0.0]])
    blob = encode_frame(4, xyz, np.array([0.1, 0.2, 0.3, 0.4]), np.array([10.0, 11.0, 12.0, 13.0]), 50.0)
    parser = RadarFrameParser()
    (frame,) = parser.feed(blob, 0.0)
    assert parser.stats.points_dropped == 2
    np.testing.assert_allclose(frame.xyz, [[5.0, 1.0, 0.0], [9.0, 0.0, 0.0]])
    np.testing.assert_allclose(frame.snr, [10.0, 13.0])
    np.testing.assert_allclose(frame.doppler, [0.1, 0.4], atol=1e-6)


# ---------------------------------------------------------------------------------------- damage
def _stream(first: int, count: int) -> list[bytes]:
    rng = np.random.default_rng(first)
    out = []
    for k in range(count):
        n = int(rng.integers(0, 6))
        xyz = np.column_stack([rng.uniform(-5, 5, n), rng.uniform(1, 40, n), np.zeros(n)])
        out.append(
            encode_frame(
                first + k,
                xyz,
                rng.uniform(-1, 1, n),
                rng.uniform(15, 40, n),
                60.0,
                range_profile=np.full(64, 5.0),
                stats=(1, 2, 3, 0, 0, 0),
                temperature=(0, 1000, 40, 40, 40, 40, 41, 41, 41, 42, 42, 42),
            )
        )
    return out


def test_garbage_truncation_and_deletion_cost_only_the_damaged_frames() -> None:
    frames = _stream(100, 12)  # frame numbers 100..111
    sizes = {100 + k: len(b) for k, b in enumerate(frames)}
    garbage = bytes(range(3, 40)) + MAGIC[:5]  # 37 bytes + a magic prefix that leads nowhere
    damaged = list(frames)
    damaged[2] = garbage + frames[2]
    damaged[5] = frames[5][:100]  # frame 105 cut: the next header arrives 100 bytes into it
    damaged[8] = frames[8][:60] + frames[8][72:]  # frame 108 loses 12 bytes in its points
    data = b"".join(damaged)
    parser = RadarFrameParser()
    got = parser.feed(data, 1.0) + parser.finish()
    numbers = [f.frame_number for f in got]
    assert numbers == [n for n in range(100, 112) if n not in (105, 108)]
    st = parser.stats
    assert (st.frames_ok, st.frames_dropped, st.frames_lost) == (10, 2, 2)
    assert st.bytes_skipped == len(garbage) + 100 + (sizes[108] - 12)
    by_number = {f.frame_number: f for f in got}
    assert by_number[102].bytes_skipped == len(garbage)
    assert by_number[106].bytes_skipped == 100
    assert by_number[109].bytes_skipped == sizes[108] - 12
    assert_bytes_accounted(parser, got, sizes)
    # the undamaged frames decode exactly as they do from a clean stream
    clean = RadarFrameParser().feed(b"".join(frames), 1.0)
    for f in got:
        np.testing.assert_array_equal(f.xyz, clean[f.frame_number - 100].xyz)


def test_damage_in_a_stream_fed_byte_by_byte() -> None:
    frames = _stream(7, 6)
    data = frames[0] + frames[1][:-40] + b"\x00" * 3 + frames[2] + frames[3][:200] + frames[4] + frames[5]
    parser = RadarFrameParser()
    got: list[RadarFrame] = []
    for i in range(len(data)):
        got += parser.feed(data[i : i + 1], float(i))
    got += parser.finish()
    assert [f.frame_number for f in got] == [7, 9, 11, 12]
    assert (parser.stats.frames_dropped, parser.stats.frames_lost) == (2, 2)
    # host time = the read in which the header became complete (40th byte of the frame)
    assert got[0].stamp == 39.0
    start_9 = len(frames[0]) + len(frames[1]) - 40 + 3
    assert got[1].stamp == float(start_9 + 39)


def test_chance_magic_in_padding_does_not_cost_the_frame() -> None:
    a, b = _stream(1, 2)
    # plant a magic word followed by nonsense in frame 1's padding (SDK 3.x pads with stale bytes)
    hdr_tlv_end = len(a) - 8
    a_bad = bytearray(a)
    a_bad[hdr_tlv_end:] = MAGIC
    pad = len(a) - (40 + sum(8 + struct.unpack_from("<I", a, off + 4)[0] for off in _tlv_offsets(a)))
    assert pad >= 8, "test frame needs room for a planted magic word"
    parser = RadarFrameParser()
    got = parser.feed(bytes(a_bad) + b, 0.0)
    assert [f.frame_number for f in got] == [1, 2]
    assert parser.stats.frames_dropped == 0 and parser.stats.bytes_skipped == 0


def _tlv_offsets(frame: bytes) -> list[int]:
    offs, off = [], 40
    for _ in range(struct.unpack_from("<I", frame, 32)[0]):
        offs.append(off)
        off += 8 + struct.unpack_from("<I", frame, off + 4)[0]
    return offs


def test_implausible_headers_are_rejected_and_resynced() -> None:
    a, b, c = _stream(50, 3)
    bad_len = bytearray(b)
    struct.pack_into("<I", bad_len, 12, len(b) + 5)  # not a multiple of 32
    bad_version = bytearray(c)
    struct.pack_into("<I", bad_version, 8, 0x07000000)
    too_many_points = bytearray(c)
    struct.pack_into("<I", too_many_points, 28, 5000)
    parser = RadarFrameParser()
    got = parser.feed(a + bytes(bad_len) + bytes(bad_version) + bytes(too_many_points) + a, 0.0)
    assert [f.frame_number for f in got] == [50, 50]
    assert parser.stats.headers_rejected == 3
    assert parser.stats.frame_number_resets == 1
    assert parser.stats.bytes_skipped == len(b) + 2 * len(c)


def test_lengths_that_do_not_add_up_drop_the_frame() -> None:
    a, b, c = _stream(20, 3)
    broken = bytearray(b)
    struct.pack_into("<I", broken, 44, struct.unpack_from("<I", b, 44)[0] + 16)  # TLV 1 longer than N says
    parser = RadarFrameParser()
    got = parser.feed(a + bytes(broken) + c, 0.0)
    assert [f.frame_number for f in got] == [20, 22]
    assert (parser.stats.frames_dropped, parser.stats.frames_lost) == (1, 1)
    assert_bytes_accounted(parser, got, {20: len(a), 22: len(c)})


def test_a_frame_overrunning_a_magic_cut_by_the_read_is_dropped_as_in_one_read() -> None:
    """Frame 2 lost 6 padding bytes, so its declared length runs 6 bytes into frame 3's magic word. A read that
    ends 7 bytes into that magic (one byte short of it) once let frame 2 through, with the magic's first bytes as
    its padding, and cost the sound frame 3; whatever the reads, frame 2 is now dropped and frame 3 kept."""
    frames = [encode_frame(k, np.array([[1.0, 5.0, 0.0]]), [0.5], 20.0, 60.0) for k in (1, 2, 3, 4)]
    assert len(frames[1]) == 96  # 76 bytes of header and TLVs, 20 of padding
    stream = frames[0] + frames[1][:90] + frames[2] + frames[3]
    cut = len(frames[0]) + 90 + 7
    for reads in ([stream], [stream[:cut], stream[cut:]]):
        parser = RadarFrameParser()
        got = [f.frame_number for chunk in reads for f in parser.feed(chunk, 0.0)] + [
            f.frame_number for f in parser.finish()
        ]
        assert got == [1, 3, 4]
        assert (parser.stats.frames_dropped, parser.stats.bytes_skipped) == (1, 90)


def test_a_frame_ending_like_a_magic_word_waits_for_bytes_or_for_the_line_to_go_quiet() -> None:
    """Two points and noise 60 dB: header and TLVs fill 96 bytes (no padding) and the frame ends in 0x58 0x02, the
    noise x 10 of its last point, and 0x02 is how a magic word starts. The parser cannot tell yet whether the next
    frame began a byte early; the next read decides, or the pause after the burst (``idle``) does, at once."""
    frame = encode_frame(7, np.array([[1.0, 5.0, 0.0], [2.0, 9.0, 0.0]]), [0.5, -0.25], 20.0, 60.0)
    assert len(frame) == 96 and frame[-1:] == MAGIC[:1]
    parser = RadarFrameParser()
    assert parser.feed(frame, 1.0) == []  # held: its last byte may start the next frame's magic
    got = parser.idle(1.02)
    assert [f.frame_number for f in got] == [7] and got[0].stamp == 1.0 and got[0].n_points == 2
    # the same bytes followed by the next frame in the next read: the same frame, and the next one
    parser = RadarFrameParser()
    assert parser.feed(frame, 1.0) == []
    nxt = encode_frame(8, np.array([[1.0, 5.0, 0.0]]), [0.5], 20.0, 30.0)
    assert [f.frame_number for f in parser.feed(nxt, 1.1) + parser.idle(1.12)] == [7, 8]


def test_a_view_of_the_buffer_held_elsewhere_does_not_stop_the_stream() -> None:
    # A bytearray that something still views (a traceback's frame of the decoder, a debugger walking objects) can
    # neither grow nor shrink: the reader failed with "BufferError: Existing exports of data" and the radar stopped.
    # The parser must go on with a copy, every frame intact.
    blobs = [encode_frame(k, np.array([[1.0, 10.0 + k, 0.0]]), np.array([0.1]), 20.0, 50.0) for k in (1, 2, 3)]
    parser = RadarFrameParser()
    got = [f.frame_number for f in parser.feed(blobs[0] + blobs[1][:40], 0.0)]
    held = memoryview(parser._buf)  # the holder the parser cannot see
    got += [f.frame_number for f in parser.feed(blobs[1][40:] + blobs[2][:10], 0.1)]
    held2 = memoryview(parser._buf)
    got += [f.frame_number for f in parser.feed(blobs[2][10:], 0.2)]
    assert got == [1, 2, 3]
    assert parser.stats.frames_ok == 3 and parser.stats.bytes_skipped == 0
    held.release()
    held2.release()


def _shipped_profile() -> RadarProfile:
    from simulator.radar_model import SHIPPED_PROFILE

    return parse_profile(SHIPPED_PROFILE.read_text())


def test_frames_one_late_read_returns_keep_the_radars_spacing() -> None:
    """A busy host reads the data port late and gets three frames in one read: they are stamped by their frame numbers
    on the radar's 0.1 s period (shifted by the least delay seen), not all at that read's time. Stamped 2 ms apart, a
    still boat's returns from three frames read the position noise as metres per second of speed."""
    profile = _shipped_profile()
    assert profile.frame_period_s == pytest.approx(0.1)
    frames = _stream(41, 8)
    parser = RadarFrameParser(profile)
    reads = [1000.004, 1000.109, 1000.203, 1000.306]  # frames 41-44 read 3-9 ms after they start
    got = [f for frame, t in zip(frames[:4], reads, strict=True) for f in parser.feed(frame, t)]
    got += parser.feed(b"".join(frames[4:7]), 1000.731)  # frames 45-47 in one read, 0.33 s late for the first
    got += parser.feed(frames[7], 1000.805)
    assert [f.frame_number for f in got] == list(range(41, 49))
    # A read that came least late so far stands; the others are the radar's time plus the least delay before them:
    # frame 41's 4 ms, then frame 43's 3 ms.
    least_41, least_43 = 1000.004 - 4.1, 1000.203 - 4.3
    expected = [1000.004, 4.2 + least_41, 1000.203] + [n / 10 + least_43 for n in range(44, 49)]
    np.testing.assert_allclose([f.stamp for f in got], expected, rtol=0, atol=1e-9)
    assert (got[0].stamp, got[2].stamp) == (1000.004, 1000.203)  # exactly their reads
    np.testing.assert_allclose(np.diff([f.stamp for f in got[3:]]), 0.1, rtol=0, atol=1e-9)
    assert all(f.stamp <= t for f, t in zip(got, reads + [1000.731] * 3 + [1000.805], strict=True))


def test_frame_stamps_without_a_profile_or_after_a_radar_restart() -> None:
    """No profile, no period: each frame keeps its read's time. A frame number going back is a radar that started
    counting again: the old delays say nothing of its new count, and no stamp goes back in time."""
    frames = _stream(41, 3)
    bare = RadarFrameParser()
    assert [f.stamp for f in bare.feed(b"".join(frames), 7.5)] == [7.5, 7.5, 7.5]
    parser = RadarFrameParser(_shipped_profile())
    assert [f.stamp for f in parser.feed(frames[0], 50.0)] == [50.0]
    assert [f.stamp for f in parser.feed(frames[1], 50.1)] == [50.1]
    restarted = _stream(1, 2)  # frames 1 and 2 of a new count
    got = parser.feed(restarted[0], 50.21) + parser.feed(restarted[1], 50.31)
    assert [f.frame_number for f in got] == [1, 2]
    assert [f.stamp for f in got] == [50.21, 50.31]
