"""The public VLP-16 captures (shared/fixtures/vlp16) through the replay source, pinned against SOURCES.md.

SOURCES.md counts were measured with velodyne-decoder's defaults (no cut angle: a frame closes after a full
turn from wherever the stream started). ``cut_angle=None`` reproduces that rule and must give the same
frames; the driver's default cut (pi, astern) splits the same points differently but must keep every one.
"""

from __future__ import annotations

import itertools
import math
import threading
from pathlib import Path

import numpy as np
import pytest
import velodyne_decoder as vd

from drivers.frames import LidarScan
from drivers.mount import Mount
from drivers.vlp16.pcap import NotAPcapError, PcapReader
from drivers.vlp16.pcap_source import VelodynePcapSource
from tests.conftest import OWN_FIXTURES
from tests.test_vlp16_decoder import LATENCY_S, MM, SPEC_ELEVATION_DEG, SPEC_OFFSET_MM, sweep

RLU = "rlu_velodyne_example.pcap"
VELOVIEW = "veloview_vlp-16-test-90deg-1-50-frames.pcap"
EINRIDE = "einride_recording_converted.pcap"


def replay(path: Path, **kwargs: object) -> tuple[list[LidarScan], VelodynePcapSource]:
    source = VelodynePcapSource(path, speed=None, **kwargs)  # type: ignore[arg-type]
    return list(source.scans(threading.Event())), source


def counts(scans: list[LidarScan]) -> tuple[int, int, int, int, int, int, int]:
    n = [s.n_points for s in scans]
    inner = n[1:-1] or [0]
    return len(n), n[0], n[-1], min(inner), int(np.median(inner)), max(inner), sum(n)


@pytest.fixture
def captures(shared_fixtures: Path) -> Path:
    return shared_fixtures / "vlp16"


# --- counts -------------------------------------------------------------------------------------------------
def test_full_turn_rule_reproduces_sources_md_frames(captures: Path) -> None:
    scans, _ = replay(captures / RLU, cut_angle=None)
    assert [s.n_points for s in scans] == [29_027, 2_603]
    scans, _ = replay(captures / VELOVIEW, cut_angle=None)
    # SOURCES.md: 51 frames, first 14,370, last 370, interior 13,955 / 13,994 / 14,019, total 700,400.
    assert counts(scans) == (51, 14_370, 370, 13_955, 13_994, 14_019, 700_400)
    scans, _ = replay(captures / EINRIDE, cut_angle=None)
    # SOURCES.md: 14 frames, first 15,798, last 1,222, interior 15,455 / 15,499 / 15,547, total 203,034
    # (the median of 12 interior frames is 15,499.5, truncated here).
    assert counts(scans) == (14, 15_798, 1_222, 15_455, 15_499, 15_547, 203_034)


def test_default_cut_astern_keeps_every_point(captures: Path) -> None:
    scans, source = replay(captures / RLU)
    assert [s.n_points for s in scans] == [24_144, 7_486]
    assert [s.packets for s in scans] == [64, 20]
    scans, source = replay(captures / VELOVIEW)
    assert counts(scans) == (51, 12_624, 7_225, 13_853, 13_889, 13_916, 700_400)
    assert sum(s.packets for s in scans) == source.stats.packets == 1902
    scans, source = replay(captures / EINRIDE)
    assert counts(scans) == (15, 4_123, 13, 15_273, 15_293, 15_330, 203_034)
    assert source.stats.missing == 0 and source.stats.wrong_size == 0


def test_every_full_revolution_starts_and_ends_astern(captures: Path) -> None:
    scans, _ = replay(captures / EINRIDE)
    for before, after in itertools.pairwise(scans):
        assert before.t.max() < after.t.min()
    for scan in scans[1:-1]:
        # Bearing past the cut (body FRD, identity mount): it only grows with time and stays within one turn,
        # so the revolution begins and ends astern. (The stern itself is blocked by the vehicle here.)
        # velodyne-decoder places firings at whole 0.01 deg, so the bearing is compared in those units.
        bearing_cdeg = np.rint(np.degrees(np.arctan2(scan.xyz[:, 1], scan.xyz[:, 0])) * 100).astype(int)
        past_cut = (bearing_cdeg - 18000) % 36000
        in_time_order = past_cut[np.argsort(scan.t, kind="stable")]
        assert np.all(np.diff(in_time_order) >= 0)
        assert in_time_order[0] < 3110 and in_time_order[-1] > 34000


# --- values -------------------------------------------------------------------------------------------------
def test_first_point_matches_the_raw_bytes_through_the_spec_formula(captures: Path) -> None:
    scans, _ = replay(captures / RLU)
    first = scans[0]
    i = int(np.argmin(first.t))
    # Pinned: body FRD (identity mount), ring 0, reflectivity 48, fired at the first packet's device time.
    assert first.xyz[i] == pytest.approx([-2.70047, -3.74980, 1.22696], abs=1e-5)
    assert (int(first.ring[i]), float(first.intensity[i])) == (0, 48.0)

    # Independently: velodyne-decoder's raw packet parser + spec sections 3 and 5.
    payload = next(iter(PcapReader(captures / RLU, ports=[2368]))).payload
    blocks, _stamp, _model, _mode = vd.util.parse_packet(payload)
    azimuth, gap = float(blocks["azimuth"][0]), float((blocks["azimuth"][1] - blocks["azimuth"][0]) % 36000)
    distance = blocks["measurements"]["distance"][0] * 0.002
    channel = int(np.argmax(distance[:16] >= 0.1))  # first laser of sequence A with a return
    alpha = math.radians((azimuth + gap * 2.304 * channel / (2 * 55.296)) / 100)
    omega = math.radians(SPEC_ELEVATION_DEG[channel])
    r = distance[channel]
    x = r * math.cos(omega) * math.cos(alpha)
    y = -r * math.cos(omega) * math.sin(alpha)
    z = r * math.sin(omega) + SPEC_OFFSET_MM[channel] * 1e-3
    assert first.xyz[i] == pytest.approx([x, -y, -z], abs=MM)


def test_device_clock_offsets_of_the_captures(captures: Path) -> None:
    # rlu: the sensor clock free-runs ~29.8 min ahead of the PC (SOURCES.md: stamp.device - host ~1790 s).
    scans, _ = replay(captures / RLU)
    assert scans[0].stamp_device - scans[0].stamp == pytest.approx(1790.033, abs=0.001)
    # einride: pcap time was made from the packets' own timestamps, so the two clocks agree exactly
    # and each point's host time is its firing time.
    scans, _ = replay(captures / EINRIDE)
    for scan in scans:
        assert scan.stamp == pytest.approx(scan.stamp_device, abs=1e-6)
    first_packet = next(iter(PcapReader(captures / EINRIDE)))
    assert scans[0].t.min() >= first_packet.timestamp_s
    assert scans[0].t.min() < first_packet.timestamp_s + 55.296e-6


def test_matches_velodyne_decoder_point_for_point_in_body_frd(captures: Path) -> None:
    """Same points as velodyne_decoder.read_pcap, converted FLU -> FRD, with the same device times."""
    ours, _ = replay(captures / EINRIDE, cut_angle=None)
    theirs = list(vd.read_pcap(str(captures / EINRIDE)))
    assert len(ours) == len(theirs)
    for scan, (stamp, points) in zip(ours, theirs, strict=True):
        np.testing.assert_array_equal(scan.xyz, points[:, :3].astype(np.float64) * [1.0, -1.0, -1.0])
        np.testing.assert_array_equal(scan.ring, points[:, 6].astype(np.uint8))
        np.testing.assert_array_equal(scan.intensity, points[:, 3])
        np.testing.assert_allclose(scan.t, stamp.device + points[:, 4].astype(np.float64), atol=1e-6)


def test_early_firmware_capture_decoded_as_vlp16_with_16_rings(captures: Path) -> None:
    forced, source = replay(captures / VELOVIEW)  # model "VLP16" is the driver's default
    assert source.assembler.stats.patched_product == 1902
    assert {s.model for s in forced} == {"VLP16"}
    assert set(np.unique(np.concatenate([s.ring for s in forced])).tolist()) == set(range(16))
    auto, _ = replay(captures / VELOVIEW, model="auto")
    assert {s.model for s in auto} == {"HDL32E"}
    assert np.concatenate([s.ring for s in auto]).max() == 31
    # Same points either way; the geometry (and so where the cut falls) differs.
    assert sum(s.n_points for s in auto) == sum(s.n_points for s in forced) == 700_400

    def elevation_deg(scans: list[LidarScan]) -> np.ndarray:
        xyz = np.concatenate([s.xyz for s in scans])
        return np.degrees(np.arctan2(-xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1])))

    assert np.abs(elevation_deg(forced)).max() < 15.5  # VLP-16: +-15 deg (+ the 1 cm beam offsets up close)
    assert elevation_deg(auto).min() < -25.0  # HDL-32E lasers reach down to -30.67 deg
    # Position packets: old firmware, no GPS.
    assert source.stats.position_packets == 367
    assert source.stats.pps_name == "absent" and not any(s.pps_locked for s in forced)


def test_mount_is_applied_once(captures: Path) -> None:
    plain, _ = replay(captures / RLU)
    mounted, _ = replay(captures / RLU, mount=Mount(x=2.0, z=-1.5, yaw=math.pi))
    # Sensor facing astern: body x = -x_s + 2, y = -y_s, z = z_s - 1.5.
    expected = plain[0].xyz * [-1.0, -1.0, 1.0] + [2.0, 0.0, -1.5]
    np.testing.assert_allclose(mounted[0].xyz, expected, atol=1e-9)


# --- the replay source --------------------------------------------------------------------------------------
def test_pcapng_fixture_replay_pinned_exactly() -> None:
    s = sweep(8)
    source = VelodynePcapSource(OWN_FIXTURES / "vlp16_synthetic.pcapng", speed=None)
    (scan,) = list(source.scans())
    assert scan.n_points == len(s.device_time)
    i, j = np.argsort(scan.t), np.argsort(s.device_time)
    np.testing.assert_allclose(scan.xyz[i], s.xyz_sensor_frd[j], atol=MM)
    np.testing.assert_allclose(scan.t[i], s.device_time[j] + LATENCY_S, atol=1e-6)
    assert scan.pps_locked  # a position packet with PPS locked came before the revolution closed
    st = source.stats
    assert (st.packets, st.wrong_size, st.position_packets, st.pps_name) == (8, 1, 1, "locked")
    assert st.nmea.startswith("$GPRMC,000001,A")


def test_replay_honours_stop_accept_ip_and_speed(captures: Path) -> None:
    # Accepting only another sender: nothing decoded, everything counted.
    scans, source = replay(captures / RLU, accept_ip="192.168.1.201")
    assert scans == [] and source.stats.foreign_source == 84
    # Paced replay (0.11 s of capture at 4x) gives the same revolutions as the fast one.
    paced = list(VelodynePcapSource(captures / RLU, speed=4.0).scans(threading.Event()))
    assert [s.n_points for s in paced] == [24_144, 7_486]
    # A slow replay (0.05x: ~50 s) stops promptly when asked.
    stop = threading.Event()
    slow = VelodynePcapSource(captures / EINRIDE, speed=0.05)
    got: list[LidarScan] = []
    worker = threading.Thread(target=lambda: got.extend(slow.scans(stop)))
    worker.start()
    stop.wait(0.3)
    stop.set()
    worker.join(timeout=5)
    assert not worker.is_alive()
    assert not slow.finished and slow.stats.packets < 1000


def test_replay_of_a_file_that_is_not_a_capture(tmp_path: Path) -> None:
    path = tmp_path / "scan.bin"
    path.write_bytes(b"\x00" * 64)
    with pytest.raises(NotAPcapError, match=r"scan\.bin"):
        VelodynePcapSource(path)
    with pytest.raises(ValueError, match="speed"):
        VelodynePcapSource(OWN_FIXTURES / "vlp16_synthetic.pcapng", speed=-1.0)
